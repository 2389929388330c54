//! Nominal kinematics of a KUKA six-axis arm as the controller sees it: poses in the KUKA
//! X/Y/Z/A/B/C convention, the robot description as plain data, forward kinematics (a pure
//! function) and closed-form inverse kinematics with the S/T configuration bits. Knows nothing
//! of KRL syntax nor of error models.

pub mod robot;

pub use robot::{Gravity, Links, Payload, RobotDescription};
