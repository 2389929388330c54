//! Problems found while parsing (errors that reject a file, warnings that only inform) and the
//! public `ParseError`. The nom parsers stay private; what leaves the module is a span, a
//! message and a one-line hint, rendered through `crate::diagnostic`.

use super::span::Span;
use super::tree::SourceFile;
use crate::diagnostic::Diagnostic;
pub use crate::diagnostic::Severity;
use std::fmt;

/// One problem in a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    pub severity: Severity,
    /// Where (may be empty: a point between two bytes).
    pub span: Span,
    pub message: String,
    /// Short text shown beside the caret.
    pub label: &'static str,
    /// One-line hint.
    pub help: &'static str,
}

impl Problem {
    pub(crate) fn error(span: Span, message: impl Into<String>, help: &'static str) -> Problem {
        Problem {
            severity: Severity::Error,
            span,
            message: message.into(),
            label: "",
            help,
        }
    }

    pub(crate) fn warning(span: Span, message: impl Into<String>, help: &'static str) -> Problem {
        Problem {
            severity: Severity::Warning,
            span,
            message: message.into(),
            label: "",
            help,
        }
    }

    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
}

/// A file with at least one error (a malformed motion, declaration or aggregate).
///
/// It still holds the whole recovered tree (malformed lines kept as `StmtKind::Invalid`), so
/// callers can report what was understood and every problem at once.
#[derive(Clone, Debug)]
pub struct ParseError {
    pub(crate) file: Box<SourceFile>,
}

impl ParseError {
    /// The tree recovered from the malformed lines.
    #[cfg(any(test, feature = "internals"))]
    pub fn recovered(&self) -> &SourceFile {
        &self.file
    }

    /// The errors (warnings left out), in source order.
    pub fn errors(&self) -> impl Iterator<Item = &Problem> {
        self.file.problems().iter().filter(|p| p.is_error())
    }

    /// Every error as a located diagnostic for file `name`.
    pub fn diagnostics(&self, name: &str) -> Vec<Diagnostic> {
        self.errors()
            .map(|p| self.file.diagnostic(p, name))
            .collect()
    }

    /// Every error rendered: `error: …`, `--> name:line:col`, the line, a caret, the help.
    #[cfg(any(test, feature = "internals"))]
    pub fn render(&self, name: &str) -> String {
        self.diagnostics(name)
            .iter()
            .map(Diagnostic::render)
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// The recovered tree.
    pub fn partial(&self) -> &SourceFile {
        &self.file
    }
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut errors = self.errors();
        if let Some(first) = errors.next() {
            let (line, col) = self.file.line_col(first.span.start as usize);
            write!(f, "{line}:{col}: {}", first.message)?;
            let more = errors.count();
            if more > 0 {
                write!(f, " (and {more} more)")?;
            }
        }
        Ok(())
    }
}

impl std::error::Error for ParseError {}
