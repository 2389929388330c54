//! Per-target CPU of the phases around the solver on the CAM fixture
//! `fixtures/programs/cam/pocket_milling.src` (22 506 LIN targets, the paper's full model):
//! motion simulation, rewrite (edits of every compensated target), applying the edits, and
//! the whole program in process. rayon's global pool is this one thread
//! (`use_current_thread`), so the benchmark thread's CPU time (the machine is shared) is all
//! the work, parallel parts included: divide by the target count for the CPU per target.

#[path = "support/cam_fixture.rs"]
mod cam_fixture;
#[path = "support/cpu_time.rs"]
mod cpu_time;

use cpu_time::ThreadCpuTime;
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use robopost::compensate::{self};
use robopost::krl::job::{program, Calibrated};

fn phases(c: &mut Criterion<ThreadCpuTime>) {
    let (model, cal_bytes, _, ws) = cam_fixture::load();
    let calibrated = Calibrated::new(&model, "kr30ha-handset.json", &cal_bytes);
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build_global()
        .expect("the global pool is this thread");
    {
        let sim = robopost::krl::interpret::simulate(&ws, &model.robot, &[]);
        let targets = program::targets(&sim, 0..sim.stops.len(), |_| false);
        let n = targets.len();
        let outcomes = compensate::compensate(
            &model,
            &sim.frames,
            &targets,
            [Default::default(); 6],
            &compensate::Options::default(),
        );
        let rw = robopost::krl::rewrite::rewrite(&ws, &sim, &outcomes, &model.robot, None);
        let edits = rw.edits.values().next().expect("the program is rewritten");
        let header = robopost::krl::Edit {
            range: 0..0,
            bytes: b"; header\n".to_vec(),
        };
        let mut g = c.benchmark_group(format!("pipeline 1 thread, pocket_milling ({n} targets)"));
        g.sample_size(10);
        g.bench_function("simulate", |b| {
            b.iter(|| black_box(robopost::krl::interpret::simulate(&ws, &model.robot, &[])))
        });
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
        g.bench_function("apply edits", |b| {
            b.iter(|| black_box(edits.apply(ws.get(ws.main).file.source(), &header)))
        });
        let options = program::Options::default();
        g.bench_function("whole program in process", |b| {
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
}

criterion_group! {
    name = benches;
    config = cpu_time::criterion(5);
    targets = phases
}
criterion_main!(benches);
