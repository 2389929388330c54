//! Reading a program from disk (the `.src`, the `.dat` beside it) into a [`Workspace`], where
//! each of its files goes on output, and writing them atomically: every file to a temporary
//! file in its target directory first, then all renamed, so a failure leaves no half-written
//! program (and never touches an input).

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::krl;
use crate::krl::interpret::workspace::{LoadError, Role};
use crate::krl::interpret::{Cell, FileId, Workspace};

use super::program::FileOutput;

/// Loads the program at `path` (or `bytes` read from standard input when `path` is `None`)
/// with its `.dat` and the `$config.dat`.
pub fn load_program(
    path: Option<&Path>,
    bytes: &[u8],
    config: Option<&Path>,
) -> Result<Workspace, LoadError> {
    load_program_streaming(path, bytes.to_vec(), config, None)
}

/// [`load_program`] taking the bytes, with the main routine's plain stretches left out of the
/// tree as runs when `stream` is given (see `krl::stream`): how the main job loads, so that a
/// long CAM program is never held as a whole tree.
pub fn load_program_streaming(
    path: Option<&Path>,
    bytes: Vec<u8>,
    config: Option<&Path>,
    stream: Option<krl::StreamOptions>,
) -> Result<Workspace, LoadError> {
    let cell = config.map(|c| Cell {
        config: Some(c.to_path_buf()),
        ..Cell::default()
    });
    load_program_in(path, bytes, cell.as_ref(), stream)
}

/// [`load_program_streaming`] in the robot's cell (`--cell`, `--config`): its shared data
/// and the modules it defines.
pub fn load_program_in(
    path: Option<&Path>,
    bytes: Vec<u8>,
    cell: Option<&Cell>,
    stream: Option<krl::StreamOptions>,
) -> Result<Workspace, LoadError> {
    let name = path.map_or_else(|| "<stdin>".to_string(), |p| p.display().to_string());
    let dat = match path.and_then(krl::companion_dat) {
        Some(d) => {
            let shown = d.display().to_string();
            let b = crate::input::read(&d).map_err(|source| LoadError::Io {
                name: shown.clone(),
                source,
            })?;
            Some((b, d, shown))
        }
        None => None,
    };
    Workspace::load_streaming(
        (bytes, path, &name),
        dat.as_ref()
            .map(|(b, d, s)| (b.as_slice(), d.as_path(), s.as_str())),
        cell,
        stream,
    )
}

/// Files from this size on are read in two halves at once (see [`read_program`]).
const READ_IN_HALVES: u64 = 8 << 20;

/// The bytes of the program at `path`. A long one is read in two halves in parallel, each
/// thread faulting in and copying its half of the buffer (a 67 MB program: 40 ms on one
/// thread, most of it the kernel's page faults); a file that grows meanwhile is read to its
/// end, one that shrinks is an error.
pub fn read_program(path: &Path) -> std::io::Result<Vec<u8>> {
    #[cfg(unix)]
    {
        use std::io::{Read, Seek};
        use std::os::unix::fs::FileExt;
        let mut file = std::fs::File::open(path)?;
        let meta = file.metadata()?;
        let len = meta.len();
        if meta.is_file() && len > crate::input::limit() {
            return Err(crate::input::too_large(crate::input::limit()));
        }
        if len >= READ_IN_HALVES && meta.is_file() {
            let mut buf = vec![0u8; len as usize];
            let (a, b) = buf.split_at_mut(len as usize / 2);
            let half = a.len() as u64;
            let (ra, rb) = rayon::join(|| file.read_exact_at(a, 0), || file.read_exact_at(b, half));
            ra?;
            rb?;
            file.seek(std::io::SeekFrom::Start(len))?;
            file.read_to_end(&mut buf)?;
            return Ok(buf);
        }
    }
    crate::input::read(path)
}

/// Where each output file goes when the main program is written to `out`: its `.dat` beside
/// it with the same stem, called modules beside it under their own names.
pub fn output_paths(ws: &Workspace, out: &Path) -> Vec<(FileId, PathBuf)> {
    let dir = out.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut v = Vec::new();
    for (i, f) in ws.files.iter().enumerate() {
        let id = i as FileId;
        let path = match f.role {
            Role::Config => continue,
            Role::Main if id == ws.main => out.to_path_buf(),
            Role::Main => {
                let ext = f
                    .path
                    .as_deref()
                    .and_then(Path::extension)
                    .map_or("dat".into(), |e| e.to_string_lossy().into_owned());
                out.with_extension(ext)
            }
            Role::Module => match f.path.as_deref().and_then(Path::file_name) {
                Some(name) => dir.join(name),
                None => continue,
            },
        };
        v.push((id, path));
    }
    v
}

/// A `.dat` left beside the output of a program that has none (see [`no_stale_dat`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{} exists beside the output {}, but {program} has no .dat: the controller would load that data list with the new program; remove it or choose another output", dat.display(), output.display())]
pub struct StaleDat {
    /// The `.dat` found.
    pub dat: PathBuf,
    /// The `.src` that would be written.
    pub output: PathBuf,
    /// The program's name.
    pub program: String,
}

/// The rule that keeps a `.src` and its `.dat` one unit on output: both are written (an
/// unchanged `.dat` too) or neither. A program without a `.dat` may therefore not be written
/// beside a `.dat` of its output name (left by an earlier run, or someone else's): the
/// controller would load that data list with the new program. That is refused, not removed.
pub fn no_stale_dat(ws: &Workspace, out: &Path) -> Result<(), StaleDat> {
    for (id, path) in output_paths(ws, out) {
        let f = ws.get(id);
        let is_src = f.file.kind() == krl::FileKind::Src;
        if !is_src || f.partner.is_some() {
            continue;
        }
        let stale = ["dat", "DAT", "Dat"]
            .iter()
            .map(|e| path.with_extension(e))
            .find(|d| std::fs::symlink_metadata(d).is_ok());
        if let Some(dat) = stale {
            return Err(StaleDat {
                dat,
                output: path,
                program: f.name.to_string(),
            });
        }
    }
    Ok(())
}

/// Writes every `(path, bytes)` as one unit (see [`write_atomic_pieces`]).
pub fn write_atomic(files: &[(PathBuf, &[u8])]) -> std::io::Result<()> {
    let pieces: Vec<(PathBuf, Vec<&[u8]>)> =
        files.iter().map(|(p, b)| (p.clone(), vec![*b])).collect();
    write_atomic_pieces(&pieces)
}

/// [`write_atomic`] of files given in pieces (see `program::Output`): every file to its
/// temporary file, synced, then all renamed as one unit ([`crate::atomic_unit`]): a reader
/// or a rerun never finds a `.src` and a `.dat` from two runs. An error names the file that
/// failed (a full disk: the `.dat` or the `.src` that did not fit).
pub fn write_atomic_pieces(files: &[(PathBuf, Vec<&[u8]>)]) -> std::io::Result<()> {
    use crate::atomic_unit::{self, Staged, WriteError};
    let mut staged = Vec::with_capacity(files.len());
    for (path, pieces) in files {
        let tmp = crate::atomic_file::temp_beside(path).map_err(WriteError::at(path))?;
        write_pieces(tmp.as_file(), pieces).map_err(WriteError::at(path))?;
        staged.push(Staged { tmp, dest: path });
    }
    atomic_unit::commit(staged)?;
    Ok(())
}

/// Files from this size on are written in two halves at once (see [`write_pieces`]).
const WRITE_IN_HALVES: usize = 8 << 20;

/// Writes `pieces` in order into the empty `file`. A long output is written as two halves at
/// their offsets, one per thread: the kernel's copying into the page cache is most of the
/// write (a 67 MB program: 25 ms on one thread).
fn write_pieces(file: &std::fs::File, pieces: &[&[u8]]) -> std::io::Result<()> {
    let total: usize = pieces.iter().map(|p| p.len()).sum();
    let write_from = |mut at: u64, part: &[&[u8]]| -> std::io::Result<()> {
        let mut w = std::io::BufWriter::with_capacity(1 << 20, Positioned { file, at: &mut at });
        for p in part {
            w.write_all(p)?;
        }
        w.flush()
    };
    if total < WRITE_IN_HALVES || cfg!(not(unix)) {
        return write_from(0, pieces);
    }
    // The first piece that ends past the middle starts the second half.
    let mut before = 0;
    let split = pieces
        .iter()
        .position(|p| {
            before += p.len();
            before > total / 2
        })
        .map_or(pieces.len(), |i| i + 1);
    let offset: usize = pieces[..split].iter().map(|p| p.len()).sum();
    let (a, b) = rayon::join(
        || write_from(0, &pieces[..split]),
        || write_from(offset as u64, &pieces[split..]),
    );
    a.and(b)
}

/// A file written from offset `at` on (positioned writes: two may fill one file at once).
struct Positioned<'a> {
    file: &'a std::fs::File,
    at: &'a mut u64,
}

impl Write for Positioned<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        #[cfg(unix)]
        let n = std::os::unix::fs::FileExt::write_at(self.file, buf, *self.at)?;
        #[cfg(not(unix))]
        let n = {
            use std::io::Seek;
            let mut f = self.file;
            f.seek(std::io::SeekFrom::Start(*self.at))?;
            f.write(buf)?
        };
        *self.at += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The files of a compensated program with their output paths.
pub fn outputs<'a>(
    ws: &Workspace,
    files: &'a [FileOutput],
    out: &Path,
) -> Vec<(PathBuf, Vec<&'a [u8]>)> {
    let paths = output_paths(ws, out);
    files
        .iter()
        .filter_map(|f| {
            paths
                .iter()
                .find(|(id, _)| *id == f.file)
                .map(|(_, p)| (p.clone(), f.bytes.pieces()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A program long enough to be read in halves (an odd length, so the halves differ) and a
    /// short one read plainly give the file's bytes.
    #[test]
    fn read_program_gives_the_bytes_whole() {
        let dir = tempfile::tempdir().unwrap();
        for len in [READ_IN_HALVES as usize + 12_345, 1_000] {
            let bytes: Vec<u8> = (0..len).map(|i| (i * 7 + i / 4099) as u8).collect();
            let path = dir.path().join(format!("p{len}.src"));
            std::fs::write(&path, &bytes).unwrap();
            assert!(read_program(&path).unwrap() == bytes, "{len} bytes");
        }
        assert!(read_program(&dir.path().join("missing.src")).is_err());
    }

    /// A long output written in two halves at once and a short one written plainly hold the
    /// pieces in order (pieces of uneven sizes, empty ones, one longer than half the total).
    #[test]
    fn write_pieces_puts_every_piece_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let big: Vec<u8> = (0..WRITE_IN_HALVES + 999)
            .map(|i| (i % 251) as u8)
            .collect();
        let small: Vec<Vec<u8>> = (0..3000)
            .map(|i| vec![(i % 256) as u8; (i * 37) % 5000])
            .collect();
        let mut cases: Vec<Vec<&[u8]>> = vec![small.iter().map(|p| p.as_slice()).collect()];
        cases.push(cases[0].iter().copied().chain([big.as_slice()]).collect());
        cases.push([big.as_slice(), b"", b"tail"].to_vec());
        cases.push(vec![b"only a little".as_slice()]);
        for (k, pieces) in cases.iter().enumerate() {
            let path = dir.path().join(format!("out{k}"));
            let file = std::fs::File::create(&path).unwrap();
            write_pieces(&file, pieces).unwrap();
            drop(file);
            assert!(std::fs::read(&path).unwrap() == pieces.concat(), "case {k}");
        }
    }
}
