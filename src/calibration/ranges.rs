//! The physical range of every quantity of a calibration file. A value outside its range is
//! not a robot's error but a typing slip, a unit mix-up or a broken fit, and compensating
//! with it would move targets by metres: the file is refused, naming the key, the range and
//! the value. The same numbers are written into the JSON Schema (`minimum`/`maximum` on the
//! types; a test keeps the two in step) and into `docs/calibration.md`.
//!
//! Ranges are generous bounds of what is physical for an industrial arm, not tolerances. An
//! effect's own numbers are bounded by the effect ([`Effect::record_range`]), in its file.

use std::path::Path;

use super::{CalError, CalibrationFile, MeasurementFrame};
use crate::model::{Effect, EffectRecord, RecordRange, RecordValue};

/// Link lengths, mm: none longer than any arm built, none negative …
pub const LINK_MM: (f64, f64) = (0.0, 5000.0);
/// … but the two offsets, which point either way on real arms (the KR 16's A3 sits 35 mm
/// below its forearm: `l3z` = −35).
pub const OFFSET_LINK_MM: (f64, f64) = (-5000.0, 5000.0);
/// The upper arm (`l2`) and the forearm (`l4x`) exist: at least 1 mm.
pub const ARM_LINK_MIN_MM: f64 = 1.0;
/// Joint limits, degrees (an axis turning two full turns either way at most).
pub const LIMIT_DEG: f64 = 720.0;
/// Offsets between KUKA and model angles, degrees.
pub const OFFSET_DEG: f64 = 360.0;
/// Link and payload masses, kg.
pub const MASS_KG: (f64, f64) = (0.0, 10_000.0);
/// Centres of gravity, mm from their frame's origin.
pub const COG_MM: f64 = 5000.0;
/// The measurement target in the flange frame, mm.
pub const TARGET_MM: f64 = 2000.0;
/// The tracker's position in the base frame, mm (100 m), and its angles, degrees.
pub const TRACKER_MM: f64 = 100_000.0;
pub const TRACKER_DEG: f64 = 360.0;
/// Grid points: within the joint-limit range, at least this far apart (degrees), at most
/// this many per grid.
pub const GRID_MIN_SPACING_DEG: f64 = 1e-3;
pub const GRID_MAX_POINTS: usize = 100_000;

fn within(
    value: f64,
    (lo, hi): (f64, f64),
    unit: &str,
    key: impl FnOnce() -> String,
    path: &Path,
) -> Result<(), CalError> {
    if (lo..=hi).contains(&value) {
        Ok(())
    } else if !value.is_finite() {
        Err(CalError::invalid(
            path,
            key(),
            "a finite number",
            value.to_string(),
        ))
    } else {
        Err(CalError::invalid(
            path,
            key(),
            format!("a value from {lo} to {hi} {unit}"),
            value.to_string(),
        ))
    }
}

fn symmetric(bound: f64) -> (f64, f64) {
    (-bound, bound)
}

/// Checks every number of `file` against its physical range.
pub fn check(file: &CalibrationFile, path: &Path) -> Result<(), CalError> {
    let d = &file.robot.description;
    let key = "robot.description";
    let l = &d.links;
    for (name, v) in l.named() {
        let range = match name {
            "l2" | "l4x" => (ARM_LINK_MIN_MM, LINK_MM.1),
            "l1x" | "l3z" => OFFSET_LINK_MM,
            _ => LINK_MM,
        };
        within(v, range, "mm", || format!("{key}.links.{name}"), path)?;
    }
    for (n, pair) in d.limits_deg.iter().enumerate() {
        for (k, v) in pair.iter().enumerate() {
            let at = || format!("{key}.limits_deg[{n}][{k}]");
            within(*v, symmetric(LIMIT_DEG), "degrees", at, path)?;
        }
    }
    for (n, v) in d.offsets_deg.iter().enumerate() {
        let at = || format!("{key}.offsets_deg[{n}]");
        within(*v, symmetric(OFFSET_DEG), "degrees", at, path)?;
    }
    if let Some(g) = &d.gravity {
        for n in 0..6 {
            let at = || format!("{key}.gravity.link_mass_kg[{n}]");
            within(g.link_mass_kg[n], MASS_KG, "kg", at, path)?;
            for c in 0..3 {
                let at = || format!("{key}.gravity.link_cog_mm[{n}][{c}]");
                within(g.link_cog_mm[n][c], symmetric(COG_MM), "mm", at, path)?;
            }
        }
    }
    if let Some(p) = &file.payload {
        within(p.mass_kg, MASS_KG, "kg", || "payload.mass_kg".into(), path)?;
        for (c, v) in p.cog_mm.iter().enumerate() {
            let at = || format!("payload.cog_mm[{c}]");
            within(*v, symmetric(COG_MM), "mm", at, path)?;
        }
    }
    for (c, v) in file.target_mm.iter().flatten().enumerate() {
        within(
            *v,
            symmetric(TARGET_MM),
            "mm",
            || format!("target_mm[{c}]"),
            path,
        )?;
    }
    if let Some(MeasurementFrame::Tracker(f)) = &file.frame {
        for (name, v, bound, unit) in [
            ("x", f.x, TRACKER_MM, "mm"),
            ("y", f.y, TRACKER_MM, "mm"),
            ("z", f.z, TRACKER_MM, "mm"),
            ("a", f.a, TRACKER_DEG, "degrees"),
            ("b", f.b, TRACKER_DEG, "degrees"),
            ("c", f.c, TRACKER_DEG, "degrees"),
        ] {
            let at = || format!("frame.tracker.{name}");
            within(v, symmetric(bound), unit, at, path)?;
        }
    }
    for (i, record) in file.effects.iter().enumerate() {
        let at = format!("effects[{i}]");
        if let Some(t) = &record.table {
            grid(&t.grid_deg, &format!("{at}.table.grid_deg"), path)?;
            if let Some(other) = &t.other_grid_deg {
                grid(other, &format!("{at}.table.other_grid_deg"), path)?;
            }
            for (k, v) in t.values_deg.iter().enumerate() {
                let key = || format!("{at}.table.values_deg[{k}]");
                within(*v, (f64::MIN, f64::MAX), "", key, path)?;
            }
        }
        // Every number finite before the effect reads it (its range is checked after, by
        // the effect: see [`effect`]).
        for (param, &v) in record.parameters.iter().flatten() {
            let key = || format!("{at}.parameters.{param}");
            within(v, (f64::MIN, f64::MAX), "", key, path)?;
        }
    }
    Ok(())
}

/// The ranges of one effect's numbers, as the effect states them
/// ([`Effect::record_range`]); `effect` is what `record` decodes to.
pub fn effect(
    record: &EffectRecord,
    effect: &dyn Effect,
    at: &str,
    path: &Path,
) -> Result<(), CalError> {
    let check = |v: f64, range: RecordRange, key: &dyn Fn() -> String| match range {
        RecordRange::Within { bound, unit } => within(v, symmetric(bound), unit, key, path),
        RecordRange::Finite => Ok(()),
    };
    if let Some(t) = &record.table {
        let range = effect.record_range(RecordValue::Table);
        for (k, v) in t.values_deg.iter().enumerate() {
            check(*v, range, &|| format!("{at}.table.values_deg[{k}]"))?;
        }
    }
    for (param, &v) in record.parameters.iter().flatten() {
        let range = effect.record_range(RecordValue::Parameter(param));
        check(v, range, &|| format!("{at}.parameters.{param}"))?;
    }
    Ok(())
}

/// A grid's points within the joint-limit range, spaced at least
/// [`GRID_MIN_SPACING_DEG`] (an increasing grid is the decoder's check), and not too many.
fn grid(points: &[f64], key: &str, path: &Path) -> Result<(), CalError> {
    if points.len() > GRID_MAX_POINTS {
        return Err(CalError::invalid(
            path,
            key,
            format!("at most {GRID_MAX_POINTS} grid points"),
            format!("{} points", points.len()),
        ));
    }
    for (k, v) in points.iter().enumerate() {
        let at = || format!("{key}[{k}]");
        within(*v, symmetric(LIMIT_DEG), "degrees", at, path)?;
    }
    for (k, w) in points.windows(2).enumerate() {
        let step = w[1] - w[0];
        if step > 0.0 && step < GRID_MIN_SPACING_DEG {
            return Err(CalError::invalid(
                path,
                format!("{key}[{}]", k + 1),
                format!(
                    "a grid point at least {GRID_MIN_SPACING_DEG}° after the previous one ({})",
                    w[0]
                ),
                w[1].to_string(),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    /// The schema shipped with the crate carries the ranges checked here.
    #[test]
    fn the_json_schema_states_the_same_ranges() {
        let schema: Value = serde_json::from_str(&super::super::json_schema()).unwrap();
        let defs = &schema["definitions"];
        let num = |v: &Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
        let links = &defs["Links"]["properties"];
        assert_eq!(num(&links["l1z"], "minimum"), LINK_MM.0);
        assert_eq!(num(&links["l1z"], "maximum"), LINK_MM.1);
        assert_eq!(num(&links["l1x"], "minimum"), OFFSET_LINK_MM.0);
        assert_eq!(num(&links["l3z"], "minimum"), OFFSET_LINK_MM.0);
        assert_eq!(num(&links["l2"], "minimum"), ARM_LINK_MIN_MM);
        assert_eq!(num(&links["l4x"], "minimum"), ARM_LINK_MIN_MM);
        let robot = &defs["RobotDescription"]["properties"];
        let limit = &robot["limits_deg"]["items"]["items"];
        assert_eq!(num(limit, "minimum"), -LIMIT_DEG);
        assert_eq!(num(limit, "maximum"), LIMIT_DEG);
        assert_eq!(num(&robot["offsets_deg"]["items"], "maximum"), OFFSET_DEG);
        let target = &schema["properties"]["target_mm"]["items"];
        assert_eq!(num(target, "maximum"), TARGET_MM);
        let table = &defs["TableRecord"]["properties"];
        assert_eq!(num(&table["grid_deg"]["items"], "maximum"), LIMIT_DEG);
        assert_eq!(
            table["grid_deg"]["maxItems"].as_u64(),
            Some(GRID_MAX_POINTS as u64)
        );
        let crate::model::RecordRange::Within { bound, .. } =
            crate::model::effects::DEVIATION_RANGE
        else {
            panic!("a deviation table is bounded")
        };
        assert_eq!(num(&table["values_deg"]["items"], "maximum"), bound);
        let payload = &defs["Payload"]["properties"];
        assert_eq!(num(&payload["mass_kg"], "maximum"), MASS_KG.1);
        assert_eq!(num(&payload["cog_mm"]["items"], "maximum"), COG_MM);
    }
}
