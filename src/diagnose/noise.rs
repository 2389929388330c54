//! The noise floor: the RMS 3-D residual a perfect model would still leave, because the laser
//! tracker itself is not exact. Estimated from repeated points when the data has enough of
//! them (the same command angles and rotation directions, measured within a few minutes so
//! that thermal drift does not count as noise), otherwise from the tracker's specification
//! (Leica AT960: MPE ±(15 µm + 6 µm/m) of a measured point, `U_xyz`; the typical 3-D error is
//! about half of it).
//!
//! Exact copies of a row (the same angles and the same measured position to the last digit: a
//! row pasted twice, or a file given twice) are not repeated measurements — a tracker never
//! reads the same point twice to the tenth of a micrometre — and would make the floor zero:
//! [`duplicates`] finds them, and diagnosis leaves them out altogether.
//!
//! Bidirectional points are not used: on indexing data a map and a backlash table fit every
//! forward/backward pair exactly along the motion, so their residuals understate the noise,
//! and without backlash in the model they measure backlash, not noise.

use std::collections::HashMap;

use nalgebra::Vector3;
use serde::Serialize;

use crate::calibration::MeasurementFrame;
use crate::compare::Row;
use crate::measure::tracker::Tracker;

/// Where the tracker is assumed to stand when the data do not say: a typical set-up 3 m in
/// front of the robot at the height of the A2 axis.
pub const ASSUMED_STATION_MM: [f64; 3] = [3000.0, 0.0, 800.0];
/// Repeats further apart than this (s) are not compared: drift would count as noise.
const REPEAT_WINDOW_S: f64 = 600.0;
/// Degrees of freedom of the repeats needed before they are trusted over the specification.
const MIN_REPEAT_DOF: usize = 10;

/// Where the noise floor came from.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum NoiseSource {
    /// The scatter of repeated points (degrees of freedom of the pooled estimate).
    Repeats {
        /// Degrees of freedom of the pooled estimate.
        dof: usize,
    },
    /// The tracker specification at the mean distance of the points from the tracker.
    TrackerSpec {
        /// Mean distance of the points from the tracker, m.
        mean_distance_m: f64,
        /// The tracker's station was not in the data and was assumed.
        station_assumed: bool,
        /// The tracker and its MPE in words ("AT960 MPE ±(15 µm + 6 µm/m)").
        #[serde(skip)]
        mpe: String,
    },
}

impl NoiseSource {
    /// In words, for the verdict.
    pub fn describe(&self) -> String {
        match self {
            NoiseSource::Repeats { dof } => {
                format!("from repeated points, {dof} degrees of freedom")
            }
            NoiseSource::TrackerSpec {
                mean_distance_m,
                station_assumed,
                mpe,
            } => format!(
                "tracker specification, typical half of the {} at {:.1} m{}",
                if mpe.is_empty() {
                    Tracker::default().mpe_words()
                } else {
                    mpe.clone()
                },
                mean_distance_m,
                if *station_assumed {
                    " from a tracker assumed 3 m in front of the robot"
                } else {
                    ""
                }
            ),
        }
    }
}

/// The noise floor as an RMS of the 3-D residual, µm.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NoiseFloor {
    /// The floor, µm RMS 3-D.
    pub rms_um: f64,
    /// Where the figure comes from.
    pub source: NoiseSource,
}

/// Estimates the noise floor of `rows` measured in `frame` with `tracker` (standing where it
/// says, else at the tracker frame's origin, else assumed).
pub fn estimate(rows: &[Row], frame: &MeasurementFrame, tracker: &Tracker) -> NoiseFloor {
    if let Some((rms_um, dof)) = from_repeats(rows) {
        return NoiseFloor {
            rms_um,
            source: NoiseSource::Repeats { dof },
        };
    }
    let (station, station_assumed) = match frame {
        // The tracker frame's origin is the tracker head.
        MeasurementFrame::Tracker(f) => (f.position(), false),
        MeasurementFrame::Base => match tracker.station_mm {
            Some(at) => (at, false),
            None => (Vector3::from(ASSUMED_STATION_MM), true),
        },
    };
    from_spec(rows, &station, station_assumed, tracker)
}

/// Spec noise: the typical 3-D error, half `tracker`'s MPE at each point's distance from the
/// tracker, as an RMS over the points.
pub fn from_spec(
    rows: &[Row],
    station: &Vector3<f64>,
    station_assumed: bool,
    tracker: &Tracker,
) -> NoiseFloor {
    let n = rows.len().max(1) as f64;
    let (mut var, mut dist) = (0.0, 0.0);
    for r in rows {
        let d_m = (r.measured - station).norm() / 1000.0;
        let typical = tracker.typical_um(d_m);
        var += typical * typical;
        dist += d_m;
    }
    NoiseFloor {
        rms_um: (var / n).sqrt(),
        source: NoiseSource::TrackerSpec {
            mean_distance_m: dist / n,
            station_assumed,
            mpe: tracker.mpe_words(),
        },
    }
}

/// For each row, whether it is an exact copy of an earlier one (same command angles and same
/// measured position, bit for bit).
pub fn duplicates(rows: &[Row]) -> Vec<bool> {
    let mut seen: std::collections::HashSet<[u64; 9]> =
        std::collections::HashSet::with_capacity(rows.len());
    rows.iter()
        .map(|r| {
            let mut key = [0u64; 9];
            for (k, a) in r.state.axes_deg.iter().enumerate() {
                key[k] = a.to_bits();
            }
            for c in 0..3 {
                key[6 + c] = r.measured[c].to_bits();
            }
            !seen.insert(key)
        })
        .collect()
}

/// Pooled within-group scatter of repeated points: `√(Σ|r − r̄_g|² / Σ(n_g − 1))` in µm (a 3-D
/// RMS), with its degrees of freedom; `None` when there are too few repeats.
fn from_repeats(rows: &[Row]) -> Option<(f64, usize)> {
    let key = |r: &Row| {
        let angles = r.state.axes_deg.map(|a| (a * 1e6).round() as i64);
        let dirs = r.state.directions().map(|d| d.sign() as i8);
        (angles, dirs)
    };
    let mut groups: HashMap<_, Vec<&Row>> = HashMap::new();
    for r in rows {
        groups.entry(key(r)).or_default().push(r);
    }
    let (mut ss, mut dof) = (0.0, 0usize);
    for group in groups.values() {
        // Split a group where consecutive measurements are far apart in time.
        let mut sorted = group.clone();
        sorted.sort_by(|a, b| a.state.time_s.total_cmp(&b.state.time_s));
        for cluster in sorted.chunk_by(|a, b| b.state.time_s - a.state.time_s <= REPEAT_WINDOW_S) {
            if cluster.len() < 2 {
                continue;
            }
            let mean: Vector3<f64> =
                cluster.iter().map(|r| r.measured).sum::<Vector3<f64>>() / cluster.len() as f64;
            ss += cluster
                .iter()
                .map(|r| (r.measured - mean).norm_squared())
                .sum::<f64>();
            dof += cluster.len() - 1;
        }
    }
    (dof >= MIN_REPEAT_DOF).then(|| ((ss / dof as f64).sqrt() * 1000.0, dof))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::AxisState;

    fn row(axes: [f64; 6], t: f64, measured: Vector3<f64>) -> Row {
        Row {
            test: "t".into(),
            source: "s".into(),
            line: 0,
            state: AxisState {
                time_s: t,
                ..AxisState::new(axes)
            },
            measured,
            predicted: measured,
            nominal: measured,
        }
    }

    #[test]
    fn spec_floor_by_hand() {
        // Points 2 m and 1 m from the tracker: typical errors ½(15 + 12) = 13.5 µm and
        // ½(15 + 6) = 10.5 µm; RMS √((13.5² + 10.5²)/2).
        let station = Vector3::new(3000.0, 0.0, 800.0);
        let rows = [
            row([0.0; 6], 0.0, Vector3::new(1000.0, 0.0, 800.0)),
            row([0.0; 6], 0.0, Vector3::new(3000.0, 0.0, 1800.0)),
        ];
        let f = from_spec(&rows, &station, true, &Tracker::default());
        assert!((f.rms_um - ((13.5f64.powi(2) + 10.5f64.powi(2)) / 2.0).sqrt()).abs() < 1e-9);
        assert_eq!(
            f.source,
            NoiseSource::TrackerSpec {
                mean_distance_m: 1.5,
                station_assumed: true,
                mpe: "AT960 MPE ±(15 µm + 6 µm/m)".into(),
            }
        );
    }

    #[test]
    fn repeats_give_the_pooled_scatter_and_ignore_far_apart_times() {
        // 12 pairs of repeats, each pair differing by (0.02, 0, 0) mm: per pair
        // Σ|r − r̄|² = 2·(0.01)² mm², one degree of freedom → RMS 0.01·√2 mm = 14.142 µm.
        let mut rows = Vec::new();
        for k in 0..12 {
            let axes = [k as f64, 0.0, 0.0, 0.0, 0.0, 0.0];
            rows.push(row(axes, 10.0 * k as f64, Vector3::new(1.0, 2.0, 3.0)));
            rows.push(row(
                axes,
                10.0 * k as f64 + 5.0,
                Vector3::new(1.02, 2.0, 3.0),
            ));
            // A third visit an hour later (drift) is not a repeat of the first two.
            rows.push(row(
                axes,
                3600.0 + 10.0 * k as f64,
                Vector3::new(1.5, 2.0, 3.0),
            ));
        }
        let (rms, dof) = from_repeats(&rows).unwrap();
        assert_eq!(dof, 12);
        assert!((rms - 0.02 / 2f64.sqrt() * 1000.0).abs() < 1e-9, "{rms}");
        // Too few repeats: no estimate.
        assert!(from_repeats(&rows[..9]).is_none());
    }

    #[test]
    fn exact_copies_are_found_and_a_file_given_twice_is_all_copies() {
        let rows: Vec<Row> = (0..5)
            .map(|k| {
                row(
                    [k as f64, 0.0, 0.0, 0.0, 0.0, 0.0],
                    k as f64,
                    Vector3::new(1.0, 2.0, 3.0),
                )
            })
            .collect();
        assert!(duplicates(&rows).iter().all(|d| !d));
        let twice: Vec<Row> = rows.iter().chain(&rows).cloned().collect();
        assert_eq!(
            duplicates(&twice),
            [false, false, false, false, false, true, true, true, true, true]
        );
        // A real repeat differs in the measured position: not a copy.
        let mut repeat = rows[0].clone();
        repeat.measured.x += 1e-4;
        assert!(!duplicates(&[rows[0].clone(), repeat])[1]);
        // Twelve rows each given twice would be 12 zero-scatter repeats: the floor they give is
        // 0 µm, which is why diagnosis drops copies before estimating it.
        let copies: Vec<Row> = (0..12)
            .flat_map(|k| {
                let r = row(
                    [k as f64, 0.0, 0.0, 0.0, 0.0, 0.0],
                    k as f64,
                    Vector3::new(1.0, 2.0, 3.0),
                );
                [r.clone(), r]
            })
            .collect();
        assert_eq!(from_repeats(&copies), Some((0.0, 12)));
        let kept: Vec<Row> = copies
            .iter()
            .zip(duplicates(&copies))
            .filter(|(_, d)| !d)
            .map(|(r, _)| r.clone())
            .collect();
        assert!(from_repeats(&kept).is_none());
    }
}
