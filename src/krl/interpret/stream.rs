//! The walk of a program whose main routine has streamed runs (`krl::parse_streaming`): the
//! statements of the tree are walked as usual, and where a run stands the walker hands every
//! stop recorded so far to a [`RunSink`], then parses the run window by window, walks each
//! window with a walker of its own (the robot's state, frames and step count carried in and
//! out) and hands the window's stops to the sink before the window is dropped. So a program
//! of a million motions is never held whole: only the skeleton and one window.
//!
//! Continuity across the cuts: every segment handed to the sink begins with *ghosts* — copies
//! of the (up to two) stops executed just before it, as far back as the compensation's
//! direction logic looks (`Stop::ghost`; never rewritten or reported) — so a window's first
//! motion starts from the right pose and its index arithmetic (`Stop::prev`) holds. Runs
//! hold only statements whose meaning depends on nothing but themselves, so walking them
//! without the routine's variables gives the stops the whole-tree walk gives (the tests
//! compare both on every fixture).

use super::*;
use crate::krl::StreamedRun;

self_cell::self_cell!(
    /// A window's workspace with the simulation of its stops, which borrows it: one value,
    /// handed from the walk to the compensation.
    pub struct Walked {
        owner: Workspace,
        #[covariant]
        dependent: Simulation,
    }
);

/// Where the stops of a streamed walk go, segment by segment, in execution order.
pub trait RunSink<'f> {
    /// The walk reached a run: `sim.stops[from..]` are the skeleton's stops since the last
    /// call (ghosts first when the previous segment was a run), their arrivals final.
    fn skeleton(&mut self, sim: &Simulation<'f>, from: usize);
    /// One window of a run, walked: its workspace holds the window as its only file (id 0),
    /// its simulation the window's stops, ghosts first. The sink may keep it until the next
    /// window or [`RunSink::run_end`].
    fn window(&mut self, walked: Walked);
    /// The run's last window was handed over.
    fn run_end(&mut self);
}

/// [`simulate`] of a workspace whose main file may have streamed runs; the skeleton's stops
/// after the last run are in the result (the sink has every stop before them).
pub fn simulate_streaming<'f>(
    ws: &'f Workspace,
    robot: &RobotDescription,
    given: &[GivenFrame],
    sink: &mut (dyn RunSink<'f> + Send),
) -> Simulation<'f> {
    let mut sim = Simulator::new(ws, robot, given);
    sim.run(Some(sink));
    sim.finish_segment();
    sim.into_simulation()
}

/// A stop as a placeholder for the segment after a cut. Its handle keeps the file and keyword
/// but names an empty statement and no numbers: a ghost is never rewritten nor reported, and
/// the statement it copies belongs to a window already dropped.
fn ghost(stop: &Stop) -> Stop<'static> {
    static GHOST: std::sync::OnceLock<Stmt> = std::sync::OnceLock::new();
    let stmt = GHOST.get_or_init(|| Stmt {
        leading: Span::default(),
        head: Span::default(),
        end: 0,
        line: 0,
        fold: None,
        kind: crate::krl::StmtKind::Opaque,
        block: None,
    });
    Stop {
        handle: Handle {
            stmt,
            origin: None,
            reference: None,
            ..stop.handle
        },
        prev: None,
        compensable: false,
        deferred: false,
        spline: None,
        ghost: true,
        ..*stop
    }
}

/// The last [`CARRIED_STOPS`] stops of `stops` (ghosts stand for the stops they copy; a window's
/// stops begin with the history it was given, so this is the history after it).
fn remember(history: &mut Vec<Stop<'static>>, stops: &[Stop]) {
    history.clear();
    history.extend(
        stops[stops.len().saturating_sub(CARRIED_STOPS)..]
            .iter()
            .map(ghost),
    );
}

impl<'f> Simulator<'f> {
    /// Walks one window (`ws`, its only file) from the state the walk is in, `history` the
    /// stops before it (updated to the last ones after it); the robot's state, frames, step
    /// count and diagnostics carry over.
    fn walk_window<'w>(
        &mut self,
        ws: &'w Workspace,
        history: &mut Vec<Stop<'static>>,
    ) -> Simulation<'w> {
        let mut walker = Simulator::new(ws, &self.robot, &self.given);
        walker.assumptions.clone_from(&self.assumptions);
        walker.used = std::cell::RefCell::new(crate::krl::interpret::assume::Used(vec![
            0;
            self.assumptions.len()
        ]));
        walker.state = self.state.clone();
        walker.warned_frames = self.warned_frames;
        walker.noted_external = self.noted_external;
        walker.steps = self.steps;
        walker.moving_iterations = self.moving_iterations;
        walker.out.frames = self.out.frames.clone();
        walker.out.stops.extend(history.iter().copied());
        if let Some(c) = &mut walker.state.current {
            // The position the window starts from is the last stop before it.
            c.stop = c.stop.and((history.len() as u32).checked_sub(1));
        }
        walker.block(0, ws.get(0).file.body(), &mut Scope::default());
        walker.finish_segment();
        walker.count_repeats();
        self.state = walker.state.clone();
        self.warned_frames = walker.warned_frames;
        self.noted_external = walker.noted_external;
        self.steps = walker.steps;
        self.moving_iterations = walker.moving_iterations;
        self.needs
            .borrow_mut()
            .append(&mut walker.needs.borrow_mut());
        self.used.borrow_mut().add(&walker.used.borrow());
        let mut out = walker.out;
        self.out.unreachable += out.unreachable;
        self.out.lost += out.lost;
        self.out.fatal |= out.fatal;
        self.out.diagnostics.append(&mut out.diagnostics);
        self.out.frames.clone_from(&out.frames);
        remember(history, &out.stops);
        out
    }

    /// The pipeline of a run's windows on rayon's pool, one step per window: step k walks
    /// window k (parsed in the step before) while window k+1 is parsed and the sink takes window
    /// k-1 (compensating it on the pool). The walk, sequential by nature, overlaps the
    /// compensation on the pool's own threads, so no thread waits for one the system has put
    /// aside, and only the windows in flight are held. `history` and `moved` as in
    /// [`Simulator::walk_window`] and `stream_run`; false when the walk stopped early (the step
    /// limit, a fatal error), after the sink took the windows walked.
    fn walk_windows<'w>(
        &mut self,
        windows: &'w [(Span, u32)],
        parse: impl Fn(&'w (Span, u32)) -> Workspace + Sync,
        (history, moved): (&mut Vec<Stop<'static>>, &mut bool),
        sink: &mut (dyn RunSink<'f> + Send),
    ) -> bool {
        let mut parsed = windows.first().map(&parse);
        let mut walked: Option<Walked> = None;
        let mut walking = true;
        for k in 0..=windows.len() {
            let ws = parsed.take().filter(|_| walking);
            let next = windows.get(k + 1).filter(|_| walking);
            let taken = walked.take();
            let walk = |ws: Workspace| {
                let _span = tracing::trace_span!("walk window").entered();
                Walked::new(ws, |ws| self.walk_window(ws, history))
            };
            let ((now_walked, now_parsed), ()) = rayon::join(
                || rayon::join(|| ws.map(walk), || next.map(&parse)),
                || {
                    if let Some(w) = taken {
                        let _span = tracing::trace_span!("compensate window").entered();
                        sink.window(w);
                    }
                },
            );
            if let Some(w) = &now_walked {
                *moved |= w.borrow_dependent().stops.iter().any(|s| !s.ghost);
                walking = self.steps < MAX_STEPS && !self.out.fatal;
            }
            (walked, parsed) = (now_walked, now_parsed);
            if walked.is_none() && !walking {
                break;
            }
        }
        let _span = tracing::trace_span!("compensate run end").entered();
        sink.run_end();
        walking
    }

    /// Arrivals of the stops recorded since the last cut made final.
    pub(super) fn finish_segment(&mut self) {
        finish(&mut self.out, &self.robot);
        let splines = std::mem::take(&mut self.splines);
        spline::finish_splines(&mut self.out, &self.robot, &splines);
    }

    /// The main routine's body, with the runs left out of it walked where they stand.
    pub(super) fn main_body(
        &mut self,
        file: FileId,
        body: &'f [Stmt],
        scope: &mut Scope<'f>,
        sink: &mut (dyn RunSink<'f> + Send),
    ) -> Flow {
        let runs = self.src(file).streamed_runs();
        let mut next = 0;
        for i in 0..=body.len() {
            while next < runs.len() && runs[next].before as usize == i {
                self.stream_run(file, &runs[next], sink);
                next += 1;
                if self.steps >= MAX_STEPS || self.out.fatal {
                    return Flow::Return;
                }
            }
            let Some(s) = body.get(i) else { break };
            match self.stmt(file, s, scope) {
                Flow::Next => {}
                other => return other,
            }
        }
        Flow::Next
    }

    /// Walks run `run` window by window, each window's stops handed to `sink` (see
    /// [`Simulator::walk_windows`]).
    fn stream_run(&mut self, file: FileId, run: &StreamedRun, sink: &mut (dyn RunSink<'f> + Send)) {
        self.finish_segment();
        sink.skeleton(&self.out, self.handed);
        self.handed = self.out.stops.len();
        let before = self.state.current.and_then(|c| c.stop);
        let mut history = Vec::new();
        remember(&mut history, &self.out.stops);
        let mut moved = false;
        let (all, file_tree) = (self.ws, &self.ws.get(file).file);
        let windows: Vec<(Span, u32)> = run.windows().collect();
        let parse = |w: &(Span, u32)| {
            let _span = tracing::trace_span!("parse window").entered();
            all.window_of(file, file_tree.window(*w))
        };
        // Taken on a thread of the pool, each step's `rayon::join` starts where it is called
        // instead of being handed over and waited for from outside.
        let walked_all =
            rayon::scope(|_| self.walk_windows(&windows, parse, (&mut history, &mut moved), sink));
        if !walked_all {
            return;
        }
        if moved {
            // The skeleton goes on from the run's last stops.
            let first = self.out.stops.len() as u32;
            self.out.stops.extend(history.iter().copied());
            if let Some(c) = &mut self.state.current {
                c.stop = c.stop.map(|_| first + history.len() as u32 - 1);
            }
        } else if let Some(c) = &mut self.state.current {
            c.stop = c.stop.and(before);
        }
    }
}
