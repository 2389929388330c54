//! Byte spans into the original source and the line index that turns a byte offset into a
//! 1-based line and column. Every node of the syntax tree refers to its text by a `Span`; the
//! text itself stays in the `SourceFile`, never copied, never decoded.

use std::fmt;
use std::ops::Range;

/// A half-open byte range `start..end` into the source of one file.
///
/// Offsets are `u32` to keep the tree small: a file is limited to 4 GiB (`parse` rejects larger).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default, PartialOrd, Ord)]
pub struct Span {
    pub start: u32,
    pub end: u32,
}

impl Span {
    /// A span from byte offsets (callers guarantee `start <= end <= u32::MAX`).
    pub fn new(start: usize, end: usize) -> Span {
        debug_assert!(start <= end);
        Span {
            start: start as u32,
            end: end as u32,
        }
    }

    /// The empty span at `offset` (an insertion point).
    pub fn at(offset: usize) -> Span {
        Span::new(offset, offset)
    }

    pub fn range(self) -> Range<usize> {
        self.start as usize..self.end as usize
    }

    pub fn len(self) -> usize {
        (self.end - self.start) as usize
    }

    pub fn is_empty(self) -> bool {
        self.start == self.end
    }

    /// The smallest span covering both.
    pub fn to(self, other: Span) -> Span {
        Span {
            start: self.start.min(other.start),
            end: self.end.max(other.end),
        }
    }

    /// Whether `other` lies inside this span.
    pub fn contains(self, other: Span) -> bool {
        self.start <= other.start && other.end <= self.end
    }
}

impl fmt::Debug for Span {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..{}", self.start, self.end)
    }
}

/// Start offsets of every line, for offset → (line, column) lookups.
///
/// Lines end at `\n` only (a `\r` before it belongs to the line ending; a lone `\r` is an
/// ordinary byte), which is how the KUKA editor counts them.
#[derive(Clone, Debug, Default)]
pub struct LineIndex {
    starts: Vec<u32>,
    len: u32,
    /// Lines before `starts[0]` (a window of a file starts at a later line).
    before: u32,
}

impl LineIndex {
    #[cfg(any(test, feature = "internals"))]
    pub fn new(src: &[u8]) -> LineIndex {
        let mut starts = Vec::with_capacity(src.len() / 40 + 1);
        starts.push(0);
        for (i, &b) in src.iter().enumerate() {
            if b == b'\n' {
                starts.push(i as u32 + 1);
            }
        }
        LineIndex {
            starts,
            len: src.len() as u32,
            before: 0,
        }
    }

    /// Builds the index from line starts already found by the line scanner.
    /// `first_line`: the 1-based number of the line starting at `starts[0]`.
    pub(crate) fn from_starts(mut starts: Vec<u32>, len: usize, first_line: u32) -> LineIndex {
        starts.shrink_to_fit();
        LineIndex {
            starts,
            len: len as u32,
            before: first_line.saturating_sub(1),
        }
    }

    /// The bytes indexed: from the first line's start to the end.
    pub fn extent(&self) -> Span {
        Span::new(
            self.starts.first().copied().unwrap_or(0) as usize,
            self.len as usize,
        )
    }

    /// Number of lines (a final line without a newline counts; an empty file has one line).
    #[cfg(any(test, feature = "internals"))]
    pub fn line_count(&self) -> usize {
        self.starts.len() + self.before as usize
    }

    /// 1-based line and 1-based byte column of a byte offset (clamped to the file).
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset =
            (offset.min(self.len as usize) as u32).max(self.starts.first().copied().unwrap_or(0));
        let line = match self.starts.binary_search(&offset) {
            Ok(i) => i,
            Err(i) => i - 1,
        };
        (
            line + 1 + self.before as usize,
            (offset - self.starts[line]) as usize + 1,
        )
    }

    /// The 1-based line of a byte offset.
    #[cfg(any(test, feature = "internals"))]
    pub fn line_of(&self, offset: usize) -> usize {
        self.line_col(offset).0
    }

    /// Span of a 1-based line without its line ending (`\n` or `\r\n`).
    pub fn line_span(&self, src: &[u8], line: usize) -> Span {
        let i = line
            .saturating_sub(self.before as usize)
            .clamp(1, self.starts.len())
            - 1;
        let start = self.starts[i] as usize;
        let mut end = match self.starts.get(i + 1) {
            Some(&next) => next as usize - 1,
            None => self.len as usize,
        };
        if end > start && src.get(end - 1) == Some(&b'\r') && src.get(end) == Some(&b'\n') {
            end -= 1;
        }
        Span::new(start, end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_lf_only() {
        let src = b"ab\r\ncd\n\nx\ry";
        let ix = LineIndex::new(src);
        assert_eq!(ix.line_count(), 4);
        assert_eq!(ix.line_col(0), (1, 1));
        assert_eq!(ix.line_col(2), (1, 3)); // the \r
        assert_eq!(ix.line_col(4), (2, 1));
        assert_eq!(ix.line_col(7), (3, 1));
        assert_eq!(ix.line_col(10), (4, 3)); // lone \r is inside line 4
        assert_eq!(ix.line_col(999), (4, 4));
        assert_eq!(&src[ix.line_span(src, 1).range()], b"ab");
        assert_eq!(&src[ix.line_span(src, 3).range()], b"");
        assert_eq!(&src[ix.line_span(src, 4).range()], b"x\ry");
    }
}
