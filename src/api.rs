//! The library's API: the handful of calls another tool (a CAM post-processor, a Python
//! binding, a cell's own scripts) makes — read a calibration, compensate a program, simulate
//! its motion, read laser-tracker measurements, identify a calibration from them, compare and
//! diagnose. Everything here takes and returns plain data; errors are one [`Error`] whose
//! `Display` is the message the command line prints (file:line:col with the source line for a
//! program). The modules behind it are the command line's and the tests' and promise no
//! stability.

use std::path::Path;

use nalgebra::Vector3;

use crate::identify::pipeline;
use crate::krl::interpret::Workspace;
use crate::krl::job::{files, program};

pub use crate::calibration::{CalError, Calibration, ExcludedPoint, MeasurementFrame, Provenance};
pub use crate::diagnose::{
    DiagnoseOptions, Diagnosis, Finding, LearnedDrivers, NoiseSource, ProgressSink, TestShare,
};
pub use crate::identify::direct::DirectResult;
pub use crate::identify::pipeline::{GrossError, Identified, TargetSource, PAPER_EFFECTS};
pub use crate::identify::refine::{Fit, Status as ParameterStatus};
pub use crate::identify::thin::Thinning;
pub use crate::identify::verdict::Verdict;
pub use crate::kinematics::{Payload, RobotDescription};
pub use crate::krl::job::report::{CalibrationRef, MaxMean, PointReport, PoseStats, SplitReport};
pub use crate::krl::job::Report;
pub use crate::krl::job::Taken;
pub use crate::measure::tracker::Tracker;
pub use crate::measure::{Columns as MeasurementColumns, Measurements, Stop as MeasuredStop};
pub use crate::model::{AxisHistory, AxisState, Direction, EffectName, NameError, RecordError};
pub use crate::stats::ErrorStats;

// Plain data reachable from the types above: nameable, so that a caller can write them down.
pub use crate::atomic_unit::WriteError;
pub use crate::diagnose::blocks::Scheme as HeldOutScheme;
pub use crate::diagnose::crossval::Score as HeldOutScore;
pub use crate::diagnose::learn::{Curve as LearnedCurve, Screened as LearnedScreened};
pub use crate::diagnose::validate::ValidationGain;
pub use crate::diagnose::DiagnoseError;
pub use crate::diagnose::NoiseFloor;
pub use crate::diagnostic::{Diagnostic, Severity};
pub use crate::identify::circle::Circle3;
pub use crate::identify::direct::{AxisLine, DeviationSample};
pub use crate::identify::lsq::LsqError;
pub use crate::identify::refine::{IdentifyError, Warning as IdentifyWarning};
pub use crate::identify::screen::Structure;
pub use crate::identify::setup::SetupError;
pub use crate::identify::verdict::TestResidual;
pub use crate::kinematics::frame::Frame;
pub use crate::kinematics::pose::Pose;
pub use crate::kinematics::robot::Gravity;
pub use crate::kinematics::{AxisAngles, Links};
pub use crate::krl::interpret::workspace::LoadError;
pub use crate::krl::job::report::AssumptionUse;
pub use crate::krl::job::taken::{PointsTaken, Reason as TakenReason};
pub use crate::measure::MeasureError;
pub use crate::model::effects::{learned::SpecError, EffectError};
pub use crate::model::table::GridError;

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
    /// An option out of its range or spelled wrong (a tracker preset, a table pitch).
    #[error("{0}")]
    Option(String),
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
    /// The new bytes of the program's `.dat`, when [`CellContext::dat`] gave one (written
    /// back whether or not compensation changed it).
    pub dat: Option<Vec<u8>>,
    /// Counts, corrections and the predicted error before and after (the `--report` JSON).
    pub report: Report,
    /// Warnings and per-target errors (a rejected target is left as written), rendered as the
    /// command line prints them.
    pub messages: Vec<String>,
}

/// A frame of the robot's cell given by number, as `--base N=X,Y,Z,A,B,C` and
/// `--tool N=…` give it: `BASE_DATA[index]` or `TOOL_DATA[index]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellFrame {
    /// `true` for `BASE_DATA[index]`, `false` for `TOOL_DATA[index]`.
    pub base: bool,
    /// The frame's number in its array.
    pub index: i64,
    /// X, Y, Z (mm) and A, B, C (degrees, KUKA's Z-Y-X angles).
    pub xyzabc: [f64; 6],
}

/// What a program is compensated with besides its own text and the calibration: the files
/// and options of the command line's `robopost IN.src -c CAL.json -o OUT.src`, held in
/// memory. The default is a program alone (no `.dat`, no cell), every point as its files
/// say.
#[derive(Clone, Debug, Default)]
pub struct CellContext {
    /// The program's own data list (the `.dat` beside its `.src`), bytes.
    pub dat: Option<Vec<u8>>,
    /// The robot's `$config.dat` (`BASE_DATA`, `TOOL_DATA`, …), bytes (`--config`).
    pub config: Option<Vec<u8>>,
    /// Frames given by number (`--base`, `--tool`).
    pub frames: Vec<CellFrame>,
    /// Which points are compensated (`--points`).
    pub points: Taken,
    /// The calibration's file, which the compensated program's header names, as the command
    /// line writes it. `None`: the header names the calibration's robot and the SHA-256 of the
    /// calibration as robopost writes it.
    pub calibration_file: Option<CalibrationSource>,
}

/// The file a calibration was read from, as a compensated program's header names it: its
/// name (the command line writes the file name without its directory) and its bytes, of
/// which the header carries the SHA-256.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CalibrationSource {
    /// The file's name, e.g. `kr30ha-example.json`.
    pub name: String,
    /// The file's bytes.
    pub bytes: Vec<u8>,
}

/// Compensates one program given as bytes (a `.src` without its `.dat`; `name` names it in
/// messages and in the report) with `calibration`, as `robopost IN.src -c CAL.json` does:
/// [`compensate_in_cell`] with the default [`CellContext`].
///
/// A target the robot cannot reach is left as written and named in
/// [`Compensated::messages`]; a program that cannot be walked at all is an
/// [`Error::Rejected`].
pub fn compensate_source(
    name: &str,
    source: &[u8],
    calibration: &Calibration,
) -> Result<Compensated, Error> {
    compensate_in_cell(name, source, calibration, &CellContext::default())
}

/// Compensates one program given as bytes in the cell `context` describes (its `.dat`, the
/// robot's `$config.dat`, frames, the points' origin): the same bytes as the command line
/// writes for the same files and options. `name` names the program in messages and in the
/// report.
pub fn compensate_in_cell(
    name: &str,
    source: &[u8],
    calibration: &Calibration,
    context: &CellContext,
) -> Result<Compensated, Error> {
    let dat_name = format!("{}.dat", name.strip_suffix(".src").unwrap_or(name));
    let dat = context
        .dat
        .as_deref()
        .map(|d| (d, Path::new(&dat_name), dat_name.as_str()));
    let stream = Some(crate::krl::StreamOptions::default());
    let mut ws = Workspace::load_streaming((source.to_vec(), None, name), dat, None, stream)?;
    if let Some(config) = &context.config {
        ws.push_shared_data(config, None, "$config.dat");
    }
    let (header_name, header_bytes) = match &context.calibration_file {
        Some(file) => (file.name.clone(), file.bytes.clone()),
        None => (
            calibration.robot_name.clone(),
            calibration
                .to_json(Path::new(&calibration.robot_name))?
                .into_bytes(),
        ),
    };
    let options = program::Options {
        parallel: true,
        frames: context
            .frames
            .iter()
            .map(|f| crate::krl::interpret::GivenFrame {
                base: f.base,
                index: f.index,
                pose: crate::kinematics::Pose::from_array(f.xyzabc),
            })
            .collect(),
        taken: context.points,
        ..program::Options::default()
    };
    let (ws, result) = compensated(ws, calibration, &header_name, &header_bytes, &options)?;
    let bytes_of = |id| {
        result
            .files
            .iter()
            .find(|f| f.file == id)
            .map(|f| f.bytes.pieces().concat())
    };
    let dat_id = ws.get(ws.main).partner;
    Ok(Compensated {
        source: bytes_of(ws.main).unwrap_or_default(),
        dat: dat_id.and_then(bytes_of),
        messages: result.diagnostics.iter().map(Diagnostic::render).collect(),
        report: result.report,
    })
}

/// The main job on a loaded program: its result, or the rejection of the whole program.
/// `header_name` and `header_bytes` are the calibration file's, which the header names.
fn compensated(
    mut ws: Workspace,
    calibration: &Calibration,
    header_name: &str,
    header_bytes: &[u8],
    options: &program::Options,
) -> Result<(Workspace, program::ProgramResult), Error> {
    ws.robot = calibration.robot_name.clone();
    let calibrated = program::Calibrated::new(calibration.model_ref(), header_name, header_bytes);
    let result = crate::krl::job::compensate_program(&ws, &calibrated, options);
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
    let json = calibration.to_json(Path::new(&calibration.robot_name))?;
    let options = program::Options {
        parallel: true,
        ..program::Options::default()
    };
    let (ws, result) = compensated(
        ws,
        calibration,
        &calibration.robot_name,
        json.as_bytes(),
        &options,
    )?;
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
    let sim = crate::krl::interpret::simulate(&ws, robot, &[]);
    if sim.rejected() {
        return Err(Error::Rejected(sim.diagnostics));
    }
    Ok(Simulated {
        stops: sim
            .stops
            .iter()
            .map(|s| ProgramStop {
                line: s.handle.stmt.line as usize,
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

/// Measurements built in memory, column by column (a binding's arrays, a data frame), with
/// the measurement CSV's checks; a rejected entry is an [`Error::Measurements`] located as
/// `source:ROW:COLUMN` (rows counted from 1, columns as `test, a1..a6, x, y, z, t`).
pub fn measurements_from_columns(
    source: &str,
    columns: &MeasurementColumns,
) -> Result<Measurements, Error> {
    Ok(Measurements::from_columns(source, columns)?)
}

/// The choices of an identification: the options of `robopost identify` (docs/cli.md). The
/// default is the command's: the paper's full model in the base frame, tables every 1°, the
/// target from the data, the default tracker.
#[derive(Clone, Debug)]
pub struct IdentifyOptions {
    /// The effects (contract names, `map:A1..A6` expands); `None`: [`PAPER_EFFECTS`]. With
    /// [`Self::calibration`], `+NAME,…` adds effects to it (`--effects`).
    pub effects: Option<String>,
    /// Positions are in a tracker frame, identified too, one per measurement set
    /// (`--frame tracker`); `false`: the robot's base frame.
    pub tracker_frame: bool,
    /// Grid pitch of the `map` and `backlash` tables, degrees (`--map-pitch`).
    pub map_pitch_deg: f64,
    /// An existing calibration: robot, target and starting values (`-c`).
    pub calibration: Option<Calibration>,
    /// A hint for the measurement target in the flange frame, mm (`--target`).
    pub target_mm: Option<[f64; 3]>,
    /// The robot's name written into the calibration (`--robot-name`).
    pub robot_name: Option<String>,
    /// Most measured points the fit uses (`--max-points`); `None`: the command's default,
    /// `Some(0)`: all.
    pub max_points: Option<usize>,
    /// The tracker: a preset or its MPE as `C+Mppm` (`--tracker`); `None`: the default.
    pub tracker: Option<String>,
    /// Where the tracker stands in the robot's base frame, mm (`--tracker-at`).
    pub tracker_at_mm: Option<[f64; 3]>,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        IdentifyOptions {
            effects: None,
            tracker_frame: false,
            map_pitch_deg: 1.0,
            calibration: None,
            target_mm: None,
            robot_name: None,
            max_points: None,
            tracker: None,
            tracker_at_mm: None,
        }
    }
}

/// Identifies a calibration of `effects` (contract names, e.g. [`PAPER_EFFECTS`]) from
/// measurement files, unaided: the target vector from the data, gross errors screened out.
pub fn identify(files: &[Measurements], effects: &str) -> Result<Identified, Error> {
    identify_with(
        files,
        &IdentifyOptions {
            effects: Some(effects.to_string()),
            ..IdentifyOptions::default()
        },
    )
}

/// Identifies a calibration from measurement sets (one per file or tracker station) as
/// `robopost identify` does with the same `options`: the same parameters for the same data.
pub fn identify_with(
    files: &[Measurements],
    options: &IdentifyOptions,
) -> Result<Identified, Error> {
    let finest = crate::model::table::MIN_PITCH_DEG;
    if !(options.map_pitch_deg.is_finite() && options.map_pitch_deg >= finest) {
        return Err(Error::Option(format!(
            "map pitch {}: the table pitch must be at least {finest} degrees",
            options.map_pitch_deg
        )));
    }
    let effects = match options.effects.as_deref() {
        None => None,
        Some(list) => match pipeline::Effects::parse(list) {
            Ok(pipeline::Effects::Add(_)) if options.calibration.is_none() => {
                return Err(Error::Option(
                    "effects `+NAME` add to an existing calibration: give one".into(),
                ));
            }
            Ok(effects) => Some(effects),
            Err(pipeline::EffectsListError::Mixed) => {
                return Err(Error::Option(
                    "effects: either every name starts with `+` (added to the calibration) or none does".into(),
                ));
            }
            Err(pipeline::EffectsListError::Name(e)) => return Err(Error::Effects(e)),
        },
    };
    let mut tracker = match &options.tracker {
        Some(spec) => crate::measure::tracker::Tracker::parse(spec).map_err(Error::Option)?,
        None => crate::measure::tracker::Tracker::default(),
    };
    if let Some(at) = options.tracker_at_mm {
        tracker.station_mm = Some(Vector3::from(at));
    }
    let mut stops = Vec::new();
    let mut file_of = Vec::new();
    for (k, f) in files.iter().enumerate() {
        file_of.extend(std::iter::repeat_n(k, f.stops.len()));
        stops.extend(f.stops.iter().cloned());
    }
    let request = pipeline::Request {
        effects,
        base: options.calibration.clone(),
        tracker_frame: options.tracker_frame,
        grid: crate::identify::setup::GridChoice {
            map_pitch_deg: options.map_pitch_deg,
            ..Default::default()
        },
        target_mm: options.target_mm,
        robot_name: options.robot_name.clone(),
        sources: files.iter().map(|f| f.source.clone()).collect(),
        file_of,
        max_points: Some(
            options
                .max_points
                .unwrap_or(crate::identify::thin::DEFAULT_MAX_POINTS),
        ),
        tracker,
        progress: None,
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
/// that embeds the command and goes on: everything the command built is freed before it
/// returns.
pub fn run_command_line(args: Vec<String>) -> i32 {
    let status = crate::cli::main(args);
    crate::cli::free_left();
    status
}

/// [`run_command_line`], then the process exits with its status without freeing the
/// program's syntax tree node by node (the exit returns the memory at once): the `robopost`
/// binary.
pub fn exit_with_command_line(args: Vec<String>) -> ! {
    std::process::exit(crate::cli::main(args))
}
