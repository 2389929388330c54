//! Compensation segment by segment, in execution order, as the walk hands the stops over
//! ([`RunSink`]): the skeleton's stops up to a streamed run, then each window of the run —
//! compensated, reported and (windows) rewritten at once, so that nothing of a window is
//! kept but its new bytes. The direction logic's look-back crosses the cuts through the
//! carried last targets ([`sequence::compensate_after`]), so the result is the one of the
//! whole sequence at once. A window is worked in two halves: what needs nothing of the
//! windows before it ([`Prepared`]: targets, first-pass solves, singularity tests) runs while
//! the window before is settled against the history, tallied and rewritten, so the
//! sequential parts of the one overlap the parallel parts of the other. The skeleton is
//! rewritten after the walk (a `.dat` point may be reached before and after a run: splitting
//! it needs every use).

use crate::diagnostic::{Diagnostic, Severity};
use crate::kinematics::Singularity;
use crate::krl::interpret::{RunSink, Simulation, Walked, Workspace};
use crate::krl::Span;
use crate::model::{Direction, Model};

use super::program::{targets, Options, Tally};
use super::report::Listing;
use super::taken::{self, Taking};
use crate::compensate::sequence::{
    self, Carried, Command, Compensated, Outcome, Target, LOOK_BACK,
};
use crate::krl::rewrite;

/// One compensated segment: the outcomes of its stops are `done.outcomes[skip..]` (the
/// ghosts' first, carried from the history).
struct Segment {
    done: Compensated,
    skip: usize,
    ghosts: usize,
    ghost_commands: Vec<Command>,
}

impl Segment {
    fn outcomes(&self) -> &[Outcome] {
        &self.done.outcomes[self.skip..]
    }
}

/// The part of a segment's work that needs nothing of the segments before it (their nominal
/// directions and warm-start chain aside): it runs while the segment before is still being
/// settled.
pub(super) struct Prepared {
    /// Leading ghosts of the segment's stops (their outcomes are in the history).
    ghosts: usize,
    targets: Vec<Target>,
    first: sequence::FirstPasses,
    /// The singularity test of every (non-ghost) stop.
    singular: Vec<Option<Singularity>>,
}

/// Prepares segments ([`Prepared`]): read-only, so one may run beside [`Segments::settle`].
#[derive(Clone, Copy)]
struct Preparer<'a> {
    model: &'a Model,
    options: &'a Options,
    taking: &'a Taking,
}

impl Preparer<'_> {
    fn prepare(
        self,
        ws: &Workspace,
        sim: &Simulation,
        from: usize,
        nominal_start: &mut [Direction; 6],
        chains: &mut sequence::Chains,
    ) -> Prepared {
        use rayon::prelude::*;
        let ghosts = sim.stops[from..].iter().take_while(|s| s.ghost).count();
        let first = from + ghosts;
        let taking = self.taking;
        let leaves = |s: &crate::krl::interpret::Stop| !taking.moves() && taking.taught(ws, s);
        let mut targets = targets(sim, first..sim.stops.len(), leaves);
        if taking.moves() {
            // `--from`: a taught target goes where the robot it was taught on reaches it.
            for (k, t) in targets.iter_mut().enumerate() {
                if let Some(place) = taking.place(first + k) {
                    t.goal = *place;
                }
            }
        }
        let passes = sequence::first_passes(
            self.model,
            &sim.frames,
            &targets,
            *nominal_start,
            chains,
            &self.options.sequence(),
        );
        if let Some(end) = passes.nominal_end() {
            *nominal_start = end;
        }
        let robot = &self.model.robot;
        // The singularity test of every stop in parallel (a million cost 0.2 s alone; a
        // window's in a few parts, not on the calling thread).
        let singular = sim.stops[first..]
            .par_iter()
            .with_min_len(1024)
            .map(|stop| {
                stop.compensable
                    .then(|| crate::kinematics::singularity(robot, &stop.nominal_axes))
                    .flatten()
            })
            .collect();
        Prepared {
            ghosts,
            targets,
            first: passes,
            singular,
        }
    }
}

pub(super) struct Segments<'a> {
    /// The main file (its skeleton): where windows take their style from.
    main: &'a crate::krl::SourceFile,
    separator: Option<Vec<u8>>,
    model: &'a Model,
    options: &'a Options,
    taking: &'a Taking,
    /// Targets taken as taught or offline, and why.
    pub taken: taken::Tally,
    /// The nominal directions after the last prepared segment.
    nominal_end: [Direction; 6],
    /// Where the last prepared segment left the warm-start chains.
    chains: sequence::Chains,
    /// The last window, prepared but not settled yet.
    pending: Option<(Walked, Prepared)>,
    history: Vec<Carried>,
    /// Outcomes of the skeleton's stops (ghosts included), in order, and their commands.
    pub skeleton: Vec<Outcome>,
    pub skeleton_commands: Vec<Command>,
    /// The windows whose numbers changed: their bytes in the main file and the new bytes.
    pub windows: Vec<(Span, Vec<u8>)>,
    pub tally: Tally,
    /// Near-singular targets and targets not compensated, in execution order.
    pub singular: Vec<Diagnostic>,
    pub target_errors: Vec<Diagnostic>,
    /// The line of each target error said so far: (its diagnostic, repeats).
    errors_at:
        std::collections::HashMap<(crate::krl::interpret::workspace::FileId, u32), (usize, usize)>,
    /// What rewriting the windows said.
    pub rewrite_diagnostics: Vec<Diagnostic>,
    /// The windows' targets written continuous near B = ±90°.
    pub euler: Option<rewrite::EulerLeft>,
    /// Applying a window's edits failed (an internal error: nothing may be written).
    pub failed: Option<Box<Diagnostic>>,
}

impl<'a> Segments<'a> {
    /// Whether taught targets are moved (`--from`).
    pub fn taking_moves(&self) -> bool {
        self.taking.moves()
    }

    /// `--points` as given.
    pub fn taking_mode(&self) -> taken::Taken {
        self.taking.mode
    }

    /// The calibrated model the segments are compensated with.
    pub fn model(&self) -> &'a Model {
        self.model
    }

    pub fn new(
        ws: &'a Workspace,
        model: &'a Model,
        options: &'a Options,
        taking: &'a Taking,
    ) -> Segments<'a> {
        Segments {
            main: &ws.get(ws.main).file,
            separator: None,
            model,
            options,
            taking,
            taken: taken::Tally::default(),
            nominal_end: [Direction::Unknown; 6],
            chains: sequence::Chains::default(),
            pending: None,
            history: Vec::new(),
            skeleton: Vec::new(),
            skeleton_commands: Vec::new(),
            windows: Vec::new(),
            tally: Tally::default(),
            singular: Vec::new(),
            target_errors: Vec::new(),
            errors_at: Default::default(),
            rewrite_diagnostics: Vec::new(),
            euler: None,
            failed: None,
        }
    }

    fn preparer(&self) -> Preparer<'a> {
        Preparer {
            model: self.model,
            options: self.options,
            taking: self.taking,
        }
    }

    /// Settles the prepared segment `sim.stops[from..]` after the carried history (the stops
    /// executed just before them: the leading ghosts stand for its last ones). The caller
    /// tallies them.
    fn settle(
        &mut self,
        ws: &Workspace,
        sim: &Simulation,
        from: usize,
        prepared: Prepared,
    ) -> Segment {
        let Prepared {
            ghosts,
            targets,
            first: passes,
            singular,
        } = prepared;
        debug_assert!(ghosts <= self.history.len());
        let first = from + ghosts;
        let done = sequence::settle(
            self.model,
            &sim.frames,
            &self.history,
            &targets,
            passes,
            &self.options.sequence(),
        );
        self.diagnose(ws, sim, first, done.targets(), singular);
        // The next history: the last (up to LOOK_BACK) targets of the carried and these.
        let states_from = targets.len() - done.last_states.len();
        let carried = |k: usize| Carried {
            target: targets[k],
            outcome: done.targets()[k],
            resolved: done.resolved[k],
            command: done.commands[k],
            state: done.last_states[k - states_from],
        };
        let keep = targets.len().min(LOOK_BACK);
        let extra = (self.history.len() + keep).saturating_sub(LOOK_BACK);
        let ghost_commands: Vec<Command> = self.history[self.history.len() - ghosts..]
            .iter()
            .map(|c| c.command)
            .collect();
        self.history.drain(..extra);
        self.history
            .extend((targets.len() - keep..targets.len()).map(carried));
        Segment {
            skip: done.history - ghosts,
            ghost_commands,
            done,
            ghosts,
        }
    }

    /// Near-singular targets (compensated in the least-squares sense there, where small
    /// Cartesian changes turn axes a lot) and targets left as written, in program order.
    fn diagnose(
        &mut self,
        ws: &Workspace,
        sim: &Simulation,
        first: usize,
        outcomes: &[Outcome],
        singular: Vec<Option<Singularity>>,
    ) {
        let stops = &sim.stops[first..];
        let mut seen = std::collections::HashSet::new();
        for ((stop, o), sing) in stops.iter().zip(outcomes).zip(singular) {
            if let Some(sing) = sing {
                if seen.insert((stop.handle.file, stop.handle.stmt.head.start)) {
                    self.singular.push(ws.diagnostic(
                        Severity::Warning,
                        stop.handle.file,
                        stop.handle.stmt.head,
                        format!("the target is near a singularity ({sing}): compensated in the least-squares sense where the pose cannot be reached exactly"),
                    ));
                }
            }
            if let Some(e) = &o.error {
                // A line executed many times (a loop) says it once, with the count.
                let at = (stop.handle.file, stop.handle.stmt.head.start);
                if let Some((_, n)) = self.errors_at.get_mut(&at) {
                    *n += 1;
                    continue;
                }
                self.errors_at.insert(at, (self.target_errors.len(), 0));
                self.target_errors.push(
                    ws.diagnostic(
                        Severity::Error,
                        stop.handle.file,
                        stop.handle.stmt.head,
                        format!("target not compensated: {e}"),
                    )
                    .with_help(
                        "the target is left as written; move it away from the limit or singularity",
                    ),
                );
            }
        }
    }

    /// Appends to each target error given for a line executed several times how often.
    pub fn count_target_errors(&mut self) {
        for (i, n) in self.errors_at.values() {
            if *n > 0 {
                self.target_errors[*i].message += &crate::krl::interpret::repeats(n + 1);
            }
        }
        self.errors_at.clear();
    }

    /// The skeleton's stops from `from` on (the rest after the walk).
    pub fn skeleton_from(&mut self, ws: &Workspace, sim: &Simulation, from: usize) {
        debug_assert_eq!(from, self.skeleton.len());
        self.flush();
        let prepared =
            self.preparer()
                .prepare(ws, sim, from, &mut self.nominal_end, &mut self.chains);
        let seg = self.settle(ws, sim, from, prepared);
        let first = from + seg.ghosts;
        let stops = &sim.stops[first..first + seg.done.targets().len()];
        self.taken.add(ws, self.taking, stops);
        let points = self.options.points;
        let uncertainty = self.options.uncertainty.as_deref().map(|c| (c, self.model));
        self.tally.add(
            ws,
            sim,
            from + seg.ghosts,
            seg.done.targets(),
            &seg.done.commands,
            Listing {
                points,
                uncertainty,
            },
        );
        self.skeleton.extend_from_slice(seg.outcomes());
        self.skeleton_commands.extend(seg.ghost_commands);
        self.skeleton_commands.extend(seg.done.commands);
    }

    /// Settles, tallies and rewrites a prepared window.
    fn window_done(&mut self, ws: &Workspace, sim: &Simulation, prepared: Prepared) {
        let part = self.settle(ws, sim, 0, prepared);
        let main = self.main;
        let separator = self
            .separator
            .get_or_insert_with(|| rewrite::file_separator(main));
        let placed = rewrite::Placed {
            from: part.ghosts,
            commands: &part.done.commands,
        };
        let robot = &self.model.robot;
        let mut rw =
            rewrite::rewrite_placed(ws, sim, part.outcomes(), placed, robot, Some(separator));
        let stops = &sim.stops[part.ghosts..part.ghosts + part.done.targets().len()];
        self.taken.add(ws, self.taking, stops);
        let points = self.options.points;
        let uncertainty = self.options.uncertainty.as_deref().map(|c| (c, self.model));
        self.tally.add(
            ws,
            sim,
            part.ghosts,
            part.done.targets(),
            &part.done.commands,
            Listing {
                points,
                uncertainty,
            },
        );
        self.rewrite_diagnostics.append(&mut rw.diagnostics);
        self.euler = rewrite::EulerLeft::merge(self.euler.take(), rw.euler.take());
        let Some(edits) = rw.edits.remove(&0).filter(|e| !e.is_empty()) else {
            return;
        };
        let file = &ws.get(0).file;
        let extent = file.extent();
        match edits.apply_in(file.source(), extent.range(), None) {
            Ok(bytes) => self.windows.push((extent, bytes)),
            Err(e) => {
                self.failed.get_or_insert_with(|| {
                    Box::new(Diagnostic::new(
                        Severity::Error,
                        &ws.get(0).name,
                        format!("internal error, nothing written: the rewrite produced {e}; please report this program"),
                    ))
                });
            }
        }
    }

    /// Finishes the window still pending, if any.
    pub fn flush(&mut self) {
        if let Some((walked, prepared)) = self.pending.take() {
            walked.with_dependent(|ws, sim| self.window_done(ws, sim, prepared));
        }
    }
}

impl<'f> RunSink<'f> for (&'f Workspace, &mut Segments<'_>) {
    fn skeleton(&mut self, sim: &Simulation<'f>, from: usize) {
        let ws = self.0;
        self.1.skeleton_from(ws, sim, from);
    }

    /// Prepares this window while the one before is settled and rewritten (which needs the
    /// history up to it): the two overlap on rayon's pool, so the sequential parts of the one
    /// fill the gaps of the other's parallel parts. The settling, sequential, starts at once;
    /// the first passes, in parallel, are taken up by the other thread as soon as it is free
    /// (in the walk's pipeline, when it has walked the next window).
    fn window(&mut self, walked: Walked) {
        let seg = &mut *self.1;
        let preparer = seg.preparer();
        let mut nominal = seg.nominal_end;
        let mut chains = seg.chains;
        let pending = seg.pending.take();
        let prepared = walked.with_dependent(|ws, sim| {
            rayon::join(
                || {
                    if let Some((w, p)) = pending {
                        w.with_dependent(|ws, sim| seg.window_done(ws, sim, p));
                    }
                },
                || preparer.prepare(ws, sim, 0, &mut nominal, &mut chains),
            )
            .1
        });
        seg.nominal_end = nominal;
        seg.chains = chains;
        seg.pending = Some((walked, prepared));
    }

    fn run_end(&mut self) {
        self.1.flush();
    }
}
