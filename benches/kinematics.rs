//! Nominal kinematics cost per point on one core: closed-form FK, IK with every branch, and
//! IK selecting one solution (by S/T, by nearness), over varied reachable poses.

use criterion::{black_box, criterion_group, criterion_main, Criterion};

#[path = "support/cpu_time.rs"]
mod cpu_time;
use cpu_time::ThreadCpuTime;
use robopost::kinematics::{
    forward, inverse, inverse_all, inverse_all_into, status_turn, Frame, RobotDescription, Select,
};

/// Axis sets spread over the workspace (within limits, clear of singularities) and their
/// flange poses.
fn poses(robot: &RobotDescription) -> Vec<([f64; 6], Frame)> {
    (0..256)
        .map(|i| {
            let t = i as f64;
            let axes = [
                (t * 1.3) % 300.0 - 150.0,
                -120.0 + (t * 0.7) % 140.0,
                -60.0 + (t * 0.9) % 200.0,
                (t * 2.1) % 600.0 - 300.0,
                5.0 + (t * 0.8) % 100.0,
                (t * 2.7) % 600.0 - 300.0,
            ];
            (axes, forward(robot, &axes))
        })
        .collect()
}

fn kinematics(c: &mut Criterion<ThreadCpuTime>) {
    let robot = RobotDescription::kr30ha();
    let points = poses(&robot);
    let n = points.len();
    let solutions: usize = points
        .iter()
        .map(|(_, f)| inverse_all(&robot, f).map_or(0, |v| v.len()))
        .sum();
    eprintln!(
        "poses: {n}, mean solutions per pose (configurations × ±360° variants): {:.1}",
        solutions as f64 / n as f64
    );
    let mut i = 0;
    c.bench_function("fk (closed form)", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(forward(black_box(&robot), black_box(&points[i].0)))
        })
    });
    c.bench_function("ik all branches with ±360° variants (new Vec)", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(inverse_all(black_box(&robot), black_box(&points[i].1)))
        })
    });
    let mut buffer = Vec::with_capacity(64);
    c.bench_function("ik all branches with ±360° variants (reused Vec)", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            let r = inverse_all_into(black_box(&robot), black_box(&points[i].1), &mut buffer);
            black_box((r, buffer.len()))
        })
    });
    let selects: Vec<Select> = points
        .iter()
        .map(|(axes, _)| {
            let (s, t) = status_turn(&robot, axes);
            Select::Status { s, t: Some(t) }
        })
        .collect();
    c.bench_function("ik selected by S and T", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(inverse(
                black_box(&robot),
                black_box(&points[i].1),
                selects[i],
            ))
        })
    });
    c.bench_function("ik nearest of all 8 configurations", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            let near = points[(i + n - 1) % n].0;
            black_box(inverse(
                black_box(&robot),
                black_box(&points[i].1),
                Select::Nearest(near),
            ))
        })
    });
    let near_selects: Vec<Select> = points
        .iter()
        .map(|(axes, _)| Select::StatusNearest {
            s: status_turn(&robot, axes).0,
            near: axes.map(|a| a + 0.1),
        })
        .collect();
    c.bench_function("ik selected by S, nearest", |b| {
        b.iter(|| {
            i = (i + 1) % n;
            black_box(inverse(
                black_box(&robot),
                black_box(&points[i].1),
                near_selects[i],
            ))
        })
    });
}

criterion_group! {
    name = benches;
    config = cpu_time::criterion(3);
    targets = kinematics
}
criterion_main!(benches);
