//! Parses and emits one KRL file N times, for CPU-time measurements of the front end that a
//! loaded machine's wall clock cannot give (see BENCH.md):
//!
//! ```sh
//! python3 fixtures/gen/cam_program.py milling /tmp/cam1m.src --points 1000000
//! cargo build --release --example krl_parse_loop
//! perf stat -e task-clock target/release/examples/krl_parse_loop /tmp/cam1m.src 5
//! ```

use robopost::krl::{self, FileKind};
use std::path::PathBuf;

fn main() {
    let mut args = std::env::args().skip(1);
    let path = PathBuf::from(args.next().expect("usage: krl_parse_loop FILE [N]"));
    let n: usize = args.next().map_or(5, |a| a.parse().expect("N is a count"));
    let src = std::fs::read(&path).expect("readable file");
    for _ in 0..n {
        let file = krl::parse(&src, FileKind::from_path(&path)).expect("a valid program");
        assert_eq!(file.emit(), src);
    }
    println!("{} bytes parsed and emitted {n} times", src.len());
}
