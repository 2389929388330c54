//! The lossless syntax tree of one file (`SourceFile`) and how it is built: lines are cut into
//! trivia and code, each line of code is parsed on its own, and a stack of open blocks nests
//! the statements. Every byte of the file is either a statement's code or trivia (a
//! statement's leading trivia, or the file's trailing trivia), so `emit` gives the file back
//! byte for byte. Unbalanced blocks and folds are recovered from with warnings.

use super::decl::{Decl, RoutineHeader};
use super::error::{ParseError, Problem};
use super::expr::{Aggregate, Expr, Member, Number};
use super::fold::{Fold, FoldId, FoldTracker, Ilf};
use super::lex::Cx;
use super::memory::{extend_mapped, Ahead};
use super::motion::Motion;
use super::nodes::{AggregateId, Members, MotionId, Nodes};
use super::span::{LineIndex, Span};
use super::stmt::{self, Arm, ArmKind, Block, BlockKind, Clause, Line, Stmt, StmtKind};
use super::stream::{
    is_plain, is_plain_kind, looks_plain, plain_lines, Held, LookedLine, StreamOptions,
    StreamedRun, Stretch,
};
use super::trivia::{split_line, RawLine};
use crate::diagnostic::Diagnostic;
use std::borrow::Cow;
use std::cell::RefCell;
use std::path::Path;
use std::sync::Arc;

/// Which kind of KRL file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FileKind {
    /// A program (`.src`, `.sub`): routines.
    Src,
    /// A data list (`.dat`): `DEFDAT` with declarations; `DECL` is optional.
    Dat,
}

impl FileKind {
    /// `.dat` (any case) is a data list, anything else a program.
    pub fn from_path(path: &Path) -> FileKind {
        match path.extension() {
            Some(e) if e.eq_ignore_ascii_case("dat") => FileKind::Dat,
            _ => FileKind::Src,
        }
    }
}

/// Deepest block nesting followed; deeper openers are kept as opaque lines.
const MAX_BLOCK_DEPTH: usize = 200;

/// A parsed KRL file: its original bytes, the statements, the fold overlay, the problems.
#[derive(Clone, Debug)]
pub struct SourceFile {
    /// Shared with the windows of its runs.
    src: Arc<Vec<u8>>,
    kind: FileKind,
    body: Vec<Stmt>,
    trailing: Span,
    folds: Vec<Fold>,
    problems: Vec<Problem>,
    lines: LineIndex,
    nodes: Nodes,
    /// Stretches of the main routine left out of the tree (`parse_streaming`).
    runs: Vec<StreamedRun>,
}

/// Counts of what a file holds (what `robopost check` prints).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    pub statements: usize,
    pub routines: usize,
    pub motions: usize,
    /// Position variables declared (`FRAME POS E6POS AXIS E6AXIS`) plus initialised elements
    /// of position arrays (`CNC1[17]={…}` in a data list).
    pub declared_points: usize,
    pub opaque: usize,
    pub invalid: usize,
    pub folds: usize,
    pub inline_forms: usize,
    pub errors: usize,
    pub warnings: usize,
}

/// Parses a file; `Err` when a motion, declaration or aggregate is malformed (the error holds
/// the recovered tree and every problem). Any byte sequence is accepted otherwise.
pub fn parse(bytes: &[u8], kind: FileKind) -> Result<SourceFile, ParseError> {
    let file = parse_recovering(bytes, kind);
    if file.has_errors() {
        Err(ParseError {
            file: Box::new(file),
        })
    } else {
        Ok(file)
    }
}

/// Parses a file, never failing: malformed lines become `StmtKind::Invalid` and are listed in
/// `problems()` as errors.
pub fn parse_recovering(bytes: &[u8], kind: FileKind) -> SourceFile {
    parse_recovering_owned(super::memory::copy_of(bytes), kind)
}

/// `parse_recovering` of bytes the file then owns (no copy: a program loaded from disk is
/// held once, not twice).
pub fn parse_recovering_owned(src: Vec<u8>, kind: FileKind) -> SourceFile {
    if src.len() > u32::MAX as usize {
        let mut problems = vec![Problem::error(
            Span::at(0),
            "file larger than 4 GiB",
            "split the program into several files",
        )];
        problems[0].label = "here";
        return SourceFile {
            lines: LineIndex::default(),
            src: Arc::default(),
            kind,
            body: Vec::new(),
            trailing: Span::default(),
            folds: Vec::new(),
            problems,
            nodes: Nodes::default(),
            runs: Vec::new(),
        };
    }
    let mut file = build(&src, kind);
    file.src = Arc::new(src);
    file
}

/// [`parse_recovering_owned`], leaving the plain stretches of the main routine out of the
/// tree as runs to be parsed window by window ([`SourceFile::window`]); `Err` as [`parse`].
pub fn parse_streaming(
    src: Vec<u8>,
    kind: FileKind,
    opts: StreamOptions,
) -> Result<SourceFile, ParseError> {
    let file = if src.len() > u32::MAX as usize {
        parse_recovering_owned(src, kind)
    } else {
        let opts = BuildOptions {
            stream: Some(opts),
            ..BuildOptions::default()
        };
        let mut file = build_in(&src, kind, 0..src.len(), 1, opts);
        file.src = Arc::new(src);
        file
    };
    if file.has_errors() {
        Err(ParseError {
            file: Box::new(file),
        })
    } else {
        Ok(file)
    }
}

/// Bytes from which a streamed parse looks at the lines in parallel first.
const PARALLEL_LOOK: usize = 4 << 20;

/// Parses `src` into a file whose `src` field is left empty (the caller moves the bytes in).
fn build(src: &[u8], kind: FileKind) -> SourceFile {
    build_in(src, kind, 0..src.len(), 1, BuildOptions::default())
}

/// What a parse does beyond reading the lines into a tree.
#[derive(Clone, Copy)]
struct BuildOptions {
    /// Leave the plain stretches of the main routine out of the tree as runs (see `stream`).
    stream: Option<StreamOptions>,
    /// Bytes from which a streamed parse looks at the lines in parallel first
    /// ([`plain_lines`]).
    parallel_look: usize,
    /// Keep each plain member's value as it is read (`Nodes::member_values`): a streamed
    /// window, walked as soon as it is parsed, then reads none of its numbers again.
    keep_values: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            stream: None,
            parallel_look: PARALLEL_LOOK,
            keep_values: false,
        }
    }
}

/// Parses the whole lines `range` of `src` (line `first_line` first) as `opts` asks.
fn build_in(
    src: &[u8],
    kind: FileKind,
    range: std::ops::Range<usize>,
    first_line: u32,
    opts: BuildOptions,
) -> SourceFile {
    let mut nodes = Nodes::for_input(range.len());
    nodes.keep_values = opts.keep_values;
    let nodes = RefCell::new(nodes);
    let mut parse = LineParse::new(src, kind, &nodes, range.clone(), first_line, opts.stream);
    // A big file's lines are looked at in parallel first (see `plain_lines`), then taken in
    // step with the loop below.
    let looked = opts
        .stream
        .filter(|_| range.len() >= opts.parallel_look)
        .map(|_| plain_lines(src, range.clone(), 1 << 20));
    let mut looked = looked.iter().flatten().flatten();
    let mut pos = range.start;
    while pos < range.end {
        let hint = looked.next();
        let l = match hint {
            Some(h) => h.raw(src.len()),
            None => split_line(src, pos),
        };
        parse.line(pos, &l, hint);
        pos = l.next.max(pos + 1);
    }
    let parsed = parse.finish();
    let mut nodes = nodes.into_inner();
    nodes.finish();
    SourceFile {
        src: Arc::default(),
        kind,
        body: parsed.body,
        trailing: Span::new(parsed.pending, range.end),
        folds: parsed.folds,
        problems: parsed.problems,
        lines: LineIndex::from_starts(parsed.starts, range.end, first_line),
        nodes,
        runs: parsed.runs,
    }
}

/// A parse under way, fed one line at a time ([`LineParse::line`]): the blocks open, the
/// folds, the lines seen, and with streaming the stretch of plain lines being collected.
struct LineParse<'s> {
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
}

/// What a finished [`LineParse`] gives the file.
struct Parsed {
    body: Vec<Stmt>,
    problems: Vec<Problem>,
    folds: Vec<Fold>,
    starts: Vec<u32>,
    pending: usize,
    runs: Vec<StreamedRun>,
}

impl<'s> LineParse<'s> {
    fn new(
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
        }
    }

    /// Takes the line starting at `pos` (cut as `l`; `hint`: the parallel look at it).
    fn line(&mut self, pos: usize, l: &RawLine, hint: Option<&LookedLine>) {
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
        let src = self.src;
        let text = &src[code.range()];
        let plain = hint.map_or_else(|| looks_plain(text), |h| h.plain) || self.parses_plain(text);
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

    /// Whether a line the quick look declined is plain after all, parsed (its nodes dropped).
    fn parses_plain(&self, text: &[u8]) -> bool {
        let nodes = self.cx.nodes;
        let mark = nodes.borrow().mark();
        let parsed = stmt::line(self.cx, self.kind, text);
        let plain = parsed.is_ok_and(|parsed| is_plain(&parsed, &nodes.borrow(), self.src));
        nodes.borrow_mut().reset(mark);
        plain
    }

    /// A line of code into the tree (parsed; an unreadable line recorded as a problem).
    fn feed(&mut self, code: Span, leading: Span, line: u32, fold: Option<FoldId>) {
        let src = self.src;
        let parsed = match stmt::line(self.cx, self.kind, &src[code.range()]) {
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

    fn finish(mut self) -> Parsed {
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
            pending: self.pending,
            runs: self.runs,
        }
    }
}

/// A `;FOLD` or `;ENDFOLD` line (a run never spans one: folds change what motions mean).
fn fold_marker(comment: &[u8]) -> bool {
    let body = comment[1..].trim_ascii_start();
    [&b"FOLD"[..], b"ENDFOLD"]
        .iter()
        .any(|w| body.len() >= w.len() && body[..w.len()].eq_ignore_ascii_case(w))
}

/// An open block being filled.
struct Frame {
    stmt: Stmt,
    kind: BlockKind,
    /// The file's first routine (its main program).
    main: bool,
}

#[derive(Default)]
struct Builder {
    top: Vec<Stmt>,
    stack: Vec<Frame>,
    problems: Vec<Problem>,
    /// Pages mapped ahead of the statement list being filled (see `memory`).
    ahead: Ahead,
    routines: u32,
    /// Blocks opened beyond [`MAX_BLOCK_DEPTH`], innermost last: kept as opaque lines, not
    /// followed. Their arms and closers are theirs (not strays of the followed blocks), and
    /// only the outermost is warned about.
    deep: Vec<BlockKind>,
}

/// Where a line of code is: its code (`head`), the trivia before it, its number and fold.
#[derive(Clone, Copy)]
struct LineAt {
    leading: Span,
    head: Span,
    line: u32,
    fold: Option<FoldId>,
}

impl LineAt {
    /// The line as a statement of `kind`.
    fn stmt(self, kind: StmtKind) -> Stmt {
        Stmt {
            leading: self.leading,
            head: self.head,
            end: self.head.end,
            line: self.line,
            fold: self.fold,
            kind,
            block: None,
        }
    }

    /// The line as a block's clause (an arm's head, a closer).
    fn clause(self) -> Clause {
        Clause {
            leading: self.leading,
            span: self.head,
            line: self.line,
        }
    }
}

impl Builder {
    /// Directly inside the main routine (where runs may be).
    fn in_main_body(&self) -> bool {
        self.stack.len() == 1
            && self.stack[0].main
            && self.stack[0]
                .stmt
                .block
                .as_ref()
                .is_some_and(|b| b.arms.is_empty())
    }

    fn main_body_len(&self) -> u32 {
        self.stack[0]
            .stmt
            .block
            .as_ref()
            .map_or(0, |b| b.body.len()) as u32
    }

    fn body(&mut self) -> &mut Vec<Stmt> {
        match self.stack.last_mut() {
            None => &mut self.top,
            Some(f) => {
                let b = f.stmt.block.as_mut().expect("frames hold blocks");
                match b.arms.last_mut() {
                    Some(a) => &mut a.body,
                    None => &mut b.body,
                }
            }
        }
    }

    /// Adds a parsed line: a statement to the innermost open block, a block opened, an arm
    /// begun, or a block closed.
    fn feed(&mut self, l: Line, at: LineAt) {
        match l {
            Line::Simple(kind) => {
                let s = at.stmt(kind);
                let mut ahead = self.ahead;
                let body = self.body();
                ahead.before_push(body);
                body.push(s);
                self.ahead = ahead;
            }
            Line::Open(kind, bk) => self.open(kind, bk, at),
            Line::Arm(..) if !self.deep.is_empty() => {
                self.body().push(at.stmt(StmtKind::Opaque));
            }
            Line::Arm(bk, arm) => self.arm(bk, arm, at),
            // Searched from the innermost: the cost is the blocks closed, linear overall.
            Line::Close(bk, _) if self.deep.iter().rev().any(|k| *k == bk) => {
                let open = self.deep.iter().rposition(|k| *k == bk).unwrap_or(0);
                self.deep.truncate(open);
                self.body().push(at.stmt(StmtKind::Opaque));
            }
            Line::Close(bk, until) => self.close(bk, until, at),
        }
    }

    /// Opens a block with statement `at(kind)` (beyond [`MAX_BLOCK_DEPTH`]: kept opaque).
    fn open(&mut self, kind: StmtKind, bk: BlockKind, at: LineAt) {
        if matches!(bk, BlockKind::Routine | BlockKind::DefDat) {
            self.close_all();
        }
        if self.stack.len() >= MAX_BLOCK_DEPTH || !self.deep.is_empty() {
            let s = at.stmt(StmtKind::Opaque);
            if self.deep.is_empty() {
                self.stray(
                    format!("blocks nested more than {MAX_BLOCK_DEPTH} deep: this block is kept as written but not followed"),
                    "split the routine",
                    s,
                );
            } else {
                self.body().push(s);
            }
            self.deep.push(bk);
            return;
        }
        let mut s = at.stmt(kind);
        s.block = Some(Box::default());
        let main = bk == BlockKind::Routine && self.stack.is_empty() && self.routines == 0;
        if bk == BlockKind::Routine {
            self.routines += 1;
        }
        self.stack.push(Frame {
            stmt: s,
            kind: bk,
            main,
        });
    }

    /// Begins an arm (`ELSE`, `CASE`, `DEFAULT`) of the innermost block, if it fits there.
    fn arm(&mut self, bk: BlockKind, arm: ArmKind, at: LineAt) {
        match self.stack.last_mut() {
            Some(f) if f.kind == bk && arm_fits(f, &arm) => {
                let b = f.stmt.block.as_mut().expect("frames hold blocks");
                b.arms.push(Arm {
                    clause: at.clause(),
                    kind: arm,
                    body: Vec::new(),
                });
            }
            _ => self.stray(
                format!("this line belongs inside {} … {}", bk.opener(), bk.closer()),
                "check the block structure around this line",
                at.stmt(StmtKind::Opaque),
            ),
        }
    }

    /// Closes the innermost open block of kind `bk` (those inside it unclosed, with warnings).
    fn close(&mut self, bk: BlockKind, until: Option<Expr>, at: LineAt) {
        // Blocks left open beyond the depth limit end with the followed one closed here.
        self.deep.clear();
        let Some(open) = self.stack.iter().rposition(|f| f.kind == bk) else {
            self.stray(
                format!("`{}` without an open `{}`", bk.closer(), bk.opener()),
                "remove it or add the line that opens the block",
                at.stmt(StmtKind::Opaque),
            );
            return;
        };
        while self.stack.len() > open + 1 {
            self.pop_unclosed();
        }
        let mut f = self.stack.pop().expect("found above");
        if let (StmtKind::Repeat(cond), Some(e)) = (&mut f.stmt.kind, until) {
            *cond = Some(Box::new(e));
        }
        let block = f.stmt.block.as_mut().expect("frames hold blocks");
        block.end = Some(at.clause());
        f.stmt.end = at.head.end;
        trim(block);
        self.body().push(f.stmt);
    }

    /// A line kept as opaque with a warning about the block structure.
    fn stray(&mut self, message: String, help: &'static str, s: Stmt) {
        self.problems.push(Problem::warning(s.head, message, help));
        self.body().push(s);
    }

    /// Closes the innermost block without its closer (a warning says so).
    fn pop_unclosed(&mut self) {
        let mut f = self.stack.pop().expect("caller checked");
        self.problems.push(Problem::warning(
            f.stmt.head,
            format!(
                "`{}` on line {} is never closed (`{}` missing)",
                f.kind.opener(),
                f.stmt.line,
                f.kind.closer()
            ),
            "add the closing line where the block ends",
        ));
        f.stmt.end = last_end(&f.stmt) as u32;
        if let Some(b) = f.stmt.block.as_mut() {
            trim(b);
        }
        self.body().push(f.stmt);
    }

    fn close_all(&mut self) {
        self.deep.clear();
        while !self.stack.is_empty() {
            self.pop_unclosed();
        }
    }

    fn finish(mut self) -> (Vec<Stmt>, Vec<Problem>) {
        self.close_all();
        self.top.shrink_to_fit();
        (self.top, self.problems)
    }
}

/// Gives back the spare capacity of a closed block's statement lists (a routine of a million
/// lines would otherwise keep up to half as much again).
fn trim(b: &mut Block) {
    b.body.shrink_to_fit();
    for a in &mut b.arms {
        a.body.shrink_to_fit();
    }
}

/// `ELSE` once per `IF`, `DEFAULT` once per `SWITCH`, `CASE` not after `DEFAULT`.
fn arm_fits(f: &Frame, arm: &ArmKind) -> bool {
    let arms = &f.stmt.block.as_ref().expect("frames hold blocks").arms;
    let has = |k: fn(&ArmKind) -> bool| arms.iter().any(|a| k(&a.kind));
    match arm {
        ArmKind::Else => !has(|k| matches!(k, ArmKind::Else)),
        ArmKind::Case(_) | ArmKind::Default => !has(|k| matches!(k, ArmKind::Default)),
    }
}

/// End of the last byte of code inside a statement (its head when the block is empty).
fn last_end(s: &Stmt) -> usize {
    let mut end = s.head.end;
    if let Some(b) = &s.block {
        if let Some(last) = b.body.last() {
            end = end.max(last.end);
        }
        for a in &b.arms {
            end = end.max(a.clause.span.end);
            if let Some(last) = a.body.last() {
                end = end.max(last.end);
            }
        }
        if let Some(e) = &b.end {
            end = end.max(e.span.end);
        }
    }
    end as usize
}

/// What a tile of the file is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileKind {
    Trivia,
    Code,
}

impl SourceFile {
    /// `Err` when the file has errors (as [`parse`]).
    pub fn checked(self) -> Result<SourceFile, ParseError> {
        if self.has_errors() {
            Err(ParseError {
                file: Box::new(self),
            })
        } else {
            Ok(self)
        }
    }

    /// The bytes this file's tree covers: the whole source, or a window's lines.
    pub fn extent(&self) -> Span {
        self.lines.extent()
    }

    /// The original bytes, shared (a window shares its file's).
    pub fn shared_source(&self) -> Arc<Vec<u8>> {
        Arc::clone(&self.src)
    }

    /// The original bytes.
    pub fn source(&self) -> &[u8] {
        &self.src
    }

    pub fn kind(&self) -> FileKind {
        self.kind
    }

    /// The bytes of a span.
    pub fn text(&self, span: Span) -> &[u8] {
        &self.src[span.range()]
    }

    /// The text of a span for display (UTF-8 if valid, else one character per byte).
    pub fn text_lossy(&self, span: Span) -> Cow<'_, str> {
        let t = self.text(span);
        match std::str::from_utf8(t) {
            Ok(s) => Cow::Borrowed(s),
            Err(_) => Cow::Owned(t.iter().map(|&b| char::from(b)).collect()),
        }
    }

    /// Whether the text of `span` is `name`, ignoring ASCII case (KRL names are
    /// case-insensitive).
    pub fn is_named(&self, span: Span, name: &str) -> bool {
        self.text(span).eq_ignore_ascii_case(name.as_bytes())
    }

    /// The stretches of the main routine left out of the tree by [`parse_streaming`].
    pub fn streamed_runs(&self) -> &[StreamedRun] {
        &self.runs
    }

    /// One window of a run (`window` from [`StreamedRun::windows`]) parsed into a file of its
    /// own: its statements at top level, the source bytes shared, spans and line numbers as
    /// in the whole file.
    ///
    /// Every statement of a window must be plain (the reason it was left out of the tree);
    /// one that is not, or a line that does not parse, is an error of the window (a bug of
    /// the quick look that chose the run's lines: the caller must not use the window).
    pub fn window(&self, (bytes, first_line): (Span, u32)) -> SourceFile {
        // Walked at once: the plain members' values are kept (`Nodes::member_values`).
        let opts = BuildOptions {
            keep_values: true,
            ..BuildOptions::default()
        };
        let mut w = build_in(&self.src, self.kind, bytes.range(), first_line, opts);
        w.src = Arc::clone(&self.src);
        let strange: Vec<Span> = w
            .body
            .iter()
            .filter(|s| s.block.is_some() || !is_plain_kind(&s.kind, &w.nodes, &w.src))
            .map(|s| s.head)
            .collect();
        for head in strange {
            w.problems.push(Problem::error(
                head,
                "internal error: a line streamed as plain is not (please report this program)",
                "compensate the program with the line changed, e.g. split the run there",
            ));
        }
        w
    }

    /// The top-level statements (header directives, routines, `DEFDAT`, stray lines).
    pub fn body(&self) -> &[Stmt] {
        &self.body
    }

    /// Trivia after the last statement.
    pub fn trailing(&self) -> Span {
        self.trailing
    }

    /// The routines (`DEF`/`DEFFCT` blocks) in order.
    pub fn routines(&self) -> impl Iterator<Item = (&Stmt, &RoutineHeader)> {
        self.body.iter().filter_map(|s| match &s.kind {
            StmtKind::Routine(h) => Some((s, &**h)),
            _ => None,
        })
    }

    /// Every statement, nested ones included, in source order (parents before children).
    pub fn statements(&self) -> Statements<'_> {
        Statements {
            stack: vec![self.body.iter()],
            pending: Vec::new(),
        }
    }

    /// Every motion statement with its motion, in source order.
    pub fn motions(&self) -> impl Iterator<Item = (&Stmt, &Motion)> {
        self.statements()
            .filter_map(|s| s.as_motion().map(|m| (s, self.motion(m))))
    }

    /// The motion of a motion statement.
    pub fn motion(&self, id: MotionId) -> &Motion {
        &self.nodes.motions[id.0 as usize]
    }

    /// The motion of `stmt`, if it is a motion statement.
    pub fn motion_of(&self, stmt: &Stmt) -> Option<&Motion> {
        stmt.as_motion().map(|m| self.motion(m))
    }

    pub fn aggregate(&self, id: AggregateId) -> &Aggregate {
        &self.nodes.aggregates[id.0 as usize]
    }

    /// The aggregate an expression is, if it is one.
    pub fn aggregate_of(&self, e: &Expr) -> Option<&Aggregate> {
        e.as_aggregate().map(|id| self.aggregate(id))
    }

    /// The members of an aggregate, in order, by value.
    pub fn members(&self, a: &Aggregate) -> Members<'_> {
        Members {
            nodes: &self.nodes,
            src: &self.src,
            packed: self.nodes.members_of(a).iter(),
        }
    }

    /// The members of an aggregate as stored: spans, plain numbers not read
    /// ([`RawMember`](super::nodes::RawMember)).
    pub fn raw_members(&self, a: &Aggregate) -> super::nodes::RawMembers<'_> {
        super::nodes::RawMembers {
            nodes: &self.nodes,
            packed: self.nodes.members_of(a).iter(),
            kept: self.nodes.kept_values_of(a).iter(),
        }
    }

    /// A raw member with its value (see [`SourceFile::members`]).
    pub fn member_of<'a>(&'a self, raw: super::nodes::RawMember<'a>) -> Member<'a> {
        self.nodes.member_of_raw(&self.src, raw)
    }

    /// The member called `name` (case-insensitive).
    pub fn member(&self, a: &Aggregate, name: &str) -> Option<Member<'_>> {
        let p = self
            .nodes
            .members_of(a)
            .iter()
            .find(|&&p| self.is_named(self.nodes.member_name(p), name))?;
        Some(self.nodes.member(&self.src, *p))
    }

    /// The `[]` right after an array member's name (`POINT2[] " "`), if any.
    pub fn member_index(&self, m: &Member) -> Option<Span> {
        let at = m.name.end as usize;
        if self.src.get(at) != Some(&b'[') {
            return None;
        }
        let close = self.src[at..].iter().position(|&b| b == b']')?;
        Some(Span::new(at, at + close + 1))
    }

    /// The number of member `name` when it is a plain (possibly signed) literal.
    pub fn member_number(&self, a: &Aggregate, name: &str) -> Option<Number> {
        self.member(a, name)?.value.as_number().copied()
    }

    /// Calls `f` on `e` and every sub-expression (aggregate members included), parents first.
    pub fn visit_expr(&self, e: &Expr, f: &mut impl FnMut(&Expr)) {
        e.visit(&self.nodes, &self.src, f);
    }

    /// Calls `f` on every expression of statement `s` (its own line only, not a block's body)
    /// and their sub-expressions, parents first.
    pub fn visit_stmt_exprs(&self, s: &Stmt, f: &mut impl FnMut(&Expr)) {
        use super::stmt::{Action, Interrupt};
        let mut v = |e: &Expr| self.visit_expr(e, f);
        let action = |a: &Action, v: &mut dyn FnMut(&Expr)| match a {
            Action::Call(e) => v(e),
            Action::Assign(a) => {
                v(&a.lhs);
                v(&a.rhs);
            }
        };
        match &s.kind {
            StmtKind::Decl(d) => d
                .vars
                .iter()
                .filter_map(|x| x.init.as_ref())
                .for_each(&mut v),
            StmtKind::Motion(id) => {
                let m = self.motion(*id);
                v(&m.target);
                if let Some(a) = m.aux() {
                    v(a);
                }
                if let Some(ca) = m.angle() {
                    v(&ca.value);
                }
                for w in m.with() {
                    v(&w.value);
                }
            }
            StmtKind::Spline(h) => h.with.iter().for_each(|w| v(&w.value)),
            StmtKind::Assign(a) => {
                v(&a.lhs);
                v(&a.rhs);
            }
            StmtKind::Call(c) => c.args.iter().flatten().for_each(&mut v),
            StmtKind::If(e)
            | StmtKind::Switch(e)
            | StmtKind::While(e)
            | StmtKind::WaitFor(e)
            | StmtKind::WaitSec(e) => v(e),
            StmtKind::Repeat(Some(e)) | StmtKind::Return(Some(e)) => v(e),
            StmtKind::For(Some(x)) => {
                v(&x.from);
                v(&x.to);
                if let Some(st) = &x.step {
                    v(st);
                }
            }
            StmtKind::Interrupt(i) => {
                if let Interrupt::Decl {
                    cond, action: a, ..
                } = &**i
                {
                    v(cond);
                    action(a, &mut v);
                }
            }
            StmtKind::Trigger(t) => {
                v(&t.value);
                action(&t.action, &mut v);
            }
            StmtKind::Anout(a) => {
                v(&a.signal);
                a.value.iter().for_each(&mut v);
            }
            _ => {}
        }
        if let Some(b) = &s.block {
            for arm in &b.arms {
                if let super::stmt::ArmKind::Case(values) = &arm.kind {
                    values.iter().for_each(&mut v);
                }
            }
        }
    }

    /// The names of the routines the file calls, statements and functions in expressions
    /// alike, in source order (repeats included).
    pub fn called_names(&self) -> Vec<Span> {
        let mut out = Vec::new();
        for st in self.statements() {
            if let StmtKind::Call(c) = &st.kind {
                out.push(c.name);
            }
            self.visit_stmt_exprs(st, &mut |e| {
                if let Expr::Call(c) = e {
                    out.push(c.name);
                }
            });
        }
        out
    }

    /// Every numeric literal in `e`, in source order.
    pub fn numbers(&self, e: &Expr) -> Vec<Number> {
        let mut out = Vec::new();
        self.visit_expr(e, &mut |x| {
            if let Expr::Number(n) = x {
                out.push(*n);
            }
        });
        out
    }

    /// Every declaration statement, in source order.
    pub fn declarations(&self) -> impl Iterator<Item = (&Stmt, &Decl)> {
        self.statements()
            .filter_map(|s| s.as_decl().map(|d| (s, d)))
    }

    /// The fold overlay (index with `FoldId.0`).
    pub fn folds(&self) -> &[Fold] {
        &self.folds
    }

    pub fn fold(&self, id: FoldId) -> &Fold {
        &self.folds[id.0 as usize]
    }

    /// The inline form a statement belongs to: its innermost enclosing fold carrying ILF
    /// parameters (walking out through `Parameters` sub-folds).
    pub fn inline_form(&self, stmt: &Stmt) -> Option<(&Fold, &Ilf)> {
        let mut id = stmt.fold;
        while let Some(i) = id {
            let f = self.fold(i);
            if let Some(ilf) = &f.ilf {
                return Some((f, ilf));
            }
            id = f.parent;
        }
        None
    }

    /// Problems found, errors and warnings, in source order.
    pub fn problems(&self) -> &[Problem] {
        &self.problems
    }

    pub fn has_errors(&self) -> bool {
        self.problems.iter().any(Problem::is_error)
    }

    /// 1-based line and byte column of an offset.
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        self.lines.line_col(offset)
    }

    pub fn line_index(&self) -> &LineIndex {
        &self.lines
    }

    /// A problem as a located diagnostic of file `name`.
    pub fn diagnostic(&self, p: &Problem, name: &str) -> Diagnostic {
        self.diagnostic_at(p.severity, name, p.span, p.message.clone())
            .with_label(p.label)
            .with_help(p.help)
    }

    /// A message about `span` of this file, located through the line index (in time
    /// independent of the file's length).
    pub fn diagnostic_at(
        &self,
        severity: crate::diagnostic::Severity,
        name: &str,
        span: Span,
        message: impl Into<String>,
    ) -> Diagnostic {
        let (line, col) = self.lines.line_col(span.start as usize);
        let line_start = (span.start as usize).saturating_sub(col - 1);
        Diagnostic::at_line(
            severity,
            name,
            &self.src,
            (line, line_start),
            span.range(),
            message,
        )
    }

    /// The file again, byte for byte, from the tree's tiles.
    pub fn emit(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.src.len());
        self.emit_into(&mut out);
        out
    }

    /// Appends the file's bytes, tile by tile, to `out` (adjacent tiles are copied together).
    pub fn emit_into(&self, out: &mut Vec<u8>) {
        let mut run = Span::default();
        let mut ahead = Ahead::default();
        self.for_each_tile(&mut |span, _| {
            if span.start == run.end {
                run.end = span.end;
            } else {
                extend_mapped(out, &mut ahead, &self.src[run.range()]);
                run = span;
            }
        });
        extend_mapped(out, &mut ahead, &self.src[run.range()]);
    }

    /// Every tile (trivia or code) of the file in order; together they cover it exactly.
    pub fn tiles(&self) -> Vec<(Span, TileKind)> {
        let mut v = Vec::new();
        self.for_each_tile(&mut |s, k| v.push((s, k)));
        v
    }

    fn for_each_tile(&self, f: &mut impl FnMut(Span, TileKind)) {
        fn clause(c: &Clause, f: &mut impl FnMut(Span, TileKind)) {
            f(c.leading, TileKind::Trivia);
            f(c.span, TileKind::Code);
        }
        fn stmt(s: &Stmt, f: &mut impl FnMut(Span, TileKind)) {
            f(s.leading, TileKind::Trivia);
            f(s.head, TileKind::Code);
            if let Some(b) = &s.block {
                b.body.iter().for_each(|c| stmt(c, f));
                for a in &b.arms {
                    clause(&a.clause, f);
                    a.body.iter().for_each(|c| stmt(c, f));
                }
                if let Some(e) = &b.end {
                    clause(e, f);
                }
            }
        }
        self.body.iter().for_each(|s| stmt(s, f));
        f(self.trailing, TileKind::Trivia);
    }

    /// Counts for reports.
    pub fn stats(&self) -> Stats {
        let mut st = Stats {
            folds: self.folds.len(),
            inline_forms: self.folds.iter().filter(|f| f.ilf.is_some()).count(),
            errors: self.problems.iter().filter(|p| p.is_error()).count(),
            ..Stats::default()
        };
        st.warnings = self.problems.len() - st.errors;
        let mut position_arrays: Vec<&[u8]> = Vec::new();
        for s in self.statements() {
            st.statements += 1;
            match &s.kind {
                StmtKind::Routine(_) => st.routines += 1,
                StmtKind::Motion(_) => st.motions += 1,
                StmtKind::Invalid => st.invalid += 1,
                StmtKind::Decl(d) if d.ty.kind.is_position() => {
                    for v in &d.vars {
                        if v.dims.is_some() {
                            position_arrays.push(self.text(v.name));
                        } else {
                            st.declared_points += 1;
                        }
                    }
                }
                StmtKind::Assign(a) => {
                    if let Some(p) = a.lhs.as_path() {
                        let root = self.text(p.root);
                        let element =
                            matches!(p.access.as_slice(), [super::expr::Access::Index { .. }]);
                        if element && position_arrays.iter().any(|n| n.eq_ignore_ascii_case(root)) {
                            st.declared_points += 1;
                        }
                    }
                }
                _ => {}
            }
            if s.is_opaque() {
                st.opaque += 1;
            }
        }
        st
    }
}

/// Depth-first iterator over statements (see `SourceFile::statements`).
pub struct Statements<'a> {
    stack: Vec<std::slice::Iter<'a, Stmt>>,
    pending: Vec<std::slice::Iter<'a, Stmt>>,
}

impl<'a> Iterator for Statements<'a> {
    type Item = &'a Stmt;

    fn next(&mut self) -> Option<&'a Stmt> {
        loop {
            let top = self.stack.last_mut()?;
            match top.next() {
                Some(s) => {
                    if let Some(b) = &s.block {
                        // Arms come after the body: push them first (stack order).
                        self.pending.clear();
                        self.pending.push(b.body.iter());
                        for a in &b.arms {
                            self.pending.push(a.body.iter());
                        }
                        while let Some(it) = self.pending.pop() {
                            self.stack.push(it);
                        }
                    }
                    return Some(s);
                }
                None => {
                    self.stack.pop();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Looking at the lines in parallel first changes nothing of a streamed parse: the same
    /// runs and windows, the same tree (emitted byte for byte), the same problems — on a
    /// program with folds, comments, blank lines, non-plain lines between plain ones and a
    /// run cut into windows.
    #[test]
    fn the_parallel_look_parses_alike() {
        let mut text = String::from("DEF p( )\r\n;FOLD INI\r\nBAS(#INITMOV,0)\r\n;ENDFOLD\r\n");
        for i in 0..400 {
            match i % 37 {
                5 => text.push_str("; a comment\r\n\r\n"),
                11 => text.push_str("IF $IN[3] THEN\r\n  LIN {X 1}\r\nENDIF\r\n"),
                23 => text.push_str("$VEL.CP = 0.1\n"),
                _ => text.push_str(&format!("LIN {{X {i}.5,Y -2,Z 3}} C_DIS\r\n")),
            }
        }
        text.push_str("END\r\n");
        let src = text.as_bytes();
        let opts = StreamOptions {
            min_run: 3,
            window: 7,
        };
        let parse = |parallel_look| {
            let opts = BuildOptions {
                stream: Some(opts),
                parallel_look,
                keep_values: false,
            };
            let mut file = build_in(src, FileKind::Src, 0..src.len(), 1, opts);
            file.src = Arc::new(src.to_vec());
            file
        };
        let (plain, looked) = (parse(usize::MAX), parse(0));
        assert!(plain.runs.len() > 5, "{} runs", plain.runs.len());
        assert_eq!(looked.runs, plain.runs);
        assert_eq!(looked.emit(), plain.emit());
        assert_eq!(
            format!("{:?}", looked.problems),
            format!("{:?}", plain.problems)
        );
        assert_eq!(format!("{:?}", looked.body), format!("{:?}", plain.body));
    }

    /// A streamed window keeps its plain members' values as the parser read them, so that
    /// the walk does not read them again: each must be the number read back from the bytes,
    /// to the bit; a whole-file tree keeps none.
    #[test]
    fn windows_keep_the_values_read() {
        let mut text = String::from("DEF p( )\n");
        let numbers = [
            "0",
            "-0.000",
            "+12.5",
            "123456.789012",
            ".5",
            "1E3",
            "-7.",
            "99999999999999999999.5",
            "0.1",
            "-1234.5678",
        ];
        for i in 0..60 {
            let (a, b) = (
                numbers[i % numbers.len()],
                numbers[(i * 7 + 3) % numbers.len()],
            );
            text.push_str(&format!("LIN {{X {a}, Y {b},Z {i}.25, A -{i}.5}} C_DIS\n"));
        }
        text.push_str("END\n");
        let src = text.as_bytes();
        let opts = StreamOptions {
            min_run: 3,
            window: 7,
        };
        let file = parse_streaming(src.to_vec(), FileKind::Src, opts).expect("parses");
        assert!(!file.streamed_runs().is_empty());
        let plain_members = |f: &SourceFile| {
            let mut out = Vec::new();
            for a in f.nodes.aggregates.iter().filter(|a| !a.nested()) {
                for m in f.raw_members(a) {
                    if let super::super::nodes::RawMember::Plain { number, kept, .. } = m {
                        out.push((
                            super::super::nodes::RawMember::plain_value(f.source(), number),
                            kept,
                        ));
                    }
                }
            }
            out
        };
        assert!(plain_members(&file).iter().all(|(_, kept)| kept.is_none()));
        let (mut kept_count, mut windows) = (0, 0);
        for run in file.streamed_runs() {
            for w in run.windows() {
                windows += 1;
                for (read, kept) in plain_members(&file.window(w)) {
                    assert_eq!(kept.map(f64::to_bits), read.map(f64::to_bits));
                    kept_count += 1;
                }
            }
        }
        assert!(
            windows > 5 && kept_count > 150,
            "{windows} windows, {kept_count} kept"
        );
    }
}
