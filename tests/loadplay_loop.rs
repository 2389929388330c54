//! Issue 33, case 3, on the physical truth robot: A2's gear rests on the flank its net torque
//! (gravity of both arms and the payload, less a counterbalance spring) presses it onto,
//! whatever the direction of motion; only near zero torque does the direction decide. The
//! truth is the shipped `kr30ha-physical.json` with a wider A2 play (0.03°), friction in A2's
//! train and a counterbalance spring of its own geometry (`simulate::physical`: a tension
//! spring between two pins, not the model's `cos`/`sin` counterbalance); "the robot without
//! the effect" is the same file with the motion alone choosing A2's flank.
//!
//! Checked: the points where the flank jumps are not listed as gross errors (they repeat in
//! both directions and in every A2 test) while a displaced point still is; `diagnose`'s first
//! advice is `loadplay:A2` in place of A2's backlash (judged re-identified with the model, as
//! its printed command identifies it: `diagnose::replace`), and the robot without the effect
//! is not advised it; after the loop (diagnose → add as printed → identify → compensate →
//! execute on the truth) the validation paths land within 1.6× of the robot without the
//! effect (XY mean and Z 2σ).
//!
//! Run with `-- --nocapture` to see the figures.

#[path = "support/readme.rs"]
mod readme;
#[path = "support/tooled.rs"]
mod tooled;
use tooled::with_identified_tool;

use std::path::Path;

use nalgebra::Vector3;
use robopost::calibration::Calibration;
use robopost::diagnose::{diagnose, DiagnoseOptions};
use robopost::identify::pipeline::{identify, Effects, Identified, Request, PAPER_EFFECTS};
use robopost::krl::interpret::Workspace;
use robopost::krl::job::{files, program, Calibrated};
use robopost::measure::{Measurements, Stop};
use robopost::model::{expand_list, Model};
use robopost::motion::{self};
use robopost::simulate::campaign::{DEFAULT_AXIS_SPEED_DEG_S, DEFAULT_DWELL_S};
use robopost::simulate::physical::{self, Counterbalance, PhysicalRobot, PTP_STEP_DEG};
use robopost::simulate::program::program_visits;
use robopost::simulate::Campaign;
use robopost::stats::{error_stats, ErrorStats};

const PATHS: [(&str, f64); 3] = [
    ("paper_path1", 1000.0),
    ("paper_path2", 500.0),
    ("paper_path3", 1500.0),
];
/// A2's play in both robots, degrees.
const A2_PLAY_DEG: f64 = 0.03;
/// Friction in A2's train of the robot with the effect, kN·m.
const A2_FRICTION_KNM: f64 = 0.02;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The physical KR 30 HA with A2's play widened; `loaded`: its flank follows the net torque.
fn truth(loaded: bool) -> PhysicalRobot {
    let path = root().join("fixtures/measurements/kr30ha-physical.json");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut file = physical::parse(&text, &path).unwrap();
    file.gears[1].play_deg = A2_PLAY_DEG;
    if loaded {
        file.gears[1].flank_friction_knm = Some(A2_FRICTION_KNM);
        // Pin on the upper arm 160 mm out along it, pulled towards a pin on the carousel
        // behind the A2 axis: it holds the arm back, and the net torque about A2 crosses zero
        // between A2 −90° and −60° in the A2 tests.
        file.counterbalance = Some(Counterbalance {
            anchor_mm: [-300.0, 100.0],
            lever_mm: 160.0,
            lever_deg: 0.0,
            tension_n: 6000.0,
            length_mm: 400.0,
            rate_n_per_mm: 15.0,
        });
    }
    PhysicalRobot::new(file, &path).unwrap()
}

/// The paper's campaign on `robot`, each row with its line in the CSV it would be written to
/// (so that a calibration's gross errors name them).
fn campaign(robot: &PhysicalRobot) -> Vec<Stop> {
    let plan = Campaign::paper().plan().unwrap();
    let mut rows = robot
        .measure(&physical::from_stops(&plan, PTP_STEP_DEG))
        .unwrap();
    for (i, r) in rows.iter_mut().enumerate() {
        r.line = i + 2;
    }
    rows
}

fn request(effects: Effects, base: Option<Calibration>) -> Request {
    Request {
        effects: Some(effects),
        base,
        sources: vec!["campaign.csv".into()],
        ..Request::default()
    }
}

fn paper(data: &[Stop]) -> Identified {
    let r = request(Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap()), None);
    identify(data, &r).unwrap()
}

/// The rows whose command lies within `margin_deg` of A2 or A3 angles where the truth's net
/// torque about A2 crosses the friction (where A2's flank changes): the points of the effect.
fn effect_rows(robot: &PhysicalRobot, data: &[Stop], margin_deg: f64) -> Vec<usize> {
    let mut rows = Vec::new();
    for (i, s) in data.iter().enumerate() {
        if s.measured_mm.is_none() {
            continue;
        }
        let loaded = |axis: usize, d: f64| {
            let mut a = s.state.axes_deg;
            a[axis] += d;
            robot.net_torques_knm(&a, s.state.time_s)[1].abs() > A2_FRICTION_KNM
        };
        let here = loaded(1, 0.0);
        let steps = (margin_deg / 0.25) as i32;
        if [1, 2]
            .iter()
            .any(|&axis| (-steps..=steps).any(|k| loaded(axis, k as f64 * 0.25) != here))
        {
            rows.push(i);
        }
    }
    rows
}

#[test]
fn structure_is_not_a_gross_error() {
    let robot = truth(true);
    let mut data = campaign(&robot);
    // A real gross error: one point of the A1 test, 0.4 mm off.
    let displaced = data
        .iter()
        .position(|s| s.test == "A1" && s.measured_mm.is_some() && s.state.axes_deg[0] > 10.0)
        .unwrap();
    *data[displaced].measured_mm.as_mut().unwrap() += Vector3::new(0.0, 0.4, 0.0);
    let effect = effect_rows(&robot, &data, 3.0);
    assert!(
        effect.len() > 50,
        "the effect covers {} points",
        effect.len()
    );
    let r = paper(&data);
    let gross: Vec<usize> = r.gross.iter().map(|g| g.row).collect();
    for g in &r.gross {
        println!(
            "gross: row {} {} {:.0} µm: {}",
            g.row, g.test, g.size_um, g.why
        );
    }
    for s in &r.structures {
        println!("systematic: {}", s.describe());
        for &i in &s.rows {
            let st = &data[i];
            println!(
                "   row {i} {} {:?} dir {:?} torque {:.3}",
                st.test,
                st.state.axes_deg,
                st.state.directions(),
                robot.net_torques_knm(&st.state.axes_deg, 0.0)[1]
            );
        }
    }
    let listed: Vec<usize> = gross
        .iter()
        .copied()
        .filter(|g| effect.contains(g))
        .collect();
    assert!(
        listed.is_empty(),
        "points of the effect listed as gross errors: {listed:?}"
    );
    assert!(
        gross.contains(&displaced),
        "the displaced point {displaced}"
    );
    // The jump is reported where it repeats (in the A3 tests, A3 moves A2's torque across
    // the friction band), and what it covers is the effect's.
    let st = r.structures.iter().find(|s| s.axis == 2);
    let st = st.expect("the flank's jump reported as systematic");
    assert!(st.tests >= 2 && st.both_directions, "{st:?}");
    assert!(st.rows.iter().all(|i| effect.contains(i)), "{st:?}");
}

/// Compensates `src` with `model`, writes it under `dir` and reads it back.
fn compensated(src: &Path, model: &Model, dir: &Path) -> Workspace {
    let tooled = dir.join("tooled");
    std::fs::create_dir_all(&tooled).unwrap();
    let src = &with_identified_tool(src, model, &tooled);
    let bytes = std::fs::read(src).unwrap();
    let ws = files::load_program(Some(src), &bytes, None).unwrap();
    let cal = Calibrated::new(model, "identified", b"");
    let result = robopost::krl::job::compensate_program(
        &ws,
        &cal,
        &program::Options {
            parallel: true,
            ..program::Options::default()
        },
    );
    assert!(!result.rejected && result.target_errors == 0);
    let out = dir.join(src.file_name().unwrap());
    files::write_atomic_pieces(&files::outputs(&ws, &result.files, &out)).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    files::load_program(Some(&out), &bytes, None).unwrap()
}

/// Measured − programmed at every stop of the three rectangles of the paths compensated with
/// `model` and run on `robot` after the campaign (`end_s`).
fn path_errors(robot: &PhysicalRobot, model: &Model, end_s: f64, dir: &Path) -> ErrorStats {
    let mut errors = Vec::new();
    for (k, (name, level_z)) in PATHS.iter().enumerate() {
        let src = root().join(format!("fixtures/programs/{name}.src"));
        let bytes = std::fs::read(&src).unwrap();
        let original = files::load_program(Some(&src), &bytes, None).unwrap();
        let points: Vec<(usize, Vector3<f64>)> =
            robopost::krl::interpret::simulate(&original, robot.robot(), &[])
                .stops
                .iter()
                .enumerate()
                .filter(|(_, s)| {
                    s.role == motion::Role::Target && (s.goal.position.z - level_z).abs() < 1e-6
                })
                .map(|(i, s)| (i, s.goal.position))
                .collect();
        let ws = compensated(&src, model, dir);
        let sim = robopost::krl::interpret::simulate(&ws, robot.robot(), &[]);
        assert!(
            !sim.rejected() && sim.unreachable == 0,
            "{:?}",
            sim.diagnostics
        );
        let mut visits = program_visits(&sim, "path", DEFAULT_DWELL_S, DEFAULT_AXIS_SPEED_DEG_S);
        let t0 = end_s + 1800.0 + 900.0 * k as f64;
        for v in &mut visits {
            v.stop.time_s += t0;
        }
        let robot = robot.clone().with_seed(robot.seed() + 100 + k as u64);
        let measured = robot
            .measure(&physical::from_program(&visits, PTP_STEP_DEG))
            .unwrap();
        // Gross tracker errors (0.3–3 mm) are measured again by an experimenter: left out.
        errors.extend(
            points
                .iter()
                .map(|(i, p)| measured[*i].measured_mm.unwrap() - p)
                .filter(|e| e.norm() < 0.25),
        );
    }
    error_stats(&errors)
}

#[test]
fn the_loop_on_case_3_lands_near_the_robot_without_the_effect() {
    let dir = tempfile::tempdir().unwrap();
    // The robot without the effect: the paper's model, compensated paths.
    let plain = truth(false);
    let plain_data = campaign(&plain);
    let plain_end = plain_data.last().unwrap().state.time_s;
    let plain_paper = paper(&plain_data);
    let without = path_errors(
        &plain,
        plain_paper.calibration.model_ref(),
        plain_end,
        dir.path(),
    );

    // Case 3: the paper's model, then the loop.
    let robot = truth(true);
    let data = campaign(&robot);
    let end = data.last().unwrap().state.time_s;
    let first = paper(&data);
    let before = path_errors(&robot, first.calibration.model_ref(), end, dir.path());
    let measurements = Measurements {
        source: "campaign.csv".into(),
        stops: data.clone(),
        ignored_columns: Vec::new(),
    };
    let d = diagnose(
        &first.calibration,
        std::slice::from_ref(&measurements),
        &DiagnoseOptions::default(),
    )
    .unwrap();
    println!("diagnose: {}", d.verdict);
    for f in &d.candidates {
        println!(
            "  {} {:.0}% {} — {}",
            f.effect,
            100.0 * f.explained,
            f.add,
            f.evidence
        );
    }
    for f in d
        .considered
        .iter()
        .filter(|f| f.effect.starts_with("loadplay"))
    {
        println!(
            "  considered {} {:.1}% t {:.1} significant {} vetoed {:?} — {}",
            f.effect,
            100.0 * f.explained,
            f.t_statistic,
            f.significant,
            f.vetoed,
            f.evidence
        );
    }
    // The first advice is the gear play under load in place of A2's backlash, printed as the
    // whole list of effects; followed exactly as printed, it identifies to a physical
    // calibration.
    let advice = d.candidates.first().expect("diagnose advises an effect");
    assert_eq!(advice.effect, "loadplay:A2", "{}", d.verdict);
    assert!(d.verdict.contains(&advice.add), "{}", d.verdict);
    // The README's sentence: the share, the RMS before and after, the values it carries and
    // those of the table it replaces.
    let replaced = first
        .calibration
        .model_ref()
        .effects()
        .iter()
        .find(|e| e.name() == "backlash:A2")
        .map(|e| e.values().len())
        .unwrap();
    readme::assert_prose(
        "loadplay-diagnose",
        &[
            (100.0 * advice.explained).round(),
            d.rms_um,
            advice.rms_after_um,
            advice.parameters as f64,
            replaced as f64,
        ],
        0.5,
    );
    let added = advice
        .add
        .strip_prefix("--effects '")
        .and_then(|a| a.strip_suffix('\''))
        .expect("an --effects option");
    let listed = expand_list(added).unwrap();
    let effects = match added.strip_prefix('+') {
        Some(a) => Effects::Add(expand_list(a).unwrap()),
        None => Effects::Exactly(listed),
    };
    // What it lists: the paper's effects with `loadplay:A2` in place of `backlash:A2`.
    let expected = PAPER_EFFECTS.replace("backlash:A1..A6", "backlash:A1,backlash:A3..A6");
    let mut expected: Vec<String> = expand_list(&format!("{expected},loadplay:A2"))
        .unwrap()
        .iter()
        .map(|n| n.to_string())
        .collect();
    let mut got: Vec<String> = match &effects {
        Effects::Exactly(l) => l.iter().map(|n| n.to_string()).collect(),
        other => panic!("{other:?}"),
    };
    expected.sort();
    got.sort();
    assert_eq!(got, expected);
    let second = identify(&data, &request(effects, Some(first.calibration.clone()))).unwrap();
    assert!(second.verdict.failure.is_none());
    second
        .calibration
        .to_json(Path::new("NEW.json"))
        .expect("a physical calibration");
    // On the robot without the effect the play is plain: no gear play under load is advised.
    let plain_measurements = Measurements {
        source: "campaign.csv".into(),
        stops: plain_data.clone(),
        ignored_columns: Vec::new(),
    };
    let plain_d = diagnose(
        &plain_paper.calibration,
        std::slice::from_ref(&plain_measurements),
        &DiagnoseOptions::default(),
    )
    .unwrap();
    assert!(
        plain_d
            .candidates
            .iter()
            .all(|f| !f.effect.starts_with("loadplay")),
        "{}",
        plain_d.verdict
    );
    let after = path_errors(&robot, second.calibration.model_ref(), end, dir.path());

    let row = |label: &str, s: &ErrorStats| {
        println!(
            "| {label} | {:.1} | {:.1} | {:.1} | {:.1} |",
            s.xy_mean_um, s.xy_2sigma_um, s.z_mean_um, s.z_2sigma_um
        )
    };
    println!("| compensated paths, µm | XY mean | XY 2σ | Z mean | Z 2σ |");
    println!("|---|---|---|---|---|");
    row("robot without the effect, paper model", &without);
    row("case 3, paper model", &before);
    row("case 3, after the loop (loadplay:A2)", &after);
    println!(
        "campaign fit: paper model {:.1} µm RMS, with loadplay:A2 {:.1} µm RMS",
        first.fit.stats.rms_um, second.fit.stats.rms_um
    );
    let values = |s: &ErrorStats| vec![s.xy_mean_um, s.xy_2sigma_um, s.z_mean_um, s.z_2sigma_um];
    // The README's figures, within 2 µm (floating-point differences between machines).
    readme::assert_rows(
        "loadplay-case-3",
        &[
            (
                "the paper's model, robot without the effect",
                values(&without),
            ),
            ("the paper's model, case 3", values(&before)),
            ("with `loadplay:A2`, case 3", values(&after)),
        ],
        2.0,
        1,
    );
    assert!(
        after.xy_mean_um <= 1.6 * without.xy_mean_um,
        "XY mean {:.1} vs {:.1}",
        after.xy_mean_um,
        without.xy_mean_um
    );
    assert!(
        after.z_2sigma_um <= 1.6 * without.z_2sigma_um,
        "Z 2σ {:.1} vs {:.1}",
        after.z_2sigma_um,
        without.z_2sigma_um
    );
}
