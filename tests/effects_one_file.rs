//! What an effect knows lives in its own file (`src/model/effects/`) and its registry entry:
//! identification, diagnosis and compensation ask the effect ([`Effect::role`], its
//! [`Kind`]) and never recognise one by its name or its type. This test reads their sources
//! and fails on a string that spells an effect's name (`"backlash:A"`, `"tilt"`) or on an
//! effect's type or module (`GearPlay`, `effects::map`) outside comments and unit tests.
//! Together with `tests/effect_added_at_run_time.rs` (a new effect as one file, used by all
//! three without edits) it is the check of issue 22's "effects as one file each".
//!
//! One exception: `learned` effects are what `diagnose::learn` writes: their definition
//! language is the diagnosis's own product, so diagnosis and the promise check of `identify`
//! read it. The evidence sentence of a kind is chosen by its registry entry
//! (`Kind::evidence`), not by its name.
//!
//! [`Effect::role`]: robopost::model::Effect::role
//! [`Kind`]: robopost::model::registry::Kind

use std::path::PathBuf;

#[path = "support/sources.rs"]
mod sources;
use sources::{has_word, root, rust_files};

use robopost::model::registry::KINDS;

const SCANNED: [&str; 7] = [
    "src/identify",
    "src/diagnose",
    "src/compensate",
    // The program job and the rewrite, which were in `src/compensate/` before issue 39.
    "src/krl/job",
    "src/krl/rewrite",
    "src/calibration",
    "src/cli",
];
const EXCEPT_FILES: [&str; 0] = [];
const EXCEPT_KINDS: [&str; 1] = ["learned"];
/// Files of `src/model/effects/` that are shared machinery, not an effect.
const SHARED: [&str; 2] = ["mod.rs", "axis_table.rs"];

/// The code of a source file: without its unit tests (`#[cfg(test)]` to the end, where this
/// crate keeps them) and without comments.
fn code(text: &str) -> Vec<(usize, String)> {
    let text = text.split("#[cfg(test)]").next().unwrap_or("");
    text.lines()
        .enumerate()
        .map(|(i, line)| {
            // A `//` outside a string starts a comment.
            let mut in_string = false;
            let mut prev = ' ';
            let mut end = line.len();
            for (k, c) in line.char_indices() {
                if c == '"' && prev != '\\' {
                    in_string = !in_string;
                }
                if !in_string && c == '/' && prev == '/' {
                    end = k - 1;
                    break;
                }
                prev = c;
            }
            (i + 1, line[..end].to_string())
        })
        .collect()
}

/// The spellings that give an effect away: each kind's name as a string (`"tilt"`,
/// `"tilt:`), and each effect file's module path and public types.
fn forbidden() -> (Vec<String>, Vec<String>) {
    let mut strings = Vec::new();
    for kind in KINDS {
        if EXCEPT_KINDS.contains(&kind.prefix) {
            continue;
        }
        strings.push(format!("\"{}\"", kind.prefix));
        strings.push(format!("\"{}:", kind.prefix));
    }
    let mut words = Vec::new();
    for path in rust_files(&root().join("src/model/effects")) {
        let file = path.file_name().unwrap().to_str().unwrap().to_string();
        let module = file.trim_end_matches(".rs").to_string();
        if SHARED.contains(&file.as_str()) || EXCEPT_KINDS.contains(&module.as_str()) {
            continue;
        }
        words.push(format!("effects::{module}"));
        for (_, line) in code(&std::fs::read_to_string(&path).unwrap()) {
            for keyword in ["pub struct ", "pub enum ", "pub trait "] {
                if let Some(rest) = line.trim_start().strip_prefix(keyword) {
                    let name: String = rest
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                        .collect();
                    words.push(name);
                }
            }
        }
    }
    (strings, words)
}

/// Every line of the scanned sources that names an effect.
fn offences(files: &[PathBuf]) -> Vec<String> {
    let (strings, words) = forbidden();
    let mut out = Vec::new();
    for path in files {
        let shown = path
            .strip_prefix(root())
            .unwrap_or(path)
            .display()
            .to_string();
        if EXCEPT_FILES.contains(&shown.as_str()) {
            continue;
        }
        for (n, line) in code(&std::fs::read_to_string(path).unwrap()) {
            let hits: Vec<&String> = strings
                .iter()
                .filter(|s| line.contains(s.as_str()))
                .chain(words.iter().filter(|w| has_word(&line, w)))
                .collect();
            if !hits.is_empty() {
                out.push(format!("{shown}:{n}: {hits:?} in `{}`", line.trim()));
            }
        }
    }
    out
}

#[test]
fn identify_diagnose_and_compensate_never_name_an_effect() {
    let (strings, words) = forbidden();
    // The lists are what they claim to be (the test would pass vacuously otherwise).
    for s in [
        "\"backlash:",
        "\"map:",
        "\"crosstalk:",
        "\"tilt\"",
        "\"geometric\"",
        "\"drift\"",
    ] {
        assert!(strings.iter().any(|x| x == s), "{s} in {strings:?}");
    }
    for w in [
        "GearPlay",
        "AngleMap",
        "Crosstalk",
        "Compliance",
        "Tilt",
        "Drift",
        "Geometric",
    ] {
        assert!(words.iter().any(|x| x == w), "{w} in {words:?}");
    }
    let files: Vec<PathBuf> = SCANNED
        .iter()
        .flat_map(|d| rust_files(&root().join(d)))
        .collect();
    assert!(files.len() > 20, "{files:?}");
    let found = offences(&files);
    assert!(
        found.is_empty(),
        "effects named outside their own file:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_scan_finds_a_name_put_back() {
    // The scanner on a file that matches by name as the code did before issue 22, with a
    // comment and a unit test that may name effects freely.
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "let Some(n) = name.strip_prefix(\"backlash:A\") else {",
            true,
        ),
        ("if name.starts_with(\"tilt\") {", true),
        ("let e = GearPlay::zeros(1, &o, &r);", true),
        (
            "use crate::model::effects::crosstalk::gravity_look_alikes;",
            true,
        ),
        ("// the play of `backlash:An` (\"backlash:A1\")", false),
        ("let s = \"mapping of the axes\";", false),
        ("let sinh = TiltAngle::new();", false),
    ];
    for (i, (line, bad)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("case{i}.rs"));
        let text = format!(
            "fn f() {{\n    {line}\n}}\n\n#[cfg(test)]\nmod tests {{\n    const X: &str = \"map:A1\";\n}}\n"
        );
        std::fs::write(&path, text).unwrap();
        let found = offences(&[path]);
        assert_eq!(!found.is_empty(), *bad, "{line}: {found:?}");
    }
}
