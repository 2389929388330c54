//! What can go wrong with a calibration file, as values whose messages name the file and
//! either the line and column (JSON syntax and types) or the JSON path with the expected and
//! the found value (everything checked after parsing).

use std::path::PathBuf;

/// Why a calibration file was refused; every variant names the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalError {
    /// The file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The calibration file.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// Not JSON, or JSON that does not fit the format's types; `excerpt` is the offending
    /// source line with a caret under the column.
    #[error("{}:{line}:{column}: {message}\n{excerpt}", path.display())]
    Syntax {
        /// The calibration file.
        path: PathBuf,
        /// 1-based line of the offending character.
        line: usize,
        /// 1-based column of the offending character.
        column: usize,
        /// What the JSON reader expected there.
        message: String,
        /// The source line with a caret under the column.
        excerpt: String,
    },
    /// Well-formed JSON with a bad value at `key` (a JSON path such as `effects[2].table`).
    #[error("{}: {key}: expected {expected}, found {found}", path.display())]
    Invalid {
        /// The calibration file.
        path: PathBuf,
        /// JSON path of the value, e.g. `robot.limits_deg[2]`.
        key: String,
        /// What the format allows there.
        expected: String,
        /// What the file holds there.
        found: String,
    },
    /// An effect record (at JSON path `at`, e.g. `effects[2]`) whose values do not describe
    /// a valid effect; `source` says which value and why.
    #[error("{}: {at}.{source}", path.display())]
    Effect {
        /// The calibration file.
        path: PathBuf,
        /// JSON path of the effect record, e.g. `effects[2]`.
        at: String,
        /// Which value of the record is wrong, and why.
        source: crate::model::RecordError,
    },
}

impl CalError {
    pub(crate) fn invalid(
        path: &std::path::Path,
        key: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> CalError {
        CalError::Invalid {
            path: path.to_path_buf(),
            key: key.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }

    /// A serde_json error at its line and column of `text`.
    pub(crate) fn syntax(path: &std::path::Path, text: &str, e: &serde_json::Error) -> CalError {
        let (line, column) = (e.line(), e.column());
        let source_line = text.lines().nth(line.saturating_sub(1)).unwrap_or("");
        // A long line (a calibration written on one line) is shown clipped around the column.
        const AROUND: usize = 120;
        let chars: Vec<char> = source_line.chars().collect();
        let at = column.saturating_sub(1).min(chars.len());
        let from = at.saturating_sub(AROUND);
        let to = (at + AROUND).min(chars.len());
        let head = if from > 0 { "..." } else { "" };
        let tail = if to < chars.len() { "..." } else { "" };
        let shown: String = chars[from..to].iter().collect();
        let excerpt = format!(
            "{line:>4} | {head}{shown}{tail}\n     | {}^",
            " ".repeat(head.len() + at - from)
        );
        // serde_json appends " at line L column C"; the location is already in front.
        let message = e.to_string();
        let message = message
            .split(" at line ")
            .next()
            .unwrap_or(&message)
            .to_string();
        // JSON has no NaN/Infinity; the only way to write a non-finite number is overflow.
        let message = if message == "number out of range" {
            "expected a finite number, found one outside the f64 range".to_string()
        } else {
            message
        };
        CalError::Syntax {
            path: path.to_path_buf(),
            line,
            column,
            message,
            excerpt,
        }
    }
}
