//! Fuzz target for the calibration reader: any bytes, read as `cal.json`, must give a
//! calibration or an error, never a panic; an accepted file must hold only numbers within
//! their physical ranges (so its model evaluates to finite predictions), write itself back
//! and read back to the same file.

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use robopost::calibration;
use robopost::model::AxisState;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = Path::new("fuzz.json");
    let Ok(cal) = calibration::parse(&text, path) else {
        return;
    };
    let model = cal.model_ref();
    let state = AxisState::new([10.0, -80.0, 95.0, 5.0, 30.0, -20.0]);
    let p = model.target_position(&state);
    assert!(p.iter().all(|v| v.is_finite()), "{p:?}");
    let json = cal.to_json(path).expect("an accepted file writes back");
    let back = calibration::parse(&json, path).expect("what was written reads back");
    assert_eq!(back.to_file(), cal.to_file());
});
