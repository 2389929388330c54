//! The library API (crate root) used as another program would: only `robopost::{…}` items
//! that the API exports, no module paths.

use std::path::{Path, PathBuf};

use robopost::{
    compare, compensate_file, compensate_source, identify, load_calibration, parse_calibration,
    read_measurements, simulate_source, CalError, Error, RecordError, RobotDescription,
    PAPER_EFFECTS,
};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn example_calibration_text() -> String {
    std::fs::read_to_string(root().join("calibrations/kr30ha-example.json")).unwrap()
}

/// The example calibration with every effect taken out: the nominal robot.
fn zero_calibration_text() -> String {
    let mut json: serde_json::Value = serde_json::from_str(&example_calibration_text()).unwrap();
    json["effects"] = serde_json::Value::Array(Vec::new());
    json.to_string()
}

const SQUARE: &str = "DEF square( )\r\n\
    $BASE = {X 1100, Y -300, Z 600, A 0, B 0, C 0}\r\n\
    $TOOL = {X 0, Y 0, Z 200, A 0, B 0, C 0}\r\n\
    PTP {A1 10, A2 -80, A3 95, A4 0, A5 30, A6 0}\r\n\
    LIN {X 0, Y 0, Z 100, A 0, B 0, C 180} ; the corner\r\n\
    LIN {X 100, Y -50, Z 120, A 0, B 0, C 180}\r\n\
    LIN {X 5000, Y 0, Z 0, A 0, B 0, C 180}\r\n\
    END\r\n";

/// A calibration without effects changes no byte of any fixture program (the invariant of the
/// command line, through the API); with the example calibration the same programs change.
#[test]
fn a_zero_calibration_leaves_programs_byte_identical() {
    let zero = parse_calibration(&zero_calibration_text(), "zero.json").unwrap();
    let example = load_calibration(&root().join("calibrations/kr30ha-example.json")).unwrap();
    let mut programs: Vec<PathBuf> = ["paper_path1.src", "vertical_segment.src"]
        .iter()
        .map(|p| root().join("fixtures/programs").join(p))
        .collect();
    programs.push(PathBuf::from("square.src"));
    for path in programs {
        let bytes = if path.is_absolute() {
            std::fs::read(&path).unwrap()
        } else {
            SQUARE.as_bytes().to_vec()
        };
        let name = path.display().to_string();
        let same = compensate_source(&name, &bytes, &zero).unwrap();
        assert!(same.source == bytes, "{name}");
        assert_eq!(same.report.compensated, 0, "{name}");
        let changed = compensate_source(&name, &bytes, &example).unwrap();
        assert!(changed.source != bytes, "{name}");
        assert!(changed.report.compensated > 0, "{name}");
    }
}

/// The stops of a program: the PTP's axes as written, the LIN targets at `$BASE` + the
/// programmed position (the base is not rotated), the targets' lines; a target out of reach
/// has no stop and is named with its line.
#[test]
fn simulate_source_gives_the_programmed_stops() {
    let sim =
        simulate_source("square.src", SQUARE.as_bytes(), &RobotDescription::kr30ha()).unwrap();
    let stops = &sim.stops;
    assert_eq!(sim.unreachable, 1);
    assert!(
        sim.messages.iter().any(|m| m.contains("square.src:7:1")),
        "{:?}",
        sim.messages
    );
    assert!(stops.iter().all(|s| s.line != 7));
    let ptp = stops.iter().find(|s| s.line == 4).unwrap();
    assert_eq!(ptp.axes_deg, [10.0, -80.0, 95.0, 0.0, 30.0, 0.0]);
    for (line, xyz) in [(5, [1100.0, -300.0, 700.0]), (6, [1200.0, -350.0, 720.0])] {
        let stop = stops.iter().find(|s| s.line == line).unwrap();
        for (got, want) in stop.tcp_mm.iter().zip(xyz) {
            assert!((got - want).abs() < 1e-9, "line {line}: {:?}", stop.tcp_mm);
        }
    }
}

/// A file compensated to disk equals the same program compensated in memory; a missing input
/// or a bad program is an error with the file's name and nothing is written.
#[test]
fn compensate_file_writes_what_compensate_source_returns() {
    let dir = tempfile::tempdir().unwrap();
    let cal = load_calibration(&root().join("calibrations/kr30ha-example.json")).unwrap();
    let input = dir.path().join("square.src");
    std::fs::write(&input, SQUARE).unwrap();
    let out = dir.path().join("out.src");
    let report = compensate_file(&input, &cal, &out).unwrap();
    let in_memory =
        compensate_source(&input.display().to_string(), SQUARE.as_bytes(), &cal).unwrap();
    assert_eq!(report.compensated, in_memory.report.compensated);
    assert!(std::fs::read(&out).unwrap() == in_memory.source);

    let missing = dir.path().join("missing.src");
    let never = dir.path().join("never.src");
    let e = compensate_file(&missing, &cal, &never).unwrap_err();
    assert!(matches!(e, Error::Program(_)), "{e:?}");
    assert!(e.to_string().contains("missing.src"), "{e}");
    assert!(!never.exists());

    let bad = dir.path().join("bad.src");
    std::fs::write(&bad, "DEF bad( )\nLIN\nEND\n").unwrap();
    let e = compensate_file(&bad, &cal, &never).unwrap_err();
    assert!(e.to_string().contains("bad.src:2:"), "{e}");
    assert!(!never.exists());
}

/// Identification through the API from the shipped campaign, unaided: the identified model
/// explains the data down to the tracker's noise (the campaign's noise floor is 12.6 µm RMS,
/// see the README), where the nominal robot is off by tenths of a millimetre.
#[test]
fn identify_and_compare_through_the_api() {
    let campaign = read_measurements(&root().join("fixtures/measurements/campaign.csv")).unwrap();
    let files = [campaign];
    let identified = identify(&files, PAPER_EFFECTS).unwrap();
    let fitted = compare(&identified.calibration, &files);
    let zero = parse_calibration(&zero_calibration_text(), "zero.json").unwrap();
    let nominal = compare(&zero, &files);
    assert_eq!(fitted.points, 3232);
    assert!(fitted.rms_um < 20.0, "{fitted:?}");
    assert!(nominal.rms_um > 100.0, "{nominal:?}");
    // The calibration's parameters come in the fit's order (what the Python binding pairs
    // with the standard errors), identified away from zero; the zero calibration's are zero.
    let names = identified.calibration.parameter_names();
    let values = identified.calibration.parameter_values();
    assert_eq!(names, identified.fit.parameter_names);
    assert_eq!(values.len(), names.len());
    assert!(values.iter().any(|v| *v != 0.0));
    assert!(zero.parameter_values().iter().all(|v| *v == 0.0));
    // The typed error names what was found, and its message says what was expected.
    match identify(&files, "map:A1,no-such-effect") {
        Err(Error::Effects(e)) => {
            assert_eq!(e.found, "no-such-effect");
            assert!(e
                .to_string()
                .starts_with("expected an effect name (geometric, map:An"));
        }
        other => panic!("{other:?}"),
    }
}

/// A calibration whose gear play of A2 has a negative width: the API's error is a value a
/// caller can match on (which effect in the file, which axis, which grid point, what width),
/// and its message is the command line's.
#[test]
fn a_negative_play_width_is_a_typed_error_naming_the_axis() {
    let mut json: serde_json::Value = serde_json::from_str(&zero_calibration_text()).unwrap();
    json["effects"] = serde_json::json!([
        {"name": "map:A1", "table": {"grid_deg": [0, 10], "values_deg": [0.0, 0.001]}},
        {"name": "backlash:A2", "table": {"grid_deg": [0, 10], "values_deg": [0.01, -0.002]}}
    ]);
    let refused = parse_calibration(&json.to_string(), "cal.json").unwrap_err();
    match &refused {
        Error::Calibration(CalError::Effect {
            at,
            source:
                RecordError::PlayWidth {
                    axis: 2,
                    index: 1,
                    width_deg,
                    max_deg,
                },
            ..
        }) => {
            assert_eq!(at, "effects[1]");
            assert_eq!((*width_deg, *max_deg), (-0.002, 1.0));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(
        refused.to_string(),
        "cal.json: effects[1].table.values_deg[1]: expected a play width in [0, 1]° (the output \
         lags the command by half of it), found -0.002"
    );
}
