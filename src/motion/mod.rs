//! Motion simulation: follows a KRL program as the controller does and yields, for every
//! executed motion, its target as a TCP pose in the robot base frame (or an axis set), the
//! nominal axis angles the controller computes for it, and the arrival motion of every axis
//! (from the simulated interpolation), together with where in the source its numbers live.
//! Knows nothing of error models; `compensate` consumes what it yields.

pub mod cell;
pub mod frame;
pub mod interpolate;
pub mod lu6;
pub mod nominal;
pub mod simulate;
pub mod spline;
pub mod value;
pub mod workspace;

pub use cell::Cell;
pub use simulate::{
    simulate, simulate_streaming, CircularAngle, GivenFrame, Rel, Role, RunSink, Simulation,
    SplineEnds, Stop, Walked,
};
pub use workspace::{FileId, Workspace};

/// The commanded axis states of a program run, in execution order: every target's nominal
/// axes with the rotation directions the simulated motion arrives with (for a virtual robot
/// that measures the stops of a program). Directions are unknown before an axis first moves
/// and after a position the simulation could not follow.
pub fn program_states(sim: &Simulation) -> Vec<crate::model::AxisState> {
    let mut state = [crate::model::Direction::Unknown; 6];
    sim.stops
        .iter()
        .map(|s| {
            state = match s.arrival {
                None => [crate::model::Direction::Unknown; 6],
                Some(v) => std::array::from_fn(|i| {
                    if v[i].abs() < interpolate::REST_DEG {
                        state[i]
                    } else if v[i] > 0.0 {
                        crate::model::Direction::Positive
                    } else {
                        crate::model::Direction::Negative
                    }
                }),
            };
            crate::model::AxisState {
                axes_deg: s.nominal_axes,
                directions: state,
                time_s: 0.0,
            }
        })
        .collect()
}
