//! Compensation of a sequence of targets, with each axis's gear play where the compensated
//! motion leaves it.
//!
//! Where an axis's gear play stands depends on the commands before, so the work runs in three
//! passes: (1) the nominal directions from the simulated nominal motion (sequential, cheap); (2)
//! every target solved with the gear of every axis engaged on the flank of its nominal direction,
//! in parallel (rayon) — after any motion longer than the play, that is where it is; (3) a
//! sequential re-check that walks the *compensated* commands through each axis's history
//! ([`AxisHistory`](crate::model::AxisHistory): the command before, the turning points of the
//! interpolated motion moved by the correction) and evaluates the play exactly. Where it disagrees
//! with the flank assumed, the target is solved again from the *output* the pose needs: the output
//! must move up (the command drives the lower flank, `c = o + b/2`), move down (`c = o − b/2`), or
//! — for an axis the program holds, when the output need not move — stay put, and then the command
//! is kept exactly where it was (inside the play, any command there gives the same output; a held
//! command does not jitter). A lagging play always has such a solution and it is found in one step,
//! so nothing oscillates. A target whose output must move back by less than the play makes the
//! command travel the play; such targets are counted and reported.
//!
//! The files of this folder, one job each: [`passes`] (passes 1 and 2, and where they run),
//! [`solving`] (one target solved within its limits, keeping its configuration and turn),
//! [`timeline`] (where the outcomes and the re-check's states are held), [`recheck`] (pass 3's
//! walk), [`stretches`] (that walk cut in stretches on the pool), [`settle`] (one target of the
//! walk settled), [`turns`] (the turning points of a compensated motion), [`play`] (a play
//! inverted: the command that puts its output where the pose needs it) and [`widths`] (the
//! play widths the walk asks, kept at hand).

use super::solve::{Method, SolveError};
use crate::kinematics::{AxisAngles, Pose};
use crate::model::{AxisState, Direction, Model};
use crate::motion::frame::Frame;
use crate::motion::interpolate;
use nalgebra::{Vector3, Vector6};

mod passes;
mod play;
mod recheck;
mod settle;
mod solving;
mod stretches;
mod timeline;
mod turns;
mod widths;

pub use passes::{first_passes, Chains, FirstPasses};
pub use recheck::settle;
pub use stretches::Stretching;
#[cfg(any(test, feature = "internals"))]
pub use {passes::nominal_directions, settle::HOLD_DEG};

pub use crate::motion::interpolate::REST_DEG;

/// Status bits a target must keep after compensation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Keep {
    /// The configuration S (Cartesian targets: the controller's IK chooses the branch by it;
    /// axis targets: a later Cartesian motion without S takes it from them).
    pub s: bool,
    /// The turn T (PTP Cartesian targets with an explicit T: the controller picks ±360° by it).
    pub t: bool,
}

/// One target of the simulated program.
#[derive(Clone, Copy, Debug)]
pub struct Target {
    /// The programmed TCP pose in the robot base frame.
    pub goal: Frame,
    /// Index of the tool (flange → TCP) in the tool table passed alongside.
    pub tool: u32,
    /// The nominal command axes (what the controller computes for the programmed target).
    pub nominal_axes: AxisAngles,
    /// Nominal motion of each axis on arrival, deg per segment (the step for PTP, the arrival
    /// velocity `dq/du` at the end for LIN/CIRC; 0 when the axis rests); `None` when the
    /// motion comes from an unknown place (first motion, unresolved target before).
    pub arrival: Option<[f64; 6]>,
    /// Each axis's last turning point inside the motion reaching it, nominal (see
    /// `motion::interpolate::Arrival::turns`).
    pub turns: interpolate::Turns,
    /// How the controller interpolates the motion reaching it.
    pub interp: Interp,
    /// For a Cartesian target whose numbers are written, the base they are written in (index
    /// into the frame table): the rewrite writes the command's TCP there.
    pub written_base: Option<u32>,
    /// Whether to compensate (false: the target still moves the robot, its command stays).
    pub compensate: bool,
    pub keep: Keep,
}

/// How the controller interpolates the motion reaching a target (from the previous one).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Interp {
    /// PTP: linear in axis space.
    #[default]
    Joint,
    /// LIN, SLIN: straight line, orientation slerp.
    Line,
    /// An `SPL` segment of a spline block: it ends along the tangent of the spline through
    /// the targets before and after it (`motion::spline`; `first`: its start begins the
    /// chain of points, `last`: its end closes it), orientation slerp.
    Curve { first: bool, last: bool },
    /// The auxiliary point of a CIRC (the arc continues to the next target).
    CircAux,
    /// The end of a CIRC (its auxiliary point is the previous target).
    CircEnd,
    /// The end of a circle with `CA` written by construction (`rewrite`): the controller
    /// follows the circle through the start, the auxiliary point and the written target,
    /// turning by `CA` — by construction the arc of `CA` from the start to the end
    /// ([`interpolate::circle_by_angle`] in the plane the rewrite chose).
    CircAngle(ArcAngle),
    /// The auxiliary point of such a circle: it only sets the plane of the written circle
    /// (its written position is on that circle, not its own command), so its directions are
    /// the nominal ones, not re-checked.
    CircAngleAux,
}

/// The `CA` of a circle written by construction and its plane (`motion::CircularAngle`):
/// held as bits (the angle's f64, the nominal normal's f32, ample for directions) so that
/// [`Interp`] stays `Eq` and small.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ArcAngle {
    bits: u64,
    negative: bool,
    from_points: bool,
    normal: [u32; 3],
}

impl ArcAngle {
    pub fn new(arc: &crate::motion::CircularAngle) -> ArcAngle {
        ArcAngle {
            bits: arc.angle_deg.to_bits(),
            negative: arc.sense < 0.0,
            from_points: arc.from_points,
            normal: std::array::from_fn(|i| (arc.normal[i] as f32).to_bits()),
        }
    }

    pub fn degrees(self) -> f64 {
        f64::from_bits(self.bits)
    }

    /// The plane of the circle written with auxiliary point `aux` (as the rewrite chooses it).
    pub fn plane(self, aux: Vector3<f64>) -> interpolate::ArcPlane {
        if self.from_points {
            interpolate::ArcPlane::Points {
                aux,
                sense: if self.negative { -1.0 } else { 1.0 },
            }
        } else {
            interpolate::ArcPlane::Near(self.normal.map(|b| f32::from_bits(b) as f64).into())
        }
    }
}

/// How a target's gear plays were settled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Resolution {
    /// The flanks the nominal motion engages are those of the compensated motion.
    #[default]
    Consistent,
    /// Some axis's output moves otherwise than the nominal motion's: solved on the flank the
    /// compensated motion engages.
    Reflanked,
    /// Axes the program holds and whose output need not move: their command kept exactly.
    Held([bool; 6]),
}

impl From<SolveError> for TargetError {
    fn from(e: SolveError) -> TargetError {
        TargetError::NotConverged {
            position_um: e.position_um,
            rotation_urad: e.rotation_urad,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum TargetError {
    #[error("the compensation did not converge (left {position_um:.3} µm, {rotation_urad:.3} µrad; near-singular pose?)")]
    NotConverged {
        position_um: f64,
        rotation_urad: f64,
    },
    #[error("the compensated A{axis} = {value:.4}° leaves its limits [{lo}, {hi}]")]
    OutOfLimits {
        axis: u8,
        value: f64,
        lo: f64,
        hi: f64,
    },
    #[error("compensation changes the configuration: S {s_from} T {t_from} → S {s_to} T {t_to}")]
    Configuration {
        s_from: u8,
        t_from: u8,
        s_to: u8,
        t_to: u8,
    },
}

/// The result for one target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// The command axes (compensated, or nominal when not compensated or rejected).
    pub axes_deg: AxisAngles,
    /// The flank each axis's gear is engaged on at arrival with the command (the direction
    /// of the commanded motion; `Unknown` before the axis first moves or, for an axis held
    /// inside its play, the direction it last moved in).
    pub directions: [Direction; 6],
    /// Directions of the nominal motion on arrival.
    pub nominal_directions: [Direction; 6],
    /// Predicted TCP error of the uncompensated command `[mm; rad]`.
    pub before: Vector6<f64>,
    /// Predicted TCP error at the command.
    pub residual: Vector6<f64>,
    pub iterations: u32,
    pub resolution: Resolution,
    pub error: Option<TargetError>,
    /// Whether the command differs from the nominal one.
    pub changed: bool,
    /// Axes held at 0° to keep the program's turn T.
    pub turn_held: [bool; 6],
    /// Axes whose output moves back by less than their play: the command travels the play
    /// (lost motion) before the output follows.
    pub travels_play: [bool; 6],
}

impl Outcome {
    /// A slot's value before its outcome is written.
    fn placeholder() -> Outcome {
        Outcome::unsolved([0.0; 6], [Direction::Unknown; 6])
    }

    /// A target commanded at `axes`, arriving with `directions` (commanded and nominal),
    /// before anything is solved or predicted.
    fn unsolved(axes: [f64; 6], directions: [Direction; 6]) -> Outcome {
        Outcome {
            axes_deg: axes.into(),
            directions,
            nominal_directions: directions,
            before: Vector6::zeros(),
            residual: Vector6::zeros(),
            iterations: 0,
            resolution: Resolution::Consistent,
            error: None,
            changed: false,
            turn_held: [false; 6],
            travels_play: [false; 6],
        }
    }

    /// Axes whose compensated motion arrives in the opposite direction to the nominal one
    /// (a direction becoming known where the nominal axis rests is not a flip).
    pub fn flipped(&self) -> [bool; 6] {
        use Direction::{Negative, Positive};
        std::array::from_fn(|i| {
            matches!(
                (self.directions[i], self.nominal_directions[i]),
                (Positive, Negative) | (Negative, Positive)
            )
        })
    }
}

#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    pub method: Method,
    /// Solve the targets on rayon's pool (else on the calling thread).
    pub parallel: bool,
    /// How the re-check cuts a long sequence to walk it on the pool.
    pub stretching: Stretching,
}

/// A target compensated before a cut (see [`compensate_after`]).
#[derive(Clone, Copy, Debug)]
pub struct Carried {
    pub target: Target,
    pub outcome: Outcome,
    /// Whether the re-check re-solved it.
    pub resolved: bool,
    pub command: Command,
    /// The compensated command on arrival and each axis's history there.
    pub state: AxisState,
}

/// A target's command as the nominal robot places it.
#[derive(Clone, Copy, Debug)]
pub struct Command {
    /// The nominal TCP of the command axes, robot base frame, unrounded: what the rewrite
    /// turns into the new numbers.
    pub tcp: Frame,
    /// Its change against the TCP of the nominal command ([`correction`]); zero when the
    /// command is the nominal one.
    pub correction: (f64, f64),
    /// `tcp` in the target's base frame as [`Frame::to_kuka_unchosen`] gives it, for a
    /// Cartesian target the re-check did not re-solve: the rewrite chooses its Euler triple
    /// from this instead of converting the matrix again.
    pub unchosen: Option<Pose>,
}

/// The command change at the TCP, µm and mdeg: the nominal TCP of the new command against
/// that of the controller's axes for the programmed target.
pub fn correction(command_tcp: &Frame, nominal_tcp: &Frame) -> (f64, f64) {
    let (cp, cr) =
        crate::motion::frame::norms(&crate::motion::frame::error(command_tcp, nominal_tcp));
    (cp * 1e3, cr.to_degrees() * 1e3)
}

/// What the re-check changed, counted over the targets of a segment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Targets solved again because the compensated motion engages another flank.
    pub reflanked: usize,
    /// Targets with an axis held still (its command kept exactly).
    pub held: usize,
    /// Targets whose output moves back by less than the play on some axis.
    pub travels_play: usize,
}

impl std::ops::AddAssign for Counts {
    fn add_assign(&mut self, other: Counts) {
        self.reflanked += other.reflanked;
        self.held += other.held;
        self.travels_play += other.travels_play;
    }
}

/// What [`compensate_after`] gives: the outcomes of the history and of the targets, and for
/// the targets what the rewrite and the next segment need.
#[derive(Debug, Default)]
pub struct Compensated {
    /// Unused slots, the history's outcomes (as carried), then those of the targets: callers
    /// take the slice they need without copying the rest.
    pub outcomes: Vec<Outcome>,
    /// Where the targets' outcomes begin (the history's are the ones just before).
    pub history: usize,
    /// Per target, whether the re-check re-solved it.
    pub resolved: Vec<bool>,
    /// Per target, its command's TCP (computed once, by the first passes) and change.
    pub commands: Vec<Command>,
    /// The compensated states of the last (up to [`LOOK_BACK`]) targets, oldest first.
    pub last_states: Vec<AxisState>,
    pub counts: Counts,
}

impl Compensated {
    /// The outcomes of the targets.
    pub fn targets(&self) -> &[Outcome] {
        &self.outcomes[self.history..]
    }
}

/// Compensates `targets` (tools indexed by `Target::tool`), the gear of every axis engaged on
/// the flank of `start` before the first target.
pub fn compensate(
    model: &Model,
    tools: &[Frame],
    targets: &[Target],
    start: [Direction; 6],
    options: &Options,
) -> Vec<Outcome> {
    compensate_counted(model, tools, targets, start, options).0
}

/// [`compensate`] with what the re-check changed.
pub fn compensate_counted(
    model: &Model,
    tools: &[Frame],
    targets: &[Target],
    start: [Direction; 6],
    options: &Options,
) -> (Vec<Outcome>, Counts) {
    let mut done = compensate_after(model, tools, &[], targets, start, options);
    done.outcomes.drain(..done.history);
    (done.outcomes, done.counts)
}

/// How far back a segment's targets need the targets before them: the stops the walk carries
/// across a cut (a circle's end looks back to its start), of which the re-check needs the
/// last's state.
pub const LOOK_BACK: usize = crate::motion::form::CARRIED_STOPS;

/// [`compensate`] of a sequence cut in segments: `history` holds the last (up to
/// [`LOOK_BACK`]) targets before `targets`, already compensated; `start` counts only when
/// there is none. Gives the outcomes of `targets` exactly as compensating the whole sequence
/// at once would, whether each was re-solved and its command's TCP (the history of the next
/// segment).
pub fn compensate_after(
    model: &Model,
    tools: &[Frame],
    history: &[Carried],
    targets: &[Target],
    start: [Direction; 6],
    options: &Options,
) -> Compensated {
    let nominal_start = match history.last() {
        Some(c) => c.outcome.nominal_directions,
        None => start,
    };
    let first = first_passes(
        model,
        tools,
        targets,
        nominal_start,
        &mut Chains::default(),
        options,
    );
    settle(model, tools, history, targets, first, options)
}

/// What the passes need besides the outcomes: the targets are the history's followed by the
/// segment's (indexed as the outcomes are).
struct Ctx<'a> {
    model: &'a Model,
    tools: &'a [Frame],
    history: &'a [Carried],
    targets: &'a [Target],
    method: Method,
}

impl<'a> Ctx<'a> {
    fn new(
        model: &'a Model,
        tools: &'a [Frame],
        history: &'a [Carried],
        targets: &'a [Target],
        method: Method,
    ) -> Ctx<'a> {
        Ctx {
            model,
            tools,
            history,
            targets,
            method,
        }
    }

    /// Target `k` of the history and segment together. (`#[inline]` here and on the small
    /// helpers the files of this folder ask of each other per target: each file may be its own
    /// codegen unit.)
    #[inline]
    fn target(&self, k: usize) -> &Target {
        match self.history.get(k) {
            Some(c) => &c.target,
            None => &self.targets[k - self.history.len()],
        }
    }

    #[inline]
    fn len(&self) -> usize {
        self.history.len() + self.targets.len()
    }

    #[inline]
    fn tool(&self, k: usize) -> &Frame {
        &self.tools[self.target(k).tool as usize]
    }

    /// For a Cartesian target whose numbers are written, `tcp` in its base frame before the
    /// choice of Euler triple ([`Frame::to_kuka_unchosen`]): the rewrite writes it near the
    /// original numbers.
    fn unchosen(&self, k: usize, tcp: &Frame) -> Option<Pose> {
        let base = &self.tools[self.target(k).written_base? as usize];
        base.inverse().compose(tcp).to_kuka_unchosen()
    }
}
