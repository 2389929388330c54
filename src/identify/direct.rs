//! The paper's direct method (section 2.3 and its reference \[8\]), the starting point of the
//! global refinement:
//! 1. every *indexing test* in the data — a test label whose measured rows move exactly one
//!    axis over at least five angles while the others stand still — gets its best-fit circle
//!    ([`super::circle`]): the centre and normal are that axis's average line at the test's
//!    reference pose;
//! 2. the geometric parameters (and the target vector) are fitted so that the model's circles
//!    match the measured ones (Gauss–Newton with a numerical Jacobian on centre, normal and
//!    radius: 7 numbers per test against 21 parameters);
//! 3. the angular position of each measured point on its circle, against where the geometric
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
use crate::measure::Stop;
use crate::model::{AxisState, Direction, Model};

/// Fewest measured angles for a test to count as an indexing test.
const MIN_ANGLES: usize = 5;

/// One indexing test found in the data.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexingTest {
    pub test: String,
    /// The indexed axis (1..=6).
    pub axis: u8,
    /// Angles of all axes during the test (the indexed one at its first measured value).
    pub reference_deg: [f64; 6],
    /// Indices into the data of the test's measured rows.
    pub rows: Vec<usize>,
}

/// The measured average line of an axis in one test.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisLine {
    pub test: String,
    pub axis: u8,
    pub reference_deg: [f64; 6],
    /// Normal oriented along a positive KUKA rotation of the axis.
    pub circle: Circle3,
}

/// One measured angular positioning deviation.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviationSample {
    pub test: String,
    pub axis: u8,
    pub reference_deg: [f64; 6],
    pub command_deg: f64,
    pub direction: Direction,
    /// Actual minus command angle, degrees, KUKA sign.
    pub deviation_deg: f64,
}

/// What the direct method found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DirectResult {
    pub lines: Vec<AxisLine>,
    pub samples: Vec<DeviationSample>,
}

/// The indexing tests of `data` (see the module documentation).
pub fn indexing_tests(data: &[Stop]) -> Vec<IndexingTest> {
    let mut groups: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, s) in data.iter().enumerate() {
        if s.measured_mm.is_some() {
            groups.entry(s.test.as_str()).or_default().push(i);
        }
    }
    let mut tests = Vec::new();
    for (test, rows) in groups {
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
                });
            }
        }
    }
    tests
}

/// The model without its angular tables: only the `geometric` effect (when present).
fn geometric_only(model: &Model) -> Option<(Model, usize)> {
    let g = model
        .effects()
        .iter()
        .position(|e| e.name() == "geometric")?;
    let mut m = Model::new(model.robot, model.payload, model.target_mm);
    m.push(model.effects()[g].clone());
    Some((m, model.effect_start(g)))
}

/// The circle a model predicts for a test: fitted to its predictions at the test's states.
fn model_circle(model: &Model, data: &[Stop], test: &IndexingTest) -> Option<Circle3> {
    let points: Vec<Vector3<f64>> = test
        .rows
        .iter()
        .map(|&i| model.target_position(&data[i].state))
        .collect();
    fit_circle(&points)
}

/// The world direction of a positive KUKA rotation of the test's axis, per the model.
fn joint_axis(model: &Model, test: &IndexingTest) -> Vector3<f64> {
    let (frames, _) = model.frames(&AxisState::new(test.reference_deg));
    frames.joint_axis(test.axis as usize)
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
    Some(geo)
}

/// Runs the direct method on `data` (positions in the base frame) and writes its estimates
/// into the model's `geometric`, `map`, `backlash` and `crosstalk` effects. `None` when the
/// data hold no indexing test.
pub fn direct_method(model: &mut Model, data: &[Stop]) -> Option<DirectResult> {
    let tests = indexing_tests(data);
    let mut lines = Vec::new();
    let mut kept = Vec::new();
    for t in &tests {
        let points: Vec<Vector3<f64>> =
            t.rows.iter().filter_map(|&i| data[i].measured_mm).collect();
        if let Some(c) = fit_circle(&points) {
            lines.push(AxisLine {
                test: t.test.clone(),
                axis: t.axis,
                reference_deg: t.reference_deg,
                circle: oriented(c, &joint_axis(model, t)),
            });
            kept.push(t.clone());
        }
    }
    if kept.is_empty() {
        return None;
    }
    let geometry = fit_geometry(model, data, &kept, &lines);
    if let (Some(geo), Some(g)) = (
        &geometry,
        model.effects().iter().position(|e| e.name() == "geometric"),
    ) {
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

/// `model` without the tables that write axis `axis`'s angle (its map, backlash and
/// crosstalk onto it).
fn without_axis_tables(model: &Model, axis: u8) -> Model {
    let own = [format!("map:A{axis}"), format!("backlash:A{axis}")];
    let onto = format!("->A{axis}");
    let mut m = Model::new(model.robot, model.payload, model.target_mm);
    for e in model.effects() {
        let name = e.name();
        if !own.contains(&name) && !name.ends_with(&onto) {
            m.push(e.clone());
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
    /// (mean of the branches, and when both exist their bidirectional difference: the
    /// negative branch minus the positive one, a gear play's width) at `x`.
    fn at(&self, x: f64) -> Option<(f64, Option<f64>)> {
        match (interpolate(&self.plus, x), interpolate(&self.minus, x)) {
            (Some(p), Some(m)) => Some(((p + m) / 2.0, Some(m - p))),
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
        let name = effect.name();
        let record = effect.record();
        let Some(table) = record.table else {
            continue;
        };
        let parse_axis = |s: &str| s.parse::<u8>().ok();
        let curves_of = |n: u8| -> Vec<&Curves> {
            by_test
                .iter()
                .filter(|(k, _)| k.0 == n)
                .map(|(_, c)| c)
                .collect()
        };
        // The mean deviation (map) or the difference between the directions (the backlash's
        // play width) of every test of the axis, at each grid angle.
        let one_d = [
            (
                "map:A",
                (|a| Some(a.0)) as fn((f64, Option<f64>)) -> Option<f64>,
            ),
            ("backlash:A", |a| a.1),
        ];
        if let Some((n, pick)) = one_d.iter().find_map(|&(prefix, pick)| {
            Some((name.strip_prefix(prefix).and_then(parse_axis)?, pick))
        }) {
            let curves = curves_of(n);
            for (j, &g) in table.grid_deg.iter().enumerate() {
                let v: Vec<f64> = curves
                    .iter()
                    .filter_map(|c| c.at(g).and_then(pick))
                    .collect();
                if let Some(m) = mean(&v) {
                    values[start + j] = m;
                }
            }
        } else if let Some((m, n)) = name
            .strip_prefix("crosstalk:A")
            .and_then(|r| r.split_once("->A"))
            .and_then(|(a, b)| Some((parse_axis(a)?, parse_axis(b)?)))
        {
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
