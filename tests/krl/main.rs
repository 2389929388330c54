//! KRL front end: byte round-trips and snapshots over every fixture, what the parser
//! understood of each program style, bad-input messages, generated programs (proptest), the
//! grammar file kept in step with the parser, and `robopost check`.

mod bad;
mod check_cli;
mod fixtures;
mod grammar;
mod props;
mod semantics;
mod stream;

use robopost::krl::{self, FileKind, SourceFile};
use std::path::{Path, PathBuf};

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every file under `fixtures/<dir>` (recursively), sorted.
pub fn files_under(dir: &str) -> Vec<PathBuf> {
    fn walk(p: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(p).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else {
                out.push(p);
            }
        }
    }
    let mut v = Vec::new();
    walk(&root().join("fixtures").join(dir), &mut v);
    v.sort();
    v
}

/// Parses a fixture (recovering), by its extension.
pub fn load(path: &Path) -> (Vec<u8>, SourceFile) {
    let bytes = std::fs::read(path).unwrap();
    let file = krl::parse_recovering(&bytes, FileKind::from_path(path));
    (bytes, file)
}

pub fn fixture(rel: &str) -> (Vec<u8>, SourceFile) {
    load(&root().join("fixtures/programs").join(rel))
}
