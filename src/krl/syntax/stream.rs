//! Streamed runs: the long straight stretches CAM systems write into a main routine —
//! thousands of motions to literal positions, with comments and speed settings between
//! them — which a caller may process window by window instead of holding a tree of them all.
//! When asked ([`super::parse_streaming`]), the parser leaves such a stretch out of the tree
//! (its bytes become the next statement's leading trivia, so the tree still emits the file
//! byte for byte) and records it as a [`StreamedRun`] cut into windows of whole lines;
//! [`super::SourceFile::window`] parses one window into a file of its own that shares the
//! source bytes, with the spans and line numbers of the whole-file parse. Only lines whose
//! meaning depends on nothing but themselves qualify (see `is_plain`), so the statements of
//! a run can be executed in order without the variables of the routine around them.

use super::expr::Expr;
use super::motion::MotionKind;
use super::nodes::Nodes;
use super::span::Span;
use super::stmt::{Line, StmtKind};
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

/// System variables whose assignment changes the motion (the walker follows them).
const MOVING_SYSTEM_VARIABLES: [&[u8]; 3] = [b"$BASE", b"$TOOL", b"$IPO_MODE"];

/// Whether a parsed line means the same wherever it stands: a `PTP`/`LIN`/`CIRC` (or their
/// `_REL` forms, relative to where the robot is) to literal aggregates (numbers only; no
/// `CA`, `WITH` or `:` chain), an assignment to a system
/// variable that does not move the robot (`$VEL.CP = 0.2`, `$OUT[3] = TRUE`), `WAIT SEC`.
pub(crate) fn is_plain(line: &Line, nodes: &Nodes, src: &[u8]) -> bool {
    match line {
        Line::Simple(kind) => is_plain_kind(kind, nodes, src),
        _ => false,
    }
}

/// [`is_plain`] of a statement's kind.
pub(crate) fn is_plain_kind(kind: &StmtKind, nodes: &Nodes, src: &[u8]) -> bool {
    match kind {
        StmtKind::Motion(id) => {
            let m = &nodes.motions[id.0 as usize];
            use MotionKind::*;
            matches!(m.kind, Ptp | Lin | Circ | PtpRel | LinRel | CircRel)
                && literal(&m.target, nodes)
                && m.aux().map_or(true, |a| literal(a, nodes))
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
fn literal(e: &Expr, nodes: &Nodes) -> bool {
    let Expr::Aggregate(_, id) = e else {
        return false;
    };
    let a = &nodes.aggregates[id.0 as usize];
    nodes
        .members_of(a)
        .iter()
        .all(|&p| nodes.member_is_number(p))
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
/// with its [`looks_plain`] verdict: what [`plain_lines`] hands the sequential pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LookedLine {
    code_start: u32,
    code_end: u32,
    /// The comment's span; empty for none (a comment holds at least its `;`).
    comment: (u32, u32),
    newline: u32,
    pub plain: bool,
}

impl LookedLine {
    fn new(src: &[u8], l: &RawLine) -> LookedLine {
        let (c0, c1) = l.comment.unwrap_or((0, 0));
        LookedLine {
            code_start: l.code_start as u32,
            code_end: l.code_end as u32,
            comment: (c0 as u32, c1 as u32),
            newline: l.newline as u32,
            plain: l.code_start < l.code_end && looks_plain(&src[l.code_start..l.code_end]),
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
/// start) and looked at ([`looks_plain`]), in order, piece by piece: worked in parallel over
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
            while pos < end {
                let l = split_line(src, pos);
                out.push(LookedLine::new(src, &l));
                pos = l.next.max(pos + 1);
            }
            out
        })
        .collect()
}

/// A fast look at a line of code: `true` only for the shapes CAM systems write by the million
/// that surely parse as plain lines — `LIN {X 1.5,Y -2,…} C_DIS` (any of `PTP`/`LIN`/`CIRC`
/// and their `_REL` forms, an optional type before `:`, numbers `[+-]d[.d]`, approximation
/// keywords), `$VEL.CP = 0.2`, `WAIT SEC 1`. Anything else goes to the parser and
/// [`is_plain`]; a window checks every statement again when it is parsed (`SourceFile::window`).
pub(crate) fn looks_plain(code: &[u8]) -> bool {
    let mut s = Scan { b: code, p: 0 };
    if s.b.first() == Some(&b'$') {
        return s.system_assignment();
    }
    let word = s.word();
    if word.eq_ignore_ascii_case(b"WAIT") {
        return s.blanks()
            && s.word().eq_ignore_ascii_case(b"SEC")
            && s.blanks()
            && s.number()
            && s.end();
    }
    let aggregates = match word.len() {
        3 | 4 | 7 | 8 => {
            let kw = match word.len() {
                7 | 8 if word[word.len() - 4..].eq_ignore_ascii_case(b"_REL") => {
                    &word[..word.len() - 4]
                }
                _ => word,
            };
            if kw.eq_ignore_ascii_case(b"LIN") || kw.eq_ignore_ascii_case(b"PTP") {
                1
            } else if kw.eq_ignore_ascii_case(b"CIRC") {
                2
            } else {
                return false;
            }
        }
        _ => return false,
    };
    if !s.blanks() || !s.aggregate() {
        return false;
    }
    if aggregates == 2 {
        s.blanks();
        if !s.eat(b',') {
            return false;
        }
        s.blanks();
        if !s.aggregate() {
            return false;
        }
    }
    loop {
        let had_blank = s.blanks();
        if s.end() {
            return true;
        }
        let w = s.word();
        if !had_blank || !APPROX.iter().any(|a| w.eq_ignore_ascii_case(a)) {
            return false;
        }
    }
}

const APPROX: [&[u8]; 4] = [b"C_DIS", b"C_PTP", b"C_VEL", b"C_ORI"];

struct Scan<'a> {
    b: &'a [u8],
    p: usize,
}

impl Scan<'_> {
    fn peek(&self) -> Option<u8> {
        self.b.get(self.p).copied()
    }

    fn end(&self) -> bool {
        self.p == self.b.len()
    }

    fn eat(&mut self, c: u8) -> bool {
        let yes = self.peek() == Some(c);
        self.p += usize::from(yes);
        yes
    }

    /// Skips spaces and tabs; whether there were any.
    fn blanks(&mut self) -> bool {
        let at = self.p;
        let mut p = at;
        while p < self.b.len() && matches!(self.b[p], b' ' | b'\t') {
            p += 1;
        }
        self.p = p;
        p > at
    }

    /// An identifier (empty when none starts here).
    fn word(&mut self) -> &[u8] {
        let at = self.p;
        let b = self.b;
        if b.get(at)
            .is_some_and(|&c| c.is_ascii_alphabetic() || c == b'_')
        {
            let mut p = at + 1;
            while p < b.len() && is_word(b[p]) {
                p += 1;
            }
            self.p = p;
        }
        &b[at..self.p]
    }

    fn digits(&mut self) -> usize {
        let at = self.p;
        // On a local index: `self.p` stored back once, not at every digit.
        let mut p = at;
        while p < self.b.len() && self.b[p].is_ascii_digit() {
            p += 1;
        }
        self.p = p;
        p - at
    }

    /// `[+-] d+ [. d+]` or `[+-] . d+`, at most 15 digits, not followed by a name character.
    fn number(&mut self) -> bool {
        match number_end(self.b, self.p) {
            Some(end) => {
                self.p = end;
                true
            }
            None => false,
        }
    }

    /// `{ [TYPE:] NAME number {, NAME number} }`.
    fn aggregate(&mut self) -> bool {
        if !self.eat(b'{') {
            return false;
        }
        self.blanks();
        let save = self.p;
        if !self.word().is_empty() {
            self.blanks();
            if self.eat(b':') {
                self.blanks();
            } else {
                self.p = save;
            }
        }
        // The members on a local index: the look's hot loop (a CAM program is made of them).
        let b = self.b;
        let blanks = |mut p: usize| {
            while p < b.len() && matches!(b[p], b' ' | b'\t') {
                p += 1;
            }
            p
        };
        let mut p = self.p;
        loop {
            if p >= b.len() || !(b[p].is_ascii_alphabetic() || b[p] == b'_') {
                return false;
            }
            p += 1;
            while p < b.len() && is_word(b[p]) {
                p += 1;
            }
            let at = blanks(p);
            if at == p {
                return false;
            }
            let Some(end) = number_end(b, at) else {
                return false;
            };
            // The usual next member, right after the number's `,`.
            if b.get(end) == Some(&b',') {
                p = blanks(end + 1);
                continue;
            }
            p = blanks(end);
            match b.get(p) {
                Some(b'}') => {
                    self.p = p + 1;
                    return true;
                }
                Some(b',') => p = blanks(p + 1),
                _ => return false,
            }
        }
    }

    /// `$NAME{.NAME|[d]} = number|TRUE|FALSE` to a system variable that does not move the
    /// robot.
    fn system_assignment(&mut self) -> bool {
        self.p = 1;
        let root = self.word();
        if root.is_empty()
            || MOVING_SYSTEM_VARIABLES
                .iter()
                .any(|v| root.eq_ignore_ascii_case(&v[1..]))
        {
            return false;
        }
        loop {
            if self.eat(b'.') {
                if self.word().is_empty() {
                    return false;
                }
            } else if self.eat(b'[') {
                if self.digits() == 0 || !self.eat(b']') {
                    return false;
                }
            } else {
                break;
            }
        }
        self.blanks();
        if !self.eat(b'=') {
            return false;
        }
        self.blanks();
        let save = self.p;
        let w = self.word();
        if w.eq_ignore_ascii_case(b"TRUE") || w.eq_ignore_ascii_case(b"FALSE") {
            return self.end();
        }
        self.p = save;
        self.number() && self.end()
    }
}

/// Bytes of a name: `A-Z a-z 0-9 _`.
static WORD: [bool; 256] = {
    let mut t = [false; 256];
    let mut b = 0;
    while b < 256 {
        let c = b as u8;
        t[b] = c.is_ascii_alphanumeric() || c == b'_';
        b += 1;
    }
    t
};

/// A byte of a name (one table lookup in the look's loops).
#[inline]
fn is_word(c: u8) -> bool {
    WORD[usize::from(c)]
}

/// Where the number [`Scan::number`] takes at `p` ends: `[+-] d+ [. d+]` or `[+-] . d+`, at
/// most 15 digits, not followed by a name character or a dot.
fn number_end(b: &[u8], mut p: usize) -> Option<usize> {
    if p < b.len() && matches!(b[p], b'+' | b'-') {
        p += 1;
    }
    let digits = |mut p: usize| {
        while p < b.len() && b[p].is_ascii_digit() {
            p += 1;
        }
        p
    };
    let int_end = digits(p);
    let int = int_end - p;
    p = int_end;
    let dot = p < b.len() && b[p] == b'.';
    let frac = if dot {
        let end = digits(p + 1);
        let frac = end - (p + 1);
        p = end;
        frac
    } else {
        0
    };
    let ok = (int > 0 || frac > 0) && int + frac <= 15 && (frac > 0 || !dot);
    let glued = p < b.len() && (is_word(b[p]) || b[p] == b'.');
    (ok && !glued).then_some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::krl::syntax::lex::Cx;
    use crate::krl::syntax::stmt;
    use crate::krl::syntax::tree::FileKind;
    use proptest::prelude::*;
    use std::cell::RefCell;

    /// The parallel look gives each line's `looks_plain`, cut in pieces of any size: CRLF
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
            want.push(l.code_start < l.code_end && looks_plain(&src[l.code_start..l.code_end]));
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

    /// What the parser says of a line: plain or not.
    fn parsed_plain(code: &[u8]) -> bool {
        let nodes = RefCell::new(Nodes::default());
        let cx = Cx::new(code, &nodes);
        match stmt::line(cx, FileKind::Src, code) {
            Ok(l) => is_plain(&l, &nodes.borrow(), code),
            Err(_) => false,
        }
    }

    #[test]
    fn the_quick_look_knows_cam_lines() {
        for yes in [
            "LIN {X 0.000,Y 0.000,Z -1.000,A 0.000,B 94.500,C 0.000} C_DIS",
            "lin {x 1, y -2.5} c_dis C_ORI",
            "PTP {E6AXIS: A1 -12.5,A2 -85,A3 105,A4 0,A5 70,A6 -12.5,E1 0}",
            "CIRC {X 1,Y 2}, {X 3,Y 4}",
            "LIN_REL {Z 5.000} C_DIS",
            "$VEL.CP = 0.080",
            "$OUT[12] = TRUE",
            "WAIT SEC 2.0",
        ] {
            assert!(looks_plain(yes.as_bytes()), "{yes}");
            assert!(parsed_plain(yes.as_bytes()), "{yes}");
        }
        for no in [
            "LIN P1",
            "LIN {X 1} C_DIS C_FOO",
            "LIN {X a}",
            "LIN {X 1E3}",
            "LIN {X 1.}",
            "LIN_REL {Z 5} #TOOL",
            "CIRC {X 1,Y 2}, {X 3,Y 4}, CA 90",
            "$BASE = {X 1}",
            "$TOOL.X = 3",
            "$VEL.CP = speed",
            "LIN {X 1}:{X 2}",
            "SLIN {X 1}",
        ] {
            assert!(!looks_plain(no.as_bytes()), "{no}");
        }
    }

    /// The look's aggregate and number as first written (a cursor stepped byte by byte),
    /// which the scan on a local index must agree with.
    struct Stepped<'a> {
        b: &'a [u8],
        p: usize,
    }

    impl Stepped<'_> {
        fn peek(&self) -> Option<u8> {
            self.b.get(self.p).copied()
        }

        fn eat(&mut self, c: u8) -> bool {
            let yes = self.peek() == Some(c);
            self.p += usize::from(yes);
            yes
        }

        fn blanks(&mut self) -> bool {
            let at = self.p;
            while matches!(self.peek(), Some(b' ' | b'\t')) {
                self.p += 1;
            }
            self.p > at
        }

        fn word(&mut self) -> bool {
            let at = self.p;
            if self
                .peek()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == b'_')
            {
                self.p += 1;
                while self
                    .peek()
                    .is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_')
                {
                    self.p += 1;
                }
            }
            self.p > at
        }

        fn digits(&mut self) -> usize {
            let at = self.p;
            while self.peek().is_some_and(|c| c.is_ascii_digit()) {
                self.p += 1;
            }
            self.p - at
        }

        fn number(&mut self) -> bool {
            if matches!(self.peek(), Some(b'+' | b'-')) {
                self.p += 1;
            }
            let int = self.digits();
            let frac = if self.eat(b'.') { self.digits() } else { 0 };
            let ok = (int > 0 || frac > 0)
                && int + frac <= 15
                && (frac > 0 || self.b[self.p - 1] != b'.');
            ok && !self
                .peek()
                .is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_' || c == b'.')
        }

        fn aggregate(&mut self) -> bool {
            if !self.eat(b'{') {
                return false;
            }
            self.blanks();
            let save = self.p;
            if self.word() {
                self.blanks();
                if self.eat(b':') {
                    self.blanks();
                } else {
                    self.p = save;
                }
            }
            loop {
                if !self.word() || !self.blanks() || !self.number() {
                    return false;
                }
                self.blanks();
                if self.eat(b'}') {
                    return true;
                }
                if !self.eat(b',') {
                    return false;
                }
                self.blanks();
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// The look's aggregate and number take what the byte-stepped cursor takes, and stop
        /// where it stops.
        #[test]
        fn the_scan_is_the_stepped_cursor(
            text in "\\{[ \t]{0,2}([A-Za-z_][A-Za-z0-9_]{0,3}[ ]?:[ ]?)?([A-Za-z_0-9][A-Za-z0-9_]{0,2}[ \t]{0,2}[-+]?[0-9]{0,9}\\.?[0-9]{0,9}[A-Za-z_.]?[ \t]{0,2}[,}]?[ ]?){0,7}[} ]?[A-Z ]{0,3}",
            number in "[ ]?[-+]?[0-9]{0,10}\\.?[0-9]{0,9}[.A-Za-z_ ,}]?",
        ) {
            for (t, is_number) in [(&text, false), (&number, true)] {
                let mut old = Stepped { b: t.as_bytes(), p: 0 };
                let mut new = Scan { b: t.as_bytes(), p: 0 };
                let (a, b) = if is_number {
                    (old.number(), new.number())
                } else {
                    (old.aggregate(), new.aggregate())
                };
                prop_assert_eq!(a, b, "{}", t);
                if a {
                    prop_assert_eq!(old.p, new.p, "{}", t);
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// Never plain by the quick look where the parser says otherwise.
        #[test]
        fn the_quick_look_is_sound(
            line in "(LIN|PTP|CIRC|lin|Ptp_Rel|LIN_REL|WAIT SEC|\\$VEL\\.CP|\\$BASE|\\$OUT\\[1\\])[ \t]{0,2}[=]?[ ]?\\{?[A-Za-z0-9_:, .+\\-]{0,30}\\}?[ ,]{0,2}\\{?[A-Z0-9 ,.\\-]{0,12}\\}?( C_DIS| C_PTP| CA 9| #TOOL)?",
        ) {
            if looks_plain(line.as_bytes()) {
                prop_assert!(parsed_plain(line.as_bytes()), "{line}");
            }
        }
    }
}
