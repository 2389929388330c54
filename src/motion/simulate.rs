//! The program walker: runs a KRL program as the controller would before run time — routines
//! and calls (same file or sibling modules), `FOR` loops with known bounds, `IF`/`SWITCH`/
//! `WHILE` with known conditions, variable and frame assignments (`$BASE`, `$TOOL`,
//! `BASE_DATA[n]`, `FDAT_ACT` + `BAS(...)` of inline forms, `WITH` clauses) — and records every
//! motion's target as a [`Stop`]: goal TCP pose in the robot base frame, the controller's
//! nominal axes (IK with S/T, or by nearness and the start's S for path motions), and the
//! arrival motion of every axis from the sampled interpolation. Whatever depends on run time
//! (a branch on `$IN[…]`, a computed target) is reported with its line; the motions concerned
//! are left out and the robot's position is unknown after them.

use std::collections::{HashMap, HashSet};

use crate::diagnostic::{Diagnostic, Severity};
use crate::kinematics::{self, status_turn, RobotDescription, Select};
use crate::krl::{
    self, Access, ArmKind, BinOp, Call, Expr, Motion, MotionKind, RelFrameKind, RoutineHeader,
    SourceFile, Span, Stmt, StmtKind, Symbols, UnOp,
};

use super::frame::Frame;
use super::interpolate::{self, Cartesian, Path};
use super::nominal::{Arm, Nominal};
use super::value::{self, Fdat, Origin, Pos, Value, VarRef};
use super::workspace::{FileId, Workspace};

/// Calls nested deeper than this are not followed (recursion).
const MAX_CALL_DEPTH: usize = 64;
/// Statements executed before the simulation gives up (an endless loop).
const MAX_STEPS: u64 = 200_000_000;
/// KUKA HOME, the reference for choosing a branch when nothing else is known.
const HOME: [f64; 6] = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];

/// A frame given on the command line: `BASE_DATA[n]` or `TOOL_DATA[n]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GivenFrame {
    pub base: bool,
    pub index: i64,
    /// X, Y, Z, A, B, C.
    pub xyzabc: [f64; 6],
}

/// What the target of a stop is relative to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rel {
    /// `_REL … #BASE` (the default): offset along the base axes, rotation about them.
    Base,
    /// `_REL … #TOOL`: `current · offset`.
    Tool,
    /// Axis-specific `PTP_REL {A1 …}`: added to the current axes.
    Axis,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Target,
    /// The auxiliary point of a circular motion.
    Aux,
}

/// One executed motion target.
#[derive(Clone, Copy, Debug)]
pub struct Stop<'f> {
    pub file: FileId,
    pub stmt: &'f Stmt,
    pub kind: MotionKind,
    pub role: Role,
    /// The programmed TCP pose in the robot base frame.
    pub goal: Frame,
    /// Index in [`Simulation::frames`] of the tool (flange → TCP) and of the base.
    pub tool: u32,
    pub base: u32,
    /// The controller's axes for the programmed target.
    pub nominal_axes: [f64; 6],
    /// Arrival motion of each axis (see `interpolate`); `None` after an unknown position.
    pub arrival: Option<[f64; 6]>,
    /// An axis target (`A1..A6`).
    pub axis: bool,
    /// The programmed values as the controller completes them (absolute: missing components
    /// from the start; relative: missing ones zero), `X Y Z A B C` in the base or `A1..A6`.
    pub programmed: [f64; 6],
    pub keep_s: bool,
    pub keep_t: bool,
    pub rel: Option<Rel>,
    /// Where the numbers are written.
    pub origin: Option<Origin<'f>>,
    /// The variable name in the motion statement, when the target is a plain variable.
    pub reference: Option<Span>,
    /// The stop this motion starts from.
    pub prev: Option<u32>,
    /// False when the target must be left as written (a warning says why).
    pub compensable: bool,
    /// The arrival is computed after the walk (short LIN segment, see `simulate`).
    deferred: bool,
}

/// The simulated program.
#[derive(Debug, Default)]
pub struct Simulation<'f> {
    pub stops: Vec<Stop<'f>>,
    /// Tools and bases referred to by the stops.
    pub frames: Vec<Frame>,
    pub diagnostics: Vec<Diagnostic>,
    /// An error rejects the whole program (unknown frame, external TCP, endless loop).
    pub fatal: bool,
    /// Targets the robot cannot reach (errors of their own; the program goes on).
    pub unreachable: usize,
}

impl Simulation<'_> {
    /// Whether an error rejects the program.
    pub fn rejected(&self) -> bool {
        self.fatal
    }
}

/// A frame variable's state.
#[derive(Clone, Debug)]
enum FrameState {
    /// Never set in the program: the controller uses whatever is active; we assume
    /// `$NULLFRAME` and say so.
    Unset,
    Known(Frame),
    /// Set from something unknown: (file, span, why).
    Unknown(FileId, Span, String),
}

#[derive(Clone, Copy, Debug)]
struct Current {
    axes: [f64; 6],
    stop: Option<u32>,
}

#[derive(Clone, Debug)]
struct State {
    base: FrameState,
    tool: FrameState,
    external_tcp: Option<(FileId, Span)>,
    fdat: Option<Fdat>,
    current: Option<Current>,
    /// A, B, C of the last Cartesian target as written: the representation to stay near when
    /// completing a partial position.
    last_abc: [f64; 3],
}

#[derive(Default)]
struct Scope<'f> {
    vars: HashMap<Vec<u8>, Value<'f>>,
    elements: HashMap<(Vec<u8>, Vec<i64>), Value<'f>>,
}

enum Flow {
    Next,
    Exit,
    Return,
}

/// Simulates the main program of `ws`.
pub fn simulate<'f>(
    ws: &'f Workspace,
    robot: &RobotDescription,
    given: &[GivenFrame],
) -> Simulation<'f> {
    let mut sim = Simulator::new(ws, robot, given);
    // At least one stop per motion statement (loops add more): no regrowth for CAM programs.
    let motions: usize = ws.files.iter().map(|f| f.file.motions().count()).sum();
    sim.out.stops.reserve(motions);
    sim.run();
    let mut out = sim.out;
    finish(&mut out, robot);
    out
}

/// The deferred arrival rates of short LIN segments, in parallel: each needs only its own end
/// and the start the walk recorded (the previous stop's axes).
fn finish(sim: &mut Simulation, robot: &RobotDescription) {
    use rayon::prelude::*;
    let rates: Vec<Option<[f64; 6]>> = (0..sim.stops.len())
        .into_par_iter()
        .with_min_len(1024)
        .map(|k| {
            let stop = &sim.stops[k];
            if !stop.deferred {
                return None;
            }
            let prev = &sim.stops[stop.prev? as usize];
            let tool = &sim.frames[stop.tool as usize];
            let start = Nominal(robot).tcp(&prev.nominal_axes, tool);
            let cart = Cartesian::new(&start, &stop.goal, &Path::Lin).ok()?;
            let a = interpolate::arrival_along(
                robot,
                tool,
                &cart,
                1.0,
                &prev.nominal_axes,
                &stop.nominal_axes,
            );
            Some(match a {
                Ok(a) => a.rate,
                Err(_) => std::array::from_fn(|i| stop.nominal_axes[i] - prev.nominal_axes[i]),
            })
        })
        .collect();
    for (stop, rate) in sim.stops.iter_mut().zip(rates) {
        if stop.deferred {
            stop.arrival = rate;
            stop.deferred = false;
        }
    }
}

struct Simulator<'f> {
    ws: &'f Workspace,
    robot: RobotDescription,
    given: Vec<GivenFrame>,
    /// Per file: index into `symbols` of its module (the file and its partner).
    module_of: Vec<usize>,
    symbols: Vec<Symbols<'f>>,
    config: Option<Symbols<'f>>,
    routines: HashMap<Vec<u8>, (FileId, &'f Stmt, &'f RoutineHeader)>,
    moves: HashMap<Vec<u8>, bool>,
    globals: Scope<'f>,
    state: State,
    out: Simulation<'f>,
    seen: HashSet<(FileId, u32, String)>,
    depth: usize,
    steps: u64,
    warned_frames: bool,
}

fn upper(b: &[u8]) -> Vec<u8> {
    b.to_ascii_uppercase()
}

impl<'f> Simulator<'f> {
    fn new(ws: &'f Workspace, robot: &RobotDescription, given: &[GivenFrame]) -> Simulator<'f> {
        let mut module_of = vec![usize::MAX; ws.files.len()];
        let mut symbols = Vec::new();
        let mut config = None;
        for (i, f) in ws.files.iter().enumerate() {
            if f.role == super::workspace::Role::Config {
                config = Some(Symbols::new(&[&f.file]));
                continue;
            }
            if module_of[i] != usize::MAX {
                continue;
            }
            let mut files = vec![&f.file];
            if let Some(p) = f.partner {
                // The data list first: its declarations are the module's.
                files.insert(0, &ws.get(p).file);
                module_of[p as usize] = symbols.len();
            }
            module_of[i] = symbols.len();
            symbols.push(Symbols::new(&files));
        }
        let mut routines = HashMap::new();
        for (i, f) in ws.files.iter().enumerate() {
            for (stmt, h) in f.file.routines() {
                routines
                    .entry(upper(f.file.text(h.name)))
                    .or_insert((i as FileId, stmt, h));
            }
        }
        Simulator {
            ws,
            robot: *robot,
            given: given.to_vec(),
            module_of,
            symbols,
            config,
            routines,
            moves: HashMap::new(),
            globals: Scope::default(),
            state: State {
                base: FrameState::Unset,
                tool: FrameState::Unset,
                external_tcp: None,
                fdat: None,
                current: None,
                last_abc: [0.0; 3],
            },
            out: Simulation::default(),
            seen: HashSet::new(),
            depth: 0,
            steps: 0,
            warned_frames: false,
        }
    }

    fn src(&self, file: FileId) -> &'f SourceFile {
        &self.ws.get(file).file
    }

    fn id_of(&self, f: &SourceFile) -> FileId {
        self.ws
            .files
            .iter()
            .position(|l| std::ptr::eq(&l.file, f))
            .unwrap_or(0) as FileId
    }

    fn report(&mut self, severity: Severity, file: FileId, span: Span, message: String) {
        if self.seen.insert((file, span.start, message.clone())) {
            let d = self.ws.diagnostic(severity, file, span, message);
            self.out.diagnostics.push(d);
        }
    }

    fn warn(&mut self, file: FileId, span: Span, message: impl Into<String>) {
        self.report(Severity::Warning, file, span, message.into());
    }

    fn error(&mut self, file: FileId, span: Span, message: impl Into<String>) {
        self.out.fatal = true;
        self.report(Severity::Error, file, span, message.into());
    }

    /// A target the robot cannot reach: an error of that target, the program goes on (its
    /// position after it unknown).
    fn unreachable(&mut self, file: FileId, s: &Stmt, why: String) {
        self.out.unreachable += 1;
        self.report(
            Severity::Error,
            file,
            s.head,
            format!(
                "{why}: this motion is left unchanged and the robot's position after it is unknown"
            ),
        );
        self.state.current = None;
    }

    fn run(&mut self) {
        let main = self.ws.main;
        let Some((stmt, _)) = self.src(main).routines().next() else {
            self.out.diagnostics.push(Diagnostic::new(
                Severity::Warning,
                &self.ws.get(main).name,
                "no routine (DEF … END) in the program: nothing to simulate",
            ));
            return;
        };
        let mut scope = Scope::default();
        self.routine(main, stmt, &mut scope);
    }

    fn routine(&mut self, file: FileId, stmt: &'f Stmt, scope: &mut Scope<'f>) {
        if let Some(b) = &stmt.block {
            self.block(file, &b.body, scope);
        }
    }

    fn block(&mut self, file: FileId, stmts: &'f [Stmt], scope: &mut Scope<'f>) -> Flow {
        for s in stmts {
            match self.stmt(file, s, scope) {
                Flow::Next => {}
                other => return other,
            }
        }
        Flow::Next
    }

    // ---- run-time dependence --------------------------------------------------------------

    /// Whether statements move the robot (directly or through a called routine).
    fn block_moves(&mut self, file: FileId, stmts: &'f [Stmt]) -> bool {
        stmts.iter().any(|s| self.stmt_moves(file, s))
    }

    fn stmt_moves(&mut self, file: FileId, s: &'f Stmt) -> bool {
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
    fn motion_lines(stmts: &[Stmt], out: &mut Vec<u32>) {
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
    fn unresolved(&mut self, file: FileId, s: &'f Stmt, why: &str) {
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

    fn stmt(&mut self, file: FileId, s: &'f Stmt, scope: &mut Scope<'f>) -> Flow {
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
                let flow = self.block(file, &b.body, scope);
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

    fn set_var(&mut self, name: &[u8], value: Value<'f>, scope: &mut Scope<'f>) {
        if scope.vars.contains_key(name) || !self.globals.vars.contains_key(name) {
            scope.vars.insert(name.to_vec(), value);
        } else {
            self.globals.vars.insert(name.to_vec(), value);
        }
    }

    fn assign(
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
            let v = self.eval(file, rhs, scope);
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

    fn is_tcp(&self, file: FileId, e: &'f Expr, scope: &Scope<'f>) -> bool {
        matches!(self.eval(file, e, scope), Value::Enum(ref n) if n == b"TCP")
    }

    /// The value of a `$BASE`/`$TOOL` assignment.
    fn frame_value(
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

    fn config_frame(&self, base: bool, n: i64) -> FrameState {
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

    fn config_element(&self, name: &[u8], n: i64) -> Option<Value<'f>> {
        let cfg = self.config.as_ref()?;
        let (f, e) = cfg.element(name, &[n])?;
        let id = self.id_of(f);
        Some(self.eval(id, e, &Scope::default()))
    }

    /// Applies `FDAT_ACT` (what `BAS(#PTP_PARAMS…)`/`BAS(#CP_PARAMS…)` do in an inline form).
    fn apply_fdat(&mut self, file: FileId, s: &Stmt) {
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

    fn frame_by_number(&self, file: FileId, s: &Stmt, base: bool, n: i64) -> FrameState {
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

    fn call(&mut self, file: FileId, s: &'f Stmt, c: &'f Call, scope: &mut Scope<'f>) {
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
        self.depth += 1;
        self.routine(target_file, stmt, &mut inner);
        self.depth -= 1;
    }

    /// `WITH` items of a motion or spline block: `$TOOL`, `$BASE`, `$IPO_MODE` for this motion.
    fn apply_with(
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
                _ => {}
            }
        }
        Some(saved)
    }

    fn restore(&mut self, saved: State) {
        // Frames set by WITH hold for that motion only; the position moves on.
        let current = self.state.current;
        self.state = saved;
        self.state.current = current;
    }

    // ---- expressions -----------------------------------------------------------------------

    fn eval(&self, file: FileId, e: &'f Expr, scope: &Scope<'f>) -> Value<'f> {
        let src = self.src(file);
        match e {
            Expr::Number(n) => {
                if n.integer && n.value.abs() < 9e15 {
                    Value::Int(n.value as i64)
                } else {
                    Value::Real(n.value)
                }
            }
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
                binary(b.op, l, r)
            }
            Expr::Call(c) => self.function(file, c, scope),
            Expr::Opaque(_) => Value::Unknown("an expression that was not understood".into()),
        }
    }

    /// The inline forms' frame functions; anything else is a run-time value.
    fn function(&self, file: FileId, c: &'f Call, scope: &Scope<'f>) -> Value<'f> {
        let src = self.src(file);
        let name = upper(src.text(c.name));
        let arg = |i: usize| {
            c.args
                .get(i)
                .and_then(|a| a.as_ref())
                .map(|a| self.eval(file, a, scope))
        };
        let frame = |base: bool, n: Option<i64>| match n.map(|n| self.config_frame(base, n)) {
            Some(FrameState::Known(f)) => Value::Pos(Pos {
                axis: false,
                v: f.to_kuka_near(&[0.0; 3]).map(Some),
                s: None,
                t: None,
                origin: None,
            }),
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
            b"SIPO_MODE" => match arg(0) {
                Some(Value::Fdat(f)) => Value::Enum(if f.external_tcp {
                    b"TCP".to_vec()
                } else {
                    b"BASE".to_vec()
                }),
                Some(v) => v,
                None => Value::Unknown("SIPO_MODE without argument".into()),
            },
            _ => Value::Unknown(format!("the function {}", src.text_lossy(c.name))),
        }
    }

    fn current_pos(&self, axis: bool) -> Value<'f> {
        let Some(cur) = self.state.current else {
            return Value::Unknown("the robot's position, unknown here".into());
        };
        let v = if axis {
            cur.axes
        } else {
            let (Some(base), Some(tool)) =
                (self.known(&self.state.base), self.known(&self.state.tool))
            else {
                return Value::Unknown("the position in an unknown frame".into());
            };
            let tcp = Nominal(&self.robot).tcp(&cur.axes, &tool);
            base.inverse().compose(&tcp).to_kuka_near(&[0.0; 3])
        };
        let (s, t) = status_turn(&self.robot, &cur.axes);
        Value::Pos(Pos {
            axis,
            v: v.map(Some),
            s: (!axis).then_some(s),
            t: (!axis).then_some(t),
            origin: None,
        })
    }

    fn known(&self, f: &FrameState) -> Option<Frame> {
        match f {
            FrameState::Known(f) => Some(*f),
            FrameState::Unset => Some(Frame::identity()),
            FrameState::Unknown(..) => None,
        }
    }

    fn lookup(&self, file: FileId, name: &[u8], scope: &Scope<'f>) -> Value<'f> {
        if let Some(v) = scope.vars.get(name).or_else(|| self.globals.vars.get(name)) {
            return v.clone();
        }
        match name {
            b"$NULLFRAME" => {
                return Value::Pos(Pos {
                    axis: false,
                    v: [Some(0.0); 6],
                    s: None,
                    t: None,
                    origin: None,
                })
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
                    Some(f) => Value::Pos(Pos {
                        axis: false,
                        v: f.to_kuka_near(&[0.0; 3]).map(Some),
                        s: None,
                        t: None,
                        origin: None,
                    }),
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
                                });
                            }
                            if sym.decl.ty.kind.is_axis() {
                                p.axis = true;
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
            None => Value::Unknown(format!("{}, not declared", String::from_utf8_lossy(name))),
        }
    }

    fn symbol(&self, file: FileId, name: &[u8]) -> Option<&krl::Symbol<'f>> {
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

    fn element(&self, file: FileId, name: &[u8], idx: &[i64], scope: &Scope<'f>) -> Value<'f> {
        let key = (name.to_vec(), idx.to_vec());
        if let Some(v) = scope
            .elements
            .get(&key)
            .or_else(|| self.globals.elements.get(&key))
        {
            return v.clone();
        }
        if idx.len() == 1 && (name == b"BASE_DATA" || name == b"TOOL_DATA") {
            let base = name == b"BASE_DATA";
            if let Some(g) = self
                .given
                .iter()
                .find(|g| g.base == base && g.index == idx[0])
            {
                return Value::Pos(Pos {
                    axis: false,
                    v: g.xyzabc.map(Some),
                    s: None,
                    t: None,
                    origin: None,
                });
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
                            p.axis = true;
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

    fn path(&self, file: FileId, p: &'f krl::Path, scope: &Scope<'f>) -> Value<'f> {
        let src = self.src(file);
        let name = upper(src.text(p.root));
        let mut access = p.access.iter();
        let mut v = match p.access.first() {
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
                    (Some((axis, k)), _) if axis == pos.axis => match pos.v[k] {
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
                u @ Value::Unknown(_) => u,
                _ => Value::Unknown("a member of a value without members".into()),
            };
        }
        v
    }

    // ---- motions ---------------------------------------------------------------------------

    fn frames_index(&mut self, f: &Frame) -> u32 {
        if let Some(i) = self.out.frames.iter().rposition(|g| g == f) {
            return i as u32;
        }
        self.out.frames.push(*f);
        (self.out.frames.len() - 1) as u32
    }

    /// The base and tool for a Cartesian motion, or an error naming where the frame was lost.
    fn motion_frames(&mut self, file: FileId, s: &Stmt) -> Option<(Frame, Frame)> {
        let mut out = [Frame::identity(); 2];
        for (k, st) in [self.state.base.clone(), self.state.tool.clone()]
            .iter()
            .enumerate()
        {
            match st {
                FrameState::Known(f) => out[k] = *f,
                FrameState::Unset => {
                    if !self.warned_frames {
                        self.warned_frames = true;
                        self.warn(
                            file,
                            s.head,
                            format!(
                                "{} is not set before this motion: assuming $NULLFRAME (set it in the program, or the compensation uses the wrong TCP)",
                                if k == 0 { "$BASE" } else { "$TOOL" }
                            ),
                        );
                    }
                }
                FrameState::Unknown(f, span, why) => {
                    let msg = if why.is_empty() {
                        "unknown frame".to_string()
                    } else {
                        why.clone()
                    };
                    let (f, span) = if span.is_empty() && *f == 0 {
                        (file, s.head)
                    } else {
                        (*f, *span)
                    };
                    self.error(
                        f,
                        span,
                        format!("{msg}: give the robot's $config.dat with --config, or the frame with --base N=X,Y,Z,A,B,C / --tool N=X,Y,Z,A,B,C"),
                    );
                    return None;
                }
            }
        }
        Some((out[0], out[1]))
    }

    fn lost(&mut self, file: FileId, s: &Stmt, why: String) {
        self.warn(
            file,
            s.head,
            format!(
                "{why}: this motion is left unchanged and the robot's position after it is unknown"
            ),
        );
        self.state.current = None;
    }

    fn motion(&mut self, file: FileId, s: &'f Stmt, m: &'f Motion, scope: &mut Scope<'f>) {
        let saved = self.apply_with(file, m.with(), scope);
        self.motion_inner(file, s, m, scope);
        if let Some(saved) = saved {
            self.restore(saved);
        }
    }

    fn motion_inner(&mut self, file: FileId, s: &'f Stmt, m: &'f Motion, scope: &mut Scope<'f>) {
        if let Some((f, span)) = self.state.external_tcp {
            self.error(
                f,
                span,
                "$IPO_MODE #TCP (external TCP, the workpiece carried by the robot) is not supported: the program is refused",
            );
            self.state.current = None;
            return;
        }
        let target = self.eval(file, &m.target, scope);
        let Value::Pos(pos) = target else {
            let why = reason(&target, "the target");
            self.lost(
                file,
                s,
                format!("the target is not known before run time ({why})"),
            );
            return;
        };
        let reference = m.target.as_path().filter(|p| p.is_simple()).map(|p| p.root);
        let rel = m.kind.is_relative().then(|| {
            if pos.axis {
                Rel::Axis
            } else if m.frame().is_some_and(|f| f.kind == RelFrameKind::Tool) {
                Rel::Tool
            } else {
                Rel::Base
            }
        });
        // An axis target of a PTP needs no frame (the tool only weighs orientation errors).
        let needs_frames = !pos.axis || !m.kind.is_joint() || m.aux().is_some();
        let (base, tool) = if needs_frames {
            match self.motion_frames(file, s) {
                Some(f) => f,
                None => {
                    self.state.current = None;
                    return;
                }
            }
        } else {
            (
                self.known(&self.state.base).unwrap_or_else(Frame::identity),
                self.known(&self.state.tool).unwrap_or_else(Frame::identity),
            )
        };
        let current = self.state.current;
        // Where the TCP starts: the previous target's goal when it was reached with the same
        // tool (the controller's axes there reproduce it), else the FK of the axes.
        let start_tcp = current.map(|c| {
            let same_tool = c
                .stop
                .map(|i| &self.out.stops[i as usize])
                .filter(|p| p.role == Role::Target && self.out.frames[p.tool as usize] == tool);
            match same_tool {
                Some(p) if p.nominal_axes == c.axes => p.goal,
                _ => Nominal(&self.robot).tcp(&c.axes, &tool),
            }
        });
        // The programmed position, completed as the controller does.
        let Some((programmed, goal, s_t)) =
            self.complete(&pos, rel, current, &base, &tool, start_tcp.as_ref())
        else {
            self.lost(
                file,
                s,
                "a partial or relative position whose start is unknown".into(),
            );
            return;
        };
        let robot = self.robot;
        // Circular motions: the auxiliary point first.
        let mut aux_stop = None;
        let mut circle = None;
        if let Some(aux_expr) = m.aux() {
            let aux = self.eval(file, aux_expr, scope);
            let Value::Pos(aux) = aux else {
                let why = reason(&aux, "the auxiliary point");
                self.lost(
                    file,
                    s,
                    format!("the auxiliary point is not known before run time ({why})"),
                );
                return;
            };
            let (Some(cur), Some(start)) = (current, start_tcp) else {
                self.lost(file, s, "a circular motion whose start is unknown".into());
                return;
            };
            let Some((aux_prog, aux_goal, _)) =
                self.complete(&aux, rel, current, &base, &tool, start_tcp.as_ref())
            else {
                self.lost(file, s, "an auxiliary point whose start is unknown".into());
                return;
            };
            let cart = match Cartesian::new(
                &start,
                &goal,
                &Path::Circ {
                    aux: aux_goal.position,
                },
            ) {
                Ok(c) => c,
                Err(e) => {
                    self.lost(file, s, e.to_string());
                    return;
                }
            };
            let u_aux = cart.fraction_at(&aux_goal.position);
            let aux_pose = Frame {
                rotation: cart.pose(u_aux).rotation,
                position: aux_goal.position,
            };
            let s_cur = status_turn(&robot, &cur.axes).0;
            let q_aux = match kinematics::inverse(
                &robot,
                &aux_pose.compose(&tool.inverse()).to_isometry(),
                Select::StatusNearest {
                    s: s_cur,
                    near: cur.axes,
                },
            ) {
                Ok(sol) => sol.axes_deg,
                Err(e) => {
                    self.unreachable(
                        file,
                        s,
                        format!("the auxiliary point cannot be reached: {e}"),
                    );
                    return;
                }
            };
            let mut q_aux = q_aux;
            let arrival =
                match interpolate::arrival_along(&robot, &tool, &cart, u_aux, &cur.axes, &q_aux) {
                    Ok(a) => {
                        q_aux = a.end;
                        Some(a.rate)
                    }
                    Err(e) => {
                        self.warn(
                            file,
                            s.head,
                            format!("auxiliary point: {e}; directions from the axis steps"),
                        );
                        Some(std::array::from_fn(|i| q_aux[i] - cur.axes[i]))
                    }
                };
            let tool_i = self.frames_index(&tool);
            let base_i = self.frames_index(&base);
            let aux_ref = aux_expr.as_path().filter(|p| p.is_simple()).map(|p| p.root);
            self.out.stops.push(Stop {
                file,
                stmt: s,
                kind: m.kind,
                role: Role::Aux,
                goal: aux_pose,
                tool: tool_i,
                base: base_i,
                nominal_axes: q_aux,
                arrival,
                axis: false,
                programmed: aux_prog,
                keep_s: true,
                keep_t: false,
                rel,
                origin: aux.origin,
                reference: aux_ref,
                prev: cur.stop,
                compensable: aux.origin.is_some() && m.angle().is_none(),
                deferred: false,
            });
            aux_stop = Some((self.out.stops.len() - 1) as u32);
            circle = Some(cart);
        }
        // The controller's axes for the target.
        let q = if pos.axis {
            programmed
        } else {
            let (s_given, t_given) = s_t;
            let select = match (m.kind.is_joint(), current) {
                (true, _) if s_given.is_some() && t_given.is_some() => Select::Status {
                    s: s_given.unwrap_or(0),
                    t: t_given,
                },
                (true, Some(c)) => Select::StatusNearest {
                    s: s_given.unwrap_or_else(|| status_turn(&robot, &c.axes).0),
                    near: c.axes,
                },
                (true, None) => match s_given {
                    Some(s) => Select::Status { s, t: None },
                    None => Select::Nearest(HOME),
                },
                (false, Some(c)) => Select::StatusNearest {
                    s: status_turn(&robot, &c.axes).0,
                    near: c.axes,
                },
                (false, None) => match s_given {
                    Some(s) => Select::Status { s, t: t_given },
                    None => Select::Nearest(HOME),
                },
            };
            let flange = goal.compose(&tool.inverse());
            match kinematics::inverse(&robot, &flange.to_isometry(), select) {
                Ok(sol) => sol.axes_deg,
                Err(e) => {
                    self.unreachable(file, s, format!("the target cannot be reached: {e}"));
                    return;
                }
            }
        };
        if pos.axis && !robot.within_limits(&q) {
            self.warn(
                file,
                s.head,
                "the axis target is outside the joint limits: left unchanged",
            );
        }
        let goal = if pos.axis {
            Nominal(&robot).tcp(&q, &tool)
        } else {
            goal
        };
        // `CA`: the motion ends on the circle at that angle (orientation of the target), not at
        // the target; the stops are kept for the directions but left unchanged.
        if let (Some(ca), Some(cart), Some(cur)) = (m.angle(), &circle, current) {
            let angle = self.eval(file, &ca.value, scope).as_f64();
            let ended = angle.and_then(|a| cart.with_arc_angle(a, &goal.rotation));
            let Some(arc) = ended else {
                self.lost(
                    file,
                    s,
                    "a circular angle CA not known before run time".into(),
                );
                return;
            };
            let end = arc.pose(1.0);
            let s_cur = status_turn(&robot, &cur.axes).0;
            let flange = end.compose(&tool.inverse());
            let select = Select::StatusNearest {
                s: s_cur,
                near: cur.axes,
            };
            let q_end = match kinematics::inverse(&robot, &flange.to_isometry(), select) {
                Ok(sol) => sol.axes_deg,
                Err(e) => {
                    self.unreachable(
                        file,
                        s,
                        format!("the end of the circle (CA) cannot be reached: {e}"),
                    );
                    return;
                }
            };
            let walked = interpolate::arrival_along(&robot, &tool, &arc, 1.0, &cur.axes, &q_end);
            let (q_end, arrival) = match walked {
                Ok(a) => (a.end, Some(a.rate)),
                Err(e) => {
                    self.warn(file, s.head, format!("{e}; directions from the axis steps"));
                    (q_end, Some(std::array::from_fn(|i| q_end[i] - cur.axes[i])))
                }
            };
            self.warn(
                file,
                s.head,
                "a circular motion with CA ends elsewhere than its target: left unchanged",
            );
            let tool_i = self.frames_index(&tool);
            let base_i = self.frames_index(&base);
            self.out.stops.push(Stop {
                file,
                stmt: s,
                kind: m.kind,
                role: Role::Target,
                goal: end,
                tool: tool_i,
                base: base_i,
                nominal_axes: q_end,
                arrival,
                axis: false,
                programmed,
                keep_s: true,
                keep_t: false,
                rel,
                origin: None,
                reference: None,
                prev: aux_stop,
                compensable: false,
                deferred: false,
            });
            let idx = (self.out.stops.len() - 1) as u32;
            self.state.current = Some(Current {
                axes: q_end,
                stop: Some(idx),
            });
            return;
        }
        let path = if m.kind.is_joint() {
            Path::Ptp
        } else if let (Some(_), Some(aux_i)) = (&circle, aux_stop) {
            Path::Circ {
                aux: self.out.stops[aux_i as usize].goal.position,
            }
        } else {
            Path::Lin
        };
        let mut q = q;
        let mut deferred = false;
        let arrival = match (current, start_tcp) {
            // A short straight segment: its arrival rate is computed after the walk, in
            // parallel with all the others (`finish`).
            (Some(_), Some(start))
                if path == Path::Lin && interpolate::lin_needs_no_samples(&start, &goal) =>
            {
                deferred = true;
                None
            }
            (Some(cur), Some(start)) => {
                match interpolate::arrival(&robot, &tool, &path, (&start, &cur.axes), (&goal, &q)) {
                    Ok(a) => {
                        q = a.end;
                        Some(a.rate)
                    }
                    Err(e) => {
                        self.warn(file, s.head, format!("{e}; directions from the axis steps"));
                        Some(std::array::from_fn(|i| q[i] - cur.axes[i]))
                    }
                }
            }
            _ => None,
        };
        let in_config = pos
            .origin
            .is_some_and(|o| self.ws.get(o.file).role == super::workspace::Role::Config);
        let compensable = pos.origin.is_some()
            && !in_config
            && m.angle().is_none()
            && (!pos.axis || robot.within_limits(&q));
        if pos.origin.is_none() {
            self.warn(
                file,
                s.head,
                "the target is computed in the program (not a literal position): left unchanged",
            );
        }
        if in_config {
            self.warn(
                file,
                s.head,
                "the target is declared in $config.dat, which robopost does not rewrite (every program shares it): left unchanged",
            );
        }
        let tool_i = self.frames_index(&tool);
        let base_i = self.frames_index(&base);
        self.out.stops.push(Stop {
            file,
            stmt: s,
            kind: m.kind,
            role: Role::Target,
            goal,
            tool: tool_i,
            base: base_i,
            nominal_axes: q,
            arrival,
            axis: pos.axis,
            programmed,
            keep_s: !pos.axis,
            keep_t: !pos.axis && m.kind.is_joint() && s_t.1.is_some(),
            rel,
            origin: pos.origin,
            reference,
            prev: aux_stop.or(current.and_then(|c| c.stop)),
            compensable,
            deferred,
        });
        let idx = (self.out.stops.len() - 1) as u32;
        if !pos.axis && rel.is_none() {
            self.state.last_abc = [programmed[3], programmed[4], programmed[5]];
        }
        self.state.current = Some(Current {
            axes: q,
            stop: Some(idx),
        });
    }

    /// The absolute programmed values (in the base, or axes), the goal TCP in the robot base
    /// and the given S/T; `None` when a missing component needs an unknown start.
    #[allow(clippy::type_complexity)]
    fn complete(
        &self,
        pos: &Pos<'f>,
        rel: Option<Rel>,
        current: Option<Current>,
        base: &Frame,
        tool: &Frame,
        start_tcp: Option<&Frame>,
    ) -> Option<([f64; 6], Frame, (Option<u8>, Option<u8>))> {
        let st = (pos.s, pos.t);
        if pos.axis {
            let q: [f64; 6] = match rel {
                Some(_) => {
                    let c = current?;
                    std::array::from_fn(|i| c.axes[i] + pos.v[i].unwrap_or(0.0))
                }
                None => {
                    if pos.is_complete() {
                        pos.v.map(|x| x.unwrap_or(0.0))
                    } else {
                        let c = current?;
                        std::array::from_fn(|i| pos.v[i].unwrap_or(c.axes[i]))
                    }
                }
            };
            let goal = Nominal(&self.robot).tcp(&q, tool);
            return Some((q, goal, st));
        }
        match rel {
            Some(kind) => {
                let start = start_tcp?;
                let r = Frame::from_kuka(&pos.v.map(|x| x.unwrap_or(0.0)));
                let start_in_base = base.inverse().compose(start);
                let p = match kind {
                    Rel::Tool => start_in_base.compose(&r),
                    _ => Frame {
                        rotation: r.rotation * start_in_base.rotation,
                        position: start_in_base.position + r.position,
                    },
                };
                let near = start_in_base.to_kuka_near(&self.state.last_abc);
                let programmed = p.to_kuka_near(&[near[3], near[4], near[5]]);
                Some((programmed, base.compose(&p), st))
            }
            None => {
                let v: [f64; 6] = if pos.is_complete() {
                    pos.v.map(|x| x.unwrap_or(0.0))
                } else {
                    let start = start_tcp?;
                    let _ = current?;
                    let last = self.state.last_abc;
                    let here = base.inverse().compose(start).to_kuka_near(&[
                        pos.v[3].unwrap_or(last[0]),
                        pos.v[4].unwrap_or(last[1]),
                        pos.v[5].unwrap_or(last[2]),
                    ]);
                    std::array::from_fn(|i| pos.v[i].unwrap_or(here[i]))
                };
                let p = Frame::from_kuka(&v);
                let goal = match pos.origin.as_ref().and_then(|o| o.prefix.as_ref()) {
                    Some(prefix) => base.compose(prefix).compose(&p),
                    None => base.compose(&p),
                };
                Some((v, goal, st))
            }
        }
    }
}

/// Why a value is not what was needed.
fn reason(v: &Value, what: &str) -> String {
    match v {
        Value::Unknown(why) => why.clone(),
        _ => format!("{what} is of the wrong kind"),
    }
}

fn binary<'f>(op: BinOp, l: Value<'f>, r: Value<'f>) -> Value<'f> {
    use Value::*;
    if let Unknown(_) = l {
        return l;
    }
    if let Unknown(_) = r {
        return r;
    }
    match op {
        BinOp::Geo => match (l, r) {
            (Pos(a), Pos(mut b)) if !a.axis && !b.axis && a.is_complete() => {
                let fa = super::frame::Frame::from_kuka(&a.v.map(|x| x.unwrap_or(0.0)));
                // Both operands written in the program: compensating the right one while the
                // left one may be compensated elsewhere would not add up; leave it.
                if a.origin.is_some() {
                    b.origin = None;
                }
                // The right operand is a frame: components it does not give are zero.
                b.v = b.v.map(|x| Some(x.unwrap_or(0.0)));
                let complete = b.is_complete();
                match &mut b.origin {
                    Some(o) => {
                        o.prefix = Some(match o.prefix {
                            Some(p) => fa.compose(&p),
                            None => fa,
                        });
                        Pos(b)
                    }
                    None if complete => {
                        let fb = super::frame::Frame::from_kuka(&b.v.map(|x| x.unwrap_or(0.0)));
                        let c = fa.compose(&fb);
                        Pos(value::Pos {
                            axis: false,
                            v: c.to_kuka_near(&[0.0; 3]).map(Some),
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
