//! How one effect is written in the calibration file: its contract name plus either named
//! scalar parameters or a table. Defined here, beside the registry that reads and writes it,
//! so that `calibration` only arranges records in a file and every effect owns its encoding.

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::table::{Grid, GridError};

/// One effect of a calibration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EffectRecord {
    /// Contract name, e.g. `geometric`, `map:A2`, `crosstalk:A3->A2` (case-insensitive).
    pub name: String,
    /// Named scalar parameters (`geometric`, `compliance`, `tilt`, `drift`); a missing name
    /// is zero.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parameters: Option<BTreeMap<String, f64>>,
    /// A table (`map`, `backlash`, `crosstalk`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<TableRecord>,
}

/// A deviation table in degrees over command angles in degrees (KUKA sign).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TableRecord {
    /// Command angles of the table's own axis, strictly increasing, at least 0.001° apart.
    #[schemars(length(min = 1, max = 100000), inner(range(min = -720, max = 720)))]
    pub grid_deg: Vec<f64>,
    /// Crosstalk only: command angles of the other (influencing) axis, strictly increasing,
    /// at least 0.001° apart.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1, max = 100000), inner(range(min = -720, max = 720)))]
    pub other_grid_deg: Option<Vec<f64>>,
    /// Deviations, degrees (|value| ≤ 1°); for crosstalk row-major,
    /// `values_deg[i·len(other_grid_deg) + j]` at `(grid_deg[i], other_grid_deg[j])`.
    #[schemars(inner(range(min = -1, max = 1)))]
    pub values_deg: Vec<f64>,
}

/// A record that does not describe a valid effect: where, what was expected, what was found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// A value at `key` (a JSON path relative to the record, e.g. `table.grid_deg[3]`) that
    /// is not what the effect needs.
    #[error("{key}: expected {expected}, found {found}")]
    Invalid {
        /// JSON path relative to the record.
        key: String,
        /// What the effect allows there.
        expected: String,
        /// What the record holds there.
        found: String,
    },
    /// The gear play of axis `axis` has width `width_deg` at grid point `index`, outside
    /// `[0, max_deg]`.
    #[error("table.values_deg[{index}]: expected a play width in [0, {max_deg}]° (the output lags the command by half of it), found {width_deg}")]
    PlayWidth {
        /// The axis, 1..=6.
        axis: u8,
        /// The grid point of the play table.
        index: usize,
        /// The width found there, degrees.
        width_deg: f64,
        /// The widest play robopost accepts, degrees.
        max_deg: f64,
    },
}

impl RecordError {
    /// An [`Invalid`](RecordError::Invalid) value.
    pub fn new(
        key: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> Self {
        RecordError::Invalid {
            key: key.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }
}

impl EffectRecord {
    /// The table, or an error naming the missing key. A table effect has no named
    /// parameters: a `parameters` block beside the table would be silently ignored, so it is
    /// an error too.
    pub fn require_table(&self) -> Result<&TableRecord, RecordError> {
        if let Some(p) = &self.parameters {
            let names: Vec<&str> = p.keys().map(String::as_str).collect();
            return Err(RecordError::new(
                "parameters",
                "a table only (no named parameters)",
                format!("parameters {{{}}}", names.join(", ")),
            ));
        }
        self.table
            .as_ref()
            .ok_or_else(|| RecordError::new("table", "a table {grid_deg, values_deg}", "nothing"))
    }

    /// Named parameters checked against `names`: unknown names and non-finite values are
    /// errors, missing names are zero. An effect of named parameters has no table: one beside
    /// them would be silently ignored, so it is an error.
    pub fn named_values(&self, names: &[String]) -> Result<Vec<f64>, RecordError> {
        if self.table.is_some() {
            return Err(RecordError::new(
                "table",
                "named parameters only",
                "a table",
            ));
        }
        let mut values = vec![0.0; names.len()];
        for (key, &value) in self.parameters.iter().flatten() {
            let Some(i) = names.iter().position(|n| n.eq_ignore_ascii_case(key)) else {
                return Err(RecordError::new(
                    format!("parameters.{key}"),
                    format!("one of {}", names.join(", ")),
                    format!("unknown parameter `{key}`"),
                ));
            };
            values[i] = finite(value, &format!("parameters.{key}"))?;
        }
        Ok(values)
    }
}

pub fn finite(value: f64, key: &str) -> Result<f64, RecordError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(RecordError::new(key, "a finite number", value.to_string()))
    }
}

/// Builds a grid from `points`, naming the key of the first bad point.
pub fn grid(points: &[f64], key: &str) -> Result<Grid, RecordError> {
    Grid::new(points.to_vec()).map_err(|e| match e {
        GridError::Empty => RecordError::new(key, "at least one grid point", "an empty list"),
        GridError::NotFinite { index, found } => RecordError::new(
            format!("{key}[{index}]"),
            "a finite number",
            found.to_string(),
        ),
        GridError::NotIncreasing {
            index,
            previous,
            found,
        } => RecordError::new(
            format!("{key}[{index}]"),
            format!("a value greater than {previous} (grid strictly increasing)"),
            found.to_string(),
        ),
        e @ GridError::TooFine { .. } => RecordError::new(key, "a coarser grid", e.to_string()),
    })
}

/// Checks that `values` has `expected` finite entries.
pub fn table_values(values: &[f64], expected: usize, what: &str) -> Result<Vec<f64>, RecordError> {
    if values.len() != expected {
        return Err(RecordError::new(
            "table.values_deg",
            format!("{expected} values ({what})"),
            format!("{} values", values.len()),
        ));
    }
    for (i, &v) in values.iter().enumerate() {
        finite(v, &format!("table.values_deg[{i}]"))?;
    }
    Ok(values.to_vec())
}

/// Scalar parameters as a record map.
pub fn named_map(names: &[String], values: &[f64]) -> BTreeMap<String, f64> {
    names.iter().cloned().zip(values.iter().copied()).collect()
}
