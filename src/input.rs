//! Reading an input file with a size limit: `/dev/zero`, a pipe that never ends or a file far
//! larger than any program or measurement campaign is refused once the limit is passed,
//! instead of being read into memory until the machine runs out of it. The limit is 1 GiB
//! (a program of a million motions is 67 MB, a campaign of a million rows 90 MB);
//! `ROBOPOST_MAX_INPUT_MB` sets another.

use std::io::{self, Read};
use std::path::Path;

/// The default limit, in MiB.
const DEFAULT_MIB: u64 = 1024;

/// The limit in bytes (`ROBOPOST_MAX_INPUT_MB`, else [`DEFAULT_MIB`]).
pub fn limit() -> u64 {
    std::env::var("ROBOPOST_MAX_INPUT_MB")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(DEFAULT_MIB)
        .saturating_mul(1 << 20)
}

/// The error of an input past the limit.
pub fn too_large(limit: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "larger than {} MiB, the limit for an input (is it the file meant? ROBOPOST_MAX_INPUT_MB sets another limit)",
            limit >> 20
        ),
    )
}

/// Everything `reader` gives, up to the limit.
pub fn read_all(reader: impl Read) -> io::Result<Vec<u8>> {
    let limit = limit();
    let mut buf = Vec::new();
    reader.take(limit.saturating_add(1)).read_to_end(&mut buf)?;
    if buf.len() as u64 > limit {
        return Err(too_large(limit));
    }
    Ok(buf)
}

/// The bytes of the file at `path`, up to the limit (a regular file past it is refused
/// before reading).
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    if meta.is_file() && meta.len() > limit() {
        return Err(too_large(limit()));
    }
    let mut reader = io::BufReader::with_capacity(1 << 16, file);
    if meta.is_file() {
        // Read straight into a buffer of the file's size.
        let mut buf = Vec::with_capacity(meta.len() as usize);
        reader
            .get_mut()
            .take(limit().saturating_add(1))
            .read_to_end(&mut buf)?;
        if buf.len() as u64 > limit() {
            return Err(too_large(limit()));
        }
        return Ok(buf);
    }
    read_all(reader)
}

/// [`read`] as text (UTF-8).
pub fn read_to_string(path: &Path) -> io::Result<String> {
    let bytes = read(path)?;
    if is_utf16(&bytes) {
        return Err(io::Error::new(io::ErrorKind::InvalidData, UTF16));
    }
    String::from_utf8(bytes)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, format!("not UTF-8 text: {e}")))
}

/// What a file saved as UTF-16 is told.
pub const UTF16: &str =
    "the file is text saved as UTF-16 (\"Unicode\"): save it as UTF-8 text (e.g. in Notepad: Save as, Encoding UTF-8)";

/// Whether `bytes` are text saved as UTF-16 (Windows editors' "Unicode"): a byte order mark,
/// or a NUL in nearly every other byte of the start.
pub fn is_utf16(bytes: &[u8]) -> bool {
    if bytes.starts_with(&[0xff, 0xfe]) || bytes.starts_with(&[0xfe, 0xff]) {
        return true;
    }
    let head = &bytes[..bytes.len().min(256)];
    let pairs = head.len() / 2;
    let nul_at = |k: usize| {
        head.chunks_exact(2)
            .filter(|p| p[k] == 0 && p[1 - k] != 0)
            .count()
    };
    pairs >= 4 && (nul_at(1) * 10 >= pairs * 9 || nul_at(0) * 10 >= pairs * 9)
}

/// Standard input, up to the limit.
pub fn stdin() -> io::Result<Vec<u8>> {
    read_all(io::stdin().lock())
}
