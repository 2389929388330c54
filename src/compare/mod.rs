//! Model versus measurement: for every measured row of a measurement file, where the
//! calibrated model says the target is (`Model::target_position` at the row's command angles,
//! rotation directions and time), where the nominal robot would put it, and where the laser
//! tracker saw it (brought into the base frame when the calibration's measurements are in a
//! tracker frame). The residual `measured − predicted` is what the model fails to explain; its
//! statistics (the paper's Table 1, overall and per test) live in [`summary`], the quantities
//! a residual may depend on (axis angles, gravity torques, time) in [`drivers`].

pub mod axis_residual;
pub mod budget;
pub mod drivers;
pub mod summary;
pub mod table;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use crate::calibration::{Calibration, MeasurementFrame};
use crate::kinematics::Frame;
use crate::measure::Measurements;
use crate::model::{AxisState, Model};

pub use drivers::{Driver, DRIVERS};
pub use summary::Summary;

/// One measured row with the model's and the nominal robot's answer (mm, base frame).
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// Label of the test or path (CSV column `test`).
    pub test: String,
    /// The measurement file and 1-based line the row came from.
    pub source: String,
    pub line: usize,
    pub state: AxisState,
    /// The tracker's position, in the base frame.
    pub measured: Vector3<f64>,
    /// The calibrated model's target position.
    pub predicted: Vector3<f64>,
    /// The nominal robot's target position (no error effects): what the program commanded.
    pub nominal: Vector3<f64>,
}

impl Row {
    /// What the model fails to explain: measured − predicted.
    pub fn residual(&self) -> Vector3<f64> {
        self.measured - self.predicted
    }
    /// The robot's error from the command: measured − nominal (the paper's Fig. 9a).
    pub fn measured_error(&self) -> Vector3<f64> {
        self.measured - self.nominal
    }
    /// The error the model predicts: predicted − nominal (the paper's Fig. 9b).
    pub fn predicted_error(&self) -> Vector3<f64> {
        self.predicted - self.nominal
    }
}

/// A measured position in the base frame, given the frame the calibration says it is in.
pub fn to_base(frame: &MeasurementFrame, measured: &Vector3<f64>) -> Vector3<f64> {
    match frame {
        MeasurementFrame::Base => *measured,
        MeasurementFrame::Tracker(f) => {
            (Frame::from_kuka(f).to_isometry() * Point3::from(*measured)).coords
        }
    }
}

/// Every measured row of `files`, in file order, predicted by `model` (rows in parallel).
pub fn rows_of(model: &Model, frame: &MeasurementFrame, files: &[Measurements]) -> Vec<Row> {
    let nominal = Model::new(model.robot, model.payload, model.target_mm);
    let measured: Vec<_> = files
        .iter()
        .flat_map(|m| {
            m.measured()
                .map(move |(stop, p)| (m.source.as_str(), stop, p))
        })
        .collect();
    measured
        .par_iter()
        .map(|&(source, stop, p)| Row {
            test: stop.test.clone(),
            source: source.to_string(),
            line: stop.line,
            state: stop.state,
            measured: to_base(frame, &p),
            predicted: model.target_position(&stop.state),
            nominal: nominal.target_position(&stop.state),
        })
        .collect()
}

/// The rows of a calibration against measurement files (each file in the tracker frame
/// `identify` found for it when the calibration lists one per file, else in its `frame`).
pub fn compare(cal: &Calibration, files: &[Measurements]) -> Vec<Row> {
    if cal.provenance.frames.is_empty() {
        return rows_of(cal.model_ref(), &cal.frame, files);
    }
    files
        .iter()
        .flat_map(|m| {
            let frame = cal
                .provenance
                .frames
                .iter()
                .find(|(source, _)| same_file(source, &m.source))
                .map_or(cal.frame, |(_, f)| MeasurementFrame::Tracker(*f));
            rows_of(cal.model_ref(), &frame, std::slice::from_ref(m))
        })
        .collect()
}

/// Whether two names of a measurement file are the same file: `identify` records them as
/// given on its command line, `compare` may be run from elsewhere, so by file name.
pub fn same_file(recorded: &str, given: &str) -> bool {
    let name = |s: &str| std::path::Path::new(s).file_name().map(|n| n.to_owned());
    recorded == given || (name(recorded).is_some() && name(recorded) == name(given))
}

/// For each row of [`compare`] (same order): why `identify` left it out of the fit as a gross
/// error, if it did (the calibration's `provenance.excluded`, matched by file and line).
pub fn gross_errors(cal: &Calibration, files: &[Measurements]) -> Vec<Option<String>> {
    let excluded = &cal.provenance.excluded;
    files
        .iter()
        .flat_map(|m| {
            let listed: std::collections::HashMap<usize, &str> = excluded
                .iter()
                .filter(|e| same_file(&e.source, &m.source))
                .map(|e| (e.line, e.why.as_str()))
                .collect();
            m.measured()
                .map(move |(stop, _)| listed.get(&stop.line).map(|w| w.to_string()))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Test labels in the order they first appear.
pub fn test_order(rows: &[Row]) -> Vec<String> {
    let mut order: Vec<String> = Vec::new();
    for r in rows {
        if order.last() != Some(&r.test) && !order.contains(&r.test) {
            order.push(r.test.clone());
        }
    }
    order
}
