//! Parses and emits one KRL file N times, for CPU-time measurements of the front end that a
//! loaded machine's wall clock cannot give (see BENCH.md), and reports the bytes the tree
//! holds (a counting global allocator: live heap bytes after parsing, minus the copy of the
//! source the file owns) per line of the file:
//!
//! ```sh
//! python3 fixtures/gen/cam_program.py milling /tmp/cam1m.src --points 1000000
//! cargo build --release --example krl_parse_loop
//! perf stat -e task-clock target/release/examples/krl_parse_loop /tmp/cam1m.src 5
//! ```

use robopost::krl::{self, FileKind};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// The system allocator, counting live bytes and the peak.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let now = LIVE.fetch_add(l.size(), Relaxed) + l.size();
        PEAK.fetch_max(now, Relaxed);
        System.alloc(l)
    }

    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        LIVE.fetch_sub(l.size(), Relaxed);
        System.dealloc(p, l)
    }

    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        if new > l.size() {
            let now = LIVE.fetch_add(new - l.size(), Relaxed) + new - l.size();
            PEAK.fetch_max(now, Relaxed);
        } else {
            LIVE.fetch_sub(l.size() - new, Relaxed);
        }
        System.realloc(p, l, new)
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

fn main() {
    let mut args = std::env::args().skip(1);
    let path = PathBuf::from(args.next().expect("usage: krl_parse_loop FILE [N]"));
    let n: usize = args.next().map_or(5, |a| a.parse().expect("N is a count"));
    let src = std::fs::read(&path).expect("readable file");
    let kind = FileKind::from_path(&path);
    let lines = src.iter().filter(|&&b| b == b'\n').count().max(1);

    let before = LIVE.load(Relaxed);
    PEAK.store(before, Relaxed);
    let file = krl::parse(&src, kind).expect("a valid program");
    let tree = LIVE.load(Relaxed) - before - file.source().len();
    let peak = PEAK.load(Relaxed) - before - file.source().len();
    println!(
        "tree: {tree} bytes = {:.1} per line ({:.2}x the input); peak while parsing {:.1} per line",
        tree as f64 / lines as f64,
        tree as f64 / src.len() as f64,
        peak as f64 / lines as f64,
    );
    drop(file);

    for _ in 0..n {
        let file = krl::parse(&src, kind).expect("a valid program");
        assert_eq!(file.emit(), src);
    }
    println!("{} bytes parsed and emitted {n} times", src.len());
}
