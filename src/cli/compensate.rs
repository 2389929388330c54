//! `robopost IN.src -c CAL.json -o OUT.src`: compensate one program (its `.dat` and called
//! modules beside it), `-` for standard input/output.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use super::Exit;
use crate::calibration;
use crate::compensate::{self, files, program, Calibrated, Method};
use crate::diagnostic::Severity;
use crate::motion::GivenFrame;

/// How a program's frames are found: shared by the main job, `batch`, `check` and
/// `simulate program` (which runs a program as the main job reads it).
#[derive(clap::Args, Debug, Clone)]
pub struct FrameArgs {
    /// The robot's `$config.dat` (BASE_DATA, TOOL_DATA).
    #[arg(long = "config", value_name = "CONFIG.dat")]
    pub config: Option<PathBuf>,
    /// A base frame: `N=X,Y,Z,A,B,C` for `BASE_DATA[N]` (repeatable).
    #[arg(long = "base", value_name = "N=X,Y,Z,A,B,C", value_parser = parse_frame_arg, allow_hyphen_values = true)]
    pub base: Vec<(i64, [f64; 6])>,
    /// A tool frame: `N=X,Y,Z,A,B,C` for `TOOL_DATA[N]` (repeatable).
    #[arg(long = "tool", value_name = "N=X,Y,Z,A,B,C", value_parser = parse_frame_arg, allow_hyphen_values = true)]
    pub tool: Vec<(i64, [f64; 6])>,
}

impl FrameArgs {
    /// The frames given on the command line.
    pub fn given(&self) -> Vec<GivenFrame> {
        let mut frames = Vec::new();
        for (n, v) in &self.base {
            frames.push(GivenFrame {
                base: true,
                index: *n,
                xyzabc: *v,
            });
        }
        for (n, v) in &self.tool {
            frames.push(GivenFrame {
                base: false,
                index: *n,
                xyzabc: *v,
            });
        }
        frames
    }
}

/// Options shared by the main job, `batch` and `check`.
#[derive(clap::Args, Debug, Clone)]
pub struct ProgramArgs {
    #[command(flatten)]
    pub frames: FrameArgs,
    /// Apply the paper's equation (3) once instead of iterating to 0.1 µm (for comparison).
    #[arg(long = "one-step")]
    pub one_step: bool,
}

/// `args.program.config` etc. read through to the frame options.
impl std::ops::Deref for ProgramArgs {
    type Target = FrameArgs;
    fn deref(&self) -> &FrameArgs {
        &self.frames
    }
}

impl ProgramArgs {
    pub fn options(&self, parallel: bool, points: bool) -> program::Options {
        let frames = self.frames.given();
        program::Options {
            method: if self.one_step {
                Method::OneStep
            } else {
                Method::Iterate
            },
            parallel,
            frames,
            points,
        }
    }
}

/// `N=X,Y,Z,A,B,C`.
pub fn parse_frame_arg(text: &str) -> Result<(i64, [f64; 6]), String> {
    let (n, rest) = text
        .split_once('=')
        .ok_or_else(|| format!("`{text}`: expected N=X,Y,Z,A,B,C"))?;
    let n: i64 = n
        .trim()
        .parse()
        .map_err(|_| format!("`{n}` is not a frame number"))?;
    let values: Vec<f64> = rest
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("`{rest}`: expected six numbers X,Y,Z,A,B,C"))?;
    let values: [f64; 6] = values
        .try_into()
        .map_err(|_| format!("`{rest}`: expected six numbers X,Y,Z,A,B,C"))?;
    if values.iter().any(|v| !v.is_finite()) {
        return Err(format!("`{rest}`: numbers must be finite"));
    }
    Ok((n, values))
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input program (.src; its .dat beside it is used too), or `-` for stdin.
    pub input: PathBuf,
    /// Calibration file.
    #[arg(short = 'c', long = "cal")]
    pub cal: PathBuf,
    /// Output program, or `-` for stdout (its .dat and called modules go beside it).
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Write a JSON report: per-target corrections, direction flips, warnings.
    #[arg(long = "report", value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub program: ProgramArgs,
}

/// Loads a calibration and names it for the output header.
/// The calibration file and its bytes (for the header's checksum); an unreadable or invalid
/// file is reported here and is a usage error (exit 2), before any program is touched.
pub fn load_calibration(path: &Path) -> Result<(calibration::Calibration, Vec<u8>), Exit> {
    let loaded = std::fs::read(path)
        .map_err(|e| format!("{}: {e}", path.display()))
        .and_then(|bytes| {
            let cal = calibration::parse(&String::from_utf8_lossy(&bytes), path)
                .map_err(|e| e.to_string())?;
            Ok((cal, bytes))
        });
    loaded.map_err(|e| {
        eprintln!("error: {e}");
        Exit::Usage
    })
}

pub fn calibrated<'a>(
    cal: &'a calibration::Calibration,
    path: &Path,
    bytes: &[u8],
) -> Calibrated<'a> {
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    Calibrated::new(cal.model_ref(), &name, bytes)
}

fn is_dash(p: &Path) -> bool {
    p.as_os_str() == "-"
}

pub fn run(args: Args) -> Exit {
    let (cal, cal_bytes) = match load_calibration(&args.cal) {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    let stdin = is_dash(&args.input);
    let bytes = if stdin {
        let mut b = Vec::new();
        if let Err(e) = std::io::stdin().read_to_end(&mut b) {
            eprintln!("error: <stdin>: {e}");
            return Exit::Usage;
        }
        b
    } else {
        match files::read_program(&args.input) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("error: {}: {e}", args.input.display());
                return Exit::Usage;
            }
        }
    };
    let input = (!stdin).then_some(args.input.as_path());
    program::lap_start();
    let stream = Some(crate::krl::StreamOptions::default());
    let ws =
        match files::load_program_streaming(input, bytes, args.program.config.as_deref(), stream) {
            Ok(ws) => ws,
            Err(e @ crate::motion::workspace::LoadError::Io { .. }) => {
                eprintln!("error: {e}");
                return Exit::Usage;
            }
            Err(e @ crate::motion::workspace::LoadError::NotKrl { .. }) => {
                eprint!("{e}");
                return Exit::Usage;
            }
            Err(e) => {
                eprintln!("{e}");
                return Exit::Rejected;
            }
        };
    program::lap("load");
    if std::env::var_os("ROBOPOST_TIMING").is_some() {
        let runs = ws.get(ws.main).file.streamed_runs();
        let windows: usize = runs.iter().map(|r| r.windows().len()).sum();
        eprintln!("  streamed: {} runs in {windows} windows", runs.len());
    }
    let to_stdout = is_dash(&args.out);
    let mut guard = crate::paths::Guard::new();
    guard
        .read(&args.cal)
        .read_all(ws.files.iter().filter_map(|f| f.path.as_deref()));
    let outputs = if to_stdout {
        Vec::new()
    } else {
        files::output_paths(&ws, &args.out)
    };
    let written = outputs.iter().map(|(_, p)| p.as_path());
    for path in written.chain(args.report.as_deref()) {
        if let Err(clash) = guard.write(path) {
            return super::refuse(&clash);
        }
    }
    if !to_stdout {
        if let Err(e) = files::no_stale_dat(&ws, &args.out) {
            eprintln!("error: {e}");
            return Exit::Usage;
        }
    }
    let calibrated = calibrated(&cal, &args.cal, &cal_bytes);
    let result = compensate::compensate_program(
        &ws,
        &calibrated,
        &args.program.options(true, args.report.is_some()),
    );
    for d in &result.diagnostics {
        eprintln!("{}", d.render());
    }
    if result.rejected {
        eprintln!("{}: rejected, nothing written", ws.get(ws.main).name);
        return Exit::Rejected;
    }
    if to_stdout {
        let main = result
            .files
            .iter()
            .find(|f| f.file == ws.main)
            .expect("the main file is an output");
        if result.files.iter().any(|f| f.file != ws.main && f.changed) {
            eprintln!("warning: the .dat or called modules changed too; they are written only with a file output (-o FILE.src)");
        }
        let mut out = std::io::stdout().lock();
        let written = main
            .bytes
            .pieces()
            .into_iter()
            .try_for_each(|p| out.write_all(p))
            .and_then(|_| out.flush());
        if let Err(e) = written {
            eprintln!("error: <stdout>: {e}");
            return Exit::Usage;
        }
    } else {
        program::lap("compensated");
        let outputs = files::outputs(&ws, &result.files, &args.out);
        if let Err(e) = files::write_atomic_pieces(&outputs) {
            eprintln!("error: writing {}: {e}", args.out.display());
            return Exit::Usage;
        }
    }
    program::lap("written");
    if let Some(path) = &args.report {
        let json = serde_json::to_string_pretty(&result.report).unwrap_or_default() + "\n";
        if let Err(e) = files::write_atomic(&[(path.clone(), json.as_bytes())]) {
            eprintln!("error: writing {}: {e}", path.display());
            return Exit::Usage;
        }
    }
    summary(&result.report);
    let status = exit_status(&result);
    // Freeing millions of syntax-tree nodes one by one takes longer than the process exit.
    std::mem::forget(result);
    std::mem::forget(ws);
    status
}

fn exit_status(result: &compensate::ProgramResult) -> Exit {
    let errors = result
        .diagnostics
        .iter()
        .any(|d| d.severity == Severity::Error);
    if result.target_errors > 0 || errors {
        Exit::Rejected
    } else {
        Exit::Success
    }
}

/// One line on standard error.
pub fn summary(r: &compensate::Report) {
    eprintln!(
        "{}: {} of {} targets compensated (correction max {:.1} µm / {:.2} mdeg, mean {:.1} µm), {} rejected, {} direction flips, {} held axes kept, {} reversals inside the play",
        r.program,
        r.compensated,
        r.targets,
        r.correction.position_um.max,
        r.correction.orientation_mdeg.max,
        r.correction.position_um.mean,
        r.rejected,
        r.direction_flips,
        r.held_axes,
        r.reversals_inside_play
    );
}

/// `check -c`: each program simulated and compensated in memory; prints a summary line per
/// program and every error and warning; writes nothing.
pub fn check_programs(programs: &[PathBuf], cal_path: &Path, args: &ProgramArgs) -> Exit {
    let (cal, cal_bytes) = match load_calibration(cal_path) {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    let calibrated = calibrated(&cal, cal_path, &cal_bytes);
    let mut exit = Exit::Success;
    for path in programs {
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("dat"))
        {
            continue;
        }
        let bytes = match crate::krl::program::read_bytes(path) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("error: {e}");
                exit = Exit::Usage;
                continue;
            }
        };
        let input = (!is_dash(path)).then_some(path.as_path());
        let ws = match files::load_program(input, &bytes, args.config.as_deref()) {
            Ok(ws) => ws,
            Err(e) => {
                eprintln!("{e}");
                exit = exit.max(Exit::Rejected);
                continue;
            }
        };
        let result = compensate::compensate_program(&ws, &calibrated, &args.options(true, false));
        for d in &result.diagnostics {
            eprintln!("{}", d.render());
        }
        let r = &result.report;
        if result.rejected {
            println!("{}: rejected", path.display());
            exit = exit.max(Exit::Rejected);
            continue;
        }
        println!(
            "{}: {} targets simulated, {} compensable, {} rejected (unreachable, out of limits or configuration), predicted error max {:.1} µm",
            path.display(),
            r.targets,
            r.compensated,
            result.target_errors,
            r.predicted_before.position_um.max
        );
        if result.target_errors > 0 {
            exit = exit.max(Exit::Rejected);
        }
    }
    exit
}
