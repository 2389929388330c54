//! Drivers learned from the residual: what the residual follows when no effect of the table
//! explains it. Every point's 3-D residual is fitted, on top of the current model, against
//! generic drivers (each axis angle, the flange's horizontal reach and height, the tool's
//! orientation to gravity, the gravity torques of A2 and A3, time, each axis's rotation
//! direction — alone, and in pairs) through every way a smooth function can act on the chain
//! (an axis angle deviation, a rotation about an axis centre, a displacement of an axis or of
//! the target): one linear least-squares problem per (drivers, action), in the chain
//! Jacobian of the current model, with the functions of `model::effects::learned` (Fourier
//! terms of angles, low powers of the rest, products of first-order terms for pairs) and a
//! small ridge. Each is scored by the same blocked cross-validation as the table's effects
//! (normal equations per fold, so a fold's fit is the total minus that fold), on held-out
//! stretches and on whole tests — a smooth function of generic drivers, unlike a table, must
//! predict poses no test it learnt from visited — and ranked by the lower of the two; the best
//! stable one with the fewest parameters among those within a tenth of the best is named, with its
//! shape in words, and checked like a candidate (re-fitted through the real model, on whole
//! tests it did not see, and on the latest data when it depends on time). It is then an effect
//! the user can add: `learned:<action>(<drivers>)`.

use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::blocks::Plan;
use super::crossval::Score;
use crate::compare::Row;
use crate::model::chain::slot_of_index;
use crate::model::effects::learned::{Action, Driver, DriverValues, Spec, MAX_TERMS};
use crate::model::{AxisState, Model, Role, Slot, N_SLOTS};

/// Ridge on the column-scaled normal equations (unit diagonal): a numerical guard only, so
/// that the screening scores what `identify` (no ridge) will fit.
const RIDGE: f64 = 1e-9;
/// Singles whose best actions are combined in pairs.
const PAIRED_SINGLES: usize = 5;
/// Actions of each single tried in its pairs.
const PAIRED_ACTIONS: usize = 3;
/// A definition within this share of the best one's `explained` competes on parsimony.
const NEAR_BEST: f64 = 0.9;
/// Of two drivers, one alone that reaches this share of the pair's gain carries it.
const CARRIES: f64 = 0.8;
/// Another driver that alone explains this share of the chosen definition's gain is named as
/// indistinguishable from it on the data …
const ALIKE: f64 = 0.97;
/// … the strongest few of them.
const MAX_ALIKE: usize = 3;
/// Most points of the plot.
const CURVE_POINTS: usize = 900;

/// One screened definition.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Screened {
    /// The definition, as `learned:ACTION(DRIVERS)`.
    pub effect: String,
    /// On held-out stretches of every test.
    pub explained: f64,
    /// On whole tests held out.
    pub explained_tests: f64,
    /// Its values.
    pub parameters: usize,
    /// Positive in all folds but at most one, no fold carrying most of the gain.
    pub stable: bool,
}

/// For the report's plot: the residual along the learned correction against the main driver.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Curve {
    /// Axis label of the driver (`horizontal reach of the flange (mm)`).
    pub driver: String,
    /// (driver value, residual along the learned correction µm, learned correction µm).
    pub points: Vec<(f64, f64, f64)>,
}

/// What the residual follows (`diagnose --json` key `learned`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LearnedDrivers {
    /// The effect that adds it, e.g. `learned:rotation@arm(reach)`.
    pub effect: String,
    /// The `identify` option that adds it.
    pub add: String,
    /// The drivers that carry it (`reach`, `A5`, `dir:A4`, `time`).
    pub drivers: Vec<String>,
    /// Other drivers that explain it about as well on these data (alone, through some
    /// action): either may be the physical cause.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub indistinguishable_from: Vec<String>,
    /// Its shape in words.
    pub shape: String,
    /// On held-out stretches of every test, fitted together with the model.
    pub explained: f64,
    /// RMS 3-D residual of the held-out predictions with it, µm.
    pub rms_after_um: f64,
    /// t statistic of its gain over the held-out stretches.
    pub t_statistic: f64,
    /// Parameters it adds to the model.
    pub parameters: usize,
    /// The gain holds in every fold but at most one.
    pub stable: bool,
    /// It passes what a finding must pass (see `diagnose`).
    pub significant: bool,
    /// The further checks it went through (whole tests held out, the latest data).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub checks: Vec<Score>,
    /// Why it is not a finding although it explains part of the residual.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vetoed: Option<String>,
    /// The best definitions of the screening, best first.
    pub screened: Vec<Screened>,
    /// The residual along the learned correction against its main driver (the report's plot).
    #[serde(skip)]
    pub curve: Curve,
}

/// The drivers that vary in the data (a constant one teaches nothing).
fn varying_drivers(points: &[Point], gravity: bool, window: Option<(f64, f64)>) -> Vec<Driver> {
    let range = |f: &dyn Fn(&DriverValues) -> f64| {
        let (lo, hi) = points
            .iter()
            .map(|p| f(&p.values))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        hi - lo
    };
    let mut out = Vec::new();
    for n in 1..=6u8 {
        if range(&|v| v.angles_deg[n as usize - 1]) > 1.0 {
            out.push(Driver::Angle(n));
        }
    }
    if range(&|v| v.reach_mm) > 1.0 {
        out.push(Driver::Reach);
    }
    if range(&|v| v.height_mm) > 1.0 {
        out.push(Driver::Height);
    }
    if (0..3).any(|c| range(&|v| v.gravity[c]) > 1e-3) {
        out.push(Driver::Gravity);
    }
    if gravity {
        for n in [2u8, 3] {
            if range(&|v| v.torques_knm[n as usize - 1]) > 1e-3 {
                out.push(Driver::Torque(n));
            }
        }
    }
    if let Some((from_h, to_h)) = window {
        out.push(Driver::Time { from_h, to_h });
    }
    for n in 1..=6u8 {
        let signs = |s: f64| {
            points
                .iter()
                .any(|p| p.values.reversal[n as usize - 1] == s)
        };
        if signs(1.0) && signs(-1.0) {
            out.push(Driver::Direction(n));
        }
    }
    out
}

/// The clock's range in hours, rounded out to 0.01 h; `None` when it spans under a minute.
pub fn time_window(rows: &[&Row]) -> Option<(f64, f64)> {
    let (lo, hi) = rows
        .iter()
        .map(|r| r.state.time_s / 3600.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
            (lo.min(t), hi.max(t))
        });
    (hi - lo > 1.0 / 60.0).then(|| ((lo * 100.0).floor() / 100.0, (hi * 100.0).ceil() / 100.0))
}

/// The screening data of one point.
struct Point {
    residual: Vector3<f64>,
    jacobian: [Vector3<f64>; N_SLOTS],
    values: DriverValues,
    /// The model's columns ([`model_columns`]), Jacobi-scaled.
    model: Vec<Vector3<f64>>,
}

/// Degree of the polynomials that stand for a table of the model (its smooth part).
const TABLE_DEGREE: usize = 4;

/// Legendre polynomials P0..=Pd at u.
fn legendre(u: f64, d: usize) -> Vec<f64> {
    let mut p = vec![1.0, u];
    for k in 1..d {
        let next = ((2 * k + 1) as f64 * u * p[k] - k as f64 * p[k - 1]) / (k + 1) as f64;
        p.push(next);
    }
    p.truncate(d + 1);
    p
}

/// The range of a table's grid, and the angle mapped onto −1..1 over it (held at the ends).
fn unit_in(grid: &[f64], x: f64) -> f64 {
    match (grid.first(), grid.last()) {
        (Some(&lo), Some(&hi)) if hi > lo => (2.0 * (x - lo) / (hi - lo) - 1.0).clamp(-1.0, 1.0),
        _ => 0.0,
    }
}

/// What the current model can still take up when it is re-identified together with a new
/// effect, at one point: the exact columns of its scalar effects (the axis geometry,
/// compliance, tilt, drift, learned effects) and, for each table, the smooth part of what it
/// can absorb — polynomials of degree [`TABLE_DEGREE`] over the table's range through the
/// axis's angle slot (times the rotation direction for backlash, a product of both axes'
/// polynomials for crosstalk). A learned function is scored on what it adds beyond these: a
/// shape the model had half absorbed is credited in full, a shape a table already has is not.
fn model_columns(
    model: &Model,
    state: &AxisState,
    jacobian: &[Vector3<f64>; N_SLOTS],
) -> Vec<Vector3<f64>> {
    let (_, exact) = model.target_jacobian(state);
    let mut out = Vec::new();
    for (i, e) in model.effects().iter().enumerate() {
        let (start, end) = (model.effect_start(i), model.effect_start(i + 1));
        let table = e.record().table;
        let angle = |n: u8| jacobian[Slot::Angle { axis: n }.index()];
        match (e.role(), table) {
            (Role::OwnAngle { axis: n }, Some(t))
            | (Role::DirectionDifference { axis: n, .. }, Some(t)) => {
                let sign = if let Role::DirectionDifference { .. } = e.role() {
                    state.directions()[n as usize - 1].sign()
                } else {
                    1.0
                };
                let u = unit_in(&t.grid_deg, state.axes_deg[n as usize - 1]);
                for p in legendre(u, TABLE_DEGREE) {
                    out.push(angle(n) * (sign * p));
                }
            }
            (Role::CrossAngle { from, to }, Some(t)) => {
                let own = legendre(unit_in(&t.grid_deg, state.axes_deg[to as usize - 1]), 3);
                let other_grid = t.other_grid_deg.unwrap_or_default();
                let other = legendre(unit_in(&other_grid, state.axes_deg[from as usize - 1]), 2);
                for p in &own {
                    for q in &other {
                        out.push(angle(to) * (p * q));
                    }
                }
            }
            _ => {
                for k in start..end {
                    out.push(
                        exact
                            .iter()
                            .find(|(j, _)| *j == k)
                            .map_or(Vector3::zeros(), |(_, v)| *v),
                    );
                }
            }
        }
    }
    out
}

/// Per cell (a stretches fold × a tests fold) the model's own normal equations.
struct ModelNormal {
    m: usize,
    a: Vec<DMatrix<f64>>,
    g: Vec<DVector<f64>>,
}

impl ModelNormal {
    fn new(blocks: &Blocks) -> ModelNormal {
        let m = blocks.model.first().map_or(0, |b| b.ncols());
        let (mut a, mut g) = (Vec::new(), Vec::new());
        for (mm, r) in blocks.model.iter().zip(&blocks.residual) {
            let mt = mm.transpose();
            a.push(&mt * mm);
            g.push(mt * r);
        }
        ModelNormal { m, a, g }
    }
}

/// The points of each cell of a fold plan, and the model's columns (one row per coordinate of
/// each point) and the residuals there as dense blocks: the normal equations of the model and
/// of every definition scored on the same cells are then matrix products, and the blocks are
/// built once for all of them.
struct Blocks {
    members: Vec<Vec<usize>>,
    model: Vec<DMatrix<f64>>,
    residual: Vec<DVector<f64>>,
}

impl Blocks {
    fn new(points: &[Point], cell_of: &[usize], cells: usize) -> Blocks {
        let m = points.first().map_or(0, |p| p.model.len());
        let mut members = vec![Vec::new(); cells];
        for (i, &c) in cell_of.iter().enumerate() {
            members[c].push(i);
        }
        let (mut model, mut residual) = (Vec::new(), Vec::new());
        for cell in &members {
            let mut mm = DMatrix::zeros(3 * cell.len(), m);
            let mut r = DVector::zeros(3 * cell.len());
            for (row, &i) in cell.iter().enumerate() {
                let pt = &points[i];
                for (j, mj) in pt.model.iter().enumerate() {
                    for d in 0..3 {
                        mm[(3 * row + d, j)] = mj[d];
                    }
                }
                for d in 0..3 {
                    r[3 * row + d] = pt.residual[d];
                }
            }
            model.push(mm);
            residual.push(r);
        }
        Blocks {
            members,
            model,
            residual,
        }
    }
}

/// The model's normal equations over every point, factored: what a definition's columns are
/// partialled against.
struct ModelFactor {
    chol: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
}

/// Ridge of the model's scaled normal equations (its columns overlap: a table's constant and
/// the zero offset, …).
const MODEL_RIDGE: f64 = 1e-6;

impl ModelFactor {
    fn new(normal: &ModelNormal) -> ModelFactor {
        let m = normal.m;
        let mut n = DMatrix::zeros(m, m);
        for a in &normal.a {
            n += a;
        }
        let scale = (0..m).map(|j| n[(j, j)]).fold(0.0, f64::max).max(1e-300);
        for j in 0..m {
            n[(j, j)] += MODEL_RIDGE * scale;
        }
        ModelFactor { chol: n.cholesky() }
    }
}

/// Normal equations of one definition (or of an effect) per cell, with its coupling to the
/// model's columns.
struct Normal {
    /// Per output, the (slot index, slot units per stored unit) it writes.
    outputs: Vec<Vec<(usize, f64)>>,
    terms: usize,
    phi: Vec<[f64; MAX_TERMS]>,
    /// For an effect of the table: its columns at every point (then `outputs` is empty).
    columns: Vec<Vec<Vector3<f64>>>,
    a: Vec<DMatrix<f64>>,
    g: Vec<DVector<f64>>,
    /// Xᵀ M per cell (p × m).
    c: Vec<DMatrix<f64>>,
    /// Xᵀ per cell, one column per coordinate of its points (in [`Blocks`] order).
    xt: Vec<DMatrix<f64>>,
}

impl Normal {
    fn new(model: &Model, points: &[Point], spec: &Spec, blocks: &Blocks) -> Normal {
        let outputs: Vec<Vec<(usize, f64)>> = spec
            .action
            .outputs(&model.robot)
            .iter()
            .map(|o| o.iter().map(|(s, f)| (s.index(), *f)).collect())
            .collect();
        let phi: Vec<[f64; MAX_TERMS]> = points
            .iter()
            .map(|pt| {
                let mut o = [0.0; MAX_TERMS];
                spec.terms(&pt.values, &mut o);
                o
            })
            .collect();
        let mut n = Normal {
            outputs,
            terms: spec.n_terms(),
            phi,
            columns: Vec::new(),
            a: Vec::new(),
            g: Vec::new(),
            c: Vec::new(),
            xt: Vec::new(),
        };
        n.accumulate(points, blocks);
        n
    }

    /// The normal equations of an effect of the table, from its own Jacobian.
    fn for_effect(
        model: &Model,
        points: &[Point],
        states: &[AxisState],
        effect: &dyn crate::model::Effect,
        blocks: &Blocks,
    ) -> Normal {
        let ctx = model.context();
        let p = effect.values().len();
        let columns = points
            .iter()
            .zip(states)
            .map(|(pt, state)| {
                let mut partials = Vec::new();
                effect.jacobian(state, &ctx, &mut partials);
                let mut cols = vec![Vector3::zeros(); p];
                for q in partials {
                    cols[q.param] += pt.jacobian[q.slot.index()] * q.value;
                }
                cols
            })
            .collect();
        let mut n = Normal {
            outputs: Vec::new(),
            terms: 0,
            phi: Vec::new(),
            columns,
            a: Vec::new(),
            g: Vec::new(),
            c: Vec::new(),
            xt: Vec::new(),
        };
        n.accumulate(points, blocks);
        n
    }

    /// The columns at point `i`.
    fn columns_at(&self, pt: &Point, i: usize) -> Vec<Vector3<f64>> {
        if self.outputs.is_empty() {
            return self.columns[i].clone();
        }
        let nt = self.terms;
        let mut out = Vec::with_capacity(self.size());
        for o in &self.outputs {
            let j = column(pt, o);
            out.extend(self.phi[i][..nt].iter().map(|f| j * *f));
        }
        out
    }

    fn accumulate(&mut self, points: &[Point], blocks: &Blocks) {
        let p = self.size();
        let (mut a, mut g, mut c, mut xts) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for ((members, m), r) in blocks
            .members
            .iter()
            .zip(&blocks.model)
            .zip(&blocks.residual)
        {
            // Xᵀ, one column per coordinate of every point of the cell.
            let mut xt = DMatrix::zeros(p, 3 * members.len());
            for (row, &i) in members.iter().enumerate() {
                for (q, x) in self.columns_at(&points[i], i).iter().enumerate() {
                    for d in 0..3 {
                        xt[(q, 3 * row + d)] = x[d];
                    }
                }
            }
            a.push(&xt * xt.transpose());
            g.push(&xt * r);
            c.push(&xt * m);
            xts.push(xt);
        }
        self.a = a;
        self.g = g;
        self.c = c;
        self.xt = xts;
    }

    fn size(&self) -> usize {
        if self.outputs.is_empty() {
            self.columns.first().map_or(0, Vec::len)
        } else {
            self.outputs.len() * self.terms
        }
    }

    /// The definition's columns with what the model spans partialled out (over every point):
    /// per cell the normal equations of X̃ = X − M·B, and B.
    fn partialled(
        &self,
        model: &ModelNormal,
        factor: &ModelFactor,
    ) -> (Vec<DMatrix<f64>>, Vec<DVector<f64>>, DMatrix<f64>) {
        let p = self.size();
        let m = model.m;
        let b = match &factor.chol {
            Some(ch) if m > 0 => {
                let mut c = DMatrix::zeros(p, m);
                for cell in &self.c {
                    c += cell;
                }
                ch.solve(&c.transpose())
            }
            _ => DMatrix::zeros(m, p),
        };
        let mut a = Vec::with_capacity(self.a.len());
        let mut g = Vec::with_capacity(self.a.len());
        for cell in 0..self.a.len() {
            let cb = &self.c[cell] * &b;
            a.push(&self.a[cell] - &cb - cb.transpose() + b.transpose() * &model.a[cell] * &b);
            g.push(&self.g[cell] - b.transpose() * &model.g[cell]);
        }
        (a, g, b)
    }

    /// Coefficients fitted on the cells `keep` accepts, from (partialled) normal equations.
    fn solve_cells(
        a_cells: &[DMatrix<f64>],
        g_cells: &[DVector<f64>],
        keep: impl Fn(usize) -> bool,
    ) -> Vec<f64> {
        let p = g_cells.first().map_or(0, |g| g.len());
        let mut a = DMatrix::zeros(p, p);
        let mut g = DVector::zeros(p);
        for (cell, (ac, gc)) in a_cells.iter().zip(g_cells).enumerate() {
            if keep(cell) {
                a += ac;
                g += gc;
            }
        }
        let largest = (0..p).map(|j| a[(j, j)]).fold(0.0, f64::max);
        let d: Vec<f64> = (0..p)
            .map(|j| {
                let v = a[(j, j)];
                if v > 1e-9 * largest && v > 0.0 {
                    1.0 / v.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        let ms = DMatrix::from_fn(p, p, |i, j| {
            a[(i, j)] * d[i] * d[j] + if i == j { RIDGE } else { 0.0 }
        });
        let r = DVector::from_fn(p, |i, _| g[i] * d[i]);
        match ms.cholesky() {
            Some(ch) => {
                let z = ch.solve(&r);
                (0..p).map(|j| z[j] * d[j]).collect()
            }
            None => vec![0.0; p],
        }
    }

    /// The output values at point `i` with coefficients `w` (stored units).
    fn values(&self, i: usize, w: &[f64]) -> Vec<f64> {
        let nt = self.terms;
        (0..self.outputs.len())
            .map(|c| {
                w[c * nt..(c + 1) * nt]
                    .iter()
                    .zip(&self.phi[i][..nt])
                    .map(|(a, b)| a * b)
                    .sum()
            })
            .collect()
    }

    /// The correction at point `i` with coefficients `w` (mm).
    fn predict(&self, pt: &Point, i: usize, w: &[f64]) -> Vector3<f64> {
        if self.outputs.is_empty() {
            return self.columns[i].iter().zip(w).map(|(c, v)| c * *v).sum();
        }
        self.values(i, w)
            .iter()
            .zip(&self.outputs)
            .map(|(v, o)| column(pt, o) * *v)
            .sum()
    }
}

/// The model's columns at a point combined with coefficients `a`.
fn model_part(pt: &Point, a: &DVector<f64>) -> Vector3<f64> {
    pt.model.iter().zip(a.iter()).map(|(c, v)| c * *v).sum()
}

/// The partialled correction X̃·w = X·w − M·(B·w) at point `i`.
/// `bw` is B·w ([`b_times`]), the same for every point.
fn partial_predict(
    normal: &Normal,
    bw: &DVector<f64>,
    pt: &Point,
    i: usize,
    w: &[f64],
) -> Vector3<f64> {
    normal.predict(pt, i, w) - model_part(pt, bw)
}

/// B·w of [`partial_predict`].
fn b_times(b: &DMatrix<f64>, w: &[f64]) -> DVector<f64> {
    b * DVector::from_column_slice(w)
}

/// d(target)/d(output) at a point: the output's slots through the chain Jacobian.
fn column(pt: &Point, output: &[(usize, f64)]) -> Vector3<f64> {
    output.iter().map(|&(s, f)| pt.jacobian[s] * f).sum()
}

/// The fold that holds each point out (every point is held out once in these plans).
fn fold_of(plan: &Plan, n: usize) -> Vec<usize> {
    let mut out = vec![0; n];
    for (f, held) in plan.held.iter().enumerate() {
        for &i in held {
            out[i] = f;
        }
    }
    out
}

/// One screened definition: its scores on held-out stretches and on whole tests.
#[derive(Clone, Debug)]
struct Screening {
    spec: Spec,
    within: Score,
    tests: Score,
    parameters: usize,
}

impl Screening {
    /// What it is ranked by: a smooth function of generic drivers must predict both the
    /// stretches of the tests it learnt from and whole tests it did not see.
    fn rank(&self) -> f64 {
        self.within.explained.min(self.tests.explained)
    }
    fn usable(&self) -> bool {
        self.within.stable() && self.rank() > 0.0
    }
}

/// The two plans, every point's cell and the model's normal equations.
struct Folds<'a> {
    within: &'a Plan,
    tests: &'a Plan,
    blocks: Blocks,
    model: ModelNormal,
    factor: ModelFactor,
}

impl<'a> Folds<'a> {
    fn new(points: &[Point], within: &'a Plan, tests: &'a Plan) -> Folds<'a> {
        let (w_of, t_of) = (fold_of(within, points.len()), fold_of(tests, points.len()));
        let kt = tests.folds();
        let cells = within.folds() * kt;
        let cell_of: Vec<usize> = (0..points.len()).map(|i| w_of[i] * kt + t_of[i]).collect();
        let blocks = Blocks::new(points, &cell_of, cells);
        let model = ModelNormal::new(&blocks);
        let factor = ModelFactor::new(&model);
        Folds {
            within,
            tests,
            blocks,
            model,
            factor,
        }
    }
}

/// Held-out scores of `spec` on both plans (linear, in the current Jacobian), with what the
/// model can take up partialled out of its columns: what it adds when the model is
/// re-identified with it, predicted on blocks the fit did not see.
fn screen(model: &Model, points: &[Point], spec: &Spec, folds: &Folds) -> Screening {
    let normal = Normal::new(model, points, spec, &folds.blocks);
    let (a_cells, g_cells, b) = normal.partialled(&folds.model, &folds.factor);
    let kt = folds.tests.folds();
    let before: Vec<Vector3<f64>> = points.iter().map(|p| p.residual).collect();
    // Each fold holds out whole cells: the partialled prediction X̃·w = X·w − M·(B·w) of a
    // cell's points is two matrix-vector products of its blocks.
    let blocks = &folds.blocks;
    let score = |plan: &Plan, fold_of_cell: &dyn Fn(usize) -> usize| {
        let mut after = vec![None; points.len()];
        for f in 0..plan.folds() {
            let w = Normal::solve_cells(&a_cells, &g_cells, |cell| fold_of_cell(cell) != f);
            let bw = b_times(&b, &w);
            let wv = DVector::from_column_slice(&w);
            for cell in (0..blocks.members.len()).filter(|&c| fold_of_cell(c) == f) {
                let predicted = normal.xt[cell].tr_mul(&wv) - &blocks.model[cell] * &bw;
                for (row, &i) in blocks.members[cell].iter().enumerate() {
                    let p = Vector3::new(
                        predicted[3 * row],
                        predicted[3 * row + 1],
                        predicted[3 * row + 2],
                    );
                    after[i] = Some(points[i].residual - p);
                }
            }
        }
        Score::new(plan, &before, &after)
    };
    Screening {
        spec: spec.clone(),
        within: score(folds.within, &|cell| cell / kt),
        tests: score(folds.tests, &|cell| cell % kt),
        parameters: normal.size(),
    }
}

/// Screens every definition and returns them best first.
fn screen_all(
    model: &Model,
    points: &[Point],
    drivers: &[Driver],
    within: &Plan,
    tests: &Plan,
) -> Vec<Screening> {
    let folds = Folds::new(points, within, tests);
    let run = |specs: Vec<Spec>| -> Vec<Screening> {
        specs
            .into_par_iter()
            .map(|spec| screen(model, points, &spec, &folds))
            .collect()
    };
    let plain: Vec<Driver> = drivers
        .iter()
        .copied()
        .filter(|d| !matches!(d, Driver::Direction(_)))
        .collect();
    let singles: Vec<Spec> = drivers
        .iter()
        .flat_map(|&d| {
            Action::all().into_iter().map(move |action| Spec {
                action,
                drivers: vec![d],
            })
        })
        .collect();
    let mut results = run(singles);
    // Pairs: each of the strongest plain drivers with every other plain driver through its
    // best actions (a driver may matter only through another, as the reach through the
    // direction A1 points the arm in), and every rotation direction with every plain driver
    // on its own axis's angle (a drag or play that depends on where the other axes stand).
    let mut best_of: Vec<(Driver, f64, Vec<Action>)> = plain
        .iter()
        .map(|&d| {
            let mut mine: Vec<&Screening> =
                results.iter().filter(|r| r.spec.drivers[0] == d).collect();
            mine.sort_by(|a, b| b.rank().total_cmp(&a.rank()));
            let top = mine.first().map_or(f64::NEG_INFINITY, |r| r.rank());
            let actions = mine
                .iter()
                .take(PAIRED_ACTIONS)
                .map(|r| r.spec.action)
                .collect();
            (d, top, actions)
        })
        .collect();
    best_of.sort_by(|a, b| b.1.total_cmp(&a.1));
    best_of.truncate(PAIRED_SINGLES);
    let mut pairs: Vec<Spec> = Vec::new();
    for (a, _, actions) in &best_of {
        for b in plain.iter().filter(|b| *b != a) {
            for action in actions {
                let spec = Spec {
                    action: *action,
                    drivers: vec![*a, *b],
                };
                let twin = Spec {
                    action: *action,
                    drivers: vec![*b, *a],
                };
                if !pairs.contains(&spec) && !pairs.contains(&twin) {
                    pairs.push(spec);
                }
            }
        }
    }
    for d in drivers {
        if let Driver::Direction(n) = d {
            for p in &plain {
                pairs.push(Spec {
                    action: Action::Angle(*n),
                    drivers: vec![*p, *d],
                });
            }
        }
    }
    results.extend(run(pairs));
    results.sort_by(|a, b| b.rank().total_cmp(&a.rank()));
    results
}

/// The chosen definition: among the usable ones within [`NEAR_BEST`] of the best, the one
/// with the fewest parameters.
fn choose(results: &[Screening]) -> Option<usize> {
    let best = results.iter().find(|r| r.usable())?.rank();
    results
        .iter()
        .enumerate()
        .filter(|(_, r)| r.usable() && r.rank() >= NEAR_BEST * best)
        .min_by(|(_, a), (_, b)| {
            a.parameters
                .cmp(&b.parameters)
                .then(b.rank().total_cmp(&a.rank()))
        })
        .map(|(i, _)| i)
}

fn pearson(xs: &[f64], ys: &[f64]) -> f64 {
    let n = xs.len().max(1) as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in xs.iter().zip(ys) {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx).powi(2);
        syy += (y - my).powi(2);
    }
    if sxx > 0.0 && syy > 0.0 {
        sxy / (sxx * syy).sqrt()
    } else {
        0.0
    }
}

/// The driver's value in display units, and the axis label.
fn display(d: &Driver, v: &DriverValues) -> (f64, String) {
    match *d {
        Driver::Angle(n) => (v.angles_deg[n as usize - 1], format!("A{n} angle (°)")),
        Driver::Reach => (v.reach_mm, "horizontal reach of the flange (mm)".into()),
        Driver::Height => (v.height_mm, "height of the flange (mm)".into()),
        Driver::Gravity => (
            v.gravity[0].clamp(-1.0, 1.0).acos().to_degrees(),
            "tool axis from pointing down (°)".into(),
        ),
        Driver::Torque(n) => (
            v.torques_knm[n as usize - 1],
            format!("A{n} gravity torque (kN·m)"),
        ),
        Driver::Time { .. } => (v.time_h, "time (h)".into()),
        Driver::Direction(n) => (
            v.reversal[n as usize - 1],
            format!("A{n} rotation direction"),
        ),
    }
}

/// "grows with the horizontal reach", "varies with the A5 angle", …: for a driver with an
/// order, the sign of the correlation between it and the function's main output (the
/// rotation or displacement component that carries most of it).
fn trend(d: &Driver, points: &[Point], main_output: &[f64]) -> String {
    let verb = match d {
        Driver::Angle(_) => "varies with",
        Driver::Direction(_) => "changes sign with",
        Driver::Gravity => "follows",
        _ => {
            let xs: Vec<f64> = points.iter().map(|p| display(d, &p.values).0).collect();
            let r = pearson(&xs, main_output);
            if r > 0.5 {
                "grows with"
            } else if r < -0.5 {
                "falls with"
            } else {
                "varies with"
            }
        }
    };
    format!("{verb} {}", d.phrase())
}

const LINKS: [&str; 6] = [
    "the base",
    "the A1–A2 link",
    "the upper arm",
    "the A3–A4 offset",
    "the forearm",
    "the wrist",
];
/// The model coordinate along the link before An (x 0, z 2).
const ALONG: [usize; 6] = [2, 2, 2, 2, 0, 0];

/// How the fitted function acts, in words, from its values at the points.
fn action_phrase(
    model: &Model,
    rows: &[&Row],
    normal: &Normal,
    w: &[f64],
    action: Action,
) -> String {
    match action {
        Action::Angle(n) => format!("as an angular deviation of A{n}"),
        Action::Tool => "as a displacement of the measured target against the flange (a \
                         deflection of the tool or its mount)"
            .into(),
        Action::Rotation(_) | Action::Arm | Action::Offset(_) => {
            let rotation = !matches!(action, Action::Offset(_));
            // World direction of the rotation vector or of the displacement at each point.
            let (mut vertical, mut total) = (0.0, 0.0);
            let mut per_output = [0.0; 3];
            for (i, r) in rows.iter().enumerate() {
                let (frames, _) = model.frames(&r.state);
                let values = normal.values(i, w);
                let mut v = Vector3::zeros();
                for (c, output) in normal.outputs.iter().enumerate() {
                    // The first slot of an output is the rotation or the displacement itself.
                    let (s, per) = output[0];
                    let pose = frames.pose_partial(slot_of_index(s), &r.predicted);
                    let part = if rotation {
                        Vector3::new(pose[3], pose[4], pose[5])
                    } else {
                        Vector3::new(pose[0], pose[1], pose[2])
                    };
                    v += part * (values[c] * per);
                    per_output[c] += values[c] * values[c];
                }
                vertical += v.z * v.z;
                total += v.norm_squared();
            }
            let share = if total > 0.0 { vertical / total } else { 0.0 };
            let orientation = if share < 0.25 {
                "horizontal"
            } else if share > 0.75 {
                "vertical"
            } else {
                "inclined"
            };
            match action {
                Action::Arm => {
                    format!("as a rotation of the arm about a {orientation} axis through the robot's base")
                }
                Action::Rotation(1) => format!(
                    "as a rotation of the whole robot about a {orientation} axis through its base"
                ),
                Action::Rotation(n) => {
                    format!("as a rotation about a {orientation} axis through the A{n} centre")
                }
                Action::Offset(1) => format!("as a {orientation} displacement of the whole robot"),
                Action::Offset(n) => {
                    let main = (0..3)
                        .max_by(|&a, &b| per_output[a].total_cmp(&per_output[b]))
                        .unwrap_or(0);
                    let link = LINKS[n as usize - 1];
                    if main == ALONG[n as usize - 1] {
                        format!("as a change of the length of {link} (A{n} moves along it)")
                    } else {
                        format!("as a displacement of A{n} across {link}")
                    }
                }
                Action::Angle(_) | Action::Tool => unreachable!("matched above"),
            }
        }
    }
}

/// The screening data of every row.
fn points_of(model: &Model, rows: &[&Row]) -> Vec<Point> {
    let ctx = model.context();
    let gravity = model.robot.gravity.is_some();
    let points: Vec<Point> = rows
        .par_iter()
        .map(|r| {
            let (frames, _) = model.frames(&r.state);
            let jacobian = frames.target_jacobian(&r.predicted);
            Point {
                residual: r.residual(),
                model: model_columns(model, &r.state, &jacobian),
                jacobian,
                values: DriverValues::at(&r.state, &ctx, true, gravity),
            }
        })
        .collect();
    // The model's columns to unit norm: its normal equations are then well scaled.
    let m = points.first().map_or(0, |p| p.model.len());
    let norms: Vec<f64> = (0..m)
        .map(|j| {
            points
                .iter()
                .map(|p| p.model[j].norm_squared())
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    let mut points = points;
    for p in &mut points {
        for (c, n) in p.model.iter_mut().zip(&norms) {
            *c = if *n > 0.0 { *c / *n } else { Vector3::zeros() };
        }
    }
    points
}

/// Screens the drivers on `rows` (the current model's residuals) under the stretches `plan`:
/// the chosen definition with its drivers, shape and plot (not yet checked through the model),
/// scored on whole `tests`, on the `latest` data when it is a function of the clock, and on
/// the `later_file` when there is one.
pub fn screen_drivers(
    model: &Model,
    rows: &[&Row],
    plan: &Plan,
    tests: &Plan,
    latest: Option<&Plan>,
    later_file: Option<&Plan>,
) -> Option<(Spec, LearnedDrivers)> {
    if rows.len() < 4 * plan.folds().max(2) {
        return None;
    }
    let gravity = model.robot.gravity.is_some();
    let points = points_of(model, rows);
    let window = time_window(rows);
    let drivers = varying_drivers(&points, gravity, window);
    if drivers.is_empty() {
        return None;
    }
    let results = screen_all(model, &points, &drivers, plan, tests);
    let chosen = choose(&results)?;
    let Screening {
        spec,
        within: score,
        tests: tests_score,
        parameters,
    } = results[chosen].clone();
    let rank = results[chosen].rank();

    // The drivers that carry it: of a pair, one alone that reaches most of its gain.
    let single = |d: &Driver| {
        results
            .iter()
            .find(|r| r.spec.drivers == [*d] && r.spec.action == spec.action)
            .map_or(0.0, |r| r.rank())
    };
    let carriers: Vec<Driver> = match spec.drivers.as_slice() {
        [a, b] => {
            if single(a) >= CARRIES * rank {
                vec![*a]
            } else if single(b) >= CARRIES * rank {
                vec![*b]
            } else {
                vec![*a, *b]
            }
        }
        other => other.to_vec(),
    };
    // Fitted on every point together with the model: its shape, and the residual it explains.
    let all = vec![0; points.len()];
    let blocks = Blocks::new(&points, &all, 1);
    let normal = Normal::new(model, &points, &spec, &blocks);
    let model_normal = ModelNormal::new(&blocks);
    let (a_cells, g_cells, b) = normal.partialled(&model_normal, &ModelFactor::new(&model_normal));
    let w = Normal::solve_cells(&a_cells, &g_cells, |_| true);
    let bw = b_times(&b, &w);
    // The part of the function the model does not already span, against which the residual
    // is plotted.
    let partial: Vec<Vector3<f64>> = points
        .iter()
        .enumerate()
        .map(|(i, p)| partial_predict(&normal, &bw, p, i, &w))
        .collect();
    let outputs: Vec<Vec<f64>> = (0..points.len()).map(|i| normal.values(i, &w)).collect();
    let main_output = (0..normal.outputs.len())
        .max_by(|&a, &b| {
            let energy = |c: usize| outputs.iter().map(|v| v[c] * v[c]).sum::<f64>();
            energy(a).total_cmp(&energy(b))
        })
        .unwrap_or(0);
    let along: Vec<f64> = outputs.iter().map(|v| v[main_output]).collect();
    let trends: Vec<String> = carriers.iter().map(|d| trend(d, &points, &along)).collect();
    // Drivers that alone, through their best action, explain about as much: on these data
    // they cannot be told apart from the chosen ones.
    let best_alone = |d: &Driver| {
        results
            .iter()
            .filter(|r| r.spec.drivers == [*d] && r.usable())
            .map(Screening::rank)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let mut alike: Vec<(Driver, f64)> = drivers
        .iter()
        .filter(|d| !spec.drivers.contains(d))
        .map(|d| (*d, best_alone(d)))
        .filter(|(_, r)| *r >= ALIKE * rank)
        .collect();
    alike.sort_by(|a, b| b.1.total_cmp(&a.1));
    let alike: Vec<Driver> = alike.into_iter().take(MAX_ALIKE).map(|(d, _)| d).collect();
    let mut shape = format!(
        "{}, {}",
        trends.join(" and "),
        action_phrase(model, rows, &normal, &w, spec.action)
    );
    if !alike.is_empty() {
        let phrases: Vec<String> = alike.iter().map(Driver::phrase).collect();
        shape += &format!(
            " (on these data {} explain{} it about as well)",
            phrases.join(" and "),
            if alike.len() == 1 { "s" } else { "" }
        );
    }
    let short = |d: &Driver| match d {
        Driver::Time { .. } => "time".to_string(),
        _ => d.to_string(),
    };
    let main = carriers[0];
    let step = points.len().div_ceil(CURVE_POINTS).max(1);
    let curve = Curve {
        driver: display(&main, &points[0].values).1,
        points: points
            .iter()
            .zip(&partial)
            .step_by(step)
            .filter(|(_, p)| p.norm() > 1e-9)
            .map(|(pt, p)| {
                let u = p.normalize();
                (
                    display(&main, &pt.values).0,
                    pt.residual.dot(&u) * 1000.0,
                    p.norm() * 1000.0,
                )
            })
            .collect(),
    };
    let effect = format!("learned:{spec}");
    let found = LearnedDrivers {
        add: super::add_option(&effect),
        effect,
        drivers: carriers.iter().map(short).collect(),
        indistinguishable_from: alike.iter().map(short).collect(),
        shape,
        explained: score.explained,
        rms_after_um: score.rms_after_um,
        t_statistic: score.t,
        parameters,
        stable: score.stable(),
        significant: false,
        checks: std::iter::once(tests_score)
            .chain(
                latest
                    .filter(|_| uses_time(&spec))
                    .map(|l| latest_score(model, &points, rows, &spec, l)),
            )
            .chain(later_file.map(|l| latest_score(model, &points, rows, &spec, l)))
            .collect(),
        vetoed: None,
        screened: results
            .iter()
            .take(6)
            .map(|r| Screened {
                effect: format!("learned:{}", r.spec),
                explained: r.within.explained,
                explained_tests: r.tests.explained,
                parameters: r.parameters,
                stable: r.within.stable(),
            })
            .collect(),
        curve,
    };
    Some((spec, found))
}

/// The score of a definition on the clock on the latest data: per fold it learns, with its
/// window set to the earlier points' clock, from those points alone (the model's columns
/// partialled out as in the screening) and predicts the later ones.
fn latest_score(model: &Model, points: &[Point], rows: &[&Row], spec: &Spec, plan: &Plan) -> Score {
    let before: Vec<Vector3<f64>> = points.iter().map(|p| p.residual).collect();
    let mut after = vec![None; points.len()];
    for (held, train) in plan.held.iter().zip(&plan.train) {
        let fold_spec = rewindowed(spec, rows, train);
        let cell_of = cells_of(points.len(), held, train);
        let blocks = Blocks::new(points, &cell_of, 3);
        let normal = Normal::new(model, points, &fold_spec, &blocks);
        let model_normal = ModelNormal::new(&blocks);
        let (a_cells, g_cells, b) =
            normal.partialled(&model_normal, &ModelFactor::new(&model_normal));
        let w = Normal::solve_cells(&a_cells, &g_cells, |cell| cell == 0);
        let bw = b_times(&b, &w);
        for &i in held {
            after[i] = Some(points[i].residual - partial_predict(&normal, &bw, &points[i], i, &w));
        }
    }
    Score::new(plan, &before, &after)
}

/// The score on the latest data of an effect of the table that extrapolates in time (drift):
/// as `latest_score`, from the effect's own Jacobian with the model's columns partialled
/// out — fitted on top of tables that took up part of it with the later data, it would count
/// that part twice.
pub fn latest_effect_score(
    model: &Model,
    rows: &[&Row],
    name: &crate::model::EffectName,
    plan: &Plan,
) -> Option<Score> {
    EffectScreen::new(model, rows).score(model, name, plan)
}

/// Per point its cell in a fold: 0 learnt from, 1 predicted, 2 neither.
fn cells_of(n: usize, held: &[usize], train: &[bool]) -> Vec<usize> {
    let mut cell_of = vec![2; n];
    for (i, t) in train.iter().enumerate() {
        if *t {
            cell_of[i] = 0;
        }
    }
    for &i in held {
        cell_of[i] = 1;
    }
    cell_of
}

/// Effects of the table scored as they will be identified — with the model's tables
/// re-fitted beside them — rather than fitted alone on top of the identified model: per fold,
/// from the effect's own Jacobian with what the model's columns span partialled out (linear,
/// at the current model). An effect whose shape a table has half taken up in one test (A3's
/// gravity torque in the A3 sweep) is credited with what it adds elsewhere, not charged for
/// counting that part twice. The points are built once for every candidate.
pub struct EffectScreen {
    points: Vec<Point>,
    states: Vec<AxisState>,
}

impl EffectScreen {
    pub fn new(model: &Model, rows: &[&Row]) -> EffectScreen {
        EffectScreen {
            points: points_of(model, rows),
            states: rows.iter().map(|r| r.state).collect(),
        }
    }

    /// Each of `names` scored under `plan` (the model's normal equations of each fold built
    /// once for all); `None` for one that cannot be created.
    pub fn scores(
        &self,
        model: &Model,
        names: &[crate::model::EffectName],
        plan: &Plan,
    ) -> Vec<Option<Score>> {
        let points = &self.points;
        let folds: Vec<(Blocks, ModelNormal, ModelFactor)> = plan
            .held
            .iter()
            .zip(&plan.train)
            .map(|(held, train)| {
                let cell_of = cells_of(points.len(), held, train);
                let blocks = Blocks::new(points, &cell_of, 3);
                let normal = ModelNormal::new(&blocks);
                let factor = ModelFactor::new(&normal);
                (blocks, normal, factor)
            })
            .collect();
        let before: Vec<Vector3<f64>> = points.iter().map(|p| p.residual).collect();
        names
            .par_iter()
            .map(|name| {
                let effect = name.create(&Default::default(), &model.robot).ok()?;
                let mut after = vec![None; points.len()];
                for (held, (blocks, model_normal, factor)) in plan.held.iter().zip(&folds) {
                    let normal =
                        Normal::for_effect(model, points, &self.states, effect.as_effect(), blocks);
                    let (a_cells, g_cells, b) = normal.partialled(model_normal, factor);
                    let w = Normal::solve_cells(&a_cells, &g_cells, |cell| cell == 0);
                    let bw = b_times(&b, &w);
                    for &i in held {
                        after[i] = Some(
                            points[i].residual - partial_predict(&normal, &bw, &points[i], i, &w),
                        );
                    }
                }
                Some(Score::new(plan, &before, &after))
            })
            .collect()
    }

    /// `name` scored under `plan`; `None` when it cannot be created.
    pub fn score(
        &self,
        model: &Model,
        name: &crate::model::EffectName,
        plan: &Plan,
    ) -> Option<Score> {
        self.scores(model, std::slice::from_ref(name), plan)
            .pop()
            .flatten()
    }
}

/// The learned definition with its clock window set to the training points' (a fit on the
/// earlier data knows nothing of the later clock and holds its edge value beyond it).
pub fn rewindowed(spec: &Spec, rows: &[&Row], train: &[bool]) -> Spec {
    let seen: Vec<&Row> = rows
        .iter()
        .zip(train)
        .filter(|(_, t)| **t)
        .map(|(r, _)| *r)
        .collect();
    let window = time_window(&seen);
    Spec {
        action: spec.action,
        drivers: spec
            .drivers
            .iter()
            .map(|d| match (d, window) {
                (Driver::Time { .. }, Some((from_h, to_h))) => Driver::Time { from_h, to_h },
                _ => *d,
            })
            .collect(),
    }
}

/// Whether the definition extrapolates in time (has a clock driver).
pub fn uses_time(spec: &Spec) -> bool {
    spec.drivers
        .iter()
        .any(|d| matches!(d, Driver::Time { .. }))
}
