//! Compensation of a sequence of targets, with each axis's gear play where the compensated
//! motion leaves it.
//!
//! Where an axis's gear play stands depends on the commands before, so the work runs in
//! three passes: (1) the nominal directions from the simulated nominal motion (sequential,
//! cheap); (2) every target solved with the gear of every axis engaged on the flank of its
//! nominal direction, in parallel (rayon) — after any motion longer than the play, that is
//! where it is; (3) a sequential re-check that walks the *compensated* commands through each
//! axis's [`AxisHistory`] (the command before, the turning points of the interpolated motion
//! moved by the correction) and evaluates the play exactly. Where it disagrees with the flank
//! assumed, the target is solved again from the *output* the pose needs: the output must
//! move up (the command drives the lower flank, `c = o + b/2`), move down (`c = o − b/2`),
//! or — for an axis the program holds, when the output need not move — stay put, and then the
//! command is kept exactly where it was (inside the play, any command there gives the same
//! output; a held command does not jitter). A lagging play always has such a solution and it
//! is found in one step, so nothing oscillates. A target whose output must move back by less
//! than the play makes the command travel the play; such targets are counted and reported.

use super::solve::{self, Method, Problem, SolveError};
use crate::kinematics::{status_turn, AxisAngles, Pose, RobotDescription};
use crate::model::table::Table1;
use crate::model::history::PlayBefore;
use crate::model::{AxisHistory, AxisState, Direction, Model};
use crate::motion::frame::Frame;
use crate::motion::interpolate;
use crate::motion::nominal::{status_turns, Arm, Nominal};
use nalgebra::{Vector3, Vector6};
use std::cell::{Cell, RefCell};
use std::mem::MaybeUninit;

mod stretches;
pub use stretches::Stretching;

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

/// Targets per chunk of the parallel pass that places the first-pass commands.
const PLACE_CHUNK: usize = 1024;

/// The signs of an arrival motion ([`signs`]); `None` when it comes from an unknown place.
type Signs = Option<[i8; 6]>;

/// What the direction logic uses of an arrival motion: per axis −1, +1, or 0 at rest.
fn signs(v: Option<[f64; 6]>) -> Signs {
    v.map(|v| {
        v.map(|x| {
            if x.abs() < REST_DEG {
                0
            } else if x > 0.0 {
                1
            } else {
                -1
            }
        })
    })
}

/// The direction state after arriving with motion of `v`'s signs from state `before`.
fn arrive_signs(before: &[Direction; 6], v: Signs) -> [Direction; 6] {
    match v {
        None => [Direction::Unknown; 6],
        Some(v) => std::array::from_fn(|i| match v[i] {
            0 => before[i],
            x => Direction::from_sign(x as i32),
        }),
    }
}

/// Directions of the nominal motion at every target, from the directions before the first.
#[cfg(any(test, feature = "internals"))]
pub fn nominal_directions(targets: &[Target], start: [Direction; 6]) -> Vec<[Direction; 6]> {
    let signs: Vec<Signs> = targets.iter().map(|t| signs(t.arrival)).collect();
    directions_after(&signs, start)
}

/// The direction states after arriving with motions of `signs` one after another.
fn directions_after(signs: &[Signs], start: [Direction; 6]) -> Vec<[Direction; 6]> {
    let mut state = start;
    signs
        .iter()
        .map(|&v| {
            state = arrive_signs(&state, v);
            state
        })
        .collect()
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

/// Passes 1 and 2 of a segment: what needs nothing of the targets before it but the nominal
/// directions they leave (`nominal_start`), so it may run while the segment before is still
/// being settled ([`settle`]).
pub struct FirstPasses {
    /// The targets' outcomes, with room in front for the history's.
    outcomes: Timeline,
    nominal_signs: Vec<Signs>,
    /// The unrounded TCP of every first-pass command, and its pose in the base frame before
    /// the choice of Euler triple (see [`Command::unchosen`]); [`settle`] completes them in
    /// place.
    commands: Vec<Command>,
}

impl FirstPasses {
    /// The nominal directions after the segment (the next segment's `nominal_start`).
    pub fn nominal_end(&self) -> Option<[Direction; 6]> {
        self.outcomes.targets().last().map(|o| o.nominal_directions)
    }
}

/// A segment's outcomes with [`LOOK_BACK`] slots in front of the targets' for the history's:
/// the re-check reads the history and the targets as one slice, and the targets' outcomes
/// (200-byte records, a million in a CAM program) are written once, in place, by the first
/// passes, never copied behind the history's, nor filled with a placeholder first.
struct Timeline {
    slots: Vec<Outcome>,
    /// Where the history's outcomes begin (`LOOK_BACK` until [`Self::behind`] puts them in).
    first: usize,
}

impl Timeline {
    /// The outcomes of `n` targets, which `solve` writes, every one of them, into the slots it
    /// is given (its panic leaves them unread).
    fn solved(n: usize, solve: impl FnOnce(&mut [MaybeUninit<Outcome>])) -> Timeline {
        let mut slots = Vec::with_capacity(LOOK_BACK + n);
        slots.resize(LOOK_BACK, Outcome::placeholder());
        solve(&mut slots.spare_capacity_mut()[..n]);
        // SAFETY: the capacity is LOOK_BACK + n, and `solve` wrote the n slots after the first
        // LOOK_BACK (`solve_chains` visits every slot, and `first_pass` writes its slot before
        // anything else). Filled with a placeholder first instead, every slot cost a 200-byte
        // copy, a percent of a CAM program's CPU time (measured in the commit making this).
        unsafe { slots.set_len(LOOK_BACK + n) };
        Timeline {
            slots,
            first: LOOK_BACK,
        }
    }

    fn targets(&self) -> &[Outcome] {
        &self.slots[LOOK_BACK..]
    }

    /// Puts the outcomes of `history` (at most [`LOOK_BACK`]) just before the targets': the
    /// slice returned is the history's followed by the targets'.
    fn behind(&mut self, history: &[Carried]) -> &mut [Outcome] {
        self.first = LOOK_BACK - history.len();
        for (slot, c) in self.slots[self.first..LOOK_BACK].iter_mut().zip(history) {
            *slot = c.outcome;
        }
        &mut self.slots[self.first..]
    }
}

/// Where a pass runs its independent pieces: on rayon's pool or in order on the calling
/// thread ([`Options::parallel`]), chosen once per pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Executor {
    Pool,
    Inline,
}

impl Executor {
    fn of(options: &Options) -> Executor {
        if options.parallel {
            Executor::Pool
        } else {
            Executor::Inline
        }
    }

    /// Runs `a` and `b`, beside each other on the pool.
    fn join<A: Send, B: Send>(
        self,
        a: impl FnOnce() -> A + Send,
        b: impl FnOnce() -> B + Send,
    ) -> (A, B) {
        match self {
            Executor::Pool => rayon::join(a, b),
            Executor::Inline => (a(), b()),
        }
    }

    /// `work` of every chunk of `items` (with the chunk's index), in order.
    fn map_chunks<T: Send, R: Send>(
        self,
        items: &mut [T],
        chunk: usize,
        work: impl Fn(usize, &mut [T]) -> R + Sync + Send,
    ) -> Vec<R> {
        use rayon::prelude::*;
        match self {
            Executor::Pool => items
                .par_chunks_mut(chunk)
                .enumerate()
                .map(|(c, a)| work(c, a))
                .collect(),
            Executor::Inline => items
                .chunks_mut(chunk)
                .enumerate()
                .map(|(c, a)| work(c, a))
                .collect(),
        }
    }
}

/// Targets in a chain of warm starts ([`solve::Chain`]); each chain's first is solved afresh.
/// Chains are cut at every multiple of this in execution order: fixed places, so that a
/// program compensated whole or window by window solves every target alike, and chains of
/// a window are worked in parallel.
const CHAIN: usize = 256;

/// Where a segment's targets stand among the chains: how many targets came before them in
/// execution order, and the chain the first of them continues.
#[derive(Clone, Copy, Debug, Default)]
pub struct Chains {
    ordinal: u64,
    open: solve::Chain,
}

/// Passes 1 and 2 of `targets`, the nominal directions before the first given, `chains`
/// where the targets before them left the warm starts (moved on past them).
pub fn first_passes(
    model: &Model,
    tools: &[Frame],
    targets: &[Target],
    nominal_start: [Direction; 6],
    chains: &mut Chains,
    options: &Options,
) -> FirstPasses {
    let run = Executor::of(options);
    // Pass 1: the nominal motions' signs (the re-check needs them again), their directions.
    let nominal_signs: Vec<Signs> = targets.iter().map(|t| signs(t.arrival)).collect();
    let nominal = directions_after(&nominal_signs, nominal_start);
    // Pass 2: every target solved with the plays engaged on the nominal flanks.
    let ctx = Ctx::new(model, tools, &[], targets, options.method);
    let outcomes = Timeline::solved(targets.len(), |slots| {
        solve_chains(&ctx, &nominal, chains, run, slots)
    });
    let commands = place_commands(&ctx, outcomes.targets(), run);
    FirstPasses {
        outcomes,
        nominal_signs,
        commands,
    }
}

/// Solves `targets` (outcomes into `slots`, every one written) in their chains of warm
/// starts, each worked in order, the first continuing the open one of `chains`, which then
/// moves on past them.
fn solve_chains(
    ctx: &Ctx,
    nominal: &[[Direction; 6]],
    chains: &mut Chains,
    run: Executor,
    slots: &mut [MaybeUninit<Outcome>],
) {
    let n = slots.len();
    let head = ((CHAIN - (chains.ordinal % CHAIN as u64) as usize) % CHAIN).min(n);
    let (head_slots, rest) = slots.split_at_mut(head);
    type Slots<'s> = &'s mut [MaybeUninit<Outcome>];
    let work = |from: usize, slots: Slots, chain: solve::Chain| -> solve::Chain {
        let mut along = solve::Along::new(ctx.model, chain);
        for (k, slot) in slots.iter_mut().enumerate() {
            let i = from + k;
            let engaged = nominal[i].map(AxisHistory::engaged);
            let target = &ctx.targets[i];
            let chain = Some(&mut along);
            first_pass(
                ctx.model, ctx.tools, target, &engaged, ctx.method, chain, slot,
            );
        }
        along.chain
    };
    // The chain continued from the segment before runs beside the fresh ones.
    let continued = chains.open;
    let (open, ends) = run.join(
        || work(0, head_slots, continued),
        || {
            run.map_chunks(rest, CHAIN, |p, slots| {
                work(head + p * CHAIN, slots, solve::Chain::default())
            })
        },
    );
    chains.open = ends.last().copied().unwrap_or(open);
    chains.ordinal += n as u64;
}

/// Where the nominal robot places every first-pass command (the rewrite's numbers): its TCP,
/// and for a Cartesian target its pose before the choice of Euler triple.
fn place_commands(ctx: &Ctx, solved: &[Outcome], run: Executor) -> Vec<Command> {
    let blank = Command {
        tcp: Frame::identity(),
        correction: (0.0, 0.0),
        unchosen: None,
    };
    let mut commands: Vec<Command> = vec![blank; solved.len()];
    let arm = Nominal(&ctx.model.robot);
    run.map_chunks(&mut commands, PLACE_CHUNK, |c, placings| {
        for (j, placing) in placings.iter_mut().enumerate() {
            let k = c * PLACE_CHUNK + j;
            let axes = &solved[k].axes_deg;
            placing.tcp = arm.tcp(axes, ctx.tool(k));
            placing.unchosen = ctx.unchosen(k, &placing.tcp);
        }
    });
    commands
}

/// Pass 3 of `targets` after the carried `history` (see [`compensate_after`]), from their
/// [`first_passes`], and the commands' TCPs.
pub fn settle(
    model: &Model,
    tools: &[Frame],
    history: &[Carried],
    targets: &[Target],
    first: FirstPasses,
    options: &Options,
) -> Compensated {
    // The re-check looks back `LOOK_BACK` targets: older history is not needed.
    let history = &history[history.len().saturating_sub(LOOK_BACK)..];
    let h = history.len();
    let FirstPasses {
        mut outcomes,
        nominal_signs,
        mut commands,
    } = first;
    let all = outcomes.behind(history);
    let ctx = Recheck::new(Ctx::new(model, tools, history, targets, options.method));
    let mut resolved: Vec<bool> = history.iter().map(|c| c.resolved).collect();
    resolved.resize(h + targets.len(), false);
    // Without a target before, the first arrives after long motions in its nominal
    // directions (those `start` leads to), as the first pass assumed.
    let previous = history.last().map(|c| c.state);
    let (counts, states) = recheck(&ctx, previous, h, all, &nominal_signs, &mut resolved, options);
    complete_commands(&ctx, &all[h..], &resolved[h..], &mut commands);
    resolved.drain(..h);
    Compensated {
        history: outcomes.first + h,
        outcomes: outcomes.slots,
        resolved,
        commands,
        last_states: states,
        counts,
    }
}

/// The commands' changes at the TCP, and the TCP of a command the re-check solved again.
/// The nominal command's TCP is the goal: the walk solved the command for it (an axis
/// target's goal is its nominal TCP).
fn complete_commands(ctx: &Ctx, outcomes: &[Outcome], resolved: &[bool], commands: &mut [Command]) {
    let h = ctx.history.len();
    let arm = Nominal(&ctx.model.robot);
    for (i, c) in commands.iter_mut().enumerate() {
        let o = &outcomes[i];
        if resolved[i] {
            c.tcp = arm.tcp(&o.axes_deg, ctx.tool(h + i));
            c.unchosen = None;
        }
        if o.changed {
            c.correction = correction(&c.tcp, &ctx.targets[i].goal);
        }
    }
}

fn tcp_error(
    model: &Model,
    tool: &Frame,
    axes: &[f64; 6],
    histories: &[AxisHistory; 6],
    goal: &Frame,
) -> Vector6<f64> {
    solve::predicted_error(model, histories, axes, tool, goal)
}

/// Solves one target with given directions and holds, checking limits and configuration.
/// An axis that the correction moves across 0° where the program's turn T fixes its sign
/// (typically A4 or A6 at exactly 0°) is held at 0° on its side — the rest of the pose
/// solved in the least-squares sense — rather than rejecting the target. Returns the axes
/// held so.
/// The first solve is warm-started along `chain` where one is given (see [`solve::Chain`]).
#[allow(clippy::too_many_arguments)]
fn solve_target(
    model: &Model,
    tool: &Frame,
    target: &Target,
    histories: &[AxisHistory; 6],
    start: [f64; 6],
    hold: [bool; 6],
    method: Method,
    chain: Option<&mut solve::Along>,
) -> Result<(solve::Solution, [bool; 6]), TargetError> {
    // Equation (3) is taken at the programmed (nominal) command, whatever the start.
    let start = if method == Method::OneStep && !hold.iter().any(|&h| h) {
        *target.nominal_axes
    } else {
        start
    };
    let problem = Problem {
        goal: target.goal,
        tool,
        start: start.into(),
        histories,
        hold,
    };
    let robot = &model.robot;
    // Near a singularity the goal may be out of reach in one direction: take the least-squares
    // command there (reported by its residual) rather than rejecting the target.
    // (Checked only on failure: the check costs as much as a chain evaluation.)
    let near_singular = || crate::kinematics::singularity(robot, &target.nominal_axes).is_some();
    let solve_or_best = |p: &Problem, m: Method| match solve::solve(model, p, m) {
        Ok(s) => Ok(s),
        Err(e) if near_singular() => Ok(*e.best),
        Err(e) => Err(e),
    };
    let mut sol = match chain {
        Some(chain) if method == Method::Iterate && !hold.contains(&true) => {
            match chain.solve(&problem) {
                Ok(s) => s,
                Err(e) if near_singular() => *e.best,
                Err(e) => return Err(e.into()),
            }
        }
        _ => solve_or_best(&problem, method)?,
    };
    let mut turn_held = [false; 6];
    let ((s0, t0), (mut s1, mut t1)) = status_turns(robot, &target.nominal_axes, &sol.axes_deg);
    // The solution's status and turn, known unless it is solved again.
    let mut solved = Some((s1, t1));
    let mut problem = problem;
    // A5 moved across 0° (the wrist singularity): the configuration S changes with its sign,
    // and a later Cartesian motion without S takes the configuration of this position. Held
    // on its programmed side, as a turn is.
    if target.keep.s && s0 ^ s1 == WRIST_BIT {
        (problem, turn_held) = turn_kept(&problem, WRIST_TURN_BIT, t0);
        sol = solve_or_best(&problem, Method::Iterate)?;
        (s1, t1) = status_turn(robot, &sol.axes_deg);
        solved = Some((s1, t1));
    }
    if target.keep.t && t0 != t1 && s0 == s1 {
        let retry;
        let held;
        (retry, held) = turn_kept(&problem, t0 ^ t1, t0);
        turn_held = std::array::from_fn(|i| turn_held[i] || held[i]);
        sol = solve_or_best(&retry, Method::Iterate)?;
        solved = None;
    }
    within_limits_and_configuration(robot, target, (s0, t0), &sol.axes_deg, solved)?;
    Ok((sol, turn_held))
}

/// `problem` with the axes of `changed` (bits of T) held just inside the side of zero the
/// programmed turn `t0` puts them on, and the axes held so.
fn turn_kept<'p>(problem: &Problem<'p>, changed: u8, t0: u8) -> (Problem<'p>, [bool; 6]) {
    let mut turn_held = [false; 6];
    let mut start = problem.start;
    let mut hold = problem.hold;
    for i in 0..6 {
        if changed >> i & 1 == 1 {
            turn_held[i] = true;
            hold[i] = true;
            // Held just inside its side of zero, by more than the written decimals can
            // move it back: held at zero, the rounded target lands on the other side,
            // where the programmed T has no solution within the limits.
            start[i] = if t0 >> i & 1 == 1 {
                -TURN_MARGIN_DEG
            } else {
                TURN_MARGIN_DEG
            };
        }
    }
    let retry = Problem {
        start,
        hold,
        ..*problem
    };
    (retry, turn_held)
}

/// A solution's axes within the joint limits, and its S and T (`status`, [`status_turn`]'s
/// when not given) those of the programmed target where the target keeps them.
fn within_limits_and_configuration(
    robot: &RobotDescription,
    target: &Target,
    (s0, t0): (u8, u8),
    axes: &[f64; 6],
    status: Option<(u8, u8)>,
) -> Result<(), TargetError> {
    for (n, (a, [lo, hi])) in axes.iter().zip(robot.limits_deg.iter()).enumerate() {
        if a < lo || a > hi {
            return Err(TargetError::OutOfLimits {
                axis: n as u8 + 1,
                value: *a,
                lo: *lo,
                hi: *hi,
            });
        }
    }
    let (s1, t1) = status.unwrap_or_else(|| status_turn(robot, axes));
    let s_bad = target.keep.s && s0 != s1;
    let t_bad = target.keep.t && t0 != t1;
    if s_bad || t_bad {
        return Err(TargetError::Configuration {
            s_from: s0,
            t_from: t0,
            s_to: s1,
            t_to: t1,
        });
    }
    Ok(())
}

/// The status bit S of A5's sign (`kinematics::status_turn`), and A5's bit of the turn T.
const WRIST_BIT: u8 = 1 << 2;
const WRIST_TURN_BIT: u8 = 1 << 4;

/// How far inside its programmed side of zero an axis is held to keep the target's T: ten
/// times what the written decimals (1e-4° of an orientation, 1e-3 mm) move a wrist axis.
const TURN_MARGIN_DEG: f64 = 1e-3;

fn first_pass(
    model: &Model,
    tools: &[Frame],
    target: &Target,
    histories: &[AxisHistory; 6],
    method: Method,
    mut chain: Option<&mut solve::Along>,
    out: &mut MaybeUninit<Outcome>,
) {
    let directions = histories.map(|h| h.simple_direction());
    // Written first, whatever follows (`Timeline::solved` relies on it).
    let out = out.write(Outcome::unsolved(*target.nominal_axes, directions));
    let tool = &tools[target.tool as usize];
    if let Some(c) = chain.as_deref_mut() {
        c.chain.follow_tool(target.tool);
    }
    if !target.compensate {
        if let Some(c) = chain {
            c.chain.forget();
        }
        out.before = tcp_error(model, tool, &target.nominal_axes, histories, &target.goal);
        out.residual = out.before;
        return;
    }
    let solved = solve_target(
        model,
        tool,
        target,
        histories,
        *target.nominal_axes,
        [false; 6],
        method,
        chain.as_deref_mut(),
    );
    if let Some(c) = chain.map(|c| &mut c.chain) {
        match &solved {
            Ok((sol, held)) if !held.contains(&true) => c.record(
                std::array::from_fn(|i| sol.axes_deg[i] - target.nominal_axes[i]),
                sol.initial,
                sol.residual,
            ),
            _ => c.forget(),
        }
    }
    match solved {
        Ok((sol, turn_held)) => {
            out.changed = sol.axes_deg != target.nominal_axes;
            out.axes_deg = sol.axes_deg.into();
            out.residual = sol.residual;
            out.iterations = sol.iterations;
            out.turn_held = turn_held;
            // The error at the nominal command (the start, unless a turn was kept by holding).
            out.before = if turn_held.iter().any(|&h| h) {
                tcp_error(model, tool, &target.nominal_axes, histories, &target.goal)
            } else {
                sol.initial
            };
        }
        Err(e) => {
            out.error = Some(e);
            out.before = tcp_error(model, tool, &target.nominal_axes, histories, &target.goal);
            out.residual = out.before;
        }
    }
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

/// The re-check's [`Ctx`], with each axis's play width table and the cells of it looked up
/// recently (the re-check runs on one thread).
struct Recheck<'a> {
    ctx: Ctx<'a>,
    plays: [Option<WidthTable<'a>>; 6],
    /// Per axis, the play's output before the last point of the history evaluated last.
    before: [RefCell<PlayBefore>; 6],
    /// The turns of the compensated motion worked out last for the target being settled
    /// ([`compensated_turns`]), cleared as each target's settling starts.
    turns: Cell<Option<TurnsKept>>,
}

/// A target's compensated turns kept ([`Recheck::turns`]): settling a target solved again
/// asks for the turns of one command up to three times (the history its prediction is taken
/// with, the next round's check, the state it leaves), each a walk of the interpolated path.
/// Within one target's settling nothing else they read changes (the commands around it, the
/// state it arrives from), so the command, the widths and the arrival are the whole key.
#[derive(Clone, Copy)]
struct TurnsKept {
    k: usize,
    from: [u64; 6],
    command: [u64; 6],
    widths: [u64; 6],
    turns: interpolate::Turns,
}

impl<'a> std::ops::Deref for Recheck<'a> {
    type Target = Ctx<'a>;
    fn deref(&self) -> &Ctx<'a> {
        &self.ctx
    }
}

/// An axis's play width table with the cells of it looked up recently: the re-check asks an
/// axis's width at its commands, a few millidegrees apart along a path, and at the turning
/// points of its history (a rippled path turns an axis round every few targets, within a
/// degree or two), so nearly every lookup falls in a cell looked up just before, where it
/// is the interpolation between two values kept at hand. The arithmetic is the table's own
/// ([`Grid::locate`](crate::model::table::Grid::locate), [`Table1::value_in`]), so a width is
/// the one [`Model::play_width_deg`] gives, to the bit.
struct WidthTable<'a> {
    table: &'a Table1,
    /// Cells looked up, each in the slot of its place on the grid (neighbouring cells in
    /// different slots).
    cells: [Cell<WidthCell>; WIDTH_SLOTS],
    /// Cells per degree, about (a slot's index only: any value is correct).
    per_deg: f64,
    /// The grid's ends and the widths held beyond them (an axis may work outside the grid
    /// the play was identified on).
    ends: (f64, f64),
    held: (f64, f64),
}

/// Slots of [`WidthTable::cells`] (a power of two).
const WIDTH_SLOTS: usize = 8;

/// A cell of a width table: the angles `[lo, hi)` it answers and the values at its ends.
#[derive(Clone, Copy, Debug)]
struct WidthCell {
    lo: f64,
    hi: f64,
    /// `1 / (hi − lo)`, as the grid computes it for the cell's weight.
    inv_width: f64,
    at_lo: f64,
    at_hi: f64,
}

impl WidthCell {
    /// A cell that answers no angle.
    const NONE: WidthCell = WidthCell {
        lo: f64::NAN,
        hi: f64::NAN,
        inv_width: f64::NAN,
        at_lo: f64::NAN,
        at_hi: f64::NAN,
    };
}

impl<'a> WidthTable<'a> {
    fn new(table: &'a Table1) -> WidthTable<'a> {
        let p = table.grid.points();
        let ends = (p[0], p[p.len() - 1]);
        let at = |x: f64| table.value_in(&table.grid.locate(x));
        WidthTable {
            table,
            cells: std::array::from_fn(|_| Cell::new(WidthCell::NONE)),
            per_deg: (p.len() - 1) as f64 / (ends.1 - ends.0),
            ends,
            held: (at(ends.0), at(ends.1)),
        }
    }

    /// The slot of the cells about `angle`.
    #[inline(always)]
    fn slot(&self, angle: f64) -> &Cell<WidthCell> {
        // Any slot is correct (an angle off the grid, or NaN, misses in any): the cheaper
        // conversion of the two.
        let place = ((angle - self.ends.0) * self.per_deg) as i32;
        &self.cells[place as usize % WIDTH_SLOTS]
    }

    /// The width at `angle` (`table.eval(angle).0`). Inlined where it is asked: most lookups
    /// are answered by a cell kept.
    #[inline(always)]
    fn width(&self, angle: f64) -> f64 {
        let slot = self.slot(angle);
        let c = slot.get();
        if c.lo <= angle && angle < c.hi {
            let w = ((angle - c.lo) * c.inv_width).clamp(0.0, 1.0);
            (1.0 - w) * c.at_lo + w * c.at_hi
        } else {
            self.outside_cells(angle, slot)
        }
    }

    /// [`Self::width`] where `slot` does not hold the cell.
    #[inline(always)]
    fn outside_cells(&self, angle: f64, slot: &Cell<WidthCell>) -> f64 {
        if angle <= self.ends.0 {
            self.held.0
        } else if angle >= self.ends.1 {
            self.held.1
        } else {
            self.look_up(angle, slot)
        }
    }

    /// [`Self::width`] inside the grid where `slot` does not hold the cell: looked up in the
    /// table, its cell kept in `slot`.
    #[inline(never)]
    fn look_up(&self, angle: f64, slot: &Cell<WidthCell>) -> f64 {
        let (table, cell) = (self.table, self.table.grid.locate(angle));
        if !cell.clamped && cell.hi == cell.lo + 1 {
            let p = table.grid.points();
            let (lo, hi) = (p[cell.lo], p[cell.hi]);
            slot.set(WidthCell {
                lo,
                hi,
                inv_width: 1.0 / (hi - lo),
                at_lo: table.values[cell.lo],
                at_hi: table.values[cell.hi],
            });
        }
        table.value_in(&cell)
    }
}

impl<'a> Recheck<'a> {
    fn new(ctx: Ctx<'a>) -> Recheck<'a> {
        let plays = std::array::from_fn(|n| ctx.model.play_width_table(n).map(WidthTable::new));
        Recheck {
            ctx,
            plays,
            before: Default::default(),
            turns: Cell::new(None),
        }
    }

    /// The width (degrees) of axis n's play at command `angle` ([`Model::play_width_deg`]).
    #[inline(always)]
    fn play_width(&self, n: usize, angle: f64) -> f64 {
        match &self.plays[n] {
            Some(play) => play.width(angle),
            None => 0.0,
        }
    }

    /// Where axis n's play output stands against the command at `state` (0 without a play).
    fn play_lag(&self, state: &AxisState, n: usize) -> f64 {
        if self.plays[n].is_none() {
            return 0.0;
        }
        // Along a path the history of an axis changes mostly in its last point from one target
        // to the next: the clamps before it are kept.
        let before = &mut self.before[n].borrow_mut();
        state.history[n]
            .play_keeping(state.axes_deg[n], |a| self.play_width(n, a), before)
            .lag_deg
    }
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

    /// Target `k` of the history and segment together.
    fn target(&self, k: usize) -> &Target {
        match self.history.get(k) {
            Some(c) => &c.target,
            None => &self.targets[k - self.history.len()],
        }
    }

    fn len(&self) -> usize {
        self.history.len() + self.targets.len()
    }

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

/// Rounds of [`settle_target`] per target before the best is kept.
const SETTLE_ROUNDS: usize = 4;

/// An axis whose output must move by no more than this (degrees) to meet the pose is held
/// still when the program holds it: the solver's own tolerance (0.1 µm at the TCP) moves an
/// axis by up to about this much, and inside the play a command anywhere gives the same
/// output, so a held command that jittered by it would only be noise.
pub const HOLD_DEG: f64 = 1e-5;

/// Pass 3: walks the compensated commands through each axis's history, re-solving the targets
/// whose gear plays stand otherwise than the flanks they were solved with (see the module
/// documentation). Targets before `from` are settled (history). Returns the counts and the
/// states of the last (up to [`LOOK_BACK`]) targets. A long sequence on the pool is walked in
/// stretches beside each other ([`stretches`]), to the same bits.
fn recheck(
    ctx: &Recheck,
    previous: Option<AxisState>,
    from: usize,
    outcomes: &mut [Outcome],
    nominal: &[Signs],
    resolved: &mut [bool],
    options: &Options,
) -> (Counts, Vec<AxisState>) {
    let mut states = States::new(previous);
    let span = Span {
        nominal_from: from,
        first: from,
    };
    let counts = if options.parallel {
        stretches::recheck(ctx, &mut states, span, outcomes, nominal, resolved, options.stretching)
    } else {
        span.settle(ctx, &mut states, from..ctx.len(), outcomes, nominal, resolved, |_, _, _| {})
    };
    // The segment's own (the history's state may still be among them).
    let keep = (ctx.len() - from).min(states.len());
    (counts, states.oldest_first().skip(states.len() - keep).copied().collect())
}

/// Where a walk of the re-check stands in its sequence: `nominal` holds the signs of the
/// targets from `nominal_from` on, and `first` is the first target it settles (a circle's end
/// there does not settle its auxiliary point again: it lies before the walk).
#[derive(Clone, Copy, Debug)]
struct Span {
    nominal_from: usize,
    first: usize,
}

impl Span {
    /// Settles targets `ks` in order after the states in `states`, telling `each` every target
    /// settled with the states after it and what it adds to the counts.
    #[allow(clippy::too_many_arguments)]
    fn settle(
        self,
        ctx: &Recheck,
        states: &mut States,
        ks: std::ops::Range<usize>,
        outcomes: &mut [Outcome],
        nominal: &[Signs],
        resolved: &mut [bool],
        mut each: impl FnMut(usize, &States, Counts),
    ) -> Counts {
        let mut counts = Counts::default();
        for k in ks {
            let step = self.settle_one(ctx, states, k, outcomes, nominal, resolved);
            counts += step;
            each(k, states, step);
        }
        counts
    }

    /// Settles target `k` after the states in `states` (then holding its own as the last), and
    /// what it adds to the counts.
    fn settle_one(
        self,
        ctx: &Recheck,
        states: &mut States,
        k: usize,
        outcomes: &mut [Outcome],
        nominal: &[Signs],
        resolved: &mut [bool],
    ) -> Counts {
        let rest = |k: usize| -> [bool; 6] {
            let turns = ctx.target(k).turns.angle_deg;
            match nominal.get(k.wrapping_sub(self.nominal_from)).copied().flatten() {
                Some(v) => std::array::from_fn(|n| v[n] == 0 && !turns[n].is_finite()),
                None => [false; 6],
            }
        };
        let (last, state) = states.last_and_next();
        settle_one(ctx, k, &rest(k), last, outcomes, &mut resolved[k], state);
        // A circle's auxiliary point and end shape one arc: the end settled, its auxiliary
        // point (settled with the end's first-pass command) is settled again, then the end.
        if ctx.target(k).interp == Interp::CircEnd && k > self.first && states.len() >= 2 {
            for _ in 0..2 {
                let (before_aux, aux) = states.before_last_and_last();
                let (aux_rest, aux_resolved) = (&rest(k - 1), &mut resolved[k - 1]);
                settle_one(ctx, k - 1, aux_rest, Some(before_aux), outcomes, aux_resolved, aux);
                let (last, state) = states.last_and_next();
                settle_one(ctx, k, &rest(k), last, outcomes, &mut resolved[k], state);
            }
        }
        let mut counts = Counts::default();
        let o = &outcomes[k];
        if resolved[k] {
            counts.reflanked += (o.resolution == Resolution::Reflanked) as usize;
            counts.held += matches!(o.resolution, Resolution::Held(_)) as usize;
        }
        counts.travels_play += o.travels_play.contains(&true) as usize;
        // The auxiliary point of a circle written by construction is not visited: the circle
        // starts from the stop before it.
        if ctx.target(k).interp == Interp::CircAngleAux {
            if let (Some(before), state) = states.last_and_next() {
                *state = *before;
            }
        }
        states.push_next();
        counts
    }
}

/// The states of the last (up to [`LOOK_BACK`]) targets settled, in a ring with a slot for
/// the next: the next target's state is written in place beside the ones it needs (they are
/// 400-byte records).
#[derive(Clone)]
struct States {
    slots: [AxisState; LOOK_BACK + 1],
    /// The slot of the last state.
    last: usize,
    /// States held (up to [`LOOK_BACK`]).
    len: usize,
}

impl States {
    /// The states after `previous` (the history's last), when there is one.
    fn new(previous: Option<AxisState>) -> States {
        let mut slots = [AxisState::default(); LOOK_BACK + 1];
        slots[0] = previous.unwrap_or_default();
        States {
            slots,
            last: 0,
            len: previous.is_some() as usize,
        }
    }

    /// The states a walk left, oldest first (up to [`LOOK_BACK`]).
    fn holding(states: &[AxisState]) -> States {
        debug_assert!(states.len() <= LOOK_BACK);
        let mut slots = [AxisState::default(); LOOK_BACK + 1];
        slots[..states.len()].copy_from_slice(states);
        States {
            slots,
            last: states.len().saturating_sub(1),
            len: states.len(),
        }
    }

    fn len(&self) -> usize {
        self.len
    }

    /// The state `back` places before the last (0: the last), when held.
    fn back(&self, back: usize) -> Option<&AxisState> {
        (back < self.len).then(|| &self.slots[self.slot(back)])
    }

    /// The slot `back` places before the last.
    fn slot(&self, back: usize) -> usize {
        (self.last + self.slots.len() - back) % self.slots.len()
    }

    /// The state in slot `from` and the one in slot `into` (another), to write.
    fn pair(&mut self, from: usize, into: usize) -> (&AxisState, &mut AxisState) {
        debug_assert_ne!(from, into);
        if from < into {
            let (a, b) = self.slots.split_at_mut(into);
            (&a[from], &mut b[0])
        } else {
            let (a, b) = self.slots.split_at_mut(from);
            (&b[0], &mut a[into])
        }
    }

    /// The last state (none before the first target) and the next one's slot.
    fn last_and_next(&mut self) -> (Option<&AxisState>, &mut AxisState) {
        let (held, next) = (self.len > 0, self.slot(self.slots.len() - 1));
        let (last, next) = self.pair(self.last, next);
        (held.then_some(last), next)
    }

    /// The state before the last and the last, to write (at least two held).
    fn before_last_and_last(&mut self) -> (&AxisState, &mut AxisState) {
        debug_assert!(self.len >= 2);
        self.pair(self.slot(1), self.last)
    }

    /// Takes the next slot's state as the last (the oldest beyond [`LOOK_BACK`] let go).
    fn push_next(&mut self) {
        self.last = self.slot(self.slots.len() - 1);
        self.len = (self.len + 1).min(LOOK_BACK);
    }

    /// The states held, oldest first.
    fn oldest_first(&self) -> impl Iterator<Item = &AxisState> {
        (0..self.len).rev().map(|back| &self.slots[self.slot(back)])
    }
}

/// Settles target `k` in `outcomes`, arriving from `previous` (see [`settle_target`]): solving
/// again moves the compensated path, which may turn an axis round elsewhere, so it is settled
/// until the plays stand where the solve assumed (a few rounds at most), else the round that
/// predicts the smallest error is kept. Writes the state it leaves into `state`; `resolved`
/// is set when it was solved again.
fn settle_one(
    ctx: &Recheck,
    k: usize,
    rest: &[bool; 6],
    previous: Option<&AxisState>,
    outcomes: &mut [Outcome],
    resolved: &mut bool,
    state: &mut AxisState,
) {
    // The turns kept are those of another target's settling (or of this one's before the
    // commands around it changed: a circle's auxiliary point settled again).
    ctx.turns.set(None);
    // The outcome solved again, once it is (until then the slice's, read in place).
    let mut again: Option<Outcome> = None;
    let mut best: Option<Outcome> = None;
    let mut settled = None;
    for _ in 0..SETTLE_ROUNDS {
        let o = again.as_ref().unwrap_or(&outcomes[k]);
        let mut travels_play = o.travels_play;
        match settle_target(ctx, k, rest, previous, (o, outcomes), &mut travels_play) {
            Settling::Settled(turns) => {
                again.as_mut().unwrap_or(&mut outcomes[k]).travels_play = travels_play;
                settled = Some(turns);
                break;
            }
            Settling::Again(how) => {
                let mut o = again.unwrap_or(outcomes[k]);
                o.travels_play = travels_play;
                solve_again(ctx, k, previous, (&mut o, outcomes), how);
                *resolved = true;
                let error = |o: &Outcome| solve::weighted_norm(&o.residual);
                if best.map_or(true, |b| error(&o) < error(&b)) {
                    best = Some(o);
                }
                again = Some(o);
            }
        }
    }
    if let Some(o) = again {
        outcomes[k] = match (settled, best) {
            (None, Some(b)) => b,
            _ => o,
        };
    }
    let o = &outcomes[k];
    let axes_deg = o.axes_deg.into();
    match (settled.flatten(), previous) {
        // The turns the settling worked out for this very command.
        (Some(turns), Some(p)) => state.advance_from(p, &turns.angle_deg, axes_deg),
        _ => {
            state.axes_deg = axes_deg;
            state.history = arrival_histories(ctx, k, previous, o, outcomes);
        }
    };
    state.time_s = 0.0;
}

/// Each axis's history on arrival at target `k` commanded as in `out`: the compensated
/// command before, then the turning points of the motion, moved with the compensated path (the
/// nominal one plus the corrections interpolated along it).
fn arrival_histories(
    ctx: &Recheck,
    k: usize,
    previous: Option<&AxisState>,
    out: &Outcome,
    outcomes: &[Outcome],
) -> [AxisHistory; 6] {
    let target = ctx.target(k);
    if target.arrival.is_none() {
        return [AxisHistory::unmoved(); 6];
    }
    let Some(p) = previous else {
        return out.nominal_directions.map(AxisHistory::engaged);
    };
    let widths = std::array::from_fn(|n| ctx.play_width(n, out.axes_deg[n]));
    let turns = compensated_turns(ctx, k, p, (&out.axes_deg, &widths), outcomes);
    p.then_through(&turns.angle_deg, out.axes_deg.into())
        .history
}

/// A motion that moves an axis by less than this many of its play's widths (degrees, plus
/// 0.001°) may turn it round by an amount that matters to the play.
const SENSITIVE_PLAYS: f64 = 4.0;
/// A correction changing along a motion by more than this share of the nominal move may turn
/// the axis round inside it (the nominal rate along a short motion varies far less).
const CORRECTION_SHARE: f64 = 10.0;

/// The turning points of the compensated motion into target `k` (from `previous`, commanded
/// at `c`, where the plays' widths are `widths`). The compensated motion is the nominal one moved by the corrections; where an axis
/// moves little, the way the correction bends along the motion decides whether and where it
/// turns round, so the motion is walked as the controller interpolates it between the
/// compensated commands (samples, exact rates at the ends). Elsewhere — and where the path
/// cannot be built — the nominal turns, moved by the corrections interpolated to them.
fn compensated_turns(
    ctx: &Recheck,
    k: usize,
    previous: &AxisState,
    (c, widths): (&[f64; 6], &[f64; 6]),
    outcomes: &[Outcome],
) -> interpolate::Turns {
    let bits = |a: &[f64; 6]| a.map(f64::to_bits);
    let (from, command, width_bits) = (bits(&previous.axes_deg), bits(c), bits(widths));
    if let Some(kept) = ctx.turns.get() {
        if kept.k == k && kept.from == from && kept.command == command && kept.widths == width_bits
        {
            return kept.turns;
        }
    }
    let turns = compensated_turns_walked(ctx, k, previous, (c, widths), outcomes);
    ctx.turns.set(Some(TurnsKept {
        k,
        from,
        command,
        widths: width_bits,
        turns,
    }));
    turns
}

/// [`compensated_turns`], worked out.
fn compensated_turns_walked(
    ctx: &Recheck,
    k: usize,
    previous: &AxisState,
    (c, widths): (&[f64; 6], &[f64; 6]),
    outcomes: &[Outcome],
) -> interpolate::Turns {
    let target = ctx.target(k);
    let prev = previous.axes_deg;
    // An axis can turn round inside the compensated motion where the nominal one does, or
    // where the correction changes along the motion by a fair part of the nominal move (a
    // resting axis, a slow one): only there does the walk decide anything.
    let nominal_prev = (k > 0).then(|| &ctx.target(k - 1).nominal_axes);
    let sensitive = (0..6).any(|n| {
        let b = widths[n];
        if !(b > 0.0 && (c[n] - prev[n]).abs() < SENSITIVE_PLAYS * b + 1e-3) {
            return false;
        }
        let Some(np) = nominal_prev else { return true };
        let nominal_move = target.nominal_axes[n] - np[n];
        let correction_change = (c[n] - target.nominal_axes[n]) - (prev[n] - np[n]);
        target.turns.angle_deg[n].is_finite()
            || correction_change.abs() * CORRECTION_SHARE > nominal_move.abs()
    });
    if sensitive && k > 0 {
        if let Some(turns) = walk_compensated(ctx, k, c, outcomes) {
            return turns;
        }
    }
    let mut turns = target.turns;
    for n in 0..6 {
        turns.angle_deg[n] = nominal_turn_moved(target, nominal_prev, prev[n], n, c[n]);
    }
    turns
}

/// Axis n's last nominal turning point inside the motion into `target` (NaN: none), moved by
/// the corrections interpolated to it: the command before at `c0` (the nominal one
/// `nominal_prev`, none for the first target), the target's at `c`.
fn nominal_turn_moved(
    target: &Target,
    nominal_prev: Option<&AxisAngles>,
    c0: f64,
    n: usize,
    c: f64,
) -> f64 {
    let (t, u) = (target.turns.angle_deg[n], target.turns.at[n]);
    let (turn, at) = match nominal_prev.filter(|_| t.is_finite()) {
        Some(np) => {
            let before = c0 - np[n];
            (t + (1.0 - u) * before - u * target.nominal_axes[n], u)
        }
        None => (f64::NAN, 0.0),
    };
    turn + at * c
}

/// The compensated motion into target `k` walked as the controller interpolates it (the
/// targets before at their commands in `outcomes`, target k at `c`, the one after — the end of
/// a circle whose auxiliary point k is — at its first-pass command): its turning points after
/// the stop before; `None` for a PTP motion (linear in the axes: none) or a path that cannot
/// be followed.
fn walk_compensated(
    ctx: &Ctx,
    k: usize,
    c: &[f64; 6],
    outcomes: &[Outcome],
) -> Option<interpolate::Turns> {
    use interpolate::{Cartesian, Path};
    let target = ctx.target(k);
    let robot = &ctx.model.robot;
    let tool = ctx.tool(k);
    let cmd = |j: usize| if j == k { *c } else { *outcomes[j].axes_deg };
    let tcp = |j: usize| Nominal(robot).tcp(&cmd(j), ctx.tool(j));
    // The path, where it starts (its command) and the share of it before the stop before.
    let (path, from, before): (Cartesian, usize, f64) = match target.interp {
        Interp::Joint | Interp::CircAngleAux => return None,
        Interp::Line => (
            Cartesian::new(&tcp(k - 1), &tcp(k), &Path::Lin).ok()?,
            k - 1,
            0.0,
        ),
        Interp::Curve { first, last } => {
            let mut p = Vec::with_capacity(4);
            if !first && k >= 2 {
                p.push(tcp(k - 2).position);
            }
            let (a, b) = (tcp(k - 1), tcp(k));
            p.push(a.position);
            p.push(b.position);
            if !last && k + 1 < ctx.len() {
                // The next point moved by this one's correction (it is not settled yet).
                let shift = b.position - target.goal.position;
                p.push(ctx.target(k + 1).goal.position + shift);
            }
            let at = p.iter().position(|q| *q == b.position)?;
            let tangents = crate::motion::spline::tangents(&p);
            (
                Cartesian::cubic(&a, &b, &tangents[at - 1], &tangents[at]),
                k - 1,
                0.0,
            )
        }
        Interp::CircEnd if k >= 2 => {
            let (start, aux, end) = (tcp(k - 2), tcp(k - 1).position, tcp(k));
            let arc = Cartesian::new(&start, &end, &Path::Circ { aux }).ok()?;
            let u_aux = arc.fraction_at(&aux);
            (arc, k - 2, u_aux)
        }
        // The auxiliary point of a circle written by construction is not on the path.
        Interp::CircAngle(a) if k >= 2 => {
            let (start, aux, end) = (tcp(k - 2), tcp(k - 1).position, tcp(k));
            let arc = interpolate::circle_by_angle(&start, &end, a.degrees(), a.plane(aux))?;
            (arc, k - 2, 0.0)
        }
        Interp::CircAux if k + 1 < ctx.len() => {
            let (start, aux, end) = (tcp(k - 1), tcp(k).position, tcp(k + 1));
            let arc = Cartesian::new(&start, &end, &Path::Circ { aux }).ok()?;
            let u_aux = arc.fraction_at(&aux);
            let (arrival, _) =
                interpolate::arrival_and_end(robot, tool, &arc, u_aux, (&cmd(k - 1), None), c)
                    .ok()?;
            return Some(arrival.turns);
        }
        _ => return None,
    };
    let (arrival, _) =
        interpolate::arrival_and_end(robot, tool, &path, 1.0, (&cmd(from), None), c).ok()?;
    // Only the turns after the stop before count (the ones before it are in its history).
    Some(arrival.turns.after(before))
}

/// One axis's motion into target `k`, compensated: from the command before (where the play's
/// output stood), through the motion's last turning point if it has one — the nominal turn
/// moved by the corrections interpolated to it, so it moves with the command — to the
/// command. The play's output on arrival is monotone in the command; [`Segment::command_for`]
/// inverts it.
struct Segment {
    /// The play's output where the motion begins.
    start_output: f64,
    /// The turning point at command `c`: `turn + at·c` (NaN: none).
    turn: f64,
    at: f64,
    /// Half the play's width.
    half: f64,
}

impl Segment {
    /// Axis n's motion into `target` from `previous`, with `turns` those of the compensated
    /// motion commanded at `c` ([`compensated_turns`]).
    fn of(
        ctx: &Recheck,
        target: &Target,
        previous: &AxisState,
        n: usize,
        (turns, c): (&interpolate::Turns, &[f64; 6]),
    ) -> Segment {
        let c0 = previous.axes_deg[n];
        let (t, u) = (turns.angle_deg[n], turns.at[n]);
        // The turn moves with the command by the share of the correction interpolated to it.
        let (turn, at) = if t.is_finite() {
            (t - u * c[n], u)
        } else {
            (f64::NAN, 0.0)
        };
        Segment {
            start_output: c0 + ctx.play_lag(previous, n),
            turn,
            at,
            half: 0.5 * ctx.play_width(n, target.nominal_axes[n]),
        }
    }

    /// The turning point when the command is `c` (NaN: none).
    fn turn(&self, c: f64) -> f64 {
        self.turn + self.at * c
    }

    /// The play's output on arrival at command `c`.
    fn output(&self, c: f64) -> f64 {
        let clamp = |o: f64, x: f64| o.clamp(x - self.half, x + self.half);
        let t = self.turn(c);
        let o = if t.is_finite() {
            clamp(self.start_output, t)
        } else {
            self.start_output
        };
        clamp(o, c)
    }

    /// The output `(command, output)` at `lo`, `hi` and its breakpoints between them (where
    /// the turn's clamp or the arrival's clamp starts or stops acting), in order of the
    /// command, into `points`; returns how many there are. The output is linear between them.
    #[inline]
    fn breakpoints(&self, lo: f64, hi: f64, points: &mut [(f64, f64); 14]) -> usize {
        let (s, h, t0, a) = (self.start_output, self.half, self.turn, self.at);
        let mut xs = [0.0; 12];
        let mut n = 0;
        let mut add = |x: f64| {
            if x.is_finite() && x > lo && x < hi {
                xs[n] = x;
                n += 1;
            }
        };
        add(s - h);
        add(s + h);
        if t0.is_finite() {
            if a > 0.0 {
                add((s + h - t0) / a);
                add((s - h - t0) / a);
            }
            if a < 1.0 {
                for k in [-h, h] {
                    for m in [-h, h] {
                        add((t0 + k - m) / (1.0 - a));
                    }
                }
            }
        }
        points[0] = (lo, self.output(lo));
        for (i, &x) in xs[..n].iter().enumerate() {
            points[i + 1] = (x, 0.0);
        }
        points[n + 1] = (hi, 0.0);
        points[..n + 2].sort_by(|p, q| p.0.total_cmp(&q.0));
        for p in points[..n + 2].iter_mut() {
            p.1 = self.output(p.0);
        }
        n + 2
    }

    /// The flank [`Self::command_for`] finds driven, when it is certain without the search
    /// (`None`: search). On a motion without a turning point whose wanted output lies clearly
    /// above where the output starts, every command that reaches it lies past the band's
    /// upper edge `start_output + half`, where the output is the command less half the play:
    /// the positive flank; clearly below, the negative one. "Clearly" is by far more than the
    /// rounding of the breakpoints (a few ulps) and the search's tolerance, and the bracket
    /// is then found well within its 360° limit. Most moving axes of a path are settled here.
    fn sure_flank(&self, wanted: f64, near: f64) -> Option<Direction> {
        const CLEAR_DEG: f64 = 1e-9;
        let (s, h) = (self.start_output, self.half);
        let certain = !self.turn.is_finite()
            && (1e-6..1.0).contains(&h)
            && s.is_finite()
            && (wanted - near).abs() < 90.0;
        if !certain {
            None
        } else if wanted > s + CLEAR_DEG {
            Some(Direction::Positive)
        } else if wanted < s - CLEAR_DEG {
            Some(Direction::Negative)
        } else {
            None
        }
    }

    /// The command whose arrival puts the play's output at `wanted`, nearest `near` where a
    /// range of commands does (inside the play), and how it does it.
    fn command_for(&self, wanted: f64, near: f64) -> (f64, Reach) {
        // The output is monotone and piecewise linear in the command (slopes 0, `at` or 1):
        // bracket, then find the first and last command that reach it by interpolating
        // between its breakpoints (no bisection).
        let tol = 1e-12;
        let mut span = 4.0 * self.half + 1e-3;
        let (mut lo, mut hi) = (near - span, near + span);
        while self.output(lo) > wanted - tol || self.output(hi) < wanted + tol {
            span *= 2.0;
            (lo, hi) = (near - span, near + span);
            if span > 360.0 {
                return (near, Reach::Stuck);
            }
        }
        let mut points = [(0.0, 0.0); 14];
        let n = self.breakpoints(lo, hi, &mut points);
        let points = &points[..n];
        let cross = |(x0, y0): (f64, f64), (x1, y1): (f64, f64), y: f64| {
            if y1 > y0 {
                (x0 + (y - y0) * (x1 - x0) / (y1 - y0)).clamp(x0, x1)
            } else {
                x1
            }
        };
        // The first command whose output reaches `wanted` and the last that does not pass it.
        let i = points
            .iter()
            .position(|p| p.1 >= wanted - tol)
            .unwrap_or(points.len() - 1)
            .max(1);
        let first = cross(points[i - 1], points[i], wanted - tol);
        let j = points
            .iter()
            .rposition(|p| p.1 <= wanted + tol)
            .unwrap_or(0)
            .min(points.len() - 2);
        let last = cross(points[j], points[j + 1], wanted + tol);
        let c = near.clamp(first, last);
        let o = self.output(c);
        let reach = if (o - (c - self.half)).abs() <= 1e-9 && self.half > 0.0 {
            Reach::Flank(Direction::Positive)
        } else if (o - (c + self.half)).abs() <= 1e-9 && self.half > 0.0 {
            Reach::Flank(Direction::Negative)
        } else {
            Reach::Stuck
        };
        (c, reach)
    }
}

/// What [`settle_target`] found.
enum Settling {
    /// The plays stand where the solve assumed; the turning points of the compensated motion
    /// into the target when they were worked out (the target's history needs them again).
    Settled(Option<interpolate::Turns>),
    /// To be solved again so.
    Again(Again),
}

/// How a command puts the play's output where it must be.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Reach {
    /// Driving the flank of a motion in this direction: the output follows the command.
    Flank(Direction),
    /// Inside the play: the output stays where the motion (or its turn) left it.
    Stuck,
}

/// Settles target `k` (its outcome so far in `out`) against where the compensated motion
/// leaves each gear play: every axis's command is the one whose arrival puts the play's output
/// where the pose needs it ([`Segment::command_for`]); the target is to be solved again where
/// that is not the first pass's flank — on the flank it drives, or, where the output stays
/// inside the play, with that axis held at its command (the program's held axes at their
/// command before) — and the axes whose output moves back by less than their play are marked
/// in `travels_play` (`out`'s on entry). Returns how to solve it again, or the turns of its
/// compensated motion where they were worked out. `rest[n]`: the nominal motion holds axis n
/// still. (It reads `out` in place: most targets settle at once, and their outcome is not
/// copied out of the slice and back.)
fn settle_target(
    ctx: &Recheck,
    k: usize,
    rest: &[bool; 6],
    previous: Option<&AxisState>,
    (out, outcomes): (&Outcome, &[Outcome]),
    travels_play: &mut [bool; 6],
) -> Settling {
    let Some(p) = previous.filter(|_| ctx.target(k).arrival.is_some()) else {
        return Settling::Settled(None);
    };
    let c: [f64; 6] = out.axes_deg.into();
    let axes = AxesOf {
        ctx,
        k,
        target: ctx.target(k),
        p,
        c,
        widths: std::array::from_fn(|n| ctx.play_width(n, c[n])),
        assumed: out.directions,
        outcomes,
    };
    let mut again = Again {
        flanks: out.directions,
        hold: [false; 6],
        start: c,
    };
    let mut differs = false;
    let mut turns: Option<interpolate::Turns> = None;
    for (n, &rest) in rest.iter().enumerate() {
        match axes.settle(n, rest, &mut turns, &mut travels_play[n]) {
            AxisSettled::Kept => continue,
            AxisSettled::Reflanked(d) => again.flanks[n] = d,
            AxisSettled::Held { command, driven } => {
                again.hold[n] = true;
                again.start[n] = command;
                again.flanks[n] = driven;
            }
        }
        differs = true;
    }
    if !differs {
        return Settling::Settled(turns);
    }
    Settling::Again(again)
}

/// What [`settle_target`] works an axis out from: the target, the state the motion arrives
/// from, the first pass's commands, their play widths and the flanks it assumed.
struct AxesOf<'x, 'a> {
    ctx: &'x Recheck<'a>,
    k: usize,
    target: &'x Target,
    p: &'x AxisState,
    c: [f64; 6],
    widths: [f64; 6],
    assumed: [Direction; 6],
    outcomes: &'x [Outcome],
}

/// Where an axis's play leaves the first pass's command.
enum AxisSettled {
    /// On the flank the solve assumed: nothing to do.
    Kept,
    /// The arrival drives the other flank: solve again on it.
    Reflanked(Direction),
    /// The output stays inside the play: solve again with the axis held at `command`, its
    /// play as the motion (last driven `driven`) leaves it.
    Held { command: f64, driven: Direction },
}

impl AxesOf<'_, '_> {
    /// Axis `n` (`rest`: the nominal motion holds it), the compensated motion's turns worked
    /// out into `turns` when first needed; `travels_play` marks an output that moves back by
    /// less than the play.
    fn settle(
        &self,
        n: usize,
        rest: bool,
        turns: &mut Option<interpolate::Turns>,
        travels_play: &mut bool,
    ) -> AxisSettled {
        let (ctx, k, p, c, b, assumed) = (
            self.ctx,
            self.k,
            self.p,
            &self.c,
            self.widths[n],
            self.assumed[n],
        );
        // Without a play every command's output is the command: nothing to settle.
        if b == 0.0 {
            return AxisSettled::Kept;
        }
        let moved = c[n] - p.axes_deg[n];
        let jitter = rest && moved != 0.0 && moved.abs() <= HOLD_DEG;
        // The common case needs nothing more: a long motion that the command continues by
        // more than the compensated path could turn it round by.
        let engaged = p.history[n].engaged_at(p.axes_deg[n]) == Some(assumed)
            && assumed.sign() * moved >= SENSITIVE_PLAYS * b + 1e-3
            && !self.target.turns.angle_deg[n].is_finite();
        if engaged && !jitter {
            return AxisSettled::Kept;
        }
        let turns = turns
            .get_or_insert_with(|| compensated_turns(ctx, k, p, (c, &self.widths), self.outcomes));
        let segment = Segment::of(ctx, self.target, p, n, (turns, c));
        let wanted = c[n] - assumed.sign() * 0.5 * b;
        // The output moves back by less than the play: the command travels it.
        let driven = p.history[n].direction(p.axes_deg[n]);
        let way = wanted - segment.start_output;
        let turning = Direction::Unknown.after_move(way);
        *travels_play = driven != Direction::Unknown
            && turning != Direction::Unknown
            && turning != driven
            && way.abs() < 2.0 * segment.half;
        if (segment.output(c[n]) - wanted).abs() <= 1e-12 && !jitter {
            return AxisSettled::Kept;
        }
        let (mut command, mut reach) = match segment.sure_flank(wanted, c[n]) {
            // The command found would only be used for an axis held inside its play.
            Some(d) => {
                debug_assert_eq!(segment.command_for(wanted, c[n]).1, Reach::Flank(d));
                (c[n], Reach::Flank(d))
            }
            None => segment.command_for(wanted, c[n]),
        };
        // A held axis whose output need not move (beyond the solver's own noise) stays exactly
        // where it was.
        if rest && (segment.output(p.axes_deg[n]) - wanted).abs() <= HOLD_DEG {
            (command, reach) = (p.axes_deg[n], Reach::Stuck);
            *travels_play = false;
        }
        match reach {
            Reach::Flank(d) if d == assumed => AxisSettled::Kept,
            Reach::Flank(d) => AxisSettled::Reflanked(d),
            Reach::Stuck => AxisSettled::Held { command, driven },
        }
    }
}

/// How [`solve_again`] solves a target: each axis on a flank, or held at its start.
struct Again {
    flanks: [Direction; 6],
    hold: [bool; 6],
    start: [f64; 6],
}

/// Target `k` solved again as [`settle_target`] decided (`again`), its prediction then taken
/// with every play evaluated exactly where the command leaves it.
fn solve_again(
    ctx: &Recheck,
    k: usize,
    previous: Option<&AxisState>,
    (out, outcomes): (&mut Outcome, &[Outcome]),
    again: Again,
) {
    let Again {
        flanks,
        hold,
        start,
    } = again;
    let (model, target, tool) = (ctx.model, ctx.target(k), ctx.tool(k));
    out.directions = flanks;
    // The held axes' plays where their commands leave them; the others on their flanks.
    if !target.compensate || out.error.is_some() {
        // The command is the nominal one: only the prediction changes.
        let nominal = arrival_histories(ctx, k, previous, out, outcomes);
        out.before = tcp_error(model, tool, &target.nominal_axes, &nominal, &target.goal);
        out.residual = out.before;
        return;
    }
    // Without an axis held, no play is taken where the commands leave it: the walk of the
    // held command's motion is not needed.
    let exact = hold.contains(&true).then(|| {
        let mut commanded = *out;
        commanded.axes_deg = start.into();
        arrival_histories(ctx, k, previous, &commanded, outcomes)
    });
    let solving: [AxisHistory; 6] = std::array::from_fn(|n| match &exact {
        Some(exact) if hold[n] => exact[n],
        _ => AxisHistory::engaged(flanks[n]),
    });
    match solve_target(model, tool, target, &solving, start, hold, ctx.method, None) {
        Ok((sol, turn_held)) => {
            out.axes_deg = sol.axes_deg.into();
            out.iterations += sol.iterations;
            out.changed = sol.axes_deg != target.nominal_axes;
            out.turn_held = turn_held;
            out.resolution = if hold.contains(&true) {
                Resolution::Held(hold)
            } else {
                Resolution::Reflanked
            };
        }
        Err(e) => {
            out.error = Some(e);
            out.axes_deg = target.nominal_axes;
            out.changed = false;
        }
    }
    let histories = arrival_histories(ctx, k, previous, out, outcomes);
    out.residual = tcp_error(model, tool, &out.axes_deg, &histories, &target.goal);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A width from a kept cell is the table's own, to the bit: along a path of small
        /// steps (inside a cell, onto and across its edges), jumps, and angles off the grid,
        /// on grids of uneven spacing.
        #[test]
        fn a_width_from_a_kept_cell_is_the_tables(
            first in -200.0f64..0.0,
            steps in prop::collection::vec(0.05f64..3.0, 1..8),
            values in prop::collection::vec(0.0f64..0.05, 8),
            start in -210.0f64..30.0,
            moves in prop::collection::vec(
                prop_oneof![
                    -1e-3f64..1e-3,
                    -0.7f64..0.7,
                    -40.0f64..40.0,
                    (0usize..8).prop_map(|i| i as f64 * 1e9),
                ],
                1..40,
            ),
        ) {
            let points: Vec<f64> = std::iter::once(first)
                .chain(steps.iter().scan(first, |x, d| {
                    *x += d;
                    Some(*x)
                }))
                .collect();
            let table = Table1 {
                values: values[..points.len()].to_vec(),
                grid: crate::model::table::Grid::new(points.clone()).unwrap(),
            };
            let play = WidthTable::new(&table);
            let mut angle = start;
            for m in moves {
                // Large moves land on a grid point (the edges of the cells).
                angle = if m >= 1e9 {
                    points[(m / 1e9) as usize % points.len()]
                } else {
                    angle + m
                };
                let (got, expected) = (play.width(angle), table.eval(angle).0);
                prop_assert_eq!(got.to_bits(), expected.to_bits(), "at {}", angle);
            }
        }

        /// Where [`Segment::sure_flank`] answers, the search answers the same: a motion
        /// without a turning point, its output starting anywhere near the command, the wanted
        /// output near it too (down to the rounding of the breakpoints).
        #[test]
        fn a_sure_flank_is_the_one_the_search_finds(
            near in -350.0f64..350.0,
            start in -1.0f64..1.0,
            half in 0.0f64..0.6,
            wanted in -1.0f64..1.0,
            scale in 0usize..4,
        ) {
            // Offsets down to a few ulps of the angle.
            let shrink = [1.0, 1e-4, 1e-8, 1e-12][scale];
            let segment = Segment {
                start_output: near + start * shrink,
                turn: f64::NAN,
                at: 0.0,
                half,
            };
            let wanted = segment.start_output + wanted * shrink;
            if let Some(d) = segment.sure_flank(wanted, near) {
                prop_assert_eq!(segment.command_for(wanted, near).1, Reach::Flank(d));
            }
        }
    }
}
