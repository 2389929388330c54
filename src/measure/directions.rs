//! Rotation-direction inference over a sequence of stops (CONTRACTS.md): the direction of an
//! axis at a stop is the sign of its motion from the previous stop; an axis that did not move
//! keeps its previous direction; before its first motion it is unknown. Explicit directions
//! (the `dirN` columns) override the inference at their row and seed what follows.

use crate::model::{AxisState, Direction};

/// Fills `directions` of every state from the motion between consecutive states, except where
/// `explicit[i][axis]` gives one.
pub fn infer_directions(states: &mut [AxisState], explicit: &[[Option<Direction>; 6]]) {
    let mut current = [Direction::Unknown; 6];
    let mut previous: Option<[f64; 6]> = None;
    for (i, state) in states.iter_mut().enumerate() {
        for axis in 0..6 {
            if let Some(prev) = previous {
                current[axis] = current[axis].after_move(state.axes_deg[axis] - prev[axis]);
            }
            if let Some(Some(d)) = explicit.get(i).map(|e| e[axis]) {
                current[axis] = d;
            }
        }
        state.directions = current;
        previous = Some(state.axes_deg);
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
        infer_directions(&mut s, &[]);
        let d: Vec<_> = s.iter().map(|x| x.directions[0]).collect();
        assert_eq!(
            d,
            vec![Unknown, Unknown, Positive, Positive, Negative, Negative, Positive]
        );
        // Axes that never move stay unknown.
        assert!(s.iter().all(|x| x.directions[1] == Unknown));
    }

    #[test]
    fn explicit_direction_overrides_and_seeds() {
        let mut s = states(&[0.0, 0.0, 0.0, 1.0]);
        let mut explicit = vec![[None; 6]; 4];
        explicit[1][0] = Some(Negative);
        infer_directions(&mut s, &explicit);
        let d: Vec<_> = s.iter().map(|x| x.directions[0]).collect();
        assert_eq!(d, vec![Unknown, Negative, Negative, Positive]);
    }
}
