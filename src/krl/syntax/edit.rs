//! Byte edits applied to an untouched source: each edit replaces a byte range (an empty range
//! inserts). This is how a compensated program is written — only the numbers that change are
//! touched, every other byte (comments, code page, line endings, spacing) is copied through.

#[cfg(any(test, feature = "internals"))]
use super::span::Span;
use std::ops::Range;

/// Replace bytes `range` of the source with `bytes`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Edit {
    pub range: Range<usize>,
    pub bytes: Vec<u8>,
}

/// A set of edits to one source, in any order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[cfg(any(test, feature = "internals"))]
pub struct Edits {
    edits: Vec<Edit>,
}

/// Why a set of edits cannot be applied.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EditError {
    #[error("edit {range:?} is outside the source ({len} bytes)")]
    OutOfBounds { range: Range<usize>, len: usize },
    #[error("edits {first:?} and {second:?} overlap")]
    Overlap {
        first: Range<usize>,
        second: Range<usize>,
    },
}

#[cfg(any(test, feature = "internals"))]
impl Edits {
    pub fn new() -> Edits {
        Edits::default()
    }

    /// Replaces the bytes of `span`.
    pub fn replace(&mut self, span: Span, bytes: impl Into<Vec<u8>>) {
        self.edits.push(Edit {
            range: span.range(),
            bytes: bytes.into(),
        });
    }

    /// Inserts `bytes` before byte `offset`.
    pub fn insert(&mut self, offset: usize, bytes: impl Into<Vec<u8>>) {
        self.edits.push(Edit {
            range: offset..offset,
            bytes: bytes.into(),
        });
    }

    pub fn push(&mut self, edit: Edit) {
        self.edits.push(edit);
    }

    pub fn len(&self) -> usize {
        self.edits.len()
    }

    pub fn is_empty(&self) -> bool {
        self.edits.is_empty()
    }

    pub fn as_slice(&self) -> &[Edit] {
        &self.edits
    }

    /// Applies the edits to `source` (see [`apply`]).
    pub fn apply(&self, source: &[u8]) -> Result<Vec<u8>, EditError> {
        apply(source, &self.edits)
    }
}

#[cfg(any(test, feature = "internals"))]
impl AsRef<[Edit]> for Edits {
    fn as_ref(&self) -> &[Edit] {
        &self.edits
    }
}

/// Applies `edits` to `source`: sorted by position (insertions at the same offset keep their
/// order and go before a replacement starting there); overlapping edits, or an insertion
/// strictly inside a replaced range, are rejected.
pub fn apply(source: &[u8], edits: impl AsRef<[Edit]>) -> Result<Vec<u8>, EditError> {
    let mut order: Vec<&Edit> = edits.as_ref().iter().collect();
    for e in &order {
        if e.range.start > e.range.end || e.range.end > source.len() {
            return Err(EditError::OutOfBounds {
                range: e.range.clone(),
                len: source.len(),
            });
        }
    }
    order.sort_by_key(|e| (e.range.start, e.range.end));
    for w in order.windows(2) {
        let (a, b) = (&w[0].range, &w[1].range);
        if b.start < a.end {
            return Err(EditError::Overlap {
                first: a.clone(),
                second: b.clone(),
            });
        }
    }
    let grow: usize = order.iter().map(|e| e.bytes.len()).sum();
    let mut out = Vec::with_capacity(source.len() + grow);
    let mut at = 0;
    for e in order {
        out.extend_from_slice(&source[at..e.range.start]);
        out.extend_from_slice(&e.bytes);
        at = e.range.end;
    }
    out.extend_from_slice(&source[at..]);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replace_and_insert() {
        let src = b"LIN {X 1.0,Y 2.0}";
        let mut e = Edits::new();
        e.replace(Span::new(13, 16), "2.5");
        e.insert(16, ",Z 0.0");
        e.replace(Span::new(7, 10), "1.25");
        assert_eq!(e.apply(src).unwrap(), b"LIN {X 1.25,Y 2.5,Z 0.0}");
        assert_eq!(apply(src, &e).unwrap(), b"LIN {X 1.25,Y 2.5,Z 0.0}");
        assert_eq!(
            apply(src, e.as_slice()).unwrap(),
            b"LIN {X 1.25,Y 2.5,Z 0.0}"
        );
    }

    #[test]
    fn insertions_at_one_offset_keep_their_order() {
        let mut e = Edits::new();
        e.insert(1, "b");
        e.replace(Span::new(1, 2), "X");
        e.insert(1, "c");
        assert_eq!(e.apply(b"a_d").unwrap(), b"abcXd");
    }

    #[test]
    fn overlaps_and_bounds_are_rejected() {
        let mut e = Edits::new();
        e.replace(Span::new(0, 3), "x");
        e.replace(Span::new(2, 4), "y");
        assert!(matches!(e.apply(b"abcdef"), Err(EditError::Overlap { .. })));
        let mut e = Edits::new();
        e.replace(Span::new(0, 3), "x");
        e.insert(1, "y");
        assert!(matches!(e.apply(b"abcdef"), Err(EditError::Overlap { .. })));
        let mut e = Edits::new();
        e.insert(7, "y");
        assert!(matches!(
            e.apply(b"abc"),
            Err(EditError::OutOfBounds { .. })
        ));
        // Touching ranges are fine.
        let mut e = Edits::new();
        e.replace(Span::new(0, 2), "x");
        e.replace(Span::new(2, 4), "y");
        assert_eq!(e.apply(b"abcd").unwrap(), b"xy");
    }
}
