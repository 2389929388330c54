//! Streamed runs: the long straight stretches CAM systems write into a main routine —
//! thousands of motions to literal positions, with comments and speed settings between
//! them — which a caller may process window by window instead of holding a tree of them all.
//! When asked ([`super::parse_streaming`]), the parser leaves such a stretch out of the tree
//! (its bytes become the next statement's leading trivia, so the tree still emits the file
//! byte for byte) and records it as a [`StreamedRun`] cut into windows of whole lines;
//! [`super::SourceFile::window`] parses one window into a file of its own that shares the
//! source bytes, with the spans and line numbers of the whole-file parse. Only lines whose
//! meaning depends on nothing but themselves qualify (see [`is_plain`]), so the statements of
//! a run can be executed in order without the variables of the routine around them.

use super::expr::Expr;
use super::motion::MotionKind;
use super::nodes::Nodes;
use super::span::Span;
use super::stmt::{Line, StmtKind};

/// How runs are found and cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamOptions {
    /// Plain lines a stretch needs to become a run (shorter stretches stay in the tree).
    pub min_run: usize,
    /// Plain lines per window.
    pub window: usize,
}

impl Default for StreamOptions {
    fn default() -> StreamOptions {
        // A window of 8k motions holds a few MB of tree, stops and results; a run of a few
        // thousand lines is already worth not holding as a tree.
        StreamOptions {
            min_run: 2_048,
            window: 8_192,
        }
    }
}

/// A stretch of the main routine's body left out of the tree.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StreamedRun {
    /// Whole lines: from the start of the first plain line to the start of the line after the
    /// last one.
    pub range: Span,
    /// Index in the main routine's body of the statement the run comes before (the body's
    /// length when it comes last).
    pub before: u32,
    /// Start offset and 1-based line number of every window.
    pub(crate) windows: Vec<(u32, u32)>,
}

impl StreamedRun {
    /// The windows: their bytes (whole lines) and the line number of their first line.
    pub fn windows(&self) -> impl ExactSizeIterator<Item = (Span, u32)> + '_ {
        (0..self.windows.len()).map(|i| {
            let (start, line) = self.windows[i];
            let end = self
                .windows
                .get(i + 1)
                .map_or(self.range.end, |&(next, _)| next);
            (Span::new(start as usize, end as usize), line)
        })
    }
}

/// System variables whose assignment changes the motion (the walker follows them).
const MOVING_SYSTEM_VARIABLES: [&[u8]; 3] = [b"$BASE", b"$TOOL", b"$IPO_MODE"];

/// Whether a parsed line means the same wherever it stands: a `PTP`/`LIN`/`CIRC` (or their
/// `_REL` forms, relative to where the robot is) to literal aggregates (numbers only; no
/// `CA`, `WITH` or `:` chain), an assignment to a system
/// variable that does not move the robot (`$VEL.CP = 0.2`, `$OUT[3] = TRUE`), `WAIT SEC`.
pub(crate) fn is_plain(line: &Line, nodes: &Nodes, src: &[u8]) -> bool {
    let Line::Simple(kind) = line else {
        return false;
    };
    match kind {
        StmtKind::Motion(id) => {
            let m = &nodes.motions[id.0 as usize];
            use MotionKind::*;
            matches!(m.kind, Ptp | Lin | Circ | PtpRel | LinRel | CircRel)
                && literal(&m.target, nodes, src)
                && m.aux().map_or(true, |a| literal(a, nodes, src))
                && m.angle().is_none()
                && m.with().is_empty()
        }
        StmtKind::Assign(a) => a.lhs.as_path().is_some_and(|p| {
            let root = &src[p.root.range()];
            root.first() == Some(&b'$')
                && !MOVING_SYSTEM_VARIABLES
                    .iter()
                    .any(|v| root.eq_ignore_ascii_case(v))
        }),
        StmtKind::WaitSec(_) => true,
        _ => false,
    }
}

/// An aggregate of numbers only.
fn literal(e: &Expr, nodes: &Nodes, src: &[u8]) -> bool {
    let Expr::Aggregate(_, id) = e else {
        return false;
    };
    let a = &nodes.aggregates[id.0 as usize];
    nodes
        .members_of(a)
        .iter()
        .all(|&p| matches!(nodes.member(src, p).value.as_ref(), Expr::Number(_)))
}

/// A line of a stretch not yet long enough to be a run (parsed again into the tree if the
/// stretch ends short).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Held {
    pub code: Span,
    pub line: u32,
}

/// The stretch being collected.
#[derive(Debug)]
pub(crate) struct Stretch {
    pub start: u32,
    pub first_line: u32,
    /// Plain lines while the stretch is shorter than `min_run`; emptied when it becomes a run.
    pub held: Vec<Held>,
    pub run: Option<StreamedRun>,
    /// Plain lines in the current window.
    pub in_window: usize,
}

impl Stretch {
    pub fn new(start: usize, line: u32) -> Stretch {
        Stretch {
            start: start as u32,
            first_line: line,
            held: Vec::new(),
            run: None,
            in_window: 0,
        }
    }

    /// Adds a plain line starting at `start` whose next line starts at `next`; `before` is the
    /// main body's length (asked only when the stretch becomes a run).
    pub fn push(
        &mut self,
        opts: &StreamOptions,
        start: usize,
        next: usize,
        held: Held,
        before: impl FnOnce() -> u32,
    ) {
        match &mut self.run {
            Some(run) => {
                if self.in_window == opts.window.max(1) {
                    run.windows.push((start as u32, held.line));
                    self.in_window = 0;
                }
                self.in_window += 1;
                run.range.end = next as u32;
            }
            None => {
                self.held.push(held);
                if self.held.len() >= opts.min_run.max(1) {
                    self.in_window = self.held.len();
                    self.held = Vec::new();
                    self.run = Some(StreamedRun {
                        range: Span::new(self.start as usize, next),
                        before: before(),
                        windows: vec![(self.start, self.first_line)],
                    });
                    // The first window may hold more than `window` lines (it took `min_run`).
                    if self.in_window > opts.window.max(1) {
                        self.in_window = opts.window.max(1);
                    }
                }
            }
        }
    }
}
