//! KRL expressions: the small AST (numbers with their spans and values, strings, bit and enum
//! literals, variable paths like `$APO.CDIS` or `P[i]`, calls, aggregates `{E6POS: X 1, …}`,
//! unary and binary operators) and its nom parser, precedence climbing over KUKA's operator
//! table. Every node keeps the byte span of its text so any number can be replaced in place.

use super::lex::{
    backtrack, bits, blanks, enum_literal, expecting, fail, ident, is_blank, is_ident_char,
    is_ident_start, keyword, number_literal, punct, string, ws, Cx, Fails, PResult,
};
use super::nodes::{AggregateId, Nodes, Packed};
use super::number;
use super::span::Span;
use std::borrow::Cow;

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
    /// `{…}`: its span and its node in the file (`SourceFile::aggregate`).
    Aggregate(Span, AggregateId),
    Unary(Box<Unary>),
    Binary(Box<Binary>),
    /// `( … )`.
    Paren(Box<Paren>),
    /// Text kept but not understood (e.g. a condition the parser cannot read).
    Opaque(Span),
}

/// A numeric literal: its value and the exact span of its text (`span()`, sign included when
/// glued to it). Packed into 16 bytes: a CAM program holds millions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Number {
    pub value: f64,
    start: u32,
    len: u16,
    /// Written without `.` and exponent (`5`, `-3`).
    pub integer: bool,
}

impl Number {
    pub(crate) fn new(value: f64, span: Span, integer: bool) -> Number {
        Number {
            value,
            start: span.start,
            len: span.len() as u16,
            integer,
        }
    }

    /// The bytes of the literal.
    pub fn span(&self) -> Span {
        Span {
            start: self.start,
            end: self.start + u32::from(self.len),
        }
    }
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
    /// `[i, j]` (empty for `[]`). `slice`: some position is left empty (`[,]`, `[1,]`: the
    /// whole array, or a row of it, as an argument or a string row is written).
    Index {
        span: Span,
        items: Vec<Expr>,
        slice: bool,
    },
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

/// `{TYPE: NAME value, …}`; its members are in the file (`SourceFile::members`). Packed into
/// 24 bytes: the type name as start and length (length 0: none), the pool flag in the top
/// bit of the member count.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Aggregate {
    pub span: Span,
    type_start: u32,
    type_len: u32,
    pub(crate) first: u32,
    /// Member count; the top bit says the members are in the nested-members pool.
    len_nested: u32,
}

const NESTED_BIT: u32 = 1 << 31;

/// `NAME value` inside an aggregate, handed out by value (`SourceFile::members`): a plain
/// number is read from the source bytes when asked for (`Cow::Owned`), any other value is
/// borrowed from the file. An array member's `[]` (`POINT2[] " "`) follows the name
/// directly: `SourceFile::member_index` gives its span.
#[derive(Clone, Debug, PartialEq)]
pub struct Member<'a> {
    pub name: Span,
    pub value: Cow<'a, Expr>,
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

    #[cfg(any(test, feature = "internals"))]
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
            Expr::Number(n) => n.span(),
            Expr::Str(s) | Expr::Bits(s) | Expr::Enum(s) | Expr::Bool(s, _) | Expr::Opaque(s) => *s,
            Expr::Path(p) => p.span,
            Expr::Call(c) => c.span,
            Expr::Aggregate(span, _) => *span,
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

    /// The aggregate's id (look it up with `SourceFile::aggregate`, or use
    /// `SourceFile::aggregate_of`).
    pub fn as_aggregate(&self) -> Option<AggregateId> {
        match self {
            Expr::Aggregate(_, id) => Some(*id),
            _ => None,
        }
    }

    pub fn as_path(&self) -> Option<&Path> {
        match self {
            Expr::Path(p) => Some(p),
            _ => None,
        }
    }

    /// Whether the expression is text the parser did not understand (conditions only: every
    /// other expression is parsed fully or the line fails).
    pub fn is_opaque(&self) -> bool {
        matches!(self, Expr::Opaque(_))
    }

    /// Whether the expression owns heap memory (a boxed node); literals and aggregate ids
    /// do not (the node pools skip visiting such nodes when they are dropped).
    pub(crate) fn owns_heap(&self) -> bool {
        match self {
            Expr::Path(_) | Expr::Call(_) | Expr::Unary(_) | Expr::Binary(_) | Expr::Paren(_) => {
                true
            }
            Expr::Number(_)
            | Expr::Str(_)
            | Expr::Bits(_)
            | Expr::Enum(_)
            | Expr::Bool(..)
            | Expr::Aggregate(..)
            | Expr::Opaque(_) => false,
        }
    }

    /// Calls `f` on this expression and every sub-expression, parents first (aggregate
    /// members are looked up in `nodes`, plain numbers read from `src`).
    pub(crate) fn visit(&self, nodes: &Nodes, src: &[u8], f: &mut impl FnMut(&Expr)) {
        f(self);
        match self {
            Expr::Path(p) => {
                for a in &p.access {
                    if let Access::Index { items, .. } = a {
                        items.iter().for_each(|e| e.visit(nodes, src, f));
                    }
                }
            }
            Expr::Call(c) => c.args.iter().flatten().for_each(|a| a.visit(nodes, src, f)),
            Expr::Aggregate(_, id) => {
                let a = &nodes.aggregates[id.0 as usize];
                for &m in nodes.members_of(a) {
                    nodes.member(src, m).value.visit(nodes, src, f);
                }
            }
            Expr::Unary(u) => u.operand.visit(nodes, src, f),
            Expr::Binary(b) => {
                b.lhs.visit(nodes, src, f);
                b.rhs.visit(nodes, src, f);
            }
            Expr::Paren(p) => p.inner.visit(nodes, src, f),
            _ => {}
        }
    }
}

impl Path {
    /// A bare name with no index or member access.
    pub fn is_simple(&self) -> bool {
        self.access.is_empty()
    }
}

impl Member<'_> {
    /// From the name to the end of the value.
    pub fn span(&self) -> Span {
        self.name.to(self.value.span())
    }
}

impl Aggregate {
    /// The `{`.
    #[cfg(any(test, feature = "internals"))]
    pub fn open(&self) -> Span {
        Span {
            start: self.span.start,
            end: self.span.start + 1,
        }
    }

    /// The `}` (insert a missing member before it).
    #[cfg(any(test, feature = "internals"))]
    pub fn close(&self) -> Span {
        Span {
            start: self.span.end - 1,
            end: self.span.end,
        }
    }

    /// `E6POS` in `{E6POS: …}`.
    #[cfg(any(test, feature = "internals"))]
    pub fn type_name(&self) -> Option<Span> {
        (self.type_len > 0).then_some(Span {
            start: self.type_start,
            end: self.type_start + self.type_len,
        })
    }

    /// Number of members.
    pub fn len(&self) -> usize {
        (self.len_nested & !NESTED_BIT) as usize
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the members are in the nested-members pool.
    pub(crate) fn nested(&self) -> bool {
        self.len_nested & NESTED_BIT != 0
    }

    pub(crate) fn range(&self) -> std::ops::Range<usize> {
        self.first as usize..self.first as usize + self.len()
    }

    /// An outermost aggregate whose `len` members start at `first` in the members pool (as
    /// `close_aggregate` records one).
    pub(crate) fn outermost(span: Span, type_name: Option<Span>, first: u32, len: u32) -> Self {
        let ty = type_name.unwrap_or_default();
        Aggregate {
            span,
            type_start: ty.start,
            type_len: ty.len() as u32,
            first,
            len_nested: len,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Parsers (each is a production of grammars/krl.ebnf).

const HELP_AGG: &str =
    "aggregate members are written NAME value, separated by commas: {X 10, Y -2.5}";

fn too_deep(i: &[u8]) -> Fails<'_, Expr> {
    fail!(
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
    // Each operator nests the tree one level deeper (left-associative chains too), and
    // dropping or walking a tree is recursive: bound the depth, not only the parentheses.
    let mut depth = d;
    loop {
        let (j, _) = ws(i)?;
        let Ok((k, (op, op_text))) = binary_op(j) else {
            break;
        };
        let bp = op.precedence();
        if bp < min_bp {
            break;
        }
        depth += 1;
        if depth > MAX_DEPTH {
            return too_deep(j);
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
        // Word operators start with O, A, E or B: anything else (`C_DIS` after a motion
        // target) is not one, without reading the word.
        [b'o' | b'O' | b'a' | b'A' | b'e' | b'E' | b'b' | b'B', ..] => {
            let (rest, w) = ident(i)?;
            let op = match w.len() {
                2 if w.eq_ignore_ascii_case(b"OR") => Or,
                3 if w.eq_ignore_ascii_case(b"AND") => And,
                4 if w.eq_ignore_ascii_case(b"EXOR") => Exor,
                4 if w.eq_ignore_ascii_case(b"B_OR") => BOr,
                5 if w.eq_ignore_ascii_case(b"B_AND") => BAnd,
                6 if w.eq_ignore_ascii_case(b"B_EXOR") => BExor,
                _ => return backtrack(i),
            };
            Ok((rest, (op, w)))
        }
        _ => backtrack(i),
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

/// A numeric literal (at most 65,535 bytes long).
fn number<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Expr> {
    let (rest, (text, lit)) = number_literal(i)?;
    let Ok(len) = u16::try_from(text.len()) else {
        return backtrack(i);
    };
    Ok((
        rest,
        Expr::Number(Number {
            value: number::value(text, &lit),
            start: cx.off(text) as u32,
            len,
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

/// `[ [expr {, expr}] ]`, or a slice with empty positions: `[,]`, `[1,]`.
fn index<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Access> {
    if d > MAX_DEPTH {
        return fail!(i, "expression nested too deeply", "simplify the index");
    }
    let (mut j, _) = punct(b'[')(i)?;
    let mut items = Vec::new();
    let mut slice = false;
    let (k, _) = ws(j)?;
    if let Ok((k, _)) = punct(b']')(k) {
        return Ok((
            k,
            Access::Index {
                span: cx.span(i, k),
                items,
                slice,
            },
        ));
    }
    loop {
        let (k, _) = ws(j)?;
        let k = match k.first() {
            Some(b',') | Some(b']') => {
                slice = true;
                k
            }
            _ => {
                let (k, e) = expr(cx, d + 1, k)?;
                items.push(e);
                k
            }
        };
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
                slice,
            },
        ));
    }
}

/// `{ [TYPE :] [member {, member}] }` — committed after `{`: a malformed aggregate is an error.
pub(crate) fn aggregate<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, Expr> {
    if d > MAX_DEPTH {
        return too_deep(i);
    }
    let (j, _) = punct(b'{')(i)?;
    let (mut j, type_name) = aggregate_type(cx, ws(j)?.0)?;
    let (nested, mark) = open_aggregate(cx);
    let close = |k: &'a [u8]| -> PResult<'a, Expr> {
        if let Some(at) = repeated_member(cx, nested, mark) {
            return fail!(
                &cx.base()[at..],
                "this member is given twice in the aggregate",
                "give each member once: of `{X 1200, X 1300}` a reader keeps one value, and which one was meant is not known",
            );
        }
        Ok((
            k,
            close_aggregate(cx, cx.span(i, k), type_name, nested, mark),
        ))
    };
    if let Ok((k, _)) = punct(b'}')(j) {
        return close(k);
    }
    loop {
        if !nested {
            match plain_members(cx, j) {
                Members::Closed(k) => return close(k),
                Members::Other(k) => j = k,
            }
        }
        let (k, (name, value)) =
            expecting!("expected a member name", HELP_AGG, |x| member(cx, d, x))(j)?;
        push_member(cx, nested, name, value);
        let (k, _) = ws(k)?;
        if let Ok((k, _)) = punct(b',')(k) {
            j = ws(k)?.0;
            continue;
        }
        if let Ok((k, _)) = punct(b'}')(k) {
            return close(k);
        }
        if k.is_empty() {
            return fail!(
                k,
                "unclosed aggregate: `}` missing",
                "close the aggregate with } on the same line (a KRL statement never continues on the next line)",
            );
        }
        return fail!(
            k,
            "expected `,` or `}` in the aggregate",
            "separate members with commas and close the aggregate with } on the same line",
        );
    }
}

/// The offset of the second name of a member given twice in the aggregate being closed (its
/// members start at `mark`); see [`repeated_name`].
fn repeated_member(cx: Cx<'_>, nested: bool, mark: usize) -> Option<usize> {
    let n = cx.nodes.borrow();
    let members = if nested {
        &n.scratch[mark..]
    } else {
        &n.members[mark..]
    };
    repeated_name(members, |m| n.member_name(m), cx.base(), 0)
}

/// The source offset of the second name of a member given twice among `members`, compared as
/// KRL does, ignoring case (`name_of`: a member's name; `src`: the source from offset
/// `offset` on, holding the names).
/// One-letter names (`X`, `A`, `S`: nearly every member of a position) are checked by a bit
/// each; the others pair by pair, few in any aggregate. An indexed member (`NAME[] "text"`)
/// names an element, not the member: not compared.
pub(crate) fn repeated_name(
    members: &[Packed],
    name_of: impl Fn(Packed) -> Span,
    src: &[u8],
    offset: usize,
) -> Option<usize> {
    let name = |m| {
        let span = name_of(m);
        let (a, b) = (span.start as usize - offset, span.end as usize - offset);
        (span.start as usize, &src[a..b], src.get(b) == Some(&b'['))
    };
    let mut letters = 0u64;
    for (i, &m) in members.iter().enumerate() {
        let (at, this, indexed) = name(m);
        if indexed {
            continue;
        }
        if let [b] = this {
            let bit = 1u64 << (b.to_ascii_uppercase() & 63);
            if letters & bit != 0 {
                return Some(at);
            }
            letters |= bit;
        } else if members[..i].iter().any(|&o| {
            let (_, other, indexed) = name(o);
            !indexed && other.len() == this.len() && other.eq_ignore_ascii_case(this)
        }) {
            return Some(at);
        }
    }
    None
}

/// The optional `TYPE :` after an aggregate's `{` (and the blanks after it).
fn aggregate_type<'a>(cx: Cx<'a>, j: &'a [u8]) -> PResult<'a, Option<Span>> {
    if let Ok((k, name)) = ident(j) {
        let (k, _) = ws(k)?;
        if let Ok((k, _)) = punct(b':')(k) {
            return Ok((ws(k)?.0, Some(cx.span_of(name))));
        }
    }
    Ok((j, None))
}

/// Enters an aggregate: whether it is nested, and where its members start. The outermost
/// aggregate writes its members straight into the pool; nested ones gather theirs on the
/// scratch stack (see `Nodes`).
fn open_aggregate(cx: Cx) -> (bool, usize) {
    let mut n = cx.nodes.borrow_mut();
    n.agg_depth += 1;
    let nested = n.agg_depth > 1;
    let mark = if nested {
        n.scratch.len()
    } else {
        n.members.len()
    };
    (nested, mark)
}

/// Where [`plain_members`] left an outermost aggregate.
enum Members<'a> {
    /// At its `}`: the input after it.
    Closed(&'a [u8]),
    /// At a member that is not `NAME number`: the input there.
    Other(&'a [u8]),
}

/// The fast path: a run of `NAME number` members (what CAM programs are made of), read
/// without the general machinery, until the `}` or the first other member.
fn plain_members<'a>(cx: Cx<'a>, mut j: &'a [u8]) -> Members<'a> {
    let mut n = cx.nodes.borrow_mut();
    let keep = n.keep_values;
    while let Some((sep, m, value)) = plain_member(j, 0, cx.off(j), keep) {
        n.push_member(m, value);
        let k = &j[sep..];
        if k[0] != b',' {
            return Members::Closed(&k[1..]);
        }
        j = &k[1..];
        j = &j[blanks(j)..];
    }
    Members::Other(j)
}

/// A member read by the general parser, onto the pool (outermost) or the scratch stack.
fn push_member(cx: Cx, nested: bool, name: Span, value: Expr) {
    let mut n = cx.nodes.borrow_mut();
    let number = match &value {
        Expr::Number(x) => x.value,
        _ => f64::NAN,
    };
    let m = n.pack(cx.base(), name, value);
    if nested {
        n.scratch.push(m);
    } else {
        n.push_member(m, number);
    }
}

/// Adds the aggregate whose members start at `mark` (in the pool, or on the scratch stack
/// for a nested one, moved to the nested pool here).
fn close_aggregate(
    cx: Cx<'_>,
    span: Span,
    type_name: Option<Span>,
    nested: bool,
    mark: usize,
) -> Expr {
    let mut guard = cx.nodes.borrow_mut();
    let n = &mut *guard;
    let (first, len) = if nested {
        let first = n.nested_members.len();
        n.nested_members.extend(n.scratch.drain(mark..));
        (first, n.nested_members.len() - first)
    } else {
        (mark, n.members.len() - mark)
    };
    n.agg_depth -= 1;
    let id = AggregateId(n.aggregates.len() as u32);
    let ty = type_name.unwrap_or_default();
    n.push_aggregate(Aggregate {
        span,
        type_start: ty.start,
        type_len: ty.len() as u32,
        first: first as u32,
        len_nested: len as u32 | if nested { NESTED_BIT } else { 0 },
    });
    Expr::Aggregate(span, id)
}

/// `NAME number` followed by blanks and `,` or `}` (not consumed), the number plain enough
/// for `number::read_plain` (`number::plain_len`); `None` sends the member to the general
/// `member` parser, which reads these the same way: the member at `p` in `b` (`base`: where
/// `b` starts in the source). Gives where the `,` or `}` is, the member and, with `keep`, the
/// number's value (else 0: `read_plain` takes the numbers `plain_len` does). Hand-written,
/// not combinators: it is the inner loop of a CAM program's parse (a million lines of six
/// members; BENCH.md, "KRL front end"), and the fast path of `plain` reads its members with
/// it too.
// Always inlined: called from the parser too, it stopped being inlined into the look
// (+3.8 % of `check`'s instructions; BENCH.md).
#[inline(always)]
pub(crate) fn plain_member(
    b: &[u8],
    p: usize,
    base: usize,
    keep: bool,
) -> Option<(usize, Packed, f64)> {
    // On local indices, not sub-slices: fewer bounds checks in the hottest loop (BENCH.md).
    let blanks = |mut q: usize| {
        while q < b.len() && is_blank(b[q]) {
            q += 1;
        }
        q
    };
    if p >= b.len() || !is_ident_start(b[p]) {
        return None;
    }
    let mut name_end = p + 1;
    while name_end < b.len() && is_ident_char(b[name_end]) {
        name_end += 1;
    }
    let at = blanks(name_end);
    let (len, value) = if keep {
        let (len, value, _) = number::read_plain(&b[at..])?;
        (len, value)
    } else {
        (number::plain_len(&b[at..])?, 0.0)
    };
    let sep = blanks(at + len);
    if !matches!(b.get(sep), Some(b',' | b'}')) {
        return None;
    }
    let packed = Packed::plain(
        Span::new(base + p, base + name_end),
        Span::new(base + at, base + at + len),
    )?;
    Some((sep, packed, value))
}

/// `NAME[[…]] value`: the name's span and the value.
fn member<'a>(cx: Cx<'a>, d: u32, i: &'a [u8]) -> PResult<'a, (Span, Expr)> {
    let (j, name) = ident(i)?;
    let j = match j.first() {
        Some(b'[') => match j.iter().position(|&b| b == b']') {
            Some(p) => &j[p + 1..],
            None => return fail!(j, "unclosed `[` in a member name", HELP_AGG),
        },
        _ => j,
    };
    let (k, gap) = ws(j)?;
    // `X1` is one name, so a value glued to the name must start with a non-name byte.
    if gap.is_empty() && k.first().is_some_and(|&b| is_ident_char(b)) {
        return fail!(
            k,
            "expected a blank between the member name and its value",
            HELP_AGG,
        );
    }
    let (rest, value) = expecting!("expected a value for the member", HELP_AGG, |x| {
        expr(cx, d + 1, x)
    })(k)?;
    Ok((rest, (cx.span_of(name), value)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::RefCell;

    fn parse(s: &[u8]) -> (usize, Expr, Nodes) {
        let nodes = RefCell::new(Nodes::default());
        let (rest, e) = expr(Cx::new(s, &nodes), 0, s).unwrap();
        (s.len() - rest.len(), e, nodes.into_inner())
    }

    fn member<'n>(n: &'n Nodes, src: &[u8], a: &Aggregate, name: &str) -> Member<'n> {
        n.members_of(a)
            .iter()
            .map(|&p| n.member(src, p))
            .find(|m| src[m.name.range()].eq_ignore_ascii_case(name.as_bytes()))
            .unwrap()
    }

    #[test]
    fn precedence_follows_kuka_table() {
        let (_, e, _) = parse(b"a + b * c : d");
        let Expr::Binary(b) = e else { panic!() };
        assert_eq!(b.op, BinOp::Add);
        let Expr::Binary(r) = &b.rhs else { panic!() };
        assert_eq!(r.op, BinOp::Mul);
        let Expr::Binary(g) = &r.rhs else { panic!() };
        assert_eq!(g.op, BinOp::Geo);
        // Comparisons bind loosest; AND binds tighter than OR.
        let (_, e, _) = parse(b"x == 1 OR y AND z");
        let Expr::Binary(b) = e else { panic!() };
        assert_eq!(b.op, BinOp::Eq);
        let Expr::Binary(r) = &b.rhs else { panic!() };
        assert_eq!(r.op, BinOp::Or);
    }

    #[test]
    fn aggregate_spans_and_values() {
        let s = b"{E6POS: X 1.0, Y -2.5E+01,Z .25, S 'B010', fCnC {X 1}, POINT2[] \" \"} C_DIS";
        let (n, e, nodes) = parse(s);
        assert_eq!(&s[..n], &s[..s.len() - 6]);
        let a = nodes.aggregates[e.as_aggregate().unwrap().0 as usize];
        assert_eq!(&s[a.type_name().unwrap().range()], b"E6POS");
        assert_eq!(a.len(), 6);
        let y = member(&nodes, s, &a, "y")
            .value
            .as_number()
            .copied()
            .unwrap();
        assert_eq!((&s[y.span().range()], y.value), (&b"-2.5E+01"[..], -25.0));
        let z = member(&nodes, s, &a, "Z")
            .value
            .as_number()
            .copied()
            .unwrap();
        assert_eq!(z.value, 0.25);
        assert!(matches!(*member(&nodes, s, &a, "S").value, Expr::Bits(_)));
        assert!(member(&nodes, s, &a, "FCNC").value.as_aggregate().is_some());
        let p2 = member(&nodes, s, &a, "POINT2");
        assert_eq!(
            &s[p2.name.end as usize..p2.value.span().start as usize],
            b"[] "
        );
        assert_eq!(&s[a.open().range()], b"{");
        assert_eq!(&s[a.close().range()], b"}");
        assert_eq!(a.close().end as usize, n);
        // The nested aggregate's member went to the nested pool, the outer run is contiguous.
        assert_eq!((nodes.members.len(), nodes.nested_members.len()), (6, 1));
    }

    /// Plain members are stored as 8-byte records and read again on demand, the rest out of
    /// line: both give the number Rust's own (correctly rounded) parser reads from the text.
    #[test]
    fn packed_and_out_of_line_members_read_back() {
        let long = "L".repeat(300);
        let text = format!(
            "{{X -0.25, Y 1.5E3, Z +7, A  12345678901234567890.5, B P1.X, {long} 2.5, C\t.125, D 3 + 4, E #BASE}}"
        );
        let s = text.as_bytes();
        let (n, e, nodes) = parse(s);
        assert_eq!(n, s.len());
        let a = nodes.aggregates[e.as_aggregate().unwrap().0 as usize];
        let ms: Vec<Member> = nodes
            .members_of(&a)
            .iter()
            .map(|&p| nodes.member(s, p))
            .collect();
        let names: Vec<&[u8]> = ms.iter().map(|m| &s[m.name.range()]).collect();
        assert_eq!(names.len(), 9);
        assert_eq!(names[5], long.as_bytes());
        for m in &ms {
            if let Some(num) = m.value.as_number() {
                let t = std::str::from_utf8(&s[num.span().range()]).unwrap();
                let want: f64 = t.parse().unwrap();
                assert_eq!(num.value.to_bits(), want.to_bits(), "{t}");
                assert_eq!(num.integer, !t.contains(['.', 'E']), "{t}");
            }
        }
        let numbers: Vec<f64> = ms
            .iter()
            .filter_map(|m| m.value.as_number())
            .map(|n| n.value)
            .collect();
        assert_eq!(numbers.len(), 6);
        assert_eq!(
            [numbers[0], numbers[1], numbers[2], numbers[4], numbers[5]],
            [-0.25, 1500.0, 7.0, 2.5, 0.125]
        );
        // Plain numbers are owned (read on demand); the exponent, the over-long name, the
        // 20-digit number and the non-numbers are out of line.
        let owned: Vec<bool> = ms
            .iter()
            .map(|m| matches!(m.value, Cow::Owned(_)))
            .collect();
        assert_eq!(
            owned,
            [true, false, true, false, false, false, true, false, false]
        );
        assert_eq!(nodes.outline.len(), 6);
        assert!(matches!(*ms[4].value, Expr::Path(_)));
        assert!(matches!(*ms[7].value, Expr::Binary(_)));
        assert!(matches!(*ms[8].value, Expr::Enum(_)));
    }

    #[test]
    fn malformed_aggregates_fail_with_labels() {
        for (s, label) in [
            (&b"{X 1, Y}"[..], "expected a value for the member"),
            (b"{X 1 Y 2}", "expected `,` or `}` in the aggregate"),
            (b"{X 1,", "expected a member name"),
            (b"{X1}", "expected a value for the member"),
            (b"{X 1", "unclosed aggregate: `}` missing"),
            (
                b"{P[]x}",
                "expected a blank between the member name and its value",
            ),
        ] {
            let nodes = RefCell::new(Nodes::default());
            match expr(Cx::new(s, &nodes), 0, s) {
                Err(nom::Err::Failure(e)) => assert_eq!(e.label(), label, "{:?}", s),
                other => panic!("{:?}: {:?}", s, other.map(|r| r.1)),
            }
        }
    }

    #[test]
    fn paths_calls_and_empty_arguments() {
        let s = b"SVEL_CP(2.0, , LCPDAT1)";
        let (n, e, _) = parse(s);
        assert_eq!(n, s.len());
        let Expr::Call(c) = e else { panic!() };
        assert_eq!(c.args.len(), 3);
        assert!(c.args[1].is_none());
        let s = b"BASE_DATA[i+1].X";
        let (n, e, _) = parse(s);
        assert_eq!(n, s.len());
        assert_eq!(e.as_path().unwrap().access.len(), 2);
    }

    #[test]
    fn deep_nesting_is_refused_not_overflowed() {
        let nodes = RefCell::new(Nodes::default());
        let s = [b'('; 10_000];
        assert!(expr(Cx::new(&s, &nodes), 0, &s).is_err());
        let mut s = vec![b'-'; 100_000];
        s.push(b'x');
        assert!(expr(Cx::new(&s, &nodes), 0, &s).is_err());
        let s = [b'{'; 10_000];
        assert!(expr(Cx::new(&s, &nodes), 0, &s).is_err());
        let s = b"a+".repeat(50_000);
        assert!(expr(Cx::new(&s, &nodes), 0, &s).is_err());
        let s = b"a+".repeat(30);
        assert!(expr(Cx::new(&s[..59], &nodes), 0, &s[..59]).is_ok());
    }
}
