//! `robopost simulate`: the virtual robot on the command line — write the built-in truth,
//! run a measurement campaign, a list of poses or a KRL program on a truth file and write the
//! measurement CSV. Thin: everything is in `crate::simulate`.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::compensate::FrameArgs;
use super::Exit;
use crate::calibration::{KukaFrame, MeasurementFrame};
use crate::diagnostic::Severity;
use crate::krl::interpret::workspace::LoadError;
use crate::krl::job::files;
use crate::measure::{write_csv, Stop};
use crate::simulate::campaign::{DEFAULT_AXIS_SPEED_DEG_S, DEFAULT_DWELL_S};
use crate::simulate::{paper, poses, program, Campaign, PlannedStop, SimulateError, Truth};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

/// How the virtual robot paces the stops it visits (the `t` column of the measurement CSV).
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct Pace {
    /// Dwell per stop, seconds.
    #[arg(long, default_value_t = DEFAULT_DWELL_S)]
    dwell: f64,
    /// Axis speed between stops, degrees per second.
    #[arg(long, default_value_t = DEFAULT_AXIS_SPEED_DEG_S)]
    speed: f64,
}

impl Pace {
    /// (dwell, speed), or the usage error for impossible values.
    fn checked(self) -> Result<(f64, f64), Exit> {
        if self.dwell >= 0.0 && self.speed > 0.0 {
            Ok((self.dwell, self.speed))
        } else {
            Err(usage("--dwell must be ≥ 0 and --speed > 0"))
        }
    }
}

#[derive(clap::Subcommand, Debug)]
pub enum What {
    /// Run an indexing campaign (the paper's by default) on the virtual robot.
    Campaign {
        /// Truth file (robopost-truth/1 or robopost-physical-truth/1).
        #[arg(long)]
        truth: PathBuf,
        /// Campaign description (JSON); the paper's campaign when absent.
        #[arg(long)]
        campaign: Option<PathBuf>,
        /// Add reversal tests (short moves back and forth of every axis, shorter and longer
        /// than a gear play) to the paper's campaign: the data that measure a play's dead band.
        #[arg(long, conflicts_with = "campaign")]
        reversal: bool,
        /// Seed of the tracker noise (overrides the truth file's).
        #[arg(long)]
        seed: Option<u64>,
        /// Measurement CSV to write, `-` for stdout.
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
    },
    /// Visit a list of axis sets (CSV: test, a1..a6[, measured]) and measure them.
    Poses {
        /// Truth file (robopost-truth/1 or robopost-physical-truth/1).
        #[arg(long)]
        truth: PathBuf,
        /// The poses, in visiting order.
        poses: PathBuf,
        /// Seed of the tracker noise (overrides the truth file's).
        #[arg(long)]
        seed: Option<u64>,
        #[command(flatten)]
        pace: Pace,
        /// Measurement CSV to write, `-` for stdout.
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
    },
    /// Run a KRL program on the virtual robot: every executed target a measured stop, with the
    /// controller's axes and the directions of the simulated motion.
    Program {
        /// Truth file (robopost-truth/1 or robopost-physical-truth/1).
        #[arg(long)]
        truth: PathBuf,
        /// The program (.src; its .dat beside it is used too), or `-` for stdin.
        program: PathBuf,
        /// Seed of the tracker noise (overrides the truth file's).
        #[arg(long)]
        seed: Option<u64>,
        #[command(flatten)]
        pace: Pace,
        #[command(flatten)]
        frames: FrameArgs,
        /// Measurement CSV to write, `-` for stdout.
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
    },
    /// Write the built-in virtual KR 30 HA truth file.
    Truth {
        /// Add effects outside the paper's model (compliance of A2/A3, tilt of A1).
        #[arg(long)]
        hidden: bool,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Report positions in a tracker frame with this pose in the base frame
        /// (`X,Y,Z,A,B,C`, mm and degrees, KUKA convention).
        #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
        tracker: Option<Vec<f64>>,
        #[arg(short = 'o', long = "out")]
        out: PathBuf,
    },
}

pub fn run(args: Args) -> Exit {
    match args.what {
        What::Campaign {
            truth,
            campaign,
            reversal,
            seed,
            out,
        } => {
            let inputs = [Some(truth.as_path()), campaign.as_deref()];
            if let Err(exit) = guard_output(inputs.into_iter().flatten(), &out) {
                return exit;
            }
            let plan = match campaign {
                None if reversal => Campaign::paper_with_reversals().plan(),
                None => Campaign::paper().plan(),
                Some(path) => match read_campaign(&path) {
                    Ok(c) => c.plan(),
                    Err(exit) => return exit,
                },
            };
            match plan {
                Ok(stops) => measure_and_write(&truth, seed, &stops, &out),
                Err(e) => usage(&format!("campaign: {e}")),
            }
        }
        What::Poses {
            truth,
            poses: file,
            seed,
            pace,
            out,
        } => {
            if let Err(exit) = guard_output([truth.as_path(), file.as_path()], &out) {
                return exit;
            }
            let (dwell, speed) = match pace.checked() {
                Ok(p) => p,
                Err(exit) => return exit,
            };
            match poses::read_poses(&file, dwell, speed) {
                Ok(stops) => measure_and_write(&truth, seed, &stops, &out),
                Err(e) => {
                    eprint!("{}", e.render());
                    Exit::Usage
                }
            }
        }
        What::Program {
            truth,
            program,
            seed,
            pace,
            frames,
            out,
        } => match pace.checked() {
            Ok(pace) => run_program(&truth, &program, seed, pace, &frames, &out),
            Err(exit) => exit,
        },
        What::Truth {
            hidden,
            seed,
            tracker,
            out,
        } => {
            let mut file = paper::truth_file(hidden, seed);
            match tracker.as_deref() {
                None => {}
                Some(&[x, y, z, a, b, c]) if [x, y, z, a, b, c].iter().all(|v| v.is_finite()) => {
                    file.model.frame =
                        Some(MeasurementFrame::Tracker(KukaFrame { x, y, z, a, b, c }));
                }
                Some(_) => return usage("--tracker takes X,Y,Z,A,B,C (mm, degrees)"),
            }
            finish(write_output(&out, file.to_json().as_bytes()), &out)
        }
    }
}

fn usage(message: &str) -> Exit {
    super::usage(message)
}

/// The guard of a run that reads `inputs` and writes `out` (see [`crate::paths`]).
fn guard_output<'a>(inputs: impl IntoIterator<Item = &'a Path>, out: &Path) -> Result<(), Exit> {
    let mut guard = crate::paths::Guard::new();
    guard.read_all(inputs);
    guard.write(out).map_err(|clash| super::refuse(&clash))
}

/// The campaign file at `path`; a usage error (file:line:col and the line) when it cannot be
/// read or is not a valid campaign.
fn read_campaign(path: &Path) -> Result<Campaign, Exit> {
    let text = crate::input::read_to_string(path)
        .map_err(|e| usage(&format!("{}: {e}", path.display())))?;
    let campaign: Campaign = serde_json::from_str(&text).map_err(|e| {
        let line = text.lines().nth(e.line().saturating_sub(1)).unwrap_or("");
        usage(&format!(
            "{}:{}:{}: {e}\n{:>4} | {line}\n     | {}^",
            path.display(),
            e.line(),
            e.column(),
            e.line(),
            " ".repeat(e.column().saturating_sub(1))
        ))
    })?;
    campaign
        .validate()
        .map_err(|e| usage(&format!("{}: {e}", path.display())))?;
    Ok(campaign)
}

fn load_robot(truth: &Path, seed: Option<u64>) -> Result<Truth, Exit> {
    let robot = Truth::load(truth).map_err(|e| usage(&e.to_string()))?;
    Ok(match seed {
        Some(s) => robot.with_seed(s),
        None => robot,
    })
}

fn measure_and_write(truth: &Path, seed: Option<u64>, stops: &[PlannedStop], out: &Path) -> Exit {
    let robot = match load_robot(truth, seed) {
        Ok(r) => r,
        Err(exit) => return exit,
    };
    match robot.measure(stops) {
        Ok(measured) => write_measured(&measured, out),
        Err(e) => usage(&e.to_string()),
    }
}

/// `simulate program`: the program loaded and simulated as the main job does, its targets
/// measured on the truth. A program the controller would stop on (a located error: syntax,
/// unreachable target, unknown frame) is rejected with exit 1 and nothing written; a tool that
/// is not the measurement target is a warning (see `simulate::program`).
fn run_program(
    truth: &Path,
    path: &Path,
    seed: Option<u64>,
    (dwell, speed): (f64, f64),
    frames: &FrameArgs,
    out: &Path,
) -> Exit {
    let robot = match load_robot(truth, seed) {
        Ok(r) => r,
        Err(exit) => return exit,
    };
    let bytes = match crate::krl::program::read_bytes(path) {
        Ok(b) => b,
        Err(e) => return usage(&e.to_string()),
    };
    let stdin = path.as_os_str() == "-";
    let cell = match frames.cell() {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    let source = String::from_utf8_lossy(&bytes).into_owned();
    let mut ws = match files::load_program_in((!stdin).then_some(path), bytes, cell.as_ref(), None)
    {
        Ok(ws) => ws,
        Err(e @ LoadError::Io { .. }) => return usage(&e.to_string()),
        Err(e @ LoadError::NotKrl { .. }) => {
            eprint!("{e}");
            return Exit::Usage;
        }
        Err(e) => {
            eprintln!("{e}");
            return Exit::Rejected;
        }
    };
    let read = ws.files.iter().filter_map(|f| f.path.as_deref());
    if let Err(exit) = guard_output(read.chain([truth]), out) {
        return exit;
    }
    ws.robot = format!("the truth {}", truth.display());
    let sim = crate::krl::interpret::simulate(&ws, robot.robot(), &frames.given());
    for d in &sim.diagnostics {
        eprintln!("{}", d.render());
    }
    if sim
        .diagnostics
        .iter()
        .any(|d| d.severity == Severity::Error)
    {
        eprintln!(
            "{}: rejected (the controller would stop), nothing written",
            ws.get(ws.main).name
        );
        return Exit::Rejected;
    }
    for d in program::tool_warnings(&ws, &sim, &robot.target_mm()) {
        eprintln!("{}", d.render());
    }
    let test = if stdin {
        "stdin".to_string()
    } else {
        path.file_stem().map_or_else(
            || path.display().to_string(),
            |s| s.to_string_lossy().into_owned(),
        )
    };
    let mut visits = program::program_visits(&sim, &test, dwell, speed);
    // A campaign program (`robopost campaign`) labels its tests and names its measured stops.
    program::label_campaign(&mut visits, &source);
    match robot.run_program(&visits) {
        Ok(measured) => write_measured(&program::rows_with_turns(&visits, &measured), out),
        Err(e) => {
            let SimulateError::OutOfLimits { index, .. } = &e;
            let s = &sim.stops[*index];
            let d = ws.diagnostic(
                Severity::Error,
                s.handle.file,
                s.handle.stmt.head,
                format!("the robot would not go here: {e}"),
            );
            eprintln!("{}", d.render());
            eprintln!("{}: rejected, nothing written", ws.get(ws.main).name);
            Exit::Rejected
        }
    }
}

fn write_measured(measured: &[Stop], out: &Path) -> Exit {
    let mut bytes = Vec::new();
    if let Err(e) = write_csv(&mut bytes, measured) {
        return usage(&e.to_string());
    }
    let exit = finish(write_output(out, &bytes), out);
    if exit == Exit::Success {
        let points = measured.iter().filter(|s| s.measured_mm.is_some()).count();
        let last = measured.last().map_or(0.0, |s| s.state.time_s);
        eprintln!(
            "robopost simulate: {} stops ({points} measured, {:.0} min of robot time) → {}",
            measured.len(),
            last / 60.0,
            out.display()
        );
    }
    exit
}

fn finish(result: std::io::Result<()>, out: &Path) -> Exit {
    match result {
        Ok(()) => Exit::Success,
        Err(e) => usage(&format!("cannot write {}: {e}", out.display())),
    }
}

/// Writes `bytes` to `path` atomically (see [`crate::atomic_file`]), or to stdout for `-`.
pub(crate) fn write_output(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if path.as_os_str() == "-" {
        let mut stdout = std::io::stdout().lock();
        stdout.write_all(bytes)?;
        return stdout.flush();
    }
    crate::atomic_file::write(path, bytes)
}
