//! The one place that knows every effect by name: parsing a contract name (`geometric`,
//! `map:A2`, `crosstalk:A3->A2`, case-insensitive) into its kind and axes, expanding
//! `A1..A6` in lists, and building an effect either at zero for identification or from its
//! calibration record. Adding an effect is one file in `effects/` plus one entry in [`KINDS`]
//! (or, for an effect defined outside the crate, one call of [`register`]); identification,
//! compensation and diagnosis ask the effect ([`Effect::role`](super::Effect::role)) or its
//! [`Kind`] what they need and never match a name.

use std::fmt;
use std::sync::RwLock;

use super::effects::{
    compliance::{self, Compliance},
    crosstalk::{self, Crosstalk},
    drift::Drift,
    geometric::Geometric,
    learned::Learned,
    loadplay::LoadPlay,
    map::AngleMap,
    play::GearPlay,
    tilt::Tilt,
    EffectError, GridOptions, ModelEffect,
};
use super::record::{EffectRecord, RecordError};
use crate::kinematics::RobotDescription;

/// Which axes a kind of effect is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arity {
    /// `geometric`, `drift`.
    Robot,
    /// `map:An`.
    Axis,
    /// `crosstalk:Am->An`.
    Pair,
    /// `learned:<definition>`: the name carries the effect's definition.
    Spec,
}

/// The axes of one effect name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Axes {
    None,
    One(u8),
    Pair {
        from: u8,
        to: u8,
    },
    /// The canonical definition after the prefix (`rotation@A1(reach*A1)`).
    Spec(&'static str),
}

/// A kind of effect: how its name is spelled and how to build one.
pub struct Kind {
    pub prefix: &'static str,
    pub arity: Arity,
    /// The physical effect, as in the contract table.
    pub meaning: &'static str,
    /// A zero effect for identification.
    pub create: CreateFn,
    /// The effect described by a calibration record.
    pub decode: DecodeFn,
    /// Rewrites a record of format `robopost-calibration/1` into this format's meaning, for
    /// the kinds whose meaning changed.
    pub upgrade_v1: Option<UpgradeFn>,
    /// The effects that physics makes look like this one on a campaign (names), which a
    /// diagnosis re-identifies beside it before it names one.
    pub look_alikes: fn(Axes) -> Vec<String>,
    /// Whether the effect is driven by the clock (column `t`): a diagnosis validates it on
    /// the latest data, as it must extrapolate in time.
    pub in_time: bool,
    /// What in the residual shows this effect: the reader a diagnosis uses for its evidence
    /// sentence.
    pub evidence: Evidence,
}

/// The signature of an effect in the residual, which a diagnosis reads for its evidence
/// sentence (each reader lives in `diagnose::evidence`). A new kind picks the reader that
/// fits its physics, or [`Evidence::Meaning`] to state what it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Evidence {
    /// Constant over the data: the axis lines' geometry or the target vector.
    AxisLines,
    /// The residual along an axis's motion varies with its own angle.
    OwnAngle,
    /// It differs between the rotation directions, and with the travel since a reversal.
    DirectionDifference,
    /// It varies with another axis's angle.
    CrossAngle,
    /// It grows with the axis's gravity torque.
    GravityTorque,
    /// The axis's rotation axis tilts with its angle.
    TiltMotion,
    /// It grows with time.
    Time,
    /// None of these: the sentence states the kind's meaning.
    Meaning,
}

pub type CreateFn =
    fn(Axes, &GridOptions, &RobotDescription) -> Result<Box<dyn ModelEffect>, EffectError>;
pub type DecodeFn =
    fn(Axes, &EffectRecord, &RobotDescription) -> Result<Box<dyn ModelEffect>, RecordError>;
pub type UpgradeFn = fn(&mut EffectRecord) -> Result<(), RecordError>;

fn one(axes: Axes) -> u8 {
    match axes {
        Axes::One(n) => n,
        _ => 0,
    }
}
fn pair(axes: Axes) -> (u8, u8) {
    match axes {
        Axes::Pair { from, to } => (from, to),
        _ => (0, 0),
    }
}
fn spec(axes: Axes) -> &'static str {
    match axes {
        Axes::Spec(s) => s,
        _ => "",
    }
}
fn boxed<E: ModelEffect + 'static, Er>(r: Result<E, Er>) -> Result<Box<dyn ModelEffect>, Er> {
    r.map(|e| Box::new(e) as Box<dyn ModelEffect>)
}

fn none(_: Axes) -> Vec<String> {
    Vec::new()
}

/// The paper's full model (section 2): the axis lines' geometry, each axis's angle map and
/// its direction dependence, and the crosstalk of A3 onto A2.
pub const PAPER_EFFECTS: &str = "geometric,map:A1..A6,backlash:A1..A6,crosstalk:A3->A2";

/// Every built-in effect kind, in the contract table's order (a diagnosis tries them in this
/// order; see [`kinds`] for the registered ones too).
pub static KINDS: &[Kind] = &[
    Kind {
        prefix: "geometric",
        arity: Arity::Robot,
        meaning: "position/orientation errors of the axis average lines and the target vector",
        create: |_, _, _| Ok(Box::new(Geometric::default())),
        decode: |_, r, _| boxed(Geometric::from_record(r)),
        upgrade_v1: None,
        look_alikes: none,
        in_time: false,
        evidence: Evidence::AxisLines,
    },
    Kind {
        prefix: "map",
        arity: Arity::Axis,
        meaning: "angular positioning deviation of an axis over its own angle",
        create: |a, o, r| boxed(AngleMap::zeros(one(a), o, r)),
        decode: |a, rec, _| boxed(AngleMap::from_record(one(a), rec)),
        upgrade_v1: None,
        look_alikes: none,
        in_time: false,
        evidence: Evidence::OwnAngle,
    },
    Kind {
        prefix: "backlash",
        arity: Arity::Axis,
        meaning: "dependence of that deviation on the rotation direction, as a gear play",
        create: |a, o, r| boxed(GearPlay::zeros(one(a), o, r)),
        decode: |a, rec, _| boxed(GearPlay::from_record(one(a), rec)),
        upgrade_v1: Some(GearPlay::upgrade_v1),
        look_alikes: none,
        in_time: false,
        evidence: Evidence::DirectionDifference,
    },
    Kind {
        prefix: "crosstalk",
        arity: Arity::Pair,
        meaning: "deviation of an axis depending on the angle of another",
        create: |a, o, r| {
            let (m, n) = pair(a);
            boxed(Crosstalk::zeros(m, n, o, r))
        },
        decode: |a, rec, _| {
            let (m, n) = pair(a);
            boxed(Crosstalk::from_record(m, n, rec))
        },
        upgrade_v1: None,
        look_alikes: |a| {
            let (m, n) = pair(a);
            crosstalk::gravity_look_alikes(m, n)
        },
        in_time: false,
        evidence: Evidence::CrossAngle,
    },
    Kind {
        prefix: "compliance",
        arity: Arity::Axis,
        meaning: "elastic deflection proportional to the gravity torque",
        create: |a, _, r| boxed(Compliance::zeros(one(a), r)),
        decode: |a, rec, r| boxed(Compliance::from_record(one(a), rec, r)),
        upgrade_v1: None,
        look_alikes: |a| compliance::gravity_look_alikes(one(a)),
        in_time: false,
        evidence: Evidence::GravityTorque,
    },
    Kind {
        prefix: "loadplay",
        arity: Arity::Axis,
        meaning: "gear play whose flank follows the net torque (gravity less counterbalance) beyond friction, the direction of motion only near zero torque",
        create: |a, _, r| boxed(LoadPlay::zeros(one(a), r)),
        decode: |a, rec, r| boxed(LoadPlay::from_record(one(a), rec, r)),
        upgrade_v1: None,
        look_alikes: none,
        in_time: false,
        evidence: Evidence::DirectionDifference,
    },
    Kind {
        prefix: "tilt",
        arity: Arity::Axis,
        meaning: "tilt error motion of an axis over its own angle",
        create: |a, _, _| Ok(Box::new(Tilt::zeros(one(a)))),
        decode: |a, rec, _| boxed(Tilt::from_record(one(a), rec)),
        upgrade_v1: None,
        look_alikes: none,
        in_time: false,
        evidence: Evidence::TiltMotion,
    },
    Kind {
        prefix: "drift",
        arity: Arity::Robot,
        meaning: "geometry change linear in time",
        create: |_, _, _| Ok(Box::new(Drift::default())),
        decode: |_, r, _| boxed(Drift::from_record(r)),
        upgrade_v1: None,
        look_alikes: none,
        in_time: true,
        evidence: Evidence::Time,
    },
    Kind {
        prefix: "learned",
        arity: Arity::Spec,
        meaning: "a smooth function of chosen drivers, acting as an angle deviation, a rotation or an offset",
        create: |a, _, r| boxed(Learned::zeros(spec(a), r)),
        decode: |a, rec, r| boxed(Learned::from_record(spec(a), rec, r)),
        upgrade_v1: None,
        look_alikes: none,
        in_time: false,
        evidence: Evidence::Meaning,
    },
];

/// Kinds added at run time by [`register`], after the built-in ones.
static REGISTERED: RwLock<Vec<&'static Kind>> = RwLock::new(Vec::new());

/// Why [`register`] refused a kind.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
#[cfg(any(test, feature = "internals"))]
pub enum RegisterError {
    /// The prefix is empty or has characters other than lowercase letters, digits and `_`.
    #[error("an effect prefix of lowercase letters, digits and `_`, found `{prefix}`")]
    BadPrefix { prefix: &'static str },
    /// Another kind (built-in or registered) already has this prefix.
    #[error("the effect prefix `{prefix}` is taken")]
    Taken { prefix: &'static str },
}

/// Adds a kind of effect defined outside this crate (a plug-in, a test's own physics): its
/// names parse, calibration files carry it, identification and compensation use it, and a
/// diagnosis tries it after the built-in kinds. Registering the same kind again is a no-op;
/// a different kind with a prefix already taken is refused.
#[cfg(any(test, feature = "internals"))]
pub fn register(kind: &'static Kind) -> Result<(), RegisterError> {
    let valid = !kind.prefix.is_empty()
        && kind
            .prefix
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
    if !valid {
        return Err(RegisterError::BadPrefix {
            prefix: kind.prefix,
        });
    }
    let mut registered = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
    let taken = kinds_in(&registered).find(|k| k.prefix.eq_ignore_ascii_case(kind.prefix));
    match taken {
        Some(k) if std::ptr::eq(k, kind) => Ok(()),
        Some(_) => Err(RegisterError::Taken {
            prefix: kind.prefix,
        }),
        None => {
            registered.push(kind);
            Ok(())
        }
    }
}

fn kinds_in<'a>(registered: &'a [&'static Kind]) -> impl Iterator<Item = &'static Kind> + 'a {
    KINDS.iter().chain(registered.iter().copied())
}

/// Every kind of effect: the built-in ones in the contract table's order, then the
/// registered ones in their order of registration.
pub fn kinds() -> Vec<&'static Kind> {
    let registered = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
    kinds_in(&registered).collect()
}

/// A parsed effect name.
#[derive(Clone, Copy)]
pub struct EffectName {
    /// The kind of effect (its prefix, arity, meaning and constructor).
    pub(crate) kind: &'static Kind,
    /// The axis or axes it is of (none, one, or a pair for crosstalk).
    pub(crate) axes: Axes,
}

impl PartialEq for EffectName {
    fn eq(&self, other: &Self) -> bool {
        self.kind.prefix == other.kind.prefix && self.axes == other.axes
    }
}

impl fmt::Debug for EffectName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EffectName({self})")
    }
}

/// The canonical spelling: `geometric`, `map:A2`, `crosstalk:A3->A2`.
impl fmt::Display for EffectName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.axes {
            Axes::None => write!(f, "{}", self.kind.prefix),
            Axes::One(n) => write!(f, "{}:A{n}", self.kind.prefix),
            Axes::Pair { from, to } => write!(f, "{}:A{from}->A{to}", self.kind.prefix),
            Axes::Spec(s) => write!(f, "{}:{s}", self.kind.prefix),
        }
    }
}

/// A name that is not an effect: what was expected and what was found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("expected {expected}, found `{found}`")]
pub struct NameError {
    /// The names (or the syntax) allowed there.
    pub expected: String,
    /// What was given.
    pub found: String,
}

fn name_error(expected: impl Into<String>, found: &str) -> NameError {
    NameError {
        expected: expected.into(),
        found: found.to_string(),
    }
}

impl Kind {
    /// How a name of this kind is spelled, for messages: `geometric`, `map:An`,
    /// `crosstalk:Am->An`, `learned:<action>(<drivers>)`.
    pub fn spelling(&self) -> String {
        let p = self.prefix;
        match self.arity {
            Arity::Robot => p.to_string(),
            Arity::Axis => format!("{p}:An"),
            Arity::Pair => format!("{p}:Am->An"),
            Arity::Spec => format!("{p}:<action>(<drivers>)"),
        }
    }
}

/// The names a parse accepts, for its message: every built-in kind's spelling, then the
/// kinds registered at run time.
fn known() -> String {
    let builtin: Vec<String> = KINDS.iter().map(Kind::spelling).collect();
    let known = format!("an effect name ({})", builtin.join(", "));
    let registered = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
    if registered.is_empty() {
        return known;
    }
    let extra: Vec<&str> = registered.iter().map(|k| k.prefix).collect();
    format!("{known} or a registered one ({})", extra.join(", "))
}

/// `a3` / `A3` → 3, checking the range 1..=6.
fn parse_axis(text: &str, whole: &str) -> Result<u8, NameError> {
    let digits = text
        .trim()
        .strip_prefix(['a', 'A'])
        .ok_or_else(|| name_error("an axis A1..A6", whole))?;
    match digits.parse::<u32>() {
        Ok(n @ 1..=6) => Ok(n as u8),
        Ok(n) => Err(name_error(
            "an axis number in 1..6",
            &format!("{whole} (axis {n})"),
        )),
        Err(_) => Err(name_error("an axis A1..A6", whole)),
    }
}

impl EffectName {
    /// Parses a contract name, case-insensitively.
    pub fn parse(text: &str) -> Result<EffectName, NameError> {
        let trimmed = text.trim();
        let (prefix, rest) = match trimmed.split_once(':') {
            Some((p, r)) => (p.trim(), Some(r.trim())),
            None => (trimmed, None),
        };
        let kind = kinds()
            .into_iter()
            .find(|k| k.prefix.eq_ignore_ascii_case(prefix))
            .ok_or_else(|| name_error(known(), trimmed))?;
        let axes = match (kind.arity, rest) {
            (Arity::Robot, None) => Axes::None,
            (Arity::Robot, Some(_)) => {
                return Err(name_error(
                    format!("`{}` without axes", kind.prefix),
                    trimmed,
                ))
            }
            (Arity::Axis, Some(r)) => Axes::One(parse_axis(r, trimmed)?),
            (Arity::Pair, Some(r)) => {
                let (m, n) = r
                    .split_once("->")
                    .ok_or_else(|| name_error("crosstalk:Am->An", trimmed))?;
                let (from, to) = (parse_axis(m, trimmed)?, parse_axis(n, trimmed)?);
                if from == to {
                    return Err(name_error(
                        "two different axes (crosstalk:Am->An, m ≠ n)",
                        trimmed,
                    ));
                }
                Axes::Pair { from, to }
            }
            (Arity::Spec, Some(r)) => {
                Axes::Spec(super::effects::learned::canonical(r).map_err(|e| {
                    name_error(
                        format!("{} ({e})", super::effects::learned::SPELLING),
                        trimmed,
                    )
                })?)
            }
            (Arity::Spec, None) => {
                return Err(name_error(super::effects::learned::SPELLING, trimmed))
            }
            (Arity::Axis, None) => return Err(name_error(format!("{}:An", kind.prefix), trimmed)),
            (Arity::Pair, None) => return Err(name_error("crosstalk:Am->An", trimmed)),
        };
        Ok(EffectName { kind, axes })
    }

    /// A zero effect of this name for identification.
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn create(
        &self,
        options: &GridOptions,
        robot: &RobotDescription,
    ) -> Result<Box<dyn ModelEffect>, EffectError> {
        (self.kind.create)(self.axes, options, robot)
    }

    /// The effect a calibration record describes (its name already parsed into `self`).
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn decode(
        &self,
        record: &EffectRecord,
        robot: &RobotDescription,
    ) -> Result<Box<dyn ModelEffect>, RecordError> {
        (self.kind.decode)(self.axes, record, robot)
    }
}

/// Splits a comma-separated list and expands `Ai..Aj` inside each name (`map:A1..A6` → six
/// names, `crosstalk:A1..A3->A6` → three), returning canonical names in order.
pub fn expand_list(list: &str) -> Result<Vec<EffectName>, NameError> {
    let mut names = Vec::new();
    for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        match expand_range(item)? {
            Some(expanded) => {
                for name in expanded {
                    names.push(EffectName::parse(&name)?);
                }
            }
            None => names.push(EffectName::parse(item)?),
        }
    }
    Ok(names)
}

/// `…Ai..Aj…` → the names with `Ak` for k = i..=j; `None` when there is no range.
fn expand_range(item: &str) -> Result<Option<Vec<String>>, NameError> {
    let Some(dots) = item.find("..") else {
        return Ok(None);
    };
    let (before, after) = (&item[..dots], &item[dots + 2..]);
    // The range's ends are `A<digit>` right before and right after the dots.
    let start = before
        .len()
        .checked_sub(2)
        .filter(|&s| before.is_char_boundary(s));
    let (Some(start), true) = (start, after.len() >= 2 && after.is_char_boundary(2)) else {
        return Err(name_error("a range A<i>..A<j>", item));
    };
    let lo = parse_axis(&before[start..], item)?;
    let hi = parse_axis(&after[..2], item)?;
    if lo > hi {
        return Err(name_error("an increasing range A<i>..A<j>", item));
    }
    Ok(Some(
        (lo..=hi)
            .map(|k| format!("{}A{k}{}", &before[..start], &after[2..]))
            .collect(),
    ))
}
