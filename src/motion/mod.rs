//! Motion simulation: follows a KRL program as the controller does and yields, for every
//! executed motion, its target as a TCP pose in the robot base frame (or an axis set), the
//! nominal axis angles the controller computes for it, and the arrival motion of every axis
//! (from the simulated interpolation), together with where in the source its numbers live.
//! Knows nothing of error models; `compensate` consumes what it yields.

pub mod frame;
pub mod interpolate;
pub mod lu6;
pub mod nominal;
pub mod spline;

// Moved to the KRL front end (`krl::interpret`); named here until the seam's next commit.
pub use crate::krl::interpret as simulate;
pub use crate::krl::interpret::workspace;
pub use crate::krl::interpret::{Assumption, Cell};
pub use simulate::{
    simulate, simulate_streaming, CircularAngle, GivenFrame, Programmed, Rel, Role, RunSink,
    Simulation, Stop, Walked,
};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use simulate::SplineEnds;
pub use workspace::{FileId, Workspace};

/// The commanded axis states of a program run, in execution order: every target's nominal
/// axes with each axis's history as the simulated motion leaves it (rotation direction on
/// arrival, the turning points inside the interpolated motions; see `model::AxisHistory`).
/// Histories start unmoved, and again after a position the simulation could not follow.
pub fn program_states(sim: &Simulation) -> Vec<crate::model::AxisState> {
    let mut previous: Option<crate::model::AxisState> = None;
    sim.stops
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let state = match (s.arrival, &previous) {
                (Some(_), Some(p)) => p.then_through(&s.turns.angle_deg, s.nominal_axes.into()),
                _ => crate::model::AxisState::new(s.nominal_axes.into()),
            };
            if !sim.passes_by(i) {
                previous = Some(state);
            }
            state
        })
        .collect()
}
