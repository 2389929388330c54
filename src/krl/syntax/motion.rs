//! Motion statements, fully structured: the kind (`PTP`, `LIN`, `CIRC`, their `_REL` forms,
//! the spline motions `SPTP SLIN SCIRC SPL` and their `_REL` forms), the target expression,
//! the auxiliary point and `CA` angle of circular motions, the approximation keywords, the
//! `#BASE`/`#TOOL` frame of relative motions and the `WITH` assignments. Once a line starts
//! with a motion keyword the parser is committed: anything malformed is an error, never
//! silently skipped, because a missed target would be left uncompensated.

use super::expr::{expr, path, Expr};
use super::lex::{expecting, fail, ident, keyword, list, punct, sep, ws, Cx, PResult};
use super::span::Span;

/// Which motion instruction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MotionKind {
    Ptp,
    Lin,
    Circ,
    PtpRel,
    LinRel,
    CircRel,
    Sptp,
    Slin,
    Scirc,
    Spl,
    SptpRel,
    SlinRel,
    ScircRel,
}

impl MotionKind {
    /// The kind named by an (upper-case) keyword.
    pub fn from_keyword(upper: &[u8]) -> Option<MotionKind> {
        use MotionKind::*;
        Some(match upper {
            b"PTP" => Ptp,
            b"LIN" => Lin,
            b"CIRC" => Circ,
            b"PTP_REL" => PtpRel,
            b"LIN_REL" => LinRel,
            b"CIRC_REL" => CircRel,
            b"SPTP" => Sptp,
            b"SLIN" => Slin,
            b"SCIRC" => Scirc,
            b"SPL" => Spl,
            b"SPTP_REL" => SptpRel,
            b"SLIN_REL" => SlinRel,
            b"SCIRC_REL" => ScircRel,
            _ => return None,
        })
    }

    pub fn keyword(self) -> &'static str {
        use MotionKind::*;
        match self {
            Ptp => "PTP",
            Lin => "LIN",
            Circ => "CIRC",
            PtpRel => "PTP_REL",
            LinRel => "LIN_REL",
            CircRel => "CIRC_REL",
            Sptp => "SPTP",
            Slin => "SLIN",
            Scirc => "SCIRC",
            Spl => "SPL",
            SptpRel => "SPTP_REL",
            SlinRel => "SLIN_REL",
            ScircRel => "SCIRC_REL",
        }
    }

    /// Axis-interpolated (the target may be an axis or a Cartesian position).
    pub fn is_joint(self) -> bool {
        use MotionKind::*;
        matches!(self, Ptp | PtpRel | Sptp | SptpRel)
    }

    /// Circular: auxiliary point, target, optional `CA`.
    pub fn is_circular(self) -> bool {
        use MotionKind::*;
        matches!(self, Circ | CircRel | Scirc | ScircRel)
    }

    /// The target is relative to the current position.
    pub fn is_relative(self) -> bool {
        use MotionKind::*;
        matches!(
            self,
            PtpRel | LinRel | CircRel | SptpRel | SlinRel | ScircRel
        )
    }
}

/// A motion statement. Packed into 40 bytes (a CAM program holds a million): the keyword and
/// approximation keywords are stored as start offsets (their length is fixed by their kind),
/// the rare parts (auxiliary point, `CA`, `WITH`, `#BASE`/`#TOOL`) are boxed.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    pub kind: MotionKind,
    /// The target: an aggregate, a variable, an array element, a `:` chain, `$AXIS_ACT`…
    pub target: Expr,
    keyword_start: u32,
    approx: Approxes,
    /// The auxiliary point, `CA`, `WITH` clause and relative frame, when any is written
    /// (boxed: a million-line program of plain `LIN`s should not pay for them).
    extra: Option<Box<MotionExtra>>,
}

#[derive(Clone, Debug, PartialEq, Default)]
struct MotionExtra {
    aux: Option<Expr>,
    angle: Option<CircAngle>,
    with: Vec<WithItem>,
    frame: Option<RelFrame>,
}

impl Motion {
    /// The motion keyword as written (`LIN`, `lin`, `Ptp_Rel`…).
    #[cfg(any(test, feature = "internals"))]
    pub fn keyword(&self) -> Span {
        let start = self.keyword_start;
        Span {
            start,
            end: start + self.kind.keyword().len() as u32,
        }
    }

    /// Approximation keywords in order (`C_DIS C_DIS` gives two).
    #[cfg(any(test, feature = "internals"))]
    pub fn approx(&self) -> Approxes {
        self.approx
    }

    /// `#BASE` or `#TOOL` of a relative motion.
    pub fn frame(&self) -> Option<RelFrame> {
        self.extra.as_ref().and_then(|e| e.frame)
    }

    /// The auxiliary point of a circular motion.
    pub fn aux(&self) -> Option<&Expr> {
        self.extra.as_ref().and_then(|e| e.aux.as_ref())
    }

    /// `CA angle` of a circular motion.
    pub fn angle(&self) -> Option<&CircAngle> {
        self.extra.as_ref().and_then(|e| e.angle.as_ref())
    }

    /// `WITH $VEL.CP = 0.2, …` (empty without a `WITH`).
    pub fn with(&self) -> &[WithItem] {
        self.extra.as_ref().map_or(&[], |e| &e.with)
    }

    /// Whether the motion owns heap memory (see `Expr::owns_heap`).
    pub(crate) fn owns_heap(&self) -> bool {
        self.extra.is_some() || self.target.owns_heap()
    }

    /// A motion with only a target and approximation keywords (no auxiliary point, `CA`,
    /// `WITH` nor relative frame), its keyword starting at `keyword_start`.
    pub(crate) fn simple(
        kind: MotionKind,
        target: Expr,
        keyword_start: u32,
        approx: Approxes,
    ) -> Motion {
        Motion {
            kind,
            target,
            keyword_start,
            approx,
            extra: None,
        }
    }

    /// A circular motion with only its auxiliary point, target and approximation keywords
    /// (no `CA`, `WITH` nor relative frame), as `motion` builds it.
    pub(crate) fn circular(
        kind: MotionKind,
        aux: Expr,
        target: Expr,
        keyword_start: u32,
        approx: Approxes,
    ) -> Motion {
        Motion {
            kind,
            target,
            keyword_start,
            approx,
            extra: Some(Box::new(MotionExtra {
                aux: Some(aux),
                ..MotionExtra::default()
            })),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct CircAngle {
    pub keyword: Span,
    pub value: Expr,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ApproxKind {
    Dis,
    Ptp,
    Vel,
    Ori,
    Spl,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Approx {
    pub kind: ApproxKind,
    pub span: Span,
}

/// Every approximation keyword is five bytes (`C_DIS`, `c_ptp`…).
const APPROX_LEN: u32 = 5;

/// Up to two approximation keywords, packed: their start offsets and, in one byte, the count
/// (bits 0–1) and the kinds (bits 2–4 and 5–7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Approxes {
    starts: [u32; 2],
    packed: u8,
}

impl Approxes {
    pub fn len(&self) -> usize {
        usize::from(self.packed & 3)
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `i`-th keyword.
    #[cfg(any(test, feature = "internals"))]
    pub fn get(&self, i: usize) -> Option<Approx> {
        if i >= self.len() {
            return None;
        }
        let kind = match (self.packed >> (2 + 3 * i)) & 7 {
            0 => ApproxKind::Dis,
            1 => ApproxKind::Ptp,
            2 => ApproxKind::Vel,
            3 => ApproxKind::Ori,
            _ => ApproxKind::Spl,
        };
        let start = self.starts[i];
        Some(Approx {
            kind,
            span: Span {
                start,
                end: start + APPROX_LEN,
            },
        })
    }

    /// The keywords in order.
    #[cfg(any(test, feature = "internals"))]
    pub fn iter(&self) -> impl Iterator<Item = Approx> + '_ {
        (0..self.len()).filter_map(|i| self.get(i))
    }

    /// Adds a keyword; `false` when two are there already.
    pub(crate) fn push(&mut self, a: Approx) -> bool {
        let n = self.len();
        if n == 2 {
            return false;
        }
        debug_assert_eq!(a.span.len() as u32, APPROX_LEN);
        let code = match a.kind {
            ApproxKind::Dis => 0,
            ApproxKind::Ptp => 1,
            ApproxKind::Vel => 2,
            ApproxKind::Ori => 3,
            ApproxKind::Spl => 4,
        };
        self.starts[n] = a.span.start;
        self.packed = (self.packed & !3) | (n as u8 + 1) | (code << (2 + 3 * n));
        true
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RelFrameKind {
    Base,
    Tool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RelFrame {
    pub kind: RelFrameKind,
    pub span: Span,
}

/// One `lhs = value` of a `WITH` clause (motions, `SPLINE … WITH`).
#[derive(Clone, Debug, PartialEq)]
pub struct WithItem {
    pub span: Span,
    /// A variable path (`$VEL_AXIS[1]`, `$APO.CDIS`).
    pub lhs: Expr,
    pub value: Expr,
}

const HELP_TARGET: &str =
    "write the target as a point name, an array element or an aggregate: LIN P1, LIN {X 100, Y 0, Z 500}";
const HELP_TAIL: &str = "after the target may follow CA angle (circular), C_DIS/C_PTP/C_VEL/C_ORI/C_SPL, #BASE/#TOOL (relative) or WITH …";
const HELP_WITH: &str =
    "WITH takes assignments separated by commas: WITH $VEL.CP = 0.2, $APO.CDIS = 5";

/// `KIND [aux ,] target [, CA angle] { approx | #BASE | #TOOL | WITH … }`; `kind` was read
/// from the first word of the line.
pub(crate) fn motion<'a>(cx: Cx<'a>, kind: MotionKind, i: &'a [u8]) -> PResult<'a, Motion> {
    let (j, kw) = ident(i)?;
    let (j, _) = ws(j)?;
    let (mut j, first) =
        expecting!("expected a motion target", HELP_TARGET, |x| expr(cx, 0, x))(j)?;
    let (aux, target) = if kind.is_circular() {
        let (k, _) = ws(j)?;
        let (k, _) = expecting!(
            "a circular motion needs an auxiliary point and a target",
            "write CIRC auxiliary_point, target_point",
            punct(b','),
        )(k)?;
        let (k, _) = ws(k)?;
        let (k, t) = expecting!(
            "expected the target of the circular motion",
            HELP_TARGET,
            |x| expr(cx, 0, x),
        )(k)?;
        j = k;
        (Some(first), t)
    } else {
        (None, first)
    };
    let mut angle = None;
    if kind.is_circular() {
        let (k, _) = ws(j)?;
        if let Ok((k, _)) = punct(b',')(k) {
            let (k, _) = ws(k)?;
            let (k, ca) = expecting!(
                "expected CA after the circular motion's target",
                "the circular angle is written CIRC aux, target, CA 90",
                keyword("CA"),
            )(k)?;
            let (k, _) = ws(k)?;
            let (k, value) = expecting!(
                "expected the circular angle after CA",
                "the circular angle is written CIRC aux, target, CA 90",
                |x| expr(cx, 0, x),
            )(k)?;
            angle = Some(CircAngle {
                keyword: cx.span_of(ca),
                value,
            });
            j = k;
        }
    }
    debug_assert_eq!(kw.len(), kind.keyword().len());
    let mut m = Motion {
        kind,
        target,
        keyword_start: cx.off(kw) as u32,
        approx: Approxes::default(),
        extra: None,
    };
    let mut frame = None;
    let mut with = Vec::new();
    let (rest, ()) = motion_tail(cx, &mut m.approx, &mut frame, &mut with, j)?;
    if aux.is_some() || angle.is_some() || !with.is_empty() || frame.is_some() {
        m.extra = Some(Box::new(MotionExtra {
            aux,
            angle,
            with,
            frame,
        }));
    }
    Ok((rest, m))
}

/// The clauses after a motion's target, in any order, up to the end of the code.
fn motion_tail<'a>(
    cx: Cx<'a>,
    approx: &mut Approxes,
    frame: &mut Option<RelFrame>,
    with: &mut Vec<WithItem>,
    i: &'a [u8],
) -> PResult<'a, ()> {
    let mut j = i;
    loop {
        let (k, _) = ws(j)?;
        if k.is_empty() {
            return Ok((k, ()));
        }
        if k[0] == b'#' {
            let (r, name) =
                ident(&k[1..]).or_else(|_| fail!(k, "expected #BASE or #TOOL", HELP_TAIL))?;
            let kind = if name.eq_ignore_ascii_case(b"BASE") {
                RelFrameKind::Base
            } else if name.eq_ignore_ascii_case(b"TOOL") {
                RelFrameKind::Tool
            } else {
                return fail!(k, "expected #BASE or #TOOL", HELP_TAIL);
            };
            *frame = Some(RelFrame {
                kind,
                span: cx.span(k, r),
            });
            j = r;
            continue;
        }
        if let Ok((r, a)) = approximation(cx, k) {
            if !approx.push(a) {
                return fail!(
                    k,
                    "too many approximation keywords",
                    "a motion takes at most two, e.g. C_DIS C_DIS",
                );
            }
            j = r;
            continue;
        }
        if let Ok((r, _)) = keyword("WITH")(k) {
            let (r, items) = with_clause(cx, r)?;
            with.extend(items);
            j = r;
            continue;
        }
        return fail!(k, "unexpected text after the motion", HELP_TAIL);
    }
}

/// `C_DIS | C_PTP | C_VEL | C_ORI | C_SPL`.
pub(crate) fn approximation<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Approx> {
    let (r, w) = ident(i)?;
    const KINDS: [(&[u8], ApproxKind); 5] = [
        (b"C_DIS", ApproxKind::Dis),
        (b"C_PTP", ApproxKind::Ptp),
        (b"C_VEL", ApproxKind::Vel),
        (b"C_ORI", ApproxKind::Ori),
        (b"C_SPL", ApproxKind::Spl),
    ];
    let Some(&(_, kind)) = KINDS.iter().find(|(k, _)| w.eq_ignore_ascii_case(k)) else {
        return super::lex::backtrack(i);
    };
    Ok((
        r,
        Approx {
            kind,
            span: cx.span_of(w),
        },
    ))
}

/// The assignments after `WITH` (the keyword already read): `item {, item}`.
pub(crate) fn with_clause<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Vec<WithItem>> {
    let (j, _) = sep(i).or_else(|_| fail!(i, "expected an assignment after WITH", HELP_WITH))?;
    list(
        j,
        expecting!("expected an assignment after WITH", HELP_WITH, |x| {
            with_item(cx, x)
        }),
    )
}

/// `path = expr`.
fn with_item<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, WithItem> {
    let (j, lhs) = path(cx, 0, i)?;
    let (j, _) = ws(j)?;
    let (j, _) = punct(b'=')(j)?;
    let (j, _) = ws(j)?;
    let (rest, value) = expecting!("expected a value after `=`", HELP_WITH, |x| expr(cx, 0, x))(j)?;
    Ok((
        rest,
        WithItem {
            span: cx.span(i, rest),
            lhs,
            value,
        },
    ))
}

#[cfg(test)]
mod tests {
    use crate::krl::syntax::{self as krl, ApproxKind, FileKind, RelFrameKind};

    #[test]
    fn packed_keyword_approx_and_frame_spans_are_the_written_text() {
        let src = b"DEF t()\nlin_Rel {X 1} c_dis C_Ptp #tool\nLIN P1\nEND\n";
        let f = krl::parse(src, FileKind::Src).unwrap();
        let ms: Vec<_> = f.motions().map(|(_, m)| m).collect();
        let m = ms[0];
        assert_eq!(f.text(m.keyword()), b"lin_Rel");
        let a = m.approx();
        assert_eq!(a.len(), 2);
        let kinds: Vec<_> = a.iter().map(|x| (x.kind, f.text(x.span))).collect();
        assert_eq!(
            kinds,
            [
                (ApproxKind::Dis, &b"c_dis"[..]),
                (ApproxKind::Ptp, &b"C_Ptp"[..])
            ]
        );
        let fr = m.frame().unwrap();
        assert_eq!(
            (fr.kind, f.text(fr.span)),
            (RelFrameKind::Tool, &b"#tool"[..])
        );
        assert!(a.get(2).is_none());
        assert_eq!(f.text(ms[1].keyword()), b"LIN");
        assert!(ms[1].approx().is_empty() && ms[1].frame().is_none());
        // Every kind code round-trips through the packed byte, in either slot.
        for (w, k) in [
            ("C_VEL", ApproxKind::Vel),
            ("C_ORI", ApproxKind::Ori),
            ("C_SPL", ApproxKind::Spl),
        ] {
            let src = format!("PTP P1 C_DIS {w}\n");
            let f = krl::parse(src.as_bytes(), FileKind::Src).unwrap();
            let (_, m) = f.motions().next().unwrap();
            assert_eq!(m.approx().get(1).unwrap().kind, k);
            assert_eq!(f.text(m.approx().get(1).unwrap().span), w.as_bytes());
        }
    }
}
