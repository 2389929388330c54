//! Aggregates that several executions write: written once when their edits agree; else a
//! declared point named at several places split into copies under new names (declared next
//! to the original, each place renamed, inline forms included), or written for its last
//! execution with a warning. A `$config.dat` point is copied into the program's data list,
//! and the offsets of geometric operators keep their numbers through unchanged copies.

use std::collections::HashSet;

use crate::diagnostic::Severity;
use crate::krl::interpret::value::{Declared, VarRef};
use crate::krl::interpret::{FileId, Simulation, Workspace};
use crate::krl::{self, Edit, Expr, SourceFile, Span};

use super::{Rewrite, SharedOrigin, Site, TargetEdits, Use};

/// KRL names are at most 24 characters.
pub(super) const MAX_NAME: usize = 24;

/// How an aggregate written by several executions is written: a `$config.dat` point copied
/// into the program ([`localize`]); alike edits once; else split into a copy per place naming
/// it ([`split_by_site`]) where it is a declared point named at several places, or written
/// for its last execution with a warning.
pub(super) fn write_shared(
    ws: &Workspace,
    sim: &Simulation,
    origin: SharedOrigin,
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) {
    let SharedOrigin { file, uses } = origin;
    if ws.get(file).role == crate::krl::interpret::workspace::Role::Config {
        localize(ws, &uses, taken, out);
        return;
    }
    let mut distinct: Vec<&TargetEdits> = Vec::new();
    for u in &uses {
        if !distinct.contains(&&u.edits) {
            distinct.push(&u.edits);
        }
    }
    if distinct.len() == 1 {
        let first = uses.into_iter().next().expect("non-empty");
        out.edits.entry(file).or_default().extend(first.edits);
        return;
    }
    let mut sites: Vec<Site> = Vec::new();
    for u in &uses {
        if !sites.contains(&u.site) {
            sites.push(u.site);
        }
    }
    let var = uses[0].origin.var.filter(|v| !v.element);
    match var {
        Some(var) if sites.len() > 1 && sites.iter().all(|s| s.1.is_some()) => {
            split_by_site(ws, file, &var, &uses, taken, out);
        }
        _ => write_last(ws, sim, file, &uses, out),
    }
}

/// Writes an aggregate for the last of its executions, with a warning that the others are
/// not compensated.
pub(super) fn write_last(
    ws: &Workspace,
    sim: &Simulation,
    file: FileId,
    uses: &[Use],
    out: &mut Rewrite,
) {
    let (origin, last) = (uses[0].origin, uses.last().expect("non-empty"));
    out.edits
        .entry(file)
        .or_default()
        .extend(last.edits.iter().cloned());
    let stop = &sim.stops[last.stop];
    out.diagnostics.push(ws.diagnostic(
        Severity::Warning,
        origin.file,
        origin.agg.span,
        format!(
            "this position is reached {} times with different rotation directions, so its compensations differ; it is written for its last use (line {}) — give each use its own point to compensate all",
            uses.len(),
            stop.handle.stmt.line
        ),
    ));
}

/// Writes a declared point named at several places: the first place's use in place, each
/// other place's as a copy under a new name ([`split`]), said in [`Rewrite::splits`].
pub(super) fn split_by_site(
    ws: &Workspace,
    file: FileId,
    var: &VarRef,
    uses: &[Use],
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) {
    let mut new_names = Vec::new();
    for (n, ((site_file, site_span), chosen)) in by_site(ws, uses, out).into_iter().enumerate() {
        if n == 0 {
            out.edits
                .entry(file)
                .or_default()
                .extend(chosen.edits.iter().cloned());
            continue;
        }
        let site = site_span.expect("every site named");
        let name = split(ws, var, &chosen.edits, site_file, site, taken, out);
        new_names.push(name);
    }
    let old = String::from_utf8_lossy(ws.get(var.file).file.text(var.name)).into_owned();
    out.splits.push((old, new_names));
}

/// Points used as the offset of a geometric operator (`P1 : P2`, P2 pinned: `Simulation::
/// pinned`) keep their written numbers there. Where such a point is rewritten in place for
/// another use, the operator gets an unchanged copy of it (one per point), said once.
pub(super) fn keep_pinned(
    ws: &Workspace,
    sim: &Simulation,
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) {
    let mut copies: Vec<(FileId, u32, Vec<u8>)> = Vec::new();
    for p in &sim.pinned {
        let Some(var) = p.origin.var.filter(|v| !v.element) else {
            continue;
        };
        if ws.get(p.origin.file).role == crate::krl::interpret::workspace::Role::Config {
            continue; // never written in place
        }
        let span = p.origin.agg.span;
        let key = (p.origin.file, span.start);
        let new = match copies.iter().find(|(f, s, _)| (*f, *s) == key) {
            Some((_, _, n)) => n.clone(),
            None => {
                let touched = out.edits.get(&p.origin.file).is_some_and(|l| {
                    l.to_edits().iter().any(|e| {
                        e.range.start >= span.start as usize && e.range.end <= span.end as usize
                    })
                });
                if !touched {
                    continue;
                }
                let old = ws.get(var.file).file.text(var.name);
                let new = fresh_name(ws, old, taken);
                copy_declaration(ws, var.file, var.name, var.stmt, &new, &[], None, out);
                if let Some(d) = &var.declared {
                    declare_like(ws, d, &new, out);
                }
                out.diagnostics.push(ws.diagnostic(
                    Severity::Warning,
                    p.site.0,
                    p.site.1,
                    format!(
                        "{} is compensated where it is a target; as the offset of this geometric operator it keeps its written numbers, through an unchanged copy {}",
                        String::from_utf8_lossy(old),
                        String::from_utf8_lossy(&new)
                    ),
                ));
                out.splits.push((
                    String::from_utf8_lossy(old).into_owned(),
                    vec![String::from_utf8_lossy(&new).into_owned()],
                ));
                copies.push((key.0, key.1, new.clone()));
                new
            }
        };
        rename_site(ws, p.site.0, p.site.1, None, &new, None, taken, out);
    }
}

/// A name not used by any loaded file nor taken before: `base_2`, `base_3`, …
pub(super) fn fresh_name(ws: &Workspace, base: &[u8], taken: &mut HashSet<Vec<u8>>) -> Vec<u8> {
    let exists = |name: &[u8]| {
        let up = name.to_ascii_uppercase();
        taken.contains(&up)
            || ws.files.iter().any(|f| {
                f.file.declarations().any(|(_, d)| {
                    d.vars
                        .iter()
                        .any(|v| f.file.text(v.name).eq_ignore_ascii_case(name))
                })
            })
    };
    for k in 2.. {
        let suffix = format!("_{k}");
        let keep = base.len().min(MAX_NAME - suffix.len());
        let mut name = base[..keep].to_vec();
        name.extend_from_slice(suffix.as_bytes());
        if !exists(&name) {
            taken.insert(name.to_ascii_uppercase());
            return name;
        }
    }
    unreachable!("some suffix is free")
}

/// Declares a copy of point `var` with this use's numbers next to the original, and renames
/// the use (and its inline form) to it. Returns the new name.
pub(super) fn split(
    ws: &Workspace,
    var: &VarRef,
    edits: &[Edit],
    site_file: FileId,
    site: Span,
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) -> String {
    let old = ws.get(var.file).file.text(var.name);
    let ilf = ilf_of(&ws.get(site_file).file, site);
    let new = new_name(ws, old, &ilf, taken);
    copy_declaration(ws, var.file, var.name, var.stmt, &new, edits, None, out);
    if let Some(d) = &var.declared {
        // Assigned by a statement: the copy needs a declaration of its own too.
        declare_like(ws, d, &new, out);
    }
    rename_site(ws, site_file, site, ilf, &new, None, taken, out);
    String::from_utf8_lossy(&new).into_owned()
}

/// A fresh name for a copy of point `old`; inline forms name the point `P1` and its position
/// `XP1`: that pairing is kept.
pub(super) fn new_name(
    ws: &Workspace,
    old: &[u8],
    ilf: &Option<(Span, Vec<u8>)>,
    taken: &mut HashSet<Vec<u8>>,
) -> Vec<u8> {
    match ilf {
        Some((_, point)) => {
            let point_new = fresh_name(ws, point, taken);
            let mut n = b"X".to_vec();
            n.extend_from_slice(&point_new);
            taken.insert(n.to_ascii_uppercase());
            n
        }
        None => fresh_name(ws, old, taken),
    }
}

/// Renames the place `site` naming a point to `new` (and its inline form, whose frame data
/// is copied `into` a data list when given, see [`copy_declaration`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn rename_site(
    ws: &Workspace,
    site_file: FileId,
    site: Span,
    ilf: Option<(Span, Vec<u8>)>,
    new: &[u8],
    into: Option<FileId>,
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) {
    out.edits.entry(site_file).or_default().push(Edit {
        range: site.range(),
        bytes: new.to_vec(),
    });
    if let Some((fold_span, point)) = ilf {
        let point_new = &new[1..];
        rename_in_fold(
            ws, site_file, fold_span, &point, point_new, into, taken, out,
        );
    }
}

/// The uses of one point grouped by the place naming it, each place with the use it is
/// written for: its last execution (a warning when its executions differ).
pub(super) fn by_site<'u, 'f>(
    ws: &Workspace,
    list: &'u [Use<'f>],
    out: &mut Rewrite,
) -> Vec<(Site, &'u Use<'f>)> {
    let mut sites: Vec<(Site, Vec<&Use>)> = Vec::new();
    for u in list {
        match sites.iter_mut().find(|(s, _)| *s == u.site) {
            Some((_, v)) => v.push(u),
            None => sites.push((u.site, vec![u])),
        }
    }
    sites
        .into_iter()
        .map(|((site_file, site_span), group)| {
            let chosen = *group.last().expect("non-empty");
            if group.iter().any(|u| u.edits != chosen.edits) {
                out.diagnostics.push(ws.diagnostic(
                    Severity::Warning,
                    site_file,
                    site_span.unwrap_or_default(),
                    "this use of the point is executed several times with different rotation directions; written for its last execution",
                ));
            }
            ((site_file, site_span), chosen)
        })
        .collect()
}

/// Copies of a `$config.dat` point for this program, which must not change a file every
/// program of the cell shares: one per module data list and distinct numbers, declared at the
/// end of that data list under a new name (without `GLOBAL`), each place naming the point
/// renamed to its copy, inline forms included. What else names the point (`$H_POS=XHOME`)
/// keeps the cell's point.
pub(super) fn localize(
    ws: &Workspace,
    list: &[Use],
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) {
    let var = list[0]
        .origin
        .var
        .expect("the walker compensates only named $config.dat points");
    let old = ws.get(var.file).file.text(var.name);
    let mut copies: Vec<(FileId, &TargetEdits, Vec<u8>)> = Vec::new();
    for ((site_file, site_span), chosen) in by_site(ws, list, out) {
        let (Some(dat), Some(site)) = (ws.get(site_file).partner, site_span) else {
            continue; // the walker compensates only points named in a module with a .dat
        };
        let ilf = ilf_of(&ws.get(site_file).file, site);
        let new = match copies
            .iter()
            .find(|(d, e, _)| *d == dat && **e == chosen.edits)
        {
            Some((_, _, n)) => n.clone(),
            None => {
                let new = new_name(ws, old, &ilf, taken);
                let edits = &chosen.edits;
                copy_declaration(
                    ws,
                    var.file,
                    var.name,
                    var.stmt,
                    &new,
                    edits,
                    Some(dat),
                    out,
                );
                copies.push((dat, edits, new.clone()));
                new
            }
        };
        rename_site(ws, site_file, site, ilf, &new, Some(dat), taken, out);
    }
    let names = copies
        .iter()
        .map(|(_, _, n)| String::from_utf8_lossy(n).into_owned())
        .collect();
    out.splits
        .push((String::from_utf8_lossy(old).into_owned(), names));
}

/// Copies the declaration line of `name` (declared at `stmt` in `file`) under `new`, with
/// `edits` applied, inserted after the original line — or, `into` a data list, as its last
/// declaration and without `GLOBAL` (a copy of a `$config.dat` point, local to its module).
#[allow(clippy::too_many_arguments)]
pub(super) fn copy_declaration(
    ws: &Workspace,
    file: FileId,
    name: Span,
    stmt: Span,
    new: &[u8],
    edits: &[Edit],
    into: Option<FileId>,
    out: &mut Rewrite,
) {
    let f = &ws.get(file).file;
    let src = f.source();
    let (start, end) = line_content(f, stmt.start as usize);
    let mut local: Vec<Edit> = edits
        .iter()
        .filter(|e| e.range.start >= start && e.range.end <= end)
        .map(|e| Edit {
            range: e.range.start - start..e.range.end - start,
            bytes: e.bytes.clone(),
        })
        .collect();
    local.push(Edit {
        range: name.start as usize - start..name.end as usize - start,
        bytes: new.to_vec(),
    });
    let global = f
        .declarations()
        .find(|(_, d)| d.vars.iter().any(|v| v.name == name))
        .and_then(|(_, d)| d.global);
    if let (Some(g), Some(_)) = (global, into) {
        // `GLOBAL ` with the blanks after it.
        let after = src[g.end as usize..end]
            .iter()
            .take_while(|b| matches!(b, b' ' | b'\t'))
            .count();
        local.push(Edit {
            range: g.start as usize - start..g.end as usize + after - start,
            bytes: Vec::new(),
        });
    }
    let Ok(text) = krl::apply(&src[start..end], &local) else {
        return;
    };
    match into {
        Some(dat) => insert_line_before_enddat(ws, dat, text, out),
        None => insert_line_after(ws, file, end, text, out),
    }
}

/// Inserts `text` as a line of data list `dat` just before its `ENDDAT` (at its end when it
/// has none).
pub(super) fn insert_line_before_enddat(
    ws: &Workspace,
    dat: FileId,
    mut text: Vec<u8>,
    out: &mut Rewrite,
) {
    let f = &ws.get(dat).file;
    let enddat = f
        .body()
        .iter()
        .find(|s| matches!(s.kind, krl::StmtKind::DefDat(_)))
        .and_then(|s| s.block.as_ref()?.end.as_ref())
        .map(|end| line_content(f, end.span.start as usize).0);
    match enddat {
        Some(at) => {
            text.extend_from_slice(newline_of(f.source()));
            out.edits.entry(dat).or_default().push(Edit {
                range: at..at,
                bytes: text,
            });
        }
        None => insert_line_after(ws, dat, f.source().len(), text, out),
    }
}

/// The line ending a file uses (CR LF when it has any).
pub(super) fn newline_of(src: &[u8]) -> &'static [u8] {
    if src.windows(2).any(|w| w == b"\r\n") {
        b"\r\n"
    } else {
        b"\n"
    }
}

/// A declaration of `new` of the type of the point declared at `d`, on a line of its own after
/// that declaration's line, indented alike: `DECL E6AXIS XHOME_2`.
pub(super) fn declare_like(ws: &Workspace, d: &Declared, new: &[u8], out: &mut Rewrite) {
    let f = &ws.get(d.file).file;
    let src = f.source();
    let (start, end) = line_content(f, d.stmt.start as usize);
    let indent = src[start..end]
        .iter()
        .take_while(|b| matches!(b, b' ' | b'\t'))
        .count();
    let mut text = src[start..start + indent].to_vec();
    text.extend_from_slice(b"DECL ");
    text.extend_from_slice(f.text(d.ty));
    text.push(b' ');
    text.extend_from_slice(new);
    insert_line_after(ws, d.file, end, text, out);
}

/// The byte range of the line holding `at` in `f`, without its line ending.
pub(super) fn line_content(f: &SourceFile, at: usize) -> (usize, usize) {
    let src = f.source();
    let lines = f.line_index();
    let (line, _) = lines.line_col(at);
    let span = lines.line_span(src, line);
    let (start, mut end) = (span.start as usize, span.end as usize);
    while end > start && (src[end - 1] == b'\n' || src[end - 1] == b'\r') {
        end -= 1;
    }
    (start, end)
}

/// Inserts `text` as a line after the line whose content ends at `end` in `file`, with the
/// file's line ending (or adds one at the end of the file).
pub(super) fn insert_line_after(
    ws: &Workspace,
    file: FileId,
    end: usize,
    mut text: Vec<u8>,
    out: &mut Rewrite,
) {
    let src = ws.get(file).file.source();
    let newline = newline_of(src);
    let after = src[end..]
        .iter()
        .position(|&b| b == b'\n')
        .map_or(src.len(), |p| end + p + 1);
    let mut bytes = Vec::new();
    if after == src.len() && !src.ends_with(b"\n") {
        bytes.extend_from_slice(newline);
        bytes.append(&mut text);
    } else {
        bytes.append(&mut text);
        bytes.extend_from_slice(newline);
    }
    out.edits.entry(file).or_default().push(Edit {
        range: after..after,
        bytes,
    });
}

/// The inline form around the motion naming `site`, with its point name (`P1` for `XP1`).
pub(super) fn ilf_of(file: &SourceFile, site: Span) -> Option<(Span, Vec<u8>)> {
    let stmt = file
        .motions()
        .find(|(s, _)| s.span().contains(site))
        .map(|(s, _)| s)?;
    let (fold, ilf) = file.inline_form(stmt)?;
    let m = ilf.motion.as_ref()?;
    let name = file.text(site);
    let point = m
        .points
        .iter()
        .map(|p| file.text(*p))
        .find(|p| name.len() == p.len() + 1 && name[1..].eq_ignore_ascii_case(p))?;
    let end = fold.close.map_or(stmt.span().end, |c| c.end);
    Some((
        Span {
            start: fold.open.start,
            end,
        },
        point.to_vec(),
    ))
}

/// Renames point `old` to `new` in an inline form: the fold title and parameters, and the
/// frame data `F<old>` (declared anew as a copy, next to it or `into` a data list, once per
/// name: `taken` remembers) named inside the fold.
#[allow(clippy::too_many_arguments)]
pub(super) fn rename_in_fold(
    ws: &Workspace,
    file: FileId,
    fold: Span,
    old: &[u8],
    new: &[u8],
    into: Option<FileId>,
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) {
    let f = &ws.get(file).file;
    let Some(folded) = f.folds().iter().find(|x| x.open.start == fold.start) else {
        return;
    };
    let mut edits = Vec::new();
    if let Some(ilf) = &folded.ilf {
        let mut spans: Vec<Span> = ilf
            .motion
            .iter()
            .flat_map(|m| m.points.iter().copied())
            .chain(ilf.params.iter().map(|(_, s)| *s))
            .chain(ilf.settings.iter().map(|(_, s)| *s))
            .filter(|s| f.text(*s).eq_ignore_ascii_case(old))
            .collect();
        spans.sort();
        spans.dedup();
        for s in spans {
            edits.push(Edit {
                range: s.range(),
                bytes: new.to_vec(),
            });
        }
    }
    // Frame data `F<old>` used inside the fold: point it at a copy `F<new>`.
    let fold_old = [b"F", old].concat();
    let fold_new = [b"F", new].concat();
    let used = rename_paths_in(f, fold, &fold_old, &fold_new, &mut edits);
    out.edits.entry(file).or_default().extend(edits);
    if used && taken.insert(fold_new.to_ascii_uppercase()) {
        copy_frame_data(ws, &fold_old, &fold_new, into, out);
    }
}

/// Adds to `edits` the renaming of every path rooted at `old` in the statements of `fold`
/// (assignments, motions' `WITH`, call arguments); whether there was one.
pub(super) fn rename_paths_in(
    f: &SourceFile,
    fold: Span,
    old: &[u8],
    new: &[u8],
    edits: &mut Vec<Edit>,
) -> bool {
    let mut used = false;
    for st in f.statements() {
        if !fold.contains(st.head) {
            continue;
        }
        let mut visit = |e: &Expr| {
            if let Expr::Path(p) = e {
                if f.text(p.root).eq_ignore_ascii_case(old) {
                    edits.push(Edit {
                        range: p.root.range(),
                        bytes: new.to_vec(),
                    });
                    used = true;
                }
            }
        };
        match &st.kind {
            krl::StmtKind::Assign(a) => {
                f.visit_expr(&a.lhs, &mut visit);
                f.visit_expr(&a.rhs, &mut visit);
            }
            krl::StmtKind::Motion(m) => {
                for w in f.motion(*m).with() {
                    f.visit_expr(&w.value, &mut visit);
                }
            }
            krl::StmtKind::Call(c) => {
                for a in c.args.iter().flatten() {
                    f.visit_expr(a, &mut visit);
                }
            }
            _ => {}
        }
    }
    used
}

/// Declares `new` as a copy of the frame data `old`, next to its first declaration (or in
/// data list `into` when `old` is a `$config.dat` point's).
pub(super) fn copy_frame_data(
    ws: &Workspace,
    old: &[u8],
    new: &[u8],
    into: Option<FileId>,
    out: &mut Rewrite,
) {
    for (id, loaded) in ws.files.iter().enumerate() {
        for (_, d) in loaded.file.declarations() {
            for v in &d.vars {
                if loaded.file.text(v.name).eq_ignore_ascii_case(old) {
                    let into = into
                        .filter(|_| loaded.role == crate::krl::interpret::workspace::Role::Config);
                    let (id, stmt) = (id as FileId, v.span);
                    copy_declaration(ws, id, v.name, stmt, new, &[], into, out);
                    return;
                }
            }
        }
    }
}
