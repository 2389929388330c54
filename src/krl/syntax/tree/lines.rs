//! Each line of a file parsed on its own: a [`LineParse`] takes the lines one at a time, cuts
//! them into trivia and code, parses the code (or, when streaming, collects a stretch of plain
//! lines into a run without building their statements) and hands the statements to the
//! [`Builder`](super::nesting::Builder).

use super::nesting::{Builder, LineAt};
use super::FileKind;
use crate::krl::syntax::error::Problem;
use crate::krl::syntax::fold::{Fold, FoldId, FoldTracker};
use crate::krl::syntax::lex::Cx;
use crate::krl::syntax::nodes::Nodes;
use crate::krl::syntax::plain::{self, Members};
use crate::krl::syntax::span::Span;
use crate::krl::syntax::stmt::{Line, Stmt, StmtKind};
use crate::krl::syntax::stream::{Held, LookedLine, StreamOptions, StreamedRun, Stretch};
use crate::krl::syntax::trivia::RawLine;
use std::cell::RefCell;

/// A parse under way, fed one line at a time ([`LineParse::line`]): the blocks open, the
/// folds, the lines seen, and with streaming the stretch of plain lines being collected.
pub(super) struct LineParse<'s> {
    src: &'s [u8],
    kind: FileKind,
    cx: Cx<'s>,
    stream: Option<StreamOptions>,
    /// The end of the lines parsed.
    end: usize,
    blocks: Builder,
    folds: FoldTracker,
    /// Where each line starts (the line index).
    starts: Vec<u32>,
    /// The number of the line being read.
    line: u32,
    /// Where the trivia before the next statement begins.
    pending: usize,
    /// Plain lines of the main routine collected for a run (see `stream`).
    stretch: Option<Stretch>,
    runs: Vec<StreamedRun>,
    /// The fast path's buffer of members when it decides whether a line streams.
    members: Members,
    /// The pool the fallback parses into when it decides whether a line streams
    /// (`plain::streams`), emptied after each line.
    scratch: RefCell<Nodes>,
}

/// What a finished [`LineParse`] gives the file.
pub(super) struct Parsed {
    pub(super) body: Vec<Stmt>,
    pub(super) problems: Vec<Problem>,
    pub(super) folds: Vec<Fold>,
    pub(super) starts: Vec<u32>,
    /// Where the file's trailing trivia starts (the tree keeps it only to emit itself).
    #[cfg(any(test, feature = "internals"))]
    pub(super) pending: usize,
    pub(super) runs: Vec<StreamedRun>,
}

impl<'s> LineParse<'s> {
    pub(super) fn new(
        src: &'s [u8],
        kind: FileKind,
        nodes: &'s RefCell<Nodes>,
        range: std::ops::Range<usize>,
        first_line: u32,
        stream: Option<StreamOptions>,
    ) -> Self {
        let mut starts = Vec::with_capacity(range.len() / 32 + 1);
        starts.push(range.start as u32);
        LineParse {
            src,
            kind,
            cx: Cx::new(src, nodes),
            stream,
            end: range.end,
            blocks: Builder::default(),
            folds: FoldTracker::default(),
            starts,
            line: first_line,
            pending: range.start,
            stretch: None,
            runs: Vec::new(),
            members: Members::default(),
            scratch: RefCell::default(),
        }
    }

    /// Takes the line starting at `pos` (cut as `l`; `hint`: the parallel look at it).
    pub(super) fn line(&mut self, pos: usize, l: &RawLine, hint: Option<&LookedLine>) {
        if l.code_start == l.code_end {
            if let Some((c0, c1)) = l.comment {
                let src = self.src;
                let comment = &src[c0..c1];
                if self.stretch.is_some() && fold_marker(comment) {
                    self.close_stretch();
                }
                self.folds.comment_line(self.cx, comment, self.line);
            }
        } else {
            let code = Span::new(l.code_start, l.code_end);
            if !self.streamed(pos, l, code, hint) {
                self.close_stretch();
                let leading = Span::new(self.pending, l.code_start);
                self.pending = l.code_end;
                self.feed(code, leading, self.line, self.folds.current());
            }
        }
        if l.newline < self.end {
            self.starts.push(l.next as u32);
            self.line += 1;
        }
    }

    /// Whether the line of `code` is left to a run (added to the stretch): with streaming, a
    /// plain line directly in the main routine, outside folds.
    fn streamed(&mut self, pos: usize, l: &RawLine, code: Span, hint: Option<&LookedLine>) -> bool {
        let Some(opts) = &self.stream else {
            return false;
        };
        if !self.blocks.in_main_body() || self.folds.current().is_some() {
            return false;
        }
        let looked = hint.map(|h| h.plain);
        let (src, kind) = (self.src, self.kind);
        let plain = plain::streams(src, kind, code, looked, &self.scratch, &mut self.members);
        if plain {
            let held = Held {
                code,
                line: self.line,
            };
            let blocks = &self.blocks;
            let stretch = self
                .stretch
                .get_or_insert_with(|| Stretch::new(pos, self.line));
            stretch.push(opts, pos, l.next.min(self.end), held, || {
                blocks.main_body_len()
            });
        }
        plain
    }

    /// A line of code into the tree (parsed; an unreadable line recorded as a problem).
    fn feed(&mut self, code: Span, leading: Span, line: u32, fold: Option<FoldId>) {
        let src = self.src;
        let text = &src[code.range()];
        let read = plain::read(self.cx, self.kind, text);
        let parsed = match read {
            Ok(parsed) => parsed,
            Err(Some(e)) => {
                let at = self.cx.off(e.at).min(code.end as usize);
                let mut p = Problem::error(
                    Span::new(at, (at + 1).min(code.end as usize).max(at)),
                    e.label(),
                    e.help(),
                );
                if p.message.is_empty() {
                    p.message = "malformed statement".into();
                }
                self.blocks.problems.push(p);
                Line::Simple(StmtKind::Invalid)
            }
            Err(None) => Line::Simple(StmtKind::Opaque),
        };
        if let Some(p) = module_name_warning(src, &parsed) {
            self.blocks.problems.push(p);
        }
        let at = LineAt {
            leading,
            head: code,
            line,
            fold,
        };
        self.blocks.feed(parsed, at);
    }

    /// Ends the stretch being collected: a run, or (too short for one) its lines parsed into
    /// the tree after all.
    fn close_stretch(&mut self) {
        let Some(st) = self.stretch.take() else {
            return;
        };
        match st.run {
            Some(run) => self.runs.push(run),
            None => {
                for h in st.held {
                    let leading = Span::new(self.pending, h.code.start as usize);
                    self.feed(h.code, leading, h.line, None);
                    self.pending = h.code.end as usize;
                }
            }
        }
    }

    pub(super) fn finish(mut self) -> Parsed {
        self.close_stretch();
        let (body, mut problems) = self.blocks.finish();
        let (folds, fold_problems) = self.folds.finish();
        problems.extend(fold_problems);
        problems.sort_by_key(|p| (p.span.start, p.severity));
        Parsed {
            body,
            problems,
            folds,
            starts: self.starts,
            #[cfg(any(test, feature = "internals"))]
            pending: self.pending,
            runs: self.runs,
        }
    }
}

/// A routine or data list whose name is not a KRL name (a generator wrote the file's path
/// into it): a warning on the name; the module is read as any other.
fn module_name_warning(src: &[u8], parsed: &Line) -> Option<Problem> {
    let (name, what) = match parsed {
        Line::Open(StmtKind::Routine(h), _) => (h.name, "routine"),
        Line::Open(StmtKind::DefDat(h), _) => (h.name, "data list"),
        _ => return None,
    };
    let text = &src[name.range()];
    if crate::krl::syntax::decl::is_name(text) {
        return None;
    }
    Some(Problem::warning(
        name,
        format!(
            "the {what} name `{}` is not a KRL name (letters, digits, `_`, `$`; not starting with a digit): the controller will refuse the module; the rest is read as usual",
            String::from_utf8_lossy(text)
        ),
        "name the module as its file, without the folder (a generator may have written the path into it)",
    ))
}

/// A `;FOLD` or `;ENDFOLD` line (a run never spans one: folds change what motions mean).
fn fold_marker(comment: &[u8]) -> bool {
    let body = comment[1..].trim_ascii_start();
    [&b"FOLD"[..], b"ENDFOLD"]
        .iter()
        .any(|w| body.len() >= w.len() && body[..w.len()].eq_ignore_ascii_case(w))
}
