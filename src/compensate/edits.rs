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
        self.apply_in(source, 0..source.len(), Some(first))
    }

    /// The bytes `within` of `source` with the edits inside them applied (and `first`, as in
    /// [`EditList::apply`], when it is inside them); edits elsewhere are left out, an edit
    /// across the bounds is an error.
    pub fn apply_in(
        &self,
        source: &[u8],
        within: Range<usize>,
        first: Option<&Edit>,
    ) -> Result<Vec<u8>, EditError> {
        // Index 0 is `first`, i + 1 the list's i-th edit: a stable sort keeps their order.
        let range = |k: u32| match k {
            0 => first.map_or(0..0, |f| f.range.clone()),
            k => Self::range(&self.pieces[k as usize - 1]),
        };
        let bytes = |k: u32| match k {
            0 => first.map_or(&[][..], |f| &f.bytes[..]),
            k => {
                let p = &self.pieces[k as usize - 1];
                &self.text[p.at..p.at + p.len as usize]
            }
        };
        let n = self.pieces.len() as u32 + 1;
        let whole = within.start == 0 && within.end == source.len();
        let mut order: Vec<u32> = Vec::with_capacity(n as usize);
        for k in 0..n {
            let r = range(k);
            if r.start > r.end || r.end > source.len() {
                return Err(EditError::OutOfBounds {
                    range: r,
                    len: source.len(),
                });
            }
            if k == 0 && first.is_none() {
                continue;
            }
            // An insertion at the end of `within` belongs to the bytes after it.
            let inside = within.start <= r.start
                && r.end <= within.end
                && !(r.is_empty() && r.start == within.end && within.end < source.len());
            let straddles = (r.start < within.start && r.end > within.start)
                || (r.start < within.end && r.end > within.end);
            if whole || inside {
                order.push(k);
            } else if straddles {
                return Err(EditError::OutOfBounds {
                    range: r,
                    len: within.end,
                });
            }
        }
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
        let mut out = Vec::with_capacity(within.len() - removed + added);
        let mut at = within.start;
        for k in order {
            let r = range(k);
            out.extend_from_slice(&source[at..r.start]);
            out.extend_from_slice(bytes(k));
            at = r.end;
        }
        out.extend_from_slice(&source[at..within.end]);
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

    proptest! {
        /// A source cut into stretches, each applied on its own (`apply_in`), gives the
        /// whole-source result: every edit lands in exactly one stretch (an insertion at a cut
        /// in the stretch after it).
        #[test]
        fn stretches_put_together_are_the_whole(
            src in "[a-z]{1,30}",
            raw in proptest::collection::vec((0usize..30, 0usize..3, "[A-Z]{0,3}"), 0..10),
            cuts in proptest::collection::vec(0usize..30, 0..4),
        ) {
            let n = src.len();
            let mut list = EditList::new();
            for (s, l, t) in &raw {
                let (s, e) = ((*s).min(n), (s + l).min(n));
                list.push(edit(s, e, t));
            }
            let first = edit(0, 0, "#");
            let Ok(whole) = list.apply(src.as_bytes(), &first) else { return Ok(()) };
            let mut at: Vec<usize> = cuts.iter().map(|c| c % n).collect();
            at.extend([0, n]);
            at.sort_unstable();
            at.dedup();
            let mut pieces = Vec::new();
            for w in at.windows(2) {
                match list.apply_in(src.as_bytes(), w[0]..w[1], Some(&first)) {
                    Ok(p) => pieces.extend(p),
                    // An edit across a cut: the caller never cuts there.
                    Err(_) => return Ok(()),
                }
            }
            prop_assert_eq!(pieces, whole);
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
