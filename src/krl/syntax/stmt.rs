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
    backtrack, fail, first_word, ident, is_ident_char, keyword, list, punct, sep, ws, Cx, PErr,
    PResult,
};
use super::motion::{motion, with_clause, MotionKind, WithItem};
use super::nodes::MotionId;
use super::span::Span;
use super::tree::FileKind;

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
        b"GOTO" => {
            let (j, _) = keyword("GOTO")(i)?;
            let (j, _) = ws(j)?;
            let (r, l) = ident(j)?;
            Ok((r, Line::Simple(K::Goto(cx.span_of(l)))))
        }
        b"WAIT" => wait_line(cx, i),
        b"INTERRUPT" => interrupt_line(cx, None, i),
        b"TRIGGER" => trigger_line(cx, i),
        _ => other_line(cx, file, i),
    }
}

/// A keyword alone on its line.
fn keyword_alone(i: &[u8], l: Line) -> PResult<'_, Line> {
    let (r, _) = ident(i)?;
    let (r, _) = ws(r)?;
    if r.is_empty() {
        Ok((r, l))
    } else {
        backtrack(i)
    }
}

/// An expression spanning the whole slice, or an opaque one; malformed aggregates still fail.
fn lenient<'a>(cx: Cx<'a>, i: &'a [u8]) -> Result<Expr, nom::Err<PErr<'a>>> {
    let (j, _) = ws(i)?;
    if j.is_empty() {
        return backtrack(j).map(|(_, e)| e);
    }
    match expr(cx, 0, j) {
        Ok((r, e)) if ws(r)?.0.is_empty() => Ok(e),
        Err(nom::Err::Failure(f)) if is_hard(&f) => Err(nom::Err::Failure(f)),
        _ => Ok(Expr::Opaque(cx.span_of(j))),
    }
}

/// `&NAME value`.
fn directive<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, name) = ident(&i[1..])?;
    let (value, _) = ws(j)?;
    Ok((
        &i[i.len()..],
        Line::Simple(StmtKind::Directive(Box::new(Directive {
            name: cx.span_of(name),
            value: cx.span_of(value),
        }))),
    ))
}

/// `[GLOBAL] DEF …` / `DEFFCT …`.
fn routine_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (r, h) = routine_header(cx, i)?;
    let (r, _) = ws(r)?;
    if !r.is_empty() {
        return fail!(
            r,
            "unexpected text after the routine header",
            "a routine header reads DEF name(p1:IN, p2:OUT)",
        );
    }
    Ok((
        r,
        Line::Open(StmtKind::Routine(Box::new(h)), BlockKind::Routine),
    ))
}

/// A variable declaration line; trailing text is an error.
fn decl_line<'a>(cx: Cx<'a>, file: FileKind, i: &'a [u8]) -> PResult<'a, Line> {
    let (r, d) = declaration(cx, file == FileKind::Dat, i)?;
    let (r, _) = ws(r)?;
    if !r.is_empty() {
        return fail!(
            r,
            "unexpected text after the declaration",
            "separate several variables with commas; give an initial value with =",
        );
    }
    Ok((r, Line::Simple(StmtKind::Decl(Box::new(d)))))
}

/// `GLOBAL` before `DEF`, `DEFFCT`, `DECL`, a type, `STRUC`, `ENUM`, `SIGNAL`, `INTERRUPT`.
fn global_line<'a>(cx: Cx<'a>, file: FileKind, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, g) = keyword("GLOBAL")(i)?;
    let (j, _) = ws(j)?;
    let mut buf = [0u8; 16];
    let w = first_word(j, &mut buf);
    match w {
        b"DEF" | b"DEFFCT" => routine_line(cx, i),
        b"STRUC" => struc(cx, i).map(|(r, s)| (r, Line::Simple(StmtKind::Struc(Box::new(s))))),
        b"ENUM" => enum_decl(cx, i).map(|(r, e)| (r, Line::Simple(StmtKind::Enum(Box::new(e))))),
        b"SIGNAL" => signal(cx, i).map(|(r, s)| (r, Line::Simple(StmtKind::Signal(Box::new(s))))),
        b"INTERRUPT" => interrupt_line(cx, Some(cx.span_of(g)), j),
        _ => decl_line(cx, file, i),
    }
}

/// `SPLINE [WITH …]` / `PTP_SPLINE [WITH …]`.
fn spline_line<'a>(cx: Cx<'a>, ptp: bool, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, _) = ident(i)?;
    let (j, _) = ws(j)?;
    let (r, with) = match keyword("WITH")(j) {
        Ok((k, _)) => with_clause(cx, k)?,
        Err(_) => (j, Vec::new()),
    };
    Ok((
        r,
        Line::Open(
            StmtKind::Spline(Box::new(SplineHead { ptp, with })),
            BlockKind::Spline,
        ),
    ))
}

/// `IF cond THEN` — the condition may stay opaque, the block structure does not.
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

/// `CASE v {, v}`.
fn case_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, _) = keyword("CASE")(i)?;
    let (j, _) = sep(j)?;
    let (k, values) = list(j, |x| expr(cx, 0, x))?;
    Ok((k, Line::Arm(BlockKind::Switch, ArmKind::Case(values))))
}

/// `FOR var = from TO to [STEP step]`; an unreadable header keeps the block.
fn for_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let open = |f| Line::Open(StmtKind::For(f), BlockKind::For);
    match for_header(cx, i) {
        Ok((r, f)) if ws(r)?.0.is_empty() => Ok((&i[i.len()..], open(Some(Box::new(f))))),
        Err(nom::Err::Failure(e)) if is_hard(&e) => Err(nom::Err::Failure(e)),
        _ => Ok((&i[i.len()..], open(None))),
    }
}

fn for_header<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, For> {
    let (j, _) = keyword("FOR")(i)?;
    let (j, _) = ws(j)?;
    let (j, var) = ident(j)?;
    let (j, _) = ws(j)?;
    let (j, _) = punct(b'=')(j)?;
    let (j, _) = ws(j)?;
    let (j, from) = expr(cx, 0, j)?;
    let (j, _) = ws(j)?;
    let (j, _) = keyword("TO")(j)?;
    let (j, _) = ws(j)?;
    let (mut j, to) = expr(cx, 0, j)?;
    let mut step = None;
    let (k, _) = ws(j)?;
    if let Ok((k, _)) = keyword("STEP")(k) {
        let (k, _) = ws(k)?;
        let (k, s) = expr(cx, 0, k)?;
        step = Some(s);
        j = k;
    }
    Ok((
        j,
        For {
            var: cx.span_of(var),
            from,
            to,
            step,
        },
    ))
}

/// `ANOUT ON signal = value {option = value}` / `ANOUT OFF signal`, and the same with `ANIN`.
fn anout_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, word) = ident(i)?;
    let input = word.eq_ignore_ascii_case(b"ANIN");
    let (j, _) = ws(j)?;
    let (j, op) = ident(j)?;
    let on = op.eq_ignore_ascii_case(b"ON");
    if !on && !op.eq_ignore_ascii_case(b"OFF") {
        return backtrack(j);
    }
    let (j, _) = ws(j)?;
    let (mut j, signal) = path(cx, 0, j)?;
    let mut value = None;
    let mut options = Vec::new();
    if on {
        let (k, _) = ws(j)?;
        let (k, _) = punct(b'=')(k)?;
        let (k, _) = ws(k)?;
        let (k, v) = expr(cx, 0, k)?;
        value = Some(v);
        j = k;
        loop {
            let (k, _) = ws(j)?;
            let Ok((k2, name)) = ident(k) else { break };
            let (k2, _) = ws(k2)?;
            let (k2, _) = punct(b'=')(k2)?;
            let (k2, _) = ws(k2)?;
            let (k2, v) = expr(cx, 0, k2)?;
            options.push((cx.span_of(name), v));
            j = k2;
        }
    }
    let (r, _) = ws(j)?;
    let a = Anout {
        input,
        on,
        signal,
        value,
        options,
    };
    Ok((r, Line::Simple(StmtKind::Anout(Box::new(a)))))
}

fn brake_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, _) = keyword("BRAKE")(i)?;
    let (j, _) = ws(j)?;
    if j.is_empty() {
        return Ok((j, Line::Simple(StmtKind::Brake(None))));
    }
    let (r, f) = keyword("F")(j)?;
    Ok((r, Line::Simple(StmtKind::Brake(Some(cx.span_of(f))))))
}

fn return_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, _) = keyword("RETURN")(i)?;
    let (j, _) = ws(j)?;
    if j.is_empty() {
        return Ok((j, Line::Simple(StmtKind::Return(None))));
    }
    let (r, e) = expr(cx, 0, j)?;
    Ok((r, Line::Simple(StmtKind::Return(Some(Box::new(e))))))
}

/// `WAIT FOR cond` / `WAIT SEC time`.
fn wait_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, _) = keyword("WAIT")(i)?;
    let (j, _) = ws(j)?;
    if let Ok((k, _)) = keyword("FOR")(j) {
        let e = lenient(cx, k)?;
        return Ok((&i[i.len()..], Line::Simple(StmtKind::WaitFor(Box::new(e)))));
    }
    let (k, _) = keyword("SEC")(j)?;
    let (k, _) = ws(k)?;
    let (r, e) = expr(cx, 0, k)?;
    Ok((r, Line::Simple(StmtKind::WaitSec(Box::new(e)))))
}

/// `INTERRUPT DECL prio WHEN cond DO action` / `INTERRUPT ON|OFF|ENABLE|DISABLE [n]`.
fn interrupt_line<'a>(cx: Cx<'a>, global: Option<Span>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, _) = keyword("INTERRUPT")(i)?;
    let (j, _) = ws(j)?;
    if let Ok((k, _)) = keyword("DECL")(j) {
        let (k, _) = ws(k)?;
        let (k, prio) = expr(cx, 0, k)?;
        let (k, _) = ws(k)?;
        let (k, _) = keyword("WHEN")(k)?;
        let (k, _) = ws(k)?;
        let (k, cond) = expr(cx, 0, k)?;
        let (k, _) = ws(k)?;
        let (k, _) = keyword("DO")(k)?;
        let (k, _) = ws(k)?;
        let (r, action) = action(cx, k)?;
        let it = Interrupt::Decl {
            global,
            prio,
            cond,
            action,
        };
        return Ok((r, Line::Simple(StmtKind::Interrupt(Box::new(it)))));
    }
    let (k, op) = ident(j)?;
    if ![&b"ON"[..], b"OFF", b"ENABLE", b"DISABLE"]
        .iter()
        .any(|w| op.eq_ignore_ascii_case(w))
    {
        return backtrack(j);
    }
    let (k, _) = ws(k)?;
    let (r, number) = if k.is_empty() {
        (k, None)
    } else {
        let (r, e) = expr(cx, 0, k)?;
        (r, Some(e))
    };
    let it = Interrupt::Control {
        op: cx.span_of(op),
        number,
    };
    Ok((r, Line::Simple(StmtKind::Interrupt(Box::new(it)))))
}

/// `TRIGGER WHEN (DISTANCE|PATH) = v [ONSTART] [DELAY = d] DO action [PRIO = p]`.
fn trigger_line<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, _) = keyword("TRIGGER")(i)?;
    let (j, _) = ws(j)?;
    let (j, _) = keyword("WHEN")(j)?;
    let (j, _) = ws(j)?;
    let (j, w) = ident(j)?;
    let when = if w.eq_ignore_ascii_case(b"DISTANCE") {
        TriggerWhen::Distance
    } else if w.eq_ignore_ascii_case(b"PATH") {
        TriggerWhen::Path
    } else {
        return backtrack(j);
    };
    let (j, _) = ws(j)?;
    let (j, _) = punct(b'=')(j)?;
    let (j, _) = ws(j)?;
    let (mut j, value) = expr(cx, 0, j)?;
    let mut onstart = None;
    let mut delay = None;
    loop {
        let (k, _) = ws(j)?;
        if let Ok((k2, o)) = keyword("ONSTART")(k) {
            onstart = Some(cx.span_of(o));
            j = k2;
        } else if let Ok((k2, _)) = keyword("DELAY")(k) {
            let (k2, _) = ws(k2)?;
            let (k2, _) = punct(b'=')(k2)?;
            let (k2, _) = ws(k2)?;
            let (k2, d) = expr(cx, 0, k2)?;
            delay = Some(d);
            j = k2;
        } else {
            j = k;
            break;
        }
    }
    let (j, _) = keyword("DO")(j)?;
    let (j, _) = ws(j)?;
    let (mut r, act) = action(cx, j)?;
    let mut prio = None;
    let (k, _) = ws(r)?;
    if let Ok((k, _)) = keyword("PRIO")(k) {
        let (k, _) = ws(k)?;
        let (k, _) = punct(b'=')(k)?;
        let (k, _) = ws(k)?;
        let (k, p) = expr(cx, 0, k)?;
        prio = Some(p);
        r = k;
    }
    let t = Trigger {
        when,
        value,
        onstart,
        delay,
        action: act,
        prio,
    };
    Ok((r, Line::Simple(StmtKind::Trigger(Box::new(t)))))
}

/// A call or an assignment (the `DO` part of interrupts and triggers).
fn action<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Action> {
    if let Ok((r, a)) = assignment(cx, i) {
        return Ok((r, Action::Assign(a)));
    }
    let (r, c) = call(cx, 0, i)?;
    Ok((r, Action::Call(c)))
}

/// `path = expr`.
fn assignment<'a>(cx: Cx<'a>, i: &'a [u8]) -> PResult<'a, Assign> {
    let (j, lhs) = path(cx, 0, i)?;
    let (j, _) = ws(j)?;
    let (j, _) = punct(b'=')(j)?;
    if j.first() == Some(&b'=') {
        return backtrack(j);
    }
    let (j, _) = ws(j)?;
    let (r, rhs) = expr(cx, 0, j)?;
    Ok((r, Assign { lhs, rhs }))
}

/// Labels, assignments, calls, user-type declarations; anything else is opaque.
fn other_line<'a>(cx: Cx<'a>, file: FileKind, i: &'a [u8]) -> PResult<'a, Line> {
    let (j, name) = ident(i)?;
    let (k, blanks) = ws(j)?;
    match k.first() {
        Some(b':') if ws(&k[1..])?.0.is_empty() => Ok((
            &i[i.len()..],
            Line::Simple(StmtKind::Label(cx.span_of(name))),
        )),
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
        _ => {
            let (r, a) = assignment(cx, i)?;
            Ok((r, Line::Simple(StmtKind::Assign(Box::new(a)))))
        }
    }
}
