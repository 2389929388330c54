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
use super::segments::Segments;
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
    pub bytes: Output,
    pub changed: bool,
}

/// A file's new bytes in pieces: rewritten stretches, and stretches of the source left as
/// they were (shared with the loaded file, not copied: a program of a million motions is
/// written without a second copy of it in memory).
#[derive(Clone, Debug, Default)]
pub struct Output {
    chunks: Vec<Chunk>,
}

#[derive(Clone, Debug)]
enum Chunk {
    Owned(Vec<u8>),
    Shared(std::sync::Arc<Vec<u8>>, std::ops::Range<usize>),
}

impl Output {
    /// The pieces in order.
    pub fn pieces(&self) -> Vec<&[u8]> {
        self.chunks
            .iter()
            .map(|c| match c {
                Chunk::Owned(b) => &b[..],
                Chunk::Shared(src, r) => &src[r.clone()],
            })
            .filter(|p| !p.is_empty())
            .collect()
    }

    /// The bytes in one buffer.
    pub fn to_vec(&self) -> Vec<u8> {
        self.pieces().concat()
    }

    pub fn len(&self) -> usize {
        self.pieces().iter().map(|p| p.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn source(file: &krl::SourceFile) -> Output {
        let src = file.shared_source();
        let len = src.len();
        Output {
            chunks: vec![Chunk::Shared(src, 0..len)],
        }
    }
}

impl From<Vec<u8>> for Output {
    fn from(bytes: Vec<u8>) -> Output {
        Output {
            chunks: vec![Chunk::Owned(bytes)],
        }
    }
}

impl PartialEq<&[u8]> for Output {
    fn eq(&self, other: &&[u8]) -> bool {
        self == *other
    }
}

impl PartialEq<[u8]> for Output {
    fn eq(&self, other: &[u8]) -> bool {
        let mut at = 0;
        for p in self.pieces() {
            if other.get(at..at + p.len()) != Some(p) {
                return false;
            }
            at += p.len();
        }
        at == other.len()
    }
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

/// The compensation targets of the stops `range` of a simulation.
pub fn targets(ws: &Workspace, sim: &Simulation, range: std::ops::Range<usize>) -> Vec<Target> {
    use rayon::prelude::*;
    sim.stops[range]
        .par_iter()
        .with_min_len(1024)
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

/// Compensates the main program of `ws` (its streamed runs, if it was loaded with
/// `Workspace::load_streaming`, window by window).
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
                bytes: Output::source(&f.file),
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
    let mut seg = Segments::new(ws, model, options);
    let sim = motion::simulate_streaming(ws, &model.robot, &options.frames, &mut (ws, &mut seg));
    diagnostics.extend(sim.diagnostics.iter().cloned());
    if sim.rejected() {
        return rejected(report, diagnostics, 0);
    }
    seg.skeleton_from(ws, &sim, seg.skeleton.len());
    lap("simulate and compensate");
    if std::env::var_os("ROBOPOST_TIMING").is_some() {
        let (state, motion) = sequence::resolved_counts();
        let ms = |a: &std::sync::atomic::AtomicU64| {
            a.load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-6
        };
        use crate::motion::simulate::stream_timing as st;
        eprintln!(
            "  windows: parse {:.0} ms, walk {:.0} ms, compensate+rewrite {:.0} ms",
            ms(&st::PARSE_NS),
            ms(&st::WALK_NS),
            ms(&st::SINK_NS)
        );
        eprintln!(
            "  re-solved: {state} for the compensated state, {motion} for the compensated motion"
        );
    }
    let target_errors = sim.unreachable + seg.target_errors.len();
    diagnostics.append(&mut seg.singular);
    diagnostics.append(&mut seg.target_errors);
    let mut rw = rewrite::rewrite(ws, &sim, &seg.skeleton, &model.robot, None);
    lap("rewrite");
    diagnostics.append(&mut seg.rewrite_diagnostics);
    diagnostics.extend(rw.diagnostics.iter().cloned());
    let unfilled = report.clone();
    seg.tally.fill(&mut report, &rw, &diagnostics);
    drop(sim);
    if let Some(d) = seg.failed.take() {
        diagnostics.push(*d);
        return rejected(unfilled, diagnostics, target_errors);
    }
    let windows = std::mem::take(&mut seg.windows);
    let files = match apply(
        ws,
        std::mem::take(&mut rw.edits),
        windows,
        cal,
        options.method,
    ) {
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

/// Every output file: the edits applied, the main file's streamed windows put in place.
fn apply(
    ws: &Workspace,
    edits: std::collections::BTreeMap<FileId, super::edits::EditList>,
    windows: Vec<(krl::Span, Vec<u8>)>,
    cal: &Calibrated,
    method: Method,
) -> Result<Vec<FileOutput>, Box<Diagnostic>> {
    let mut edits = edits;
    let mut windows = Some(windows).filter(|w| !w.is_empty());
    ws.files
        .iter()
        .enumerate()
        .filter(|(_, f)| f.role != FileRole::Config)
        .map(|(i, f)| {
            let id = i as FileId;
            let list = edits.remove(&id).unwrap_or_default();
            let windows = if id == ws.main { windows.take() } else { None };
            if list.is_empty() && windows.is_none() {
                return Ok(FileOutput {
                    file: id,
                    bytes: Output::source(&f.file),
                    changed: false,
                });
            }
            // The header first: insertions at one offset keep their order.
            let (at, text) = header(&f.file, cal, method);
            let first = krl::Edit {
                range: at..at,
                bytes: text,
            };
            let failed = |e: krl::EditError| {
                Box::new(Diagnostic::new(
                    Severity::Error,
                    &f.name,
                    format!("internal error, nothing written: the rewrite produced {e}; please report this program"),
                ))
            };
            let src = f.file.source();
            let bytes = match windows {
                None => Output::from(list.apply(src, &first).map_err(failed)?),
                Some(windows) => {
                    // The skeleton's stretches between the runs with its edits, the windows
                    // that changed, the others shared with the source.
                    let shared = f.file.shared_source();
                    let mut chunks = Vec::new();
                    let mut at = 0;
                    let mut changed = windows.into_iter().peekable();
                    for run in f.file.streamed_runs() {
                        let r = run.range.range();
                        chunks.push(Chunk::Owned(
                            list.apply_in(src, at..r.start, Some(&first)).map_err(failed)?,
                        ));
                        for (w, _) in run.windows() {
                            match changed.next_if(|(c, _)| *c == w) {
                                Some((_, new)) => chunks.push(Chunk::Owned(new)),
                                None => chunks.push(Chunk::Shared(shared.clone(), w.range())),
                            }
                        }
                        at = r.end;
                    }
                    chunks.push(Chunk::Owned(
                        list.apply_in(src, at..src.len(), Some(&first)).map_err(failed)?,
                    ));
                    Output { chunks }
                }
            };
            Ok(FileOutput {
                file: id,
                bytes,
                changed: true,
            })
        })
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
    /// Correction, predicted error before and after: position and orientation each.
    figures: [Running; 6],
    direction_flips: usize,
    oscillations_resolved: usize,
    points: Vec<PointReport>,
}

impl Tally {
    /// The targets `sim.stops[first..]` with their `outcomes`; `rw` the rewrite of `sim`
    /// when it has been made (it holds the command change of every target it wrote).
    #[allow(clippy::too_many_arguments)]
    pub fn add(
        &mut self,
        ws: &Workspace,
        sim: &Simulation,
        first: usize,
        outcomes: &[Outcome],
        robot: &RobotDescription,
        rw: Option<&Rewrite>,
        points: bool,
    ) {
        use rayon::prelude::*;
        let stops = &sim.stops[first..first + outcomes.len()];
        let arm = Nominal(robot);
        let compensated =
            |i: usize| outcomes[i].changed && outcomes[i].error.is_none() && stops[i].compensable;
        // Command change at the TCP, µm and mdeg.
        let corr: Vec<(f64, f64)> = (0..outcomes.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|i| {
                let (stop, o) = (&stops[i], &outcomes[i]);
                if !o.changed {
                    return (0.0, 0.0);
                }
                if let Some(c) = rw.and_then(|rw| rw.correction(first + i)) {
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
            for (i, (stop, o)) in stops.iter().zip(outcomes).enumerate() {
                self.points
                    .push(point_report(ws, stop, o, corr[i], compensated(i)));
            }
        }
        self.targets += outcomes.len();
        self.rejected += outcomes.iter().filter(|o| o.error.is_some()).count();
        for i in (0..outcomes.len()).filter(|&i| compensated(i)) {
            self.compensated += 1;
            let o = &outcomes[i];
            let (bp, br) = frame::norms(&o.before);
            let (rp, rr) = frame::norms(&o.residual);
            let values = [
                corr[i].0,
                corr[i].1,
                bp * 1e3,
                br.to_degrees() * 1e3,
                rp * 1e3,
                rr.to_degrees() * 1e3,
            ];
            for (f, v) in self.figures.iter_mut().zip(values) {
                f.add(v);
            }
        }
        self.direction_flips += outcomes
            .iter()
            .filter(|o| o.flipped().iter().any(|&f| f))
            .count();
        self.oscillations_resolved += outcomes
            .iter()
            .filter(|o| matches!(o.resolution, Resolution::Held(_) | Resolution::Branch))
            .count();
    }

    /// The report with the figures, the split points and the diagnostics.
    pub fn fill(&mut self, report: &mut Report, rw: &Rewrite, diagnostics: &[Diagnostic]) {
        let f = &self.figures;
        report.targets = self.targets;
        report.compensated = self.compensated;
        report.rejected = self.rejected;
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
        report.direction_flips = self.direction_flips;
        report.oscillations_resolved = self.oscillations_resolved;
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
    stop: &motion::Stop,
    o: &Outcome,
    (correction_um, correction_mdeg): (f64, f64),
    compensated: bool,
) -> PointReport {
    let (bp, _) = frame::norms(&o.before);
    let (rp, rr) = frame::norms(&o.residual);
    let flipped = o.flipped();
    PointReport {
        file: ws.get(stop.file).name.clone(),
        line: stop.stmt.line,
        motion: stop.kind.keyword(),
        role: match stop.role {
            Role::Target => "target",
            Role::Aux => "aux",
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
            Resolution::Rebranched => "rebranched".into(),
            Resolution::Held(m) => format!("held:{}", axes_list(&m).join(",")),
            Resolution::Branch => "branch".into(),
        } + &if o.turn_held.iter().any(|&h| h) {
            format!(" turn-kept:{}", axes_list(&o.turn_held).join(","))
        } else {
            String::new()
        },
        compensated,
        error: o.error.map(|e| e.to_string()),
    }
}
