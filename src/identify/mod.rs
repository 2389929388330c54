//! Identification: from laser-tracker measurements to a calibrated error model (the paper's
//! section 2.3 direct method, then a global sparse least-squares refinement over every
//! requested effect).

pub mod circle;
pub mod covariance;
pub mod direct;
pub mod lsq;
pub mod pipeline;
pub mod promise;
pub mod refine;
pub mod register;
pub mod robust;
pub mod screen;
pub mod setup;
pub mod thin;
pub mod verdict;

pub use refine::{refine, Free, IdentifyError, Progress, RefineOptions, Status, Warning};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use refine::{Fit, ProgressFn};
