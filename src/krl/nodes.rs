//! Per-file pools for the nodes a program has by the million — motions, aggregates and their
//! members — referred to by typed ids. A CAM program of a million `LIN {…}` lines would
//! otherwise make several million small heap allocations (and as many frees); pooled, parsing
//! stays at memory speed. `SourceFile` gives access through `motion(id)`, `aggregate(id)` and
//! `members(aggregate)`.

use super::expr::{Aggregate, Member};
use super::memory::Ahead;
use super::motion::Motion;

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
    pub members: Vec<Member>,
    /// Members of aggregates nested in another one (each run moved here from `scratch` when
    /// its aggregate closes, so runs stay contiguous while the parent's run grows).
    pub nested_members: Vec<Member>,
    pub scratch: Vec<Member>,
    /// Aggregates open on the current line (reset per line: a failure may leave it high,
    /// which only sends later aggregates of that line down the nested path).
    pub agg_depth: u32,
    /// Whether some member of `members` owns heap memory (a path, call or operator value):
    /// when none does, dropping the pool need not visit its millions of members.
    members_own_heap: bool,
    /// The same for `motions` (a target that is a path or an expression, a boxed extra).
    motions_own_heap: bool,
    /// Pages mapped ahead of the three big pools (see `memory`).
    ahead: [Ahead; 3],
}

impl Drop for Nodes {
    fn drop(&mut self) {
        if !self.members_own_heap {
            // SAFETY: no member of the pool owns heap memory (`push_member` records every
            // one that does), so forgetting them frees nothing that dropping them would;
            // the buffer itself is still freed with the Vec. Length 0 is always valid.
            unsafe { self.members.set_len(0) }
        }
        if !self.motions_own_heap {
            // SAFETY: as above; `push_motion` records every motion that owns heap memory.
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
}

impl Nodes {
    pub fn mark(&self) -> Mark {
        Mark {
            motions: self.motions.len(),
            aggregates: self.aggregates.len(),
            members: self.members.len(),
            nested_members: self.nested_members.len(),
        }
    }

    pub fn reset(&mut self, m: Mark) {
        self.motions.truncate(m.motions);
        self.aggregates.truncate(m.aggregates);
        self.members.truncate(m.members);
        self.nested_members.truncate(m.nested_members);
        self.scratch.clear();
        self.agg_depth = 0;
    }

    /// Starts a line: nothing is open.
    pub fn new_line(&mut self) {
        self.scratch.clear();
        self.agg_depth = 0;
    }

    /// The members of an aggregate.
    pub fn members_of(&self, a: &Aggregate) -> &[Member] {
        let pool = if a.nested() {
            &self.nested_members
        } else {
            &self.members
        };
        &pool[a.range()]
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

    /// Adds a member of an outermost aggregate.
    #[inline]
    pub fn push_member(&mut self, m: Member) {
        self.members_own_heap |= m.value.owns_heap();
        self.ahead[0].before_push(&self.members);
        self.members.push(m);
    }

    #[inline]
    pub fn push_motion(&mut self, m: Motion) {
        self.motions_own_heap |= m.owns_heap();
        self.ahead[1].before_push(&self.motions);
        self.motions.push(m);
    }

    #[inline]
    pub fn push_aggregate(&mut self, a: Aggregate) {
        self.ahead[2].before_push(&self.aggregates);
        self.aggregates.push(a);
    }

    /// Releases spare capacity and the scratch buffer once the file is parsed.
    pub fn finish(&mut self) {
        self.scratch = Vec::new();
        self.motions.shrink_to_fit();
        self.aggregates.shrink_to_fit();
        self.members.shrink_to_fit();
        self.nested_members.shrink_to_fit();
    }
}
