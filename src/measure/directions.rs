//! Axis histories over a sequence of stops (CONTRACTS.md): each stop is reached from the one
//! before by a motion monotone in every axis (the rows of a measurement file are the stops
//! the robot visited, approach moves included), so the history of an axis at a stop is its
//! history at the stop before, advanced through that stop's command. The rotation direction
//! of an axis at a stop is then the sign of its motion from the previous stop; an axis that did
//! not move keeps its previous direction; before its first motion it is unknown. Explicit
//! directions (the `dirN` columns) override the inference at their row: the gear is taken as
//! engaged on that flank there, and what follows continues from it.

use crate::model::{AxisHistory, AxisState, Direction};

/// Fills the history of every state from the commands of the states before it, except where
/// `explicit[i][axis]` gives a direction.
pub fn infer_histories(states: &mut [AxisState], explicit: &[[Option<Direction>; 6]]) {
    let mut previous: Option<AxisState> = None;
    for (i, state) in states.iter_mut().enumerate() {
        let mut history = match &previous {
            Some(p) => p.then(state.axes_deg).history,
            None => [AxisHistory::unmoved(); 6],
        };
        for (axis, h) in history.iter_mut().enumerate() {
            if let Some(Some(d)) = explicit.get(i).map(|e| e[axis]) {
                *h = AxisHistory::engaged(d);
            }
        }
        state.history = history;
        previous = Some(*state);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Direction::*;

    fn states(a1: &[f64]) -> Vec<AxisState> {
        a1.iter()
            .map(|&a| AxisState::new([a, 0.0, 0.0, 0.0, 0.0, 0.0]))
            .collect()
    }

    #[test]
    fn sign_of_motion_kept_at_rest_unknown_before_first_move() {
        let mut s = states(&[0.0, 0.0, 1.0, 1.0, 0.5, 0.5, 2.0]);
        infer_histories(&mut s, &[]);
        let d: Vec<_> = s.iter().map(|x| x.directions()[0]).collect();
        assert_eq!(
            d,
            vec![Unknown, Unknown, Positive, Positive, Negative, Negative, Positive]
        );
        // Axes that never move stay unknown.
        assert!(s.iter().all(|x| x.directions()[1] == Unknown));
    }

    #[test]
    fn explicit_direction_overrides_and_seeds() {
        let mut s = states(&[0.0, 0.0, 0.0, 1.0]);
        let mut explicit = vec![[None; 6]; 4];
        explicit[1][0] = Some(Negative);
        infer_histories(&mut s, &explicit);
        let d: Vec<_> = s.iter().map(|x| x.directions()[0]).collect();
        assert_eq!(d, vec![Unknown, Negative, Negative, Positive]);
    }

    #[test]
    fn the_play_follows_the_rows() {
        // Up by 3°, back by 0.004°: inside a play of 0.01°, the output stays where the long
        // motion left it (3 − 0.005), so the lag is −0.005 + 0.004.
        let mut s = states(&[0.0, 3.0, 2.996]);
        infer_histories(&mut s, &[]);
        let b = |_: f64| 0.01;
        let lag = s[2].history[0].play(2.996, b).lag_deg;
        assert!((lag - (-0.001)).abs() < 1e-12, "{lag}");
        assert_eq!(s[2].directions()[0], Negative);
        assert!((s[2].history[0].travel_since_reversal(2.996) - 0.004).abs() < 1e-12);
    }
}
