//! The per-program report (`--report FILE.json`) and how its figures are gathered: segment
//! by segment in execution order, as the program is compensated (`Tally`), each sum over the
//! compensated targets in program order (the same bits as summed in one go).

use serde::Serialize;

use crate::diagnostic::{Diagnostic, Severity};
use crate::identify::covariance::{sigma_um, Covariance};
use crate::krl::interpret::{Simulation, Workspace};
use crate::model::{AxisState, Direction, Model};
use crate::motion::frame;
use crate::motion::Role;

use crate::compensate::sequence::{Command, Outcome, Resolution};
use crate::krl::rewrite::Rewrite;

/// Statistics of one quantity over the targets.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct MaxMean {
    /// The largest value.
    pub max: f64,
    /// The mean value.
    pub mean: f64,
}

#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
/// A pose difference over the targets: its position and orientation parts.
pub struct PoseStats {
    /// Position part, µm.
    pub position_um: MaxMean,
    /// Orientation part (rotation angle), mdeg.
    pub orientation_mdeg: MaxMean,
}

/// One target in the report.
#[derive(Clone, Debug, Serialize)]
pub struct PointReport {
    /// The file the target's numbers are written in.
    pub file: String,
    /// 1-based line of the motion statement.
    pub line: u32,
    /// The motion's keyword (`PTP`, `LIN`, `CIRC`, `SPL`, …).
    pub motion: &'static str,
    /// `target`; `aux` for a CIRC's auxiliary point; `end` for where a CIRC with `CA` ends
    /// when that is not its programmed target (not written).
    pub role: &'static str,
    /// Command change at the TCP: µm and mdeg.
    pub correction_um: f64,
    /// The orientation part of the command change, mdeg.
    pub correction_mdeg: f64,
    /// Predicted TCP error of the original command, and left at the new one.
    pub before_um: f64,
    /// Predicted TCP position error left at the new command, µm.
    pub residual_um: f64,
    /// Predicted TCP orientation error left at the new command, mdeg.
    pub residual_mdeg: f64,
    /// Steps to the tolerance after the nominal command, each one evaluation of the model:
    /// 0 when the nominal command already met it, usually 1 or 2, whether the target was
    /// predicted from the ones before it along the path (`solve::Chain`) or linearised afresh.
    pub iterations: u32,
    /// `+`, `-` or `0` (unknown) per axis on arrival, compensated motion.
    pub directions: String,
    /// Axes whose direction differs from the nominal motion's.
    pub flipped: Vec<String>,
    /// `consistent`, `rebranched`, `held:A1,A4`, `branch`.
    pub resolution: String,
    /// Whether the target's numbers were rewritten.
    pub compensated: bool,
    /// Predicted uncertainty of the TCP's position at the command, one standard deviation
    /// per base coordinate X, Y, Z (µm): the calibration campaign's tracker noise carried
    /// through the identification to this target (only with the campaign given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_um: Option<[f64; 3]>,
    /// Why the target was left as written, when it was.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The per-program report (`--report FILE.json`).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Report {
    /// The program's name (its path, or `-` for standard input).
    pub program: String,
    /// The calibration applied: its file, robot and digest.
    pub calibration: CalibrationRef,
    /// `iterate` (the model inverted to the tolerance) or `one-step` (equation (3) applied
    /// once, `--one-step`).
    pub method: &'static str,
    /// Motion targets simulated (auxiliary points included).
    pub targets: usize,
    /// Targets whose numbers changed.
    pub compensated: usize,
    /// Targets refused by an error of their own (unreachable, beyond the joint limits, not
    /// compensable): left as written, named with their line; counted in `targets`.
    pub rejected: usize,
    /// Targets whose numbers can be rewritten (literal positions in files robopost writes).
    pub compensable: usize,
    /// Motion executions whose target the walk could not resolve before run time (left
    /// unchanged; not counted in `targets`).
    pub unresolved: usize,
    /// What the program needs that was found nowhere (`routine SetFrames`, `BASE_DATA[3]`).
    pub needs: Vec<String>,
    /// The command change at the TCP over the compensated targets.
    pub correction: PoseStats,
    /// The model's predicted TCP error of the original commands.
    pub predicted_before: PoseStats,
    /// The model's predicted TCP error left at the new commands.
    pub predicted_after: PoseStats,
    /// Predicted uncertainty of the compensated targets' positions, the 3-D one standard
    /// deviation `√(σx² + σy² + σz²)` (µm; only with the calibration campaign given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub predicted_sigma_3d_um: Option<MaxMean>,
    /// Targets where an axis's compensated direction differs from the nominal one.
    pub direction_flips: usize,
    /// Targets where an axis the program holds was kept exactly still (its output need not
    /// move; inside its gear play any command there gives the same output).
    pub held_axes: usize,
    /// Targets whose output moves back by less than an axis's gear play: the command travels
    /// the play before the output follows.
    pub reversals_inside_play: usize,
    /// `.dat` points reached with different corrections, split into one point per use.
    pub split_points: Vec<SplitReport>,
    /// Warnings, rendered as the command line prints them.
    pub warnings: Vec<String>,
    /// Per-target and per-program errors, rendered as the command line prints them.
    pub errors: Vec<String>,
    /// Every target, in execution order.
    pub points: Vec<PointReport>,
    /// Targets taken as taught (left as they are) or offline (compensated), and why.
    pub points_taken: super::taken::PointsTaken,
    /// Every `--assume` given, and how often the walk used it.
    pub assumptions: Vec<AssumptionUse>,
}

/// One `--assume NAME=VALUE` and how often the walk used it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct AssumptionUse {
    /// `NAME=VALUE` as given.
    pub assumption: String,
    /// How many times the walk read the assumed value.
    pub uses: u64,
}

impl Report {
    /// `40 of 46 targets compensated, 2 rejected` — the one count every summary gives (the
    /// main job, `batch`, `check -c`), with the motions the walk could not resolve.
    pub fn counts(&self) -> String {
        format!(
            "{} of {} targets compensated, {} rejected{}",
            self.compensated,
            self.targets,
            self.rejected,
            self.unresolved_text()
        )
    }

    /// What `check` without a calibration says: the targets it resolved and could rewrite.
    pub fn resolution(&self) -> String {
        format!(
            "{} of {} targets resolved and compensable, {} rejected{}",
            self.compensable,
            self.targets,
            self.rejected,
            self.unresolved_text()
        )
    }

    fn unresolved_text(&self) -> String {
        match self.unresolved {
            0 => String::new(),
            n => format!(
                ", {n} motion{} not resolved before run time (left unchanged)",
                if n == 1 { "" } else { "s" }
            ),
        }
    }

    /// `; assumed lnUsedBase=2 (used 3 times)`, and which targets were taken as taught (see
    /// `PointsTaken::text`): empty when nothing was assumed and no target taken as taught.
    pub fn taken_text(&self) -> String {
        let mut text = String::new();
        if !self.assumptions.is_empty() {
            let list: Vec<String> = self
                .assumptions
                .iter()
                .map(|a| {
                    format!(
                        "{} (used {} time{})",
                        a.assumption,
                        a.uses,
                        if a.uses == 1 { "" } else { "s" }
                    )
                })
                .collect();
            text += &format!("; assumed {}", list.join(", "));
        }
        text + &self.points_taken.text()
    }

    /// `; needs: routine SetFrames, BASE_DATA[3]` (empty when nothing is missing).
    pub fn needs_text(&self) -> String {
        if self.needs.is_empty() {
            String::new()
        } else {
            format!("; needs: {}", self.needs.join(", "))
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
/// The calibration a program was compensated with.
pub struct CalibrationRef {
    /// The calibration file's name as given.
    pub file: String,
    /// SHA-256 of its bytes (hex).
    pub sha256: String,
}

#[derive(Clone, Debug, Serialize)]
/// A `.dat` point reached by several targets that need different corrections: each use gets
/// a copy of its own.
pub struct SplitReport {
    /// The point's name in the `.dat`.
    pub point: String,
    /// The names of its copies, in order of use.
    pub copies: Vec<String>,
}

fn dir_char(d: Direction) -> char {
    match d {
        Direction::Positive => '+',
        Direction::Negative => '-',
        Direction::Unknown => '0',
    }
}

fn axes_list(mask: &[bool; 6]) -> Vec<String> {
    (0..6)
        .filter(|&i| mask[i])
        .map(|i| format!("A{}", i + 1))
        .collect()
}

/// A running maximum and mean (summed in the order given).
#[derive(Clone, Copy, Debug, Default)]
struct Running {
    max: f64,
    sum: f64,
    n: usize,
}

impl Running {
    fn add(&mut self, v: f64) {
        self.max = self.max.max(v);
        self.sum += v;
        self.n += 1;
    }

    fn get(&self) -> MaxMean {
        MaxMean {
            max: self.max,
            mean: if self.n > 0 {
                self.sum / self.n as f64
            } else {
                0.0
            },
        }
    }
}

/// The report's figures, gathered segment by segment in execution order.
#[derive(Debug, Default)]
pub(super) struct Tally {
    targets: usize,
    compensated: usize,
    rejected: usize,
    compensable: usize,
    /// Correction, predicted error before and after: position and orientation each.
    figures: [Running; 6],
    direction_flips: usize,
    held_axes: usize,
    reversals_inside_play: usize,
    points: Vec<PointReport>,
    /// Corrections above [`LARGE_CORRECTION_UM`] or [`LARGE_CORRECTION_MDEG`]: how many, and
    /// the first few as located warnings.
    large: usize,
    large_shown: Vec<Diagnostic>,
    /// 3-D predicted uncertainty of the compensated targets, when a covariance is given.
    sigma_3d: Option<Running>,
}

/// The parameter covariance and the model it belongs to.
pub(super) type Uncertainty<'a> = (&'a Covariance, &'a Model);

/// What the report lists per target: every target (`--report`), and with a covariance each
/// one's predicted uncertainty.
#[derive(Clone, Copy)]
pub(super) struct Listing<'a> {
    pub points: bool,
    pub uncertainty: Option<Uncertainty<'a>>,
}

/// One standard deviation per coordinate (µm) of the TCP's position at a target's command.
fn target_sigma_um(
    (covariance, model): Uncertainty<'_>,
    sim: &Simulation,
    stop: &crate::krl::interpret::Stop,
    o: &Outcome,
) -> [f64; 3] {
    let state = AxisState::with_directions(o.axes_deg.0, o.directions);
    let tool = sim
        .frames
        .get(stop.tool as usize)
        .copied()
        .unwrap_or_else(crate::kinematics::Frame::identity);
    sigma_um(&covariance.tcp(model, &state, &tool))
}

/// A correction larger than this (5 mm, 1°) is no calibrated robot's error but a calibration
/// that does not fit the robot (a table in the wrong unit, another robot's file): warned
/// about, with its line, before anything is written.
pub const LARGE_CORRECTION_UM: f64 = 5000.0;
pub const LARGE_CORRECTION_MDEG: f64 = 1000.0;
/// Large corrections warned about one by one; the rest are counted.
const LARGE_SHOWN: usize = 5;

impl Tally {
    /// The targets `sim.stops[first..]` with their `outcomes` and `commands`.
    pub fn add(
        &mut self,
        ws: &Workspace,
        sim: &Simulation,
        first: usize,
        outcomes: &[Outcome],
        commands: &[Command],
        Listing {
            points,
            uncertainty,
        }: Listing<'_>,
    ) {
        use rayon::prelude::*;
        let stops = &sim.stops[first..first + outcomes.len()];
        let compensated =
            |i: usize| outcomes[i].changed && outcomes[i].error.is_none() && stops[i].compensable;
        // Command change at the TCP, µm and mdeg.
        let corr = |i: usize| commands[i].correction;
        let mut sigmas: Vec<Option<[f64; 3]>> = Vec::new();
        if let Some(u) = uncertainty {
            (0..outcomes.len())
                .into_par_iter()
                .with_min_len(64)
                .map(|i| Some(target_sigma_um(u, sim, &stops[i], &outcomes[i])))
                .collect_into_vec(&mut sigmas);
            let running = self.sigma_3d.get_or_insert_with(Running::default);
            for (i, s) in sigmas.iter().enumerate() {
                if let (true, Some(s)) = (compensated(i), s) {
                    running.add(s.iter().map(|v| v * v).sum::<f64>().sqrt());
                }
            }
        }
        if points {
            let mut listed = Vec::new();
            (0..outcomes.len())
                .into_par_iter()
                .with_min_len(512)
                .map(|i| {
                    let mut p = point_report(ws, &stops[i], &outcomes[i], corr(i), compensated(i));
                    p.sigma_um = sigmas.get(i).copied().flatten();
                    p
                })
                .collect_into_vec(&mut listed);
            self.points.append(&mut listed);
        }
        // Each target's figures in parallel; summed in execution order (the means are
        // those of one sequential sum).
        let figures: Vec<Option<[f64; 6]>> = (0..outcomes.len())
            .into_par_iter()
            .with_min_len(512)
            .map(|i| {
                let o = &outcomes[i];
                compensated(i).then(|| {
                    let (bp, br) = frame::norms(&o.before);
                    let (rp, rr) = frame::norms(&o.residual);
                    let (cp, cr) = corr(i);
                    [
                        cp,
                        cr,
                        bp * 1e3,
                        br.to_degrees() * 1e3,
                        rp * 1e3,
                        rr.to_degrees() * 1e3,
                    ]
                })
            })
            .collect();
        self.targets += outcomes.len();
        self.rejected += outcomes.iter().filter(|o| o.error.is_some()).count();
        self.compensable += stops.iter().filter(|s| s.compensable).count();
        for (i, values) in figures.into_iter().enumerate() {
            let Some(values) = values else { continue };
            if values[0] > LARGE_CORRECTION_UM || values[1] > LARGE_CORRECTION_MDEG {
                self.large += 1;
                if self.large_shown.len() < LARGE_SHOWN {
                    let s = &stops[i];
                    let message = format!(
                        "the calibration moves this target by {:.1} mm / {:.3}°, more than any robot's error (5 mm / 1°): check that the calibration belongs to this robot",
                        values[0] / 1000.0,
                        values[1] / 1000.0
                    );
                    let d = ws.diagnostic(
                        Severity::Warning,
                        s.handle.file,
                        s.handle.stmt.head,
                        message,
                    );
                    self.large_shown.push(d);
                }
            }
            self.compensated += 1;
            for (f, v) in self.figures.iter_mut().zip(values) {
                f.add(v);
            }
        }
        self.direction_flips += outcomes
            .iter()
            .filter(|o| o.flipped().iter().any(|&f| f))
            .count();
        self.held_axes += outcomes
            .iter()
            .filter(|o| matches!(o.resolution, Resolution::Held(_)))
            .count();
        self.reversals_inside_play += outcomes
            .iter()
            .filter(|o| o.travels_play.contains(&true))
            .count();
    }

    /// Warnings about corrections above a sane size (the first few located, then a count).
    pub fn large_corrections(&mut self) -> Vec<Diagnostic> {
        let mut out = std::mem::take(&mut self.large_shown);
        let more = self.large.saturating_sub(out.len());
        if more > 0 {
            if let Some(first) = out.first() {
                out.push(Diagnostic::new(
                    Severity::Warning,
                    &first.file,
                    format!("{more} more targets are moved by more than 5 mm or 1°"),
                ));
            }
        }
        out
    }

    /// The report with the figures, the split points and the diagnostics.
    pub fn fill(&mut self, report: &mut Report, rw: &Rewrite, diagnostics: &[Diagnostic]) {
        let f = &self.figures;
        report.targets = self.targets;
        report.compensated = self.compensated;
        report.rejected = self.rejected;
        report.compensable = self.compensable;
        report.correction = PoseStats {
            position_um: f[0].get(),
            orientation_mdeg: f[1].get(),
        };
        report.predicted_before = PoseStats {
            position_um: f[2].get(),
            orientation_mdeg: f[3].get(),
        };
        report.predicted_after = PoseStats {
            position_um: f[4].get(),
            orientation_mdeg: f[5].get(),
        };
        report.predicted_sigma_3d_um = self.sigma_3d.map(|r| r.get());
        report.direction_flips = self.direction_flips;
        report.held_axes = self.held_axes;
        report.reversals_inside_play = self.reversals_inside_play;
        report.points = std::mem::take(&mut self.points);
        report.split_points = rw
            .splits
            .iter()
            .map(|(p, c)| SplitReport {
                point: p.clone(),
                copies: c.clone(),
            })
            .collect();
        for d in diagnostics {
            let line = format!("{}:{}:{}: {}", d.file, d.line, d.col, d.message);
            match d.severity {
                Severity::Warning => report.warnings.push(line),
                Severity::Error => report.errors.push(line),
            }
        }
    }
}

fn point_report(
    ws: &Workspace,
    stop: &crate::krl::interpret::Stop,
    o: &Outcome,
    (correction_um, correction_mdeg): (f64, f64),
    compensated: bool,
) -> PointReport {
    let (bp, _) = frame::norms(&o.before);
    let (rp, rr) = frame::norms(&o.residual);
    let flipped = o.flipped();
    PointReport {
        file: ws.get(stop.handle.file).name.clone(),
        line: stop.handle.stmt.line,
        motion: stop.handle.kind.keyword(),
        role: match stop.role {
            Role::Target => "target",
            Role::Aux => "aux",
            Role::End => "end",
        },
        correction_um,
        correction_mdeg,
        before_um: bp * 1e3,
        residual_um: rp * 1e3,
        residual_mdeg: rr.to_degrees() * 1e3,
        iterations: o.iterations,
        directions: o.directions.iter().map(|d| dir_char(*d)).collect(),
        flipped: axes_list(&flipped),
        resolution: match o.resolution {
            Resolution::Consistent => "consistent".into(),
            Resolution::Reflanked => "reflanked".into(),
            Resolution::Held(m) => format!("held:{}", axes_list(&m).join(",")),
        } + &if o.travels_play.contains(&true) {
            format!(" travels-play:{}", axes_list(&o.travels_play).join(","))
        } else {
            String::new()
        } + &if o.turn_held.iter().any(|&h| h) {
            format!(" turn-kept:{}", axes_list(&o.turn_held).join(","))
        } else {
            String::new()
        },
        compensated,
        sigma_um: None,
        error: o.error.map(|e| e.to_string()),
    }
}
