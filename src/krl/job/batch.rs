//! A library of programs: find the programs under some directories, compensate them in
//! parallel (rayon over programs, and over targets inside large ones), write each program's
//! files atomically into a mirrored tree, and collect every failure without stopping the
//! others — the shape of `sd`: transform in parallel, then write atomically, report all.
//!
//! A `.src` whose routine is called by another program of its directory is a module (RoboDK
//! numbered files): it is compensated as part of its caller, not on its own. KRL files that
//! belong to no program (a lone `.dat`, an uncalled `.sub`) are copied unchanged so that the
//! output tree is a complete library; so is a program that is rejected, with a note beside it
//! saying why (`NAME.src.robopost-rejected.txt`).

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::diagnostic::Severity;
use crate::krl::{self, FileKind, StmtKind};

use super::files;
use super::program::{self, Calibrated, Report};

/// One program of the library and where its files go.
#[derive(Clone, Debug)]
pub struct Job {
    /// The `.src` (its `.dat` and modules are found beside it).
    pub src: PathBuf,
    /// Output path of the `.src`.
    pub out: PathBuf,
}

/// What happened to one program.
#[derive(Debug)]
pub enum Done {
    /// Written; `target_errors` targets were left unchanged by an error of their own.
    Written {
        report: Box<Report>,
        target_errors: usize,
        warnings: usize,
    },
    /// Rejected (parse error, unknown frame, …) or not readable/writable: nothing of it
    /// compensated; `kept`: what its place in the output tree holds.
    Failed { message: String, kept: Kept },
}

/// What a rejected program's place in the output tree holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kept {
    /// Its files copied unchanged, with the note of why (no output was there).
    Copied,
    /// The output an earlier run wrote, left as it was, with the note of why: a rejected
    /// program writes nothing over a good output.
    Earlier,
    /// Nothing (it could not be read, or the copy failed).
    Nothing,
}

/// The plan of a batch: programs to compensate and files to copy as they are.
#[derive(Debug, Default)]
pub struct Plan {
    pub jobs: Vec<Job>,
    pub copies: Vec<(PathBuf, PathBuf)>,
    /// Files that could not be read while planning.
    pub unreadable: Vec<(PathBuf, std::io::Error)>,
    /// Directories not entered because they were reached before (a link back up the tree,
    /// or a second link to one directory).
    pub skipped: Vec<PathBuf>,
}

fn is_krl(p: &Path) -> bool {
    p.extension().is_some_and(|e| {
        ["src", "dat", "sub"]
            .iter()
            .any(|k| e.eq_ignore_ascii_case(k))
    })
}

fn is_src(p: &Path) -> bool {
    p.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("src") || e.eq_ignore_ascii_case("sub"))
}

/// Device and inode of a directory (links followed), the identity a walk remembers.
#[cfg(unix)]
fn dir_id(dir: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(dir).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn dir_id(dir: &Path) -> Option<PathBuf> {
    dir.canonicalize().ok()
}

/// The KRL files under `dir`, sorted. A directory is entered once: a symbolic link back up
/// the tree (`loop -> ..`) or a second link to a directory already walked is skipped and
/// listed in `skipped`, so a loop cannot multiply the library.
fn walk<Id: Eq + std::hash::Hash>(
    dir: &Path,
    id: &impl Fn(&Path) -> Option<Id>,
    visited: &mut HashSet<Id>,
    out: &mut Vec<PathBuf>,
    skipped: &mut Vec<PathBuf>,
) -> std::io::Result<()> {
    if let Some(me) = id(dir) {
        if !visited.insert(me) {
            skipped.push(dir.to_path_buf());
            return Ok(());
        }
    }
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            walk(&p, id, visited, out, skipped)?;
        } else if is_krl(&p) {
            out.push(p);
        }
    }
    Ok(())
}

/// Routine names a program calls (upper case), or why it could not be read.
type Called = std::io::Result<HashSet<Vec<u8>>>;

/// Routine names called by a `.src` (upper case); its syntax errors are the compensation's
/// to report, so only a file that cannot be read fails.
fn calls(path: &Path) -> Called {
    let bytes = crate::input::read(path)?;
    let file = krl::parse_recovering(&bytes, FileKind::Src);
    let mut out = HashSet::new();
    for st in file.statements() {
        if let StmtKind::Call(c) = &st.kind {
            out.insert(file.text(c.name).to_ascii_uppercase());
        }
    }
    Ok(out)
}

/// Finds the programs under `inputs` (directories or single `.src` files), mirrored under
/// `out_dir`.
pub fn plan(inputs: &[PathBuf], out_dir: &Path) -> std::io::Result<Plan> {
    let mut plan = Plan::default();
    let mut visited = HashSet::new();
    for input in inputs {
        let (root, found) = if input.is_dir() {
            let mut v = Vec::new();
            walk(input, &dir_id, &mut visited, &mut v, &mut plan.skipped)?;
            (input.clone(), v)
        } else {
            let parent = input.parent().map(Path::to_path_buf).unwrap_or_default();
            let mut v = vec![input.clone()];
            if let Some(d) = krl::companion_dat(input) {
                v.push(d);
            }
            (parent, v)
        };
        let srcs: Vec<&PathBuf> = found.iter().filter(|p| is_src(p)).collect();
        let called: Vec<(PathBuf, Called)> =
            srcs.par_iter().map(|p| ((*p).clone(), calls(p))).collect();
        // Names called per directory.
        let mut by_dir: HashMap<PathBuf, HashSet<Vec<u8>>> = HashMap::new();
        for (p, c) in called {
            match c {
                Ok(names) => by_dir
                    .entry(p.parent().map(Path::to_path_buf).unwrap_or_default())
                    .or_default()
                    .extend(names),
                Err(e) => plan.unreadable.push((p, e)),
            }
        }
        let mirrored = |p: &Path| out_dir.join(p.strip_prefix(&root).unwrap_or(p));
        let mut taken: HashSet<PathBuf> = HashSet::new();
        for p in &srcs {
            let dir = p.parent().map(Path::to_path_buf).unwrap_or_default();
            let stem = p
                .file_stem()
                .map(|s| s.to_string_lossy().to_ascii_uppercase().into_bytes())
                .unwrap_or_default();
            let module = by_dir.get(&dir).is_some_and(|n| n.contains(&stem));
            if module || plan.unreadable.iter().any(|(u, _)| u == *p) {
                continue;
            }
            plan.jobs.push(Job {
                src: (*p).clone(),
                out: mirrored(p),
            });
            taken.insert((*p).clone());
            if let Some(d) = krl::companion_dat(p) {
                taken.insert(d);
            }
        }
        // Modules are written by their callers; anything else is copied.
        for p in &found {
            if taken.contains(p) {
                continue;
            }
            let stem_called =
                is_src(p) || p.extension().is_some_and(|e| e.eq_ignore_ascii_case("dat"));
            let dir = p.parent().map(Path::to_path_buf).unwrap_or_default();
            let stem = p
                .file_stem()
                .map(|s| s.to_string_lossy().to_ascii_uppercase().into_bytes())
                .unwrap_or_default();
            if stem_called && by_dir.get(&dir).is_some_and(|n| n.contains(&stem)) {
                continue;
            }
            plan.copies.push((p.clone(), mirrored(p)));
        }
    }
    Ok(plan)
}

/// Compensates one program (in the robot's `cell`, when given; `robot` names the robot in
/// messages) and writes its files atomically. A program rejected is copied unchanged, with
/// the note of why beside it.
pub fn run_job(
    job: &Job,
    cal: &Calibrated,
    options: &program::Options,
    cell: Option<&crate::krl::interpret::Cell>,
    robot: &str,
) -> Done {
    let failed = |message: String| {
        let kept = keep_unchanged(job, &message).unwrap_or(Kept::Nothing);
        Done::Failed { message, kept }
    };
    let bytes = match crate::input::read(&job.src) {
        Ok(b) => b,
        Err(e) => {
            return Done::Failed {
                message: format!("{}: {e}", job.src.display()),
                kept: Kept::Nothing,
            }
        }
    };
    let stream = Some(crate::krl::StreamOptions::default());
    let mut ws = match files::load_program_in(Some(&job.src), bytes, cell, stream) {
        Ok(ws) => ws,
        Err(e) => return failed(e.to_string()),
    };
    ws.robot = robot.to_string();
    ws.assumptions.clone_from(&options.assumptions);
    let result = program::compensate_program(&ws, cal, options);
    let warnings = result
        .diagnostics
        .iter()
        .filter(|d| d.severity == Severity::Warning)
        .count();
    if result.rejected {
        let text: Vec<String> = result
            .diagnostics
            .iter()
            .filter(|d| d.severity == Severity::Error)
            .map(|d| d.render())
            .collect();
        return failed(text.join("\n"));
    }
    if let Err(e) = files::no_stale_dat(&ws, &job.out) {
        return failed(e.to_string());
    }
    let outputs = files::outputs(&ws, &result.files, &job.out);
    if let Err(e) = files::write_atomic_pieces(&outputs) {
        return Done::Failed {
            message: format!("{e}; nothing of {} was written", job.out.display()),
            kept: Kept::Nothing,
        };
    }
    // A note of an earlier rejection no longer holds.
    let _ = std::fs::remove_file(rejected_note(&job.out));
    Done::Written {
        report: Box::new(result.report),
        target_errors: result.target_errors,
        warnings,
    }
}

/// The note written beside a rejected program in the output tree.
pub fn rejected_note(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_os_string();
    name.push(".robopost-rejected.txt");
    PathBuf::from(name)
}

/// A rejected program's place in the output tree: its files copied unchanged with the note
/// of why, all as one unit — or, where an earlier run left an output (`.src` or `.dat`),
/// that output left as it was and only the note written.
fn keep_unchanged(job: &Job, message: &str) -> Result<Kept, CopyError> {
    let dat = krl::companion_dat(&job.src).map(|dat| {
        let ext = dat
            .extension()
            .map(|e| e.to_os_string())
            .unwrap_or_default();
        let out = job.out.with_extension(ext);
        (dat, out)
    });
    let exists = |p: &Path| std::fs::symlink_metadata(p).is_ok();
    let earlier = exists(&job.out) || dat.as_ref().is_some_and(|(_, out)| exists(out));
    let path = rejected_note(&job.out);
    let write_err = |source| CopyError::Write {
        path: job.out.clone(),
        source,
    };
    if earlier {
        let note = format!(
            "robopost rejected this program: the output an earlier run wrote here is left as it was (it is not of the program as it is now).\n\n{message}\n"
        );
        files::write_atomic(&[(path, note.as_bytes())]).map_err(write_err)?;
        return Ok(Kept::Earlier);
    }
    let read = |p: &Path| {
        crate::input::read(p).map_err(|source| CopyError::Read {
            path: p.to_path_buf(),
            source,
        })
    };
    let src = read(&job.src)?;
    let dat_bytes = dat.as_ref().map(|(from, _)| read(from)).transpose()?;
    let note = format!(
        "robopost rejected this program: it is copied here unchanged (not compensated).\n\n{message}\n"
    );
    let mut unit = vec![(job.out.clone(), src.as_slice())];
    if let (Some((_, out)), Some(bytes)) = (&dat, &dat_bytes) {
        unit.push((out.clone(), bytes.as_slice()));
    }
    unit.push((path, note.as_bytes()));
    files::write_atomic(&unit).map_err(write_err)?;
    Ok(Kept::Copied)
}

/// Why a file could not be copied: the file and what the system said.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CopyError {
    /// The file to copy could not be read.
    #[error("{}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The copy could not be written (nothing was left half-written); the error names the
    /// file.
    #[error("{source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Copies a file atomically.
pub fn copy(from: &Path, to: &Path) -> Result<(), CopyError> {
    let bytes = crate::input::read(from).map_err(|source| CopyError::Read {
        path: from.to_path_buf(),
        source,
    })?;
    files::write_atomic(&[(to.to_path_buf(), bytes.as_slice())]).map_err(|source| {
        CopyError::Write {
            path: to.to_path_buf(),
            source,
        }
    })
}
