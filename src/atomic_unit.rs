//! Several files of one directory written as one unit (a program's `.src`, its `.dat`, the
//! modules it calls): a reader, a rerun or a second run writing the same output never keeps
//! files from two runs. One rename is atomic, two are not, so the unit is committed with an
//! intent record:
//!
//! 1. every file is written to its temporary file (see [`crate::atomic_file`]) and synced;
//! 2. the directory is locked (`flock` on it, waited for: two runs writing the same output
//!    commit one after the other) and a record left by a killed run is completed first;
//! 3. the record — the list of (temporary name, final name) — is written, synced and renamed
//!    to `.robopost-commit-XXXXXX`: from here the unit is decided;
//! 4. the temporary files are renamed to their names, the directory synced, the record
//!    removed.
//!
//! A run killed before step 3 leaves the old files and its temporary files (removed as
//! stale); killed after, it leaves a record whose renames [`recover`] finishes: the next run
//! writing into the directory does so before anything else, and [`pending`] lets a reader
//! (`check`) say that a program's files are being written.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use tempfile::NamedTempFile;

use crate::atomic_file;

const RECORD_PREFIX: &str = ".robopost-commit-";
/// The record's last line: a record without it was cut short (its renames never began).
const RECORD_END: &[u8] = b"end\n";

/// Directories whose lock this process holds for its whole run (a batch's output directory):
/// its writes there are not locked again (the lock is per open file, so a second `flock`
/// would wait for the first forever), nor recovered per write (the batch recovers once,
/// before its jobs start).
static HELD: Mutex<Vec<(u64, u64)>> = Mutex::new(Vec::new());

/// A file of a unit written to its temporary file, and the name it takes.
pub struct Staged<'a> {
    pub tmp: NamedTempFile,
    pub dest: &'a Path,
}

/// Why a unit could not be written: the file concerned and what the system said.
#[derive(Debug, thiserror::Error)]
#[error("writing {}: {source}", path.display())]
pub struct WriteError {
    /// The file that could not be written.
    pub path: PathBuf,
    #[source]
    /// What the system said.
    pub source: io::Error,
}

impl WriteError {
    /// The error of writing `path`, for `map_err`.
    pub fn at(path: &Path) -> impl FnOnce(io::Error) -> WriteError + '_ {
        move |source| WriteError {
            path: path.to_path_buf(),
            source,
        }
    }
}

impl From<WriteError> for io::Error {
    fn from(e: WriteError) -> io::Error {
        io::Error::new(e.source.kind(), e.to_string())
    }
}

#[cfg(unix)]
fn dir_id(dir: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(dir).ok().map(|m| (m.dev(), m.ino()))
}

#[cfg(not(unix))]
fn dir_id(_dir: &Path) -> Option<(u64, u64)> {
    None
}

/// Notes that this process holds `dir`'s lock until it ends (see [`HELD`]).
pub fn hold(dir: &Path) {
    if let Some(id) = dir_id(dir) {
        HELD.lock().unwrap_or_else(|p| p.into_inner()).push(id);
    }
}

fn held(dir: &Path) -> bool {
    dir_id(dir).is_some_and(|id| HELD.lock().unwrap_or_else(|p| p.into_inner()).contains(&id))
}

/// `path`'s directory (`.` for a bare name).
pub fn dir_of(path: &Path) -> &Path {
    path.parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Syncs a directory's entries (a rename made durable). A file system that cannot sync a
/// directory is not an error: the files themselves are synced.
pub fn sync_dir(dir: &Path) {
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

/// An exclusive `flock` on `dir`, waited for; released when dropped.
fn lock(dir: &Path) -> io::Result<std::fs::File> {
    let d = std::fs::File::open(dir)?;
    #[cfg(unix)]
    {
        use std::os::unix::io::AsRawFd;
        loop {
            // SAFETY: `flock` on a descriptor this function owns.
            if unsafe { libc::flock(d.as_raw_fd(), libc::LOCK_EX) } == 0 {
                break;
            }
            let e = io::Error::last_os_error();
            if e.kind() != io::ErrorKind::Interrupted {
                return Err(e);
            }
        }
    }
    Ok(d)
}

/// Renames the staged files to their names as one unit (see the module's comment). Every
/// destination must lie in one directory. The temporary files are synced here.
pub fn commit(staged: Vec<Staged>) -> Result<(), WriteError> {
    for s in &staged {
        s.tmp.as_file().sync_all().map_err(WriteError::at(s.dest))?;
    }
    let Some(first) = staged.first() else {
        return Ok(());
    };
    let dir = dir_of(first.dest).to_path_buf();
    let _lock = if held(&dir) {
        None
    } else {
        // A file system without locks (some network mounts) still gets the record and the
        // recovery; only two runs at once are not kept apart there.
        let l = lock(&dir).ok();
        // A killed run's decided unit first: it must not land over this one later.
        recover(&dir).map_err(WriteError::at(&dir))?;
        l
    };
    if staged.len() == 1 {
        let s = staged.into_iter().next().expect("one file");
        let dest = s.dest;
        atomic_file::persist(s.tmp, dest).map_err(WriteError::at(dest))?;
        sync_dir(&dir);
        return Ok(());
    }
    let name = |p: &Path| p.file_name().map(|n| n.to_os_string()).unwrap_or_default();
    let mut record = Vec::new();
    for s in &staged {
        if dir_of(s.dest) != dir {
            return Err(WriteError {
                path: s.dest.to_path_buf(),
                source: io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "the files of a program must be written into one directory",
                ),
            });
        }
        record.extend_from_slice(name(s.tmp.path()).as_encoded_bytes());
        record.push(0);
        record.extend_from_slice(name(s.dest).as_encoded_bytes());
        record.push(0);
    }
    record.extend_from_slice(RECORD_END);
    let record_path = write_record(&dir, &record).map_err(WriteError::at(&dir))?;
    for s in staged {
        // A plain rename (not an exchange): a finished rename leaves no file at the temporary
        // name, so a recovery never renames an old file back.
        let dest = s.dest;
        let kept = s.tmp.into_temp_path();
        kept.persist(dest)
            .map_err(|e| WriteError::at(dest)(e.error))?;
    }
    sync_dir(&dir);
    let _ = std::fs::remove_file(&record_path);
    Ok(())
}

/// Writes the record (synced, then renamed to its name, the directory synced): its path.
fn write_record(dir: &Path, record: &[u8]) -> io::Result<PathBuf> {
    let mut tmp = atomic_file::temp_beside(&dir.join("x"))?;
    tmp.write_all(record)?;
    tmp.as_file().sync_all()?;
    let random = tmp
        .path()
        .file_name()
        .and_then(|n| n.to_str())
        .and_then(|n| n.strip_prefix(".robopost-"))
        .unwrap_or("000000")
        .to_string();
    let path = dir.join(format!("{RECORD_PREFIX}{random}"));
    tmp.persist_noclobber(&path).map_err(|e| e.error)?;
    sync_dir(dir);
    Ok(path)
}

fn is_record(name: &std::ffi::OsStr) -> bool {
    name.to_str().is_some_and(|n| n.starts_with(RECORD_PREFIX))
}

/// The (temporary, final) names of a record; `None` when it was cut short.
fn read_record(bytes: &[u8]) -> Option<Vec<(PathBuf, PathBuf)>> {
    let body = bytes.strip_suffix(RECORD_END)?;
    let fields: Vec<&[u8]> = body.split(|&b| b == 0).collect();
    // The body ends with a NUL: the last field is empty.
    let (last, pairs) = fields.split_last()?;
    if !last.is_empty() || pairs.len() % 2 != 0 {
        return None;
    }
    let path = |b: &[u8]| -> Option<PathBuf> {
        let s = std::str::from_utf8(b).ok()?;
        let p = PathBuf::from(s);
        // A name inside the directory, nothing else.
        (p.components().count() == 1 && !s.is_empty() && s != "." && s != "..").then_some(p)
    };
    pairs
        .chunks(2)
        .map(|c| Some((path(c[0])?, path(c[1])?)))
        .collect()
}

/// Finishes the units a killed run left decided but not renamed in `dir` (see the module's
/// comment) and returns the files completed. A record cut short is removed (its run never
/// began renaming: the old files stand). To be called by a writer holding `dir`'s lock.
pub fn recover(dir: &Path) -> io::Result<Vec<PathBuf>> {
    let mut done = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(done);
    };
    let mut found = false;
    for e in entries.flatten() {
        if !is_record(&e.file_name()) {
            continue;
        }
        found = true;
        let bytes = std::fs::read(e.path())?;
        for (tmp, dest) in read_record(&bytes).unwrap_or_default() {
            let from = dir.join(&tmp);
            if std::fs::symlink_metadata(&from).is_ok() {
                std::fs::rename(&from, dir.join(&dest))?;
                done.push(dir.join(dest));
            }
        }
        sync_dir(dir);
        std::fs::remove_file(e.path())?;
    }
    if found {
        sync_dir(dir);
    }
    Ok(done)
}

/// [`recover`] under `dir`'s lock (waited for), unless this process holds it already.
pub fn recover_locked(dir: &Path) -> io::Result<Vec<PathBuf>> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    let _lock = if held(dir) { None } else { Some(lock(dir)?) };
    recover(dir)
}

/// Whether a killed run's record in `path`'s directory names `path`: its files there may be
/// from two runs until the next run writing into the directory completes them.
pub fn pending(path: &Path) -> bool {
    let dir = dir_of(path);
    let Some(me) = path.file_name() else {
        return false;
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return false;
    };
    entries.flatten().any(|e| {
        is_record(&e.file_name())
            && std::fs::read(e.path())
                .ok()
                .and_then(|b| read_record(&b))
                .is_some_and(|pairs| pairs.iter().any(|(_, d)| d.as_os_str() == me))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn staged<'a>(dest: &'a Path, bytes: &[u8]) -> Staged<'a> {
        let mut tmp = atomic_file::temp_beside(dest).unwrap();
        tmp.write_all(bytes).unwrap();
        Staged { tmp, dest }
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        v.sort();
        v
    }

    /// A unit replaces both files and leaves nothing else behind.
    #[test]
    fn a_unit_is_written_whole() {
        let dir = tempfile::tempdir().unwrap();
        let (src, dat) = (dir.path().join("p.src"), dir.path().join("p.dat"));
        std::fs::write(&src, b"old src").unwrap();
        commit(vec![staged(&src, b"new src"), staged(&dat, b"new dat")]).unwrap();
        assert_eq!(std::fs::read(&src).unwrap(), b"new src");
        assert_eq!(std::fs::read(&dat).unwrap(), b"new dat");
        assert_eq!(names(dir.path()), ["p.dat", "p.src"]);
    }

    /// A run killed after deciding (the record written, one rename done) is finished by the
    /// next writer; a record cut short is dropped and the old files stand.
    #[test]
    fn a_decided_unit_is_finished_and_a_cut_record_dropped() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("p.src"), b"old src").unwrap();
        std::fs::write(d.join("p.dat"), b"old dat").unwrap();
        // Killed after renaming the .dat: the .src's temporary file is still there.
        std::fs::write(d.join("p.dat"), b"new dat").unwrap();
        std::fs::write(d.join(".robopost-Ab12Cd"), b"new src").unwrap();
        std::fs::write(
            d.join(".robopost-commit-Zz99Yy"),
            b".robopost-Ef34Gh\0p.dat\0.robopost-Ab12Cd\0p.src\0end\n",
        )
        .unwrap();
        assert!(pending(&d.join("p.src")));
        assert!(!pending(&d.join("q.src")));
        assert_eq!(recover(d).unwrap(), vec![d.join("p.src")]);
        assert_eq!(std::fs::read(d.join("p.src")).unwrap(), b"new src");
        assert_eq!(names(d), ["p.dat", "p.src"]);
        assert!(!pending(&d.join("p.src")));
        // Cut short: no end line; its temporary file is left for the stale clean-up.
        std::fs::write(d.join(".robopost-Ij56Kl"), b"newer src").unwrap();
        std::fs::write(d.join(".robopost-commit-Xx11Ww"), b".robopost-Ij56Kl\0p.s").unwrap();
        assert!(recover(d).unwrap().is_empty());
        assert_eq!(std::fs::read(d.join("p.src")).unwrap(), b"new src");
        assert_eq!(names(d), [".robopost-Ij56Kl", "p.dat", "p.src"]);
    }

    /// A record never names a file outside its directory.
    #[test]
    fn a_record_names_only_files_of_its_directory() {
        assert!(read_record(b"../x\0p.src\0end\n").is_none());
        assert!(read_record(b"a\0/etc/p\0end\n").is_none());
        assert!(read_record(b"a\0b\0c\0end\n").is_none());
        assert_eq!(
            read_record(b"a\0b\0end\n").unwrap(),
            vec![(PathBuf::from("a"), PathBuf::from("b"))]
        );
    }
}
