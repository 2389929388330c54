//! Calls: routines in the same or a sibling module with their arguments, the built-in frame
//! routines (`BAS`), and the frames a motion's `WITH` clause sets for that motion only.

use crate::krl::{self, Call, Stmt, StmtKind};

use super::*;
use crate::motion::value::Value;
use crate::motion::workspace::FileId;

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
            self.warn(
                file,
                c.name,
                format!(
                    "routine {} is not found here or beside the program: assumed not to move the robot",
                    src.text_lossy(c.name)
                ),
            );
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
        for (i, p) in header.params.iter().enumerate() {
            let v = match c.args.get(i).and_then(|a| a.as_ref()) {
                Some(a) => self.eval(file, a, scope),
                None => Value::Unknown("parameter not passed".into()),
            };
            inner.vars.insert(upper(callee.text(p.name)), v);
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
