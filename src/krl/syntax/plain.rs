//! The one fast path of the reader, and its one fallback. CAM systems write millions of lines
//! of a few shapes: a motion to literal aggregates (`LIN {X 1.5,Y -2,…} C_DIS`: `PTP`, `LIN`,
//! `CIRC` or their `_REL` forms, approximation keywords after), a setting of a system
//! variable that does not move the robot (`$VEL.CP = 0.2`, `$OUT[3] = TRUE`) and `WAIT SEC 1`.
//! [`look`] recognises these shapes in one pass over a line's bytes, without the grammar's
//! general machinery; a line it does not take, or has any doubt about, goes to the grammar's
//! parser (`stmt::line`), as ripgrep hands a line its literal search cannot decide to the
//! regex engine. The two questions a reader asks of a line are both answered here, the look
//! first and the parser after it:
//!
//! - [`read`]: the line's statement for the tree. A motion the look took is built here into
//!   the very nodes the parser builds for it (its members read into the pool by the parser's own
//!   `expr::plain_member`, so the values are the parser's bit for bit); any other line is the
//!   parser's.
//! - [`streams`]: whether the line may be left to a streamed run (see `stream`): the look's
//!   yes, else the parser's statement judged by [`is_plain_kind`], the definition of a plain
//!   line (parsed into a pool of its own, emptied after).
//!
//! Tests hold the look to the parser: whatever it takes, the parser reads into the same nodes
//! and judges plain. The look is hand-written, not nom combinators: it is the hot path of a
//! CAM program's parse (BENCH.md, "KRL front end").

use super::expr::{self, Aggregate, Expr};
use super::lex::{is_blank, is_ident_char, is_ident_start, Cx};
use super::motion::{Approx, ApproxKind, Approxes, Motion, MotionKind};
use super::nodes::{AggregateId, MotionId, Nodes, Packed};
use super::span::Span;
use super::stmt::{self, Line, LineError, StmtKind};
use super::tree::FileKind;
use std::cell::RefCell;

/// A buffer for the members the look reads when it builds no tree (the parallel pass,
/// `streams`), reused from line to line.
#[derive(Default)]
pub(crate) struct Members {
    packed: Vec<Packed>,
    /// In step with `packed` when values are kept, else empty.
    values: Vec<f64>,
}

/// What the look took a line for.
pub(crate) enum Shape {
    /// A motion to literal aggregates, their members in the look's [`Members`].
    Motion(Seen),
    /// `$VEL.CP = 0.2`, `WAIT SEC 1`: plain; the parser builds its statement.
    Setting,
}

/// A motion as the look read it.
pub(crate) struct Seen {
    kind: MotionKind,
    keyword_start: u32,
    /// The auxiliary point of a circular motion, then the target (the first `count`).
    aggregates: [SeenAggregate; 2],
    count: usize,
    approx: Approxes,
}

/// An aggregate the look read; its `members` start at `first` where the look wrote them.
#[derive(Clone, Copy, Default)]
struct SeenAggregate {
    span: Span,
    type_name: Option<Span>,
    first: u32,
    members: u32,
}

/// The line of `code` (no comment, no surrounding blanks; `base`: where it starts in the
/// source) when it has one of the fast path's shapes, its members (values with `keep`) in
/// `members`; `None` hands the line to the parser.
pub(crate) fn look(code: &[u8], base: usize, keep: bool, members: &mut Members) -> Option<Shape> {
    members.packed.clear();
    members.values.clear();
    look_into(code, base, keep, &mut members.packed, &mut members.values)
}

/// [`look`], the members pushed onto `packed` (and `values` with `keep`); on `None`, both as
/// they were.
fn look_into(
    code: &[u8],
    base: usize,
    keep: bool,
    packed: &mut Vec<Packed>,
    values: &mut Vec<f64>,
) -> Option<Shape> {
    if code.first() == Some(&b'$') {
        return Scan { b: code, p: 0 }
            .system_assignment()
            .then_some(Shape::Setting);
    }
    let end = ident_end(code, 0)?;
    let word = &code[..end];
    if word.eq_ignore_ascii_case(b"WAIT") {
        return Scan { b: code, p: end }
            .wait_sec()
            .then_some(Shape::Setting);
    }
    let kind = motion_keyword(word)?;
    let (n, v) = (packed.len(), values.len());
    let seen = Reader {
        b: code,
        p: end,
        base,
    }
    .motion(kind, keep, packed, values);
    if seen.is_none() {
        packed.truncate(n);
        values.truncate(v);
    }
    seen.map(Shape::Motion)
}

/// The statement of a line of code (a sub-slice of the source): the look's motion built into
/// the pools, or the parser's line.
pub(crate) fn read<'a>(cx: Cx<'a>, file: FileKind, code: &'a [u8]) -> Result<Line, LineError<'a>> {
    let mut guard = cx.nodes.borrow_mut();
    let nodes = &mut *guard;
    let keep = nodes.keep_values;
    // Straight into the pool (a CAM line has a handful of members; more only map later).
    let (packed, values) = nodes.members_for(16);
    match look_into(code, cx.off(code), keep, packed, values) {
        Some(Shape::Motion(seen)) => Ok(build(nodes, &seen)),
        _ => {
            drop(guard);
            stmt::line(cx, file, code)
        }
    }
}

/// Whether the line `code` of `src` may be left to a streamed run: the look's yes (`looked`:
/// its verdict when already taken, as the parallel pass gives it), else whether the parser
/// reads a plain statement ([`is_plain_kind`]), parsed into `scratch` (emptied after).
pub(crate) fn streams(
    src: &[u8],
    file: FileKind,
    code: Span,
    looked: Option<bool>,
    scratch: &RefCell<Nodes>,
    members: &mut Members,
) -> bool {
    let text = &src[code.range()];
    let fast = looked.unwrap_or_else(|| look(text, code.start as usize, false, members).is_some());
    if fast {
        return true;
    }
    let plain = match stmt::line(Cx::new(src, scratch), file, text) {
        Ok(Line::Simple(kind)) => is_plain_kind(&kind, &scratch.borrow(), src),
        _ => false,
    };
    scratch.borrow_mut().clear();
    plain
}

/// The motion the look read (its members already in the pool), into the pools as the parser
/// puts it there.
fn build(nodes: &mut Nodes, seen: &Seen) -> Line {
    nodes.new_line();
    let mut exprs = [None, None];
    for (a, e) in seen.aggregates[..seen.count].iter().zip(&mut exprs) {
        let id = AggregateId(nodes.aggregates.len() as u32);
        nodes.push_aggregate(Aggregate::outermost(
            a.span,
            a.type_name,
            a.first,
            a.members,
        ));
        *e = Some(Expr::Aggregate(a.span, id));
    }
    let motion = match exprs {
        [Some(target), None] => Motion::simple(seen.kind, target, seen.keyword_start, seen.approx),
        [Some(aux), Some(target)] => {
            Motion::circular(seen.kind, aux, target, seen.keyword_start, seen.approx)
        }
        _ => unreachable!("the look reads one aggregate, two for a circular motion"),
    };
    let id = MotionId(nodes.motions.len() as u32);
    nodes.push_motion(motion);
    Line::Simple(StmtKind::Motion(id))
}

/// The motions the look takes: `PTP`, `LIN`, `CIRC` and their `_REL` forms.
fn motion_keyword(word: &[u8]) -> Option<MotionKind> {
    let (kw, rel) = match word.len() {
        7 | 8 if word[word.len() - 4..].eq_ignore_ascii_case(b"_REL") => {
            (&word[..word.len() - 4], true)
        }
        _ => (word, false),
    };
    use MotionKind::*;
    Some(match kw.len() {
        3 if kw.eq_ignore_ascii_case(b"LIN") => [Lin, LinRel][usize::from(rel)],
        3 if kw.eq_ignore_ascii_case(b"PTP") => [Ptp, PtpRel][usize::from(rel)],
        4 if kw.eq_ignore_ascii_case(b"CIRC") => [Circ, CircRel][usize::from(rel)],
        _ => return None,
    })
}

/// Whether a parsed statement means the same wherever it stands: a `PTP`/`LIN`/`CIRC` (or
/// their `_REL` forms, relative to where the robot is) to literal aggregates (numbers only; no
/// `CA`, `WITH` or `:` chain), an assignment to a system variable that does not move the
/// robot (`$VEL.CP = 0.2`, `$OUT[3] = TRUE`), `WAIT SEC`. The definition the look is held to.
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

/// System variables whose assignment changes the motion (the walker follows them).
const MOVING_SYSTEM_VARIABLES: [&[u8]; 3] = [b"$BASE", b"$TOOL", b"$IPO_MODE"];

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

/// The end of the identifier starting at `p`, if one does.
#[inline]
fn ident_end(b: &[u8], p: usize) -> Option<usize> {
    if !is_ident_start(*b.get(p)?) {
        return None;
    }
    Some(p + 1 + b[p + 1..].iter().take_while(|&&c| is_ident_char(c)).count())
}

/// The look at a motion line, after its keyword.
struct Reader<'a> {
    b: &'a [u8],
    /// The position in `b`.
    p: usize,
    /// Where `b` starts in the source.
    base: usize,
}

impl Reader<'_> {
    fn blanks(&mut self) {
        self.p += self.b[self.p..]
            .iter()
            .take_while(|&&c| is_blank(c))
            .count();
    }

    fn span(&self, from: usize, to: usize) -> Span {
        Span::new(self.base + from, self.base + to)
    }

    /// `aggregate [, aggregate] { approximation }` to the end (two aggregates for a circular
    /// motion: its auxiliary point and target).
    fn motion(
        mut self,
        kind: MotionKind,
        keep: bool,
        packed: &mut Vec<Packed>,
        values: &mut Vec<f64>,
    ) -> Option<Seen> {
        let mut seen = Seen {
            kind,
            keyword_start: self.base as u32,
            aggregates: Default::default(),
            count: 0,
            approx: Approxes::default(),
        };
        let count = if kind.is_circular() { 2 } else { 1 };
        while seen.count < count {
            self.blanks();
            if seen.count > 0 {
                if self.b.get(self.p) != Some(&b',') {
                    return None;
                }
                self.p += 1;
                self.blanks();
            }
            seen.aggregates[seen.count] = self.aggregate(keep, packed, values)?;
            seen.count += 1;
        }
        seen.approx = self.approximations()?;
        Some(seen)
    }

    /// `{ [TYPE :] NAME number {, NAME number} }`, its members pushed onto `packed` (and
    /// their values onto `values` with `keep`).
    fn aggregate(
        &mut self,
        keep: bool,
        packed: &mut Vec<Packed>,
        values: &mut Vec<f64>,
    ) -> Option<SeenAggregate> {
        let open = self.p;
        if self.b.get(open) != Some(&b'{') {
            return None;
        }
        self.p += 1;
        self.blanks();
        let type_name = self.type_prefix();
        let first = packed.len();
        loop {
            let (sep, member, value) = expr::plain_member(self.b, self.p, self.base, keep)?;
            packed.push(member);
            if keep {
                values.push(value);
            }
            // At the `,` or `}` `plain_member` found.
            self.p = sep;
            let close = self.b[self.p] == b'}';
            self.p += 1;
            if close {
                break;
            }
            self.blanks();
        }
        // A member given twice is an error: the grammar's parser says so.
        let read = &packed[first..];
        if expr::repeated_name(read, Packed::plain_name, self.b, self.base).is_some() {
            return None;
        }
        Some(SeenAggregate {
            span: self.span(open, self.p),
            type_name,
            first: first as u32,
            members: read.len() as u32,
        })
    }

    /// `TYPE :` before the members, or nothing (the members start where the name did).
    fn type_prefix(&mut self) -> Option<Span> {
        let end = ident_end(self.b, self.p)?;
        let at = self.p;
        self.p = end;
        self.blanks();
        if self.b.get(self.p) == Some(&b':') {
            self.p += 1;
            self.blanks();
            Some(self.span(at, end))
        } else {
            self.p = at;
            None
        }
    }

    /// At most two approximation keywords (`C_DIS`, `C_PTP`, `C_VEL`, `C_ORI`, `C_SPL`) to
    /// the end of the line.
    fn approximations(&mut self) -> Option<Approxes> {
        let mut approx = Approxes::default();
        loop {
            self.blanks();
            if self.p == self.b.len() {
                return Some(approx);
            }
            let end = ident_end(self.b, self.p)?;
            let which = match &self.b[self.p..end] {
                [c, u, a, b, d] if c.eq_ignore_ascii_case(&b'C') && *u == b'_' => {
                    approx_kind([*a, *b, *d])?
                }
                _ => return None,
            };
            if !approx.push(Approx {
                kind: which,
                span: self.span(self.p, end),
            }) {
                return None;
            }
            self.p = end;
        }
    }
}

/// The kind of `C_xyz` from `xyz`.
fn approx_kind(xyz: [u8; 3]) -> Option<ApproxKind> {
    Some(match &xyz.map(|c| c.to_ascii_uppercase()) {
        b"DIS" => ApproxKind::Dis,
        b"PTP" => ApproxKind::Ptp,
        b"VEL" => ApproxKind::Vel,
        b"ORI" => ApproxKind::Ori,
        b"SPL" => ApproxKind::Spl,
        _ => return None,
    })
}

/// The look at a setting: a cursor over its bytes.
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
        while matches!(self.peek(), Some(b' ' | b'\t')) {
            self.p += 1;
        }
        self.p > at
    }

    /// A name of letters, digits and `_` (empty when none starts here).
    fn word(&mut self) -> &[u8] {
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
        &self.b[at..self.p]
    }

    fn digits(&mut self) -> usize {
        let at = self.p;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.p += 1;
        }
        self.p - at
    }

    /// `[+-] d+ [. d+]` or `[+-] . d+`, at most 15 digits, not followed by a name character
    /// or a dot.
    fn number(&mut self) -> bool {
        if matches!(self.peek(), Some(b'+' | b'-')) {
            self.p += 1;
        }
        let int = self.digits();
        let dot = self.eat(b'.');
        let frac = if dot { self.digits() } else { 0 };
        let ok = (int > 0 || frac > 0) && int + frac <= 15 && (frac > 0 || !dot);
        ok && !self
            .peek()
            .is_some_and(|c| c.is_ascii_alphanumeric() || c == b'_' || c == b'.')
    }

    /// After `WAIT`: ` SEC number` to the end.
    fn wait_sec(&mut self) -> bool {
        self.blanks()
            && self.word().eq_ignore_ascii_case(b"SEC")
            && self.blanks()
            && self.number()
            && self.end()
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What a line leaves: the line and the pools, as text (NaN and -0.0 included).
    fn state(line: &Option<Line>, n: &Nodes) -> String {
        format!(
            "{line:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{:?}\n{}",
            n.motions,
            n.aggregates,
            n.members,
            n.member_values
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            n.nested_members,
            n.outline,
            n.scratch,
            n.agg_depth
        )
    }

    /// Reads `code` (placed after `prefix` in the source, so spans are not all from 0) both
    /// ways; `Some(state)` when the look took it as a motion, after checking that the nodes
    /// built equal the parser's and that the parser judges the line plain; `None` when the
    /// look declined it or took it as a setting (then the parser must judge it plain).
    fn both(prefix: &str, code: &str, keep: bool) -> Option<String> {
        let src = format!("{prefix}{code}");
        let code_at = prefix.len();
        let fresh = || {
            let mut n = Nodes::default();
            n.keep_values = keep;
            // A line before, so ids and pool offsets do not start at 0.
            let cell = RefCell::new(n);
            let cx = Cx::new(src.as_bytes(), &cell);
            let before = prefix.trim_end().len();
            if before > 0 {
                assert!(stmt::line(cx, FileKind::Src, &src.as_bytes()[..before]).is_ok());
            }
            cell
        };
        let text = &src.as_bytes()[code_at..];
        let mut members = Members::default();
        let shape = look(text, code_at, keep, &mut members);
        let parser_nodes = fresh();
        let cx = Cx::new(src.as_bytes(), &parser_nodes);
        let parsed = stmt::line(cx, FileKind::Src, text).ok();
        if shape.is_some() {
            let plain = matches!(&parsed, Some(Line::Simple(k))
                if is_plain_kind(k, &parser_nodes.borrow(), src.as_bytes()));
            assert!(
                plain,
                "the look took a line the parser does not judge plain: {code}"
            );
        }
        let Some(Shape::Motion(_)) = shape else {
            return None;
        };
        let direct_nodes = fresh();
        let cx = Cx::new(src.as_bytes(), &direct_nodes);
        let direct = read(cx, FileKind::Src, text).ok();
        let want = state(&parsed, &parser_nodes.borrow());
        let got = state(&direct, &direct_nodes.borrow());
        assert_eq!(got, want, "{code}");
        Some(got)
    }

    #[test]
    fn cam_lines_are_read_as_the_parser_reads_them() {
        for line in [
            "LIN {X 0.000,Y 0.000,Z -1.000,A 0.000,B 94.500,C 0.000} C_DIS",
            "lin {x 1, y -2.5} c_dis C_ORI",
            "PTP {A1 -12.500,A2 -85.000,A3 105.000,A4 0.000,A5 70.000,A6 -12.500,E1 0.000}",
            "PTP {E6AXIS: A1 -12.5,A2 -85,A3 105,A4 0,A5 70,A6 -12.5,E1 0}",
            "LIN_REL {Z 5.000} C_DIS",
            "Ptp_Rel{A1 +1.5 }",
            "LIN {POS : X .5,Y -0,Z 1.}C_VEL c_spl",
            "LIN\t{ X\t1 , Y 2\t}\t",
            "LIN{X 1}",
            "LIN {X 1}C_DIS",
            "CIRC {X 1,Y 2}, {X 3,Y 4}",
            "circ_rel {X 1,Y 2} ,{E6POS: X 3,Y 4} C_DIS C_ORI",
        ] {
            for keep in [false, true] {
                assert!(both("LIN P1\n", line, keep).is_some(), "{line}");
            }
        }
        for line in [
            "LIN P1",
            "LIN {}",
            "LIN {X 1,}",
            "LIN {X 1} C_DIS C_DIS C_DIS",
            "LIN {X 1} C_FOO",
            "LIN {X 1} #TOOL",
            "LIN {X 1}:{X 2}",
            "LIN {X 1} + P1",
            "LIN {X 1E3}",
            "LIN {X a}",
            "LIN {X -(1)}",
            "LIN {X 1, Y {A 1}}",
            "LIN {X 12345678901234567890}",
            "LIN {X 1} WITH $VEL.CP = 1",
            "CIRC {X 1}, {X 2}, CA 90",
            "CIRC {X 1}",
            "CIRC {X 1}, P2",
            "LIN {X 1, x 2}",
            "PTP {A1 1, a1 2}",
            "SLIN {X 1}",
            "LINE {X 1}",
            "$VEL.CP = 0.2",
        ] {
            for keep in [false, true] {
                assert!(both("LIN P1\n", line, keep).is_none(), "{line}");
            }
        }
    }

    /// Every motion line of the fixture programs the look takes is read as the parser reads
    /// it, and it takes the CAM programs' lines.
    #[test]
    fn fixture_lines_are_read_as_the_parser_reads_them() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
        let mut files = vec![dir];
        let (mut taken, mut cam) = (0, 0);
        while let Some(path) = files.pop() {
            if path.is_dir() {
                files.extend(std::fs::read_dir(&path).unwrap().map(|e| e.unwrap().path()));
                continue;
            }
            if !path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("src"))
            {
                continue;
            }
            let text = String::from_utf8_lossy(&std::fs::read(&path).unwrap()).into_owned();
            for l in text.lines() {
                let code = l.split(';').next().unwrap().trim();
                if code.is_empty() {
                    continue;
                }
                let is_cam = code.starts_with("LIN {X ") && code.ends_with("} C_DIS");
                let read = both("", code, true).is_some();
                taken += usize::from(read);
                cam += usize::from(is_cam);
                assert!(read || !is_cam, "{}: {code}", path.display());
            }
        }
        assert!(cam > 1000 && taken >= cam, "{taken} taken, {cam} CAM lines");
    }

    /// What the parser says of a line: plain or not.
    fn parsed_plain(code: &[u8]) -> bool {
        let nodes = RefCell::new(Nodes::default());
        let cx = Cx::new(code, &nodes);
        match stmt::line(cx, FileKind::Src, code) {
            Ok(Line::Simple(k)) => is_plain_kind(&k, &nodes.borrow(), code),
            _ => false,
        }
    }

    fn looks_plain(code: &str) -> bool {
        look(code.as_bytes(), 0, false, &mut Members::default()).is_some()
    }

    #[test]
    fn the_look_knows_cam_lines_and_settings() {
        for yes in [
            "LIN {X 0.000,Y 0.000,Z -1.000,A 0.000,B 94.500,C 0.000} C_DIS",
            "lin {x 1, y -2.5} c_dis C_ORI",
            "PTP {E6AXIS: A1 -12.5,A2 -85,A3 105,A4 0,A5 70,A6 -12.5,E1 0}",
            "CIRC {X 1,Y 2}, {X 3,Y 4}",
            "LIN_REL {Z 5.000} C_DIS",
            "LIN {X 1.}",
            "$VEL.CP = 0.080",
            "$OUT[12] = TRUE",
            "WAIT SEC 2.0",
        ] {
            assert!(looks_plain(yes), "{yes}");
            assert!(parsed_plain(yes.as_bytes()), "{yes}");
        }
        for no in [
            "LIN P1",
            "LIN {X 1} C_DIS C_FOO",
            "LIN {X 1} C_DIS C_DIS C_DIS",
            "LIN {X 1, X 2}",
            "LIN {X a}",
            "LIN {X 1E3}",
            "LIN_REL {Z 5} #TOOL",
            "CIRC {X 1,Y 2}, {X 3,Y 4}, CA 90",
            "$BASE = {X 1}",
            "$TOOL.X = 3",
            "$VEL.CP = speed",
            "LIN {X 1}:{X 2}",
            "SLIN {X 1}",
            "WAIT FOR $IN[1]",
        ] {
            assert!(!looks_plain(no), "{no}");
        }
        // Plain by the parser's word, which the look leaves to it.
        for fallback in ["$VEL.CP = speed", "LIN {X 1E3}", "LIN {}"] {
            assert!(parsed_plain(fallback.as_bytes()), "{fallback}");
        }
    }

    /// The fallback answers for the lines the look declines, and leaves its pool empty.
    #[test]
    fn streams_asks_the_parser_after_the_look() {
        let src = b"LIN {X 1E3}\nLIN P1\nLIN {X 1} C_DIS C_DIS C_DIS\n$VEL.CP = v\nLIN {X 1}\n";
        let scratch = RefCell::new(Nodes::default());
        let mut members = Members::default();
        let mut verdicts = Vec::new();
        let mut at = 0;
        for line in src.split(|&b| b == b'\n').filter(|l| !l.is_empty()) {
            let code = Span::new(at, at + line.len());
            at += line.len() + 1;
            verdicts.push(streams(
                src,
                FileKind::Src,
                code,
                None,
                &scratch,
                &mut members,
            ));
            assert!(scratch.borrow().motions.is_empty() && scratch.borrow().members.is_empty());
        }
        assert_eq!(verdicts, [true, false, false, true, true]);
        // A verdict already taken is not taken again: `Some(true)` is the look's yes.
        let code = Span::new(12, 18);
        assert!(streams(
            src,
            FileKind::Src,
            code,
            Some(true),
            &scratch,
            &mut members
        ));
        assert!(!streams(
            src,
            FileKind::Src,
            code,
            Some(false),
            &scratch,
            &mut members
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// Never plain by the look where the parser says otherwise (settings included).
        #[test]
        fn the_look_is_sound(
            line in "(LIN|PTP|CIRC|lin|Ptp_Rel|LIN_REL|WAIT SEC|\\$VEL\\.CP|\\$BASE|\\$OUT\\[1\\])[ \t]{0,2}[=]?[ ]?\\{?[A-Za-z0-9_:, .+\\-]{0,30}\\}?[ ,]{0,2}\\{?[A-Z0-9 ,.\\-]{0,12}\\}?( C_DIS| C_PTP| CA 9| #TOOL)?",
        ) {
            if looks_plain(&line) {
                prop_assert!(parsed_plain(line.as_bytes()), "{line}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Random lines near the plain shape: whatever the reader takes, it reads as the
        /// parser does (and a good share it takes).
        #[test]
        fn the_look_builds_what_the_parser_builds(
            kw in prop_oneof![8 => "(LIN|PTP|lin|Ptp_Rel|LIN_REL)", 1 => "(LINX|SLIN|CIRC)"],
            circ in prop_oneof![3 => "", 1 => "(CIRC|Circ_Rel) \\{X 1,Y 2\\}[ ]?,[ ]?"],
            gap in "[ \t]{0,2}",
            ty in "(E6POS[ ]?:[ ]?|POS:|)",
            members in prop::collection::vec(
                (
                    "[A-Za-z][A-Za-z0-9_]{0,2}",
                    prop_oneof![9 => "[ \t]{1,2}", 1 => ""],
                    prop_oneof![
                        8 => "[-+]?[0-9]{1,4}(\\.[0-9]{0,4})?",
                        1 => "[-+]?\\.[0-9]{0,3}",
                        1 => "([-+]?[0-9]{15,21}|A|\\(1\\)|1E3|1\\.5e2|-)",
                    ],
                    "[ ]{0,1}",
                ),
                0..8,
            ),
            sep in prop_oneof![8 => "(,|, | ,)", 1 => "(,,|;)"],
            tail in prop_oneof![
                6 => "(| C_DIS| c_ptp C_ORI|C_VEL| C_SPL)",
                1 => "( C_DIS C_DIS C_DIS| C_FOO| #TOOL| :P1| AND 1| C_DISX)",
            ],
            keep in any::<bool>(),
        ) {
            let body: Vec<String> = members
                .iter()
                .map(|(n, g, v, after)| format!("{n}{g}{v}{after}"))
                .collect();
            let line = if circ.is_empty() {
                format!("{kw}{gap}{{{ty}{}}}{tail}", body.join(&sep))
            } else {
                format!("{circ}{{{ty}{}}}{tail}", body.join(&sep))
            };
            let line = line.trim_end();
            both("PTP {A1 0}\n", line, keep);
        }
    }
}
