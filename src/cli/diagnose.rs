//! `robopost diagnose -c CAL.json MEAS.csv... [--json]`: which effect of the contract table
//! the calibration is missing, with the evidence and the command that adds it.

use std::path::PathBuf;

use super::compare::load_inputs;
use super::Exit;
use crate::diagnose::{self, DiagnoseOptions, Diagnosis};
use crate::model::expand_list;

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
    let Some((cals, data)) = load_inputs(&[args.cal.as_path()], &args.measurements) else {
        return Exit::Usage;
    };
    let options = DiagnoseOptions {
        folds: args.folds as usize,
        only,
    };
    let d = match diagnose::diagnose(&cals[0], &data, &options) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("error: {e}");
            return Exit::Usage;
        }
    };
    if args.json {
        match serde_json::to_string_pretty(&d) {
            Ok(s) => println!("{s}"),
            Err(e) => {
                eprintln!("error: {e}");
                return Exit::Usage;
            }
        }
    } else {
        print!("{}", text(&d, &args));
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
    }
    if d.candidates.len() > 1 {
        out += "   (Add the first finding and diagnose again: the smaller ones often explain part of the same residual.)\n";
    }
    let rest: Vec<String> = d
        .considered
        .iter()
        .filter(|f| !f.significant && f.not_evaluated.is_none())
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
    out += &format!("\n{}\n", d.verdict);
    out
}
