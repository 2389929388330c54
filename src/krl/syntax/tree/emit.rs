//! A [`SourceFile`] given back byte for byte from its tiles of trivia and code: the proof that
//! the tree is lossless, which robopost's own tests and fuzz targets check (the rewrite itself
//! edits the original bytes and never emits a tree).

use super::SourceFile;
use crate::krl::syntax::memory::{extend_mapped, Ahead};
use crate::krl::syntax::span::Span;
use crate::krl::syntax::stmt::{Clause, Stmt};

/// What a tile of the file is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileKind {
    Trivia,
    Code,
}

impl SourceFile {
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
}
