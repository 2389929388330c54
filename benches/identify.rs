//! Identification of the paper's full model (`geometric,map:A1..A6,backlash:A1..A6,
//! crosstalk:A3->A2`, ~2,300 parameters) from the paper's campaign (3,232 measured points,
//! `fixtures/measurements/campaign.csv`): the whole `robopost identify` job (direct method,
//! Levenberg–Marquardt refinement, standard errors of every parameter), and the refinement
//! alone without standard errors.

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use robopost::identify::pipeline::{identify, Request};
use robopost::identify::{refine, setup, RefineOptions};
use robopost::kinematics::{Payload, RobotDescription};
use robopost::measure::read_csv;
use robopost::model::{expand_list, Model};
use robopost::simulate::paper::TARGET_MM;

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/measurements/campaign.csv");
    let stops = read_csv(&path).expect("fixture").stops;
    let request = Request {
        target_mm: Some(TARGET_MM),
        ..Request::default()
    };
    let mut group = c.benchmark_group("identify");
    group.sample_size(10);
    group.bench_function("paper_model_paper_campaign", |b| {
        b.iter(|| identify(&stops, &request).expect("identify"))
    });
    let mut model = Model::new(
        RobotDescription::kr30ha(),
        Payload::default(),
        nalgebra::Vector3::from(TARGET_MM),
    );
    let names =
        expand_list("geometric,map:A1..A6,backlash:A1..A6,crosstalk:A3->A2").expect("names");
    setup::add_effects(&mut model, &names, &stops, &setup::GridChoice::default()).expect("grids");
    let options = RefineOptions {
        standard_errors: false,
        ..RefineOptions::default()
    };
    group.bench_function("refine_only_no_standard_errors", |b| {
        b.iter(|| refine(&mut model.clone(), &stops, &options).expect("refine"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
