//! Variables and frames: assignments to variables, `$BASE`/`$TOOL`, `BASE_DATA[n]`/`TOOL_DATA[n]`
//! from the program, the `$config.dat` or the command line, and `FDAT` base numbers.

use crate::krl::{Access, Expr, Stmt};

use super::eval::reason;
use super::*;
use crate::motion::frame::Frame;
use crate::motion::value::{self, Declared, Value, VarRef};
use crate::motion::workspace::FileId;

impl<'f> Simulator<'f> {
    pub(super) fn set_var(&mut self, name: &[u8], value: Value<'f>, scope: &mut Scope<'f>) {
        if scope.vars.contains_key(name) || !self.globals.vars.contains_key(name) {
            scope.vars.insert(name.to_vec(), value);
        } else {
            self.globals.vars.insert(name.to_vec(), value);
        }
    }

    pub(super) fn assign(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        lhs: &'f Expr,
        rhs: &'f Expr,
        scope: &mut Scope<'f>,
    ) {
        let Some(p) = lhs.as_path() else {
            return;
        };
        let src = self.src(file);
        let root = upper(src.text(p.root));
        if p.access.is_empty() {
            match root.as_slice() {
                b"$BASE" => {
                    self.state.base = self.frame_value(file, s, rhs, scope, "$BASE");
                    return;
                }
                b"$TOOL" => {
                    self.state.tool = self.frame_value(file, s, rhs, scope, "$TOOL");
                    return;
                }
                b"$IPO_MODE" => {
                    self.state.external_tcp =
                        self.is_tcp(file, rhs, scope).then_some((file, s.head));
                    return;
                }
                b"$ORI_TYPE" => {
                    self.state.ori_type = self.ori_type_of(file, rhs, scope);
                    return;
                }
                b"LDAT_ACT" => {
                    self.state.ldat_ori = match self.eval(file, rhs, scope) {
                        Value::Ldat(ori) => ori.filter(|o| o != b"VAR"),
                        _ => None,
                    };
                    return;
                }
                b"FDAT_ACT" => {
                    self.state.fdat = match self.eval(file, rhs, scope) {
                        Value::Fdat(f) => Some(f),
                        _ => None,
                    };
                    return;
                }
                _ => {}
            }
            if root.starts_with(b"$") {
                return; // other system variables do not move the robot
            }
            let mut v = self.eval(file, rhs, scope);
            if let Value::Pos(pos) = &mut v {
                if let Some(o) = pos.origin.as_mut().filter(|o| o.var.is_none()) {
                    o.var = self.assigned_point(file, s, p.root, &root);
                }
            }
            self.set_var(&root, v, scope);
            return;
        }
        if root.starts_with(b"$") {
            return;
        }
        // An element or member assignment: `P[3] = {…}`, `P1.X = 100`.
        let v = self.eval(file, rhs, scope);
        match p.access.as_slice() {
            [Access::Index { items, .. }] => {
                let idx: Option<Vec<i64>> = items
                    .iter()
                    .map(|e| self.eval(file, e, scope).as_int())
                    .collect();
                if let Some(idx) = idx {
                    let key = (root, idx);
                    if scope.elements.contains_key(&key)
                        || !self.globals.elements.contains_key(&key)
                            && scope.vars.contains_key(&key.0)
                    {
                        scope.elements.insert(key, v);
                    } else {
                        self.globals.elements.insert(key, v);
                    }
                }
            }
            [Access::Field { name, .. }] => {
                let field = upper(src.text(*name));
                let mut current = self.lookup(file, &root, scope);
                if let (Value::Pos(pos), Some((axis, k))) = (&mut current, value::component(&field))
                {
                    if pos.axis == axis {
                        pos.v[k] = v.as_f64();
                        // Computed now: its numbers are no longer those of the aggregate.
                        pos.origin = None;
                    }
                }
                self.set_var(&root, current, scope);
            }
            _ => {}
        }
    }

    /// The point `name` (written at `at`) given a literal position by statement `s`, when it
    /// is declared without a value in a file of the program (not `$config.dat`): a use of it
    /// reached with other rotation directions than another can then get a copy of its own,
    /// declared and assigned next to the original.
    fn assigned_point(&self, file: FileId, s: &Stmt, at: Span, name: &[u8]) -> Option<VarRef> {
        // Declared in this module (its .src or .dat): where the copy's declaration may go.
        let own = *self.module_of.get(file as usize)?;
        let sym = self.symbols.get(own)?.get(name)?;
        if sym.var.init.is_some() || sym.var.dims.is_some() || sym.decl.constant.is_some() {
            return None;
        }
        Some(VarRef {
            file,
            name: at,
            stmt: s.head,
            element: false,
            declared: Some(Declared {
                file: self.id_of(sym.file),
                stmt: sym.var.span,
                ty: sym.decl.ty.span,
            }),
        })
    }

    pub(super) fn is_tcp(&self, file: FileId, e: &'f Expr, scope: &Scope<'f>) -> bool {
        matches!(self.eval(file, e, scope), Value::Enum(ref n) if n == b"TCP")
    }

    /// The value of a `$BASE`/`$TOOL` assignment.
    pub(super) fn frame_value(
        &mut self,
        file: FileId,
        s: &Stmt,
        rhs: &'f Expr,
        scope: &Scope<'f>,
        what: &str,
    ) -> FrameState {
        match self.eval(file, rhs, scope) {
            Value::Pos(p) if !p.axis && p.is_complete() => {
                FrameState::Known(Frame::from_kuka(&p.v.map(|x| x.unwrap_or(0.0))))
            }
            Value::Pos(p) if !p.axis => {
                // Missing components of a frame aggregate are zero.
                FrameState::Known(Frame::from_kuka(&p.v.map(|x| x.unwrap_or(0.0))))
            }
            v => FrameState::Unknown(
                file,
                s.head,
                format!("{what} is set from {}", reason(&v, "an unknown value")),
            ),
        }
    }

    pub(super) fn config_frame(&self, base: bool, n: i64) -> FrameState {
        let name: &[u8] = if base { b"BASE_DATA" } else { b"TOOL_DATA" };
        if n == 0 {
            return FrameState::Known(Frame::identity());
        }
        if let Some(g) = self.given.iter().find(|g| g.base == base && g.index == n) {
            return FrameState::Known(Frame::from_kuka(&g.xyzabc));
        }
        let value = self.config_element(name, n);
        match value {
            Some(Value::Pos(p)) if !p.axis => {
                FrameState::Known(Frame::from_kuka(&p.v.map(|x| x.unwrap_or(0.0))))
            }
            _ => FrameState::Unknown(0, Span::default(), String::new()),
        }
    }

    pub(super) fn config_element(&self, name: &[u8], n: i64) -> Option<Value<'f>> {
        let cfg = self.config.as_ref()?;
        let (f, e) = cfg.element(name, &[n])?;
        let id = self.id_of(f);
        Some(self.eval(id, e, &Scope::default()))
    }

    /// An orientation type other than `#VAR` assigned to `$ORI_TYPE`.
    pub(super) fn ori_type_of(
        &self,
        file: FileId,
        rhs: &'f Expr,
        scope: &Scope<'f>,
    ) -> Option<Vec<u8>> {
        match self.eval(file, rhs, scope) {
            Value::Enum(e) if e != b"VAR" => Some(e),
            _ => None,
        }
    }

    /// Applies `FDAT_ACT` (what `BAS(#PTP_PARAMS…)`/`BAS(#CP_PARAMS…)` do in an inline form).
    pub(super) fn apply_fdat(&mut self, file: FileId, s: &Stmt) {
        let Some(fdat) = self.state.fdat else {
            return;
        };
        if let Some(n) = fdat.tool_no {
            self.state.tool = self.frame_by_number(file, s, false, n);
        }
        if let Some(n) = fdat.base_no {
            self.state.base = self.frame_by_number(file, s, true, n);
        }
        self.state.external_tcp = fdat.external_tcp.then_some((file, s.head));
    }

    pub(super) fn frame_by_number(&self, file: FileId, s: &Stmt, base: bool, n: i64) -> FrameState {
        match self.config_frame(base, n) {
            FrameState::Unknown(..) => FrameState::Unknown(
                file,
                s.head,
                format!(
                    "{}[{n}] is not known",
                    if base { "BASE_DATA" } else { "TOOL_DATA" }
                ),
            ),
            k => k,
        }
    }
}
