//! The paper's direct method (section 2.3 and its reference \[8\]), the starting point of the
//! global refinement:
//! 1. every *indexing test* in the data — a test label (per file) whose measured rows move
//!    exactly one axis over at least five angles while the others stand still — gets its
//!    best-fit circle ([`super::circle`]): the centre and normal are that axis's average line
//!    at the test's reference pose, the normal oriented by the points' own sense of rotation
//!    (no model or frame needed);
//! 2. the target vector in closed form from the A5 and A6 circles ([`target_from_circles`]):
//!    the A6 circle's radius and phase give the target's offset from the A6 axis, the point
//!    where the A6 axis meets the A5 axis (the wrist point) its position along it. Fitting the
//!    target together with the axis lines from a wrong start can end in a wrong minimum (the
//!    A6 circle does not change with the target's phase about A6, and a target started on
//!    the A6 axis has no A6 circle at all), so the target comes first;
//! 3. the geometric parameters are fitted so that the model's circles match the measured ones
//!    (Gauss–Newton with a numerical Jacobian on centre, normal and radius: 7 numbers per
//!    test against 21 parameters), from that target;
//! 4. the angular position of each measured point on its circle, against where the geometric
//!    model puts the same command, is the angular positioning deviation of that axis at that
//!    command angle and rotation direction; the mean of the two directions fills `map:An`,
//!    their difference (negative minus positive: the play's width) `backlash:An`, and the
//!    spread between repeats of the test at
//!    several angles of another axis fills `crosstalk:Am->An`.
//!
//! Data that holds no indexing test (arbitrary poses, paths) yields nothing here and the
//! refinement starts from the model as it is.

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector, Vector3};

use super::circle::{fit_circle, Circle3};
use super::screen::oriented_by_motion;
use crate::measure::Stop;
use crate::model::{AxisState, Direction, Effect, Model, Role, Slot};

/// Fewest measured angles for a test to count as an indexing test.
const MIN_ANGLES: usize = 5;

/// Most rows of a test at which the model's circle is evaluated while fitting the geometry
/// (evenly spread over the test): more add time, not information, to a 7-number circle.
const MAX_MODEL_CIRCLE_ROWS: usize = 240;

/// One indexing test found in the data.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexingTest {
    /// The indexing test.
    pub test: String,
    /// The indexed axis (1..=6).
    /// The indexed axis, 1..=6.
    pub axis: u8,
    /// Angles of all axes during the test (the indexed one at its first measured value).
    /// The other axes' angles during the test, degrees.
    pub reference_deg: [f64; 6],
    /// Indices into the data of the test's measured rows.
    pub rows: Vec<usize>,
    /// The file (tracker set-up) the test was measured in.
    pub group: usize,
}

/// The measured average line of an axis in one test.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisLine {
    /// The indexing test.
    pub test: String,
    /// The indexed axis, 1..=6.
    pub axis: u8,
    /// The other axes' angles during the test, degrees.
    pub reference_deg: [f64; 6],
    /// Normal oriented along a positive KUKA rotation of the axis.
    pub circle: Circle3,
    /// The test's measured points: (row, command angle of the axis, position).
    pub points: Vec<(usize, f64, Vector3<f64>)>,
}

/// One measured angular positioning deviation.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviationSample {
    /// The indexing test.
    pub test: String,
    /// The indexed axis, 1..=6.
    pub axis: u8,
    /// The other axes' angles during the test, degrees.
    pub reference_deg: [f64; 6],
    /// The indexed axis's command angle, degrees.
    pub command_deg: f64,
    /// The direction it arrived in.
    pub direction: Direction,
    /// Actual minus command angle, degrees, KUKA sign.
    pub deviation_deg: f64,
}

/// What the direct method found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DirectResult {
    /// The measured average line of each axis in each indexing test.
    pub lines: Vec<AxisLine>,
    /// Every measured angular positioning deviation.
    pub samples: Vec<DeviationSample>,
}

/// The indexing tests of `data` (see the module documentation), all from one file.
#[cfg(any(test, feature = "internals"))]
pub fn indexing_tests(data: &[Stop]) -> Vec<IndexingTest> {
    indexing_tests_grouped(data, &[])
}

/// The indexing tests of `data` whose rows come from the files `group_of` (one entry per
/// row; empty: one file): a label is a test of its own file.
pub fn indexing_tests_grouped(data: &[Stop], group_of: &[usize]) -> Vec<IndexingTest> {
    let mut groups: BTreeMap<(usize, &str), Vec<usize>> = BTreeMap::new();
    let mut run: Option<((usize, &str), Vec<usize>)> = None;
    for (i, s) in data.iter().enumerate() {
        if s.measured_mm.is_some() {
            let key = (group_of.get(i).copied().unwrap_or(0), s.test.as_str());
            // Rows of a test come in runs: one map look-up per run.
            match &mut run {
                Some((k, rows)) if *k == key => rows.push(i),
                _ => {
                    if let Some((k, rows)) = run.replace((key, vec![i])) {
                        groups.entry(k).or_default().extend(rows);
                    }
                }
            }
        }
    }
    if let Some((k, rows)) = run {
        groups.entry(k).or_default().extend(rows);
    }
    let mut tests = Vec::new();
    for ((group, test), rows) in groups {
        let first = data[rows[0]].state.axes_deg;
        let moving: Vec<usize> = (0..6)
            .filter(|&k| rows.iter().any(|&i| data[i].state.axes_deg[k] != first[k]))
            .collect();
        if let [k] = moving[..] {
            let mut angles: Vec<f64> = rows.iter().map(|&i| data[i].state.axes_deg[k]).collect();
            angles.sort_by(f64::total_cmp);
            angles.dedup();
            if angles.len() >= MIN_ANGLES {
                tests.push(IndexingTest {
                    test: test.to_string(),
                    axis: k as u8 + 1,
                    reference_deg: first,
                    rows,
                    group,
                });
            }
        }
    }
    tests
}

/// The model without its angular tables: only the `geometric` effect (when present).
fn geometric_only(model: &Model) -> Option<(Model, usize)> {
    let g = axis_lines(model)?;
    let mut m = Model::new(model.robot, model.payload, model.target_mm);
    m.push(model.effects()[g].clone_model_effect());
    Some((m, model.effect_start(g)))
}

/// The circle a model predicts for a test: fitted to its predictions at (up to
/// [`MAX_MODEL_CIRCLE_ROWS`] of) the test's states.
fn model_circle(model: &Model, data: &[Stop], test: &IndexingTest) -> Option<Circle3> {
    let step = test.rows.len().div_ceil(MAX_MODEL_CIRCLE_ROWS).max(1);
    let points: Vec<Vector3<f64>> = test
        .rows
        .iter()
        .step_by(step)
        .map(|&i| model.target_position(&data[i].state))
        .collect();
    fit_circle(&points)
}

/// The measured circle of a test, its normal along a positive rotation of the axis.
pub fn measured_circle(data: &[Stop], test: &IndexingTest) -> Option<Circle3> {
    let points: Vec<Vector3<f64>> = test
        .rows
        .iter()
        .filter_map(|&i| data[i].measured_mm)
        .collect();
    let circle = fit_circle(&points)?;
    Some(oriented_by_motion(
        circle,
        data,
        &test.rows,
        test.axis as usize - 1,
    ))
}

fn oriented(mut circle: Circle3, axis: &Vector3<f64>) -> Circle3 {
    if circle.normal.dot(axis) < 0.0 {
        circle.normal = -circle.normal;
    }
    circle
}

/// Centre (3), normal scaled by the radius (3) and radius (1) of a circle: the numbers two
/// circles are compared by, all in mm.
fn circle_vector(c: &Circle3) -> [f64; 7] {
    let n = c.normal.into_inner() * c.radius;
    [c.centre.x, c.centre.y, c.centre.z, n.x, n.y, n.z, c.radius]
}

/// Fits the geometric parameters to the measured circles (step 2). Returns the fitted
/// geometric-only model.
fn fit_geometry(
    model: &Model,
    data: &[Stop],
    tests: &[IndexingTest],
    lines: &[AxisLine],
) -> Option<Model> {
    let (mut geo, _) = geometric_only(model)?;
    let n = geo.n_parameters();
    let target: Vec<f64> = lines
        .iter()
        .flat_map(|l| circle_vector(&l.circle))
        .collect();
    let predict = |m: &Model| -> Option<Vec<f64>> {
        let mut out = Vec::with_capacity(target.len());
        for (t, l) in tests.iter().zip(lines) {
            let c = oriented(model_circle(m, data, t)?, &l.circle.normal);
            out.extend(circle_vector(&c));
        }
        Some(out)
    };
    let mismatch = |m: &Model| -> Option<f64> {
        let p = predict(m)?;
        Some(target.iter().zip(&p).map(|(t, b)| (t - b).powi(2)).sum())
    };
    let start = mismatch(&geo)?;
    let start_values = geo.values();
    for _ in 0..6 {
        let base = predict(&geo)?;
        let r = DVector::from_iterator(target.len(), target.iter().zip(&base).map(|(t, b)| t - b));
        let values = geo.values();
        let mut jac = DMatrix::zeros(target.len(), n);
        const STEP: f64 = 1e-4;
        for j in 0..n {
            let mut v = values.clone();
            v[j] += STEP;
            let mut probe = geo.clone();
            probe.set_values(&v);
            let p = predict(&probe)?;
            for (i, (a, b)) in p.iter().zip(&base).enumerate() {
                jac[(i, j)] = (a - b) / STEP;
            }
        }
        // Damped, column-scaled normal equations: parameters the circles do not determine
        // stay where they are.
        let mut jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        for j in 0..n {
            jtj[(j, j)] += 1e-9 * jtj[(j, j)].max(1e-6) + 1e-12;
        }
        let step = jtj.cholesky()?.solve(&jtr);
        let next: Vec<f64> = values.iter().zip(step.iter()).map(|(v, s)| v + s).collect();
        geo.set_values(&next);
        if step.amax() < 1e-9 {
            break;
        }
    }
    // Circles that no geometry of this robot matches (data in another frame, another robot)
    // send Gauss–Newton anywhere: keep the start then, and let the verdict say why.
    let end = mismatch(&geo).filter(|e| e.is_finite())?;
    if end > start {
        geo.set_values(&start_values);
    }
    Some(geo)
}

/// Runs the direct method on `data` (positions in the base frame) and writes its estimates
/// into the model's `geometric`, `map`, `backlash` and `crosstalk` effects. `None` when the
/// data hold no indexing test.
#[cfg(any(test, feature = "internals"))]
pub fn direct_method(model: &mut Model, data: &[Stop]) -> Option<DirectResult> {
    direct_method_grouped(model, data, &[])
}

/// [`direct_method`] for rows from several files (`group_of`, one entry per row; each file's
/// positions already mapped into the base frame). When the data hold an A5 and an A6 test
/// at the same A1..A4 the target vector is set from them first ([`target_from_circles`]).
pub fn direct_method_grouped(
    model: &mut Model,
    data: &[Stop],
    group_of: &[usize],
) -> Option<DirectResult> {
    let tests = indexing_tests_grouped(data, group_of);
    let mut lines = Vec::new();
    let mut kept = Vec::new();
    for t in &tests {
        if let Some(circle) = measured_circle(data, t) {
            lines.push(AxisLine {
                test: t.test.clone(),
                axis: t.axis,
                reference_deg: t.reference_deg,
                circle,
                points: t
                    .rows
                    .iter()
                    .filter_map(|&i| {
                        let m = data[i].measured_mm?;
                        Some((i, data[i].state.axes_deg[t.axis as usize - 1], m))
                    })
                    .collect(),
            });
            kept.push(t.clone());
        }
    }
    if kept.is_empty() {
        return None;
    }
    if let Some(p) = target_from_circles(&model.robot, &kept, &lines) {
        set_target_a6(model, &p);
    }
    let geometry = fit_geometry(model, data, &kept, &lines);
    if let (Some(geo), Some(g)) = (&geometry, axis_lines(model)) {
        let mut values = model.values();
        let start = model.effect_start(g);
        values[start..start + geo.n_parameters()].copy_from_slice(&geo.values());
        model.set_values(&values);
    }
    let reference_model = match geometry {
        Some(g) => g,
        None => Model::new(model.robot, model.payload, model.target_mm),
    };
    // Pass 1 against the geometric model alone; pass 2 against the model with the other
    // axes' tables from pass 1, so that a neighbour's deviation at the test's reference
    // pose (e.g. A3's at A3 = 153° during an A2 test) is not read as this axis's deviation.
    let mut samples = deviation_samples(&kept, &lines, data, |_| reference_model.clone());
    fill_tables(model, &samples);
    let full = model.clone();
    samples = deviation_samples(&kept, &lines, data, |axis| without_axis_tables(&full, axis));
    fill_tables(model, &samples);
    Some(DirectResult { lines, samples })
}

/// A given target within this distance (mm) of the one the circles give is kept as the
/// calibration's `target_mm` (the difference goes into the target correction `p6`): it is the
/// user's `$TOOL` for the target. Farther off, the hint was wrong and the circles' target is
/// written instead.
pub const TARGET_HINT_TOLERANCE_MM: f64 = 1.0;

/// The effective target of `model` in the A6 frame: `target_mm` plus the correction `p6`.
pub fn effective_target_a6(model: &Model) -> Vector3<f64> {
    let mut p = model.target_a6();
    if let Some(g) = axis_lines(model) {
        let effect = &model.effects()[g];
        for (c, j) in target_correction(effect.as_effect()).iter().enumerate() {
            if let Some(j) = j {
                p[c] += effect.values()[*j];
            }
        }
    }
    p
}

/// Makes `p` (A6 frame, mm) the model's effective target: `target_mm` stays when it is within
/// [`TARGET_HINT_TOLERANCE_MM`] of `p`, else becomes `p` rounded to the micrometre; the
/// correction `p6` of the `geometric` effect (when the model has it) takes the rest.
pub fn set_target_a6(model: &mut Model, p: &Vector3<f64>) {
    let to_flange = crate::model::chain::a6_to_flange().transpose();
    let g = axis_lines(model);
    if g.is_none() || (model.target_a6() - p).norm() > TARGET_HINT_TOLERANCE_MM {
        let flange = to_flange * p;
        model.target_mm = if g.is_some() {
            flange.map(|v| (v * 1000.0).round() / 1000.0)
        } else {
            flange
        };
    }
    let Some(g) = g else {
        return;
    };
    let rest = p - model.target_a6();
    let start = model.effect_start(g);
    let mut values = model.values();
    for (c, j) in target_correction(model.effects()[g].as_effect())
        .iter()
        .enumerate()
    {
        if let Some(j) = j {
            values[start + j] = rest[c];
        }
    }
    model.set_values(&values);
}

/// The effect that carries the axis lines' geometry ([`Role::AxisLines`]), if the model has it.
pub fn axis_lines(model: &Model) -> Option<usize> {
    model
        .effects()
        .iter()
        .position(|e| e.role() == Role::AxisLines)
}

/// The parameters of `effect` that add a constant to the target vector, per A6-frame axis.
fn target_correction(effect: &dyn Effect) -> [Option<usize>; 3] {
    [0, 1, 2].map(|coord| effect.constant_in(Slot::Target { coord }))
}

/// The target vector in the A6 frame (mm) from an A5 and an A6 indexing test measured in one
/// file at the same A1..A4 (averaged over such pairs); `None` when the data hold none.
///
/// All from the measured circles, so neither a starting target nor the tracker frame enters:
/// the A6 axis `x6` is the A6 circle's normal times A6's sense, the A5 axis (the A6 frame's
/// `y` at A6 = 0) the A5 circle's normal times A5's sense. The target's offset from the A6 axis
/// is each A6 point's position about the circle's centre, turned back by its command angle;
/// its position along the axis is the A6 centre's distance from the wrist point (where the A6
/// axis comes closest to the A5 axis) minus `l5x`. What the geometric errors of the last
/// links add (tens of micrometres) is left to the fits that follow.
pub fn target_from_circles(
    robot: &crate::kinematics::RobotDescription,
    tests: &[IndexingTest],
    lines: &[AxisLine],
) -> Option<Vector3<f64>> {
    let same_arm = |a: &IndexingTest, b: &IndexingTest| {
        a.group == b.group && (0..4).all(|k| (a.reference_deg[k] - b.reference_deg[k]).abs() < 1e-6)
    };
    let mut sum = Vector3::zeros();
    let mut count = 0.0;
    for (t6, l6) in tests.iter().zip(lines).filter(|(t, _)| t.axis == 6) {
        for (_, l5) in tests
            .iter()
            .zip(lines)
            .filter(|(t, _)| t.axis == 5 && same_arm(t, t6))
        {
            let x6 = l6.circle.normal.into_inner() * robot.senses[5];
            let a5 = l5.circle.normal.into_inner() * robot.senses[4];
            let y0 = a5 - x6 * x6.dot(&a5);
            if y0.norm() < 0.5 {
                continue; // the axes are far from perpendicular: not this robot's wrist
            }
            let y0 = y0.normalize();
            let z0 = x6.cross(&y0);
            // Offset from the A6 axis: each point turned back by its model angle θ6.
            let (mut py, mut pz, mut n) = (0.0, 0.0, 0.0);
            for (_, command, m) in &l6.points {
                let d = m - l6.circle.centre;
                let (u, v) = (d.dot(&y0), d.dot(&z0));
                let theta =
                    robot.senses[5] * command.to_radians() + robot.offsets_deg[5].to_radians();
                let (sin, cos) = theta.sin_cos();
                py += cos * u + sin * v;
                pz += -sin * u + cos * v;
                n += 1.0;
            }
            if n == 0.0 {
                continue;
            }
            // Along the axis: the wrist point is where the A6 line comes closest to the A5 line.
            let w0 = l6.circle.centre - l5.circle.centre;
            let b = x6.dot(&a5);
            let denominator = 1.0 - b * b;
            if denominator < 1e-6 {
                continue;
            }
            let s = (b * a5.dot(&w0) - x6.dot(&w0)) / denominator;
            let px = -s - robot.links.l5x;
            sum += Vector3::new(px, py / n, pz / n);
            count += 1.0;
        }
    }
    (count > 0.0).then(|| sum / count)
}

/// The angular deviation of every measured point of every test, against the positions the
/// model `reference(axis)` predicts.
fn deviation_samples(
    tests: &[IndexingTest],
    lines: &[AxisLine],
    data: &[Stop],
    reference: impl Fn(u8) -> Model,
) -> Vec<DeviationSample> {
    let mut samples = Vec::new();
    for (t, line) in tests.iter().zip(lines) {
        let model = reference(t.axis);
        for &i in &t.rows {
            let (Some(m), state) = (data[i].measured_mm, data[i].state) else {
                continue;
            };
            let predicted = model.target_position(&state);
            samples.push(DeviationSample {
                test: t.test.clone(),
                axis: t.axis,
                reference_deg: t.reference_deg,
                command_deg: state.axes_deg[t.axis as usize - 1],
                direction: engaged_direction(&state, t.axis),
                deviation_deg: line.circle.angle_of(&m, &predicted).to_degrees(),
            });
        }
    }
    samples
}

/// `model` without the tables that write axis `axis`'s angle (its own-angle and direction
/// tables and the cross tables onto it).
fn without_axis_tables(model: &Model, axis: u8) -> Model {
    let mut m = Model::new(model.robot, model.payload, model.target_mm);
    for e in model.effects() {
        if e.role().angle_of() != Some(axis) {
            m.push(e.clone_model_effect());
        }
    }
    m
}

/// Linear interpolation in sorted `(x, y)` samples (duplicates averaged); `None` outside.
fn interpolate(samples: &[(f64, f64)], x: f64) -> Option<f64> {
    let i = samples.partition_point(|s| s.0 < x);
    if i < samples.len() && samples[i].0 == x {
        let same: Vec<f64> = samples[i..]
            .iter()
            .take_while(|s| s.0 == x)
            .map(|s| s.1)
            .collect();
        return Some(same.iter().sum::<f64>() / same.len() as f64);
    }
    if i == 0 || i == samples.len() {
        return None;
    }
    let (a, b) = (samples[i - 1], samples[i]);
    Some(a.1 + (b.1 - a.1) * (x - a.0) / (b.0 - a.0))
}

/// One test's deviation curve per direction.
struct Curves {
    other: BTreeMap<u8, f64>,
    plus: Vec<(f64, f64)>,
    minus: Vec<(f64, f64)>,
}

impl Curves {
    /// (mean of the branches, and when both exist the positive branch minus the negative
    /// one) at `x`.
    fn at(&self, x: f64) -> Option<(f64, Option<f64>)> {
        match (interpolate(&self.plus, x), interpolate(&self.minus, x)) {
            (Some(p), Some(m)) => Some(((p + m) / 2.0, Some(p - m))),
            (Some(v), None) | (None, Some(v)) => Some((v, None)),
            (None, None) => None,
        }
    }
}

/// A command travel after which a robot's gear play is engaged: plays are hundredths of a
/// degree; the paper's indexing steps are 1°.
const ENGAGED_TRAVEL_DEG: f64 = 0.5;

/// The direction of axis `axis` at `state` when its gear is surely engaged on that flank (the
/// two branches of the paper's model); `Unknown` inside a reversal shorter than any play
/// could be (a reversal test's short moves), which the tables' starting values leave out.
fn engaged_direction(state: &AxisState, axis: u8) -> Direction {
    let n = axis as usize - 1;
    let travel = state.history[n].travel_since_reversal(state.axes_deg[n]);
    if travel >= ENGAGED_TRAVEL_DEG {
        state.directions()[n]
    } else {
        Direction::Unknown
    }
}

/// Step 3: the tables from the deviation samples.
fn fill_tables(model: &mut Model, samples: &[DeviationSample]) {
    let mut by_test: BTreeMap<(u8, &str), Curves> = BTreeMap::new();
    for s in samples {
        let c = by_test
            .entry((s.axis, s.test.as_str()))
            .or_insert_with(|| Curves {
                other: (1..=6u8)
                    .map(|k| (k, s.reference_deg[k as usize - 1]))
                    .collect(),
                plus: Vec::new(),
                minus: Vec::new(),
            });
        match s.direction {
            Direction::Positive => c.plus.push((s.command_deg, s.deviation_deg)),
            Direction::Negative => c.minus.push((s.command_deg, s.deviation_deg)),
            Direction::Unknown => {}
        }
    }
    for c in by_test.values_mut() {
        c.plus.sort_by(|a, b| a.0.total_cmp(&b.0));
        c.minus.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    let mean = |v: &[f64]| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let mut values = model.values();
    for (e, effect) in model.effects().iter().enumerate() {
        let start = model.effect_start(e);
        let record = effect.record();
        let Some(table) = record.table else {
            continue;
        };
        let curves_of = |n: u8| -> Vec<&Curves> {
            by_test
                .iter()
                .filter(|(k, _)| k.0 == n)
                .map(|(_, c)| c)
                .collect()
        };
        // An own-angle table takes the mean deviation of every test of the axis at each grid
        // angle (`None`), a direction table the difference between the directions (`Some(k)`:
        // positive minus negative is `2k · value`).
        let one_d = match effect.role() {
            Role::OwnAngle { axis } => Some((axis, None)),
            Role::DirectionDifference {
                axis,
                per_direction,
            } => Some((axis, Some(per_direction))),
            _ => None,
        };
        if let Some((n, pick)) = one_d {
            let curves = curves_of(n);
            for (j, &g) in table.grid_deg.iter().enumerate() {
                let v: Vec<f64> = curves
                    .iter()
                    .filter_map(|c| {
                        let (mean, difference) = c.at(g)?;
                        match pick {
                            None => Some(mean),
                            Some(k) => difference.map(|d| d / (2.0 * k)),
                        }
                    })
                    .collect();
                if let Some(m) = mean(&v) {
                    values[start + j] = m;
                }
            }
        } else if let Role::CrossAngle { from: m, to: n } = effect.role() {
            let Some(columns) = &table.other_grid_deg else {
                continue;
            };
            let curves = curves_of(n);
            for (i, &g) in table.grid_deg.iter().enumerate() {
                let all: Vec<f64> = curves.iter().filter_map(|c| c.at(g).map(|a| a.0)).collect();
                let Some(pooled) = mean(&all) else {
                    continue;
                };
                for (j, &col) in columns.iter().enumerate() {
                    let at_col: Vec<f64> = curves
                        .iter()
                        .filter(|c| (c.other[&m] - col).abs() < 1e-6)
                        .filter_map(|c| c.at(g).map(|a| a.0))
                        .collect();
                    if let Some(v) = mean(&at_col) {
                        values[start + i * columns.len() + j] = v - pooled;
                    }
                }
            }
        }
    }
    model.set_values(&values);
}
