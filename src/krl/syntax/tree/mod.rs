//! The lossless syntax tree of one file (`SourceFile`) and how it is built: lines are cut into
//! trivia and code, each line of code is parsed on its own, and a stack of open blocks nests
//! the statements. Every byte of the file is either a statement's code or trivia (a
//! statement's leading trivia, or the file's trailing trivia), so `emit` gives the file back
//! byte for byte. Unbalanced blocks and folds are recovered from with warnings.
//!
//! Here: the file's types and the entry points (whole, recovering, streamed). The steps live
//! beside it: `lines` parses each line (and, streaming, collects the runs of plain lines),
//! `nesting` nests the statements into blocks, `queries` answers what the built tree holds,
//! `output` gives it back (bytes, tiles, diagnostics, counts).

use super::error::{ParseError, Problem};
use super::fold::Fold;
use super::nodes::Nodes;
use super::span::{LineIndex, Span};
use super::stmt::{self, Stmt};
use super::stream::{plain_lines, StreamOptions, StreamedRun};
use super::trivia::split_line;
use std::cell::RefCell;
use std::path::Path;
use std::sync::Arc;

#[cfg(any(test, feature = "internals"))]
mod emit;
mod lines;
mod nesting;
mod output;
mod queries;
#[cfg(test)]
mod tests;

#[cfg(any(test, feature = "internals"))]
pub use emit::TileKind;
use lines::LineParse;
// What only robopost's own tests name through this path.
#[cfg(any(test, feature = "internals"))]
pub use queries::Statements;

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

/// A parsed KRL file: its original bytes, the statements, the fold overlay, the problems.
#[derive(Clone, Debug)]
pub struct SourceFile {
    /// Shared with the windows of its runs.
    src: Arc<Vec<u8>>,
    kind: FileKind,
    body: Vec<Stmt>,
    /// The trivia after the last statement; only emitting the whole tree (tests, fuzz) reads it.
    #[cfg(any(test, feature = "internals"))]
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
            #[cfg(any(test, feature = "internals"))]
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
        #[cfg(any(test, feature = "internals"))]
        trailing: Span::new(parsed.pending, range.end),
        folds: parsed.folds,
        problems: parsed.problems,
        lines: LineIndex::from_starts(parsed.starts, range.end, first_line),
        nodes,
        runs: parsed.runs,
    }
}
