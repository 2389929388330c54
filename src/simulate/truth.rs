//! The truth file of the virtual robot: what the robot really is (a calibration file, so that
//! any effect of the contract table can be hidden in it, including effects a later
//! calibration leaves out), how the simulated laser tracker measures (noise, where it stands,
//! the frame it reports in) and the random seed. One format for truth and calibration keeps
//! "identify, then compare with the truth" a comparison of two files of the same kind.
//!
//! ```json
//! {
//!   "format": "robopost-truth/1",
//!   "model": { "format": "robopost-calibration/1", "robot": {…}, "payload": {…},
//!              "target_mm": [60, 40, 150],
//!              "frame": { "tracker": { "x": 3200, "y": -900, "z": 150, "a": 150, "b": 0.4, "c": -0.2 } },
//!              "effects": [ … ] },
//!   "tracker": { "sigma_um": 5.0, "sigma_um_per_m": 2.5, "station_mm": [3200, -900, 150] },
//!   "seed": 1
//! }
//! ```
//!
//! `model.frame` says where the tracker reports positions: `"base"` (the robot base frame) or
//! `{"tracker": F}`, F being the pose of the tracker frame in the base frame as a KUKA frame
//! (`p_base = F · p_tracker`) — the same transform `robopost identify --frame tracker` writes.

use std::path::Path;

use nalgebra::Vector3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::calibration::{CalError, Calibration, CalibrationFile, MeasurementFrame};

/// The only truth-file format this build reads and writes.
pub const TRUTH_FORMAT: &str = "robopost-truth/1";

/// A truth file, as on disk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TruthFile {
    /// Always `robopost-truth/1`.
    pub format: String,
    /// The robot as it really is, written as a calibration file (robot, payload, target,
    /// measurement frame, effects).
    pub model: CalibrationFile,
    /// The simulated laser tracker; defaults when absent.
    #[serde(default)]
    pub tracker: TrackerNoise,
    /// Seed of the tracker noise; 0 when absent (the command line may override it).
    #[serde(default)]
    pub seed: u64,
    /// Free text: what this truth is for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<String>,
}

/// The tracker's random error: independent per coordinate, normal with standard deviation
/// `sigma_um + sigma_um_per_m · distance` (distance from the tracker head to the target, m).
/// Defaults 5 µm + 2.5 µm/m: about half of a Leica AT960's MPE of ±(15 µm + 6 µm/m), the
/// typical error (MODEL.md).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrackerNoise {
    #[serde(default = "default_sigma")]
    pub sigma_um: f64,
    #[serde(default = "default_sigma_per_m")]
    pub sigma_um_per_m: f64,
    /// Tracker head in the robot base frame, mm. Absent: the origin of the tracker frame
    /// when there is one, else [`DEFAULT_STATION_MM`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub station_mm: Option<[f64; 3]>,
}

fn default_sigma() -> f64 {
    5.0
}
fn default_sigma_per_m() -> f64 {
    2.5
}

/// Where the tracker stands when nothing says otherwise: 3 m in front of the robot, at the
/// height of the A2 axis, a typical set-up for measuring the whole workspace.
pub const DEFAULT_STATION_MM: [f64; 3] = [3000.0, 0.0, 800.0];

impl Default for TrackerNoise {
    fn default() -> Self {
        TrackerNoise {
            sigma_um: default_sigma(),
            sigma_um_per_m: default_sigma_per_m(),
            station_mm: None,
        }
    }
}

impl TrackerNoise {
    /// No noise at all (for tests that need exact truth).
    #[cfg(any(test, feature = "internals"))]
    pub const NONE: TrackerNoise = TrackerNoise {
        sigma_um: 0.0,
        sigma_um_per_m: 0.0,
        station_mm: None,
    };

    /// Standard deviation per coordinate (mm) at `distance_mm` from the tracker.
    pub fn sigma_mm(&self, distance_mm: f64) -> f64 {
        (self.sigma_um + self.sigma_um_per_m * distance_mm / 1000.0) / 1000.0
    }
}

impl TruthFile {
    /// A truth file around a calibration, with default tracker and seed 0.
    pub fn new(model: CalibrationFile) -> TruthFile {
        TruthFile {
            format: TRUTH_FORMAT.to_string(),
            model,
            tracker: TrackerNoise::default(),
            seed: 0,
            notes: None,
        }
    }

    /// Checks everything (the embedded calibration with keys prefixed `model.`).
    pub fn validate(&self, path: &Path) -> Result<Calibration, CalError> {
        if self.format != TRUTH_FORMAT {
            return Err(CalError::invalid(
                path,
                "format",
                format!("\"{TRUTH_FORMAT}\""),
                format!("\"{}\"", self.format),
            ));
        }
        let t = &self.tracker;
        for (key, v) in [
            ("tracker.sigma_um", t.sigma_um),
            ("tracker.sigma_um_per_m", t.sigma_um_per_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CalError::invalid(
                    path,
                    key,
                    "a non-negative number",
                    v.to_string(),
                ));
            }
        }
        for (c, v) in t.station_mm.iter().flatten().enumerate() {
            if !v.is_finite() {
                return Err(CalError::invalid(
                    path,
                    format!("tracker.station_mm[{c}]"),
                    "a finite number",
                    v.to_string(),
                ));
            }
        }
        Calibration::from_file(self.model.clone(), path).map_err(|e| match e {
            CalError::Invalid {
                path,
                key,
                expected,
                found,
            } => CalError::Invalid {
                path,
                key: format!("model.{key}"),
                expected,
                found,
            },
            CalError::Effect { path, at, source } => CalError::Effect {
                path,
                at: format!("model.{at}"),
                source,
            },
            other => other,
        })
    }

    /// Where the tracker head stands, base frame, mm.
    pub fn station_mm(&self) -> Vector3<f64> {
        match (self.tracker.station_mm, self.model.frame) {
            (Some(s), _) => Vector3::from(s),
            (None, Some(MeasurementFrame::Tracker(f))) => f.position(),
            (None, _) => Vector3::from(DEFAULT_STATION_MM),
        }
    }

    /// Pretty JSON, newline-terminated.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).map_or_else(|_| String::new(), |s| s + "\n")
    }
}

/// Parses truth-file JSON; `path` only names the source in errors (line and column for JSON
/// errors, the key path for bad values).
pub fn parse(text: &str, path: &Path) -> Result<TruthFile, CalError> {
    let file: TruthFile =
        serde_json::from_str(text).map_err(|e| CalError::syntax(path, text, &e))?;
    file.validate(path)?;
    Ok(file)
}

/// Reads and validates a truth file.
#[cfg(any(test, feature = "internals"))]
pub fn load(path: &Path) -> Result<TruthFile, CalError> {
    let text = crate::input::read_to_string(path).map_err(|source| CalError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text, path)
}
