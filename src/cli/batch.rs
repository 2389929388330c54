//! `robopost batch IN_DIR... -c CAL.json -o OUT_DIR [--jobs N]`: compensate a library of
//! programs in parallel into a mirrored tree; a progress bar on a terminal, one summary line
//! per program on standard output and a total at the end, every failure reported without
//! stopping the others (a rejected program is copied into the tree unchanged, with a note
//! beside it saying why).

use std::collections::BTreeSet;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::compensate::{calibrated, cell_fitted, load_calibration, robot_label, ProgramArgs};
use super::Exit;
use crate::krl;
use crate::krl::job::batch::{self, Done, Kept};
use crate::krl::job::files;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Directories (searched recursively) or single programs.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Calibration file.
    #[arg(short = 'c', long = "cal")]
    pub cal: PathBuf,
    /// Output directory: the input tree is mirrored under it.
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
    /// Worker threads (default: one per core).
    #[arg(short = 'j', long = "jobs")]
    pub jobs: Option<usize>,
    /// Write a JSON summary of every program (per-program report without the point list).
    #[arg(long = "report", value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub program: ProgramArgs,
}

pub fn run(args: Args) -> Exit {
    let started = std::time::SystemTime::now();
    let (mut cal, cal_bytes) = match load_calibration(&args.cal) {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    let mut guard = crate::paths::Guard::new();
    guard
        .read(&args.cal)
        .read_all(args.program.config.iter().map(PathBuf::as_path));
    if let Some(cell) = &args.program.cell {
        guard.read_tree(cell);
    }
    let cell = match cell_fitted(&args.program, &mut cal, &args.cal) {
        Ok(c) => c,
        Err(exit) => return exit,
    };
    for input in &args.inputs {
        if std::fs::symlink_metadata(input).is_err() {
            return super::usage(format!("{}: no such file or directory", input.display()));
        }
        if input.is_dir() {
            guard.read_tree(input);
        } else {
            guard
                .read(input)
                .read_all(krl::companion_dat(input).as_deref());
        }
    }
    if let Err(clash) = guard.write_tree(&args.out) {
        return super::refuse(&clash);
    }
    if let Some(report) = &args.report {
        if let Err(clash) = guard.write(report) {
            return super::refuse(&clash);
        }
    }
    let pool = match rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
    {
        Ok(p) => p,
        Err(e) => return super::usage(format!("--jobs: {e}")),
    };
    let plan = match pool.install(|| batch::plan(&args.inputs, &args.out)) {
        Ok(p) => p,
        Err(e) => return super::usage(format!("reading the inputs: {e}")),
    };
    // A link inside the output tree must not lead a write back into an input.
    let outputs = plan.jobs.iter().map(|j| &j.out);
    for out in outputs.chain(plan.copies.iter().map(|(_, to)| to)) {
        if let Err(clash) = guard.write(out) {
            return super::refuse(&clash);
        }
    }
    let _lock = match lock(&args.out) {
        Ok(lock) => lock,
        Err(exit) => return exit,
    };
    let dirs: BTreeSet<&Path> = plan
        .jobs
        .iter()
        .map(|j| &j.out)
        .chain(plan.copies.iter().map(|(_, to)| to))
        .filter_map(|p| p.parent())
        .collect();
    // Programs a killed run had decided to write are finished first (their temporary files
    // are named in its record, see `atomic_unit`), then the rest of its temporary files go.
    // The output directory is locked for the whole run: its writes need no lock of their own.
    crate::atomic_unit::hold(&args.out);
    let mut finished = 0;
    for d in &dirs {
        match crate::atomic_unit::recover_locked(d) {
            Ok(done) => finished += done.len(),
            Err(e) => {
                return super::usage(format!(
                    "{}: completing an interrupted run's output: {e}",
                    d.display()
                ))
            }
        }
    }
    if finished > 0 {
        eprintln!(
            "note: completed {finished} file(s) of programs an interrupted run was writing in {}",
            args.out.display()
        );
    }
    let stale: Vec<PathBuf> = dirs
        .into_iter()
        .flat_map(|d| crate::atomic_file::remove_stale(d, started))
        .collect();
    if !stale.is_empty() {
        eprintln!(
            "note: removed {} temporary file(s) an interrupted run left in {} (robopost's own `.robopost-XXXXXX` files, older than this run), e.g. {}",
            stale.len(),
            args.out.display(),
            stale[0].display()
        );
    }
    for dir in &plan.skipped {
        eprintln!(
            "note: {}: skipped, a link to a directory already searched",
            dir.display()
        );
    }
    pool.install(|| run_in_pool(&args, &cal, &cal_bytes, &plan, cell.as_ref()))
}

/// The output directory (created) locked against a second batch writing into it at the same
/// time: an advisory `flock` on the directory itself, released when the value is dropped (or
/// the process ends), so nothing is left behind.
fn lock(out: &Path) -> Result<std::fs::File, Exit> {
    let fail = |e: std::io::Error| super::usage(format!("{}: {e}", out.display()));
    std::fs::create_dir_all(out).map_err(fail)?;
    let dir = std::fs::File::open(out).map_err(fail)?;
    #[cfg(unix)]
    {
        use std::os::unix::io::AsRawFd;
        // SAFETY: `flock` on a descriptor this function owns; it reads nothing else.
        if unsafe { libc::flock(dir.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() == std::io::ErrorKind::WouldBlock {
                return Err(super::usage(format!(
                    "{}: another robopost batch is writing into this directory; wait for it or choose another output",
                    out.display()
                )));
            }
            return Err(fail(e));
        }
    }
    Ok(dir)
}

fn run_in_pool(
    args: &Args,
    cal: &crate::calibration::Calibration,
    cal_bytes: &[u8],
    plan: &batch::Plan,
    cell: Option<&crate::krl::interpret::Cell>,
) -> Exit {
    let calibrated = calibrated(cal, &args.cal, cal_bytes);
    let options = args.program.options(true, false);
    let robot = robot_label(cal, &args.cal);
    let bar = if std::io::stderr().is_terminal() {
        let b = indicatif::ProgressBar::new((plan.jobs.len() + plan.copies.len()) as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} programs  {elapsed_precise}  {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    let failed_count = AtomicUsize::new(0);
    let done: Vec<(PathBuf, Done)> = plan
        .jobs
        .par_iter()
        .map(|job| {
            let d = batch::run_job(job, &calibrated, &options, cell, &robot);
            if matches!(d, Done::Failed { .. }) {
                let n = failed_count.fetch_add(1, Ordering::Relaxed) + 1;
                bar.set_message(format!("{n} failed"));
            }
            bar.inc(1);
            (job.src.clone(), d)
        })
        .collect();
    let copy_errors: Vec<String> = plan
        .copies
        .par_iter()
        .filter_map(|(from, to)| {
            let r = batch::copy(from, to).err().map(|e| e.to_string());
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    // One line per program on standard output, in the plan's order; the details on stderr.
    let mut exit = super::Exit::Success;
    let (mut written, mut targets, mut compensated, mut target_errors, mut warnings) =
        (0, 0, 0, 0, 0);
    let mut max_um: f64 = 0.0;
    let mut reports = Vec::new();
    for (path, d) in &done {
        match d {
            Done::Written {
                report,
                target_errors: te,
                warnings: w,
            } => {
                written += 1;
                targets += report.targets;
                compensated += report.compensated;
                target_errors += te;
                warnings += w;
                max_um = max_um.max(report.correction.position_um.max);
                super::outln!(
                    "{}: {}, {w} warning{}{}",
                    path.display(),
                    report.counts(),
                    if *w == 1 { "" } else { "s" },
                    report.taken_text()
                );
                if *te > 0 {
                    exit = super::Exit::Rejected;
                }
                reports.push(report.as_ref());
            }
            Done::Failed { message, kept } => {
                let first = message.lines().next().unwrap_or_default();
                match kept {
                    Kept::Copied => {
                        super::outln!("{}: rejected, copied unchanged ({first})", path.display())
                    }
                    Kept::Earlier => super::outln!(
                        "{}: rejected, the earlier output left as it was ({first})",
                        path.display()
                    ),
                    Kept::Nothing => {
                        super::outln!("{}: failed, nothing written ({first})", path.display())
                    }
                }
                eprintln!("{}: rejected\n{message}", path.display());
                exit = super::Exit::Rejected;
            }
        }
    }
    for (path, e) in &plan.unreadable {
        super::outln!("{}: unreadable ({e})", path.display());
        exit = super::Exit::Rejected;
    }
    for e in &copy_errors {
        eprintln!("error: {e}");
        exit = super::Exit::Rejected;
    }
    let failed = done.len() - written + plan.unreadable.len();
    eprintln!(
        "batch: {written} of {} programs written, {failed} rejected (copied unchanged where readable), {} other files copied; {compensated} of {targets} targets compensated, {target_errors} rejected (max correction {max_um:.1} µm), {warnings} warnings",
        done.len() + plan.unreadable.len(),
        plan.copies.len() - copy_errors.len(),
    );
    if let Some(path) = &args.report {
        let json = serde_json::json!({
            "programs": done.len() + plan.unreadable.len(),
            "written": written,
            "failed": failed,
            "targets": targets,
            "compensated": compensated,
            "rejected_targets": target_errors,
            "reports": reports,
            "failures": done.iter().filter_map(|(p, d)| match d {
                Done::Failed { message, kept } => Some(serde_json::json!({ "program": p.display().to_string(), "message": message, "copied_unchanged": *kept == Kept::Copied, "earlier_output_kept": *kept == Kept::Earlier })),
                _ => None,
            }).collect::<Vec<_>>(),
        });
        let text = serde_json::to_string_pretty(&json).unwrap_or_default() + "\n";
        if let Err(e) = files::write_atomic(&[(path.clone(), text.as_bytes())]) {
            eprintln!("error: writing {}: {e}", path.display());
            return super::Exit::Usage;
        }
    }
    exit
}
