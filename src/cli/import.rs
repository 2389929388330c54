//! `robopost import EXPORT... --plan PLAN.csv -o MEAS.csv [--units mm|m|inch] [--allow-missing]`
//! and `robopost import STREAM --plan PLAN.csv --stream [--dwell S] [--radius MM] -o MEAS.csv`:
//! a tracker package's export joined to the campaign's plan into the measurement CSV, with a
//! summary of what was seen and matched on standard error. Thin over `crate::measure`.

use std::path::PathBuf;

use super::Exit;
use crate::measure::export::{parse_export, Export, Unit};
use crate::measure::join::{self, DwellRule};
use crate::measure::plan::parse_plan;
use crate::measure::{write_csv, MeasureError};

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Units {
    Mm,
    M,
    Inch,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The tracker package's exports (point name, X, Y, Z [, time]), or with --stream one
    /// stream (time, X, Y, Z).
    #[arg(required = true)]
    pub exports: Vec<PathBuf>,
    /// The campaign's plan (test, point, a1..a6 [, t]), as `robopost campaign` writes it.
    #[arg(long)]
    pub plan: PathBuf,
    /// Measurement CSV to write, `-` for stdout.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// The unit of the exports' coordinates when they do not state it (default mm).
    #[arg(long, value_enum)]
    pub units: Option<Units>,
    /// Write a planned point that no export has as visited but not measured (else an error).
    #[arg(long = "allow-missing")]
    pub allow_missing: bool,
    /// The export is a continuous stream: find its dwells and match them to the plan's
    /// measured stops in order.
    #[arg(long)]
    pub stream: bool,
    /// Shortest dwell of a stream, seconds.
    #[arg(long, default_value_t = 1.0)]
    pub dwell: f64,
    /// How far a sample may stray from its dwell's mean and still be still, mm.
    #[arg(long, default_value_t = 0.05)]
    pub radius: f64,
}

fn print_errors(errors: &[MeasureError]) -> Exit {
    for e in errors {
        eprint!("{}", e.render());
    }
    Exit::Usage
}

pub fn run(args: Args) -> Exit {
    if !(args.dwell > 0.0 && args.radius > 0.0 && args.dwell.is_finite() && args.radius.is_finite())
    {
        return super::usage("--dwell and --radius must be positive");
    }
    if args.stream && args.exports.len() != 1 {
        return super::usage("--stream joins one stream to the plan");
    }
    let mut guard = crate::paths::Guard::new();
    guard
        .read_all(args.exports.iter().map(PathBuf::as_path))
        .read(&args.plan);
    if let Err(clash) = guard.write(&args.out) {
        return super::refuse(&clash);
    }
    let read = |path: &PathBuf| {
        std::fs::read(path).map_err(|e| MeasureError {
            file: path.display().to_string(),
            line: 0,
            col: 0,
            source_line: String::new(),
            message: format!("cannot read: {e}"),
            help: None,
        })
    };
    let plan = match read(&args.plan).and_then(|b| parse_plan(&b, &args.plan.display().to_string()))
    {
        Ok(p) => p,
        Err(e) => return print_errors(&[e]),
    };
    let unit = args.units.map(|u| match u {
        Units::Mm => Unit::Mm,
        Units::M => Unit::M,
        Units::Inch => Unit::Inch,
    });
    let mut exports: Vec<Export> = Vec::new();
    for path in &args.exports {
        match read(path)
            .and_then(|b| parse_export(&b, &path.display().to_string(), unit, args.stream))
        {
            Ok(e) => exports.push(e),
            Err(e) => return print_errors(&[e]),
        }
    }
    let joined = if args.stream {
        let rule = DwellRule {
            min_s: args.dwell,
            radius_mm: args.radius,
        };
        let found = match join::dwells(&exports[0], rule) {
            Ok(d) => d,
            Err(e) => return print_errors(&[e]),
        };
        eprintln!(
            "{}: {} samples ({}), {} dwells of at least {} s within {} mm",
            exports[0].source,
            exports[0].points.len(),
            exports[0].describe(),
            found.len(),
            args.dwell,
            args.radius
        );
        join::join_in_order(&plan, &exports[0], &found)
    } else {
        for e in &exports {
            eprintln!(
                "{}: {} points ({}; {} header lines skipped)",
                e.source,
                e.points.len(),
                e.describe(),
                e.skipped_lines
            );
        }
        join::join_by_name(&plan, &exports, args.allow_missing)
    };
    let joined = match joined {
        Ok(j) => j,
        Err(errors) => return print_errors(&errors),
    };
    let mut bytes = Vec::new();
    if let Err(e) = write_csv(&mut bytes, &joined.stops) {
        return super::usage(format!("cannot write: {e}"));
    }
    if let Err(e) = super::simulate::write_output(&args.out, &bytes) {
        return super::usage(format!("cannot write {}: {e}", args.out.display()));
    }
    eprintln!(
        "matched {} measured stops of {} by {}; {} approach rows{}; wrote {}",
        joined.matched,
        plan.source,
        if args.stream { "order" } else { "point name" },
        joined.approach,
        if joined.missing.is_empty() {
            String::new()
        } else {
            format!(
                "; {} planned points not measured ({})",
                joined.missing.len(),
                joined.missing.join(", ")
            )
        },
        args.out.display()
    );
    Exit::Success
}
