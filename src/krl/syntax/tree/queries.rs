//! What a built [`SourceFile`] answers: its text, statements, motions, aggregates and their
//! members, folds, declarations and called names.

use super::{build_in, BuildOptions, FileKind, SourceFile};
use crate::krl::syntax::decl::{Decl, RoutineHeader};
use crate::krl::syntax::error::{ParseError, Problem};
#[cfg(any(test, feature = "internals"))]
use crate::krl::syntax::expr::Number;
use crate::krl::syntax::expr::{Aggregate, Expr, Member};
use crate::krl::syntax::fold::{Fold, FoldId, Ilf};
use crate::krl::syntax::motion::Motion;
use crate::krl::syntax::nodes::{AggregateId, Members, MotionId};
use crate::krl::syntax::plain::is_plain_kind;
use crate::krl::syntax::span::Span;
use crate::krl::syntax::stmt::{Stmt, StmtKind};
use crate::krl::syntax::stream::StreamedRun;
use std::borrow::Cow;
use std::sync::Arc;

impl SourceFile {
    /// `Err` when the file has errors (as [`parse`]).
    pub fn checked(self) -> Result<SourceFile, ParseError> {
        if self.has_errors() {
            Err(ParseError {
                file: Box::new(self),
            })
        } else {
            Ok(self)
        }
    }

    /// The bytes this file's tree covers: the whole source, or a window's lines.
    pub fn extent(&self) -> Span {
        self.lines.extent()
    }

    /// The original bytes, shared (a window shares its file's).
    pub fn shared_source(&self) -> Arc<Vec<u8>> {
        Arc::clone(&self.src)
    }

    /// The original bytes.
    pub fn source(&self) -> &[u8] {
        &self.src
    }

    pub fn kind(&self) -> FileKind {
        self.kind
    }

    /// The bytes of a span.
    pub fn text(&self, span: Span) -> &[u8] {
        &self.src[span.range()]
    }

    /// The text of a span for display (UTF-8 if valid, else one character per byte).
    pub fn text_lossy(&self, span: Span) -> Cow<'_, str> {
        let t = self.text(span);
        match std::str::from_utf8(t) {
            Ok(s) => Cow::Borrowed(s),
            Err(_) => Cow::Owned(t.iter().map(|&b| char::from(b)).collect()),
        }
    }

    /// Whether the text of `span` is `name`, ignoring ASCII case (KRL names are
    /// case-insensitive).
    pub fn is_named(&self, span: Span, name: &str) -> bool {
        self.text(span).eq_ignore_ascii_case(name.as_bytes())
    }

    /// The stretches of the main routine left out of the tree by [`parse_streaming`].
    pub fn streamed_runs(&self) -> &[StreamedRun] {
        &self.runs
    }

    /// One window of a run (`window` from [`StreamedRun::windows`]) parsed into a file of its
    /// own: its statements at top level, the source bytes shared, spans and line numbers as
    /// in the whole file.
    ///
    /// Every statement of a window must be plain (the reason it was left out of the tree);
    /// one that is not, or a line that does not parse, is an error of the window (a bug of
    /// `plain::streams`, which chose the run's lines: the caller must not use the window).
    pub fn window(&self, (bytes, first_line): (Span, u32)) -> SourceFile {
        // Walked at once: the plain members' values are kept (`Nodes::member_values`).
        let opts = BuildOptions {
            keep_values: true,
            ..BuildOptions::default()
        };
        let mut w = build_in(&self.src, self.kind, bytes.range(), first_line, opts);
        w.src = Arc::clone(&self.src);
        let strange: Vec<Span> = w
            .body
            .iter()
            .filter(|s| s.block.is_some() || !is_plain_kind(&s.kind, &w.nodes, &w.src))
            .map(|s| s.head)
            .collect();
        for head in strange {
            w.problems.push(Problem::error(
                head,
                "internal error: a line streamed as plain is not (please report this program)",
                "compensate the program with the line changed, e.g. split the run there",
            ));
        }
        w
    }

    /// The top-level statements (header directives, routines, `DEFDAT`, stray lines).
    pub fn body(&self) -> &[Stmt] {
        &self.body
    }

    /// Trivia after the last statement.
    #[cfg(any(test, feature = "internals"))]
    pub fn trailing(&self) -> Span {
        self.trailing
    }

    /// The routines (`DEF`/`DEFFCT` blocks) in order.
    pub fn routines(&self) -> impl Iterator<Item = (&Stmt, &RoutineHeader)> {
        self.body.iter().filter_map(|s| match &s.kind {
            StmtKind::Routine(h) => Some((s, &**h)),
            _ => None,
        })
    }

    /// Every statement, nested ones included, in source order (parents before children).
    pub fn statements(&self) -> Statements<'_> {
        Statements {
            stack: vec![self.body.iter()],
            pending: Vec::new(),
        }
    }

    /// Every motion statement with its motion, in source order.
    pub fn motions(&self) -> impl Iterator<Item = (&Stmt, &Motion)> {
        self.statements()
            .filter_map(|s| s.as_motion().map(|m| (s, self.motion(m))))
    }

    /// The motion of a motion statement.
    pub fn motion(&self, id: MotionId) -> &Motion {
        &self.nodes.motions[id.0 as usize]
    }

    /// The motion of `stmt`, if it is a motion statement.
    #[cfg(any(test, feature = "internals"))]
    pub fn motion_of(&self, stmt: &Stmt) -> Option<&Motion> {
        stmt.as_motion().map(|m| self.motion(m))
    }

    pub fn aggregate(&self, id: AggregateId) -> &Aggregate {
        &self.nodes.aggregates[id.0 as usize]
    }

    /// The aggregate an expression is, if it is one.
    pub fn aggregate_of(&self, e: &Expr) -> Option<&Aggregate> {
        e.as_aggregate().map(|id| self.aggregate(id))
    }

    /// The members of an aggregate, in order, by value.
    pub fn members(&self, a: &Aggregate) -> Members<'_> {
        Members {
            nodes: &self.nodes,
            src: &self.src,
            packed: self.nodes.members_of(a).iter(),
        }
    }

    /// The members of an aggregate as stored: spans, plain numbers not read
    /// ([`RawMember`](crate::krl::syntax::nodes::RawMember)).
    pub fn raw_members(&self, a: &Aggregate) -> crate::krl::syntax::nodes::RawMembers<'_> {
        crate::krl::syntax::nodes::RawMembers {
            nodes: &self.nodes,
            packed: self.nodes.members_of(a).iter(),
            kept: self.nodes.kept_values_of(a).iter(),
        }
    }

    /// A raw member with its value (see [`SourceFile::members`]).
    pub fn member_of<'a>(&'a self, raw: crate::krl::syntax::nodes::RawMember<'a>) -> Member<'a> {
        self.nodes.member_of_raw(&self.src, raw)
    }

    /// The member called `name` (case-insensitive).
    pub fn member(&self, a: &Aggregate, name: &str) -> Option<Member<'_>> {
        let p = self
            .nodes
            .members_of(a)
            .iter()
            .find(|&&p| self.is_named(self.nodes.member_name(p), name))?;
        Some(self.nodes.member(&self.src, *p))
    }

    /// The `[]` right after an array member's name (`POINT2[] " "`), if any.
    #[cfg(any(test, feature = "internals"))]
    pub fn member_index(&self, m: &Member) -> Option<Span> {
        let at = m.name.end as usize;
        if self.src.get(at) != Some(&b'[') {
            return None;
        }
        let close = self.src[at..].iter().position(|&b| b == b']')?;
        Some(Span::new(at, at + close + 1))
    }

    /// The number of member `name` when it is a plain (possibly signed) literal.
    #[cfg(any(test, feature = "internals"))]
    pub fn member_number(&self, a: &Aggregate, name: &str) -> Option<Number> {
        self.member(a, name)?.value.as_number().copied()
    }

    /// Calls `f` on `e` and every sub-expression (aggregate members included), parents first.
    pub fn visit_expr(&self, e: &Expr, f: &mut impl FnMut(&Expr)) {
        e.visit(&self.nodes, &self.src, f);
    }

    /// Calls `f` on every expression of statement `s` (its own line only, not a block's body)
    /// and their sub-expressions, parents first.
    pub fn visit_stmt_exprs(&self, s: &Stmt, f: &mut impl FnMut(&Expr)) {
        use super::stmt::{Action, Interrupt};
        let mut v = |e: &Expr| self.visit_expr(e, f);
        let action = |a: &Action, v: &mut dyn FnMut(&Expr)| match a {
            Action::Call(e) => v(e),
            Action::Assign(a) => {
                v(&a.lhs);
                v(&a.rhs);
            }
        };
        match &s.kind {
            StmtKind::Decl(d) => d
                .vars
                .iter()
                .filter_map(|x| x.init.as_ref())
                .for_each(&mut v),
            StmtKind::Motion(id) => {
                let m = self.motion(*id);
                v(&m.target);
                if let Some(a) = m.aux() {
                    v(a);
                }
                if let Some(ca) = m.angle() {
                    v(&ca.value);
                }
                for w in m.with() {
                    v(&w.value);
                }
            }
            StmtKind::Spline(h) => h.with.iter().for_each(|w| v(&w.value)),
            StmtKind::Assign(a) => {
                v(&a.lhs);
                v(&a.rhs);
            }
            StmtKind::Call(c) => c.args.iter().flatten().for_each(&mut v),
            StmtKind::If(e)
            | StmtKind::Switch(e)
            | StmtKind::While(e)
            | StmtKind::WaitFor(e)
            | StmtKind::WaitSec(e) => v(e),
            StmtKind::Repeat(Some(e)) | StmtKind::Return(Some(e)) => v(e),
            StmtKind::For(Some(x)) => {
                v(&x.from);
                v(&x.to);
                if let Some(st) = &x.step {
                    v(st);
                }
            }
            StmtKind::Interrupt(i) => {
                if let Interrupt::Decl {
                    cond, action: a, ..
                } = &**i
                {
                    v(cond);
                    action(a, &mut v);
                }
            }
            StmtKind::Trigger(t) => {
                v(&t.value);
                action(&t.action, &mut v);
            }
            StmtKind::Anout(a) => {
                v(&a.signal);
                a.value.iter().for_each(&mut v);
            }
            _ => {}
        }
        if let Some(b) = &s.block {
            for arm in &b.arms {
                if let super::stmt::ArmKind::Case(values) = &arm.kind {
                    values.iter().for_each(&mut v);
                }
            }
        }
    }

    /// The names of the routines the file calls, statements and functions in expressions
    /// alike, in source order (repeats included).
    pub fn called_names(&self) -> Vec<Span> {
        let mut out = Vec::new();
        for st in self.statements() {
            if let StmtKind::Call(c) = &st.kind {
                out.push(c.name);
            }
            self.visit_stmt_exprs(st, &mut |e| {
                if let Expr::Call(c) = e {
                    out.push(c.name);
                }
            });
        }
        out
    }

    /// Every numeric literal in `e`, in source order.
    #[cfg(any(test, feature = "internals"))]
    pub fn numbers(&self, e: &Expr) -> Vec<Number> {
        let mut out = Vec::new();
        self.visit_expr(e, &mut |x| {
            if let Expr::Number(n) = x {
                out.push(*n);
            }
        });
        out
    }

    /// Every declaration statement, in source order.
    pub fn declarations(&self) -> impl Iterator<Item = (&Stmt, &Decl)> {
        self.statements()
            .filter_map(|s| s.as_decl().map(|d| (s, d)))
    }

    /// The fold overlay (index with `FoldId.0`).
    pub fn folds(&self) -> &[Fold] {
        &self.folds
    }

    pub fn fold(&self, id: FoldId) -> &Fold {
        &self.folds[id.0 as usize]
    }

    /// The inline form a statement belongs to: its innermost enclosing fold carrying ILF
    /// parameters (walking out through `Parameters` sub-folds).
    pub fn inline_form(&self, stmt: &Stmt) -> Option<(&Fold, &Ilf)> {
        let mut id = stmt.fold;
        while let Some(i) = id {
            let f = self.fold(i);
            if let Some(ilf) = &f.ilf {
                return Some((f, ilf));
            }
            id = f.parent;
        }
        None
    }
}

/// Depth-first iterator over statements (see `SourceFile::statements`).
pub struct Statements<'a> {
    stack: Vec<std::slice::Iter<'a, Stmt>>,
    pending: Vec<std::slice::Iter<'a, Stmt>>,
}

impl<'a> Iterator for Statements<'a> {
    type Item = &'a Stmt;

    fn next(&mut self) -> Option<&'a Stmt> {
        loop {
            let top = self.stack.last_mut()?;
            match top.next() {
                Some(s) => {
                    if let Some(b) = &s.block {
                        // Arms come after the body: push them first (stack order).
                        self.pending.clear();
                        self.pending.push(b.body.iter());
                        for a in &b.arms {
                            self.pending.push(a.body.iter());
                        }
                        while let Some(it) = self.pending.pop() {
                            self.stack.push(it);
                        }
                    }
                    return Some(s);
                }
                None => {
                    self.stack.pop();
                }
            }
        }
    }
}
