//! A KRL program as the virtual robot runs it: the motion simulation of the main job
//! (`crate::krl::interpret::simulate`, the controller's nominal IK with S/T and continuity, LIN/CIRC
//! interpolation) turned into the robot's visiting sequence — one stop per executed target,
//! the command axes the controller computes for it, the axis histories its simulated motion
//! arrives with (directions and turning points inside the interpolated motions), a clock paced as the campaign's — together with where each target was
//! programmed, so that "measured − programmed" is the positioning error. The auxiliary points
//! of circular motions are passed through, not stopped at: they are visited (their motion
//! sets the directions) but not measured.
//!
//! The tracker measures the truth's measurement target (the SMR on the flange); the error is
//! "measured − programmed" only where the program's TCP is that target. [`tool_warnings`]
//! names every tool that is not (a warning, not an error: the CSV is still valid tracker data
//! of the target, for `identify` and `compare`).

use nalgebra::Vector3;

use super::campaign::{paced, PlannedStop};
use crate::diagnostic::{Diagnostic, Severity};
use crate::krl::interpret::{Simulation, Workspace};
use crate::model::AxisState;
use crate::motion::{program_states, Role};

/// Tools within this distance of the measurement target (mm) are taken as the target: the
/// rounding of a `$TOOL` written to the micrometre.
pub const TOOL_MATCH_MM: f64 = 0.001;

/// One executed target of a program, as the virtual robot visits it.
#[derive(Clone, Debug, PartialEq)]
pub struct ProgramVisit {
    /// Test label, command axes, measured (not on auxiliary points), time.
    pub stop: PlannedStop,
    /// The command angle of each axis's last turning point inside the interpolated motion
    /// that reaches this stop (NaN: none), so that the gear play sees the whole trajectory.
    pub turns: [f64; 6],
    /// The motion starts from a position the simulation could not follow: every axis's
    /// history starts anew.
    pub from_unknown: bool,
    /// The robot passes this stop by without visiting it (the auxiliary point of a circle
    /// with `CA`): the motion after it continues the history from the stop before.
    pub passed_by: bool,
    /// The programmed TCP position in the robot base frame, mm.
    pub programmed_mm: Vector3<f64>,
    /// The tool of the motion: the TCP in the flange frame, mm.
    pub tool_mm: Vector3<f64>,
    /// 1-based source line of the motion statement.
    pub line: u32,
}

/// The visits of a simulated program, one per stop of `sim` and in its order, labelled
/// `test` and time-stamped at `dwell_s` per stop and `axis_speed_deg_s` between stops.
pub fn program_visits(
    sim: &Simulation,
    test: &str,
    dwell_s: f64,
    axis_speed_deg_s: f64,
) -> Vec<ProgramVisit> {
    let states = program_states(&sim.stops, &sim.arcs);
    let stops = paced(
        sim.stops
            .iter()
            .zip(&states)
            .map(|(s, state)| (test.to_string(), state.axes_deg, s.role == Role::Target)),
        dwell_s,
        axis_speed_deg_s,
    );
    stops
        .into_iter()
        .zip(states)
        .zip(&sim.stops)
        .enumerate()
        .map(|(i, ((stop, _), s))| ProgramVisit {
            stop,
            turns: s.turns.angle_deg,
            from_unknown: s.arrival.is_none(),
            passed_by: sim.passes_by(i),
            programmed_mm: s.goal.position,
            tool_mm: sim.frames[s.tool as usize].position,
            line: s.handle.stmt.line,
        })
        .collect()
}

/// The axis states of `visits` in order: each reached from the one before through its
/// motion's turning points (see [`AxisState::then_through`]).
pub fn visit_states(visits: &[ProgramVisit]) -> Vec<AxisState> {
    let mut previous: Option<AxisState> = None;
    visits
        .iter()
        .map(|v| {
            let mut state = match (&previous, v.from_unknown) {
                (Some(p), false) => p.then_through(&v.turns, v.stop.axes_deg),
                _ => AxisState::new(v.stop.axes_deg),
            };
            state.time_s = v.stop.time_s;
            if !v.passed_by {
                previous = Some(state);
            }
            state
        })
        .collect()
}

/// Labels the visits of a program `robopost campaign` wrote ([`super::lab`]) by its markers:
/// each stop gets its test's label, and only the stops with a point name are measured (the
/// approach moves are visited, not measured), as on the real cell. `false` (nothing changed)
/// for any other program.
pub fn label_campaign(visits: &mut [ProgramVisit], source: &str) -> bool {
    let Some(marks) = super::lab::markers(source) else {
        return false;
    };
    for v in visits.iter_mut() {
        if let Some((test, point)) = marks.get(&v.line) {
            v.stop.test = test.clone();
            v.stop.measured = point.is_some();
        }
    }
    true
}

/// The rows of a measurement file for `visits` measured as `stops` (one per visit): before
/// every visit whose motion turns an axis round, an unmeasured row with those axes at their
/// turning points (the others where the motion started), so that the histories a reader
/// infers from the rows are the ones the run had.
pub fn rows_with_turns(
    visits: &[ProgramVisit],
    stops: &[crate::measure::Stop],
) -> Vec<crate::measure::Stop> {
    let mut rows = Vec::with_capacity(stops.len());
    let mut from: Option<[f64; 6]> = None;
    for (v, s) in visits.iter().zip(stops) {
        if v.passed_by {
            // Not visited: not a row (a reader would take it for a stop).
            continue;
        }
        let turning = v.turns.iter().any(|t| t.is_finite());
        if let (true, false, Some(from)) = (turning, v.from_unknown, from) {
            let axes = std::array::from_fn(|n| {
                if v.turns[n].is_finite() {
                    v.turns[n]
                } else {
                    from[n]
                }
            });
            rows.push(crate::measure::Stop {
                test: s.test.clone(),
                state: AxisState {
                    time_s: s.state.time_s,
                    ..AxisState::new(axes)
                },
                measured_mm: None,
                line: s.line,
            });
        }
        rows.push(s.clone());
        from = Some(v.stop.axes_deg);
    }
    rows
}

/// A warning at the first measured motion of every tool that is not the measurement target
/// `target_mm`, with both vectors: there the measured position is not the TCP's.
pub fn tool_warnings(
    ws: &Workspace,
    sim: &Simulation,
    target_mm: &Vector3<f64>,
) -> Vec<Diagnostic> {
    let mut warned: Vec<u32> = Vec::new();
    let mut out = Vec::new();
    for s in &sim.stops {
        if s.role != Role::Target || warned.contains(&s.tool) {
            continue;
        }
        let tool = sim.frames[s.tool as usize].position;
        if (tool - target_mm).norm() <= TOOL_MATCH_MM {
            continue;
        }
        warned.push(s.tool);
        let v = |p: &Vector3<f64>| format!("({:.3}, {:.3}, {:.3})", p.x, p.y, p.z);
        out.push(
            ws.diagnostic(
                Severity::Warning,
                s.handle.file,
                s.handle.stmt.head,
                format!(
                    "the TCP of this motion is {} on the flange (the tool's X, Y, Z), but the \
                     tracker measures the truth's target at {}: for the motions with this tool \
                     the measured positions are the target's, not the TCP's, so measured − \
                     programmed is not their positioning error",
                    v(&tool),
                    v(target_mm)
                ),
            )
            .with_help(format!(
                "to measure the TCP, program the tool as the measurement target: \
                 $TOOL = {{X {}, Y {}, Z {}, A 0, B 0, C 0}}",
                target_mm.x, target_mm.y, target_mm.z
            )),
        );
    }
    out
}
