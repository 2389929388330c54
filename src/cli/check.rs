//! `robopost check FILE... [-c CAL.json]`: parse, simulate, report problems; writes nothing.
//!
//! Parse-only part: one summary line per file on stdout (motions, declared points, opaque
//! statements; a `.src` is checked together with the `.dat` beside it), then every problem on
//! stderr with file:line:col, the source line and a hint. Exit status per CONTRACTS.md: 0 all
//! files accepted, 1 some file has errors, 2 a file could not be read.

use super::Exit;
use crate::diagnostic::Severity;
use crate::krl::program::Program;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Programs to check (.src finds its .dat beside it; .dat alone is accepted).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Calibration: also simulate and compensate the motion, and report unreachable or
    /// near-singular targets (with `--cell`, `--config` or `--robot` the programs are
    /// simulated without one: what the walk resolves and what is missing).
    #[arg(short = 'c', long = "cal")]
    pub cal: Option<PathBuf>,
    #[command(flatten)]
    pub program: super::compensate::ProgramArgs,
}

pub fn run(args: Args) -> Exit {
    // A bad calibration is a usage error found before anything is printed.
    if let Some(cal) = &args.cal {
        if let Err(exit) = super::compensate::load_calibration(cal) {
            return exit;
        }
    }
    // With a calibration, a cell or a robot the programs are simulated too, and the walk says
    // what it could not resolve: the parse alone does not list undeclared names then (the
    // cell may declare them).
    let p = &args.program;
    let simulate =
        args.cal.is_some() || p.cell.is_some() || !p.config.is_empty() || p.robot.is_some();
    let mut exit = Exit::Success;
    let mut programs = Vec::new();
    // Programs that parsed without errors, simulated with -c (one with errors is already
    // reported and rejected: loading it again would print its errors twice).
    let mut to_simulate = Vec::new();
    // A .dat given explicitly after its .src is already checked with it.
    let mut companions: HashSet<PathBuf> = HashSet::new();
    for path in &args.files {
        if companions.contains(&canonical(path)) {
            continue;
        }
        match Program::load(path) {
            Ok(p) => {
                if let Some(d) = not_krl(&p) {
                    eprint!("{}", d.render());
                    exit = worse(exit, Exit::Usage);
                    continue;
                }
                if let Some(d) = &p.dat_path {
                    companions.insert(canonical(d));
                }
                if crate::atomic_unit::pending(path) {
                    eprintln!(
                        "warning: {}: a robopost run was killed while writing this program: its .src and .dat may be from two runs until the next run writing into its directory completes them",
                        path.display()
                    );
                }
                let (line, rejected) = summary(&p, !simulate);
                super::outln!("{line}");
                for d in p.diagnostics_with(!simulate) {
                    eprintln!("{}", d.render());
                }
                if rejected {
                    exit = worse(exit, Exit::Rejected);
                } else {
                    to_simulate.push(path.clone());
                }
                programs.push(p);
            }
            Err(e) => {
                eprintln!("error: {e}");
                exit = worse(exit, Exit::Usage);
            }
        }
    }
    if simulate {
        // Simulate (and compensate) in memory: what the walk resolves, unreachable,
        // out-of-limit and near-singular targets, nothing written.
        let sim =
            super::compensate::check_programs(&to_simulate, args.cal.as_deref(), &args.program);
        exit = worse(exit, sim);
    }
    exit
}

/// The first file of `p` that is not KRL at all, as a located error (see `krl::sniff`).
fn not_krl(p: &Program) -> Option<crate::diagnostic::Diagnostic> {
    let main = (&p.main, p.path.display().to_string());
    let dat = p.dat.as_ref().zip(p.dat_path.as_ref());
    let dat = dat.map(|(f, path)| (f, path.display().to_string()));
    [Some(main), dat]
        .into_iter()
        .flatten()
        .find_map(|(f, name)| crate::krl::not_krl(f).map(|problem| f.diagnostic(&problem, &name)))
}

/// The one-line summary of a program and whether it is rejected.
fn summary(p: &Program, undeclared: bool) -> (String, bool) {
    let mut st = p.main.stats();
    let mut name = p.path.display().to_string();
    if let (Some(dat), Some(dp)) = (&p.dat, &p.dat_path) {
        let ds = dat.stats();
        st.declared_points += ds.declared_points;
        st.opaque += ds.opaque;
        name += &format!(" (+ {})", file_name(dp));
    }
    let diags = p.diagnostics_with(undeclared);
    let errors = diags
        .iter()
        .filter(|d| d.severity == Severity::Error)
        .count();
    let warnings = diags.len() - errors;
    let mut line = format!(
        "{name}: {} motion{}, {} declared point{}, {} opaque statement{}",
        st.motions,
        plural(st.motions),
        st.declared_points,
        plural(st.declared_points),
        st.opaque,
        plural(st.opaque),
    );
    if errors > 0 {
        line += &format!(", {errors} error{}", plural(errors));
    }
    if warnings > 0 {
        line += &format!(", {warnings} warning{}", plural(warnings));
    }
    (line, errors > 0)
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

fn canonical(p: &Path) -> PathBuf {
    p.canonicalize().unwrap_or_else(|_| p.to_path_buf())
}

fn worse(a: Exit, b: Exit) -> Exit {
    if (b as i32) > (a as i32) {
        b
    } else {
        a
    }
}
