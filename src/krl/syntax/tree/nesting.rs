//! The statements nested into blocks: a stack of open blocks (`DEF`, `IF`, `FOR`, …) that each
//! statement is pushed into, opened and closed by the block statements, with recovery (and a
//! warning) where the blocks do not balance.

use crate::krl::syntax::error::Problem;
use crate::krl::syntax::expr::Expr;
use crate::krl::syntax::fold::FoldId;
use crate::krl::syntax::memory::Ahead;
use crate::krl::syntax::span::Span;
use crate::krl::syntax::stmt::{Arm, ArmKind, Block, BlockKind, Clause, Line, Stmt, StmtKind};

/// Deepest block nesting followed; deeper openers are kept as opaque lines.
const MAX_BLOCK_DEPTH: usize = 200;

/// An open block being filled.
struct Frame {
    stmt: Stmt,
    kind: BlockKind,
    /// The file's first routine (its main program).
    main: bool,
}

#[derive(Default)]
pub(super) struct Builder {
    top: Vec<Stmt>,
    stack: Vec<Frame>,
    pub(super) problems: Vec<Problem>,
    /// Pages mapped ahead of the statement list being filled (see `memory`).
    ahead: Ahead,
    routines: u32,
    /// Blocks opened beyond [`MAX_BLOCK_DEPTH`], innermost last: kept as opaque lines, not
    /// followed. Their arms and closers are theirs (not strays of the followed blocks), and
    /// only the outermost is warned about.
    deep: Vec<BlockKind>,
}

/// Where a line of code is: its code (`head`), the trivia before it, its number and fold.
#[derive(Clone, Copy)]
pub(super) struct LineAt {
    pub(super) leading: Span,
    pub(super) head: Span,
    pub(super) line: u32,
    pub(super) fold: Option<FoldId>,
}

impl LineAt {
    /// The line as a statement of `kind`.
    fn stmt(self, kind: StmtKind) -> Stmt {
        Stmt {
            leading: self.leading,
            head: self.head,
            end: self.head.end,
            line: self.line,
            fold: self.fold,
            kind,
            block: None,
        }
    }

    /// The line as a block's clause (an arm's head, a closer).
    fn clause(self) -> Clause {
        Clause {
            leading: self.leading,
            span: self.head,
            line: self.line,
        }
    }
}

impl Builder {
    /// Directly inside the main routine (where runs may be).
    pub(super) fn in_main_body(&self) -> bool {
        self.stack.len() == 1
            && self.stack[0].main
            && self.stack[0]
                .stmt
                .block
                .as_ref()
                .is_some_and(|b| b.arms.is_empty())
    }

    pub(super) fn main_body_len(&self) -> u32 {
        self.stack[0]
            .stmt
            .block
            .as_ref()
            .map_or(0, |b| b.body.len()) as u32
    }

    fn body(&mut self) -> &mut Vec<Stmt> {
        match self.stack.last_mut() {
            None => &mut self.top,
            Some(f) => {
                let b = f.stmt.block.as_mut().expect("frames hold blocks");
                match b.arms.last_mut() {
                    Some(a) => &mut a.body,
                    None => &mut b.body,
                }
            }
        }
    }

    /// Adds a parsed line: a statement to the innermost open block, a block opened, an arm
    /// begun, or a block closed.
    pub(super) fn feed(&mut self, l: Line, at: LineAt) {
        match l {
            Line::Simple(kind) => {
                let s = at.stmt(kind);
                let mut ahead = self.ahead;
                let body = self.body();
                ahead.before_push(body);
                body.push(s);
                self.ahead = ahead;
            }
            Line::Open(kind, bk) => self.open(kind, bk, at),
            Line::Arm(..) if !self.deep.is_empty() => {
                self.body().push(at.stmt(StmtKind::Opaque));
            }
            Line::Arm(bk, arm) => self.arm(bk, arm, at),
            // Searched from the innermost: the cost is the blocks closed, linear overall.
            Line::Close(bk, _) if self.deep.iter().rev().any(|k| *k == bk) => {
                let open = self.deep.iter().rposition(|k| *k == bk).unwrap_or(0);
                self.deep.truncate(open);
                self.body().push(at.stmt(StmtKind::Opaque));
            }
            Line::Close(bk, until) => self.close(bk, until, at),
        }
    }

    /// Opens a block with statement `at(kind)` (beyond [`MAX_BLOCK_DEPTH`]: kept opaque).
    fn open(&mut self, kind: StmtKind, bk: BlockKind, at: LineAt) {
        if matches!(bk, BlockKind::Routine | BlockKind::DefDat) {
            self.close_all();
        }
        if self.stack.len() >= MAX_BLOCK_DEPTH || !self.deep.is_empty() {
            let s = at.stmt(StmtKind::Opaque);
            if self.deep.is_empty() {
                self.stray(
                    format!("blocks nested more than {MAX_BLOCK_DEPTH} deep: this block is kept as written but not followed"),
                    "split the routine",
                    s,
                );
            } else {
                self.body().push(s);
            }
            self.deep.push(bk);
            return;
        }
        let mut s = at.stmt(kind);
        s.block = Some(Box::default());
        let main = bk == BlockKind::Routine && self.stack.is_empty() && self.routines == 0;
        if bk == BlockKind::Routine {
            self.routines += 1;
        }
        self.stack.push(Frame {
            stmt: s,
            kind: bk,
            main,
        });
    }

    /// Begins an arm (`ELSE`, `CASE`, `DEFAULT`) of the innermost block, if it fits there.
    fn arm(&mut self, bk: BlockKind, arm: ArmKind, at: LineAt) {
        match self.stack.last_mut() {
            Some(f) if f.kind == bk && arm_fits(f, &arm) => {
                let b = f.stmt.block.as_mut().expect("frames hold blocks");
                b.arms.push(Arm {
                    clause: at.clause(),
                    kind: arm,
                    body: Vec::new(),
                });
            }
            _ => self.stray(
                format!("this line belongs inside {} … {}", bk.opener(), bk.closer()),
                "check the block structure around this line",
                at.stmt(StmtKind::Opaque),
            ),
        }
    }

    /// Closes the innermost open block of kind `bk` (those inside it unclosed, with warnings).
    fn close(&mut self, bk: BlockKind, until: Option<Expr>, at: LineAt) {
        // Blocks left open beyond the depth limit end with the followed one closed here.
        self.deep.clear();
        let Some(open) = self.stack.iter().rposition(|f| f.kind == bk) else {
            self.stray(
                format!("`{}` without an open `{}`", bk.closer(), bk.opener()),
                "remove it or add the line that opens the block",
                at.stmt(StmtKind::Opaque),
            );
            return;
        };
        while self.stack.len() > open + 1 {
            self.pop_unclosed();
        }
        let mut f = self.stack.pop().expect("found above");
        if let (StmtKind::Repeat(cond), Some(e)) = (&mut f.stmt.kind, until) {
            *cond = Some(Box::new(e));
        }
        let block = f.stmt.block.as_mut().expect("frames hold blocks");
        block.end = Some(at.clause());
        f.stmt.end = at.head.end;
        trim(block);
        self.body().push(f.stmt);
    }

    /// A line kept as opaque with a warning about the block structure.
    fn stray(&mut self, message: String, help: &'static str, s: Stmt) {
        self.problems.push(Problem::warning(s.head, message, help));
        self.body().push(s);
    }

    /// Closes the innermost block without its closer (a warning says so).
    fn pop_unclosed(&mut self) {
        let mut f = self.stack.pop().expect("caller checked");
        self.problems.push(Problem::warning(
            f.stmt.head,
            format!(
                "`{}` on line {} is never closed (`{}` missing)",
                f.kind.opener(),
                f.stmt.line,
                f.kind.closer()
            ),
            "add the closing line where the block ends",
        ));
        f.stmt.end = last_end(&f.stmt) as u32;
        if let Some(b) = f.stmt.block.as_mut() {
            trim(b);
        }
        self.body().push(f.stmt);
    }

    fn close_all(&mut self) {
        self.deep.clear();
        while !self.stack.is_empty() {
            self.pop_unclosed();
        }
    }

    pub(super) fn finish(mut self) -> (Vec<Stmt>, Vec<Problem>) {
        self.close_all();
        self.top.shrink_to_fit();
        (self.top, self.problems)
    }
}

/// Gives back the spare capacity of a closed block's statement lists (a routine of a million
/// lines would otherwise keep up to half as much again).
fn trim(b: &mut Block) {
    b.body.shrink_to_fit();
    for a in &mut b.arms {
        a.body.shrink_to_fit();
    }
}

/// `ELSE` once per `IF`, `DEFAULT` once per `SWITCH`, `CASE` not after `DEFAULT`.
fn arm_fits(f: &Frame, arm: &ArmKind) -> bool {
    let arms = &f.stmt.block.as_ref().expect("frames hold blocks").arms;
    let has = |k: fn(&ArmKind) -> bool| arms.iter().any(|a| k(&a.kind));
    match arm {
        ArmKind::Else => !has(|k| matches!(k, ArmKind::Else)),
        ArmKind::Case(_) | ArmKind::Default => !has(|k| matches!(k, ArmKind::Default)),
    }
}

/// End of the last byte of code inside a statement (its head when the block is empty).
fn last_end(s: &Stmt) -> usize {
    let mut end = s.head.end;
    if let Some(b) = &s.block {
        if let Some(last) = b.body.last() {
            end = end.max(last.end);
        }
        for a in &b.arms {
            end = end.max(a.clause.span.end);
            if let Some(last) = a.body.last() {
                end = end.max(last.end);
            }
        }
        if let Some(e) = &b.end {
            end = end.max(e.span.end);
        }
    }
    end as usize
}
