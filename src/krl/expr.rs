//! KRL expressions: the small AST (numbers with their spans and values, strings, bit and enum
//! literals, variable paths like `$APO.CDIS` or `P[i]`, calls, aggregates `{E6POS: X 1, …}`,
//! unary and binary operators) and its nom parser, precedence climbing over KUKA's operator
//! table. Every node keeps the byte span of its text so any number can be replaced in place.

use super::lex::{
    bits, enum_literal, expect, fail, ident, is_ident_char, keyword, number_literal, punct, string,
    ws, Cx, Fails, PResult,
};
use super::number;
use super::span::Span;

/// Deepest nesting of parentheses, aggregates, indices and calls the parser follows.
pub(crate) const MAX_DEPTH: u32 = 64;

/// An expression.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    Number(Number),
    /// `"text"` (span includes the quotes).
    Str(Span),
    /// `'B010'`, `'H1F'` (span includes the quotes).
    Bits(Span),
    /// `#BASE` (span includes `#`).
    Enum(Span),
    /// `TRUE` / `FALSE` in any case.
    Bool(Span, bool),
    /// A variable: `XP1`, `$VEL.CP`, `P[3]`, `BASE_DATA[i].X`.
    Path(Box<Path>),
    /// A function call `SVEL_JOINT(100.0)`.
    Call(Box<Call>),
    /// `{…}`.
    Aggregate(Box<Aggregate>),
    Unary(Box<Unary>),
    Binary(Box<Binary>),
    /// `( … )`.
    Paren(Box<Paren>),
    /// Text kept but not understood (e.g. a condition the parser cannot read).
    Opaque(Span),
}

/// A numeric literal: its exact text span (sign included when glued to it) and its value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Number {
    pub span: Span,
    pub value: f64,
    /// Written without `.` and exponent (`5`, `-3`).
    pub integer: bool,
}

/// A variable reference: a root name and member/index accesses.
#[derive(Clone, Debug, PartialEq)]
pub struct Path {
    pub span: Span,
    pub root: Span,
    pub access: Vec<Access>,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Access {
    /// `[i, j]` (empty for `[]`).
    Index { span: Span, items: Vec<Expr> },
    /// `.NAME`.
    Field { span: Span, name: Span },
}

#[derive(Clone, Debug, PartialEq)]
pub struct Call {
    pub span: Span,
    pub name: Span,
    pub open: Span,
    /// Arguments in order; `None` for an empty position (`SVEL_CP(2.0, , LCPDAT1)`).
    pub args: Vec<Option<Expr>>,
    pub close: Span,
}

/// `{TYPE: NAME value, …}`.
#[derive(Clone, Debug, PartialEq)]
pub struct Aggregate {
    pub span: Span,
    /// The `{`.
    pub open: Span,
    /// `E6POS` in `{E6POS: …}`.
    pub type_name: Option<Span>,
    pub members: Vec<Member>,
    /// The `}`.
    pub close: Span,
}

/// `NAME value` inside an aggregate (`POINT2[] " "` has `index` = `[]`).
#[derive(Clone, Debug, PartialEq)]
pub struct Member {
    pub span: Span,
    pub name: Span,
    pub index: Option<Span>,
    pub value: Expr,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UnOp {
    Neg,
    Plus,
    Not,
    BNot,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Unary {
    pub span: Span,
    pub op: UnOp,
    pub op_span: Span,
    pub operand: Expr,
}

/// Binary operators. `Geo` is the geometric operator `:` (frame composition).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinOp {
    Geo,
    Mul,
    Div,
    Add,
    Sub,
    And,
    BAnd,
    Exor,
    BExor,
    Or,
    BOr,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
}

impl BinOp {
    /// Binding power, after the KUKA operator priority table (geometric `:` first; then
    /// `* /`; `+ -`; `AND B_AND`; `EXOR B_EXOR`; `OR B_OR`; comparisons last).
    pub fn precedence(self) -> u8 {
        use BinOp::*;
        match self {
            Geo => 7,
            Mul | Div => 6,
            Add | Sub => 5,
            And | BAnd => 4,
            Exor | BExor => 3,
            Or | BOr => 2,
            Eq | Ne | Lt | Le | Gt | Ge => 1,
        }
    }

    pub fn symbol(self) -> &'static str {
        use BinOp::*;
        match self {
            Geo => ":",
            Mul => "*",
            Div => "/",
            Add => "+",
            Sub => "-",
            And => "AND",
            BAnd => "B_AND",
            Exor => "EXOR",
            BExor => "B_EXOR",
            Or => "OR",
            BOr => "B_OR",
            Eq => "==",
            Ne => "<>",
            Lt => "<",
            Le => "<=",
            Gt => ">",
            Ge => ">=",
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Binary {
    pub span: Span,
    pub op: BinOp,
    pub op_span: Span,
    pub lhs: Expr,
    pub rhs: Expr,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Paren {
    pub span: Span,
    pub inner: Expr,
}

impl Expr {
    pub fn span(&self) -> Span {
        match self {
            Expr::Number(n) => n.span,
            Expr::Str(s) | Expr::Bits(s) | Expr::Enum(s) | Expr::Bool(s, _) | Expr::Opaque(s) => *s,
            Expr::Path(p) => p.span,
            Expr::Call(c) => c.span,
            Expr::Aggregate(a) => a.span,
            Expr::Unary(u) => u.span,
            Expr::Binary(b) => b.span,
            Expr::Paren(p) => p.span,
        }
    }

    pub fn as_number(&self) -> Option<&Number> {
        match self {
            Expr::Number(n) => Some(n),
            _ => None,
        }
    }

    pub fn as_aggregate(&self) -> Option<&Aggregate> {
        match self {
            Expr::Aggregate(a) => Some(a),
            _ => None,
        }
    }

    pub fn as_path(&self) -> Option<&Path> {
        match self {
            Expr::Path(p) => Some(p),
            _ => None,
        }
    }

    /// Whether any part of the expression was not understood.
    pub fn has_opaque(&self) -> bool {
        let mut found = false;
        self.visit(&mut |e| found |= matches!(e, Expr::Opaque(_)));
        found
    }

    /// Calls `f` on this expression and every sub-expression, parents first.
    pub fn visit(&self, f: &mut impl FnMut(&Expr)) {
        f(self);
        match self {
            Expr::Path(p) => p.visit_items(f),
            Expr::Call(c) => c.args.iter().flatten().for_each(|a| a.visit(f)),
            Expr::Aggregate(a) => a.members.iter().for_each(|m| m.value.visit(f)),
            Expr::Unary(u) => u.operand.visit(f),
            Expr::Binary(b) => {
                b.lhs.visit(f);
                b.rhs.visit(f);
            }
            Expr::Paren(p) => p.inner.visit(f),
            _ => {}
        }
    }

    /// Every numeric literal in the expression, in source order.
    pub fn numbers(&self) -> Vec<Number> {
        let mut out = Vec::new();
        self.visit(&mut |e| {
            if let Expr::Number(n) = e {
                out.push(*n);
            }
        });
        out
    }
}

impl Path {
    /// A bare name with no index or member access.
    pub fn is_simple(&self) -> bool {
        self.access.is_empty()
    }

    fn visit_items(&self, f: &mut impl FnMut(&Expr)) {
        for a in &self.access {
            if let Access::Index { items, .. } = a {
                items.iter().for_each(|e| e.visit(f));
            }
        }
    }
}

impl Aggregate {
    /// The member called `name` (case-insensitive); `src` is the file's source.
    pub fn member(&self, src: &[u8], name: &str) -> Option<&Member> {
        self.members
            .iter()
            .find(|m| src[m.name.range()].eq_ignore_ascii_case(name.as_bytes()))
    }

    /// The number of member `name` when it is a plain (possibly signed) literal.
    pub fn number(&self, src: &[u8], name: &str) -> Option<&Number> {
        self.member(src, name)?.value.as_number()
    }
}

// ---------------------------------------------------------------------------------------------
// Parsers (each is a production of grammars/krl.ebnf).

const HELP_AGG: &str =
    "aggregate members are written NAME value, separated by commas: {X 10, Y -2.5}";

fn too_deep(i: &[u8]) -> Fails<'_, Expr> {
    fail(
        i,
        "expression nested too deeply",
        "split the expression into several assignments",
    )
}

/// Any expression.
pub(crate) fn expr<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    binary(cx, d, i, 1)
}

/// Binary operators by precedence climbing (all left-associative).
fn binary<'a>(cx: Cx<'a>, d: u32, i: &'a [u8], min_bp: u8) -> PResult<'a, Expr> {
    if d > MAX_DEPTH {
        return too_deep(i);
    }
    let (mut i, mut lhs) = unary(cx, d, i)?;
    loop {
        let (j, _) = ws(i)?;
        let Ok((k, (op, op_text))) = binary_op(j) else {
            break;
        };
        let bp = op.precedence();
        if bp < min_bp {
            break;
        }
        let (k, _) = ws(k)?;
        let (k, rhs) = match binary(cx, d + 1, k, bp + 1) {
            Ok(r) => r,
            // An operator without an operand: stop before it, the caller reports the rest.
            Err(nom::Err::Error(_)) => break,
            Err(e) => return Err(e),
        };
        let span = lhs.span().to(rhs.span());
        lhs = Expr::Binary(Box::new(Binary {
            span,
            op,
            op_span: cx.span_of(op_text),
            lhs,
            rhs,
        }));
        i = k;
    }
    Ok((i, lhs))
}

/// A binary operator symbol or word.
fn binary_op(i: &[u8]) -> PResult<'_, (BinOp, &[u8])> {
    use BinOp::*;
    let two = |op, n: usize| Ok((&i[n..], (op, &i[..n])));
    match i {
        [b'=', b'=', ..] => two(Eq, 2),
        [b'<', b'>', ..] => two(Ne, 2),
        [b'<', b'=', ..] => two(Le, 2),
        [b'>', b'=', ..] => two(Ge, 2),
        [b'<', ..] => two(Lt, 1),
        [b'>', ..] => two(Gt, 1),
        [b':', ..] => two(Geo, 1),
        [b'*', ..] => two(Mul, 1),
        [b'/', ..] => two(Div, 1),
        [b'+', ..] => two(Add, 1),
        [b'-', ..] => two(Sub, 1),
        _ => {
            let (rest, w) = ident(i)?;
            let op = match w.len() {
                2 if w.eq_ignore_ascii_case(b"OR") => Or,
                3 if w.eq_ignore_ascii_case(b"AND") => And,
                4 if w.eq_ignore_ascii_case(b"EXOR") => Exor,
                4 if w.eq_ignore_ascii_case(b"B_OR") => BOr,
                5 if w.eq_ignore_ascii_case(b"B_AND") => BAnd,
                6 if w.eq_ignore_ascii_case(b"B_EXOR") => BExor,
                _ => return super::lex::backtrack(i),
            };
            Ok((rest, (op, w)))
        }
    }
}

/// Prefix operators `- + NOT B_NOT`; a sign glued to a number belongs to the number.
fn unary<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    let op = match i.first() {
        Some(b'-') | Some(b'+') => {
            if let Ok(r) = number(cx, i) {
                return Ok(r);
            }
            Some(if i[0] == b'-' { UnOp::Neg } else { UnOp::Plus })
        }
        Some(b'n' | b'N') if keyword("NOT")(i).is_ok() => Some(UnOp::Not),
        Some(b'b' | b'B') if keyword("B_NOT")(i).is_ok() => Some(UnOp::BNot),
        _ => None,
    };
    let Some(op) = op else {
        return primary(cx, d, i);
    };
    let n = match op {
        UnOp::Neg | UnOp::Plus => 1,
        UnOp::Not => 3,
        UnOp::BNot => 5,
    };
    if d > MAX_DEPTH {
        return too_deep(i);
    }
    let (j, _) = ws(&i[n..])?;
    let (rest, operand) = unary(cx, d + 1, j)?;
    Ok((
        rest,
        Expr::Unary(Box::new(Unary {
            span: Span::new(cx.off(i), cx.off(rest)),
            op,
            op_span: cx.span_of(&i[..n]),
            operand,
        })),
    ))
}

/// Literals, names, calls, aggregates, parentheses.
fn primary<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    match i.first() {
        Some(b) if b.is_ascii_digit() || *b == b'.' => number(cx, i),
        Some(b'"') => {
            let (r, s) = string(i)?;
            Ok((r, Expr::Str(cx.span_of(s))))
        }
        Some(b'\'') => {
            let (r, s) = bits(i)?;
            Ok((r, Expr::Bits(cx.span_of(s))))
        }
        Some(b'#') => {
            let (r, s) = enum_literal(i)?;
            Ok((r, Expr::Enum(cx.span_of(s))))
        }
        Some(b'{') => aggregate(cx, d, i),
        Some(b'(') => paren(cx, d, i),
        _ => path_or_call(cx, d, i),
    }
}

/// A numeric literal.
fn number<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Expr> {
    let (rest, (text, lit)) = number_literal(i)?;
    Ok((
        rest,
        Expr::Number(Number {
            span: cx.span_of(text),
            value: number::value(text, &lit),
            integer: lit.is_integer(),
        }),
    ))
}

/// `( expr )`.
fn paren<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    if d > MAX_DEPTH {
        return too_deep(i);
    }
    let (j, _) = punct(b'(')(i)?;
    let (j, _) = ws(j)?;
    let (j, inner) = expr(cx, d + 1, j)?;
    let (j, _) = ws(j)?;
    let (rest, _) = punct(b')')(j)?;
    Ok((
        rest,
        Expr::Paren(Box::new(Paren {
            span: cx.span(i, rest),
            inner,
        })),
    ))
}

/// `TRUE`, `FALSE`, a variable path, or a call `NAME(args)`.
fn path_or_call<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    let (rest, name) = ident(i)?;
    if name.eq_ignore_ascii_case(b"TRUE") || name.eq_ignore_ascii_case(b"FALSE") {
        let v = name.len() == 4;
        return Ok((rest, Expr::Bool(cx.span_of(name), v)));
    }
    let (after_ws, _) = ws(rest)?;
    if after_ws.first() == Some(&b'(') {
        return call(cx, d, i);
    }
    path(cx, d, i)
}

/// `NAME ( [arg] {, [arg]} )`.
pub(crate) fn call<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    if d > MAX_DEPTH {
        return too_deep(i);
    }
    let (j, name) = ident(i)?;
    let (j, _) = ws(j)?;
    let (mut j, open) = punct(b'(')(j)?;
    let mut args = Vec::new();
    let (k, _) = ws(j)?;
    if let Ok((k, close)) = punct(b')')(k) {
        return Ok((k, call_expr(cx, i, k, name, open, args, close)));
    }
    loop {
        let (k, _) = ws(j)?;
        let (k, arg) = match k.first() {
            Some(b',') | Some(b')') => (k, None),
            _ => {
                let (k, e) = expr(cx, d + 1, k)?;
                (k, Some(e))
            }
        };
        args.push(arg);
        let (k, _) = ws(k)?;
        if let Ok((k, _)) = punct(b',')(k) {
            j = k;
            continue;
        }
        let (k, close) = punct(b')')(k)?;
        return Ok((k, call_expr(cx, i, k, name, open, args, close)));
    }
}

fn call_expr<'a>(
    cx: Cx<'a>,
    start: &'a [u8],
    rest: &'a [u8],
    name: &'a [u8],
    open: &'a [u8],
    args: Vec<Option<Expr>>,
    close: &'a [u8],
) -> Expr {
    Expr::Call(Box::new(Call {
        span: cx.span(start, rest),
        name: cx.span_of(name),
        open: cx.span_of(open),
        args,
        close: cx.span_of(close),
    }))
}

/// `NAME { [index] | .FIELD }`.
pub(crate) fn path<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    let (mut j, root) = ident(i)?;
    let mut access = Vec::new();
    loop {
        let (k, _) = ws(j)?;
        match k.first() {
            Some(b'[') => {
                let (k, a) = index(cx, d, k)?;
                access.push(a);
                j = k;
            }
            Some(b'.') if j.first() == Some(&b'.') => {
                let Ok((k2, name)) = ident(&j[1..]) else {
                    break;
                };
                access.push(Access::Field {
                    span: cx.span(j, k2),
                    name: cx.span_of(name),
                });
                j = k2;
            }
            _ => break,
        }
    }
    Ok((
        j,
        Expr::Path(Box::new(Path {
            span: cx.span(i, j),
            root: cx.span_of(root),
            access,
        })),
    ))
}

/// `[ [expr {, expr}] ]`.
fn index<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Access> {
    if d > MAX_DEPTH {
        return fail(i, "expression nested too deeply", "simplify the index");
    }
    let (mut j, _) = punct(b'[')(i)?;
    let mut items = Vec::new();
    let (k, _) = ws(j)?;
    if let Ok((k, _)) = punct(b']')(k) {
        return Ok((
            k,
            Access::Index {
                span: cx.span(i, k),
                items,
            },
        ));
    }
    loop {
        let (k, _) = ws(j)?;
        let (k, e) = expr(cx, d + 1, k)?;
        items.push(e);
        let (k, _) = ws(k)?;
        if let Ok((k, _)) = punct(b',')(k) {
            j = k;
            continue;
        }
        let (k, _) = punct(b']')(k)?;
        return Ok((
            k,
            Access::Index {
                span: cx.span(i, k),
                items,
            },
        ));
    }
}

/// `{ [TYPE :] [member {, member}] }` — committed after `{`: a malformed aggregate is an error.
pub(crate) fn aggregate<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    if d > MAX_DEPTH {
        return too_deep(i);
    }
    let (j, open) = punct(b'{')(i)?;
    let (mut j, _) = ws(j)?;
    let mut type_name = None;
    if let Ok((k, name)) = ident(j) {
        let (k, _) = ws(k)?;
        if let Ok((k, _)) = punct(b':')(k) {
            type_name = Some(cx.span_of(name));
            j = ws(k)?.0;
        }
    }
    let mut members = Vec::new();
    if let Ok((k, close)) = punct(b'}')(j) {
        return Ok((k, agg_expr(cx, i, k, open, type_name, members, close)));
    }
    loop {
        let (k, m) = expect("expected a member name", HELP_AGG, |x| member(cx, d, x))(j)?;
        members.push(m);
        let (k, _) = ws(k)?;
        if let Ok((k, _)) = punct(b',')(k) {
            j = ws(k)?.0;
            continue;
        }
        if let Ok((k, close)) = punct(b'}')(k) {
            return Ok((k, agg_expr(cx, i, k, open, type_name, members, close)));
        }
        if k.is_empty() {
            return fail(
                k,
                "unclosed aggregate: `}` missing",
                "close the aggregate with } on the same line (a KRL statement never continues on the next line)",
            );
        }
        return fail(
            k,
            "expected `,` or `}` in the aggregate",
            "separate members with commas and close the aggregate with } on the same line",
        );
    }
}

fn agg_expr<'a>(
    cx: Cx<'a>,
    start: &'a [u8],
    rest: &'a [u8],
    open: &'a [u8],
    type_name: Option<Span>,
    members: Vec<Member>,
    close: &'a [u8],
) -> Expr {
    Expr::Aggregate(Box::new(Aggregate {
        span: cx.span(start, rest),
        open: cx.span_of(open),
        type_name,
        members,
        close: cx.span_of(close),
    }))
}

/// `NAME[[…]] value`.
fn member<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Member> {
    let (j, name) = ident(i)?;
    let (j, index) = match j.first() {
        Some(b'[') => match j.iter().position(|&b| b == b']') {
            Some(p) => (&j[p + 1..], Some(cx.span_of(&j[..p + 1]))),
            None => return fail(j, "unclosed `[` in a member name", HELP_AGG),
        },
        _ => (j, None),
    };
    let (k, blanks) = ws(j)?;
    // `X1` is one name, so a value glued to the name must start with a non-name byte.
    if blanks.is_empty() && k.first().is_some_and(|&b| is_ident_char(b)) {
        return fail(
            k,
            "expected a blank between the member name and its value",
            HELP_AGG,
        );
    }
    let (rest, value) = expect("expected a value for the member", HELP_AGG, |x| {
        expr(cx, d + 1, x)
    })(k)?;
    Ok((
        rest,
        Member {
            span: cx.span(i, rest),
            name: cx.span_of(name),
            index,
            value,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &[u8]) -> (usize, Expr) {
        let cx = Cx::new(s);
        let (rest, e) = expr(cx, 0, s).unwrap();
        (s.len() - rest.len(), e)
    }

    #[test]
    fn precedence_follows_kuka_table() {
        let (_, e) = parse(b"a + b * c : d");
        let Expr::Binary(b) = e else { panic!() };
        assert_eq!(b.op, BinOp::Add);
        let Expr::Binary(r) = &b.rhs else { panic!() };
        assert_eq!(r.op, BinOp::Mul);
        let Expr::Binary(g) = &r.rhs else { panic!() };
        assert_eq!(g.op, BinOp::Geo);
        // Comparisons bind loosest; AND binds tighter than OR.
        let (_, e) = parse(b"x == 1 OR y AND z");
        let Expr::Binary(b) = e else { panic!() };
        assert_eq!(b.op, BinOp::Eq);
        let Expr::Binary(r) = &b.rhs else { panic!() };
        assert_eq!(r.op, BinOp::Or);
    }

    #[test]
    fn aggregate_spans_and_values() {
        let s = b"{E6POS: X 1.0, Y -2.5E+01,Z .25, S 'B010', fCnC {X 1}, POINT2[] \" \"} C_DIS";
        let (n, e) = parse(s);
        assert_eq!(&s[..n], &s[..s.len() - 6]);
        let a = e.as_aggregate().unwrap();
        assert_eq!(&s[a.type_name.unwrap().range()], b"E6POS");
        assert_eq!(a.members.len(), 6);
        let y = a.number(s, "y").unwrap();
        assert_eq!((&s[y.span.range()], y.value), (&b"-2.5E+01"[..], -25.0));
        assert_eq!(a.number(s, "Z").unwrap().value, 0.25);
        assert!(matches!(a.member(s, "S").unwrap().value, Expr::Bits(_)));
        assert!(a.member(s, "FCNC").unwrap().value.as_aggregate().is_some());
        assert_eq!(&s[a.members[5].index.unwrap().range()], b"[]");
        assert_eq!(&s[a.open.range()], b"{");
        assert_eq!(a.close.end as usize, n);
    }

    #[test]
    fn malformed_aggregates_fail_with_labels() {
        for (s, label) in [
            (&b"{X 1, Y}"[..], "expected a value for the member"),
            (b"{X 1 Y 2}", "expected `,` or `}` in the aggregate"),
            (b"{X 1,", "expected a member name"),
            (b"{X1}", "expected a value for the member"),
            (
                b"{P[]x}",
                "expected a blank between the member name and its value",
            ),
        ] {
            match expr(Cx::new(s), 0, s) {
                Err(nom::Err::Failure(e)) => assert_eq!(e.label, label, "{:?}", s),
                other => panic!("{:?}: {:?}", s, other.map(|r| r.1)),
            }
        }
    }

    #[test]
    fn paths_calls_and_empty_arguments() {
        let s = b"SVEL_CP(2.0, , LCPDAT1)";
        let (n, e) = parse(s);
        assert_eq!(n, s.len());
        let Expr::Call(c) = e else { panic!() };
        assert_eq!(c.args.len(), 3);
        assert!(c.args[1].is_none());
        let s = b"BASE_DATA[i+1].X";
        let (n, e) = parse(s);
        assert_eq!(n, s.len());
        assert_eq!(e.as_path().unwrap().access.len(), 2);
    }

    #[test]
    fn deep_nesting_is_refused_not_overflowed() {
        let s = [b'('; 10_000];
        assert!(expr(Cx::new(&s), 0, &s).is_err());
        let mut s = vec![b'-'; 100_000];
        s.push(b'x');
        assert!(expr(Cx::new(&s), 0, &s).is_err());
    }
}
