//! The calibration reader and the measurement CSV reader under random input, as the
//! `fuzz/` targets `calibration` and `measurements` check them, but inside `cargo test`: any
//! bytes, and valid files with a number replaced by an absurd one or bytes cut, inserted or
//! changed, give a result or an error, never a panic; what is accepted holds only numbers
//! within their physical ranges and reads back. `PROPTEST_CASES=N` runs longer.

use std::path::Path;

use proptest::prelude::*;
use robopost::calibration;
use robopost::kinematics::RobotDescription;
use robopost::measure::{self, ANGLE_RANGE_DEG, POSITION_RANGE_MM};
use robopost::model::AxisState;

fn shipped(rel: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
}

/// Numbers that have broken readers: huge, tiny, negative zero, beyond f64, integers.
const ABSURD: &[&str] = &[
    "1e308",
    "-1e308",
    "1e999",
    "1e-300",
    "-0",
    "0",
    "45",
    "-850",
    "1e20",
    "1e12",
    "720.0001",
    "NaN",
    "inf",
    "18446744073709551616",
    "-1",
    "5000.5",
    "\"x\"",
    "null",
    "[]",
];

/// Byte offsets where a number starts in `text`.
fn number_starts(text: &str) -> Vec<usize> {
    let b = text.as_bytes();
    (0..b.len())
        .filter(|&i| {
            (b[i].is_ascii_digit() || b[i] == b'-')
                && (i == 0 || matches!(b[i - 1], b' ' | b'[' | b',' | b':' | b'\n'))
        })
        .collect()
}

/// `text` with the number at `start` replaced by `by`.
fn replace_number(text: &str, start: usize, by: &str) -> String {
    let b = text.as_bytes();
    let mut end = start + 1;
    while end < b.len() && (b[end].is_ascii_alphanumeric() || matches!(b[end], b'.' | b'-' | b'+'))
    {
        end += 1;
    }
    format!("{}{by}{}", &text[..start], &text[end..])
}

#[derive(Clone, Debug)]
enum Edit {
    Number(usize, usize),
    Cut(usize, usize),
    Insert(usize, Vec<u8>),
    Flip(usize, u8),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), 0..ABSURD.len()).prop_map(|(i, k)| Edit::Number(i, k)),
        (any::<usize>(), 1usize..40).prop_map(|(i, n)| Edit::Cut(i, n)),
        (any::<usize>(), prop::collection::vec(any::<u8>(), 1..12))
            .prop_map(|(i, b)| Edit::Insert(i, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::Flip(i, b)),
    ]
}

fn apply(text: &str, edits: &[Edit]) -> Vec<u8> {
    let mut bytes = text.as_bytes().to_vec();
    for e in edits {
        match e {
            Edit::Number(i, k) => {
                let s = String::from_utf8_lossy(&bytes).into_owned();
                let starts = number_starts(&s);
                if !starts.is_empty() {
                    bytes = replace_number(&s, starts[i % starts.len()], ABSURD[*k]).into_bytes();
                }
            }
            Edit::Cut(i, n) if !bytes.is_empty() => {
                let at = i % bytes.len();
                bytes.drain(at..(at + n).min(bytes.len()));
            }
            Edit::Cut(..) => {}
            Edit::Insert(i, b) => {
                let at = i % (bytes.len() + 1);
                bytes.splice(at..at, b.iter().copied());
            }
            Edit::Flip(i, b) if !bytes.is_empty() => {
                let at = i % bytes.len();
                bytes[at] = *b;
            }
            Edit::Flip(..) => {}
        }
    }
    bytes
}

/// The fuzz target `calibration`'s checks.
fn check_calibration(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let path = Path::new("fuzz.json");
    let Ok(cal) = calibration::parse(&text, path) else {
        return;
    };
    let state = AxisState::new([10.0, -80.0, 95.0, 5.0, 30.0, -20.0]);
    let p = cal.model_ref().target_position(&state);
    assert!(p.iter().all(|v| v.is_finite()), "{p:?}");
    let json = cal.to_json(path).expect("an accepted file writes back");
    let back = calibration::parse(&json, path).expect("what was written reads back");
    assert_eq!(back.to_file(), cal.to_file());
}

/// The fuzz target `measurements`' checks.
fn check_measurements(data: &[u8]) {
    let lines = data.split(|&b| b == b'\n').count();
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
}

fn small_csv() -> String {
    let campaign = shipped("fixtures/measurements/campaign.csv");
    let mut text: String = campaign
        .lines()
        .take(12)
        .map(|l| format!("{l}\n"))
        .collect();
    text += "# a comment\r\n\r\nA1,-40,-60,100,0,45,0,1300.1,1000.2,796.7,60.0,1,,,,,\r\n";
    text
}

proptest! {
    #[test]
    fn calibration_reader_survives_any_bytes(data in prop::collection::vec(any::<u8>(), 0..600)) {
        check_calibration(&data);
    }

    #[test]
    fn calibration_reader_survives_edited_files(
        which in 0usize..2,
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let text = shipped(["calibrations/kr30ha-example.json", "calibrations/kr30ha-nominal.json"][which]);
        check_calibration(&apply(&text, &edits));
    }

    #[test]
    fn csv_reader_survives_any_bytes(data in prop::collection::vec(any::<u8>(), 0..600)) {
        check_measurements(&data);
    }

    #[test]
    fn csv_reader_survives_edited_files(edits in prop::collection::vec(edit(), 1..5)) {
        check_measurements(&apply(&small_csv(), &edits));
    }
}

/// The edits reach the checks: a number replaced by one out of range is refused with its
/// key, so an accepted edited file is not an accident of the mutation.
#[test]
fn an_absurd_number_edited_in_is_refused() {
    let text = shipped("calibrations/kr30ha-example.json");
    let at = text.find("\"l2\": ").unwrap() + "\"l2\": ".len();
    let edited = replace_number(&text, at, "-850");
    let e = calibration::parse(&edited, Path::new("c.json")).unwrap_err();
    assert!(e.to_string().contains("robot.description.links.l2"), "{e}");
    let csv = small_csv();
    let starts = number_starts(&csv);
    let edited = replace_number(&csv, starts[3], "1e20");
    assert!(measure::parse_csv(edited.as_bytes(), "m.csv").is_err());
}
