//! The virtual robot: a truth model, a simulated laser tracker, the measurement campaigns of
//! the paper's section 2.3 and runs of KRL programs, so that identification, compensation and
//! diagnosis can be proven on data whose truth is known. Two kinds of truth: a model truth
//! (`truth`, `virtual_robot`: a calibration file taken as the robot) and a physical one
//! (`physical`: the arm, gears, loads and tracker in physical terms, sharing no code with the
//! model).

pub mod any_truth;
pub mod campaign;
pub mod lab;
pub mod paper;
pub mod physical;
pub mod poses;
pub mod program;
pub mod truth;
pub mod virtual_robot;

pub use any_truth::Truth;
pub use campaign::{Campaign, PlannedStop};
pub use virtual_robot::SimulateError;
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use {
    campaign::paced,
    truth::{TrackerNoise, TruthFile},
    virtual_robot::VirtualRobot,
};
