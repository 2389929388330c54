//! Measurements built in memory, column by column (a binding's arrays, a data frame), with the
//! checks and the history inference of the CSV reader: every command angle finite and within
//! its physical range, `x, y, z` all given or all missing (NaN), the clock never running
//! backwards. A rejected row is located as `source:ROW:COLUMN`, where ROW counts the rows from
//! 1 and COLUMN counts `test, a1..a6, x, y, z, t` from 1.

use nalgebra::Vector3;

use super::{
    infer_histories, MeasureError, Measurements, Stop, ANGLE_RANGE_DEG, POSITION_RANGE_MM,
    TIME_RANGE_S,
};
use crate::model::AxisState;

/// The columns of a measurement table, one entry per stop in the order the robot visited
/// them (as the rows of the measurement CSV, docs/measurements.md).
#[derive(Clone, Copy, Debug)]
pub struct Columns<'a> {
    /// The label of the test or path of each stop.
    pub test: &'a [String],
    /// The command angles A1..A6 of each stop, degrees.
    pub axes_deg: &'a [[f64; 6]],
    /// The measured target position of each stop, mm; all three NaN on a stop that was
    /// visited but not measured (an approach row).
    pub position_mm: &'a [[f64; 3]],
    /// Seconds since the start of the campaign of each stop (`t`); `None`: no clock.
    pub time_s: Option<&'a [f64]>,
}

/// The column numbers of errors: `test, a1..a6, x, y, z, t`.
const X_COLUMN: usize = 8;
const T_COLUMN: usize = 11;

impl Measurements {
    /// The measurements of `columns`; `source` names them in errors and reports (as a file
    /// name would). Each axis's history is inferred from the visiting order, as for a file.
    pub fn from_columns(source: &str, columns: &Columns) -> Result<Measurements, MeasureError> {
        let rows = columns.test.len();
        let error = |row: usize, col: usize, message: String| MeasureError {
            file: source.to_string(),
            line: row,
            col,
            source_line: String::new(),
            message,
            help: None,
        };
        let lengths = [
            ("axes", columns.axes_deg.len()),
            ("positions", columns.position_mm.len()),
            ("times", columns.time_s.map_or(rows, <[f64]>::len)),
        ];
        if let Some((name, n)) = lengths.iter().find(|(_, n)| *n != rows) {
            return Err(error(
                0,
                0,
                format!("{rows} test labels but {n} rows of {name}: every column needs one entry per stop"),
            ));
        }
        let mut stops = Vec::with_capacity(rows);
        let mut last_time: Option<(f64, usize)> = None;
        for i in 0..rows {
            let row = i + 1;
            let axes = columns.axes_deg[i];
            for (k, a) in axes.iter().enumerate() {
                if !(a.abs() <= ANGLE_RANGE_DEG) {
                    return Err(error(
                        row,
                        2 + k,
                        format!(
                            "command angle A{} = {a} is not a finite angle within ±{ANGLE_RANGE_DEG}°",
                            k + 1
                        ),
                    ));
                }
            }
            let p = columns.position_mm[i];
            let measured_mm = if p.iter().all(|v| v.is_nan()) {
                None
            } else if let Some(k) = p.iter().position(|v| v.is_nan()) {
                return Err(error(
                    row,
                    X_COLUMN + k,
                    "x, y and z must all be given or all be missing (NaN)".into(),
                ));
            } else if let Some(k) = p.iter().position(|v| !(v.abs() <= POSITION_RANGE_MM)) {
                return Err(error(
                    row,
                    X_COLUMN + k,
                    format!(
                        "{} = {} is beyond any physical range (at most ±{POSITION_RANGE_MM} mm)",
                        ["x", "y", "z"][k],
                        p[k]
                    ),
                ));
            } else {
                Some(Vector3::from(p))
            };
            let time_s = match columns.time_s {
                None => 0.0,
                Some(times) => {
                    let t = times[i];
                    if !(t.abs() <= TIME_RANGE_S) {
                        return Err(error(
                            row,
                            T_COLUMN,
                            format!("t = {t} is not a time within ±{TIME_RANGE_S} s"),
                        ));
                    }
                    if let Some((before, at)) = last_time.filter(|(before, _)| t < *before) {
                        return Err(error(
                            row,
                            T_COLUMN,
                            format!("time runs backwards: t = {t} s, after {before} s on row {at}"),
                        ));
                    }
                    last_time = Some((t, row));
                    t
                }
            };
            stops.push(Stop {
                test: columns.test[i].clone(),
                state: AxisState {
                    time_s,
                    ..AxisState::new(axes)
                },
                measured_mm,
                line: row,
            });
        }
        let mut states: Vec<AxisState> = stops.iter().map(|s| s.state).collect();
        infer_histories(&mut states, &[]);
        for (stop, state) in stops.iter_mut().zip(states) {
            stop.state = state;
        }
        Ok(Measurements {
            source: source.to_string(),
            stops,
            ignored_columns: Vec::new(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// The shipped campaign read from its file and built from its columns are the same
    /// stops: the same angles, positions, times and inferred histories.
    #[test]
    fn columns_give_the_stops_of_the_csv() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/measurements/campaign.csv");
        let file = super::super::read_csv(&path).unwrap();
        let test: Vec<String> = file.stops.iter().map(|s| s.test.clone()).collect();
        let axes: Vec<[f64; 6]> = file.stops.iter().map(|s| s.state.axes_deg).collect();
        let position: Vec<[f64; 3]> = file
            .stops
            .iter()
            .map(|s| s.measured_mm.map_or([f64::NAN; 3], Into::into))
            .collect();
        let time: Vec<f64> = file.stops.iter().map(|s| s.state.time_s).collect();
        let built = Measurements::from_columns(
            "campaign",
            &Columns {
                test: &test,
                axes_deg: &axes,
                position_mm: &position,
                time_s: Some(&time),
            },
        )
        .unwrap();
        assert_eq!(built.stops.len(), file.stops.len());
        assert!(built.stops.iter().any(|s| s.measured_mm.is_none()));
        for (b, f) in built.stops.iter().zip(&file.stops) {
            assert_eq!(
                (&b.test, &b.state, b.measured_mm),
                (&f.test, &f.state, f.measured_mm)
            );
        }
    }

    fn one(axes: [f64; 6], p: [f64; 3], t: [f64; 2]) -> Result<Measurements, MeasureError> {
        let test = vec!["A1".to_string(); 2];
        Measurements::from_columns(
            "mem",
            &Columns {
                test: &test,
                axes_deg: &[[0.0; 6], axes],
                position_mm: &[[1.0, 2.0, 3.0], p],
                time_s: Some(&t),
            },
        )
    }

    /// A bad value is refused at its row and column.
    #[test]
    fn bad_values_are_located() {
        let ok = one([0.0; 6], [f64::NAN; 3], [0.0, 1.0]).unwrap();
        assert_eq!(ok.stops[1].measured_mm, None);
        let e = one([0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0], [1.0; 3], [0.0, 1.0]).unwrap_err();
        assert_eq!((e.line, e.col), (2, 3), "{e}");
        let e = one([0.0; 6], [1.0, f64::NAN, 1.0], [0.0, 1.0]).unwrap_err();
        assert_eq!((e.line, e.col), (2, 9), "{e}");
        let e = one([0.0; 6], [1.0; 3], [1.0, 0.5]).unwrap_err();
        assert_eq!((e.line, e.col), (2, 11), "{e}");
        assert!(
            e.to_string().starts_with("mem:2:11: time runs backwards"),
            "{e}"
        );
        let test = vec!["A1".to_string()];
        let e = Measurements::from_columns(
            "mem",
            &Columns {
                test: &test,
                axes_deg: &[],
                position_mm: &[[0.0; 3]],
                time_s: None,
            },
        )
        .unwrap_err();
        assert!(e.message.contains("0 rows of axes"), "{e}");
    }
}
