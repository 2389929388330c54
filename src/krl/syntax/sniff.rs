//! Whether a parsed file is KRL at all. The parser is lossless and recovering, so any bytes
//! parse: a megabyte of noise comes back as thousands of opaque statements. A file is taken
//! for KRL unless it holds binary data (a NUL byte, or more than [`MAX_CONTROL_SHARE`] of
//! control characters, in its first and last [`SAMPLE`] bytes) or it has code of which no
//! statement is recognised (no routine, declaration, assignment, motion or call: text that
//! is not a program, such as a CSV file renamed). Only the ends of a large file are looked at,
//! so the check costs nothing next to the parse.

use super::error::Problem;
use super::span::Span;
use super::stmt::StmtKind;
use super::tree::SourceFile;

/// Bytes looked at from each end of the file.
pub const SAMPLE: usize = 64 << 10;
/// Share of control characters (other than tab, line ends, form feed and the DOS end-of-file
/// mark) above which a file is binary.
pub const MAX_CONTROL_SHARE: f64 = 0.05;

fn is_control(b: u8) -> bool {
    (b < 0x20 && !matches!(b, b'\t' | b'\n' | b'\r' | 0x0c | 0x1a)) || b == 0x7f
}

/// Text saved as UTF-16 (Windows editors' "Unicode"): a byte order mark, or a NUL in every
/// other byte of the first line. Named as such, with the way out, rather than "binary".
fn utf16(src: &[u8]) -> Option<Problem> {
    crate::input::is_utf16(src).then(|| {
        Problem::error(
            Span::new(0, src.len().min(2)),
            "not a KRL file: it is text saved as UTF-16 (\"Unicode\"), which the controller does not read",
            "save it as ANSI (Windows-1252) or UTF-8 text, e.g. in Notepad: Save as, Encoding",
        )
    })
}

/// Why `file` is not KRL, as an error at the first place that shows it; `None` for a KRL
/// file (an empty one or one of comments only included).
pub fn not_krl(file: &SourceFile) -> Option<Problem> {
    let src = file.source();
    let head = ..src.len().min(SAMPLE);
    let tail = src.len().saturating_sub(SAMPLE).max(head.end)..;
    let parts = [(0, &src[head]), (tail.start, &src[tail])];
    if let Some(e) = utf16(src) {
        return Some(e);
    }
    for (at, part) in parts {
        if let Some(i) = memchr::memchr(0, part) {
            let at = at + i;
            return Some(Problem::error(
                Span::new(at, at + 1),
                "not a KRL file: it holds NUL bytes (binary data, not text)",
                "give the program's .src (or .dat) file, as text",
            ));
        }
    }
    let sampled: usize = parts.iter().map(|(_, p)| p.len()).sum();
    let control = parts
        .iter()
        .flat_map(|(_, p)| p.iter())
        .filter(|&&b| is_control(b))
        .count();
    if sampled > 0 && control as f64 > MAX_CONTROL_SHARE * sampled as f64 {
        let first = src.iter().position(|&b| is_control(b)).unwrap_or(0);
        return Some(Problem::error(
            Span::new(first, first + 1),
            format!(
                "not a KRL file: {:.0}% of its bytes are control characters (binary data, not text)",
                100.0 * control as f64 / sampled as f64
            ),
            "give the program's .src (or .dat) file, as text",
        ));
    }
    if !file.streamed_runs().is_empty() {
        return None;
    }
    let mut first_unrecognised = None;
    for s in file.statements() {
        match s.kind {
            StmtKind::Opaque | StmtKind::Invalid => {
                first_unrecognised.get_or_insert(s.head);
            }
            _ => return None,
        }
    }
    first_unrecognised.map(|head| {
        Problem::error(
            head,
            "not a KRL file: no line of it is a KRL statement (no DEF, DEFDAT, declaration, assignment, motion or call)",
            "give the program's .src (or .dat) file",
        )
    })
}
