//! The calibration file `cal.json`: reading, validating, writing it atomically, and turning
//! it into a [`Model`]. This module owns the file layout; each effect's entry is encoded by
//! the effect itself through the model's registry.
//!
//! # Format (`robopost-calibration/2`)
//!
//! ```json
//! {
//!   "format": "robopost-calibration/2",
//!   "robot": { "name": "KR 30 HA",
//!              "description": { "links": { "l1x": 350, "l1z": 815, "l2": 850, "l3z": 145,
//!                                          "l4x": 820, "l5x": 170 },
//!                               "limits_deg": [[-185, 185], …], "senses": [-1, 1, 1, -1, 1, -1],
//!                               "offsets_deg": [0, 90, -90, 0, 0, 0],
//!                               "gravity": { "link_mass_kg": […], "link_cog_mm": […] } } },
//!   "payload": { "mass_kg": 12.0, "cog_mm": [0, 0, 80] },
//!   "target_mm": [0, 0, 150],
//!   "frame": "base",
//!   "effects": [
//!     { "name": "geometric", "parameters": { "dx21": 0.012, "a21": -0.003, "dth20": 0.01 } },
//!     { "name": "map:A2", "table": { "grid_deg": [-135, -134, …], "values_deg": [0.001, …] } },
//!     { "name": "backlash:A2", "table": { "grid_deg": […], "values_deg": […] } },
//!     { "name": "crosstalk:A3->A2",
//!       "table": { "grid_deg": [-135, -130, …], "other_grid_deg": [58, 105, 153],
//!                  "values_deg": [ /* row-major: one row per grid_deg point */ ] } },
//!     { "name": "compliance:A2", "parameters": { "c": 0.004 } },
//!     { "name": "tilt:A1", "parameters": { "x.cos1": 0.001, "y.sin2": -0.0005 } },
//!     { "name": "drift", "parameters": { "l1z": 0.003 } }
//!   ],
//!   "provenance": { "sources": ["campaign.csv"], "date": "2026-03-01",
//!                   "fit": { "points": 1860, "rms_um": 21.4 }, "notes": "…" }
//! }
//! ```
//!
//! Only `format`, `robot` and `effects` are required. Units: mm, degrees, deg/kNm
//! (compliance), mm/h (drift). `frame` is `"base"` (positions measured in the robot base
//! frame) or `{"tracker": {"x":…, "y":…, "z":…, "a":…, "b":…, "c":…}}`, the tracker → base
//! transform as a KUKA frame. Effect names are those of the contract table,
//! case-insensitive. Scalar effects list `parameters` by name (a missing one is zero):
//! `geometric` has the paper's `dx21 a21 dth20 dz32 a32 g32 dth30 dz43 dy43 g43 dth40 dx54
//! dz54 g54 dth50 dz65 dy65 g65` (mm / deg, paper sign; `dth` = Δθ in the model's sign) and
//! the target correction `p6x p6y p6z` (mm, A6 frame: at HOME x, y, z of the base);
//! `compliance:An` has `c`; `tilt:An` has `<axis>.<cos1|sin1|cos2|sin2>` for its two
//! perpendicular model axes; `drift` has `l1z l1x l2 l3z l4x l5x`. Tables are over KUKA
//! command angles with deviations in KUKA sign (`backlash:An`: the gear play's width, ≥ 0);
//! grids strictly increasing; values held at the edges outside the grid. Files of the earlier
//! format `robopost-calibration/1` are read too (their backlash tables converted, see
//! `model::effects::play`). Unknown keys are errors. The JSON Schema generated from these
//! types ships as `calibrations/calibration.schema.json`.

mod duplicates;
mod error;
mod file;
pub mod ranges;
pub mod robots;

use std::path::Path;

use nalgebra::Vector3;

pub use error::CalError;
pub use file::{
    CalibrationFile, ExcludedPoint, KukaFrame, MeasurementFrame, Provenance, RobotRecord, FORMAT,
    FORMAT_V1,
};

use crate::kinematics::{Payload, RobotDescription};
use crate::model::{EffectName, Model};

/// A validated calibration: the model plus what the file says about it.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// The robot's name as the file gives it (written in compensated programs' headers).
    pub robot_name: String,
    /// The frame the identification's measurements were in (base or a tracker frame).
    pub frame: MeasurementFrame,
    /// How the calibration was made: data, effects, fit, gross errors left out.
    pub provenance: Provenance,
    model: Model,
}

impl Calibration {
    /// A calibration of `model`, named and described.
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn from_model(
        robot_name: &str,
        model: Model,
        frame: MeasurementFrame,
        provenance: Provenance,
    ) -> Self {
        Calibration {
            robot_name: robot_name.to_string(),
            frame,
            provenance,
            model,
        }
    }

    /// The error model (a copy; identification changes its own).
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn model(&self) -> Model {
        self.model.clone()
    }

    /// The error model, borrowed (what compensation evaluates).
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn model_ref(&self) -> &Model {
        &self.model
    }

    /// The error model's parameter names (`effect:parameter`), in the order of
    /// [`Self::parameter_values`] and of an identification's `Fit::parameter_names`.
    pub fn parameter_names(&self) -> Vec<String> {
        self.model.parameter_names()
    }

    /// The error model's parameter values (units as the effects give them), in the order of
    /// [`Self::parameter_names`].
    pub fn parameter_values(&self) -> Vec<f64> {
        self.model.values()
    }

    /// The robot's software limits replaced (by those of the robot's machine data).
    pub fn set_limits(&mut self, limits_deg: [[f64; 2]; 6]) {
        self.model.robot.limits_deg = limits_deg;
    }

    /// The file contents for this calibration.
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn to_file(&self) -> CalibrationFile {
        let m = &self.model;
        CalibrationFile {
            format: FORMAT.to_string(),
            robot: RobotRecord {
                name: self.robot_name.clone(),
                description: m.robot,
            },
            payload: (m.payload != Payload::default()).then_some(m.payload),
            target_mm: Some(m.target_mm.into()),
            frame: Some(self.frame),
            effects: m.effects().iter().map(|e| e.record()).collect(),
            provenance: (self.provenance != Provenance::default()).then(|| self.provenance.clone()),
        }
    }

    /// Validates `file` (read from `path`) and builds its model.
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn from_file(file: CalibrationFile, path: &Path) -> Result<Calibration, CalError> {
        let model = validate(&file, path)?;
        Ok(Calibration {
            robot_name: file.robot.name,
            frame: file.frame.unwrap_or_default(),
            provenance: file.provenance.unwrap_or_default(),
            model,
        })
    }

    /// The file as pretty JSON, after checking that it would load again.
    pub fn to_json(&self, path: &Path) -> Result<String, CalError> {
        let file = self.to_file();
        validate(&file, path)?;
        serde_json::to_string_pretty(&file)
            .map(|s| s + "\n")
            .map_err(|e| CalError::invalid(path, "", "serialisable data", e.to_string()))
    }

    /// Writes the file atomically: a temporary file beside it, renamed over it once whole.
    pub fn save_atomic(&self, path: &Path) -> Result<(), CalError> {
        let json = self.to_json(path)?;
        let io = |source| CalError::Io {
            path: path.to_path_buf(),
            source,
        };
        crate::atomic_file::write(path, json.as_bytes()).map_err(io)
    }
}

/// Reads and validates a calibration file.
pub fn load(path: &Path) -> Result<Calibration, CalError> {
    let text = crate::input::read_to_string(path).map_err(|source| CalError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse(&text, path)
}

/// Parses calibration JSON; `path` only names the source in errors.
pub fn parse(text: &str, path: &Path) -> Result<Calibration, CalError> {
    // A key given twice is refused before the reader keeps one of its values.
    if let Err(e) = duplicates::check(text) {
        if e.is_data() {
            return Err(CalError::syntax(path, text, &e));
        }
    }
    match serde_json::from_str::<CalibrationFile>(text) {
        Ok(file) => Calibration::from_file(file, path),
        Err(e) => {
            // A file of another format version fails on its fields first: say so instead.
            if let Ok(value) = serde_json::from_str::<serde_json::Value>(text) {
                check_format(value.get("format"), path)?;
            }
            Err(CalError::syntax(path, text, &e))
        }
    }
}

/// The JSON Schema of the format, as shipped in `calibrations/calibration.schema.json`.
#[cfg(any(test, feature = "internals"))]
pub fn json_schema() -> String {
    let schema = schemars::schema_for!(CalibrationFile);
    serde_json::to_string_pretty(&schema)
        .map(|s| s + "\n")
        .unwrap_or_default()
}

fn check_format(found: Option<&serde_json::Value>, path: &Path) -> Result<(), CalError> {
    match found {
        Some(serde_json::Value::String(s)) if s == FORMAT || s == FORMAT_V1 => Ok(()),
        Some(v) => Err(CalError::invalid(
            path,
            "format",
            format!("\"{FORMAT}\""),
            v.to_string(),
        )),
        None => Err(CalError::invalid(
            path,
            "format",
            format!("\"{FORMAT}\""),
            "nothing",
        )),
    }
}

fn finite(value: f64, key: impl FnOnce() -> String, path: &Path) -> Result<(), CalError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(CalError::invalid(
            path,
            key(),
            "a finite number",
            value.to_string(),
        ))
    }
}

fn validate_robot(robot: &RobotDescription, path: &Path) -> Result<(), CalError> {
    let key = "robot.description";
    let l = &robot.links;
    for (name, v) in l.named() {
        finite(v, || format!("{key}.links.{name}"), path)?;
    }
    for (n, [lo, hi]) in robot.limits_deg.iter().enumerate() {
        finite(*lo, || format!("{key}.limits_deg[{n}][0]"), path)?;
        finite(*hi, || format!("{key}.limits_deg[{n}][1]"), path)?;
        if lo >= hi {
            let found = format!("[{lo}, {hi}]");
            return Err(CalError::invalid(
                path,
                format!("{key}.limits_deg[{n}]"),
                "[min, max] with min < max",
                found,
            ));
        }
    }
    for (n, s) in robot.senses.iter().enumerate() {
        if s.abs() != 1.0 {
            return Err(CalError::invalid(
                path,
                format!("{key}.senses[{n}]"),
                "1 or -1",
                s.to_string(),
            ));
        }
        finite(
            robot.offsets_deg[n],
            || format!("{key}.offsets_deg[{n}]"),
            path,
        )?;
    }
    if let Some(g) = &robot.gravity {
        for k in 0..6 {
            finite(
                g.link_mass_kg[k],
                || format!("{key}.gravity.link_mass_kg[{k}]"),
                path,
            )?;
            for c in 0..3 {
                finite(
                    g.link_cog_mm[k][c],
                    || format!("{key}.gravity.link_cog_mm[{k}][{c}]"),
                    path,
                )?;
            }
        }
    }
    Ok(())
}

/// Every check after parsing; on success the model the file describes.
fn validate(file: &CalibrationFile, path: &Path) -> Result<Model, CalError> {
    check_format(Some(&serde_json::Value::String(file.format.clone())), path)?;
    let robot = file.robot.description;
    validate_robot(&robot, path)?;
    let payload = file.payload.unwrap_or_default();
    finite(payload.mass_kg, || "payload.mass_kg".into(), path)?;
    for (c, v) in payload.cog_mm.iter().enumerate() {
        finite(*v, || format!("payload.cog_mm[{c}]"), path)?;
    }
    let target = file.target_mm.unwrap_or([0.0; 3]);
    for (c, v) in target.iter().enumerate() {
        finite(*v, || format!("target_mm[{c}]"), path)?;
    }
    ranges::check(file, path)?;
    if let Some(MeasurementFrame::Tracker(f)) = &file.frame {
        for (name, v) in [
            ("x", f.x),
            ("y", f.y),
            ("z", f.z),
            ("a", f.a),
            ("b", f.b),
            ("c", f.c),
        ] {
            finite(v, || format!("frame.tracker.{name}"), path)?;
        }
    }
    let mut model = Model::new(robot, payload, Vector3::from(target));
    let mut seen: Vec<(String, usize)> = Vec::new();
    for (i, record) in file.effects.iter().enumerate() {
        let at = |key: &str| format!("effects[{i}].{key}");
        let name = EffectName::parse(&record.name).map_err(|e| {
            CalError::invalid(path, at("name"), e.expected, format!("\"{}\"", e.found))
        })?;
        let canonical = name.to_string();
        if let Some((_, first)) = seen.iter().find(|(n, _)| *n == canonical) {
            let found = format!("\"{}\" again (first at effects[{first}])", record.name);
            return Err(CalError::invalid(
                path,
                at("name"),
                "each effect at most once",
                found,
            ));
        }
        seen.push((canonical, i));
        let invalid = |source| CalError::Effect {
            path: path.to_path_buf(),
            at: format!("effects[{i}]"),
            source,
        };
        let effect = match (file.format == FORMAT_V1, name.kind.upgrade_v1) {
            (true, Some(upgrade)) => {
                let mut upgraded = record.clone();
                upgrade(&mut upgraded).map_err(invalid)?;
                name.decode(&upgraded, &robot)
            }
            _ => name.decode(record, &robot),
        }
        .map_err(invalid)?;
        ranges::effect(record, effect.as_effect(), &format!("effects[{i}]"), path)?;
        model.push(effect);
    }
    Ok(model)
}
