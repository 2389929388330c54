//! Statements: executes one statement (assignments, calls, loops, branches with conditions known
//! before run time) and decides, for blocks whose execution depends on run time, which motions
//! are left unchanged. A loop that ends on a run-time condition (an `EXIT` under an `IF $IN[…]`
//! in `REPEAT … UNTIL FALSE`) or that nothing in it can end is followed twice, as a cycle (the
//! second pass starts where the first ends, as in production), then left with the robot's
//! position unknown — in milliseconds, not after the walk's statement budget.

use crate::krl::{ArmKind, Stmt, StmtKind};

use super::eval::reason;
use super::*;
use crate::krl::interpret::value::Value;
use crate::krl::interpret::workspace::FileId;

impl<'f> Simulator<'f> {
    // ---- run-time dependence --------------------------------------------------------------

    /// Whether statements move the robot (directly or through a called routine).
    pub(super) fn block_moves(&mut self, file: FileId, stmts: &'f [Stmt]) -> bool {
        stmts.iter().any(|s| self.stmt_moves(file, s))
    }

    pub(super) fn stmt_moves(&mut self, file: FileId, s: &'f Stmt) -> bool {
        match &s.kind {
            StmtKind::Motion(_) => return true,
            StmtKind::Call(c) => {
                let name = upper(self.src(file).text(c.name));
                if let Some(m) = self.moves.get(&name) {
                    return *m;
                }
                self.moves.insert(name.clone(), false); // recursion guard
                let m = match self.routines.get(&name).copied() {
                    Some((f, st, _)) => st
                        .block
                        .as_ref()
                        .is_some_and(|b| self.block_moves(f, &b.body)),
                    None => false,
                };
                self.moves.insert(name, m);
                return m;
            }
            _ => {}
        }
        match &s.block {
            Some(b) => {
                self.block_moves(file, &b.body)
                    || b.arms.iter().any(|a| self.block_moves(file, &a.body))
            }
            None => false,
        }
    }

    /// Lines of the motions inside statements (for messages).
    pub(super) fn motion_lines(stmts: &[Stmt], out: &mut Vec<u32>) {
        for s in stmts {
            if matches!(s.kind, StmtKind::Motion(_)) {
                out.push(s.line);
            }
            if let Some(b) = &s.block {
                Self::motion_lines(&b.body, out);
                for a in &b.arms {
                    Self::motion_lines(&a.body, out);
                }
            }
        }
    }

    /// Whether statements leave the loop around them (`EXIT` outside an inner loop) or the
    /// routine (`RETURN`, `GOTO`).
    fn exits(stmts: &[Stmt], in_inner_loop: bool) -> bool {
        stmts.iter().any(|s| {
            let inner = in_inner_loop
                || matches!(
                    s.kind,
                    StmtKind::For(_) | StmtKind::While(_) | StmtKind::Repeat(_) | StmtKind::Loop
                );
            match &s.kind {
                StmtKind::Exit if !in_inner_loop => true,
                StmtKind::Return(_) | StmtKind::Goto(_) => true,
                _ => s.block.as_ref().is_some_and(|b| {
                    Self::exits(&b.body, inner)
                        || b.arms.iter().any(|a| Self::exits(&a.body, inner))
                }),
            }
        })
    }

    /// A block whose execution depends on run time: if it moves the robot, say which motions
    /// are left unchanged; afterwards the robot's position is unknown.
    pub(super) fn unresolved(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        why: &str,
        scope: &mut Scope<'f>,
    ) {
        if s.block.as_ref().is_some_and(|b| {
            Self::exits(&b.body, false) || b.arms.iter().any(|a| Self::exits(&a.body, false))
        }) {
            self.exit_unknown = Some((file, s.line));
        }
        self.forget_assigned(file, s, why, scope);
        let moves = self.stmt_moves(file, s);
        if !moves {
            return;
        }
        let mut lines = Vec::new();
        Self::motion_lines(std::slice::from_ref(s), &mut lines);
        let list = if lines.is_empty() {
            "motions in called routines".to_string()
        } else {
            format!(
                "the motions at line{} {}",
                if lines.len() > 1 { "s" } else { "" },
                lines
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        self.out.lost += lines.len().max(1);
        self.warn(
            file,
            s.head,
            format!("{why}: {list} are left unchanged, and the robot's position after this block is unknown"),
        );
        self.state.current = None;
    }

    /// What the statements of block `s` (executed or not, depending on run time) assign is
    /// unknown after it: variables, members (their variable), elements whose index is known,
    /// `$BASE` and `$TOOL`.
    fn forget_assigned(&mut self, file: FileId, s: &'f Stmt, why: &str, scope: &mut Scope<'f>) {
        let mut lhs: Vec<&'f crate::krl::Expr> = Vec::new();
        fn gather<'f>(stmts: &'f [Stmt], out: &mut Vec<&'f crate::krl::Expr>) {
            for st in stmts {
                if let StmtKind::Assign(a) = &st.kind {
                    out.push(&a.lhs);
                }
                if let Some(b) = &st.block {
                    gather(&b.body, out);
                    for a in &b.arms {
                        gather(&a.body, out);
                    }
                }
            }
        }
        if let Some(b) = &s.block {
            gather(&b.body, &mut lhs);
            for a in &b.arms {
                gather(&a.body, &mut lhs);
            }
        }
        let src = self.src(file);
        let said = format!("set in the block at line {} ({why})", s.line);
        for e in lhs {
            let Some(p) = e.as_path() else { continue };
            let root = upper(src.text(p.root));
            match root.as_slice() {
                b"$BASE" | b"$TOOL" => {
                    let st = FrameState::Unknown(
                        file,
                        s.head,
                        format!("{} may be {said}", src.text_lossy(p.root)),
                        "set the frame outside branches that depend on run time, or state what decides the branch with --assume NAME=VALUE",
                    );
                    if root == b"$BASE" {
                        self.state.base = st;
                    } else {
                        self.state.tool = st;
                    }
                }
                r if r.starts_with(b"$") => {}
                _ => {
                    let unknown =
                        Value::Unknown(format!("{} may be {said}", src.text_lossy(p.span)));
                    match p.access.first() {
                        Some(crate::krl::Access::Index {
                            items,
                            slice: false,
                            ..
                        }) => {
                            let idx: Option<Vec<i64>> = items
                                .iter()
                                .map(|i| self.eval(file, i, scope).as_int())
                                .collect();
                            if let Some(idx) = idx {
                                self.set_element(file, &root, idx, unknown, scope);
                            }
                        }
                        _ => self.set_var(file, &root, unknown, scope),
                    }
                }
            }
        }
    }

    /// After iteration `n` (from 1) of loop `s` (whose condition would have it go on): whether
    /// to go on. A loop that ends on a run-time condition met in the iteration, or whose
    /// iteration changed nothing (`changed`: assignments made), is followed twice; the loop
    /// limits ([`MAX_LOOP_ITERATIONS`], [`MAX_LOOP_TOTAL`]) end any loop. When it stops here,
    /// the robot's position is unknown.
    fn again(&mut self, file: FileId, s: &Stmt, n: LoopCount, changed: bool) -> bool {
        let why = if let Some((_, line)) = self.exit_unknown {
            format!("this loop ends on a condition known only at run time (line {line})")
        } else if !changed {
            "nothing in this loop changes what ends it before run time (it runs until a signal or forever)".to_string()
        } else if self.loop_limit_reached(n) {
            format!(
                "this loop ran {} times before run time without ending ({})",
                n.all,
                loop_limits()
            )
        } else {
            return true;
        };
        if n.all < 2 {
            return true;
        }
        self.warn(
            file,
            s.head,
            format!(
                "{why}: it is followed {} times, as a cycle, and the robot's position after it is unknown",
                n.all
            ),
        );
        self.state.current = None;
        false
    }

    // ---- statements ------------------------------------------------------------------------

    pub(super) fn stmt(&mut self, file: FileId, s: &'f Stmt, scope: &mut Scope<'f>) -> Flow {
        self.steps += 1;
        if self.steps == MAX_STEPS {
            self.error(
                file,
                s.head,
                "the program runs more than 200 million statements before run time (an endless loop?): simulation stopped",
            );
        }
        if self.steps >= MAX_STEPS {
            return Flow::Return;
        }
        match &s.kind {
            StmtKind::Motion(id) => {
                let m = self.src(file).motion(*id);
                self.motion(file, s, m, scope);
                Flow::Next
            }
            StmtKind::Assign(a) => {
                self.assign(file, s, &a.lhs, &a.rhs, scope);
                Flow::Next
            }
            StmtKind::Call(c) => {
                self.call(file, s, c, scope);
                Flow::Next
            }
            StmtKind::Decl(d) => {
                // Local declarations of a routine (with an initial value when given); a
                // parameter's declaration keeps the value the call bound.
                for v in &d.vars {
                    let name = upper(self.src(file).text(v.name));
                    if scope.params.contains(&name) {
                        continue;
                    }
                    let value = match &v.init {
                        Some(e) => self.eval(file, e, scope),
                        None => Value::Unknown(format!(
                            "{} has no value yet",
                            String::from_utf8_lossy(&name)
                        )),
                    };
                    scope.vars.insert(name, value);
                }
                Flow::Next
            }
            StmtKind::If(cond) => {
                let b = s.block.as_ref().expect("IF is a block");
                match self.eval(file, cond, scope) {
                    Value::Bool(true) => self.block(file, &b.body, scope),
                    Value::Bool(false) => match b.arms.iter().find(|a| a.kind == ArmKind::Else) {
                        Some(a) => self.block(file, &a.body, scope),
                        None => Flow::Next,
                    },
                    v => {
                        let why = reason(&v, "the condition");
                        self.unresolved(file, s, &format!("IF depends on run time ({why})"), scope);
                        Flow::Next
                    }
                }
            }
            StmtKind::Switch(sel) => {
                let b = s.block.as_ref().expect("SWITCH is a block");
                let v = self.eval(file, sel, scope);
                let Some(key) = case_key(&v) else {
                    let why = reason(&v, "the selector");
                    self.unresolved(
                        file,
                        s,
                        &format!("SWITCH depends on run time ({why})"),
                        scope,
                    );
                    return Flow::Next;
                };
                let mut chosen = None;
                for a in &b.arms {
                    if let ArmKind::Case(values) = &a.kind {
                        for e in values {
                            match case_key(&self.eval(file, e, scope)) {
                                Some(k) if k == key => chosen = chosen.or(Some(a)),
                                Some(_) => {}
                                None => {
                                    self.unresolved(
                                        file,
                                        s,
                                        "a CASE value is not a constant",
                                        scope,
                                    );
                                    return Flow::Next;
                                }
                            }
                        }
                    }
                }
                let arm = chosen.or_else(|| b.arms.iter().find(|a| a.kind == ArmKind::Default));
                match arm {
                    Some(a) => self.block(file, &a.body, scope),
                    None => Flow::Next,
                }
            }
            StmtKind::For(Some(f)) => {
                let b = s.block.as_ref().expect("FOR is a block");
                let from = self.eval(file, &f.from, scope).as_int();
                let to = self.eval(file, &f.to, scope).as_int();
                let step = match &f.step {
                    Some(e) => self.eval(file, e, scope).as_int(),
                    None => Some(1),
                };
                let (Some(from), Some(to), Some(step)) = (from, to, step) else {
                    self.unresolved(
                        file,
                        s,
                        "the FOR bounds are not known before run time",
                        scope,
                    );
                    return Flow::Next;
                };
                if step == 0 {
                    self.unresolved(file, s, "FOR with STEP 0", scope);
                    return Flow::Next;
                }
                let var = upper(self.src(file).text(f.var));
                let outer = self.exit_unknown.take();
                let within = |i: i64| (step > 0 && i <= to) || (step < 0 && i >= to);
                let mut i = from;
                let mut n = LoopCount::default();
                while within(i) {
                    self.set_var(file, &var, Value::Int(i), scope);
                    let stops = self.out.stops.len();
                    match self.block(file, &b.body, scope) {
                        Flow::Next => {}
                        Flow::Exit => break,
                        Flow::Return => return Flow::Return,
                    }
                    if self.steps >= MAX_STEPS {
                        return Flow::Return;
                    }
                    self.count_iteration(&mut n, stops);
                    // An overflowing counter ends the loop (the controller's would stop).
                    let Some(next) = i.checked_add(step) else {
                        break;
                    };
                    i = next;
                    if within(i) && self.loop_limit_reached(n) {
                        let left = (i128::from(to) - i128::from(i)) / i128::from(step) + 1;
                        self.warn(
                            file,
                            s.head,
                            format!(
                                "this FOR loop runs {} times; it is followed {} times ({}), as a cycle, and the robot's position after it is unknown",
                                left + i128::from(n.all),
                                n.all,
                                loop_limits()
                            ),
                        );
                        self.state.current = None;
                        self.exit_unknown = outer;
                        return Flow::Next;
                    }
                }
                if let Some((_, line)) = self.exit_unknown.take() {
                    // It may end at any iteration: where the robot is after it is not known.
                    self.warn(
                        file,
                        s.head,
                        format!("this loop may end early on a condition known only at run time (line {line}): the robot's position after it is unknown"),
                    );
                    self.state.current = None;
                }
                self.exit_unknown = outer;
                Flow::Next
            }
            StmtKind::For(None) => {
                self.unresolved(file, s, "a FOR header that was not understood", scope);
                Flow::Next
            }
            StmtKind::While(cond) => {
                let b = s.block.as_ref().expect("WHILE is a block");
                let outer = self.exit_unknown.take();
                let flow = self.while_loop(file, s, cond, &b.body, scope);
                self.exit_unknown = outer;
                flow
            }
            StmtKind::Repeat(cond) => {
                let b = s.block.as_ref().expect("REPEAT is a block");
                let outer = self.exit_unknown.take();
                let flow = self.repeat_loop(file, s, cond.as_deref(), &b.body, scope);
                self.exit_unknown = outer;
                flow
            }
            StmtKind::Loop => {
                // An endless loop (the cell's main cycle): its body runs twice, so that the
                // second pass starts where the first ends, as in production.
                let b = s.block.as_ref().expect("LOOP is a block");
                for _ in 0..2 {
                    match self.block(file, &b.body, scope) {
                        Flow::Next => {}
                        Flow::Exit => return Flow::Next,
                        Flow::Return => return Flow::Return,
                    }
                }
                Flow::Next
            }
            StmtKind::Spline(head) => {
                let b = s.block.as_ref().expect("SPLINE is a block");
                let saved = self.apply_with(file, &head.with, scope);
                let first = self.out.stops.len();
                let flow = self.block(file, &b.body, scope);
                if !head.ptp {
                    self.spline_block(first);
                }
                if let Some(saved) = saved {
                    self.restore(saved);
                }
                flow
            }
            StmtKind::Anout(a) if a.input && a.on => {
                // A variable an analog input updates cyclically: known only at run time.
                if let Some(p) = a.signal.as_path() {
                    let name = upper(self.src(file).text(p.root));
                    let why = format!(
                        "{}, which ANIN ON at line {} updates at run time",
                        self.src(file).text_lossy(p.root),
                        s.line
                    );
                    self.set_var(file, &name, Value::Unknown(why), scope);
                }
                Flow::Next
            }
            StmtKind::Exit => Flow::Exit,
            StmtKind::Return(_) => Flow::Return,
            StmtKind::Goto(_) => {
                self.warn(
                    file,
                    s.head,
                    "GOTO is not followed: the rest of this routine is not simulated and the robot's position after it is unknown",
                );
                self.state.current = None;
                Flow::Return
            }
            _ => {
                // Blocks not handled above (nested routines are only entered by calls).
                Flow::Next
            }
        }
    }
}

/// The loop limits, as messages state them.
fn loop_limits() -> String {
    format!("robopost follows a loop at most {MAX_LOOP_ITERATIONS} times, {MAX_MOVING_ITERATIONS} of them moving the robot, and {MAX_MOVING_TOTAL} moving iterations of all loops of a program")
}

/// Iterations of one loop followed so far: all, and those that moved the robot.
#[derive(Clone, Copy, Debug, Default)]
struct LoopCount {
    all: u64,
    moving: u64,
}

impl<'f> Simulator<'f> {
    /// Counts an iteration just run (`stops`: the stops before it).
    fn count_iteration(&mut self, n: &mut LoopCount, stops: usize) {
        n.all += 1;
        if self.out.stops.len() != stops {
            n.moving += 1;
            self.moving_iterations += 1;
        }
    }

    /// Whether a loop that would go on after `n` iterations has reached a loop limit (it is
    /// then ended as a cycle by the caller).
    fn loop_limit_reached(&self, n: LoopCount) -> bool {
        n.all >= MAX_LOOP_ITERATIONS
            || n.moving >= MAX_MOVING_ITERATIONS
            || self.moving_iterations >= MAX_MOVING_TOTAL
    }

    /// `WHILE cond … ENDWHILE`.
    fn while_loop(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        cond: &'f crate::krl::Expr,
        body: &'f [Stmt],
        scope: &mut Scope<'f>,
    ) -> Flow {
        let mut n = LoopCount::default();
        loop {
            match self.eval(file, cond, scope) {
                Value::Bool(true) => {}
                Value::Bool(false) => return Flow::Next,
                v => {
                    let why = reason(&v, "the condition");
                    self.unresolved(
                        file,
                        s,
                        &format!("WHILE depends on run time ({why})"),
                        scope,
                    );
                    return Flow::Next;
                }
            }
            let before = self.assignments;
            let stops = self.out.stops.len();
            match self.block(file, body, scope) {
                Flow::Next => {}
                Flow::Exit => return Flow::Next,
                Flow::Return => return Flow::Return,
            }
            if self.steps >= MAX_STEPS {
                return Flow::Return;
            }
            self.count_iteration(&mut n, stops);
            let goes_on = matches!(self.eval(file, cond, scope), Value::Bool(true));
            let changed =
                self.assignments != before && (!constant(cond) || Self::exits(body, false));
            if goes_on && !self.again(file, s, n, changed) {
                return Flow::Next;
            }
        }
    }

    /// `REPEAT … UNTIL cond`.
    fn repeat_loop(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        cond: Option<&'f crate::krl::Expr>,
        body: &'f [Stmt],
        scope: &mut Scope<'f>,
    ) -> Flow {
        let mut n = LoopCount::default();
        loop {
            let before = self.assignments;
            let stops = self.out.stops.len();
            match self.block(file, body, scope) {
                Flow::Next => {}
                Flow::Exit => return Flow::Next,
                Flow::Return => return Flow::Return,
            }
            let v = match cond {
                Some(c) => self.eval(file, c, scope),
                None => Value::Unknown("no UNTIL condition".into()),
            };
            match v {
                Value::Bool(true) => return Flow::Next,
                Value::Bool(false) => {}
                v => {
                    let why = reason(&v, "the condition");
                    self.unresolved(
                        file,
                        s,
                        &format!("REPEAT … UNTIL depends on run time ({why})"),
                        scope,
                    );
                    return Flow::Next;
                }
            }
            if self.steps >= MAX_STEPS {
                return Flow::Return;
            }
            self.count_iteration(&mut n, stops);
            let changed = self.assignments != before
                && (!cond.is_some_and(constant) || Self::exits(body, false));
            if !self.again(file, s, n, changed) {
                return Flow::Next;
            }
        }
    }
}

/// A condition written as a constant (`TRUE`, `FALSE`, `NOT FALSE`): nothing the loop does
/// changes it.
fn constant(e: &crate::krl::Expr) -> bool {
    use crate::krl::Expr;
    match e {
        Expr::Bool(..) | Expr::Number(_) => true,
        Expr::Paren(p) => constant(&p.inner),
        Expr::Unary(u) => constant(&u.operand),
        _ => false,
    }
}

/// What a `SWITCH` selector and its `CASE` values compare by: an integer (or a character's
/// code) or an enumeration value (upper case); `None` for anything else or unknown.
pub(super) fn case_key(v: &Value) -> Option<Result<i64, Vec<u8>>> {
    match v {
        Value::Enum(e) => Some(Err(e.clone())),
        v => v.as_int().map(Ok),
    }
}
