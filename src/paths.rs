//! Where a command may write: never onto a file it reads. Every command lists the paths it
//! reads ([`Guard::read`], or [`Guard::read_tree`] for a directory whose files it reads) and
//! asks before each write ([`Guard::write`]); a path written is refused when it names an input
//! after symlinks, `.`/`..` and hard links are resolved (same canonical path or same device and
//! inode), when it lies inside an input tree, when an input lies inside it (an output
//! directory), or when another output of the same run already goes there. `-` (standard input
//! or output) is never a file.

use std::fmt;
use std::path::{Component, Path, PathBuf};

/// A path as the file system resolves it: absolute, symlinks and `.`/`..` resolved as far as
/// the path exists, and the file's (device, inode) when it exists.
#[derive(Clone, Debug)]
struct Resolved {
    shown: PathBuf,
    path: PathBuf,
    id: Option<(u64, u64)>,
    tree: bool,
}

/// Why an output was refused.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Clash {
    pub output: PathBuf,
    pub other: PathBuf,
    pub why: &'static str,
}

impl fmt::Display for Clash {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "the output {} {} {}: nothing written, choose another output",
            self.output.display(),
            self.why,
            self.other.display()
        )
    }
}

impl std::error::Error for Clash {}

/// The inputs of one run and the outputs granted so far.
#[derive(Clone, Debug, Default)]
pub struct Guard {
    inputs: Vec<Resolved>,
    outputs: Vec<Resolved>,
}

fn is_dash(p: &Path) -> bool {
    p.as_os_str() == "-"
}

#[cfg(unix)]
fn file_id(meta: &std::fs::Metadata) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    Some((meta.dev(), meta.ino()))
}

#[cfg(not(unix))]
fn file_id(_: &std::fs::Metadata) -> Option<(u64, u64)> {
    None
}

/// `path` made absolute with symlinks resolved in the part that exists and `.`/`..` applied
/// to the rest (`dir/../x` is `x` even before `dir` exists: writing creates `dir`, then
/// writes `x`).
pub fn resolve(path: &Path) -> PathBuf {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    let mut existing = absolute.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(c) = existing.canonicalize() {
            let mut out = c;
            for part in rest.iter().rev() {
                match part {
                    Component::ParentDir => {
                        out.pop();
                    }
                    Component::CurDir => {}
                    other => out.push(other.as_os_str()),
                }
            }
            return out;
        }
        match (existing.parent(), existing.components().next_back()) {
            (Some(parent), Some(last)) => {
                rest.push(last);
                existing = parent;
            }
            _ => return absolute,
        }
    }
}

impl Resolved {
    fn new(path: &Path, tree: bool) -> Resolved {
        let resolved = resolve(path);
        let id = std::fs::metadata(&resolved).ok().as_ref().and_then(file_id);
        Resolved {
            shown: path.to_path_buf(),
            path: resolved,
            id,
            tree,
        }
    }

    fn same(&self, other: &Resolved) -> bool {
        self.path == other.path || (self.id.is_some() && self.id == other.id)
    }
}

impl Guard {
    pub fn new() -> Guard {
        Guard::default()
    }

    /// A file the run reads (`-` is ignored).
    pub fn read(&mut self, path: &Path) -> &mut Guard {
        if !is_dash(path) {
            self.inputs.push(Resolved::new(path, false));
        }
        self
    }

    /// A directory whose files the run reads: nothing may be written inside it.
    pub fn read_tree(&mut self, dir: &Path) -> &mut Guard {
        if !is_dash(dir) {
            self.inputs.push(Resolved::new(dir, true));
        }
        self
    }

    /// Every path of `paths` read.
    pub fn read_all<'a>(&mut self, paths: impl IntoIterator<Item = &'a Path>) -> &mut Guard {
        for p in paths {
            self.read(p);
        }
        self
    }

    /// Grants the file `path` as an output of this run, or says which input (or earlier
    /// output) it would overwrite. `-` is always granted.
    pub fn write(&mut self, path: &Path) -> Result<(), Clash> {
        self.check(path, false)
    }

    /// Grants the directory `dir` as an output tree: no input may lie inside it, and it may
    /// not lie inside an input tree or be an input.
    pub fn write_tree(&mut self, dir: &Path) -> Result<(), Clash> {
        self.check(dir, true)
    }

    fn check(&mut self, path: &Path, tree: bool) -> Result<(), Clash> {
        if is_dash(path) {
            return Ok(());
        }
        let out = Resolved::new(path, tree);
        let clash = |other: &Resolved, why| Clash {
            output: path.to_path_buf(),
            other: other.shown.clone(),
            why,
        };
        for input in &self.inputs {
            if out.same(input) {
                let why = if out.path == input.path && out.shown != input.shown {
                    "names the same file as the input"
                } else if out.path == input.path {
                    "is the input"
                } else {
                    "is a hard link to the input"
                };
                return Err(clash(input, why));
            }
            if input.tree && out.path.starts_with(&input.path) {
                return Err(clash(input, "lies inside the input directory"));
            }
            if tree && input.path.starts_with(&out.path) {
                return Err(clash(input, "holds the input"));
            }
        }
        for earlier in &self.outputs {
            if out.same(earlier) {
                return Err(clash(earlier, "is the same file as the other output"));
            }
        }
        self.outputs.push(out);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aliases_of_an_input_are_refused_and_other_paths_granted() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("in.src"), b"x").unwrap();
        std::fs::create_dir(d.join("sub")).unwrap();
        std::fs::hard_link(d.join("in.src"), d.join("hard.src")).unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(d.join("in.src"), d.join("soft.src")).unwrap();
        let mut g = Guard::new();
        g.read(&d.join("in.src"));
        for alias in [
            d.join("in.src"),
            d.join("sub/../in.src"),
            d.join("./in.src"),
            d.join("hard.src"),
            d.join("soft.src"),
            d.join("missing/../in.src"),
        ] {
            assert!(g.clone().write(&alias).is_err(), "{}", alias.display());
        }
        assert!(g.clone().write(&d.join("out.src")).is_ok());
        assert!(g.clone().write(Path::new("-")).is_ok());
        let mut twice = g.clone();
        twice.write(&d.join("out.src")).unwrap();
        assert!(twice.write(&d.join("sub/../out.src")).is_err());
    }

    #[test]
    fn trees_refuse_outputs_inside_inputs_and_inputs_inside_outputs() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir_all(d.join("lib/cell")).unwrap();
        let mut g = Guard::new();
        g.read_tree(&d.join("lib"));
        assert!(g.clone().write_tree(&d.join("lib/out")).is_err());
        assert!(g.clone().write(&d.join("lib/cell/report.json")).is_err());
        assert!(g.clone().write_tree(d).is_err());
        assert!(g.clone().write_tree(&d.join("out")).is_ok());
        assert!(g.clone().write_tree(&d.join("library")).is_ok());
    }
}
