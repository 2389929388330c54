//! Per-file pools for the nodes a program has by the million — motions, aggregates and their
//! members — referred to by typed ids. A CAM program of a million `LIN {…}` lines would
//! otherwise make several million small heap allocations (and as many frees); pooled, parsing
//! stays at memory speed. `SourceFile` gives access through `motion(id)`, `aggregate(id)` and
//! `members(aggregate)`. Members are stored as 8-byte records (`Packed`): a `NAME number`
//! member keeps only where its name and number are, the number being read again from the
//! source bytes when asked for; any other member's value lives in an out-of-line pool.

use super::expr::{Aggregate, Expr, Member, Number};
use super::memory::Ahead;
use super::motion::Motion;
use super::number;
use super::span::Span;
use std::borrow::Cow;

/// A motion statement's data in its file (`SourceFile::motion`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MotionId(pub u32);

/// An aggregate in its file (`SourceFile::aggregate`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct AggregateId(pub u32);

#[derive(Clone, Debug, Default)]
pub(crate) struct Nodes {
    pub motions: Vec<Motion>,
    pub aggregates: Vec<Aggregate>,
    /// Members of outermost aggregates, written in place as they are parsed.
    pub members: Vec<Packed>,
    /// With `keep_values`, the value of each plain member of `members`, in step with it (NaN
    /// for the others): a streamed window, walked as soon as it is parsed, then needs not
    /// read its numbers again. Empty otherwise (a whole file's tree keeps spans only).
    pub member_values: Vec<f64>,
    pub keep_values: bool,
    /// Members of aggregates nested in another one (each run moved here from `scratch` when
    /// its aggregate closes, so runs stay contiguous while the parent's run grows).
    pub nested_members: Vec<Packed>,
    pub scratch: Vec<Packed>,
    /// Name and value of every member that is not a plain `NAME number` (paths, strings,
    /// enums, nested aggregates, expressions, numbers `read_plain` declines).
    pub outline: Vec<(Span, Expr)>,
    /// Aggregates open on the current line (reset per line: a failure may leave it high,
    /// which only sends later aggregates of that line down the nested path).
    pub agg_depth: u32,
    /// Whether some motion owns heap memory (a target that is a path or an expression, a
    /// boxed extra): when none does, dropping the pool need not visit its million motions.
    motions_own_heap: bool,
    /// Pages mapped ahead of the three big pools (see `memory`).
    ahead: PoolsAhead,
}

/// Where each big pool has pages mapped ahead of its end ([`Ahead`]).
#[derive(Clone, Copy, Debug, Default)]
struct PoolsAhead {
    members: Ahead,
    motions: Ahead,
    aggregates: Ahead,
}

impl Drop for Nodes {
    fn drop(&mut self) {
        if !self.motions_own_heap {
            // SAFETY: no motion of the pool owns heap memory (`push_motion` records every
            // one that does), so forgetting them frees nothing that dropping them would;
            // the buffer itself is still freed with the Vec. Length 0 is always valid.
            unsafe { self.motions.set_len(0) }
        }
    }
}

/// Pool sizes before a line was parsed, to drop what a failed line left behind.
#[derive(Clone, Copy)]
pub(crate) struct Mark {
    motions: usize,
    aggregates: usize,
    members: usize,
    nested_members: usize,
    outline: usize,
}

impl Nodes {
    pub fn mark(&self) -> Mark {
        Mark {
            motions: self.motions.len(),
            aggregates: self.aggregates.len(),
            members: self.members.len(),
            nested_members: self.nested_members.len(),
            outline: self.outline.len(),
        }
    }

    pub fn reset(&mut self, m: Mark) {
        self.motions.truncate(m.motions);
        self.aggregates.truncate(m.aggregates);
        self.members.truncate(m.members);
        self.member_values.truncate(m.members);
        self.nested_members.truncate(m.nested_members);
        self.outline.truncate(m.outline);
        self.scratch.clear();
        self.agg_depth = 0;
    }

    /// Empties the pools (a pool reused line after line).
    pub fn clear(&mut self) {
        self.reset(Mark {
            motions: 0,
            aggregates: 0,
            members: 0,
            nested_members: 0,
            outline: 0,
        });
    }

    /// Starts a line: nothing is open.
    pub fn new_line(&mut self) {
        self.scratch.clear();
        self.agg_depth = 0;
    }

    /// The stored members of an aggregate.
    pub fn members_of(&self, a: &Aggregate) -> &[Packed] {
        let pool = if a.nested() {
            &self.nested_members
        } else {
            &self.members
        };
        &pool[a.range()]
    }

    /// A member's name without reading its value.
    #[inline]
    pub fn member_name(&self, p: Packed) -> Span {
        if p.name_len == 0 {
            self.outline[p.at as usize].0
        } else {
            Span::new(p.at as usize, p.at as usize + usize::from(p.name_len))
        }
    }

    /// Whether a member's value is a number, without reading it (a packed member's always
    /// is: `pack` and the parser's plain path store only numbers `read_plain` reads whole).
    #[inline]
    pub fn member_is_number(&self, p: Packed) -> bool {
        p.name_len != 0 || matches!(self.outline[p.at as usize].1, Expr::Number(_))
    }

    /// A member with its value (a plain number is read again from `src`, the bytes the
    /// file was parsed from, giving the value the parser read).
    pub fn member<'n>(&'n self, src: &[u8], p: Packed) -> Member<'n> {
        self.member_of_raw(src, self.raw_member(p, None))
    }

    /// A raw member with its value, a plain number read from `src` (see [`Nodes::member`]).
    pub fn member_of_raw<'n>(&'n self, src: &[u8], raw: RawMember<'n>) -> Member<'n> {
        match raw {
            RawMember::Outline { name, value } => Member {
                name,
                value: Cow::Borrowed(value),
            },
            RawMember::Plain {
                name, number: span, ..
            } => {
                let value = match src.get(span.range()).and_then(number::read_plain) {
                    Some((len, value, integer)) if len == span.len() => {
                        Expr::Number(Number::new(value, span, integer))
                    }
                    // Unreachable: `pack` stores only numbers `read_plain` reads back whole.
                    _ => Expr::Opaque(span),
                };
                Member {
                    name,
                    value: Cow::Owned(value),
                }
            }
        }
    }

    /// A member as stored, its plain number not read ([`RawMember`]); `kept`: its value
    /// from `member_values`, if kept.
    #[inline]
    pub fn raw_member(&self, p: Packed, kept: Option<f64>) -> RawMember<'_> {
        if p.name_len == 0 {
            let (name, value) = &self.outline[p.at as usize];
            return RawMember::Outline { name: *name, value };
        }
        let name = self.member_name(p);
        let start = name.end as usize + usize::from(p.gap);
        RawMember::Plain {
            name,
            number: Span::new(start, start + usize::from(p.value_len)),
            kept,
        }
    }

    /// The kept values of the members of `a` (empty when none are kept).
    pub fn kept_values_of(&self, a: &Aggregate) -> &[f64] {
        if a.nested() || self.member_values.len() != self.members.len() {
            return &[];
        }
        &self.member_values[a.range()]
    }

    /// The record of member `name` = `value` in `src`: packed when the value is a number
    /// `read_plain` gives back bit for bit, else out of line.
    pub fn pack(&mut self, src: &[u8], name: Span, value: Expr) -> Packed {
        if let Expr::Number(n) = &value {
            let span = n.span();
            let fits = matches!(number::read_plain(&src[span.range()]),
                Some((len, v, integer)) if len == span.len()
                    && v.to_bits() == n.value.to_bits()
                    && integer == n.integer);
            if fits && span.start >= name.end {
                if let Some(p) = Packed::plain(name, span) {
                    return p;
                }
            }
        }
        let at = self.outline.len() as u32;
        self.outline.push((name, value));
        Packed {
            at,
            name_len: 0,
            gap: 0,
            value_len: 0,
        }
    }

    /// Pools sized for a file of `len` bytes, in the proportions of a CAM program (one
    /// motion and aggregate per ~60 bytes, a member per ~10): reserving only claims address
    /// space, pages are touched as nodes are written, and `finish` gives back what is unused.
    pub fn for_input(len: usize) -> Nodes {
        let mut n = Nodes::default();
        n.motions.reserve(len / 56);
        n.aggregates.reserve(len / 56);
        n.members.reserve(len / 9);
        n
    }

    /// Adds a member of an outermost aggregate; `value`: a plain member's (see
    /// `member_values`).
    #[inline]
    pub fn push_member(&mut self, m: Packed, value: f64) {
        self.ahead.members.before_push(&self.members);
        self.members.push(m);
        if self.keep_values {
            self.member_values.push(value);
        }
    }

    /// The members pool and its values (`member_values`, pushed in step only with
    /// `keep_values`), the pages of the next `n` members mapped: for a reader that writes
    /// them itself (`plain::read`).
    #[inline]
    pub fn members_for(&mut self, n: usize) -> (&mut Vec<Packed>, &mut Vec<f64>) {
        self.ahead.members.before_extend(&self.members, n);
        (&mut self.members, &mut self.member_values)
    }

    #[inline]
    pub fn push_motion(&mut self, m: Motion) {
        self.motions_own_heap |= m.owns_heap();
        self.ahead.motions.before_push(&self.motions);
        self.motions.push(m);
    }

    #[inline]
    pub fn push_aggregate(&mut self, a: Aggregate) {
        self.ahead.aggregates.before_push(&self.aggregates);
        self.aggregates.push(a);
    }

    /// Releases spare capacity and the scratch buffer once the file is parsed.
    pub fn finish(&mut self) {
        self.scratch = Vec::new();
        self.motions.shrink_to_fit();
        self.aggregates.shrink_to_fit();
        self.members.shrink_to_fit();
        self.member_values.shrink_to_fit();
        self.nested_members.shrink_to_fit();
        self.outline.shrink_to_fit();
    }
}

/// A member as stored, 8 bytes. A plain member: `at` is where its name starts, `name_len`
/// (≥ 1) its length, the number starts `gap` bytes after the name and is `value_len` long.
/// `name_len` 0 marks a member held out of line: `at` is its index in `Nodes::outline`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Packed {
    at: u32,
    name_len: u8,
    gap: u8,
    value_len: u16,
}

impl Packed {
    /// A plain member's name (`name_len` ≥ 1; an out-of-line member's is in `Nodes::outline`).
    #[inline]
    pub fn plain_name(self) -> Span {
        debug_assert!(self.name_len != 0);
        Span::new(
            self.at as usize,
            self.at as usize + usize::from(self.name_len),
        )
    }

    /// A plain member's record, if its lengths fit.
    #[inline]
    pub fn plain(name: Span, number: Span) -> Option<Packed> {
        Some(Packed {
            at: name.start,
            name_len: u8::try_from(name.len()).ok().filter(|&l| l > 0)?,
            gap: u8::try_from(number.start.checked_sub(name.end)?).ok()?,
            value_len: u16::try_from(number.len()).ok()?,
        })
    }
}

/// A member as stored, for readers that need only spans (the rewrite's decimals and
/// literal places): a plain `NAME number` member gives where its name and number are
/// without reading the number (read it with [`RawMember::plain_value`] if needed), any other
/// member its name and value expression.
#[derive(Clone, Copy, Debug)]
pub enum RawMember<'a> {
    /// `kept`: the number's value, when the tree keeps its plain members' values
    /// (`Nodes::member_values`).
    Plain {
        name: Span,
        number: Span,
        kept: Option<f64>,
    },
    Outline {
        name: Span,
        value: &'a Expr,
    },
}

impl RawMember<'_> {
    pub fn name(&self) -> Span {
        match self {
            RawMember::Plain { name, .. } | RawMember::Outline { name, .. } => *name,
        }
    }

    /// The value of a plain member's number in `src` (the file's bytes): the value the
    /// parser read (`Nodes::pack` keeps only numbers `read_plain` gives back bit for bit).
    #[inline]
    pub fn plain_value(src: &[u8], number: Span) -> Option<f64> {
        Self::plain_value_kept(src, number, None)
    }

    /// [`Self::plain_value`], or `kept` when the tree kept it (the same value: the parser
    /// read it with the same function).
    #[inline]
    pub fn plain_value_kept(src: &[u8], number: Span, kept: Option<f64>) -> Option<f64> {
        if kept.is_some() {
            return kept;
        }
        match src.get(number.range()).and_then(number::read_plain) {
            Some((len, value, _)) if len == number.len() => Some(value),
            _ => None,
        }
    }
}

/// The members of an aggregate as stored (`SourceFile::raw_members`).
#[derive(Clone)]
pub struct RawMembers<'a> {
    pub(crate) nodes: &'a Nodes,
    pub(crate) packed: std::slice::Iter<'a, Packed>,
    /// In step with `packed`, or empty (`Nodes::kept_values_of`).
    pub(crate) kept: std::slice::Iter<'a, f64>,
}

impl<'a> Iterator for RawMembers<'a> {
    type Item = RawMember<'a>;

    #[inline]
    fn next(&mut self) -> Option<RawMember<'a>> {
        let p = *self.packed.next()?;
        let kept = self.kept.next().copied();
        Some(self.nodes.raw_member(p, kept))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.packed.size_hint()
    }
}

impl ExactSizeIterator for RawMembers<'_> {}

/// The members of an aggregate, in order, by value (`SourceFile::members`).
#[derive(Clone)]
pub struct Members<'a> {
    pub(crate) nodes: &'a Nodes,
    pub(crate) src: &'a [u8],
    pub(crate) packed: std::slice::Iter<'a, Packed>,
}

impl<'a> Iterator for Members<'a> {
    type Item = Member<'a>;

    fn next(&mut self) -> Option<Member<'a>> {
        let p = *self.packed.next()?;
        Some(self.nodes.member(self.src, p))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.packed.size_hint()
    }
}

impl DoubleEndedIterator for Members<'_> {
    fn next_back(&mut self) -> Option<Self::Item> {
        let p = *self.packed.next_back()?;
        Some(self.nodes.member(self.src, p))
    }
}

impl ExactSizeIterator for Members<'_> {}
