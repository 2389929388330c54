//! `compare` and its HTML report: residuals and Table 1 statistics against hand-computed
//! values, the tracker frame, the CLI's JSON keys (CONTRACTS.md) and side-by-side table, bad
//! input, and the report opened in a real browser (headless Chromium).

use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::{Rotation3, Vector3};
use robopost::calibration::{Calibration, KukaFrame, MeasurementFrame, Provenance};
use robopost::compare::{self, Summary};
use robopost::kinematics::{Payload, RobotDescription};
use robopost::measure::{self, infer_histories, Measurements, Stop};
use robopost::model::{expand_list, AxisState, GridOptions, Model};
use robopost::simulate::campaign::{Campaign, IndexingTest, Repeat};

fn model(effects: &str) -> Model {
    let mut m = Model::new(
        RobotDescription::kr30ha(),
        Payload::default(),
        Vector3::new(0.0, 0.0, 150.0),
    );
    for name in expand_list(effects).unwrap() {
        m.push_named(&name, &GridOptions::default()).unwrap();
    }
    m
}

/// The nominal robot with A1 turned 0.01° further than commanded everywhere.
fn a1_offset_truth(theta_deg: f64) -> Model {
    let mut m = model("map:A1");
    let n = m.n_parameters();
    m.set_values(&vec![theta_deg; n]);
    m
}

fn small_campaign() -> Campaign {
    let reference = [0.0, -60.0, 100.0, 0.0, 45.0, 0.0];
    let test = |axis, from, to, repeat| IndexingTest {
        axis,
        from_deg: from,
        to_deg: to,
        pitch_deg: 5.0,
        reference_deg: reference,
        repeat,
        approach_deg: 2.0,
    };
    Campaign {
        reversals: Vec::new(),
        reference: None,
        tests: vec![
            test(1, -30.0, 30.0, None),
            test(
                2,
                -100.0,
                -30.0,
                Some(Repeat {
                    axis: 3,
                    angles_deg: vec![60.0, 140.0],
                }),
            ),
            test(3, 30.0, 140.0, None),
        ],
        dwell_s: 3.2,
        axis_speed_deg_s: 30.0,
    }
}

/// The campaign's stops with the target exactly where `truth` puts it.
fn measure_exactly(truth: &Model) -> Measurements {
    let plan = small_campaign().plan().unwrap();
    let mut states: Vec<AxisState> = plan
        .iter()
        .map(|p| AxisState {
            time_s: p.time_s,
            ..AxisState::new(p.axes_deg)
        })
        .collect();
    infer_histories(&mut states, &[]);
    let stops = plan
        .iter()
        .zip(states)
        .map(|(p, state)| Stop {
            test: p.test.clone(),
            state,
            measured_mm: p.measured.then(|| truth.target_position(&state)),
            line: 0,
        })
        .collect();
    Measurements {
        source: "exact.csv".into(),
        stops,
        ignored_columns: vec![],
    }
}

#[test]
fn residual_of_a_missing_a1_offset_is_the_rotation_about_the_base_z_axis() {
    let theta = 0.01f64;
    let data = measure_exactly(&a1_offset_truth(theta));
    let nominal = model("");
    let rows = compare::rows_of(&nominal, &MeasurementFrame::Base, &[data]);
    assert!(rows.len() > 50);
    // A positive KUKA A1 deviation turns the arm about −Z (MODEL.md): p' = Rz(−θ)·p.
    let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), -theta.to_radians());
    let mut chords = Vec::new();
    for r in &rows {
        let expected = turn * r.nominal - r.nominal;
        assert!(
            (r.residual() - expected).norm() < 1e-9,
            "{:?}",
            r.residual()
        );
        // The chord of the arc: 2 r sin(θ/2), r the distance from the A1 axis.
        chords.push(2.0 * r.nominal.xy().norm() * (theta.to_radians() / 2.0).sin() * 1000.0);
    }
    let s = Summary::residuals(&rows);
    let mean = chords.iter().sum::<f64>() / chords.len() as f64;
    assert!(
        (s.all.xy_mean_um - mean).abs() < 1e-6,
        "{} vs {mean}",
        s.all.xy_mean_um
    );
    assert!(s.all.z_mean_um.abs() < 1e-6);
    assert!((s.all.d3_mean_um - mean).abs() < 1e-6);
    // The arm reaches about 1.2–2 m from A1: 0.01° is 0.2–0.35 mm there.
    assert!((200.0..360.0).contains(&mean), "{mean}");
    // Per test: the same statistics over the test's rows only.
    let a1_rows: Vec<_> = rows.iter().filter(|r| r.test == "A1").cloned().collect();
    assert_eq!(s.tests["A1"], Summary::residuals(&a1_rows).all);
    assert_eq!(s.order, vec!["A1", "A2@A3=60", "A2@A3=140", "A3"]);
}

#[test]
fn tracker_frame_measurements_are_brought_into_the_base_frame() {
    let truth = a1_offset_truth(0.02);
    let frame = KukaFrame {
        x: 1200.0,
        y: -300.0,
        z: 50.0,
        a: 30.0,
        b: -5.0,
        c: 2.0,
    };
    // Tracker → base is Trans(x,y,z)·Rz(A)·Ry(B)·Rx(C); build it from elementary rotations.
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), frame.a.to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), frame.b.to_radians())
        * Rotation3::from_axis_angle(&Vector3::x_axis(), frame.c.to_radians());
    let t = Vector3::new(frame.x, frame.y, frame.z);
    let mut data = measure_exactly(&truth);
    for s in &mut data.stops {
        s.measured_mm = s.measured_mm.map(|p| r.inverse() * (p - t));
    }
    let rows = compare::rows_of(&truth, &MeasurementFrame::Tracker(frame), &[data.clone()]);
    assert!(rows.iter().all(|r| r.residual().norm() < 1e-9));
    // Read as base-frame positions they are metres off.
    let wrong = compare::rows_of(&truth, &MeasurementFrame::Base, &[data]);
    assert!(wrong.iter().all(|r| r.residual().norm() > 100.0));
}

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_robopost")
}

/// A temporary directory with `nominal.json`, `truth.json` (A1 + 0.01°) and `meas.csv`.
fn workspace() -> (tempfile::TempDir, PathBuf, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let save = |name: &str, m: Model| {
        let path = dir.path().join(name);
        Calibration::from_model("KR 30 HA", m, MeasurementFrame::Base, Provenance::default())
            .save_atomic(&path)
            .unwrap();
        path
    };
    let nominal = save("nominal.json", model(""));
    let truth = save("truth.json", a1_offset_truth(0.01));
    let data = measure_exactly(&a1_offset_truth(0.01));
    let csv = dir.path().join("meas.csv");
    measure::write_csv(std::fs::File::create(&csv).unwrap(), &data.stops).unwrap();
    (dir, nominal, truth, csv)
}

fn run(args: &[&Path]) -> std::process::Output {
    Command::new(bin()).args(args).output().unwrap()
}

#[test]
fn cli_json_has_the_contract_keys_and_the_fall_against_another_calibration() {
    let (_dir, nominal, truth, csv) = workspace();
    let out = run(&[
        Path::new("compare"),
        Path::new("-c"),
        &truth,
        &csv,
        Path::new("--json"),
        Path::new("--against"),
        &nominal,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let keys = [
        "points",
        "xy_mean_um",
        "xy_2sigma_um",
        "z_mean_um",
        "z_2sigma_um",
        "d3_mean_um",
        "d3_max_um",
        "rms_um",
    ];
    for k in keys {
        assert!(v[k].is_number(), "top-level key {k} missing: {v}");
        for t in ["A1", "A2@A3=60", "A2@A3=140", "A3"] {
            assert!(v["tests"][t][k].is_number(), "tests.{t}.{k} missing");
        }
    }
    // 13 stops per sweep, both directions: A1, A2 at two A3 angles, and A3 (23 stops).
    assert_eq!(v["points"], 13 * 2 + 15 * 2 * 2 + 23 * 2);
    // The truth explains the data up to the CSV's 0.1 µm rounding; the nominal model leaves
    // the whole A1 error.
    assert!(v["rms_um"].as_f64().unwrap() < 0.2, "{}", v["rms_um"]);
    let library = Summary::uncompensated(&compare::rows_of(
        &model(""),
        &MeasurementFrame::Base,
        &[measure::read_csv(&csv).unwrap()],
    ));
    let against = v["against"]["rms_um"].as_f64().unwrap();
    assert!((against - library.all.rms_um).abs() < 1e-6 && against > 200.0);
    assert_eq!(v["nominal"]["rms_um"], v["against"]["rms_um"]);

    let out = run(&[
        Path::new("compare"),
        Path::new("-c"),
        &truth,
        &csv,
        Path::new("--against"),
        &nominal,
    ]);
    let text = String::from_utf8(out.stdout).unwrap();
    let all: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("all"))
        .take(3)
        .collect();
    assert!(all[0].contains("nominal"), "{text}");
    assert!(
        all[1].contains("nominal.json") && all[1].trim_end().ends_with("+0%"),
        "{text}"
    );
    assert!(
        all[2].contains("truth.json") && all[2].trim_end().ends_with("-100%"),
        "{text}"
    );
}

#[test]
fn bad_measurement_file_is_located_and_nothing_is_written() {
    let (dir, _nominal, truth, csv) = workspace();
    let mut text = std::fs::read_to_string(&csv).unwrap();
    text = text.replacen("\nA1,", "\nA1,1O,", 1);
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, text.replacen(",1O,", ",1O", 1)).unwrap();
    let report = dir.path().join("report");
    let out = run(&[
        Path::new("compare"),
        Path::new("-c"),
        &truth,
        &bad,
        Path::new("--report"),
        &report,
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.csv:2:4"), "{err}");
    assert!(err.contains("`1O-32.000000` is not a number"), "{err}");
    assert!(!report.exists());
}

/// Opens the report in headless Chromium: every plot is in the DOM, the page paints, the
/// browser logs no console error. Without a browser the check is skipped with a note, unless
/// ROBOPOST_REQUIRE_BROWSER is set (`.ci/run` installs Chromium and sets it);
/// ROBOPOST_SKIP_BROWSER=1 skips it outright.
#[test]
fn report_renders_in_headless_chromium() {
    let (dir, nominal, truth, csv) = workspace();
    let report = dir.path().join("report");
    let out = run(&[
        Path::new("compare"),
        Path::new("-c"),
        &nominal,
        &csv,
        Path::new("--against"),
        &truth,
        Path::new("--report"),
        &report,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let page = report.join("index.html");
    let html = std::fs::read_to_string(&page).unwrap();
    // 2 histograms + 6 drivers (A1–A3 angles, A2/A3 torques, time; A4–A6 never move here)
    // + per test (4 tests): Fig. 9, Fig. 10 and the two angle plots + the drivers learned
    // from the residual.
    let expected = 2 + 6 + 4 * 4 + 1;
    assert!(html.contains("Learned from the residual"));
    assert_eq!(html.matches("<svg").count(), expected);
    assert!(!html.contains("plot failed"));
    assert!(html.contains("did not vary in these measurements (nothing can be learnt about them here): the A4 angle, the A5 angle, the A6 angle."));

    if std::env::var_os("ROBOPOST_SKIP_BROWSER").is_some() {
        eprintln!("ROBOPOST_SKIP_BROWSER set: not opening the report in a browser");
        return;
    }
    let found = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|c| {
            Command::new(c)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        });
    let Some(chromium) = found else {
        // `.ci/run` sets ROBOPOST_REQUIRE_BROWSER where it installed one: there a missing
        // browser is a failure, elsewhere (a developer's machine without it) a skip.
        assert!(
            std::env::var_os("ROBOPOST_REQUIRE_BROWSER").is_none(),
            "ROBOPOST_REQUIRE_BROWSER is set but no headless Chromium runs"
        );
        eprintln!("no headless Chromium (apt-get install -y chromium): browser check skipped");
        return;
    };
    let url = format!("file://{}", page.display());
    let browser = |extra: &[&str]| {
        Command::new(chromium)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                "--enable-logging=stderr",
                "--v=0",
                "--window-size=1500,2200",
            ])
            .args(extra)
            .arg(&url)
            .output()
            .unwrap()
    };
    let dom = browser(&["--dump-dom"]);
    let dom_text = String::from_utf8_lossy(&dom.stdout);
    assert_eq!(
        dom_text.matches("<svg").count(),
        expected,
        "the browser's DOM lacks plots"
    );
    let console = |stderr: &[u8]| {
        String::from_utf8_lossy(stderr)
            .lines()
            .filter(|l| l.contains("CONSOLE") || l.contains("Uncaught"))
            .map(String::from)
            .collect::<Vec<_>>()
    };
    assert!(
        console(&dom.stderr).is_empty(),
        "{:?}",
        console(&dom.stderr)
    );

    let shot = dir.path().join("shot.png");
    let shoot = browser(&[&format!("--screenshot={}", shot.display())]);
    assert!(
        console(&shoot.stderr).is_empty(),
        "{:?}",
        console(&shoot.stderr)
    );
    let keep = std::env::var_os("ROBOPOST_KEEP_SCREENSHOT");
    if let Some(to) = &keep {
        std::fs::copy(&shot, to).unwrap();
        std::fs::copy(&page, Path::new(to).with_extension("html")).unwrap();
    }
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let pixels: Vec<&[u8]> = buf[..info.buffer_size()].chunks(channels).collect();
    let non_white = pixels
        .iter()
        .filter(|p| p[..3].iter().any(|&c| c < 235))
        .count();
    // Coloured plot lines: pixels where one channel stands well clear of another.
    let coloured = pixels
        .iter()
        .filter(|p| {
            let (lo, hi) = (p[..3].iter().min().unwrap(), p[..3].iter().max().unwrap());
            hi - lo > 80
        })
        .count();
    let n = pixels.len();
    assert!(
        non_white * 50 > n,
        "screenshot nearly blank: {non_white} of {n}"
    );
    assert!(
        coloured * 1000 > n,
        "no coloured plot pixels: {coloured} of {n}"
    );
}
