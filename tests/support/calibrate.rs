//! The identification the diagnosis tests start from: a calibration with exactly the effects
//! named, identified on virtual-robot data with the robot, payload and target of `truth`
//! known and the angle tables at `pitch_deg`. Included with
//! `#[path = "support/calibrate.rs"] mod calibrate;`.

use nalgebra::Vector3;
use robopost::calibration::{Calibration, MeasurementFrame, Provenance};
use robopost::identify::pipeline::{identify, Effects, Request};
use robopost::identify::setup::GridChoice;
use robopost::measure::Stop;
use robopost::model::{expand_list, Model};
use robopost::simulate::paper;

pub fn calibrate(truth: &Model, effects: &str, data: &[Stop], pitch_deg: f64) -> Calibration {
    let start = Calibration::from_model(
        "KR 30 HA (virtual)",
        Model::new(truth.robot, truth.payload, Vector3::from(paper::TARGET_MM)),
        MeasurementFrame::Base,
        Provenance::default(),
    );
    let request = Request {
        effects: Some(Effects::Exactly(expand_list(effects).unwrap())),
        base: Some(start),
        grid: GridChoice {
            map_pitch_deg: pitch_deg,
            ..GridChoice::default()
        },
        ..Request::default()
    };
    identify(data, &request).unwrap().calibration
}
