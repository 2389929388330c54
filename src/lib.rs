//! robopost: an offline-programming post-processor that compensates KUKA KRL programs with an
//! extended kinematic error model (axis average lines, bidirectional angular positioning
//! deviation, axis-to-axis crosstalk and further physical effects).
//!
//! Data flows one way:
//! `bytes → krl (lossless syntax) → motion (targets, joints, directions) → model (error effects)
//! → compensate → krl edits → bytes`, and `csv → identify → model`, `model + csv → report`.
//! `krl` knows nothing of kinematics; `kinematics` knows nothing of KRL.

pub mod atomic_file;
pub mod calibration;
pub mod cli;
pub mod compare;
pub mod compensate;
pub mod diagnose;
pub mod diagnostic;
pub mod identify;
pub mod kinematics;
pub mod krl;
pub mod measure;
pub mod model;
pub mod motion;
pub mod paths;
pub mod report;
pub mod simulate;
pub mod stats;
