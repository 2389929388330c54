//! The files a program run touches: the program (`.src`) and its data list (`.dat`), the
//! modules it calls (found beside it by file name, as RoboDK's numbered files called from a
//! main, or anywhere in the robot's cell by the routines they define), and the data every
//! program of the cell sees (`$config.dat` with `BASE_DATA`/`TOOL_DATA`, the `GLOBAL`
//! declarations of public data lists; see [`Cell`]). Each file is parsed once; modules are
//! loaded until every called routine is found or known missing.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use super::cell::Cell;
use crate::diagnostic::{Diagnostic, Severity};
use crate::krl::{self, FileKind, SourceFile};

/// Index of a file in [`Workspace::files`].
pub type FileId = u32;

/// One parsed file.
#[derive(Debug)]
pub struct Loaded {
    /// Where it was read from (`None` for standard input).
    pub path: Option<PathBuf>,
    /// The name used in messages.
    pub name: String,
    pub file: SourceFile,
    /// The `.src` this `.dat` belongs to, or the `.dat` of this `.src`.
    pub partner: Option<FileId>,
    pub role: Role,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// The program being compensated (and its `.dat`).
    Main,
    /// A module it calls (and its `.dat`).
    Module,
    /// Data every program of the cell shares, never written: the robot's `$config.dat` and
    /// the data lists whose `GLOBAL` declarations every program sees.
    Config,
}

/// Every file of one program run.
#[derive(Debug, Default)]
pub struct Workspace {
    pub files: Vec<Loaded>,
    /// The main `.src`.
    pub main: FileId,
    /// The robot the walk assumes, as messages name it (`KR 16-2 (cal.json)`); empty when
    /// not said.
    pub robot: String,
    /// What loading the cell had to say (several `$config.dat` in a tree…).
    pub notes: Vec<String>,
    /// What the user states about run time (`--assume`, see [`super::assume`]).
    pub assumptions: Vec<super::Assumption>,
}

/// A file that could not be read or parsed: the program is rejected.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The file could not be read.
    #[error("{name}: {source}")]
    Io {
        /// The file, as given.
        name: String,
        /// What the system said.
        source: std::io::Error,
    },
    /// Syntax errors.
    #[error("{}", .diagnostics.iter().map(|d| d.render()).collect::<Vec<_>>().join("\n"))]
    Parse {
        /// Each error, located.
        diagnostics: Vec<Diagnostic>,
    },
    /// Not a KRL file at all (binary data, or text without a KRL statement): like an
    /// unreadable file, a usage error.
    #[error("{}", .diagnostic.render())]
    NotKrl {
        /// What was seen, located.
        diagnostic: Box<Diagnostic>,
    },
}

impl LoadError {
    /// A file that could not be used at all (unreadable, or not KRL): exit status 2, where a
    /// parse error in a program is its rejection (exit 1).
    pub fn is_unusable(&self) -> bool {
        matches!(self, LoadError::Io { .. } | LoadError::NotKrl { .. })
    }
}

fn parse(bytes: &[u8], kind: FileKind, name: &str) -> Result<SourceFile, LoadError> {
    checked(krl::parse(bytes, kind), name)
}

/// A parsed file, unless it is not KRL at all (see `krl::sniff`) or has errors.
fn checked(
    parsed: Result<SourceFile, krl::ParseError>,
    name: &str,
) -> Result<SourceFile, LoadError> {
    let file = match &parsed {
        Ok(f) => f,
        Err(e) => e.partial(),
    };
    if let Some(p) = krl::not_krl(file) {
        return Err(LoadError::NotKrl {
            diagnostic: Box::new(file.diagnostic(&p, name)),
        });
    }
    parsed.map_err(|e| LoadError::Parse {
        diagnostics: e.diagnostics(name),
    })
}

fn read(path: &Path, name: &str) -> Result<Vec<u8>, LoadError> {
    crate::input::read(path).map_err(|source| LoadError::Io {
        name: name.to_string(),
        source,
    })
}

impl Workspace {
    /// The program `src` (read from `path`, or from standard input when `path` is `None`),
    /// with `dat` beside it when given, and `$config.dat` when given.
    #[cfg(any(test, feature = "internals"))]
    pub fn load(
        src: (&[u8], Option<&Path>, &str),
        dat: Option<(&[u8], &Path, &str)>,
        config: Option<&Path>,
    ) -> Result<Workspace, LoadError> {
        let (bytes, path, name) = src;
        let cell = config.map(|c| Cell {
            config: Some(c.to_path_buf()),
            ..Cell::default()
        });
        Workspace::load_streaming((bytes.to_vec(), path, name), dat, cell.as_ref(), None)
    }

    /// [`Workspace::load`] taking the program's bytes and the robot's cell; with `stream`,
    /// the plain stretches of its main routine are left out of the tree as runs
    /// (`krl::parse_streaming`), to be walked window by window with
    /// `crate::krl::interpret::simulate_streaming`.
    pub fn load_streaming(
        src: (Vec<u8>, Option<&Path>, &str),
        dat: Option<(&[u8], &Path, &str)>,
        cell: Option<&Cell>,
        stream: Option<krl::StreamOptions>,
    ) -> Result<Workspace, LoadError> {
        let mut ws = Workspace::default();
        let (bytes, path, name) = src;
        let parsed = match stream {
            Some(opts) => krl::parse_streaming(bytes, FileKind::Src, opts),
            None => krl::parse_recovering_owned(bytes, FileKind::Src).checked(),
        };
        let file = checked(parsed, name)?;
        ws.files.push(Loaded {
            path: path.map(Path::to_path_buf),
            name: name.to_string(),
            file,
            partner: None,
            role: Role::Main,
        });
        if let Some((bytes, path, name)) = dat {
            ws.push_pair_dat(0, bytes, path, name, Role::Main)?;
        }
        if let Some(cell) = cell {
            ws.notes.extend(cell.notes.iter().cloned());
            // `$config.dat` first: where a name is declared twice, its declaration wins.
            for path in cell.config.iter().chain(&cell.data) {
                if ws.find(path).is_some() {
                    continue;
                }
                let name = path.display().to_string();
                let bytes = read(path, &name)?;
                ws.push_shared_data(&bytes, Some(path), &name);
            }
        }
        // A program named without a directory (`main1.src`) is in the current one.
        let dir = path.map(|p| match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        });
        ws.load_modules(dir.as_deref(), cell)?;
        Ok(ws)
    }

    /// Adds a data list of the cell that every program sees (`$config.dat`, a public data
    /// list): where a name is declared twice, the one added first wins. A line the controller
    /// would not accept either leaves that declaration out, said once in [`Self::notes`]; the
    /// rest is used. `path` is `None` for data given in memory.
    pub fn push_shared_data(&mut self, bytes: &[u8], path: Option<&Path>, name: &str) {
        let file = krl::parse_recovering(bytes, FileKind::Dat);
        if let Some(p) = file
            .problems()
            .iter()
            .find(|p| p.severity == krl::Severity::Error)
        {
            let d = file.diagnostic(p, name);
            self.notes.push(format!(
                "{}:{}: {} — that declaration is left out, the rest of the data list is used",
                d.file, d.line, d.message
            ));
        }
        self.files.push(Loaded {
            path: path.map(Path::to_path_buf),
            name: name.to_string(),
            file,
            partner: None,
            role: Role::Config,
        });
    }

    /// The loaded file read from `path`, if any.
    fn find(&self, path: &Path) -> Option<FileId> {
        self.files
            .iter()
            .position(|f| f.path.as_deref().is_some_and(|p| same_path(p, path)))
            .map(|i| i as FileId)
    }

    fn push_pair_dat(
        &mut self,
        src: FileId,
        bytes: &[u8],
        path: &Path,
        name: &str,
        role: Role,
    ) -> Result<(), LoadError> {
        let id = self.files.len() as FileId;
        self.files.push(Loaded {
            path: Some(path.to_path_buf()),
            name: name.to_string(),
            file: parse(bytes, FileKind::Dat, name)?,
            partner: Some(src),
            role,
        });
        self.files[src as usize].partner = Some(id);
        Ok(())
    }

    /// Loads the modules defining routines that are called (as statements or functions) but
    /// not defined: from `dir` by file name, then from the cell by the routines its modules
    /// define, until nothing new is found.
    fn load_modules(&mut self, dir: Option<&Path>, cell: Option<&Cell>) -> Result<(), LoadError> {
        let mut tried: HashSet<Vec<u8>> = HashSet::new();
        let entries: Vec<PathBuf> = dir
            .and_then(|d| std::fs::read_dir(d).ok())
            .map(|rd| rd.filter_map(|e| e.ok().map(|e| e.path())).collect())
            .unwrap_or_default();
        loop {
            let defined = self.defined_routines();
            let mut wanted: Vec<Vec<u8>> = Vec::new();
            for f in &self.files {
                if f.role == Role::Config {
                    continue;
                }
                for name in f.file.called_names() {
                    let name = f.file.text(name).to_ascii_uppercase();
                    if !defined.contains(&name) && tried.insert(name.clone()) {
                        wanted.push(name);
                    }
                }
            }
            if wanted.is_empty() {
                return Ok(());
            }
            let mut any = false;
            for name in wanted {
                let beside = entries.iter().find(|p| {
                    p.extension().is_some_and(|e| {
                        e.eq_ignore_ascii_case("src") || e.eq_ignore_ascii_case("sub")
                    }) && p
                        .file_stem()
                        .is_some_and(|s| s.to_string_lossy().as_bytes().eq_ignore_ascii_case(&name))
                });
                let in_cell = || cell?.module_of(&name, dir.unwrap_or(Path::new(".")));
                let Some(path) = beside.map(PathBuf::as_path).or_else(in_cell) else {
                    continue;
                };
                if self.find(path).is_some() {
                    continue;
                }
                let shown = path.display().to_string();
                let bytes = read(path, &shown)?;
                let id = self.files.len() as FileId;
                self.files.push(Loaded {
                    path: Some(path.to_path_buf()),
                    name: shown.clone(),
                    file: parse(&bytes, FileKind::Src, &shown)?,
                    partner: None,
                    role: Role::Module,
                });
                if let Some(dat) = krl::companion_dat(path) {
                    match self.find(&dat) {
                        // A data list the cell shares: the module's, and never written.
                        Some(shared) => self.files[id as usize].partner = Some(shared),
                        None => {
                            let shown = dat.display().to_string();
                            let bytes = read(&dat, &shown)?;
                            self.push_pair_dat(id, &bytes, &dat, &shown, Role::Module)?;
                        }
                    }
                }
                any = true;
            }
            if !any {
                return Ok(());
            }
        }
    }

    fn defined_routines(&self) -> HashSet<Vec<u8>> {
        self.files
            .iter()
            .flat_map(|f| {
                f.file
                    .routines()
                    .map(|(_, h)| f.file.text(h.name).to_ascii_uppercase())
            })
            .collect()
    }

    pub fn get(&self, id: FileId) -> &Loaded {
        &self.files[id as usize]
    }

    /// The same files with the main one parsed whole (no streamed runs).
    pub fn whole(&self) -> Workspace {
        let files = self
            .files
            .iter()
            .enumerate()
            .map(|(i, f)| Loaded {
                path: f.path.clone(),
                name: f.name.clone(),
                file: if i as FileId == self.main && !f.file.streamed_runs().is_empty() {
                    krl::parse_recovering(f.file.source(), FileKind::Src)
                } else {
                    f.file.clone()
                },
                partner: f.partner,
                role: f.role,
            })
            .collect();
        Workspace {
            files,
            main: self.main,
            robot: self.robot.clone(),
            notes: self.notes.clone(),
            assumptions: self.assumptions.clone(),
        }
    }

    /// A workspace holding one window of a streamed run of file `id` as its only file.
    pub fn window_of(&self, id: FileId, window: SourceFile) -> Workspace {
        let f = self.get(id);
        Workspace {
            files: vec![Loaded {
                path: f.path.clone(),
                name: f.name.clone(),
                file: window,
                partner: None,
                role: Role::Main,
            }],
            main: 0,
            robot: self.robot.clone(),
            notes: Vec::new(),
            assumptions: self.assumptions.clone(),
        }
    }

    /// The main program's `.dat`, if any.
    #[cfg(any(test, feature = "internals"))]
    pub fn main_dat(&self) -> Option<FileId> {
        self.files[self.main as usize].partner
    }

    /// The first shared data list (`$config.dat` when given), if any.
    #[cfg(any(test, feature = "internals"))]
    pub fn config(&self) -> Option<FileId> {
        self.files
            .iter()
            .position(|f| f.role == Role::Config)
            .map(|i| i as FileId)
    }

    /// A located message about bytes `span` of file `id`.
    pub fn diagnostic(
        &self,
        severity: Severity,
        id: FileId,
        span: krl::Span,
        message: impl Into<String>,
    ) -> Diagnostic {
        let f = self.get(id);
        f.file.diagnostic_at(severity, &f.name, span, message)
    }
}

/// Whether two paths name the same file (compared as given when either cannot be resolved).
fn same_path(a: &Path, b: &Path) -> bool {
    a == b || matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y)
}
