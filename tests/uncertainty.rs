//! The predicted uncertainty of compensated targets (`sigma_um` in `--report`): the
//! identification's parameter covariance (the campaign's tracker noise carried through the
//! fit) carried to each target's command. Checked where the answer is known: a virtual robot
//! whose errors the identified model can represent exactly (the shipped example calibration
//! taken as the robot), measured by the default tracker in the paper's campaign under several
//! noise draws, identified, and the paper's three validation paths compensated and run on it
//! without measurement noise — so what is left at each stop is the model's estimation error
//! alone, which `sigma_um` claims to describe. A stated 1σ must hold about 68 % of the
//! coordinates' errors, 2σ about 95 %.

#[path = "support/tooled.rs"]
mod tooled;
use tooled::with_identified_tool;

use std::path::Path;
use std::sync::Arc;

use nalgebra::Vector3;
use robopost::identify::covariance::{self, Covariance};
use robopost::identify::pipeline::{identify, Effects, Request, PAPER_EFFECTS};
use robopost::krl::interpret::Workspace;
use robopost::krl::job::{files, program, Calibrated};
use robopost::measure::read_csv;
use robopost::model::{expand_list, Model};
use robopost::motion::{self};
use robopost::simulate::campaign::{Campaign, DEFAULT_AXIS_SPEED_DEG_S, DEFAULT_DWELL_S};
use robopost::simulate::program::program_visits;
use robopost::simulate::{TrackerNoise, VirtualRobot};

const PATHS: [(&str, f64); 3] = [
    ("paper_path1", 1000.0),
    ("paper_path2", 500.0),
    ("paper_path3", 1500.0),
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn load(path: &Path) -> Workspace {
    let bytes = std::fs::read(path).unwrap();
    files::load_program(Some(path), &bytes, None).unwrap()
}

/// Compensates the program at `src` (its tool the identified target) with `model`, the
/// report listing every target with its uncertainty; returns the compensated program as
/// written and read back, and the report.
fn compensated(
    src: &Path,
    model: &Model,
    covariance: &Arc<Covariance>,
    dir: &Path,
) -> (Workspace, robopost::krl::job::Report) {
    let tooled_dir = dir.join("tooled");
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&tooled_dir).unwrap();
    std::fs::create_dir_all(&out_dir).unwrap();
    let tooled = with_identified_tool(src, model, &tooled_dir);
    let ws = load(&tooled);
    let cal = Calibrated::new(model, "identified", b"");
    let result = robopost::krl::job::compensate_program(
        &ws,
        &cal,
        &program::Options {
            parallel: true,
            points: true,
            uncertainty: Some(covariance.clone()),
            ..program::Options::default()
        },
    );
    assert!(!result.rejected && result.target_errors == 0);
    let out = out_dir.join(src.file_name().unwrap());
    files::write_atomic_pieces(&files::outputs(&ws, &result.files, &out)).unwrap();
    (load(&out), result.report)
}

/// Where `robot` puts every stop of `ws` (measured as its tracker measures).
fn run(ws: &Workspace, robot: &VirtualRobot) -> Vec<Option<Vector3<f64>>> {
    let sim = robopost::krl::interpret::simulate(ws, &robot.truth.robot, &[]);
    assert!(!sim.rejected() && sim.unreachable == 0);
    let visits = program_visits(&sim, "path", DEFAULT_DWELL_S, DEFAULT_AXIS_SPEED_DEG_S);
    robot
        .run_program(&visits)
        .unwrap()
        .into_iter()
        .map(|s| s.measured_mm)
        .collect()
}

/// Per coordinate of every rectangle stop: (|actual error|, stated 1σ), µm.
fn errors_and_sigmas(robot: &VirtualRobot, seed: u64, dir: &Path) -> Vec<(f64, f64)> {
    let campaign = robot
        .clone()
        .with_seed(seed)
        .measure(&Campaign::paper().plan().unwrap())
        .unwrap();
    let request = Request {
        effects: Some(Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap())),
        ..Request::default()
    };
    let identified = identify(&campaign, &request).unwrap();
    let model = identified.calibration.model_ref();
    let cov = identified.fit.covariance().cloned().expect("a covariance");
    let exact = robot.clone().with_noise(TrackerNoise::NONE);
    let mut out = Vec::new();
    for (name, level_z) in PATHS {
        let src = root().join(format!("fixtures/programs/{name}.src"));
        let original = load(&src);
        let sim = robopost::krl::interpret::simulate(&original, &robot.truth.robot, &[]);
        let (ws, report) = compensated(&src, model, &cov, &dir.join(format!("{seed}-{name}")));
        assert_eq!(report.points.len(), sim.stops.len());
        let measured = run(&ws, &exact);
        for (i, stop) in sim.stops.iter().enumerate() {
            let on_rectangle =
                stop.role == motion::Role::Target && (stop.goal.position.z - level_z).abs() < 1e-6;
            if !on_rectangle {
                continue;
            }
            let point = &report.points[i];
            assert!(point.compensated);
            let sigma = point.sigma_um.expect("sigma_um with a covariance");
            let error = (measured[i].unwrap() - stop.goal.position) * 1e3;
            for k in 0..3 {
                out.push((error[k].abs(), sigma[k]));
            }
        }
    }
    out
}

fn within(pairs: &[(f64, f64)], factor: f64) -> f64 {
    pairs.iter().filter(|(e, s)| *e <= factor * s).count() as f64 / pairs.len() as f64
}

#[test]
fn predicted_uncertainty_covers_the_error_at_its_stated_level() {
    let example =
        robopost::calibration::load(&root().join("calibrations/kr30ha-example.json")).unwrap();
    let base = VirtualRobot::load(&root().join("fixtures/measurements/kr30ha-truth.json")).unwrap();
    // The robot is a calibration of the model's own form: nothing the model cannot represent.
    let robot = VirtualRobot {
        truth: example.model(),
        ..base
    };
    let dir = tempfile::tempdir().unwrap();
    let mut pairs = Vec::new();
    for seed in [21, 22, 23] {
        pairs.extend(errors_and_sigmas(&robot, seed, dir.path()));
    }
    let (one, two, half) = (
        within(&pairs, 1.0),
        within(&pairs, 2.0),
        within(&pairs, 0.5),
    );
    let mean_sigma = pairs.iter().map(|p| p.1).sum::<f64>() / pairs.len() as f64;
    let rms_error = (pairs.iter().map(|p| p.0 * p.0).sum::<f64>() / pairs.len() as f64).sqrt();
    println!(
        "{} coordinates: within 1σ {:.1} %, within 2σ {:.1} %, within σ/2 {:.1} %; mean σ {mean_sigma:.1} µm, RMS error {rms_error:.1} µm",
        pairs.len(),
        one * 100.0,
        two * 100.0,
        half * 100.0
    );
    // A normal error lies within 1σ 68.3 % of the time, within 2σ 95.4 %; the stops of a
    // path share the parameters' errors, so three campaigns are fewer independent draws
    // than coordinates: honest bands around those levels.
    assert!((0.55..=0.85).contains(&one), "within 1σ: {one}");
    assert!((0.88..=0.99).contains(&two), "within 2σ: {two}");
    // Half the stated σ (a covariance too optimistic by 2×) would fail the 1σ band: the
    // test can tell.
    assert!(half < 0.55, "within σ/2: {half}");
}

/// `robopost IN.src -c CAL.json -o OUT.src --report R.json --campaign MEAS.csv`: every target
/// of the report has its uncertainty, and it is the one the identification's own fit gives
/// (the covariance rebuilt from the calibration and its campaign equals the fit's).
#[test]
fn report_gives_each_target_its_uncertainty_from_the_campaign() {
    let dir = tempfile::tempdir().unwrap();
    let campaign_path = root().join("fixtures/measurements/campaign.csv");
    let campaign = read_csv(&campaign_path).unwrap();
    let request = Request {
        effects: Some(Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap())),
        ..Request::default()
    };
    let identified = identify(&campaign.stops, &request).unwrap();
    let own = identified.fit.covariance().cloned().unwrap();
    let cal_path = root().join("calibrations/kr30ha-example.json");
    let cal = robopost::calibration::load(&cal_path).unwrap();
    let rebuilt = covariance::of_calibration(&cal, std::slice::from_ref(&campaign)).unwrap();
    assert!((rebuilt.sigma_mm / own.sigma_mm - 1.0).abs() < 0.01);

    let src = root().join("fixtures/programs/paper_path1.src");
    let tooled = with_identified_tool(&src, cal.model_ref(), dir.path());
    let out = dir.path().join("out.src");
    let report_path = dir.path().join("report.json");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_robopost"))
        .arg(&tooled)
        .arg("-c")
        .arg(&cal_path)
        .arg("-o")
        .arg(&out)
        .arg("--report")
        .arg(&report_path)
        .arg("--campaign")
        .arg(&campaign_path)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_path).unwrap()).unwrap();
    let points = report["points"].as_array().unwrap();
    // The same program compensated in the library with the identification's own covariance.
    let ws = load(&tooled);
    let library = robopost::krl::job::compensate_program(
        &ws,
        &Calibrated::new(cal.model_ref(), "example", b""),
        &program::Options {
            parallel: true,
            points: true,
            uncertainty: Some(own),
            ..program::Options::default()
        },
    );
    assert_eq!(points.len(), library.report.points.len());
    let mut largest = 0.0f64;
    for (p, q) in points.iter().zip(&library.report.points) {
        let sigma: Vec<f64> = p["sigma_um"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert!(sigma.iter().all(|s| s.is_finite() && *s > 0.0), "{p}");
        let expected = q.sigma_um.unwrap();
        for k in 0..3 {
            largest = largest.max((sigma[k] / expected[k] - 1.0).abs());
        }
    }
    assert!(largest < 0.02, "rebuilt vs own: {largest}");
    let summary = &report["predicted_sigma_3d_um"];
    assert!(summary["mean"].as_f64().unwrap() > 1.0, "{summary}");
    assert!(summary["max"].as_f64().unwrap() >= summary["mean"].as_f64().unwrap());
    // Without the campaign the report has no uncertainty.
    let plain = dir.path().join("plain.json");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_robopost"))
        .arg(&tooled)
        .arg("-c")
        .arg(&cal_path)
        .arg("-o")
        .arg(dir.path().join("plain.src"))
        .arg("--report")
        .arg(&plain)
        .output()
        .unwrap();
    assert!(run.status.success());
    let text = std::fs::read_to_string(&plain).unwrap();
    assert!(!text.contains("sigma_um"), "{text}");
}
