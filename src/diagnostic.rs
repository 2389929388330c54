//! User-facing error messages for every input robopost reads: `file:line:col`, the offending
//! source line, a caret under the problem, a short label and a one-line help, rendered with
//! annotate-snippets. Any module that rejects input (programs, measurement files, calibration
//! files) can build a `Diagnostic` from its bytes and a byte range, without caring how the
//! file is encoded: the line is shown as UTF-8 when it is UTF-8 and byte-per-character
//! (Latin-1, close to the Windows code pages controllers write) otherwise.

use annotate_snippets::{Level, Renderer, Snippet};
use std::fmt;
use std::ops::Range;

/// The most characters underlined under a source line: the line shown is clipped around the
/// underline, so this bounds what one diagnostic prints whatever the line's length.
pub const MAX_UNDERLINE: usize = 80;

/// How serious a diagnostic is: errors reject the input, warnings only inform.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Severity {
    /// The input is rejected (exit status 1 for a program, 2 for a file that cannot be read).
    Error,
    /// Worth knowing; the job goes on.
    Warning,
}

impl fmt::Display for Severity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Severity::Error => "error",
            Severity::Warning => "warning",
        })
    }
}

/// One located message about an input file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// File name as the user gave it.
    pub file: String,
    /// 1-based line; 0 when the message is about the whole file.
    pub line: usize,
    /// 1-based column in characters of the shown line.
    pub col: usize,
    /// The first line: what is wrong.
    pub message: String,
    /// The offending line as shown (empty when there is none).
    pub source_line: String,
    /// Characters underlined (at least one caret is drawn).
    pub width: usize,
    /// Short text beside the caret.
    pub label: Option<String>,
    /// One-line hint on how to fix it.
    pub help: Option<String>,
}

impl Diagnostic {
    /// A message about a whole file (no line to show).
    pub fn new(severity: Severity, file: &str, message: impl Into<String>) -> Diagnostic {
        Diagnostic {
            severity,
            file: file.to_string(),
            line: 0,
            col: 0,
            message: message.into(),
            source_line: String::new(),
            width: 0,
            label: None,
            help: None,
        }
    }

    /// A message about bytes `range` of `src` (a range spanning lines is cut at the first
    /// line's end; an empty range points between two bytes).
    pub fn at_bytes(
        severity: Severity,
        file: &str,
        src: &[u8],
        range: Range<usize>,
        message: impl Into<String>,
    ) -> Diagnostic {
        let start = range.start.min(src.len());
        let line_start = src[..start]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |p| p + 1);
        let line = src[..line_start].iter().filter(|&&b| b == b'\n').count() + 1;
        Diagnostic::at_line(severity, file, src, (line, line_start), range, message)
    }

    /// [`Diagnostic::at_bytes`] where the caller knows the 1-based line of `range.start` and
    /// where that line starts (from a line index: counting the lines before is linear in the
    /// file, and a file with many problems would take quadratic time).
    pub fn at_line(
        severity: Severity,
        file: &str,
        src: &[u8],
        (line, line_start): (usize, usize),
        range: Range<usize>,
        message: impl Into<String>,
    ) -> Diagnostic {
        let start = range.start.min(src.len());
        let line_start = line_start.min(start);
        let mut line_end = src[start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(src.len(), |p| start + p);
        if line_end > line_start && src[line_end - 1] == b'\r' {
            line_end -= 1;
        }
        let text = &src[line_start..line_end];
        let start_in_line = (start - line_start).min(text.len());
        let end_in_line = range
            .end
            .clamp(start, line_end.max(start))
            .saturating_sub(line_start)
            .min(text.len());
        let col = display_text(&text[..start_in_line]).chars().count() + 1;
        let width = display_text(&text[start_in_line..end_in_line])
            .chars()
            .count();
        Diagnostic {
            severity,
            file: file.to_string(),
            line,
            col,
            message: message.into(),
            source_line: display_text(text),
            width,
            label: None,
            help: None,
        }
    }

    /// The same diagnostic with a label under the marked span (an empty one leaves none).
    pub fn with_label(mut self, label: impl Into<String>) -> Diagnostic {
        let label = label.into();
        self.label = (!label.is_empty()).then_some(label);
        self
    }

    /// The same diagnostic with a `help:` line (an empty one leaves none).
    pub fn with_help(mut self, help: impl Into<String>) -> Diagnostic {
        let help = help.into();
        self.help = (!help.is_empty()).then_some(help);
        self
    }

    /// The full message: title, `--> file:line:col`, the source line with a caret, the help.
    pub fn render(&self) -> String {
        let level = match self.severity {
            Severity::Error => Level::Error,
            Severity::Warning => Level::Warning,
        };
        let title;
        let mut message = if self.line == 0 {
            title = format!("{}: {}", self.file, self.message);
            level.title(&title)
        } else {
            level.title(&self.message)
        };
        // A tab is shown as one blank: annotate-snippets would misplace the caret after a tab,
        // and one column per character keeps `--> file:line:col` equal to `self.col`.
        // A span inside the line's leading blanks (a located error at column 1 of an indented
        // line) makes annotate-snippets 0.11 underflow on long lines: there the blanks are
        // shown as `·`. Other control characters are shown as U+FFFD (sources the caller did
        // not pass through `display_text`).
        let c0 = self.col.saturating_sub(1);
        let leading = self
            .source_line
            .chars()
            .take_while(|c| c.is_whitespace())
            .count();
        let dots = self.line > 0 && c0 < leading;
        let mut shown = String::with_capacity(self.source_line.len());
        let mut byte_at = Vec::with_capacity(self.source_line.len() + 1);
        for (k, c) in self.source_line.chars().enumerate() {
            byte_at.push(shown.len());
            if dots && k < leading {
                shown.push('·');
            } else if c == '\t' || (c.is_whitespace() && c.is_control()) {
                shown.push(' ');
            } else if c.is_control() {
                shown.push('\u{FFFD}');
            } else {
                shown.push(c);
            }
        }
        byte_at.push(shown.len());
        if self.line > 0 {
            let at = |c: usize| byte_at[c.min(byte_at.len() - 1)];
            let start = at(c0);
            // A long span (a statement on a 10 MB line) is underlined for its first
            // characters only: annotate-snippets clips the line around the annotation, and
            // would otherwise print all of it.
            let end = at(c0 + self.width.clamp(1, MAX_UNDERLINE)).max(start);
            let mut annotation = level.span(start..end);
            if let Some(label) = &self.label {
                annotation = annotation.label(label);
            }
            message = message.snippet(
                Snippet::source(&shown)
                    .line_start(self.line)
                    .origin(&self.file)
                    .annotation(annotation),
            );
        }
        if let Some(help) = &self.help {
            message = message.footer(Level::Help.title(help));
        }
        let mut out = Renderer::plain().render(message).to_string();
        out.push('\n');
        out
    }
}

impl fmt::Display for Diagnostic {
    /// One line: `file:line:col: error: message`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}: {}", self.file, self.severity, self.message)
        } else {
            write!(
                f,
                "{}:{}:{}: {}: {}",
                self.file, self.line, self.col, self.severity, self.message
            )
        }
    }
}

/// `text` as a message quotes it: at most `max` characters, the cut marked with `...` (a
/// 50 MB field is not echoed whole; cli.md promises messages of a few hundred bytes).
pub fn clip(text: &str, max: usize) -> String {
    if text.chars().count() <= max {
        return text.to_string();
    }
    let head: String = text.chars().take(max.saturating_sub(3)).collect();
    format!("{head}... ({} bytes)", text.len())
}

/// Bytes as shown to the user: UTF-8 when valid, else one character per byte (Latin-1);
/// control characters other than tab become `�` so the terminal is never disturbed and every
/// byte still takes one column.
pub fn display_text(bytes: &[u8]) -> String {
    let clean = |c: char| {
        if c.is_control() && c != '\t' {
            '\u{FFFD}'
        } else {
            c
        }
    };
    match std::str::from_utf8(bytes) {
        Ok(s) => s.chars().map(clean).collect(),
        Err(_) => bytes.iter().map(|&b| clean(char::from(b))).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Found by fuzzing the CSV reader: a long line whose located column lies in its leading
    /// blanks (here vertical tabs, a control character) panicked inside annotate-snippets.
    #[test]
    fn a_span_in_a_long_lines_leading_blanks_renders() {
        let mut line = "\u{b}".repeat(27);
        line += &"\u{ff}".repeat(46);
        line += "\u{b}\u{b}1";
        let d = Diagnostic {
            line: 1,
            col: 1,
            source_line: line,
            ..Diagnostic::new(Severity::Error, "m.csv", "bad")
        };
        let out = d.render();
        assert!(out.contains("m.csv:1:1") && out.contains("·"), "{out}");
        let d = Diagnostic {
            line: 3,
            col: 2,
            source_line: format!("{}{}", " ".repeat(40), "x".repeat(300)),
            ..Diagnostic::new(Severity::Error, "a.src", "bad")
        };
        assert!(d.render().contains("a.src:3:2"));
    }

    #[test]
    fn located_message_shows_line_and_caret() {
        let src = b"DEF a()\r\n  LIN {X 1,\r\nEND";
        let d = Diagnostic::at_bytes(Severity::Error, "a.src", src, 20..20, "unclosed aggregate")
            .with_label("expected `}`")
            .with_help("close the aggregate with }");
        assert_eq!((d.line, d.col, d.width), (2, 12, 0));
        assert_eq!(d.source_line, "  LIN {X 1,");
        assert_eq!(d.to_string(), "a.src:2:12: error: unclosed aggregate");
        let r = d.render();
        assert!(r.contains("--> a.src:2:12"), "{r}");
        assert!(r.contains("2 |   LIN {X 1,"), "{r}");
        assert!(r.contains("help: close the aggregate with }"), "{r}");
    }

    /// A diagnostic on a 10 MB line prints a few hundred bytes, with the true column.
    #[test]
    fn a_long_line_is_clipped_around_the_caret() {
        let mut src = b"DEF a()\nPTP {A1 0".to_vec();
        src.extend(vec![b' '; 10_000_000]);
        src.extend(
            b"}\nLIN {X 1, Y 2, Q 7"
                .iter()
                .chain(&vec![b' '; 5_000_000]),
        );
        src.extend(b"BAD}\nEND\n");
        let whole = Diagnostic::at_bytes(Severity::Warning, "a.src", &src, 8..10_000_018, "w");
        let r = whole.render();
        assert!(r.len() < 1000, "{} bytes", r.len());
        assert!(r.contains("--> a.src:2:1"), "{r}");
        let at = src.windows(3).position(|w| w == b"BAD").unwrap();
        let late = Diagnostic::at_bytes(Severity::Error, "a.src", &src, at..at + 3, "e");
        let r = late.render();
        assert!(r.len() < 1000, "{} bytes", r.len());
        assert!(r.contains("--> a.src:3:5000019"), "{r}");
        assert!(r.contains("BAD}"), "{r}");
    }

    #[test]
    fn windows_1252_bytes_keep_one_column_each() {
        let src = b"; Stra\xdfe\nLIN x y";
        let d = Diagnostic::at_bytes(Severity::Error, "f", src, 0..3, "m");
        assert_eq!(d.source_line, "; Stra\u{df}e");
        assert_eq!(d.width, 3);
        let d = Diagnostic::at_bytes(Severity::Error, "f", b"\xe4\xe4 X", 3..4, "m");
        assert_eq!(d.col, 4);
    }
}
