//! `learned:<action>(<drivers>)` — an effect nobody coded, defined by its name: a smooth
//! low-order function of one or two generic *drivers* that acts on the chain in one chosen way.
//! `diagnose` proposes one when the residual follows something the contract table has no
//! effect for (see `docs/learned-effect.md`); a user may also write one by hand.
//!
//! Drivers (evaluated on the nominal robot at the command angles, so the effect is a function
//! of the command like every other): `An` the command angle (Fourier terms cos, sin of A and
//! 2A), `reach` the horizontal distance of the flange centre from the A1 axis and `height` its
//! height (powers 1..3 of (value − 1 m)/1 m and (value − l1z)/1 m), `gravity` the direction of
//! gravity seen from the A6 frame (its three components), `torque:An` the gravity torque on An
//! (powers 1, 2 of τ/1 kN·m; needs the robot's mass data), `time[T0:T1h]` the campaign clock
//! held at the edge outside the window T0..T1 (hours; powers 1..3 of the clock mapped onto
//! −1..1) and `dir:An` the rotation direction of An (±1, 0 before it first moves). With two
//! drivers `a*b` the function has both drivers' terms plus the products of their first-order
//! terms. There is no constant term: a constant is the geometric effect's.
//!
//! Actions: `angle@An` an angular positioning deviation of An (degrees, KUKA sign),
//! `rotation@An` a small rotation about An's centre, one function per model axis x, y, z of
//! the frame An is carried by (degrees; `rotation@A1` turns the whole robot about its base, in
//! the base frame), `rotation@arm` a rotation of the whole arm about the base's origin with
//! axes that turn with A1 (x along the arm's horizontal direction, y across it, z up: a base
//! that leans under the arm's load), `offset@An` a displacement of An and everything beyond it
//! along the axes of the frame it is carried by (mm; `offset@A1` moves the whole robot in the
//! base frame), `offset@tool` a displacement of the measured target along the A6 frame's axes
//! (mm; at HOME the base X, Y, Z). Parameters are the coefficients, named `<axis>.<term>`
//! (`y.reach1`), linear in the chain slots.

use std::f64::consts::PI;
use std::fmt;
use std::sync::Mutex;

use nalgebra::Vector3;

use super::compliance::gravity_torques_knm;
use super::{EffectError, ToRecord};
use crate::kinematics::RobotDescription;
use crate::model::chain::{link_vectors, ChainFrames};
use crate::model::effect::{ChainErrors, Context, Effect, Parameter, Partial, Slot};
use crate::model::record::{self, EffectRecord, RecordError};
use crate::model::AxisState;

/// How a name's definition is written, for error messages.
pub const SPELLING: &str = "learned:<action>(<driver>[*<driver>]) with action angle@An, \
     rotation@An, rotation@arm, offset@An or offset@tool and drivers An, reach, height, gravity, torque:An, \
     time[T0:T1h], dir:An";

/// Most basis functions of one spec (two angles: 4 + 4 + 2·2; gravity and an angle: 3 + 4 + 3·2).
pub const MAX_TERMS: usize = 16;

/// The `dir:An` driver of axis `n` (0-based): the sign of its last motion, an instant switch.
/// A learned term stays a switch on purpose: a lag that grows with the travel since the last
/// reversal is the gear play's (`backlash:An`), which `diagnose` proposes in its place when
/// the residuals follow the travel (`diagnose::play`).
pub fn reversal(state: &AxisState, n: usize) -> f64 {
    state.directions()[n].sign()
}

/// One generic driver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Driver {
    /// Command angle of An (1..=6).
    Angle(u8),
    /// Horizontal distance of the flange centre from the A1 axis.
    Reach,
    /// Height of the flange centre.
    Height,
    /// Direction of gravity in the A6 frame.
    Gravity,
    /// Gravity torque on An.
    Torque(u8),
    /// The campaign clock, held at the window's edges (hours).
    Time { from_h: f64, to_h: f64 },
    /// Rotation direction of An.
    Direction(u8),
}

/// How the function acts on the chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Action {
    Angle(u8),
    Rotation(u8),
    /// About the base's origin, axes turning with A1.
    Arm,
    Offset(u8),
    Tool,
}

/// Every driver value one state offers (computed once per state, shared by all specs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriverValues {
    pub angles_deg: [f64; 6],
    pub reach_mm: f64,
    pub height_mm: f64,
    /// Unit vector of gravity in the A6 frame.
    pub gravity: [f64; 3],
    pub torques_knm: [f64; 6],
    pub time_h: f64,
    pub reversal: [f64; 6],
}

impl DriverValues {
    /// The drivers at `state` on the nominal robot of `ctx` (the pose only when `pose`, the
    /// torques only when `torques` and the robot has mass data).
    pub fn at(state: &AxisState, ctx: &Context, pose: bool, torques: bool) -> DriverValues {
        let mut v = DriverValues {
            angles_deg: state.axes_deg,
            time_h: state.time_s / 3600.0,
            reversal: std::array::from_fn(|n| reversal(state, n)),
            ..DriverValues::default()
        };
        if pose {
            let frames = ChainFrames::new(ctx.robot, &state.axes_deg, &ChainErrors::default());
            let p = frames.flange_position();
            v.reach_mm = p.x.hypot(p.y);
            v.height_mm = p.z;
            let g = frames.body_rotation(6).transpose() * Vector3::new(0.0, 0.0, -1.0);
            v.gravity = [g.x, g.y, g.z];
        }
        if torques {
            if let Some(t) = gravity_torques_knm(ctx.robot, ctx.payload, &state.axes_deg) {
                v.torques_knm = t;
            }
        }
        v
    }
}

/// A driver's value mapped to about −1..1 (the variable its powers are taken of).
fn unit(driver: &Driver, v: &DriverValues) -> f64 {
    match *driver {
        Driver::Reach => v.reach_mm / 1000.0 - 1.0,
        Driver::Height => (v.height_mm - 1000.0) / 1000.0,
        Driver::Torque(n) => v.torques_knm[n as usize - 1],
        Driver::Time { from_h, to_h } => {
            if to_h > from_h {
                let t = v.time_h.clamp(from_h, to_h);
                2.0 * (t - from_h) / (to_h - from_h) - 1.0
            } else {
                v.time_h
            }
        }
        _ => 0.0,
    }
}

impl Driver {
    /// Number of main terms and of first-order terms.
    pub fn sizes(&self) -> (usize, usize) {
        match self {
            Driver::Angle(_) => (4, 2),
            Driver::Reach | Driver::Height | Driver::Time { .. } => (3, 1),
            Driver::Gravity => (3, 3),
            Driver::Torque(_) => (2, 1),
            Driver::Direction(_) => (1, 1),
        }
    }

    /// The main terms at `v` into `out` (the first-order ones come first).
    pub fn main_terms(&self, v: &DriverValues, out: &mut [f64]) {
        match *self {
            Driver::Angle(n) => {
                let a = v.angles_deg[n as usize - 1].to_radians();
                let (s1, c1) = a.sin_cos();
                let (s2, c2) = (2.0 * a).sin_cos();
                out[..4].copy_from_slice(&[c1, s1, c2, s2]);
            }
            Driver::Gravity => out[..3].copy_from_slice(&v.gravity),
            Driver::Direction(n) => out[0] = v.reversal[n as usize - 1],
            Driver::Reach | Driver::Height | Driver::Time { .. } | Driver::Torque(_) => {
                let u = unit(self, v);
                let (k, _) = self.sizes();
                let mut p = 1.0;
                for o in out.iter_mut().take(k) {
                    p *= u;
                    *o = p;
                }
            }
        }
    }

    /// Names of the main terms, in order.
    pub fn term_names(&self) -> Vec<String> {
        match *self {
            Driver::Angle(n) => ["cos1", "sin1", "cos2", "sin2"]
                .iter()
                .map(|h| format!("A{n}.{h}"))
                .collect(),
            Driver::Reach => (1..=3).map(|k| format!("reach{k}")).collect(),
            Driver::Height => (1..=3).map(|k| format!("height{k}")).collect(),
            Driver::Time { .. } => (1..=3).map(|k| format!("time{k}")).collect(),
            Driver::Gravity => ["gx", "gy", "gz"].iter().map(|s| s.to_string()).collect(),
            Driver::Torque(n) => (1..=2).map(|k| format!("torque:A{n}.{k}")).collect(),
            Driver::Direction(n) => vec![format!("dir:A{n}")],
        }
    }

    /// Whether the driver needs the pose (reach, height, gravity) or the torques.
    fn needs(&self) -> (bool, bool) {
        match self {
            Driver::Reach | Driver::Height | Driver::Gravity => (true, false),
            Driver::Torque(_) => (false, true),
            _ => (false, false),
        }
    }

    /// The driver in a sentence: `the horizontal reach`, `the A5 angle`.
    pub fn phrase(&self) -> String {
        match *self {
            Driver::Angle(n) => format!("the A{n} angle"),
            Driver::Reach => "the horizontal reach".into(),
            Driver::Height => "the height of the flange".into(),
            Driver::Gravity => "the tool's orientation to gravity".into(),
            Driver::Torque(n) => format!("the A{n} gravity torque"),
            Driver::Time { .. } => "time".into(),
            Driver::Direction(n) => format!("the A{n} rotation direction"),
        }
    }
}

impl fmt::Display for Driver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Driver::Angle(n) => write!(f, "A{n}"),
            Driver::Reach => write!(f, "reach"),
            Driver::Height => write!(f, "height"),
            Driver::Gravity => write!(f, "gravity"),
            Driver::Torque(n) => write!(f, "torque:A{n}"),
            Driver::Time { from_h, to_h } if to_h > from_h => write!(f, "time[{from_h}:{to_h}h]"),
            Driver::Time { .. } => write!(f, "time"),
            Driver::Direction(n) => write!(f, "dir:A{n}"),
        }
    }
}

/// The chain slots one output of an action writes, with slot units per stored unit.
pub type Output = Vec<(Slot, f64)>;

impl Action {
    /// Per output (one for an angle, three otherwise, in parameter order) the chain slots it
    /// writes and how much per stored unit (degree or mm).
    pub fn outputs(&self, robot: &RobotDescription) -> Vec<Output> {
        let rad = PI / 180.0;
        match *self {
            Action::Angle(axis) => vec![vec![(Slot::Angle { axis }, rad)]],
            Action::Rotation(axis) => (0..3)
                .map(|coord| vec![(Slot::Tilt { axis, coord }, rad)])
                .collect(),
            Action::Offset(axis) => (0..3)
                .map(|coord| vec![(Slot::Offset { axis, coord }, 1.0)])
                .collect(),
            Action::Tool => (0..3)
                .map(|coord| vec![(Slot::Target { coord }, 1.0)])
                .collect(),
            Action::Arm => {
                // A rotation ω about A2's centre (the tilt slots of A2, in the frame turned by
                // A1) plus the displacement ω × L2 of that centre is the same rotation about
                // the base's origin (to first order).
                let l2 = link_vectors(robot)[1];
                (0..3u8)
                    .map(|coord| {
                        let mut e = Vector3::zeros();
                        e[coord as usize] = 1.0;
                        let shift = e.cross(&l2);
                        let mut out = vec![(Slot::Tilt { axis: 2, coord }, rad)];
                        for (j, v) in shift.iter().enumerate() {
                            if *v != 0.0 {
                                out.push((
                                    Slot::Offset {
                                        axis: 2,
                                        coord: j as u8,
                                    },
                                    rad * v,
                                ));
                            }
                        }
                        out
                    })
                    .collect()
            }
        }
    }

    /// The stored unit of its coefficients.
    fn unit(&self) -> &'static str {
        match self {
            Action::Angle(_) | Action::Rotation(_) | Action::Arm => "deg",
            Action::Offset(_) | Action::Tool => "mm",
        }
    }

    /// Every action, in screening order.
    pub fn all() -> Vec<Action> {
        let mut v: Vec<Action> = (1..=6).map(Action::Angle).collect();
        v.extend((1..=6).map(Action::Rotation));
        v.push(Action::Arm);
        v.extend((1..=6).map(Action::Offset));
        v.push(Action::Tool);
        v
    }
}

impl fmt::Display for Action {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Action::Angle(n) => write!(f, "angle@A{n}"),
            Action::Rotation(n) => write!(f, "rotation@A{n}"),
            Action::Arm => write!(f, "rotation@arm"),
            Action::Offset(n) => write!(f, "offset@A{n}"),
            Action::Tool => write!(f, "offset@tool"),
        }
    }
}

/// A parsed definition: the action and one or two drivers.
#[derive(Clone, Debug, PartialEq)]
pub struct Spec {
    pub action: Action,
    pub drivers: Vec<Driver>,
}

impl fmt::Display for Spec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d: Vec<String> = self.drivers.iter().map(|d| d.to_string()).collect();
        write!(f, "{}({})", self.action, d.join("*"))
    }
}

fn axis_number(text: &str) -> Option<u8> {
    let digits = text.strip_prefix(['a', 'A'])?;
    match digits.parse::<u8>() {
        Ok(n @ 1..=6) => Some(n),
        _ => None,
    }
}

/// A `learned:` definition that does not parse: the offending part and what was expected.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpecError {
    /// Not `<action>(<drivers>)`.
    #[error("`{definition}`: expected <action>(<drivers>)")]
    Shape {
        /// The definition given.
        definition: String,
    },
    /// Not one of the actions.
    #[error(
        "`{action}` is not an action (angle@An, rotation@An, rotation@arm, offset@An, offset@tool)"
    )]
    UnknownAction {
        /// The action given.
        action: String,
    },
    /// Not one of the drivers.
    #[error(
        "`{driver}` is not a driver (An, reach, height, gravity, torque:An, time[T0:T1h], dir:An)"
    )]
    UnknownDriver {
        /// The driver given.
        driver: String,
    },
    /// A driver of one axis (`torque:An`, `dir:An`) without an axis 1..6 after `prefix`.
    #[error("`{driver}`: expected {prefix}An with n in 1..6")]
    DriverAxis {
        /// The driver given.
        driver: String,
        /// Its prefix (`torque:`, `dir:`).
        prefix: String,
    },
    /// A time window that is not `time[T0:T1h]` with finite `T0 < T1`.
    #[error("`{driver}`: expected time[T0:T1h] with T0 < T1 in hours")]
    TimeWindow {
        /// The driver given.
        driver: String,
    },
    /// No driver, or more than two.
    #[error("`{definition}`: one driver or two joined by `*`")]
    DriverCount {
        /// The definition given.
        definition: String,
    },
    /// The same driver twice (`A2*A2`).
    #[error("`{definition}`: the same driver twice")]
    SameDriver {
        /// The definition given.
        definition: String,
    },
}

fn parse_driver(text: &str) -> Result<Driver, SpecError> {
    let t = text.trim();
    let lower = t.to_ascii_lowercase();
    if let Some(n) = axis_number(t) {
        return Ok(Driver::Angle(n));
    }
    let axis_after = |prefix: &str| {
        lower
            .strip_prefix(prefix)
            .and_then(axis_number)
            .ok_or_else(|| SpecError::DriverAxis {
                driver: t.to_string(),
                prefix: prefix.to_string(),
            })
    };
    match lower.as_str() {
        "reach" => return Ok(Driver::Reach),
        "height" => return Ok(Driver::Height),
        "gravity" => return Ok(Driver::Gravity),
        "time" => {
            return Ok(Driver::Time {
                from_h: 0.0,
                to_h: 0.0,
            })
        }
        _ => {}
    }
    if lower.starts_with("torque:") {
        return axis_after("torque:").map(Driver::Torque);
    }
    if lower.starts_with("dir:") {
        return axis_after("dir:").map(Driver::Direction);
    }
    if let Some(window) = lower
        .strip_prefix("time[")
        .and_then(|w| w.strip_suffix("h]"))
    {
        let bad = || SpecError::TimeWindow {
            driver: t.to_string(),
        };
        let (a, b) = window.split_once(':').ok_or_else(bad)?;
        let (from_h, to_h) = (
            a.trim().parse::<f64>().map_err(|_| bad())?,
            b.trim().parse::<f64>().map_err(|_| bad())?,
        );
        if !(from_h.is_finite() && to_h.is_finite() && from_h < to_h) {
            return Err(bad());
        }
        return Ok(Driver::Time { from_h, to_h });
    }
    Err(SpecError::UnknownDriver {
        driver: t.to_string(),
    })
}

fn parse_action(text: &str) -> Result<Action, SpecError> {
    let t = text.trim();
    let lower = t.to_ascii_lowercase();
    let bad = || SpecError::UnknownAction {
        action: t.to_string(),
    };
    let (kind, at) = lower.split_once('@').ok_or_else(bad)?;
    if kind == "offset" && at == "tool" {
        return Ok(Action::Tool);
    }
    if kind == "rotation" && at == "arm" {
        return Ok(Action::Arm);
    }
    let n = axis_number(at).ok_or_else(bad)?;
    match kind {
        "angle" => Ok(Action::Angle(n)),
        "rotation" => Ok(Action::Rotation(n)),
        "offset" => Ok(Action::Offset(n)),
        _ => Err(bad()),
    }
}

impl Spec {
    /// Parses the part after `learned:`.
    pub fn parse(text: &str) -> Result<Spec, SpecError> {
        let t = text.trim();
        let open = t
            .find('(')
            .filter(|_| t.ends_with(')'))
            .ok_or_else(|| SpecError::Shape {
                definition: t.to_string(),
            })?;
        let action = parse_action(&t[..open])?;
        let inner = &t[open + 1..t.len() - 1];
        let drivers = inner
            .split('*')
            .map(parse_driver)
            .collect::<Result<Vec<_>, _>>()?;
        if drivers.is_empty() || drivers.len() > 2 {
            return Err(SpecError::DriverCount {
                definition: t.to_string(),
            });
        }
        if drivers.len() == 2
            && std::mem::discriminant(&drivers[0]) == std::mem::discriminant(&drivers[1])
            && drivers[0].to_string() == drivers[1].to_string()
        {
            return Err(SpecError::SameDriver {
                definition: t.to_string(),
            });
        }
        Ok(Spec { action, drivers })
    }

    /// Number of basis functions.
    pub fn n_terms(&self) -> usize {
        let (m0, f0) = self.drivers[0].sizes();
        match self.drivers.get(1) {
            None => m0,
            Some(d) => {
                let (m1, f1) = d.sizes();
                m0 + m1 + f0 * f1
            }
        }
    }

    /// Names of the basis functions, in order.
    pub fn term_names(&self) -> Vec<String> {
        let mut names = self.drivers[0].term_names();
        if let Some(d) = self.drivers.get(1) {
            let (f0, f1) = (self.drivers[0].sizes().1, d.sizes().1);
            let (a, b) = (names.clone(), d.term_names());
            names.extend(b.iter().cloned());
            for x in &a[..f0] {
                for y in &b[..f1] {
                    names.push(format!("{x}*{y}"));
                }
            }
        }
        names
    }

    /// The basis functions at `v` into `out[..n_terms()]`.
    pub fn terms(&self, v: &DriverValues, out: &mut [f64; MAX_TERMS]) {
        let d0 = &self.drivers[0];
        let (m0, f0) = d0.sizes();
        d0.main_terms(v, &mut out[..m0]);
        if let Some(d1) = self.drivers.get(1) {
            let (m1, f1) = d1.sizes();
            d1.main_terms(v, &mut out[m0..m0 + m1]);
            let mut k = m0 + m1;
            for i in 0..f0 {
                for j in 0..f1 {
                    out[k] = out[i] * out[m0 + j];
                    k += 1;
                }
            }
        }
    }

    /// Parameter names as written in the calibration file: `<axis>.<term>` (the term alone
    /// for an angle).
    pub fn local_names(&self) -> Vec<String> {
        let terms = self.term_names();
        match self.action {
            Action::Angle(_) => terms,
            _ => ["x", "y", "z"]
                .iter()
                .flat_map(|c| terms.iter().map(move |t| format!("{c}.{t}")))
                .collect(),
        }
    }

    /// Whether the drivers need the pose and the torques.
    pub fn needs(&self) -> (bool, bool) {
        self.drivers.iter().fold((false, false), |(p, t), d| {
            let (dp, dt) = d.needs();
            (p || dp, t || dt)
        })
    }
}

/// Canonical spellings seen so far, kept for the life of the process so that an effect name
/// can stay a `Copy` value (a handful per run).
static SPELLINGS: Mutex<Vec<&'static str>> = Mutex::new(Vec::new());

/// The canonical spelling of a definition (the part after `learned:`), checked.
pub fn canonical(text: &str) -> Result<&'static str, SpecError> {
    let spelled = Spec::parse(text)?.to_string();
    let mut seen = SPELLINGS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(s) = seen.iter().find(|s| **s == spelled) {
        return Ok(s);
    }
    let leaked: &'static str = Box::leak(spelled.into_boxed_str());
    seen.push(leaked);
    Ok(leaked)
}

#[derive(Clone, Debug, PartialEq)]
pub struct Learned {
    pub spec: Spec,
    /// Coefficients, output-major: `values[c·n_terms + k]` for output c and term k.
    pub values: Vec<f64>,
    outputs: Vec<Output>,
    needs: (bool, bool),
}

impl Learned {
    /// A zero effect of definition `text`; an error when it cannot be evaluated on `robot`.
    pub fn zeros(text: &str, robot: &RobotDescription) -> Result<Learned, EffectError> {
        let spec = Spec::parse(text)?;
        if spec.needs().1 && robot.gravity.is_none() {
            return Err(EffectError::NeedsGravity {
                effect: format!("learned:{spec}"),
            });
        }
        let outputs = spec.action.outputs(robot);
        let needs = spec.needs();
        Ok(Learned {
            values: vec![0.0; outputs.len() * spec.n_terms()],
            spec,
            outputs,
            needs,
        })
    }

    pub fn from_record(
        text: &str,
        rec: &EffectRecord,
        robot: &RobotDescription,
    ) -> Result<Learned, RecordError> {
        let mut l = Learned::zeros(text, robot)
            .map_err(|e| RecordError::new("name", SPELLING, e.to_string()))?;
        l.values = rec.named_values(&l.spec.local_names())?;
        Ok(l)
    }

    /// The basis at `state` and the number of terms.
    fn terms(&self, state: &AxisState, ctx: &Context) -> ([f64; MAX_TERMS], usize) {
        let v = DriverValues::at(state, ctx, self.needs.0, self.needs.1);
        let mut out = [0.0; MAX_TERMS];
        self.spec.terms(&v, &mut out);
        (out, self.spec.n_terms())
    }

    /// The slot values at `state` (slot units).
    fn contributions(&self, state: &AxisState, ctx: &Context) -> Vec<(Slot, f64)> {
        let (phi, n) = self.terms(state, ctx);
        let mut out = Vec::with_capacity(self.outputs.len() * 2);
        for (c, output) in self.outputs.iter().enumerate() {
            let w = &self.values[c * n..(c + 1) * n];
            let value: f64 = w.iter().zip(&phi[..n]).map(|(a, b)| a * b).sum();
            out.extend(output.iter().map(|&(slot, per)| (slot, per * value)));
        }
        out
    }
}

impl Effect for Learned {
    fn name(&self) -> String {
        format!("learned:{}", self.spec)
    }
    fn parameters(&self) -> Vec<Parameter> {
        let name = self.name();
        let unit = self.spec.action.unit();
        self.spec
            .local_names()
            .into_iter()
            .map(|n| Parameter {
                name: format!("{name}[{n}]"),
                unit,
            })
            .collect()
    }
    fn values(&self) -> &[f64] {
        &self.values
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }
    fn add_to(&self, state: &AxisState, ctx: &Context, errors: &mut ChainErrors) {
        for (slot, value) in self.contributions(state, ctx) {
            errors.add(slot, value);
        }
    }
    fn jacobian(&self, state: &AxisState, ctx: &Context, out: &mut Vec<Partial>) {
        let (phi, n) = self.terms(state, ctx);
        for (c, output) in self.outputs.iter().enumerate() {
            for (k, f) in phi[..n].iter().enumerate() {
                for &(slot, per) in output {
                    out.push(Partial {
                        param: c * n + k,
                        slot,
                        value: per * f,
                    });
                }
            }
        }
    }
    fn varies_with_axes(&self) -> bool {
        !self
            .spec
            .drivers
            .iter()
            .all(|d| matches!(d, Driver::Time { .. }))
    }
    fn adds_angles_only(&self) -> bool {
        matches!(self.spec.action, Action::Angle(_)) && self.varies_with_axes()
    }
    fn add_angles(&self, state: &AxisState, ctx: &Context, angles: &mut [f64; 6]) {
        for (slot, value) in self.contributions(state, ctx) {
            if let Slot::Angle { axis } = slot {
                angles[axis as usize - 1] += value;
            }
        }
    }
    #[cfg(any(test, feature = "internals"))]
    fn clamped(&self, state: &AxisState) -> bool {
        let h = state.time_s / 3600.0;
        self.spec.drivers.iter().any(|d| match *d {
            Driver::Time { from_h, to_h } => to_h > from_h && (h < from_h || h > to_h),
            _ => false,
        })
    }
    fn direction_axes(&self) -> Vec<u8> {
        self.spec
            .drivers
            .iter()
            .filter_map(|d| match *d {
                Driver::Direction(n) => Some(n),
                _ => None,
            })
            .collect()
    }
    fn parameters_are_cells(&self) -> bool {
        true
    }
}

impl ToRecord for Learned {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&self.spec.local_names(), &self.values)),
            table: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::Payload;
    use crate::model::Direction;

    fn ctx_of<'a>(robot: &'a RobotDescription, payload: &'a Payload) -> Context<'a> {
        Context { robot, payload }
    }

    #[test]
    fn spellings_parse_to_one_canonical_form() {
        let s = Spec::parse(" Rotation@a1( REACH * a1 ) ").unwrap();
        assert_eq!(s.to_string(), "rotation@A1(reach*A1)");
        assert_eq!(
            Spec::parse("angle@A4(dir:a4*A5)").unwrap().to_string(),
            "angle@A4(dir:A4*A5)"
        );
        assert_eq!(
            Spec::parse("offset@A3(time[0:2.5h])").unwrap().to_string(),
            "offset@A3(time[0:2.5h])"
        );
        assert_eq!(
            Spec::parse("offset@tool(gravity)").unwrap().to_string(),
            "offset@tool(gravity)"
        );
        for bad in [
            "angle@A7(A1)",
            "turn@A1(A1)",
            "angle@A1",
            "angle@A1()",
            "angle@A1(A1*A1)",
            "angle@A1(A1*A2*A3)",
            "angle@A1(time[2:1h])",
            "angle@A1(torque:A9)",
            "offset@flange(A1)",
        ] {
            assert!(Spec::parse(bad).is_err(), "{bad} accepted");
        }
        assert_eq!(
            canonical("rotation@a1(reach*a1)").unwrap(),
            canonical("rotation@A1(reach*A1)").unwrap()
        );
    }

    #[test]
    fn terms_and_names_of_a_product() {
        // A5 (4 main, 2 first-order) with dir:A4 (1, 1): 4 + 1 + 2·1 = 7 terms.
        let s = Spec::parse("angle@A4(A5*dir:A4)").unwrap();
        assert_eq!(s.n_terms(), 7);
        assert_eq!(
            s.term_names(),
            [
                "A5.cos1",
                "A5.sin1",
                "A5.cos2",
                "A5.sin2",
                "dir:A4",
                "A5.cos1*dir:A4",
                "A5.sin1*dir:A4"
            ]
        );
        let mut v = DriverValues {
            angles_deg: [0.0, 0.0, 0.0, 0.0, 30.0, 0.0],
            ..DriverValues::default()
        };
        v.reversal[3] = -1.0;
        let mut out = [0.0; MAX_TERMS];
        s.terms(&v, &mut out);
        let (c, sn) = (30f64.to_radians().cos(), 0.5);
        let expected = [c, sn, 0.5, 60f64.to_radians().sin(), -1.0, -c, -sn];
        for (a, b) in out[..7].iter().zip(expected) {
            assert!((a - b).abs() < 1e-12, "{out:?}");
        }
        // Three slots × 7 terms for a rotation.
        let r = Spec::parse("rotation@A2(A5*dir:A4)").unwrap();
        assert_eq!(r.local_names().len(), 21);
        assert_eq!(r.local_names()[7], "y.A5.cos1");
    }

    #[test]
    fn drivers_by_hand_at_home() {
        // HOME: flange at (1340, 0, 1810) mm, flange Z (= A6 x) pointing +X, flange X down:
        // the A6 frame equals the base frame, so gravity is (0, 0, −1) in it.
        let robot = RobotDescription::kr30ha();
        let payload = Payload::default();
        let mut state = AxisState::new([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]);
        state.time_s = 5400.0;
        state.history[1] = crate::model::AxisHistory::engaged(Direction::Negative);
        let v = DriverValues::at(&state, &ctx_of(&robot, &payload), true, false);
        assert!((v.reach_mm - 1340.0).abs() < 1e-9 && (v.height_mm - 1810.0).abs() < 1e-9);
        assert!((v.gravity[2] + 1.0).abs() < 1e-12 && v.gravity[0].abs() < 1e-12);
        assert_eq!(v.reversal[1], -1.0);
        assert_eq!(v.time_h, 1.5);
        // Powers of (reach − 1 m)/1 m: 0.34, 0.34², 0.34³.
        let mut out = [0.0; MAX_TERMS];
        Spec::parse("offset@A1(reach)").unwrap().terms(&v, &mut out);
        assert!((out[0] - 0.34).abs() < 1e-12 && (out[2] - 0.34f64.powi(3)).abs() < 1e-12);
        // Time held at the window's edge: 1.5 h in a window 0..1 h is its end, +1.
        Spec::parse("offset@A1(time[0:1h])")
            .unwrap()
            .terms(&v, &mut out);
        assert_eq!(out[0], 1.0);
    }

    #[test]
    fn an_angle_deviation_writes_its_slot_in_radians_and_its_jacobian_matches() {
        let robot = RobotDescription::kr30ha();
        let payload = Payload::default();
        let ctx = ctx_of(&robot, &payload);
        let mut l = Learned::zeros("angle@A2(A3)", &robot).unwrap();
        // 0.01° · cos A3 + 0.02° · sin 2A3 at A3 = 30°.
        l.values = vec![0.01, 0.0, 0.0, 0.02];
        let state = AxisState::new([0.0, -60.0, 30.0, 0.0, 0.0, 0.0]);
        let mut e = ChainErrors::default();
        l.add_to(&state, &ctx, &mut e);
        let expected =
            (0.01 * 30f64.to_radians().cos() + 0.02 * 60f64.to_radians().sin()).to_radians();
        assert!((e.get(Slot::Angle { axis: 2 }) - expected).abs() < 1e-15);
        let mut partials = Vec::new();
        l.jacobian(&state, &ctx, &mut partials);
        let by_jacobian: f64 = partials.iter().map(|p| p.value * l.values[p.param]).sum();
        assert!((by_jacobian - expected).abs() < 1e-15);
        let mut angles = [0.0; 6];
        l.add_angles(&state, &ctx, &mut angles);
        assert!((angles[1] - expected).abs() < 1e-15);
    }

    #[test]
    fn the_arm_rotation_turns_about_the_base_origin() {
        // 0.01° about the arm frame's y axis at A1 = 30°: every point of the arm moves as if
        // turned about the horizontal axis through the base origin across the arm,
        // d = ω × p with ω = 0.01° · (sin 30°, cos 30°, 0) in the base frame (A1 turns about −Z).
        let robot = RobotDescription::kr30ha();
        let payload = Payload::default();
        let ctx = ctx_of(&robot, &payload);
        // A driver that is 1 at this state: dir:A1 after a positive move.
        let mut l = Learned::zeros("rotation@arm(dir:A1)", &robot).unwrap();
        l.values = vec![0.0, 0.01, 0.0];
        let mut state = AxisState::new([30.0, -60.0, 100.0, 20.0, 40.0, -50.0]);
        state.history[0] = crate::model::AxisHistory::engaged(Direction::Positive);
        let mut e = ChainErrors::default();
        l.add_to(&state, &ctx, &mut e);
        let moved = ChainFrames::new(&robot, &state.axes_deg, &e).flange_position();
        let p =
            ChainFrames::new(&robot, &state.axes_deg, &ChainErrors::default()).flange_position();
        let a = 30f64.to_radians();
        let omega = Vector3::new(a.sin(), a.cos(), 0.0) * 0.01f64.to_radians();
        let expected = p + omega.cross(&p);
        assert!((moved - expected).norm() < 1e-4, "{moved} vs {expected}");
    }

    #[test]
    fn record_round_trip_and_unknown_parameter() {
        let robot = RobotDescription::kr30ha();
        let mut l = Learned::zeros("offset@tool(gravity)", &robot).unwrap();
        l.values[4] = 0.05; // y.gy
        let rec = l.record();
        assert_eq!(rec.name, "learned:offset@tool(gravity)");
        assert_eq!(rec.parameters.as_ref().unwrap()["y.gy"], 0.05);
        let back = Learned::from_record("offset@tool(gravity)", &rec, &robot).unwrap();
        assert_eq!(back, l);
        let mut bad = rec.clone();
        bad.parameters.as_mut().unwrap().insert("w.gx".into(), 1.0);
        assert!(Learned::from_record("offset@tool(gravity)", &bad, &robot).is_err());
        let mut no_mass = robot;
        no_mass.gravity = None;
        assert!(Learned::zeros("angle@A2(torque:A2)", &no_mass).is_err());
    }
}
