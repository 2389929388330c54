//! The global refinement: Levenberg–Marquardt over the chosen parameters of a [`Model`]
//! (optionally with the 6 parameters of the tracker → base registration) against every
//! measured stop, minimising `Σ |T·m_k − p̂(q_k)|²` (measured position `m_k` mapped to the base
//! frame, predicted target `p̂`).
//!
//! How it is set up, and why:
//! - **Sparse.** A stop's three rows touch the geometric parameters plus two (or four) cells of
//!   each table; the damped normal equations are formed and factored sparse
//!   ([`super::lsq::SparseLsq`]). Columns are scaled to unit norm (Jacobi scaling), so the
//!   damping `λ·I` is Marquardt's `λ·diag(JᵀJ)` and the diagonal of the inverse scaled
//!   normal matrix is each parameter's variance inflation factor (VIF, `1/(1−R²)`).
//! - **Pins** (MODEL.md "Frames"): where two parameters move the target identically, one is
//!   pinned by a row fixing a data-weighted mean to zero — the mean of `map:A2..A5` when the
//!   zero offset `dthN0` is free, of `map:A6` when the target vector is free (a rotation of
//!   6p about A6), of `map:A1` when the tracker frame is registered (a rotation about Z), and
//!   of `crosstalk:Am->An` over the other axis at each own-axis grid point when `map:An` is
//!   free (a function of A_n alone is the map's).
//! - **Unobserved cells** (no measured stop interpolates in them, e.g. backlash cells visited
//!   only before the axis first moved) get smoothness rows (second differences, first at the
//!   table edge) and nothing else: they follow their observed neighbours linearly, or hold the
//!   edge value, and do not bias the observed cells. **Thin** cells (observed at under
//!   [`RefineOptions::thin`] of their table's median strength, e.g. a 1° cell between stops
//!   2° apart that only a small interpolation weight reaches) get the same rows, which then
//!   outweigh their few data: otherwise they would carry those stops' noise magnified by the
//!   inverse weight. Effects that no measurement depends on at all are held and reported.
//! - **Identifiability.** At the solution, parameters whose VIF exceeds
//!   [`RefineOptions::vif_limit`] are reported with the parameters they are correlated with
//!   (from the columns of the inverse normal matrix); a floor on the damping keeps them at
//!   their starting values instead of letting round-off move them.

use std::collections::BTreeMap;
use std::sync::Arc;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use super::lsq::{LsqError, SparseLsq};
use super::register::rigid_fit;
use crate::kinematics::Frame;
use crate::measure::Stop;
use crate::model::{AxisState, EffectName, JacobianScratch, Model, Role, Slot};
use crate::stats::{error_stats, ErrorStats};

/// Which parameters the refinement moves; the others are held at their current values.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Free {
    /// Every parameter of the model.
    #[default]
    All,
    /// The parameters of these effects (contract names, any spelling `EffectName` accepts).
    Effects(Vec<String>),
    /// One flag per parameter of the flat vector (robopost's own tests choose parameters so).
    #[cfg(any(test, feature = "internals"))]
    Mask(Vec<bool>),
}

/// A progress callback (called after every iteration).
pub type ProgressFn = Arc<dyn Fn(&Progress) + Send + Sync>;

/// Progress of the iteration, for a progress bar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    /// What is running (`refining`; the pipeline reports its other stages through the same
    /// callback, with `rms_um` and `lambda` NaN).
    pub stage: &'static str,
    pub iteration: usize,
    pub max_iterations: usize,
    /// RMS of the 3-D residual, µm.
    pub rms_um: f64,
    pub lambda: f64,
}

/// Options of [`refine`].
#[derive(Clone)]
pub struct RefineOptions {
    pub free: Free,
    /// The measured positions are in a tracker frame: identify its pose in the base frame
    /// (6 extra parameters) together with the model.
    pub tracker_frame: bool,
    /// Starting pose of the tracker frame in the base frame; `None`: the rigid best fit of the
    /// measured points onto the current model's predictions.
    pub initial_frame: Option<Frame>,
    /// Tracker frame of every data stop (an index into the frames), for data measured from
    /// several tracker set-ups (one file per day, the tracker moved): each gets its own pose.
    /// Empty: every stop in frame 0. Only with `tracker_frame`.
    pub frame_of: Vec<usize>,
    /// Starting poses of the frames by index; a missing one starts from `initial_frame` (frame
    /// 0) or the rigid best fit of its points.
    pub initial_frames: Vec<Frame>,
    pub max_iterations: usize,
    /// Converged when an accepted step lowers the cost by less than this fraction.
    pub tolerance: f64,
    /// Weight of the smoothness rows of unobserved table cells, relative to the effect's
    /// typical column norm (the result does not depend on it; conditioning does).
    pub smoothing: f64,
    /// A table cell whose column norm is below this fraction of its table's median (observed
    /// cells) is *thin*: like an unobserved cell it gets smoothness rows and follows its
    /// neighbours. A cell that a stop reaches only through a small interpolation weight (1°
    /// tables on 2°-pitch data) would otherwise take the noise of that stop magnified by the
    /// inverse weight. 0 turns this off.
    pub thin: f64,
    /// VIF above which a parameter is reported unidentifiable.
    pub vif_limit: f64,
    /// Compute per-parameter standard errors (the inverse of the normal matrix).
    pub standard_errors: bool,
    pub progress: Option<ProgressFn>,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            free: Free::All,
            tracker_frame: false,
            initial_frame: None,
            frame_of: Vec::new(),
            initial_frames: Vec::new(),
            max_iterations: 30,
            tolerance: 1e-10,
            smoothing: 1.0,
            thin: 0.2,
            vif_limit: 1e6,
            standard_errors: true,
            progress: None,
        }
    }
}

impl std::fmt::Debug for RefineOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RefineOptions")
            .field("free", &self.free)
            .field("tracker_frame", &self.tracker_frame)
            .field("initial_frame", &self.initial_frame)
            .field("frame_of", &self.frame_of.len())
            .field("initial_frames", &self.initial_frames)
            .field("max_iterations", &self.max_iterations)
            .field("tolerance", &self.tolerance)
            .field("smoothing", &self.smoothing)
            .field("thin", &self.thin)
            .field("vif_limit", &self.vif_limit)
            .field("standard_errors", &self.standard_errors)
            .finish_non_exhaustive()
    }
}

/// Why identification could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IdentifyError {
    #[error("no measured stop in the data (every row has empty x, y, z)")]
    /// No row has a measured position.
    NoMeasurements,
    #[error("{points} measured stops give {rows} equations for {parameters} free parameters: measure more points or free fewer effects")]
    /// Fewer equations than free parameters.
    TooFewPoints {
        /// Measured stops.
        points: usize,
        /// Equations they give (three per stop).
        rows: usize,
        /// Free parameters.
        parameters: usize,
    },
    #[error("the free-parameter mask has {found} entries, the model has {expected} parameters")]
    /// A mask of free parameters of the wrong length.
    BadMask {
        /// The model's parameters.
        expected: usize,
        /// The mask's entries.
        found: usize,
    },
    #[error("`{name}` is not an effect of the model (it has: {available})")]
    /// An effect named that the model does not have.
    UnknownEffect {
        /// The name given.
        name: String,
        /// The model's effects, comma-separated.
        available: String,
    },
    #[error("cannot start the tracker-frame registration: the measured points are collinear or fewer than three")]
    /// The tracker frame has no starting value: fewer than three points, or collinear.
    FrameStart,
    #[error("cannot set up the effect: {0}")]
    /// An effect could not be built.
    Setup(#[from] super::setup::SetupError),
    #[error("least squares failed: {0}")]
    /// The least-squares solve failed.
    Lsq(#[from] LsqError),
}

/// Something the user should know about the fit.
#[derive(Clone, Debug, PartialEq)]
pub enum Warning {
    /// No measured stop depends on this effect (or this scalar parameter of an effect): it
    /// was held at its current values.
    Unobserved {
        /// The effect (or `effect:parameter`).
        effect: String,
    },
    /// These parameters are not determined by the data (VIF above the limit); they were held
    /// near their starting values. `correlated_with` are the parameters they trade off
    /// against.
    Unidentifiable {
        /// The parameters held.
        parameters: Vec<String>,
        /// What they trade off against.
        correlated_with: Vec<String>,
        /// The largest variance inflation factor among them.
        vif: f64,
    },
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::Unobserved { effect } => write!(
                f,
                "{effect}: no measured stop depends on it; held at its current values"
            ),
            Warning::Unidentifiable {
                parameters,
                correlated_with,
                vif,
            } => {
                let shown = abbreviate(parameters, 6);
                write!(f, "unidentifiable: {shown} (variance inflation {vif:.1e})")?;
                if !correlated_with.is_empty() {
                    write!(f, "; correlated with {}", abbreviate(correlated_with, 6))?;
                }
                write!(f, "; held near the starting values")
            }
        }
    }
}

fn abbreviate(names: &[String], max: usize) -> String {
    if names.len() <= max {
        names.join(", ")
    } else {
        format!("{} and {} more", names[..max].join(", "), names.len() - max)
    }
}

/// How a parameter came out of the fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Not free (held by the options).
    Held,
    /// Determined by the data.
    Identified,
    /// No data; set by smoothness from its neighbours.
    Smoothed,
    /// Free but not determined by the data (see the warnings), or its effect unobserved.
    Unidentifiable,
}

/// The result of the refinement (`identify`'s fit). Residuals are `measured − predicted`, in
/// the base frame, mm.
#[derive(Clone, Debug)]
pub struct Fit {
    /// Index into the data of each measured stop, in order.
    pub points: Vec<usize>,
    /// The residual of each of those stops, mm.
    pub residuals_mm: Vec<Vector3<f64>>,
    /// Table 1 statistics of the residual (all points).
    pub stats: ErrorStats,
    /// The same per test label.
    pub per_test: BTreeMap<String, ErrorStats>,
    /// Residual statistics before the refinement.
    pub initial_stats: ErrorStats,
    /// Estimated measurement noise: residual standard deviation per coordinate, mm.
    pub sigma_mm: f64,
    /// Every model parameter, flat order.
    pub parameter_names: Vec<String>,
    /// The unit of each parameter (`mm`, `deg`, …).
    pub units: Vec<&'static str>,
    /// What the fit did with each parameter.
    pub status: Vec<Status>,
    /// One standard error per model parameter, in its unit; `None` unless identified.
    pub standard_errors: Vec<Option<f64>>,
    /// Identified pose of the tracker frame in the base frame (`p_base = F·p_tracker`); the
    /// first of [`Self::tracker_frames`].
    pub tracker_frame: Option<Frame>,
    /// Standard errors of the frame: translation x, y, z (mm), rotation about the base x, y,
    /// z axes (degrees).
    pub tracker_frame_standard_errors: Option<[f64; 6]>,
    /// Every identified tracker frame, by index (the tracker station of each point).
    pub tracker_frames: Vec<Frame>,
    /// Their standard errors (as [`Self::tracker_frame_standard_errors`]).
    pub tracker_frames_standard_errors: Vec<[f64; 6]>,
    /// Parameters the data do not determine, effects they do not observe.
    pub warnings: Vec<Warning>,
    /// Levenberg–Marquardt iterations run.
    pub iterations: usize,
    /// The cost stopped falling: the last accepted step lowered it by less than the
    /// tolerance, or no step lowered it at all.
    pub converged: bool,
    /// The parameters' covariance at the solution (with the standard errors), for the
    /// uncertainty of predicted positions.
    pub(crate) covariance: Option<Arc<super::covariance::Covariance>>,
}

impl Fit {
    /// The `n` identified parameters with the largest standard errors (name, standard error,
    /// unit), for reports; mixed units, so most useful within one effect.
    pub fn largest_standard_errors(&self, n: usize) -> Vec<(String, f64, &'static str)> {
        let mut v: Vec<(String, f64, &'static str)> = self
            .standard_errors
            .iter()
            .enumerate()
            .filter_map(|(i, s)| s.map(|s| (self.parameter_names[i].clone(), s, self.units[i])))
            .collect();
        v.sort_by(|a, b| b.1.total_cmp(&a.1));
        v.truncate(n);
        v
    }

    /// The parameters' covariance at the solution (robopost's own tests read it).
    #[cfg(any(test, feature = "internals"))]
    pub fn covariance(&self) -> Option<&Arc<super::covariance::Covariance>> {
        self.covariance.as_ref()
    }
}

/// One measured stop as the fit sees it.
struct Point {
    state: AxisState,
    measured: Vector3<f64>,
    /// Its tracker frame.
    frame: usize,
}

/// A linear row `weight · Σ coef·x[flat] ≈ 0` over the flat parameter vector.
struct Constraint {
    entries: Vec<(usize, f64)>,
}

/// The table layout of an effect: (own-axis points, other-axis points), or `None`.
fn table_shape(model: &Model, effect: usize) -> Option<(usize, usize)> {
    let record = model.effects()[effect].record();
    let t = record.table?;
    let cols = t.other_grid_deg.as_ref().map_or(1, Vec::len);
    Some((t.grid_deg.len(), cols))
}

/// The free flags of the flat vector.
fn free_mask(model: &Model, free: &Free) -> Result<Vec<bool>, IdentifyError> {
    let n = model.n_parameters();
    match free {
        Free::All => Ok(vec![true; n]),
        #[cfg(any(test, feature = "internals"))]
        Free::Mask(m) if m.len() == n => Ok(m.clone()),
        #[cfg(any(test, feature = "internals"))]
        Free::Mask(m) => Err(IdentifyError::BadMask {
            expected: n,
            found: m.len(),
        }),
        Free::Effects(names) => {
            let mut mask = vec![false; n];
            let effect_names: Vec<String> = model.effects().iter().map(|e| e.name()).collect();
            for name in names {
                let canonical = EffectName::parse(name).map_or(name.clone(), |e| e.to_string());
                let Some(i) = effect_names.iter().position(|e| *e == canonical) else {
                    return Err(IdentifyError::UnknownEffect {
                        name: name.clone(),
                        available: effect_names.join(", "),
                    });
                };
                let end = model.effect_start(i) + model.effects()[i].values().len();
                mask[model.effect_start(i)..end].fill(true);
            }
            Ok(mask)
        }
    }
}

/// The effect a flat parameter index belongs to.
fn effect_of(model: &Model, flat: usize) -> usize {
    (0..model.effects().len())
        .rev()
        .find(|&e| model.effect_start(e) <= flat)
        .unwrap_or(0)
}

/// Flat index of the axis-lines parameter that adds a constant to `slot`, when the model
/// has one.
fn constant_param(model: &Model, slot: Slot) -> Option<usize> {
    let g = super::direct::axis_lines(model)?;
    Some(model.effect_start(g) + model.effects()[g].constant_in(slot)?)
}

/// Whether the model has an own-angle table of axis `axis` ([`Role::OwnAngle`]) with a free
/// cell.
fn free_own_angle(model: &Model, free: &[bool], axis: u8) -> bool {
    model.effects().iter().enumerate().any(|(m, e)| {
        let start = model.effect_start(m);
        e.role() == Role::OwnAngle { axis } && free[start..start + e.values().len()].contains(&true)
    })
}

/// Refines `model` in place against the measured stops of `data` (stops in visiting order,
/// directions already inferred). See the module documentation.
pub fn refine(
    model: &mut Model,
    data: &[Stop],
    options: &RefineOptions,
) -> Result<Fit, IdentifyError> {
    let frame_of = |i: usize| {
        if options.tracker_frame {
            options.frame_of.get(i).copied().unwrap_or(0)
        } else {
            0
        }
    };
    let (indices, points): (Vec<usize>, Vec<Point>) = data
        .iter()
        .enumerate()
        .filter_map(|(i, s)| {
            s.measured_mm.map(|m| {
                (
                    i,
                    Point {
                        state: s.state,
                        measured: m,
                        frame: frame_of(i),
                    },
                )
            })
        })
        .unzip();
    if points.is_empty() {
        return Err(IdentifyError::NoMeasurements);
    }
    let n_flat = model.n_parameters();
    let mut free = free_mask(model, &options.free)?;
    let mut warnings = Vec::new();

    let n_frames = points.iter().map(|p| p.frame + 1).max().unwrap_or(1);
    let mut frames = Vec::with_capacity(n_frames);
    for f in 0..n_frames {
        let given = options.initial_frames.get(f).copied().or(if f == 0 {
            options.initial_frame
        } else {
            None
        });
        frames.push(match (options.tracker_frame, given) {
            (false, _) => Isometry3::identity(),
            (true, Some(frame)) => frame.to_isometry(),
            (true, None) => {
                let (measured, predicted): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = points
                    .iter()
                    .filter(|p| p.frame == f)
                    .map(|p| (p.measured, model.target_position(&p.state)))
                    .unzip();
                rigid_fit(&measured, &predicted)
                    .ok_or(IdentifyError::FrameStart)?
                    .to_isometry()
            }
        });
    }
    let mut frame = frames;

    // Observation strength of every parameter: its column norm over the data rows.
    let mut norms = column_norms(model, &points);
    one_sided_direction_cells(model, &points, &free, &mut norms);
    let mut smoothed = vec![false; n_flat];
    let mut constraints: Vec<Constraint> = Vec::new();
    let mut scale = norms.clone();
    for (e, effect) in model.effects().iter().enumerate() {
        let start = model.effect_start(e);
        let len = effect.values().len();
        let range = start..start + len;
        if !free[range.clone()].iter().any(|&f| f) {
            continue;
        }
        let max = norms[range.clone()].iter().copied().fold(0.0, f64::max);
        if max == 0.0 {
            free[range].fill(false);
            warnings.push(Warning::Unobserved {
                effect: effect.name(),
            });
            continue;
        }
        let observed = |i: usize| norms[i] > 1e-6 * max;
        match table_shape(model, e) {
            Some((rows, cols)) => {
                let mut typical: Vec<f64> = range
                    .clone()
                    .filter(|&i| observed(i))
                    .map(|i| norms[i])
                    .collect();
                typical.sort_by(f64::total_cmp);
                let median = typical[typical.len() / 2];
                let weight = options.smoothing * median;
                let thin = |i: usize| norms[i] < options.thin * median;
                let cell = |i: usize, j: usize| start + i * cols + j;
                let line_observed = |fixed_col: Option<usize>, fixed_row: Option<usize>| match (
                    fixed_col, fixed_row,
                ) {
                    (Some(j), _) => (0..rows).any(|i| observed(cell(i, j))),
                    (_, Some(i)) => (0..cols).any(|j| observed(cell(i, j))),
                    _ => false,
                };
                for i in 0..rows {
                    for j in 0..cols {
                        let k = cell(i, j);
                        if !free[k] || (observed(k) && !thin(k)) {
                            continue;
                        }
                        let along_own = rows > 1 && line_observed(Some(j), None);
                        let along_other = cols > 1 && (!along_own || !line_observed(None, Some(i)));
                        let mut any = false;
                        if along_own || (rows > 1 && !along_other) {
                            constraints.push(smoothness(k, i, rows, cols, weight));
                            any = true;
                        }
                        if along_other {
                            constraints.push(smoothness(k, j, cols, 1, weight));
                            any = true;
                        }
                        if any {
                            smoothed[k] = true;
                            scale[k] = weight;
                        } else {
                            free[k] = false;
                        }
                    }
                }
            }
            None => {
                let names = effect.parameters();
                for (local, i) in range.enumerate() {
                    if free[i] && !observed(i) {
                        free[i] = false;
                        warnings.push(Warning::Unobserved {
                            effect: names[local].name.clone(),
                        });
                    }
                }
            }
        }
    }
    constraints.extend(pins(model, &free, &norms, &points, options.tracker_frame));

    // Free columns: model parameters, then the frame.
    let flat_of: Vec<usize> = (0..n_flat).filter(|&i| free[i]).collect();
    let mut col_of = vec![None; n_flat];
    for (c, &i) in flat_of.iter().enumerate() {
        col_of[i] = Some(c);
    }
    let n_model_cols = flat_of.len();
    let n_frame_cols = if options.tracker_frame {
        6 * n_frames
    } else {
        0
    };
    let n_cols = n_model_cols + n_frame_cols;
    let rows = 3 * points.len();
    let n_data_cols = n_cols - flat_of.iter().filter(|&&i| smoothed[i]).count();
    if rows < n_data_cols {
        return Err(IdentifyError::TooFewPoints {
            points: points.len(),
            rows,
            parameters: n_data_cols,
        });
    }
    let mut col_scale: Vec<f64> = flat_of.iter().map(|&i| scale[i]).collect();
    if options.tracker_frame {
        // Frame columns: translation moves every point of the frame by 1 mm per mm; rotation
        // by the distance from the base origin (rad).
        for (f, pose) in frame.iter().enumerate() {
            let own: Vec<&Point> = points.iter().filter(|p| p.frame == f).collect();
            let n = own.len().max(1) as f64;
            let radius = (own
                .iter()
                .map(|p| {
                    (pose * nalgebra::Point3::from(p.measured))
                        .coords
                        .norm_squared()
                })
                .sum::<f64>()
                / n)
                .sqrt();
            col_scale.extend([n.sqrt(); 3]);
            col_scale.extend([n.sqrt() * radius.max(1.0); 3]);
        }
    }

    let problem = Problem {
        points: &points,
        constraints: &constraints,
        col_of: &col_of,
        flat_of: &flat_of,
        col_scale: &col_scale,
        tracker: options.tracker_frame,
    };

    let initial = problem.residuals(model, &frame);
    let initial_stats = error_stats(&initial.iter().map(|r| -r).collect::<Vec<_>>());
    let mut cost = problem.cost(model, &initial);
    let mut lambda = 1e-3;
    const LAMBDA_MIN: f64 = 1e-9;
    let mut iterations = 0;
    let mut converged = false;
    let mut residuals = initial;
    while iterations < options.max_iterations {
        iterations += 1;
        let lsq = problem.system(model, &frame, &residuals, lambda)?;
        let step = match lsq.solve() {
            Ok(s) => s.x,
            Err(LsqError::Singular) => {
                lambda *= 10.0;
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let (trial_model, trial_frame) = problem.apply(model, &frame, &step);
        let trial_residuals = problem.residuals(&trial_model, &trial_frame);
        let trial_cost = problem.cost(&trial_model, &trial_residuals);
        if trial_cost <= cost {
            let decrease = (cost - trial_cost) / cost.max(f64::MIN_POSITIVE);
            *model = trial_model;
            frame = trial_frame;
            residuals = trial_residuals;
            cost = trial_cost;
            lambda = (lambda / 10.0).max(LAMBDA_MIN);
            if decrease < options.tolerance {
                converged = true;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                converged = true; // no step lowers the cost: at the minimum to round-off
            }
        }
        if let Some(progress) = &options.progress {
            progress(&Progress {
                stage: "refining",
                iteration: iterations,
                max_iterations: options.max_iterations,
                rms_um: rms_um(&residuals),
                lambda,
            });
        }
        if converged {
            break;
        }
    }

    // Statistics at the solution.
    let errors: Vec<Vector3<f64>> = residuals.iter().map(|r| -r).collect();
    let stats = error_stats(&errors);
    let mut by_test: BTreeMap<String, Vec<Vector3<f64>>> = BTreeMap::new();
    for (k, &i) in indices.iter().enumerate() {
        by_test
            .entry(data[i].test.clone())
            .or_default()
            .push(errors[k]);
    }
    let per_test = by_test
        .iter()
        .map(|(t, e)| (t.clone(), error_stats(e)))
        .collect();
    let n_smoothed = flat_of.iter().filter(|&&i| smoothed[i]).count();
    let dof = rows.saturating_sub(n_cols - n_smoothed).max(1);
    let rss: f64 = residuals.iter().map(|r| r.norm_squared()).sum();
    let sigma_mm = (rss / dof as f64).sqrt();

    let names = model.parameter_names();
    let units: Vec<&'static str> = model.parameters().iter().map(|p| p.unit).collect();
    let mut status: Vec<Status> = (0..n_flat)
        .map(|i| {
            if smoothed[i] && free[i] {
                Status::Smoothed
            } else if free[i] {
                Status::Identified
            } else {
                Status::Held
            }
        })
        .collect();
    // Parameters freed by the options but dropped for lack of data.
    let requested = free_mask(model, &options.free)?;
    for i in 0..n_flat {
        if requested[i] && !free[i] {
            status[i] = Status::Unidentifiable;
        }
    }
    let mut standard_errors = vec![None; n_flat];
    let mut frames_se = Vec::new();
    let mut covariance = None;
    if options.standard_errors {
        let lsq = problem.system(model, &frame, &residuals, LAMBDA_MIN)?;
        let solution = lsq.solve()?;
        let mut col_names: Vec<String> = flat_of.iter().map(|&i| names[i].clone()).collect();
        if options.tracker_frame {
            for f in 0..n_frames {
                let prefix = if n_frames == 1 {
                    "frame".to_string()
                } else {
                    format!("frame[{f}]")
                };
                col_names
                    .extend(["x", "y", "z", "rx", "ry", "rz"].map(|k| format!("{prefix}.{k}")));
            }
        }
        // Columns of the inverse in blocks, the blocks in parallel.
        const CHUNK: usize = 128;
        type Block = (Vec<(usize, f64)>, Vec<(usize, Vec<f64>)>);
        let blocks: Vec<Block> = (0..n_cols)
            .step_by(CHUNK)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|chunk_start| {
                let columns: Vec<usize> =
                    (chunk_start..(chunk_start + CHUNK).min(n_cols)).collect();
                let inverse = solution.inverse_normal_columns(&columns);
                let mut diagonal = Vec::with_capacity(columns.len());
                let mut flagged = Vec::new();
                for (k, &c) in columns.iter().enumerate() {
                    let v = inverse[(c, k)];
                    diagonal.push((c, v));
                    let is_smoothed = c < n_model_cols && smoothed[flat_of[c]];
                    if v > options.vif_limit && !is_smoothed {
                        flagged.push((c, (0..n_cols).map(|r| inverse[(r, k)]).collect()));
                    }
                }
                (diagonal, flagged)
            })
            .collect();
        let mut vif = vec![0.0; n_cols];
        let mut flagged: Vec<(usize, Vec<f64>)> = Vec::new();
        for (diagonal, f) in blocks {
            for (c, v) in diagonal {
                vif[c] = v;
            }
            flagged.extend(f);
        }
        let flagged_set: Vec<usize> = flagged.iter().map(|(c, _)| *c).collect();
        // One warning per effect (the frame counts as one): its unidentifiable parameters and
        // the identified parameters most correlated with them.
        let group_of = |c: usize| {
            if c < n_model_cols {
                effect_of(model, flat_of[c])
            } else {
                usize::MAX
            }
        };
        let mut groups: Vec<usize> = flagged_set.iter().map(|&c| group_of(c)).collect();
        groups.dedup();
        for group in groups {
            let members: Vec<&(usize, Vec<f64>)> = flagged
                .iter()
                .filter(|(c, _)| group_of(*c) == group)
                .collect();
            let mut partners: BTreeMap<usize, f64> = BTreeMap::new();
            for (c, column) in &members {
                for r in 0..n_cols {
                    if flagged_set.contains(&r) {
                        continue;
                    }
                    let rho = (column[r] / (vif[*c] * vif[r]).sqrt()).abs();
                    if rho > 0.5 {
                        let e = partners.entry(r).or_insert(0.0);
                        *e = e.max(rho);
                    }
                }
            }
            let mut partners: Vec<(usize, f64)> = partners.into_iter().collect();
            partners.sort_by(|a, b| b.1.total_cmp(&a.1));
            warnings.push(Warning::Unidentifiable {
                parameters: members.iter().map(|(c, _)| col_names[*c].clone()).collect(),
                correlated_with: partners
                    .iter()
                    .take(8)
                    .map(|&(r, _)| col_names[r].clone())
                    .collect(),
                vif: members.iter().map(|(c, _)| vif[*c]).fold(0.0, f64::max),
            });
        }
        for c in 0..n_cols {
            let se = sigma_mm * vif[c].max(0.0).sqrt() / col_scale[c];
            if c < n_model_cols {
                let i = flat_of[c];
                if flagged_set.contains(&c) {
                    status[i] = Status::Unidentifiable;
                } else if !smoothed[i] {
                    standard_errors[i] = Some(se);
                }
            }
        }
        if options.tracker_frame {
            let se = |c: usize| sigma_mm * vif[c].max(0.0).sqrt() / col_scale[c];
            for f in 0..n_frames {
                let b = n_model_cols + 6 * f;
                frames_se.push([
                    se(b),
                    se(b + 1),
                    se(b + 2),
                    se(b + 3).to_degrees(),
                    se(b + 4).to_degrees(),
                    se(b + 5).to_degrees(),
                ]);
            }
        }
        covariance = Some(Arc::new(super::covariance::Covariance::new(
            solution,
            col_of.clone(),
            col_scale.clone(),
            sigma_mm,
            n_cols - n_smoothed,
        )));
    }

    Ok(Fit {
        points: indices,
        residuals_mm: errors,
        stats,
        per_test,
        initial_stats,
        sigma_mm,
        parameter_names: names,
        units,
        status,
        standard_errors,
        tracker_frame: options
            .tracker_frame
            .then(|| Frame::from_isometry(&frame[0])),
        tracker_frame_standard_errors: frames_se.first().copied(),
        tracker_frames: if options.tracker_frame {
            frame.iter().map(Frame::from_isometry).collect()
        } else {
            Vec::new()
        },
        tracker_frames_standard_errors: frames_se,
        warnings,
        iterations,
        converged,
        covariance,
    })
}

fn rms_um(residuals: &[Vector3<f64>]) -> f64 {
    let n = residuals.len().max(1) as f64;
    (residuals.iter().map(|r| r.norm_squared()).sum::<f64>() / n).sqrt() * 1000.0
}

/// The smoothness row of cell `k` at position `at` of a line of `len` cells spaced `stride`
/// apart in the flat vector: a second difference inside, a first difference at the ends.
fn smoothness(k: usize, at: usize, len: usize, stride: usize, weight: f64) -> Constraint {
    let entries = if at == 0 {
        vec![(k, weight), (k + stride, -weight)]
    } else if at + 1 == len {
        vec![(k, weight), (k - stride, -weight)]
    } else {
        vec![
            (k, weight),
            (k - stride, -0.5 * weight),
            (k + stride, -0.5 * weight),
        ]
    };
    Constraint { entries }
}

/// Column norms of the data Jacobian (flat order).
fn column_norms(model: &Model, points: &[Point]) -> Vec<f64> {
    let mut sq = vec![0.0; model.n_parameters()];
    let mut scratch = JacobianScratch::default();
    let mut out = Vec::new();
    for p in points {
        model.target_jacobian_into(&p.state, &mut scratch, &mut out);
        for (i, d) in &out {
            sq[*i] += d.norm_squared();
        }
    }
    sq.into_iter().map(f64::sqrt).collect()
}

/// A direction table's cell is told apart from the own-angle table's cell only by data on
/// both branches: where the measured stops approached a cell from one direction only, `map ±
/// backlash` is all the data say, so the direction cell counts as unobserved (and is
/// smoothed) when the own-angle table of its axis is free.
fn one_sided_direction_cells(model: &Model, points: &[Point], free: &[bool], norms: &mut [f64]) {
    let ctx = model.context();
    let mut partials = Vec::new();
    for (e, effect) in model.effects().iter().enumerate() {
        let Role::DirectionDifference { axis: n, .. } = effect.role() else {
            continue;
        };
        if !free_own_angle(model, free, n) {
            continue;
        }
        let start = model.effect_start(e);
        let len = effect.values().len();
        let (mut plus, mut minus) = (vec![0.0; len], vec![0.0; len]);
        for p in points {
            partials.clear();
            effect.jacobian(&p.state, &ctx, &mut partials);
            for q in &partials {
                if q.value > 0.0 {
                    plus[q.param] += q.value;
                } else {
                    minus[q.param] -= q.value;
                }
            }
        }
        let max = plus.iter().chain(&minus).copied().fold(0.0, f64::max);
        for j in 0..len {
            if plus[j].min(minus[j]) <= 1e-6 * max {
                norms[start + j] = 0.0;
            }
        }
    }
}

/// Data weight of each parameter: the summed absolute interpolation weight over the measured
/// stops (what "the mean over the data" of a table weighs its cells by).
fn data_weights(model: &Model, points: &[Point]) -> Vec<f64> {
    let ctx = model.context();
    let mut w = vec![0.0; model.n_parameters()];
    let mut partials = Vec::new();
    for (e, effect) in model.effects().iter().enumerate() {
        let start = model.effect_start(e);
        for p in points {
            partials.clear();
            effect.jacobian(&p.state, &ctx, &mut partials);
            for q in &partials {
                w[start + q.param] += q.value.abs();
            }
        }
    }
    w
}

/// The pin rows of MODEL.md "Frames" (see the module documentation).
fn pins(
    model: &Model,
    free: &[bool],
    norms: &[f64],
    points: &[Point],
    tracker: bool,
) -> Vec<Constraint> {
    let is_free = |i: Option<usize>| i.is_some_and(|i| free[i]);
    // Whether a constant angle offset of axis n is already carried by another free parameter.
    let offset_carried = |n: u8| match n {
        1 => tracker,
        2..=5 => is_free(constant_param(model, Slot::Angle { axis: n })),
        // A6 turns the target about its axis: the target correction across it carries the
        // offset.
        _ => {
            is_free(constant_param(model, Slot::Target { coord: 1 }))
                && is_free(constant_param(model, Slot::Target { coord: 2 }))
        }
    };
    let weights = data_weights(model, points);
    let mut out = Vec::new();
    let mean_row = |cells: &[usize]| -> Option<Constraint> {
        let cells: Vec<usize> = cells.iter().copied().filter(|&i| free[i]).collect();
        let total: f64 = cells.iter().map(|&i| weights[i]).sum();
        let strength = cells.iter().map(|&i| norms[i]).fold(0.0, f64::max);
        (total > 0.0 && strength > 0.0).then(|| Constraint {
            entries: cells
                .iter()
                .filter(|&&i| weights[i] > 0.0)
                .map(|&i| (i, strength * weights[i] / total))
                .collect(),
        })
    };
    for (e, effect) in model.effects().iter().enumerate() {
        let start = model.effect_start(e);
        let len = effect.values().len();
        match effect.role() {
            Role::OwnAngle { axis: n } if offset_carried(n) => {
                out.extend(mean_row(&(start..start + len).collect::<Vec<_>>()));
            }
            Role::CrossAngle { to, .. } => {
                let map_free = free_own_angle(model, free, to);
                let Some((rows, cols)) = table_shape(model, e) else {
                    continue;
                };
                if map_free {
                    for i in 0..rows {
                        let row: Vec<usize> = (0..cols).map(|j| start + i * cols + j).collect();
                        out.extend(mean_row(&row));
                    }
                } else if offset_carried(to) {
                    out.extend(mean_row(&(start..start + len).collect::<Vec<_>>()));
                }
            }
            _ => {}
        }
    }
    out
}

/// The least-squares problem at fixed data and structure.
struct Problem<'a> {
    points: &'a [Point],
    constraints: &'a [Constraint],
    col_of: &'a [Option<usize>],
    flat_of: &'a [usize],
    col_scale: &'a [f64],
    tracker: bool,
}

impl Problem<'_> {
    /// `predicted − T·measured` per point (the negated error), base frame.
    fn residuals(&self, model: &Model, frames: &[Isometry3<f64>]) -> Vec<Vector3<f64>> {
        self.points
            .par_iter()
            .map(|p| {
                model.target_position(&p.state)
                    - (frames[p.frame] * nalgebra::Point3::from(p.measured)).coords
            })
            .collect()
    }

    fn constraint_value(&self, c: &Constraint, values: &[f64]) -> f64 {
        c.entries.iter().map(|&(i, w)| w * values[i]).sum()
    }

    fn cost(&self, model: &Model, residuals: &[Vector3<f64>]) -> f64 {
        let values = model.values();
        residuals.iter().map(|r| r.norm_squared()).sum::<f64>()
            + self
                .constraints
                .iter()
                .map(|c| self.constraint_value(c, &values).powi(2))
                .sum::<f64>()
    }

    /// The scaled, damped linear system of one Gauss–Newton step.
    fn system(
        &self,
        model: &Model,
        frames: &[Isometry3<f64>],
        residuals: &[Vector3<f64>],
        lambda: f64,
    ) -> Result<SparseLsq, LsqError> {
        let n_cols = self.col_scale.len();
        let mut lsq = SparseLsq::new(n_cols);
        let mut scratch = JacobianScratch::default();
        let mut partials = Vec::new();
        let mut row: [Vec<(usize, f64)>; 3] = Default::default();
        let frame_start = self.flat_of.len();
        for (p, r) in self.points.iter().zip(residuals) {
            model.target_jacobian_into(&p.state, &mut scratch, &mut partials);
            row.iter_mut().for_each(Vec::clear);
            for (i, d) in &partials {
                if let Some(c) = self.col_of[*i] {
                    for k in 0..3 {
                        row[k].push((c, d[k] / self.col_scale[c]));
                    }
                }
            }
            if self.tracker {
                // d(p̂ − T·m)/dδt = −I; d/dδω = [T·m]×.
                let a = (frames[p.frame] * nalgebra::Point3::from(p.measured)).coords;
                let cross = a.cross_matrix();
                let first = frame_start + 6 * p.frame;
                for k in 0..3 {
                    let c = first + k;
                    row[k].push((c, -1.0 / self.col_scale[c]));
                    for j in 0..3 {
                        let c = first + 3 + j;
                        row[k].push((c, cross[(k, j)] / self.col_scale[c]));
                    }
                }
            }
            for k in 0..3 {
                lsq.push_row(&row[k], -r[k])?;
            }
        }
        let values = model.values();
        for c in self.constraints {
            let entries: Vec<(usize, f64)> = c
                .entries
                .iter()
                .filter_map(|&(i, w)| self.col_of[i].map(|col| (col, w / self.col_scale[col])))
                .collect();
            lsq.push_row(&entries, -self.constraint_value(c, &values))?;
        }
        lsq.push_damping(&vec![lambda; n_cols])?;
        Ok(lsq)
    }

    /// The model and frames after a scaled step.
    fn apply(
        &self,
        model: &Model,
        frames: &[Isometry3<f64>],
        step: &[f64],
    ) -> (Model, Vec<Isometry3<f64>>) {
        let mut values = model.values();
        for (c, &i) in self.flat_of.iter().enumerate() {
            values[i] += step[c] / self.col_scale[c];
        }
        let mut next = model.clone();
        next.set_values(&values);
        let mut frames = frames.to_vec();
        if self.tracker {
            for (f, frame) in frames.iter_mut().enumerate() {
                let b = self.flat_of.len() + 6 * f;
                let d = |k: usize| step[b + k] / self.col_scale[b + k];
                let rotation = UnitQuaternion::from_scaled_axis(Vector3::new(d(3), d(4), d(5)));
                *frame =
                    Isometry3::from_parts(Translation3::new(d(0), d(1), d(2)), rotation) * *frame;
            }
        }
        (next, frames)
    }
}
