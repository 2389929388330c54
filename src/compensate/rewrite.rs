//! Turning compensated commands back into KRL: for each target, the new numbers of its
//! aggregate as byte edits on the untouched source, in the original's style (decimals kept,
//! never fewer than 3 in mm and 4 in degrees), completing a partial aggregate when its
//! target changed (missing components would otherwise come from the *compensated* previous
//! position); relative targets rewritten relative to the compensated previous command;
//! auxiliary points in position only (the controller ignores their orientation). A number
//! whose rounded value does not change keeps its bytes. An aggregate executed several times
//! with different commands (reached with different rotation directions) is split when it is
//! a declared point named at several places — a copy with a new name declared next to the
//! original (a point assigned by a statement: its copy declared after the declaration and
//! assigned after the assignment), and the place renamed (inline forms included) — otherwise
//! written for its last execution, with a warning. A point of `$config.dat`, which every
//! program of the cell shares, is never written there: the program's data list gets a copy
//! under a new name and the place is renamed the same way.

use std::collections::{BTreeMap, HashSet};

use rayon::prelude::*;

use crate::diagnostic::{Diagnostic, Severity};
use crate::krl::{self, number::format_like, Aggregate, Edit, Expr, RawMember, SourceFile, Span};

use crate::motion::frame::{abc_continuous, kuka_near, Frame};
use crate::motion::nominal::{Arm, Nominal};
use crate::motion::value::{self, Declared, Origin, VarRef, AXIS_NAMES, CARTESIAN_NAMES};
use crate::motion::{FileId, Rel, Role, Simulation, Stop, Workspace};

use super::edits::EditList;
pub use super::sequence::correction;
use super::sequence::{self, Command, Outcome};

/// Fewest decimals written for millimetres and degrees.
pub const MIN_DECIMALS_MM: usize = 3;
pub const MIN_DECIMALS_DEG: usize = 4;
/// KRL names are at most 24 characters.
const MAX_NAME: usize = 24;

/// Edits per file, and what the rewrite has to say.
#[derive(Debug, Default)]
pub struct Rewrite {
    pub edits: BTreeMap<FileId, EditList>,
    pub diagnostics: Vec<Diagnostic>,
    /// Declared points split into copies (original name, new names).
    pub splits: Vec<(String, Vec<String>)>,
    /// Targets near B = ±90° written continuous with the program's angles (`abc_continuous`).
    pub euler: Option<EulerLeft>,
}

/// Targets written with A, B, C continuous near B = ±90°: said once per program.
#[derive(Debug, Clone)]
pub struct EulerLeft {
    pub count: usize,
    /// The most orientation left out, rad.
    pub max_rad: f64,
    /// Where the first of them (in file and line order) is: the warning's place.
    pub first: Diagnostic,
}

impl EulerLeft {
    /// Both programs' parts together.
    pub fn merge(a: Option<EulerLeft>, b: Option<EulerLeft>) -> Option<EulerLeft> {
        match (a, b) {
            (Some(a), Some(b)) => {
                let key = |d: &Diagnostic| (d.file.clone(), d.line, d.col);
                let first = if key(&b.first) < key(&a.first) {
                    b.first
                } else {
                    a.first
                };
                Some(EulerLeft {
                    count: a.count + b.count,
                    max_rad: a.max_rad.max(b.max_rad),
                    first,
                })
            }
            (a, b) => a.or(b),
        }
    }

    /// The warning.
    pub fn diagnostic(self) -> Diagnostic {
        let n = self.count;
        let mut d = self.first;
        d.message = format!(
            "{n} target{} near B = ±90° (this one the first) written with A, B, C continuous with the program's: the part of the orientation correction the Euler angles cannot express there with small changes is left out (at most {:.3} mdeg; the position is compensated)",
            if n == 1 { "" } else { "s" },
            self.max_rad.to_degrees() * 1e3
        );
        d
    }
}

/// The commands the compensation placed already ([`Command`]): those of the stops
/// `from..`; the others' are computed from their axes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Placed<'a> {
    pub from: usize,
    pub commands: &'a [Command],
}

impl Placed<'_> {
    fn command(&self, i: usize) -> Option<&Command> {
        self.commands.get(i.checked_sub(self.from)?)
    }
}

/// The TCP a target is commanded to and, where the compensation worked it out, its pose in
/// the target's base frame before the choice of Euler triple ([`Command::unchosen`]).
#[derive(Clone, Copy)]
struct Commanded {
    tcp: Frame,
    unchosen: Option<[f64; 6]>,
}

/// The edits of one target's aggregate: replacements of member values and insertions of
/// missing members (`offset`, text), in source order.
type TargetEdits = Vec<Edit>;

fn min_decimals(axis: bool, k: usize) -> usize {
    if axis || k >= 3 {
        MIN_DECIMALS_DEG
    } else {
        MIN_DECIMALS_MM
    }
}

/// The most orientation an Euler triple kept continuous near B = ±90° may leave out: what the
/// written decimals (1e-4° in A, B and C) leave anyway.
const CONTINUITY_LEFT_RAD: f64 = 3.0 * 0.5e-4 * std::f64::consts::PI / 180.0;

/// The new component values of `stop` commanded at `axes` (`None`: nothing can be written);
/// `euler_left`: the orientation left out near B = ±90° (see `abc_continuous`), if any.
#[allow(clippy::too_many_arguments)]
fn new_values(
    sim: &Simulation,
    outcomes: &[Outcome],
    stop: &Stop,
    axes: &[f64; 6],
    command: &Commanded,
    original: &[Option<f64>; 6],
    robot: &crate::kinematics::RobotDescription,
    euler_left: &mut Option<f64>,
) -> Option<[f64; 6]> {
    // A relative circle's points are both relative to where the motion starts: the target's
    // `prev` is its auxiliary point, whose own `prev` is the start.
    let start_stop = match stop.prev {
        Some(p) if stop.role != Role::Aux && sim.stops[p as usize].role == Role::Aux => {
            sim.stops[p as usize].prev
        }
        p => p,
    };
    let prev_cmd = start_stop.map(|p| outcomes[p as usize].axes_deg);
    if stop.axis {
        return match stop.rel {
            Some(_) => {
                let prev = prev_cmd?;
                Some(std::array::from_fn(|i| axes[i] - prev[i]))
            }
            None => Some(*axes),
        };
    }
    let tool = &sim.frames[stop.tool as usize];
    let base = &sim.frames[stop.base as usize];
    let arm = Nominal(robot);
    let in_base = || base.inverse().compose(&command.tcp);
    let near = |k: usize| original[k].unwrap_or(0.0);
    let abc_near = [near(3), near(4), near(5)];
    match stop.rel {
        None => {
            let near_abc = [
                original[3].unwrap_or(stop.programmed[3]),
                original[4].unwrap_or(stop.programmed[4]),
                original[5].unwrap_or(stop.programmed[5]),
            ];
            let suffix = stop.origin.and_then(|o| o.suffix);
            // The pose written: in the base, or before a geometric operator's prefix frame or
            // after its suffix (`P : offset`: the point is what puts the TCP there once offset).
            let written = || match (stop.origin.and_then(|o| o.prefix), suffix) {
                (Some(i), _) => sim.prefixes[i as usize].inverse().compose(&in_base()),
                (None, Some(i)) => in_base().compose(&sim.prefixes[i as usize].inverse()),
                (None, None) => in_base(),
            };
            let mut v = match (
                stop.origin.and_then(|o| o.prefix),
                suffix,
                &command.unchosen,
            ) {
                (None, None, Some(u)) => kuka_near(u, &near_abc),
                _ => written().to_kuka_near(&near_abc),
            };
            // Near B = ±90° the angles stay continuous with the program's (`abc_continuous`)
            // where that costs no more than the written decimals; beyond, the exact triple is
            // written (A and C turn together there, A ∓ C stays continuous): an orientation
            // correction left out would leave the TCP off by it times the tool's lever.
            if let Some((abc, left)) =
                abc_continuous(&written().rotation, [v[3], v[4], v[5]], &near_abc)
                    .filter(|(_, left)| stop.role == Role::Target && *left <= CONTINUITY_LEFT_RAD)
            {
                v[3..].copy_from_slice(&abc);
                *euler_left = Some(left);
            }
            Some(v)
        }
        Some(Rel::Tool) => {
            let start = base.inverse().compose(&arm.tcp(&prev_cmd?, tool));
            Some(start.inverse().compose(&in_base()).to_kuka_near(&abc_near))
        }
        Some(_) => {
            let start = base.inverse().compose(&arm.tcp(&prev_cmd?, tool));
            let p_c = in_base();
            let rel = Frame {
                rotation: p_c.rotation * start.rotation.transpose(),
                position: p_c.position - start.position,
            };
            Some(rel.to_kuka_near(&abc_near))
        }
    }
}

/// Whether stop `i`'s numbers are rewritten: a compensated target that changed, and the
/// auxiliary point of a `CA` circle written by construction exactly when its end is (it is
/// moved onto that circle).
fn written(sim: &Simulation, outcomes: &[Outcome], i: usize) -> bool {
    let done = |i: usize| {
        let (stop, o) = (&sim.stops[i], &outcomes[i]);
        stop.compensable && o.changed && o.error.is_none()
    };
    let stop = &sim.stops[i];
    if stop.role == Role::Aux && i + 1 < outcomes.len() && sim.arc_ending_at(i + 1).is_some() {
        return stop.compensable && done(i + 1);
    }
    done(i)
}

/// For the auxiliary point and end of a `CA` circle written by construction, the pose to
/// write (`Some(None)`: no such circle; `None`: not such a stop).
///
/// The controller moves on the circle through the start S', the written auxiliary point A'
/// and target T' (S' → A' → T'), and stops after turning by `CA` from S', with T''s
/// orientation. `CA` is the user's number and stays; S' is the previous target's command;
/// the end must be E_c, the compensated end. So the written circle C' is the one through S'
/// and E_c turning by exactly `CA` between them (radius |E_c − S'| / (2|sin(CA/2)|)), in the
/// plane through S', the compensated auxiliary point A_c and E_c — or, where the nominal
/// points define their plane poorly (A near the start or the end, see
/// `interpolate::PLANE_MIN_SINE`), the nominal plane carried over, tilted as little as the
/// chord S'E_c requires — turning the nominal way (`CircularAngle::sense`); A' and T'
/// are its points at the angles A and T had on the nominal circle — any two points of C'
/// beyond S' define it, these keep the written circle's points where the nominal ones were
/// up to the correction (the nominal S, A, E give back the nominal circle exactly). T' takes
/// E_c's orientation (the controller ends with the target's); A''s orientation is not
/// written.
fn circular_angle(
    sim: &Simulation,
    outcomes: &[Outcome],
    command: &dyn Fn(usize) -> Frame,
    robot: &crate::kinematics::RobotDescription,
    i: usize,
) -> Option<Option<Frame>> {
    let stop = &sim.stops[i];
    let (end, aux) = match stop.role {
        Role::Aux => (i + 1, i),
        _ => (i, i.checked_sub(1)?),
    };
    let arc = sim.arc_ending_at(end).filter(|_| end < outcomes.len())?;
    let tool = &sim.frames[sim.stops[end].tool as usize];
    let Some(start) = sim.stops[aux].prev else {
        return Some(None);
    };
    // Where the controller starts: the previous command's axes with this motion's tool.
    let s_c = Nominal(robot).tcp(&outcomes[start as usize].axes_deg, tool);
    let a_c = match outcomes[aux].error {
        None => command(aux),
        Some(_) => sim.stops[aux].goal,
    };
    let e_c = command(end);
    use crate::motion::interpolate::{circle_by_angle, ArcPlane};
    let near = ArcPlane::Near(arc.normal);
    let plane = if arc.from_points {
        ArcPlane::Points {
            aux: a_c.position,
            sense: arc.sense,
        }
    } else {
        near
    };
    let circle = circle_by_angle(&s_c, &e_c, arc.angle_deg, plane)
        .or_else(|| circle_by_angle(&s_c, &e_c, arc.angle_deg, near));
    let Some(circle) = circle else {
        return Some(None);
    };
    let at = |deg: f64| circle.pose(deg / arc.angle_deg).position;
    Some(Some(if i == aux {
        Frame {
            rotation: a_c.rotation,
            position: at(arc.aux_deg),
        }
    } else {
        Frame {
            rotation: e_c.rotation,
            position: at(arc.target_deg),
        }
    }))
}

/// The literal a member's value is written with: (span to replace, literal text).
fn literal_span(e: &Expr) -> Option<(Span, Span)> {
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
fn first_separator(file: &SourceFile) -> Option<(u32, Vec<u8>)> {
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
fn separators(file: &SourceFile, agg: &Aggregate, file_sep: Option<&[u8]>) -> (Vec<u8>, Vec<u8>) {
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
struct Component {
    /// The whole member (`X 1.5`): missing members are inserted next to it.
    member: Span,
    /// The span a new number replaces and the literal's own text ([`literal_span`]).
    literal: Option<(Span, Span)>,
    /// The literal's value ([`value::literal`]).
    value: Option<f64>,
}

/// The members of `agg` that are position components of its kind (`X..C`, or `A1..A6` for
/// `axis`), with the component's index.
fn position_members<'a>(
    file: &'a SourceFile,
    agg: &'a Aggregate,
    axis: bool,
) -> impl Iterator<Item = (usize, RawMember<'a>)> + 'a {
    let src = file.source();
    file.raw_members(agg).filter_map(move |m| {
        let (is_axis, k) = value::component(&src[m.name().range()])?;
        (is_axis == axis).then_some((k, m))
    })
}

/// The position components (`X..C`, or `A1..A6` for `axis`) of `agg`, in one pass over its
/// members; a component written twice is the later one. `read`: values the walk read from
/// the aggregate's literals (the components of `Origin::literals`), not read again.
fn components(
    file: &SourceFile,
    agg: &Aggregate,
    axis: bool,
    read: Option<(&[f64; 6], u8)>,
) -> [Option<Component>; 6] {
    let src = file.source();
    let mut out = [None; 6];
    for (k, m) in position_members(file, agg, axis) {
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

/// Appends to `out` the edits of `agg` (in `file`, components `present`) writing `values` for
/// the components in `write`, sorted by position; false (and nothing added) when a number
/// to replace is not a literal.
#[allow(clippy::too_many_arguments)]
fn aggregate_edits(
    file: &SourceFile,
    agg: &Aggregate,
    axis: bool,
    present: &[Option<Component>; 6],
    values: &[f64; 6],
    write: [bool; 6],
    relative: bool,
    out: &mut EditList,
    file_sep: Option<&[u8]>,
) -> bool {
    let mark = out.mark();
    let names = if axis { AXIS_NAMES } else { CARTESIAN_NAMES };
    // Decimals of inserted numbers: as many as the aggregate's most precise number.
    let decimals = |k: usize| {
        let most = present
            .iter()
            .flatten()
            .filter_map(|c| c.literal)
            .map(|(_, lit)| value::literal_decimals(file.text(lit)))
            .max()
            .unwrap_or(0);
        most.max(min_decimals(axis, k))
    };
    for k in 0..6 {
        if !write[k] {
            continue;
        }
        match &present[k] {
            Some(c) => {
                let (Some((replace, lit)), Some(orig_value)) = (c.literal, c.value) else {
                    out.truncate(mark);
                    return false;
                };
                out.replace_with(replace.range(), |text| {
                    replacement(
                        file.text(lit),
                        orig_value,
                        values[k],
                        min_decimals(axis, k),
                        text,
                    )
                });
            }
            None => {
                let text = match units(values[k], decimals(k)) {
                    Some(u) => plain_text(u, decimals(k)),
                    None => format!("{:.*}", decimals(k), values[k]),
                };
                let zero = text.bytes().all(|b| b == b'0' || b == b'.' || b == b'-');
                // A relative motion's missing components are zero: write only those that
                // are not.
                if relative && zero {
                    continue;
                }
                let (sep, nv) = separators(file, agg, file_sep);
                let text = if zero {
                    text.trim_start_matches('-').to_string()
                } else {
                    text
                };
                let mut entry = names[k].as_bytes().to_vec();
                entry.extend_from_slice(&nv);
                entry.extend_from_slice(text.as_bytes());
                // Before the first present component that follows in X..C order, else after
                // the last present one.
                if let Some(next) = (k + 1..6).find_map(|j| present[j].as_ref()) {
                    entry.extend_from_slice(&sep);
                    let at = next.member.start as usize;
                    out.replace(at..at, &entry);
                } else if let Some(prev) = (0..k).rev().find_map(|j| present[j].as_ref()) {
                    let mut text = sep.clone();
                    text.extend_from_slice(&entry);
                    let at = prev.member.end as usize;
                    out.replace(at..at, &text);
                } else {
                    out.truncate(mark);
                    return false;
                }
            }
        }
    }
    // Insertions at one offset must keep X..C order: they were pushed in that order.
    out.sort_since(mark);
    true
}

/// The decimals of a literal written plainly: `-?digits[.digits]` (no exponent, sign `+` or
/// leading dot), the style of nearly every program; those are formatted here without
/// allocation beyond the result, the others (`None`) by `format_like`.
fn plain_decimals(text: &[u8]) -> Option<usize> {
    let body = text.strip_prefix(b"-").unwrap_or(text);
    let int = body.iter().take_while(|b| b.is_ascii_digit()).count();
    if int == 0 {
        return None;
    }
    match &body[int..] {
        [] => Some(0),
        [b'.', rest @ ..] => rest.iter().all(u8::is_ascii_digit).then_some(rest.len()),
        _ => None,
    }
}

/// `value` rounded to `decimals` as an integer count of units, the way the compensation's
/// direction check rounds commands (`sequence::Quantum`).
fn units(value: f64, decimals: usize) -> Option<i64> {
    let scaled = (value * sequence::ten_to(decimals)).round();
    (scaled.abs() < 9.0e15).then_some(scaled as i64)
}

/// Appends the plain literal of `units` at `decimals` (`-0.000` written `0.000`): digits by
/// integer division, no formatting machinery. The digits go straight into `out`, over a
/// block of zeros appended at once and cut back: built in a stack buffer and copied as a
/// block, the wide load of bytes just stored one by one stalled on store forwarding (a
/// third of the function's time).
fn write_plain(units: i64, decimals: usize, out: &mut Vec<u8>) {
    /// Fraction digits written this way (10^18 < 2^64); more go the long way.
    const MAX_DECIMALS: usize = 18;
    /// Bytes of zeros appended at once: every number up to this length.
    const BLOCK: usize = 24;
    if decimals > MAX_DECIMALS {
        return write_plain_long(units, decimals, out);
    }
    let n = units.unsigned_abs();
    // The usual decimals by constant divisors (a multiplication), the rest by a division.
    let (mut int, mut frac) = match decimals {
        3 => (n / 1_000, n % 1_000),
        4 => (n / 10_000, n % 10_000),
        _ => {
            let unit = 10u64.pow(decimals as u32);
            (n / unit, n % unit)
        }
    };
    let int_digits = int.checked_ilog10().map_or(1, |l| l as usize + 1);
    let sign = usize::from(units < 0);
    let point = usize::from(decimals > 0);
    let len = sign + int_digits + point + decimals;
    let start = out.len();
    if len <= BLOCK {
        out.extend_from_slice(&[b'0'; BLOCK]);
    } else {
        out.resize(start + len, b'0');
    }
    let text = &mut out[start..start + len];
    // Right to left: the fraction (its leading zeros are there already), point, integer.
    let mut at = len;
    while frac > 0 {
        at -= 1;
        text[at] = b'0' + (frac % 10) as u8;
        frac /= 10;
    }
    at = len - decimals - point;
    if point == 1 {
        text[at] = b'.';
    }
    loop {
        at -= 1;
        text[at] = b'0' + (int % 10) as u8;
        int /= 10;
        if int == 0 {
            break;
        }
    }
    if sign == 1 {
        text[0] = b'-';
    }
    out.truncate(start + len);
}

/// [`write_plain`] for any number of decimals.
fn write_plain_long(units: i64, decimals: usize, out: &mut Vec<u8>) {
    let digits = units.unsigned_abs().to_string();
    if units < 0 {
        out.push(b'-');
    }
    if digits.len() <= decimals {
        out.extend_from_slice(b"0.");
        out.resize(out.len() + decimals - digits.len(), b'0');
        out.extend_from_slice(digits.as_bytes());
    } else {
        let (int, frac) = digits.as_bytes().split_at(digits.len() - decimals);
        out.extend_from_slice(int);
        out.push(b'.');
        out.extend_from_slice(frac);
    }
}

/// A plain literal of `units` at `decimals` (see [`write_plain`]).
fn plain_text(units: i64, decimals: usize) -> String {
    let mut out = Vec::with_capacity(24 + decimals);
    write_plain(units, decimals, &mut out);
    String::from_utf8(out).expect("digits, sign and dot are ASCII")
}

/// Appends to `out` the new text of a literal `orig_text` (value `orig`) for `value`; false
/// (nothing appended) when the written number would not change.
fn replacement(orig_text: &[u8], orig: f64, value: f64, min: usize, out: &mut Vec<u8>) -> bool {
    if let Some(own) = plain_decimals(orig_text) {
        let decimals = own.max(min);
        if let (Some(new), Some(old)) = (units(value, decimals), units(orig, decimals)) {
            if new == old {
                return false;
            }
            write_plain(new, decimals, out);
            return true;
        }
    }
    let new = format_like(orig_text, value, min);
    if new == format_like(orig_text, orig, min) {
        return false;
    }
    out.extend_from_slice(new.as_bytes());
    true
}

/// The decimals each component of the aggregate at `origin` will be written with: its own
/// literal's (never fewer than 3 in mm and 4 in degrees), or for a missing one the
/// aggregate's most precise. From what the walk read (`Origin::decimals`): where the origin is
/// known every component given is a literal.
pub fn decimals(origin: &Origin, axis: bool) -> [u8; 6] {
    let own: [Option<usize>; 6] = std::array::from_fn(|k| {
        (origin.literals & (1 << k) != 0).then_some(usize::from(origin.decimals[k]))
    });
    let most = own.iter().flatten().copied().max().unwrap_or(0);
    std::array::from_fn(|k| own[k].unwrap_or(most).max(min_decimals(axis, k)).min(12) as u8)
}

/// The place a point is named from: file and name span.
type Site = (FileId, Option<Span>);

/// One execution's edits of an origin.
struct Use<'f> {
    stop: usize,
    edits: TargetEdits,
    site: (FileId, Option<Span>),
    origin: Origin<'f>,
}

/// Computes the edits of every compensated target. `separator`: what goes between members
/// added to a partial aggregate when it has no two of its own (found in the file when `None`;
/// a streamed window is given its file's, see [`file_separator`]).
pub fn rewrite(
    ws: &Workspace,
    sim: &Simulation,
    outcomes: &[Outcome],
    robot: &crate::kinematics::RobotDescription,
    separator: Option<&[u8]>,
) -> Rewrite {
    rewrite_placed(ws, sim, outcomes, Placed::default(), robot, separator)
}

/// Targets whose edits a rewrite's list makes room for at once (a window's are fewer).
const EDITS_RESERVED: usize = 2048;

/// [`rewrite`] with the commands the compensation placed (their TCPs are not computed again).
pub fn rewrite_placed(
    ws: &Workspace,
    sim: &Simulation,
    outcomes: &[Outcome],
    placed: Placed,
    robot: &crate::kinematics::RobotDescription,
    separator: Option<&[u8]>,
) -> Rewrite {
    let mut out = Rewrite::default();
    // Each compensated target's edits, in parallel.
    /// Why a target's numbers cannot be written (the diagnostic is built afterwards: a
    /// `Diagnostic` per slot would cost a few hundred bytes for each of a million targets).
    enum Skip {
        Relative(usize),
        NotLiteral(usize),
        Circle(usize),
    }
    // One target's edits appended to a list: `None` for a target not to be written.
    let command = |i: usize| match placed.command(i) {
        Some(c) => Commanded {
            tcp: c.tcp,
            unchosen: c.unchosen,
        },
        None => Commanded {
            tcp: Nominal(robot).tcp(
                &outcomes[i].axes_deg,
                &sim.frames[sim.stops[i].tool as usize],
            ),
            unchosen: None,
        },
    };
    let command_tcp = |i: usize| command(i).tcp;
    // Targets written continuous near B = ±90°: how many, the first in the files (file and
    // byte), the most left out (rad, as bits: a maximum of non-negative numbers).
    let euler = (
        std::sync::atomic::AtomicUsize::new(0),
        std::sync::atomic::AtomicU64::new(u64::MAX),
        std::sync::atomic::AtomicU64::new(0),
    );
    let edits_into = |i: usize, list: &mut EditList| -> Option<Result<(), Skip>> {
        let (stop, o) = (&sim.stops[i], &outcomes[i]);
        let origin = stop.origin?;
        if !written(sim, outcomes, i) {
            return None;
        }
        let commanded = match circular_angle(sim, outcomes, &command_tcp, robot, i) {
            Some(Some(tcp)) => Commanded {
                tcp,
                unchosen: None,
            },
            Some(None) => return Some(Err(Skip::Circle(i))),
            None => command(i),
        };
        let file = &ws.get(origin.file).file;
        // An absolute target's programmed values are its position's (`motion::simulate`).
        let read = stop
            .rel
            .is_none()
            .then_some((&stop.programmed, origin.literals));
        let present = components(file, origin.agg, stop.axis, read);
        let original = present.map(|c| c.and_then(|c| c.value));
        let mut left = None;
        let Some(values) = new_values(
            sim,
            outcomes,
            stop,
            &o.axes_deg,
            &commanded,
            &original,
            robot,
            &mut left,
        ) else {
            return Some(Err(Skip::Relative(i)));
        };
        if let Some(l) = left {
            use std::sync::atomic::Ordering::Relaxed;
            euler.0.fetch_add(1, Relaxed);
            let place = (u64::from(stop.file) << 32) | u64::from(stop.stmt.head.start);
            euler.1.fetch_min(place, Relaxed);
            euler.2.fetch_max(l.to_bits(), Relaxed);
        }
        let write: [bool; 6] = std::array::from_fn(|k| stop.role == Role::Target || k < 3);
        let written = aggregate_edits(
            file,
            origin.agg,
            stop.axis,
            &present,
            &values,
            write,
            stop.rel.is_some(),
            list,
            separator,
        );
        Some(if written {
            Ok(())
        } else {
            Err(Skip::NotLiteral(i))
        })
    };
    let per_stop = |i: usize| -> Option<Result<Use, Skip>> {
        let mut list = EditList::new();
        let stop = &sim.stops[i];
        edits_into(i, &mut list).map(|r| {
            r.map(|()| Use {
                stop: i,
                edits: list.to_edits(),
                site: (stop.file, stop.reference),
                origin: stop.origin.expect("written for its origin"),
            })
        })
    };
    // Which aggregates are written by more than one execution: sort the (origin, stop)
    // keys; an origin used once (every target of a CAM program) takes the fast path.
    let mut keys: Vec<(FileId, u32, u32)> = (0..sim.stops.len())
        .into_par_iter()
        .with_min_len(1024)
        .filter_map(|i| {
            let origin = sim.stops[i].origin?;
            written(sim, outcomes, i).then_some((origin.file, origin.agg.span.start, i as u32))
        })
        .collect();
    keys.par_sort_unstable();
    let shared = |k: usize| {
        let same = |j: usize| keys[j].0 == keys[k].0 && keys[j].1 == keys[k].1;
        (k > 0 && same(k - 1))
            || (k + 1 < keys.len() && same(k + 1))
            // A `$config.dat` point is never written in place: copied (see `localize`).
            || ws.get(keys[k].0).role == crate::motion::workspace::Role::Config
    };
    let mut skips: Vec<Skip> = Vec::new();
    let report = |skip: Skip, out: &mut Rewrite| {
        let at_stop = |i: usize| (sim.stops[i].file, sim.stops[i].stmt.head);
        let ((file, span), why) = match skip {
            Skip::Relative(i) => (
                at_stop(i),
                "a relative target after an unknown position cannot be rewritten: left unchanged",
            ),
            Skip::Circle(i) => (
                at_stop(i),
                "no circle turns by this CA from the compensated start to the compensated end (its start unknown, or start and end together): left unchanged",
            ),
            Skip::NotLiteral(i) => {
                let origin = sim.stops[i].origin.expect("skipped for its origin");
                (
                    (origin.file, origin.agg.span),
                    "this position's numbers are not plain literals: left unchanged",
                )
            }
        };
        out.diagnostics
            .push(ws.diagnostic(Severity::Warning, file, span, why));
    };
    // Fast path, in parallel: the edits straight into one list per file.
    // (Keys are sorted by file: a chunk's edits are runs of one file each.)
    type Chunk = (Vec<(FileId, EditList)>, Vec<Skip>);
    let single: Vec<Chunk> = (0..keys.len())
        .into_par_iter()
        .with_min_len(1024)
        .filter(|&k| !shared(k))
        .fold(
            || (Vec::new(), Vec::new()),
            |(mut edits, mut skips): Chunk, k| {
                let file = keys[k].0;
                if edits.last().map_or(true, |(f, _)| *f != file) {
                    // Room for the six numbers of every target left (a window's at most).
                    let left = (keys.len() - k).min(EDITS_RESERVED);
                    edits.push((file, EditList::with_capacity(6 * left, 6 * 12 * left)));
                }
                let list = &mut edits.last_mut().expect("pushed").1;
                if let Some(Err(s)) = edits_into(keys[k].2 as usize, list) {
                    skips.push(s);
                }
                (edits, skips)
            },
        )
        .collect();
    // Joined by moving each chunk's segment (see `EditList::append`), not copying.
    for (edits, s) in single {
        for (file, mut list) in edits {
            out.edits.entry(file).or_default().append(&mut list);
        }
        skips.extend(s);
    }
    // Shared origins, grouped, in execution order.
    let mut uses: Vec<((FileId, u32), Vec<Use>)> = Vec::new();
    for k in (0..keys.len()).filter(|&k| shared(k)) {
        match per_stop(keys[k].2 as usize) {
            Some(Ok(u)) => {
                let key = (keys[k].0, keys[k].1);
                match uses.last_mut() {
                    Some((last, list)) if *last == key => list.push(u),
                    _ => uses.push((key, vec![u])),
                }
            }
            Some(Err(s)) => skips.push(s),
            None => {}
        }
    }
    for s in skips {
        report(s, &mut out);
    }
    let n = euler.0.into_inner();
    if n > 0 {
        let place = euler.1.into_inner();
        let stop = sim
            .stops
            .iter()
            .find(|s| (u64::from(s.file) << 32) | u64::from(s.stmt.head.start) == place)
            .expect("a stop written");
        out.euler = Some(EulerLeft {
            count: n,
            max_rad: f64::from_bits(euler.2.into_inner()),
            first: ws.diagnostic(Severity::Warning, stop.file, stop.stmt.head, String::new()),
        });
    }
    let mut taken: HashSet<Vec<u8>> = HashSet::new();
    for ((file, _), list) in uses {
        if ws.get(file).role == crate::motion::workspace::Role::Config {
            localize(ws, &list, &mut taken, &mut out);
            continue;
        }
        let distinct = {
            let mut v: Vec<&TargetEdits> = Vec::new();
            for u in &list {
                if !v.contains(&&u.edits) {
                    v.push(&u.edits);
                }
            }
            v.len()
        };
        let origin = list[0].origin;
        if distinct == 1 {
            let first = list.into_iter().next().expect("non-empty");
            out.edits.entry(file).or_default().extend(first.edits);
            continue;
        }
        let mut sites: Vec<Site> = Vec::new();
        for u in &list {
            if !sites.contains(&u.site) {
                sites.push(u.site);
            }
        }
        let splittable = origin.var.is_some_and(|v| !v.element)
            && sites.len() > 1
            && sites.iter().all(|s| s.1.is_some());
        if !splittable {
            let last = list.last().expect("non-empty");
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
                    list.len(),
                    stop.stmt.line
                ),
            ));
            continue;
        }
        let var = origin.var.expect("checked");
        let mut new_names = Vec::new();
        for (n, ((site_file, site_span), chosen)) in
            by_site(ws, &list, &mut out).into_iter().enumerate()
        {
            if n == 0 {
                out.edits
                    .entry(file)
                    .or_default()
                    .extend(chosen.edits.iter().cloned());
                continue;
            }
            let name = split(
                ws,
                sim,
                &var,
                &chosen.edits,
                site_file,
                site_span.expect("checked"),
                &mut taken,
                &mut out,
            );
            new_names.push(name);
        }
        let old = String::from_utf8_lossy(ws.get(var.file).file.text(var.name)).into_owned();
        out.splits.push((old, new_names));
    }
    keep_pinned(ws, sim, &mut taken, &mut out);
    out
}

/// Points used as the offset of a geometric operator (`P1 : P2`, P2 pinned: `Simulation::
/// pinned`) keep their written numbers there. Where such a point is rewritten in place for
/// another use, the operator gets an unchanged copy of it (one per point), said once.
fn keep_pinned(ws: &Workspace, sim: &Simulation, taken: &mut HashSet<Vec<u8>>, out: &mut Rewrite) {
    let mut copies: Vec<(FileId, u32, Vec<u8>)> = Vec::new();
    for p in &sim.pinned {
        let Some(var) = p.origin.var.filter(|v| !v.element) else {
            continue;
        };
        if ws.get(p.origin.file).role == crate::motion::workspace::Role::Config {
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
fn fresh_name(ws: &Workspace, base: &[u8], taken: &mut HashSet<Vec<u8>>) -> Vec<u8> {
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
#[allow(clippy::too_many_arguments)]
fn split(
    ws: &Workspace,
    sim: &Simulation,
    var: &VarRef,
    edits: &[Edit],
    site_file: FileId,
    site: Span,
    taken: &mut HashSet<Vec<u8>>,
    out: &mut Rewrite,
) -> String {
    let _ = sim;
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
fn new_name(
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
fn rename_site(
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
fn by_site<'u, 'f>(
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
fn localize(ws: &Workspace, list: &[Use], taken: &mut HashSet<Vec<u8>>, out: &mut Rewrite) {
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
fn copy_declaration(
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
fn insert_line_before_enddat(ws: &Workspace, dat: FileId, mut text: Vec<u8>, out: &mut Rewrite) {
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
fn newline_of(src: &[u8]) -> &'static [u8] {
    if src.windows(2).any(|w| w == b"\r\n") {
        b"\r\n"
    } else {
        b"\n"
    }
}

/// A declaration of `new` of the type of the point declared at `d`, on a line of its own after
/// that declaration's line, indented alike: `DECL E6AXIS XHOME_2`.
fn declare_like(ws: &Workspace, d: &Declared, new: &[u8], out: &mut Rewrite) {
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
fn line_content(f: &SourceFile, at: usize) -> (usize, usize) {
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
fn insert_line_after(
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
fn ilf_of(file: &SourceFile, site: Span) -> Option<(Span, Vec<u8>)> {
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
fn rename_in_fold(
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
    let mut fold_old = b"F".to_vec();
    fold_old.extend_from_slice(old);
    let mut fold_new = b"F".to_vec();
    fold_new.extend_from_slice(new);
    let mut used = false;
    for st in f.statements() {
        if !fold.contains(st.head) {
            continue;
        }
        let mut visit = |e: &Expr| {
            if let Expr::Path(p) = e {
                if f.text(p.root).eq_ignore_ascii_case(&fold_old) {
                    edits.push(Edit {
                        range: p.root.range(),
                        bytes: fold_new.clone(),
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
    out.edits.entry(file).or_default().extend(edits);
    if used && taken.insert(fold_new.to_ascii_uppercase()) {
        // Declare F<new> next to F<old> (or in the data list the point's copy went to).
        for (id, loaded) in ws.files.iter().enumerate() {
            for (_, d) in loaded.file.declarations() {
                for v in &d.vars {
                    if loaded.file.text(v.name).eq_ignore_ascii_case(&fold_old) {
                        let into =
                            into.filter(|_| loaded.role == crate::motion::workspace::Role::Config);
                        let (id, stmt) = (id as FileId, v.span);
                        copy_declaration(ws, id, v.name, stmt, &fold_new, &[], into, out);
                        return;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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

    /// The decimals of `agg`'s components read from its text (what `decimals` took from the
    /// file before the walk kept them).
    fn decimals_from_text(file: &SourceFile, agg: &Aggregate, axis: bool) -> [u8; 6] {
        let mut own = [None; 6];
        for (k, m) in position_members(file, agg, axis) {
            let lit = match m {
                RawMember::Plain { number, .. } => Some(number),
                RawMember::Outline { value: e, .. } => literal_span(e).map(|(_, lit)| lit),
            };
            own[k] = lit.map(|lit| value::literal_decimals(file.text(lit)));
        }
        let most = own.iter().flatten().copied().max().unwrap_or(0);
        std::array::from_fn(|k| own[k].unwrap_or(most).max(min_decimals(axis, k)).min(12) as u8)
    }

    /// The rewrite takes an absolute target's literal values from the walk
    /// (`Origin::literals`) instead of reading the numbers again, and the compensation its
    /// decimals (`Origin::decimals`): on every fixture program, every component so taken must
    /// be the number read from the file, to the bit, and the decimals those of its text.
    #[test]
    fn values_and_decimals_taken_from_the_walk_are_the_files() {
        let mut programs = Vec::new();
        sources_under(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/programs"),
            &mut programs,
        );
        let robot = crate::kinematics::RobotDescription::kr30ha();
        let (mut taken, mut files) = (0, 0);
        for path in &programs {
            let bytes = std::fs::read(path).expect("a fixture");
            let Ok(ws) = super::super::files::load_program(Some(path), &bytes, None) else {
                continue;
            };
            files += 1;
            let sim = crate::motion::simulate(&ws, &robot, &[]);
            for stop in &sim.stops {
                let Some(origin) = stop.origin.filter(|_| stop.rel.is_none()) else {
                    continue;
                };
                let file = &ws.get(origin.file).file;
                assert_eq!(
                    decimals(&origin, stop.axis),
                    decimals_from_text(file, origin.agg, stop.axis),
                    "{}",
                    path.display()
                );
                let read = components(file, origin.agg, stop.axis, None);
                let given = Some((&stop.programmed, origin.literals));
                let taken_here = components(file, origin.agg, stop.axis, given);
                for k in 0..6 {
                    let bits = |c: &Option<Component>| c.and_then(|c| c.value).map(f64::to_bits);
                    assert_eq!(bits(&read[k]), bits(&taken_here[k]), "{}", path.display());
                    if origin.literals & (1 << k) != 0 {
                        assert_eq!(read[k].and_then(|c| c.value), Some(stop.programmed[k]));
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

    /// The literal text by `format!` (the formatter the digit writer replaced): the integer
    /// count of units as a decimal string, the dot put in by hand.
    fn plain_by_format(units: i64, decimals: usize) -> String {
        let digits = units.unsigned_abs().to_string();
        let sign = if units < 0 { "-" } else { "" };
        if decimals == 0 {
            return format!("{sign}{digits}");
        }
        let padded = format!("{digits:0>width$}", width = decimals + 1);
        let (int, frac) = padded.split_at(padded.len() - decimals);
        format!("{sign}{int}.{frac}")
    }

    proptest! {
        #[test]
        fn digit_writer_matches_format(units in any::<i64>(), decimals in 0usize..30) {
            prop_assert_eq!(plain_text(units, decimals), plain_by_format(units, decimals));
        }

        /// A plain literal's replacement equals `format_like` of the new value whenever the
        /// rounded number changes and the value is not a tie between two last digits.
        #[test]
        fn replacement_matches_format_like(
            orig_units in -10_000_000i64..10_000_000,
            delta in -5.0f64..5.0,
            decimals in 0usize..6,
            min in 3usize..5,
        ) {
            let orig_text = plain_by_format(orig_units, decimals);
            let orig: f64 = orig_text.parse().unwrap();
            let value = orig + delta;
            let d = decimals.max(min);
            let scaled = value * 10f64.powi(d as i32);
            prop_assume!((scaled.fract().abs() - 0.5).abs() > 1e-6);
            let mut out = Vec::new();
            let changed = replacement(orig_text.as_bytes(), orig, value, min, &mut out);
            let by_format = format_like(orig_text.as_bytes(), value, min);
            let unchanged = by_format == format_like(orig_text.as_bytes(), orig, min);
            prop_assert_eq!(changed, !unchanged);
            if changed {
                prop_assert_eq!(String::from_utf8(out).unwrap(), by_format);
            } else {
                prop_assert!(out.is_empty());
            }
        }
    }

    #[test]
    fn plain_literals_by_hand() {
        assert_eq!(plain_text(0, 3), "0.000");
        assert_eq!(plain_text(-5, 3), "-0.005");
        assert_eq!(plain_text(12345, 3), "12.345");
        assert_eq!(plain_text(-1234500, 4), "-123.4500");
        assert_eq!(plain_text(7, 0), "7");
        assert_eq!(plain_text(i64::MIN, 2), "-92233720368547758.08");
        assert_eq!(plain_text(-12, 18), "-0.000000000000000012");
        assert_eq!(plain_text(12, 20), "0.00000000000000000012");
        assert_eq!(plain_text(i64::MAX, 18), "9.223372036854775807");
    }
}
