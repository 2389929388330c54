//! The library's API: the handful of calls another tool (a CAM post-processor, a Python
//! binding, a cell's own scripts) makes — read a calibration, compensate a program, simulate
//! its motion, read laser-tracker measurements, identify a calibration from them, compare and
//! diagnose. Everything here takes and returns plain data; errors are one [`Error`] whose
//! `Display` is the message the command line prints (file:line:col with the source line for a
//! program). The modules behind it are the command line's and the tests' and promise no
//! stability.

use std::path::Path;

use nalgebra::Vector3;

use crate::compensate::{self, files, program};
use crate::diagnostic::Diagnostic;
use crate::identify::pipeline;
use crate::motion::{self, workspace::LoadError, Workspace};

pub use crate::calibration::{CalError, Calibration};
pub use crate::compensate::report::{CalibrationRef, MaxMean, PointReport, PoseStats, SplitReport};
pub use crate::compensate::Report;
pub use crate::diagnose::{
    DiagnoseOptions, Diagnosis, Finding, LearnedDrivers, NoiseSource, ProgressSink, TestShare,
};
pub use crate::identify::direct::DirectResult;
pub use crate::identify::pipeline::{GrossError, Identified, TargetSource, PAPER_EFFECTS};
pub use crate::identify::refine::Fit;
pub use crate::identify::thin::Thinning;
pub use crate::identify::verdict::Verdict;
pub use crate::kinematics::RobotDescription;
pub use crate::measure::{Measurements, Stop as MeasuredStop};
pub use crate::model::{EffectName, NameError, RecordError};
pub use crate::stats::ErrorStats;

/// Why a call could not do its job.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The program could not be read, is not KRL, or has a syntax error.
    #[error("{0}")]
    Program(#[from] LoadError),
    /// The program was read but compensating it failed as a whole (an unknown frame, an
    /// endless loop, …): nothing is written. The diagnostics say where.
    #[error("{}", .0.iter().map(Diagnostic::render).collect::<Vec<_>>().join("\n"))]
    Rejected(Vec<Diagnostic>),
    /// A calibration file that cannot be read or whose numbers are out of range.
    #[error("{0}")]
    Calibration(#[from] CalError),
    /// A measurement CSV that cannot be read.
    #[error("{0}")]
    Measurements(#[from] crate::measure::MeasureError),
    /// Identification could not run on the data.
    #[error("{0}")]
    Identify(#[from] crate::identify::refine::IdentifyError),
    /// Diagnosis could not run on the data.
    #[error("{0}")]
    Diagnose(#[from] crate::diagnose::DiagnoseError),
    /// Writing an output file failed (nothing was left half-written).
    #[error("writing {path}: {source}")]
    Write {
        /// The output that could not be written.
        path: String,
        /// What the system said.
        source: std::io::Error,
    },
    /// An effect list that names no known effect (`--effects` syntax).
    #[error("{0}")]
    Effects(#[from] crate::model::NameError),
}

/// Reads a calibration file (`robopost-calibration/2` JSON, docs/calibration.md).
pub fn load_calibration(path: &Path) -> Result<Calibration, Error> {
    Ok(crate::calibration::load(path)?)
}

/// A calibration from its JSON text; `name` only names it in error messages.
pub fn parse_calibration(text: &str, name: &str) -> Result<Calibration, Error> {
    Ok(crate::calibration::parse(text, Path::new(name))?)
}

/// A compensated program: the new bytes of its `.src` and what was done to it.
#[derive(Debug)]
pub struct Compensated {
    /// The program's new bytes: the source with only the numbers that must change rewritten
    /// and a header comment naming the calibration.
    pub source: Vec<u8>,
    /// Counts, corrections and the predicted error before and after (the `--report` JSON).
    pub report: Report,
    /// Warnings and per-target errors (a rejected target is left as written), rendered as the
    /// command line prints them.
    pub messages: Vec<String>,
}

/// Compensates one program given as bytes (a `.src` without its `.dat`; `name` names it in
/// messages and in the report) with `calibration`, as `robopost IN.src -c CAL.json` does.
///
/// A target the robot cannot reach is left as written and named in
/// [`Compensated::messages`]; a program that cannot be walked at all is an
/// [`Error::Rejected`].
pub fn compensate_source(
    name: &str,
    source: &[u8],
    calibration: &Calibration,
) -> Result<Compensated, Error> {
    let ws = Workspace::load_streaming((source.to_vec(), None, name), None, None, None)?;
    let (ws, result) = compensated(ws, calibration, name, source)?;
    let main = result
        .files
        .iter()
        .find(|f| f.file == ws.main)
        .expect("the main file is an output");
    Ok(Compensated {
        source: main.bytes.pieces().concat(),
        messages: result.diagnostics.iter().map(Diagnostic::render).collect(),
        report: result.report,
    })
}

/// The main job on a loaded program: its result, or the rejection of the whole program.
fn compensated(
    mut ws: Workspace,
    calibration: &Calibration,
    label: &str,
    bytes: &[u8],
) -> Result<(Workspace, program::ProgramResult), Error> {
    ws.robot = calibration.robot_name.clone();
    let calibrated = program::Calibrated::new(calibration.model_ref(), label, bytes);
    let result = compensate::compensate_program(
        &ws,
        &calibrated,
        &program::Options {
            parallel: true,
            ..program::Options::default()
        },
    );
    if result.rejected {
        return Err(Error::Rejected(result.diagnostics));
    }
    Ok((ws, result))
}

/// Compensates the program at `input` (with the `.dat` beside it) and writes it to `output`
/// (and its `.dat` beside that), every file atomically: on any error nothing is written.
pub fn compensate_file(
    input: &Path,
    calibration: &Calibration,
    output: &Path,
) -> Result<Report, Error> {
    let bytes = files::read_program(input).map_err(|source| LoadError::Io {
        name: input.display().to_string(),
        source,
    })?;
    let ws = files::load_program(Some(input), &bytes, None)?;
    let (ws, result) = compensated(ws, calibration, &input.display().to_string(), &bytes)?;
    let outputs = files::outputs(&ws, &result.files, output);
    files::write_atomic_pieces(&outputs).map_err(|source| Error::Write {
        path: output.display().to_string(),
        source,
    })?;
    Ok(result.report)
}

/// One stop of a simulated program: where the controller takes the robot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgramStop {
    /// Line of the motion statement (1-based).
    pub line: usize,
    /// The nominal axis angles A1..A6 at the stop, degrees.
    pub axes_deg: [f64; 6],
    /// The programmed TCP position in the robot's base frame, mm.
    pub tcp_mm: [f64; 3],
}

/// A simulated program: its stops and what the walk had to say.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulated {
    /// The stops in execution order (a target the robot cannot reach has none).
    pub stops: Vec<ProgramStop>,
    /// Targets the robot cannot reach (each also in `messages`).
    pub unreachable: usize,
    /// Warnings and errors, rendered as the command line prints them.
    pub messages: Vec<String>,
}

/// Walks a program (bytes of a `.src`) as the controller would on `robot`: loops unrolled,
/// PTP/LIN/CIRC/spline targets resolved through `$BASE`/`$TOOL`.
pub fn simulate_source(
    name: &str,
    source: &[u8],
    robot: &RobotDescription,
) -> Result<Simulated, Error> {
    let ws = Workspace::load_streaming((source.to_vec(), None, name), None, None, None)?;
    let sim = motion::simulate(&ws, robot, &[]);
    if sim.rejected() {
        return Err(Error::Rejected(sim.diagnostics));
    }
    Ok(Simulated {
        stops: sim
            .stops
            .iter()
            .map(|s| ProgramStop {
                line: s.stmt.line as usize,
                axes_deg: s.nominal_axes.into(),
                tcp_mm: s.goal.position.into(),
            })
            .collect(),
        unreachable: sim.unreachable,
        messages: sim.diagnostics.iter().map(Diagnostic::render).collect(),
    })
}

/// Reads a measurement CSV (docs/measurements.md): command angles, measured positions, time.
pub fn read_measurements(path: &Path) -> Result<Measurements, Error> {
    Ok(crate::measure::read_csv(path)?)
}

/// Identifies a calibration of `effects` (contract names, e.g. [`PAPER_EFFECTS`]) from
/// measurement files, unaided: the target vector from the data, gross errors screened out.
pub fn identify(files: &[Measurements], effects: &str) -> Result<Identified, Error> {
    let names = crate::model::expand_list(effects)?;
    let mut stops = Vec::new();
    let mut file_of = Vec::new();
    for (k, f) in files.iter().enumerate() {
        file_of.extend(std::iter::repeat(k).take(f.stops.len()));
        stops.extend(f.stops.iter().cloned());
    }
    let request = pipeline::Request {
        effects: Some(pipeline::Effects::Exactly(names)),
        sources: files.iter().map(|f| f.source.clone()).collect(),
        file_of,
        ..pipeline::Request::default()
    };
    Ok(pipeline::identify(&stops, &request)?)
}

/// The measured error, the model's predicted error and their difference at every measured
/// point, as statistics of the residual (measured − predicted, µm; CONTRACTS' `compare`).
pub fn compare(calibration: &Calibration, files: &[Measurements]) -> ErrorStats {
    let residuals: Vec<Vector3<f64>> = crate::compare::compare(calibration, files)
        .iter()
        .map(|r| r.residual())
        .collect();
    crate::stats::error_stats(&residuals)
}

/// Where the model fails on `files` and which physical effect it most likely misses.
pub fn diagnose(
    calibration: &Calibration,
    files: &[Measurements],
    options: &DiagnoseOptions,
) -> Result<Diagnosis, Error> {
    Ok(crate::diagnose::diagnose(calibration, files, options)?)
}

/// The `robopost` command itself (docs/cli.md): `args` as the process received them, the
/// program's name first; prints as the command does and returns its exit status (0 done,
/// 1 some input rejected, 2 usage error or unreadable input, nothing written). For a wrapper
/// that embeds the command; the `robopost` binary is this call.
pub fn run_command_line(args: Vec<String>) -> i32 {
    crate::cli::main(args)
}
