//! Declarations, in `.src` and `.dat` alike: variables (`DECL`, optional; `GLOBAL`, `CONST`;
//! built-in and user types; arrays of up to three dimensions; initialisers on the same line),
//! user types (`STRUC`, `ENUM`), `SIGNAL`, external routines (`EXT`, `EXTFCT` and the
//! protected `EXTP`, `EXTFCTP` of system files), and the headers of routines (`DEF`,
//! `DEFFCT` with `p:IN`, `a[,]:OUT` parameters, an array return type `CHAR[15]`) and data lists
//! (`DEFDAT name PUBLIC`). A line starting with `DECL` or a built-in type is committed:
//! malformed means error, because position data would otherwise go unseen.

use super::expr::{expr, Expr};
use super::lex::{
    expecting, fail, ident, is_ident_char, keyword, list, next_item, punct, sep, ws, Cx, Fails,
    PResult,
};
use super::span::Span;

/// The type of a declaration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TypeKind {
    Int,
    Real,
    Bool,
    Char,
    Frame,
    Pos,
    E6Pos,
    Axis,
    E6Axis,
    Fdat,
    Pdat,
    Ldat,
    /// A `STRUC`/`ENUM` type or any other named type (`LOAD`, `BASIS_SUGG_T`…).
    User,
}

impl TypeKind {
    /// The built-in type named by an upper-case keyword.
    pub fn builtin(upper: &[u8]) -> Option<TypeKind> {
        use TypeKind::*;
        Some(match upper {
            b"INT" => Int,
            b"REAL" => Real,
            b"BOOL" => Bool,
            b"CHAR" => Char,
            b"FRAME" => Frame,
            b"POS" => Pos,
            b"E6POS" => E6Pos,
            b"AXIS" => Axis,
            b"E6AXIS" => E6Axis,
            b"FDAT" => Fdat,
            b"PDAT" => Pdat,
            b"LDAT" => Ldat,
            _ => return None,
        })
    }

    fn of(name: &[u8]) -> TypeKind {
        let mut buf = [0u8; 8];
        if name.len() > buf.len() {
            return TypeKind::User;
        }
        for (d, s) in buf.iter_mut().zip(name) {
            *d = s.to_ascii_uppercase();
        }
        TypeKind::builtin(&buf[..name.len()]).unwrap_or(TypeKind::User)
    }

    /// A robot position: `FRAME POS E6POS AXIS E6AXIS`.
    pub fn is_position(self) -> bool {
        use TypeKind::*;
        matches!(self, Frame | Pos | E6Pos | Axis | E6Axis)
    }

    /// A position given by axis angles: `AXIS E6AXIS`.
    pub fn is_axis(self) -> bool {
        matches!(self, TypeKind::Axis | TypeKind::E6Axis)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TypeRef {
    pub kind: TypeKind,
    pub span: Span,
}

/// `[GLOBAL] [DECL] [GLOBAL] [CONST] TYPE var {, var}`.
#[derive(Clone, Debug, PartialEq)]
pub struct Decl {
    pub global: Option<Span>,
    /// The `DECL` keyword, when written.
    pub decl: Option<Span>,
    pub constant: Option<Span>,
    pub ty: TypeRef,
    pub vars: Vec<DeclVar>,
}

/// `name [dims] [= value]`.
#[derive(Clone, Debug, PartialEq)]
pub struct DeclVar {
    pub span: Span,
    pub name: Span,
    pub dims: Option<Dims>,
    pub init: Option<Expr>,
}

/// `[30000]`, `[10,3]`: one size expression per dimension (`None` when left empty).
#[derive(Clone, Debug, PartialEq)]
pub struct Dims {
    pub span: Span,
    pub sizes: Vec<Option<Expr>>,
}

/// `[GLOBAL] STRUC name TYPE m1, m2, TYPE2 m3`.
#[derive(Clone, Debug, PartialEq)]
pub struct Struc {
    pub global: Option<Span>,
    pub name: Span,
    pub fields: Vec<(TypeRef, Vec<DeclVar>)>,
}

/// `[GLOBAL] ENUM name v1, v2`.
#[derive(Clone, Debug, PartialEq)]
pub struct EnumDecl {
    pub global: Option<Span>,
    pub name: Span,
    pub values: Vec<Span>,
}

/// `[GLOBAL] SIGNAL name $OUT[1] [TO $OUT[8]]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Signal {
    pub global: Option<Span>,
    pub name: Span,
    pub from: Expr,
    pub to: Option<Expr>,
}

/// `EXT name(params)` / `EXTFCT TYPE name(params)` (or the protected `EXTP`, `EXTFCTP`);
/// parameters kept as text.
#[derive(Clone, Debug, PartialEq)]
pub struct Ext {
    pub function: bool,
    /// `EXTP` / `EXTFCTP`.
    pub protected: bool,
    pub ret: Option<TypeRef>,
    pub name: Span,
    pub params: Span,
}

/// Header of `[GLOBAL] DEF name(params)` or `[GLOBAL] DEFFCT TYPE name(params)`.
#[derive(Clone, Debug, PartialEq)]
pub struct RoutineHeader {
    pub global: Option<Span>,
    pub function: bool,
    pub ret: Option<TypeRef>,
    pub name: Span,
    pub params: Vec<Param>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamMode {
    In,
    Out,
    /// No `:IN`/`:OUT` written.
    Default,
}

/// `name[,]:OUT`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Param {
    pub span: Span,
    pub name: Span,
    /// `[]`, `[,]` of an array parameter (or `[256]`, a size as system listings write it).
    pub array: Option<Span>,
    pub mode: ParamMode,
}

/// `DEFDAT name [PUBLIC]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DatHeader {
    pub name: Span,
    pub public: Option<Span>,
}

const HELP_DECL: &str =
    "declarations read DECL TYPE name[size] = value, e.g. DECL E6POS XP1={X 0,Y 0,Z 0,A 0,B 0,C 0}";

fn opt_word<'a>(word: &'static str, i: &'a [u8]) -> (&'a [u8], Option<&'a [u8]>) {
    match keyword(word)(i) {
        Ok((r, w)) => match sep(r) {
            Ok((r, _)) => (r, Some(w)),
            Err(_) => (i, None),
        },
        Err(_) => (i, None),
    }
}

/// A variable declaration. Committed once `DECL` or a built-in type is seen, or when
/// `commit_user` says a user type is certain (data lists).
pub(crate) fn declaration<'a>(cx: Cx<'a>, commit_user: bool, i: &'a [u8]) -> PResult<'a, Decl> {
    let (j, global) = opt_word("GLOBAL", i);
    let (j, decl) = opt_word("DECL", j);
    let (j, global2) = opt_word("GLOBAL", j);
    let (j, constant) = opt_word("CONST", j);
    let (k, ty) = match ident(j) {
        Ok(r) => r,
        Err(_) if decl.is_some() => {
            return fail!(j, "expected a type after DECL", HELP_DECL);
        }
        Err(e) => return Err(e),
    };
    let kind = TypeKind::of(ty);
    let committed = decl.is_some() || kind != TypeKind::User || commit_user;
    let body = |x| decl_vars(cx, x);
    let (rest, vars) = if committed {
        expecting!("expected a variable name after the type", HELP_DECL, body)(k)?
    } else {
        body(k)?
    };
    Ok((
        rest,
        Decl {
            global: global.or(global2).map(|g| cx.span_of(g)),
            decl: decl.map(|d| cx.span_of(d)),
            constant: constant.map(|c| cx.span_of(c)),
            ty: TypeRef {
                kind,
                span: cx.span_of(ty),
            },
            vars,
        },
    ))
}

/// Blanks then `var {, var}`.
fn decl_vars<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Vec<DeclVar>> {
    let (j, blanks) = ws(i)?;
    if blanks.is_empty() {
        return super::lex::backtrack(i);
    }
    let (mut j, first) = decl_var(cx, j)?;
    let mut vars = vec![first];
    loop {
        let Some(k) = next_item(j) else {
            return Ok((j, vars));
        };
        // After a comma the next name is certain: a failure is the user's error.
        let (k, v) = expecting!("expected a variable name after `,`", HELP_DECL, |x| {
            decl_var(cx, x)
        })(k)?;
        vars.push(v);
        j = k;
    }
}

/// `name [dims] [= value]`.
fn decl_var<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, DeclVar> {
    let (mut j, name) = ident(i)?;
    let mut dims = None;
    let (k, _) = ws(j)?;
    if k.first() == Some(&b'[') {
        let (k2, d) = dims_list(cx, k)?;
        dims = Some(d);
        j = k2;
    }
    let mut init = None;
    let (k, _) = ws(j)?;
    if let Ok((k2, _)) = punct(b'=')(k) {
        let (k3, _) = ws(k2)?;
        let (k4, value) = expecting!("expected an initial value after `=`", HELP_DECL, |x| {
            expr(cx, 0, x)
        })(k3)?;
        init = Some(value);
        j = k4;
    }
    Ok((
        j,
        DeclVar {
            span: cx.span(i, j),
            name: cx.span_of(name),
            dims,
            init,
        },
    ))
}

/// `[ [size] {, [size]} ]`, one to three dimensions.
fn dims_list<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Dims> {
    let (mut j, _) = punct(b'[')(i)?;
    let mut sizes = Vec::new();
    loop {
        let (k, _) = ws(j)?;
        let (k, size) = match k.first() {
            Some(b',') | Some(b']') => (k, None),
            _ => {
                let (k, e) =
                    expecting!("expected an array size", HELP_DECL, |x| expr(cx, 0, x))(k)?;
                (k, Some(e))
            }
        };
        sizes.push(size);
        let (k, _) = ws(k)?;
        if let Ok((k, _)) = punct(b',')(k) {
            j = k;
            continue;
        }
        let (k, _) = expecting!("expected `]` after the array size", HELP_DECL, punct(b']'))(k)?;
        if sizes.len() > 3 {
            return fail!(i, "an array has at most three dimensions", HELP_DECL);
        }
        return Ok((
            k,
            Dims {
                span: cx.span(i, k),
                sizes,
            },
        ));
    }
}

/// `[GLOBAL] WORD name` and the blanks after it: (rest, (`GLOBAL` span, name span)).
fn named_head<'a>(cx: Cx<'a>, word: &'static str, i: &'a [u8]) -> Fails<'a, (Option<Span>, Span)> {
    let (j, global) = opt_word("GLOBAL", i);
    let (j, _) = keyword(word)(j)?;
    let (j, _) = ws(j)?;
    let (j, name) = ident(j)?;
    let (j, _) = ws(j)?;
    Ok((j, (global.map(|g| cx.span_of(g)), cx.span_of(name))))
}

/// `[GLOBAL] STRUC name TYPE m {, m} {, TYPE m {, m}}`.
pub(crate) fn struc<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Struc> {
    let (j, (global, name)) = named_head(cx, "STRUC", i)?;
    let mut fields: Vec<(TypeRef, Vec<DeclVar>)> = Vec::new();
    let (j, _) = list(j, |j| {
        // `TYPE name` starts a new group; a lone `name` continues the current one.
        let (k, first) = ident(j)?;
        let (k2, blanks) = ws(k)?;
        if !blanks.is_empty() && k2.first().is_some_and(|&b| is_ident_char(b)) {
            let (k3, v) = decl_var(cx, k2)?;
            fields.push((
                TypeRef {
                    kind: TypeKind::of(first),
                    span: cx.span_of(first),
                },
                vec![v],
            ));
            Ok((k3, ()))
        } else {
            let Some(last) = fields.last_mut() else {
                return super::lex::backtrack(j);
            };
            let (k3, v) = decl_var(cx, j)?;
            last.1.push(v);
            Ok((k3, ()))
        }
    })?;
    Ok((
        j,
        Struc {
            global,
            name,
            fields,
        },
    ))
}

/// `[GLOBAL] ENUM name v {, v}`.
pub(crate) fn enum_decl<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, EnumDecl> {
    let (j, (global, name)) = named_head(cx, "ENUM", i)?;
    let (j, values) = list(j, |x| ident(x).map(|(k, v)| (k, cx.span_of(v))))?;
    Ok((
        j,
        EnumDecl {
            global,
            name,
            values,
        },
    ))
}

/// `[GLOBAL] SIGNAL name expr [TO expr]`.
pub(crate) fn signal<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Signal> {
    let (j, (global, name)) = named_head(cx, "SIGNAL", i)?;
    let (mut j, from) = expr(cx, 0, j)?;
    let mut to = None;
    let (k, _) = ws(j)?;
    if let Ok((k, _)) = keyword("TO")(k) {
        let (k, _) = ws(k)?;
        let (k, e) = expr(cx, 0, k)?;
        to = Some(e);
        j = k;
    }
    Ok((
        j,
        Signal {
            global,
            name,
            from,
            to,
        },
    ))
}

/// `WORD name` or `FCT_WORD TYPE name` (`EXT`/`EXTFCT`, `DEF`/`DEFFCT`, each also with a
/// `P` for the protected forms when `protected` allows them) and the blanks after the
/// name: (rest, (is a function, is protected, return type, name)). A function's type may be
/// an array (`CHAR[15]`).
#[allow(clippy::type_complexity)]
fn callable_head<'a>(
    cx: Cx<'a>,
    word: &[u8],
    fct_word: &[u8],
    protected_forms: bool,
    i: &'a [u8],
) -> Fails<'a, (bool, bool, Option<TypeRef>, &'a [u8])> {
    // A routine's name is a module's (see `module_name`); an external declaration's an ident.
    let name_of = if protected_forms { ident } else { module_name };
    let (j, kw) = ident(i)?;
    let is = |w: &[u8], p: bool| {
        let (base, tail) = kw.split_at(kw.len().min(w.len()));
        base.eq_ignore_ascii_case(w)
            && if p {
                protected_forms && tail.eq_ignore_ascii_case(b"P")
            } else {
                tail.is_empty()
            }
    };
    let (function, protected) = match () {
        _ if is(fct_word, false) => (true, false),
        _ if is(word, false) => (false, false),
        _ if is(fct_word, true) => (true, true),
        _ if is(word, true) => (false, true),
        _ => return super::lex::backtrack(i),
    };
    let (mut j, _) = ws(j)?;
    let mut ret = None;
    if function {
        let (k, t) = ident(j)?;
        ret = Some(TypeRef {
            kind: TypeKind::of(t),
            span: cx.span_of(t),
        });
        let (k2, _) = ws(k)?;
        let k = match k2.first() {
            // `CHAR[15]`: a string (or array) result.
            Some(b'[') => match k2.iter().position(|&b| b == b']') {
                Some(n) => &k2[n + 1..],
                None => return super::lex::backtrack(k2),
            },
            _ => k,
        };
        j = ws(k)?.0;
    }
    let (j, name) = name_of(j)?;
    let (j, _) = ws(j)?;
    Ok((j, (function, protected, ret, name)))
}

/// `EXT name(…)` or `EXTFCT TYPE name(…)`, or the protected `EXTP`, `EXTFCTP`.
pub(crate) fn ext<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Ext> {
    let (j, (function, protected, ret, name)) = callable_head(cx, b"EXT", b"EXTFCT", true, i)?;
    let (rest, params) = paren_text(j)?;
    Ok((
        rest,
        Ext {
            function,
            protected,
            ret,
            name: cx.span_of(name),
            params: cx.span_of(params),
        },
    ))
}

/// `( … )` with balanced brackets, as text.
fn paren_text(i: &[u8]) -> PResult<'_, &[u8]> {
    if i.first() != Some(&b'(') {
        return super::lex::backtrack(i);
    }
    let mut depth = 0usize;
    for (n, &b) in i.iter().enumerate() {
        match b {
            b'(' => depth += 1,
            b')' => {
                depth -= 1;
                if depth == 0 {
                    return Ok((&i[n + 1..], &i[..n + 1]));
                }
            }
            _ => {}
        }
    }
    super::lex::backtrack(i)
}

/// The name after `DEF`/`DEFFCT`/`DEFDAT`: a KRL name, or — as generators write the path
/// of the file into it (`DEF Archivos_KRL/Contorno_KRL/cilindro( )`) — any bytes up to a
/// blank, `(` or `;`. A name that is not a KRL name is a warning on it (`tree::lines`), the
/// module otherwise read as any other; `is_name` tells which.
pub(crate) fn module_name(i: &[u8]) -> PResult<'_, &[u8]> {
    let n = i
        .iter()
        .take_while(|&&b| !super::lex::is_blank(b) && !matches!(b, b'(' | b';'))
        .count();
    if n == 0 {
        return super::lex::backtrack(i);
    }
    Ok((&i[n..], &i[..n]))
}

/// Whether `name` is a KRL name (a letter, `_` or `$`, then letters, digits, `_`, `$`).
pub(crate) fn is_name(name: &[u8]) -> bool {
    matches!(ident(name), Ok((rest, _)) if rest.is_empty())
}

const HELP_DEF: &str = "routines start with DEF name(p1:IN, p2:OUT) or DEFFCT TYPE name()";

/// `[GLOBAL] DEF name ( params )` / `[GLOBAL] DEFFCT TYPE name ( params )`.
pub(crate) fn routine_header<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, RoutineHeader> {
    let (j, global) = opt_word("GLOBAL", i);
    let (j, (function, _, ret, name)) = callable_head(cx, b"DEF", b"DEFFCT", false, j)?;
    let (mut j, _) = punct(b'(')(j)?;
    let mut params = Vec::new();
    let (k, _) = ws(j)?;
    if let Ok((k, _)) = punct(b')')(k) {
        j = k;
    } else {
        loop {
            let (k, _) = ws(j)?;
            let (k, p) = expecting!("expected a parameter name", HELP_DEF, |x| param(cx, x))(k)?;
            params.push(p);
            let (k, _) = ws(k)?;
            if let Ok((k, _)) = punct(b',')(k) {
                j = k;
                continue;
            }
            let (k, _) = expecting!("expected `)` after the parameters", HELP_DEF, punct(b')'))(k)?;
            j = k;
            break;
        }
    }
    Ok((
        j,
        RoutineHeader {
            global: global.map(|g| cx.span_of(g)),
            function,
            ret,
            name: cx.span_of(name),
            params,
        },
    ))
}

/// `name [ [ {,} ] ] [ : IN | : OUT ]`.
fn param<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Param> {
    let (mut j, name) = ident(i)?;
    let mut array = None;
    if j.first() == Some(&b'[') {
        let n = j.iter().position(|&b| b == b']').map(|p| p + 1);
        // `[]`, `[,]`; a size (`[256]`) as system listings write it.
        let Some(n) = n.filter(|&n| {
            j[1..n - 1]
                .iter()
                .all(|&b| b == b',' || b == b' ' || b.is_ascii_digit())
        }) else {
            return fail!(
                j,
                "expected `[]` or `[,]` after an array parameter",
                HELP_DEF,
            );
        };
        array = Some(cx.span_of(&j[..n]));
        j = &j[n..];
    }
    let mut mode = ParamMode::Default;
    let (k, _) = ws(j)?;
    if let Ok((k, _)) = punct(b':')(k) {
        let (at, _) = ws(k)?;
        let (k, m) = expecting!("expected IN or OUT after `:`", HELP_DEF, ident)(at)?;
        mode = if m.eq_ignore_ascii_case(b"IN") {
            ParamMode::In
        } else if m.eq_ignore_ascii_case(b"OUT") {
            ParamMode::Out
        } else {
            return fail!(at, "expected IN or OUT after `:`", HELP_DEF);
        };
        j = k;
    }
    Ok((
        j,
        Param {
            span: cx.span(i, j),
            name: cx.span_of(name),
            array,
            mode,
        },
    ))
}

/// `DEFDAT name [PUBLIC]`.
pub(crate) fn dat_header<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, DatHeader> {
    let (j, _) = keyword("DEFDAT")(i)?;
    let (j, _) = ws(j)?;
    let (j, name) = module_name(j)?;
    let (k, _) = ws(j)?;
    let (rest, public) = match keyword("PUBLIC")(k) {
        Ok((r, p)) => (r, Some(cx.span_of(p))),
        Err(_) => (j, None),
    };
    Ok((
        rest,
        DatHeader {
            name: cx.span_of(name),
            public,
        },
    ))
}
