//! `robopost campaign --robot NAME|FILE --tool X,Y,Z --tracker-at X,Y,Z -o NAME.src
//! [--plan PLAN.csv] [--reference A1,..,A6] [--reflector-axis X,Y,Z] [--acceptance DEG]
//! [--floor Z] [--box X1,Y1,Z1,X2,Y2,Z2]... [--pitch DEG] [--dwell S] [--speed DEG/S]
//! [--pulse N]`: the measurement campaign for a real cell as a KRL program and data list, and
//! its plan beside it (docs/campaign-program.md). Thin over `crate::simulate::lab`.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use super::Exit;
use crate::measure::plan::{write_plan, PlanStop};
use crate::simulate::lab::{self, Cell, Choices};

#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// The robot: a shipped robot's name (`KR 16`) or a calibration file.
    #[arg(long)]
    pub robot: String,
    /// The reflector's centre in the flange frame, mm (`X,Y,Z`).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub tool: Vec<f64>,
    /// The tracker head in the robot base frame, mm (`X,Y,Z`).
    #[arg(
        long = "tracker-at",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    pub tracker_at: Vec<f64>,
    /// The program to write (`NAME.src`; `NAME.dat` beside it).
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// The plan to write (default: `NAME_plan.csv` beside the program).
    #[arg(long)]
    pub plan: Option<PathBuf>,
    /// The pose every test starts from, degrees (`A1,..,A6`).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub reference: Option<Vec<f64>>,
    /// The direction the reflector opens towards, in the flange frame (`X,Y,Z`); default:
    /// facing the tracker at the reference pose.
    #[arg(
        long = "reflector-axis",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    pub reflector_axis: Option<Vec<f64>>,
    /// The reflector's acceptance half-angle, degrees (1.5" SMR: 30).
    #[arg(long, default_value_t = 30.0)]
    pub acceptance: f64,
    /// No stop puts the reflector or the flange below this height (base frame), mm.
    #[arg(long, allow_negative_numbers = true)]
    pub floor: Option<f64>,
    /// A keep-out box (two opposite corners, base frame, mm): no stop puts the reflector or
    /// the flange inside it. Repeat for more boxes.
    #[arg(
        long = "box",
        value_name = "X1,Y1,Z1,X2,Y2,Z2",
        allow_hyphen_values = true
    )]
    pub boxes: Vec<String>,
    /// Step of the indexing tests, degrees.
    #[arg(long, default_value_t = 1.0)]
    pub pitch: f64,
    /// Dwell per measured stop (`WAIT SEC`), seconds.
    #[arg(long, default_value_t = crate::simulate::campaign::DEFAULT_DWELL_S)]
    pub dwell: f64,
    /// Axis speed assumed between stops for the plan's times, degrees per second.
    #[arg(long, default_value_t = crate::simulate::campaign::DEFAULT_AXIS_SPEED_DEG_S)]
    pub speed: f64,
    /// The reversal tests' back-and-forth moves, degrees (some shorter and some longer than
    /// a gear play; a stream's dwells need moves longer than --radius of `import`).
    #[arg(long = "reversal-steps", value_delimiter = ',')]
    pub reversal_steps: Option<Vec<f64>>,
    /// Pulse this output half-way through each measured stop's dwell (triggered capture).
    #[arg(long)]
    pub pulse: Option<u16>,
}

fn triple(v: &[f64], what: &str) -> Result<Vector3<f64>, Exit> {
    match v {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vector3::new(*x, *y, *z)),
        _ => Err(super::usage(format!("{what} takes X,Y,Z in mm"))),
    }
}

/// The KRL name of the program: the file stem, which KRL requires to be an identifier.
fn program_name(out: &Path) -> Result<String, Exit> {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ok = !stem.is_empty()
        && stem.len() <= 24
        && stem
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && stem.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if ok
        && out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("src"))
    {
        Ok(stem)
    } else {
        Err(super::usage(format!(
            "-o {}: a KRL program NAME.src, NAME a letter then at most 23 letters, digits or _",
            out.display()
        )))
    }
}

/// The `--box` arguments, six numbers each.
fn boxes(args: &[String]) -> Result<Vec<[f64; 6]>, Exit> {
    args.iter()
        .map(|arg| {
            let v: Vec<f64> = arg
                .split(',')
                .map(|c| c.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| {
                    super::usage(format!("--box {arg}: expected X1,Y1,Z1,X2,Y2,Z2 in mm"))
                })?;
            match v.as_slice() {
                [a, b, c, d, e, f] if v.iter().all(|x| x.is_finite()) => {
                    Ok([*a, *b, *c, *d, *e, *f])
                }
                _ => Err(super::usage(format!(
                    "--box {arg}: expected X1,Y1,Z1,X2,Y2,Z2 in mm"
                ))),
            }
        })
        .collect()
}

pub fn run(args: Args) -> Exit {
    match build(&args) {
        Ok(exit) => exit,
        Err(exit) => exit,
    }
}

fn build(args: &Args) -> Result<Exit, Exit> {
    let cal = crate::calibration::robots::resolve(&args.robot)
        .map_err(|e| super::usage(format!("--robot: {e}")))?;
    let name = program_name(&args.out)?;
    if !(args.pitch > 0.0 && args.dwell > 0.0 && args.speed > 0.0 && args.acceptance > 0.0)
        || !(args.acceptance <= 90.0)
    {
        return Err(super::usage(
            "--pitch, --dwell and --speed must be positive, --acceptance in (0, 90]°",
        ));
    }
    let mut choices = Choices {
        pitch_deg: args.pitch,
        dwell_s: args.dwell,
        axis_speed_deg_s: args.speed,
        ..Choices::default()
    };
    if let Some(steps) = &args.reversal_steps {
        if !steps
            .iter()
            .all(|s| s.is_finite() && *s > 0.0 && *s <= 10.0)
        {
            return Err(super::usage("--reversal-steps: steps in (0, 10]°"));
        }
        choices.reversal_steps_deg = steps.clone();
    }
    if let Some(r) = &args.reference {
        match r.as_slice() {
            [a, b, c, d, e, f] if r.iter().all(|v| v.is_finite()) => {
                choices.reference_deg = [*a, *b, *c, *d, *e, *f]
            }
            _ => return Err(super::usage("--reference takes A1,..,A6 in degrees")),
        }
    }
    let reflector_axis = match &args.reflector_axis {
        None => None,
        Some(v) => {
            let a = triple(v, "--reflector-axis")?;
            if a.norm() < 1e-9 {
                return Err(super::usage("--reflector-axis must not be zero"));
            }
            Some(a)
        }
    };
    let cell = Cell {
        robot: cal.model_ref().robot,
        robot_name: cal.robot_name.clone(),
        tool_mm: triple(&args.tool, "--tool")?,
        reflector_axis,
        tracker_mm: triple(&args.tracker_at, "--tracker-at")?,
        acceptance_deg: args.acceptance,
        floor_mm: args.floor,
        boxes: boxes(&args.boxes)?,
    };
    let plan_path = args
        .plan
        .clone()
        .unwrap_or_else(|| args.out.with_file_name(format!("{name}_plan.csv")));
    let dat_path = args.out.with_extension("dat");
    let mut guard = crate::paths::Guard::new();
    for p in [&args.out, &dat_path, &plan_path] {
        guard.write(p).map_err(|c| super::refuse(&c))?;
    }
    let campaign = lab::fit(&cell, &choices).map_err(super::usage)?;
    let (src, dat) = lab::program(&campaign, &cell, &name, args.dwell, args.pulse);
    let plan: Vec<PlanStop> = campaign
        .stops
        .iter()
        .zip(&campaign.points)
        .map(|(s, p)| PlanStop {
            test: s.test.clone(),
            point: p.clone(),
            axes_deg: s.axes_deg,
            time_s: Some(s.time_s),
            line: 0,
            point_col: 0,
        })
        .collect();
    let mut plan_bytes = Vec::new();
    write_plan(&mut plan_bytes, &plan).map_err(|e| super::usage(e.to_string()))?;
    for (path, bytes) in [
        (&args.out, src.as_bytes()),
        (&dat_path, dat.as_bytes()),
        (&plan_path, plan_bytes.as_slice()),
    ] {
        crate::atomic_file::write(path, bytes)
            .map_err(|e| super::usage(format!("cannot write {}: {e}", path.display())))?;
    }
    for note in &campaign.notes {
        eprintln!("note: {note}");
    }
    let measured = campaign.points.iter().filter(|p| !p.is_empty()).count();
    let hours = campaign.stops.last().map_or(0.0, |s| s.time_s) / 3600.0;
    eprintln!(
        "robopost campaign: {} stops ({measured} measured, about {hours:.1} h) for the {} → {}, {}, {}",
        campaign.stops.len(),
        cell.robot_name,
        args.out.display(),
        dat_path.display(),
        plan_path.display()
    );
    Ok(Exit::Success)
}
