//! The byte edits of one rewritten file, stored compactly: a million-target program makes
//! six million small replacements, and a `krl::Edit` each (range plus its own heap buffer,
//! ~70 bytes with the allocation) would cost more memory than the source itself. Here every
//! edit is 24 bytes of range and offset into one shared buffer of replacement text. Applying
//! follows `krl::apply` exactly — sorted by position, insertions at one offset in the order
//! given, overlaps and out-of-range edits rejected — and writes straight into the output.

use std::ops::Range;

use crate::krl::{Edit, EditError};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Piece {
    start: u32,
    end: u32,
    len: u32,
    /// Offset of the replacement text in [`EditList::text`].
    at: usize,
}

/// A length of an [`EditList`] ([`EditList::mark`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mark {
    pieces: usize,
    text: usize,
}

/// Edits of one source in the order they were made.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct EditList {
    pieces: Vec<Piece>,
    text: Vec<u8>,
}

impl EditList {
    pub fn new() -> EditList {
        EditList::default()
    }

    pub fn len(&self) -> usize {
        self.pieces.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pieces.is_empty()
    }

    /// Replaces `range` (empty: inserts) with `bytes`.
    pub fn replace(&mut self, range: Range<usize>, bytes: &[u8]) {
        // Sources are addressed with u32 spans (krl::Span), and so are their edits.
        self.pieces.push(Piece {
            start: range.start as u32,
            end: range.end as u32,
            len: bytes.len() as u32,
            at: self.text.len(),
        });
        self.text.extend_from_slice(bytes);
    }

    pub fn push(&mut self, edit: Edit) {
        self.replace(edit.range, &edit.bytes);
    }

    /// Replaces `range` with the bytes `write` appends to the list's text, written in place
    /// (no buffer of its own); when `write` returns false nothing is added.
    pub fn replace_with(
        &mut self,
        range: Range<usize>,
        write: impl FnOnce(&mut Vec<u8>) -> bool,
    ) -> bool {
        let at = self.text.len();
        if !write(&mut self.text) {
            self.text.truncate(at);
            return false;
        }
        self.pieces.push(Piece {
            start: range.start as u32,
            end: range.end as u32,
            len: (self.text.len() - at) as u32,
            at,
        });
        true
    }

    /// Where the list ends now: to drop or reorder what is added after it.
    pub fn mark(&self) -> Mark {
        Mark {
            pieces: self.pieces.len(),
            text: self.text.len(),
        }
    }

    /// Drops the edits added since `mark`.
    pub fn truncate(&mut self, mark: Mark) {
        self.pieces.truncate(mark.pieces);
        self.text.truncate(mark.text);
    }

    /// Sorts the edits added since `mark` by where they start, keeping the order of those
    /// that start at one place (a stable sort: insertions there stay in the order given).
    pub fn sort_since(&mut self, mark: Mark) {
        self.pieces[mark.pieces..].sort_by_key(|p| p.start);
    }

    /// The edits as `krl::Edit`s, in the order they were made.
    pub fn to_edits(&self) -> Vec<Edit> {
        self.pieces
            .iter()
            .map(|p| Edit {
                range: Self::range(p),
                bytes: self.text[p.at..p.at + p.len as usize].to_vec(),
            })
            .collect()
    }

    /// Room for `edits` more edits with `text` more bytes of replacement text.
    pub fn reserve(&mut self, edits: usize, text: usize) {
        self.pieces.reserve(edits);
        self.text.reserve(text);
    }

    /// Bytes of replacement text.
    pub fn text_len(&self) -> usize {
        self.text.len()
    }

    /// Moves the edits of `other` to the end of this list.
    pub fn append(&mut self, other: &mut EditList) {
        let shift = self.text.len();
        self.pieces.extend(other.pieces.drain(..).map(|p| Piece {
            at: p.at + shift,
            ..p
        }));
        self.text.append(&mut other.text);
    }

    fn range(p: &Piece) -> Range<usize> {
        p.start as usize..p.end as usize
    }

    /// `source` with `first` (an insertion or replacement that goes before any edit of the
    /// list at the same place) and the edits applied (see `krl::apply`).
    pub fn apply(&self, source: &[u8], first: &Edit) -> Result<Vec<u8>, EditError> {
        // Index 0 is `first`, i + 1 the list's i-th edit: a stable sort keeps their order.
        let range = |k: u32| match k {
            0 => first.range.clone(),
            k => Self::range(&self.pieces[k as usize - 1]),
        };
        let bytes = |k: u32| match k {
            0 => &first.bytes[..],
            k => {
                let p = &self.pieces[k as usize - 1];
                &self.text[p.at..p.at + p.len as usize]
            }
        };
        let n = self.pieces.len() as u32 + 1;
        for k in 0..n {
            let r = range(k);
            if r.start > r.end || r.end > source.len() {
                return Err(EditError::OutOfBounds {
                    range: r,
                    len: source.len(),
                });
            }
        }
        let mut order: Vec<u32> = (0..n).collect();
        // Already in order for a CAM program's fast path: the stable sort sees one run.
        order.sort_by_key(|&k| {
            let r = range(k);
            (r.start, r.end)
        });
        for w in order.windows(2) {
            let (a, b) = (range(w[0]), range(w[1]));
            if b.start < a.end {
                return Err(EditError::Overlap {
                    first: a,
                    second: b,
                });
            }
        }
        let removed: usize = order.iter().map(|&k| range(k).len()).sum();
        let added: usize = order.iter().map(|&k| bytes(k).len()).sum();
        let mut out = Vec::with_capacity(source.len() - removed + added);
        let mut at = 0;
        for k in order {
            let r = range(k);
            out.extend_from_slice(&source[at..r.start]);
            out.extend_from_slice(bytes(k));
            at = r.end;
        }
        out.extend_from_slice(&source[at..]);
        Ok(out)
    }
}

impl Extend<Edit> for EditList {
    fn extend<I: IntoIterator<Item = Edit>>(&mut self, iter: I) {
        for e in iter {
            self.push(e);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn edit(start: usize, end: usize, text: &str) -> Edit {
        Edit {
            range: start..end,
            bytes: text.as_bytes().to_vec(),
        }
    }

    proptest! {
        /// Same result as `krl::apply` with `first` in front, errors included: random edits,
        /// appended from two lists.
        #[test]
        fn applies_like_krl_apply(
            src in "[a-z]{0,30}",
            raw in proptest::collection::vec((0usize..34, 0usize..4, "[A-Z]{0,3}"), 0..12),
            first_at in 0usize..34,
            split in 0usize..12,
        ) {
            let edits: Vec<Edit> = raw.iter().map(|(s, l, t)| edit(*s, s + l, t)).collect();
            let first = edit(first_at, first_at, "#");
            let mut a = EditList::new();
            let mut b = EditList::new();
            for (i, e) in edits.iter().enumerate() {
                if i < split { a.push(e.clone()) } else { b.push(e.clone()) }
            }
            a.append(&mut b);
            prop_assert!(b.is_empty());
            prop_assert_eq!(a.len(), edits.len());
            let mut all = vec![first.clone()];
            all.extend(edits);
            let expected = crate::krl::apply(src.as_bytes(), &all);
            prop_assert_eq!(a.apply(src.as_bytes(), &first), expected);
        }
    }

    #[test]
    fn insertions_at_one_offset_keep_their_order_after_first() {
        let mut l = EditList::new();
        l.push(edit(1, 1, "b"));
        l.push(edit(1, 2, "X"));
        l.push(edit(1, 1, "c"));
        assert_eq!(l.apply(b"a_d", &edit(1, 1, "H")).unwrap(), b"aHbcXd");
    }
}
