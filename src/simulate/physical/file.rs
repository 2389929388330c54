//! The physical truth file, `robopost-physical-truth/1`: the robot as it is built and the
//! tracker that measures it, in physical quantities (joint-frame errors in mm and degrees,
//! gear harmonics, play widths, compliances, masses, growth, ppm). Read with
//! `deny_unknown_fields`; every number is checked and a bad one is named by its JSON path.
//! The layout is documented in `docs/physical-truth.md`.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::calibration::{CalError, KukaFrame, RobotRecord};
use crate::kinematics::Payload;

/// The only physical-truth format this build reads and writes.
pub const PHYSICAL_FORMAT: &str = "robopost-physical-truth/1";

/// A physical truth file, as on disk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicalTruthFile {
    /// Always `robopost-physical-truth/1`.
    pub format: String,
    /// The nominal robot: links, limits, senses, offsets and (for gravity) masses.
    pub robot: RobotRecord,
    /// What the arm carries during the measurements.
    #[serde(default)]
    pub payload: Payload,
    /// The retroreflector in the KUKA flange frame, mm.
    pub target_mm: [f64; 3],
    /// The error of each joint frame (A1..A6), relative to where the nominal arm puts it.
    #[serde(default)]
    pub joints: [JointError; 6],
    /// Each axis's gear: transmission error and play.
    #[serde(default)]
    pub gears: [Gear; 6],
    /// Angular deflection of each axis per gravity torque about it, deg/kN·m.
    #[serde(default)]
    pub compliance_deg_per_knm: [f64; 6],
    /// Deviation of each axis per change of the moment of inertia it drives (relative to the
    /// reference pose), deg/(kg·m²): the paper's explanation of the A3 → A2 crosstalk.
    #[serde(default)]
    pub inertia_deg_per_kgm2: [f64; 6],
    /// The spring that balances the upper arm on A2; absent: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counterbalance: Option<Counterbalance>,
    /// Links that grow as the robot warms up.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub thermal: Vec<Growth>,
    /// The laser tracker.
    #[serde(default)]
    pub tracker: Tracker,
    /// Seed of the tracker's random errors.
    #[serde(default)]
    pub seed: u64,
    /// Free text: what this truth is for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
}

/// A small rigid displacement of a joint frame, in that frame (base-aligned at the
/// reference pose): translation, then rotation R = Rz(z)·Ry(y)·Rx(x).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointError {
    #[serde(default)]
    pub translation_mm: [f64; 3],
    #[serde(default)]
    pub rotation_deg: [f64; 3],
}

/// One axis's gear.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gear {
    /// Periodic transmission error over the command angle (tooth mesh, eccentricities).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub harmonics: Vec<Harmonic>,
    /// Slow cumulative error: `trend_deg[0]·u + trend_deg[1]·u²`, u = command / 100°.
    #[serde(default)]
    pub trend_deg: [f64; 2],
    /// Width of the play (lost motion) b ≥ 0, degrees: the output lags the command by up to
    /// b/2 and stays put while a reversal is shorter than the play.
    #[serde(default)]
    pub play_deg: f64,
    /// Friction in the train, kN·m: where the net torque about the axis (gravity, plus the
    /// counterbalance on A2) is larger, it holds the output on the flank it pushes towards,
    /// whatever the direction of motion. Absent: the motion alone chooses the flank.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flank_friction_knm: Option<f64>,
}

/// A tension spring from the carousel to the upper arm that balances A2 (a KUKA arm's
/// counterbalance), in the vertical plane of the arm, coordinates from the A2 axis: x forward
/// (away from A1 at A1 = 0), z up. The pin on the arm turns with A2 (A2 = 0: the upper arm
/// horizontal forward, −90°: vertical).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Counterbalance {
    /// The pin on the carousel, [x, z] mm.
    pub anchor_mm: [f64; 2],
    /// Distance of the pin on the upper arm from the A2 axis, mm.
    pub lever_mm: f64,
    /// Angle of that pin from the upper arm's direction, degrees, in A2's sense.
    pub lever_deg: f64,
    /// Tension at length `length_mm`, N.
    pub tension_n: f64,
    /// The spring's length (pin to pin) at tension `tension_n`, mm.
    pub length_mm: f64,
    /// Tension gained per mm of stretch, N/mm.
    pub rate_n_per_mm: f64,
}

impl Counterbalance {
    /// The torque the spring puts on the upper arm about A2 at output angle `a2_deg`, kN·m,
    /// signed like the KUKA angle (A2 turns about +Y).
    pub fn torque_knm(&self, a2_deg: f64) -> f64 {
        let turn = (a2_deg + self.lever_deg).to_radians();
        // Turning +x about +Y by θ gives (cos θ, −sin θ) in (x, z).
        let pin = [self.lever_mm * turn.cos(), -self.lever_mm * turn.sin()];
        let to_anchor = [self.anchor_mm[0] - pin[0], self.anchor_mm[1] - pin[1]];
        let length = to_anchor[0].hypot(to_anchor[1]);
        if length == 0.0 {
            return 0.0;
        }
        let tension = self.tension_n + self.rate_n_per_mm * (length - self.length_mm);
        let force = [
            tension * to_anchor[0] / length,
            tension * to_anchor[1] / length,
        ];
        // (r × F)·ŷ = r_z·F_x − r_x·F_z, N·mm.
        (pin[1] * force[0] - pin[0] * force[1]) / 1e6
    }
}

/// `amplitude · sin(2π·A/period + phase)`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Harmonic {
    pub amplitude_deg: f64,
    pub period_deg: f64,
    #[serde(default)]
    pub phase_deg: f64,
}

/// A link that grows as it warms up: the offset into joint frame `joint` (1..6; 7 is the
/// flange) gains `mm` (in the previous frame) as `1 − exp(−t/τ)` of the campaign clock.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Growth {
    pub joint: u8,
    pub mm: [f64; 3],
    pub time_constant_h: f64,
}

/// The laser tracker: where it stands, the frame it reports in, its scale and its noise.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tracker {
    /// Pose of the tracker's frame in the robot base frame (`p_base = F · p_tracker`, a KUKA
    /// frame); absent: it reports in the base frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<KukaFrame>,
    /// Tracker head in the base frame, mm; absent: the frame's origin, else 3 m in front of
    /// the robot at the height of A2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub station_mm: Option<[f64; 3]>,
    /// Distance scale error, ppm (air temperature and pressure compensation: 1 ppm per °C).
    #[serde(default)]
    pub scale_ppm: f64,
    #[serde(default)]
    pub noise: Noise,
}

/// Random error per coordinate: `sigma_um + sigma_um_per_m · distance` times a unit-variance
/// Student-t draw (normal when `student_t_dof` is absent), and with probability
/// `gross_probability` a gross error of `gross_mm[0]..gross_mm[1]` in a random direction (a
/// beam break, a dirty reflector).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Noise {
    #[serde(default = "default_sigma")]
    pub sigma_um: f64,
    #[serde(default = "default_sigma_per_m")]
    pub sigma_um_per_m: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub student_t_dof: Option<f64>,
    #[serde(default)]
    pub gross_probability: f64,
    #[serde(default = "default_gross")]
    pub gross_mm: [f64; 2],
}

fn default_sigma() -> f64 {
    5.0
}
fn default_sigma_per_m() -> f64 {
    2.5
}
fn default_gross() -> [f64; 2] {
    [0.3, 3.0]
}

impl Default for Noise {
    fn default() -> Self {
        Noise {
            sigma_um: default_sigma(),
            sigma_um_per_m: default_sigma_per_m(),
            student_t_dof: None,
            gross_probability: 0.0,
            gross_mm: default_gross(),
        }
    }
}

impl Noise {
    /// No random error at all.
    #[cfg(any(test, feature = "internals"))]
    pub const NONE: Noise = Noise {
        sigma_um: 0.0,
        sigma_um_per_m: 0.0,
        student_t_dof: None,
        gross_probability: 0.0,
        gross_mm: [0.3, 3.0],
    };
}

impl PhysicalTruthFile {
    /// Checks every value; errors name the JSON path.
    pub fn validate(&self, path: &Path) -> Result<(), CalError> {
        let bad = |key: String, expected: &str, found: String| {
            Err(CalError::invalid(path, key, expected, found))
        };
        if self.format != PHYSICAL_FORMAT {
            return bad(
                "format".into(),
                &format!("\"{PHYSICAL_FORMAT}\""),
                format!("\"{}\"", self.format),
            );
        }
        let d = &self.robot.description;
        let l = &d.links;
        for (name, v) in l.named() {
            if !v.is_finite() {
                return bad(
                    format!("robot.description.links.{name}"),
                    "a finite number",
                    v.to_string(),
                );
            }
        }
        for k in 0..6 {
            let [lo, hi] = d.limits_deg[k];
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return bad(
                    format!("robot.description.limits_deg[{k}]"),
                    "[min, max] with min < max",
                    format!("[{lo}, {hi}]"),
                );
            }
            if d.senses[k] != 1.0 && d.senses[k] != -1.0 {
                return bad(
                    format!("robot.description.senses[{k}]"),
                    "1 or -1",
                    d.senses[k].to_string(),
                );
            }
            if !d.offsets_deg[k].is_finite() {
                return bad(
                    format!("robot.description.offsets_deg[{k}]"),
                    "a finite number",
                    d.offsets_deg[k].to_string(),
                );
            }
        }
        let finite = |key: String, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                bad(key, "a finite number", v.to_string())
            }
        };
        let non_negative = |key: String, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                bad(key, "a non-negative number", v.to_string())
            }
        };
        finite("payload.mass_kg".into(), self.payload.mass_kg)?;
        for c in 0..3 {
            finite(format!("payload.cog_mm[{c}]"), self.payload.cog_mm[c])?;
            finite(format!("target_mm[{c}]"), self.target_mm[c])?;
        }
        for (j, e) in self.joints.iter().enumerate() {
            for c in 0..3 {
                finite(
                    format!("joints[{j}].translation_mm[{c}]"),
                    e.translation_mm[c],
                )?;
                finite(format!("joints[{j}].rotation_deg[{c}]"), e.rotation_deg[c])?;
            }
        }
        for (g, gear) in self.gears.iter().enumerate() {
            non_negative(format!("gears[{g}].play_deg"), gear.play_deg)?;
            if let Some(f) = gear.flank_friction_knm {
                non_negative(format!("gears[{g}].flank_friction_knm"), f)?;
            }
            for c in 0..2 {
                finite(format!("gears[{g}].trend_deg[{c}]"), gear.trend_deg[c])?;
            }
            for (h, harmonic) in gear.harmonics.iter().enumerate() {
                let key = |k: &str| format!("gears[{g}].harmonics[{h}].{k}");
                finite(key("amplitude_deg"), harmonic.amplitude_deg)?;
                finite(key("phase_deg"), harmonic.phase_deg)?;
                if !(harmonic.period_deg.is_finite() && harmonic.period_deg > 0.0) {
                    return bad(
                        key("period_deg"),
                        "a positive number",
                        harmonic.period_deg.to_string(),
                    );
                }
            }
        }
        for k in 0..6 {
            finite(
                format!("compliance_deg_per_knm[{k}]"),
                self.compliance_deg_per_knm[k],
            )?;
            finite(
                format!("inertia_deg_per_kgm2[{k}]"),
                self.inertia_deg_per_kgm2[k],
            )?;
        }
        let loads = self
            .compliance_deg_per_knm
            .iter()
            .chain(&self.inertia_deg_per_kgm2)
            .any(|&c| c != 0.0);
        if loads && d.gravity.is_none() {
            return bad(
                "robot.description.gravity".into(),
                "link masses (compliance and inertia need them)",
                "nothing".into(),
            );
        }
        if let Some(c) = &self.counterbalance {
            for (key, v) in [
                ("anchor_mm[0]", c.anchor_mm[0]),
                ("anchor_mm[1]", c.anchor_mm[1]),
                ("lever_deg", c.lever_deg),
                ("rate_n_per_mm", c.rate_n_per_mm),
            ] {
                finite(format!("counterbalance.{key}"), v)?;
            }
            for (key, v) in [
                ("lever_mm", c.lever_mm),
                ("tension_n", c.tension_n),
                ("length_mm", c.length_mm),
            ] {
                non_negative(format!("counterbalance.{key}"), v)?;
            }
        }
        for (i, g) in self.thermal.iter().enumerate() {
            if !(1..=7).contains(&g.joint) {
                return bad(
                    format!("thermal[{i}].joint"),
                    "a joint 1..6 or 7 (the flange)",
                    g.joint.to_string(),
                );
            }
            for c in 0..3 {
                finite(format!("thermal[{i}].mm[{c}]"), g.mm[c])?;
            }
            if !(g.time_constant_h.is_finite() && g.time_constant_h > 0.0) {
                return bad(
                    format!("thermal[{i}].time_constant_h"),
                    "a positive number",
                    g.time_constant_h.to_string(),
                );
            }
        }
        let t = &self.tracker;
        finite("tracker.scale_ppm".into(), t.scale_ppm)?;
        if let Some(f) = &t.frame {
            for (c, v) in f.to_array().iter().enumerate() {
                finite(format!("tracker.frame[{c}]"), *v)?;
            }
        }
        for (c, v) in t.station_mm.iter().flatten().enumerate() {
            finite(format!("tracker.station_mm[{c}]"), *v)?;
        }
        let n = &t.noise;
        non_negative("tracker.noise.sigma_um".into(), n.sigma_um)?;
        non_negative("tracker.noise.sigma_um_per_m".into(), n.sigma_um_per_m)?;
        if let Some(dof) = n.student_t_dof {
            if !(dof.is_finite() && dof > 2.0) {
                return bad(
                    "tracker.noise.student_t_dof".into(),
                    "a number greater than 2 (finite variance)",
                    dof.to_string(),
                );
            }
        }
        if !(0.0..=1.0).contains(&n.gross_probability) {
            return bad(
                "tracker.noise.gross_probability".into(),
                "a probability 0..1",
                n.gross_probability.to_string(),
            );
        }
        let [lo, hi] = n.gross_mm;
        if !(lo.is_finite() && hi.is_finite() && 0.0 <= lo && lo <= hi) {
            return bad(
                "tracker.noise.gross_mm".into(),
                "[min, max] with 0 ≤ min ≤ max",
                format!("[{lo}, {hi}]"),
            );
        }
        Ok(())
    }

    /// Pretty JSON, newline-terminated.
    #[cfg(any(test, feature = "internals"))]
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).map_or_else(|_| String::new(), |s| s + "\n")
    }
}

/// Parses and validates physical-truth JSON; `path` only names the source in errors.
pub fn parse(text: &str, path: &Path) -> Result<PhysicalTruthFile, CalError> {
    let file: PhysicalTruthFile =
        serde_json::from_str(text).map_err(|e| CalError::syntax(path, text, &e))?;
    file.validate(path)?;
    Ok(file)
}
