//! One target of the re-check settled: for every axis, the command whose arrival puts the
//! play's output where the pose needs it ([`super::play`]), and where that is not the flank
//! the first pass assumed, the target solved again — on the flank the compensated motion
//! drives, or with the axis held at its command inside the play — until the plays stand where
//! the solve assumed (a few rounds at most, else the round with the smallest predicted error
//! is kept). Also each axis's history on arrival, which the next target starts from.

use super::play::{Reach, Segment};
use super::recheck::Recheck;
use super::solving::{solve_target, tcp_error};
use super::turns::{compensated_turns, SENSITIVE_PLAYS};
use super::{Outcome, Resolution, Target};
use crate::compensate::solve;
use crate::model::{AxisHistory, AxisState, Direction};
use crate::motion::interpolate;

/// Rounds of [`settle_target`] per target before the best is kept.
const SETTLE_ROUNDS: usize = 4;

/// An axis whose output must move by no more than this (degrees) to meet the pose is held
/// still when the program holds it: the solver's own tolerance (0.1 µm at the TCP) moves an
/// axis by up to about this much, and inside the play a command anywhere gives the same
/// output, so a held command that jittered by it would only be noise.
pub const HOLD_DEG: f64 = 1e-5;

/// Settles target `k` in `outcomes`, arriving from `previous` (see [`settle_target`]): solving
/// again moves the compensated path, which may turn an axis round elsewhere, so it is settled
/// until the plays stand where the solve assumed (a few rounds at most), else the round that
/// predicts the smallest error is kept. Writes the state it leaves into `state`; `resolved`
/// is set when it was solved again.
pub(super) fn settle_one(
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
pub(super) fn arrival_histories(
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

/// What [`settle_target`] found.
pub(super) enum Settling {
    /// The plays stand where the solve assumed; the turning points of the compensated motion
    /// into the target when they were worked out (the target's history needs them again).
    Settled(Option<interpolate::Turns>),
    /// To be solved again so.
    Again(Again),
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
pub(super) fn settle_target(
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
pub(super) struct AxesOf<'x, 'a> {
    pub(super) ctx: &'x Recheck<'a>,
    pub(super) k: usize,
    pub(super) target: &'x Target,
    pub(super) p: &'x AxisState,
    pub(super) c: [f64; 6],
    pub(super) widths: [f64; 6],
    pub(super) assumed: [Direction; 6],
    pub(super) outcomes: &'x [Outcome],
}

/// Where an axis's play leaves the first pass's command.
pub(super) enum AxisSettled {
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
    pub(super) fn settle(
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
pub(super) struct Again {
    pub(super) flanks: [Direction; 6],
    pub(super) hold: [bool; 6],
    pub(super) start: [f64; 6],
}

/// Target `k` solved again as [`settle_target`] decided (`again`), its prediction then taken
/// with every play evaluated exactly where the command leaves it.
pub(super) fn solve_again(
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
