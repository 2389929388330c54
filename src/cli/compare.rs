//! `robopost compare -c CAL.json MEAS.csv... [--json] [--report DIR] [--against OTHER.json]`:
//! the model's prediction against every measured row, the paper's Table 1 statistics overall
//! and per test, optionally a second calibration side by side and an HTML report.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use super::Exit;
use crate::calibration::{self, Calibration};
use crate::compare::{self, table, Row, Summary};
use crate::measure::{self, Measurements};
use crate::report::{self, ReportInput, ReportModel};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Calibration whose model is compared with the measurements.
    #[arg(short = 'c', long = "cal")]
    pub cal: PathBuf,
    /// Measurement CSV files (laser tracker data), `-` for stdin.
    #[arg(required = true)]
    pub measurements: Vec<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write an HTML report (index.html with inline SVG plots) into this directory.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// A second calibration shown side by side (e.g. the one before adding an effect).
    #[arg(long, value_name = "OTHER.json")]
    pub against: Option<PathBuf>,
    /// Write every measured point's residual under the calibration (`-c`) to this CSV
    /// (docs/residuals.md).
    #[arg(long, value_name = "FILE.csv")]
    pub residuals: Option<PathBuf>,
    /// The measurement files the calibration was identified from: an error budget of the
    /// measurements (tracker, identification, model form, unexplained), overall, per test and
    /// (`--json`) per point.
    #[arg(long, value_name = "CAMPAIGN.csv")]
    pub budget: Vec<PathBuf>,
    /// With `--budget`: the tracker of the measurements (its accuracy and station).
    #[command(flatten)]
    pub tracker: super::instrument::TrackerArgs,
}

/// Loads calibrations and measurement files, printing errors; `None` means exit 2.
pub(crate) fn load_inputs(
    cals: &[&Path],
    files: &[PathBuf],
) -> Option<(Vec<Calibration>, Vec<Measurements>)> {
    let mut loaded = Vec::new();
    for path in cals {
        match calibration::load(path) {
            Ok(c) => loaded.push(c),
            Err(e) => {
                eprintln!("error: {e}");
                return None;
            }
        }
    }
    let mut data = Vec::new();
    // Every row within the joint limits of the robot the measurements are compared with.
    let limits = loaded.first().map(|c| c.model_ref().robot.limits_deg);
    for path in files {
        match measure::read_csv_within(path, limits.as_ref()) {
            Ok(m) => {
                if !m.ignored_columns.is_empty() {
                    eprintln!(
                        "note: {}: ignored columns: {}",
                        m.source,
                        m.ignored_columns.join(", ")
                    );
                }
                data.push(m);
            }
            Err(e) => {
                eprint!("{}", e.render());
                return None;
            }
        }
    }
    if data.iter().all(|m| m.measured().next().is_none()) {
        eprintln!("error: the measurement files hold no measured row (x, y, z all empty)");
        return None;
    }
    Some((loaded, data))
}

/// A mean 3-D error this large (µm) is no robot's calibrated or even uncalibrated error (a
/// few mm at most): the calibration is of another robot, or the positions are in another
/// frame.
const IMPLAUSIBLE_MEAN_UM: f64 = 20_000.0;

/// Warns when the calibration at `path` predicts the measurements implausibly badly (see
/// [`IMPLAUSIBLE_MEAN_UM`]): a KR 16 calibration on KR 30 measurements is 0.5 m off.
fn warn_if_implausible(path: &Path, cal: &Calibration, s: &Summary) {
    let mean_mm = s.all.d3_mean_um / 1000.0;
    if s.all.d3_mean_um.is_finite() && s.all.d3_mean_um <= IMPLAUSIBLE_MEAN_UM {
        return;
    }
    let robot = &cal.robot_name;
    eprintln!(
        "warning: {}: the model predicts the measured positions {mean_mm:.1} mm off on average, far more than any robot's error (a few mm at most): is it a calibration of this robot (it describes a {robot})? are the positions in the robot's base frame (identify --frame tracker otherwise)?",
        path.display()
    );
}

/// The file name a user recognises in a table column.
pub(crate) fn short_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

fn summary_json(s: &Summary, path: &Path) -> Value {
    let mut v = serde_json::to_value(s).unwrap_or(Value::Null);
    if let Value::Object(map) = &mut v {
        map.insert("calibration".into(), json!(path.display().to_string()));
    }
    v
}

/// The version line of a residuals file.
pub const RESIDUALS_VERSION: &str = "# robopost-residuals/1";

/// One line per measured point: where it came from, its command, the measured and predicted
/// positions (mm) and the residual (µm), and whether identification left it out.
fn residuals_csv<T>(rows: &[Row], marks: &[Option<T>]) -> Vec<u8> {
    let mut out = format!(
        "{RESIDUALS_VERSION}\nsource,line,test,a1,a2,a3,a4,a5,a6,t,x,y,z,predicted_x,predicted_y,predicted_z,dx_um,dy_um,dz_um,d3_um,gross\n"
    );
    for (r, m) in rows.iter().zip(marks) {
        let d = r.residual() * 1000.0;
        let a = r.state.axes_deg;
        let quote = |t: &str| {
            if t.contains([',', '"', '\n']) {
                format!("\"{}\"", t.replace('"', "\"\""))
            } else {
                t.to_string()
            }
        };
        out.push_str(&format!(
            "{},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.1},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.2},{:.2},{:.2},{:.2},{}\n",
            quote(&r.source),
            r.line,
            quote(&r.test),
            a[0],
            a[1],
            a[2],
            a[3],
            a[4],
            a[5],
            r.state.time_s,
            r.measured.x,
            r.measured.y,
            r.measured.z,
            r.predicted.x,
            r.predicted.y,
            r.predicted.z,
            d.x,
            d.y,
            d.z,
            d.norm(),
            u8::from(m.is_some())
        ));
    }
    out.into_bytes()
}

pub fn run(args: Args) -> Exit {
    let mut cal_paths = vec![args.cal.as_path()];
    cal_paths.extend(args.against.as_deref());
    if let Some(dir) = &args.report {
        let mut guard = crate::paths::Guard::new();
        guard
            .read_all(cal_paths.iter().copied())
            .read_all(args.measurements.iter().map(PathBuf::as_path))
            .read_all(args.budget.iter().map(PathBuf::as_path));
        if let Err(clash) = guard.write(&dir.join(report::INDEX)) {
            return super::refuse(&clash);
        }
    }
    if let Some(out) = &args.residuals {
        let mut guard = crate::paths::Guard::new();
        guard
            .read_all(cal_paths.iter().copied())
            .read_all(args.measurements.iter().map(PathBuf::as_path))
            .read_all(args.budget.iter().map(PathBuf::as_path));
        if let Err(clash) = guard.write(out) {
            return super::refuse(&clash);
        }
    }
    let Some((cals, data)) = load_inputs(&cal_paths, &args.measurements) else {
        return Exit::Usage;
    };
    let rows: Vec<Vec<Row>> = cals.iter().map(|c| compare::compare(c, &data)).collect();
    // Points the main calibration's identification left out as gross errors: marked, and not
    // in the statistics of any model (the same points for all).
    let marks = compare::gross_errors(&cals[0], &data);
    let n_marked = marks.iter().filter(|m| m.is_some()).count();
    // The rows without the marked ones, copied only when some are marked (a million rows
    // are ~0.5 GB a copy).
    let unmarked = |r: &[Row], summary: fn(&[Row]) -> Summary| -> Summary {
        if n_marked == 0 {
            return summary(r);
        }
        let kept: Vec<Row> = r
            .iter()
            .zip(&marks)
            .filter(|(_, m)| m.is_none())
            .map(|(row, _)| row.clone())
            .collect();
        summary(&kept)
    };
    let summaries: Vec<Summary> = rows
        .iter()
        .map(|r| unmarked(r, Summary::residuals))
        .collect();
    let nominal = unmarked(&rows[0], Summary::uncompensated);
    let budget = if args.budget.is_empty() {
        None
    } else {
        let kept: Vec<Row> = rows[0]
            .iter()
            .zip(&marks)
            .filter(|(_, m)| m.is_none())
            .map(|(r, _)| r.clone())
            .collect();
        match super::budget::budget(&cals[0], &args.budget, &args.tracker, &kept) {
            Ok(b) => Some(b),
            Err(exit) => return exit,
        }
    };
    // The measurements are needed again only by the report: freed here otherwise.
    let data = args.report.as_ref().map(|_| data);
    for ((path, cal), s) in cal_paths.iter().zip(&cals).zip(&summaries) {
        warn_if_implausible(path, cal, s);
    }

    if let Some(out) = &args.residuals {
        let bytes = residuals_csv(&rows[0], &marks);
        if let Err(e) = super::simulate::write_output(out, &bytes) {
            eprintln!("error: cannot write {}: {e}", out.display());
            return Exit::Usage;
        }
    }
    if let (Some(dir), Some(data)) = (&args.report, &data) {
        let labels: Vec<String> = cal_paths.iter().map(|p| short_name(p)).collect();
        let learned = crate::diagnose::learned_only(&cals[0], data);
        let input = ReportInput {
            models: cals
                .iter()
                .zip(&rows)
                .zip(&labels)
                .map(|((c, r), l)| ReportModel {
                    label: l,
                    model: c.model_ref(),
                    rows: r,
                })
                .collect(),
            sources: args
                .measurements
                .iter()
                .map(|p| p.display().to_string())
                .collect(),
            gross_errors: marks.clone(),
            learned: learned.as_ref(),
        };
        match report::write(dir, &input) {
            Ok(path) => eprintln!("report: {}", path.display()),
            Err(e) => {
                eprintln!("error: cannot write the report in {}: {e}", dir.display());
                return Exit::Usage;
            }
        }
    }

    if args.json {
        let mut out = summary_json(&summaries[0], &args.cal);
        if let Value::Object(map) = &mut out {
            map.insert("gross_errors".into(), json!(n_marked));
            map.insert(
                "nominal".into(),
                serde_json::to_value(&nominal).unwrap_or(Value::Null),
            );
            if let (Some(path), Some(s)) = (&args.against, summaries.get(1)) {
                map.insert("against".into(), summary_json(s, path));
            }
            if let Some(b) = &budget {
                map.insert(
                    "budget".into(),
                    serde_json::to_value(b).unwrap_or(Value::Null),
                );
            }
        }
        super::outln!(
            "{}",
            serde_json::to_string_pretty(&out).unwrap_or_else(|_| "{}".into())
        );
    } else {
        let mut models: Vec<(String, &Summary)> = vec![("nominal".into(), &nominal)];
        // The baseline first, so ΔRMS on the calibration's line is the fall it brought.
        if let (Some(path), Some(s)) = (&args.against, summaries.get(1)) {
            models.push((short_name(path), s));
        }
        models.push((short_name(&args.cal), &summaries[0]));
        let refs: Vec<(&str, &Summary)> = models.iter().map(|(l, s)| (l.as_str(), *s)).collect();
        super::out!("{}", table::render(&refs));
        super::outln!(
            "(residual = measured − predicted; `nominal` is the robot's error from the command)"
        );
        if n_marked > 0 {
            super::outln!(
                "{n_marked} point(s) that identify left out as gross errors are not in these \
                 statistics (marked in the --report page; listed in the calibration's \
                 provenance.excluded)"
            );
        }
        if let Some(b) = &budget {
            super::out!("{}", super::budget::render(b));
        }
    }
    Exit::Success
}
