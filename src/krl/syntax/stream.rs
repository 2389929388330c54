//! Streamed runs: the long straight stretches CAM systems write into a main routine —
//! thousands of motions to literal positions, with comments and speed settings between
//! them — which a caller may process window by window instead of holding a tree of them all.
//! When asked ([`super::parse_streaming`]), the parser leaves such a stretch out of the tree
//! (its bytes become the next statement's leading trivia, so the tree still emits the file
//! byte for byte) and records it as a [`StreamedRun`] cut into windows of whole lines;
//! [`super::SourceFile::window`] parses one window into a file of its own that shares the
//! source bytes, with the spans and line numbers of the whole-file parse. Only lines whose
//! meaning depends on nothing but themselves qualify (`plain::streams` decides), so the
//! statements of a run can be executed in order without the variables of the routine around
//! them.

use super::plain::{look, Members};
use super::span::Span;
use super::trivia::{split_line, RawLine};

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
        // A run of a few thousand lines is already worth not holding as a tree. A window is
        // one step of the walk-and-compensate pipeline, and each step waits for its slowest
        // part: windows of 2,048 motions (~0.5 MB of tree, ~1 MB of stops and results) make
        // that wait a small share of the step and still keep the pipeline's start and end
        // short (the sweep of window sizes is in BENCH.md).
        StreamOptions {
            min_run: 2_048,
            window: 2_048,
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

/// One line as `split_line` cuts it, in 32-bit offsets (a streamed file is under 4 GiB),
/// with the verdict of the fast path's look (`plain::look`): what [`plain_lines`] hands the
/// sequential pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LookedLine {
    code_start: u32,
    code_end: u32,
    /// The comment's span; empty for none (a comment holds at least its `;`).
    comment: (u32, u32),
    newline: u32,
    /// The look took the line (else the sequential pass asks the parser).
    pub plain: bool,
}

impl LookedLine {
    fn new(src: &[u8], l: &RawLine, members: &mut Members) -> LookedLine {
        let (c0, c1) = l.comment.unwrap_or((0, 0));
        LookedLine {
            code_start: l.code_start as u32,
            code_end: l.code_end as u32,
            comment: (c0 as u32, c1 as u32),
            newline: l.newline as u32,
            plain: l.code_start < l.code_end
                && look(&src[l.code_start..l.code_end], l.code_start, false, members).is_some(),
        }
    }

    /// The line as `split_line` cuts it from a file of `len` bytes.
    pub fn raw(&self, len: usize) -> RawLine {
        let (c0, c1) = self.comment;
        RawLine {
            code_start: self.code_start as usize,
            code_end: self.code_end as usize,
            comment: (c0 < c1).then_some((c0 as usize, c1 as usize)),
            newline: self.newline as usize,
            next: (self.newline as usize + 1).min(len),
        }
    }
}

/// Every line of `src[range]` cut (as `split_line` cuts them, from `range.start`, a line
/// start) and looked at (`plain::look`), in order, piece by piece: worked in parallel over
/// pieces of about `piece` bytes cut at line starts, so that loading a CAM program does not
/// cut and scan its millions of lines on one core. `src` is under 4 GiB.
pub(crate) fn plain_lines(
    src: &[u8],
    range: std::ops::Range<usize>,
    piece: usize,
) -> Vec<Vec<LookedLine>> {
    use rayon::prelude::*;
    let piece = piece.max(1);
    // Piece starts: the line start at or after each piece's length.
    let mut starts = vec![range.start];
    let mut at = range.start + piece;
    while at < range.end {
        match src[at - 1..range.end].iter().position(|&b| b == b'\n') {
            Some(n) if at + n < range.end => starts.push(at + n),
            _ => break,
        }
        at = *starts.last().expect("pushed") + piece;
    }
    starts.push(range.end);
    starts
        .par_windows(2)
        .map(|w| {
            let (mut pos, end) = (w[0], w[1]);
            let mut out = Vec::with_capacity((end - pos) / 32 + 1);
            let mut members = Members::default();
            while pos < end {
                let l = split_line(src, pos);
                out.push(LookedLine::new(src, &l, &mut members));
                pos = l.next.max(pos + 1);
            }
            out
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parallel look gives each line's `plain::look`, cut in pieces of any size: CRLF
    /// and LF lines, blank and comment lines, a `;` in a string, a last line without a
    /// newline, a BOM.
    #[test]
    fn the_parallel_look_is_the_look_of_each_line() {
        let text = "\u{feff}DEF p( )\r\nLIN {X 1,Y 2} C_DIS\r\n\r\n  ; note\r\nLIN {X 3, Y 4}\n\
                    $VEL.CP = 0.1 ; fast\r\nMSG(\"a;b\")\r\nLIN {X 5}\r\n\n\nWAIT SEC 1\r\nEND";
        let src = text.as_bytes();
        let (mut want, mut cuts) = (Vec::new(), Vec::new());
        let mut pos = 0;
        while pos < src.len() {
            let l = split_line(src, pos);
            let code = &src[l.code_start..l.code_end];
            let mut members = Members::default();
            want.push(!code.is_empty() && look(code, l.code_start, false, &mut members).is_some());
            cuts.push(l);
            pos = l.next.max(pos + 1);
        }
        assert_eq!(want.iter().filter(|&&p| p).count(), 5, "{want:?}");
        assert_eq!(cuts.iter().filter(|l| l.comment.is_some()).count(), 2);
        let flat = |pieces: &[Vec<LookedLine>]| pieces.concat();
        let verdicts = |lines: &[LookedLine]| lines.iter().map(|l| l.plain).collect::<Vec<_>>();
        let cut = |lines: &[LookedLine]| lines.iter().map(|l| l.raw(src.len())).collect::<Vec<_>>();
        for piece in [1, 2, 7, 16, 33, 64, 1 << 20] {
            let lines = flat(&plain_lines(src, 0..src.len(), piece));
            assert_eq!(verdicts(&lines), want, "pieces of {piece}");
            assert_eq!(cut(&lines), cuts, "pieces of {piece}");
        }
        // From a line start inside the text, as a window's parse starts.
        let from = text.find("LIN {X 3").unwrap();
        let skip = text[..from].matches('\n').count();
        for piece in [1, 5, 1 << 20] {
            let lines = flat(&plain_lines(src, from..src.len(), piece));
            assert_eq!(verdicts(&lines), want[skip..]);
            assert_eq!(cut(&lines), cuts[skip..]);
        }
    }
}
