//! The seam between the robot language and the rest of the house (issue 39): the KRL front
//! end (`src/krl/`: its reader `syntax`, its interpreter `interpret`, its rewriter `rewrite`
//! and the program `job`) hands the language-neutral motion form (`motion::form`) to the
//! planning, the compensation and the model, which never name the front end. This test reads
//! the sources of the language-neutral rooms and fails on any mention of `krl` in code (a
//! path `crate::krl::…`, `krl::Span`, `use crate::{krl, …}`), comments and string contents
//! aside; and it holds the front end's reader to the project's rule that the KRL syntax
//! knows nothing of kinematics: its code names no module of the crate but its own, the
//! diagnostics and the input reader, and climbs out of `syntax` by no `super::`.

use std::path::{Path, PathBuf};

#[path = "support/sources.rs"]
mod sources;
use sources::{has_word, root, rust_files};

/// The language-neutral rooms: whatever a second robot language would share.
const NEUTRAL: [&str; 7] = [
    "src/motion",
    "src/compensate",
    "src/model",
    "src/kinematics",
    "src/identify",
    "src/diagnose",
    "src/compare",
];
/// The KRL reader.
const SYNTAX: &str = "src/krl/syntax";
/// What the reader may name with `crate::`.
const SYNTAX_MAY_USE: [&str; 3] = ["crate::krl::syntax", "crate::diagnostic", "crate::input"];

/// The code of a source text, line by line (numbered from 1): comments removed and the
/// contents of string literals blanked (a message may say "KRL"; code that names the front
/// end may not). Unit tests are code too: they are held to the seam as well.
fn code(text: &str) -> Vec<(usize, String)> {
    let mut in_block = 0usize;
    text.lines()
        .enumerate()
        .map(|(i, line)| {
            let c: Vec<char> = line.chars().collect();
            let mut out = String::new();
            let mut in_string = false;
            let mut k = 0;
            while k < c.len() {
                let next = c.get(k + 1).copied();
                if in_block > 0 {
                    if c[k] == '*' && next == Some('/') {
                        in_block -= 1;
                        k += 1;
                    } else if c[k] == '/' && next == Some('*') {
                        in_block += 1;
                        k += 1;
                    }
                } else if in_string {
                    match c[k] {
                        '\\' => k += 1,
                        '"' => {
                            in_string = false;
                            out.push('"');
                        }
                        _ => {}
                    }
                } else {
                    match (c[k], next) {
                        ('/', Some('/')) => break,
                        ('/', Some('*')) => {
                            in_block += 1;
                            k += 1;
                        }
                        ('"', _) => {
                            in_string = true;
                            out.push('"');
                        }
                        // A character literal of a quote or a backslash is no string.
                        ('\'', Some('"')) if c.get(k + 2) == Some(&'\'') => k += 2,
                        ('\'', Some('\\')) if c.get(k + 3) == Some(&'\'') => k += 3,
                        (ch, _) => out.push(ch),
                    }
                }
                k += 1;
            }
            (i + 1, out)
        })
        .collect()
}

/// Every line of `text` (shown as `shown`) that names the KRL front end.
fn names_the_front_end(shown: &str, text: &str) -> Vec<String> {
    code(text)
        .into_iter()
        .filter(|(_, line)| has_word(line, "krl"))
        .map(|(n, line)| format!("{shown}:{n}: `{}`", line.trim()))
        .collect()
}

/// Every line of the reader's file `text` that reaches outside the reader: a `crate::` path
/// not in [`SYNTAX_MAY_USE`], or more `super::` than the file's depth below `syntax`
/// (`depth` 0 for `syntax/mod.rs`, 1 for `syntax/lex.rs` and `syntax/tree/mod.rs`…).
fn leaves_the_reader(shown: &str, text: &str, depth: usize) -> Vec<String> {
    let mut out = Vec::new();
    for (n, line) in code(text) {
        let foreign = line.match_indices("crate::").any(|(i, _)| {
            let before = line[..i].chars().next_back();
            let path_start = !before.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_');
            path_start && !SYNTAX_MAY_USE.iter().any(|p| line[i..].starts_with(p))
        });
        let climbs = line
            .match_indices("super::")
            .map(|(i, _)| line[i..].split("::").take_while(|s| *s == "super").count())
            .max()
            .unwrap_or(0);
        if foreign || climbs > depth {
            out.push(format!("{shown}:{n}: `{}`", line.trim()));
        }
    }
    out
}

/// A file's module depth below `dir` (see [`leaves_the_reader`]).
fn depth(dir: &Path, file: &Path) -> usize {
    let rel = file.strip_prefix(dir).unwrap();
    let parts = rel.components().count();
    if rel.file_name().is_some_and(|n| n == "mod.rs") {
        parts - 1
    } else {
        parts
    }
}

fn shown(path: &Path) -> String {
    path.strip_prefix(root())
        .unwrap_or(path)
        .display()
        .to_string()
}

#[test]
fn the_language_neutral_rooms_never_name_the_krl_front_end() {
    let files: Vec<PathBuf> = NEUTRAL
        .iter()
        .flat_map(|d| rust_files(&root().join(d)))
        .collect();
    // The rooms are where the test looks (it would pass vacuously on a moved tree).
    for must in [
        "src/motion/form.rs",
        "src/motion/interpolate.rs",
        "src/compensate/sequence/mod.rs",
        "src/compensate/solve.rs",
        "src/model/model.rs",
    ] {
        assert!(files.contains(&root().join(must)), "{must} not scanned");
    }
    let found: Vec<String> = files
        .iter()
        .flat_map(|p| names_the_front_end(&shown(p), &std::fs::read_to_string(p).unwrap()))
        .collect();
    assert!(
        found.is_empty(),
        "the language-neutral rooms name the KRL front end:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_krl_reader_knows_nothing_of_kinematics() {
    let dir = root().join(SYNTAX);
    let files = rust_files(&dir);
    assert!(files.len() > 20, "{files:?}");
    let found: Vec<String> = files
        .iter()
        .flat_map(|p| {
            leaves_the_reader(
                &shown(p),
                &std::fs::read_to_string(p).unwrap(),
                depth(&dir, p),
            )
        })
        .collect();
    assert!(
        found.is_empty(),
        "the KRL reader names what lies outside it:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_scans_find_what_is_put_back() {
    // Each way code can name the front end, and what is not naming it.
    let cases = [
        ("use crate::krl::{Span, Stmt};", true),
        ("pub stmt: &'f crate::krl::Stmt,", true),
        ("use crate::{krl, model};", true),
        ("let s = krl::parse(b, FileKind::Src);", true),
        ("    krl,", true),
        ("// turned into KRL edits by `krl::rewrite`", false),
        ("/* krl::Span */ let a = 1;", false),
        ("let m = \"not a krl file\";", false),
        ("let krl_like = 2; // krl", false),
        (
            "let m = \"escaped \\\" quote\"; use crate::krl::Span;",
            true,
        ),
        ("if c == '\"' { krl::parse(b) }", true),
        ("if c == '\\\\' { \"krl\" }", false),
    ];
    for (line, named) in cases {
        let found = names_the_front_end("x.rs", line);
        assert_eq!(!found.is_empty(), named, "{line}: {found:?}");
    }
    // A block comment over lines.
    assert!(names_the_front_end("x.rs", "/*\nuse crate::krl::Span;\n*/\nfn f() {}").is_empty());
    assert_eq!(
        names_the_front_end("x.rs", "/*\n*/\nuse crate::krl::Span;").len(),
        1
    );

    // The reader reaching out, by path or by climbing.
    let reader = [
        ("use crate::kinematics::Pose;", 1, true),
        ("use crate::motion::frame::Frame;", 1, true),
        ("use crate::krl::interpret::Value;", 1, true),
        ("use crate::krl::syntax::span::Span;", 1, false),
        ("use crate::diagnostic::Severity;", 1, false),
        ("use super::lex::Token;", 1, false),
        ("use super::super::nodes::Nodes;", 2, false),
        ("use super::super::interpret::Value;", 1, true),
        ("use super::rewrite;", 0, true),
        ("// crate::motion::Stop", 1, false),
    ];
    for (line, depth, out) in reader {
        let found = leaves_the_reader("x.rs", line, depth);
        assert_eq!(!found.is_empty(), out, "{line} at depth {depth}: {found:?}");
    }
    let dir = Path::new("/r/src/krl/syntax");
    assert_eq!(depth(dir, &dir.join("mod.rs")), 0);
    assert_eq!(depth(dir, &dir.join("lex.rs")), 1);
    assert_eq!(depth(dir, &dir.join("tree/mod.rs")), 1);
    assert_eq!(depth(dir, &dir.join("tree/tests.rs")), 2);
}
