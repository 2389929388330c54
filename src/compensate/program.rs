//! One program end to end: simulate its motion, compensate every target, rewrite the files,
//! and summarise what happened in a report. Input is a loaded [`Workspace`]; output the new
//! bytes of every file that belongs to the program (main `.src`/`.dat` and called modules),
//! the report and the diagnostics. Writing files is the caller's business.

use serde::Serialize;

use crate::diagnostic::{Diagnostic, Severity};
use crate::kinematics::RobotDescription;
use crate::krl::{self, StmtKind};
use crate::model::{Direction, Model};
use crate::motion::frame::{self, Frame};
use crate::motion::nominal::{Arm, Nominal};
use crate::motion::workspace::Role as FileRole;
use crate::motion::{self, FileId, GivenFrame, Role, Simulation, Workspace};

use super::rewrite::{self, Rewrite};
use super::sequence::{self, Interp, Keep, Outcome, Quantum, Resolution, Target};
use super::solve::Method;

/// The first words of the header comment robopost writes; a file carrying it was compensated.
pub const HEADER_MARK: &str = "; robopost: compensated with ";

/// The calibration as the output names it.
#[derive(Clone, Debug)]
pub struct Calibrated<'a> {
    pub model: &'a Model,
    /// File name shown in the header comment.
    pub name: String,
    /// SHA-256 of the calibration file, hex.
    pub sha256: String,
}

impl<'a> Calibrated<'a> {
    /// `name` and checksum of calibration file bytes `bytes`.
    pub fn new(model: &'a Model, name: &str, bytes: &[u8]) -> Calibrated<'a> {
        use sha2::Digest;
        let digest = sha2::Sha256::digest(bytes);
        Calibrated {
            model,
            name: name.to_string(),
            sha256: digest.iter().map(|b| format!("{b:02x}")).collect(),
        }
    }
}

#[derive(Clone, Debug, Default)]
pub struct Options {
    pub method: Method,
    /// Solve targets on rayon's pool.
    pub parallel: bool,
    /// `BASE_DATA[n]`/`TOOL_DATA[n]` given on the command line.
    pub frames: Vec<GivenFrame>,
    /// List every target in the report (`--report`); the summary is always filled.
    pub points: bool,
}

/// The new contents of one file of the program.
#[derive(Clone, Debug)]
pub struct FileOutput {
    pub file: FileId,
    pub bytes: Vec<u8>,
    pub changed: bool,
}

/// What compensating a program produced.
#[derive(Debug)]
pub struct ProgramResult {
    /// Every file of the program (not `$config.dat`), changed or not.
    pub files: Vec<FileOutput>,
    pub report: Report,
    pub diagnostics: Vec<Diagnostic>,
    /// An error rejects the whole program: write nothing.
    pub rejected: bool,
    /// Targets rejected (left unchanged) by an error of their own.
    pub target_errors: usize,
}

/// Statistics of one quantity over the targets.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct MaxMean {
    pub max: f64,
    pub mean: f64,
}

#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct PoseStats {
    pub position_um: MaxMean,
    pub orientation_mdeg: MaxMean,
}

/// One target in the report.
#[derive(Clone, Debug, Serialize)]
pub struct PointReport {
    pub file: String,
    pub line: u32,
    pub motion: &'static str,
    pub role: &'static str,
    /// Command change at the TCP: µm and mdeg.
    pub correction_um: f64,
    pub correction_mdeg: f64,
    /// Predicted TCP error of the original command, and left at the new one.
    pub before_um: f64,
    pub residual_um: f64,
    pub residual_mdeg: f64,
    pub iterations: u32,
    /// `+`, `-` or `0` (unknown) per axis on arrival, compensated motion.
    pub directions: String,
    /// Axes whose direction differs from the nominal motion's.
    pub flipped: Vec<String>,
    /// `consistent`, `rebranched`, `held:A1,A4`, `branch`.
    pub resolution: String,
    pub compensated: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The per-program report (`--report FILE.json`).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Report {
    pub program: String,
    pub calibration: CalibrationRef,
    pub method: &'static str,
    /// Motion targets simulated (auxiliary points included).
    pub targets: usize,
    /// Targets whose numbers changed.
    pub compensated: usize,
    pub rejected: usize,
    pub correction: PoseStats,
    pub predicted_before: PoseStats,
    pub predicted_after: PoseStats,
    /// Targets where an axis's compensated direction differs from the nominal one.
    pub direction_flips: usize,
    /// Targets resolved by holding an axis or choosing a branch (backlash oscillation).
    pub oscillations_resolved: usize,
    pub split_points: Vec<SplitReport>,
    pub warnings: Vec<String>,
    pub errors: Vec<String>,
    pub points: Vec<PointReport>,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct CalibrationRef {
    pub file: String,
    pub sha256: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct SplitReport {
    pub point: String,
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

/// The compensation targets of a simulation.
pub fn targets(ws: &Workspace, sim: &Simulation) -> Vec<Target> {
    sim.stops
        .iter()
        .map(|s| Target {
            goal: s.goal,
            tool: s.tool,
            nominal_axes: s.nominal_axes,
            arrival: s.arrival,
            interp: match (s.kind.is_joint(), s.kind.is_circular(), s.role) {
                (true, _, _) => Interp::Joint,
                (false, true, Role::Aux) => Interp::CircAux,
                (false, true, Role::Target) => Interp::CircEnd,
                (false, false, _) => match s.spline {
                    Some(e) => Interp::Curve {
                        first: e.first,
                        last: e.last,
                    },
                    None => Interp::Line,
                },
            },
            compensate: s.compensable,
            quantum: s.origin.filter(|_| s.compensable).map(|o| Quantum {
                base: s.base,
                axis: s.axis,
                decimals: rewrite::decimals(&ws.get(o.file).file, o.agg, s.axis),
            }),
            keep: Keep {
                s: s.keep_s,
                t: s.keep_t,
            },
        })
        .collect()
}

/// Whether a file already carries robopost's header.
fn already_compensated(file: &krl::SourceFile) -> Option<usize> {
    let src = file.source();
    let mark = HEADER_MARK.as_bytes();
    // The mark starts with `;`: compare only there (a whole-file window scan costs 0.1 s on a
    // 70 MB program).
    src.iter()
        .enumerate()
        .filter(|&(_, &b)| b == b';')
        .map(|(i, _)| i)
        .find(|&i| {
            src[i..]
                .get(..mark.len())
                .is_some_and(|w| w.eq_ignore_ascii_case(mark))
        })
}

/// The header comment line and where it goes: after the `&ACCESS`-style directives.
fn header(file: &krl::SourceFile, cal: &Calibrated, method: Method) -> (usize, Vec<u8>) {
    let src = file.source();
    let newline: &[u8] = if src.windows(2).any(|w| w == b"\r\n") {
        b"\r\n"
    } else {
        b"\n"
    };
    let directives = file
        .body()
        .iter()
        .any(|s| matches!(s.kind, StmtKind::Directive { .. }));
    let first = file
        .body()
        .iter()
        .find(|s| !matches!(s.kind, StmtKind::Directive { .. }))
        .map_or(src.len(), |s| s.leading.start as usize);
    // After the directives' last line ending (the controller wants `&…` lines first).
    let at = if directives {
        src[first..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(src.len(), |p| first + p + 1)
    } else {
        0
    };
    let mut text = format!(
        "{HEADER_MARK}{} (sha256 {}){}, do not compensate this file again",
        cal.name,
        cal.sha256,
        if method == Method::OneStep {
            ", one step"
        } else {
            ""
        }
    )
    .into_bytes();
    // A file whose directives end without a line ending needs one first.
    let mut bytes = Vec::new();
    if at > 0 && src[at - 1] != b'\n' {
        bytes.extend_from_slice(newline);
    }
    bytes.append(&mut text);
    bytes.extend_from_slice(newline);
    (at, bytes)
}

/// Where the phase laps count from: the first [`lap_start`] or [`lap`].
static LAP_ORIGIN: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();

/// Starts the clock of the phase laps (the CLI, before loading the program).
pub fn lap_start() {
    LAP_ORIGIN.get_or_init(std::time::Instant::now);
}

/// With `ROBOPOST_TIMING` set: prints the time since [`lap_start`] and the peak memory so far
/// (Linux) after a phase of the main job.
pub fn lap(what: &str) {
    if std::env::var_os("ROBOPOST_TIMING").is_none() {
        return;
    }
    let t0 = *LAP_ORIGIN.get_or_init(std::time::Instant::now);
    let peak = std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
            line.split_whitespace().nth(1)?.parse::<f64>().ok()
        })
        .map_or(String::new(), |kb| format!(", peak {:.0} MB", kb / 1024.0));
    eprintln!("{what}: {:.3} s{peak}", t0.elapsed().as_secs_f64());
}

/// Compensates the main program of `ws`.
pub fn compensate_program(ws: &Workspace, cal: &Calibrated, options: &Options) -> ProgramResult {
    let main = ws.get(ws.main);
    let mut report = Report {
        program: main.name.clone(),
        calibration: CalibrationRef {
            file: cal.name.clone(),
            sha256: cal.sha256.clone(),
        },
        method: match options.method {
            Method::Iterate => "iterate",
            Method::OneStep => "one-step",
        },
        ..Report::default()
    };
    let mut diagnostics = Vec::new();
    for (i, f) in ws.files.iter().enumerate() {
        if f.role == FileRole::Config {
            continue;
        }
        if let Some(at) = already_compensated(&f.file) {
            diagnostics.push(
                ws.diagnostic(
                    Severity::Error,
                    i as FileId,
                    krl::Span::new(at, at + HEADER_MARK.len()),
                    "this file was already compensated by robopost: compensating it again would apply the correction twice",
                )
                .with_help("compensate the original program"),
            );
        }
    }
    // The program is refused: every file as it was, the report listing the errors.
    let rejected = |mut report: Report, diagnostics: Vec<Diagnostic>, target_errors: usize| {
        report.errors = diagnostics
            .iter()
            .filter(|d| d.severity == Severity::Error)
            .map(|d| d.render())
            .collect();
        let files = ws
            .files
            .iter()
            .enumerate()
            .filter(|(_, f)| f.role != FileRole::Config)
            .map(|(i, f)| FileOutput {
                file: i as FileId,
                bytes: f.file.source().to_vec(),
                changed: false,
            })
            .collect();
        ProgramResult {
            files,
            report,
            diagnostics,
            rejected: true,
            target_errors,
        }
    };
    if !diagnostics.is_empty() {
        return rejected(report, diagnostics, 0);
    }
    let model = cal.model;
    let sim = motion::simulate(ws, &model.robot, &options.frames);
    lap("simulate");
    diagnostics.extend(sim.diagnostics.iter().cloned());
    if sim.rejected() {
        return rejected(report, diagnostics, 0);
    }
    let targets = targets(ws, &sim);
    let outcomes = sequence::compensate(
        model,
        &sim.frames,
        &targets,
        [Direction::Unknown; 6],
        &sequence::Options {
            method: options.method,
            parallel: options.parallel,
        },
    );
    drop(targets);
    lap("compensate");
    let mut target_errors = sim.unreachable;
    // Near-singular targets: the compensation there is least squares, and small Cartesian
    // changes turn axes a lot.
    let robot = &model.robot;
    let mut seen = std::collections::HashSet::new();
    // The singularity test of every stop in parallel (a million of them cost 0.2 s alone),
    // the warnings in program order.
    let singular: Vec<(usize, crate::kinematics::Singularity)> = {
        use rayon::prelude::*;
        (0..sim.stops.len())
            .into_par_iter()
            .with_min_len(4096)
            .filter_map(|i| {
                let stop = &sim.stops[i];
                (stop.compensable)
                    .then(|| crate::kinematics::singularity(robot, &stop.nominal_axes))
                    .flatten()
                    .map(|s| (i, s))
            })
            .collect()
    };
    for (i, sing) in singular {
        let stop = &sim.stops[i];
        if seen.insert((stop.file, stop.stmt.head.start)) {
            diagnostics.push(ws.diagnostic(
                Severity::Warning,
                stop.file,
                stop.stmt.head,
                format!("the target is near a singularity ({sing}): compensated in the least-squares sense where the pose cannot be reached exactly"),
            ));
        }
    }
    for (stop, o) in sim.stops.iter().zip(&outcomes) {
        if let Some(e) = &o.error {
            target_errors += 1;
            diagnostics.push(
                ws.diagnostic(
                    Severity::Error,
                    stop.file,
                    stop.stmt.head,
                    format!("target not compensated: {e}"),
                )
                .with_help(
                    "the target is left as written; move it away from the limit or singularity",
                ),
            );
        }
    }
    let mut rw = rewrite::rewrite(ws, &sim, &outcomes, &model.robot);
    lap("rewrite");
    diagnostics.extend(rw.diagnostics.iter().cloned());
    // The report before applying the edits, so that the stops and outcomes are freed before
    // the new bytes are built (the peak memory of a long program).
    let unfilled = report.clone();
    fill_report(
        &mut report,
        ws,
        &sim,
        &outcomes,
        &model.robot,
        &rw,
        &diagnostics,
        options.points,
    );
    lap("report");
    drop((sim, outcomes));
    let files = match apply(ws, std::mem::take(&mut rw.edits), cal, options.method) {
        Ok(files) => files,
        Err(d) => {
            diagnostics.push(*d);
            return rejected(unfilled, diagnostics, target_errors);
        }
    };
    lap("apply");
    ProgramResult {
        files,
        report,
        diagnostics,
        rejected: false,
        target_errors,
    }
}

fn apply(
    ws: &Workspace,
    edits: std::collections::BTreeMap<FileId, super::edits::EditList>,
    cal: &Calibrated,
    method: Method,
) -> Result<Vec<FileOutput>, Box<Diagnostic>> {
    let mut edits = edits;
    ws.files
        .iter()
        .enumerate()
        .filter(|(_, f)| f.role != FileRole::Config)
        .map(|(i, f)| {
            let id = i as FileId;
            let src = f.file.source();
            match edits.remove(&id) {
                Some(list) if !list.is_empty() => {
                    // The header first: insertions at one offset keep their order.
                    let (at, text) = header(&f.file, cal, method);
                    let first = krl::Edit {
                        range: at..at,
                        bytes: text,
                    };
                    match list.apply(src, &first) {
                        Ok(bytes) => Ok(FileOutput {
                            file: id,
                            bytes,
                            changed: true,
                        }),
                        Err(e) => Err(Box::new(Diagnostic::new(
                            Severity::Error,
                            &f.name,
                            format!("internal error, nothing written: the rewrite produced {e}; please report this program"),
                        ))),
                    }
                }
                _ => Ok(FileOutput {
                    file: id,
                    bytes: src.to_vec(),
                    changed: false,
                }),
            }
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn fill_report(
    report: &mut Report,
    ws: &Workspace,
    sim: &Simulation,
    outcomes: &[Outcome],
    robot: &RobotDescription,
    rw: &Rewrite,
    diagnostics: &[Diagnostic],
    points: bool,
) {
    use rayon::prelude::*;
    let arm = Nominal(robot);
    let compensated =
        |i: usize| outcomes[i].changed && outcomes[i].error.is_none() && sim.stops[i].compensable;
    // Command change at the TCP, µm and mdeg.
    let corr: Vec<(f64, f64)> = (0..outcomes.len())
        .into_par_iter()
        .with_min_len(4096)
        .map(|i| {
            let (stop, o) = (&sim.stops[i], &outcomes[i]);
            if !o.changed {
                return (0.0, 0.0);
            }
            // The rewrite has it for every target it wrote.
            if let Some(c) = rw.correction(i) {
                return c;
            }
            let tool: &Frame = &sim.frames[stop.tool as usize];
            rewrite::correction(
                &arm.tcp(&o.axes_deg, tool),
                &arm.tcp(&stop.nominal_axes, tool),
            )
        })
        .collect();
    if points {
        for (i, (stop, o)) in sim.stops.iter().zip(outcomes).enumerate() {
            let (bp, _) = frame::norms(&o.before);
            let (rp, rr) = frame::norms(&o.residual);
            let flipped = o.flipped();
            report.points.push(PointReport {
                file: ws.get(stop.file).name.clone(),
                line: stop.stmt.line,
                motion: stop.kind.keyword(),
                role: match stop.role {
                    Role::Target => "target",
                    Role::Aux => "aux",
                },
                correction_um: corr[i].0,
                correction_mdeg: corr[i].1,
                before_um: bp * 1e3,
                residual_um: rp * 1e3,
                residual_mdeg: rr.to_degrees() * 1e3,
                iterations: o.iterations,
                directions: o.directions.iter().map(|d| dir_char(*d)).collect(),
                flipped: axes_list(&flipped),
                resolution: match o.resolution {
                    Resolution::Consistent => "consistent".into(),
                    Resolution::Rebranched => "rebranched".into(),
                    Resolution::Held(m) => format!("held:{}", axes_list(&m).join(",")),
                    Resolution::Branch => "branch".into(),
                } + &if o.turn_held.iter().any(|&h| h) {
                    format!(" turn-kept:{}", axes_list(&o.turn_held).join(","))
                } else {
                    String::new()
                },
                compensated: compensated(i),
                error: o.error.map(|e| e.to_string()),
            });
        }
    }
    report.targets = outcomes.len();
    // Every statistic in one pass over the targets; each sum runs over the compensated
    // targets in program order, so the means come out to the same bits as summed one by one.
    #[derive(Default)]
    struct Sum {
        max: f64,
        sum: f64,
    }
    impl Sum {
        fn add(&mut self, v: f64) {
            self.max = self.max.max(v);
            self.sum += v;
        }
        fn done(&self, n: usize) -> MaxMean {
            MaxMean {
                max: self.max,
                mean: if n > 0 { self.sum / n as f64 } else { 0.0 },
            }
        }
    }
    let mut sums: [Sum; 6] = Default::default();
    let (mut n, mut rejected, mut flips, mut resolved) = (0usize, 0usize, 0usize, 0usize);
    for (i, o) in outcomes.iter().enumerate() {
        rejected += usize::from(o.error.is_some());
        flips += usize::from(o.flipped().iter().any(|&f| f));
        resolved += usize::from(matches!(
            o.resolution,
            Resolution::Held(_) | Resolution::Branch
        ));
        if !compensated(i) {
            continue;
        }
        n += 1;
        let (bp, br) = frame::norms(&o.before);
        let (rp, rr) = frame::norms(&o.residual);
        for (sum, v) in sums.iter_mut().zip([
            corr[i].0,
            corr[i].1,
            bp * 1e3,
            br.to_degrees() * 1e3,
            rp * 1e3,
            rr.to_degrees() * 1e3,
        ]) {
            sum.add(v);
        }
    }
    report.compensated = n;
    report.rejected = rejected;
    report.correction = PoseStats {
        position_um: sums[0].done(n),
        orientation_mdeg: sums[1].done(n),
    };
    report.predicted_before = PoseStats {
        position_um: sums[2].done(n),
        orientation_mdeg: sums[3].done(n),
    };
    report.predicted_after = PoseStats {
        position_um: sums[4].done(n),
        orientation_mdeg: sums[5].done(n),
    };
    report.direction_flips = flips;
    report.oscillations_resolved = resolved;
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
