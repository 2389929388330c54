//! The README's asserted figures: blocks between `<!-- asserted: NAME -->` and
//! `<!-- /asserted -->` hold numbers that a test computes afresh and compares, so a stale
//! README fails CI and updating a figure is editing the README only. Three shapes:
//!
//! - a Markdown table: [`assert_row`] compares one row's numeric cells (found by its label);
//! - a fenced block of command output: [`assert_output`] compares it with the output a test
//!   produced, token by token (words exactly, numbers within a tolerance; `...` and `(...)`
//!   skip any amount of output; line breaks do not matter);
//! - prose: [`assert_prose`] compares every number of the block, in order.
//!
//! Included by the tests that compute the figures (`#[path = "support/readme.rs"] mod readme;`).

#![allow(dead_code)]

use std::path::Path;

/// One asserted block of the README.
#[derive(Clone, Debug)]
pub struct Block {
    pub name: String,
    pub text: String,
    /// 1-based README line of the opening marker.
    pub line: usize,
}

const OPEN: &str = "<!-- asserted: ";
const CLOSE: &str = "<!-- /asserted -->";

/// Set `ROBOPOST_README_UPDATE=1` to have the asserting functions write the computed figures
/// into the README instead of failing (as `INSTA_UPDATE` does for snapshots; run with
/// `--test-threads=1` and review the diff).
fn updating() -> bool {
    std::env::var_os("ROBOPOST_README_UPDATE").is_some_and(|v| v == "1")
}

/// The numbers of `text` as [`numbers`] finds them: (byte start incl. sign, byte end, decimals,
/// sign character or none, thousands separators used).
fn number_spans(text: &str) -> Vec<(usize, usize, usize, Option<char>, bool)> {
    let chars: Vec<(usize, char)> = text.char_indices().collect();
    let byte = |k: usize| chars.get(k).map_or(text.len(), |c| c.0);
    let mut out = Vec::new();
    let mut in_code = false;
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i].1;
        if c == '`' {
            in_code = !in_code;
            i += 1;
            continue;
        }
        let glued = i > 0 && (chars[i - 1].1.is_alphanumeric() || chars[i - 1].1 == '_');
        if in_code || !c.is_ascii_digit() || glued {
            i += 1;
            continue;
        }
        let sign =
            (i > 0 && (chars[i - 1].1 == '−' || chars[i - 1].1 == '-')).then(|| chars[i - 1].1);
        let (mut j, mut decimals, mut grouped, mut after_point) = (i, 0, false, false);
        while j < chars.len() {
            let d = chars[j].1;
            if d.is_ascii_digit() {
                if after_point {
                    decimals += 1;
                }
                j += 1;
            } else if d == ','
                && chars[j + 1..]
                    .iter()
                    .take(3)
                    .filter(|x| x.1.is_ascii_digit())
                    .count()
                    == 3
                && !chars.get(j + 4).is_some_and(|x| x.1.is_ascii_digit())
            {
                grouped = true;
                j += 1;
            } else if d == '.' && chars.get(j + 1).is_some_and(|x| x.1.is_ascii_digit()) {
                after_point = true;
                j += 1;
            } else {
                break;
            }
        }
        let start = if sign.is_some() { byte(i - 1) } else { byte(i) };
        out.push((start, byte(j), decimals, sign, grouped));
        i = j;
    }
    out
}

/// `text` with its numbers (from the `skip`-th on) replaced by `values`, each written with the
/// decimals, sign style and thousands separators of the number it replaces.
fn rewrite_numbers(text: &str, skip: usize, values: &[f64]) -> String {
    let spans = number_spans(text);
    let mut out = text.to_string();
    for (k, &(start, end, decimals, sign, grouped)) in spans.iter().enumerate().skip(skip).rev() {
        let Some(&v) = values.get(k - skip) else {
            continue;
        };
        let mut digits = format!("{:.decimals$}", v.abs());
        if grouped {
            let (int, frac) = digits
                .split_once('.')
                .map_or((digits.as_str(), ""), |(a, b)| (a, b));
            let mut g = String::new();
            for (n, ch) in int.chars().enumerate() {
                if n > 0 && (int.len() - n) % 3 == 0 {
                    g.push(',');
                }
                g.push(ch);
            }
            digits = if frac.is_empty() {
                g
            } else {
                format!("{g}.{frac}")
            };
        }
        let negative = v < 0.0 && digits.chars().any(|c| c.is_ascii_digit() && c != '0');
        let minus = sign.unwrap_or('−');
        let new = if negative {
            format!("{minus}{digits}")
        } else {
            digits
        };
        out.replace_range(start..end, &new);
    }
    out
}

/// Rewrites block `name` of the README through `edit`.
fn update_block(name: &str, edit: impl Fn(&str) -> String) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md");
    let text = std::fs::read_to_string(&path).expect("README.md");
    let open = format!("{OPEN}{name} -->");
    let start = text.find(&open).expect("block") + open.len();
    let end = start + text[start..].find(CLOSE).expect("block end");
    let new = format!(
        "{}{}{}",
        &text[..start],
        edit(&text[start..end]),
        &text[end..]
    );
    std::fs::write(&path, new).expect("README.md written");
}

/// Writes `computed` into the row `label` of table block `name`.
fn update_row(name: &str, label: &str, computed: &[f64]) {
    update_block(name, |block| {
        block
            .split_inclusive('\n')
            .map(|line| {
                let cells: Vec<&str> = line.trim().trim_matches('|').split('|').collect();
                if line.trim_start().starts_with('|') && cells[0].trim().starts_with(label) {
                    let first = line.find('|').unwrap() + 1;
                    let first = first + line[first..].find('|').unwrap();
                    format!(
                        "{}{}",
                        &line[..first],
                        rewrite_numbers(&line[first..], 0, computed)
                    )
                } else {
                    line.to_string()
                }
            })
            .collect()
    });
}

pub fn readme_text() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md");
    std::fs::read_to_string(path).expect("README.md")
}

/// Every asserted block, in README order.
pub fn blocks_of(text: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut rest = text;
    let mut offset = 0;
    while let Some(start) = rest.find(OPEN) {
        let after = &rest[start + OPEN.len()..];
        let name_end = after.find("-->").expect("an asserted marker ends with -->");
        let name = after[..name_end].trim().to_string();
        let body = &after[name_end + 3..];
        let end = body
            .find(CLOSE)
            .unwrap_or_else(|| panic!("README block `{name}` has no {CLOSE}"));
        let line = text[..offset + start].lines().count() + 1;
        out.push(Block {
            name,
            text: body[..end].to_string(),
            line,
        });
        let consumed = start + OPEN.len() + name_end + 3 + end + CLOSE.len();
        offset += consumed;
        rest = &rest[consumed..];
    }
    out
}

pub fn blocks() -> Vec<Block> {
    blocks_of(&readme_text())
}

/// The asserted block `name` (exactly one).
pub fn block(name: &str) -> Block {
    let found: Vec<Block> = blocks().into_iter().filter(|b| b.name == name).collect();
    assert_eq!(
        found.len(),
        1,
        "README: asserted block `{name}` found {} times",
        found.len()
    );
    found.into_iter().next().unwrap()
}

/// A number written in the README or printed by a command: `−` or `-` sign, thousands
/// separators (`3,376`), decimals. Returns the value and the rest of the token around it.
pub fn parse_number(token: &str) -> Option<f64> {
    let t = token.replace('−', "-");
    let t = t.trim_matches(|c: char| !(c.is_ascii_digit() || c == '-' || c == '.'));
    let t = t.trim_end_matches('.');
    if t.is_empty() || !t.chars().any(|c| c.is_ascii_digit()) {
        return None;
    }
    t.replace(',', "").parse::<f64>().ok()
}

/// Every number in `text` outside inline code, in order: a run of digits (with `,` thousands
/// groups and a decimal part) not glued to a letter on the left (`A1`, `dx21`, `path1` are
/// names, not figures), with a leading minus.
pub fn numbers(text: &str) -> Vec<f64> {
    let mut out = Vec::new();
    let chars: Vec<char> = text.chars().collect();
    let mut in_code = false;
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if c == '`' {
            in_code = !in_code;
            i += 1;
            continue;
        }
        let glued = i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_');
        if in_code || !c.is_ascii_digit() || glued {
            i += 1;
            continue;
        }
        let negative = i > 0 && (chars[i - 1] == '−' || chars[i - 1] == '-');
        let mut j = i;
        let mut s = String::new();
        while j < chars.len() {
            let d = chars[j];
            if d.is_ascii_digit() {
                s.push(d);
                j += 1;
            } else if d == ','
                && j + 3 < chars.len() + 1
                && chars[j + 1..]
                    .iter()
                    .take(3)
                    .filter(|x| x.is_ascii_digit())
                    .count()
                    == 3
                && !chars.get(j + 4).is_some_and(|x| x.is_ascii_digit())
            {
                j += 1;
            } else if d == '.' && chars.get(j + 1).is_some_and(|x| x.is_ascii_digit()) {
                s.push('.');
                j += 1;
            } else {
                break;
            }
        }
        // A name glued on the right (`3-D` is a figure; `2x` is not one we write).
        let v: f64 = s.parse().unwrap();
        out.push(if negative { -v } else { v });
        i = j;
    }
    out
}

/// The rows of the Markdown table in `block` (header and separator excluded) as cells.
pub fn table_rows(block: &Block) -> Vec<Vec<String>> {
    let rows: Vec<Vec<String>> = block
        .text
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with('|'))
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect()
        })
        .collect();
    rows.into_iter()
        .skip(1)
        .filter(|r| !r.iter().all(|c| c.chars().all(|x| x == '-' || x == ':')))
        .collect()
}

/// The row of table block `name` whose first cell starts with `label`: its cells after the
/// first, and their numbers (an empty cell gives none).
pub fn row(name: &str, label: &str) -> Vec<String> {
    let b = block(name);
    let rows: Vec<Vec<String>> = table_rows(&b)
        .into_iter()
        .filter(|r| r[0].starts_with(label))
        .collect();
    assert_eq!(
        rows.len(),
        1,
        "README block `{name}` (line {}): {} rows start with `{label}`",
        b.line,
        rows.len()
    );
    rows[0][1..].to_vec()
}

/// Compares the numeric cells of the row `label` of table `name` with `computed`, each within
/// `tolerance`.
pub fn assert_row(name: &str, label: &str, computed: &[f64], tolerance: f64) {
    let cells = row(name, label);
    if updating() {
        let written: Vec<f64> = cells.iter().flat_map(|c| numbers(c)).collect();
        if written.len() != computed.len()
            || written
                .iter()
                .zip(computed)
                .any(|(w, c)| (w - c).abs() > tolerance)
        {
            update_row(name, label, computed);
        }
        return;
    }
    let written: Vec<f64> = cells.iter().flat_map(|c| numbers(c)).collect();
    assert_eq!(
        written.len(),
        computed.len(),
        "README `{name}` row `{label}`: {} numbers written ({cells:?}), {} computed ({computed:?})",
        written.len(),
        computed.len()
    );
    for (k, (w, c)) in written.iter().zip(computed).enumerate() {
        assert!(
            (w - c).abs() <= tolerance,
            "README `{name}` row `{label}`, value {k}: the README says {w}, this build computes \
             {c:.3} (tolerance {tolerance}). Update the README: {computed:?}"
        );
    }
}

/// [`assert_row`] for several rows, reporting every stale one at once with the computed rows
/// (rounded as `decimals`) ready to paste.
pub fn assert_rows(name: &str, rows: &[(&str, Vec<f64>)], tolerance: f64, decimals: usize) {
    let mut stale = Vec::new();
    for (label, computed) in rows {
        let cells = row(name, label);
        let written: Vec<f64> = cells.iter().flat_map(|c| numbers(c)).collect();
        let fits = written.len() == computed.len()
            && written
                .iter()
                .zip(computed)
                .all(|(w, c)| (w - c).abs() <= tolerance);
        if !fits && updating() {
            update_row(name, label, computed);
        } else if !fits {
            stale.push(format!(
                "  `{label}`: README {written:?}, computed | {} |",
                computed
                    .iter()
                    .map(|v| format!("{v:.decimals$}"))
                    .collect::<Vec<_>>()
                    .join(" | ")
            ));
        }
    }
    assert!(
        stale.is_empty(),
        "README `{name}`: rows differ from this build by more than {tolerance}:\n{}",
        stale.join("\n")
    );
}

/// Compares every number of the prose block `name` (outside inline code) with `computed`,
/// in order, each within `tolerance`.
pub fn assert_prose(name: &str, computed: &[f64], tolerance: f64) {
    let b = block(name);
    let written = numbers(&b.text);
    if updating() {
        if written.len() == computed.len()
            && written
                .iter()
                .zip(computed)
                .any(|(w, c)| (w - c).abs() > tolerance)
        {
            update_block(name, |t| rewrite_numbers(t, 0, computed));
        }
        return;
    }
    assert_eq!(
        written.len(),
        computed.len(),
        "README `{name}` (line {}): numbers written {written:?}, computed {computed:?}",
        b.line
    );
    for (w, c) in written.iter().zip(computed) {
        assert!(
            (w - c).abs() <= tolerance,
            "README `{name}` (line {}): the README says {w}, this build computes {c:.3} \
             (tolerance {tolerance}); written {written:?}, computed {computed:?}",
            b.line
        );
    }
}

/// The output lines of a fenced block: the code between the fences, without `$ command`
/// lines (and their `\`-continued lines).
fn output_of(block: &Block) -> String {
    let mut out = String::new();
    let mut inside = false;
    let mut continued = false;
    for line in block.text.lines() {
        if line.trim_start().starts_with("```") {
            inside = !inside;
            continue;
        }
        if !inside {
            continue;
        }
        if line.starts_with("$ ") || continued {
            continued = line.trim_end().ends_with('\\');
            continue;
        }
        out += line;
        out.push('\n');
    }
    out
}

fn tokens_match(written: &str, actual: &str, tolerance: f64) -> bool {
    if written == actual {
        return true;
    }
    let strip = |t: &str| -> String {
        t.chars()
            .filter(|c| !(c.is_ascii_digit() || *c == '.' || *c == '-' || *c == '−' || *c == ','))
            .collect()
    };
    match (parse_number(written), parse_number(actual)) {
        (Some(w), Some(a)) => strip(written) == strip(actual) && (w - a).abs() <= tolerance,
        _ => false,
    }
}

/// Compares the command output written in block `name` with `actual`: the written tokens, in
/// segments separated by `...` or `(...)`, must appear in `actual` in order, each segment as
/// a contiguous run of tokens; numbers within `tolerance`, words exactly. A token
/// containing `...` or `…` is an elision (the text before it still matches).
pub fn assert_output(name: &str, actual: &str, tolerance: f64) {
    let b = block(name);
    let written = output_of(&b);
    let actual_tokens: Vec<&str> = actual.split_whitespace().collect();
    let mut segments: Vec<Vec<&str>> = vec![Vec::new()];
    for t in written.split_whitespace() {
        if let Some(at) = t.find("...").or_else(|| t.find('…')) {
            // An elision, possibly glued to text: `word(...)`, `...).`
            let head = t[..at].trim_end_matches('(');
            if !head.is_empty() {
                segments.last_mut().unwrap().push(head);
            }
            segments.push(Vec::new());
        } else {
            segments.last_mut().unwrap().push(t);
        }
    }
    let mut at = 0;
    for segment in segments.iter().filter(|s| !s.is_empty()) {
        let found = (at..=actual_tokens.len().saturating_sub(segment.len())).find(|&start| {
            segment
                .iter()
                .zip(&actual_tokens[start..])
                .all(|(w, a)| tokens_match(w, a, tolerance))
        });
        match found {
            Some(start) => at = start + segment.len(),
            None => panic!(
                "README `{name}` (line {}): this output is not what this build prints \
                 (numbers within {tolerance}):\n  README: {}\n\nThe build printed:\n{actual}",
                b.line,
                segment.join(" ")
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_rewritten_in_their_own_style() {
        assert_eq!(
            rewrite_numbers(
                "| A1 | 1.5 | −3 | 3,376 | `x 9` |",
                0,
                &[2.26, -4.0, 13400.0]
            ),
            "| A1 | 2.3 | −4 | 13,400 | `x 9` |"
        );
        assert_eq!(rewrite_numbers("a -1 b 2", 1, &[-0.04]), "a -1 b 0");
    }

    #[test]
    fn numbers_are_figures_not_names() {
        assert_eq!(
            numbers("A1 at −0.5 and 3,376 points; `x 9` dx21 → 14.5 µm, 57%"),
            vec![-0.5, 3376.0, 14.5, 57.0]
        );
        assert_eq!(parse_number("-83%"), Some(-83.0));
        assert_eq!(parse_number("(29.9"), Some(29.9));
        assert_eq!(parse_number("µm"), None);
    }
}
