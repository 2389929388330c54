//! A target's aggregate as text: its position components and the literals they are written
//! with, the separators its members use, and the edits that write new values into it —
//! replacing the literals that change, inserting the components it lacks.

use crate::krl::interpret::value::{self, Naming};
use crate::krl::{self, number, Aggregate, Expr, RawMember, SourceFile, Span};

use super::edits::{append_range, EditList};

/// Fewest decimals written for millimetres and degrees.
pub const MIN_DECIMALS_MM: usize = 3;

pub const MIN_DECIMALS_DEG: usize = 4;

/// Fewest decimals written for component `k` of a position named so.
pub(super) fn min_decimals(naming: Naming, k: usize) -> usize {
    if naming.is_angle(k) {
        MIN_DECIMALS_DEG
    } else {
        MIN_DECIMALS_MM
    }
}

/// The literal a member's value is written with: (span to replace, literal text).
pub(super) fn literal_span(e: &Expr) -> Option<(Span, Span)> {
    match e {
        Expr::Number(n) => Some((n.span(), n.span())),
        Expr::Unary(u) => match &u.operand {
            Expr::Number(n) => Some((u.span, n.span())),
            _ => None,
        },
        Expr::Paren(p) => literal_span(&p.inner).map(|(_, lit)| (p.span, lit)),
        _ => None,
    }
}

/// The text between members of the file's first aggregate with several (`,` or `, `),
/// streamed runs included (the first window before the tree's first such aggregate that has
/// one).
pub fn file_separator(file: &SourceFile) -> Vec<u8> {
    let in_tree = first_separator(file);
    for run in file.streamed_runs() {
        if in_tree
            .as_ref()
            .is_some_and(|(at, _)| *at < run.range.start)
        {
            break;
        }
        for w in run.windows() {
            if let Some((_, sep)) = first_separator(&file.window(w)) {
                return sep;
            }
        }
    }
    in_tree.map_or_else(|| b", ".to_vec(), |(_, sep)| sep)
}

/// Where the tree's first aggregate with several members is, and the text between them.
pub(super) fn first_separator(file: &SourceFile) -> Option<(u32, Vec<u8>)> {
    let src = file.source();
    for st in file.statements() {
        let mut found = None;
        let mut look = |e: &Expr| {
            if let (None, Expr::Aggregate(_, id)) = (&found, e) {
                let mut ms = file.members(file.aggregate(*id));
                if let (Some(a), Some(b)) = (ms.next(), ms.next()) {
                    found = Some(src[a.span().end as usize..b.span().start as usize].to_vec());
                }
            }
        };
        match &st.kind {
            krl::StmtKind::Motion(m) => file.visit_expr(&file.motion(*m).target, &mut look),
            krl::StmtKind::Assign(a) => file.visit_expr(&a.rhs, &mut look),
            krl::StmtKind::Decl(d) => d
                .vars
                .iter()
                .filter_map(|v| v.init.as_ref())
                .for_each(|e| file.visit_expr(e, &mut look)),
            _ => {}
        }
        if let Some(sep) = found {
            return Some((st.head.start, sep));
        }
    }
    None
}

/// The text between two members (`, `) and between a name and its value (` `).
/// `file_sep`: the file's separator when known (a window's is its file's).
pub(super) fn separators(
    file: &SourceFile,
    agg: &Aggregate,
    file_sep: Option<&[u8]>,
) -> (Vec<u8>, Vec<u8>) {
    let src = file.source();
    let mut members = file.members(agg);
    let (first, second) = (members.next(), members.next());
    let sep = first
        .as_ref()
        .zip(second)
        .map(|(a, b)| src[a.span().end as usize..b.span().start as usize].to_vec())
        .unwrap_or_else(|| file_sep.map_or_else(|| file_separator(file), <[u8]>::to_vec));
    let nv = first
        .map(|m| src[m.name.end as usize..m.value.span().start as usize].to_vec())
        .filter(|v| !v.is_empty())
        .unwrap_or_else(|| b" ".to_vec());
    (sep, nv)
}

/// A position component of an aggregate: its member and, when its value is a literal,
/// where that literal is and what it says.
#[derive(Clone, Copy, Debug)]
pub(super) struct Component {
    /// The whole member (`X 1.5`): missing members are inserted next to it.
    pub(super) member: Span,
    /// The span a new number replaces and the literal's own text ([`literal_span`]).
    pub(super) literal: Option<(Span, Span)>,
    /// The literal's value ([`value::literal`]).
    pub(super) value: Option<f64>,
}

/// The members of `agg` that are position components named as `naming` says, with the
/// component's index.
pub(super) fn position_members<'a>(
    file: &'a SourceFile,
    agg: &'a Aggregate,
    naming: Naming,
) -> impl Iterator<Item = (usize, RawMember<'a>)> + 'a {
    let src = file.source();
    file.raw_members(agg).filter_map(move |m| {
        let (named, k) = value::component(&src[m.name().range()])?;
        (named == naming).then_some((k, m))
    })
}

/// The position components (named as `naming` says) of `agg`, in one pass over its
/// members; a component written twice is the later one. `read`: values the walk read from
/// the aggregate's literals (the components of `Origin::literals`), not read again.
pub(super) fn components(
    file: &SourceFile,
    agg: &Aggregate,
    naming: Naming,
    read: Option<(&[f64; 6], u8)>,
) -> [Option<Component>; 6] {
    let src = file.source();
    let mut out = [None; 6];
    for (k, m) in position_members(file, agg, naming) {
        out[k] = Some(match m {
            // A plain number is its own literal (what `literal_span` and `value::literal`
            // give for an `Expr::Number`), read here without building the expression.
            RawMember::Plain { name, number, kept } => {
                let value = match read {
                    Some((values, bits)) if bits & (1 << k) != 0 => {
                        debug_assert_eq!(
                            RawMember::plain_value(src, number).map(f64::to_bits),
                            Some(values[k].to_bits()),
                            "the walk's value of component {k}"
                        );
                        Some(values[k])
                    }
                    _ => RawMember::plain_value_kept(src, number, kept),
                };
                Component {
                    member: name.to(number),
                    literal: value.map(|_| (number, number)),
                    value,
                }
            }
            RawMember::Outline { name, value: e } => Component {
                member: name.to(e.span()),
                literal: literal_span(e),
                value: value::literal(e),
            },
        });
    }
    out
}

/// An aggregate being written: where it is and what kind of target it holds.
pub(super) struct AggregateTarget<'f> {
    pub(super) file: &'f SourceFile,
    pub(super) agg: &'f Aggregate,
    /// How its components are named.
    pub(super) naming: Naming,
    /// A relative motion's (its missing components are zero, not the previous position's).
    pub(super) relative: bool,
    /// The file's separator between members when known (a window's is its file's).
    pub(super) file_sep: Option<&'f [u8]>,
}

/// Appends to `out` the edits of `target` (components `present`) writing `values` for the
/// components in `write`, sorted by position (one joined edit where every number is replaced
/// in place, see [`joined_edit`]); false (and nothing added) when a number to replace is not
/// a literal.
pub(super) fn aggregate_edits(
    target: &AggregateTarget,
    present: &[Option<Component>; 6],
    values: &[f64; 6],
    write: [bool; 6],
    out: &mut EditList,
) -> bool {
    if literals_in_order(present, write) {
        joined_edit(target, present, values, write, out);
        return true;
    }
    number_edits(target, present, values, write, out)
}

/// [`aggregate_edits`] number by number: an edit for each number replaced, an insertion for
/// each component missing (the way for any aggregate; [`joined_edit`] where it can).
fn number_edits(
    target: &AggregateTarget,
    present: &[Option<Component>; 6],
    values: &[f64; 6],
    write: [bool; 6],
    out: &mut EditList,
) -> bool {
    let (file, naming) = (target.file, target.naming);
    let mark = out.mark();
    // Decimals of inserted numbers: as many as the aggregate's most precise number.
    let decimals = |k: usize| {
        let most = present
            .iter()
            .flatten()
            .filter_map(|c| c.literal)
            .map(|(_, lit)| value::literal_decimals(file.text(lit)))
            .max()
            .unwrap_or(0);
        most.max(min_decimals(naming, k))
    };
    for k in 0..6 {
        if !write[k] {
            continue;
        }
        let done = match &present[k] {
            Some(c) => {
                let (Some((replace, lit)), Some(orig_value)) = (c.literal, c.value) else {
                    out.truncate(mark);
                    return false;
                };
                out.replace_with(replace.range(), |text| {
                    number::write_like(
                        file.text(lit),
                        orig_value,
                        values[k],
                        min_decimals(naming, k),
                        text,
                    )
                });
                true
            }
            None => insert_member(target, present, k, values[k], decimals(k), out),
        };
        if !done {
            out.truncate(mark);
            return false;
        }
    }
    // Insertions at one offset must keep X..C order: they were pushed in that order.
    out.sort_since(mark);
    true
}

/// Whether the components to write are all present as literals, in X..C order in the text
/// (nearly every target's): [`joined_edit`] writes them.
fn literals_in_order(present: &[Option<Component>; 6], write: [bool; 6]) -> bool {
    let mut end = 0;
    for k in (0..6).filter(|&k| write[k]) {
        match present[k] {
            Some(Component {
                literal: Some((replace, _)),
                value: Some(_),
                ..
            }) if replace.start >= end => end = replace.end,
            _ => return false,
        }
    }
    true
}

/// [`aggregate_edits`] of components all replaced in place, in order ([`literals_in_order`]):
/// one edit from the first number that changes to the last, the text between them kept —
/// one piece for the applying to copy in place of one per number.
fn joined_edit(
    target: &AggregateTarget,
    present: &[Option<Component>; 6],
    values: &[f64; 6],
    write: [bool; 6],
    out: &mut EditList,
) {
    let (file, src) = (target.file, target.file.source());
    out.replace_written(|text| {
        // The source range replaced so far: from the first number changed to the last.
        let mut changed: Option<(u32, u32)> = None;
        for k in (0..6).filter(|&k| write[k]) {
            let Some(Component {
                literal: Some((replace, lit)),
                value: Some(old),
                ..
            }) = present[k]
            else {
                continue;
            };
            let at = text.len();
            if let Some((_, end)) = changed {
                append_range(text, src, end as usize..replace.start as usize);
            }
            let min = min_decimals(target.naming, k);
            if number::write_like(file.text(lit), old, values[k], min, text) {
                let start = changed.map_or(replace.start, |(start, _)| start);
                changed = Some((start, replace.end));
            } else {
                text.truncate(at);
            }
        }
        changed.map(|(start, end)| start as usize..end as usize)
    });
}

/// Adds missing component `k` with `value` to the aggregate (`present` its components), in
/// the aggregate's own separators; false when there is no component to place it next to.
pub(super) fn insert_member(
    target: &AggregateTarget,
    present: &[Option<Component>; 6],
    k: usize,
    value: f64,
    decimals: usize,
    out: &mut EditList,
) -> bool {
    let mut text = Vec::new();
    number::write_fixed(value, decimals, &mut text);
    let zero = text.iter().all(|&b| b == b'0' || b == b'.' || b == b'-');
    // A relative motion's missing components are zero: write only those that are not.
    if target.relative && zero {
        return true;
    }
    let (sep, nv) = separators(target.file, target.agg, target.file_sep);
    let text = if zero {
        text.strip_prefix(b"-").unwrap_or(&text)
    } else {
        &text
    };
    let names = target.naming.names();
    let mut entry = names[k].as_bytes().to_vec();
    entry.extend_from_slice(&nv);
    entry.extend_from_slice(text);
    // Before the first present component that follows in X..C order, else after the last
    // present one.
    if let Some(next) = (k + 1..6).find_map(|j| present[j].as_ref()) {
        entry.extend_from_slice(&sep);
        let at = next.member.start as usize;
        out.replace(at..at, &entry);
    } else if let Some(prev) = (0..k).rev().find_map(|j| present[j].as_ref()) {
        let mut text = sep;
        text.extend_from_slice(&entry);
        let at = prev.member.end as usize;
        out.replace(at..at, &text);
    } else {
        return false;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sources_under(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for e in std::fs::read_dir(dir).expect("the fixtures") {
            let p = e.expect("an entry").path();
            if p.is_dir() {
                sources_under(&p, out);
            } else if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("src")) {
                out.push(p);
            }
        }
    }

    /// The rewrite takes an absolute target's literal values from the walk
    /// (`Origin::literals`) instead of reading the numbers again: on every fixture program,
    /// every component so taken must be the number read from the file, to the bit.
    #[test]
    fn values_taken_from_the_walk_are_the_files() {
        let mut programs = Vec::new();
        sources_under(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/programs"),
            &mut programs,
        );
        let robot = crate::kinematics::RobotDescription::kr30ha();
        let (mut taken, mut files) = (0, 0);
        for path in &programs {
            let bytes = std::fs::read(path).expect("a fixture");
            let Ok(ws) = crate::krl::job::files::load_program(Some(path), &bytes, None) else {
                continue;
            };
            files += 1;
            let sim = crate::krl::interpret::simulate(&ws, &robot, &[]);
            for stop in &sim.stops {
                let Some(origin) = stop.handle.origin.filter(|_| stop.rel.is_none()) else {
                    continue;
                };
                let file = &ws.get(origin.file).file;
                let naming = crate::krl::interpret::value::Naming::of(&stop.programmed);
                let read = components(file, origin.agg, naming, None);
                let values = stop.programmed.components();
                let given = Some((&values, origin.literals));
                let taken_here = components(file, origin.agg, naming, given);
                for k in 0..6 {
                    let bits = |c: &Option<Component>| c.and_then(|c| c.value).map(f64::to_bits);
                    assert_eq!(bits(&read[k]), bits(&taken_here[k]), "{}", path.display());
                    if origin.literals & (1 << k) != 0 {
                        assert_eq!(read[k].and_then(|c| c.value), Some(values[k]));
                        taken += 1;
                    }
                }
            }
        }
        assert!(
            files >= 20 && taken > 100_000,
            "{files} files, {taken} values"
        );
    }

    /// The first aggregate of the one-motion program `text`, its file loaded.
    fn first_aggregate(ws: &crate::krl::interpret::Workspace) -> &Aggregate {
        let file = &ws.get(0).file;
        file.statements()
            .find_map(|st| match &st.kind {
                krl::StmtKind::Motion(m) => file.aggregate_of(&file.motion(*m).target),
                _ => None,
            })
            .expect("the motion's aggregate")
    }

    proptest::proptest! {
        /// The joined edit of a target whose numbers are replaced in place writes the bytes
        /// the edits number by number write, for literals of any length and decimals and
        /// new values moved by nothing, by less than a last decimal, or by units (most
        /// numbers changed, some kept), orientation written or not (an auxiliary point's).
        #[test]
        fn joined_edit_writes_what_the_edits_number_by_number_write(
            units in proptest::array::uniform6(-2_000_000i64..2_000_000),
            decimals in proptest::array::uniform6(0usize..5),
            moves in proptest::array::uniform6(proptest::prop_oneof![
                proptest::strategy::Just(0.0),
                -1e-5f64..1e-5,
                -3.0f64..3.0,
            ]),
            orientation: bool,
        ) {
            let texts: Vec<String> = (0..6)
                .map(|k| {
                    let scale = 10i64.pow(decimals[k] as u32);
                    let (int, frac) = (units[k].abs() / scale, units[k].abs() % scale);
                    let sign = if units[k] < 0 { "-" } else { "" };
                    match decimals[k] {
                        0 => format!("{sign}{int}"),
                        d => format!("{sign}{int}.{frac:0d$}"),
                    }
                })
                .collect();
            let program = format!(
                "DEF t ( )\nLIN {{X {},Y {},Z {},A {},B {},C {}}} C_DIS\nEND\n",
                texts[0], texts[1], texts[2], texts[3], texts[4], texts[5]
            );
            let ws = crate::krl::job::files::load_program(None, program.as_bytes(), None)
                .expect("the program loads");
            let file = &ws.get(0).file;
            let agg = first_aggregate(&ws);
            let present = components(file, agg, Naming::Cartesian, None);
            let values: [f64; 6] =
                std::array::from_fn(|k| present[k].and_then(|c| c.value).expect("a literal") + moves[k]);
            let write: [bool; 6] = std::array::from_fn(|k| orientation || k < 3);
            proptest::prop_assert!(literals_in_order(&present, write));
            let target = AggregateTarget {
                file,
                agg,
                naming: Naming::Cartesian,
                relative: false,
                file_sep: None,
            };
            let (mut joined, mut each) = (EditList::new(), EditList::new());
            joined_edit(&target, &present, &values, write, &mut joined);
            proptest::prop_assert!(number_edits(&target, &present, &values, write, &mut each));
            let src = file.source();
            let apply = |l: &EditList| l.apply_in(src, 0..src.len(), None).expect("applies");
            proptest::prop_assert_eq!(
                String::from_utf8(apply(&joined)).expect("text"),
                String::from_utf8(apply(&each)).expect("text")
            );
            proptest::prop_assert!(joined.len() <= 1);
        }
    }
}
