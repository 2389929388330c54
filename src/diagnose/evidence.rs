//! The evidence for a candidate in plain words, read off the residuals of the current model:
//! for an angular effect of axis n the residual along the target's motion about n (µm) —
//! against n's own angle (map), between the rotation directions or, where the data hold short
//! reversals, against the travel since the last reversal (backlash, [`super::play`]), against another
//! axis's angle over the tests that sweep n (crosstalk), against n's gravity torque
//! (compliance); the residual across that motion against n's angle (tilt); each residual
//! component against time (drift).

use std::collections::HashMap;

use nalgebra::Vector3;

use crate::compare::axis_residual::indexed_axis;
use crate::compare::{Driver, Row};
use crate::model::registry::{Axes, Evidence};
use crate::model::{Direction, EffectName, Model, Slot};

/// The unit vector of the target's motion when axis n turns, or `None` when the turn barely
/// moves it (under 1 mm per radian).
fn motion(model: &Model, row: &Row, axis: u8) -> Option<Vector3<f64>> {
    let (frames, _) = model.frames(&row.state);
    let j = frames.point_partial(Slot::Angle { axis }, &row.predicted);
    (j.norm() > 1.0).then(|| j.normalize())
}

/// The residual along axis n's motion, µm.
fn along(model: &Model, row: &Row, axis: u8) -> Option<f64> {
    motion(model, row, axis).map(|u| row.residual().dot(&u) * 1000.0)
}

/// Least-squares line `y = a + b·x`: (slope b, correlation r); `None` without spread in x.
pub fn line(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = points.len() as f64;
    if points.len() < 3 {
        return None;
    }
    let (mx, my) = (
        points.iter().map(|p| p.0).sum::<f64>() / n,
        points.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let syy: f64 = points.iter().map(|p| (p.1 - my).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 1e-12).then(|| {
        (
            sxy / sxx,
            if syy > 0.0 {
                sxy / (sxx * syy).sqrt()
            } else {
                0.0
            },
        )
    })
}

/// Means of `y` per whole degree of `x`.
fn binned(points: impl Iterator<Item = (f64, f64)>) -> HashMap<i64, f64> {
    let mut sums: HashMap<i64, (f64, usize)> = HashMap::new();
    for (x, y) in points {
        let e = sums.entry(x.round() as i64).or_default();
        e.0 += y;
        e.1 += 1;
    }
    sums.into_iter()
        .map(|(k, (s, n))| (k, s / n as f64))
        .collect()
}

fn peak_to_peak(values: impl Iterator<Item = f64>) -> f64 {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if hi >= lo {
        hi - lo
    } else {
        0.0
    }
}

/// The 1-2-5 step nearest (in ratio) to half a range, for "X µm per 50°".
fn step(range: f64) -> f64 {
    let raw = (range / 2.0).max(1e-9);
    let decade = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .min_by(|a, b| (a / raw).ln().abs().total_cmp(&(b / raw).ln().abs()))
        .unwrap_or(decade)
}

/// Rows of the tests that sweep axis n alone (indexing tests of n), or every row when the
/// data have none.
fn sweeping(rows: &[Row], axis: u8) -> Vec<&Row> {
    let mut by_test: HashMap<&str, Vec<&Row>> = HashMap::new();
    for r in rows {
        by_test.entry(r.test.as_str()).or_default().push(r);
    }
    let chosen: Vec<&Row> = by_test
        .into_values()
        .filter(|t| indexed_axis(t.iter().copied()) == Some(axis))
        .flatten()
        .collect();
    if chosen.is_empty() {
        rows.iter().collect()
    } else {
        chosen
    }
}

/// One sentence of evidence for `name`, from the current model's residuals: the reader its
/// kind names ([`Evidence`]).
pub fn describe(name: &EffectName, model: &Model, rows: &[Row]) -> String {
    match (name.kind.evidence, name.axes) {
        (Evidence::OwnAngle, Axes::One(n)) => map(model, rows, n),
        (Evidence::DirectionDifference, Axes::One(n)) => backlash(model, rows, n),
        (Evidence::CrossAngle, Axes::Pair { from, to }) => crosstalk(model, rows, from, to),
        (Evidence::GravityTorque, Axes::One(n)) => compliance(model, rows, n),
        (Evidence::TiltMotion, Axes::One(n)) => tilt(model, rows, n),
        (Evidence::Time, _) => drift(rows),
        (Evidence::AxisLines, _) => "the residual is consistent with errors of the axis \
                                     average lines or the target vector, constant over the \
                                     campaign"
            .into(),
        _ => format!("the residual is consistent with {}", name.kind.meaning),
    }
}

fn by_direction(
    model: &Model,
    rows: &[&Row],
    n: u8,
    x: impl Fn(&Row) -> f64,
) -> [Vec<(f64, f64)>; 2] {
    let mut out = [Vec::new(), Vec::new()];
    for r in rows {
        let Some(u) = along(model, r, n) else {
            continue;
        };
        match r.state.directions()[n as usize - 1] {
            Direction::Positive => out[0].push((x(r), u)),
            Direction::Negative => out[1].push((x(r), u)),
            Direction::Unknown => {}
        }
    }
    out
}

fn map(model: &Model, rows: &[Row], n: u8) -> String {
    let rows = sweeping(rows, n);
    let a = |r: &Row| r.state.axes_deg[n as usize - 1];
    let all = binned(
        rows.iter()
            .filter_map(|r| along(model, r, n).map(|u| (a(r), u))),
    );
    let ptp = peak_to_peak(all.values().copied());
    let [plus, minus] = by_direction(model, &rows, n, a);
    let (p, m) = (binned(plus.into_iter()), binned(minus.into_iter()));
    let common: Vec<(f64, f64)> = p
        .iter()
        .filter_map(|(k, v)| m.get(k).map(|w| (*v, *w)))
        .collect();
    let same = line(&common).is_some_and(|(_, r)| r > 0.5);
    format!(
        "A{n} residual along its motion varies with the A{n} angle by {ptp:.0} µm peak to peak{}",
        if same {
            ", the same in both directions"
        } else {
            ""
        }
    )
}

/// The play's dead band when the data hold stops after short reversals of n (the only data
/// that tell a play from an instant switch of sign), else the gap between the directions.
fn backlash(model: &Model, rows: &[Row], n: u8) -> String {
    if let Some(e) = super::play::evidence(model, rows, n) {
        return super::play::describe(&e, n);
    }
    let rows = sweeping(rows, n);
    let a = |r: &Row| r.state.axes_deg[n as usize - 1];
    let [plus, minus] = by_direction(model, &rows, n, a);
    let (p, m) = (binned(plus.into_iter()), binned(minus.into_iter()));
    let gaps: Vec<f64> = p
        .iter()
        .filter_map(|(k, v)| m.get(k).map(|w| v - w))
        .collect();
    if gaps.is_empty() {
        return format!("A{n} was measured in one rotation direction only");
    }
    let mean = gaps.iter().sum::<f64>() / gaps.len() as f64;
    format!(
        "A{n} residual along its motion differs between the rotation directions by {:.0} µm \
         on average (+ minus −, at {} angles)",
        mean,
        gaps.len()
    )
}

fn crosstalk(model: &Model, rows: &[Row], m: u8, n: u8) -> String {
    let rows = sweeping(rows, n);
    let other = |r: &Row| r.state.axes_deg[m as usize - 1];
    let range = peak_to_peak(rows.iter().map(|r| other(r)));
    if range < 1e-6 {
        return format!("A{m} did not change while A{n} was measured");
    }
    let [plus, minus] = by_direction(model, &rows, n, other);
    let all: Vec<(f64, f64)> = plus.iter().chain(&minus).copied().collect();
    let Some((slope, _)) = line(&all) else {
        return format!("A{m} did not change while A{n} was measured");
    };
    let s = step(range);
    let per = |v: &[(f64, f64)]| line(v).map(|(b, _)| b * s);
    let both = match (per(&plus), per(&minus)) {
        (Some(a), Some(b)) => {
            if a.signum() == b.signum() && a.abs().min(b.abs()) > 0.3 * a.abs().max(b.abs()) {
                ", in both directions"
            } else if a.abs() > b.abs() {
                ", mostly in the + direction"
            } else {
                ", mostly in the − direction"
            }
        }
        _ => "",
    };
    format!(
        "A{n} residual {} with the A{m} angle: {:.0} µm per {s}°{both}",
        if slope >= 0.0 { "grows" } else { "falls" },
        (slope * s).abs()
    )
}

fn compliance(model: &Model, rows: &[Row], n: u8) -> String {
    let torque = Driver::Torque(n);
    let points: Vec<(f64, f64)> = rows
        .iter()
        .filter_map(|r| Some((torque.value(model, &r.state)?, along(model, r, n)?)))
        .collect();
    match line(&points) {
        Some((slope, r)) => format!(
            "A{n} residual along its motion follows its gravity torque: {slope:.0} µm per kN·m \
             (correlation {r:.2})"
        ),
        None => format!("the A{n} gravity torque did not change in these measurements"),
    }
}

fn tilt(model: &Model, rows: &[Row], n: u8) -> String {
    let rows = sweeping(rows, n);
    let a = |r: &Row| r.state.axes_deg[n as usize - 1];
    let across: Vec<(f64, Vector3<f64>)> = rows
        .iter()
        .filter_map(|r| {
            let u = motion(model, r, n)?;
            let res = r.residual() * 1000.0;
            Some((a(r), res - u * res.dot(&u)))
        })
        .collect();
    let ptp = (0..3)
        .map(|c| peak_to_peak(binned(across.iter().map(|(x, v)| (*x, v[c]))).into_values()))
        .fold(0.0, f64::max);
    format!("the residual across the A{n} motion changes with the A{n} angle by {ptp:.0} µm peak to peak")
}

/// The residual's trend over time within each test (each test's own mean removed, so that
/// what the tables absorbed test by test does not count), pooled over the tests.
fn drift(rows: &[Row]) -> String {
    let mut by_test: HashMap<&str, Vec<&Row>> = HashMap::new();
    for r in rows {
        by_test.entry(r.test.as_str()).or_default().push(r);
    }
    let (mut sxy, mut sxx) = (Vector3::zeros(), 0.0);
    for test in by_test.values() {
        let n = test.len() as f64;
        let t_mean = test.iter().map(|r| r.state.time_s).sum::<f64>() / n / 3600.0;
        let r_mean = test.iter().map(|r| r.residual()).sum::<Vector3<f64>>() / n * 1000.0;
        for r in test {
            let dt = r.state.time_s / 3600.0 - t_mean;
            sxy += (r.residual() * 1000.0 - r_mean) * dt;
            sxx += dt * dt;
        }
    }
    if sxx <= 0.0 {
        return "the measurements carry no time (column t)".into();
    }
    let rate: Vector3<f64> = sxy / sxx;
    let main = (0..3)
        .max_by(|&a, &b| rate[a].abs().total_cmp(&rate[b].abs()))
        .unwrap_or(2);
    format!(
        "within each test the residual moves with time: {:.0} µm per hour, mostly in {}",
        rate.norm(),
        ["X", "Y", "Z"][main]
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{Payload, RobotDescription};
    use crate::model::AxisState;

    /// A2 swept at A3 = 58°, 105° and 153°, both directions, with a residual along A2's motion
    /// of 0.82 µm per degree of A3 above 105° (plus a tilt-free, direction-free rest).
    fn a3_to_a2_rows(model: &Model) -> Vec<Row> {
        let mut rows = Vec::new();
        for a3 in [58.0, 105.0, 153.0] {
            for (dir, sweep) in [
                (Direction::Positive, [-100.0, -80.0, -60.0, -40.0]),
                (Direction::Negative, [-40.0, -60.0, -80.0, -100.0]),
            ] {
                for a2 in sweep {
                    let state = AxisState::with_directions([0.0, a2, a3, 0.0, 45.0, 0.0], [dir; 6]);
                    let p = model.target_position(&state);
                    let (frames, _) = model.frames(&state);
                    let u = frames
                        .point_partial(Slot::Angle { axis: 2 }, &p)
                        .normalize();
                    rows.push(Row {
                        test: format!("A2@A3={a3}"),
                        source: "s".into(),
                        line: 0,
                        state,
                        measured: p + u * (0.82e-3 * (a3 - 105.0)),
                        predicted: p,
                        nominal: p,
                    });
                }
            }
        }
        rows
    }

    #[test]
    fn crosstalk_evidence_reads_the_slope_per_round_step_in_both_directions() {
        let model = Model::new(
            RobotDescription::kr30ha(),
            Payload::default(),
            Vector3::zeros(),
        );
        let rows = a3_to_a2_rows(&model);
        // 0.82 µm/° × 50° = 41 µm per 50° (A3 spans 95°, half of it rounds to 50°).
        assert_eq!(
            crosstalk(&model, &rows, 3, 2),
            "A2 residual grows with the A3 angle: 41 µm per 50°, in both directions"
        );
        // Nothing depends on A2 itself: averaged over the three A3 angles every A2 angle has
        // the same residual, so a map of A2 has nothing to explain.
        assert!(
            map(&model, &rows, 2)
                .starts_with("A2 residual along its motion varies with the A2 angle by 0 µm"),
            "{}",
            map(&model, &rows, 2)
        );
        // No direction dependence.
        assert!(backlash(&model, &rows, 2).contains("by 0 µm"));
    }

    #[test]
    fn line_and_step_by_hand() {
        let (b, r) = line(&[(0.0, 1.0), (1.0, 3.0), (2.0, 5.0)]).unwrap();
        assert!((b - 2.0).abs() < 1e-12 && (r - 1.0).abs() < 1e-12);
        assert!(line(&[(1.0, 1.0), (1.0, 2.0), (1.0, 3.0)]).is_none());
        assert_eq!(step(95.0), 50.0); // half of 95 is 47.5 → the nearest 1-2-5 step
        assert_eq!(step(100.0), 50.0);
        assert_eq!(step(6.0), 2.0); // 3 is nearer 2 than 5 in ratio
        assert_eq!(step(15.0), 10.0);
    }
}
