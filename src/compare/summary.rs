//! The paper's Table 1 statistics of a set of rows, overall and per test, in the JSON shape of
//! CONTRACTS.md (`compare --json`): the overall keys at the top level and the same keys per
//! test under `tests`. Which error is summarised (residual, or the robot's error from the
//! command) is the caller's choice.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::Serialize;

use super::{test_order, Row};
use crate::stats::{error_stats, ErrorStats};

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    #[serde(flatten)]
    pub all: ErrorStats,
    pub tests: BTreeMap<String, ErrorStats>,
    /// Test labels in the order they first appear in the files (the JSON map is sorted).
    #[serde(skip)]
    pub order: Vec<String>,
}

impl Summary {
    /// Statistics of `error(row)` over `rows`.
    pub fn of(rows: &[Row], error: impl Fn(&Row) -> Vector3<f64>) -> Summary {
        let all: Vec<Vector3<f64>> = rows.iter().map(&error).collect();
        let order = test_order(rows);
        let tests = order
            .iter()
            .map(|t| {
                let errors: Vec<_> = rows.iter().filter(|r| &r.test == t).map(&error).collect();
                (t.clone(), error_stats(&errors))
            })
            .collect();
        Summary {
            all: error_stats(&all),
            tests,
            order,
        }
    }

    /// Statistics of what the model leaves unexplained (measured − predicted).
    pub fn residuals(rows: &[Row]) -> Summary {
        Summary::of(rows, Row::residual)
    }

    /// Statistics of the robot's error from the command (measured − nominal): the paper's
    /// "uncompensated" row.
    pub fn uncompensated(rows: &[Row]) -> Summary {
        Summary::of(rows, Row::measured_error)
    }
}
