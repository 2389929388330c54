//! The physical effects of the contract table, one file each, and what they share: the
//! [`ModelEffect`] trait (an [`Effect`] that can also write itself into the calibration file)
//! and the grid options of identification constructors. Every effect writes the chain-error
//! slots documented in `effect.rs`; tables store degrees and slots take radians.

pub mod axis_table;
pub mod compliance;
pub mod crosstalk;
pub mod drift;
pub mod geometric;
pub mod learned;
pub mod loadplay;
pub mod map;
pub mod play;
pub mod tilt;

use super::effect::{Effect, RecordRange};
use super::record::EffectRecord;
use super::table::GridError;

/// Why a zero effect could not be built for identification: its grid, the robot's data or
/// (for `learned:`) its definition. The message is the one the command line prints after the
/// effect's name.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EffectError {
    /// The table of axis `axis` (`map:An`, `backlash:An`) cannot be laid out over
    /// `lo_deg..hi_deg` at `pitch_deg`.
    #[error("grid {lo_deg}..{hi_deg} step {pitch_deg}: {source}")]
    Grid {
        /// The axis, 1..=6.
        axis: u8,
        /// The range's start, degrees.
        lo_deg: f64,
        /// The range's end, degrees.
        hi_deg: f64,
        /// The pitch, degrees.
        pitch_deg: f64,
        /// Why not.
        source: GridError,
    },
    /// One grid of a crosstalk table, the one over axis `axis`, cannot be laid out.
    #[error("grid of A{axis}: {source}")]
    PairGrid {
        /// The axis, 1..=6.
        axis: u8,
        /// Why not.
        source: GridError,
    },
    /// The effect `effect` (its contract name) evaluates the gravity torque and the robot has
    /// no link masses.
    #[error("{effect} needs the link masses (robot.gravity) to compute gravity torques")]
    NeedsGravity {
        /// The effect.
        effect: String,
    },
    /// A `learned:` definition that does not parse.
    #[error(transparent)]
    Spec(#[from] learned::SpecError),
}

/// An effect as a [`Model`](super::Model) holds it: the [`Effect`] trait plus its calibration
/// record. Implemented for every `Effect + ToRecord + Clone`.
pub trait ModelEffect: Effect {
    /// The effect's entry in the calibration file.
    fn record(&self) -> EffectRecord;
    /// The same object as a plain [`Effect`].
    fn as_effect(&self) -> &dyn Effect;
    fn clone_model_effect(&self) -> Box<dyn ModelEffect>;
}

/// The calibration-file encoding of one effect type (its decoding lives in the registry entry).
pub trait ToRecord {
    fn record(&self) -> EffectRecord;
}

impl<T: Effect + ToRecord + Clone + 'static> ModelEffect for T {
    fn record(&self) -> EffectRecord {
        ToRecord::record(self)
    }
    fn as_effect(&self) -> &dyn Effect {
        self
    }
    fn clone_model_effect(&self) -> Box<dyn ModelEffect> {
        Box::new(self.clone())
    }
}

/// Grid choices for a table effect created for identification (all tables start at zero).
///
/// Defaults: the range is the axis's joint limits; the pitch is 1° for `map` and `backlash`
/// (the paper's indexing pitch), and 5° along the own axis for `crosstalk`. Along the other
/// axis of a crosstalk table the grid is `other_grid_deg` when given — identification passes
/// the distinct angles at which the data visited that axis (the paper: A3 at 58°, 105°, 153°),
/// the data-driven choice — otherwise the other axis's joint limits at `other_pitch_deg`
/// (default 15°).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GridOptions {
    pub pitch_deg: Option<f64>,
    pub range_deg: Option<[f64; 2]>,
    pub other_pitch_deg: Option<f64>,
    pub other_range_deg: Option<[f64; 2]>,
    pub other_grid_deg: Option<Vec<f64>>,
}

/// The physical range of an angular deviation table (`map`, `crosstalk`), degrees: a gear
/// error of a degree is already a broken robot.
pub const DEVIATION_RANGE: RecordRange = RecordRange::Within {
    bound: 1.0,
    unit: "degrees",
};

/// A grid point in a parameter name: Rust's shortest round-trip form (`-45`, `12.5`).
pub(crate) fn grid_label(x: f64) -> String {
    format!("{x}")
}
