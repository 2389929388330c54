//! Every fixture: byte-identical emit, tiles covering the file exactly, numbers whose text
//! reads back (through the standard library parser) to the value the parser stored, and a
//! snapshot of the dump of what was understood.

use super::{files_under, load};
use robopost::krl::{self, dump, Expr, FileKind, Stmt, TileKind};

#[test]
fn every_fixture_round_trips_byte_for_byte() {
    let files: Vec<_> = files_under("programs")
        .into_iter()
        .chain(files_under("bad"))
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("src" | "dat")))
        .collect();
    assert!(files.len() >= 35, "{}", files.len());
    for path in files {
        let (bytes, file) = load(&path);
        assert_eq!(file.emit(), bytes, "{}", path.display());
        // The tiles cover the file exactly, in order, and code tiles hold no line end.
        let mut at = 0;
        for (span, kind) in file.tiles() {
            assert_eq!(span.start as usize, at, "{}", path.display());
            at = span.end as usize;
            if kind == TileKind::Code {
                assert!(!file.text(span).contains(&b'\n'), "{}", path.display());
                assert!(!span.is_empty());
            }
        }
        assert_eq!(at, bytes.len());
    }
}

fn check_numbers(file: &krl::SourceFile, e: &Expr, path: &std::path::Path) -> usize {
    let mut n = 0;
    for num in file.numbers(e) {
        let text = std::str::from_utf8(file.text(num.span())).unwrap();
        let want: f64 = text.parse().unwrap();
        assert_eq!(
            num.value.to_bits(),
            want.to_bits(),
            "{} {text}",
            path.display()
        );
        n += 1;
    }
    n
}

#[test]
fn every_number_of_every_position_reads_back_exactly() {
    let mut total = 0;
    for path in files_under("programs") {
        let (_, file) = load(&path);
        for s in file.statements() {
            if let Some(m) = file.motion_of(s) {
                total += check_numbers(&file, &m.target, &path);
                if let Some(a) = m.aux() {
                    total += check_numbers(&file, a, &path);
                }
            }
            if let Some(d) = s.as_decl() {
                for v in d.vars.iter().filter_map(|v| v.init.as_ref()) {
                    total += check_numbers(&file, v, &path);
                }
            }
            if let krl::StmtKind::Assign(a) = &s.kind {
                total += check_numbers(&file, &a.rhs, &path);
            }
        }
    }
    assert!(total > 130_000, "{total}");
}

#[test]
fn no_fixture_program_has_errors() {
    for path in files_under("programs") {
        if !matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("src" | "dat")
        ) {
            continue;
        }
        let bytes = std::fs::read(&path).unwrap();
        if let Err(e) = krl::parse(&bytes, FileKind::from_path(&path)) {
            panic!("{}", e.render(&path.display().to_string()));
        }
    }
}

#[test]
fn dumps_of_what_was_understood() {
    insta::glob!("../../fixtures/programs", "**/*.{src,dat}", |path| {
        let (_, file) = load(path);
        insta::assert_snapshot!(dump::dump_limited(&file, 300));
    });
}

/// Statement spans nest: children inside parents, heads inside spans.
#[test]
fn spans_nest() {
    fn walk(s: &Stmt) {
        assert!(s.span().contains(s.head));
        for c in s.children() {
            assert!(s.span().contains(c.span()), "{:?} {:?}", s.span(), c.span());
            walk(c);
        }
    }
    for path in files_under("programs") {
        let (_, file) = load(&path);
        file.body().iter().for_each(walk);
    }
}
