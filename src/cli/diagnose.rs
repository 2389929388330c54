//! `robopost diagnose -c CAL.json MEAS.csv... [--json] [--report DIR]`: which effect of the
//! contract table the calibration is missing, with the evidence and the command that adds it,
//! and what the residual follows when none is (a `learned:` effect to add). A progress bar on
//! a terminal.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::Arc;

use super::compare::load_inputs;
use super::Exit;
use crate::diagnose::{self, DiagnoseOptions, Diagnosis, ProgressSink};
use crate::model::expand_list;
use crate::report::{self, ReportInput, ReportModel};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The calibration to diagnose.
    #[arg(short = 'c', long = "cal")]
    pub cal: PathBuf,
    /// Measurement CSV files (laser tracker data), `-` for stdin.
    #[arg(required = true)]
    pub measurements: Vec<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Try only these effects (comma-separated list, `A1..A6` expands); default: every effect
    /// of the table the calibration lacks.
    #[arg(long, value_name = "LIST")]
    pub only: Option<String>,
    /// Folds of the cross-validation.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(2..=20))]
    pub folds: u32,
    /// Do not learn the drivers of the residual (faster; no `learned:` effect proposed).
    #[arg(long = "no-learn")]
    pub no_learn: bool,
    /// Measurements taken elsewhere in the workspace and later than the campaign: the first
    /// advice is identified as printed and credited with its gain on them (not given where it
    /// does not lower their error), and the drivers where they leave the campaign's range are
    /// named.
    #[arg(long = "validate", value_name = "FILE.csv")]
    pub validate: Vec<PathBuf>,
    /// Also write the HTML report (as `compare --report`, with the learned drivers) into DIR.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub instrument: super::instrument::TrackerArgs,
}

pub fn run(args: Args) -> Exit {
    let only = match args.only.as_deref().map(expand_list) {
        None => None,
        Some(Ok(names)) => Some(names),
        Some(Err(e)) => {
            eprintln!("error: --only: {e}");
            return Exit::Usage;
        }
    };
    let tracker = match args.instrument.tracker() {
        Ok(t) => t,
        Err(exit) => return exit,
    };
    let Some((cals, data)) = load_inputs(&[args.cal.as_path()], &args.measurements) else {
        return Exit::Usage;
    };
    let limits = cals[0].model_ref().robot.limits_deg;
    let mut validate = Vec::new();
    for file in &args.validate {
        match crate::measure::read_csv_within(file, Some(&limits)) {
            Ok(m) => validate.push(m),
            Err(e) => {
                eprint!("{}", e.render());
                return Exit::Usage;
            }
        }
    }
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(1);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {msg} {pos}/{len} [{elapsed}]")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
        bar
    });
    let options = DiagnoseOptions {
        folds: args.folds as usize,
        only,
        learn: !args.no_learn,
        tracker,
        validate,
        progress: bar.clone().map(|bar| {
            ProgressSink(Arc::new(move |stage: &str, done: usize, of: usize| {
                bar.set_message(stage.to_string());
                bar.set_length(of as u64);
                bar.set_position(done as u64);
            }))
        }),
        ..DiagnoseOptions::default()
    };
    let result = diagnose::diagnose(&cals[0], &data, &options);
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let d = match result {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {e}");
            return Exit::Usage;
        }
    };
    if let Some(dir) = &args.report {
        let rows = crate::compare::compare(&cals[0], &data);
        let label = args.cal.file_name().map_or_else(
            || args.cal.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        let input = ReportInput {
            models: vec![ReportModel {
                label: &label,
                model: cals[0].model_ref(),
                rows: &rows,
            }],
            gross_errors: Vec::new(),
            sources: args
                .measurements
                .iter()
                .map(|p| p.display().to_string())
                .collect(),
            learned: d.learned.as_ref(),
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
        match serde_json::to_string_pretty(&d) {
            Ok(s) => super::outln!("{s}"),
            Err(e) => {
                eprintln!("error: {e}");
                return Exit::Usage;
            }
        }
    } else {
        super::out!("{}", text(&d, &args));
    }
    Exit::Success
}

fn text(d: &Diagnosis, args: &Args) -> String {
    let files: Vec<String> = args
        .measurements
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let mut out = format!(
        "{} points, residual {:.1} µm RMS, noise floor {:.1} µm ({})\n\n",
        d.points,
        d.rms_um,
        d.noise_um,
        d.noise_source.describe()
    );
    if d.duplicates > 0 {
        out += &format!(
            "{} rows are exact copies of another row (same angles, same position to the last \
             digit: a row pasted twice or a file given twice?); they are not repeated \
             measurements and were left out.\n",
            d.duplicates
        );
    }
    if let Some(why) = &d.screened {
        out += &format!("{why}.\n");
    }
    if d.duplicates > 0 || d.screened.is_some() {
        out += "\n";
    }
    if d.candidates.is_empty() {
        out += "No significant finding.\n";
    }
    for (i, f) in d.candidates.iter().enumerate() {
        out += &format!(
            "{}. {:<20} explains {:>3.0}%  → {:.1} µm RMS\n   {}\n   robopost identify -c {} {} {} -o NEW.json\n",
            i + 1,
            f.effect,
            100.0 * f.explained,
            f.rms_after_um,
            f.evidence,
            args.cal.display(),
            files.join(" "),
            f.add
        );
        if let Some(g) = &f.validation {
            out += &format!(
                "   on the validation data ({} points): {:.1} → {:.1} µm RMS ({:+.0}%)\n",
                g.points,
                g.rms_before_um,
                g.rms_after_um,
                100.0 * g.explained()
            );
        }
    }
    if d.candidates.len() > 1 {
        out += "   (Add the first finding and diagnose again: the smaller ones often explain part of the same residual.)\n";
    }
    for f in d.considered.iter().filter(|f| f.vetoed.is_some()) {
        out += &format!(
            "Not a finding: {} explains {:.0}% of held-out stretches, but {}\n",
            f.effect,
            100.0 * f.explained,
            f.vetoed.as_deref().unwrap_or_default()
        );
    }
    let rest: Vec<String> = d
        .considered
        .iter()
        .filter(|f| !f.significant && f.not_evaluated.is_none() && f.vetoed.is_none())
        .take(5)
        .map(|f| format!("{} {:+.0}%", f.effect, 100.0 * f.explained))
        .collect();
    if !rest.is_empty() {
        out += &format!(
            "\nNot significant (best of {} tried): {}\n",
            d.considered.len(),
            rest.join(", ")
        );
    }
    let unobserved: Vec<&str> = d
        .considered
        .iter()
        .filter(|f| f.not_evaluated.is_some())
        .map(|f| f.effect.as_str())
        .collect();
    if !unobserved.is_empty() {
        out += &format!(
            "Not observable in these measurements: {}\n",
            unobserved.join(", ")
        );
    }
    if let Some(l) = &d.learned {
        out += &format!(
            "\nLearned from the residual: it {}.\n   {} ({} parameters) explains {:.0}% of \
             held-out stretches (→ {:.1} µm RMS){}\n",
            l.shape,
            l.effect,
            l.parameters,
            100.0 * l.explained.max(0.0),
            l.rms_after_um,
            if l.stable {
                ", stable across the folds"
            } else {
                ", not stable across the folds"
            }
        );
        for c in &l.checks {
            out += &format!("   {}\n", c.describe());
        }
        match &l.vetoed {
            None => {
                out += &format!(
                    "   robopost identify -c {} {} {} -o NEW.json\n",
                    args.cal.display(),
                    files.join(" "),
                    l.add
                )
            }
            Some(why) => out += &format!("   not a finding: {why}\n"),
        }
    }
    out += &format!("\n{}\n", d.verdict);
    out
}
