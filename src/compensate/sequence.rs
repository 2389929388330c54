//! Compensation of a sequence of targets with the rotation directions of the compensated
//! motion.
//!
//! Directions depend on the previous target, so the work runs in three passes: (1) the
//! nominal directions from the simulated nominal motion (sequential, cheap); (2) every target
//! solved with its nominal directions, in parallel (rayon); (3) a sequential re-check of the
//! directions of the *compensated* motion. An axis whose compensated motion reverses the
//! assumed direction is re-solved on the other backlash branch; when that flips it back again
//! (the axis moves less than the correction difference, e.g. A1 on a vertical segment: the
//! iteration would oscillate between branches with no consistent solution) the target is
//! resolved deliberately by the candidate predicting the smaller error: hold the axis still
//! (its direction then stays the previous one, consistent by construction; the other axes
//! solve the pose in the least-squares sense) or accept one branch and evaluate it with the
//! direction its motion really has.
//!
//! The compensated motion's direction of axis i on arrival at target k is the sign of
//! `v = arrival_i + (c_k,i − c_k−1,i)`, `c = command − nominal`: exact for PTP (interpolated
//! linearly in axis space, `arrival` is the nominal step) and to first order in the
//! correction for LIN/CIRC (whose joint path moves by the interpolated correction).

use nalgebra::{Vector3, Vector6};
use rayon::prelude::*;

use super::solve::{self, weighted_norm, Method, Problem, SolveError};
use crate::kinematics::{status_turn, ArmState};
use crate::model::{Direction, Model};
use crate::motion::frame::{kuka_near, Frame};
use crate::motion::interpolate::{self, Cartesian, Path};
use crate::motion::nominal::{status_turns, Arm, Nominal};

pub use crate::motion::interpolate::REST_DEG;

/// Status bits a target must keep after compensation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Keep {
    /// The configuration S (Cartesian targets; the controller's IK chooses the branch by it).
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
    pub nominal_axes: [f64; 6],
    /// Nominal motion of each axis on arrival, deg per segment (the step for PTP, the arrival
    /// velocity `dq/du` at the end for LIN/CIRC; 0 when the axis rests); `None` when the
    /// motion comes from an unknown place (first motion, unresolved target before).
    pub arrival: Option<[f64; 6]>,
    /// How the controller interpolates the motion reaching it.
    pub interp: Interp,
    /// How its command will be written (rounded), when it is written: the directions of the
    /// compensated motion are those of the rounded commands.
    pub quantum: Option<Quantum>,
    /// Whether to compensate (false: the target still moves the robot, its command stays).
    pub compensate: bool,
    pub keep: Keep,
}

/// The rounding of a written command: decimals of `X Y Z A B C` in the base (index into the
/// frame table), or of `A1..A6`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quantum {
    pub base: u32,
    pub axis: bool,
    pub decimals: [u8; 6],
}

fn round_to(v: f64, decimals: u8) -> f64 {
    let scale = ten_to(decimals as usize);
    (v * scale).round() / scale
}

/// `10f64.powi(decimals)`, from a table where that is exact (10^22 = 2^22·5^22 and 5^22 <
/// 2^53: every power up to it is a double, and so is every product `powi` forms on the way).
pub(super) fn ten_to(decimals: usize) -> f64 {
    const TABLE: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    match TABLE.get(decimals) {
        Some(&p) => p,
        None => 10f64.powi(decimals as i32),
    }
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

/// How a target's directions were settled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Resolution {
    /// The nominal directions held for the compensated motion.
    #[default]
    Consistent,
    /// Some axis's direction came out reversed; re-solved on that branch, which is consistent.
    Rebranched,
    /// Oscillation between branches: these axes were held still.
    Held([bool; 6]),
    /// Oscillation between branches: one branch accepted (it predicted the smaller error).
    Branch,
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
    pub axes_deg: [f64; 6],
    /// Directions of the commanded motion on arrival.
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
            axes_deg: axes,
            directions,
            nominal_directions: directions,
            before: Vector6::zeros(),
            residual: Vector6::zeros(),
            iterations: 0,
            resolution: Resolution::Consistent,
            error: None,
            changed: false,
            turn_held: [false; 6],
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
}

/// Targets per chunk of the parallel arrival-rate pass.
const RATE_CHUNK: usize = 1024;

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

/// The direction state after arriving with motion `v` from state `before`.
fn arrive(before: &[Direction; 6], v: Option<[f64; 6]>) -> [Direction; 6] {
    arrive_signs(before, signs(v))
}

/// [`arrive`] from the motion's [`signs`].
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
    /// `tcp` in the target's base frame as [`Frame::to_kuka_unchosen`] gives it, when the
    /// re-check worked it out (a Cartesian target it did not re-solve): the rewrite chooses
    /// its Euler triple from this instead of converting the matrix again.
    pub unchosen: Option<[f64; 6]>,
}

/// The command change at the TCP, µm and mdeg: the nominal TCP of the new command against
/// that of the controller's axes for the programmed target.
pub fn correction(command_tcp: &Frame, nominal_tcp: &Frame) -> (f64, f64) {
    let (cp, cr) =
        crate::motion::frame::norms(&crate::motion::frame::error(command_tcp, nominal_tcp));
    (cp * 1e3, cr.to_degrees() * 1e3)
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
    /// Per target, its command's TCP (computed once, by the arrival-rate pass) and change.
    pub commands: Vec<Command>,
}

impl Compensated {
    /// The outcomes of the targets.
    pub fn targets(&self) -> &[Outcome] {
        &self.outcomes[self.history..]
    }
}

/// Compensates `targets` (tools indexed by `Target::tool`), directions before the first
/// target given by `start`.
pub fn compensate(
    model: &Model,
    tools: &[Frame],
    targets: &[Target],
    start: [Direction; 6],
    options: &Options,
) -> Vec<Outcome> {
    let mut done = compensate_after(model, tools, &[], targets, start, options);
    done.outcomes.drain(..done.history);
    done.outcomes
}

/// How far back the re-check of a target looks: its arrival depends on the commands of the
/// two targets before it (the start and auxiliary point of a circle).
pub const LOOK_BACK: usize = 2;

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
    settle(model, tools, history, targets, start, first, options)
}

/// Passes 1 and 2 of a segment: what needs nothing of the targets before it but the nominal
/// directions they leave (`nominal_start`), so it may run while the segment before is still
/// being settled ([`settle`]).
pub struct FirstPasses {
    /// `LOOK_BACK` slots for the history's outcomes (filled by [`settle`]), then the targets'.
    outcomes: Vec<Outcome>,
    nominal_signs: Vec<Signs>,
    /// Signs of the first-pass arrival motions; those of the first [`LOOK_BACK`] targets
    /// depend on the history's commands and are left to [`settle`].
    rates: Vec<Signs>,
    /// The unrounded TCP of every first-pass command, and its pose in the base frame before
    /// the choice of Euler triple (see [`Command::unchosen`]); [`settle`] completes them in
    /// place.
    commands: Vec<Command>,
}

impl FirstPasses {
    /// The nominal directions after the segment (the next segment's `nominal_start`).
    pub fn nominal_end(&self) -> Option<[Direction; 6]> {
        self.outcomes[LOOK_BACK..]
            .last()
            .map(|o| o.nominal_directions)
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
    // The nominal motions' signs in parallel (the re-check needs them again), their
    // directions in order.
    let nominal_signs: Vec<Signs> = if options.parallel {
        targets
            .par_iter()
            .with_min_len(1024)
            .map(|t| signs(t.arrival))
            .collect()
    } else {
        targets.iter().map(|t| signs(t.arrival)).collect()
    };
    let nominal = directions_after(&nominal_signs, nominal_start);
    // The chains of these targets, each worked in order, the first continuing the open one.
    // Each chain writes its outcomes in place, after `LOOK_BACK` slots left for the history
    // (`settle`): collected per chain and joined, the 208-byte outcomes were copied twice.
    let n = targets.len();
    let head = (CHAIN - (chains.ordinal % CHAIN as u64) as usize) % CHAIN;
    let head = head.min(n);
    let mut outcomes = vec![Outcome::placeholder(); LOOK_BACK + n];
    let (head_slots, rest) = outcomes[LOOK_BACK..].split_at_mut(head);
    let work = |from: usize, slots: &mut [Outcome], mut chain: solve::Chain| -> solve::Chain {
        for (k, slot) in slots.iter_mut().enumerate() {
            let i = from + k;
            first_pass(
                model,
                tools,
                &targets[i],
                &nominal[i],
                options.method,
                Some(&mut chain),
                slot,
            );
        }
        chain
    };
    let fresh = |(p, slots): (usize, &mut [Outcome])| {
        work(head + p * CHAIN, slots, solve::Chain::default())
    };
    let continued = chains.open;
    // The chain continued from the segment before runs beside the fresh ones.
    let (open, last): (solve::Chain, Option<solve::Chain>) = if options.parallel {
        rayon::join(
            || work(0, head_slots, continued),
            || {
                let ends: Vec<solve::Chain> =
                    rest.par_chunks_mut(CHAIN).enumerate().map(fresh).collect();
                ends.last().copied()
            },
        )
    } else {
        (
            work(0, head_slots, continued),
            rest.chunks_mut(CHAIN).enumerate().map(fresh).last(),
        )
    };
    chains.open = last.unwrap_or(open);
    chains.ordinal += n as u64;
    let solved = &outcomes[LOOK_BACK..];
    // The segment alone: target k of the segment is k here.
    let ctx = Ctx {
        model,
        tools,
        history: &[],
        targets,
        method: options.method,
    };
    // Arrival motions of the first-pass commands, chunk by chunk: each rate needs its
    // neighbours' written TCPs, computed once per chunk (plus the few around its ends), and
    // the re-check needs only the signs. The chain is evaluated once per target: its TCP
    // (kept for the rewrite) and, for a Cartesian arrival, its Jacobian. Each chunk writes
    // its signs and TCPs in place.
    let cmd = |j: usize| solved[j].axes_deg;
    let chunk = |(c, (rates, placings)): (usize, (&mut [Signs], &mut [Command]))| {
        let (a, b) = (c * RATE_CHUNK, ((c + 1) * RATE_CHUNK).min(n));
        let from = a.saturating_sub(2);
        let mut arms: Vec<Option<ArmState>> = Vec::with_capacity(b - a);
        for (k, placing) in (a..b).zip(placings.iter_mut()) {
            let (tcp, arm) = ctx.forward(k, &solved[k].axes_deg);
            placing.tcp = tcp;
            arms.push(arm);
        }
        let tcps: Vec<Frame> = (from..(b + 1).min(n))
            .map(
                |k| match k.checked_sub(a).and_then(|i| placings.get_mut(i)) {
                    Some(placing) => {
                        let raw = placing.tcp;
                        let (written, u) = ctx.written_keeping(k, &solved[k].axes_deg, || raw);
                        placing.unchosen = u;
                        written
                    }
                    None => ctx.tcp(k, &solved[k].axes_deg),
                },
            )
            .collect();
        for ((k, sign), jacobian) in (a..b).zip(rates.iter_mut()).zip(&arms) {
            if k >= LOOK_BACK {
                let cache = Some((from, &tcps[..]));
                let rate = ctx.rate(k, &solved[k].axes_deg, &cmd, cache, jacobian.as_ref());
                *sign = signs(rate);
            }
        }
    };
    let mut rates: Vec<Signs> = vec![None; n];
    let blank = Command {
        tcp: Frame::identity(),
        correction: (0.0, 0.0),
        unchosen: None,
    };
    let mut tcps: Vec<Command> = vec![blank; n];
    if options.parallel {
        rates
            .par_chunks_mut(RATE_CHUNK)
            .zip(tcps.par_chunks_mut(RATE_CHUNK))
            .enumerate()
            .for_each(chunk);
    } else {
        rates
            .chunks_mut(RATE_CHUNK)
            .zip(tcps.chunks_mut(RATE_CHUNK))
            .enumerate()
            .for_each(chunk);
    }
    FirstPasses {
        outcomes,
        nominal_signs,
        rates,
        commands: tcps,
    }
}

/// Pass 3 of `targets` after the carried `history` (see [`compensate_after`]), from their
/// [`first_passes`], and the commands' TCPs.
pub fn settle(
    model: &Model,
    tools: &[Frame],
    history: &[Carried],
    targets: &[Target],
    start: [Direction; 6],
    first: FirstPasses,
    options: &Options,
) -> Compensated {
    // The re-check looks back `LOOK_BACK` targets: older history is not needed.
    let history = &history[history.len().saturating_sub(LOOK_BACK)..];
    let h = history.len();
    let state_start = match history.last() {
        Some(c) => c.outcome.directions,
        None => start,
    };
    // The history's outcomes go into the slots left before the targets' (no copy of these),
    // the unused slots first: `all[pad..]` is the history followed by the targets.
    let mut all = first.outcomes;
    let pad = LOOK_BACK - h;
    for (slot, c) in all[pad..pad + h].iter_mut().zip(history) {
        *slot = c.outcome;
    }
    let outcomes = &mut all[pad..];
    let ctx = Ctx {
        model,
        tools,
        history,
        targets,
        method: options.method,
    };
    let mut resolved: Vec<bool> = history.iter().map(|c| c.resolved).collect();
    resolved.resize(h + targets.len(), false);
    recheck(
        &ctx,
        state_start,
        h,
        outcomes,
        (&first.nominal_signs, &first.rates),
        &mut resolved,
    );
    // The commands' changes at the TCP, the command of a target the re-check re-solved anew.
    // The nominal command's TCP is the goal: the walk solved the command for it (an axis
    // target's goal is its nominal TCP).
    let arm = Nominal(&model.robot);
    let complete = |(i, c): (usize, &mut Command)| {
        let (k, t) = (h + i, &targets[i]);
        let o = &outcomes[k];
        if resolved[k] {
            c.tcp = arm.tcp(&o.axes_deg, ctx.tool(k));
            c.unchosen = None;
        }
        if o.changed {
            c.correction = correction(&c.tcp, &t.goal);
        }
    };
    let mut commands = first.commands;
    if options.parallel {
        commands
            .par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(complete);
    } else {
        commands.iter_mut().enumerate().for_each(complete);
    }
    resolved.drain(..h);
    Compensated {
        outcomes: all,
        history: pad + h,
        resolved,
        commands,
    }
}

fn tcp_error(
    model: &Model,
    tool: &Frame,
    axes: &[f64; 6],
    dirs: &[Direction; 6],
    goal: &Frame,
) -> Vector6<f64> {
    solve::predicted_error(model, dirs, axes, tool, goal)
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
    directions: &[Direction; 6],
    start: [f64; 6],
    hold: [bool; 6],
    method: Method,
    chain: Option<&mut solve::Chain>,
) -> Result<(solve::Solution, [bool; 6]), TargetError> {
    // Equation (3) is taken at the programmed (nominal) command, whatever the start.
    let start = if method == Method::OneStep && !hold.iter().any(|&h| h) {
        target.nominal_axes
    } else {
        start
    };
    let problem = Problem {
        goal: target.goal,
        tool,
        start,
        directions: *directions,
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
            match solve::solve_in_chain(model, &problem, chain) {
                Ok(s) => s,
                Err(e) if near_singular() => *e.best,
                Err(e) => return Err(e.into()),
            }
        }
        _ => solve_or_best(&problem, method)?,
    };
    let mut turn_held = [false; 6];
    let ((s0, t0), (mut s1, mut t1)) = status_turns(robot, &target.nominal_axes, &sol.axes_deg);
    if target.keep.t && t0 != t1 && s0 == s1 {
        let mut start = sol.axes_deg;
        let mut hold = hold;
        for i in 0..6 {
            if (t0 ^ t1) >> i & 1 == 1 {
                turn_held[i] = true;
                hold[i] = true;
                start[i] = if t0 >> i & 1 == 1 { -1e-9 } else { 0.0 };
            }
        }
        let retry = Problem {
            start,
            hold,
            ..problem
        };
        sol = solve_or_best(&retry, Method::Iterate)?;
        (s1, t1) = status_turn(robot, &sol.axes_deg);
    }
    for (n, (a, [lo, hi])) in sol.axes_deg.iter().zip(robot.limits_deg.iter()).enumerate() {
        if a < lo || a > hi {
            return Err(TargetError::OutOfLimits {
                axis: n as u8 + 1,
                value: *a,
                lo: *lo,
                hi: *hi,
            });
        }
    }
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
    Ok((sol, turn_held))
}

fn first_pass(
    model: &Model,
    tools: &[Frame],
    target: &Target,
    directions: &[Direction; 6],
    method: Method,
    mut chain: Option<&mut solve::Chain>,
    out: &mut Outcome,
) {
    let tool = &tools[target.tool as usize];
    if let Some(c) = chain.as_deref_mut() {
        c.follow_tool(target.tool);
    }
    *out = Outcome::unsolved(target.nominal_axes, *directions);
    if !target.compensate {
        if let Some(c) = chain {
            c.forget();
        }
        out.before = tcp_error(model, tool, &target.nominal_axes, directions, &target.goal);
        out.residual = out.before;
        return;
    }
    let solved = solve_target(
        model,
        tool,
        target,
        directions,
        target.nominal_axes,
        [false; 6],
        method,
        chain.as_deref_mut(),
    );
    if let Some(c) = chain {
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
            out.axes_deg = sol.axes_deg;
            out.residual = sol.residual;
            out.iterations = sol.iterations;
            out.turn_held = turn_held;
            // The error at the nominal command (the start, unless a turn was kept by holding).
            out.before = if turn_held.iter().any(|&h| h) {
                tcp_error(model, tool, &target.nominal_axes, directions, &target.goal)
            } else {
                sol.initial
            };
        }
        Err(e) => {
            out.error = Some(e);
            out.before = tcp_error(model, tool, &target.nominal_axes, directions, &target.goal);
            out.residual = out.before;
        }
    }
}

/// What the re-check needs besides the outcomes: the targets are the history's followed by
/// the segment's (indexed as the outcomes are).
struct Ctx<'a> {
    model: &'a Model,
    tools: &'a [Frame],
    history: &'a [Carried],
    targets: &'a [Target],
    method: Method,
}

impl Ctx<'_> {
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

    /// The TCP commanded at target `k` with `axes`, as written (rounded) when it is written.
    fn tcp(&self, k: usize, axes: &[f64; 6]) -> Frame {
        self.written(k, axes, || self.forward(k, axes).0)
    }

    /// [`Self::tcp`] given the unrounded TCP of `axes`, `raw` (not called for axis commands:
    /// they are written as rounded axes).
    fn written(&self, k: usize, axes: &[f64; 6], raw: impl FnOnce() -> Frame) -> Frame {
        self.written_keeping(k, axes, raw).0
    }

    /// [`Self::written`] and, for a Cartesian target, the unrounded pose in its base frame
    /// before the choice of Euler triple ([`Frame::to_kuka_unchosen`]), which the rewrite
    /// writes near the original numbers.
    fn written_keeping(
        &self,
        k: usize,
        axes: &[f64; 6],
        raw: impl FnOnce() -> Frame,
    ) -> (Frame, Option<[f64; 6]>) {
        match self.target(k).quantum {
            Some(q) if q.axis => {
                let r: [f64; 6] = std::array::from_fn(|i| round_to(axes[i], q.decimals[i]));
                (Nominal(&self.model.robot).tcp(&r, self.tool(k)), None)
            }
            Some(q) => {
                let base = &self.tools[q.base as usize];
                let in_base = base.inverse().compose(&raw());
                let unchosen = in_base.to_kuka_unchosen();
                let p = match &unchosen {
                    Some(u) => kuka_near(u, &[0.0; 3]),
                    None => in_base.to_kuka_near(&[0.0; 3]),
                };
                let r: [f64; 6] = std::array::from_fn(|i| round_to(p[i], q.decimals[i]));
                (base.compose(&Frame::from_kuka(&r)), unchosen)
            }
            None => (raw(), None),
        }
    }

    /// The nominal TCP of `axes` at target `k` and, when its arrival rate needs them (a
    /// Cartesian interpolation), the arm's axis lines there — what `motion::interpolate`
    /// solves the nominal arrival with, so both are computed alike.
    fn forward(&self, k: usize, axes: &[f64; 6]) -> (Frame, Option<ArmState>) {
        let t = self.target(k);
        let tool = self.tool(k);
        // Not on the target's place in the sequence: a target's TCP comes from the same
        // evaluation whichever segment it falls in (windowed = whole, to the bit).
        if t.arrival.is_some() && t.interp != Interp::Joint {
            let arm = ArmState::new(&self.model.robot, axes);
            (
                crate::motion::interpolate::tcp_of_arm(&arm, tool),
                Some(arm),
            )
        } else {
            (Nominal(&self.model.robot).tcp(axes, tool), None)
        }
    }

    /// How the commanded motion arrives at target `k` commanded at `axes`, the other targets
    /// at `cmd(j)`: the controller's interpolation between the commands, exactly as
    /// `motion::interpolate` computes the nominal arrival (`dq/du` at the end).
    fn rate(
        &self,
        k: usize,
        axes: &[f64; 6],
        cmd: &dyn Fn(usize) -> [f64; 6],
        cache: Option<(usize, &[Frame])>,
        arm: Option<&ArmState>,
    ) -> Option<[f64; 6]> {
        let t = self.target(k);
        let nominal = t.arrival?;
        if k == 0 {
            return Some(nominal);
        }
        // The written (rounded) TCP of target j: from the cache of first-pass commands, or
        // computed (target k itself is evaluated at `axes`).
        let tcp = |j: usize| match cache {
            Some((from, c)) => c[j - from],
            None if j == k => self.tcp(k, axes),
            None => self.tcp(j, &cmd(j)),
        };
        let prev = cmd(k - 1);
        let step: [f64; 6] = std::array::from_fn(|i| axes[i] - prev[i]);
        let twist = match t.interp {
            Interp::Joint => return Some(step),
            Interp::Line => {
                let (a, b) = (tcp(k - 1), tcp(k));
                let w = crate::motion::frame::log_so3(&(b.rotation * a.rotation.transpose()));
                let v = b.position - a.position;
                nalgebra::Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
            }
            Interp::Curve { first, last } => {
                // The spline through the written TCPs around it, as `motion::simulate` builds
                // it from the programmed ones.
                let (a, b) = (tcp(k - 1), tcp(k));
                let mut p = [Vector3::zeros(); 4];
                let mut n = 0;
                if !first && k >= 2 {
                    p[0] = tcp(k - 2).position;
                    n = 1;
                }
                p[n] = a.position;
                p[n + 1] = b.position;
                let at = n + 1;
                n += 2;
                if !last && k + 1 < self.len() {
                    // The next point moved by this one's correction: the re-check runs
                    // forward, the next command is not settled yet (and the correction varies
                    // slowly along a dense spline).
                    let shift = b.position - t.goal.position;
                    p[n] = self.target(k + 1).goal.position + shift;
                    n += 1;
                }
                let v =
                    crate::motion::spline::tangents(&p[..n])[at] * (b.position - a.position).norm();
                let w = crate::motion::frame::log_so3(&(b.rotation * a.rotation.transpose()));
                nalgebra::Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
            }
            Interp::CircEnd if k >= 2 => {
                let (start, aux, end) = (tcp(k - 2), tcp(k - 1).position, tcp(k));
                match Cartesian::new(&start, &end, &Path::Circ { aux }) {
                    Ok(c) => c.twist(1.0),
                    Err(_) => return Some(step),
                }
            }
            Interp::CircAngle(a) if k >= 2 => {
                let (start, aux, end) = (tcp(k - 2), tcp(k - 1).position, tcp(k));
                match interpolate::circle_by_angle(&start, &end, a.degrees(), a.plane(aux)) {
                    Some(c) => c.twist(1.0),
                    None => return Some(step),
                }
            }
            Interp::CircAngleAux => return Some(nominal),
            Interp::CircAux if k + 1 < self.len() => {
                let (start, aux, end) = (tcp(k - 1), tcp(k).position, tcp(k + 1));
                match Cartesian::new(&start, &end, &Path::Circ { aux }) {
                    Ok(c) => {
                        let u = c.fraction_at(&aux);
                        c.twist(u) * u
                    }
                    Err(_) => return Some(step),
                }
            }
            _ => return Some(step),
        };
        let computed;
        let arm = match arm {
            Some(arm) => arm,
            None => {
                computed = ArmState::new(&self.model.robot, axes);
                &computed
            }
        };
        let p = crate::motion::interpolate::tcp_of_arm(arm, self.tool(k)).position;
        let (v, w) = (twist.fixed_rows::<3>(0), twist.fixed_rows::<3>(3));
        let rate = arm.rates(&p, &v.into_owned(), &w.into_owned());
        Some(std::array::from_fn(|i| match rate {
            Some(r) if r[i].is_finite() && r[i].abs() >= REST_DEG => r[i],
            // A turning point right at the target: the sign of the whole step.
            _ => step[i],
        }))
    }
}

/// Pass 3: walks the compensated motion, re-solving targets whose directions differ from those
/// they were solved with. `rates[k]` is the arrival motion's signs at k with the first-pass
/// commands; it is recomputed when a command it depends on changed since; `nominal[k]` the
/// nominal motion's. Targets before `from` are settled (history); `rates[k - from]`.
fn recheck(
    ctx: &Ctx,
    start: [Direction; 6],
    from: usize,
    outcomes: &mut [Outcome],
    (nominal, rates): (&[Signs], &[Signs]),
    resolved: &mut [bool],
) {
    let mut state = start;
    let (mut n_expected, mut n_actual) = (0usize, 0usize);
    for k in from..ctx.len() {
        let target = ctx.target(k);
        let tool = ctx.tool(k);
        let fixed = !target.compensate || outcomes[k].error.is_some();
        // The nominal motion's signs, but resting axes keep the *compensated* state: after an
        // earlier flip this differs from the nominal directions the first pass assumed.
        let expected = arrive_signs(&state, nominal[k - from]);
        if expected != outcomes[k].directions && !fixed {
            let mut o = Outcome::placeholder();
            first_pass(
                ctx.model, ctx.tools, target, &expected, ctx.method, None, &mut o,
            );
            o.nominal_directions = outcomes[k].nominal_directions;
            outcomes[k] = o;
            resolved[k] = true;
            n_expected += 1;
        }
        // The first targets' arrivals depend on the history's commands (see `first_passes`).
        let stale = k - from < LOOK_BACK
            || resolved[k]
            || (k >= 1 && resolved[k - 1])
            || (k >= 2 && resolved[k - 2]);
        let rate = if stale {
            let snapshot = |j: usize| outcomes[j].axes_deg;
            signs(ctx.rate(k, &outcomes[k].axes_deg, &snapshot, None, None))
        } else {
            rates[k - from]
        };
        let actual = arrive_signs(&state, rate);
        if actual != outcomes[k].directions {
            n_actual += 1;
            outcomes[k] = if fixed || outcomes[k].error.is_some() {
                // The command is the nominal one: only the prediction changes.
                let mut o = outcomes[k];
                o.directions = actual;
                o.before = tcp_error(ctx.model, tool, &target.nominal_axes, &actual, &target.goal);
                o.residual = o.before;
                o
            } else {
                resolved[k] = true;
                resettle(ctx, k, outcomes, &state, actual)
            };
        }
        state = outcomes[k].directions;
    }
    RESOLVED[0].fetch_add(n_expected, std::sync::atomic::Ordering::Relaxed);
    RESOLVED[1].fetch_add(n_actual, std::sync::atomic::Ordering::Relaxed);
}

/// Targets re-solved for the compensated state and for the compensated motion, since the
/// process started (what `ROBOPOST_TIMING` prints).
static RESOLVED: [std::sync::atomic::AtomicUsize; 2] = [
    std::sync::atomic::AtomicUsize::new(0),
    std::sync::atomic::AtomicUsize::new(0),
];

/// The two counts of `RESOLVED`.
pub fn resolved_counts() -> (usize, usize) {
    use std::sync::atomic::Ordering::Relaxed;
    (RESOLVED[0].load(Relaxed), RESOLVED[1].load(Relaxed))
}

/// Candidate command of a target with its true directions and predicted error.
struct Candidate {
    axes: [f64; 6],
    directions: [Direction; 6],
    error: Vector6<f64>,
    iterations: u32,
    resolution: Resolution,
}

/// Re-solves target k whose compensated motion arrives with `actual` directions instead of the
/// ones it was solved with.
fn resettle(
    ctx: &Ctx,
    k: usize,
    outcomes: &[Outcome],
    state: &[Direction; 6],
    actual: [Direction; 6],
) -> Outcome {
    let (model, method) = (ctx.model, ctx.method);
    let target = ctx.target(k);
    let tool = ctx.tool(k);
    let first = &outcomes[k];
    let cmd = |j: usize| outcomes[j].axes_deg;
    let directions_at = |axes: &[f64; 6]| arrive(state, ctx.rate(k, axes, &cmd, None, None));
    let mut out = *first;
    // The first solution, evaluated with the direction its motion really has.
    let mut candidates = vec![Candidate {
        axes: first.axes_deg,
        directions: actual,
        error: tcp_error(model, tool, &first.axes_deg, &actual, &target.goal),
        iterations: first.iterations,
        resolution: Resolution::Branch,
    }];
    let mut oscillating = [false; 6];
    match solve_target(
        model,
        tool,
        target,
        &actual,
        first.axes_deg,
        [false; 6],
        method,
        None,
    ) {
        Ok((sol, turn_held)) => {
            let again = directions_at(&sol.axes_deg);
            if again == actual {
                out.axes_deg = sol.axes_deg;
                out.directions = actual;
                out.residual = sol.residual;
                out.iterations += sol.iterations;
                out.resolution = Resolution::Rebranched;
                out.changed = sol.axes_deg != target.nominal_axes;
                out.turn_held = turn_held;
                return out;
            }
            for i in 0..6 {
                oscillating[i] = again[i] != actual[i];
            }
            candidates.push(Candidate {
                axes: sol.axes_deg,
                directions: again,
                error: tcp_error(model, tool, &sol.axes_deg, &again, &target.goal),
                iterations: sol.iterations,
                resolution: Resolution::Branch,
            });
        }
        Err(_) => {
            for i in 0..6 {
                oscillating[i] = actual[i] != first.directions[i];
            }
        }
    }
    // Hold the oscillating axes still — the same command as at the previous target — so that
    // they rest and keep `state` (exactly for PTP; along a Cartesian path up to the path's
    // own second-order motion, which the evaluation below takes into account).
    if k > 0 && target.arrival.is_some() && oscillating.iter().any(|&o| o) {
        let mut start = first.axes_deg;
        let prev = cmd(k - 1);
        let mut dirs = actual;
        for i in 0..6 {
            if oscillating[i] {
                start[i] = prev[i];
                dirs[i] = state[i];
            }
        }
        if let Ok((sol, _)) =
            solve_target(model, tool, target, &dirs, start, oscillating, method, None)
        {
            let really = directions_at(&sol.axes_deg);
            candidates.push(Candidate {
                axes: sol.axes_deg,
                directions: really,
                error: tcp_error(model, tool, &sol.axes_deg, &really, &target.goal),
                iterations: sol.iterations,
                resolution: Resolution::Held(oscillating),
            });
            // Along a Cartesian path a held axis still moves by the path's own second-order
            // motion, which may flip its branch after all: then let the other axes make up
            // for the branch it really arrives on (solved again with those directions).
            if really != dirs {
                if let Ok((again, _)) = solve_target(
                    model,
                    tool,
                    target,
                    &really,
                    sol.axes_deg,
                    oscillating,
                    method,
                    None,
                ) {
                    let really_again = directions_at(&again.axes_deg);
                    candidates.push(Candidate {
                        axes: again.axes_deg,
                        directions: really_again,
                        error: tcp_error(model, tool, &again.axes_deg, &really_again, &target.goal),
                        iterations: sol.iterations + again.iterations,
                        resolution: Resolution::Held(oscillating),
                    });
                }
            }
        }
    }
    let best = candidates
        .into_iter()
        .min_by(|a, b| weighted_norm(&a.error).total_cmp(&weighted_norm(&b.error)))
        .expect("the first solution is always a candidate");
    out.axes_deg = best.axes;
    out.directions = best.directions;
    out.residual = best.error;
    out.iterations += best.iterations;
    out.resolution = best.resolution;
    out.changed = best.axes != target.nominal_axes;
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn powers_of_ten_from_the_table_are_powi() {
        for d in 0..40 {
            assert_eq!(
                super::ten_to(d).to_bits(),
                10f64.powi(d as i32).to_bits(),
                "10^{d}"
            );
        }
    }
}
