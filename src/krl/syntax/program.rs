//! A program as the controller sees it: a `.src` and the `.dat` beside it (same stem), both
//! parsed (recovering: problems are collected, not thrown), with name resolution across the
//! two and checks that need both files (motion targets declared nowhere).

use super::error::Problem;
use super::expr::Expr;
use super::span::Span;
use super::symbols::Symbols;
use super::tree::{parse_recovering_owned, FileKind, SourceFile};
use crate::diagnostic::Diagnostic;
use std::path::{Path, PathBuf};

/// A file that could not be read.
#[derive(Debug, thiserror::Error)]
#[error("cannot read {}: {source}", path.display())]
pub struct LoadError {
    pub path: PathBuf,
    pub source: std::io::Error,
}

/// A parsed `.src` (or a lone `.dat`) and its data list.
#[derive(Debug)]
pub struct Program {
    /// Path as given (`-` for standard input).
    pub path: PathBuf,
    pub main: SourceFile,
    pub dat_path: Option<PathBuf>,
    pub dat: Option<SourceFile>,
}

/// Reads a file (`-` reads standard input).
pub fn read_bytes(path: &Path) -> Result<Vec<u8>, LoadError> {
    let err = |source| LoadError {
        path: path.to_path_buf(),
        source,
    };
    if path.as_os_str() == "-" {
        return crate::input::stdin().map_err(err);
    }
    crate::input::read(path).map_err(err)
}

impl Program {
    /// Reads and parses `path`; a `.src` also reads the `.dat` beside it when there is one.
    pub fn load(path: &Path) -> Result<Program, LoadError> {
        let kind = FileKind::from_path(path);
        let main = parse_recovering_owned(read_bytes(path)?, kind);
        let dat_path = if path.as_os_str() == "-" {
            None
        } else {
            super::companion_dat(path)
        };
        let dat = match &dat_path {
            Some(p) => Some(parse_recovering_owned(read_bytes(p)?, FileKind::Dat)),
            None => None,
        };
        Ok(Program {
            path: path.to_path_buf(),
            main,
            dat_path,
            dat,
        })
    }

    /// Declarations of both files (the data list first: a routine's local declarations do
    /// not hide module data when resolving motion targets by name).
    pub fn symbols(&self) -> Symbols<'_> {
        let mut files: Vec<&SourceFile> = self.dat.iter().collect();
        files.push(&self.main);
        Symbols::new(&files)
    }

    /// Every problem of both files as diagnostics, including targets declared nowhere.
    #[cfg(any(test, feature = "internals"))]
    pub fn diagnostics(&self) -> Vec<Diagnostic> {
        self.diagnostics_with(true)
    }

    /// Every problem of both files as diagnostics; targets declared in neither file only when
    /// `undeclared` (a cell may declare them: the walk says what it could not resolve).
    pub fn diagnostics_with(&self, undeclared: bool) -> Vec<Diagnostic> {
        let name = self.path.display().to_string();
        let unresolved = if undeclared {
            unresolved_targets(&self.main, &self.symbols())
        } else {
            Vec::new()
        };
        let mut out: Vec<Diagnostic> = self
            .main
            .problems()
            .iter()
            .chain(&unresolved)
            .map(|p| self.main.diagnostic(p, &name))
            .collect();
        if let (Some(dat), Some(p)) = (&self.dat, &self.dat_path) {
            let dname = p.display().to_string();
            out.extend(dat.problems().iter().map(|pr| dat.diagnostic(pr, &dname)));
        }
        out.sort_by(|a, b| (&a.file, a.line, a.col).cmp(&(&b.file, b.line, b.col)));
        out
    }

    /// Whether either file has an error.
    #[cfg(any(test, feature = "internals"))]
    pub fn has_errors(&self) -> bool {
        self.main.has_errors() || self.dat.as_ref().is_some_and(SourceFile::has_errors)
    }
}

/// Warnings for motion targets (and circular auxiliary points) that are variables declared in
/// neither file. System variables (`$AXIS_ACT`, `$POS_ACT`) are exempt; a name may still be
/// declared globally elsewhere (`$config.dat`), hence a warning, not an error.
pub fn unresolved_targets(file: &SourceFile, symbols: &Symbols<'_>) -> Vec<Problem> {
    // First use of each unknown name, and how many motions use it.
    let mut unknown: Vec<(Vec<u8>, Span, usize)> = Vec::new();
    for (_, m) in file.motions() {
        let mut names = Vec::new();
        for e in m.aux().into_iter().chain(std::iter::once(&m.target)) {
            file.visit_expr(e, &mut |x| {
                if let Expr::Path(p) = x {
                    names.push(p.root);
                }
            });
        }
        for span in names {
            let name = file.text(span);
            if name.starts_with(b"$") || symbols.get(name).is_some() {
                continue;
            }
            let key = name.to_ascii_uppercase();
            match unknown.iter_mut().find(|(k, _, _)| *k == key) {
                Some(u) => u.2 += 1,
                None => unknown.push((key, span, 1)),
            }
        }
    }
    unknown
        .into_iter()
        .map(|(_, span, uses)| {
            let more = if uses > 1 {
                format!(" (used {uses} times)")
            } else {
                String::new()
            };
            Problem::warning(
                span,
                format!(
                    "`{}` is declared neither in the program nor in its data list{more}",
                    file.text_lossy(span)
                ),
                "declare it in the .dat, or make sure it is declared globally ($config.dat)",
            )
        })
        .collect()
}
