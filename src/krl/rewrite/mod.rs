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
//!
//! The steps are [`rewrite_placed`]'s. The rooms: `target` works out what a target's numbers
//! become, `aggregate` writes them into its aggregate's text (the digits by
//! [`krl::number`](crate::krl::number)), `shared` decides how an aggregate that several
//! executions write is written.

mod aggregate;
pub mod edits;
pub mod output;
mod shared;
mod target;

use std::collections::{BTreeMap, HashSet};
use std::sync::atomic::Ordering::Relaxed;
use std::sync::atomic::{AtomicU64, AtomicUsize};

use rayon::prelude::*;

use crate::diagnostic::{Diagnostic, Severity};
use crate::krl::interpret::value::Origin;
use crate::krl::interpret::{FileId, Simulation, Stop, Workspace};
use crate::krl::{Edit, Span};
use crate::motion::frame::Frame;
use crate::motion::nominal::{Arm, Nominal};
use crate::motion::Role;

use self::edits::EditList;
// What only robopost's own tests name through this path.
#[cfg(any(test, feature = "internals"))]
pub use crate::compensate::sequence::correction;
use crate::compensate::sequence::{Command, Outcome};
pub use aggregate::file_separator;
use aggregate::{aggregate_edits, components, AggregateTarget};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use aggregate::{MIN_DECIMALS_DEG, MIN_DECIMALS_MM};
use shared::{keep_pinned, write_shared};
use target::written;

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
    unchosen: Option<crate::kinematics::Pose>,
}

/// The edits of one target's aggregate: replacements of member values and insertions of
/// missing members (`offset`, text), in source order.
type TargetEdits = Vec<Edit>;

/// The place a point is named from: file and name span.
type Site = (FileId, Option<Span>);

/// One execution's edits of an origin.
struct Use<'f> {
    stop: usize,
    edits: TargetEdits,
    site: Site,
    origin: Origin<'f>,
}

/// Computes the edits of every compensated target. `separator`: what goes between members
/// added to a partial aggregate when it has no two of its own (found in the file when `None`;
/// a streamed window is given its file's, see [`file_separator`]).
#[cfg(any(test, feature = "internals"))]
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
///
/// The steps: find the targets to write (`Writer::written_keys`); write the aggregates that
/// one execution alone writes straight into their file's edit list, in parallel (the fast
/// path, every target of a CAM program: `Writer::write_single`); gather the executions of
/// the others per aggregate (`Writer::shared_uses`); say why some targets could not be
/// written; write each shared aggregate once, split into copies or localized
/// (`write_shared`); last, keep the offsets of geometric operators (`keep_pinned`).
pub fn rewrite_placed(
    ws: &Workspace,
    sim: &Simulation,
    outcomes: &[Outcome],
    placed: Placed,
    robot: &crate::kinematics::RobotDescription,
    separator: Option<&[u8]>,
) -> Rewrite {
    let writer = Writer {
        ws,
        sim,
        outcomes,
        placed,
        robot,
        separator,
        euler: EulerTally::default(),
    };
    let keys = writer.written_keys();
    let mut out = Rewrite::default();
    let mut skips = writer.write_single(&keys, &mut out);
    let shared = writer.shared_uses(&keys, &mut skips);
    for skip in skips {
        out.diagnostics.push(skip.diagnostic(ws, sim));
    }
    out.euler = writer.euler.into_left(ws, sim);
    let mut taken: HashSet<Vec<u8>> = HashSet::new();
    for origin in shared {
        write_shared(ws, sim, origin, &mut taken, &mut out);
    }
    keep_pinned(ws, sim, &mut taken, &mut out);
    out
}

/// Why a target's numbers cannot be written. The diagnostic is built afterwards, for the few
/// skipped: a `Diagnostic` per target would cost a few hundred bytes for each of a million.
enum Skip {
    /// A relative target after an unknown position.
    Relative(usize),
    /// A number to replace is not a literal.
    NotLiteral(usize),
    /// No circle turns by the `CA` from the compensated start to the compensated end.
    Circle(usize),
}

impl Skip {
    fn diagnostic(self, ws: &Workspace, sim: &Simulation) -> Diagnostic {
        let at_stop = |i: usize| (sim.stops[i].handle.file, sim.stops[i].handle.stmt.head);
        let ((file, span), why) = match self {
            Skip::Relative(i) => (
                at_stop(i),
                "a relative target after an unknown position cannot be rewritten: left unchanged",
            ),
            Skip::Circle(i) => (
                at_stop(i),
                "no circle turns by this CA from the compensated start to the compensated end (its start unknown, or start and end together): left unchanged",
            ),
            Skip::NotLiteral(i) => {
                let origin = sim.stops[i].handle.origin.expect("skipped for its origin");
                (
                    (origin.file, origin.agg.span),
                    "this position's numbers are not plain literals: left unchanged",
                )
            }
        };
        ws.diagnostic(Severity::Warning, file, span, why)
    }
}

/// What became of one target's numbers ([`Writer::target_edits`]).
enum TargetWrite {
    /// Nothing to write: not compensated, unchanged, or not written from an aggregate.
    Unwritten,
    /// Its edits were appended.
    Written,
    Skipped(Skip),
}

/// A written target: its aggregate (file, where it starts) and the stop executing it. Sorted,
/// the executions of one aggregate are neighbours, in execution order.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct UseKey {
    file: FileId,
    agg_start: u32,
    stop: u32,
}

impl UseKey {
    fn same_aggregate(&self, other: &UseKey) -> bool {
        self.file == other.file && self.agg_start == other.agg_start
    }
}

/// The executions of an aggregate written by several (or of a `$config.dat` point), each with
/// its edits: [`write_shared`] decides how it is written.
struct SharedOrigin<'f> {
    file: FileId,
    uses: Vec<Use<'f>>,
}

/// Targets written continuous near B = ±90°, counted from the parallel fast path: how many,
/// the first in the files (file and byte), the most left out (rad, as bits: a maximum of
/// non-negative numbers).
struct EulerTally {
    count: AtomicUsize,
    first_place: AtomicU64,
    max_left_bits: AtomicU64,
}

impl Default for EulerTally {
    fn default() -> Self {
        EulerTally {
            count: AtomicUsize::new(0),
            first_place: AtomicU64::new(u64::MAX),
            max_left_bits: AtomicU64::new(0),
        }
    }
}

impl EulerTally {
    fn place(stop: &Stop) -> u64 {
        (u64::from(stop.handle.file) << 32) | u64::from(stop.handle.stmt.head.start)
    }

    fn record(&self, stop: &Stop, left_rad: f64) {
        self.count.fetch_add(1, Relaxed);
        self.first_place.fetch_min(Self::place(stop), Relaxed);
        self.max_left_bits.fetch_max(left_rad.to_bits(), Relaxed);
    }

    /// The program's warning, if any target was written so.
    fn into_left(self, ws: &Workspace, sim: &Simulation) -> Option<EulerLeft> {
        let count = self.count.into_inner();
        if count == 0 {
            return None;
        }
        let place = self.first_place.into_inner();
        let stop = sim
            .stops
            .iter()
            .find(|s| Self::place(s) == place)
            .expect("a stop written");
        Some(EulerLeft {
            count,
            max_rad: f64::from_bits(self.max_left_bits.into_inner()),
            first: ws.diagnostic(
                Severity::Warning,
                stop.handle.file,
                stop.handle.stmt.head,
                String::new(),
            ),
        })
    }
}

/// One rewrite's inputs, shared by its steps (and by the threads of the fast path).
struct Writer<'a> {
    ws: &'a Workspace,
    sim: &'a Simulation<'a>,
    outcomes: &'a [Outcome],
    placed: Placed<'a>,
    robot: &'a crate::kinematics::RobotDescription,
    separator: Option<&'a [u8]>,
    euler: EulerTally,
}

impl<'a> Writer<'a> {
    /// The targets whose numbers are written, sorted by aggregate ([`UseKey`]).
    fn written_keys(&self) -> Vec<UseKey> {
        let (sim, outcomes) = (self.sim, self.outcomes);
        let mut keys: Vec<UseKey> = (0..sim.stops.len())
            .into_par_iter()
            .with_min_len(1024)
            .filter_map(|i| {
                let origin = sim.stops[i].handle.origin.as_ref()?;
                written(sim, outcomes, i).then_some(UseKey {
                    file: origin.file,
                    agg_start: origin.agg.span.start,
                    stop: i as u32,
                })
            })
            .collect();
        keys.par_sort_unstable();
        keys
    }

    /// Whether `keys[k]`'s aggregate is written by more than one execution, or is a
    /// `$config.dat` point (never written in place but copied: see [`localize`]).
    fn is_shared(&self, keys: &[UseKey], k: usize) -> bool {
        (k > 0 && keys[k - 1].same_aggregate(&keys[k]))
            || keys
                .get(k + 1)
                .is_some_and(|next| next.same_aggregate(&keys[k]))
            || self.ws.get(keys[k].file).role == crate::krl::interpret::workspace::Role::Config
    }

    /// The fast path, in parallel: each aggregate that one execution alone writes, its edits
    /// straight into one list per file (keys are sorted by file: a chunk's edits are runs of
    /// one file each; chunks are joined by moving their segments, see `EditList::append`).
    /// Returns the targets skipped.
    fn write_single(&self, keys: &[UseKey], out: &mut Rewrite) -> Vec<Skip> {
        type Chunk = (Vec<(FileId, EditList)>, Vec<Skip>);
        let chunks: Vec<Chunk> = (0..keys.len())
            .into_par_iter()
            .with_min_len(1024)
            .filter(|&k| !self.is_shared(keys, k))
            .fold(
                || (Vec::new(), Vec::new()),
                |(mut edits, mut skips): Chunk, k| {
                    let file = keys[k].file;
                    if edits.last().map_or(true, |(f, _)| *f != file) {
                        // Room for the six numbers of every target left (a window's at most).
                        let left = (keys.len() - k).min(EDITS_RESERVED);
                        edits.push((file, EditList::with_capacity(6 * left, 6 * 12 * left)));
                    }
                    let list = &mut edits.last_mut().expect("pushed").1;
                    if let TargetWrite::Skipped(s) = self.target_edits(keys[k].stop as usize, list)
                    {
                        skips.push(s);
                    }
                    (edits, skips)
                },
            )
            .collect();
        let mut skips = Vec::new();
        for (edits, s) in chunks {
            for (file, mut list) in edits {
                out.edits.entry(file).or_default().append(&mut list);
            }
            skips.extend(s);
        }
        skips
    }

    /// The slow path's input: the executions of each shared aggregate ([`Self::is_shared`]),
    /// grouped, in execution order, each with edits of its own. Targets skipped are added to
    /// `skips`.
    fn shared_uses(&self, keys: &[UseKey], skips: &mut Vec<Skip>) -> Vec<SharedOrigin<'a>> {
        let mut shared: Vec<SharedOrigin> = Vec::new();
        let mut last: Option<UseKey> = None;
        for k in (0..keys.len()).filter(|&k| self.is_shared(keys, k)) {
            let i = keys[k].stop as usize;
            let mut list = EditList::new();
            match self.target_edits(i, &mut list) {
                TargetWrite::Written => {
                    let stop = &self.sim.stops[i];
                    let u = Use {
                        stop: i,
                        edits: list.to_edits(),
                        site: (stop.handle.file, stop.handle.reference),
                        origin: stop.handle.origin.expect("written for its origin"),
                    };
                    match shared.last_mut() {
                        Some(s) if last.is_some_and(|l| l.same_aggregate(&keys[k])) => {
                            s.uses.push(u)
                        }
                        _ => shared.push(SharedOrigin {
                            file: keys[k].file,
                            uses: vec![u],
                        }),
                    }
                    last = Some(keys[k]);
                }
                TargetWrite::Skipped(s) => skips.push(s),
                TargetWrite::Unwritten => {}
            }
        }
        shared
    }

    /// The TCP stop `i` is commanded to: the one the compensation placed, or computed from its
    /// axes.
    fn commanded(&self, i: usize) -> Commanded {
        match self.placed.command(i) {
            Some(c) => Commanded {
                tcp: c.tcp,
                unchosen: c.unchosen,
            },
            None => Commanded {
                tcp: Nominal(self.robot).tcp(
                    &self.outcomes[i].axes_deg,
                    &self.sim.frames[self.sim.stops[i].tool as usize],
                ),
                unchosen: None,
            },
        }
    }

    /// Appends to `list` the edits writing target `i`'s command into its aggregate.
    fn target_edits(&self, i: usize, list: &mut EditList) -> TargetWrite {
        let (sim, stop) = (self.sim, &self.sim.stops[i]);
        let Some(origin) = stop
            .handle
            .origin
            .as_ref()
            .filter(|_| written(sim, self.outcomes, i))
        else {
            return TargetWrite::Unwritten;
        };
        let commanded = match self.circular_angle(i) {
            Some(Some(tcp)) => Commanded {
                tcp,
                unchosen: None,
            },
            Some(None) => return TargetWrite::Skipped(Skip::Circle(i)),
            None => self.commanded(i),
        };
        let file = &self.ws.get(origin.file).file;
        // An absolute target's programmed values are its position's (`crate::krl::interpret::simulate`).
        let programmed = stop.programmed.components();
        let read = stop.rel.is_none().then_some((&programmed, origin.literals));
        let present = components(
            file,
            origin.agg,
            crate::krl::interpret::value::Naming::of(&stop.programmed),
            read,
        );
        let original = present.map(|c| c.and_then(|c| c.value));
        let axes = &self.outcomes[i].axes_deg;
        let Some((values, left)) = self.new_values(stop, axes, &commanded, &original) else {
            return TargetWrite::Skipped(Skip::Relative(i));
        };
        if let Some(left) = left {
            self.euler.record(stop, left);
        }
        let write: [bool; 6] = std::array::from_fn(|k| stop.role == Role::Target || k < 3);
        let target = AggregateTarget {
            file,
            agg: origin.agg,
            naming: crate::krl::interpret::value::Naming::of(&stop.programmed),
            relative: stop.rel.is_some(),
            file_sep: self.separator,
        };
        if aggregate_edits(&target, &present, &values.components(), write, list) {
            TargetWrite::Written
        } else {
            TargetWrite::Skipped(Skip::NotLiteral(i))
        }
    }
}
