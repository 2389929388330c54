//! The lab loop on the virtual robot (issue 36): `campaign` → `simulate program` → the
//! measurements written out as each tracker package exports them → `import` → the same
//! measurement CSV, hence the same calibration; a 100 Hz stream with dwells joins to the same
//! rows; the campaign program passes `check` for three robots and keeps out of a keep-out box;
//! an export given straight to `identify` gets an error naming what was seen; `--tracker`
//! moves the noise floor and the gross-error threshold as its MPE says.

use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::Vector3;
use robopost::identify::pipeline::{identify, Request};
use robopost::kinematics::flange_frame;
use robopost::measure::plan::parse_plan;
use robopost::measure::tracker::Tracker;
use robopost::measure::{read_csv, Stop};

fn robopost(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_robopost"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(args: &[&str]) -> String {
    let out = robopost(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The truth's measurement target (the reflector), the tracker station and a campaign with
/// its direct measurement CSV (`simulate program` of the program).
struct Run {
    dir: tempfile::TempDir,
    plan: PathBuf,
    direct: PathBuf,
}

fn run(steps: Option<&str>) -> Run {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    ok(&["simulate", "truth", "-o", s(&p("truth.json"))]);
    let mut args = vec![
        "campaign",
        "--robot",
        "KR 30 HA",
        "--tool=-120,-80,180",
        "--tracker-at",
        "3000,0,800",
        "--floor",
        "0",
        "-o",
    ];
    let src = p("cal.src");
    args.push(s(&src));
    let joined;
    if let Some(steps) = steps {
        joined = format!("--reversal-steps={steps}");
        args.push(&joined);
    }
    ok(&args);
    let direct = p("direct.csv");
    ok(&[
        "simulate",
        "program",
        "--truth",
        s(&p("truth.json")),
        s(&src),
        "-o",
        s(&direct),
    ]);
    Run {
        plan: p("cal_plan.csv"),
        direct,
        dir,
    }
}

/// The measured rows of the direct CSV with their plan point names, in order.
fn named(run: &Run) -> Vec<(String, Vector3<f64>, f64)> {
    let plan = parse_plan(&std::fs::read(&run.plan).unwrap(), "plan").unwrap();
    let direct = read_csv(&run.direct).unwrap();
    assert_eq!(plan.stops.len(), direct.stops.len());
    plan.stops
        .iter()
        .zip(&direct.stops)
        .filter_map(|(p, d)| {
            assert_eq!(p.axes_deg, d.state.axes_deg);
            assert_eq!(p.point.is_empty(), d.measured_mm.is_none(), "{}", p.line);
            d.measured_mm.map(|m| (p.point.clone(), m, d.state.time_s))
        })
        .collect()
}

/// 10:00:00 plus `t` seconds as `hh:mm:ss.fff`.
fn clock(t: f64) -> String {
    let ms = (t * 1000.0).round() as u64 + 36_000_000;
    format!(
        "{:02}:{:02}:{:02}.{:03}",
        ms / 3_600_000,
        ms / 60_000 % 60,
        ms / 1000 % 60,
        ms % 1000
    )
}

fn utf16(text: &str, big_endian: bool) -> Vec<u8> {
    let mark: &[u8] = if big_endian { b"\xFE\xFF" } else { b"\xFF\xFE" };
    let body = text.encode_utf16().flat_map(|u| {
        if big_endian {
            u.to_be_bytes()
        } else {
            u.to_le_bytes()
        }
    });
    mark.iter().copied().chain(body).collect()
}

/// The measured points written as each package exports them (modelled on their documented
/// text exports; see docs/import.md): (file name, bytes).
fn exports(points: &[(String, Vector3<f64>, f64)]) -> Vec<(&'static str, Vec<u8>)> {
    let mut sa = String::from(
        "// SpatialAnalyzer ASCII export\r\n// Frame: ROBOT BASE\r\n// Units: Millimeters\r\n",
    );
    let mut pilot = String::from("Point ID,X [m],Y [m],Z [m],Timestamp\r\n");
    let mut cam2 = String::from("Feature Name\tX (in)\tY (in)\tZ (in)\tTime\r\n");
    let mut poly = String::from("# PolyWorks|Inspector text export\n# Units: mm\nName,Nominal X,Nominal Y,Nominal Z,Measured X,Measured Y,Measured Z,Dev 3D\n");
    let mut german: Vec<u8> = b"Pr\xFCfpunkt;X [mm];Y [mm];Z [mm];Zeitstempel\r\n".to_vec();
    let mut api = String::from("Name\tX\tY\tZ\r\n");
    for (name, m, t) in points {
        sa.push_str(&format!(
            "ROBOT  Calibration  {name}  {:.4}  {:.4}  {:.4}\r\n",
            m.x, m.y, m.z
        ));
        pilot.push_str(&format!(
            "{name},{:.7},{:.7},{:.7},2026-12-02 {}\r\n",
            m.x / 1000.0,
            m.y / 1000.0,
            m.z / 1000.0,
            clock(*t)
        ));
        cam2.push_str(&format!(
            "{name}\t{:.9}\t{:.9}\t{:.9}\t{}\r\n",
            m.x / 25.4,
            m.y / 25.4,
            m.z / 25.4,
            clock(*t)
        ));
        poly.push_str(&format!(
            "{name},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},0.1000\n",
            m.x + 0.1,
            m.y,
            m.z,
            m.x,
            m.y,
            m.z
        ));
        let numbers = format!("{name};{:.4};{:.4};{:.4}", m.x, m.y, m.z).replace('.', ",");
        let stamp = format!("02.12.2026 {}", clock(*t).replace('.', ","));
        german.extend(format!("{numbers};{stamp}\r\n").bytes());
        api.push_str(&format!("{name}\t{:.4}\t{:.4}\t{:.4}\r\n", m.x, m.y, m.z));
    }
    vec![
        ("spatial_analyzer.txt", sa.into_bytes()),
        ("tracker_pilot.csv", pilot.into_bytes()),
        ("cam2_utf16le.txt", utf16(&cam2, false)),
        ("polyworks.txt", poly.into_bytes()),
        ("german_excel.csv", german),
        ("utf16be.txt", utf16(&api, true)),
    ]
}

#[test]
fn every_export_format_and_a_stream_import_to_the_direct_csv() {
    let run = run(None);
    let points = named(&run);
    assert!(points.len() > 900, "{}", points.len());
    let direct = std::fs::read(&run.direct).unwrap();
    for (name, bytes) in exports(&points) {
        let export = run.dir.path().join(name);
        std::fs::write(&export, bytes).unwrap();
        let out = run.dir.path().join(format!("{name}.csv"));
        let said = ok(&["import", s(&export), "--plan", s(&run.plan), "-o", s(&out)]);
        assert!(
            said.contains(&format!("matched {} measured stops", points.len())),
            "{said}"
        );
        let back = std::fs::read(&out).unwrap();
        assert!(back == direct, "{name}: {said}");
    }
    // The same calibration from the direct CSV and an imported one (the German Excel file's).
    let direct_cal = run.dir.path().join("direct.json");
    let imported_cal = run.dir.path().join("imported.json");
    ok(&["identify", s(&run.direct), "-o", s(&direct_cal)]);
    let imported = run.dir.path().join("german_excel.csv.csv");
    ok(&["identify", s(&imported), "-o", s(&imported_cal)]);
    let model = |p: &Path| -> serde_json::Value {
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap();
        v["model"].clone()
    };
    assert_eq!(model(&direct_cal), model(&imported_cal));
}

#[test]
fn a_100_hz_stream_with_dwells_joins_to_the_same_rows() {
    // Reversal moves of 0.5° and more: a stream tells stops apart by motion beyond --radius.
    let run = run(Some("0.5,1"));
    let points = named(&run);
    let mut stream = String::from("Time;X;Y;Z\n");
    let mut sample = |t: f64, p: &Vector3<f64>| {
        stream.push_str(&format!("{};{:.5};{:.5};{:.5}\n", clock(t), p.x, p.y, p.z))
    };
    let mut last: Option<(f64, Vector3<f64>)> = None;
    for (_, m, t) in &points {
        if let Some((end, from)) = last {
            // Two measured stops at one place (a sweep's turn: its approach move lies
            // between them): the reflector leaves and comes back.
            let from = if (m - from).norm() < 1.0 {
                let away = from + Vector3::new(0.0, 0.0, 5.0);
                for k in 1..30 {
                    sample(
                        end + k as f64 * 0.01,
                        &(from + (away - from) * (k as f64 / 30.0)),
                    );
                }
                away
            } else {
                from
            };
            let end = end + 0.3;
            // Motion at 100 Hz from the last dwell, with a 0.3 s pause half way (shorter than
            // a dwell), no sample within 0.5 mm of either stop.
            let n = ((t - end) * 100.0).round() as usize;
            for k in 1..n {
                let f = k as f64 / n as f64;
                let p = from
                    + (m - from) * (f.min(0.5) * 2.0).min(1.0) * 0.5
                    + (m - from) * ((f - 0.6).max(0.0) / 0.4) * 0.5;
                if (p - from).norm() > 0.5 && (p - m).norm() > 0.5 {
                    sample(end + k as f64 * 0.01, &p);
                }
            }
        }
        // A 2 s dwell: noise of ±3 µm in pairs, so that the mean is the point.
        for k in 0..200 {
            let e = if k % 2 == 0 { 0.003 } else { -0.003 };
            sample(t + k as f64 * 0.01, &(m + Vector3::new(e, -e, e)));
        }
        last = Some((t + 1.99, *m));
    }
    let file = run.dir.path().join("stream.csv");
    std::fs::write(&file, stream).unwrap();
    let out = run.dir.path().join("from_stream.csv");
    let said = ok(&[
        "import",
        s(&file),
        "--plan",
        s(&run.plan),
        "--stream",
        "-o",
        s(&out),
    ]);
    assert!(said.contains(&format!("{} dwells", points.len())), "{said}");
    assert!(
        std::fs::read(&out).unwrap() == std::fs::read(&run.direct).unwrap(),
        "{said}"
    );
}

#[test]
fn exports_given_to_identify_name_what_was_seen() {
    let dir = tempfile::tempdir().unwrap();
    let german = dir.path().join("german.csv");
    std::fs::write(
        &german,
        b"Punkt;X [mm];Y [mm];Z [mm]\r\nP1;1234,5;2,25;3\r\n",
    )
    .unwrap();
    let cam2 = dir.path().join("cam2.txt");
    std::fs::write(
        &cam2,
        utf16("Feature Name\tX\tY\tZ\r\nP1\t1\t2\t3\r\n", false),
    )
    .unwrap();
    for (file, seen) in [
        (&german, "its header row is `;`-separated"),
        (&cam2, "reads as UTF-16 LE; its header row is tab-separated"),
    ] {
        let out = robopost(&["identify", s(file), "-o", s(&dir.path().join("c.json"))]);
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("required column `test` is missing"), "{err}");
        assert!(err.contains(seen), "{err}");
        assert!(err.contains("robopost import"), "{err}");
    }
    // An export whose point the plan lacks: located in the export.
    let plan = dir.path().join("plan.csv");
    std::fs::write(
        &plan,
        "test,point,a1,a2,a3,a4,a5,a6\nA1,P2,0,-60,100,0,45,0\n",
    )
    .unwrap();
    let out = robopost(&[
        "import",
        s(&german),
        "--plan",
        s(&plan),
        "-o",
        s(&dir.path().join("m.csv")),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("german.csv:2:1"), "{err}");
    assert!(err.contains("plan.csv:2:4"), "{err}");
    assert!(!dir.path().join("m.csv").exists());
}

#[test]
fn the_campaign_passes_check_for_three_robots_and_keeps_out_of_the_box() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (robot, cal) in [
        ("KR 16-2", "kr16-2-nominal.json"),
        ("KR 6 R900 sixx", "kr6r900sixx-nominal.json"),
        ("KR 120 R2500 pro", "kr120r2500pro-nominal.json"),
    ] {
        let src = dir.path().join("cal.src");
        let open = dir.path().join("open.src");
        let description = robopost::calibration::load(&root.join("calibrations").join(cal))
            .unwrap()
            .model_ref()
            .robot;
        let common = [
            "campaign",
            "--robot",
            robot,
            "--tool",
            "0,60,120",
            "--tracker-at",
            "2500,0,700",
            "--floor",
            "50",
        ];
        ok(&[&common[..], &["-o", s(&open)]].concat());
        // A box of ±60 mm around the reflector at the lowest A2 stop of the open campaign.
        let open_plan = parse_plan(
            &std::fs::read(dir.path().join("open_plan.csv")).unwrap(),
            "p",
        )
        .unwrap();
        let low = open_plan
            .stops
            .iter()
            .filter(|st| st.test == "A2")
            .min_by(|a, b| a.axes_deg[1].total_cmp(&b.axes_deg[1]))
            .unwrap();
        let (r, p) = flange_frame(&description, &low.axes_deg);
        let c = p + r * Vector3::new(0.0, 60.0, 120.0);
        let keep_out = [
            c.x - 60.0,
            c.y - 60.0,
            c.z - 60.0,
            c.x + 60.0,
            c.y + 60.0,
            c.z + 60.0,
        ];
        let b = keep_out.map(|v: f64| v.to_string()).join(",");
        ok(&[&common[..], &["--box", &b, "-o", s(&src)]].concat());
        let check = robopost(&[
            "check",
            s(&src),
            "-c",
            s(&root.join("calibrations").join(cal)),
        ]);
        let err = String::from_utf8_lossy(&check.stderr);
        assert_eq!(check.status.code(), Some(0), "{robot}: {err}");
        assert!(
            !err.contains("error") && !err.contains("warning"),
            "{robot}: {err}"
        );
        // Every stop's flange and reflector out of the box, computed here from the plan by the
        // nominal kinematics; the campaign without the box has stops inside it.
        let inside = |plan: &Path| {
            let plan = parse_plan(&std::fs::read(plan).unwrap(), "plan").unwrap();
            plan.stops
                .iter()
                .filter(|st| {
                    let (r, p) = flange_frame(&description, &st.axes_deg);
                    [p, p + r * Vector3::new(0.0, 60.0, 120.0)]
                        .iter()
                        .any(|q| (0..3).all(|k| q[k] >= keep_out[k] && q[k] <= keep_out[k + 3]))
                })
                .count()
        };
        assert_eq!(inside(&dir.path().join("cal_plan.csv")), 0, "{robot}");
        assert!(inside(&dir.path().join("open_plan.csv")) > 0, "{robot}");
    }
}

/// The data of a run as stops, with one measured point moved by `offset_mm`.
fn stops_with_outlier(run: &Run, offset_mm: f64) -> (Vec<Stop>, usize) {
    // The indexing tests only: the reversal tests and the reference pose repeat points, and
    // a floor from repeats does not depend on the tracker's specification.
    let mut stops: Vec<Stop> = read_csv(&run.direct)
        .unwrap()
        .stops
        .into_iter()
        .filter(|s| s.test != "REF" && !s.test.contains("reversal"))
        .collect();
    let i = stops
        .iter()
        .enumerate()
        .filter(|(_, s)| s.test == "A2" && s.measured_mm.is_some())
        .map(|(i, _)| i)
        .nth(20)
        .unwrap();
    if let Some(m) = stops[i].measured_mm.as_mut() {
        m.x += offset_mm;
    }
    (stops, i)
}

#[test]
fn the_tracker_sets_the_noise_floor_and_the_gross_error_threshold() {
    let run = run(None);
    // A 0.2 mm gross error: beyond 5σ of an AT960 (σ = 5 µm + 2.5 µm/m · about 1.5 m, about
    // 9 µm), within 5σ of a tracker of MPE ±(100 µm + 40 µm/m) (σ about 58 µm: 5σ about
    // 290 µm; its robust scale stays 1, the data's noise being far below it).
    let (stops, row) = stops_with_outlier(&run, 0.2);
    let station = Vector3::new(3000.0, 0.0, 800.0);
    let request = |tracker: Tracker| Request {
        tracker: Tracker {
            station_mm: Some(station),
            ..tracker
        },
        ..Request::default()
    };
    let at960 = identify(&stops, &request(Tracker::default())).unwrap();
    let loose = identify(&stops, &request(Tracker::parse("100+40/m").unwrap())).unwrap();
    assert!(
        at960.gross.iter().any(|g| g.row == row),
        "{:?}",
        at960.gross
    );
    assert!(
        !loose.gross.iter().any(|g| g.row == row),
        "{:?}",
        loose.gross
    );
    // The floor from the specification: half the MPE at each point's distance from the
    // station, as an RMS over the measured points — computed here from the data.
    let spec = |c: f64, m: f64| {
        let d: Vec<f64> = stops
            .iter()
            .filter_map(|s| s.measured_mm)
            .map(|p| 0.5 * (c + m * (p - station).norm() / 1000.0))
            .collect();
        (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt()
    };
    let floor = |t: &robopost::identify::pipeline::Identified| t.verdict.noise.rms_um;
    let kind = format!("{:?}", at960.verdict.noise.source);
    if kind.contains("TrackerSpec") {
        // The points of the fit (all but the gross errors) set it: within 0.1 % of all.
        assert!((floor(&at960) / spec(15.0, 6.0) - 1.0).abs() < 1e-3);
        assert!((floor(&loose) / spec(100.0, 40.0) - 1.0).abs() < 1e-3);
    } else {
        panic!("the floor came from repeats: {kind}");
    }
}

/// The example exports of docs/import.md (three points of the measurement CSV example, as each
/// package writes them) all import to the same rows, `fixtures/exports/expected.csv`: the
/// coordinates and times written there by hand from the plan and the points.
#[test]
fn the_documented_example_exports_import_to_the_expected_rows() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/exports");
    let expected = std::fs::read_to_string(dir.join("expected.csv")).unwrap();
    let out = tempfile::tempdir().unwrap();
    for name in [
        "spatial_analyzer.txt",
        "tracker_pilot.csv",
        "cam2_utf16le.txt",
        "polyworks.txt",
        "german_excel.csv",
        "utf16be.txt",
        "stream.csv",
    ] {
        let to = out.path().join(format!("{name}.csv"));
        let export = dir.join(name);
        let mut args = vec!["import", s(&export)];
        let plan = dir.join("plan.csv");
        args.extend(["--plan", s(&plan), "-o", s(&to)]);
        if name == "stream.csv" {
            args.push("--stream");
        }
        ok(&args);
        assert_eq!(std::fs::read_to_string(&to).unwrap(), expected, "{name}");
    }
}

/// `compare --residuals`: a row per measured point whose numbers agree with the measurement
/// file and with themselves, and whose RMS (gross errors left out) is `compare --json`'s.
#[test]
fn compare_writes_every_points_residual() {
    let run = run(None);
    let cal = run.dir.path().join("cal.json");
    ok(&["identify", s(&run.direct), "-o", s(&cal)]);
    let file = run.dir.path().join("residuals.csv");
    let out = robopost(&[
        "compare",
        "-c",
        s(&cal),
        s(&run.direct),
        "--json",
        "--residuals",
        s(&file),
    ]);
    assert!(out.status.success());
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("# robopost-residuals/1"));
    assert!(lines.next().unwrap().starts_with("source,line,test,a1"));
    let measured: Vec<Vector3<f64>> = read_csv(&run.direct)
        .unwrap()
        .stops
        .iter()
        .filter_map(|s| s.measured_mm)
        .collect();
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    assert_eq!(rows.len(), measured.len());
    let (mut ss, mut n) = (0.0, 0);
    for (r, m) in rows.iter().zip(&measured) {
        let f = |i: usize| r[i].parse::<f64>().unwrap();
        assert_eq!([f(10), f(11), f(12)], [m.x, m.y, m.z]);
        for c in 0..3 {
            // The residual in µm is measured − predicted (both written to 0.1 µm).
            assert!((f(16 + c) - (f(10 + c) - f(13 + c)) * 1000.0).abs() < 0.11);
        }
        if r[20] == "0" {
            ss += f(19) * f(19);
            n += 1;
        }
    }
    let rms = (ss / n as f64).sqrt();
    assert!(
        (rms - json["rms_um"].as_f64().unwrap()).abs() < 0.01,
        "{rms} {json}"
    );
}
