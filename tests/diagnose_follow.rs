//! Advice the user can follow (issue 33, case 1): `diagnose` identifies its first finding as
//! the printed command will and does not advise one whose identification leaves the physical
//! range. The physical truth robot's A5 deflects under gravity by 1.5° per kN·m, beyond what a
//! calibration may hold for `compliance` (−1..1); `identify -c CAL --effects +compliance:A5`
//! would refuse to write it, so `diagnose::follow` says so and `diagnose` does not rank it
//! first.

use std::path::Path;

use robopost::diagnose::{self, DiagnoseOptions};
use robopost::identify::pipeline::{identify, Effects, Request, PAPER_EFFECTS};
use robopost::measure::Measurements;
use robopost::model::{expand_list, EffectName};
use robopost::simulate::physical::{self, PhysicalRobot, PTP_STEP_DEG};
use robopost::simulate::Campaign;

#[test]
fn an_advice_that_cannot_be_written_is_not_given_first() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/measurements/kr30ha-physical.json");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut file = physical::parse(&text, &path).unwrap();
    file.compliance_deg_per_knm[4] = 1.5;
    let robot = PhysicalRobot::new(file, &path).unwrap();
    let plan = Campaign::paper().plan().unwrap();
    let mut data = robot
        .measure(&physical::from_stops(&plan, PTP_STEP_DEG))
        .unwrap();
    for (i, r) in data.iter_mut().enumerate() {
        r.line = i + 2;
    }
    let request = Request {
        effects: Some(Effects::Exactly(expand_list(PAPER_EFFECTS).unwrap())),
        sources: vec!["campaign.csv".into()],
        ..Request::default()
    };
    let cal = identify(&data, &request).unwrap().calibration;
    let measurements = Measurements {
        source: "campaign.csv".into(),
        stops: data,
        ignored_columns: Vec::new(),
    };
    let files = std::slice::from_ref(&measurements);
    let name = EffectName::parse("compliance:A5").unwrap();
    let why = diagnose::follow(&cal, files, &name, false).unwrap_err();
    assert!(
        why.contains("not physical") && why.contains("parameters.c"),
        "{why}"
    );
    let d = diagnose::diagnose(&cal, files, &DiagnoseOptions::default()).unwrap();
    if let Some(first) = d.candidates.first() {
        assert_ne!(first.effect, "compliance:A5", "{:#?}", d.candidates);
    }
    let c = d
        .considered
        .iter()
        .find(|f| f.effect == "compliance:A5")
        .unwrap();
    println!("compliance:A5: {:?}", c.vetoed);
    println!("first: {:?}", d.candidates.first().map(|f| &f.effect));
}
