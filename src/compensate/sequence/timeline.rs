//! Where the work of a segment is held: the outcomes of its targets with room in front for the
//! history's ([`Timeline`], written once in place by the first pass), and the states of the
//! last targets the re-check settled, in a ring beside the slot the next one is written into
//! ([`States`]). Both exist so that the 200- and 400-byte records of a million-target
//! program are neither copied nor filled twice.

use super::{Carried, Outcome, LOOK_BACK};
use crate::model::AxisState;
use std::mem::MaybeUninit;

/// A segment's outcomes with [`LOOK_BACK`] slots in front of the targets' for the history's:
/// the re-check reads the history and the targets as one slice, and the targets' outcomes
/// (200-byte records, a million in a CAM program) are written once, in place, by the first
/// passes, never copied behind the history's, nor filled with a placeholder first.
pub(super) struct Timeline {
    pub(super) slots: Vec<Outcome>,
    /// Where the history's outcomes begin (`LOOK_BACK` until [`Self::behind`] puts them in).
    pub(super) first: usize,
}

impl Timeline {
    /// The outcomes of `n` targets, which `solve` writes, every one of them, into the slots it
    /// is given (its panic leaves them unread).
    pub(super) fn solved(n: usize, solve: impl FnOnce(&mut [MaybeUninit<Outcome>])) -> Timeline {
        let mut slots = Vec::with_capacity(LOOK_BACK + n);
        slots.resize(LOOK_BACK, Outcome::placeholder());
        solve(&mut slots.spare_capacity_mut()[..n]);
        // SAFETY: the capacity is LOOK_BACK + n, and `solve` wrote the n slots after the first
        // LOOK_BACK (`solve_chains` visits every slot, and `first_pass` writes its slot before
        // anything else). Filled with a placeholder first instead, every slot cost a 200-byte
        // copy, a percent of a CAM program's CPU time (measured in the commit making this);
        // collected chain by chain and appended, 1.09 % more instructions (BENCH.md, the
        // re-check's third pass).
        unsafe { slots.set_len(LOOK_BACK + n) };
        Timeline {
            slots,
            first: LOOK_BACK,
        }
    }

    pub(super) fn targets(&self) -> &[Outcome] {
        &self.slots[LOOK_BACK..]
    }

    /// Puts the outcomes of `history` (at most [`LOOK_BACK`]) just before the targets': the
    /// slice returned is the history's followed by the targets'.
    pub(super) fn behind(&mut self, history: &[Carried]) -> &mut [Outcome] {
        self.first = LOOK_BACK - history.len();
        for (slot, c) in self.slots[self.first..LOOK_BACK].iter_mut().zip(history) {
            *slot = c.outcome;
        }
        &mut self.slots[self.first..]
    }
}

/// The states of the last (up to [`LOOK_BACK`]) targets settled, in a ring with a slot for
/// the next: the next target's state is written in place beside the ones it needs (they are
/// 400-byte records).
#[derive(Clone)]
pub(super) struct States {
    pub(super) slots: [AxisState; LOOK_BACK + 1],
    /// The slot of the last state.
    pub(super) last: usize,
    /// States held (up to [`LOOK_BACK`]).
    pub(super) len: usize,
}

impl States {
    /// The states after `previous` (the history's last), when there is one.
    pub(super) fn new(previous: Option<AxisState>) -> States {
        let mut slots = [AxisState::default(); LOOK_BACK + 1];
        slots[0] = previous.unwrap_or_default();
        States {
            slots,
            last: 0,
            len: previous.is_some() as usize,
        }
    }

    /// The states a walk left, oldest first (up to [`LOOK_BACK`]).
    pub(super) fn holding(states: &[AxisState]) -> States {
        debug_assert!(states.len() <= LOOK_BACK);
        let mut slots = [AxisState::default(); LOOK_BACK + 1];
        slots[..states.len()].copy_from_slice(states);
        States {
            slots,
            last: states.len().saturating_sub(1),
            len: states.len(),
        }
    }

    #[inline]
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// The state `back` places before the last (0: the last), when held.
    #[inline]
    pub(super) fn back(&self, back: usize) -> Option<&AxisState> {
        (back < self.len).then(|| &self.slots[self.slot(back)])
    }

    /// The slot `back` places before the last.
    #[inline]
    fn slot(&self, back: usize) -> usize {
        (self.last + self.slots.len() - back) % self.slots.len()
    }

    /// The state in slot `from` and the one in slot `into` (another), to write.
    #[inline]
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
    #[inline]
    pub(super) fn last_and_next(&mut self) -> (Option<&AxisState>, &mut AxisState) {
        let (held, next) = (self.len > 0, self.slot(self.slots.len() - 1));
        let (last, next) = self.pair(self.last, next);
        (held.then_some(last), next)
    }

    /// The state before the last and the last, to write (at least two held).
    pub(super) fn before_last_and_last(&mut self) -> (&AxisState, &mut AxisState) {
        debug_assert!(self.len >= 2);
        self.pair(self.slot(1), self.last)
    }

    /// Takes the next slot's state as the last (the oldest beyond [`LOOK_BACK`] let go).
    #[inline]
    pub(super) fn push_next(&mut self) {
        self.last = self.slot(self.slots.len() - 1);
        self.len = (self.len + 1).min(LOOK_BACK);
    }

    /// The states held, oldest first.
    pub(super) fn oldest_first(&self) -> impl Iterator<Item = &AxisState> {
        (0..self.len).rev().map(|back| &self.slots[self.slot(back)])
    }
}
