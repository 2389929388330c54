//! Laser-tracker measurements: the measurement CSV of `docs/measurements.md` read into
//! [`Stop`]s (command axis angles, each axis's history — rotation direction and gear-play
//! memory — inferred from the visiting order, time, measured position) and written back.
//! Histories are inferred here once, so that identification, diagnosis and the virtual robot
//! all agree on where each axis's gear play stood. A tracker package's own export is read
//! ([`export`], [`text`]) and joined to the campaign's plan ([`plan`], [`join`]) into the same
//! rows.

mod columns;
mod csv_file;
mod directions;
pub mod export;
pub mod join;
pub mod plan;
pub mod text;
pub mod tracker;

pub use csv_file::{
    read_csv, read_csv_within, write_csv, MeasureError, ANGLE_RANGE_DEG, POSITION_RANGE_MM,
    TIME_RANGE_S,
};
// What only robopost's own tests, benches and fuzz targets name through this path.
pub use columns::Columns;
#[cfg(any(test, feature = "internals"))]
pub use csv_file::{parse_csv, parse_csv_within};
pub use directions::infer_histories;

use crate::model::AxisState;
use nalgebra::Vector3;

/// One robot stop: a row of the measurement CSV.
#[derive(Clone, Debug, PartialEq)]
pub struct Stop {
    /// Label of the test or path the row belongs to.
    pub test: String,
    /// Command angles, rotation directions and time at this stop.
    pub state: AxisState,
    /// Measured target position (mm); `None` on an approach row that was not measured.
    pub measured_mm: Option<Vector3<f64>>,
    /// 1-based line of the row in its file (0 when not read from a file).
    pub line: usize,
}

/// The rows of one measurement file, in the order the robot visited them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Measurements {
    /// Where the rows came from (file name, or `-` for stdin).
    pub source: String,
    /// Every row, measured or not (approach rows carry the axes' history only).
    pub stops: Vec<Stop>,
    /// Columns that were present but are not part of the contract (ignored).
    pub ignored_columns: Vec<String>,
}

impl Measurements {
    /// The measured rows only.
    pub fn measured(&self) -> impl Iterator<Item = (&Stop, Vector3<f64>)> {
        self.stops
            .iter()
            .filter_map(|s| s.measured_mm.map(|p| (s, p)))
    }
}
