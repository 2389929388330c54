//! One program end to end: simulate its motion, compensate every target (segment by segment
//! as the walk hands the stops over, see `segments`), rewrite the files, and summarise what
//! happened in a report (`report`). Input is a loaded [`Workspace`]; output the new
//! bytes of every file that belongs to the program (main `.src`/`.dat` and called modules),
//! the report and the diagnostics. Writing files is the caller's business.

use crate::diagnostic::{Diagnostic, Severity};
use crate::krl::interpret::workspace::Role as FileRole;
use crate::krl::interpret::{FileId, GivenFrame, Simulation, Workspace};
use crate::krl::{self, StmtKind};
use crate::model::Model;
use crate::motion::{Interpolation, Programmed, Role};

pub(super) use super::report::Tally;
pub use super::report::{CalibrationRef, Report};
use super::taken::Taken;
use crate::krl::rewrite::output::Chunk;
pub use crate::krl::rewrite::output::Output;
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use super::report::{MaxMean, PointReport, PoseStats, SplitReport};
use super::segments::Segments;
use crate::compensate::sequence::{ArcAngle, Interp, Keep, Target};
use crate::compensate::solve::Method;
use crate::krl::rewrite;

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
    /// How the re-check cuts a long sequence to walk it on the pool.
    pub stretching: crate::compensate::sequence::Stretching,
    /// What the user states about run time (`--assume`); the caller puts them in the
    /// workspace (`Workspace::assumptions`), where the walk reads them.
    pub assumptions: Vec<crate::krl::interpret::Assumption>,
    /// Which points are taken as taught (left as they are) and which as offline
    /// (compensated): `--points`.
    pub taken: Taken,
    /// The calibration's parameter covariance (from the campaign it was identified from):
    /// each target's predicted uncertainty goes into the report (`sigma_um`).
    pub uncertainty: Option<std::sync::Arc<crate::identify::covariance::Covariance>>,
}

impl Options {
    /// What the per-target solving takes of them.
    pub fn sequence(&self) -> crate::compensate::sequence::Options {
        crate::compensate::sequence::Options {
            method: self.method,
            parallel: self.parallel,
            stretching: self.stretching,
        }
    }
}

/// The new contents of one file of the program.
#[derive(Clone, Debug)]
pub struct FileOutput {
    pub file: FileId,
    pub bytes: Output,
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

/// The compensation targets of the stops `range` of a simulation.
/// `taught` says which stops are taken as taught: left as they are.
pub fn targets(
    sim: &Simulation,
    range: std::ops::Range<usize>,
    taught: impl Fn(&crate::krl::interpret::Stop) -> bool + Sync,
) -> Vec<Target> {
    use rayon::prelude::*;
    let from = range.start;
    sim.stops[range]
        .par_iter()
        .enumerate()
        .with_min_len(1024)
        .map(|(i, s)| Target {
            goal: s.goal,
            tool: s.tool,
            nominal_axes: s.nominal_axes,
            arrival: s.arrival,
            turns: s.turns,
            interp: match (s.interpolation, s.role) {
                (Interpolation::Joint, _) => Interp::Joint,
                // A `CA` circle written by construction (see `Writer::circular_angle` in `rewrite/target.rs`).
                (Interpolation::Circular, Role::Aux)
                    if sim.arc_ending_at(from + i + 1).is_some() =>
                {
                    Interp::CircAngleAux
                }
                (Interpolation::Circular, Role::Target | Role::End) => {
                    match sim.arc_ending_at(from + i) {
                        Some(a) => Interp::CircAngle(ArcAngle::new(a)),
                        None => Interp::CircEnd,
                    }
                }
                (Interpolation::Circular, Role::Aux) => Interp::CircAux,
                (Interpolation::Linear, _) => match s.spline {
                    Some(e) => Interp::Curve {
                        first: e.first,
                        last: e.last,
                    },
                    None => Interp::Line,
                },
            },
            compensate: s.compensable && !taught(s),
            written_base: match s.programmed {
                Programmed::Pose(_) if s.compensable && s.handle.origin.is_some() => Some(s.base),
                _ => None,
            },
            keep: Keep {
                // An axis target's S is not programmed, but a later Cartesian motion without
                // S takes the configuration of the position it starts from.
                s: true,
                t: s.keep_t,
            },
        })
        .collect()
}

/// Whether a file already carries robopost's header.
fn already_compensated(file: &krl::SourceFile) -> Option<usize> {
    header_mark(file.source())
}

/// Bytes searched as one piece by [`header_mark`]: the pieces are searched in parallel, so
/// that a long program's search does not keep one core busy while the other waits (measured
/// in BENCH.md, seventh pass).
const PIECE: usize = 8 << 20;

/// Where robopost's header mark first starts in `src` (any case).
fn header_mark(src: &[u8]) -> Option<usize> {
    use rayon::prelude::*;
    let mark = HEADER_MARK.as_bytes();
    // The mark starts with `;`: compare only there (memchr finds them; comparing a window at
    // every byte of a CAM program of tens of megabytes is what the pieces avoid). A mark
    // begun in a piece is that piece's, its bytes read on past the piece's end.
    let first_in = |k: usize| {
        let start = k * PIECE;
        let piece = &src[start..(start + PIECE).min(src.len())];
        memchr::memchr_iter(b';', piece)
            .map(|i| start + i)
            .find(|&i| {
                src[i..]
                    .get(..mark.len())
                    .is_some_and(|w| w.eq_ignore_ascii_case(mark))
            })
    };
    (0..src.len().div_ceil(PIECE))
        .into_par_iter()
        .find_map_first(first_in)
}

/// The header comment line and where it goes: after the `&ACCESS`-style directives.
fn header(file: &krl::SourceFile, cal: &Calibrated, method: Method) -> (usize, Vec<u8>) {
    let src = file.source();
    let newline: &[u8] = if memchr::memmem::find(src, b"\r\n").is_some() {
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
    // After the directives' last line ending (the controller wants `&…` lines first); a
    // UTF-8 byte order mark stays the file's first bytes.
    let at = if directives {
        src[first..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(src.len(), |p| first + p + 1)
    } else if src.starts_with(b"\xEF\xBB\xBF") {
        3
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
    if directives && at > 0 && src[at - 1] != b'\n' {
        bytes.extend_from_slice(newline);
    }
    bytes.append(&mut text);
    bytes.extend_from_slice(newline);
    (at, bytes)
}

/// Compensates the main program of `ws` (its streamed runs, if it was loaded with
/// `Workspace::load_streaming`, window by window), in four steps: refuse a file compensated
/// before; walk the motion and compensate every segment as the walk hands it over; rewrite
/// the skeleton's targets and gather what every step said into the report; apply the edits.
/// Any step that fails leaves every file as it was (`rejected`).
pub fn compensate_program(ws: &Workspace, cal: &Calibrated, options: &Options) -> ProgramResult {
    compensate_program_from(ws, cal, None, options)
}

/// [`compensate_program`] of a program taught on another robot (`--from A.json -c B.json`):
/// the targets taken as taught are where robot `from` (its calibrated model) reaches them —
/// at the axis angles the controller stored, with the gear-play history of the program's
/// nominal motion — and are compensated so that the robot of `cal` reaches those places;
/// the other targets as usual. The two robots must be of one type (the caller checks).
pub fn compensate_program_from(
    ws: &Workspace,
    cal: &Calibrated,
    from: Option<&Model>,
    options: &Options,
) -> ProgramResult {
    if from.is_some() && !ws.get(ws.main).file.streamed_runs().is_empty() {
        // The places are found on the whole walk, stop by stop.
        return compensate_program_from(&ws.whole(), cal, from, options);
    }
    let report = empty_report(ws, cal, options);
    let compensated_before = already_compensated_files(ws);
    if !compensated_before.is_empty() {
        return rejected(ws, report, compensated_before, 0);
    }
    let model = cal.model;
    let mut taking = super::taken::Taking::new(ws, options.taken);
    if let Some(from) = from {
        let places = taught_places(ws, from, options, &taking);
        taking = taking.with_places(places);
    }
    let mut seg = Segments::new(ws, model, options, &taking);
    let sim = tracing::info_span!("simulate and compensate").in_scope(|| {
        crate::krl::interpret::simulate_streaming(
            ws,
            &model.robot,
            &options.frames,
            &mut (ws, &mut seg),
        )
    });
    if sim.needs_whole_tree {
        drop((sim, seg));
        return compensate_program_from(&ws.whole(), cal, from, options);
    }
    // What loading the cell had to say (a shared data list with a line left out…).
    let main = ws.get(ws.main);
    let mut diagnostics: Vec<Diagnostic> = ws
        .notes
        .iter()
        .map(|n| Diagnostic::new(Severity::Warning, &main.name, n.clone()))
        .collect();
    diagnostics.extend(sim.diagnostics.iter().cloned());
    if sim.rejected() {
        return rejected(ws, report, diagnostics, 0);
    }
    let unfilled = report.clone();
    let (edits, report) = rewrite_and_report(ws, &sim, &mut seg, report, &mut diagnostics);
    let target_errors = report.rejected;
    drop(sim);
    if let Some(d) = seg.failed.take() {
        diagnostics.push(*d);
        return rejected(ws, unfilled, diagnostics, target_errors);
    }
    if let Some(d) = nothing_known(ws, &report) {
        diagnostics.push(d);
        return rejected(ws, unfilled, diagnostics, target_errors);
    }
    let windows = std::mem::take(&mut seg.windows);
    let applied =
        tracing::info_span!("apply").in_scope(|| apply(ws, edits, windows, cal, options.method));
    match applied {
        Ok(files) => ProgramResult {
            files,
            report,
            diagnostics,
            rejected: false,
            target_errors,
        },
        Err(d) => {
            diagnostics.push(*d);
            rejected(ws, unfilled, diagnostics, target_errors)
        }
    }
}

/// Where robot `from` reaches each target taken as taught (`None` for the others): the walk
/// on its nominal geometry, nothing compensated, each target's predicted pose error added to
/// its programmed pose.
fn taught_places(
    ws: &Workspace,
    from: &Model,
    options: &Options,
    taking: &super::taken::Taking,
) -> Vec<Option<crate::motion::frame::Frame>> {
    let sim = crate::krl::interpret::simulate(ws, &from.robot, &options.frames);
    let all = targets(&sim, 0..sim.stops.len(), |_| true);
    let outcomes = crate::compensate::sequence::compensate(
        from,
        &sim.frames,
        &all,
        [crate::model::Direction::Unknown; 6],
        &options.sequence(),
    );
    sim.stops
        .iter()
        .zip(&outcomes)
        .map(|(s, o)| {
            taking.taught(ws, s).then(|| {
                let e = &o.before;
                crate::motion::frame::Frame {
                    position: s.goal.position + nalgebra::Vector3::new(e[0], e[1], e[2]),
                    rotation: crate::motion::frame::exp_so3(&nalgebra::Vector3::new(
                        e[3], e[4], e[5],
                    )) * s.goal.rotation,
                }
            })
        })
        .collect()
}

/// The report before anything was done: the program, the calibration and the method.
fn empty_report(ws: &Workspace, cal: &Calibrated, options: &Options) -> Report {
    Report {
        program: ws.get(ws.main).name.clone(),
        calibration: CalibrationRef {
            file: cal.name.clone(),
            sha256: cal.sha256.clone(),
        },
        method: match options.method {
            Method::Iterate => "iterate",
            Method::OneStep => "one-step",
        },
        ..Report::default()
    }
}

/// An error for every file of the program that carries robopost's header: compensating it
/// again would apply the correction twice.
fn already_compensated_files(ws: &Workspace) -> Vec<Diagnostic> {
    ws.files
        .iter()
        .enumerate()
        .filter(|(_, f)| f.role != FileRole::Config)
        .filter_map(|(i, f)| {
            let at = already_compensated(&f.file)?;
            Some(
                ws.diagnostic(
                    Severity::Error,
                    i as FileId,
                    krl::Span::new(at, at + HEADER_MARK.len()),
                    "this file was already compensated by robopost: compensating it again would apply the correction twice",
                )
                .with_help("compensate the original program"),
            )
        })
        .collect()
}

/// A program no target of which can be compensated because what its motions go to is
/// declared nowhere (its `.dat` missing, or the program read from standard input without
/// it): compensating it would write it back unchanged and look like success, so it is
/// refused with the reason. (A program whose only motions wait for a position known at run
/// time, with nothing missing, is not: that is the program.)
fn nothing_known(ws: &Workspace, report: &Report) -> Option<Diagnostic> {
    if report.compensable > 0 || report.unresolved == 0 || report.needs.is_empty() {
        return None;
    }
    let main = ws.get(ws.main);
    let has_dat = main.partner.is_some();
    let why = if main.path.is_none() {
        "a program read from standard input comes without its .dat: give the file's path instead of `-`"
    } else if !has_dat {
        "it has no .dat beside it: put the .dat of the same name beside the .src, or give the cell (--config $config.dat, --cell DIR)"
    } else {
        "give what it needs (--config $config.dat, --cell DIR, --base, --tool)"
    };
    Some(
        Diagnostic::new(
            Severity::Error,
            &main.name,
            format!(
                "no target could be compensated: {} motion(s) go to positions not known before run time{}",
                report.unresolved,
                report.needs_text()
            ),
        )
        .with_help(why),
    )
}

/// The program refused: every file as it was, the report listing the errors.
fn rejected(
    ws: &Workspace,
    mut report: Report,
    diagnostics: Vec<Diagnostic>,
    target_errors: usize,
) -> ProgramResult {
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
}

/// After the walk: the skeleton's targets compensated and rewritten (the windows were
/// rewritten as they came), what every step said appended to `diagnostics`, and the report
/// filled. Returns the skeleton's edits and the report.
fn rewrite_and_report(
    ws: &Workspace,
    sim: &Simulation,
    seg: &mut Segments,
    mut report: Report,
    diagnostics: &mut Vec<Diagnostic>,
) -> (
    std::collections::BTreeMap<FileId, crate::krl::rewrite::edits::EditList>,
    Report,
) {
    let robot = &seg.model().robot;
    seg.skeleton_from(ws, sim, seg.skeleton.len());
    seg.count_target_errors();
    diagnostics.append(&mut seg.singular);
    diagnostics.append(&mut seg.target_errors);
    let placed = rewrite::Placed {
        from: 0,
        commands: &seg.skeleton_commands,
    };
    let mut rw = tracing::info_span!("rewrite")
        .in_scope(|| rewrite::rewrite_placed(ws, sim, &seg.skeleton, placed, robot, None));
    diagnostics.append(&mut seg.rewrite_diagnostics);
    diagnostics.extend(rw.diagnostics.iter().cloned());
    diagnostics.append(&mut seg.tally.large_corrections());
    if let Some(e) = rewrite::EulerLeft::merge(seg.euler.take(), rw.euler.take()) {
        diagnostics.push(e.diagnostic());
    }
    seg.tally.fill(&mut report, &rw, diagnostics.as_slice());
    // Targets the walk refused (unreachable, beyond the joint limits) are targets rejected:
    // one count of rejected targets everywhere (summary, report, `check`, exit status).
    report.targets += sim.unreachable;
    report.rejected += sim.unreachable;
    report.unresolved = sim.lost;
    report.needs = sim.needs.iter().cloned().collect();
    report.points_taken = seg.taken.fill(seg.taking_mode(), seg.taking_moves());
    report.assumptions = ws
        .assumptions
        .iter()
        .enumerate()
        .map(|(k, a)| super::report::AssumptionUse {
            assumption: a.to_string(),
            uses: sim.assumptions_used.0.get(k).copied().unwrap_or(0),
        })
        .collect();
    for a in report.assumptions.iter().filter(|a| a.uses == 0) {
        let d = Diagnostic::new(
            Severity::Warning,
            &ws.get(ws.main).name,
            format!(
                "--assume {}: never used (the walk never read it where the program leaves the value open)",
                a.assumption
            ),
        );
        report.warnings.push(format!("{}: {}", d.file, d.message));
        diagnostics.push(d);
    }
    (std::mem::take(&mut rw.edits), report)
}

/// Every output file: the edits applied, the main file's streamed windows put in place.
fn apply(
    ws: &Workspace,
    edits: std::collections::BTreeMap<FileId, crate::krl::rewrite::edits::EditList>,
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
                    Output::from_chunks(chunks)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The mark is found wherever it starts, across the pieces searched at once: the first
    /// one in the file, in any case, one begun at a piece's end and ending in the next.
    #[test]
    fn header_mark_found_across_pieces() {
        let mark = HEADER_MARK.as_bytes();
        let mut src = vec![b'x'; 2 * PIECE + 100];
        src[10] = b';';
        src[PIECE / 2] = b';';
        assert_eq!(header_mark(&src), None);
        for at in [PIECE - 3, PIECE + 7, 2 * PIECE + 100 - mark.len()] {
            let mut s = src.clone();
            s[at..at + mark.len()].copy_from_slice(&mark.to_ascii_uppercase());
            assert_eq!(header_mark(&s), Some(at));
            // A later mark does not hide the first.
            s[2 * PIECE + 90 - mark.len()..2 * PIECE + 90].copy_from_slice(mark);
            assert_eq!(header_mark(&s), Some(at.min(2 * PIECE + 90 - mark.len())));
        }
        let cut = &src[..PIECE + 1];
        assert_eq!(header_mark(cut), None);
        assert_eq!(header_mark(b""), None);
    }
}
