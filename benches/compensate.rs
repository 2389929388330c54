//! Compensation cost per phase on the CAM fixture `fixtures/programs/cam/pocket_milling.src`
//! (22 506 LIN targets, the paper's full model from `calibrations/kr30ha-handset.json`):
//! parse + load, motion simulation, the compensation itself (one thread), rewrite, and the
//! whole program in process. CPU time of the benchmark thread (the machine is shared). The
//! end-to-end runs on a generated 1 000 000-point program and a 1000 × 1000 batch are in
//! `scripts/bench_compensate.sh` (wall time and peak memory with /usr/bin/time).

#[path = "support/cam_fixture.rs"]
mod cam_fixture;
#[path = "support/cpu_time.rs"]
mod cpu_time;

use std::path::Path;

use cpu_time::ThreadCpuTime;
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use robopost::compensate::{self};
use robopost::krl::job::{files, program, Calibrated};

use cam_fixture::PROGRAM;

fn phases(c: &mut Criterion<ThreadCpuTime>) {
    let (model, cal_bytes, bytes, ws) = cam_fixture::load();
    let calibrated = Calibrated::new(&model, "kr30ha-handset.json", &cal_bytes);
    let sim = robopost::krl::interpret::simulate(&ws, &model.robot, &[]);
    let targets = program::targets(&sim, 0..sim.stops.len(), |_| false);
    let n = targets.len();
    let serial = compensate::Options {
        method: compensate::Method::Iterate,
        parallel: false,
        stretching: robopost::compensate::sequence::Stretching::DEFAULT,
    };
    let options = program::Options {
        parallel: false,
        stretching: robopost::compensate::sequence::Stretching::DEFAULT,
        ..Default::default()
    };
    let mut g = c.benchmark_group(format!("pocket_milling ({n} targets)"));
    g.sample_size(10);
    g.bench_function("load (parse .src)", |b| {
        b.iter(|| black_box(files::load_program(Some(Path::new(PROGRAM)), &bytes, None).unwrap()))
    });
    g.bench_function("simulate", |b| {
        b.iter(|| black_box(robopost::krl::interpret::simulate(&ws, &model.robot, &[])))
    });
    g.bench_function("compensate targets (1 thread)", |b| {
        b.iter(|| {
            black_box(compensate::compensate(
                &model,
                &sim.frames,
                &targets,
                [Default::default(); 6],
                &serial,
            ))
        })
    });
    let outcomes = compensate::compensate(
        &model,
        &sim.frames,
        &targets,
        [Default::default(); 6],
        &serial,
    );
    g.bench_function("rewrite", |b| {
        b.iter(|| {
            black_box(robopost::krl::rewrite::rewrite(
                &ws,
                &sim,
                &outcomes,
                &model.robot,
                None,
            ))
        })
    });
    g.bench_function("whole program in process (1 thread)", |b| {
        b.iter(|| {
            black_box(robopost::krl::job::compensate_program(
                &ws,
                &calibrated,
                &options,
            ))
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = cpu_time::criterion(8);
    targets = phases
}
criterion_main!(benches);
