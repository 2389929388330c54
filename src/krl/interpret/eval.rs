//! Expressions and values: evaluates an expression to a [`Value`] as far as it is known before
//! run time (variables, array elements, struct members, `$POS_ACT`, operators, functions).

use crate::kinematics::status_turn;
use crate::krl::{self, Access, BinOp, Call, Expr, UnOp};

use super::*;
use crate::krl::interpret::value::{self, Components, Pos, Value, VarRef};
use crate::krl::interpret::workspace::FileId;
use crate::motion::frame::Frame;
use crate::motion::nominal::Nominal;

impl<'f> Simulator<'f> {
    // ---- expressions -----------------------------------------------------------------------

    pub(super) fn eval(&self, file: FileId, e: &'f Expr, scope: &Scope<'f>) -> Value<'f> {
        let src = self.src(file);
        match e {
            Expr::Number(n) => value::number(n),
            Expr::Bool(_, b) => Value::Bool(*b),
            Expr::Enum(s) => Value::Enum(upper(&src.text(*s)[1..])),
            Expr::Bits(s) => match value::bits_value(src.text(*s)) {
                Some(v) => Value::Int(v),
                None => Value::Unknown("a bit literal".into()),
            },
            Expr::Str(_) => Value::Unknown("a string".into()),
            Expr::Aggregate(_, id) => {
                value::aggregate(src, file, src.aggregate(*id), |e| self.eval(file, e, scope))
            }
            Expr::Path(p) => self.path(file, p, scope),
            Expr::Paren(p) => self.eval(file, &p.inner, scope),
            Expr::Unary(u) => {
                let v = self.eval(file, &u.operand, scope);
                match (u.op, v) {
                    (UnOp::Neg, Value::Int(i)) => Value::Int(-i),
                    (UnOp::Neg, Value::Real(r)) => Value::Real(-r),
                    (UnOp::Plus, v @ (Value::Int(_) | Value::Real(_))) => v,
                    (UnOp::Not, Value::Bool(b)) => Value::Bool(!b),
                    (_, v @ Value::Unknown(_)) => v,
                    _ => Value::Unknown("an operator on a value it does not apply to".into()),
                }
            }
            Expr::Binary(b) => {
                let l = self.eval(file, &b.lhs, scope);
                let r = self.eval(file, &b.rhs, scope);
                binary(b.op, l, r, &self.prefixes)
            }
            Expr::Call(c) => self.function(file, c, scope),
            Expr::Opaque(_) => Value::Unknown("an expression that was not understood".into()),
        }
    }

    /// The inline forms' frame functions; anything else is a run-time value.
    pub(super) fn function(&self, file: FileId, c: &'f Call, scope: &Scope<'f>) -> Value<'f> {
        let src = self.src(file);
        let name = upper(src.text(c.name));
        let arg = |i: usize| {
            c.args
                .get(i)
                .and_then(|a| a.as_ref())
                .map(|a| self.eval(file, a, scope))
        };
        let frame = |base: bool, n: Option<i64>| match n.map(|n| self.config_frame(base, n)) {
            Some(FrameState::Known(f)) => Value::Pos(Pos::numbers(Components::of_pose(
                &f.to_kuka_near(&[0.0; 3]),
            ))),
            _ => Value::Unknown(format!(
                "{}[{}], which is not known",
                if base { "BASE_DATA" } else { "TOOL_DATA" },
                n.map_or("?".to_string(), |n| n.to_string())
            )),
        };
        match name.as_slice() {
            b"STOOL2" | b"STOOL" => match arg(0) {
                Some(Value::Fdat(f)) => frame(false, f.tool_no),
                Some(v) => frame(false, v.as_int()),
                None => Value::Unknown("STOOL2 without argument".into()),
            },
            b"SBASE" => match arg(0) {
                Some(Value::Fdat(f)) => frame(true, f.base_no),
                Some(v) => frame(true, v.as_int()),
                None => Value::Unknown("SBASE without argument".into()),
            },
            b"SORI_TYP" => match arg(0) {
                Some(Value::Ldat(Some(ori))) => Value::Enum(ori),
                _ => Value::Unknown("SORI_TYP of an unknown motion data set".into()),
            },
            b"SIPO_MODE" => match arg(0) {
                Some(Value::Fdat(f)) => Value::Enum(if f.external_tcp {
                    b"TCP".to_vec()
                } else {
                    b"BASE".to_vec()
                }),
                Some(v) => v,
                None => Value::Unknown("SIPO_MODE without argument".into()),
            },
            _ => self.user_function(file, c, scope),
        }
    }

    pub(super) fn current_pos(&self, axis: bool) -> Value<'f> {
        let Some(cur) = self.state.current else {
            return Value::Unknown("the robot's position, unknown here".into());
        };
        let v = if axis {
            Components::Axes(cur.axes.map(Some))
        } else {
            let (Some(base), Some(tool)) =
                (self.known(&self.state.base), self.known(&self.state.tool))
            else {
                return Value::Unknown("the position in an unknown frame".into());
            };
            let tcp = Nominal(&self.robot).tcp(&cur.axes, &tool);
            Components::of_pose(&base.inverse().compose(&tcp).to_kuka_near(&[0.0; 3]))
        };
        let (s, t) = status_turn(&self.robot, &cur.axes);
        Value::Pos(Pos {
            v,
            s: (!axis).then_some(s),
            t: (!axis).then_some(t),
            origin: None,
        })
    }

    pub(super) fn known(&self, f: &FrameState) -> Option<Frame> {
        match f {
            FrameState::Known(f) => Some(*f),
            FrameState::Unset => Some(Frame::identity()),
            FrameState::Unknown(..) => None,
        }
    }

    pub(super) fn lookup(&self, file: FileId, name: &[u8], scope: &Scope<'f>) -> Value<'f> {
        // A value the walk knows from the program's own assignments wins over an assumption;
        // an assumption wins over what only run time knows and over a declared initial value.
        let assumed = || {
            (!self.assumptions.is_empty())
                .then(|| self.assumed(name, &[]))
                .flatten()
        };
        if let Some(v) = scope.vars.get(name) {
            if let (Value::Unknown(_), Some(a)) = (v, assumed()) {
                return a;
            }
            return v.clone();
        }
        if !self.globals.vars.is_empty() {
            if let Some(v) = self.globals.vars.get(&self.global_key(file, name)) {
                if let (Value::Unknown(_), Some(a)) = (v, assumed()) {
                    return a;
                }
                return v.clone();
            }
        }
        if let Some(a) = assumed() {
            return a;
        }
        match name {
            b"$NULLFRAME" => return Value::Pos(Pos::numbers(Components::Pose([Some(0.0); 6]))),
            // The operating mode: compensated programs are for the production run,
            // automatic external (said once, see `Simulator::mode_assumed`).
            b"$T1" | b"$T2" | b"$AUT" | b"$EXT" => {
                self.mode_assumed.set(true);
                return Value::Bool(name == b"$EXT");
            }
            b"$MODE_OP" => {
                self.mode_assumed.set(true);
                return Value::Enum(b"EX".to_vec());
            }
            b"$POS_ACT" | b"$POS_INT" | b"$POS_RET" => return self.current_pos(false),
            b"$AXIS_ACT" | b"$AXIS_INT" | b"$AXIS_RET" => return self.current_pos(true),
            b"$BASE" | b"$TOOL" => {
                let st = if name == b"$BASE" {
                    &self.state.base
                } else {
                    &self.state.tool
                };
                return match self.known(st) {
                    Some(f) => Value::Pos(Pos::numbers(Components::of_pose(
                        &f.to_kuka_near(&[0.0; 3]),
                    ))),
                    None => {
                        Value::Unknown(format!("{}, unknown here", String::from_utf8_lossy(name)))
                    }
                };
            }
            _ => {}
        }
        if name.starts_with(b"$") {
            return Value::Unknown(format!(
                "the run-time value {}",
                String::from_utf8_lossy(name)
            ));
        }
        match self.symbol(file, name) {
            Some(sym) => {
                let id = self.id_of(sym.file);
                match &sym.var.init {
                    Some(e) => {
                        let mut v = self.eval(id, e, &Scope::default());
                        if let Value::Pos(p) = &mut v {
                            if let Some(o) = &mut p.origin {
                                o.var = Some(VarRef {
                                    file: id,
                                    name: sym.var.name,
                                    stmt: sym.var.span,
                                    element: false,
                                    declared: None,
                                });
                            }
                            if sym.decl.ty.kind.is_axis() {
                                p.v = Components::Axes(*p.v.values());
                            }
                        }
                        v
                    }
                    None => Value::Unknown(format!(
                        "{}, declared without a value",
                        String::from_utf8_lossy(name)
                    )),
                }
            }
            None => {
                self.need(format!(
                    "{} (declared nowhere)",
                    String::from_utf8_lossy(name)
                ));
                Value::Unknown(format!("{}, not declared", String::from_utf8_lossy(name)))
            }
        }
    }

    pub(super) fn symbol(&self, file: FileId, name: &[u8]) -> Option<&krl::Symbol<'f>> {
        let own = self
            .module_of
            .get(file as usize)
            .copied()
            .unwrap_or(usize::MAX);
        if let Some(s) = self.symbols.get(own).and_then(|s| s.get(name)) {
            return Some(s);
        }
        self.symbols
            .iter()
            .find_map(|s| s.get(name))
            .or_else(|| self.config.as_ref().and_then(|c| c.get(name)))
    }

    pub(super) fn element(
        &self,
        file: FileId,
        name: &[u8],
        idx: &[i64],
        scope: &Scope<'f>,
    ) -> Value<'f> {
        let assumed = || {
            (!self.assumptions.is_empty())
                .then(|| self.assumed(name, idx))
                .flatten()
        };
        if let Some(v) = scope.elements.get(&(name.to_vec(), idx.to_vec())) {
            if let (Value::Unknown(_), Some(a)) = (v, assumed()) {
                return a;
            }
            return v.clone();
        }
        if let Some(why) = self.unknown_arrays.get(name) {
            return assumed().unwrap_or_else(|| Value::Unknown(why.clone()));
        }
        if let Some((caller, array)) = scope.arrays.get(name) {
            // An array passed whole: the caller's elements.
            return self.element(*caller, array, idx, &Scope::default());
        }
        if !self.globals.elements.is_empty() {
            let key = (self.global_key(file, name), idx.to_vec());
            if let Some(v) = self.globals.elements.get(&key) {
                if let (Value::Unknown(_), Some(a)) = (v, assumed()) {
                    return a;
                }
                return v.clone();
            }
        }
        if let Some(a) = assumed() {
            return a;
        }
        if idx.len() == 1 && (name == b"BASE_DATA" || name == b"TOOL_DATA") {
            let base = name == b"BASE_DATA";
            if let Some(g) = self
                .given
                .iter()
                .find(|g| g.base == base && g.index == idx[0])
            {
                return Value::Pos(Pos::numbers(Components::of_pose(&g.pose)));
            }
        }
        let own = self
            .module_of
            .get(file as usize)
            .copied()
            .unwrap_or(usize::MAX);
        let found = self
            .symbols
            .get(own)
            .and_then(|s| s.element(name, idx))
            .or_else(|| self.symbols.iter().find_map(|s| s.element(name, idx)))
            .or_else(|| self.config.as_ref().and_then(|c| c.element(name, idx)));
        match found {
            Some((f, e)) => {
                let id = self.id_of(f);
                let mut v = self.eval(id, e, &Scope::default());
                if let Value::Pos(p) = &mut v {
                    if let Some(sym) = self.symbol(file, name) {
                        if sym.decl.ty.kind.is_axis() {
                            p.v = Components::Axes(*p.v.values());
                        }
                    }
                }
                v
            }
            None => Value::Unknown(format!(
                "{}[{}], not initialised",
                String::from_utf8_lossy(name),
                idx.iter().map(i64::to_string).collect::<Vec<_>>().join(",")
            )),
        }
    }

    pub(super) fn path(&self, file: FileId, p: &'f krl::Path, scope: &Scope<'f>) -> Value<'f> {
        let src = self.src(file);
        let name = upper(src.text(p.root));
        let mut access = p.access.iter();
        let mut v = match p.access.first() {
            Some(Access::Index { slice: true, .. }) => {
                return Value::Unknown(format!("the array slice {}", src.text_lossy(p.span)))
            }
            Some(Access::Index { items, .. }) => {
                access.next();
                let idx: Result<Vec<i64>, String> = items
                    .iter()
                    .map(|e| {
                        let v = self.eval(file, e, scope);
                        v.as_int().ok_or_else(|| reason(&v, "an index"))
                    })
                    .collect();
                match idx {
                    Ok(idx) => {
                        if let Some(a) = (!self.assumptions.is_empty())
                            .then(|| self.assumed(&name, &idx))
                            .flatten()
                        {
                            return a;
                        }
                        if name.starts_with(b"$") && name != b"$BASE_DATA" {
                            return Value::Unknown(format!(
                                "the run-time value {}",
                                src.text_lossy(p.span)
                            ));
                        }
                        self.element(file, &name, &idx, scope)
                    }
                    Err(why) => return Value::Unknown(why),
                }
            }
            _ => self.lookup(file, &name, scope),
        };
        for a in access {
            let Access::Field { name: field, .. } = a else {
                return Value::Unknown("an index into a non-array".into());
            };
            let field = upper(src.text(*field));
            v = match v {
                Value::Pos(pos) => match (value::component(&field), field.as_slice()) {
                    (Some((naming, k)), _) if naming == pos.v.naming() => match pos.v.values()[k] {
                        Some(x) => Value::Real(x),
                        None => Value::Unknown("a component not given".into()),
                    },
                    (_, b"S") => pos.s.map_or(Value::Unknown("S not given".into()), |s| {
                        Value::Int(s.into())
                    }),
                    (_, b"T") => pos.t.map_or(Value::Unknown("T not given".into()), |t| {
                        Value::Int(t.into())
                    }),
                    _ => Value::Unknown(format!("the member {}", String::from_utf8_lossy(&field))),
                },
                Value::Fdat(f) => match field.as_slice() {
                    b"TOOL_NO" => f
                        .tool_no
                        .map_or(Value::Unknown("TOOL_NO".into()), Value::Int),
                    b"BASE_NO" => f
                        .base_no
                        .map_or(Value::Unknown("BASE_NO".into()), Value::Int),
                    b"IPO_FRAME" => Value::Enum(if f.external_tcp {
                        b"TCP".to_vec()
                    } else {
                        b"BASE".to_vec()
                    }),
                    _ => Value::Unknown(format!("the member {}", String::from_utf8_lossy(&field))),
                },
                Value::Struc(members) => match members.into_iter().find(|(n, _)| *n == field) {
                    Some((_, v)) => v,
                    None => Value::Unknown(format!(
                        "the member {} of {}, not set",
                        String::from_utf8_lossy(&field),
                        src.text_lossy(p.root)
                    )),
                },
                u @ Value::Unknown(_) => u,
                _ => Value::Unknown("a member of a value without members".into()),
            };
        }
        v
    }
}

/// Why a value is not what was needed.
pub(super) fn reason(v: &Value, what: &str) -> String {
    match v {
        Value::Unknown(why) => why.clone(),
        _ => format!("{what} is of the wrong kind"),
    }
}

/// `l op r`; a geometric operator's prefix frame goes into `prefixes`.
pub(super) fn binary<'f>(
    op: BinOp,
    l: Value<'f>,
    r: Value<'f>,
    prefixes: &std::cell::RefCell<Vec<Frame>>,
) -> Value<'f> {
    use Value::*;
    if let Unknown(_) = l {
        return l;
    }
    if let Unknown(_) = r {
        return r;
    }
    match op {
        BinOp::Geo => match (l, r) {
            (Pos(a), Pos(mut b)) if !a.v.is_axes() && !b.v.is_axes() && a.is_complete() => {
                let fa = crate::motion::frame::Frame::from_kuka(&a.frame_pose());
                // Both operands written in the program: compensating the right one while the
                // left one may be compensated elsewhere would not add up; leave it.
                if a.origin.is_some() {
                    b.origin = None;
                }
                // The right operand is a frame: components it does not give are zero.
                b.v = value::Components::of_pose(&b.frame_pose());
                let complete = b.is_complete();
                match &mut b.origin {
                    Some(o) => {
                        let prefix = match o.prefix {
                            Some(p) => fa.compose(&prefixes.borrow()[p as usize]),
                            None => fa,
                        };
                        let mut table = prefixes.borrow_mut();
                        table.push(prefix);
                        o.prefix = Some((table.len() - 1) as u32);
                        Pos(b)
                    }
                    None if complete => {
                        let fb = crate::motion::frame::Frame::from_kuka(&b.frame_pose());
                        let c = fa.compose(&fb);
                        Pos(value::Pos {
                            v: value::Components::of_pose(&c.to_kuka_near(&[0.0; 3])),
                            s: b.s,
                            t: b.t,
                            origin: None,
                        })
                    }
                    None => Unknown("a geometric operator on a partial position".into()),
                }
            }
            _ => Unknown("a geometric operator on values that are not frames".into()),
        },
        BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div => match (l, r) {
            (Int(a), Int(b)) => match op {
                BinOp::Add => Int(a.wrapping_add(b)),
                BinOp::Sub => Int(a.wrapping_sub(b)),
                BinOp::Mul => Int(a.wrapping_mul(b)),
                _ if b != 0 => Int(a / b),
                _ => Unknown("a division by zero".into()),
            },
            (a, b) => match (a.as_f64(), b.as_f64()) {
                (Some(a), Some(b)) => Real(match op {
                    BinOp::Add => a + b,
                    BinOp::Sub => a - b,
                    BinOp::Mul => a * b,
                    _ => a / b,
                }),
                _ => Unknown("arithmetic on values that are not numbers".into()),
            },
        },
        BinOp::And | BinOp::Or | BinOp::Exor => match (l, r) {
            (Bool(a), Bool(b)) => Bool(match op {
                BinOp::And => a && b,
                BinOp::Or => a || b,
                _ => a != b,
            }),
            _ => Unknown("a logic operator on values that are not booleans".into()),
        },
        BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
            let cmp = match (&l, &r) {
                (Bool(a), Bool(b)) => Some(a.cmp(b)),
                (Enum(a), Enum(b)) => Some(a.cmp(b)),
                _ => match (l.as_f64(), r.as_f64()) {
                    (Some(a), Some(b)) => a.partial_cmp(&b),
                    _ => None,
                },
            };
            let Some(c) = cmp else {
                return Unknown("a comparison of values of different kinds".into());
            };
            use std::cmp::Ordering::*;
            Bool(match op {
                BinOp::Eq => c == Equal,
                BinOp::Ne => c != Equal,
                BinOp::Lt => c == Less,
                BinOp::Le => c != Greater,
                BinOp::Gt => c == Greater,
                _ => c != Less,
            })
        }
        BinOp::BAnd | BinOp::BOr | BinOp::BExor => match (l.as_int(), r.as_int()) {
            (Some(a), Some(b)) => Int(match op {
                BinOp::BAnd => a & b,
                BinOp::BOr => a | b,
                _ => a ^ b,
            }),
            _ => Unknown("a bit operator on values that are not integers".into()),
        },
    }
}
