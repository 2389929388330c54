//! Pass 3, the re-check: walks the compensated commands in order through each axis's history
//! and settles every target against where the compensated motion leaves its plays
//! ([`super::settle`]), on one thread or, for a long sequence on the pool, in stretches
//! ([`super::stretches`]); then completes the commands' TCPs and changes. [`Recheck`] is what
//! the walk reads besides the outcomes: the targets, each axis's width table, the play's
//! output kept from the last evaluation and the turns of the target being settled.

use super::passes::{FirstPasses, Signs};
use super::settle::settle_one;
use super::stretches;
use super::timeline::States;
use super::widths::WidthTable;
use super::{
    correction, Carried, Command, Compensated, Counts, Ctx, Interp, Options, Outcome, Resolution,
    Target, LOOK_BACK,
};
use crate::model::history::PlayBefore;
use crate::model::{AxisState, Model};
use crate::motion::frame::Frame;
use crate::motion::interpolate;
use crate::motion::nominal::{Arm, Nominal};
use std::cell::{Cell, RefCell};

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
    let (counts, states) = recheck(
        &ctx,
        previous,
        h,
        all,
        &nominal_signs,
        &mut resolved,
        options,
    );
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
pub(super) fn complete_commands(
    ctx: &Ctx,
    outcomes: &[Outcome],
    resolved: &[bool],
    commands: &mut [Command],
) {
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

/// The re-check's [`Ctx`], with each axis's play width table and the cells of it looked up
/// recently (the re-check runs on one thread).
pub(super) struct Recheck<'a> {
    pub(super) ctx: Ctx<'a>,
    pub(super) plays: [Option<WidthTable<'a>>; 6],
    /// Per axis, the play's output before the last point of the history evaluated last.
    pub(super) before: [RefCell<PlayBefore>; 6],
    /// The turns of the compensated motion worked out last for the target being settled
    /// ([`compensated_turns`]), cleared as each target's settling starts.
    pub(super) turns: Cell<Option<TurnsKept>>,
}

/// A target's compensated turns kept ([`Recheck::turns`]): settling a target solved again
/// asks for the turns of one command up to three times (the history its prediction is taken
/// with, the next round's check, the state it leaves), each a walk of the interpolated path.
/// Within one target's settling nothing else they read changes (the commands around it, the
/// state it arrives from), so the command, the widths and the arrival are the whole key.
#[derive(Clone, Copy)]
pub(super) struct TurnsKept {
    pub(super) k: usize,
    pub(super) from: [u64; 6],
    pub(super) command: [u64; 6],
    pub(super) widths: [u64; 6],
    pub(super) turns: interpolate::Turns,
}

impl<'a> std::ops::Deref for Recheck<'a> {
    type Target = Ctx<'a>;
    fn deref(&self) -> &Ctx<'a> {
        &self.ctx
    }
}

impl<'a> Recheck<'a> {
    pub(super) fn new(ctx: Ctx<'a>) -> Recheck<'a> {
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
    pub(super) fn play_width(&self, n: usize, angle: f64) -> f64 {
        match &self.plays[n] {
            Some(play) => play.width(angle),
            None => 0.0,
        }
    }

    /// Where axis n's play output stands against the command at `state` (0 without a play).
    pub(super) fn play_lag(&self, state: &AxisState, n: usize) -> f64 {
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

/// Pass 3: walks the compensated commands through each axis's history, re-solving the targets
/// whose gear plays stand otherwise than the flanks they were solved with (see the module
/// documentation). Targets before `from` are settled (history). Returns the counts and the
/// states of the last (up to [`LOOK_BACK`]) targets. A long sequence on the pool is walked in
/// stretches beside each other ([`stretches`]), to the same bits.
pub(super) fn recheck(
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
        stretches::recheck(
            ctx,
            &mut states,
            span,
            outcomes,
            nominal,
            resolved,
            options.stretching,
        )
    } else {
        span.settle(
            ctx,
            &mut states,
            from..ctx.len(),
            outcomes,
            nominal,
            resolved,
            |_, _, _| {},
        )
    };
    // The segment's own (the history's state may still be among them).
    let keep = (ctx.len() - from).min(states.len());
    (
        counts,
        states
            .oldest_first()
            .skip(states.len() - keep)
            .copied()
            .collect(),
    )
}

/// Where a walk of the re-check stands in its sequence: `nominal` holds the signs of the
/// targets from `nominal_from` on, and `first` is the first target it settles (a circle's end
/// there does not settle its auxiliary point again: it lies before the walk).
#[derive(Clone, Copy, Debug)]
pub(super) struct Span {
    pub(super) nominal_from: usize,
    pub(super) first: usize,
}

impl Span {
    /// Settles targets `ks` in order after the states in `states`, telling `each` every target
    /// settled with the states after it and what it adds to the counts.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn settle(
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
    pub(super) fn settle_one(
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
            match nominal
                .get(k.wrapping_sub(self.nominal_from))
                .copied()
                .flatten()
            {
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
                settle_one(
                    ctx,
                    k - 1,
                    aux_rest,
                    Some(before_aux),
                    outcomes,
                    aux_resolved,
                    aux,
                );
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
