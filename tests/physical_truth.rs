//! The paper's experiment on a truth that is not the model: the physical KR 30 HA of
//! `fixtures/measurements/kr30ha-physical.json` (`robopost::simulate::physical`: its own
//! chain of joint frames with 6-DOF errors, smooth gear errors off every table grid, a gear
//! play run over the command trajectory, compliance and an inertia crosstalk from the link
//! masses, warm-up growth, and a tracker with a scale error, a registration residual and
//! heavy-tailed noise with gross errors). The paper's campaign is measured on it, the paper's
//! model identified, the three validation paths compensated and run on it again: Table 1.
//!
//! What the model cannot represent shows as a floor above the tracker alone; the figures are
//! the README's (block `physical-table-1`), asserted here within 2 µm.
//!
//! Program runs are expanded into command samples linearly in axis space between the
//! walker's targets (`physical::from_program`) until the walker gives dense samples of each
//! LIN segment.

#[path = "support/campaign_cli.rs"]
mod campaign_cli;
#[path = "support/readme.rs"]
mod readme;
#[path = "support/tooled.rs"]
mod tooled;
use tooled::with_identified_tool;

use std::path::Path;

use nalgebra::Vector3;
use robopost::identify::pipeline::{identify, Effects, Request, PAPER_EFFECTS};
use robopost::krl::interpret::Workspace;
use robopost::krl::job::{files, program, Calibrated};
use robopost::measure::{read_csv, Stop};
use robopost::model::{expand_list, Model};
use robopost::motion::{self};
use robopost::simulate::campaign::{DEFAULT_AXIS_SPEED_DEG_S, DEFAULT_DWELL_S};
use robopost::simulate::physical::{self, PhysicalRobot, PTP_STEP_DEG};
use robopost::simulate::program::{program_visits, visit_states};
use robopost::simulate::Campaign;
use robopost::stats::{error_stats, ErrorStats};

const PATHS: [(&str, f64); 3] = [
    ("paper_path1", 1000.0),
    ("paper_path2", 500.0),
    ("paper_path3", 1500.0),
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn truth() -> PhysicalRobot {
    PhysicalRobot::load(&root().join("fixtures/measurements/kr30ha-physical.json")).unwrap()
}

fn load(path: &Path) -> Workspace {
    let bytes = std::fs::read(path).unwrap();
    files::load_program(Some(path), &bytes, None).unwrap()
}

/// The paper's campaign on the physical robot.
fn campaign(robot: &PhysicalRobot) -> Vec<Stop> {
    let plan = Campaign::paper().plan().unwrap();
    robot
        .measure(&physical::from_stops(&plan, PTP_STEP_DEG))
        .unwrap()
}

/// The measured positions of every stop of `ws` run on `robot`, starting at `t0_s`.
fn run(ws: &Workspace, robot: &PhysicalRobot, t0_s: f64) -> Vec<Option<Vector3<f64>>> {
    let sim = robopost::krl::interpret::simulate(ws, robot.robot(), &[]);
    assert!(
        !sim.rejected() && sim.unreachable == 0,
        "{:?}",
        sim.diagnostics
    );
    let mut visits = program_visits(&sim, "path", DEFAULT_DWELL_S, DEFAULT_AXIS_SPEED_DEG_S);
    for v in &mut visits {
        v.stop.time_s += t0_s;
    }
    robot
        .measure(&physical::from_program(&visits, PTP_STEP_DEG))
        .unwrap()
        .into_iter()
        .map(|s| s.measured_mm)
        .collect()
}

fn rectangle(ws: &Workspace, robot: &PhysicalRobot, level_z: f64) -> Vec<(usize, Vector3<f64>)> {
    robopost::krl::interpret::simulate(ws, robot.robot(), &[])
        .stops
        .iter()
        .enumerate()
        .filter(|(_, s)| {
            s.role == motion::Role::Target && (s.goal.position.z - level_z).abs() < 1e-6
        })
        .map(|(i, s)| (i, s.goal.position))
        .collect()
}

/// The compensated program, written and read back, and how many of its targets had to have
/// their written turn `T` changed to be reachable at all.
///
/// A robopost bug (reported): where compensation holds an axis at 0° to keep the program's
/// `T` ("turn-kept"), the Cartesian target written with its rounded decimals can put that axis
/// a hair below 0°, and the controller refuses the target with the written `T`. The experiment
/// then runs the target with the `T` of the nearest available solution (the same pose); the
/// count is asserted, so a new case does not go unnoticed.
fn compensated(src: &Path, model: &Model, dir: &Path) -> (Workspace, usize) {
    let tooled = dir.join("tooled");
    std::fs::create_dir_all(&tooled).unwrap();
    let src = &with_identified_tool(src, model, &tooled);
    let ws = load(src);
    let cal = Calibrated::new(model, "identified", b"");
    let result = robopost::krl::job::compensate_program(
        &ws,
        &cal,
        &program::Options {
            parallel: true,
            stretching: robopost::compensate::sequence::Stretching::DEFAULT,
            ..program::Options::default()
        },
    );
    assert!(!result.rejected && result.target_errors == 0);
    let out = dir.join(src.file_name().unwrap());
    files::write_atomic_pieces(&files::outputs(&ws, &result.files, &out)).unwrap();
    let written = load(&out);
    let sim = robopost::krl::interpret::simulate(&written, &model.robot, &[]);
    let refused: Vec<(String, usize, String)> = sim
        .diagnostics
        .iter()
        .filter(|d| d.message.contains("no solution with S"))
        .map(|d| (d.file.clone(), d.line, d.message.clone()))
        .collect();
    for (file, line, message) in &refused {
        let text = std::fs::read_to_string(file).unwrap();
        let mut lines: Vec<String> = text.split('\n').map(String::from).collect();
        let numbers: Vec<u32> = message
            .split(|c: char| !c.is_ascii_digit())
            .filter(|t| !t.is_empty())
            .map(|t| t.parse().unwrap())
            .collect();
        // "no solution with S s T t; available (S, T): (s1, t1), (s2, t2), …"
        let (s, t) = (numbers[0], numbers[1]);
        let nearest = numbers[2..]
            .chunks(2)
            .filter(|st| st[0] == s)
            .min_by_key(|st| (st[1] ^ t).count_ones())
            .unwrap()[1];
        let l = &mut lines[line - 1];
        *l = l.replace(&format!("T {t}}}"), &format!("T {nearest}}}"));
        std::fs::write(file, lines.join("\n")).unwrap();
    }
    (load(&out), refused.len())
}

/// The compensation's own residual at each of `points` (programmed positions of the targets,
/// by stop index): the calibrated model's prediction at the written program's commands, with
/// the rotation directions of its motion, less the programmed position. What the iteration's
/// tolerance, the play's inversion and the rounding of the written numbers leave.
fn compensation_residual(
    written: &Workspace,
    model: &Model,
    points: &[(usize, Vector3<f64>)],
) -> Vec<Vector3<f64>> {
    let sim = robopost::krl::interpret::simulate(written, &model.robot, &[]);
    let visits = program_visits(&sim, "path", DEFAULT_DWELL_S, DEFAULT_AXIS_SPEED_DEG_S);
    let states = visit_states(&visits);
    points
        .iter()
        .map(|(i, p)| model.target_position(&states[*i]) - p)
        .collect()
}

fn values(s: &ErrorStats) -> [f64; 4] {
    [s.xy_mean_um, s.xy_2sigma_um, s.z_mean_um, s.z_2sigma_um]
}

#[test]
fn paper_table_one_on_the_physical_truth() {
    let robot = truth();
    let data = campaign(&robot);
    let end = data.last().unwrap().state.time_s;
    let request = |list: &str| Request {
        effects: Some(Effects::Exactly(expand_list(list).unwrap())),
        ..Request::default()
    };
    let full = identify(&data, &request(PAPER_EFFECTS)).unwrap();
    let without = identify(&data, &request("geometric,map:A1..A6,backlash:A1..A6")).unwrap();
    println!(
        "campaign: {} rows, fit RMS {:.1} µm (full model)",
        data.len(),
        full.fit.stats.rms_um
    );

    let error_free = robot.error_free();
    let dir = tempfile::tempdir().unwrap();
    let conditions = [
        "uncompensated",
        "compensated without crosstalk",
        "compensated, full model",
        "tracker alone",
    ];
    let mut errors: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); conditions.len()];
    let mut turned = 0;
    let mut compensation: Vec<Vector3<f64>> = Vec::new();
    for (k, (name, level_z)) in PATHS.iter().enumerate() {
        let src = root().join(format!("fixtures/programs/{name}.src"));
        let original = load(&src);
        // After the campaign, on the warm robot; each path its own tracker draws, the same
        // for every condition.
        let t0 = end + 1800.0 + 900.0 * k as f64;
        let seed = robot.seed() + 100 + k as u64;
        let robot = robot.clone().with_seed(seed);
        let error_free = error_free.clone().with_seed(seed);
        let points = rectangle(&original, &robot, *level_z);
        assert_eq!(points.len(), 49, "{name}");
        let (without_ws, n1) = compensated(&src, without.calibration.model_ref(), dir.path());
        let (full_ws, n2) = compensated(&src, full.calibration.model_ref(), dir.path());
        turned += n1 + n2;
        compensation.extend(compensation_residual(
            &full_ws,
            full.calibration.model_ref(),
            &points,
        ));
        let runs = [
            run(&original, &robot, t0),
            run(&without_ws, &robot, t0),
            run(&full_ws, &robot, t0),
            run(&original, &error_free, t0),
        ];
        for (c, measured) in runs.iter().enumerate() {
            errors[c].extend(points.iter().map(|(i, p)| measured[*i].unwrap() - p));
        }
    }
    println!("compensated targets written unreachable with their T: {turned}");
    // A gross tracker error (0.3–3 mm) hits the same stop in every condition (paired draws);
    // an experimenter sees it and measures again: stops where the tracker alone is off by more
    // than 0.25 mm are left out of every row.
    let gross: Vec<usize> = (0..errors[3].len())
        .filter(|&i| errors[3][i].norm() > 0.25)
        .collect();
    println!("stops with a gross tracker error, left out: {gross:?}");
    for e in &mut errors {
        *e = e
            .iter()
            .enumerate()
            .filter(|(i, _)| !gross.contains(i))
            .map(|(_, v)| *v)
            .collect();
    }
    let stats: Vec<ErrorStats> = errors.iter().map(|e| error_stats(e)).collect();
    // The compensation's own residual (full model), a part of the error budget of the
    // compensated paths: at most the written numbers' rounding (three decimals of a mm, four
    // of a degree: half a unit each, √3·0.5 µm in position and about as much again through
    // the orientation's lever) on top of the solver's 0.1 µm.
    let rms = (compensation.iter().map(|e| e.norm_squared()).sum::<f64>()
        / compensation.len() as f64)
        .sqrt()
        * 1e3;
    let worst = compensation.iter().map(|e| e.norm()).fold(0.0, f64::max) * 1e3;
    let mut sizes: Vec<f64> = compensation.iter().map(|e| e.norm() * 1e3).collect();
    sizes.sort_by(f64::total_cmp);
    let median = sizes[sizes.len() / 2];
    let off: Vec<usize> = (0..compensation.len())
        .filter(|&i| compensation[i].norm() > 0.002)
        .collect();
    println!(
        "compensation's own residual: {rms:.2} µm RMS, median {median:.2} µm, worst {worst:.2} µm; over 2 µm at targets {off:?}"
    );
    assert!(median < 1.0, "{median}");
    // Known (reported): at two targets where A2 reverses inside the motion that reaches them
    // and comes back by less than its play, the model's prediction at the written command
    // misses the target by 3–10 µm. The count is asserted, so a new case does not go unnoticed.
    assert_eq!(off.len(), 2, "{off:?}");
    readme::assert_prose("error-budget-compensation", &[rms, median, worst], 0.1);
    println!("| measured − programmed, µm | XY mean | XY 2σ | Z mean | Z 2σ |");
    println!("|---|---|---|---|---|");
    for (label, s) in conditions.iter().zip(&stats) {
        let v = values(s);
        println!(
            "| {label} | {:.0} | {:.0} | {:.0} | {:.0} |",
            v[0], v[1], v[2], v[3]
        );
    }
    // The README's figures, within 2 µm (the same code and seeds give the same numbers; the
    // tolerance covers floating-point differences between machines).
    let rows: Vec<(&str, Vec<f64>)> = conditions
        .iter()
        .zip(&stats)
        .map(|(label, s)| (*label, values(s).to_vec()))
        .collect();
    readme::assert_rows("physical-table-1", &rows, 2.0, 0);
    assert_eq!(
        turned, 0,
        "{turned} compensated targets were written with a T the robot cannot reach"
    );
    let [uncompensated, without_ct, with_ct, tracker] = [stats[0], stats[1], stats[2], stats[3]];
    // Physical expectations, independent of the figures: compensation removes most of the
    // error, and the model cannot reach the tracker's floor on a robot it does not describe.
    assert!(with_ct.xy_mean_um < 0.5 * uncompensated.xy_mean_um);
    assert!(with_ct.xy_mean_um > tracker.xy_mean_um);
    assert!(without_ct.xy_mean_um > tracker.xy_mean_um);
}

/// The command line runs either kind of truth: `simulate campaign --truth physical.json`
/// writes the same rows as the library, which `identify` reads.
#[test]
fn simulate_campaign_accepts_a_physical_truth() {
    let exe = env!("CARGO_BIN_EXE_robopost");
    let dir = tempfile::tempdir().unwrap();
    let campaign_json = dir.path().join("campaign.json");
    std::fs::write(
        &campaign_json,
        r#"{ "tests": [ { "axis": 1, "from_deg": -10, "to_deg": 10, "pitch_deg": 2,
                        "reference_deg": [0, -60, 100, 0, 45, 0] } ] }"#,
    )
    .unwrap();
    let out = dir.path().join("m.csv");
    let truth_path = root().join("fixtures/measurements/kr30ha-physical.json");
    campaign_cli::simulate_campaign(&truth_path, &campaign_json, Some(4), &out);
    let file = read_csv(&out).unwrap();
    let campaign: robopost::simulate::Campaign =
        serde_json::from_str(&std::fs::read_to_string(&campaign_json).unwrap()).unwrap();
    let expected = truth()
        .with_seed(4)
        .measure(&physical::from_stops(
            &campaign.plan().unwrap(),
            PTP_STEP_DEG,
        ))
        .unwrap();
    assert_eq!(file.stops.len(), expected.len());
    for (row, e) in file.stops.iter().zip(&expected) {
        assert_eq!(row.state.directions(), e.state.directions());
        match (row.measured_mm, e.measured_mm) {
            (Some(a), Some(b)) => assert!((a - b).amax() < 1e-4),
            (None, None) => {}
            other => panic!("{other:?}"),
        }
    }
    // A bad value is named by its JSON path, exit 2, nothing written.
    let text = std::fs::read_to_string(&truth_path).unwrap();
    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        text.replace("\"play_deg\": 0.012", "\"play_deg\": -0.012"),
    )
    .unwrap();
    let never = dir.path().join("never.csv");
    let run = std::process::Command::new(exe)
        .args(["simulate", "campaign", "--truth"])
        .arg(&bad)
        .arg("-o")
        .arg(&never)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("gears[0].play_deg"), "{stderr}");
    assert!(!never.exists());
}

/// The arm of the physical truth alone (its joint frames with their 6-DOF errors; perfect
/// gears, rigid, no growth, a perfect tracker): the paper's geometric model, identified from
/// the campaign, reproduces it to well under a micrometre everywhere, paths included, and the
/// compensated paths land on their programmed points. The two chains share no code, so this
/// checks both: the model's equation (2) and the physical frames describe the same arm.
#[test]
fn joint_frame_errors_alone_are_what_the_paper_model_describes() {
    let mut file = truth().file().clone();
    file.gears = Default::default();
    file.compliance_deg_per_knm = [0.0; 6];
    file.inertia_deg_per_kgm2 = [0.0; 6];
    file.thermal.clear();
    file.tracker = physical::Tracker {
        noise: physical::Noise::NONE,
        ..physical::Tracker::default()
    };
    let robot = PhysicalRobot::new(file, Path::new("arm only")).unwrap();
    let data = campaign(&robot);
    // A1's zero (joint 1's rotation about its axis) is the mean of the A1 map.
    let request = Request {
        effects: Some(Effects::Exactly(expand_list("geometric,map:A1").unwrap())),
        ..Request::default()
    };
    let identified = identify(&data, &request).unwrap();
    let model = identified.calibration.model_ref();
    assert!(
        identified.fit.stats.rms_um < 0.5,
        "{:?}",
        identified.fit.stats
    );
    // Poses the campaign never visited: the paths' stops.
    let dir = tempfile::tempdir().unwrap();
    let mut worst_prediction: f64 = 0.0;
    let mut worst_compensated: f64 = 0.0;
    let mut uncompensated: f64 = 0.0;
    for (name, level_z) in PATHS {
        let src = root().join(format!("fixtures/programs/{name}.src"));
        let original = load(&src);
        let sim = robopost::krl::interpret::simulate(&original, robot.robot(), &[]);
        for (i, p) in rectangle(&original, &robot, level_z) {
            let axes: [f64; 6] = sim.stops[i].nominal_axes.into();
            let truth = robot.target_at(&axes, 0.0);
            let predicted = model.target_position(&robopost::model::AxisState::new(axes));
            worst_prediction = worst_prediction.max((predicted - truth).norm());
            uncompensated = uncompensated.max((truth - p).norm());
        }
        let (ws, turned) = compensated(&src, model, dir.path());
        assert_eq!(turned, 0, "{name}");
        let measured = run(&ws, &robot, 0.0);
        for (i, p) in rectangle(&original, &robot, level_z) {
            worst_compensated = worst_compensated.max((measured[i].unwrap() - p).norm());
        }
    }
    println!(
        "arm only: fit {:.4} µm, worst prediction {:.4} µm, uncompensated {:.0} µm, \
         compensated {:.3} µm",
        identified.fit.stats.rms_um,
        worst_prediction * 1e3,
        uncompensated * 1e3,
        worst_compensated * 1e3
    );
    // The README's figures: the first two within 0.005 µm, the compensated worst within
    // 0.1 µm (written decimals), the uncompensated within 2 µm.
    let b = readme::block("physical-arm-only");
    let written = readme::numbers(&b.text);
    let computed = [
        identified.fit.stats.rms_um,
        worst_prediction * 1e3,
        worst_compensated * 1e3,
        uncompensated * 1e3,
    ];
    for (k, tolerance) in [0.005, 0.005, 0.1, 2.0].iter().enumerate() {
        assert!(
            (written[k] - computed[k]).abs() <= *tolerance,
            "README physical-arm-only: {written:?} vs {computed:?}"
        );
    }
    assert!(uncompensated > 0.2, "the arm's errors are visible");
    assert!(worst_prediction < 1e-3, "{worst_prediction} mm");
    // The written decimals (1 µm, 1e-4°) and the solver's 0.1 µm.
    assert!(worst_compensated < 2e-3, "{worst_compensated} mm");
}

/// What the floor is made of: the physical truth's effects taken away one after another (each
/// row keeps the removals above it), the paper's model identified and the paths compensated
/// again: the full model's Table 1 row for each (README block `physical-floor`, within 2 µm).
#[test]
fn the_floor_taken_apart() {
    let file = truth().file().clone();
    let mut variants: Vec<(&str, physical::PhysicalTruthFile)> = Vec::new();
    let mut f = file;
    f.tracker.noise.gross_probability = 0.0;
    variants.push(("without gross tracker errors", f.clone()));
    f.tracker.noise = physical::Noise::NONE;
    variants.push(("… nor tracker noise", f.clone()));
    f.tracker.scale_ppm = 0.0;
    f.tracker.frame = None;
    variants.push(("… nor tracker scale and registration errors", f.clone()));
    f.thermal.clear();
    variants.push(("… nor warm-up growth", f.clone()));
    for gear in &mut f.gears {
        gear.play_deg = 0.0;
    }
    variants.push(("… nor gear play", f.clone()));
    f.compliance_deg_per_knm = [0.0; 6];
    f.inertia_deg_per_kgm2 = [0.0; 6];
    variants.push(("… nor compliance and inertia crosstalk", f.clone()));
    for gear in &mut f.gears {
        gear.harmonics.retain(|h| h.period_deg > 5.0);
    }
    variants.push(("… nor gear harmonics shorter than 5°", f.clone()));
    let mut rows: Vec<(&str, Vec<f64>)> = Vec::new();
    for (label, file) in variants {
        let robot = PhysicalRobot::new(file, Path::new(label)).unwrap();
        let data = campaign(&robot);
        let end = data.last().unwrap().state.time_s;
        let request = Request {
            effects: Some(Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap())),
            ..Request::default()
        };
        let full = identify(&data, &request).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let mut errors = Vec::new();
        for (k, (name, level_z)) in PATHS.iter().enumerate() {
            let src = root().join(format!("fixtures/programs/{name}.src"));
            let original = load(&src);
            let t0 = end + 1800.0 + 900.0 * k as f64;
            let robot = robot.clone().with_seed(robot.seed() + 100 + k as u64);
            let (ws, _) = compensated(&src, full.calibration.model_ref(), dir.path());
            let measured = run(&ws, &robot, t0);
            let points = rectangle(&original, &robot, *level_z);
            errors.extend(points.iter().map(|(i, p)| measured[*i].unwrap() - p));
        }
        let s = error_stats(&errors);
        let row = [
            full.fit.stats.rms_um,
            s.xy_mean_um,
            s.xy_2sigma_um,
            s.z_mean_um,
            s.z_2sigma_um,
        ];
        println!(
            "| {label} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} |",
            row[0], row[1], row[2], row[3], row[4]
        );
        rows.push((label, row.to_vec()));
    }
    readme::assert_rows("physical-floor", &rows, 2.0, 0);
}

/// Diagnosis on the physical truth (its gross tracker errors left out: they are a handful of
/// points that dominate any RMS, see Table 1): the paper's model identified from the campaign
/// and 200 poses with every axis moving; `diagnose` must name as missing an effect the truth
/// really has and the paper's model lacks — the truth deflects A3 under gravity (which at one
/// payload is the twin of a crosstalk A2 → A3), A2, A4, A5 too, and grows as it warms up.
/// What adding the finding does on 200 other poses that no fit saw is measured and stated.
#[test]
fn diagnose_names_what_the_physical_truth_has() {
    use robopost::compare::{self, Summary};
    use robopost::diagnose::{diagnose, DiagnoseOptions};
    use robopost::measure::Measurements;

    let mut file = truth().file().clone();
    file.tracker.noise.gross_probability = 0.0;
    let robot = PhysicalRobot::new(file, Path::new("no gross errors")).unwrap();
    let poses = |seed: u64, t0: f64, label: &str| {
        robopost::simulate::poses::random_poses(seed, 200, t0, label)
    };
    let mut plan = Campaign::paper().plan().unwrap();
    let end = plan.last().unwrap().time_s;
    plan.extend(poses(7, end + 60.0, "poses"));
    let data = robot
        .measure(&physical::from_stops(&plan, PTP_STEP_DEG))
        .unwrap();
    let held_out = robot
        .clone()
        .with_seed(99)
        .measure(&physical::from_stops(
            &poses(8, end + 1500.0, "held-out"),
            PTP_STEP_DEG,
        ))
        .unwrap();
    let request = |base: Option<robopost::calibration::Calibration>, effects: Effects| Request {
        effects: Some(effects),
        base,
        ..Request::default()
    };
    let old = identify(
        &data,
        &request(None, Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap())),
    )
    .unwrap()
    .calibration;
    let file_of = |stops: &[Stop], name: &str| Measurements {
        source: name.into(),
        stops: stops.to_vec(),
        ignored_columns: vec![],
    };
    let d = diagnose(&old, &[file_of(&data, "data")], &DiagnoseOptions::default()).unwrap();
    let top = d
        .candidates
        .first()
        .unwrap_or_else(|| panic!("{}", d.verdict));
    println!("{}", d.verdict);
    for c in &d.candidates {
        println!(
            "  {} {:.0}% → {:.1} µm",
            c.effect,
            100.0 * c.explained,
            c.rms_after_um
        );
    }
    let present = [
        "compliance:A2",
        "compliance:A3",
        "compliance:A4",
        "compliance:A5",
        "drift",
    ];
    let physical_cause = present.contains(&top.effect.as_str())
        || (top.effect == "crosstalk:A2->A3"
            && top
                .indistinguishable_from
                .iter()
                .any(|e| e == "compliance:A3"));
    assert!(
        physical_cause,
        "diagnose names {} (twins {:?}), which the truth does not have",
        top.effect, top.indistinguishable_from
    );
    let new = identify(
        &data,
        &request(
            Some(old.clone()),
            Effects::Add(expand_list(&top.effect).unwrap()),
        ),
    )
    .unwrap()
    .calibration;
    let squares = |cal: &robopost::calibration::Calibration| -> Vec<f64> {
        compare::compare(cal, &[file_of(&held_out, "held-out")])
            .iter()
            .map(|r| (r.residual() * 1e3).norm_squared())
            .collect()
    };
    let (before, after) = (squares(&old), squares(&new));
    let n = before.len() as f64;
    let gain: Vec<f64> = before.iter().zip(&after).map(|(b, a)| b - a).collect();
    let mean = gain.iter().sum::<f64>() / n;
    let se = (gain.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    let rms = |v: &[f64]| (v.iter().sum::<f64>() / n).sqrt();
    let stats = |cal| {
        Summary::residuals(&compare::compare(cal, &[file_of(&held_out, "held-out")]))
            .all
            .rms_um
    };
    println!(
        "held-out RMS {:.1} → {:.1} µm (gain {mean:.0} ± {se:.0} µm²)",
        rms(&before),
        rms(&after)
    );
    assert!((stats(&old) - rms(&before)).abs() < 1e-6);
    // What it does on poses no fit saw is reported, not required: on this truth the finding
    // that cross-validation over the campaign's own points credits does not lower the error at
    // arbitrary poses (README). It must not make it significantly worse.
    assert!(
        mean > -3.0 * se,
        "adding {} makes the held-out error worse: {mean} ± {se} µm²",
        top.effect
    );
    readme::assert_prose(
        "physical-diagnose",
        &[
            100.0 * top.explained,
            d.rms_um,
            top.rms_after_um,
            n,
            rms(&before),
            rms(&after),
        ],
        0.15,
    );
}

/// The full model's and the tracker alone's Table 1 rows (µm) on the physical truth after
/// the campaign `plan`, identified with `effects` and `map:`/`backlash:` tables at
/// `map_pitch_deg` from every measured point (no thinning): the same three paths, compensated and run half an hour after the
/// campaign, with the same tracker draws as the tracker alone, and the stops with a gross
/// tracker error left out of both rows (as in Table 1).
fn after_campaign(
    robot: &PhysicalRobot,
    plan: &[robopost::simulate::campaign::PlannedStop],
    effects: &str,
    map_pitch_deg: f64,
) -> [ErrorStats; 2] {
    let data = robot
        .measure(&physical::from_stops(plan, PTP_STEP_DEG))
        .unwrap();
    let end = data.last().unwrap().state.time_s;
    let mut request = Request {
        effects: Some(Effects::Exactly(expand_list(effects).unwrap())),
        ..Request::default()
    };
    request.grid.map_pitch_deg = map_pitch_deg;
    request.max_points = Some(0);
    let full = identify(&data, &request).unwrap();
    println!(
        "campaign {} rows, {:.1} h, fit {:.1} µm",
        data.len(),
        end / 3600.0,
        full.fit.stats.rms_um
    );
    let error_free = robot.error_free();
    let dir = tempfile::tempdir().unwrap();
    let mut errors: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); 2];
    for (k, (name, level_z)) in PATHS.iter().enumerate() {
        let src = root().join(format!("fixtures/programs/{name}.src"));
        let original = load(&src);
        let t0 = end + 1800.0 + 900.0 * k as f64;
        let seed = robot.seed() + 100 + k as u64;
        let robot = robot.clone().with_seed(seed);
        let error_free = error_free.clone().with_seed(seed);
        let points = rectangle(&original, &robot, *level_z);
        let (full_ws, turned) = compensated(&src, full.calibration.model_ref(), dir.path());
        assert_eq!(turned, 0);
        let runs = [run(&full_ws, &robot, t0), run(&original, &error_free, t0)];
        for (c, measured) in runs.iter().enumerate() {
            errors[c].extend(points.iter().map(|(i, p)| measured[*i].unwrap() - p));
        }
    }
    let gross: Vec<usize> = (0..errors[1].len())
        .filter(|&i| errors[1][i].norm() > 0.25)
        .collect();
    for e in &mut errors {
        *e = e
            .iter()
            .enumerate()
            .filter(|(i, _)| !gross.contains(i))
            .map(|(_, v)| *v)
            .collect();
    }
    let stats = [error_stats(&errors[0]), error_stats(&errors[1])];
    let labels = ["compensated, full model", "tracker alone"];
    for (label, s) in labels.iter().zip(&stats) {
        let v = values(s);
        println!(
            "| {label} | {:.0} | {:.0} | {:.0} | {:.0} |",
            v[0], v[1], v[2], v[3]
        );
    }
    stats
}

/// `stats` (the full model's and the tracker alone's rows) against the README block `name`,
/// within 2 µm.
fn assert_table(name: &str, stats: &[ErrorStats; 2]) {
    let labels = ["compensated, full model", "tracker alone"];
    readme::assert_rows(
        name,
        &labels
            .iter()
            .zip(stats)
            .map(|(l, s)| (*l, values(s).to_vec()))
            .collect::<Vec<_>>(),
        2.0,
        0,
    );
}

/// The error budget names the warm-up between the campaign and the paths, the identification's
/// noise and the model form. The recommended campaign (the paper's tests run three times,
/// the crosstalk at seven A3 angles: `Campaign::recommended`, 10.8 hours) answers the first
/// two: the robot is warm for most of it, and four times the points average the tracker's
/// noise down. Identified from it on the physical truth, the same three paths, compensated
/// and run half an hour after it, with the same tracker draws as the tracker alone.
#[test]
fn the_recommended_campaign_on_the_physical_truth() {
    let plan = Campaign::recommended().plan().unwrap();
    let stats = after_campaign(&truth(), &plan, PAPER_EFFECTS, 1.0);
    assert_table("physical-table-1-recommended", &stats);
    // Physical expectations, independent of the figures: the model still does not reach the
    // tracker alone, and comes within the issue's 1.15× of it in the XY mean.
    let [model, tracker] = stats;
    assert!(model.xy_mean_um > tracker.xy_mean_um);
    assert!(model.xy_mean_um < 1.15 * tracker.xy_mean_um);
}

/// What is left after the recommended campaign is the model form (README, "An error budget"):
/// with the tracker perfect and the model fitting its campaign to 0.0 µm, the gear harmonics
/// alone leave 8 µm (1σ, Z) at the paths, because a 1° table interpolates linearly between
/// the campaign's stops what turns with periods of 3 to 7°; and the gravity deflection of A3
/// depends on A2, which no table over A3 alone follows. The fine campaign
/// (`fixtures/campaigns/fine.json`: the recommended one at half the pitch, 21.4 hours)
/// identified with 0.5° tables from all its points (`--map-pitch 0.5 --max-points 0`) and the truth's compliance of A2 and A3
/// answers both: within 1.15× of the tracker alone in the XY mean and the Z 2σ.
#[test]
fn the_fine_campaign_on_the_physical_truth() {
    let path = root().join("fixtures/campaigns/fine.json");
    let fine: Campaign = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let mut expected = Campaign::recommended();
    for t in &mut expected.tests {
        t.pitch_deg = 0.5;
    }
    assert_eq!(
        fine, expected,
        "fine.json is the recommended campaign at 0.5°"
    );
    let effects = format!("{PAPER_EFFECTS},compliance:A2,compliance:A3");
    let stats = after_campaign(&truth(), &fine.plan().unwrap(), &effects, 0.5);
    assert_table("physical-table-1-fine", &stats);
    // The issue's criterion, independent of the figures: within 1.15× of the tracker alone.
    let [model, tracker] = stats;
    assert!(model.xy_mean_um < 1.15 * tracker.xy_mean_um);
    assert!(model.z_2sigma_um < 1.15 * tracker.z_2sigma_um);
}

/// The model form after a campaign, measured alone: the physical truth with a perfect tracker,
/// no warm-up and no gear play (its joint frames, gear harmonics, compliance and inertia
/// crosstalk kept), the paths compensated and run as in Table 1. What is left at the paths is
/// what the model does not describe there (README block `physical-model-form`, within 2 µm):
/// the tables' linear interpolation between the campaign's stops, and A3's gravity deflection,
/// which depends on A2 as well.
#[test]
fn the_model_form_the_fine_campaign_removes() {
    let mut file = truth().file().clone();
    file.tracker.noise = physical::Noise::NONE;
    file.tracker.scale_ppm = 0.0;
    file.tracker.frame = None;
    file.thermal.clear();
    for gear in &mut file.gears {
        gear.play_deg = 0.0;
    }
    let robot = PhysicalRobot::new(file, Path::new("model form only")).unwrap();
    let recommended = Campaign::recommended().plan().unwrap();
    let mut fine = Campaign::recommended();
    for t in &mut fine.tests {
        t.pitch_deg = 0.5;
    }
    let fine = fine.plan().unwrap();
    let compliance = format!("{PAPER_EFFECTS},compliance:A2,compliance:A3");
    let cases = [
        (
            "recommended campaign, the paper's model",
            &recommended,
            PAPER_EFFECTS,
            1.0,
        ),
        (
            "fine campaign, the paper's model",
            &fine,
            PAPER_EFFECTS,
            0.5,
        ),
        (
            "fine campaign, and compliance:A2, A3",
            &fine,
            compliance.as_str(),
            0.5,
        ),
    ];
    let mut rows: Vec<(&str, Vec<f64>)> = Vec::new();
    for (label, plan, effects, pitch) in cases {
        let [model, tracker] = after_campaign(&robot, plan, effects, pitch);
        // A perfect tracker reads the error-free robot exactly.
        assert!(tracker.d3_max_um < 1e-6, "{tracker:?}");
        rows.push((label, vec![model.xy_mean_um, model.z_2sigma_um]));
    }
    for (label, row) in &rows {
        println!("| {label} | {:.0} | {:.0} |", row[0], row[1]);
    }
    readme::assert_rows("physical-model-form", &rows, 2.0, 0);
    // Each step removes a part of the model form, in the XY mean and in the Z 2σ.
    for k in 1..rows.len() {
        assert!(rows[k].1[1] < rows[k - 1].1[1], "{rows:?}");
    }
    assert!(rows[2].1[0] < rows[0].1[0], "{rows:?}");
}
