//! Fuzz target for the measurement CSV reader: any bytes must give rows or a located error,
//! never a panic; an error's line is a line of the file (its text the error's source line);
//! accepted rows hold numbers within the physical ranges, and with the KR 30 HA's joint
//! limits the reader accepts only rows within them.

#![no_main]

use libfuzzer_sys::fuzz_target;
use robopost::kinematics::RobotDescription;
use robopost::measure::{self, ANGLE_RANGE_DEG, POSITION_RANGE_MM};

fuzz_target!(|data: &[u8]| {
    // Lines as the reader counts them: LF, CRLF, or a lone CR (an old Mac export).
    let lines = 1 + data
        .iter()
        .enumerate()
        .filter(|&(i, &b)| b == b'\n' || (b == b'\r' && data.get(i + 1) != Some(&b'\n')))
        .count();
    match measure::parse_csv(data, "fuzz.csv") {
        Err(e) => {
            assert!(e.line <= lines, "line {} of {lines}", e.line);
            let _ = e.render();
        }
        Ok(m) => {
            for s in &m.stops {
                assert!(s.line >= 2 && s.line <= lines, "row at line {}", s.line);
                assert!(s.state.axes_deg.iter().all(|a| a.abs() <= ANGLE_RANGE_DEG));
                if let Some(p) = s.measured_mm {
                    assert!(p.iter().all(|v| v.abs() <= POSITION_RANGE_MM));
                }
            }
        }
    }
    let limits = RobotDescription::kr30ha().limits_deg;
    if let Ok(m) = measure::parse_csv_within(data, "fuzz.csv", Some(&limits)) {
        for s in &m.stops {
            for (a, [lo, hi]) in s.state.axes_deg.iter().zip(limits) {
                assert!(
                    *a >= lo - 1e-6 && *a <= hi + 1e-6,
                    "{a} outside [{lo}, {hi}]"
                );
            }
        }
    }
});
