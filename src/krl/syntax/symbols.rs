//! Name resolution across a program and its data list: which declaration a name refers to
//! (case-insensitive, as KRL), and the initialiser of an array element (`CNC1[17]={…}` lines
//! of a `.dat`). This is how a motion to `XP1` or `CNC1[i]` finds its numbers.

use super::decl::{Decl, DeclVar};
use super::expr::{Access, Expr};
use super::stmt::StmtKind;
use super::tree::SourceFile;
use std::collections::HashMap;

/// A declared variable.
#[derive(Clone, Copy, Debug)]
pub struct Symbol<'f> {
    pub file: &'f SourceFile,
    pub decl: &'f Decl,
    pub var: &'f DeclVar,
}

/// Upper-cased array name and the element's indices.
type ElementKey = (Vec<u8>, Vec<i64>);

/// Declarations and array-element initialisers of a set of files (earlier files win).
#[derive(Debug, Default)]
pub struct Symbols<'f> {
    names: HashMap<Vec<u8>, Symbol<'f>>,
    elements: HashMap<ElementKey, (&'f SourceFile, &'f Expr)>,
}

fn key(name: &[u8]) -> Vec<u8> {
    name.to_ascii_uppercase()
}

impl<'f> Symbols<'f> {
    /// Collects every declaration and every `name[i,…] = value` with literal integer indices
    /// of the given files (typically the `.dat` and the `.src`).
    pub fn new(files: &[&'f SourceFile]) -> Symbols<'f> {
        let mut s = Symbols::default();
        for &f in files {
            for st in f.statements() {
                match &st.kind {
                    StmtKind::Decl(d) => {
                        for v in &d.vars {
                            s.names.entry(key(f.text(v.name))).or_insert(Symbol {
                                file: f,
                                decl: d,
                                var: v,
                            });
                        }
                    }
                    StmtKind::Assign(a) => {
                        if let Some((name, idx)) = element_of(f, &a.lhs) {
                            s.elements.entry((key(name), idx)).or_insert((f, &a.rhs));
                        }
                    }
                    _ => {}
                }
            }
        }
        s
    }

    /// What data lists share with every program: all declarations of a system data list
    /// (`DEFDAT $CONFIG`, or a file without a `DEFDAT` line, as a `$config.dat` given alone),
    /// the `GLOBAL` ones of any other, with their arrays' element initialisers. Earlier
    /// files win.
    pub fn shared(files: &[&'f SourceFile]) -> Symbols<'f> {
        let mut s = Symbols::default();
        for &f in files {
            let system = f
                .statements()
                .find_map(|st| match &st.kind {
                    StmtKind::DefDat(h) => Some(f.text(h.name).starts_with(b"$")),
                    _ => None,
                })
                .unwrap_or(true);
            let mut arrays = std::collections::HashSet::new();
            for st in f.statements() {
                match &st.kind {
                    StmtKind::Decl(d) if system || d.global.is_some() => {
                        for v in &d.vars {
                            arrays.insert(key(f.text(v.name)));
                            s.names.entry(key(f.text(v.name))).or_insert(Symbol {
                                file: f,
                                decl: d,
                                var: v,
                            });
                        }
                    }
                    StmtKind::Assign(a) => {
                        if let Some((name, idx)) = element_of(f, &a.lhs) {
                            if arrays.contains(&key(name)) {
                                s.elements.entry((key(name), idx)).or_insert((f, &a.rhs));
                            }
                        }
                    }
                    _ => {}
                }
            }
        }
        s
    }

    /// The declaration of `name`.
    pub fn get(&self, name: &[u8]) -> Option<&Symbol<'f>> {
        self.names.get(&key(name))
    }

    /// The value assigned to element `index` of array `name` (in the file it was found in).
    pub fn element(&self, name: &[u8], index: &[i64]) -> Option<(&'f SourceFile, &'f Expr)> {
        self.elements.get(&(key(name), index.to_vec())).copied()
    }

    /// Number of declared names.
    #[cfg(any(test, feature = "internals"))]
    pub fn len(&self) -> usize {
        self.names.len()
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }
}

/// `NAME[1,2]` with integer literal indices → (name, indices).
fn element_of<'a>(f: &'a SourceFile, e: &Expr) -> Option<(&'a [u8], Vec<i64>)> {
    let p = e.as_path()?;
    let [Access::Index {
        items,
        slice: false,
        ..
    }] = p.access.as_slice()
    else {
        return None;
    };
    let idx = items
        .iter()
        .map(|i| i.as_number().filter(|n| n.integer).map(|n| n.value as i64))
        .collect::<Option<Vec<_>>>()?;
    (!idx.is_empty()).then(|| (f.text(p.root), idx))
}
