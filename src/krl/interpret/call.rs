//! Calls: routines in the same or another module with their arguments — `:IN` by value,
//! `:OUT` (and no mode, KRL's default) by reference, written back to the caller's variable,
//! element or member when the routine returns; arrays passed whole (`P[]`, `P[,]`) — the
//! built-in frame routines (`BAS`), and the frames a motion's `WITH` clause sets for that
//! motion only.

use crate::krl::{self, Call, Stmt, StmtKind};

use super::*;
use crate::krl::interpret::value::Value;
use crate::krl::interpret::workspace::FileId;

impl<'f> Simulator<'f> {
    pub(super) fn call(&mut self, file: FileId, s: &'f Stmt, c: &'f Call, scope: &mut Scope<'f>) {
        let src = self.src(file);
        let name = upper(src.text(c.name));
        if name == b"BAS" {
            let kind = c
                .args
                .first()
                .and_then(|a| a.as_ref())
                .map(|a| self.eval(file, a, scope));
            let arg = c
                .args
                .get(1)
                .and_then(|a| a.as_ref())
                .map(|a| self.eval(file, a, scope));
            let Some(Value::Enum(k)) = kind else {
                return;
            };
            match k.as_slice() {
                b"TOOL" | b"BASE" => {
                    let base = k == b"BASE";
                    let st = match arg.and_then(|v| v.as_int()) {
                        Some(n) => self.frame_by_number(file, s, base, n),
                        None => FrameState::Unknown(
                            file,
                            s.head,
                            "BAS with a run-time frame number".into(),
                            GIVE_FRAME,
                        ),
                    };
                    if base {
                        self.state.base = st;
                    } else {
                        self.state.tool = st;
                    }
                }
                b"PTP_PARAMS" | b"CP_PARAMS" | b"FRAMES" | b"PTP_DAT" | b"CP_DAT" => {
                    if k == b"CP_PARAMS" || k == b"CP_DAT" {
                        self.state.ori_type = self.state.ldat_ori.clone();
                    }
                    self.apply_fdat(file, s)
                }
                _ => {}
            }
            return;
        }
        let Some((target_file, stmt, header)) = self.routines.get(&name).copied() else {
            self.missing_routine(file, s, c);
            return;
        };
        if self.depth >= MAX_CALL_DEPTH {
            self.warn(
                file,
                s.head,
                "calls nested too deeply (recursion?): not followed",
            );
            self.state.current = None;
            return;
        }
        let mut inner = Scope::default();
        let callee = self.src(target_file);
        // Where each by-reference argument goes back to when the routine returns.
        let mut back: Vec<(Vec<u8>, Result<super::assign::Place, String>, bool)> = Vec::new();
        for (i, p) in header.params.iter().enumerate() {
            let pname = upper(callee.text(p.name));
            inner.params.insert(pname.clone());
            let arg = c.args.get(i).and_then(|a| a.as_ref());
            let by_reference = p.mode != crate::krl::ParamMode::In;
            let whole_array = arg
                .and_then(|a| a.as_path())
                .filter(|a| matches!(a.access.as_slice(), [crate::krl::Access::Index { items, .. }] if items.is_empty()));
            if let Some(a) = whole_array {
                // An array passed whole: its elements are the caller's, read through.
                let array = upper(src.text(a.root));
                let caller_key = self.global_key(file, &array);
                let mine: Vec<_> = scope
                    .elements
                    .iter()
                    .filter(|((n, _), _)| *n == array)
                    .map(|((_, ix), v)| (ix.clone(), v.clone()))
                    .collect();
                let theirs: Vec<_> = self
                    .globals
                    .elements
                    .iter()
                    .filter(|((n, _), _)| *n == caller_key)
                    .map(|((_, ix), v)| (ix.clone(), v.clone()))
                    .collect();
                for (ix, v) in theirs.into_iter().chain(mine) {
                    inner.elements.insert((pname.clone(), ix), v);
                }
                inner.arrays.insert(pname.clone(), (file, array.clone()));
                inner
                    .vars
                    .insert(pname.clone(), Value::Unknown("an array".into()));
                if by_reference {
                    back.push((
                        pname,
                        Err(String::from_utf8_lossy(&array).into_owned()),
                        true,
                    ));
                }
                continue;
            }
            let v = match arg {
                Some(a) => self.eval(file, a, scope),
                None => Value::Unknown("parameter not passed".into()),
            };
            inner.vars.insert(pname.clone(), v);
            if let (true, Some(path)) = (by_reference, arg.and_then(|a| a.as_path())) {
                back.push((pname, self.place(file, path, scope), false));
            }
        }
        if target_file == self.ws.main
            && !self.src(target_file).streamed_runs().is_empty()
            && self
                .src(target_file)
                .routines()
                .next()
                .is_some_and(|(main, _)| std::ptr::eq(main, stmt))
        {
            // The main routine called again: its streamed runs are not in the tree, so the
            // program must be walked from the whole tree (the caller does it again so).
            self.out.needs_whole_tree = true;
            self.state.current = None;
            return;
        }
        self.depth += 1;
        self.routine(target_file, stmt, &mut inner);
        self.depth -= 1;
        // By-reference parameters the routine set: their values go back to the caller's.
        for (pname, place, array) in back {
            if !inner.written.contains(&pname) {
                continue;
            }
            if array {
                let Err(array) = place else { continue };
                let array = array.into_bytes();
                let elements: Vec<_> = inner
                    .elements
                    .iter()
                    .filter(|((n, _), _)| *n == pname)
                    .map(|((_, ix), v)| (ix.clone(), v.clone()))
                    .collect();
                for (ix, v) in elements {
                    self.set_element(file, &array, ix, v, scope);
                }
                continue;
            }
            let Ok(place) = place else { continue };
            if let Some(v) = inner.vars.remove(&pname) {
                self.store(file, place, v, scope);
            }
        }
    }

    /// A routine found nowhere: assumed not to move the robot (said so). While `$BASE` or
    /// `$TOOL` has not been set, it may be what sets them (`SetBaseTool(1, 2)` in a module
    /// not given): they become unknown, naming the routine, instead of `$NULLFRAME`.
    fn missing_routine(&mut self, file: FileId, s: &Stmt, c: &Call) {
        let src = self.src(file);
        let shown = src.text_lossy(c.name).into_owned();
        self.need(format!("routine {shown}"));
        let mut unset = Vec::new();
        for (base, st) in [(true, &mut self.state.base), (false, &mut self.state.tool)] {
            if matches!(st, FrameState::Unset) {
                *st = FrameState::Unknown(
                    file,
                    s.head,
                    format!(
                        "{} is not set in the program, and routine {shown}, which may set it, is not found",
                        if base { "$BASE" } else { "$TOOL" }
                    ),
                    "give the module defining that routine (--cell DIR, or --config FILE), or set the frame in the program",
                );
                unset.push(if base { "$BASE" } else { "$TOOL" });
            }
        }
        let frames = if unset.is_empty() {
            String::new()
        } else {
            format!(
                "; {} not set before it, so unknown after it",
                unset.join(" and ")
            )
        };
        self.warn(
            file,
            c.name,
            format!(
                "routine {shown} is not found here, beside the program or in the cell: assumed not to move the robot{frames}"
            ),
        );
    }

    /// `WITH` items of a motion or spline block: `$TOOL`, `$BASE`, `$IPO_MODE` for this motion.
    pub(super) fn apply_with(
        &mut self,
        file: FileId,
        with: &'f [krl::WithItem],
        scope: &Scope<'f>,
    ) -> Option<State> {
        if with.is_empty() {
            return None;
        }
        let saved = self.state.clone();
        for w in with {
            let Some(p) = w.lhs.as_path() else { continue };
            let name = upper(self.src(file).text(p.root));
            let fake = Stmt {
                leading: w.span,
                head: w.span,
                end: w.span.end,
                line: 0,
                fold: None,
                kind: StmtKind::Opaque,
                block: None,
            };
            match name.as_slice() {
                b"$TOOL" => {
                    self.state.tool = self.frame_value(file, &fake, &w.value, scope, "$TOOL")
                }
                b"$BASE" => {
                    self.state.base = self.frame_value(file, &fake, &w.value, scope, "$BASE")
                }
                b"$IPO_MODE" => {
                    self.state.external_tcp =
                        self.is_tcp(file, &w.value, scope).then_some((file, w.span))
                }
                b"$ORI_TYPE" => self.state.ori_type = self.ori_type_of(file, &w.value, scope),
                _ => {}
            }
        }
        Some(saved)
    }

    pub(super) fn restore(&mut self, saved: State) {
        // Frames set by WITH hold for that motion only; the position moves on.
        let current = self.state.current;
        self.state = saved;
        self.state.current = current;
    }
}
