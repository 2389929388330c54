//! The CAM fixture the compensation benchmarks run on: `fixtures/programs/cam/pocket_milling.src`
//! (22 506 LIN targets) with the paper's full model from `calibrations/kr30ha-handset.json`.

use std::path::Path;

use robopost::krl::interpret::Workspace;
use robopost::krl::job::files;
use robopost::model::Model;

pub const PROGRAM: &str = "fixtures/programs/cam/pocket_milling.src";
pub const CAL: &str = "calibrations/kr30ha-handset.json";

/// The model, the calibration file's bytes (for `Calibrated`), the program's bytes and the
/// loaded program.
pub fn load() -> (Model, Vec<u8>, Vec<u8>, Workspace) {
    let cal_bytes = std::fs::read(CAL).expect("calibration");
    let cal = robopost::calibration::parse(&String::from_utf8_lossy(&cal_bytes), Path::new(CAL))
        .expect("valid calibration");
    let bytes = std::fs::read(PROGRAM).expect("fixture");
    let ws = files::load_program(Some(Path::new(PROGRAM)), &bytes, None).expect("parses");
    (cal.model(), cal_bytes, bytes, ws)
}
