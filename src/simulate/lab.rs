//! The campaign for a real cell (`robopost campaign`): the paper's indexing tests, a reversal
//! test of every axis (as ISO 230-2 measures an axis's reversal value) and a reference pose
//! measured at the start, between the tests and at the end (so that drift and the tracker's
//! stability show), fitted to the user's robot, tool and cell. Each indexing test sweeps its
//! axis over the widest range around the reference angle in which every stop — approach moves
//! included — is inside the joint limits, keeps the reflector and the flange above the floor
//! and out of every keep-out box, and has the reflector facing the tracker within its
//! acceptance angle. The stops are those of [`Campaign::plan`] (the virtual campaign's), so the
//! program, the plan and a simulated run agree stop for stop; [`program`] writes them as KRL
//! with a dwell and a point name per measured stop, and markers `simulate program` reads.

use nalgebra::{Matrix3, Vector3};

use super::campaign::{paced, Campaign, IndexingTest, PlannedStop, Repeat, ReversalTest};
use crate::kinematics::{flange_frame, RobotDescription};

/// The version marker that opens a campaign program (a KRL comment).
pub const PROGRAM_VERSION: &str = "; robopost-campaign/1";
/// The comment that starts a test's stops in a campaign program.
pub const TEST_MARK: &str = "; test: ";
/// The comment that names a measured stop (after its motion).
pub const POINT_MARK: &str = "; point ";

/// The cell: robot, reflector, tracker and what the robot must keep out of.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    pub robot: RobotDescription,
    pub robot_name: String,
    /// The reflector's centre in the flange frame, mm.
    pub tool_mm: Vector3<f64>,
    /// The direction the reflector opens towards, in the flange frame (unit); `None`: the
    /// direction of the tracker at the reference pose (the reflector mounted facing it).
    pub reflector_axis: Option<Vector3<f64>>,
    /// The tracker head in the robot base frame, mm.
    pub tracker_mm: Vector3<f64>,
    /// The reflector's acceptance half-angle, degrees (a 1.5" SMR: about 30°).
    pub acceptance_deg: f64,
    /// No stop puts the reflector or the flange below this height, mm.
    pub floor_mm: Option<f64>,
    /// Keep-out boxes, `[x1, y1, z1, x2, y2, z2]` (any two opposite corners), mm.
    pub boxes: Vec<[f64; 6]>,
}

/// The choices of a campaign.
#[derive(Clone, Debug, PartialEq)]
pub struct Choices {
    /// The pose every test starts from (the indexed axis's entry overridden).
    pub reference_deg: [f64; 6],
    pub pitch_deg: f64,
    pub approach_deg: f64,
    /// Reversal steps of every axis, degrees (some shorter, some longer than a gear play).
    pub reversal_steps_deg: Vec<f64>,
    pub dwell_s: f64,
    pub axis_speed_deg_s: f64,
}

impl Default for Choices {
    fn default() -> Choices {
        Choices {
            reference_deg: [0.0, -60.0, 100.0, 0.0, 45.0, 0.0],
            pitch_deg: 1.0,
            approach_deg: 2.0,
            reversal_steps_deg: vec![0.005, 0.01, 0.02, 0.05, 0.1, 0.5, 1.0],
            dwell_s: super::campaign::DEFAULT_DWELL_S,
            axis_speed_deg_s: super::campaign::DEFAULT_AXIS_SPEED_DEG_S,
        }
    }
}

/// Why a pose is refused.
#[derive(Clone, Debug, PartialEq)]
pub enum Refusal {
    Limits,
    Floor,
    KeepOut(usize),
    Facing(f64),
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::Limits => f.write_str("outside the joint limits"),
            Refusal::Floor => f.write_str("below the floor"),
            Refusal::KeepOut(k) => write!(f, "inside keep-out box {}", k + 1),
            Refusal::Facing(a) => write!(f, "reflector {a:.1}° off the tracker"),
        }
    }
}

/// A campaign fitted to a cell.
#[derive(Clone, Debug)]
pub struct LabCampaign {
    /// The stops in visiting order (reference visits labelled `REF`).
    pub stops: Vec<PlannedStop>,
    /// The point name of each measured stop (empty on approach stops).
    pub points: Vec<String>,
    /// The reflector axis used (flange frame).
    pub reflector_axis: Vector3<f64>,
    /// What was left out or shortened, and why, in words.
    pub notes: Vec<String>,
}

impl Cell {
    /// The reflector's position and opening direction (base frame) at `axes`.
    fn reflector(
        &self,
        axes: &[f64; 6],
        axis: &Vector3<f64>,
    ) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let (r, p): (Matrix3<f64>, Vector3<f64>) = flange_frame(&self.robot, axes);
        (p + r * self.tool_mm, r * axis, p)
    }

    /// The reflector axis facing the tracker at `reference` (in the flange frame).
    pub fn facing_axis(&self, reference: &[f64; 6]) -> Vector3<f64> {
        let (r, p) = flange_frame(&self.robot, reference);
        let to_tracker = self.tracker_mm - (p + r * self.tool_mm);
        (r.transpose() * to_tracker).normalize()
    }

    /// Whether a stop at `axes` is allowed, with reflector axis `axis` (flange frame).
    pub fn check(&self, axes: &[f64; 6], axis: &Vector3<f64>) -> Result<(), Refusal> {
        if !self.robot.within_limits(axes) {
            return Err(Refusal::Limits);
        }
        let (smr, opens, flange) = self.reflector(axes, axis);
        if let Some(floor) = self.floor_mm {
            if smr.z < floor || flange.z < floor {
                return Err(Refusal::Floor);
            }
        }
        for (k, b) in self.boxes.iter().enumerate() {
            let inside = |p: &Vector3<f64>| {
                (0..3).all(|c| p[c] >= b[c].min(b[c + 3]) && p[c] <= b[c].max(b[c + 3]))
            };
            if inside(&smr) || inside(&flange) {
                return Err(Refusal::KeepOut(k));
            }
        }
        let to_tracker = (self.tracker_mm - smr).normalize();
        let off = opens.dot(&to_tracker).clamp(-1.0, 1.0).acos().to_degrees();
        if off > self.acceptance_deg {
            return Err(Refusal::Facing(off));
        }
        Ok(())
    }
}

/// The stops of one test alone (approach moves included), as the campaign plans them.
fn stops_of(test: &IndexingTest) -> Vec<PlannedStop> {
    Campaign {
        tests: vec![test.clone()],
        reversals: Vec::new(),
        reference: None,
        dwell_s: 0.0,
        axis_speed_deg_s: 1.0,
    }
    .plan()
    .unwrap_or_default()
}

/// The test of `axis` over the widest range around the reference angle where every stop is
/// allowed, or `None` (with the reason) when not even three stops are.
fn fitted_test(
    cell: &Cell,
    choices: &Choices,
    axis: u8,
    repeat: Option<Repeat>,
    reflector: &Vector3<f64>,
) -> Result<IndexingTest, String> {
    let k = axis as usize - 1;
    let [lo, hi] = cell.robot.limits_deg[k];
    let pitch = choices.pitch_deg;
    let margin = choices.approach_deg;
    let centre = choices.reference_deg[k];
    let mut test = IndexingTest {
        axis,
        // At most half a turn either way of the reference (the paper's A6 test: ±180°).
        from_deg: ((lo + margin).max(centre - 180.0) / pitch).ceil() * pitch,
        to_deg: ((hi - margin).min(centre + 180.0) / pitch).floor() * pitch,
        pitch_deg: pitch,
        reference_deg: choices.reference_deg,
        repeat,
        approach_deg: margin,
    };
    // Shrink from the side of each refused stop (relative to the reference angle) until
    // every stop is allowed: the range is the contiguous one around the reference.
    loop {
        if test.to_deg - test.from_deg < 2.0 * pitch {
            return Err(format!(
                "A{axis}: fewer than three stops around A{axis} = {centre}° are allowed"
            ));
        }
        let refused = stops_of(&test)
            .into_iter()
            .find_map(|s| cell.check(&s.axes_deg, reflector).err().map(|e| (s, e)));
        let Some((stop, _)) = refused else {
            return Ok(test);
        };
        let a = stop.axes_deg[k];
        if a < centre {
            test.from_deg = ((a + margin) / pitch).floor() * pitch + pitch;
        } else {
            test.to_deg = ((a - margin) / pitch).ceil() * pitch - pitch;
        }
    }
}

/// Fits the paper's campaign to `cell`: an indexing test of every axis (A2 repeated at three
/// A3 angles and A3 at three A2 angles, spread over their ranges, where allowed), a reversal
/// test of every axis at three angles of its range, the reference pose at the start, between
/// tests and at the end. `Err` when the reference pose itself is refused.
pub fn fit(cell: &Cell, choices: &Choices) -> Result<LabCampaign, String> {
    let reflector = cell
        .reflector_axis
        .map(|a| a.normalize())
        .unwrap_or_else(|| cell.facing_axis(&choices.reference_deg));
    if let Err(why) = cell.check(&choices.reference_deg, &reflector) {
        return Err(format!(
            "the reference pose {:?} is refused: {why}",
            choices.reference_deg
        ));
    }
    let mut notes = Vec::new();
    let mut tests = Vec::new();
    for axis in 1..=6u8 {
        match fitted_test(cell, choices, axis, None, &reflector) {
            Ok(t) => tests.push(t),
            Err(why) => notes.push(why),
        }
    }
    // Crosstalk: A2 at three angles of A3's range, A3 at three of A2's, each kept only if its
    // own sweep is allowed.
    for (axis, other) in [(2u8, 3u8), (3, 2)] {
        let Some(range) = tests.iter().find(|t| t.axis == other) else {
            continue;
        };
        let span = range.to_deg - range.from_deg;
        let angles: Vec<f64> = [1.0 / 6.0, 0.5, 5.0 / 6.0]
            .map(|f| (range.from_deg + f * span).round())
            .to_vec();
        let mut kept = Vec::new();
        for a in angles {
            let mut c = choices.clone();
            c.reference_deg[other as usize - 1] = a;
            if cell.check(&c.reference_deg, &reflector).is_ok()
                && fitted_test(cell, &c, axis, None, &reflector).is_ok()
            {
                kept.push(a);
            }
        }
        if kept.is_empty() {
            notes.push(format!(
                "A{axis} is not repeated at other A{other} angles: none is allowed"
            ));
            continue;
        }
        let repeat = Repeat {
            axis: other,
            angles_deg: kept,
        };
        match fitted_test(cell, choices, axis, Some(repeat), &reflector) {
            Ok(t) => tests.push(t),
            Err(why) => notes.push(why),
        }
    }
    let reversals: Vec<ReversalTest> = tests
        .iter()
        .filter(|t| t.repeat.is_none())
        .map(|t| ReversalTest {
            axis: t.axis,
            at_deg: [0.25, 0.5, 0.75]
                .map(|f| (t.from_deg + f * (t.to_deg - t.from_deg)).round())
                .to_vec(),
            steps_deg: choices.reversal_steps_deg.clone(),
            reference_deg: t.reference_deg,
        })
        .collect();
    // Visits: REF, each test, REF, …, the reversal tests, REF.
    let mut visits: Vec<(String, [f64; 6], bool)> = Vec::new();
    let reference = |visits: &mut Vec<(String, [f64; 6], bool)>| {
        let below = choices.reference_deg.map(|a| a - choices.approach_deg);
        if cell.check(&below, &reflector).is_ok() {
            visits.push(("REF".into(), below, false));
        }
        visits.push(("REF".into(), choices.reference_deg, true));
    };
    reference(&mut visits);
    let of = |c: Campaign| -> Vec<(String, [f64; 6], bool)> {
        c.plan()
            .unwrap_or_default()
            .into_iter()
            .map(|s| (s.test, s.axes_deg, s.measured))
            .collect()
    };
    for t in &tests {
        visits.extend(of(Campaign {
            tests: vec![t.clone()],
            reversals: Vec::new(),
            reference: None,
            dwell_s: 0.0,
            axis_speed_deg_s: 1.0,
        }));
        reference(&mut visits);
    }
    for r in reversals {
        let planned = of(Campaign {
            tests: Vec::new(),
            reversals: vec![r.clone()],
            reference: None,
            dwell_s: 0.0,
            axis_speed_deg_s: 1.0,
        });
        if let Some((_, axes, _)) = planned
            .iter()
            .find(|(_, a, _)| cell.check(a, &reflector).is_err())
        {
            notes.push(format!(
                "A{} reversal test left out: a stop at {:?} is refused",
                r.axis, axes
            ));
            continue;
        }
        visits.extend(planned);
    }
    reference(&mut visits);
    let stops = paced(visits, choices.dwell_s, choices.axis_speed_deg_s);
    let mut n = 0;
    let points = stops
        .iter()
        .map(|s| {
            if s.measured {
                n += 1;
                format!("P{n:05}")
            } else {
                String::new()
            }
        })
        .collect();
    Ok(LabCampaign {
        stops,
        points,
        reflector_axis: reflector,
        notes,
    })
}

/// The KRL program (`.src`) and its data list (`.dat`) of `campaign`, named `name`: a PTP
/// axis motion per stop, a `; test:` marker where a test starts, `; point NAME` after a
/// measured stop's motion and `; approach` after an approach's, then `WAIT SEC dwell` (with
/// `pulse`, a pulse on that output half-way through the dwell to trigger the tracker).
pub fn program(
    campaign: &LabCampaign,
    cell: &Cell,
    name: &str,
    dwell_s: f64,
    pulse: Option<u16>,
) -> (String, String) {
    let mut src = String::new();
    let measured = campaign.points.iter().filter(|p| !p.is_empty()).count();
    src.push_str(&format!("DEF {name} ( )\n"));
    src.push_str(&format!(
        "{PROGRAM_VERSION}: {} stops, {measured} measured, for the {}\n",
        campaign.stops.len(),
        cell.robot_name
    ));
    let t = cell.tool_mm;
    let a = campaign.reflector_axis;
    src.push_str(&format!(
        "; reflector at X {:.3} Y {:.3} Z {:.3} mm in the flange, opening towards ({:.4}, {:.4}, {:.4}); tracker at X {:.1} Y {:.1} Z {:.1} mm\n",
        t.x, t.y, t.z, a.x, a.y, a.z, cell.tracker_mm.x, cell.tracker_mm.y, cell.tracker_mm.z
    ));
    src.push_str(&format!(
        "$TOOL = {{X {:.3},Y {:.3},Z {:.3},A 0.000,B 0.000,C 0.000}}\n",
        t.x, t.y, t.z
    ));
    src.push_str("$BASE = {X 0.000,Y 0.000,Z 0.000,A 0.000,B 0.000,C 0.000}\n");
    let mut test = None;
    for (s, point) in campaign.stops.iter().zip(&campaign.points) {
        if test != Some(&s.test) {
            src.push_str(&format!("{TEST_MARK}{}\n", s.test));
            test = Some(&s.test);
        }
        let x = s.axes_deg;
        src.push_str(&format!(
            "PTP {{AXIS: A1 {:.6},A2 {:.6},A3 {:.6},A4 {:.6},A5 {:.6},A6 {:.6}}}",
            x[0], x[1], x[2], x[3], x[4], x[5]
        ));
        if point.is_empty() {
            src.push_str(" ; approach\n");
            continue;
        }
        src.push_str(&format!(" {POINT_MARK}{point}\n"));
        match pulse {
            Some(out) => {
                let half = dwell_s / 2.0;
                src.push_str(&format!("WAIT SEC {half:.3}\n"));
                src.push_str(&format!("PULSE($OUT[{out}], TRUE, 0.1)\n"));
                src.push_str(&format!("WAIT SEC {half:.3}\n"));
            }
            None => src.push_str(&format!("WAIT SEC {dwell_s:.3}\n")),
        }
    }
    src.push_str("END\n");
    let dat = format!("DEFDAT {name}\n{PROGRAM_VERSION}\nENDDAT\n");
    (src, dat)
}

/// The test label and whether it is measured of each motion line of a campaign program
/// (1-based line → (test, point name)), read from its markers; `None` when the program is
/// not a campaign program.
pub fn markers(source: &str) -> Option<std::collections::HashMap<u32, (String, Option<String>)>> {
    let mut lines = source.lines();
    if !lines
        .by_ref()
        .take(3)
        .any(|l| l.starts_with(PROGRAM_VERSION))
    {
        return None;
    }
    let mut out = std::collections::HashMap::new();
    let mut test = String::new();
    for (i, l) in source.lines().enumerate() {
        if let Some(t) = l.strip_prefix(TEST_MARK) {
            test = t.trim().to_string();
        } else if l.starts_with("PTP ") {
            let point = l.split_once(POINT_MARK).map(|(_, p)| p.trim().to_string());
            out.insert(i as u32 + 1, (test.clone(), point));
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell() -> Cell {
        Cell {
            robot: RobotDescription::kr30ha(),
            robot_name: "KR 30 HA".into(),
            tool_mm: Vector3::new(0.0, 50.0, 150.0),
            reflector_axis: None,
            tracker_mm: Vector3::new(3000.0, 0.0, 800.0),
            acceptance_deg: 30.0,
            floor_mm: Some(0.0),
            boxes: Vec::new(),
        }
    }

    #[test]
    fn every_stop_is_allowed_and_the_reference_recurs() {
        let c = cell();
        let lab = fit(&c, &Choices::default()).unwrap();
        let axis = lab.reflector_axis;
        for s in &lab.stops {
            assert_eq!(c.check(&s.axes_deg, &axis), Ok(()), "{s:?}");
        }
        let refs = lab
            .stops
            .iter()
            .filter(|s| s.test == "REF" && s.measured)
            .count();
        // Start, after each of the 8 tests (6 axes + 2 crosstalk), end.
        assert_eq!(refs, 1 + 8 + 1, "{:?}", lab.notes);
        // Each sweep is the widest allowed: one step more on either side (its approach move
        // one step further out) is refused, beyond the limits or half a turn from the reference.
        let reference = Choices::default().reference_deg;
        for k in 0..6 {
            let label = format!("A{}", k + 1);
            let angles: Vec<f64> = lab
                .stops
                .iter()
                .filter(|s| s.test == label && s.measured)
                .map(|s| s.axes_deg[k])
                .collect();
            let (lo, hi) = angles
                .iter()
                .fold((f64::MAX, f64::MIN), |(l, h), a| (l.min(*a), h.max(*a)));
            for beyond in [lo - 2.0 - 1.0, hi + 2.0 + 1.0] {
                let mut axes = reference;
                axes[k] = beyond;
                let half_turn = (beyond - reference[k]).abs() > 180.0;
                assert!(
                    half_turn || c.check(&axes, &axis).is_err(),
                    "{label}: {lo}..{hi}"
                );
            }
        }
        // A1 turns the reflector away from the tracker: its sweep is far shorter than its limits.
        let a1: Vec<f64> = lab
            .stops
            .iter()
            .filter(|s| s.test == "A1")
            .map(|s| s.axes_deg[0])
            .collect();
        assert!(a1.iter().all(|a| a.abs() < 60.0));
    }

    #[test]
    fn a_keep_out_box_shortens_the_sweeps_and_markers_read_back() {
        let mut c = cell();
        // A box just below the reference pose's reflector.
        let reference = Choices::default().reference_deg;
        let (r, p) = flange_frame(&c.robot, &reference);
        let smr = p + r * c.tool_mm;
        c.boxes.push([
            smr.x - 400.0,
            smr.y - 400.0,
            0.0,
            smr.x + 400.0,
            smr.y + 400.0,
            smr.z - 80.0,
        ]);
        let lab = fit(&c, &Choices::default()).unwrap();
        let b = c.boxes[0];
        for s in &lab.stops {
            let (r, p) = flange_frame(&c.robot, &s.axes_deg);
            for q in [p, p + r * c.tool_mm] {
                let inside =
                    (0..3).all(|k| q[k] >= b[k].min(b[k + 3]) && q[k] <= b[k].max(b[k + 3]));
                assert!(!inside, "{s:?}");
            }
        }
        let (src, dat) = program(&lab, &c, "cal", 3.2, Some(17));
        assert!(dat.starts_with("DEFDAT cal"));
        let m = markers(&src).unwrap();
        let measured = m.values().filter(|(_, p)| p.is_some()).count();
        assert_eq!(
            measured,
            lab.points.iter().filter(|p| !p.is_empty()).count()
        );
        assert_eq!(m.len(), lab.stops.len());
        assert!(src.contains("PULSE($OUT[17], TRUE, 0.1)"));
        assert!(markers("DEF x ( )\nEND\n").is_none());
    }
}
