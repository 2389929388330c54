//! User functions (`DEFFCT TYPE name(params)`) evaluated where an expression needs their value
//! (`LIN Offset(XP1, 20)`, `F = GetFrame(3)`): the body run on the arguments, by value, with
//! its own variables and the data it reads. A function that moves the robot, calls a routine,
//! waits, writes data outside itself, returns values through `:OUT` parameters or depends on
//! run time has no value before run time, and the value says why. The value of a position is
//! computed: it is not written back.

use crate::krl::{ArmKind, Call, ParamMode, Stmt, StmtKind};

use super::assign::{with_member, Place};
use super::eval::reason;
use super::*;
use crate::krl::interpret::value::Value;
use crate::krl::interpret::workspace::FileId;

/// Functions nested deeper than this are not evaluated (recursion).
const MAX_FN_DEPTH: usize = 16;
/// Statements one evaluation may run (with the functions it calls).
const MAX_FN_STEPS: u64 = 1_000_000;

enum FnFlow<'f> {
    Next,
    Exit,
    Return(Value<'f>),
}

impl<'f> Simulator<'f> {
    /// The value of a call of a user function, or why it has none before run time.
    pub(super) fn user_function(&self, file: FileId, c: &'f Call, scope: &Scope<'f>) -> Value<'f> {
        let src = self.src(file);
        let name = upper(src.text(c.name));
        let shown = src.text_lossy(c.name);
        let Some((fn_file, stmt, header)) = self.routines.get(&name).copied() else {
            return Value::Unknown(format!("the function {shown}"));
        };
        if !header.function {
            return Value::Unknown(format!("{shown}, a routine without a value"));
        }
        let depth = self.fn_depth.get();
        if depth >= MAX_FN_DEPTH {
            return Value::Unknown(format!("{shown}: functions nested too deeply (recursion?)"));
        }
        if depth == 0 {
            self.fn_steps.set(0);
        }
        let callee = self.src(fn_file);
        let mut local = Scope::default();
        for (i, p) in header.params.iter().enumerate() {
            if p.mode == ParamMode::Out {
                return Value::Unknown(format!(
                    "the function {shown}, which returns values through :OUT parameters"
                ));
            }
            let v = match c.args.get(i).and_then(|a| a.as_ref()) {
                Some(a) => self.eval(file, a, scope),
                None => Value::Unknown("a parameter not passed".into()),
            };
            let pname = upper(callee.text(p.name));
            local.params.insert(pname.clone());
            local.vars.insert(pname, v);
        }
        let Some(body) = stmt.block.as_ref().map(|b| &b.body) else {
            return Value::Unknown(format!("the function {shown}, without a body"));
        };
        self.fn_depth.set(depth + 1);
        let flow = self.fn_block(fn_file, body, &mut local);
        self.fn_depth.set(depth);
        match flow {
            Ok(FnFlow::Return(Value::Unknown(why))) => {
                Value::Unknown(format!("the function {shown}, which returns {why}"))
            }
            Ok(FnFlow::Return(v)) => computed(v),
            Ok(_) => Value::Unknown(format!("the function {shown}, which ends without RETURN")),
            Err(why) => Value::Unknown(format!("the function {shown} ({why})")),
        }
    }

    fn fn_block(
        &self,
        file: FileId,
        stmts: &'f [Stmt],
        scope: &mut Scope<'f>,
    ) -> Result<FnFlow<'f>, String> {
        for s in stmts {
            match self.fn_stmt(file, s, scope)? {
                FnFlow::Next => {}
                other => return Ok(other),
            }
        }
        Ok(FnFlow::Next)
    }

    /// A condition's value, or why it is not known.
    fn fn_cond(
        &self,
        file: FileId,
        e: &'f crate::krl::Expr,
        scope: &Scope<'f>,
    ) -> Result<bool, String> {
        match self.eval(file, e, scope) {
            Value::Bool(b) => Ok(b),
            v => Err(format!("it depends on {}", reason(&v, "a condition"))),
        }
    }

    fn fn_stmt(
        &self,
        file: FileId,
        s: &'f Stmt,
        scope: &mut Scope<'f>,
    ) -> Result<FnFlow<'f>, String> {
        let steps = self.fn_steps.get() + 1;
        self.fn_steps.set(steps);
        if steps > MAX_FN_STEPS {
            return Err(format!("it runs more than {MAX_FN_STEPS} statements"));
        }
        let line = s.line;
        let src = self.src(file);
        Ok(match &s.kind {
            StmtKind::Decl(d) => {
                for v in &d.vars {
                    let name = upper(src.text(v.name));
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
                FnFlow::Next
            }
            StmtKind::Assign(a) => {
                let p = a
                    .lhs
                    .as_path()
                    .ok_or_else(|| format!("line {line}: an assignment not understood"))?;
                let v = self.eval(file, &a.rhs, scope);
                let place = self.place(file, p, scope)?;
                if !scope.vars.contains_key(&place.root) {
                    return Err(format!(
                        "it sets {} at line {line}, data outside the function",
                        place.text()
                    ));
                }
                self.store_local(file, place, v, scope);
                FnFlow::Next
            }
            StmtKind::If(cond) => {
                let b = s.block.as_ref().expect("IF is a block");
                if self.fn_cond(file, cond, scope)? {
                    self.fn_block(file, &b.body, scope)?
                } else {
                    match b.arms.iter().find(|a| a.kind == ArmKind::Else) {
                        Some(a) => self.fn_block(file, &a.body, scope)?,
                        None => FnFlow::Next,
                    }
                }
            }
            StmtKind::Switch(sel) => {
                let b = s.block.as_ref().expect("SWITCH is a block");
                let v = self.eval(file, sel, scope);
                let key = super::flow::case_key(&v).ok_or_else(|| {
                    format!("it depends on {}", reason(&v, "its SWITCH selector"))
                })?;
                let mut chosen = None;
                for a in &b.arms {
                    if let ArmKind::Case(values) = &a.kind {
                        for e in values {
                            if super::flow::case_key(&self.eval(file, e, scope)).as_ref()
                                == Some(&key)
                            {
                                chosen = chosen.or(Some(a));
                            }
                        }
                    }
                }
                match chosen.or_else(|| b.arms.iter().find(|a| a.kind == ArmKind::Default)) {
                    Some(a) => self.fn_block(file, &a.body, scope)?,
                    None => FnFlow::Next,
                }
            }
            StmtKind::For(Some(f)) => {
                let b = s.block.as_ref().expect("FOR is a block");
                let int = |e: &'f crate::krl::Expr, scope: &Scope<'f>| {
                    self.eval(file, e, scope)
                        .as_int()
                        .ok_or_else(|| format!("line {line}: FOR bounds known only at run time"))
                };
                let (from, to) = (int(&f.from, scope)?, int(&f.to, scope)?);
                let step = match &f.step {
                    Some(e) => int(e, scope)?,
                    None => 1,
                };
                if step == 0 {
                    return Err(format!("line {line}: FOR with STEP 0"));
                }
                let var = upper(src.text(f.var));
                if !scope.vars.contains_key(&var) {
                    return Err(format!("line {line}: its loop variable is data outside it"));
                }
                let mut i = from;
                while (step > 0 && i <= to) || (step < 0 && i >= to) {
                    scope.vars.insert(var.clone(), Value::Int(i));
                    match self.fn_block(file, &b.body, scope)? {
                        FnFlow::Next => {}
                        FnFlow::Exit => break,
                        r @ FnFlow::Return(_) => return Ok(r),
                    }
                    i += step;
                }
                FnFlow::Next
            }
            StmtKind::While(cond) => {
                let b = s.block.as_ref().expect("WHILE is a block");
                while self.fn_cond(file, cond, scope)? {
                    match self.fn_block(file, &b.body, scope)? {
                        FnFlow::Next => {}
                        FnFlow::Exit => break,
                        r @ FnFlow::Return(_) => return Ok(r),
                    }
                }
                FnFlow::Next
            }
            StmtKind::Repeat(cond) => {
                let b = s.block.as_ref().expect("REPEAT is a block");
                let cond = cond
                    .as_deref()
                    .ok_or_else(|| format!("line {line}: REPEAT without UNTIL"))?;
                loop {
                    match self.fn_block(file, &b.body, scope)? {
                        FnFlow::Next => {}
                        FnFlow::Exit => break,
                        r @ FnFlow::Return(_) => return Ok(r),
                    }
                    if self.fn_cond(file, cond, scope)? {
                        break;
                    }
                }
                FnFlow::Next
            }
            StmtKind::Loop => {
                let b = s.block.as_ref().expect("LOOP is a block");
                loop {
                    match self.fn_block(file, &b.body, scope)? {
                        FnFlow::Next => {}
                        FnFlow::Exit => break,
                        r @ FnFlow::Return(_) => return Ok(r),
                    }
                }
                FnFlow::Next
            }
            StmtKind::Exit => FnFlow::Exit,
            StmtKind::Return(Some(e)) => FnFlow::Return(self.eval(file, e, scope)),
            StmtKind::Return(None) => return Err(format!("line {line}: RETURN without a value")),
            StmtKind::Motion(_) | StmtKind::Spline(_) => {
                return Err(format!("it moves the robot (line {line})"))
            }
            StmtKind::Call(c) => {
                return Err(format!(
                    "it calls the routine {} (line {line})",
                    src.text_lossy(c.name)
                ))
            }
            StmtKind::WaitFor(_) | StmtKind::Goto(_) | StmtKind::Halt => {
                return Err(format!("line {line} waits or jumps at run time"))
            }
            StmtKind::Opaque | StmtKind::Invalid | StmtKind::For(None) => {
                return Err(format!("line {line} was not understood"))
            }
            // Waiting a time, comments of the controller, interrupts, outputs: no value.
            _ => FnFlow::Next,
        })
    }

    /// Stores a value at a place of the function's own variables.
    fn store_local(&self, file: FileId, place: Place, value: Value<'f>, scope: &mut Scope<'f>) {
        let value = if place.fields.is_empty() {
            value
        } else {
            let text = place.text();
            let current = self.root_value(file, &place, scope);
            with_member(current, &place.fields, value, &text)
        };
        match place.index {
            Some(idx) => {
                scope.elements.insert((place.root, idx), value);
            }
            None => {
                scope.vars.insert(place.root, value);
            }
        }
    }
}

/// A function's value as the caller gets it: a position computed, not one to write back.
fn computed(v: Value<'_>) -> Value<'_> {
    match v {
        Value::Pos(mut p) => {
            p.origin = None;
            Value::Pos(p)
        }
        Value::Struc(members) => {
            Value::Struc(members.into_iter().map(|(n, v)| (n, computed(v))).collect())
        }
        v => v,
    }
}
