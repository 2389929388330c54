//! `robopost IN.src -c CAL.json -o OUT.src`: compensate one program (its `.dat` and called
//! modules beside it), `-` for standard input/output.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::Exit;
use crate::calibration;
use crate::compensate::Method;
use crate::diagnostic::Severity;
use crate::kinematics::{Pose, RobotDescription};
use crate::krl::interpret::{Cell, GivenFrame};
use crate::krl::job::{files, program, Calibrated};

/// How a program's frames and shared data are found: shared by the main job, `batch`,
/// `check` and `simulate program` (which runs a program as the main job reads it).
#[derive(clap::Args, Debug, Clone)]
pub struct FrameArgs {
    /// The robot's `$config.dat` (BASE_DATA, TOOL_DATA…), or another data list or module of
    /// its cell; repeatable, for a partial backup.
    #[arg(long = "config", value_name = "FILE")]
    pub config: Vec<PathBuf>,
    /// The robot's cell: a backup or project tree (`KRC/R1/…`, or any folder). Its
    /// `$config.dat`, the GLOBAL data of its public data lists, the modules defining the
    /// routines a program calls (wherever they are) and its machine data are used.
    #[arg(long = "cell", value_name = "DIR")]
    pub cell: Option<PathBuf>,
    /// A base frame: `N=X,Y,Z,A,B,C` for `BASE_DATA[N]` (repeatable).
    #[arg(long = "base", value_name = "N=X,Y,Z,A,B,C", value_parser = parse_frame_arg, allow_hyphen_values = true)]
    pub base: Vec<(i64, Pose)>,
    /// A tool frame: `N=X,Y,Z,A,B,C` for `TOOL_DATA[N]` (repeatable).
    #[arg(long = "tool", value_name = "N=X,Y,Z,A,B,C", value_parser = parse_frame_arg, allow_hyphen_values = true)]
    pub tool: Vec<(i64, Pose)>,
}

impl FrameArgs {
    /// The cell of `--cell` and `--config` (`None` when neither is given); a directory or
    /// file that cannot be read is a usage error, said here.
    pub fn cell(&self) -> Result<Option<Cell>, Exit> {
        if self.cell.is_none() && self.config.is_empty() {
            return Ok(None);
        }
        for p in &self.config {
            if !p.is_file() {
                eprintln!("error: --config {}: no such file", p.display());
                return Err(Exit::Usage);
            }
        }
        if let Some(d) = &self.cell {
            if !d.is_dir() {
                eprintln!("error: --cell {}: not a directory", d.display());
                return Err(Exit::Usage);
            }
        }
        match Cell::scan(self.cell.as_deref(), &self.config) {
            Ok(c) => Ok(Some(c)),
            Err(e) => {
                eprintln!("error: reading the cell: {e}");
                Err(Exit::Usage)
            }
        }
    }

    /// The frames given on the command line.
    pub fn given(&self) -> Vec<GivenFrame> {
        let mut frames = Vec::new();
        for (n, v) in &self.base {
            frames.push(GivenFrame {
                base: true,
                index: *n,
                pose: *v,
            });
        }
        for (n, v) in &self.tool {
            frames.push(GivenFrame {
                base: false,
                index: *n,
                pose: *v,
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
    /// The robot: a name (`"KR 16"`, see the README) or a calibration file. With `-c` it
    /// must be the calibration's robot (a check); without, the robot `check` simulates.
    #[arg(long = "robot", value_name = "NAME|FILE")]
    pub robot: Option<String>,
    /// Apply the paper's equation (3) once instead of iterating to 0.1 µm (for comparison).
    #[arg(long = "one-step")]
    pub one_step: bool,
    /// A value the walk cannot know before run time, `NAME=VALUE` (repeatable): a variable
    /// (`lnUsedBase=2`), an array element or input (`$IN[5]=TRUE`), an enum (`side=#LEFT`).
    #[arg(long = "assume", value_name = "NAME=VALUE", allow_hyphen_values = true)]
    pub assume: Vec<crate::krl::interpret::Assumption>,
    /// Which points to compensate: `offline` (computed away from the robot: every point),
    /// `taught` (taught on the robot: none, unless --from), `auto` (each point as the
    /// evidence in its files says).
    #[arg(long = "points", value_enum, default_value_t = PointOrigin::Auto)]
    pub point_origin: PointOrigin,
}

/// `--points`: where the program's points come from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointOrigin {
    Auto,
    Offline,
    Taught,
}

impl PointOrigin {
    fn taken(self) -> crate::krl::job::Taken {
        match self {
            PointOrigin::Auto => crate::krl::job::Taken::Auto,
            PointOrigin::Offline => crate::krl::job::Taken::Offline,
            PointOrigin::Taught => crate::krl::job::Taken::Taught,
        }
    }
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
            stretching: Default::default(),
            assumptions: self.assume.clone(),
            taken: self.point_origin.taken(),
            uncertainty: None,
        }
    }
}

/// A robot the user or the cell states: by `--robot`, or by the cell's machine data.
#[derive(Clone, Debug)]
pub struct StatedRobot {
    pub name: String,
    pub robot: RobotDescription,
    /// Where it was said (`--robot`, the machine data's path).
    pub source: String,
    /// Its limits are the controller's configured ones (machine data).
    pub configured: bool,
}

/// The robots `--robot` and the cell's machine data state; an unknown name, an unreadable
/// file or machine data of a robot robopost cannot model are usage errors, said here.
pub fn stated_robots(robot: Option<&str>, cell: Option<&Cell>) -> Result<Vec<StatedRobot>, Exit> {
    let mut out = Vec::new();
    if let Some(arg) = robot {
        match crate::calibration::robots::resolve(arg) {
            Ok(c) => out.push(StatedRobot {
                name: c.robot_name.clone(),
                robot: c.model_ref().robot,
                source: format!("--robot {arg}"),
                configured: false,
            }),
            Err(e) => {
                eprintln!("error: --robot: {e}");
                return Err(Exit::Usage);
            }
        }
    }
    if let Some(path) = cell.and_then(|c| c.machine.as_deref()) {
        match crate::krl::interpret::cell::machine_robot(path) {
            Ok((name, robot)) => out.push(StatedRobot {
                name,
                robot,
                source: format!("the machine data {}", path.display()),
                configured: true,
            }),
            Err(e) => {
                eprintln!("error: {e}");
                return Err(Exit::Usage);
            }
        }
    }
    Ok(out)
}

fn links_text(r: &RobotDescription) -> String {
    let l = &r.links;
    format!(
        "l1x {} l1z {} l2 {} l3z {} l4x {} l5x {} mm",
        l.l1x, l.l1z, l.l2, l.l3z, l.l4x, l.l5x
    )
}

/// The cell given (`--cell`, `--config`), with the calibration checked against the robots it
/// and `--robot` state (see [`fit_robot`]).
pub fn cell_fitted(
    program: &ProgramArgs,
    cal: &mut calibration::Calibration,
    cal_path: &Path,
) -> Result<Option<Cell>, Exit> {
    let cell = program.cell()?;
    let stated = stated_robots(program.robot.as_deref(), cell.as_ref())?;
    fit_robot(cal, cal_path, &stated)?;
    Ok(cell)
}

/// Checks that the robots stated are the calibration's (links within 0.5 mm: a calibration
/// of one robot compensates no other) and takes the software limits of the machine data,
/// which the controller enforces. A mismatch is a usage error, said here.
pub fn fit_robot(
    cal: &mut calibration::Calibration,
    cal_path: &Path,
    stated: &[StatedRobot],
) -> Result<(), Exit> {
    for s in stated {
        let mine = cal.model_ref().robot;
        let (a, b) = (mine.links, s.robot.links);
        let same = [
            (a.l1x, b.l1x),
            (a.l1z, b.l1z),
            (a.l2, b.l2),
            (a.l3z, b.l3z),
            (a.l4x, b.l4x),
            (a.l5x, b.l5x),
        ]
        .iter()
        .all(|(x, y)| (x - y).abs() <= 0.5);
        if !same {
            eprintln!(
                "error: the calibration {} describes a {} ({}), but {} says the robot is a {} ({}): compensate with a calibration of that robot",
                cal_path.display(),
                cal.robot_name,
                links_text(&mine),
                s.source,
                s.name,
                links_text(&s.robot)
            );
            return Err(Exit::Usage);
        }
        if s.configured && s.robot.limits_deg != mine.limits_deg {
            cal.set_limits(s.robot.limits_deg);
        }
    }
    Ok(())
}

/// How messages name the robot of a calibration: `KR 16-2 (cal.json)`.
pub fn robot_label(cal: &calibration::Calibration, cal_path: &Path) -> String {
    let file = cal_path.file_name().map_or_else(
        || cal_path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    format!("{} ({file})", cal.robot_name)
}

/// `N=X,Y,Z,A,B,C`.
pub fn parse_frame_arg(text: &str) -> Result<(i64, Pose), String> {
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
    Ok((n, Pose::from_array(values)))
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
    /// The calibration of the robot the program was taught on (a twin or the robot replaced):
    /// the targets taken as taught are compensated to where that robot reaches them.
    #[arg(long = "from", value_name = "A.json")]
    pub from: Option<PathBuf>,
    /// The measurement files the calibration was identified from: the report gives every
    /// target's predicted uncertainty (`sigma_um`), their tracker noise carried through the
    /// identification.
    #[arg(long = "campaign", value_name = "MEAS.csv", requires = "report")]
    pub campaign: Vec<PathBuf>,
    #[command(flatten)]
    pub program: ProgramArgs,
}

/// Loads a calibration and names it for the output header.
/// The calibration file and its bytes (for the header's checksum); an unreadable or invalid
/// file is reported here and is a usage error (exit 2), before any program is touched.
pub fn load_calibration(path: &Path) -> Result<(calibration::Calibration, Vec<u8>), Exit> {
    let loaded = crate::input::read(path)
        .map_err(|e| format!("{}: {e}", path.display()))
        .and_then(|bytes| {
            if crate::input::is_utf16(&bytes) {
                return Err(format!("{}: {}", path.display(), crate::input::UTF16));
            }
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
    let (mut cal, cal_bytes) = match load_calibration(&args.cal) {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    let cell = match cell_fitted(&args.program, &mut cal, &args.cal) {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    let from = match &args.from {
        None => None,
        Some(path) => {
            let (mut a, _) = match load_calibration(path) {
                Ok(c) => c,
                Err(exit) => return exit,
            };
            // The robot of -c stated for the robot of --from: one type, or no transfer.
            let b = StatedRobot {
                name: cal.robot_name.clone(),
                robot: cal.model_ref().robot,
                source: format!("-c {}", args.cal.display()),
                configured: false,
            };
            if let Err(exit) = fit_robot(&mut a, path, &[b]) {
                return exit;
            }
            Some(a)
        }
    };
    let uncertainty = match super::budget::covariance_of(&cal, &args.campaign) {
        Ok(u) => u,
        Err(exit) => return exit,
    };
    let stdin = is_dash(&args.input);
    let bytes = if stdin {
        match crate::input::stdin() {
            Ok(b) => b,
            Err(e) => {
                eprintln!("error: <stdin>: {e}");
                return Exit::Usage;
            }
        }
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
    let stream = Some(crate::krl::StreamOptions::default());
    let loaded = tracing::info_span!("load")
        .in_scope(|| files::load_program_in(input, bytes, cell.as_ref(), stream));
    let mut ws = match loaded {
        Ok(ws) => ws,
        Err(e @ crate::krl::interpret::workspace::LoadError::Io { .. }) => {
            eprintln!("error: {e}");
            return Exit::Usage;
        }
        Err(e @ crate::krl::interpret::workspace::LoadError::NotKrl { .. }) => {
            eprint!("{e}");
            return Exit::Usage;
        }
        Err(e) => {
            eprintln!("{e}");
            return Exit::Rejected;
        }
    };
    ws.robot = robot_label(&cal, &args.cal);
    ws.assumptions.clone_from(&args.program.assume);
    if tracing::enabled!(tracing::Level::DEBUG) {
        let runs = ws.get(ws.main).file.streamed_runs();
        let windows: usize = runs.iter().map(|r| r.windows().len()).sum();
        tracing::debug!(runs = runs.len(), windows, "streamed");
    }
    let to_stdout = is_dash(&args.out);
    let mut guard = crate::paths::Guard::new();
    guard
        .read(&args.cal)
        .read_all(args.from.iter().map(PathBuf::as_path))
        .read_all(args.campaign.iter().map(PathBuf::as_path))
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
    let result = crate::krl::job::compensate_program_from(
        &ws,
        &calibrated,
        from.as_ref().map(|a| a.model_ref()),
        &program::Options {
            uncertainty,
            ..args.program.options(true, args.report.is_some())
        },
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
        // Standard output carries one file: a .src printed without the .dat (or modules) its
        // compensation changed would use values or names (XHOME_2) the controller does not
        // have. Refused before anything is printed.
        let changed: Vec<String> = result
            .files
            .iter()
            .filter(|f| f.file != ws.main && f.changed)
            .map(|f| ws.get(f.file).name.to_string())
            .collect();
        if !changed.is_empty() {
            eprintln!(
                "error: compensating {} changes {} too (new or changed declarations the program uses), which standard output cannot carry: nothing written; write to a file (-o OUT.src) to get the program with its .dat",
                ws.get(ws.main).name,
                changed.join(", ")
            );
            return Exit::Usage;
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
        let outputs = files::outputs(&ws, &result.files, &args.out);
        let written =
            tracing::info_span!("write").in_scope(|| files::write_atomic_pieces(&outputs));
        if let Err(e) = written {
            // The error names the file that failed (`writing OUT.dat: No space left…`).
            eprintln!("error: {e}; nothing of {} was written", args.out.display());
            return Exit::Usage;
        }
    }
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
    super::free_after((result, ws));
    status
}

fn exit_status(result: &crate::krl::job::ProgramResult) -> Exit {
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
pub fn summary(r: &crate::krl::job::Report) {
    eprintln!(
        "{}: {} (correction max {:.1} µm / {:.2} mdeg, mean {:.1} µm), {} direction flips, {} held axes kept, {} reversals inside the play{}",
        r.program,
        r.counts(),
        r.correction.position_um.max,
        r.correction.orientation_mdeg.max,
        r.correction.position_um.mean,
        r.direction_flips,
        r.held_axes,
        r.reversals_inside_play,
        r.taken_text()
    );
}

/// `check -c` / `check --cell`: each program simulated (and with a calibration compensated)
/// in memory; prints a summary line per program — the counts of the main job's summary, and
/// what the walk could not resolve and the user must add — and every error and warning;
/// writes nothing. Without a calibration the robot is `--robot`'s or the cell's (machine
/// data), else the KR 30 HA, said so.
pub fn check_programs(programs: &[PathBuf], cal_path: Option<&Path>, args: &ProgramArgs) -> Exit {
    let cell = match args.cell() {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    let stated = match stated_robots(args.robot.as_deref(), cell.as_ref()) {
        Ok(s) => s,
        Err(exit) => return exit,
    };
    let (cal, cal_bytes, label) = match cal_path {
        Some(p) => {
            let (mut cal, bytes) = match load_calibration(p) {
                Ok(c) => c,
                Err(exit) => return exit,
            };
            if let Err(exit) = fit_robot(&mut cal, p, &stated) {
                return exit;
            }
            let label = robot_label(&cal, p);
            (cal, bytes, label)
        }
        None => {
            let (name, robot, source) = match stated.first() {
                Some(s) => (s.name.clone(), s.robot, s.source.clone()),
                None => {
                    let r = crate::calibration::robots::ROBOTS[0];
                    eprintln!(
                        "note: no calibration, --robot or machine data: simulating a {}",
                        r.name
                    );
                    (
                        r.name.to_string(),
                        r.calibration().model_ref().robot,
                        "assumed".into(),
                    )
                }
            };
            let model = crate::model::Model::new(
                robot,
                crate::kinematics::Payload::default(),
                nalgebra::Vector3::zeros(),
            );
            let cal = calibration::Calibration::from_model(
                &name,
                model,
                Default::default(),
                Default::default(),
            );
            (cal, Vec::new(), format!("{name} ({source})"))
        }
    };
    let calibrated = calibrated(&cal, cal_path.unwrap_or(Path::new("nominal")), &cal_bytes);
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
        let mut ws = match files::load_program_in(input, bytes, cell.as_ref(), None) {
            Ok(ws) => ws,
            Err(e) => {
                eprintln!("{e}");
                exit = exit.max(Exit::Rejected);
                continue;
            }
        };
        ws.robot = label.clone();
        ws.assumptions.clone_from(&args.assume);
        let result =
            crate::krl::job::compensate_program(&ws, &calibrated, &args.options(true, false));
        for d in &result.diagnostics {
            eprintln!("{}", d.render());
        }
        let r = &result.report;
        if result.rejected {
            super::outln!("{}: rejected", path.display());
            exit = exit.max(Exit::Rejected);
            continue;
        }
        let counts = if cal_path.is_some() {
            r.counts()
        } else {
            r.resolution()
        };
        super::outln!(
            "{}: {counts}{}{}",
            path.display(),
            r.needs_text(),
            r.taken_text()
        );
        if r.rejected > 0 {
            exit = exit.max(Exit::Rejected);
        }
    }
    exit
}
