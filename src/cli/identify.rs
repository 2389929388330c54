//! `robopost identify MEAS.csv... -o CAL.json [--effects LIST] [--frame base|tracker]
//! [--map-pitch DEG] [-c OLD.json]`: identify a calibration from laser-tracker measurements
//! and print the fit report. `--effects +NAME` with `-c OLD.json` adds an effect to an
//! existing calibration and re-identifies. Thin over `crate::identify::pipeline`.

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;

use super::Exit;
use crate::identify::pipeline::{identify, Effects, Identified, Request, PAPER_EFFECTS};
use crate::identify::setup::GridChoice;
use crate::identify::{Progress, Status};
use crate::measure::read_csv;
use crate::model::expand_list;
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
    /// Measurement target in the flange frame, mm (`X,Y,Z`), when there is no `-c`.
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub target: Option<Vec<f64>>,
    /// Robot name written into the calibration.
    #[arg(long = "robot-name")]
    pub robot_name: Option<String>,
    /// Measurement files kept out of the fit, on which `-c OLD --effects +NAME` compares the
    /// old and the new model (besides held-out folds of the fit's data).
    #[arg(long = "validate", value_name = "FILE.csv")]
    pub validate: Vec<PathBuf>,
}

fn usage(message: &str) -> Exit {
    eprintln!("robopost identify: {message}");
    Exit::Usage
}

pub fn run(args: Args) -> Exit {
    if !(args.map_pitch.is_finite() && args.map_pitch > 0.0) {
        return usage("--map-pitch must be a positive number of degrees");
    }
    let mut stops = Vec::new();
    let mut files = Vec::new();
    for file in &args.files {
        match read_csv(file) {
            Ok(m) => {
                if !m.ignored_columns.is_empty() {
                    eprintln!(
                        "note: {}: ignored columns {}",
                        file.display(),
                        m.ignored_columns.join(", ")
                    );
                }
                stops.extend(m.stops.iter().cloned());
                files.push(m);
            }
            Err(e) => {
                eprint!("{}", e.render());
                return Exit::Usage;
            }
        }
    }
    let mut validation = Vec::new();
    for file in &args.validate {
        match read_csv(file) {
            Ok(m) => validation.push(m),
            Err(e) => {
                eprint!("{}", e.render());
                return Exit::Usage;
            }
        }
    }
    let base = match &args.cal {
        Some(path) => match crate::calibration::load(path) {
            Ok(c) => Some(c),
            Err(e) => return usage(&e.to_string()),
        },
        None => None,
    };
    let effects = match args.effects.as_deref() {
        None => None,
        Some(list) => {
            let items: Vec<&str> = list
                .split(',')
                .map(str::trim)
                .filter(|s| !s.is_empty())
                .collect();
            let adds = items.iter().filter(|s| s.starts_with('+')).count();
            if adds > 0 && adds < items.len() {
                return usage(
                    "--effects: either every name starts with `+` (add to -c) or none does",
                );
            }
            if adds > 0 && base.is_none() {
                return usage(
                    "--effects +NAME adds to an existing calibration: give it with -c OLD.json",
                );
            }
            let stripped: Vec<&str> = items.iter().map(|s| s.trim_start_matches('+')).collect();
            match expand_list(&stripped.join(",")) {
                Ok(names) if adds > 0 => Some(Effects::Add(names)),
                Ok(names) => Some(Effects::Exactly(names)),
                Err(e) => return usage(&format!("--effects: {e}")),
            }
        }
    };
    let target_mm = match args.target.as_deref() {
        None => None,
        Some([x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => Some([*x, *y, *z]),
        Some(_) => return usage("--target takes X,Y,Z in mm"),
    };
    let progress = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(30);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} refining {pos}/{len} {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
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
        progress: progress.clone().map(|bar| {
            Arc::new(move |p: &Progress| {
                bar.set_length(p.max_iterations as u64);
                bar.set_position(p.iteration as u64);
                bar.set_message(format!("rms {:.1} µm", p.rms_um));
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
    if let Err(e) = identified.calibration.save_atomic(&args.out) {
        return usage(&e.to_string());
    }
    print!(
        "{}",
        report(
            &identified,
            args.effects.as_deref().unwrap_or(PAPER_EFFECTS)
        )
    );
    println!("wrote {}", args.out.display());
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
        print!("{text}");
        if worse {
            eprintln!("warning: the new calibration predicts held-out data worse than the old one (see the promise check above)");
        }
    }
    Exit::Success
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
    out += &format!(
        "refinement: {} iterations ({}), σ per coordinate {:.1} µm\n",
        fit.iterations,
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
    out += &stats_row("after", &fit.stats);
    for (test, s) in &fit.per_test {
        out += &stats_row(&format!("  {test}"), s);
    }
    if let (Some(f), Some(se)) = (fit.tracker_frame, fit.tracker_frame_standard_errors) {
        let k = crate::calibration::KukaFrame::from_isometry(&f);
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
    for (i, name) in fit.parameter_names.iter().enumerate() {
        let effect = name.split('[').next().unwrap_or(name);
        let is_table = name.contains('[') && !effect.starts_with("tilt");
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
    for w in &fit.warnings {
        out += &format!("warning: {w}\n");
    }
    out
}
