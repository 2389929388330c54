//! Statements: executes one statement (assignments, calls, loops, branches with conditions known
//! before run time) and decides, for blocks whose execution depends on run time, which motions
//! are left unchanged.

use crate::krl::{ArmKind, Stmt, StmtKind};

use super::eval::reason;
use super::*;
use crate::motion::value::Value;
use crate::motion::workspace::FileId;

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

    /// A block whose execution depends on run time: if it moves the robot, say which motions
    /// are left unchanged; afterwards the robot's position is unknown.
    pub(super) fn unresolved(&mut self, file: FileId, s: &'f Stmt, why: &str) {
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
        self.warn(
            file,
            s.head,
            format!("{why}: {list} are left unchanged, and the robot's position after this block is unknown"),
        );
        self.state.current = None;
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
                // Local declarations of a routine (with an initial value when given).
                for v in &d.vars {
                    let name = upper(self.src(file).text(v.name));
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
                        self.unresolved(file, s, &format!("IF depends on run time ({why})"));
                        Flow::Next
                    }
                }
            }
            StmtKind::Switch(sel) => {
                let b = s.block.as_ref().expect("SWITCH is a block");
                let v = self.eval(file, sel, scope);
                let Some(key) = v.as_int() else {
                    let why = reason(&v, "the selector");
                    self.unresolved(file, s, &format!("SWITCH depends on run time ({why})"));
                    return Flow::Next;
                };
                let mut chosen = None;
                for a in &b.arms {
                    if let ArmKind::Case(values) = &a.kind {
                        for e in values {
                            match self.eval(file, e, scope).as_int() {
                                Some(k) if k == key => chosen = chosen.or(Some(a)),
                                Some(_) => {}
                                None => {
                                    self.unresolved(file, s, "a CASE value is not a constant");
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
                    self.unresolved(file, s, "the FOR bounds are not known before run time");
                    return Flow::Next;
                };
                if step == 0 {
                    self.unresolved(file, s, "FOR with STEP 0");
                    return Flow::Next;
                }
                let var = upper(self.src(file).text(f.var));
                let mut i = from;
                while (step > 0 && i <= to) || (step < 0 && i >= to) {
                    self.set_var(&var, Value::Int(i), scope);
                    match self.block(file, &b.body, scope) {
                        Flow::Next => {}
                        Flow::Exit => break,
                        Flow::Return => return Flow::Return,
                    }
                    if self.steps >= MAX_STEPS {
                        return Flow::Return;
                    }
                    i += step;
                }
                Flow::Next
            }
            StmtKind::For(None) => {
                self.unresolved(file, s, "a FOR header that was not understood");
                Flow::Next
            }
            StmtKind::While(cond) => {
                let b = s.block.as_ref().expect("WHILE is a block");
                loop {
                    match self.eval(file, cond, scope) {
                        Value::Bool(true) => match self.block(file, &b.body, scope) {
                            Flow::Next => {}
                            Flow::Exit => return Flow::Next,
                            Flow::Return => return Flow::Return,
                        },
                        Value::Bool(false) => return Flow::Next,
                        v => {
                            let why = reason(&v, "the condition");
                            self.unresolved(file, s, &format!("WHILE depends on run time ({why})"));
                            return Flow::Next;
                        }
                    }
                    if self.steps >= MAX_STEPS {
                        return Flow::Return;
                    }
                }
            }
            StmtKind::Repeat(cond) => {
                let b = s.block.as_ref().expect("REPEAT is a block");
                loop {
                    match self.block(file, &b.body, scope) {
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
                            );
                            return Flow::Next;
                        }
                    }
                    if self.steps >= MAX_STEPS {
                        return Flow::Return;
                    }
                }
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
