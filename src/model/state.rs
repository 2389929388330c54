//! What the error model is evaluated at: the command axis angles, each axis's history (the
//! rotation direction it arrives with and where its gear play stands, see [`AxisHistory`]) and
//! the time since the start of the campaign.

use super::history::AxisHistory;

/// The rotation direction of one axis at a stop: the sign of its last motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Direction {
    /// The last motion went towards smaller angles.
    Negative,
    /// The axis has not moved yet: models use the mean of both branches.
    #[default]
    Unknown,
    /// The last motion went towards larger angles.
    Positive,
}

impl Direction {
    /// +1, −1, or 0 for unknown.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Negative => -1.0,
            Direction::Unknown => 0.0,
            Direction::Positive => 1.0,
        }
    }

    /// The direction of a move by `delta` degrees, keeping `self` when the axis does not move.
    pub fn after_move(self, delta: f64) -> Direction {
        if delta > 0.0 {
            Direction::Positive
        } else if delta < 0.0 {
            Direction::Negative
        } else {
            self
        }
    }

    /// The direction of sign `s` (+1, −1; 0 is unknown).
    pub fn from_sign(s: i32) -> Direction {
        match s.signum() {
            1 => Direction::Positive,
            -1 => Direction::Negative,
            _ => Direction::Unknown,
        }
    }
}

/// The state at which the error model is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct AxisState {
    /// Command angles A1..A6 in degrees (KUKA convention, as on the teach pendant).
    pub axes_deg: [f64; 6],
    /// Each axis's past up to the start of the motion that arrives at `axes_deg`.
    pub history: [AxisHistory; 6],
    /// Seconds since the start of the campaign (the `drift` effect's clock).
    pub time_s: f64,
}

impl AxisState {
    /// A state whose axes have not moved yet (directions unknown).
    pub fn new(axes_deg: [f64; 6]) -> Self {
        AxisState {
            axes_deg,
            history: [AxisHistory::unmoved(); 6],
            time_s: 0.0,
        }
    }

    /// A state reached after long motions in `directions` (the paper's ±1 branches).
    pub fn with_directions(axes_deg: [f64; 6], directions: [Direction; 6]) -> Self {
        AxisState {
            axes_deg,
            history: directions.map(AxisHistory::engaged),
            time_s: 0.0,
        }
    }

    /// The rotation direction of each axis on arrival.
    pub fn directions(&self) -> [Direction; 6] {
        std::array::from_fn(|n| self.history[n].direction(self.axes_deg[n]))
    }

    /// The state of the next stop, at `axes_deg`, reached by a motion that is monotone in
    /// every axis (PTP; Cartesian motions add their turning points with [`Self::then_through`]).
    pub fn then(&self, axes_deg: [f64; 6]) -> AxisState {
        self.then_through(&[f64::NAN; 6], axes_deg)
    }

    /// The state of the next stop, at `axes_deg`, reached by a motion whose axis n turns round
    /// last at command `turns[n]` (NaN: it does not turn round).
    pub fn then_through(&self, turns: &[f64; 6], axes_deg: [f64; 6]) -> AxisState {
        let mut next = *self;
        next.advance_through(turns, axes_deg);
        next
    }

    /// [`Self::then_through`] of `previous`, written into `self` (its old value unread): axis
    /// by axis, not by a copy of the whole 400-byte record first.
    pub fn advance_from(&mut self, previous: &AxisState, turns: &[f64; 6], axes_deg: [f64; 6]) {
        for (n, &turn) in turns.iter().enumerate() {
            self.history[n] = previous.history[n];
            self.history[n].push(previous.axes_deg[n]);
            if turn.is_finite() {
                self.history[n].push(turn);
            }
        }
        self.axes_deg = axes_deg;
        self.time_s = previous.time_s;
    }

    /// Whether `other` is the same state to the bit (every axis's history as
    /// [`AxisHistory::same_bits`] holds it).
    pub fn same_bits(&self, other: &AxisState) -> bool {
        let bits = |a: &[f64; 6], b: &[f64; 6]| (0..6).all(|n| a[n].to_bits() == b[n].to_bits());
        bits(&self.axes_deg, &other.axes_deg)
            && self.time_s.to_bits() == other.time_s.to_bits()
            && (0..6).all(|n| self.history[n].same_bits(&other.history[n]))
    }

    /// [`Self::then_through`] in place (the state is a 400-byte record).
    pub fn advance_through(&mut self, turns: &[f64; 6], axes_deg: [f64; 6]) {
        for (n, &turn) in turns.iter().enumerate() {
            self.history[n].push(self.axes_deg[n]);
            if turn.is_finite() {
                self.history[n].push(turn);
            }
        }
        self.axes_deg = axes_deg;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// [`AxisState::advance_from`] writes the state [`AxisState::then_through`] returns,
        /// whatever the slot held before: histories of any memory, turns or none (NaN).
        #[test]
        fn advancing_from_a_state_is_then_through(
            path in prop::collection::vec(prop::array::uniform6(-3.0f64..3.0), 1..9),
            turns in prop::array::uniform6(prop_oneof![Just(f64::NAN), -3.0f64..3.0]),
            to in prop::array::uniform6(-3.0f64..3.0),
            time_s in 0.0f64..10.0,
            stale in prop::array::uniform6(-3.0f64..3.0),
        ) {
            let mut previous = AxisState::new(path[0]);
            for axes in &path[1..] {
                previous.advance_through(&[f64::NAN; 6], *axes);
            }
            previous.time_s = time_s;
            let mut slot = AxisState::with_directions(stale, [Direction::Negative; 6]);
            slot.advance_from(&previous, &turns, to);
            prop_assert_eq!(slot, previous.then_through(&turns, to));
        }
    }
}
