//! The serde types of `cal.json`, exactly as written on disk (see the module documentation
//! for the format). Unknown keys are rejected so that a typo is an error, not a silent zero.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::kinematics::{Payload, Pose, RobotDescription};
use crate::model::EffectRecord;

/// The format version this build writes.
pub const FORMAT: &str = "robopost-calibration/2";
/// The earlier version, still read: its `backlash:An` tables held the signed half difference
/// of an instant switch, read now as gear-play widths (see `model::effects::play`).
pub const FORMAT_V1: &str = "robopost-calibration/1";

/// A calibration file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// `robopost-calibration/2` (`/1` is still read).
    pub format: String,
    pub robot: RobotRecord,
    /// Payload at the flange during the measurements (compliance effect); none when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<Payload>,
    /// Measurement target (retroreflector) in the KUKA flange frame, mm; origin when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(inner(range(min = -2000, max = 2000)))]
    pub target_mm: Option<[f64; 3]>,
    /// Frame of the measured positions; `base` when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<MeasurementFrame>,
    /// The error effects, each at most once.
    pub effects: Vec<EffectRecord>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<Provenance>,
}

/// The robot the calibration belongs to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RobotRecord {
    /// e.g. `KR 30 HA`, with a serial number if you like.
    pub name: String,
    pub description: RobotDescription,
}

/// Where the laser tracker's positions are given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum MeasurementFrame {
    /// The robot base frame ($ROBROOT).
    #[default]
    Base,
    /// The tracker's own frame, with the identified tracker → base transform.
    Tracker(KukaFrame),
}

/// A KUKA FRAME as written in the file: the kinematics' [`Pose`].
pub type KukaFrame = Pose;

/// Where a calibration came from. Every field is optional.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    /// Measurement files the calibration was identified from.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sources: Vec<String>,
    /// Date of identification, ISO 8601.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub date: Option<String>,
    /// Fit statistics by name, e.g. `points`, `rms_um`, `max_um`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub fit: BTreeMap<String, f64>,
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
    /// Measured points left out of the fit as gross errors (`compare` marks them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub excluded: Vec<ExcludedPoint>,
    /// With data from several tracker set-ups: the tracker → base frame of each measurement
    /// file (as `frame`), by the file's name as given to `identify`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub frames: BTreeMap<String, KukaFrame>,
    /// Why the fit failed its check against the noise floor, when the file was written
    /// anyway (`identify --accept-poor-fit`); absent for a fit that passed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failed: Option<String>,
}

/// A measured point `identify` left out as a gross error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExcludedPoint {
    /// The measurement file, as given to `identify`.
    pub source: String,
    /// 1-based line of the row in that file.
    pub line: usize,
    /// The point's test (the CSV's `test` column).
    pub test: String,
    /// The point's residual against the model fitted without it, µm.
    pub size_um: f64,
    /// Why it was left out.
    pub why: String,
}
