//! Gross errors in one indexing test (a broken beam, a stray reflection): found before any
//! model is fitted, from what the test itself says. The measured points of a test lie on a
//! circle about the indexed axis; seen in the circle's own coordinates (radial, axial and
//! along the circle) every coordinate changes smoothly with the command angle — the radial and
//! axial ones hardly at all, the one along the circle by the axis's angular positioning
//! deviation, whose two rotation directions differ by the smooth backlash. A point is a
//! suspect when it leaves that smooth course by more than the tracker's noise allows:
//! - radially or axially: its distance from the running median (five neighbours in command
//!   order, same rotation direction) of those coordinates;
//! - along the circle: the difference between its direction's and the other direction's
//!   position at the same command angle, against the running median of that difference (the
//!   backlash table must be smooth; the gear-pitch ripple common to both directions cancels),
//!   blamed on whichever of the two points leaves its own direction's course more; a point
//!   without a partner in the other direction against its own direction's course.
//!
//! Each statistic is scaled by the tracker's noise at the point and by the test's own robust
//! scatter of that statistic (never below the tracker's noise), so a noisier set-up does not
//! flag its good points, and compared with 5 such standard deviations, more in long tests
//! ([`super::robust::threshold`]). Global screening (against the fitted model) comes later in the
//! pipeline; this stage keeps the circles of the direct method clean and catches what a fitted
//! table would absorb: a displacement along the circle at a command angle only one point of
//! that direction visits.

use nalgebra::Vector3;

use super::circle::{fit_circle, Circle3};
use crate::measure::Stop;
use crate::model::Direction;

/// Half-width of the running median (points on each side).
const HALF_WINDOW: usize = 2;
/// Median of the χ distribution with 2 degrees of freedom, √(2 ln 2): the median length of a
/// 2-D normal vector with unit standard deviation per coordinate.
const CHI2_MEDIAN: f64 = 1.177_410_022_515_474_6;
/// Median of |N(0, 1)|.
const HALF_NORMAL_MEDIAN: f64 = 0.674_489_750_196_081_7;

/// A measured row that does not belong with its test's other points.
#[derive(Clone, Debug, PartialEq)]
pub struct Suspect {
    /// Index of the row in the data.
    pub row: usize,
    /// Estimated size of the error, mm.
    pub size_mm: f64,
    /// Why, in words.
    pub why: String,
}

/// One measured point of a test in the circle's coordinates.
struct Local {
    row: usize,
    command_deg: f64,
    direction: Direction,
    radial: f64,
    axial: f64,
    /// Displacement along the circle relative to the command, mm.
    along: f64,
    sigma: f64,
}

/// The rows of `rows` (measured rows of one indexing test of axis `axis`, 1..=6) that leave
/// the smooth course of their neighbours, with `sigma_mm(row)` the tracker's standard
/// deviation per coordinate at a row. Also returns the circle fitted without them.
pub fn screen_test(
    data: &[Stop],
    rows: &[usize],
    axis: u8,
    sigma_mm: &dyn Fn(usize) -> f64,
) -> (Vec<Suspect>, Option<Circle3>) {
    let k = axis as usize - 1;
    let rows: Vec<usize> = rows
        .iter()
        .copied()
        .filter(|&i| data[i].measured_mm.is_some())
        .collect();
    let points = |keep: &dyn Fn(usize) -> bool| -> Vec<Vector3<f64>> {
        rows.iter()
            .filter(|&&i| keep(i))
            .filter_map(|&i| data[i].measured_mm)
            .collect()
    };
    let Some(first) = fit_circle(&points(&|_| true)) else {
        return (Vec::new(), None);
    };
    let circle = oriented_by_motion(first, data, &rows, k);
    let locals = local_coordinates(&circle, data, &rows, k, sigma_mm);
    let suspects = suspects(&locals, axis);
    let refit = if suspects.is_empty() {
        Some(circle)
    } else {
        let bad: Vec<usize> = suspects.iter().map(|s| s.row).collect();
        fit_circle(&points(&|i| !bad.contains(&i))).map(|c| oriented_by_motion(c, data, &rows, k))
    };
    (suspects, refit)
}

/// The circle with its normal along a positive rotation of axis `k` (0-based): the measured
/// points turn counter-clockwise about it as the command angle grows. Read off the data, so
/// it needs no model and no frame.
pub fn oriented_by_motion(mut circle: Circle3, data: &[Stop], rows: &[usize], k: usize) -> Circle3 {
    let n = circle.normal.into_inner();
    let mut sense = 0.0;
    let measured: Vec<(f64, Vector3<f64>)> = rows
        .iter()
        .filter_map(|&i| data[i].measured_mm.map(|m| (data[i].state.axes_deg[k], m)))
        .collect();
    for pair in measured.windows(2) {
        let (a0, p0) = pair[0];
        let (a1, p1) = pair[1];
        let step = a1 - a0;
        if step != 0.0 && step.abs() < 90.0 {
            let turn = n.dot(&(p0 - circle.centre).cross(&(p1 - circle.centre)));
            sense += step.signum() * turn.signum();
        }
    }
    if sense < 0.0 {
        circle.normal = -circle.normal;
    }
    circle
}

fn local_coordinates(
    circle: &Circle3,
    data: &[Stop],
    rows: &[usize],
    k: usize,
    sigma_mm: &dyn Fn(usize) -> f64,
) -> Vec<Local> {
    let n = circle.normal.into_inner();
    let Some(&r0) = rows.first() else {
        return Vec::new();
    };
    let (reference, a0) = match data[r0].measured_mm {
        Some(m) => (m, data[r0].state.axes_deg[k]),
        None => return Vec::new(),
    };
    rows.iter()
        .filter_map(|&i| {
            let m = data[i].measured_mm?;
            let d = m - circle.centre;
            let axial = n.dot(&d);
            let in_plane = (d - n * axial).norm();
            let command = data[i].state.axes_deg[k];
            let turned = circle.angle_of(&m, &reference);
            let deviation = wrap(turned - (command - a0).to_radians());
            Some(Local {
                row: i,
                command_deg: command,
                direction: data[i].state.directions()[k],
                radial: in_plane - circle.radius,
                axial,
                along: deviation * in_plane,
                sigma: sigma_mm(i).max(1e-9),
            })
        })
        .collect()
}

/// An angle wrapped into (−π, π].
fn wrap(a: f64) -> f64 {
    let t = std::f64::consts::TAU;
    a - t * ((a + std::f64::consts::PI) / t).floor()
}

/// `values[i] −` the median of the window of `2·HALF_WINDOW + 1` values around `i` (shifted
/// inwards at the ends), for values sorted by command angle.
fn spikes(values: &[f64]) -> Vec<f64> {
    let n = values.len();
    let width = (2 * HALF_WINDOW + 1).min(n);
    let mut window = Vec::with_capacity(width);
    (0..n)
        .map(|i| {
            let start = i.saturating_sub(HALF_WINDOW).min(n - width);
            window.clear();
            window.extend_from_slice(&values[start..start + width]);
            window.sort_by(f64::total_cmp);
            values[i] - window[width / 2]
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The robust scale of normalised statistics (`median / expected median`), never below 1.
fn scale(normalised: &[f64], expected_median: f64) -> f64 {
    median(normalised.to_vec()).map_or(1.0, |m| (m / expected_median).max(1.0))
}

/// Per-point statistics of a test (see the module documentation) and the suspects.
fn suspects(locals: &[Local], axis: u8) -> Vec<Suspect> {
    // Own-direction spikes of each coordinate, by index into `locals`.
    let n = locals.len();
    let (mut radial, mut axial, mut along) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut branches: [Vec<usize>; 3] = Default::default();
    for (i, l) in locals.iter().enumerate() {
        branches[(l.direction.sign() + 1.0) as usize].push(i);
    }
    for branch in branches.iter_mut() {
        branch.sort_by(|&a, &b| locals[a].command_deg.total_cmp(&locals[b].command_deg));
        if branch.len() < 2 * HALF_WINDOW + 1 {
            continue;
        }
        let column =
            |f: fn(&Local) -> f64| -> Vec<f64> { branch.iter().map(|&i| f(&locals[i])).collect() };
        for (target, values) in [
            (&mut radial, spikes(&column(|l| l.radial))),
            (&mut axial, spikes(&column(|l| l.axial))),
            (&mut along, spikes(&column(|l| l.along))),
        ] {
            for (&i, v) in branch.iter().zip(values) {
                target[i] = v;
            }
        }
    }
    // Pairs of the two directions at the same command angle.
    let [minus, _, plus] = &branches;
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    let mut j = 0;
    for &p in plus {
        while j < minus.len() && locals[minus[j]].command_deg < locals[p].command_deg - 1e-6 {
            j += 1;
        }
        if j < minus.len() && (locals[minus[j]].command_deg - locals[p].command_deg).abs() <= 1e-6 {
            pairs.push((p, minus[j]));
            j += 1;
        }
    }
    let mut difference = vec![None; n];
    if pairs.len() > 2 * HALF_WINDOW {
        let d: Vec<f64> = pairs
            .iter()
            .map(|&(p, m)| locals[p].along - locals[m].along)
            .collect();
        for (&(p, m), s) in pairs.iter().zip(spikes(&d)) {
            difference[p] = Some((s, m));
            difference[m] = Some((-s, p));
        }
    }

    let normalised = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(locals)
            .map(|(x, l)| x.abs() / l.sigma)
            .collect()
    };
    let off_circle: Vec<f64> = (0..n)
        .map(|i| radial[i].hypot(axial[i]) / locals[i].sigma)
        .collect();
    let off_scale = scale(&off_circle, CHI2_MEDIAN);
    let along_n = normalised(&along);
    let along_scale = scale(&along_n, HALF_NORMAL_MEDIAN);
    let diff_n: Vec<f64> = (0..n)
        .filter_map(|i| difference[i].map(|(s, _)| s.abs() / locals[i].sigma))
        .collect();
    let diff_scale = scale(&diff_n, HALF_NORMAL_MEDIAN);

    use super::robust::threshold;
    let (limit_off, limit_along) = (threshold(n, 2), threshold(n, 1));
    let mut out = Vec::new();
    for i in 0..n {
        let l = &locals[i];
        let circle_off = off_circle[i] > limit_off * off_scale;
        let tangential = match difference[i] {
            // Paired: the difference must jump, and this point must be the one that moved.
            Some((s, partner)) => (s.abs() / l.sigma > limit_along * diff_scale
                && along_n[i] >= along_n[partner])
                .then_some(along[i]),
            None => (along_n[i] > limit_along * along_scale).then_some(along[i]),
        };
        if !circle_off && tangential.is_none() {
            continue;
        }
        let t = tangential.unwrap_or(0.0);
        let size = (radial[i].powi(2) + axial[i].powi(2) + t * t).sqrt();
        let mut parts = Vec::new();
        if circle_off {
            parts.push(format!(
                "{:.3} mm off the A{axis} circle (radial {:+.3}, axial {:+.3} mm)",
                radial[i].hypot(axial[i]),
                radial[i],
                axial[i]
            ));
        }
        if let Some(t) = tangential {
            parts.push(format!(
                "{t:+.3} mm along the A{axis} circle off the smooth angular deviation \
                 (the backlash between the directions jumps there)"
            ));
        }
        out.push(Suspect {
            row: l.row,
            size_mm: size,
            why: format!(
                "{}; tracker noise there σ {:.0} µm",
                parts.join(", "),
                l.sigma * 1000.0
            ),
        });
    }
    out
}

/// Suspects that are not isolated: the same jump seen at one angle of the indexed axis in
/// both directions, in several tests or over a run of neighbours. A gross error is one point,
/// unlike its neighbours, its partner in the other direction and the same pose in another test;
/// a jump that repeats is the robot's (a flank that changes with the load, a contact), which
/// the fit must see and the user must be told of.
#[derive(Clone, Debug, PartialEq)]
pub struct Structure {
    /// The indexed axis, 1..=6.
    pub axis: u8,
    /// The command angles of that axis where it shows, degrees (lowest, highest).
    pub angles_deg: [f64; 2],
    /// The rows of the data it covers.
    pub rows: Vec<usize>,
    /// Tests of that axis showing it, and the axis's indexing tests in all.
    pub tests: usize,
    /// The axis's indexing tests in all.
    pub of_tests: usize,
    /// Whether it shows in both rotation directions.
    pub both_directions: bool,
}

impl Structure {
    /// "the residual jumps at A2 ≈ −65° in every A2 test (4 tests, 14 points, both directions)".
    pub fn describe(&self) -> String {
        let [lo, hi] = self.angles_deg;
        let at = if hi - lo < 1.5 {
            format!("A{} ≈ {:.0}°", self.axis, 0.5 * (lo + hi))
        } else {
            format!("A{} {lo:.0}..{hi:.0}°", self.axis)
        };
        let tests = if self.tests == self.of_tests && self.tests > 1 {
            format!("in every A{} test ({} tests", self.axis, self.tests)
        } else {
            format!(
                "in {} of {} A{} tests ({} test{}",
                self.tests,
                self.of_tests,
                self.axis,
                self.tests,
                if self.tests == 1 { "" } else { "s" }
            )
        };
        format!(
            "the residual jumps at {at} {tests}, {} points{})",
            self.rows.len(),
            if self.both_directions {
                ", both directions"
            } else {
                ""
            }
        )
    }
}

/// Two suspects are the same jump seen twice only when their sizes agree within this factor.
const SAME_SIZE: f64 = 3.0;
/// Systematic suspects of one axis this close (degrees) are reported as one jump: where a
/// flank changes with the load, the angle shifts from test to test with the other axes.
const ONE_JUMP_DEG: f64 = 15.0;

/// One suspect of the screening with where it lies: its indexing test, axis, command angle
/// of that axis, rotation direction, and the test's pitch (degrees between neighbouring
/// command angles).
#[derive(Clone, Debug)]
pub struct Located {
    pub suspect: Suspect,
    pub test: usize,
    pub axis: u8,
    pub angle_deg: f64,
    pub direction: Direction,
    pub pitch_deg: f64,
}

/// The pitch of a test's command angles of axis `axis`: the median step between its distinct
/// angles (1° when it has fewer than two).
pub fn pitch_deg(data: &[Stop], rows: &[usize], axis: u8) -> f64 {
    let mut angles: Vec<f64> = rows
        .iter()
        .map(|&i| data[i].state.axes_deg[axis as usize - 1])
        .collect();
    angles.sort_by(f64::total_cmp);
    angles.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    let steps: Vec<f64> = angles.windows(2).map(|w| w[1] - w[0]).collect();
    median(steps).unwrap_or(1.0)
}

/// Splits located suspects into the isolated ones (gross errors) and the structures: a
/// suspect with another of about its size ([`SAME_SIZE`]) in its own test, at the same angle
/// (within the test's pitch) in the other direction or at a neighbouring angle in its own
/// direction, is systematic when such jumps show in more than one test of the axis at nearby
/// angles (reported as one structure); the rest are isolated. `tests_of_axis[n-1]`: how many indexing tests axis n has.
pub fn systematic(
    located: Vec<Located>,
    tests_of_axis: [usize; 6],
) -> (Vec<Suspect>, Vec<Structure>) {
    // A jump that repeats repeats at about its size; a millimetre beside a few hundredths is
    // a gross error next to noise.
    let alike = |x: f64, y: f64| x.max(y) <= SAME_SIZE * x.min(y);
    let near = |a: &Located, b: &Located| {
        (a.angle_deg - b.angle_deg).abs() <= 1.01 * a.pitch_deg.min(b.pitch_deg)
    };
    let repeated: Vec<bool> = located
        .iter()
        .enumerate()
        .map(|(i, a)| {
            located.iter().enumerate().any(|(j, b)| {
                j != i
                    && a.axis == b.axis
                    && near(a, b)
                    && alike(a.suspect.size_mm, b.suspect.size_mm)
                    // In its own test: the other direction, or a run in its own direction
                    // (a neighbouring angle, not the same one). Gross errors of other tests
                    // meet at one angle by chance where they are many.
                    && a.test == b.test
                    && (a.direction != b.direction || (a.angle_deg - b.angle_deg).abs() > 1e-6)
            })
        })
        .collect();
    let mut isolated = Vec::new();
    let mut kept: Vec<Located> = Vec::new();
    for (l, r) in located.into_iter().zip(repeated) {
        if r {
            kept.push(l);
        } else {
            isolated.push(l.suspect);
        }
    }
    // Structures: the systematic suspects of one axis, grouped where their angles chain.
    kept.sort_by(|a, b| {
        (a.axis, a.angle_deg)
            .partial_cmp(&(b.axis, b.angle_deg))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut structures: Vec<Structure> = Vec::new();
    let mut group: Vec<&Located> = Vec::new();
    let flush = |group: &mut Vec<&Located>, structures: &mut Vec<Structure>| {
        if let (Some(first), Some(last)) = (group.first(), group.last()) {
            let mut tests: Vec<usize> = group.iter().map(|l| l.test).collect();
            tests.sort_unstable();
            tests.dedup();
            let mut rows: Vec<usize> = group.iter().map(|l| l.suspect.row).collect();
            rows.sort_unstable();
            let axis = first.axis;
            structures.push(Structure {
                axis,
                angles_deg: [first.angle_deg, last.angle_deg],
                rows,
                tests: tests.len(),
                of_tests: tests_of_axis[axis as usize - 1].max(tests.len()),
                both_directions: group.iter().any(|l| l.direction == Direction::Positive)
                    && group.iter().any(|l| l.direction == Direction::Negative),
            });
        }
        group.clear();
    };
    for l in &kept {
        let chained = group.last().is_some_and(|g: &&Located| {
            g.axis == l.axis
                && l.angle_deg - g.angle_deg
                    <= ONE_JUMP_DEG.max(2.01 * g.pitch_deg.max(l.pitch_deg))
        });
        if !chained {
            flush(&mut group, &mut structures);
        }
        group.push(l);
    }
    flush(&mut group, &mut structures);
    // A pair of gross errors can meet by chance in one test; a jump the robot makes shows in
    // more than one test of its axis.
    let (structures, chance): (Vec<Structure>, Vec<Structure>) =
        structures.into_iter().partition(|s| s.tests >= 2);
    for st in chance {
        isolated.extend(
            kept.iter()
                .filter(|l| st.rows.contains(&l.suspect.row))
                .map(|l| l.suspect.clone()),
        );
    }
    (isolated, structures)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::AxisState;

    /// A bidirectional sweep of A1 on a 1,000 mm circle with a smooth deviation, a smooth
    /// backlash and a deterministic ±10 µm ripple; three points displaced by hand.
    fn sweep(displaced: &[(usize, Vector3<f64>)]) -> Vec<Stop> {
        let mut stops = Vec::new();
        let mut push = |a: f64, direction: Direction, i: usize| {
            let deviation =
                0.003 * (a / 9.0 * std::f64::consts::TAU).sin() + direction.sign() * 0.002;
            let angle = (a + deviation).to_radians();
            let ripple = 0.010 * ((i as f64) * 2.7).sin();
            let mut p = Vector3::new(1000.0 * angle.cos(), 1000.0 * angle.sin(), ripple);
            if let Some((_, d)) = displaced.iter().find(|(k, _)| *k == i) {
                p += d;
            }
            let mut state = AxisState::new([a, 0.0, 0.0, 0.0, 0.0, 0.0]);
            state.history[0] = crate::model::AxisHistory::engaged(direction);
            stops.push(Stop {
                test: "A1".into(),
                state,
                measured_mm: Some(p),
                line: i + 2,
            });
        };
        let mut i = 0;
        for a in -30..=30 {
            push(a as f64, Direction::Positive, i);
            i += 1;
        }
        for a in (-30..=30).rev() {
            push(a as f64, Direction::Negative, i);
            i += 1;
        }
        stops
    }

    #[test]
    fn displaced_points_are_found_and_only_those() {
        // Row 10: 0.3 mm radially; row 40: 0.3 mm along the circle (at A1 = 10°, the tangent
        // is (−sin, cos)); row 90: 0.25 mm axially.
        let t = 10f64.to_radians();
        let displaced = [
            (
                10,
                Vector3::new(
                    0.3 * (-20f64).to_radians().cos(),
                    0.3 * (-20f64).to_radians().sin(),
                    0.0,
                ),
            ),
            (40, Vector3::new(-t.sin(), t.cos(), 0.0) * 0.3),
            (90, Vector3::new(0.0, 0.0, 0.25)),
        ];
        let data = sweep(&displaced);
        let rows: Vec<usize> = (0..data.len()).collect();
        let (found, circle) = screen_test(&data, &rows, 1, &|_| 0.010);
        let mut flagged: Vec<usize> = found.iter().map(|s| s.row).collect();
        flagged.sort_unstable();
        assert_eq!(flagged, vec![10, 40, 90], "{found:#?}");
        let along = found.iter().find(|s| s.row == 40).unwrap();
        assert!((along.size_mm - 0.3).abs() < 0.03, "{along:?}");
        assert!(along.why.contains("along the A1 circle"), "{}", along.why);
        // The refitted circle is the clean one.
        let c = circle.unwrap();
        assert!(
            (c.radius - 1000.0).abs() < 0.005 && c.centre.norm() < 0.005,
            "{c:?}"
        );
        // A positive A1 command turns the points counter-clockwise about +Z here.
        assert!(c.normal.z > 0.99);
        // Without displaced points nothing is flagged.
        let (none, _) = screen_test(&sweep(&[]), &rows, 1, &|_| 0.010);
        assert!(none.is_empty(), "{none:#?}");
    }

    #[test]
    fn running_median_spikes() {
        let s = spikes(&[0.0, 1.0, 2.0, 30.0, 4.0, 5.0, 6.0]);
        assert_eq!(s[3], 30.0 - 4.0);
        assert_eq!(s[0], 0.0 - 2.0); // window shifted inwards at the ends
        assert!((wrap(3.5 * std::f64::consts::PI) + 0.5 * std::f64::consts::PI).abs() < 1e-12);
    }
}
