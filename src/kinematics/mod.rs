//! Nominal kinematics of a KUKA six-axis arm as the controller sees it: poses in the KUKA
//! X/Y/Z/A/B/C convention, the robot description as plain data, forward kinematics (a pure
//! function), the S/T configuration bits, singularity distances, and closed-form inverse
//! kinematics with every branch and the controller's ways of choosing one. Knows nothing of
//! KRL syntax nor of error models. Its words: [`AxisAngles`] are the six axis angles, never a
//! pose; a [`Pose`] is the KUKA record a user writes (X, Y, Z, A, B, C), read and written at
//! the edges; a rigid transform is a [`Frame`] (rotation matrix + position) here and
//! downstream: FK gives one, IK takes one, the error model's flange is one, motion composes
//! them.

mod branches;
pub mod fk;
pub mod frame;
pub mod ik;
pub mod pose;
mod rates;
pub mod robot;
pub mod trig;
mod turns;

pub use fk::{flange_frame, forward, singularity, status_turn, Singularity};
pub use frame::Frame;
pub use ik::{inverse, inverse_all, IkError, IkSolution, Select};
pub use pose::{abc_to_matrix, matrix_to_abc, AxisAngles, Pose};
pub use rates::ArmState;
pub use robot::{Links, Payload, RobotDescription};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use {
    fk::{
        singularity_distances, singularity_with, wrist_point, SingularityKind,
        SingularityThresholds,
    },
    ik::inverse_all_into,
    pose::{E6Axis, E6Pos},
    robot::Gravity,
};
