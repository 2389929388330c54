//! Statements: the node types (one KRL line each; blocks gather the lines between an opener
//! and its closer) and the parser of one line of code, dispatched on its first word. Motions,
//! declarations and routine headers are committed (malformed → error); every other line that
//! does not parse is kept as an opaque statement, never an error — except a malformed
//! aggregate, which is an error wherever it appears.

use super::decl::{
    dat_header, declaration, enum_decl, ext, routine_header, signal, struc, DatHeader, Decl,
    EnumDecl, Ext, RoutineHeader, Signal, Struc, TypeKind,
};
use super::expr::{call, expr, path, Call, Expr};
use super::fold::FoldId;
use super::lex::{
    backtrack, expecting, first_word, ident, is_ident_char, keyword, list, only_backtracks, punct,
    sep, tok, ws, Cx, PErr, PResult,
};
use super::motion::{motion, with_clause, MotionKind, WithItem};
use super::nodes::MotionId;
use super::span::Span;
use super::tree::FileKind;
use nom::branch::alt;
use nom::combinator::{all_consuming, eof, map, not, opt, value};
use nom::multi::{fold_many0, many0};
use nom::sequence::{pair, preceded, separated_pair, terminated, tuple};

/// One statement: a line of code, or a block (opener line, nested statements, closer line).
#[derive(Clone, Debug, PartialEq)]
pub struct Stmt {
    /// Trivia before the statement: the previous line's comment and line ending, blank and
    /// comment lines (folds included), the indentation.
    pub leading: Span,
    /// The code of the first line (the opener of a block), without comment and blanks.
    pub head: Span,
    /// End of the whole statement (see `span()`).
    pub(crate) end: u32,
    /// 1-based line of the first line.
    pub line: u32,
    /// The innermost fold the statement is in.
    pub fold: Option<FoldId>,
    pub kind: StmtKind,
    /// The body of a block statement.
    pub block: Option<Box<Block>>,
}

/// The lines inside a block statement.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Block {
    /// Statements after the opener (before the first arm).
    pub body: Vec<Stmt>,
    /// `ELSE`, `CASE …`, `DEFAULT` with the statements after each.
    pub arms: Vec<Arm>,
    /// The closer (`ENDIF`, `END`, `UNTIL cond`…); `None` when missing (a warning says so).
    pub end: Option<Clause>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Arm {
    pub clause: Clause,
    pub kind: ArmKind,
    pub body: Vec<Stmt>,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ArmKind {
    Else,
    /// `CASE 1, 2`.
    Case(Vec<Expr>),
    Default,
}

/// A line of a block other than its opener (arm or closer): its trivia, code and line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clause {
    pub leading: Span,
    pub span: Span,
    pub line: u32,
}

/// What a statement is.
#[derive(Clone, Debug, PartialEq)]
pub enum StmtKind {
    /// `&ACCESS RVP`, `&REL 1`, `&PARAM EDITMASK = *`, `&COMMENT …`.
    Directive(Box<Directive>),
    /// `DEF`/`DEFFCT` … `END`/`ENDFCT` (block).
    Routine(Box<RoutineHeader>),
    /// `DEFDAT` … `ENDDAT` (block).
    DefDat(Box<DatHeader>),
    Decl(Box<Decl>),
    Struc(Box<Struc>),
    Enum(Box<EnumDecl>),
    Signal(Box<Signal>),
    Ext(Box<Ext>),
    /// A motion (`SourceFile::motion`).
    Motion(MotionId),
    /// `SPLINE` / `PTP_SPLINE` … `ENDSPLINE` (block).
    Spline(Box<SplineHead>),
    Assign(Box<Assign>),
    Call(Box<Call>),
    /// `IF cond THEN` (block; `ELSE` arm).
    If(Box<Expr>),
    /// `SWITCH expr` (block; `CASE`/`DEFAULT` arms).
    Switch(Box<Expr>),
    /// `FOR i = a TO b [STEP s]` (block); `None` when the header was not understood.
    For(Option<Box<For>>),
    /// `WHILE cond` (block).
    While(Box<Expr>),
    /// `REPEAT` … `UNTIL cond` (block); the condition of the `UNTIL` line.
    Repeat(Option<Box<Expr>>),
    /// `LOOP` … `ENDLOOP` (block).
    Loop,
    Exit,
    Halt,
    Continue,
    /// `ON_ERROR_PROCEED`: the next statement's run-time error is ignored (KSS 8.3).
    OnErrorProceed,
    /// `RESUME`: ends an interrupt routine and the routines interrupted.
    Resume,
    /// `ANOUT ON signal = value …` / `ANOUT OFF signal`: a cyclic analog output (and
    /// `ANIN ON variable = factor * $ANIN[n] …`, a cyclic analog input).
    Anout(Box<Anout>),
    /// `BRAKE` or `BRAKE F`.
    Brake(Option<Span>),
    Return(Option<Box<Expr>>),
    Goto(Span),
    /// `name:`.
    Label(Span),
    WaitFor(Box<Expr>),
    WaitSec(Box<Expr>),
    Interrupt(Box<Interrupt>),
    Trigger(Box<Trigger>),
    /// A malformed motion, declaration or aggregate (an error was recorded); bytes kept.
    Invalid,
    /// A line not understood; bytes kept, counted by `check`.
    Opaque,
}

/// `&NAME value`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Directive {
    pub name: Span,
    pub value: Span,
}

/// `ANOUT ON signal = value [DELAY = t] [MINIMUM = a] [MAXIMUM = b]` or `ANOUT OFF signal`;
/// `ANIN ON variable = value` or `ANIN OFF variable` (`input`).
#[derive(Clone, Debug, PartialEq)]
pub struct Anout {
    pub input: bool,
    pub on: bool,
    pub signal: Expr,
    /// The value (`ON` only) and the options after it, by name.
    pub value: Option<Expr>,
    pub options: Vec<(Span, Expr)>,
}

/// `SPLINE [WITH …]` or `PTP_SPLINE [WITH …]`.
#[derive(Clone, Debug, PartialEq)]
pub struct SplineHead {
    pub ptp: bool,
    pub with: Vec<WithItem>,
}

/// `lhs = rhs`.
#[derive(Clone, Debug, PartialEq)]
pub struct Assign {
    /// A variable path.
    pub lhs: Expr,
    pub rhs: Expr,
}

#[derive(Clone, Debug, PartialEq)]
pub struct For {
    pub var: Span,
    pub from: Expr,
    pub to: Expr,
    pub step: Option<Expr>,
}

/// The action of an interrupt or trigger.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    Call(Expr),
    Assign(Assign),
}

#[derive(Clone, Debug, PartialEq)]
pub enum Interrupt {
    /// `[GLOBAL] INTERRUPT DECL prio WHEN cond DO action`.
    Decl {
        global: Option<Span>,
        prio: Expr,
        cond: Expr,
        action: Action,
    },
    /// `INTERRUPT ON|OFF|ENABLE|DISABLE [n]`.
    Control { op: Span, number: Option<Expr> },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TriggerWhen {
    Distance,
    Path,
}

/// `TRIGGER WHEN DISTANCE=0 DELAY=20 DO … PRIO=-1`, `TRIGGER WHEN PATH=-10 ONSTART DO …`.
#[derive(Clone, Debug, PartialEq)]
pub struct Trigger {
    pub when: TriggerWhen,
    pub value: Expr,
    pub onstart: Option<Span>,
    pub delay: Option<Expr>,
    pub action: Action,
    pub prio: Option<Expr>,
}

impl Stmt {
    /// The whole statement, closer line included for blocks.
    pub fn span(&self) -> Span {
        Span {
            start: self.head.start,
            end: self.end,
        }
    }

    /// Everything inside the block (body and arms), in order.
    #[cfg(any(test, feature = "internals"))]
    pub fn children(&self) -> impl Iterator<Item = &Stmt> {
        self.block.iter().flat_map(|b| {
            b.body
                .iter()
                .chain(b.arms.iter().flat_map(|a| a.body.iter()))
        })
    }

    /// The motion's id (look it up with `SourceFile::motion`, or use `SourceFile::motion_of`).
    pub fn as_motion(&self) -> Option<MotionId> {
        match &self.kind {
            StmtKind::Motion(m) => Some(*m),
            _ => None,
        }
    }

    pub fn as_decl(&self) -> Option<&Decl> {
        match &self.kind {
            StmtKind::Decl(d) => Some(d),
            _ => None,
        }
    }

    /// Whether the statement (or its header) was understood.
    pub fn is_opaque(&self) -> bool {
        let opaque = |e: &Expr| e.is_opaque();
        match &self.kind {
            StmtKind::Opaque | StmtKind::For(None) => true,
            StmtKind::If(e) | StmtKind::Switch(e) | StmtKind::While(e) | StmtKind::WaitFor(e) => {
                opaque(e)
            }
            StmtKind::Repeat(Some(e)) => opaque(e),
            _ => false,
        }
    }
}

/// Which block a line opens, continues or closes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BlockKind {
    Routine,
    DefDat,
    If,
    Switch,
    For,
    While,
    Repeat,
    Loop,
    Spline,
}

impl BlockKind {
    pub fn opener(self) -> &'static str {
        match self {
            BlockKind::Routine => "DEF",
            BlockKind::DefDat => "DEFDAT",
            BlockKind::If => "IF",
            BlockKind::Switch => "SWITCH",
            BlockKind::For => "FOR",
            BlockKind::While => "WHILE",
            BlockKind::Repeat => "REPEAT",
            BlockKind::Loop => "LOOP",
            BlockKind::Spline => "SPLINE",
        }
    }

    pub fn closer(self) -> &'static str {
        match self {
            BlockKind::Routine => "END",
            BlockKind::DefDat => "ENDDAT",
            BlockKind::If => "ENDIF",
            BlockKind::Switch => "ENDSWITCH",
            BlockKind::For => "ENDFOR",
            BlockKind::While => "ENDWHILE",
            BlockKind::Repeat => "UNTIL",
            BlockKind::Loop => "ENDLOOP",
            BlockKind::Spline => "ENDSPLINE",
        }
    }
}

/// What one line of code is to the block structure.
#[derive(Debug)]
pub(crate) enum Line {
    Simple(StmtKind),
    Open(StmtKind, BlockKind),
    Arm(BlockKind, ArmKind),
    /// A closer; `UNTIL` carries its condition.
    Close(BlockKind, Option<Expr>),
}

/// A line that could not be read: the error to report, or `None` for an opaque line.
pub(crate) type LineError<'a> = Option<PErr<'a>>;

/// Parses one line of code (no comment, no surrounding blanks, not empty).
pub(crate) fn line<'a>(cx: Cx<'a>, file: FileKind, code: &'a [u8]) -> Result<Line, LineError<'a>> {
    let mut buf = [0u8; 16];
    let word = first_word(code, &mut buf);
    // Only asked when the line fails.
    let committed =
        || is_committed(word, code) || (file == FileKind::Dat && looks_like_user_decl(word, code));
    let mark = {
        let mut n = cx.nodes.borrow_mut();
        n.new_line();
        n.mark()
    };
    let result = statement(cx, file, word, code);
    if !matches!(&result, Ok((rest, _)) if rest.is_empty()) {
        // Whatever the failed line added to the pools is unreferenced: drop it.
        cx.nodes.borrow_mut().reset(mark);
    }
    match result {
        Ok((b"", l)) => Ok(l),
        Ok((rest, _)) => {
            if committed() {
                Err(Some(PErr {
                    at: rest,
                    msg: &super::lex::Msg {
                        label: "unexpected text after the statement",
                        help: "one statement per line; comments start with ;",
                    },
                }))
            } else {
                Err(None)
            }
        }
        Err(nom::Err::Failure(e)) if committed() || is_hard(&e) => Err(Some(e)),
        Err(_) => Err(None),
    }
}

/// Lines whose malformation is an error: motions, declarations, routine and data headers.
fn is_committed(word: &[u8], code: &[u8]) -> bool {
    if word == b"GLOBAL" {
        let rest = &code[6..];
        let mut buf = [0u8; 16];
        let w2 = first_word(ws(rest).map_or(rest, |r| r.0), &mut buf);
        return is_committed(w2, rest) && w2 != b"GLOBAL";
    }
    MotionKind::from_keyword(word).is_some()
        || TypeKind::builtin(word).is_some()
        || matches!(word, b"DECL" | b"DEF" | b"DEFFCT" | b"DEFDAT")
}

/// Words that start a statement other than a declaration.
const STATEMENT_WORDS: &[&[u8]] = &[
    b"ENDDAT",
    b"STRUC",
    b"ENUM",
    b"SIGNAL",
    b"EXT",
    b"EXTFCT",
    b"EXTP",
    b"EXTFCTP",
    b"ANOUT",
    b"ANIN",
    b"SPLINE",
    b"PTP_SPLINE",
    b"IF",
    b"SWITCH",
    b"CASE",
    b"FOR",
    b"WHILE",
    b"UNTIL",
    b"BRAKE",
    b"RETURN",
    b"GOTO",
    b"WAIT",
    b"INTERRUPT",
    b"TRIGGER",
    b"GLOBAL",
    b"IMPORT",
];

/// `TYPE name…` with a user type (in a data list nothing else starts with two names).
fn looks_like_user_decl(word: &[u8], code: &[u8]) -> bool {
    if word.is_empty() || STATEMENT_WORDS.contains(&word) {
        return false;
    }
    let after = &code[word.len().min(code.len())..];
    let blanks = after
        .iter()
        .take_while(|&&b| super::lex::is_blank(b))
        .count();
    blanks > 0
        && after
            .get(blanks)
            .is_some_and(|&b| super::lex::is_ident_start(b))
}

/// Failures that are errors in any statement: malformed aggregates.
fn is_hard(e: &PErr<'_>) -> bool {
    e.label().contains("aggregate") || e.label().contains("member")
}

/// A statement, dispatched on its upper-cased first word.
fn statement<'a>(cx: Cx<'a>, file: FileKind, word: &[u8], i: &'a [u8]) -> PResult<'a, Line> {
    use StmtKind as K;
    if let Some(kind) = MotionKind::from_keyword(word) {
        let (r, m) = motion(cx, kind, i)?;
        let mut nodes = cx.nodes.borrow_mut();
        let id = MotionId(nodes.motions.len() as u32);
        nodes.push_motion(m);
        return Ok((r, Line::Simple(K::Motion(id))));
    }
    if TypeKind::builtin(word).is_some() {
        return decl_line(cx, file, i);
    }
    let alone = |l: Line| -> PResult<'a, Line> { keyword_alone(i, l) };
    match word {
        b"" if i.first() == Some(&b'&') => directive(cx, i),
        b"DEF" | b"DEFFCT" => routine_line(cx, i),
        b"DEFDAT" => {
            let (r, h) = dat_header(cx, i)?;
            Ok((r, Line::Open(K::DefDat(Box::new(h)), BlockKind::DefDat)))
        }
        b"END" | b"ENDFCT" => alone(Line::Close(BlockKind::Routine, None)),
        b"ENDDAT" => alone(Line::Close(BlockKind::DefDat, None)),
        b"DECL" => decl_line(cx, file, i),
        b"GLOBAL" => global_line(cx, file, i),
        b"STRUC" => struc(cx, i).map(|(r, s)| (r, Line::Simple(K::Struc(Box::new(s))))),
        b"ENUM" => enum_decl(cx, i).map(|(r, e)| (r, Line::Simple(K::Enum(Box::new(e))))),
        b"SIGNAL" => signal(cx, i).map(|(r, s)| (r, Line::Simple(K::Signal(Box::new(s))))),
        b"EXT" | b"EXTFCT" | b"EXTP" | b"EXTFCTP" => {
            ext(cx, i).map(|(r, e)| (r, Line::Simple(K::Ext(Box::new(e)))))
        }
        b"ANOUT" | b"ANIN" => anout_line(cx, i),
        b"SPLINE" | b"PTP_SPLINE" => spline_line(cx, word == b"PTP_SPLINE", i),
        b"ENDSPLINE" => alone(Line::Close(BlockKind::Spline, None)),
        b"IF" => if_line(cx, i),
        b"ELSE" => alone(Line::Arm(BlockKind::If, ArmKind::Else)),
        b"ENDIF" => alone(Line::Close(BlockKind::If, None)),
        b"SWITCH" => {
            let e = lenient(cx, &i[6..])?;
            Ok((
                &i[i.len()..],
                Line::Open(K::Switch(Box::new(e)), BlockKind::Switch),
            ))
        }
        b"CASE" => case_line(cx, i),
        b"DEFAULT" => alone(Line::Arm(BlockKind::Switch, ArmKind::Default)),
        b"ENDSWITCH" => alone(Line::Close(BlockKind::Switch, None)),
        b"FOR" => for_line(cx, i),
        b"ENDFOR" => alone(Line::Close(BlockKind::For, None)),
        b"WHILE" => {
            let e = lenient(cx, &i[5..])?;
            Ok((
                &i[i.len()..],
                Line::Open(K::While(Box::new(e)), BlockKind::While),
            ))
        }
        b"ENDWHILE" => alone(Line::Close(BlockKind::While, None)),
        b"REPEAT" => alone(Line::Open(K::Repeat(None), BlockKind::Repeat)),
        b"UNTIL" => {
            let e = lenient(cx, &i[5..])?;
            Ok((&i[i.len()..], Line::Close(BlockKind::Repeat, Some(e))))
        }
        b"LOOP" => alone(Line::Open(K::Loop, BlockKind::Loop)),
        b"ENDLOOP" => alone(Line::Close(BlockKind::Loop, None)),
        b"EXIT" => alone(Line::Simple(K::Exit)),
        b"HALT" => alone(Line::Simple(K::Halt)),
        b"CONTINUE" => alone(Line::Simple(K::Continue)),
        b"RESUME" => alone(Line::Simple(K::Resume)),
        b"ON_ERROR_PROCEED" => alone(Line::Simple(K::OnErrorProceed)),
        b"BRAKE" => brake_line(cx, i),
        b"RETURN" => return_line(cx, i),
        b"GOTO" => map(preceded(keyword("GOTO"), tok(ident)), |l| {
            Line::Simple(K::Goto(cx.span_of(l)))
        })(i),
        b"WAIT" => wait_line(cx, i),
        b"INTERRUPT" => interrupt_line(cx, None, i),
        b"TRIGGER" => trigger_line(cx, i),
        _ => other_line(cx, file, i),
    }
}

/// keyword_alone: a keyword alone on its line.
fn keyword_alone(i: &[u8], l: Line) -> PResult<'_, Line> {
    let (r, _) = all_consuming(terminated(ident, ws))(i)?;
    Ok((r, l))
}

/// An expression spanning the whole slice, or an opaque one; malformed aggregates still fail.
fn lenient<'a>(cx: Cx<'a>, i: &'a [u8]) -> Result<Expr, nom::Err<PErr<'a>>> {
    let (j, _) = ws(i)?;
    if j.is_empty() {
        return backtrack(j).map(|(_, e)| e);
    }
    match terminated(|x| expr(cx, 0, x), ws)(j) {
        Ok((r, e)) if r.is_empty() => Ok(e),
        Err(nom::Err::Failure(f)) if is_hard(&f) => Err(nom::Err::Failure(f)),
        _ => Ok(Expr::Opaque(cx.span_of(j))),
    }
}

/// directive: `&NAME value` (the value: the rest of the line).
fn directive<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (value, name) = preceded(punct(b'&'), terminated(ident, ws))(i)?;
    let d = Directive {
        name: cx.span_of(name),
        value: cx.span_of(value),
    };
    Ok((
        &i[i.len()..],
        Line::Simple(StmtKind::Directive(Box::new(d))),
    ))
}

/// routine_line: `[GLOBAL] DEF …` / `DEFFCT …`, nothing after the header.
fn routine_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let nothing_after = expecting!(
        "unexpected text after the routine header",
        "a routine header reads DEF name(p1:IN, p2:OUT)",
        eof,
    );
    map(
        terminated(|x| routine_header(cx, x), tok(nothing_after)),
        |h| Line::Open(StmtKind::Routine(Box::new(h)), BlockKind::Routine),
    )(i)
}

/// decl_line: a variable declaration, nothing after it.
fn decl_line<'a>(cx: Cx<'a>, file: FileKind, i: &'a [u8]) -> PResult<'a, Line> {
    let nothing_after = expecting!(
        "unexpected text after the declaration",
        "separate several variables with commas; give an initial value with =",
        eof,
    );
    map(
        terminated(
            |x| declaration(cx, file == FileKind::Dat, x),
            tok(nothing_after),
        ),
        |d| Line::Simple(StmtKind::Decl(Box::new(d))),
    )(i)
}

/// global_line: `GLOBAL` before `DEF`, `DEFFCT`, `DECL`, a type, `STRUC`, `ENUM`, `SIGNAL`,
/// `INTERRUPT` (dispatched on the word after it, as `statement` is on the first).
fn global_line<'a>(cx: Cx<'a>, file: FileKind, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, g) = terminated(keyword("GLOBAL"), ws)(i)?;
    let mut buf = [0u8; 16];
    let simple = |k| Line::Simple(k);
    match first_word(j, &mut buf) {
        b"DEF" | b"DEFFCT" => routine_line(cx, i),
        b"STRUC" => map(|x| struc(cx, x), |s| simple(StmtKind::Struc(Box::new(s))))(i),
        b"ENUM" => map(
            |x| enum_decl(cx, x),
            |e| simple(StmtKind::Enum(Box::new(e))),
        )(i),
        b"SIGNAL" => map(|x| signal(cx, x), |s| simple(StmtKind::Signal(Box::new(s))))(i),
        b"INTERRUPT" => interrupt_line(cx, Some(cx.span_of(g)), j),
        _ => decl_line(cx, file, i),
    }
}

/// spline_line: `SPLINE [WITH …]` / `PTP_SPLINE [WITH …]`.
fn spline_line<'a>(cx: Cx<'a>, ptp: bool, i: &'a [u8]) -> PResult<'a, Line> {
    // `with_clause` never backtracks (a malformed clause is a failure), so `opt` only
    // decides whether a `WITH` is there.
    map(
        preceded(
            terminated(ident, ws),
            opt(preceded(keyword("WITH"), |x| with_clause(cx, x))),
        ),
        move |with| {
            let head = SplineHead {
                ptp,
                with: with.unwrap_or_default(),
            };
            Line::Open(StmtKind::Spline(Box::new(head)), BlockKind::Spline)
        },
    )(i)
}

/// if_line: `IF cond THEN` — the condition may stay opaque, the block structure does not.
/// Hand-written: `THEN` is found from the end of the line, so a condition the expression
/// grammar does not read still opens the block.
fn if_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let n = i.len();
    let then_at = n
        .checked_sub(4)
        .filter(|&p| i[p..].eq_ignore_ascii_case(b"THEN") && p > 2 && !is_ident_char(i[p - 1]));
    let Some(p) = then_at else {
        return backtrack(i);
    };
    let cond = lenient(cx, &i[2..p])?;
    Ok((
        &i[n..],
        Line::Open(StmtKind::If(Box::new(cond)), BlockKind::If),
    ))
}

/// case_line: `CASE v {, v}`.
fn case_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    map(
        preceded(pair(keyword("CASE"), sep), |x| list(x, |y| expr(cx, 0, y))),
        |values| Line::Arm(BlockKind::Switch, ArmKind::Case(values)),
    )(i)
}

/// for_line: `FOR var = from TO to [STEP step]`; an unreadable header keeps the block.
fn for_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let open = |f| Line::Open(StmtKind::For(f), BlockKind::For);
    match terminated(|x| for_header(cx, x), ws)(i) {
        Ok((r, f)) if r.is_empty() => Ok((r, open(Some(Box::new(f))))),
        Err(nom::Err::Failure(e)) if is_hard(&e) => Err(nom::Err::Failure(e)),
        _ => Ok((&i[i.len()..], open(None))),
    }
}

/// for_header: `FOR var = from TO to [STEP step]`.
fn for_header<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, For> {
    let e = |x| expr(cx, 0, x);
    map(
        tuple((
            preceded(keyword("FOR"), tok(ident)),
            preceded(tok(punct(b'=')), tok(e)),
            preceded(tok(keyword("TO")), tok(e)),
            opt(preceded(tok(keyword("STEP")), tok(e))),
        )),
        |(var, from, to, step)| For {
            var: cx.span_of(var),
            from,
            to,
            step,
        },
    )(i)
}

/// anout_line: `ANOUT ON signal = value {option = value}` / `ANOUT OFF signal`, and the same
/// with `ANIN`.
fn anout_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let e = |x| expr(cx, 0, x);
    let signal = |x| path(cx, 0, x);
    let option = separated_pair(ident, tok(punct(b'=')), tok(e));
    let on = map(
        preceded(
            keyword("ON"),
            tuple((
                tok(signal),
                preceded(tok(punct(b'=')), tok(e)),
                many0(tok(option)),
            )),
        ),
        |(signal, value, options)| (true, signal, Some(value), options),
    );
    let off = map(preceded(keyword("OFF"), tok(signal)), |signal| {
        (false, signal, None, Vec::new())
    });
    let (r, (word, (on, signal, value, options))) =
        terminated(pair(terminated(ident, ws), alt((on, off))), ws)(i)?;
    let a = Anout {
        input: word.eq_ignore_ascii_case(b"ANIN"),
        on,
        signal,
        value,
        options: options
            .into_iter()
            .map(|(name, v)| (cx.span_of(name), v))
            .collect(),
    };
    Ok((r, Line::Simple(StmtKind::Anout(Box::new(a)))))
}

/// brake_line: `BRAKE` or `BRAKE F`.
fn brake_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    map(preceded(keyword("BRAKE"), tok(opt(keyword("F")))), |f| {
        Line::Simple(StmtKind::Brake(f.map(|f| cx.span_of(f))))
    })(i)
}

/// return_line: `RETURN [value]`.
fn return_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    map(
        preceded(keyword("RETURN"), tok(opt(|x| expr(cx, 0, x)))),
        |e| Line::Simple(StmtKind::Return(e.map(Box::new))),
    )(i)
}

/// wait_line: `WAIT FOR cond` / `WAIT SEC time`.
fn wait_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let wait_for = |k: &'a [u8]| -> PResult<'a, Line> {
        let e = lenient(cx, k)?;
        Ok((&k[k.len()..], Line::Simple(StmtKind::WaitFor(Box::new(e)))))
    };
    let wait_sec = map(preceded(keyword("SEC"), tok(|x| expr(cx, 0, x))), |e| {
        Line::Simple(StmtKind::WaitSec(Box::new(e)))
    });
    preceded(
        keyword("WAIT"),
        tok(alt((preceded(keyword("FOR"), wait_for), wait_sec))),
    )(i)
}

/// interrupt_line: `INTERRUPT DECL prio WHEN cond DO action` / `INTERRUPT
/// ON|OFF|ENABLE|DISABLE [n]`.
fn interrupt_line<'a>(cx: Cx<'a>, global: Option<Span>, i: &'a [u8]) -> PResult<'a, Line> {
    let e = |x| expr(cx, 0, x);
    let decl = map(
        tuple((
            preceded(keyword("DECL"), tok(e)),
            preceded(tok(keyword("WHEN")), tok(e)),
            preceded(tok(keyword("DO")), tok(|x| action(cx, x))),
        )),
        |(prio, cond, action)| Interrupt::Decl {
            global,
            prio,
            cond,
            action,
        },
    );
    let op = alt((
        keyword("ON"),
        keyword("OFF"),
        keyword("ENABLE"),
        keyword("DISABLE"),
    ));
    let control = map(pair(op, tok(opt(e))), |(op, number)| Interrupt::Control {
        op: cx.span_of(op),
        number,
    });
    map(
        preceded(keyword("INTERRUPT"), tok(alt((decl, control)))),
        |it| Line::Simple(StmtKind::Interrupt(Box::new(it))),
    )(i)
}

/// trigger_line: `TRIGGER WHEN (DISTANCE|PATH) = v [ONSTART] [DELAY = d] DO action
/// [PRIO = p]`.
fn trigger_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let e = |x| expr(cx, 0, x);
    let setting = |word| preceded(pair(keyword(word), tok(punct(b'='))), tok(e));
    let when = alt((
        value(TriggerWhen::Distance, keyword("DISTANCE")),
        value(TriggerWhen::Path, keyword("PATH")),
    ));
    // `ONSTART` and `DELAY = d` in any order, the last of each kept.
    let options = fold_many0(
        tok(alt((
            map(keyword("ONSTART"), |o| (Some(o), None)),
            map(setting("DELAY"), |d| (None, Some(d))),
        ))),
        || (None, None),
        |(onstart, delay), (o, d)| (o.or(onstart), d.or(delay)),
    );
    let (r, (when, value, (onstart, delay), action, prio)) = preceded(
        pair(keyword("TRIGGER"), tok(keyword("WHEN"))),
        tuple((
            tok(when),
            preceded(tok(punct(b'=')), tok(e)),
            options,
            preceded(tok(keyword("DO")), tok(|x| action(cx, x))),
            opt(tok(setting("PRIO"))),
        )),
    )(i)?;
    let t = Trigger {
        when,
        value,
        onstart: onstart.map(|o| cx.span_of(o)),
        delay,
        action,
        prio,
    };
    Ok((r, Line::Simple(StmtKind::Trigger(Box::new(t)))))
}

/// action: a call or an assignment (the `DO` part of interrupts and triggers). An assignment
/// that fails in any way leaves the line to the call.
fn action<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Action> {
    alt((
        map(only_backtracks(|x| assignment(cx, x)), Action::Assign),
        map(|x| call(cx, 0, x), Action::Call),
    ))(i)
}

/// assignment: `path = expr` (not `==`).
fn assignment<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Assign> {
    map(
        separated_pair(
            |x| path(cx, 0, x),
            tok(terminated(punct(b'='), not(punct(b'=')))),
            tok(|x| expr(cx, 0, x)),
        ),
        |(lhs, rhs)| Assign { lhs, rhs },
    )(i)
}

/// other_line: labels, assignments, calls, user-type declarations; anything else is opaque.
/// Dispatched on what follows the first name, as `statement` is on the first word.
fn other_line<'a>(cx: Cx<'a>, file: FileKind, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, name) = ident(i)?;
    let (k, blanks) = ws(j)?;
    match k.first() {
        Some(b':') => {
            let (r, _) = all_consuming(preceded(punct(b':'), ws))(k)?;
            Ok((r, Line::Simple(StmtKind::Label(cx.span_of(name)))))
        }
        Some(b'(') => {
            let (r, c) = call(cx, 0, i)?;
            let Expr::Call(c) = c else {
                return backtrack(i);
            };
            Ok((r, Line::Simple(StmtKind::Call(c))))
        }
        Some(&b) if !blanks.is_empty() && (b.is_ascii_alphabetic() || b == b'_' || b == b'$') => {
            decl_line(cx, file, i)
        }
        _ => map(
            |x| assignment(cx, x),
            |a| Line::Simple(StmtKind::Assign(Box::new(a))),
        )(i),
    }
}
