//! Which targets are compensated as offline points and which are left as taught ones
//! (`--points offline|taught|auto`): `auto` takes each target as its files' evidence says
//! (`crate::krl::interpret::provenance`), the others every target alike. A taught point is already where
//! the operator put it: compensating it would move the robot away by the model's correction.
//! The tally says, per kind of evidence, how many targets were taken as which, and names the
//! declared points taken as taught.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::krl::interpret::provenance::{self, Evidence, Facts};
use crate::krl::interpret::{Stop, Workspace};
use crate::motion::frame::Frame;

/// `--points`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Taken {
    /// Each target as the evidence says.
    #[default]
    Auto,
    /// Every target computed away from the robot: all compensated.
    Offline,
    /// Every target taught on the robot: none compensated.
    Taught,
}

impl Taken {
    /// The option's value as `--points` spells it.
    pub fn name(self) -> &'static str {
        match self {
            Taken::Auto => "auto",
            Taken::Offline => "offline",
            Taken::Taught => "taught",
        }
    }
}

/// The decision for one program: the mode and what its files say.
#[derive(Debug)]
pub struct Taking {
    pub mode: Taken,
    facts: Facts,
    /// With `--from`: per stop of the whole-tree walk, where the robot the points were taught
    /// on reaches a target taken as taught (its model at the axis angles the controller
    /// stored, with the gear-play history of the program's motion) — the goal it is
    /// compensated to instead of its written pose. `None` for the other targets.
    places: Option<Vec<Option<Frame>>>,
}

impl Taking {
    pub fn new(ws: &Workspace, mode: Taken) -> Taking {
        let facts = match mode {
            Taken::Auto => Facts::of(ws),
            _ => Facts::default(),
        };
        Taking {
            mode,
            facts,
            places: None,
        }
    }

    /// The places of the taught targets on the robot they were taught on (see `places`).
    pub fn with_places(mut self, places: Vec<Option<Frame>>) -> Taking {
        self.places = Some(places);
        self
    }

    /// Whether taught targets are moved (`--from`) rather than left.
    pub fn moves(&self) -> bool {
        self.places.is_some()
    }

    /// Where stop `k` of the walk is to go, when it is a taught target moved (`--from`).
    pub fn place(&self, k: usize) -> Option<&Frame> {
        self.places.as_ref()?.get(k)?.as_ref()
    }

    /// The evidence on `stop` (`Literal` without looking when the mode decides alone).
    pub fn evidence(&self, ws: &Workspace, stop: &Stop) -> Evidence {
        match self.mode {
            Taken::Auto => self.facts.evidence(ws, stop),
            _ => Evidence::Literal,
        }
    }

    /// Whether `stop` is taken as taught.
    pub fn taught(&self, ws: &Workspace, stop: &Stop) -> bool {
        match self.mode {
            Taken::Auto => self.facts.evidence(ws, stop).taught(),
            Taken::Offline => false,
            Taken::Taught => true,
        }
    }

    /// The generator header of a file of `ws`, for the report's wording.
    pub fn header_of(&self, ws: &Workspace, stop: &Stop) -> Option<String> {
        let file = stop
            .handle
            .origin
            .and_then(|o| o.var)
            .map_or(stop.handle.file, |v| v.file);
        let (f, h) = self
            .facts
            .header(ws, file)
            .or_else(|| self.facts.header(ws, stop.handle.file))?;
        Some(format!("{}:{} (\"{}\")", ws.get(f).name, h.line, h.word))
    }
}

/// How many targets were taken as which, and why.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct PointsTaken {
    /// `auto`, `offline` or `taught` (`--points`).
    pub mode: &'static str,
    /// Targets taken as taught (left as they are unless `--from`).
    pub taught: usize,
    /// Targets taken as offline (compensated).
    pub offline: usize,
    /// Per reason: taken as which, why, how many targets, the first one's place.
    pub reasons: Vec<Reason>,
    /// The declared points taken as taught: `file:line NAME`.
    pub taught_points: Vec<String>,
    /// `--from`: the taught targets were compensated to where the robot they were taught on
    /// reaches them (rather than left as they are).
    pub moved_from: bool,
}

/// One reason for taking targets as taught or offline.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Reason {
    /// `taught` or `offline`.
    pub taken: &'static str,
    /// The evidence, in words (e.g. the header that says the points were taught).
    pub why: String,
    /// How many targets this reason took.
    pub targets: usize,
    /// The first target's motion statement: `file:line`.
    pub first: String,
}

/// The running tally (segment by segment).
#[derive(Debug, Default)]
pub(super) struct Tally {
    /// (taught, evidence) → (count, first place, header wording).
    by: BTreeMap<(bool, Evidence), (usize, String, Option<String>)>,
    taught_points: Vec<String>,
}

impl Tally {
    pub fn add(&mut self, ws: &Workspace, taking: &Taking, stops: &[Stop]) {
        for s in stops.iter().filter(|s| !s.ghost) {
            let evidence = taking.evidence(ws, s);
            let taught = match taking.mode {
                Taken::Auto => evidence.taught(),
                m => m == Taken::Taught,
            };
            let entry = self.by.entry((taught, evidence)).or_insert_with(|| {
                let header = (evidence == Evidence::Generator)
                    .then(|| taking.header_of(ws, s))
                    .flatten();
                (
                    0,
                    format!("{}:{}", ws.get(s.handle.file).name, s.handle.stmt.line),
                    header,
                )
            });
            entry.0 += 1;
            if taught {
                if let Some((f, name)) = provenance::point_name(s) {
                    let file = ws.get(f);
                    let text = format!(
                        "{}:{} {}",
                        file.name,
                        file.file.line_col(name.start as usize).0,
                        String::from_utf8_lossy(file.file.text(name))
                    );
                    if !self.taught_points.contains(&text) {
                        self.taught_points.push(text);
                    }
                }
            }
        }
    }

    pub fn fill(&self, mode: Taken, moved_from: bool) -> PointsTaken {
        let mut out = PointsTaken {
            mode: mode.name(),
            moved_from,
            taught_points: self.taught_points.clone(),
            ..PointsTaken::default()
        };
        for ((taught, evidence), (n, first, header)) in &self.by {
            if *taught {
                out.taught += n;
            } else {
                out.offline += n;
            }
            let why = match (mode, header) {
                (Taken::Offline, _) => "--points offline".to_string(),
                (Taken::Taught, _) => "--points taught".to_string(),
                (Taken::Auto, Some(h)) => format!("{} at {h}", evidence.why()),
                (Taken::Auto, None) => evidence.why().to_string(),
            };
            out.reasons.push(Reason {
                taken: if *taught { "taught" } else { "offline" },
                why,
                targets: *n,
                first: first.clone(),
            });
        }
        out
    }
}

impl PointsTaken {
    /// `; 4 targets taken as taught (a teach-pendant inline form …), left as they are` —
    /// empty when every target was taken as offline by default (nothing to say).
    pub fn text(&self) -> String {
        if self.taught == 0 && self.mode == "auto" {
            return String::new();
        }
        let reasons = |taught: &str| {
            self.reasons
                .iter()
                .filter(|r| r.taken == taught)
                .map(|r| format!("{} {}", r.targets, r.why))
                .collect::<Vec<_>>()
                .join("; ")
        };
        let mut text = format!(
            "; {} target{} taken as taught ({}){}, {} as offline",
            self.taught,
            if self.taught == 1 { "" } else { "s" },
            reasons("taught"),
            if self.moved_from {
                " and moved to where the robot of --from reaches them"
            } else {
                ""
            },
            self.offline
        );
        if self.offline > 0 {
            text += &format!(" ({})", reasons("offline"));
        }
        text
    }
}
