//! Variables and frames: assignments to variables, `$BASE`/`$TOOL`, `BASE_DATA[n]`/`TOOL_DATA[n]`
//! from the program, the `$config.dat` or the command line, and `FDAT` base numbers.

use crate::krl::{Access, Expr, SourceFile, Stmt};

use super::eval::reason;
use super::*;
use crate::krl::interpret::value::{self, Declared, Value, VarRef};
use crate::krl::interpret::workspace::FileId;
use crate::motion::frame::Frame;

/// An assignable place: a variable or array element, and the members under it
/// (`P[3].X`: root `P`, index `[3]`, fields `X`).
pub(super) struct Place {
    pub root: Vec<u8>,
    pub index: Option<Vec<i64>>,
    pub fields: Vec<Vec<u8>>,
}

impl Place {
    /// `P`, `P[i, j]`, `P.X`, `P[i].F.X` as written (for messages).
    pub fn text(&self) -> String {
        let mut t = String::from_utf8_lossy(&self.root).into_owned();
        if let Some(ix) = &self.index {
            t += &format!(
                "[{}]",
                ix.iter().map(i64::to_string).collect::<Vec<_>>().join(",")
            );
        }
        for f in &self.fields {
            t.push('.');
            t += &String::from_utf8_lossy(f);
        }
        t
    }
}

/// `value` with its member at `fields` replaced by `new`: a position's components (`X`,
/// `A1`, `S`, `T`; a value it does not have yet starts a partial position) or a structure's
/// members, nested. A member set from a value not known before run time makes the whole
/// value unknown, saying which member and why.
pub(super) fn with_member<'f>(
    value: Value<'f>,
    fields: &[Vec<u8>],
    new: Value<'f>,
    place: &str,
) -> Value<'f> {
    let Some((field, rest)) = fields.split_first() else {
        return new;
    };
    if new.is_unknown() {
        // The whole value is unknown now (the message says which member and why).
        return new;
    }
    match value {
        Value::Pos(mut pos) if rest.is_empty() => {
            let component = value::component(field);
            match (component, field.as_slice()) {
                (Some((naming, k)), _)
                    if naming == pos.v.naming() || pos.v.values().iter().all(Option::is_none) =>
                {
                    let Some(x) = new.as_f64() else {
                        return Value::Unknown(format!(
                            "{place} was set from a value that is not a number"
                        ));
                    };
                    pos.v = value::Components::named(naming, *pos.v.values());
                    pos.v.values_mut()[k] = Some(x);
                }
                (_, b"S") | (_, b"T") => {
                    let Some(x) = new.as_int() else {
                        return Value::Unknown(format!(
                            "{place} was set from a value that is not an integer"
                        ));
                    };
                    if field == b"S" {
                        pos.s = Some(x as u8);
                    } else {
                        pos.t = Some(x as u8);
                    }
                }
                // External axes and other members do not change the position.
                _ => return Value::Pos(pos),
            }
            // Computed now: its numbers are no longer those of the aggregate.
            pos.origin = None;
            Value::Pos(pos)
        }
        Value::Struc(mut members) => {
            let at = members.iter().position(|(n, _)| n == field);
            let old = at.map_or_else(
                || Value::Unknown("a member not set".into()),
                |i| members[i].1.clone(),
            );
            let v = with_member(old, rest, new, place);
            match at {
                Some(i) => members[i].1 = v,
                None => members.push((field.clone(), v)),
            }
            Value::Struc(members)
        }
        // Nothing known yet: a structure (or a position, by its component names) begins.
        Value::Unknown(_) => {
            let start = if rest.is_empty() && value::component(field).is_some() {
                Value::Pos(value::Pos::numbers(value::Components::Pose([None; 6])))
            } else {
                Value::Struc(Vec::new())
            };
            with_member(start, fields, new, place)
        }
        _ => Value::Unknown(format!("{place}: a member of a value without members")),
    }
}

impl<'f> Simulator<'f> {
    /// The key of variable `name` used in `file` in the walk's global store: a variable of a
    /// module's own data (not shared by the cell) is that module's, so two modules' `i` are
    /// two variables.
    pub(super) fn global_key(&self, file: FileId, name: &[u8]) -> Vec<u8> {
        let own = self
            .module_of
            .get(file as usize)
            .copied()
            .unwrap_or(usize::MAX);
        match self.symbols.get(own).and_then(|s| s.get(name)) {
            Some(sym) if self.module_of_file(sym.file) == Some(own) => {
                let mut k = format!("{own}:").into_bytes();
                k.extend_from_slice(name);
                k
            }
            _ => name.to_vec(),
        }
    }

    fn module_of_file(&self, f: &SourceFile) -> Option<usize> {
        let id = self.id_of(f) as usize;
        self.module_of.get(id).copied().filter(|&m| m != usize::MAX)
    }

    /// Sets variable `name`: the routine's own (declared in it, a parameter, a loop
    /// variable it declares) or else the data the routine sees (its module's, the cell's),
    /// which other routines read after it.
    pub(super) fn set_var(
        &mut self,
        file: FileId,
        name: &[u8],
        value: Value<'f>,
        scope: &mut Scope<'f>,
    ) {
        self.assignments += 1;
        if scope.vars.contains_key(name) {
            if scope.params.contains(name) {
                scope.written.insert(name.to_vec());
            }
            scope.vars.insert(name.to_vec(), value);
        } else {
            let key = self.global_key(file, name);
            self.globals.vars.insert(key, value);
        }
    }

    /// Sets element `idx` of array `name` (see [`Simulator::set_var`] for whose it is).
    pub(super) fn set_element(
        &mut self,
        file: FileId,
        name: &[u8],
        idx: Vec<i64>,
        value: Value<'f>,
        scope: &mut Scope<'f>,
    ) {
        self.assignments += 1;
        if scope.vars.contains_key(name) || scope.arrays.contains_key(name) {
            if scope.params.contains(name) {
                scope.written.insert(name.to_vec());
            }
            scope.elements.insert((name.to_vec(), idx), value);
        } else {
            let key = self.global_key(file, name);
            self.globals.elements.insert((key, idx), value);
        }
    }

    /// The place a path names, its indices evaluated; `Err` says why it is not one.
    pub(super) fn place(
        &self,
        file: FileId,
        p: &'f crate::krl::Path,
        scope: &Scope<'f>,
    ) -> Result<Place, String> {
        let src = self.src(file);
        let mut place = Place {
            root: upper(src.text(p.root)),
            index: None,
            fields: Vec::new(),
        };
        for (k, a) in p.access.iter().enumerate() {
            match a {
                Access::Index { items, slice, .. } if k == 0 && !slice => {
                    let idx: Result<Vec<i64>, String> = items
                        .iter()
                        .map(|e| {
                            let v = self.eval(file, e, scope);
                            v.as_int().ok_or_else(|| reason(&v, "an index"))
                        })
                        .collect();
                    place.index = Some(idx?);
                }
                Access::Field { name, .. } => place.fields.push(upper(src.text(*name))),
                _ => return Err("an index that is not the first access".into()),
            }
        }
        Ok(place)
    }

    /// The value at a place's root (the variable, or the element).
    pub(super) fn root_value(&self, file: FileId, place: &Place, scope: &Scope<'f>) -> Value<'f> {
        match &place.index {
            Some(idx) => self.element(file, &place.root, idx, scope),
            None => self.lookup(file, &place.root, scope),
        }
    }

    /// Stores `value` at `place` (members replaced inside the root's value).
    pub(super) fn store(
        &mut self,
        file: FileId,
        place: Place,
        value: Value<'f>,
        scope: &mut Scope<'f>,
    ) {
        let value = if place.fields.is_empty() {
            value
        } else {
            let text = place.text();
            let current = self.root_value(file, &place, scope);
            with_member(current, &place.fields, value, &text)
        };
        match place.index {
            Some(idx) => self.set_element(file, &place.root, idx, value, scope),
            None => self.set_var(file, &place.root, value, scope),
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
        if root.starts_with(b"$") {
            self.assign_system(file, s, p, &root, rhs, scope);
            return;
        }
        match (root.as_slice(), p.access.is_empty()) {
            (b"LDAT_ACT", true) => {
                self.state.ldat_ori = match self.eval(file, rhs, scope) {
                    Value::Ldat(ori) => ori.filter(|o| o != b"VAR"),
                    _ => None,
                };
                return;
            }
            (b"FDAT_ACT", true) => {
                self.state.fdat = match self.eval(file, rhs, scope) {
                    Value::Fdat(f) => Some(f),
                    _ => None,
                };
                return;
            }
            _ => {}
        }
        if p.access
            .iter()
            .any(|a| matches!(a, Access::Index { slice: true, .. }))
        {
            // A slice (`NAME[1,] = "PICK"`): a string or a row of an array, nothing that moves.
            return;
        }
        let mut v = self.eval(file, rhs, scope);
        let place = match self.place(file, p, scope) {
            Ok(place) => place,
            Err(why) => {
                // An element whose index is known only at run time: which one it sets is not
                // known, so none of the array's elements is known after it (said once).
                let indexed = matches!(p.access.first(), Some(Access::Index { .. }));
                let shown = src.text_lossy(p.root).into_owned();
                let first = !self.unknown_arrays.contains_key(&root);
                let said = format!("{shown}[…] set at line {} with an index {why}", s.line);
                if indexed {
                    self.unknown_arrays.entry(root.clone()).or_insert(said);
                } else {
                    self.set_var(file, &root, Value::Unknown(said), scope);
                }
                if first || !indexed {
                    let whole = if indexed {
                        " (the whole array; said once)"
                    } else {
                        ""
                    };
                    self.warn(
                        file,
                        s.head,
                        format!("this assignment is not followed ({why}): what it sets is unknown after it{whole}"),
                    );
                }
                return;
            }
        };
        if let Value::Unknown(why) = &v {
            // Said where it happens: the next use says only that the value is unknown.
            v = Value::Unknown(format!(
                "{} set at line {} from {why}",
                src.text_lossy(p.span),
                s.line
            ));
        }
        if let (Value::Pos(pos), None, true) = (&mut v, &place.index, place.fields.is_empty()) {
            if let Some(o) = pos.origin.as_mut().filter(|o| o.var.is_none()) {
                o.var = self.assigned_point(file, s, p.root, &root);
            }
        }
        self.store(file, place, v, scope);
    }

    /// An assignment to a system variable: frames and interpolation settings the walk
    /// follows (whole or a member: `$BASE.X = …`); others do not move the robot.
    fn assign_system(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        p: &'f crate::krl::Path,
        root: &[u8],
        rhs: &'f Expr,
        scope: &mut Scope<'f>,
    ) {
        let whole = p.access.is_empty();
        match root {
            b"$BASE" | b"$TOOL" => {
                let what = if root == b"$BASE" { "$BASE" } else { "$TOOL" };
                let st = if whole {
                    self.frame_value(file, s, rhs, scope, what)
                } else {
                    match self.place(file, p, scope) {
                        Ok(place) => {
                            let current = self.lookup(file, root, scope);
                            let v = self.eval(file, rhs, scope);
                            let v = with_member(current, &place.fields, v, &place.text());
                            self.frame_of(file, s, v, what)
                        }
                        Err(why) => FrameState::Unknown(file, s.head, why, GIVE_FRAME),
                    }
                };
                if root == b"$BASE" {
                    self.state.base = st;
                } else {
                    self.state.tool = st;
                }
            }
            b"$IPO_MODE" if whole => {
                self.state.external_tcp = self.is_tcp(file, rhs, scope).then_some((file, s.head));
            }
            b"$ORI_TYPE" if whole => {
                self.state.ori_type = self.ori_type_of(file, rhs, scope);
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
        let v = self.eval(file, rhs, scope);
        self.frame_of(file, s, v, what)
    }

    /// A frame's state from a value (missing components of a frame aggregate are zero).
    pub(super) fn frame_of(&self, file: FileId, s: &Stmt, v: Value<'f>, what: &str) -> FrameState {
        match v {
            Value::Pos(p) if !p.v.is_axes() => FrameState::Known(Frame::from_kuka(&p.frame_pose())),
            v => FrameState::Unknown(
                file,
                s.head,
                format!("{what} is set from {}", reason(&v, "an unknown value")),
                GIVE_FRAME,
            ),
        }
    }

    pub(super) fn config_frame(&self, base: bool, n: i64) -> FrameState {
        let name: &[u8] = if base { b"BASE_DATA" } else { b"TOOL_DATA" };
        if n == 0 {
            return FrameState::Known(Frame::identity());
        }
        if let Some(g) = self.given.iter().find(|g| g.base == base && g.index == n) {
            return FrameState::Known(Frame::from_kuka(&g.pose));
        }
        let value = self.config_element(name, n);
        match value {
            Some(Value::Pos(p)) if !p.v.is_axes() => {
                FrameState::Known(Frame::from_kuka(&p.frame_pose()))
            }
            _ => FrameState::Unknown(0, Span::default(), String::new(), GIVE_FRAME),
        }
    }

    /// Without a `$config.dat` holding frames (none given, none in the cell's tree): the
    /// frames of it the program's files name (`TOOL_DATA[n]`, `BASE_DATA[n]`, an `FDAT`'s
    /// `TOOL_NO`/`BASE_NO`), none given on the command line, and how to give them.
    pub(super) fn frames_without_config(&self) -> Option<String> {
        let has = self
            .config
            .as_ref()
            .is_some_and(|c| c.get(b"TOOL_DATA").is_some() || c.get(b"BASE_DATA").is_some());
        if has {
            return None;
        }
        let mut named = std::collections::BTreeSet::new();
        for f in self
            .ws
            .files
            .iter()
            .filter(|f| f.role != crate::krl::interpret::workspace::Role::Config)
        {
            config_frames_named(f.file.source(), &mut named);
        }
        named.retain(|&(base, n)| {
            n != 0 && !self.given.iter().any(|g| g.base == base && g.index == n)
        });
        if named.is_empty() {
            return None;
        }
        let what = |(base, n): &(bool, i64)| {
            format!("{}[{n}]", if *base { "BASE_DATA" } else { "TOOL_DATA" })
        };
        let arg = |(base, n): &(bool, i64)| {
            format!("--{} {n}=X,Y,Z,A,B,C", if *base { "base" } else { "tool" })
        };
        // Tools first, as the pendant lists them.
        let mut order: Vec<&(bool, i64)> = named.iter().collect();
        order.sort_by_key(|(base, n)| (*base, *n));
        for (base, n) in &order {
            self.need(what(&(*base, *n)));
        }
        Some(format!(
            "no $config.dat was given or found in the cell, and this program needs {}: give {} with {}, or the robot's $config.dat apart with --config FILE",
            order.iter().map(|f| what(f)).collect::<Vec<_>>().join(", "),
            if order.len() == 1 { "it" } else { "them" },
            order.iter().map(|f| arg(f)).collect::<Vec<_>>().join(" "),
        ))
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
            FrameState::Unknown(..) => {
                let what = format!("{}[{n}]", if base { "BASE_DATA" } else { "TOOL_DATA" });
                self.need(what.clone());
                FrameState::Unknown(file, s.head, format!("{what} is not known"), GIVE_FRAME)
            }
            k => k,
        }
    }
}

/// The frames of `$config.dat` named in `src`: `TOOL_DATA[n]`, `BASE_DATA[n]`, and an
/// `FDAT`'s `TOOL_NO n`, `BASE_NO n` (any case), as (base, n).
fn config_frames_named(src: &[u8], out: &mut std::collections::BTreeSet<(bool, i64)>) {
    let upper = src.to_ascii_uppercase();
    for (pattern, base, bracket) in [
        (&b"TOOL_DATA["[..], false, true),
        (b"BASE_DATA[", true, true),
        (b"TOOL_NO", false, false),
        (b"BASE_NO", true, false),
    ] {
        for at in memchr::memmem::find_iter(&upper, pattern) {
            let rest = &upper[at + pattern.len()..];
            let rest = if bracket {
                rest
            } else {
                rest.trim_ascii_start()
            };
            let digits = rest.iter().take_while(|b| b.is_ascii_digit()).count();
            let closed = !bracket || rest.get(digits) == Some(&b']');
            let n = std::str::from_utf8(&rest[..digits])
                .ok()
                .and_then(|d| d.parse::<i64>().ok());
            if let (Some(n), true) = (n, closed) {
                out.insert((base, n));
            }
        }
    }
}
