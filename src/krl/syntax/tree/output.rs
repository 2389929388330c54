//! A [`SourceFile`] given back: its problems as diagnostics, its line index, and counts of what
//! it holds (its bytes and tiles are in `emit`).

use super::{SourceFile, Stats};
use crate::diagnostic::Diagnostic;
use crate::krl::syntax::error::Problem;
use crate::krl::syntax::span::{LineIndex, Span};
use crate::krl::syntax::stmt::StmtKind;

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
                            [crate::krl::syntax::expr::Access::Index { .. }]
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
