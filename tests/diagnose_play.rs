//! Diagnosis of a gear play on a robot that has one, from a calibration that models the
//! rotation-direction dependence as an instant switch of sign (the paper's ±1 branches, as a
//! calibration made by another tool has it: here `learned:angle@An(dir:An)`) or not at all
//! (maps only).
//!
//! The robot is the physical truth of `fixtures/measurements/kr30ha-physical.json` (its own
//! chain, gears with a play operator run over the commanded trajectory: not the model), with
//! the play left on A2, A4 and A5 only, so that "the right axes" means something, and without
//! the effects the paper's model lacks besides the play (compliance, inertia crosstalk,
//! warm-up, gross tracker errors: `tests/physical_truth.rs` diagnoses those), so that the play
//! is what is missing. Its gear harmonics, joint-frame errors and tracker (noise, scale,
//! registration) stay.
//!
//! - With reversal tests (`Campaign::paper_with_reversals`: each axis moved back and forth by
//!   0.001° to 0.05° at five angles), `diagnose` names `backlash:An` first, for axes with a
//!   play (A2 and A4 at least: A5's finding fails the whole-test check) and for no axis
//!   without one, with evidence that reads the dead band off the travel since the last
//!   reversal (its width within a third of the truth's) and a cross-validated fall of the
//!   residual; identified as it says (the play in place of the switch), it lowers the error
//!   on reversal tests at other angles measured afterwards by a fifth at least.
//! - On the paper's campaign alone (every stop after a long motion) the play and the instant
//!   switch predict alike: `diagnose` names no `backlash:An`, and its verdict says the data
//!   cannot tell them apart.
//! - A calibration with maps only (no direction dependence) misses the play too: diagnose
//!   names a play, of an axis that has one.
//!
//! Tables at 2° pitch (a small campaign, so the suite stays quick).

#[path = "support/readme.rs"]
mod readme;

use std::path::Path;

use robopost::calibration::Calibration;
use robopost::compare::{self, Summary};
use robopost::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use robopost::identify::pipeline::{identify, Effects, Request};
use robopost::identify::setup::GridChoice;
use robopost::measure::{Measurements, Stop};
use robopost::model::expand_list;
use robopost::simulate::campaign::Campaign;
use robopost::simulate::paper;
use robopost::simulate::physical::{self, PhysicalRobot, PTP_STEP_DEG};

const PITCH: f64 = 2.0;
/// The axes (1-based) that keep their play in the truth.
const WITH_PLAY: [u8; 3] = [2, 4, 5];
const MAP_ONLY: &str = "geometric,map:A1..A6,crosstalk:A3->A2";

fn instant_switch() -> String {
    let switches: Vec<String> = (1..=6)
        .map(|n| format!("learned:angle@A{n}(dir:A{n})"))
        .collect();
    format!("{MAP_ONLY},{}", switches.join(","))
}

fn robot() -> PhysicalRobot {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let full =
        PhysicalRobot::load(&root.join("fixtures/measurements/kr30ha-physical.json")).unwrap();
    let mut file = full.file().clone();
    file.tracker.noise.gross_probability = 0.0;
    file.compliance_deg_per_knm = [0.0; 6];
    file.inertia_deg_per_kgm2 = [0.0; 6];
    file.thermal.clear();
    for (k, gear) in file.gears.iter_mut().enumerate() {
        if !WITH_PLAY.contains(&(k as u8 + 1)) {
            gear.play_deg = 0.0;
        }
    }
    PhysicalRobot::new(file, Path::new("play on A2, A4, A5")).unwrap()
}

fn campaign(reversals: bool) -> Campaign {
    let mut c = if reversals {
        Campaign::paper_with_reversals()
    } else {
        Campaign::paper()
    };
    for t in &mut c.tests {
        t.pitch_deg = PITCH;
    }
    c
}

fn measure(robot: &PhysicalRobot, campaign: &Campaign) -> Vec<Stop> {
    robot
        .measure(&physical::from_stops(
            &campaign.plan().unwrap(),
            PTP_STEP_DEG,
        ))
        .unwrap()
}

fn file(stops: &[Stop], name: &str) -> Measurements {
    Measurements {
        source: name.into(),
        stops: stops.to_vec(),
        ignored_columns: vec![],
    }
}

/// The calibration with exactly `effects`, identified unaided from `data`.
fn calibrate(effects: &str, data: &[Stop]) -> Calibration {
    let request = Request {
        effects: Some(Effects::Exactly(expand_list(effects).unwrap())),
        target_mm: Some(paper::TARGET_MM),
        grid: GridChoice {
            map_pitch_deg: PITCH,
            ..GridChoice::default()
        },
        ..Request::default()
    };
    identify(data, &request).unwrap().calibration
}

fn run(cal: &Calibration, data: &[Stop]) -> Diagnosis {
    let d = diagnose(cal, &[file(data, "data")], &DiagnoseOptions::default()).unwrap();
    println!("{:.1} µm RMS, floor {:.1} µm", d.rms_um, d.noise_um);
    for c in &d.considered {
        if c.effect.starts_with("backlash") || c.significant {
            println!(
                "  {}{} {:.1}% t {:.1} → {:.1} µm: {}",
                if c.significant { "* " } else { "  " },
                c.effect,
                100.0 * c.explained,
                c.t_statistic,
                c.rms_after_um,
                c.evidence
            );
            for k in &c.checks {
                println!("      check {:?}: {}", k.scheme, k.describe());
            }
            println!("      add {}", c.add);
        }
    }
    println!("{}", d.verdict);
    d
}

fn named_backlash(d: &Diagnosis) -> Vec<u8> {
    let mut axes: Vec<u8> = d
        .candidates
        .iter()
        .filter_map(|c| c.effect.strip_prefix("backlash:A")?.parse().ok())
        .collect();
    axes.sort_unstable();
    axes
}

/// The width the evidence sentence reads off the data ("a play of about 0.016°").
fn width_in(evidence: &str) -> Option<f64> {
    let rest = evidence.split("a play of about ").nth(1)?;
    rest.split('°').next()?.parse().ok()
}

/// Every named play comes with evidence from the dead band, read off the travel since the
/// reversal, with a width within a third of the truth's (the reversal steps of 0.001° to
/// 0.05° bracket a width by steps 20–30 % apart; tracker noise of a few µm on levers of
/// 0.1–1.5 m), and lowers the cross-validated residual.
fn evidence_reads_the_play(d: &Diagnosis, robot: &PhysicalRobot) {
    let plays = d
        .candidates
        .iter()
        .filter(|c| c.effect.starts_with("backlash:"));
    for c in plays {
        let axis: usize = c.effect["backlash:A".len()..].parse().unwrap();
        assert!(
            c.evidence.contains("travel since the reversal"),
            "{}",
            c.evidence
        );
        let width = width_in(&c.evidence).unwrap_or_else(|| panic!("{}", c.evidence));
        let truth = robot.file().gears[axis - 1].play_deg;
        assert!(
            (width - truth).abs() <= truth / 3.0,
            "A{axis}: width {width}° read, truth {truth}°"
        );
        assert!(c.explained > 0.0 && c.rms_after_um < d.rms_um);
    }
}

/// Reversal tests of every axis at four angles the campaign's tests did not use.
fn other_reversals() -> Campaign {
    let mut c = Campaign::paper_with_reversals();
    for r in &mut c.reversals {
        let t = Campaign::paper()
            .tests
            .into_iter()
            .find(|t| t.axis == r.axis)
            .unwrap();
        r.at_deg = [0.2, 0.4, 0.6, 0.8]
            .map(|f| (t.from_deg + f * (t.to_deg - t.from_deg)).round() + 0.5)
            .to_vec();
    }
    c.tests.clear();
    c
}

fn report_of(cal: &Calibration, data: &[Stop]) -> String {
    let rows = compare::compare(cal, &[file(data, "data")]);
    robopost::report::html(&robopost::report::ReportInput {
        models: vec![robopost::report::ReportModel {
            label: "old.json",
            model: cal.model_ref(),
            rows: &rows,
        }],
        sources: vec!["data".into()],
        gross_errors: Vec::new(),
        learned: None,
    })
}

/// The campaign's indexing sweeps, without its reversal tests: what a calibration made by
/// another tool from the paper's campaign saw.
fn sweeps_of(data: &[Stop]) -> Vec<Stop> {
    data.iter()
        .filter(|s| !s.test.contains("reversal"))
        .cloned()
        .collect()
}

fn rms(cal: &Calibration, data: &[Stop]) -> f64 {
    Summary::residuals(&compare::compare(cal, &[file(data, "validation")]))
        .all
        .rms_um
}

#[test]
fn the_play_is_named_where_reversal_tests_show_it() {
    let robot = robot();
    let data = measure(&robot, &campaign(true));
    // The calibration another tool made from the paper's campaign: maps and an instant switch
    // of sign per axis.
    let sweeps = sweeps_of(&data);
    let old = calibrate(&instant_switch(), &sweeps);
    let d = run(&old, &data);
    let named = named_backlash(&d);
    println!("named {named:?}");
    // Best first, and only axes that have a play; the two widest plays (A4 0.020°, A2
    // 0.016°) at least.
    let first = &d.candidates.first().expect("a finding").effect;
    assert!(first.starts_with("backlash:"), "first finding {first}");
    assert!(
        named.iter().all(|a| WITH_PLAY.contains(a)),
        "names the play of an axis without one: {named:?}"
    );
    assert!(named.contains(&2) && named.contains(&4), "{named:?}");
    evidence_reads_the_play(&d, &robot);
    // Identified as diagnose says (the play in place of the switch), the robot's error on
    // reversal tests at other angles, measured afterwards, falls.
    let best = &d.candidates[0];
    let list = best
        .add
        .strip_prefix("--effects '")
        .and_then(|l| l.strip_suffix('\''))
        .unwrap_or_else(|| panic!("{}", best.add));
    let request = Request {
        effects: Some(Effects::Exactly(expand_list(list).unwrap())),
        base: Some(old.clone()),
        target_mm: Some(paper::TARGET_MM),
        grid: GridChoice {
            map_pitch_deg: PITCH,
            ..GridChoice::default()
        },
        ..Request::default()
    };
    let new = identify(&data, &request).unwrap().calibration;
    let validation = measure(
        &robot.clone().with_seed(robot.seed() + 1),
        &other_reversals(),
    );
    let (before, after) = (rms(&old, &validation), rms(&new, &validation));
    println!("validation reversal tests: {before:.1} → {after:.1} µm RMS");
    assert!(after < 0.8 * before, "{before} → {after}");
    let width = width_in(&best.evidence).unwrap();
    let truth = robot.file().gears[1].play_deg;
    assert_eq!(best.effect, "backlash:A2");
    readme::assert_prose(
        "diagnose-play",
        &[
            100.0 * best.explained,
            d.rms_um,
            best.rms_after_um,
            before,
            after,
        ],
        0.6,
    );
    readme::assert_prose("diagnose-play-width", &[width, truth], 0.0006);
    // The report shows where the switch fails: the residual against the travel since the
    // last reversal of every axis that reversed by little.
    let page = report_of(&old, &data);
    for n in 1..=6 {
        assert!(
            page.contains(&format!(
                "A{n}: residual against travel since the last reversal"
            )),
            "no reversal figure of A{n}"
        );
    }
}

#[test]
fn without_short_reversals_the_play_is_not_named() {
    let robot = robot();
    let data = measure(&robot, &campaign(false));
    let cal = calibrate(&instant_switch(), &data);
    let d = run(&cal, &data);
    assert!(named_backlash(&d).is_empty(), "{}", d.verdict);
    for n in 1..=6 {
        assert!(
            d.considered
                .iter()
                .any(|c| c.effect == format!("backlash:A{n}")),
            "backlash:A{n} was not tried"
        );
    }
    assert!(!report_of(&cal, &data).contains("travel since the last reversal"));
    assert!(
        d.verdict.contains("gear play or an instant switch") && d.verdict.contains("cannot tell"),
        "{}",
        d.verdict
    );
}

#[test]
fn a_map_only_calibration_misses_the_play_where_reversal_tests_show_it() {
    let robot = robot();
    let data = measure(&robot, &campaign(true));
    let sweeps = sweeps_of(&data);
    let d = run(&calibrate(MAP_ONLY, &sweeps), &data);
    let named = named_backlash(&d);
    println!("named {named:?}");
    assert!(named.iter().all(|a| WITH_PLAY.contains(a)), "{named:?}");
    assert!(!named.is_empty());
}
