//! The virtual robot: a truth model, a simulated laser tracker, the measurement campaigns of
//! the paper's section 2.3 and runs of KRL programs, so that identification, compensation and
//! diagnosis can be proven on data whose truth is known.

pub mod campaign;
pub mod paper;
pub mod poses;
pub mod program;
pub mod truth;
pub mod virtual_robot;

pub use campaign::{paced, Campaign, PlannedStop};
pub use truth::{TrackerNoise, TruthFile};
pub use virtual_robot::{SimulateError, VirtualRobot};
