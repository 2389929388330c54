//! Issue 33's harness: effects outside the model's table, drawn at random, on the physical
//! truth robot. The truth is the shipped `kr30ha-physical.json` with what the paper's model
//! cannot carry switched off (compliance, inertia, thermal growth), so that the drawn effect is
//! the only thing missing; it is added to every measured position as the displacement it
//! causes at the commanded pose and time. Families: an axis angle deviation following the
//! forearm's angle to gravity (case 1), a mount tilting with the arm's reach (case 2), an
//! angle deviation that steps where another axis crosses a threshold, one that follows an
//! arm axis's gravity torque squared, a slow drift in time, and a height that steps with the
//! reach; sizes 20–150 µm at the campaign's typical reach.
//!
//! For each draw: the paper's model identified on the campaign; `diagnose` given the campaign
//! and the first path measured after it (as a user who measured a validation path runs it);
//! its first advice followed exactly as printed (identified on both files); both calibrations
//! compared on the two paths measured later still, which nothing learnt from. Asserted: the
//! first advice identifies (its calibration is physical); it is never worse on the later paths
//! than adding nothing (explained ≥ −2 %); on the clean robot nothing is recommended. Printed
//! (`-- --nocapture`): the median gain, and the gain over the paper's model re-identified on
//! the same two files without the advice (stricter: it separates the effect from the path
//! added to the fit).
//!
//! `twenty_hidden_effects` takes some ten minutes and is run by hand
//! (`cargo test --test diagnose_hidden -- --ignored --nocapture`). Measured (2026-12-02): 20
//! draws, 0 worse than adding nothing, median gain +18 %; over the re-identified model 1 draw
//! is worse by 2.1 % of the sum of squares (a 33 µrad/m mount tilt advised `compliance:A3`:
//! 28.3 → 28.6 µm RMS), median +2.6 %; 8 draws get no advice.

use std::path::Path;

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robopost::calibration::Calibration;
use robopost::compare;
use robopost::diagnose::{diagnose, DiagnoseOptions, Finding};
use robopost::identify::pipeline::{identify, Effects, Request, PAPER_EFFECTS};
use robopost::krl::job::files;
use robopost::measure::{Measurements, Stop};
use robopost::model::expand_list;
use robopost::simulate::campaign::{DEFAULT_AXIS_SPEED_DEG_S, DEFAULT_DWELL_S};
use robopost::simulate::physical::{self, PhysicalRobot, PTP_STEP_DEG};
use robopost::simulate::program::program_visits;
use robopost::simulate::Campaign;

const PATHS: [&str; 3] = ["paper_path1", "paper_path2", "paper_path3"];
/// Advice "worse" on the later paths: it removes less than this share of their residual (the
/// cross-validation's own bound, `crossval::WORSE_EXPLAINED`).
const WORSE: f64 = -0.02;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The physical KR 30 HA with only what the paper's model describes.
fn clean_truth() -> PhysicalRobot {
    let path = root().join("fixtures/measurements/kr30ha-physical.json");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut file = physical::parse(&text, &path).unwrap();
    file.compliance_deg_per_knm = [0.0; 6];
    file.inertia_deg_per_kgm2 = [0.0; 6];
    file.thermal.clear();
    // The tracker's registration residual to the base frame (0.0008° about X and Y) is
    // missing from a model identified in the base frame as well: seen from the turning A1 it
    // is a first harmonic of A1's tilt, and with a path measured after the campaign
    // `diagnose` rightly finds `tilt:A1` on it (later paths 30.1 → 23.8 µm RMS). It is a
    // hidden effect of its own, so the clean robot has a perfectly registered tracker; the
    // noise and the gross errors stay.
    file.tracker.frame = None;
    file.tracker.scale_ppm = 0.0;
    PhysicalRobot::new(file, &path).unwrap()
}

/// A hidden effect: what it does to a commanded pose at a time.
#[derive(Clone, Debug)]
enum Hidden {
    /// Axis `axis`'s angle deviates by `deg · cos(A2 + A3 + phase)`: the forearm's angle to
    /// gravity (case 1).
    ForearmGravity {
        axis: usize,
        deg: f64,
        phase_deg: f64,
    },
    /// The mount tilts about the base's `about` axis (0: X, 1: Y) by `urad_per_m` per metre
    /// of reach (the flange's distance from the A1 axis) (case 2).
    MountTilt { about: usize, urad_per_m: f64 },
    /// Axis `axis` deviates by `deg` where axis `by` is beyond `at_deg`, by −`deg` below.
    AngleStep {
        axis: usize,
        by: usize,
        at_deg: f64,
        deg: f64,
    },
    /// Axis `axis` deviates by `deg · (τ/τ_max)²` with τ the gravity torque of axis `by`.
    TorqueSquared { axis: usize, by: usize, deg: f64 },
    /// The target drifts by `um_per_h` along `dir` per hour.
    Drift { dir: Vector3<f64>, um_per_h: f64 },
    /// The height steps by `um` where the reach passes `at_mm`.
    ReachStep { at_mm: f64, um: f64 },
}

impl Hidden {
    /// The displacement of the measured target at `stop`'s commanded pose and time, mm.
    fn displacement(&self, robot: &PhysicalRobot, stop: &Stop) -> Vector3<f64> {
        let a = stop.state.axes_deg;
        let t = stop.state.time_s;
        let angle = |axis: usize, deg: f64| {
            let mut b = a;
            b[axis] += deg;
            robot.target_at(&b, t) - robot.target_at(&a, t)
        };
        let here = robot.target_at(&a, t);
        let reach_mm = here.xy().norm();
        match *self {
            Hidden::ForearmGravity {
                axis,
                deg,
                phase_deg,
            } => angle(axis, deg * (a[1] + a[2] + phase_deg).to_radians().cos()),
            Hidden::MountTilt { about, urad_per_m } => {
                let theta = urad_per_m * 1e-6 * reach_mm / 1000.0;
                let axis = if about == 0 {
                    Vector3::x_axis()
                } else {
                    Vector3::y_axis()
                };
                nalgebra::Rotation3::from_axis_angle(&axis, theta) * here - here
            }
            Hidden::AngleStep {
                axis,
                by,
                at_deg,
                deg,
            } => angle(axis, if a[by] > at_deg { deg } else { -deg }),
            Hidden::TorqueSquared { axis, by, deg } => {
                let tau = robot.net_torques_knm(&a, t)[by];
                angle(axis, deg * (tau / 1.2).powi(2))
            }
            Hidden::Drift { dir, um_per_h } => dir * um_per_h * 1e-3 * t / 3600.0,
            Hidden::ReachStep { at_mm, um } => {
                Vector3::new(0.0, 0.0, if reach_mm > at_mm { um } else { 0.0 } * 1e-3)
            }
        }
    }
}

/// An angle whose effect at about 1.2 m from the axis is `um`.
fn deg_for(um: f64) -> f64 {
    (um * 1e-3 / 1200.0).to_degrees()
}

/// Draw `k`: a family in turn, its parameters and size (20–150 µm) at random.
fn draw(k: usize, rng: &mut ChaCha8Rng) -> Hidden {
    let um = rng.gen_range(20.0..150.0);
    match k % 6 {
        0 => Hidden::ForearmGravity {
            axis: rng.gen_range(1..3),
            deg: deg_for(um),
            phase_deg: rng.gen_range(-90.0..90.0),
        },
        1 => Hidden::MountTilt {
            about: rng.gen_range(0..2),
            urad_per_m: um / 1.5,
        },
        2 => Hidden::AngleStep {
            axis: rng.gen_range(0..3),
            by: rng.gen_range(0..3),
            at_deg: rng.gen_range(-60.0..60.0),
            deg: deg_for(um) / 2.0,
        },
        3 => Hidden::TorqueSquared {
            axis: rng.gen_range(0..3),
            by: rng.gen_range(1..3),
            deg: deg_for(um),
        },
        4 => {
            let d = Vector3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            Hidden::Drift {
                dir: d.normalize(),
                um_per_h: um / 3.0,
            }
        }
        _ => Hidden::ReachStep {
            at_mm: rng.gen_range(900.0..1500.0),
            um,
        },
    }
}

/// The paper's campaign and the three paths run after it, measured on `robot` (one list of
/// stops per path, in time order).
struct Measured {
    campaign: Vec<Stop>,
    paths: Vec<Vec<Stop>>,
}

fn measure(robot: &PhysicalRobot) -> Measured {
    let plan = Campaign::paper().plan().unwrap();
    let mut campaign = robot
        .measure(&physical::from_stops(&plan, PTP_STEP_DEG))
        .unwrap();
    for (i, r) in campaign.iter_mut().enumerate() {
        r.line = i + 2;
    }
    let end = campaign.last().unwrap().state.time_s;
    let mut paths = Vec::new();
    for (k, name) in PATHS.iter().enumerate() {
        let src = root().join(format!("fixtures/programs/{name}.src"));
        let bytes = std::fs::read(&src).unwrap();
        let ws = files::load_program(Some(&src), &bytes, None).unwrap();
        let sim = robopost::krl::interpret::simulate(&ws, robot.robot(), &[]);
        let mut visits = program_visits(&sim, "path", DEFAULT_DWELL_S, DEFAULT_AXIS_SPEED_DEG_S);
        for v in &mut visits {
            v.stop.time_s += end + 1800.0 + 900.0 * k as f64;
        }
        let robot = robot.clone().with_seed(robot.seed() + 100 + k as u64);
        let rows = robot
            .measure(&physical::from_program(&visits, PTP_STEP_DEG))
            .unwrap();
        paths.push(
            rows.into_iter()
                .filter(|r| r.measured_mm.is_some())
                .collect(),
        );
    }
    Measured { campaign, paths }
}

fn with_hidden(robot: &PhysicalRobot, stops: &[Stop], hidden: Option<&Hidden>) -> Vec<Stop> {
    let mut out = stops.to_vec();
    if let Some(h) = hidden {
        for s in &mut out {
            let d = h.displacement(robot, s);
            if let Some(m) = s.measured_mm.as_mut() {
                *m += d;
            }
        }
    }
    out
}

fn files_of(source: &str, stops: Vec<Stop>) -> Vec<Measurements> {
    vec![Measurements {
        source: source.into(),
        stops,
        ignored_columns: Vec::new(),
    }]
}

/// RMS 3-D residual of `cal` on `paths`, µm, gross tracker errors (over 0.25 mm) left out.
fn rms_on(cal: &Calibration, paths: &[Measurements]) -> f64 {
    let r: Vec<f64> = compare::compare(cal, paths)
        .iter()
        .map(|r| r.residual().norm_squared())
        .filter(|e| *e < 0.25 * 0.25)
        .collect();
    (r.iter().sum::<f64>() / r.len() as f64).sqrt() * 1000.0
}

/// The effects an advice's `add` option identifies.
fn effects_of(advice: &Finding) -> Effects {
    let added = advice
        .add
        .strip_prefix("--effects '")
        .and_then(|a| a.strip_suffix('\''))
        .expect("an --effects option");
    match added.strip_prefix('+') {
        Some(a) => Effects::Add(expand_list(a).unwrap()),
        None => Effects::Exactly(expand_list(added).unwrap()),
    }
}

/// What one draw measured on the later paths (RMS 3-D, µm).
struct Outcome {
    advice: Option<String>,
    /// The calibration identified on the campaign (adding nothing).
    before: f64,
    /// The paper's model re-identified on what `diagnose` saw, without the advice.
    reidentified: f64,
    /// The advice followed as printed.
    after: f64,
}

/// One draw. `diagnose` is given the campaign and the first path measured after it, as a user
/// who measured a validation path would (`diagnose -c paper.json campaign.csv path1.csv`);
/// its first advice is followed exactly as printed (`identify -c paper.json campaign.csv
/// path1.csv --effects …`) and judged on the two paths measured later still, which nothing
/// learnt from.
fn run(robot: &PhysicalRobot, base: &Measured, hidden: Option<&Hidden>) -> Outcome {
    let campaign = with_hidden(robot, &base.campaign, hidden);
    let path1 = with_hidden(robot, &base.paths[0], hidden);
    let later: Vec<Stop> = base.paths[1..]
        .iter()
        .flat_map(|p| with_hidden(robot, p, hidden))
        .collect();
    let later = files_of("later.csv", later);
    let mut seen = campaign.clone();
    seen.extend(path1.iter().cloned());
    let mut file_of = vec![0; campaign.len()];
    file_of.resize(seen.len(), 1);
    let request = |effects: Effects, base: Option<Calibration>, two: bool| Request {
        effects: Some(effects),
        base,
        sources: if two {
            vec!["campaign.csv".into(), "path1.csv".into()]
        } else {
            vec!["campaign.csv".into()]
        },
        file_of: if two { file_of.clone() } else { Vec::new() },
        max_points: Some(robopost::identify::thin::DEFAULT_MAX_POINTS),
        ..Request::default()
    };
    let paper = || Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap());
    let cal = identify(&campaign, &request(paper(), None, false))
        .unwrap()
        .calibration;
    let before = rms_on(&cal, &later);
    let reidentified = identify(&seen, &request(paper(), Some(cal.clone()), true))
        .map(|r| rms_on(&r.calibration, &later))
        .unwrap_or(f64::NAN);
    let mut files = files_of("campaign.csv", campaign);
    files.extend(files_of("path1.csv", path1));
    let d = diagnose(&cal, &files, &DiagnoseOptions::default()).unwrap();
    for f in d.considered.iter().take(4) {
        println!(
            "   considered: {} {:+.0}% t {:.1}{}",
            f.effect,
            100.0 * f.explained,
            f.t_statistic,
            if f.significant { ", significant" } else { "" }
        );
    }
    for f in d.considered.iter().filter(|f| f.vetoed.is_some()) {
        println!(
            "   not a finding: {} — {}",
            f.effect,
            f.vetoed.as_deref().unwrap_or_default()
        );
    }
    let Some(advice) = d.candidates.first() else {
        return Outcome {
            advice: None,
            before,
            reidentified,
            after: before,
        };
    };
    // Followed exactly as printed: it identifies, to a calibration `identify` writes.
    let followed = identify(&seen, &request(effects_of(advice), Some(cal.clone()), true))
        .unwrap_or_else(|e| panic!("{hidden:?}: {} fails: {e}", advice.effect));
    followed
        .calibration
        .to_json(Path::new("NEW.json"))
        .unwrap_or_else(|e| panic!("{hidden:?}: {} is not physical: {e}", advice.effect));
    Outcome {
        advice: Some(advice.effect.clone()),
        before,
        reidentified,
        after: rms_on(&followed.calibration, &later),
    }
}

fn harness(draws: &[Hidden]) {
    let robot = clean_truth();
    let base = measure(&robot);
    let (mut gains, mut strict_gains) = (Vec::new(), Vec::new());
    let (mut worse, mut strict_worse) = (Vec::new(), Vec::new());
    for h in draws {
        let o = run(&robot, &base, Some(h));
        // Adding nothing: the calibration as it was. Stricter: the paper's model re-identified
        // on the same files without the advice (what the printed command gives without its
        // effect). No advice changes nothing.
        let gain_over = |nothing: f64| {
            if o.advice.is_some() {
                1.0 - (o.after / nothing).powi(2)
            } else {
                0.0
            }
        };
        let (gain, strict) = (gain_over(o.before), gain_over(o.before.min(o.reidentified)));
        println!(
            "{h:?}: {} — later paths {:.1} (re-identified {:.1}) → {:.1} µm RMS ({:+.0}%, \
             {:+.0}% over the re-identified)",
            o.advice.as_deref().unwrap_or("no advice"),
            o.before,
            o.reidentified,
            o.after,
            100.0 * gain,
            100.0 * strict
        );
        let line = format!("{h:?}: {:?} {:.1} → {:.1} µm", o.advice, o.before, o.after);
        if gain < WORSE {
            worse.push(line.clone());
        }
        if strict < WORSE {
            strict_worse.push(line);
        }
        gains.push(gain);
        strict_gains.push(strict);
    }
    let median = |g: &mut Vec<f64>| {
        g.sort_by(f64::total_cmp);
        g[g.len() / 2]
    };
    println!(
        "{} draws: median gain on the later paths {:+.1}% ({:+.1}% over the re-identified), \
         worse in {} ({} over the re-identified)",
        draws.len(),
        100.0 * median(&mut gains),
        100.0 * median(&mut strict_gains),
        worse.len(),
        strict_worse.len()
    );
    assert!(
        worse.is_empty(),
        "advice worse on the later paths than adding nothing: {worse:#?}"
    );
}

/// Clean data: nothing recommended. Before advice was judged on the later file, `compliance:A5`
/// was advised here (on the later paths it changed nothing, 30.1 → 30.1 µm RMS); now it is
/// "not a finding: it does not lower the error on data measured later".
#[test]
fn clean_robot_gets_no_advice() {
    let robot = clean_truth();
    let base = measure(&robot);
    let o = run(&robot, &base, None);
    println!(
        "clean: {:?} — later paths {:.1} → {:.1} µm RMS",
        o.advice, o.before, o.after
    );
    assert_eq!(o.advice, None, "advice on the clean robot");
}

/// Cases 1 and 2: each first advice identifies and lowers the later paths (measured: case 1
/// `compliance:A3`, scored with the A3 table re-fitted beside it, 27.6 → 24.0 µm RMS; case 2
/// `tilt:A1`, 41.1 → 27.2). Before advice was judged on the later file, case 2 was advised
/// `tilt:A1` from the campaign alone and the later paths rose 45.6 → 88.3 µm RMS.
#[test]
fn a_few_hidden_effects() {
    harness(&[
        // Case 1: A3 follows the forearm's angle to gravity, 80 µm.
        Hidden::ForearmGravity {
            axis: 2,
            deg: deg_for(80.0),
            phase_deg: 0.0,
        },
        // Case 2: the mount tilts with the reach, 60 µrad per metre about Y.
        Hidden::MountTilt {
            about: 1,
            urad_per_m: 60.0,
        },
    ]);
}

#[test]
#[ignore = "some ten minutes: cargo test --test diagnose_hidden -- --ignored"]
fn twenty_hidden_effects() {
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let draws: Vec<Hidden> = (0..20).map(|k| draw(k, &mut rng)).collect();
    harness(&draws);
}
