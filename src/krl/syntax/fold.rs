//! Folds: `;FOLD … ;ENDFOLD` comment pairs, nested, kept verbatim as trivia, and described by
//! an overlay (`Fold`) that every statement points into. Inline forms (ILF) written by the
//! teach pendant carry their parameters twice — in the fold title (`PTP P1 CONT Vel=100 %
//! PDAT1 Tool[1] Base[0]`) and in the `%P 1:PTP, 2:P1, …` list (KSS 8.5+ spline forms in a
//! nested `;FOLD Parameters ;%{h}` with a `;Params Kuka.PointName=P1; …` line); both are
//! exposed so the motion simulator can resolve the point, motion data and frames through the
//! `.dat` (`X<point>`, `F<point>`, `P<data>` / `L<data>`, KUKA's naming).

use super::error::Problem;
use super::lex::Cx;
use super::motion::MotionKind;
use super::number;
use super::span::Span;

/// Index of a fold in `SourceFile::folds()`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FoldId(pub u32);

/// One `;FOLD` … `;ENDFOLD` pair.
#[derive(Clone, Debug, PartialEq)]
pub struct Fold {
    /// The `;FOLD …` comment (without the line ending).
    pub open: Span,
    pub open_line: u32,
    /// The `;ENDFOLD …` comment, if the fold is closed.
    pub close: Option<Span>,
    pub close_line: Option<u32>,
    pub parent: Option<FoldId>,
    /// The text after `;FOLD` up to `;%{…}` (what the editor shows).
    pub title: Span,
    pub ilf: Option<Ilf>,
}

/// Parameters of an inline form.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Ilf {
    /// `%{PE}%R …` — everything after the title.
    pub meta: Span,
    /// `%M` (`KUKATPBASIS`), `%C` (`MOVE`), `%V` (`PTP`).
    pub module: Option<Span>,
    pub command: Option<Span>,
    pub variant: Option<Span>,
    /// `%P` items `n:value` (values may be empty).
    pub params: Vec<(u32, Span)>,
    /// `key=value` pairs of a nested `Parameters` fold (`Kuka.PointName=P1`).
    pub settings: Vec<(Span, Span)>,
    /// The motion described by the title, if it is a motion form.
    pub motion: Option<IlfMotion>,
}

/// A motion inline form, as read from its title.
#[derive(Clone, Debug, PartialEq)]
pub struct IlfMotion {
    pub kind: MotionKind,
    /// Point names (`P1`; auxiliary and target for circular motions).
    pub points: Vec<Span>,
    /// `CONT` (approximated).
    pub cont: Option<Span>,
    pub velocity: Option<IlfVelocity>,
    /// Motion data set (`PDAT1`, `CPDAT1`).
    pub data: Option<Span>,
    pub tool: Option<IlfFrame>,
    pub base: Option<IlfFrame>,
}

/// `Vel=100 %`, `Vel= 2 m/s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IlfVelocity {
    pub value: f64,
    pub span: Span,
    pub unit: Option<Span>,
}

/// `Tool[1]`, `Base[2]:table`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IlfFrame {
    pub span: Span,
    pub index: Option<i64>,
    pub name: Option<Span>,
}

impl IlfMotion {
    /// Name of the position variable of point `k` in the `.dat`: `X` + point name.
    #[cfg(any(test, feature = "internals"))]
    pub fn position_var(&self, src: &[u8], k: usize) -> Option<Vec<u8>> {
        self.points.get(k).map(|p| prefixed(b"X", &src[p.range()]))
    }

    /// Name of the frame data (`FDAT`) of the target point: `F` + point name.
    #[cfg(any(test, feature = "internals"))]
    pub fn frame_data_var(&self, src: &[u8]) -> Option<Vec<u8>> {
        self.points.last().map(|p| prefixed(b"F", &src[p.range()]))
    }

    /// Name of the motion data: `P` + data set (`PDAT`) for PTP forms, `L` + data set (`LDAT`)
    /// for path forms.
    #[cfg(any(test, feature = "internals"))]
    pub fn motion_data_var(&self, src: &[u8]) -> Option<Vec<u8>> {
        let prefix: &[u8] = if self.kind.is_joint() { b"P" } else { b"L" };
        self.data.map(|d| prefixed(prefix, &src[d.range()]))
    }
}

impl Ilf {
    /// The `%P` parameter `n`.
    #[cfg(any(test, feature = "internals"))]
    pub fn param(&self, n: u32) -> Option<Span> {
        self.params.iter().find(|(k, _)| *k == n).map(|(_, s)| *s)
    }

    /// The value of setting `key` (case-insensitive) of the nested `Parameters` fold.
    #[cfg(any(test, feature = "internals"))]
    pub fn setting<'s>(&self, src: &'s [u8], key: &str) -> Option<&'s [u8]> {
        self.settings
            .iter()
            .find(|(k, _)| src[k.range()].eq_ignore_ascii_case(key.as_bytes()))
            .map(|(_, v)| &src[v.range()])
    }
}

#[cfg(any(test, feature = "internals"))]
fn prefixed(p: &[u8], name: &[u8]) -> Vec<u8> {
    let mut v = p.to_vec();
    v.extend_from_slice(name);
    v
}

/// Builds the fold overlay while the lines are read.
#[derive(Default)]
pub(crate) struct FoldTracker {
    pub folds: Vec<Fold>,
    stack: Vec<FoldId>,
    pub problems: Vec<Problem>,
}

fn starts_word(text: &[u8], word: &[u8]) -> bool {
    text.len() >= word.len()
        && text[..word.len()].eq_ignore_ascii_case(word)
        && !text
            .get(word.len())
            .is_some_and(|&b| super::lex::is_ident_char(b))
}

impl FoldTracker {
    /// The innermost open fold.
    pub fn current(&self) -> Option<FoldId> {
        self.stack.last().copied()
    }

    /// A comment that is alone on its line (`comment` starts with `;`).
    pub fn comment_line(&mut self, cx: Cx<'_>, comment: &[u8], line: u32) {
        // `; FOLD` with blanks after the `;`, as system files write it.
        let body = &comment[1 + super::lex::blanks(&comment[1..])..];
        if starts_word(body, b"FOLD") {
            let id = FoldId(self.folds.len() as u32);
            let fold = parse_fold(cx, comment, line, self.current());
            self.folds.push(fold);
            self.stack.push(id);
        } else if starts_word(body, b"ENDFOLD") {
            match self.stack.pop() {
                Some(id) => {
                    let f = &mut self.folds[id.0 as usize];
                    f.close = Some(cx.span_of(comment));
                    f.close_line = Some(line);
                }
                None => self.problems.push(Problem::warning(
                    cx.span_of(comment),
                    "`;ENDFOLD` without an open `;FOLD`",
                    "remove it or add the matching ;FOLD line",
                )),
            }
        } else if let Some(id) = self.current() {
            self.settings_line(cx, id, comment);
        }
    }

    /// `;Params k=v; k2=v2` lines of a nested `Parameters` fold feed its parent's ILF.
    fn settings_line(&mut self, cx: Cx<'_>, id: FoldId, comment: &[u8]) {
        let fold = &self.folds[id.0 as usize];
        let title = cx_slice(cx, fold.title);
        let Some(parent) = fold.parent else { return };
        if !title.eq_ignore_ascii_case(b"Parameters") {
            return;
        }
        let Some(ilf) = self.folds[parent.0 as usize].ilf.as_mut() else {
            return;
        };
        let mut text = &comment[1..];
        if starts_word(text, b"Params") {
            text = &text[6..];
        }
        for item in text.split(|&b| b == b';') {
            let Some(eq) = item.iter().position(|&b| b == b'=') else {
                continue;
            };
            let key = trim(&item[..eq]);
            let value = trim(&item[eq + 1..]);
            if !key.is_empty() {
                ilf.settings.push((cx.span_of(key), cx.span_of(value)));
            }
        }
    }

    /// Closes the bookkeeping at the end of the file.
    pub fn finish(mut self) -> (Vec<Fold>, Vec<Problem>) {
        for id in self.stack.drain(..) {
            let f = &self.folds[id.0 as usize];
            self.problems.push(Problem::warning(
                f.open,
                format!("`;FOLD` opened on line {} is never closed", f.open_line),
                "add ;ENDFOLD where the fold ends",
            ));
        }
        (self.folds, self.problems)
    }
}

fn cx_slice<'a>(cx: Cx<'a>, s: Span) -> &'a [u8] {
    &cx.base()[s.range()]
}

fn trim(s: &[u8]) -> &[u8] {
    let a = s.iter().take_while(|b| b.is_ascii_whitespace()).count();
    let b = s[a..]
        .iter()
        .rev()
        .take_while(|b| b.is_ascii_whitespace())
        .count();
    &s[a..s.len() - b]
}

/// Reads a `;FOLD` comment: title, ILF meta data, motion parameters.
fn parse_fold(cx: Cx<'_>, comment: &[u8], line: u32, parent: Option<FoldId>) -> Fold {
    let rest = &comment[5 + super::lex::blanks(&comment[1..])..];
    let meta_at = rest.windows(2).position(|w| w == b";%");
    let title = trim(&rest[..meta_at.unwrap_or(rest.len())]);
    let ilf = meta_at.and_then(|p| {
        let meta = &rest[p + 1..];
        // `%{h}` marks a hidden helper fold (the `Parameters` of spline forms), not a form.
        (meta.starts_with(b"%{") && !meta.starts_with(b"%{h}")).then(|| parse_ilf(cx, title, meta))
    });
    Fold {
        open: cx.span_of(comment),
        open_line: line,
        close: None,
        close_line: None,
        parent,
        title: cx.span_of(title),
        ilf,
    }
}

/// `%{PE}%R 8.3.43,%MKUKATPBASIS,%CMOVE,%VPTP,%P 1:PTP, 2:P1, 3:, 5:100, 7:PDAT1`.
fn parse_ilf(cx: Cx<'_>, title: &[u8], meta: &[u8]) -> Ilf {
    let mut ilf = Ilf {
        meta: cx.span_of(meta),
        ..Ilf::default()
    };
    // Items start at a `%` at the beginning, after `}` or after `,`.
    let starts: Vec<usize> = (0..meta.len())
        .filter(|&k| meta[k] == b'%' && (k == 0 || matches!(meta[k - 1], b'}' | b',')))
        .collect();
    for (n, &s) in starts.iter().enumerate() {
        let end = starts.get(n + 1).map_or(meta.len(), |&e| e);
        let item = &meta[s + 1..end];
        let item = item.strip_suffix(b",").unwrap_or(item);
        let Some((&letter, value)) = item.split_first() else {
            continue;
        };
        let value = trim(value);
        match letter {
            b'M' => ilf.module = Some(cx.span_of(value)),
            b'C' => ilf.command = Some(cx.span_of(value)),
            b'V' => ilf.variant = Some(cx.span_of(value)),
            b'P' => ilf.params = parse_params(cx, value),
            _ => {}
        }
    }
    ilf.motion = parse_title_motion(cx, title);
    ilf
}

/// `1:PTP, 2:P1, 3:, 5:100` — an item ends at a comma followed by `digits:`.
fn parse_params(cx: Cx<'_>, text: &[u8]) -> Vec<(u32, Span)> {
    let mut out = Vec::new();
    let mut items = Vec::new();
    let mut start = 0;
    for k in 0..text.len() {
        if text[k] == b',' {
            let after = trim(&text[k + 1..]);
            let d = after.iter().take_while(|b| b.is_ascii_digit()).count();
            if d > 0 && after.get(d) == Some(&b':') {
                items.push(&text[start..k]);
                start = k + 1;
            }
        }
    }
    items.push(&text[start..]);
    for item in items {
        let item = trim(item);
        let d = item.iter().take_while(|b| b.is_ascii_digit()).count();
        if d == 0 || item.get(d) != Some(&b':') {
            continue;
        }
        let n = std::str::from_utf8(&item[..d])
            .ok()
            .and_then(|s| s.parse().ok());
        if let Some(n) = n {
            out.push((n, cx.span_of(trim(&item[d + 1..]))));
        }
    }
    out
}

/// The motion of a title like `LIN P2 CONT Vel=2 m/s CPDAT1 Tool[1]:grip Base[0]`; also
/// technology forms that embed one (`ARCON WDAT1 LIN P1 …`).
fn parse_title_motion(cx: Cx<'_>, title: &[u8]) -> Option<IlfMotion> {
    let tokens: Vec<&[u8]> = title
        .split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
        .collect();
    let (at, kind) = tokens.iter().enumerate().find_map(|(n, t)| {
        let upper = t.to_ascii_uppercase();
        MotionKind::from_keyword(&upper).map(|k| (n, k))
    })?;
    let mut m = IlfMotion {
        kind,
        points: Vec::new(),
        cont: None,
        velocity: None,
        data: None,
        tool: None,
        base: None,
    };
    let n_points = if kind.is_circular() { 2 } else { 1 };
    let mut k = at + 1;
    while k < tokens.len() && m.points.len() < n_points && !is_title_keyword(tokens[k]) {
        m.points.push(cx.span_of(tokens[k]));
        k += 1;
    }
    let mut after_velocity = false;
    while k < tokens.len() {
        let t = tokens[k];
        k += 1;
        if t.eq_ignore_ascii_case(b"CONT") {
            m.cont = Some(cx.span_of(t));
        } else if t.len() >= 4 && t[..4].eq_ignore_ascii_case(b"Vel=") {
            let mut v = &t[4..];
            if v.is_empty() && k < tokens.len() {
                v = tokens[k];
                k += 1;
            }
            let Some(lit) = number::scan(v) else { continue };
            let mut unit = (lit.len < v.len()).then(|| cx.span_of(&v[lit.len..]));
            if unit.is_none() && k < tokens.len() && is_unit(tokens[k]) {
                unit = Some(cx.span_of(tokens[k]));
                k += 1;
            }
            m.velocity = Some(IlfVelocity {
                value: number::value(v, &lit),
                span: cx.span_of(&v[..lit.len]),
                unit,
            });
            after_velocity = true;
        } else if let Some(f) = frame_token(cx, t, b"Tool[") {
            m.tool = Some(f);
        } else if let Some(f) = frame_token(cx, t, b"Base[") {
            m.base = Some(f);
        } else if after_velocity && m.data.is_none() && !t.contains(&b'[') {
            m.data = Some(cx.span_of(t));
        }
    }
    Some(m)
}

fn is_title_keyword(t: &[u8]) -> bool {
    t.eq_ignore_ascii_case(b"CONT") || (t.len() >= 4 && t[..4].eq_ignore_ascii_case(b"Vel="))
}

fn is_unit(t: &[u8]) -> bool {
    t == b"%" || t.contains(&b'/')
}

/// `Tool[1]` or `Tool[1]:name`.
fn frame_token(cx: Cx<'_>, t: &[u8], prefix: &[u8]) -> Option<IlfFrame> {
    if t.len() < prefix.len() || !t[..prefix.len()].eq_ignore_ascii_case(prefix) {
        return None;
    }
    let close = t.iter().position(|&b| b == b']')?;
    let inside = &t[prefix.len()..close];
    let index = std::str::from_utf8(inside)
        .ok()
        .and_then(|s| s.parse().ok());
    let name = t[close + 1..]
        .strip_prefix(b":")
        .filter(|n| !n.is_empty())
        .map(|n| cx.span_of(n));
    Some(IlfFrame {
        span: cx.span_of(t),
        index,
        name,
    })
}
