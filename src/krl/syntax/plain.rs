//! The line CAM systems write by the million, `LIN {X 1.5,Y -2,…} C_DIS`, read directly:
//! a `PTP`/`LIN` (or `_REL` form) to an aggregate of `NAME number` members followed by
//! approximation keywords. [`motion_line`] builds the very nodes the grammar's parser
//! (`stmt::line`) builds for such a line, in one pass over its bytes without the general
//! expression machinery; any other line (or any doubt) is left to that parser. It reads
//! numbers with the parser's own functions, so the values are the parser's bit for bit.

use super::expr::{Aggregate, Expr};
use super::lex::{is_blank, is_ident_char, is_ident_start, Cx};
use super::motion::{Approx, ApproxKind, Approxes, Motion, MotionKind};
use super::nodes::{AggregateId, MotionId, Packed};
use super::number;
use super::span::Span;
use super::stmt::{Line, StmtKind};

/// The line of `code` (a sub-slice of the source, no comment, no surrounding blanks) as
/// `stmt::line` reads it, when it is a plain motion; `None` (the pools untouched) otherwise.
pub(crate) fn motion_line(cx: Cx<'_>, code: &[u8]) -> Option<Line> {
    let kind = keyword(code)?;
    let base = cx.off(code);
    let mut guard = cx.nodes.borrow_mut();
    let nodes = &mut *guard;
    nodes.new_line();
    let mark = nodes.mark();
    let read = Reader {
        b: code,
        p: kind.keyword().len(),
        base,
    }
    .motion(nodes, kind);
    match read {
        Some(motion) => {
            let id = MotionId(nodes.motions.len() as u32);
            nodes.push_motion(motion);
            Some(Line::Simple(StmtKind::Motion(id)))
        }
        None => {
            nodes.reset(mark);
            None
        }
    }
}

/// The motion a line starts with, when it is one of the four the reader takes.
fn keyword(code: &[u8]) -> Option<MotionKind> {
    let end = ident_end(code, 0)?;
    let (word, rel) = match end {
        3 => (&code[..3], false),
        7 if code[3..7].eq_ignore_ascii_case(b"_REL") => (&code[..3], true),
        _ => return None,
    };
    Some(
        match (
            word.eq_ignore_ascii_case(b"LIN"),
            word.eq_ignore_ascii_case(b"PTP"),
        ) {
            (true, _) if rel => MotionKind::LinRel,
            (true, _) => MotionKind::Lin,
            (_, true) if rel => MotionKind::PtpRel,
            (_, true) => MotionKind::Ptp,
            _ => return None,
        },
    )
}

/// The end of the identifier starting at `p`, if one does.
#[inline]
fn ident_end(b: &[u8], p: usize) -> Option<usize> {
    if !is_ident_start(*b.get(p)?) {
        return None;
    }
    Some(p + 1 + b[p + 1..].iter().take_while(|&&c| is_ident_char(c)).count())
}

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

    /// After the keyword: `{ [TYPE :] member {, member} } { approximation }`, to the end.
    fn motion(mut self, nodes: &mut super::nodes::Nodes, kind: MotionKind) -> Option<Motion> {
        self.blanks();
        let open = self.p;
        if self.b.get(open) != Some(&b'{') {
            return None;
        }
        self.p += 1;
        self.blanks();
        let type_name = self.type_prefix();
        let first = nodes.members.len();
        self.members(nodes)?;
        // A member given twice is an error: the grammar's parser says so.
        let members = &nodes.members[first..];
        if super::expr::repeated_name(nodes, members, self.b, self.base).is_some() {
            return None;
        }
        let span = self.span(open, self.p);
        let len = (nodes.members.len() - first) as u32;
        let id = AggregateId(nodes.aggregates.len() as u32);
        nodes.push_aggregate(Aggregate::outermost(span, type_name, first as u32, len));
        let approx = self.approximations()?;
        Some(Motion::simple(
            kind,
            Expr::Aggregate(span, id),
            self.base as u32,
            approx,
        ))
    }

    /// `TYPE :` before the members, or nothing (the members start where the name did).
    fn type_prefix(&mut self) -> Option<Span> {
        let end = ident_end(self.b, self.p)?;
        let (name, at) = (self.p, self.p);
        self.p = end;
        self.blanks();
        if self.b.get(self.p) == Some(&b':') {
            self.p += 1;
            self.blanks();
            Some(self.span(name, end))
        } else {
            self.p = at;
            None
        }
    }

    /// The `NAME number` members up to and including the closing brace, pushed to `nodes`; on
    /// a local index, as this is the hot loop of a CAM program's parse.
    fn members(&mut self, nodes: &mut super::nodes::Nodes) -> Option<()> {
        let keep = nodes.keep_values;
        let (b, base) = (self.b, self.base);
        let blanks = |mut p: usize| {
            while p < b.len() && is_blank(b[p]) {
                p += 1;
            }
            p
        };
        let mut p = self.p;
        loop {
            let name = p;
            if p >= b.len() || !is_ident_start(b[p]) {
                return None;
            }
            p += 1;
            while p < b.len() && is_ident_char(b[p]) {
                p += 1;
            }
            let name_end = p;
            let at = blanks(p);
            let rest = &b[at..];
            let (len, value) = if keep {
                let (len, value, _) = number::read_plain(rest)?;
                (len, value)
            } else {
                (number::plain_len(rest)?, 0.0)
            };
            p = blanks(at + len);
            let close = match b.get(p) {
                Some(b',') => false,
                Some(b'}') => true,
                _ => return None,
            };
            let packed = Packed::plain(
                Span::new(base + name, base + name_end),
                Span::new(base + at, base + at + len),
            )?;
            nodes.push_member(packed, value);
            p += 1;
            if close {
                break;
            }
            p = blanks(p);
        }
        self.p = p;
        Some(())
    }

    /// The approximation keywords (`C_DIS`, `C_PTP`, `C_VEL`, `C_ORI`) to the end of the line.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::krl::syntax::nodes::Nodes;
    use crate::krl::syntax::stmt;
    use crate::krl::syntax::tree::FileKind;
    use proptest::prelude::*;
    use std::cell::RefCell;

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
    /// ways; `Some(state)` when the direct reader took it, after checking it equals the
    /// parser's; when it declined, checks it left the pools as they were.
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
        let direct_nodes = fresh();
        let before = state(&None, &direct_nodes.borrow());
        let cx = Cx::new(src.as_bytes(), &direct_nodes);
        let direct = motion_line(cx, &src.as_bytes()[code_at..]);
        if direct.is_none() {
            assert_eq!(state(&None, &direct_nodes.borrow()), before, "{code}");
            return None;
        }
        let parser_nodes = fresh();
        let cx = Cx::new(src.as_bytes(), &parser_nodes);
        let parsed = stmt::line(cx, FileKind::Src, &src.as_bytes()[code_at..]).ok();
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
            "CIRC {X 1}, {X 2}",
            "SLIN {X 1}",
            "LINE {X 1}",
            "$VEL.CP = 0.2",
        ] {
            for keep in [false, true] {
                assert!(both("LIN P1\n", line, keep).is_none(), "{line}");
            }
        }
    }

    /// Every motion line of the fixture programs the reader takes is read as the parser reads
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

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4000))]
        /// Random lines near the plain shape: whatever the reader takes, it reads as the
        /// parser does (and a good share it takes).
        #[test]
        fn the_direct_reader_is_the_parser(
            kw in prop_oneof![8 => "(LIN|PTP|lin|Ptp_Rel|LIN_REL)", 1 => "(CIRC|LINX|SLIN)"],
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
            let line = format!("{kw}{gap}{{{ty}{}}}{tail}", body.join(&sep));
            let line = line.trim_end();
            both("PTP {A1 0}\n", line, keep);
        }
    }
}
