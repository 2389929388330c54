//! Compensation tests: the solver and sequence logic (`core`), and later the KRL pipeline.

mod cell;
mod cells;
mod circular_angle;
mod cli;
mod core;
mod jacobian;
mod pipeline;
mod spline;

use std::path::Path;

use robopost::calibration;
use robopost::model::Model;

pub fn handset() -> Model {
    calibration::load(Path::new("calibrations/kr30ha-handset.json"))
        .expect("hand-set calibration")
        .model()
}

pub fn nominal() -> Model {
    calibration::load(Path::new("calibrations/kr30ha-nominal.json"))
        .expect("nominal calibration")
        .model()
}
