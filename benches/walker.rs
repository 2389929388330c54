//! The walker's CPU per target on the CAM fixture `fixtures/programs/cam/pocket_milling.src`
//! (22 506 LIN targets): parsing the program (the code every streamed window goes through),
//! walking it with the deferred arrival rates (`robopost::krl::interpret::simulate`: statement dispatch,
//! aggregate evaluation, IK, arrivals) and building the solver's targets from its stops
//! (`program::targets`). rayon's global pool is this one thread, so the benchmark thread's CPU
//! time is all the work: divide by the target count for the CPU per target.

#[path = "support/cam_fixture.rs"]
mod cam_fixture;
#[path = "support/cpu_time.rs"]
mod cpu_time;

use cpu_time::ThreadCpuTime;
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use robopost::krl::job::program;

fn walker(c: &mut Criterion<ThreadCpuTime>) {
    let (model, _, bytes, ws) = cam_fixture::load();
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build_global()
        .expect("the global pool is this thread");
    let sim = robopost::krl::interpret::simulate(&ws, &model.robot, &[]);
    let n = sim.stops.len();
    let mut g = c.benchmark_group(format!("walker 1 thread, pocket_milling ({n} stops)"));
    g.sample_size(10);
    g.bench_function("parse", |b| {
        b.iter(|| {
            black_box(robopost::krl::parse_recovering(
                &bytes,
                robopost::krl::FileKind::Src,
            ))
        })
    });
    g.bench_function("simulate (walk + arrivals)", |b| {
        b.iter(|| black_box(robopost::krl::interpret::simulate(&ws, &model.robot, &[])))
    });
    g.bench_function("targets", |b| {
        b.iter(|| black_box(program::targets(&sim, 0..n, |_| false)))
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = cpu_time::criterion(4);
    targets = walker
}
criterion_main!(benches);
