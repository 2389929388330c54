//! The error model: what the robot really does when commanded to a set of axis angles.
//!
//! Every physical effect (the paper's geometric errors of the axis average lines, angular
//! positioning deviation maps, backlash, crosstalk, and effects beyond the paper) implements the
//! one [`Effect`] trait: it turns an [`AxisState`] into additive contributions to a fixed
//! vector of [`ChainErrors`] (per axis: a small displacement and rotation of the axis line and
//! an angular deviation; plus the measurement target vector), and gives the Jacobian of those
//! contributions with respect to its parameters. The error chain (the paper's equation 2)
//! turns chain errors into a predicted pose. Identification, compensation and diagnosis use
//! only the trait, so a new effect is one new file plus one registration line.

pub mod chain;
pub mod effect;
pub mod effects;
pub mod history;
pub mod merged;
#[allow(clippy::module_inception)]
pub mod model;
pub mod record;
pub mod registry;
pub mod state;
pub mod table;

pub use effect::{
    AxisSlopes, ChainErrors, Effect, Observed, RecordRange, RecordValue, Role, Slot, N_SLOTS,
};
pub use effects::{EffectError, GridOptions, ModelEffect};
pub use history::AxisHistory;
#[cfg(any(test, feature = "internals"))]
pub use history::PlayAt;
pub use model::{JacobianScratch, Model};
pub use record::{EffectRecord, RecordError};
pub use registry::{expand_list, EffectName, NameError};
// What only robopost's own tests, benches and fuzz targets name through this path.
pub use state::{AxisState, Direction};
#[cfg(any(test, feature = "internals"))]
pub use {
    effect::{Context, Parameter, Partial, JOINT_SLOTS},
    history::{ENGAGING_RUN_DEG, MAX_PLAY_DEG},
    record::TableRecord,
    registry::RegisterError,
};
