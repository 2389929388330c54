//! KRL front-end throughput: parse + emit of a generated 1,000,000-line CAM milling program
//! (~60 MB, one `LIN {X …,Y …,Z …,A …,B …,C …} C_DIS` per line, CRLF) on one core.
//! Target: ≥ 200 MB/s. Numbers in BENCH.md.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use robopost::krl::{self, FileKind};
use std::fmt::Write;
use std::time::Duration;

/// The same shape as `fixtures/gen/cam_program.py milling`, with `lines` LIN points.
fn cam_program(lines: usize) -> Vec<u8> {
    let mut s = String::with_capacity(lines * 64);
    s.push_str("&ACCESS RVP\r\n&REL 1\r\nDEF bench_cam ( )\r\n");
    s.push_str("$BASE = {FRAME: X 1500.000,Y -250.000,Z 620.000,A 0.000,B 0.000,C 0.000}\r\n");
    s.push_str("$TOOL = {FRAME: X 0.000,Y 0.000,Z 245.300,A 0.000,B -90.000,C 0.000}\r\n");
    s.push_str("$VEL.CP = 0.080\r\n");
    for k in 0..lines {
        let t = k as f64;
        let x = 300.0 * ((t * 0.013).sin() * 0.5 + 0.5);
        let y = 2.4 * (k / 150) as f64 % 180.0;
        let z = -1.0 - 0.35 * (t * 0.01).cos();
        let b = 90.0 + 4.5 * (x / 40.0).cos();
        let c = 2.0 * (y / 30.0).sin();
        let _ = write!(
            s,
            "LIN {{X {x:.3},Y {y:.3},Z {z:.3},A 0.000,B {b:.3},C {c:.3}}} C_DIS\r\n"
        );
    }
    s.push_str("END\r\n");
    s.into_bytes()
}

fn parse_and_emit(c: &mut Criterion) {
    let src = cam_program(1_000_000);
    let mut g = c.benchmark_group("krl");
    g.throughput(Throughput::Bytes(src.len() as u64));
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(20));
    g.bench_function("parse+emit 1M-line CAM program", |b| {
        b.iter(|| {
            let file = krl::parse(black_box(&src), FileKind::Src).expect("valid program");
            let out = file.emit();
            assert_eq!(out.len(), src.len());
            out
        })
    });
    g.bench_function("parse 1M-line CAM program", |b| {
        b.iter(|| krl::parse(black_box(&src), FileKind::Src).expect("valid program"))
    });
    g.finish();
}

criterion_group!(benches, parse_and_emit);
criterion_main!(benches);
