//! robopost: an offline-programming post-processor that compensates KUKA KRL programs with an
//! extended kinematic error model (axis average lines, angular positioning deviation over the
//! command angle with the gear play, axis-to-axis crosstalk and further physical effects),
//! identified from laser-tracker measurements.
//!
//! The library's API is the crate root: [`load_calibration`], [`compensate_source`] /
//! [`compensate_file`], [`simulate_source`], [`read_measurements`], [`identify`], [`compare`]
//! and [`diagnose`], with one [`Error`]. Compensating a program held in memory:
//!
//! ```
//! let calibration = robopost::load_calibration(std::path::Path::new(concat!(
//!     env!("CARGO_MANIFEST_DIR"),
//!     "/calibrations/kr30ha-example.json"
//! )))?;
//! let program = "DEF square( )\r\n\
//!     $BASE = {X 1100, Y -300, Z 600, A 0, B 0, C 0}\r\n\
//!     $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}\r\n\
//!     PTP {A1 10, A2 -80, A3 95, A4 0, A5 30, A6 0}\r\n\
//!     LIN {X 0, Y 0, Z 100, A 0, B 0, C 180} ; the corner\r\n\
//!     LIN {X 100, Y -50, Z 120, A 0, B 0, C 180}\r\n\
//!     END\r\n";
//! let done = robopost::compensate_source("square.src", program.as_bytes(), &calibration)?;
//! let text = String::from_utf8(done.source).unwrap();
//! // Every target is rewritten (the PTP's axes too); comments and CR LF stay as they were.
//! assert_eq!((done.report.compensated, done.report.rejected), (3, 0));
//! assert!(text.contains("} ; the corner\r\nLIN {X "));
//! assert!(!text.contains("LIN {X 100, Y -50, Z 120, A 0, B 0, C 180}"));
//! # Ok::<(), robopost::Error>(())
//! ```
//!
//! Data flows one way inside:
//! `bytes → krl::syntax (lossless syntax) → krl::interpret → motion::form (targets, joints,
//! axis histories; language-neutral) → model (error effects) → compensate → krl::rewrite →
//! bytes`, and `csv → identify → model`, `model + csv → report` (docs/architecture.md: the
//! rooms and the seam). The KRL syntax knows nothing of kinematics; `kinematics`, `motion`,
//! `model` and `compensate` know nothing of KRL. Those modules are private: the API above and [`run_command_line`] (the `robopost`
//! command itself, `src/cli/`) are all there is. robopost's own tests, benches and fuzz targets
//! reach inside through the `internals` feature, which promises no stability.

#![warn(missing_docs)]
// Every type a public signature mentions can be written down by a caller: the check that the
// library's surface is the API of `api.rs` and nothing that leaks from the rooms behind it.
#![deny(unnameable_types)]

mod api;
mod cli;
pub use api::*;

// The modules behind the API: private, unless the `internals` feature (robopost's own tests,
// benches and fuzz targets turn it on) opens them, hidden from the docs and unstable. Written
// out twice rather than by a macro so that rustfmt (which does not expand macros) formats them.
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod atomic_file;
#[cfg(not(feature = "internals"))]
mod atomic_file;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod atomic_unit;
#[cfg(not(feature = "internals"))]
mod atomic_unit;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod calibration;
#[cfg(not(feature = "internals"))]
mod calibration;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod compare;
#[cfg(not(feature = "internals"))]
mod compare;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod compensate;
#[cfg(not(feature = "internals"))]
mod compensate;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod diagnose;
#[cfg(not(feature = "internals"))]
mod diagnose;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod diagnostic;
#[cfg(not(feature = "internals"))]
mod diagnostic;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod identify;
#[cfg(not(feature = "internals"))]
mod identify;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod input;
#[cfg(not(feature = "internals"))]
mod input;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod kinematics;
#[cfg(not(feature = "internals"))]
mod kinematics;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod krl;
#[cfg(not(feature = "internals"))]
mod krl;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod measure;
#[cfg(not(feature = "internals"))]
mod measure;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod model;
#[cfg(not(feature = "internals"))]
mod model;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod motion;
#[cfg(not(feature = "internals"))]
mod motion;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod paths;
#[cfg(not(feature = "internals"))]
mod paths;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod report;
#[cfg(not(feature = "internals"))]
mod report;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod simulate;
#[cfg(not(feature = "internals"))]
mod simulate;
#[cfg(feature = "internals")]
#[doc(hidden)]
pub mod stats;
#[cfg(not(feature = "internals"))]
mod stats;
