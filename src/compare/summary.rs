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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compare::table;
    use crate::model::AxisState;
    use proptest::prelude::*;

    fn row(test: u8, e: (f64, f64, f64)) -> Row {
        let nominal = Vector3::new(1000.0, 0.0, 1000.0);
        Row {
            test: format!("T{test}"),
            source: "s".into(),
            line: 0,
            state: AxisState::default(),
            measured: nominal + Vector3::new(e.0, e.1, e.2),
            predicted: nominal,
            nominal,
        }
    }

    proptest! {
        /// Every row counts once in its test and once overall; a test's statistics are those
        /// of its rows alone; the table has one line per test and model plus `all`.
        #[test]
        fn per_test_statistics_partition_the_rows(
            rows in prop::collection::vec((0u8..4, (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)), 1..60)
        ) {
            let rows: Vec<Row> = rows.into_iter().map(|(t, e)| row(t, e)).collect();
            let s = Summary::residuals(&rows);
            prop_assert_eq!(s.all.points, rows.len());
            prop_assert_eq!(s.tests.values().map(|t| t.points).sum::<usize>(), rows.len());
            for (name, stats) in &s.tests {
                let own: Vec<Vector3<f64>> =
                    rows.iter().filter(|r| &r.test == name).map(Row::residual).collect();
                prop_assert_eq!(*stats, error_stats(&own));
            }
            let lines = table::lines(&[("a", &s), ("b", &s)]);
            prop_assert_eq!(lines.len(), 2 * (s.order.len() + 1));
            // The same statistics twice: no change from the line above.
            prop_assert!(lines.iter().skip(1).step_by(2).all(|l| l.rms_change.map_or(true, |c| c == 0.0)));
        }
    }
}
