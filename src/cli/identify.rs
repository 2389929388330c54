//! `robopost identify MEAS.csv... -o CAL.json [--effects LIST] [--frame base|tracker]
//! [--map-pitch DEG] [-c OLD.json] [--target X,Y,Z] [--accept-poor-fit] [--max-points N]`:
//! identify a calibration from laser-tracker measurements and print the fit report.
//! `--effects +NAME` with `-c OLD.json` adds an effect to an existing calibration and
//! re-identifies. A fit that fails its check against the noise floor is refused (exit 1,
//! nothing written) unless `--accept-poor-fit`. Thin over `crate::identify::pipeline`: read
//! the files, identify, report, then write or refuse.

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;

use super::Exit;
use crate::identify::direct::TARGET_HINT_TOLERANCE_MM;
use crate::identify::pipeline::{
    identify, Effects, EffectsListError, Identified, Request, TargetSource, PAPER_EFFECTS,
};
use crate::identify::setup::GridChoice;
use crate::identify::{Progress, Status};
use crate::kinematics::RobotDescription;
use crate::measure::read_csv_within;
use crate::stats::ErrorStats;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Frame {
    /// Positions are in the robot base frame.
    Base,
    /// Positions are in a tracker frame fixed to the base; its pose is identified too.
    Tracker,
}

#[derive(clap::Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Measurement CSV files (rows in visiting order).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Calibration file to write.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Effects to identify, comma-separated (`map:A1..A6` expands). `+NAME,...` with `-c`
    /// adds effects to the existing calibration. Default: the paper's full model.
    #[arg(long)]
    pub effects: Option<String>,
    /// Frame of the measured positions.
    #[arg(long, value_enum, default_value_t = Frame::Base)]
    pub frame: Frame,
    /// Grid pitch of the map and backlash tables, degrees.
    #[arg(long = "map-pitch", default_value_t = 1.0)]
    pub map_pitch: f64,
    /// Existing calibration: robot, target and starting values.
    #[arg(short = 'c', long = "cal")]
    pub cal: Option<PathBuf>,
    /// A hint for the measurement target in the flange frame, mm (`X,Y,Z`), when there is no
    /// `-c`. Not needed: the A5 and A6 indexing tests give the target; the hint is kept as
    /// `target_mm` when within 1 mm of it, and is the start when the data hold no such tests.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub target: Option<Vec<f64>>,
    /// Robot name written into the calibration.
    #[arg(long = "robot-name")]
    pub robot_name: Option<String>,
    /// Write the calibration even when the fit fails its check against the noise floor (the
    /// failure is recorded in the file's provenance).
    #[arg(long = "accept-poor-fit")]
    pub accept_poor_fit: bool,
    /// Most measured points the fit uses; denser data are thinned evenly (every point is
    /// still checked against the result). 0: use all.
    #[arg(long = "max-points", default_value_t = crate::identify::thin::DEFAULT_MAX_POINTS)]
    pub max_points: usize,
    /// Measurement files kept out of the fit, on which `-c OLD --effects +NAME` compares the
    /// old and the new model (besides held-out folds of the fit's data).
    #[arg(long = "validate", value_name = "FILE.csv")]
    pub validate: Vec<PathBuf>,
    #[command(flatten)]
    pub instrument: super::instrument::TrackerArgs,
}

/// Gross errors printed one per line (all are in the calibration's provenance).
const GROSS_LINES: usize = 40;

fn usage(message: &str) -> Exit {
    super::usage(message)
}

pub fn run(args: Args) -> Exit {
    let finest = crate::model::table::MIN_PITCH_DEG;
    if !(args.map_pitch.is_finite() && args.map_pitch >= finest) {
        return usage(&format!(
            "--map-pitch {}: the table pitch must be at least {finest} degrees",
            args.map_pitch
        ));
    }
    let tracker = match args.instrument.tracker() {
        Ok(t) => t,
        Err(exit) => return exit,
    };
    let mut guard = crate::paths::Guard::new();
    guard
        .read_all(args.files.iter().map(PathBuf::as_path))
        .read_all(args.cal.as_deref())
        .read_all(args.validate.iter().map(PathBuf::as_path));
    if let Err(clash) = guard.write(&args.out) {
        return super::refuse(&clash);
    }
    let base = match &args.cal {
        Some(path) => match crate::calibration::load(path) {
            Ok(c) => Some(c),
            Err(e) => return usage(&e.to_string()),
        },
        None => None,
    };
    // Every row within the joint limits of the robot identified (the nominal KR 30 HA's
    // without -c, as the identification assumes).
    let limits = base
        .as_ref()
        .map_or(RobotDescription::kr30ha().limits_deg, |c| {
            c.model_ref().robot.limits_deg
        });
    let mut validation = Vec::new();
    for file in &args.validate {
        match read_csv_within(file, Some(&limits)) {
            Ok(m) => validation.push(m),
            Err(e) => {
                eprint!("{}", e.render());
                return Exit::Usage;
            }
        }
    }
    let spinner = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new_spinner();
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        bar
    });
    let mut stops = Vec::new();
    let mut files = Vec::new();
    let mut file_of = Vec::new();
    for (k, file) in args.files.iter().enumerate() {
        if let Some(bar) = &spinner {
            bar.set_message(format!("reading {}", file.display()));
        }
        match read_csv_within(file, Some(&limits)) {
            Ok(m) => {
                if !m.ignored_columns.is_empty() {
                    eprintln!(
                        "note: {}: ignored columns {}",
                        file.display(),
                        m.ignored_columns.join(", ")
                    );
                }
                file_of.resize(file_of.len() + m.stops.len(), k);
                stops.extend(m.stops.iter().cloned());
                files.push(m);
            }
            Err(e) => {
                eprint!("{}", e.render());
                return Exit::Usage;
            }
        }
    }
    if let Some(bar) = spinner {
        bar.finish_and_clear();
    }
    let effects = match args.effects.as_deref() {
        None => None,
        Some(list) => match Effects::parse(list) {
            Ok(Effects::Add(_)) if base.is_none() => {
                return usage(
                    "--effects +NAME adds to an existing calibration: give it with -c OLD.json",
                );
            }
            Ok(effects) => Some(effects),
            Err(EffectsListError::Mixed) => {
                return usage(
                    "--effects: either every name starts with `+` (add to -c) or none does",
                );
            }
            Err(EffectsListError::Name(e)) => return usage(&format!("--effects: {e}")),
        },
    };
    let target_mm = match args.target.as_deref() {
        None => None,
        Some([x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => Some([*x, *y, *z]),
        Some(_) => return usage("--target takes X,Y,Z in mm"),
    };
    let progress = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(30);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {prefix} {pos}/{len} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        bar
    });
    let request = Request {
        effects,
        base,
        tracker_frame: args.frame == Frame::Tracker,
        grid: GridChoice {
            map_pitch_deg: args.map_pitch,
            ..GridChoice::default()
        },
        target_mm,
        robot_name: args.robot_name.clone(),
        sources: args.files.iter().map(|f| f.display().to_string()).collect(),
        file_of,
        max_points: Some(args.max_points),
        tracker,
        progress: progress.clone().map(|bar| {
            Arc::new(move |p: &Progress| {
                bar.set_prefix(p.stage);
                bar.set_length(p.max_iterations as u64);
                bar.set_position(p.iteration as u64);
                if p.rms_um.is_finite() {
                    bar.set_message(format!("rms {:.1} µm", p.rms_um));
                } else {
                    bar.set_message("");
                }
            }) as Arc<dyn Fn(&Progress) + Send + Sync>
        }),
    };
    let added = match &request.effects {
        Some(Effects::Add(names)) => names.clone(),
        _ => Vec::new(),
    };
    let old = request.base.clone();
    let result = identify(&stops, &request);
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    let identified = match result {
        Ok(r) => r,
        Err(e) => return usage(&e.to_string()),
    };
    // With `-o -` the calibration goes to standard output: the report goes to standard error.
    let to_stdout = args.out.as_os_str() == "-";
    let say = |text: &str| {
        if to_stdout {
            eprint!("{text}");
        } else {
            super::out!("{text}");
        }
    };
    say(&report(
        &identified,
        args.effects.as_deref().unwrap_or(PAPER_EFFECTS),
    ));
    if let Some(failure) = &identified.verdict.failure {
        if !args.accept_poor_fit {
            eprint!("robopost identify: {failure}");
            eprintln!(
                "Nothing was written. `--accept-poor-fit` writes the calibration anyway (its \
                 provenance records the failure)."
            );
            return Exit::Rejected;
        }
        eprint!("warning: {failure}");
        eprintln!(
            "warning: written anyway (--accept-poor-fit); the provenance records the failure"
        );
    }
    let saved = if to_stdout {
        identified
            .calibration
            .to_json(&args.out)
            .map(|json| super::out!("{json}"))
    } else {
        identified.calibration.save_atomic(&args.out)
    };
    match saved {
        Ok(()) => {}
        // A value outside its physical range: the fit went astray (a failed fit written
        // with --accept-poor-fit); no command could read the file back.
        Err(
            e @ (crate::calibration::CalError::Invalid { .. }
            | crate::calibration::CalError::Effect { .. }),
        ) => {
            eprintln!(
                "robopost identify: the identified calibration is not physical ({e}); nothing \
                 was written"
            );
            return Exit::Rejected;
        }
        Err(e) => return usage(&e.to_string()),
    }
    if !to_stdout {
        super::outln!("wrote {}", args.out.display());
    }
    if let (Some(old), false) = (&old, added.is_empty()) {
        let (text, worse) = crate::identify::promise::run(
            old,
            &identified.calibration,
            &files,
            &validation,
            &added,
            &args
                .cal
                .as_deref()
                .map(|p| p.display().to_string())
                .unwrap_or_default(),
            &args.out.display().to_string(),
        );
        say(&text);
        if worse {
            eprintln!("warning: the new calibration predicts held-out data worse than the old one (see the promise check above)");
        }
    }
    Exit::Success
}

fn describe_target(r: &Identified) -> String {
    let m = r.calibration.model_ref();
    let t = m.target_mm;
    let written = format!("target_mm ({:.3}, {:.3}, {:.3})", t.x, t.y, t.z);
    match &r.target {
        TargetSource::Circles {
            target_a6,
            hint_off_mm,
        } => {
            let mut s = format!(
                "from the A5/A6 circles ({:.3}, {:.3}, {:.3} mm, A6 frame); {written}",
                target_a6[0], target_a6[1], target_a6[2]
            );
            if let Some(off) = hint_off_mm {
                s += &if *off > TARGET_HINT_TOLERANCE_MM {
                    format!("; the --target hint was {off:.1} mm from it and is not used")
                } else {
                    format!("; the --target hint is {off:.3} mm from it, kept as target_mm")
                };
            }
            s
        }
        TargetSource::LeastSquares { hint } => format!(
            "fitted to all points (no A5/A6 indexing tests) from {}; {written}",
            hint.map_or("the flange origin".into(), |h| format!(
                "the --target hint ({}, {}, {})",
                h[0], h[1], h[2]
            ))
        ),
        TargetSource::Calibration => format!("from the calibration given with -c; {written}"),
    }
}

fn stats_row(label: &str, s: &ErrorStats) -> String {
    format!(
        "  {label:<28} {:>6} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1} {:>9.1}\n",
        s.points, s.xy_mean_um, s.xy_2sigma_um, s.z_mean_um, s.z_2sigma_um, s.d3_max_um, s.rms_um
    )
}

/// The text report of an identification.
pub fn report(r: &Identified, requested: &str) -> String {
    let fit = &r.fit;
    let mut out = String::new();
    out += &format!(
        "effects: {} (requested: {requested})\n",
        r.effects.join(",")
    );
    if let Some(t) = &r.thinning {
        out += &format!("data: {}\n", t.describe());
    }
    if let Some(d) = &r.direct {
        out += &format!(
            "direct method: {} indexing tests, {} deviation samples\n",
            d.lines.len(),
            d.samples.len()
        );
        for l in &d.lines {
            out += &format!(
                "  {:<14} A{} circle radius {:>9.3} mm, rms {:>6.1} µm\n",
                l.test,
                l.axis,
                l.circle.radius,
                l.circle.rms * 1000.0
            );
        }
    }
    out += &format!("target: {}\n", describe_target(r));
    out += &format!(
        "refinement: {} iterations in {} round(s) of leaving out gross errors ({}), σ per \
         coordinate {:.1} µm\n",
        fit.iterations,
        r.rounds,
        if fit.converged {
            "converged"
        } else {
            "iteration limit"
        },
        fit.sigma_mm * 1000.0
    );
    out += &format!(
        "  {:<28} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}\n",
        "residual (µm)", "points", "XY mean", "XY 2σ", "Z mean", "Z 2σ", "3-D max", "RMS"
    );
    out += &stats_row("before", &fit.initial_stats);
    out += &stats_row("after", &r.stats);
    for (test, s) in &r.per_test {
        out += &stats_row(&format!("  {test}"), s);
    }
    out += &format!(
        "noise floor {:.1} µm RMS ({}); {}\n",
        r.verdict.noise.rms_um,
        r.verdict.noise.source.describe(),
        if r.verdict.failed() {
            "the fit FAILED (see below)"
        } else {
            "every test within the check"
        }
    );
    if let Some(note) = &r.verdict.note {
        out += &format!("note: {note}\n");
    }
    if r.gross.is_empty() {
        out += "gross errors: none\n";
    } else {
        out += &format!(
            "gross errors: {} left out of the fit (file:line test size: why)\n",
            r.gross.len()
        );
        for g in r.gross.iter().take(GROSS_LINES) {
            out += &format!(
                "  {}:{} {} {:.0} µm: {}\n",
                g.file, g.line, g.test, g.size_um, g.why
            );
        }
        if r.gross.len() > GROSS_LINES {
            out += &format!(
                "  … and {} more (all under provenance.excluded in the calibration)\n",
                r.gross.len() - GROSS_LINES
            );
        }
    }
    for st in &r.structures {
        out += &format!(
            "systematic, kept in the fit: {}; a jump that repeats is the robot's, not the \
             tracker's: an effect the model lacks (a flank that follows the load: \
             `loadplay:A{}` in place of `backlash:A{}`, see docs/effects.md)\n",
            st.describe(),
            st.axis,
            st.axis
        );
    }
    if let (Some(f), Some(se)) = (fit.tracker_frame, fit.tracker_frame_standard_errors) {
        let k = f.to_pose();
        out += &format!(
            "tracker frame: X {:.4} Y {:.4} Z {:.4} mm, A {:.5} B {:.5} C {:.5}° (±{:.4} {:.4} {:.4} mm, ±{:.5} {:.5} {:.5}°)\n",
            k.x, k.y, k.z, k.a, k.b, k.c, se[0], se[1], se[2], se[3], se[4], se[5]
        );
    }
    // Standard errors: every scalar parameter, and a summary per table.
    let model = r.calibration.model_ref();
    let mut tables: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    out += "standard errors:\n";
    let values = model.values();
    // Whether each parameter, in the model's flat order, is a cell of a table.
    let cells: Vec<bool> = model
        .effects()
        .iter()
        .flat_map(|e| std::iter::repeat_n(e.parameters_are_cells(), e.values().len()))
        .collect();
    for (i, name) in fit.parameter_names.iter().enumerate() {
        let effect = name.split('[').next().unwrap_or(name);
        let is_table = cells.get(i).copied().unwrap_or(false);
        match (fit.standard_errors[i], is_table) {
            (Some(se), true) => tables.entry(effect.to_string()).or_default().push(se),
            (Some(se), false) => {
                out += &format!(
                    "  {name:<12} {:>12.6} ± {:<10.6} {}\n",
                    values[i], se, fit.units[i]
                )
            }
            (None, _) => {}
        }
    }
    for (effect, mut se) in tables {
        se.sort_by(f64::total_cmp);
        out += &format!(
            "  {effect:<18} {} cells: median ± {:.5}°, largest ± {:.5}°\n",
            se.len(),
            se[se.len() / 2],
            se[se.len() - 1]
        );
    }
    let smoothed = fit
        .status
        .iter()
        .filter(|s| **s == Status::Smoothed)
        .count();
    if smoothed > 0 {
        out += &format!(
            "{smoothed} table cells without data were interpolated from their neighbours\n"
        );
    }
    let warnings = (r.physical.iter().cloned()).chain(fit.warnings.iter().map(|w| w.to_string()));
    for w in warnings {
        out += &format!("warning: {w}\n");
    }
    out
}
