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
    AxisSlopes, ChainErrors, Context, Effect, Observed, Parameter, Partial, RecordRange,
    RecordValue, Role, Slot, JOINT_SLOTS, N_SLOTS,
};
pub use effects::{EffectError, GridOptions, ModelEffect};
pub use history::{AxisHistory, PlayAt, ENGAGING_RUN_DEG, MAX_PLAY_DEG};
pub use model::{JacobianScratch, Model};
pub use record::{EffectRecord, RecordError, TableRecord};
pub use registry::{expand_list, EffectName, NameError, RegisterError};
pub use state::{AxisState, Direction};
