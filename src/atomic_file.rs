//! Writing a file so that a reader sees the old file or the whole new one, never a part: the
//! bytes go to a temporary file beside the destination, which then takes the destination's
//! name. Every file robopost writes (programs, calibrations, reports, simulated
//! measurements) goes through here, so all are made alike: an ordinary readable file (0644,
//! not the temporary file's private 0600), and on Linux an existing file replaced by
//! exchanging the two names and removing the old one. A plain rename over an existing file
//! makes ext4 (`auto_da_alloc`) allocate and start writing the new file's blocks inside the
//! rename: 40 ms for a 67 MB program, in the critical path of the main job.
//!
//! A run killed between the two steps leaves its temporary file (`.robopost-` and six
//! letters or digits); [`remove_stale`] removes such files, and only those, once they are
//! older than the run that finds them.

use std::io;
use std::path::Path;

use tempfile::NamedTempFile;

const TEMP_PREFIX: &str = ".robopost-";
const TEMP_RANDOM: usize = 6;

/// Whether `name` is one of this module's temporary files.
pub fn is_temporary(name: &std::ffi::OsStr) -> bool {
    let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(TEMP_PREFIX)) else {
        return false;
    };
    rest.len() == TEMP_RANDOM && rest.bytes().all(|b| b.is_ascii_alphanumeric())
}

/// Removes the temporary files of this module in `dir` last modified before `before` (left
/// by a run killed during its write; a live run's file is younger than the run that looks)
/// and returns their paths. Nothing else is touched; errors are ignored (a file another run
/// removed meanwhile, an unreadable directory).
pub fn remove_stale(dir: &Path, before: std::time::SystemTime) -> Vec<std::path::PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut removed = Vec::new();
    for e in entries.flatten() {
        if !is_temporary(&e.file_name()) {
            continue;
        }
        let old = e
            .metadata()
            .ok()
            .filter(std::fs::Metadata::is_file)
            .and_then(|m| m.modified().ok())
            .is_some_and(|t| t < before);
        if old && std::fs::remove_file(e.path()).is_ok() {
            removed.push(e.path());
        }
    }
    removed
}

/// An empty temporary file in `path`'s directory (created if missing), readable by all.
pub fn temp_beside(path: &Path) -> io::Result<NamedTempFile> {
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let tmp = tempfile::Builder::new()
        .prefix(TEMP_PREFIX)
        .rand_bytes(TEMP_RANDOM)
        .tempfile_in(dir)?;
    // A temporary file is private (0600); what robopost writes is an ordinary file.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))?;
    }
    Ok(tmp)
}

/// Gives `tmp` (written) the name `path`, atomically.
pub fn persist(tmp: NamedTempFile, path: &Path) -> io::Result<()> {
    #[cfg(target_os = "linux")]
    if exchange(tmp.path(), path) {
        // `tmp`'s name now holds the old file: dropping it removes it.
        drop(tmp);
        return Ok(());
    }
    tmp.persist(path).map(drop).map_err(|e| e.error)
}

/// `path` written with `bytes` (see [`temp_beside`], [`persist`]); the file is synced before
/// it takes the name and the directory after, so that a power cut leaves the old file or the
/// new one, not an empty one.
pub fn write(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut tmp = temp_beside(path)?;
    io::Write::write_all(&mut tmp, bytes)?;
    tmp.as_file().sync_all()?;
    persist(tmp, path)?;
    crate::atomic_unit::sync_dir(crate::atomic_unit::dir_of(path));
    Ok(())
}

/// Exchanges the names `new` and `old` where `old` is a regular file (not a directory or a
/// link, which a rename would replace rather than swap); false when not done (no such file,
/// or a file system without `RENAME_EXCHANGE`): the caller renames.
#[cfg(target_os = "linux")]
fn exchange(new: &Path, old: &Path) -> bool {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let is_file = std::fs::symlink_metadata(old).is_ok_and(|m| m.file_type().is_file());
    let (Ok(a), Ok(b)) = (
        CString::new(new.as_os_str().as_bytes()),
        CString::new(old.as_os_str().as_bytes()),
    ) else {
        return false;
    };
    // SAFETY: two NUL-terminated paths that live across the call; the call reads them only.
    is_file
        && unsafe {
            libc::renameat2(
                libc::AT_FDCWD,
                a.as_ptr(),
                libc::AT_FDCWD,
                b.as_ptr(),
                libc::RENAME_EXCHANGE,
            )
        } == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A new file and a replaced one get the bytes, are readable by all, and leave no
    /// temporary file (the old content is gone with the exchanged name).
    #[test]
    fn writes_new_and_replaced_files_whole_and_readable() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join("out.src");
        write(&path, b"first").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"first");
        write(&path, b"second, longer").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second, longer");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(mode & 0o777, 0o644);
        }
        let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("out.src")]);
    }

    /// Only this module's temporary files older than the given time are removed.
    #[test]
    fn removes_only_stale_temporary_files() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for name in [
            ".robopost-aB3xY9",
            ".robopost-short",
            "keep.src",
            ".robopost-aB3xY9z",
        ] {
            std::fs::write(d.join(name), b"x").unwrap();
        }
        assert!(remove_stale(d, std::time::SystemTime::UNIX_EPOCH).is_empty());
        let later = std::time::SystemTime::now() + std::time::Duration::from_secs(5);
        let removed = remove_stale(d, later);
        assert_eq!(removed, vec![d.join(".robopost-aB3xY9")]);
        let mut left: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        left.sort();
        assert_eq!(left, [".robopost-aB3xY9z", ".robopost-short", "keep.src"]);
        let tmp = temp_beside(&d.join("x.src")).unwrap();
        assert!(is_temporary(tmp.path().file_name().unwrap()));
    }

    /// A directory at the destination is not swapped away: the write fails and the directory
    /// stays.
    #[test]
    fn a_directory_in_the_way_is_an_error_and_stays() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.src");
        std::fs::create_dir(&path).unwrap();
        std::fs::write(path.join("keep"), b"x").unwrap();
        assert!(write(&path, b"bytes").is_err());
        assert_eq!(std::fs::read(path.join("keep")).unwrap(), b"x");
        let names = std::fs::read_dir(dir.path()).unwrap().count();
        assert_eq!(names, 1, "no temporary file left");
    }
}
