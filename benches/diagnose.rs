//! `diagnose` over every candidate the paper's model lacks (42 effects, 4-fold
//! cross-validation each, plus the re-identifications that look for twins of a finding) on
//! the paper's campaign (the shipped fixtures, about 3,000 measured points). Target: ≤ 10 s
//! on the 2-core machine.

//!
//! Through the library's API alone, as another tool would call it.

use std::path::Path;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use robopost::{diagnose, identify, load_calibration, read_measurements, DiagnoseOptions};

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(name)
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("diagnose (paper campaign, all candidates)");
    group.sample_size(10);

    // Nothing missing: the shipped example calibration on the campaign it was identified from.
    let cal = load_calibration(&fixture("calibrations/kr30ha-example.json")).expect("calibration");
    let clean =
        read_measurements(&fixture("fixtures/measurements/campaign.csv")).expect("campaign");
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
    // Identified unaided (the target vector from the data), as a user's campaign would be.
    let hidden =
        read_measurements(&fixture("fixtures/measurements/campaign-hidden.csv")).expect("campaign");
    let paths = read_measurements(&fixture("fixtures/measurements/validation-hidden.csv"))
        .expect("validation");
    let paper = identify(std::slice::from_ref(&hidden), robopost::PAPER_EFFECTS)
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
