//! Diagnosis on data with a hidden effect, made by the virtual robot: for each effect of the
//! contract table at a realistic size, identify a calibration without it, check that
//! `diagnose` ranks it first (or an effect it reports as indistinguishable from it on these
//! data), add the finding with `robopost identify -c OLD --effects +NAME`, and check that the
//! error on independent validation poses falls to what a calibration identified with the
//! hidden effect from the start achieves. On data without a hidden effect, no finding.
//!
//! Data (small, so the suite stays quick): the paper's indexing campaign at 2° pitch plus 200
//! random workspace poses (all six axes moving, which the indexing tests alone would not
//! show), KR 30 HA with a 30 kg payload, tracker noise of the virtual robot; validation: 200
//! other random poses measured afterwards. Tables at 2° pitch, the campaign's.

#[path = "support/calibrate.rs"]
mod calibrate;
#[path = "support/readme.rs"]
mod readme;

use std::path::Path;
use std::process::Command;

use robopost::calibration::{self, Calibration, MeasurementFrame, Provenance};
use robopost::compare::{self, Summary};
use robopost::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use robopost::kinematics::Payload;
use robopost::measure::{self, Measurements, Stop};
use robopost::model::effects::crosstalk::Crosstalk;
use robopost::model::{EffectName, GridOptions, Model};
use robopost::simulate::campaign::{Campaign, PlannedStop};
use robopost::simulate::paper;
use robopost::simulate::virtual_robot::VirtualRobot;

const PAPER: &str = "geometric,map:A1..A6,backlash:A1..A6,crosstalk:A3->A2";
const PITCH: f64 = 2.0;

/// The virtual KR 30 HA of the fixtures (the paper's effects) carrying 30 kg.
fn paper_truth() -> Model {
    let mut truth = paper::truth_model(false);
    truth.payload = Payload {
        mass_kg: 30.0,
        cog_mm: [0.0, 0.0, 100.0],
    };
    truth
}

fn with_effect(mut truth: Model, name: &str, values: &[f64]) -> Model {
    let name = EffectName::parse(name).unwrap();
    let mut effect = name.create(&GridOptions::default(), &truth.robot).unwrap();
    effect.values_mut()[..values.len()].copy_from_slice(values);
    truth.push(effect);
    truth
}

fn without(truth: &Model, name: &str) -> Model {
    let mut m = Model::new(truth.robot, truth.payload, truth.target_mm);
    for e in truth.effects().iter().filter(|e| e.name() != name) {
        m.push(e.clone_model_effect());
    }
    m
}

/// `count` random poses inside the campaign's ranges, visited in order from `t0_s`.
fn poses(seed: u64, count: usize, t0_s: f64, label: &str) -> Vec<PlannedStop> {
    robopost::simulate::poses::random_poses(seed, count, t0_s, label)
}

/// (identification data, validation data) measured on `truth`.
fn measure(truth: &Model) -> (Vec<Stop>, Vec<Stop>) {
    let mut campaign = Campaign::paper();
    for t in &mut campaign.tests {
        t.pitch_deg = PITCH;
    }
    let mut plan = campaign.plan().unwrap();
    let end = plan.last().unwrap().time_s;
    plan.extend(poses(7, 200, end + 60.0, "poses"));
    let data = VirtualRobot::new(truth.clone())
        .with_seed(1)
        .measure(&plan)
        .unwrap();
    let validation = VirtualRobot::new(truth.clone())
        .with_seed(2)
        .measure(&poses(8, 200, end + 900.0, "validation"))
        .unwrap();
    (data, validation)
}

/// A calibration with exactly `effects`, identified on `data` (robot, payload and target known).
fn calibrate(truth: &Model, effects: &str, data: &[Stop]) -> Calibration {
    calibrate::calibrate(truth, effects, data, PITCH)
}

fn validation_rms(cal: &Calibration, validation: &[Stop]) -> f64 {
    Summary::residuals(&compare::compare(cal, &[as_file(validation)]))
        .all
        .rms_um
}

fn as_file(stops: &[Stop]) -> Measurements {
    Measurements {
        source: "validation".into(),
        stops: stops.to_vec(),
        ignored_columns: vec![],
    }
}

/// Squared 3-D residual (µm²) of every validation point under `cal`.
fn squared_residuals(cal: &Calibration, validation: &[Stop]) -> Vec<f64> {
    compare::compare(cal, &[as_file(validation)])
        .iter()
        .map(|r| (r.residual() * 1e3).norm_squared())
        .collect()
}

/// Mean and standard error of the per-point difference `a − b`.
fn paired(a: &[f64], b: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The README's bounds on diagnose's t statistic: (clean data at most, a missing effect from,
/// to).
fn readme_t_bounds() -> (f64, f64, f64) {
    let n = readme::numbers(&readme::block("diagnose-t").text);
    assert_eq!(n.len(), 3, "diagnose-t: {n:?}");
    (n[0], n[1], n[2])
}

fn run_diagnose(cal: &Calibration, data: &[Stop]) -> Diagnosis {
    let m = Measurements {
        source: "data".into(),
        stops: data.to_vec(),
        ignored_columns: vec![],
    };
    diagnose(cal, &[m], &DiagnoseOptions::default()).unwrap()
}

/// `robopost identify -c old.json data.csv --effects +NAME --map-pitch 2 -o new.json`.
fn add_with_cli(old: &Calibration, data: &[Stop], name: &str) -> Calibration {
    let dir = tempfile::tempdir().unwrap();
    let (old_path, csv, new_path) = (
        dir.path().join("old.json"),
        dir.path().join("data.csv"),
        dir.path().join("new.json"),
    );
    old.save_atomic(&old_path).unwrap();
    measure::write_csv(std::fs::File::create(&csv).unwrap(), data).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_robopost"))
        .args(["identify", "-c"])
        .arg(&old_path)
        .arg(&csv)
        .args([
            "--effects",
            &format!("+{name}"),
            "--map-pitch",
            &PITCH.to_string(),
            "-o",
        ])
        .arg(&new_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "identify failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    calibration::load(Path::new(&new_path)).unwrap()
}

/// How a finding must relate to the hidden effect.
#[derive(Clone, Copy, PartialEq)]
enum Expect {
    /// Diagnose ranks the hidden effect itself first.
    Itself,
    /// At one payload the hidden effect has a twin that explains the same residual: diagnose
    /// may rank the twin first if it names the hidden effect as indistinguishable from it.
    ItselfOrTwin,
}

/// The whole loop for one hidden effect, the README's row `label` of `diagnose-table`.
///
/// The thresholds are physical, not fitted to observed falls: the calibration identified with
/// the hidden effect from the start is the floor (`best`); the hidden effect adds u² =
/// before² − best² to the validation mean square. The fall must be significant on the
/// independent validation points (paired mean of the per-point squared residuals more than 3
/// standard errors), and adding the finding must remove at least 90 % of
/// u² (a twin, which cannot follow the hidden effect's shape exactly: 75 %).
fn hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
    truth: Model,
    base_effects: &str,
    hidden: &str,
    label: &str,
    expect: Expect,
) -> (Calibration, Vec<Stop>, Diagnosis) {
    let (data, validation) = measure(&truth);
    let old = calibrate(&truth, base_effects, &data);
    let complete = calibrate(&truth, &format!("{base_effects},{hidden}"), &data);
    let d = run_diagnose(&old, &data);
    let top = d.candidates.first().unwrap_or_else(|| {
        panic!(
            "no finding for hidden {hidden}: {}\n{:#?}",
            d.verdict,
            &d.considered[..5]
        )
    });
    let accepted = top.effect == hidden
        || (expect == Expect::ItselfOrTwin
            && top.indistinguishable_from.iter().any(|e| e == hidden));
    assert!(
        accepted,
        "hidden {hidden}, diagnose ranks first {} (indistinguishable from {:?}); {}",
        top.effect, top.indistinguishable_from, d.verdict
    );
    let (_, t_from, t_to) = readme_t_bounds();
    assert!(
        (t_from..=t_to).contains(&top.t_statistic),
        "{hidden}: t = {:.1}, the README says a missing effect scores {t_from}–{t_to}",
        top.t_statistic
    );
    if top.effect != hidden {
        // The output says so, in the evidence and in the verdict.
        assert!(top
            .evidence
            .contains("indistinguishable on these data from"));
        assert!(top.evidence.contains(hidden) && d.verdict.contains(hidden));
    }
    assert!(d.verdict.starts_with(&format!("Missing: {}", top.effect)));
    assert!(top.evidence.len() > 40 && top.add == format!("--effects '+{}'", top.effect));

    let new = add_with_cli(&old, &data, &top.effect);
    let (before, after, best) = (
        validation_rms(&old, &validation),
        validation_rms(&new, &validation),
        validation_rms(&complete, &validation),
    );
    eprintln!(
        "{hidden}: diagnose → {} ({:.0}%), validation RMS {before:.1} → {after:.1} µm \
         (calibration with {hidden} from the start: {best:.1} µm)",
        top.effect,
        100.0 * top.explained
    );
    let (gain, se) = paired(
        &squared_residuals(&old, &validation),
        &squared_residuals(&new, &validation),
    );
    // One pre-stated hypothesis on independent points: three standard errors (diagnose needs
    // five because it tries 48 candidates on the same data).
    assert!(
        gain > 3.0 * se,
        "{hidden}: the fall {before:.1} → {after:.1} µm is not significant on the validation \
         points (paired gain {gain:.1} ± {se:.1} µm²)"
    );
    let u2 = before * before - best * best;
    let left = (after * after - best * best).max(0.0);
    let share = if top.effect == hidden { 0.1 } else { 0.25 };
    assert!(
        left <= share * u2,
        "{hidden}: adding {} leaves {:.0}% of the {:.1} µm the hidden effect adds ({before:.1} → \
         {after:.1} µm; with {hidden} from the start {best:.1} µm)",
        top.effect,
        100.0 * left / u2,
        u2.sqrt()
    );
    // The README's row: what diagnose ranks first, and the three RMS figures (printed to
    // 0.1 µm; within 0.15).
    let first = if top.indistinguishable_from.is_empty() {
        top.effect.clone()
    } else {
        format!(
            "{}, indistinguishable from {}",
            top.effect,
            top.indistinguishable_from.join(", ")
        )
    };
    assert_eq!(
        readme::row("diagnose-table", label)[0],
        first,
        "README diagnose-table row `{label}`"
    );
    readme::assert_row("diagnose-table", label, &[before, after, best], 0.15);
    (old, data, d)
}

#[test]
fn clean_data_gives_no_finding() {
    let truth = paper_truth();
    let (data, _) = measure(&truth);
    let cal = calibrate(&truth, PAPER, &data);
    let d = run_diagnose(&cal, &data);
    assert!(
        d.candidates.is_empty(),
        "findings on clean data: {:#?}",
        d.candidates
    );
    assert!(
        d.verdict.starts_with("Nothing significant is missing"),
        "{}",
        d.verdict
    );
    // Every missing effect of the table was tried: 62 − 14 in the paper's model.
    assert_eq!(d.considered.len(), 48);
    assert!(d.considered.iter().all(|f| !f.significant));
    let (clean_at_most, _, _) = readme_t_bounds();
    let worst = d
        .considered
        .iter()
        .map(|f| f.t_statistic)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(
        worst <= clean_at_most,
        "on clean data a candidate scores t = {worst:.2}; the README says {clean_at_most} at most"
    );
    assert_eq!(
        readme::row("diagnose-table", "none")[0],
        "no finding, \"Nothing significant is missing\""
    );
}

#[test]
fn crosstalk_a3_to_a2_as_in_the_paper() {
    // The paper's Fig. 5 crosstalk is in the virtual robot; the calibration lacks it.
    hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
        paper_truth(),
        "geometric,map:A1..A6,backlash:A1..A6",
        "crosstalk:A3->A2",
        "crosstalk A3→A2",
        Expect::Itself,
    );
}

#[test]
fn crosstalk_a2_to_a3_as_in_fig_7() {
    // A3's deviation shifts by about ±0.004° between A2 = −112° and −19° (the paper's Fig. 7).
    let mut truth = paper_truth();
    let options = GridOptions {
        pitch_deg: Some(1.0),
        other_pitch_deg: Some(1.0),
        ..GridOptions::default()
    };
    let mut x = Crosstalk::zeros(2, 3, &options, &truth.robot).unwrap();
    let (rows, cols) = (
        x.table.rows.points().to_vec(),
        x.table.columns.points().to_vec(),
    );
    for (i, a3) in rows.iter().enumerate() {
        for (j, a2) in cols.iter().enumerate() {
            x.table.values[i * cols.len() + j] =
                0.004 * (a2 + 65.0) / 47.0 * (1.0 + 0.3 * (a3 - 85.0f64).to_radians().sin());
        }
    }
    truth.push(Box::new(x));
    hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
        truth,
        PAPER,
        "crosstalk:A2->A3",
        "crosstalk A2→A3",
        Expect::Itself,
    );
}

/// At one payload compliance has a twin: the gravity torque on A2 is a function of A2 and A3,
/// which a crosstalk table also is. Diagnose may rank the twin first if it shows, by
/// re-identifying around each, that the two explain the same residual and names compliance as
/// indistinguishable; the two-payload test below requires compliance itself.
#[test]
fn compliance_of_a2_under_30_kg_at_one_payload() {
    // 0.004°/kN·m. With the paper's crosstalk A3->A2 in both truth and model, that table takes
    // up A2's gravity deflection almost entirely (the torque on A2 is a function of A2 and A3
    // at one payload), so this case hides it from a model without that crosstalk.
    let truth = with_effect(
        without(&paper_truth(), "crosstalk:A3->A2"),
        "compliance:A2",
        &[0.004],
    );
    hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
        truth,
        "geometric,map:A1..A6,backlash:A1..A6",
        "compliance:A2",
        "compliance A2",
        Expect::ItselfOrTwin,
    );
}

/// As for A2: at one payload crosstalk A2→A3 is compliance A3's twin.
#[test]
fn compliance_of_a3_under_30_kg_at_one_payload() {
    // 0.006°/kN·m on top of the paper's effects.
    hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
        with_effect(paper_truth(), "compliance:A3", &[0.006]),
        PAPER,
        "compliance:A3",
        "compliance A3",
        Expect::ItselfOrTwin,
    );
}

/// Compliance told apart from crosstalk the physical way: the same campaign and poses measured
/// with two payloads (0 and 30 kg). A crosstalk table is a function of the angles alone and
/// cannot follow a deflection that changes with the payload at the same angles; compliance is a
/// function of the gravity torque and can. Diagnose must rank compliance first (no twin), and
/// adding it must bring the validation error down to the complete calibration's.
///
/// Needs a payload per measurement file, which neither `identify` nor `diagnose` accepts today
/// (a calibration has one payload and every row is taken at it); the test writes the interface
/// it needs (`--payload MASS,X,Y,Z` before the files it applies to).
#[test]
#[ignore = "needs issue 23: a payload per measurement file in identify and diagnose"]
fn compliance_is_told_from_crosstalk_with_two_payloads() {
    for (hidden, value) in [("compliance:A2", 0.004), ("compliance:A3", 0.006)] {
        let dir = tempfile::tempdir().unwrap();
        let mut files = Vec::new();
        let mut validation = Vec::new();
        for (k, mass) in [0.0, 30.0].into_iter().enumerate() {
            let mut truth = with_effect(paper_truth(), hidden, &[value]);
            truth.payload = Payload {
                mass_kg: mass,
                cog_mm: [0.0, 0.0, 100.0],
            };
            let (data, check) = measure(&truth);
            let csv = dir.path().join(format!("payload{k}.csv"));
            measure::write_csv(std::fs::File::create(&csv).unwrap(), &data).unwrap();
            files.push((format!("{mass},0,0,100"), csv));
            validation.push((truth, check));
        }
        let robopost = |args: &[String]| {
            let out = Command::new(env!("CARGO_BIN_EXE_robopost"))
                .args(args)
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "robopost {args:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            String::from_utf8_lossy(&out.stdout).into_owned()
        };
        let with_payloads = |mut args: Vec<String>| {
            for (payload, csv) in &files {
                args.push("--payload".into());
                args.push(payload.clone());
                args.push(csv.display().to_string());
            }
            args
        };
        let old = dir.path().join("old.json");
        robopost(&with_payloads(vec![
            "identify".into(),
            "--target=-120,-80,180".into(),
            "--map-pitch".into(),
            PITCH.to_string(),
            "--effects".into(),
            PAPER.into(),
            "-o".into(),
            old.display().to_string(),
        ]));
        let d: serde_json::Value = serde_json::from_str(&robopost(&with_payloads(vec![
            "diagnose".into(),
            "--json".into(),
            "-c".into(),
            old.display().to_string(),
        ])))
        .unwrap();
        assert_eq!(d["candidates"][0]["effect"], hidden, "{d:#}");
        let new = dir.path().join("new.json");
        robopost(&with_payloads(vec![
            "identify".into(),
            "-c".into(),
            old.display().to_string(),
            "--effects".into(),
            format!("+{hidden}"),
            "--map-pitch".into(),
            PITCH.to_string(),
            "-o".into(),
            new.display().to_string(),
        ]));
        let old = calibration::load(&old).unwrap();
        let new = calibration::load(&new).unwrap();
        for (truth, check) in &validation {
            let at = |cal: &Calibration| {
                let mut model = cal.model();
                model.payload = truth.payload;
                Calibration::from_model("v", model, MeasurementFrame::Base, Provenance::default())
            };
            let (before, after) = (
                validation_rms(&at(&old), check),
                validation_rms(&at(&new), check),
            );
            assert!(
                after < before,
                "{hidden} at {:?}: {before} → {after}",
                truth.payload
            );
        }
    }
}

#[test]
fn tilt_of_a1_of_four_thousandths_of_a_degree() {
    // The A1 axis wobbles by 0.004° about X and Y, once per turn.
    let (old, data, library) = hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
        with_effect(
            paper_truth(),
            "tilt:A1",
            &[0.004, 0.0, 0.0, 0.0, 0.0, 0.004, 0.0, 0.0],
        ),
        PAPER,
        "tilt:A1",
        "tilt A1",
        Expect::Itself,
    );
    // The command line prints the same diagnosis with the keys of CONTRACTS.md.
    let dir = tempfile::tempdir().unwrap();
    let (cal, csv) = (dir.path().join("cal.json"), dir.path().join("data.csv"));
    old.save_atomic(&cal).unwrap();
    measure::write_csv(std::fs::File::create(&csv).unwrap(), &data).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_robopost"))
        .args(["diagnose", "--json", "-c"])
        .arg(&cal)
        .arg(&csv)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in ["rms_um", "noise_um"] {
        assert!(v[key].is_number(), "{key} missing");
    }
    assert!(v["verdict"].is_string());
    let (candidates, considered) = (
        v["candidates"].as_array().unwrap(),
        v["considered"].as_array().unwrap(),
    );
    assert_eq!(considered.len(), 48);
    assert!(!candidates.is_empty() && candidates.len() <= considered.len());
    for c in candidates.iter().chain(considered) {
        assert!(c["effect"].is_string() && c["evidence"].is_string());
        assert!(c["explained"].as_f64().unwrap() <= 1.0 && c["rms_after_um"].is_number());
    }
    // Best first, and the file's rounding (0.1 µm) does not change the finding.
    let explained: Vec<f64> = candidates
        .iter()
        .map(|c| c["explained"].as_f64().unwrap())
        .collect();
    assert!(explained.windows(2).all(|w| w[0] >= w[1]));
    assert_eq!(
        candidates[0]["effect"],
        library.candidates[0].effect.as_str()
    );
    assert!((v["rms_um"].as_f64().unwrap() - library.rms_um).abs() < 0.1);
}

#[test]
fn drift_of_a_tenth_of_a_millimetre_per_hour() {
    // The column (l1z) grows 0.1 mm/h over the two-hour campaign.
    hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
        with_effect(paper_truth(), "drift", &[0.1]),
        PAPER,
        "drift",
        "drift",
        Expect::Itself,
    );
}

#[test]
fn backlash_of_a1_when_the_model_has_only_its_map() {
    hidden_effect_is_found_and_adding_it_lowers_the_validation_error(
        paper_truth(),
        "geometric,map:A1..A6,backlash:A2..A6,crosstalk:A3->A2",
        "backlash:A1",
        "backlash A1",
        Expect::Itself,
    );
}
