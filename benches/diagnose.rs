//! `diagnose` over every candidate the paper's model lacks (42 effects, 4-fold
//! cross-validation each, plus the re-identifications that look for twins of a finding) on
//! the paper's campaign (the shipped fixtures, about 3,000 measured points). Target: ≤ 10 s
//! on the 2-core machine.

use std::path::Path;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use robopost::calibration;
use robopost::diagnose::{diagnose, DiagnoseOptions};
use robopost::identify::pipeline::{identify, Request};
use robopost::measure::read_csv;

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(name)
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("diagnose (paper campaign, all candidates)");
    group.sample_size(10);

    // Nothing missing: the shipped example calibration on the campaign it was identified from.
    let cal = calibration::load(&fixture("calibrations/kr30ha-example.json")).expect("calibration");
    let clean = read_csv(&fixture("fixtures/measurements/campaign.csv")).expect("campaign");
    group.bench_function("clean campaign", |b| {
        b.iter(|| {
            black_box(diagnose(
                &cal,
                std::slice::from_ref(&clean),
                &DiagnoseOptions::default(),
            ))
        })
    });

    // A finding (tilt of A1) and its twin search: the paper's model identified on the campaign
    // of the virtual robot with hidden effects, diagnosed on that campaign and the paths.
    let hidden = read_csv(&fixture("fixtures/measurements/campaign-hidden.csv")).expect("campaign");
    let paths =
        read_csv(&fixture("fixtures/measurements/validation-hidden.csv")).expect("validation");
    let request = Request {
        target_mm: Some([-120.0, -80.0, 180.0]),
        ..Request::default()
    };
    let paper = identify(&hidden.stops, &request)
        .expect("identify")
        .calibration;
    let data = [hidden, paths];
    group.bench_function("hidden effects campaign + paths", |b| {
        b.iter(|| black_box(diagnose(&paper, &data, &DiagnoseOptions::default())))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
