//! The serde types of `cal.json`, exactly as written on disk (see the module documentation
//! for the format). Unknown keys are rejected so that a typo is an error, not a silent zero.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::kinematics::{Payload, RobotDescription};
use crate::model::EffectRecord;

/// The only format version this build reads and writes.
pub const FORMAT: &str = "robopost-calibration/1";

/// A calibration file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// Always `robopost-calibration/1`.
    pub format: String,
    pub robot: RobotRecord,
    /// Payload at the flange during the measurements (compliance effect); none when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<Payload>,
    /// Measurement target (retroreflector) in the KUKA flange frame, mm; origin when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
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

/// A KUKA FRAME: X, Y, Z in mm and A, B, C in degrees, R = Rz(A)·Ry(B)·Rx(C).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct KukaFrame {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub a: f64,
    pub b: f64,
    pub c: f64,
}

impl KukaFrame {
    /// The frame as a rigid transform, R = Rz(A)·Ry(B)·Rx(C) (KUKA's ZYX Euler angles).
    // TODO(integrator): delegate to `kinematics::Pose::to_isometry` once the kinematics
    // branch has landed (same convention).
    pub fn to_isometry(&self) -> nalgebra::Isometry3<f64> {
        let rotation = nalgebra::UnitQuaternion::from_euler_angles(
            self.c.to_radians(),
            self.b.to_radians(),
            self.a.to_radians(),
        );
        nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(self.x, self.y, self.z),
            rotation,
        )
    }

    /// The inverse of [`Self::to_isometry`].
    pub fn from_isometry(iso: &nalgebra::Isometry3<f64>) -> KukaFrame {
        let (c, b, a) = iso.rotation.euler_angles();
        let t = iso.translation.vector;
        KukaFrame {
            x: t.x,
            y: t.y,
            z: t.z,
            a: a.to_degrees(),
            b: b.to_degrees(),
            c: c.to_degrees(),
        }
    }
}

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
}
