//! Fuzz target for the tracker export and plan readers (`robopost import`): any bytes, in any
//! encoding, with or without a time on each row, must give points or a located error, never a
//! panic; an error's line is a line of the decoded text; accepted points are finite numbers
//! on lines of the file.

#![no_main]

use libfuzzer_sys::fuzz_target;
use robopost::measure::{export, plan};

fuzz_target!(|data: &[u8]| {
    let (stream, unit, bytes) = match data.split_first() {
        Some((&flags, rest)) => (
            flags & 1 == 1,
            match flags >> 1 & 3 {
                1 => Some(export::Unit::Mm),
                2 => export::Unit::parse("m"),
                3 => export::Unit::parse("inch"),
                _ => None,
            },
            rest,
        ),
        None => (false, None, data),
    };
    match export::parse_export(bytes, "fuzz.txt", unit, stream) {
        Err(e) => {
            let _ = e.render();
        }
        Ok(x) => {
            for p in &x.points {
                assert!(p.line >= 1 && p.line <= x.lines.len(), "point at line {}", p.line);
                assert!(p.mm.iter().all(|v| v.is_finite()));
                assert!(p.time_s.is_none_or(f64::is_finite));
            }
            let _ = x.describe();
        }
    }
    match plan::parse_plan(bytes, "plan.csv") {
        Err(e) => {
            let _ = e.render();
        }
        Ok(p) => {
            for s in p.measured() {
                assert!(s.axes_deg.iter().all(|a| a.is_finite()));
            }
        }
    }
});
