//! The command-line interface: argument parsing (clap derive) and dispatch to one file per
//! subcommand. Thin on purpose: every command calls library code and only formats its results.
//!
//! `robopost IN.src -c CAL.json -o OUT.src` (no subcommand) is the main job; it is routed to
//! the `compensate` subcommand before clap sees the arguments.

use clap::{Parser, Subcommand};

pub mod batch;
pub mod budget;
pub mod campaign;
pub mod check;
pub mod compare;
pub mod compensate;
pub mod diagnose;
pub mod identify;
pub mod import;
pub mod instrument;
pub mod kin;
pub mod simulate;

/// Writes to standard output that fail (a full disk, `/dev/full`, a closed descriptor) are
/// remembered, not panicked on: the command finishes (a batch still writes its `--report`)
/// and [`main`] then says so and sets the exit status. `println!` would panic (exit 101).
static STDOUT_ERROR: std::sync::Mutex<Option<std::io::Error>> = std::sync::Mutex::new(None);

/// Writes `text` to standard output; the first failure is kept for [`main`].
pub fn write_stdout(text: std::fmt::Arguments) {
    use std::io::Write;
    let result = std::io::stdout().lock().write_fmt(text);
    if let Err(e) = result {
        remember_stdout_error(e);
    }
}

/// Records a failed write to standard output (the first one is reported).
pub fn remember_stdout_error(e: std::io::Error) {
    let mut kept = STDOUT_ERROR.lock().unwrap_or_else(|p| p.into_inner());
    kept.get_or_insert(e);
}

/// `print!` to standard output through [`write_stdout`].
macro_rules! out {
    ($($arg:tt)*) => { $crate::cli::write_stdout(format_args!($($arg)*)) };
}

/// `println!` to standard output through [`write_stdout`].
macro_rules! outln {
    ($($arg:tt)*) => { $crate::cli::write_stdout(format_args!("{}\n", format_args!($($arg)*))) };
}
pub(crate) use {out, outln};

/// Exit status per `docs/cli.md`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Exit {
    /// The job ran and every input was accepted.
    Success = 0,
    /// The job ran but some input was rejected (one file of a batch, unreachable targets).
    Rejected = 1,
    /// Usage error or unreadable input; nothing was written.
    Usage = 2,
}

/// A usage error: `error: message` on standard error, exit 2 (nothing written).
pub fn usage(message: impl std::fmt::Display) -> Exit {
    eprintln!("error: {message}");
    Exit::Usage
}

/// An output refused by the guard of [`crate::paths`]: exit 2, nothing written.
pub fn refuse(clash: &crate::paths::Clash) -> Exit {
    usage(clash)
}

#[derive(Parser, Debug)]
#[command(
    name = "robopost",
    version,
    about = "Compensate KUKA KRL programs with a calibrated robot error model"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Compensate one program (the default: `robopost IN.src -c CAL.json -o OUT.src`).
    Compensate(compensate::Args),
    /// Compensate a library of programs in parallel into a mirrored tree.
    Batch(batch::Args),
    /// Parse (and with -c simulate) programs and report problems; writes nothing.
    Check(check::Args),
    /// Flange pose of axis angles, nominal or as the calibrated model predicts.
    Fk(kin::FkArgs),
    /// Axis angles of every IK branch of a flange pose, or the selected one.
    Ik(kin::IkArgs),
    /// Compare a calibration's model with measurements: Table 1 statistics, HTML report.
    Compare(compare::Args),
    /// Which effect of the contract table the calibration is missing, with the evidence.
    Diagnose(diagnose::Args),
    /// The virtual robot: measurement campaigns and pose lists on a truth model.
    Simulate(simulate::Args),
    /// Identify a calibration from laser-tracker measurements.
    Identify(identify::Args),
    /// The measurement campaign for a real cell: a KRL program and its plan.
    Campaign(campaign::Args),
    /// Join a tracker package's export (or a stream) to a campaign's plan: the measurement CSV.
    Import(import::Args),
}

const SUBCOMMANDS: &[&str] = &[
    "compensate",
    "batch",
    "check",
    "simulate",
    "identify",
    "compare",
    "diagnose",
    "import",
    "campaign",
    "fk",
    "ik",
    "help",
];

/// Inserts the implicit `compensate` subcommand when the first argument is a program: not a
/// subcommand, and a file that exists or a name that looks like one (`-`, an extension, a
/// directory part). A bare word that is neither (`identfy`) is left to clap, which names the
/// subcommand meant ("a similar subcommand exists: 'identify'").
fn with_default_subcommand(mut args: Vec<String>) -> Vec<String> {
    if let Some(first) = args.get(1) {
        let is_flag = first.starts_with('-') && first != "-";
        let path = std::path::Path::new(first);
        let looks_like_a_file = first == "-"
            || path.extension().is_some()
            || first.contains(std::path::MAIN_SEPARATOR)
            || first.contains('/')
            || std::fs::symlink_metadata(path).is_ok();
        if !is_flag && !SUBCOMMANDS.contains(&first.as_str()) && looks_like_a_file {
            args.insert(1, "compensate".to_string());
        }
    }
    args
}

/// What a command left for the process's exit to free: freeing millions of syntax-tree nodes
/// one by one takes longer than the exit. The `robopost` binary exits without freeing them
/// ([`crate::exit_with_command_line`]); a caller that goes on frees them when the command
/// returns ([`crate::run_command_line`]), so that nothing leaks per call.
static LEFT_FOR_EXIT: std::sync::Mutex<Vec<Box<dyn Send>>> = std::sync::Mutex::new(Vec::new());

/// Leaves `value` to be freed after the command (see [`LEFT_FOR_EXIT`]).
pub(crate) fn free_after(value: impl Send + 'static) {
    LEFT_FOR_EXIT
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .push(Box::new(value));
}

/// Frees what the last commands left for the exit.
pub fn free_left() {
    let left = std::mem::take(&mut *LEFT_FOR_EXIT.lock().unwrap_or_else(|p| p.into_inner()));
    drop(left);
}

/// Runs the command line on `args` (the program's name first) and returns the exit status.
pub fn main(args: Vec<String>) -> i32 {
    let args = with_default_subcommand(args);
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() {
                Exit::Usage as i32
            } else {
                0
            };
            let _ = e.print();
            return code;
        }
    };
    // A batch's product is its output tree: a lost summary on standard output is a rejected
    // part of the job, not "nothing written".
    let stdout_lost = if matches!(cli.command, Command::Batch(_)) {
        Exit::Rejected
    } else {
        Exit::Usage
    };
    let exit = match cli.command {
        Command::Compensate(a) => compensate::run(a),
        Command::Batch(a) => batch::run(a),
        Command::Check(a) => check::run(a),
        Command::Fk(a) => kin::run_fk(a),
        Command::Ik(a) => kin::run_ik(a),
        Command::Compare(a) => compare::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Identify(a) => identify::run(a),
        Command::Import(a) => import::run(a),
        Command::Campaign(a) => campaign::run(a),
    };
    let flushed = std::io::Write::flush(&mut std::io::stdout().lock());
    if let Err(e) = flushed {
        remember_stdout_error(e);
    }
    let lost = STDOUT_ERROR
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .take();
    match lost {
        Some(e) => {
            eprintln!("error: writing standard output: {e}");
            exit.max(stdout_lost) as i32
        }
        None => exit as i32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(s: &[&str]) -> Vec<String> {
        s.iter().map(|x| x.to_string()).collect()
    }

    #[test]
    fn main_job_needs_no_subcommand() {
        assert_eq!(
            with_default_subcommand(v(&["robopost", "in.src", "-c", "cal.json"])),
            v(&["robopost", "compensate", "in.src", "-c", "cal.json"])
        );
        assert_eq!(
            with_default_subcommand(v(&["robopost", "-", "-c", "x"]))[1],
            "compensate"
        );
        assert_eq!(
            with_default_subcommand(v(&["robopost", "check", "a.src"]))[1],
            "check"
        );
        assert_eq!(
            with_default_subcommand(v(&["robopost", "--help"]))[1],
            "--help"
        );
        assert_eq!(
            with_default_subcommand(v(&["robopost", "cells/weld", "-c", "x"]))[1],
            "compensate"
        );
    }

    /// A mistyped subcommand gets clap's suggestion, not a "cannot read identfy" error.
    #[test]
    fn a_mistyped_subcommand_is_named() {
        let args = with_default_subcommand(v(&["robopost", "identfy", "m.csv", "-o", "c.json"]));
        assert_eq!(args[1], "identfy");
        let e = Cli::try_parse_from(args).unwrap_err().to_string();
        assert!(e.contains("similar subcommand exists: 'identify'"), "{e}");
    }
}
