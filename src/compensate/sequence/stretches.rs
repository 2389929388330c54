//! The re-check (pass 3) of a long sequence in stretches walked beside each other, to the
//! same bits as one walk from the first target to the last.
//!
//! A gear play forgets its past once its axis runs on far enough (or closes a loop: the
//! wiping-out rule of [`AxisHistory`](crate::model::AxisHistory)), so where the walk stands at a target depends, in
//! practice, on a few dozen targets before it. Each stretch but a round's first is walked from
//! a guess — the nominal flanks, as at a program's start — through a warm-up of the targets
//! before it, beside the stretch before, which is walked for real. Once that one is done, its
//! end is compared with the guessed walk at the cut: the states the walk carries and the two
//! outcomes it reads back. Where they agree to the bit, the guessed walk *is* the walk from
//! there on (each step is a function of exactly those and of first-pass outcomes both read
//! alike). Where not, the real walk goes on target by target until it meets the guessed one,
//! and takes the rest from it. A stretch whose guess never meets costs one walk, as before;
//! nothing taken from a guess differs from what one walk gives.
//!
//! A round holds [`Stretching::per_round`] stretches, so that the guessed walks' copies of
//! their outcomes stay small (a window of a streamed program is a round or two).

use super::passes::Signs;
use super::recheck::{Recheck, Span};
use super::timeline::States;
use super::{AxisState, Counts, Ctx, Interp, Outcome, LOOK_BACK};
use std::ops::Range;

/// How the re-check cuts a long sequence into stretches walked beside each other.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stretching {
    /// Targets per stretch.
    pub targets: usize,
    /// Targets a guessed walk settles before its stretch's first (at least [`LOOK_BACK`]).
    pub warm_up: usize,
    /// Stretches per round (the first walked for real, the others guessed beside it).
    pub per_round: usize,
}

impl Stretching {
    /// What a program is compensated with (BENCH.md: the re-check's stretches). Short
    /// stretches: a guess seeded far from the round's start carries more first-pass commands
    /// into the turning points its histories keep, and misses more often; a stretch whose
    /// guess misses is walked again for real, on the critical path. 128 targets with a
    /// warm-up of 16 did the least work of those tried on the sawtooth surfaces (BENCH.md).
    pub const DEFAULT: Stretching = Stretching {
        targets: 128,
        warm_up: 16,
        per_round: 4,
    };
}

impl Default for Stretching {
    fn default() -> Stretching {
        Stretching::DEFAULT
    }
}

/// A guessed walk's stretch, `stretch` (global indices), and what it copied to work on.
struct Guess {
    stretch: Range<usize>,
    /// Global index of the copy's first outcome.
    base: usize,
    /// The first-pass outcomes from `base` to the stretch's end and the target after it (a
    /// circle's auxiliary point looks at its end); the walk settles them in place.
    outcomes: Vec<Outcome>,
}

/// What a guessed walk found for its stretch.
struct Guessed {
    guess: Guess,
    resolved: Vec<bool>,
    /// The state after each target from [`LOOK_BACK`] before the stretch to its end.
    states: Vec<AxisState>,
    /// What each target of the stretch adds to the counts.
    counts: Vec<Counts>,
}

impl Guessed {
    fn outcome(&self, k: usize) -> &Outcome {
        &self.guess.outcomes[k - self.guess.base]
    }

    fn state(&self, k: usize) -> &AxisState {
        &self.states[k + LOOK_BACK - self.guess.stretch.start]
    }

    /// Whether a walk that settled target `k` last — its states in `states`, its outcomes in
    /// `outcomes` — stands where this guessed walk stood after `k`: every later step reads
    /// the same then.
    fn meets(&self, k: usize, states: &States, outcomes: &[Outcome]) -> bool {
        (0..LOOK_BACK).all(|back| {
            let j = k - back;
            states
                .back(back)
                .is_some_and(|s| s.same_bits(self.state(j)))
                && same_bits(&outcomes[j], self.outcome(j))
        })
    }
}

/// Pass 3 of targets from `span.first` on, after the states in `states` (left holding the last
/// ones): see the module documentation.
pub(super) fn recheck(
    ctx: &Recheck,
    states: &mut States,
    span: Span,
    outcomes: &mut [Outcome],
    nominal: &[Signs],
    resolved: &mut [bool],
    stretching: Stretching,
) -> Counts {
    let n = ctx.len();
    // The walks are compared on the states after the two targets before the cut: a guessed
    // walk settles them itself.
    let stretching = Stretching {
        warm_up: stretching.warm_up.max(LOOK_BACK),
        ..stretching
    };
    let mut counts = Counts::default();
    let mut k = span.first;
    while k < n {
        let (first, guesses) = round(ctx, k, stretching);
        let guesses: Vec<Guess> = guesses
            .into_iter()
            .map(|stretch| {
                let base = stretch.start - stretching.warm_up - LOOK_BACK;
                let end = (stretch.end + 1).min(n);
                Guess {
                    stretch,
                    base,
                    outcomes: outcomes[base..end].to_vec(),
                }
            })
            .collect();
        let seeds = seeds(ctx, k, states, outcomes, &guesses);
        let mut found: Vec<Option<Guessed>> = guesses.iter().map(|_| None).collect();
        let (model, tools, targets, method) = (ctx.model, ctx.tools, ctx.targets, ctx.method);
        let h = ctx.history.len();
        rayon::in_place_scope(|scope| {
            for ((slot, guess), seed) in found.iter_mut().zip(guesses).zip(seeds) {
                scope.spawn(move |_| {
                    let local = &targets[guess.base - h..guess.base - h + guess.outcomes.len()];
                    let ctx = Recheck::new(Ctx::new(model, tools, &[], local, method));
                    let nominal = &nominal[guess.base - span.nominal_from..];
                    *slot = Some(walk_guessed(&ctx, guess, seed, nominal, stretching.warm_up));
                });
            }
            counts += span.settle(
                ctx,
                states,
                first,
                outcomes,
                nominal,
                resolved,
                |_, _, _| {},
            );
        });
        for guessed in found.into_iter().flatten() {
            let stretch = guessed.guess.stretch.clone();
            let (adopted, met) = adopt(ctx, span, states, guessed, outcomes, nominal, resolved);
            counts += adopted;
            tracing::trace!(
                ?stretch,
                walked_for_real = met - stretch.start,
                "guessed stretch"
            );
        }
        k = round_end(k, n, stretching);
    }
    counts
}

/// Where the round from target `k` of `n` ends.
fn round_end(k: usize, n: usize, stretching: Stretching) -> usize {
    (k + stretching.targets * stretching.per_round.max(1)).min(n)
}

/// The round from target `k`: the stretch walked for real, and the stretches guessed beside
/// it. A stretch is cut only where a guessed walk can start: after its warm-up and the
/// outcomes it reads back, and not at a circle's end (which settles its auxiliary point, the
/// target before the cut, again).
fn round(ctx: &Recheck, k: usize, stretching: Stretching) -> (Range<usize>, Vec<Range<usize>>) {
    let end = round_end(k, ctx.len(), stretching);
    // A stretch at least as long as a guessed walk's lead, so that the lead lies after `k`.
    let length = stretching.targets.max(stretching.warm_up + LOOK_BACK + 1);
    let mut cuts = Vec::new();
    let mut s = k + length;
    while s < end {
        while s < end && ctx.target(s).interp == Interp::CircEnd {
            s += 1;
        }
        if s < end {
            cuts.push(s);
        }
        s += length;
    }
    let first = k..cuts.first().copied().unwrap_or(end);
    let guessed = cuts
        .iter()
        .enumerate()
        .map(|(i, &s)| s..cuts.get(i + 1).copied().unwrap_or(end))
        .collect();
    (first, guessed)
}

/// The states each guessed walk starts from: the real walk's at the round's start (target
/// `k`), carried to the walk's first target through the first-pass commands and their nominal
/// turns, without settling anything — so that what each axis's history holds from before the
/// round (an axis that has not run far for a long time keeps old turning points) is the real
/// walk's to the bit, and the warm-up only has the recent part to make up.
fn seeds(
    ctx: &Recheck,
    k: usize,
    states: &States,
    outcomes: &[Outcome],
    guesses: &[Guess],
) -> Vec<States> {
    let Some(mut last) = states.back(0).copied() else {
        return guesses.iter().map(|_| States::new(None)).collect();
    };
    let mut j = k;
    guesses
        .iter()
        .map(|g| {
            // The guessed walk settles from the target after its copy's read-only front.
            while j < g.base + LOOK_BACK {
                // In place: a copy of the 400-byte state per target carried cost more than
                // the carrying.
                last.advance_through(&ctx.target(j).turns.angle_deg, *outcomes[j].axes_deg);
                j += 1;
            }
            States::new(Some(last))
        })
        .collect()
}

/// Walks `guess`'s warm-up and stretch from `states` (indices local to its copy, `ctx` its
/// targets from the copy's first).
fn walk_guessed(
    ctx: &Recheck,
    guess: Guess,
    mut states: States,
    nominal: &[Signs],
    warm_up: usize,
) -> Guessed {
    let mut guess = guess;
    let local = |k: usize| k - guess.base;
    let (start, end) = (local(guess.stretch.start), local(guess.stretch.end));
    let mut resolved = vec![false; guess.outcomes.len()];
    let mut kept = Vec::with_capacity(end - start + LOOK_BACK);
    let mut counts = Vec::with_capacity(end - start);
    let span = Span {
        nominal_from: 0,
        first: LOOK_BACK,
    };
    debug_assert_eq!(start, LOOK_BACK + warm_up);
    span.settle(
        ctx,
        &mut states,
        LOOK_BACK..end,
        &mut guess.outcomes,
        nominal,
        &mut resolved,
        |k, states, step| {
            if k + LOOK_BACK >= start {
                kept.extend(states.back(0).copied());
            }
            if k >= start {
                counts.push(step);
            }
        },
    );
    Guessed {
        resolved: resolved[start..end].to_vec(),
        guess,
        states: kept,
        counts,
    }
}

/// Takes what `guessed` found into the real walk, which has settled every target before its
/// stretch: from the cut if the walks meet there, else from where the real walk, going on,
/// meets the guessed one (the whole stretch walked for real if never). Returns the counts of
/// the stretch and where the guessed walk was taken from.
fn adopt(
    ctx: &Recheck,
    span: Span,
    states: &mut States,
    guessed: Guessed,
    outcomes: &mut [Outcome],
    nominal: &[Signs],
    resolved: &mut [bool],
) -> (Counts, usize) {
    let stretch = guessed.guess.stretch.clone();
    let mut counts = Counts::default();
    let mut from = stretch.start;
    while !guessed.meets(from - 1, states, outcomes) {
        if from == stretch.end {
            return (counts, from);
        }
        counts += span.settle_one(ctx, states, from, outcomes, nominal, resolved);
        from += 1;
    }
    for k in from..stretch.end {
        outcomes[k] = *guessed.outcome(k);
        resolved[k] = guessed.resolved[k - stretch.start];
        counts += guessed.counts[k - stretch.start];
    }
    if from < stretch.end {
        let last: Vec<AxisState> = (stretch.end - LOOK_BACK..stretch.end)
            .map(|k| *guessed.state(k))
            .collect();
        *states = States::holding(&last);
    }
    (counts, from)
}

/// Whether two outcomes are the same to the bit.
fn same_bits(a: &Outcome, b: &Outcome) -> bool {
    let bits = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits());
    bits(&a.axes_deg[..], &b.axes_deg[..])
        && bits(a.before.as_slice(), b.before.as_slice())
        && bits(a.residual.as_slice(), b.residual.as_slice())
        && a.directions == b.directions
        && a.nominal_directions == b.nominal_directions
        && a.iterations == b.iterations
        && a.resolution == b.resolution
        && a.error == b.error
        && a.changed == b.changed
        && a.turn_held == b.turn_held
        && a.travels_play == b.travels_play
}
