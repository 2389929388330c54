//! The program walker: runs a KRL program as the controller would before run time — routines
//! and calls with their `:IN`/`:OUT` parameters (same file, sibling modules, the cell's),
//! functions (`DEFFCT`) whose bodies can be evaluated, `FOR` loops with known bounds,
//! `IF`/`SWITCH`/`WHILE` with known conditions (a loop that ends on a run-time condition is
//! followed twice, as a cycle), variable, array element and structure member assignments,
//! frames (`$BASE`, `$TOOL`, `BASE_DATA[n]`, `FDAT_ACT` + `BAS(...)` of inline forms, `WITH`
//! clauses) — and records every
//! motion's target as a [`Stop`] of the language-neutral motion form (`motion::form`) with
//! KRL's [`Handle`] (file, statement, keyword, where its numbers are written), which only
//! `krl::rewrite` and `krl::job` read: goal TCP pose in the robot base frame, the controller's
//! nominal axes (IK with S/T, or by nearness and the start's S for path motions), and the
//! arrival motion of every axis from the sampled interpolation (along the curve for the `SPL`
//! segments of spline blocks). Whatever depends on run time
//! (a branch on `$IN[…]`, a computed target) is reported with its line; the motions concerned
//! are left out and the robot's position is unknown after them.

use std::collections::{HashMap, HashSet};

use crate::diagnostic::{Diagnostic, Severity};
use crate::kinematics::{Pose, RobotDescription};
use crate::krl::{MotionKind, RoutineHeader, SourceFile, Span, Stmt, Symbols};

use crate::motion::frame::Frame;
use crate::motion::interpolate::{self, Cartesian, Path};
use crate::motion::nominal::{Arm, Nominal};
use value::{Fdat, Origin, Value};
pub use workspace::{FileId, Workspace};

pub mod assume;
pub mod cell;
pub mod provenance;
pub mod value;
pub mod workspace;

mod assign;
mod call;
mod eval;
mod flow;
mod function;
mod spline;
mod stream;
mod target;

pub use crate::motion::form::{
    CircularAngle, Interpolation, Programmed, Rel, Role, SplineEnds, CARRIED_STOPS,
};
pub use assume::Assumption;
pub use cell::Cell;
pub use stream::{simulate_streaming, RunSink, Walked};

/// Calls nested deeper than this are not followed (recursion).
const MAX_CALL_DEPTH: usize = 64;
/// Statements executed before the simulation gives up (an endless loop).
const MAX_STEPS: u64 = 200_000_000;
/// Iterations of one loop (`FOR`, `WHILE`, `REPEAT`) followed before run time. Past a limit
/// the loop is followed as a cycle (like `LOOP`): the robot's position after it is unknown,
/// said with a warning.
const MAX_LOOP_ITERATIONS: u64 = 1_000_000;
/// Iterations of one loop that moved the robot: a counted loop of a billion iterations with a
/// motion inside would hold a stop per iteration, and each statement is written with one
/// correction however often it runs (its last use).
const MAX_MOVING_ITERATIONS: u64 = 1_000;
/// Iterations that moved the robot, of all loops of a run together (nested loops multiply).
const MAX_MOVING_TOTAL: u64 = 10_000;
/// KUKA HOME, the reference for choosing a branch when nothing else is known.
const HOME: [f64; 6] = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];

/// A frame given on the command line: `BASE_DATA[n]` or `TOOL_DATA[n]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GivenFrame {
    pub base: bool,
    pub index: i64,
    pub pose: Pose,
}

/// KRL's handle of a stop (`motion::form::Stop::handle`): where in the program the stop comes
/// from and where its numbers are written — read by the rewriter and the program job only.
#[derive(Clone, Copy, Debug)]
pub struct Handle<'f> {
    pub file: FileId,
    pub stmt: &'f Stmt,
    pub kind: MotionKind,
    /// Where the numbers are written.
    pub origin: Option<Origin<'f>>,
    /// The variable name in the motion statement, when the target is a plain variable.
    pub reference: Option<Span>,
}

/// How a KRL motion moves the robot, in the motion form's words.
pub fn interpolation(kind: MotionKind) -> Interpolation {
    if kind.is_joint() {
        Interpolation::Joint
    } else if kind.is_circular() {
        Interpolation::Circular
    } else {
        Interpolation::Linear
    }
}

/// One executed motion target of a KRL program: the motion form with KRL's handle.
pub type Stop<'f> = crate::motion::form::Stop<Handle<'f>>;

/// The simulated program.
#[derive(Debug, Default)]
pub struct Simulation<'f> {
    pub stops: Vec<Stop<'f>>,
    /// Tools and bases referred to by the stops.
    pub frames: Vec<Frame>,
    /// Prefix frames of positions written as `prefix : position` (`Origin::prefix`).
    pub prefixes: Vec<Frame>,
    pub diagnostics: Vec<Diagnostic>,
    /// An error rejects the whole program (unknown frame, external TCP, endless loop).
    pub fatal: bool,
    /// Targets the robot cannot reach (errors of their own; the program goes on).
    pub unreachable: usize,
    /// The streamed walk met what only the whole tree can follow (the main routine called
    /// again): walk the program parsed without streamed runs instead.
    pub needs_whole_tree: bool,
    /// The circular motions with `CA` compensated by construction, by end stop.
    pub arcs: Vec<CircularAngle>,
    /// Executions of motions whose target the walk could not resolve before run time (left
    /// unchanged): a run-time branch, an unknown value, a computed position it cannot know.
    pub lost: usize,
    /// What the program needs that was found nowhere (`routine SetFrames`, `BASE_DATA[3]`,
    /// `XHOME (declared nowhere)`): what the user must add.
    pub needs: std::collections::BTreeSet<String>,
    /// How often the walk used each of `Workspace::assumptions` (in their order).
    pub assumptions_used: crate::krl::interpret::assume::Used,
    /// Declared points used as the offset of a geometric operator (`P1 : P2`: P2), which
    /// must keep their written numbers there.
    pub pinned: Vec<Pinned<'f>>,
}

/// A declared point used, unchanged, as the offset of a geometric operator in a target.
#[derive(Clone, Copy, Debug)]
pub struct Pinned<'f> {
    pub origin: Origin<'f>,
    /// The place naming it (file, name).
    pub site: (FileId, Span),
}

impl Simulation<'_> {
    /// The `CA` circle ending at stop `end`, if it is one compensated by construction.
    pub fn arc_ending_at(&self, end: usize) -> Option<&CircularAngle> {
        crate::motion::form::arc_ending_at(&self.arcs, end)
    }

    /// Whether the robot passes stop `i` by without visiting it: the auxiliary point of a
    /// circle with `CA` only sets the circle's plane (the circle starts from the stop before).
    pub fn passes_by(&self, i: usize) -> bool {
        crate::motion::form::passes_by(&self.stops, &self.arcs, i)
    }

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
    /// Set from something unknown: (file, span, why, what the user can give).
    Unknown(FileId, Span, String, &'static str),
}

/// The hint of a frame from `$config.dat` or the command line.
const GIVE_FRAME: &str =
    "give the robot's $config.dat (--cell DIR, --config FILE), or the frame with --base N=X,Y,Z,A,B,C / --tool N=X,Y,Z,A,B,C";

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
    /// `$ORI_TYPE` when it is not the default `#VAR` (`CONSTANT`, `JOINT`), which the
    /// walker does not simulate (a warning says so at each Cartesian motion).
    ori_type: Option<Vec<u8>>,
    /// The orientation type of `LDAT_ACT` (applied by `BAS(#CP_PARAMS…)`).
    ldat_ori: Option<Vec<u8>>,
    current: Option<Current>,
    /// A, B, C of the last Cartesian target as written: the representation to stay near when
    /// completing a partial position.
    last_abc: [f64; 3],
}

#[derive(Default)]
struct Scope<'f> {
    vars: HashMap<Vec<u8>, Value<'f>>,
    elements: HashMap<(Vec<u8>, Vec<i64>), Value<'f>>,
    /// Parameters bound by the call: their declarations in the body keep the value.
    params: HashSet<Vec<u8>>,
    /// Arrays passed whole (`P[]`, `P[,]`): parameter → the caller's array, whose declared
    /// elements are read where the routine has no value of its own.
    arrays: HashMap<Vec<u8>, (FileId, Vec<u8>)>,
    /// Parameters the routine assigned (only those go back to the caller).
    written: HashSet<Vec<u8>>,
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
    sim.run(None);
    sim.finish_segment();
    sim.into_simulation()
}

/// A deferred arrival: the rate and turns, `None` where the segment has no start or path.
type Deferred = Option<([f64; 6], interpolate::Turns)>;

/// The deferred arrival rates of short LIN segments, in parallel: each needs only its own end
/// and the start the walk recorded (the previous stop's axes). A streamed window's stops fit
/// in one task: they are written in place, without a table of rates.
fn finish(sim: &mut Simulation, robot: &RobotDescription) {
    /// Stops per task: consecutive stops share a chain evaluation (see [`Deferrer`]); a
    /// streamed window's (`krl::StreamOptions::window` and the ghosts before them) fit in one.
    const CHUNK: usize = 4096;
    finish_in(sim, robot, CHUNK);
}

/// [`finish`] in tasks of `chunk` stops.
fn finish_in(sim: &mut Simulation, robot: &RobotDescription, chunk: usize) {
    use rayon::prelude::*;
    if sim.stops.len() <= chunk {
        let mut deferrer = Deferrer::default();
        for k in 0..sim.stops.len() {
            if sim.stops[k].deferred {
                let rate = deferrer.arrival(sim, robot, k);
                settle(&mut sim.stops[k], rate);
            }
        }
        return;
    }
    let mut rates: Vec<Deferred> = vec![None; sim.stops.len()];
    rates
        .par_chunks_mut(chunk)
        .enumerate()
        .for_each(|(c, out)| {
            let mut deferrer = Deferrer::default();
            for (j, slot) in out.iter_mut().enumerate() {
                let k = c * chunk + j;
                if sim.stops[k].deferred {
                    *slot = deferrer.arrival(sim, robot, k);
                }
            }
        });
    for (stop, rate) in sim.stops.iter_mut().zip(rates) {
        if stop.deferred {
            settle(stop, rate);
        }
    }
}

/// A deferred stop's arrival made final.
fn settle(stop: &mut Stop, rate: Deferred) {
    stop.arrival = rate.map(|r| r.0);
    stop.turns = rate.map_or(interpolate::NO_TURNS, |r| r.1);
    stop.deferred = false;
}

/// The deferred arrivals of consecutive stops, in order. The arm at the end of the stop just
/// done (`arms[live]`), with its index and tool, is the next stop's start when it starts
/// there (a CAM path), its TCP bit for bit what `interpolate::end_tcp` of the previous axes
/// gives. The next end is written in the other slot, so the 430-byte records are never moved.
#[derive(Default)]
struct Deferrer {
    carry: Option<(u32, u32)>,
    arms: [Option<interpolate::ArmAt>; 2],
    live: usize,
}

impl Deferrer {
    /// The arrival of deferred stop `k` (see [`finish`]).
    fn arrival(&mut self, sim: &Simulation, robot: &RobotDescription, k: usize) -> Deferred {
        let stop = &sim.stops[k];
        let p = stop.prev?;
        let prev = &sim.stops[p as usize];
        let tool = &sim.frames[stop.tool as usize];
        let (first, second) = self.arms.split_at_mut(1);
        let (held, spare) = if self.live == 0 {
            (&first[0], &mut second[0])
        } else {
            (&second[0], &mut first[0])
        };
        let carried = match self.carry {
            Some((i, t)) if i == p && t == stop.tool => held.as_ref(),
            _ => None,
        };
        let start = match carried {
            Some(at) => at.tcp,
            None => interpolate::end_tcp(robot, &prev.nominal_axes, tool),
        };
        let Ok(cart) = Cartesian::new(&start, &stop.goal, &Path::Lin) else {
            self.carry = None;
            return None;
        };
        let a = interpolate::arrival_into(
            robot,
            tool,
            &cart,
            1.0,
            (&*prev.nominal_axes, carried),
            &stop.nominal_axes,
            spare,
        );
        self.carry = None;
        Some(match a {
            Ok(a) => {
                if a.end == stop.nominal_axes {
                    self.carry = Some((k as u32, stop.tool));
                    self.live = 1 - self.live;
                }
                (a.rate, a.turns)
            }
            Err(_) => (
                std::array::from_fn(|i| stop.nominal_axes[i] - prev.nominal_axes[i]),
                interpolate::NO_TURNS,
            ),
        })
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
    /// Messages already given, by place and wording (numbers aside): (diagnostic, repeats).
    seen: HashMap<(FileId, u32, Severity, String), (usize, usize)>,
    depth: usize,
    steps: u64,
    /// Loop iterations that moved the robot in the run (see [`MAX_MOVING_TOTAL`]).
    moving_iterations: u64,
    warned_frames: bool,
    /// The note on external axes was given.
    noted_external: bool,
    /// Prefix frames of geometric operators (see `Origin::prefix`), filled while evaluating.
    prefixes: std::cell::RefCell<Vec<Frame>>,
    /// The `SPL` segments of CP spline blocks, whose arrivals are taken along the curve.
    splines: Vec<spline::SplineSegment>,
    /// Stops already handed to a [`RunSink`].
    handed: usize,
    /// What the program needs that was found nowhere, noted while evaluating.
    needs: std::cell::RefCell<std::collections::BTreeSet<String>>,
    /// A loop exit (`EXIT`, `RETURN`) under a condition known only at run time was passed:
    /// where (the loop around it ends on a run-time condition).
    exit_unknown: Option<(FileId, u32)>,
    /// Assignments executed (a loop whose iteration changes nothing never ends).
    assignments: u64,
    /// Arrays an element of which was set with an index known only at run time: none of
    /// their elements is known after it (why).
    unknown_arrays: HashMap<Vec<u8>, String>,
    /// The operating mode (`$T1`, `$EXT`, `$MODE_OP`) was read: automatic external assumed.
    mode_assumed: std::cell::Cell<bool>,
    /// Functions being evaluated, and the statements they ran (see `function`).
    fn_depth: std::cell::Cell<usize>,
    fn_steps: std::cell::Cell<u64>,
    /// The user's assumptions (`Workspace::assumptions`; a window's walker gets the
    /// program's) and how often each was used.
    assumptions: Vec<crate::krl::interpret::Assumption>,
    used: std::cell::RefCell<crate::krl::interpret::assume::Used>,
}

fn upper(b: &[u8]) -> Vec<u8> {
    b.to_ascii_uppercase()
}

/// A message with its numbers left out: the same message of every execution of a line.
fn numbers_aside(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut in_number = false;
    for c in message.chars() {
        let digit = c.is_ascii_digit() || (in_number && c == '.');
        if digit {
            if !in_number {
                out.push('#');
            }
        } else {
            out.push(c);
        }
        in_number = digit;
    }
    out
}

/// How often a line said a message, as appended to it.
pub(crate) fn repeats(n: usize) -> String {
    format!(" (this line, {n} times: the first is shown)")
}

impl<'f> Simulator<'f> {
    pub(super) fn new(
        ws: &'f Workspace,
        robot: &RobotDescription,
        given: &[GivenFrame],
    ) -> Simulator<'f> {
        let mut module_of = vec![usize::MAX; ws.files.len()];
        let mut symbols = Vec::new();
        let shared: Vec<&SourceFile> = ws
            .files
            .iter()
            .filter(|f| f.role == workspace::Role::Config)
            .map(|f| &f.file)
            .collect();
        let config = (!shared.is_empty()).then(|| Symbols::shared(&shared));
        for (i, f) in ws.files.iter().enumerate() {
            if f.role == workspace::Role::Config && module_of[i] == usize::MAX {
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
                ori_type: None,
                ldat_ori: None,
                current: None,
                last_abc: [0.0; 3],
            },
            out: Simulation::default(),
            seen: HashMap::new(),
            depth: 0,
            steps: 0,
            moving_iterations: 0,
            warned_frames: false,
            noted_external: false,
            prefixes: Default::default(),
            splines: Vec::new(),
            handed: 0,
            needs: Default::default(),
            exit_unknown: None,
            assignments: 0,
            unknown_arrays: HashMap::new(),
            mode_assumed: Default::default(),
            fn_depth: Default::default(),
            fn_steps: Default::default(),
            assumptions: ws.assumptions.clone(),
            used: std::cell::RefCell::new(crate::krl::interpret::assume::Used(vec![
                0;
                ws.assumptions
                    .len()
            ])),
        }
    }

    /// The value the user assumed for `name` (capitals) at `index`, counted as used.
    pub(super) fn assumed(&self, name: &[u8], index: &[i64]) -> Option<Value<'f>> {
        let k = self.assumptions.iter().position(|a| a.is(name, index))?;
        if let Some(n) = self.used.borrow_mut().0.get_mut(k) {
            *n += 1;
        }
        Some(self.assumptions[k].value())
    }

    /// The walk's result, its messages counted and its notes gathered.
    pub(super) fn into_simulation(mut self) -> Simulation<'f> {
        self.count_repeats();
        if self.mode_assumed.get() {
            self.out.diagnostics.push(Diagnostic::new(
                Severity::Warning,
                &self.ws.get(self.ws.main).name,
                "the program reads the operating mode ($T1, $T2, $AUT, $EXT or $MODE_OP): walked as it runs in production, automatic external ($EXT)",
            ));
        }
        let mut out = self.out;
        out.assumptions_used = self.used.into_inner();
        out.prefixes = self.prefixes.into_inner();
        out.needs.append(&mut self.needs.into_inner());
        out
    }

    pub(super) fn src(&self, file: FileId) -> &'f SourceFile {
        &self.ws.get(file).file
    }

    pub(super) fn id_of(&self, f: &SourceFile) -> FileId {
        self.ws
            .files
            .iter()
            .position(|l| std::ptr::eq(&l.file, f))
            .unwrap_or(0) as FileId
    }

    /// Reports a message once per place and wording: a line executed many times (a loop)
    /// says it once, with the count (see [`Simulator::count_repeats`]).
    pub(super) fn report(&mut self, severity: Severity, file: FileId, span: Span, message: String) {
        let key = (file, span.start, severity, numbers_aside(&message));
        match self.seen.get_mut(&key) {
            Some((_, n)) => *n += 1,
            None => {
                let d = self.ws.diagnostic(severity, file, span, message);
                self.seen.insert(key, (self.out.diagnostics.len(), 0));
                self.out.diagnostics.push(d);
            }
        }
    }

    /// Appends to every message given more than once how often its line said it.
    pub(super) fn count_repeats(&mut self) {
        for (i, n) in self.seen.values() {
            if *n > 0 {
                if let Some(d) = self.out.diagnostics.get_mut(*i) {
                    d.message += &repeats(n + 1);
                }
            }
        }
        self.seen.clear();
    }

    /// Notes something the program needs that was found nowhere.
    pub(super) fn need(&self, what: String) {
        self.needs.borrow_mut().insert(what);
    }

    pub(super) fn warn(&mut self, file: FileId, span: Span, message: impl Into<String>) {
        self.report(Severity::Warning, file, span, message.into());
    }

    pub(super) fn error(&mut self, file: FileId, span: Span, message: impl Into<String>) {
        self.out.fatal = true;
        self.report(Severity::Error, file, span, message.into());
    }

    /// A target the robot cannot reach: an error of that target, the program goes on (its
    /// position after it unknown). The message names the robot assumed.
    pub(super) fn unreachable(&mut self, file: FileId, s: &Stmt, why: String) {
        self.out.unreachable += 1;
        let robot = match self.ws.robot.as_str() {
            "" => String::new(),
            r => format!(" (robot: {r})"),
        };
        self.report(
            Severity::Error,
            file,
            s.head,
            format!(
                "{why}{robot}: this motion is left unchanged and the robot's position after it is unknown"
            ),
        );
        self.state.current = None;
    }

    /// Walks the main routine; its streamed runs (if any) go to `sink`.
    pub(super) fn run(&mut self, sink: Option<&mut (dyn RunSink<'f> + Send)>) {
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
        match sink {
            Some(sink) => {
                if let Some(b) = &stmt.block {
                    self.main_body(main, &b.body, &mut scope, sink);
                }
            }
            None => {
                if !self.src(main).streamed_runs().is_empty() {
                    let name = &self.ws.get(main).name;
                    self.out.fatal = true;
                    self.out.diagnostics.push(Diagnostic::new(
                        Severity::Error,
                        name,
                        "internal error: a program parsed with streamed runs needs simulate_streaming",
                    ));
                    return;
                }
                self.routine(main, stmt, &mut scope);
            }
        }
    }

    pub(super) fn routine(&mut self, file: FileId, stmt: &'f Stmt, scope: &mut Scope<'f>) {
        if let Some(b) = &stmt.block {
            self.block(file, &b.body, scope);
        }
    }

    pub(super) fn block(&mut self, file: FileId, stmts: &'f [Stmt], scope: &mut Scope<'f>) -> Flow {
        for s in stmts {
            match self.stmt(file, s, scope) {
                Flow::Next => {}
                other => return other,
            }
        }
        Flow::Next
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        /// A window's arrivals, written in place in one pass, are those of the parallel tasks
        /// of a whole program, to the bit, wherever the tasks are cut.
        #[test]
        fn deferred_arrivals_in_place_are_the_tasks(
            steps in proptest::collection::vec(proptest::array::uniform6(-3.0f64..3.0), 2..40),
            chunk in 1usize..8,
        ) {
            let mut src = String::from(
                "DEF prog( )\n$BASE = {X 900, Y -300, Z 500}\n$TOOL = {X 0, Y 0, Z 200}\nPTP {A1 0, A2 -80, A3 100, A4 0, A5 60, A6 0}\nLIN {X 100, Y 200, Z 0, A 0, B 0, C 180}\n",
            );
            let mut at = [100.0, 200.0, 0.0, 0.0, 0.0, 180.0];
            for step in &steps {
                for (a, d) in at.iter_mut().zip(step) {
                    *a += d;
                }
                let [x, y, z, a, b, c] = at;
                src += &format!("LIN {{X {x}, Y {y}, Z {z}, A {a}, B {b}, C {c}}}\n");
            }
            src += "END\n";
            let ws = Workspace::load((src.as_bytes(), None, "prog.src"), None, None).unwrap();
            let robot = RobotDescription::kr30ha();
            let mut sim = Simulator::new(&ws, &robot, &[]);
            sim.run(None);
            let out = &sim.out;
            let walked = || Simulation {
                stops: out.stops.clone(),
                frames: out.frames.clone(),
                ..Simulation::default()
            };
            let (mut one, mut tasks) = (walked(), walked());
            proptest::prop_assert!(one.stops.iter().filter(|s| s.deferred).count() > steps.len() / 2);
            finish_in(&mut one, &robot, usize::MAX);
            finish_in(&mut tasks, &robot, chunk);
            let bits = |s: &Stop| {
                let arrival = s.arrival.map(|r| r.map(f64::to_bits));
                let turns = [s.turns.angle_deg, s.turns.at].map(|t| t.map(f64::to_bits));
                (arrival, turns, s.deferred)
            };
            for (a, b) in one.stops.iter().zip(&tasks.stops) {
                proptest::prop_assert_eq!(bits(a), bits(b));
            }
        }
    }
}
