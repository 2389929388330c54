//! The byte edits of one rewritten file, stored compactly: a million-target program makes
//! a million small replacements or more (one per target whose numbers are replaced in place,
//! `rewrite`'s joined edits; else one per number), and a `krl::Edit` each (range plus its own
//! heap buffer, ~70 bytes with the allocation) would cost more memory than the source itself.
//! Here every edit is 24 bytes of range and offset into a shared buffer of replacement text,
//! in segments: lists built in parallel are joined by moving their segments, not by copying
//! hundreds of megabytes. Applying follows `krl::apply` exactly — sorted by position,
//! insertions at one offset in the order given, overlaps and out-of-range edits rejected — and
//! writes straight into the output; edits already in order (a CAM program's) are streamed
//! without sorting.

use std::ops::Range;

use crate::krl::{Edit, EditError};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Piece {
    start: u32,
    end: u32,
    len: u32,
    /// Offset of the replacement text in its segment's `text`.
    at: usize,
}

impl Piece {
    fn range(&self) -> Range<usize> {
        self.start as usize..self.end as usize
    }

    fn key(&self) -> (u32, u32) {
        (self.start, self.end)
    }
}

/// A run of edits with their text.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Segment {
    pieces: Vec<Piece>,
    text: Vec<u8>,
}

impl Segment {
    fn bytes(&self, p: &Piece) -> &[u8] {
        &self.text[p.at..p.at + p.len as usize]
    }

    fn range(&self, p: &Piece) -> Range<usize> {
        p.at..p.at + p.len as usize
    }
}

/// The size of [`append_range`]'s fixed block.
pub(crate) const BLOCK: usize = 16;

/// Appends `src[range]` to `out`. Nearly every piece of a rewritten program is a few bytes
/// (a number, the text between two numbers): where `src` has the bytes after it, such a
/// piece is copied as one fixed block and cut back, a move or two instead of a library
/// `memcpy` call — twelve million calls for a million-target program.
/// `out` should have `BLOCK` bytes of capacity to spare at its end, or the last block grows it.
#[inline]
pub(crate) fn append_range(out: &mut Vec<u8>, src: &[u8], range: Range<usize>) {
    let n = range.len();
    if n <= BLOCK {
        if let Some(block) = src.get(range.start..range.start + BLOCK) {
            let block: &[u8; BLOCK] = block.try_into().expect("a block's bytes");
            let len = out.len();
            out.extend_from_slice(block);
            out.truncate(len + n);
            return;
        }
    }
    out.extend_from_slice(&src[range]);
}

/// A stretch of the merged, ordered edits of [`EditList::apply`]: pieces of one segment, or
/// the edit that goes first.
#[derive(Clone, Copy, Debug)]
enum Run {
    Pieces { seg: usize, from: usize, to: usize },
    First,
}

/// A length of an [`EditList`] ([`EditList::mark`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mark {
    segment: usize,
    pieces: usize,
    text: usize,
}

/// Edits of one source in the order they were made.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct EditList {
    /// Never empty once an edit was made; new edits go to the last.
    segments: Vec<Segment>,
}

impl EditList {
    pub fn new() -> EditList {
        EditList::default()
    }

    /// A list with room for `pieces` edits of `text` bytes in all (a list grown edit by edit
    /// copies itself a dozen times on its way to a window's few thousand).
    pub fn with_capacity(pieces: usize, text: usize) -> EditList {
        EditList {
            segments: vec![Segment {
                pieces: Vec::with_capacity(pieces),
                text: Vec::with_capacity(text),
            }],
        }
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn len(&self) -> usize {
        self.segments.iter().map(|s| s.pieces.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.segments.iter().all(|s| s.pieces.is_empty())
    }

    fn last(&mut self) -> &mut Segment {
        if self.segments.is_empty() {
            self.segments.push(Segment::default());
        }
        self.segments.last_mut().expect("just made sure")
    }

    /// Replaces `range` (empty: inserts) with `bytes`.
    pub fn replace(&mut self, range: Range<usize>, bytes: &[u8]) {
        let seg = self.last();
        // Sources are addressed with u32 spans (krl::Span), and so are their edits.
        seg.pieces.push(Piece {
            start: range.start as u32,
            end: range.end as u32,
            len: bytes.len() as u32,
            at: seg.text.len(),
        });
        seg.text.extend_from_slice(bytes);
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
        let seg = self.last();
        let at = seg.text.len();
        if !write(&mut seg.text) {
            seg.text.truncate(at);
            return false;
        }
        seg.pieces.push(Piece {
            start: range.start as u32,
            end: range.end as u32,
            len: (seg.text.len() - at) as u32,
            at,
        });
        true
    }

    /// One edit whose bytes `write` appends to the list's text and whose range it returns,
    /// known only once written (`None`: nothing added).
    pub fn replace_written(&mut self, write: impl FnOnce(&mut Vec<u8>) -> Option<Range<usize>>) {
        let seg = self.last();
        let at = seg.text.len();
        match write(&mut seg.text) {
            Some(range) => seg.pieces.push(Piece {
                start: range.start as u32,
                end: range.end as u32,
                len: (seg.text.len() - at) as u32,
                at,
            }),
            None => seg.text.truncate(at),
        }
    }

    /// Where the list ends now: to drop or reorder what is added after it.
    pub fn mark(&mut self) -> Mark {
        let segment = self.segments.len().max(1) - 1;
        let seg = self.last();
        Mark {
            segment,
            pieces: seg.pieces.len(),
            text: seg.text.len(),
        }
    }

    /// Drops the edits added since `mark` (with no [`Self::append`] in between).
    pub fn truncate(&mut self, mark: Mark) {
        let seg = &mut self.segments[mark.segment];
        seg.pieces.truncate(mark.pieces);
        seg.text.truncate(mark.text);
    }

    /// Sorts the edits added since `mark` (with no [`Self::append`] in between) by where they
    /// start, keeping the order of those that start at one place (a stable sort: insertions
    /// there stay in the order given).
    pub fn sort_since(&mut self, mark: Mark) {
        self.segments[mark.segment].pieces[mark.pieces..].sort_by_key(|p| p.start);
    }

    /// The edits as `krl::Edit`s, in the order they were made.
    pub fn to_edits(&self) -> Vec<Edit> {
        self.segments
            .iter()
            .flat_map(|s| {
                s.pieces.iter().map(|p| Edit {
                    range: p.range(),
                    bytes: s.bytes(p).to_vec(),
                })
            })
            .collect()
    }

    /// Moves the edits of `other` to the end of this list (its segments, not copied).
    pub fn append(&mut self, other: &mut EditList) {
        self.segments
            .retain(|s| !s.pieces.is_empty() || !s.text.is_empty());
        self.segments
            .extend(other.segments.drain(..).filter(|s| !s.pieces.is_empty()));
    }

    fn pieces(&self) -> impl Iterator<Item = (&Segment, &Piece)> + '_ {
        self.segments
            .iter()
            .flat_map(|s| s.pieces.iter().map(move |p| (s, p)))
    }

    /// `source` with `first` (an insertion or replacement that goes before any edit of the
    /// list at the same place) and the edits applied (see `krl::apply`).
    pub fn apply(&self, source: &[u8], first: &Edit) -> Result<Vec<u8>, EditError> {
        let out_of_bounds = |r: Range<usize>| {
            (r.start > r.end || r.end > source.len()).then_some(EditError::OutOfBounds {
                range: r,
                len: source.len(),
            })
        };
        if let Some(e) = out_of_bounds(first.range.clone()) {
            return Err(e);
        }
        if let Some(e) = self.pieces().find_map(|(_, p)| out_of_bounds(p.range())) {
            return Err(e);
        }
        if !self.in_order() {
            return self.apply_in(source, 0..source.len(), Some(first));
        }
        self.apply_in_order(source, first)
    }

    /// Whether the edits were made in the order a stable sort by position would put them.
    fn in_order(&self) -> bool {
        let mut keys = self.pieces().map(|(_, p)| p.key());
        match keys.next() {
            Some(k0) => keys
                .try_fold(k0, |prev, k| (prev <= k).then_some(k))
                .is_some(),
            None => true,
        }
    }

    /// The bytes `within` of `source` with the edits inside them applied (and `first`, as in
    /// [`EditList::apply`], when it is inside them); edits elsewhere are left out, an edit
    /// across the bounds is an error. An insertion at the end of `within` belongs to the
    /// bytes after it (unless they end the source).
    pub fn apply_in(
        &self,
        source: &[u8],
        within: Range<usize>,
        first: Option<&Edit>,
    ) -> Result<Vec<u8>, EditError> {
        if first.is_none() && self.in_order() {
            return self.apply_in_ordered(source, within);
        }
        self.apply_in_sorted(source, within, first)
    }

    /// [`Self::apply_in`] of edits in any order: gathered and sorted.
    fn apply_in_sorted(
        &self,
        source: &[u8],
        within: Range<usize>,
        first: Option<&Edit>,
    ) -> Result<Vec<u8>, EditError> {
        let mut items: Vec<(Range<usize>, &[u8])> = Vec::new();
        let all = first
            .map(|f| (f.range.clone(), &f.bytes[..]))
            .into_iter()
            .chain(self.pieces().map(|(s, p)| (p.range(), s.bytes(p))));
        for (r, bytes) in all {
            if r.start > r.end || r.end > source.len() {
                return Err(EditError::OutOfBounds {
                    range: r,
                    len: source.len(),
                });
            }
            let inside = within.start <= r.start
                && r.end <= within.end
                && !(r.is_empty() && r.start == within.end && within.end < source.len());
            let straddles = (r.start < within.start && r.end > within.start)
                || (r.start < within.end && r.end > within.end);
            if inside {
                items.push((r, bytes));
            } else if straddles {
                return Err(EditError::OutOfBounds {
                    range: r,
                    len: within.end,
                });
            }
        }
        // Stable: `first` and insertions at one offset keep their order.
        items.sort_by_key(|(r, _)| (r.start, r.end));
        for w in items.windows(2) {
            if w[1].0.start < w[0].0.end {
                return Err(EditError::Overlap {
                    first: w[0].0.clone(),
                    second: w[1].0.clone(),
                });
            }
        }
        let removed: usize = items.iter().map(|(r, _)| r.len()).sum();
        let added: usize = items.iter().map(|(_, b)| b.len()).sum();
        let mut out = Vec::with_capacity(within.len() - removed + added);
        let mut at = within.start;
        for (r, bytes) in items {
            out.extend_from_slice(&source[at..r.start]);
            out.extend_from_slice(bytes);
            at = r.end;
        }
        out.extend_from_slice(&source[at..within.end]);
        Ok(out)
    }

    /// [`Self::apply_in`] without `first` for edits already in order (a streamed window's):
    /// the same checks in the same order — bounds of every edit first, then overlaps — and
    /// the output written straight from the pieces, with no list to gather and sort.
    fn apply_in_ordered(&self, source: &[u8], within: Range<usize>) -> Result<Vec<u8>, EditError> {
        let inside = |r: &Range<usize>| {
            within.start <= r.start
                && r.end <= within.end
                && !(r.is_empty() && r.start == within.end && within.end < source.len())
        };
        let (mut removed, mut added) = (0, 0);
        for (s, p) in self.pieces() {
            let r = p.range();
            if r.start > r.end || r.end > source.len() {
                return Err(EditError::OutOfBounds {
                    range: r,
                    len: source.len(),
                });
            }
            if inside(&r) {
                removed += r.len();
                added += s.bytes(p).len();
            } else if (r.start < within.start && r.end > within.start)
                || (r.start < within.end && r.end > within.end)
            {
                return Err(EditError::OutOfBounds {
                    range: r,
                    len: within.end,
                });
            }
        }
        // Overlapping edits may remove more than the stretch holds: refused below.
        let mut out = Vec::with_capacity(within.len().saturating_sub(removed) + added + BLOCK);
        let mut at = within.start;
        let mut last: Option<Range<usize>> = None;
        for (s, p) in self.pieces() {
            let r = p.range();
            if !inside(&r) {
                continue;
            }
            if let Some(l) = last.filter(|l| r.start < l.end) {
                return Err(EditError::Overlap {
                    first: l,
                    second: r,
                });
            }
            append_range(&mut out, source, at..r.start);
            append_range(&mut out, &s.text, s.range(p));
            at = r.end;
            last = Some(r);
        }
        out.extend_from_slice(&source[at..within.end]);
        Ok(out)
    }

    /// [`Self::apply`] for edits already in order: `first` goes before the first edit not
    /// ahead of it (where a stable sort with `first` in front would put it). The merged
    /// sequence is cut into runs that are measured and then written in parallel, each into
    /// its own part of the output.
    fn apply_in_order(&self, source: &[u8], first: &Edit) -> Result<Vec<u8>, EditError> {
        use rayon::prelude::*;
        let runs = Runs::cut(self, first);
        let measured: Vec<Result<usize, EditError>> = (0..runs.len())
            .into_par_iter()
            .map(|j| runs.written_len(j))
            .collect();
        let lengths = measured.into_iter().collect::<Result<Vec<usize>, _>>()?;
        let tail = &source[runs.len().checked_sub(1).map_or(0, |j| runs.last_end(j))..];
        let mut out = vec![0u8; lengths.iter().sum::<usize>() + tail.len()];
        let mut parts = Vec::with_capacity(runs.len());
        let mut rest = &mut out[..];
        for &len in &lengths {
            let (part, after) = rest.split_at_mut(len);
            parts.push(part);
            rest = after;
        }
        rest.copy_from_slice(tail);
        parts
            .into_par_iter()
            .enumerate()
            .for_each(|(j, part)| runs.write(j, source, part));
        Ok(out)
    }
}

/// The merged, ordered edits of [`EditList::apply_in_order`] cut into [`Run`]s: each run is
/// measured and written on its own, starting where the run before it ended in the source.
struct Runs<'e> {
    list: &'e EditList,
    first: &'e Edit,
    runs: Vec<Run>,
}

impl<'e> Runs<'e> {
    /// Edits per run (a few in tests, so that they cut runs everywhere).
    const RUN: usize = if cfg!(test) { 3 } else { 1 << 16 };

    fn cut(list: &'e EditList, first: &'e Edit) -> Runs<'e> {
        let first_key = (first.range.start as u32, first.range.end as u32);
        let mut runs = Vec::new();
        let pieces = |seg: usize, from: usize, to: usize, runs: &mut Vec<Run>| {
            for a in (from..to).step_by(Self::RUN) {
                runs.push(Run::Pieces {
                    seg,
                    from: a,
                    to: (a + Self::RUN).min(to),
                });
            }
        };
        let mut placed = false;
        for (seg, s) in list.segments.iter().enumerate() {
            let mut from = 0;
            if !placed {
                let at = s.pieces.partition_point(|p| p.key() < first_key);
                if at < s.pieces.len() {
                    pieces(seg, 0, at, &mut runs);
                    runs.push(Run::First);
                    placed = true;
                    from = at;
                }
            }
            pieces(seg, from, s.pieces.len(), &mut runs);
        }
        if !placed {
            runs.push(Run::First);
        }
        Runs { list, first, runs }
    }

    fn len(&self) -> usize {
        self.runs.len()
    }

    /// Edit `k` of run `j`: the source range it replaces and its bytes.
    fn item(&self, j: usize, k: usize) -> (Range<usize>, &'e [u8]) {
        match self.runs[j] {
            Run::First => (self.first.range.clone(), &self.first.bytes[..]),
            Run::Pieces { seg, from, .. } => {
                let s = &self.list.segments[seg];
                let p = &s.pieces[from + k];
                (p.range(), s.bytes(p))
            }
        }
    }

    fn count(&self, j: usize) -> usize {
        match self.runs[j] {
            Run::First => 1,
            Run::Pieces { from, to, .. } => to - from,
        }
    }

    /// Where run `j` starts in the source: where the run before it ended.
    fn start(&self, j: usize) -> usize {
        if j == 0 {
            0
        } else {
            self.last_end(j - 1)
        }
    }

    fn last_end(&self, j: usize) -> usize {
        self.item(j, self.count(j) - 1).0.end
    }

    /// The bytes run `j` writes (the source between its edits included), or the first
    /// overlap in it, the one with the run before checked first.
    fn written_len(&self, j: usize) -> Result<usize, EditError> {
        let mut last = (j > 0).then(|| self.item(j - 1, self.count(j - 1) - 1).0);
        let (mut removed, mut added) = (0, 0);
        for k in 0..self.count(j) {
            let (r, bytes) = self.item(j, k);
            if let Some(a) = &last {
                if r.start < a.end {
                    return Err(EditError::Overlap {
                        first: a.clone(),
                        second: r,
                    });
                }
            }
            removed += r.len();
            added += bytes.len();
            last = Some(r);
        }
        Ok(self.last_end(j) - self.start(j) - removed + added)
    }

    /// Run `j` written into `part` (exactly [`Self::written_len`] bytes).
    fn write(&self, j: usize, source: &[u8], part: &mut [u8]) {
        let (mut at, mut w) = (self.start(j), 0);
        for k in 0..self.count(j) {
            let (r, bytes) = self.item(j, k);
            let keep = &source[at..r.start];
            part[w..w + keep.len()].copy_from_slice(keep);
            w += keep.len();
            part[w..w + bytes.len()].copy_from_slice(bytes);
            w += bytes.len();
            at = r.end;
        }
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

        /// Edits made in order (the streaming path), in up to three segments, with `first`
        /// anywhere: the same as `krl::apply`, overlaps included.
        #[test]
        fn ordered_edits_apply_like_krl_apply(
            src in "[a-z]{0,40}",
            steps in proptest::collection::vec((0usize..4, 0usize..3, "[A-Z]{0,3}"), 0..14),
            first_at in 0usize..44,
            first_len in 0usize..2,
            cuts in (0usize..14, 0usize..14),
        ) {
            let mut at = 0;
            let mut edits = Vec::new();
            for (gap, len, text) in &steps {
                at += gap;
                edits.push(edit(at, at + len, text));
                at += len;
            }
            let first = edit(first_at, first_at + first_len, "#");
            let (c1, c2) = (cuts.0.min(cuts.1), cuts.0.max(cuts.1));
            let mut lists = [EditList::new(), EditList::new(), EditList::new()];
            for (i, e) in edits.iter().enumerate() {
                lists[usize::from(i >= c1) + usize::from(i >= c2)].push(e.clone());
            }
            let [mut a, mut b, mut c] = lists;
            a.append(&mut b);
            a.append(&mut c);
            prop_assert_eq!(a.to_edits(), edits.clone());
            let mut all = vec![first.clone()];
            all.extend(edits);
            prop_assert_eq!(a.apply(src.as_bytes(), &first), crate::krl::apply(src.as_bytes(), &all));
        }
    }

    proptest! {
        /// A stretch of edits made in order (or not), without `first`: the streamed path of
        /// `apply_in` gives what gathering and sorting gives, errors included.
        #[test]
        fn ordered_stretch_applies_like_sorted(
            src in "[a-z]{1,40}",
            steps in proptest::collection::vec((-2i64..4, 0usize..3, "[A-Z]{0,3}"), 0..14),
            shuffle in any::<bool>(),
            bounds in (0usize..44, 0usize..44),
        ) {
            let n = src.len();
            let mut at = 0usize;
            let mut edits = Vec::new();
            for (gap, len, text) in &steps {
                // A step back now and then (an overlap), past the end too (out of bounds).
                at = (at as i64 + gap).max(0) as usize;
                edits.push(edit(at, at + len, text));
                at += len;
            }
            if shuffle {
                edits.reverse();
            }
            let mut list = EditList::new();
            for e in &edits {
                list.push(e.clone());
            }
            let (a, b) = (bounds.0.min(bounds.1).min(n), bounds.0.max(bounds.1).min(n));
            prop_assert_eq!(
                list.apply_in(src.as_bytes(), a..b, None),
                list.apply_in_sorted(src.as_bytes(), a..b, None)
            );
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
