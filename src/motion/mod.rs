//! Motion simulation: follows a KRL program as the controller does and yields, for every
//! executed motion, its target as a TCP pose in the robot base frame (or an axis set), the
//! nominal axis angles the controller computes for it, and the arrival motion of every axis
//! (from the simulated interpolation), together with where in the source its numbers live.
//! Knows nothing of error models; `compensate` consumes what it yields.

pub mod frame;
pub mod interpolate;
pub mod nominal;
pub mod simulate;
pub mod value;
pub mod workspace;

pub use simulate::{simulate, GivenFrame, Rel, Role, Simulation, Stop};
pub use workspace::{FileId, Workspace};
