//! The error budget (`compare --budget`): on three virtual truths — the clean one (only the
//! model's effects), the one with a hidden effect the model lacks, and the independently
//! written physical truth — a calibration identified from the paper's campaign is compared
//! with validation measurements at the paper's validation poses, and the budget's measured
//! parts (validation tracker noise, identification noise carried through the fit, the
//! model form measured as the campaign's lack of fit) are set against the measured residual.

#[path = "support/readme.rs"]
mod readme;

use std::path::Path;

use robopost::calibration::Calibration;
use robopost::compare::budget::{budget, Budget, Instrument};
use robopost::compare::{self, Row};
use robopost::identify::covariance;
use robopost::identify::pipeline::{identify, Effects, Request, PAPER_EFFECTS};
use robopost::measure::tracker::Tracker;
use robopost::measure::{read_csv, Measurements, Stop};
use robopost::model::expand_list;
use robopost::simulate::physical::{self, PhysicalRobot, PTP_STEP_DEG};
use robopost::simulate::poses::read_poses;
use robopost::simulate::Campaign;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Stops as a file would hold them (lines numbered from 2, below the header), so that the
/// gross errors `identify` leaves out are named by line.
fn file(name: &str, mut stops: Vec<Stop>) -> Measurements {
    for (i, s) in stops.iter_mut().enumerate() {
        s.line = i + 2;
    }
    Measurements {
        source: name.into(),
        stops,
        ignored_columns: Vec::new(),
    }
}

/// The calibration's budget on `validation`, identified from `campaign`.
fn budget_of(campaign: &Measurements, validation: &Measurements) -> (Calibration, Budget) {
    let request = Request {
        effects: Some(Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap())),
        sources: vec![campaign.source.clone()],
        ..Request::default()
    };
    let cal = identify(&campaign.stops, &request).unwrap().calibration;
    let cov = covariance::of_calibration(&cal, std::slice::from_ref(campaign)).unwrap();
    let kept = |rows: Vec<Row>, marks: Vec<Option<String>>| -> Vec<Row> {
        rows.into_iter()
            .zip(marks)
            .filter(|(_, m)| m.is_none())
            .map(|(r, _)| r)
            .collect()
    };
    let campaign_rows = kept(
        compare::compare(&cal, std::slice::from_ref(campaign)),
        compare::gross_errors(&cal, std::slice::from_ref(campaign)),
    );
    let validation_rows = compare::compare(&cal, std::slice::from_ref(validation));
    let instrument = Instrument {
        tracker: Tracker::default(),
        station_mm: nalgebra::Vector3::from(robopost::simulate::truth::DEFAULT_STATION_MM),
    };
    let b = budget(
        cal.model_ref(),
        &cov,
        &campaign_rows,
        &validation_rows,
        &instrument,
    );
    (cal, b)
}

fn show(name: &str, b: &Budget) {
    let p = &b.all;
    println!(
        "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} |",
        p.points,
        p.measured_um,
        p.tracker_um,
        p.identification_um,
        p.model_form_um,
        p.explained_um,
        p.unexplained_um,
        p.offset_um,
        p.explained_um / p.measured_um
    );
}

#[test]
fn budget_parts_account_for_the_measured_error_on_three_truths() {
    let read =
        |name: &str| read_csv(&root().join(format!("fixtures/measurements/{name}"))).unwrap();
    // Clean and hidden-effect truths: the shipped campaigns and validation measurements.
    let (_, clean) = budget_of(&read("campaign.csv"), &read("validation.csv"));
    let (_, hidden) = budget_of(&read("campaign-hidden.csv"), &read("validation-hidden.csv"));
    // The physical truth: its paper campaign, then the validation poses half an hour later.
    let robot =
        PhysicalRobot::load(&root().join("fixtures/measurements/kr30ha-physical.json")).unwrap();
    let plan = Campaign::paper().plan().unwrap();
    let end = plan.last().unwrap().time_s;
    let campaign = robot
        .measure(&physical::from_stops(&plan, PTP_STEP_DEG))
        .unwrap();
    let mut poses = read_poses(
        &root().join("fixtures/measurements/validation-poses.csv"),
        3.0,
        30.0,
    )
    .unwrap();
    for p in &mut poses {
        p.time_s += end + 1800.0;
    }
    let validation = robot
        .clone()
        .with_seed(robot.seed() + 7)
        .measure(&physical::from_stops(&poses, PTP_STEP_DEG))
        .unwrap();
    let (_, physical_budget) = budget_of(
        &file("physical-campaign", campaign),
        &file("physical-validation", validation),
    );
    println!("| truth | points | measured | tracker | identification | model form | explained | unexplained | offset | explained/measured |");
    for (name, b) in [
        ("clean", &clean),
        ("hidden effect", &hidden),
        ("physical", &physical_budget),
    ] {
        show(name, b);
    }
    let v = |b: &Budget| {
        let p = &b.all;
        vec![
            p.measured_um,
            p.tracker_um,
            p.identification_um,
            p.model_form_um,
            p.explained_um,
            p.unexplained_um,
        ]
    };
    readme::assert_rows(
        "error-budget",
        &[
            ("clean", v(&clean)),
            ("hidden effect", v(&hidden)),
            ("physical", v(&physical_budget)),
        ],
        0.1,
        1,
    );
    // The clean truth: every part is one the budget measures; they account for the error.
    let ratio = |b: &Budget| b.all.explained_um / b.all.measured_um;
    assert!(
        (0.9..=1.1).contains(&ratio(&clean)),
        "clean {}",
        ratio(&clean)
    );
    // On the clean truth the model form (1° tables, three crosstalk columns against the
    // truth's finer structure) is small next to the tracker.
    assert!(clean.all.model_form_um < clean.all.tracker_um, "{clean:?}");
    // The hidden effect shows in the campaign's lack of fit as model form, larger than on
    // the clean truth.
    assert!(hidden.all.model_form_um > clean.all.model_form_um);
    // Where the robot has what the model lacks, the campaign (one axis moving at a time)
    // shows only part of it: at the validation poses the largest part is what no measured
    // source explains, and the budget says so rather than spreading it over the others.
    for b in [&hidden, &physical_budget] {
        let p = &b.all;
        assert!(ratio(b) < 0.9, "{p:?}");
        assert!(
            p.unexplained_um > p.tracker_um
                && p.unexplained_um > p.identification_um
                && p.unexplained_um > p.model_form_um,
            "{p:?}"
        );
    }
    // On the physical truth most of the unexplained part is a constant offset of the
    // validation (its warm-up since the campaign).
    let p = &physical_budget.all;
    assert!(
        p.offset_um.powi(2) > 0.5 * p.unexplained_um.powi(2),
        "{p:?}"
    );
    readme::assert_prose("error-budget-offset", &[p.offset_um, p.unexplained_um], 0.1);
    // Per test and per point, the same parts.
    assert_eq!(clean.points.len(), clean.all.points);
    assert_eq!(
        clean.tests.values().map(|t| t.points).sum::<usize>(),
        clean.all.points
    );
    let mean_square = |f: &dyn Fn(&robopost::compare::budget::PointParts) -> f64| {
        (clean.points.iter().map(|p| f(p).powi(2)).sum::<f64>() / clean.points.len() as f64).sqrt()
    };
    assert!((mean_square(&|p| p.measured_um) - clean.all.measured_um).abs() < 1e-9);
    assert!((mean_square(&|p| p.identification_um) - clean.all.identification_um).abs() < 1e-9);
}

/// `robopost compare -c CAL.json VALIDATION.csv --budget CAMPAIGN.csv [--json]`: the budget
/// of the shipped example calibration on the shipped validation measurements is the
/// library's (the calibration identified from the same campaign in this test); an unreadable
/// campaign is a usage error.
#[test]
fn compare_budget_on_the_command_line() {
    let exe = env!("CARGO_BIN_EXE_robopost");
    let m = |name: &str| root().join(format!("fixtures/measurements/{name}"));
    let cal = root().join("calibrations/kr30ha-example.json");
    let run = |extra: &[&str], campaign: &Path| {
        std::process::Command::new(exe)
            .arg("compare")
            .arg("-c")
            .arg(&cal)
            .arg(m("validation.csv"))
            .arg("--budget")
            .arg(campaign)
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&["--json"], &m("campaign.csv"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let b = &json["budget"];
    let (_, library) = budget_of(
        &read_csv(&m("campaign.csv")).unwrap(),
        &read_csv(&m("validation.csv")).unwrap(),
    );
    for key in [
        "measured_um",
        "tracker_um",
        "identification_um",
        "model_form_um",
        "explained_um",
        "unexplained_um",
    ] {
        let cli = b[key].as_f64().unwrap();
        let lib = serde_json::to_value(library.all).unwrap()[key]
            .as_f64()
            .unwrap();
        assert!((cli - lib).abs() < 0.05, "{key}: {cli} vs {lib}");
    }
    assert_eq!(b["points"].as_array().unwrap().len(), 144);
    assert_eq!(b["tests"].as_object().unwrap().len(), 3);
    // The table.
    let out = run(&[], &m("campaign.csv"));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("error budget") && text.contains("| all | 144 |"),
        "{text}"
    );
    // Another robot's campaign: computed, with a warning that it is not the calibration's.
    let out = run(&[], &m("campaign-hidden.csv"));
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("may not be the files it was identified from"),
        "{stderr}"
    );
    let out = run(&[], &m("campaign.csv"));
    assert!(!String::from_utf8_lossy(&out.stderr).contains("warning"));
    // A campaign that cannot be read: exit 2, the file named.
    let out = run(&[], &m("no-such-campaign.csv"));
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no-such-campaign.csv"));
}
