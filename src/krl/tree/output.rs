//! A [`SourceFile`] given back: its bytes (`emit`, byte for byte), its tiles of trivia and
//! code, its problems as diagnostics, and counts of what it holds.

use super::{SourceFile, Stats};
use crate::diagnostic::Diagnostic;
use crate::krl::error::Problem;
use crate::krl::memory::{extend_mapped, Ahead};
use crate::krl::span::{LineIndex, Span};
use crate::krl::stmt::{Clause, Stmt, StmtKind};

/// What a tile of the file is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileKind {
    Trivia,
    Code,
}

impl SourceFile {
    /// Problems found, errors and warnings, in source order.
    pub fn problems(&self) -> &[Problem] {
        &self.problems
    }

    pub fn has_errors(&self) -> bool {
        self.problems.iter().any(Problem::is_error)
    }

    /// 1-based line and byte column of an offset.
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        self.lines.line_col(offset)
    }

    pub fn line_index(&self) -> &LineIndex {
        &self.lines
    }

    /// A problem as a located diagnostic of file `name`.
    pub fn diagnostic(&self, p: &Problem, name: &str) -> Diagnostic {
        self.diagnostic_at(p.severity, name, p.span, p.message.clone())
            .with_label(p.label)
            .with_help(p.help)
    }

    /// A message about `span` of this file, located through the line index (in time
    /// independent of the file's length).
    pub fn diagnostic_at(
        &self,
        severity: crate::diagnostic::Severity,
        name: &str,
        span: Span,
        message: impl Into<String>,
    ) -> Diagnostic {
        let (line, col) = self.lines.line_col(span.start as usize);
        let line_start = (span.start as usize).saturating_sub(col - 1);
        Diagnostic::at_line(
            severity,
            name,
            &self.src,
            (line, line_start),
            span.range(),
            message,
        )
    }

    /// The file again, byte for byte, from the tree's tiles.
    pub fn emit(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.src.len());
        self.emit_into(&mut out);
        out
    }

    /// Appends the file's bytes, tile by tile, to `out` (adjacent tiles are copied together).
    pub fn emit_into(&self, out: &mut Vec<u8>) {
        let mut run = Span::default();
        let mut ahead = Ahead::default();
        self.for_each_tile(&mut |span, _| {
            if span.start == run.end {
                run.end = span.end;
            } else {
                extend_mapped(out, &mut ahead, &self.src[run.range()]);
                run = span;
            }
        });
        extend_mapped(out, &mut ahead, &self.src[run.range()]);
    }

    /// Every tile (trivia or code) of the file in order; together they cover it exactly.
    pub fn tiles(&self) -> Vec<(Span, TileKind)> {
        let mut v = Vec::new();
        self.for_each_tile(&mut |s, k| v.push((s, k)));
        v
    }

    fn for_each_tile(&self, f: &mut impl FnMut(Span, TileKind)) {
        fn clause(c: &Clause, f: &mut impl FnMut(Span, TileKind)) {
            f(c.leading, TileKind::Trivia);
            f(c.span, TileKind::Code);
        }
        fn stmt(s: &Stmt, f: &mut impl FnMut(Span, TileKind)) {
            f(s.leading, TileKind::Trivia);
            f(s.head, TileKind::Code);
            if let Some(b) = &s.block {
                b.body.iter().for_each(|c| stmt(c, f));
                for a in &b.arms {
                    clause(&a.clause, f);
                    a.body.iter().for_each(|c| stmt(c, f));
                }
                if let Some(e) = &b.end {
                    clause(e, f);
                }
            }
        }
        self.body.iter().for_each(|s| stmt(s, f));
        f(self.trailing, TileKind::Trivia);
    }

    /// Counts for reports.
    pub fn stats(&self) -> Stats {
        let mut st = Stats {
            folds: self.folds.len(),
            inline_forms: self.folds.iter().filter(|f| f.ilf.is_some()).count(),
            errors: self.problems.iter().filter(|p| p.is_error()).count(),
            ..Stats::default()
        };
        st.warnings = self.problems.len() - st.errors;
        let mut position_arrays: Vec<&[u8]> = Vec::new();
        for s in self.statements() {
            st.statements += 1;
            match &s.kind {
                StmtKind::Routine(_) => st.routines += 1,
                StmtKind::Motion(_) => st.motions += 1,
                StmtKind::Invalid => st.invalid += 1,
                StmtKind::Decl(d) if d.ty.kind.is_position() => {
                    for v in &d.vars {
                        if v.dims.is_some() {
                            position_arrays.push(self.text(v.name));
                        } else {
                            st.declared_points += 1;
                        }
                    }
                }
                StmtKind::Assign(a) => {
                    if let Some(p) = a.lhs.as_path() {
                        let root = self.text(p.root);
                        let element = matches!(
                            p.access.as_slice(),
                            [crate::krl::expr::Access::Index { .. }]
                        );
                        if element && position_arrays.iter().any(|n| n.eq_ignore_ascii_case(root)) {
                            st.declared_points += 1;
                        }
                    }
                }
                _ => {}
            }
            if s.is_opaque() {
                st.opaque += 1;
            }
        }
        st
    }
}
