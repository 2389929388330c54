//! Whether the data tell time from pose. A residual that changes through a campaign can be
//! the clock (the robot warming, the tracker's station settling) or the poses visited at that
//! time; only a pose measured again, hours apart, separates the two. An effect of the clock
//! (`drift`, a learned function of the time) is advised only where the data hold such a pose
//! (the reference pose every test of `robopost campaign` starts from), and otherwise the
//! diagnosis says what to measure.

use std::collections::HashMap;

use crate::compare::Row;

/// Axis angles this close (degrees) are the same pose.
const SAME_POSE_DEG: f64 = 0.01;
/// A pose tells time from pose when it is measured at least this many times …
const MIN_VISITS: usize = 3;
/// … spread over at least this share of the data's time span.
const MIN_SPREAD: f64 = 0.5;

/// The most-repeated pose's visits spread over the data's time span (0..1), and its visits.
pub fn repeated_pose_spread(rows: &[Row]) -> (f64, usize) {
    let (lo, hi) = rows
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r.state.time_s), hi.max(r.state.time_s))
        });
    if !(hi > lo) {
        return (0.0, 0);
    }
    let mut poses: HashMap<[i64; 6], (f64, f64, usize)> = HashMap::new();
    for r in rows {
        let key = r.state.axes_deg.map(|a| (a / SAME_POSE_DEG).round() as i64);
        let t = r.state.time_s;
        let e = poses.entry(key).or_insert((t, t, 0));
        e.0 = e.0.min(t);
        e.1 = e.1.max(t);
        e.2 += 1;
    }
    poses
        .values()
        .filter(|(_, _, n)| *n >= MIN_VISITS)
        .map(|(a, b, n)| ((b - a) / (hi - lo), *n))
        .max_by(|x, y| x.0.total_cmp(&y.0))
        .unwrap_or((0.0, 0))
}

/// Whether some pose is measured again across the data's time span.
pub fn tells_time_from_pose(rows: &[Row]) -> bool {
    repeated_pose_spread(rows).0 >= MIN_SPREAD
}

/// Why an effect of the clock is not advised on data that do not tell time from pose.
pub fn cannot_tell() -> String {
    "the data do not tell time from pose (no pose is measured again across their time span): \
     measure a reference pose every 10 to 15 minutes through the campaign (every test of \
     `robopost campaign` starts at its reference pose) and diagnose again"
        .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::AxisState;
    use nalgebra::Vector3;

    fn row(axes: [f64; 6], t: f64) -> Row {
        let mut state = AxisState::new(axes);
        state.time_s = t;
        Row {
            test: "T".into(),
            source: "m.csv".into(),
            line: 2,
            state,
            measured: Vector3::zeros(),
            predicted: Vector3::zeros(),
            nominal: Vector3::zeros(),
        }
    }

    #[test]
    fn a_pose_visited_through_the_campaign_tells_time_from_pose() {
        let home = [0.0, -60.0, 100.0, 0.0, 45.0, 0.0];
        // A1 swept 1..100° (never the home pose's 0°), one pose every 10 s.
        let mut rows: Vec<Row> = (0..100)
            .map(|k| {
                row(
                    [k as f64 + 1.0, -60.0, 100.0, 0.0, 45.0, 0.0],
                    10.0 * k as f64,
                )
            })
            .collect();
        // Every pose once: the clock and the A1 angle are the same driver.
        assert!(!tells_time_from_pose(&rows));
        // The home pose at 0, 300 and 600 s of 990: spread 0.61.
        for t in [0.0, 300.0, 600.0] {
            rows.push(row(home, t));
        }
        let (spread, visits) = repeated_pose_spread(&rows);
        assert!((spread - 600.0 / 990.0).abs() < 1e-12, "{spread}");
        assert_eq!(visits, 3);
        assert!(tells_time_from_pose(&rows));
        // Twice only, or a few seconds apart: not enough.
        let mut twice = rows[..100].to_vec();
        twice.push(row(home, 0.0));
        twice.push(row(home, 900.0));
        assert!(!tells_time_from_pose(&twice));
    }
}
