//! Cross-validated worth of one candidate effect under a blocked plan ([`super::blocks`]): for
//! each fold the candidate is added at zero to a copy of the current model (in place of the
//! effects it [`replaced`]) and fitted with only
//! its own parameters free (`identify::refine`) on the points the fold may learn from, then
//! predicts the points it holds out. Each held-out point is predicted by a fit that saw neither
//! it nor its neighbours in time, so a table with many parameters that only follows the noise,
//! or an effect that explains each test's own offsets, predicts worse than the current model
//! and cannot win.
//!
//! Score ([`Score`]): `explained = 1 − Σ|r_after|² / Σ|r_before|²` over the held-out
//! predictions, a paired t statistic of the per-point gains `|r_before|² − |r_after|²`, and the
//! share of the residual each fold's gain removes — its stability: a gain that one fold carries
//! is not a finding.

use nalgebra::Vector3;
use serde::Serialize;

use super::blocks::{Plan, Scheme};
use crate::identify::setup::{add_effects, GridChoice, SetupError};
use crate::identify::{refine, Free, IdentifyError, RefineOptions, Warning};
use crate::measure::Stop;
use crate::model::{EffectName, GridOptions, Model};

/// Why a candidate could not be scored.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum NotEvaluated {
    /// The candidate could not be added to the model (its tables do not fit the data).
    #[error("{0}")]
    Candidate(#[from] SetupError),
    /// A fold's fit failed.
    #[error("{0}")]
    Fit(#[from] IdentifyError),
    /// A fold's training points do not observe the candidate.
    #[error("{0}")]
    Unobserved(Warning),
    /// The data do not show the candidate apart from a simpler effect of the table.
    #[error("{0}")]
    NotShown(String),
}

/// Iterations of each fit: the candidate enters linearly to first order, so a few suffice.
const MAX_ITERATIONS: usize = 3;
/// A stable gain: positive in all folds but at most one, and no fold carrying more than this
/// share of it.
pub const MAX_FOLD_SHARE: f64 = 0.6;
/// Significantly worse: a t statistic of the gains at or below this, …
pub const WORSE_T: f64 = -2.0;
/// … or a loss of more than this fraction of the residual whatever its t.
pub const WORSE_EXPLAINED: f64 = -0.02;

/// The held-out score of one candidate under one scheme.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Score {
    /// How the held-out points were chosen.
    pub scheme: Scheme,
    /// Fraction of the held-out residual sum of squares removed (negative: worse).
    pub explained: f64,
    /// RMS 3-D residual of the held-out points before, µm …
    pub rms_before_um: f64,
    /// … and after, µm.
    pub rms_after_um: f64,
    /// Paired t statistic of the per-point gains.
    pub t: f64,
    /// Per fold, the fraction of that fold's residual sum of squares removed.
    pub fold_explained: Vec<f64>,
    /// Share of the total gain carried by the fold that gains most (1/folds: evenly spread;
    /// 1: all in one fold).
    pub best_fold_share: f64,
    /// Held-out points scored.
    pub points: usize,
}

impl Score {
    /// Scores held-out predictions `after` (`None`: not predicted) against `before`.
    #[cfg_attr(feature = "internals", visibility::make(pub))]
    pub(crate) fn new(
        plan: &Plan,
        before: &[Vector3<f64>],
        after: &[Option<Vector3<f64>>],
    ) -> Score {
        let mut gains = Vec::new();
        let (mut ss_before, mut ss_after) = (0.0, 0.0);
        let mut fold_gain = Vec::new();
        let mut fold_explained = Vec::new();
        for held in &plan.held {
            let (mut g, mut ss) = (0.0, 0.0);
            for &i in held {
                let Some(a) = after[i] else { continue };
                let (b2, a2) = (before[i].norm_squared(), a.norm_squared());
                gains.push(b2 - a2);
                ss_before += b2;
                ss_after += a2;
                g += b2 - a2;
                ss += b2;
            }
            fold_gain.push(g);
            fold_explained.push(if ss > 0.0 { g / ss } else { 0.0 });
        }
        let total: f64 = fold_gain.iter().sum();
        let best = fold_gain.iter().copied().fold(0.0, f64::max);
        let n = gains.len().max(1) as f64;
        Score {
            scheme: plan.scheme,
            explained: if ss_before > 0.0 {
                1.0 - ss_after / ss_before
            } else {
                0.0
            },
            rms_before_um: (ss_before / n).sqrt() * 1000.0,
            rms_after_um: (ss_after / n).sqrt() * 1000.0,
            t: t_statistic(&gains),
            fold_explained,
            best_fold_share: if total > 0.0 { best / total } else { 1.0 },
            points: gains.len(),
        }
    }

    /// The gain holds across the folds (see [`MAX_FOLD_SHARE`]).
    pub fn stable(&self) -> bool {
        let losing = self.fold_explained.iter().filter(|e| **e <= 0.0).count();
        losing <= 1 && self.best_fold_share <= MAX_FOLD_SHARE
    }

    /// The candidate predicts these held-out points worse than the current model.
    pub fn worse(&self) -> bool {
        self.explained < 0.0 && (self.t <= WORSE_T || self.explained < WORSE_EXPLAINED)
    }

    /// "explains 12% (stable over 4 folds)" or "… worse: −8%".
    pub fn describe(&self) -> String {
        // A fit that extrapolates wildly is worse by a factor, not by a percentage of the sum
        // of squares nobody can read.
        let share = if self.explained > -9.0 {
            format!("{:+.0}%", 100.0 * self.explained)
        } else {
            format!(
                "{:.0} times the error",
                self.rms_after_um / self.rms_before_um.max(f64::MIN_POSITIVE)
            )
        };
        format!(
            "{share} on {} ({:.1} → {:.1} µm RMS)",
            self.scheme.describe(),
            self.rms_before_um,
            self.rms_after_um
        )
    }
}

/// The cross-validated result for one candidate.
#[derive(Clone, Debug)]
pub struct Evaluation {
    pub name: EffectName,
    /// Parameters the candidate adds.
    pub parameters: usize,
    /// Fraction of the held-out residual sum of squares the candidate removes on the main
    /// plan (negative when it makes predictions worse).
    pub explained: f64,
    /// RMS 3-D residual of the held-out predictions with the candidate, µm.
    pub rms_after_um: f64,
    /// Paired t statistic of the per-point gains.
    pub t: f64,
    /// The main plan's score.
    pub within: Option<Score>,
    /// Scores on the checks: whole tests held out, the latest data (for effects that
    /// extrapolate in time).
    pub checks: Vec<Score>,
    /// What the candidate changes at each measured point (held-out prediction − current
    /// prediction, mm): its signature, to tell which candidates explain the same residual.
    pub correction: Vec<Vector3<f64>>,
    /// Why it could not be evaluated (no measured point depends on it, or the fit failed).
    pub not_evaluated: Option<NotEvaluated>,
    /// Set when the score is of the whole model re-identified with it in place of the
    /// effects it replaces ([`super::replace`]), not of held-out predictions.
    pub reidentified: Option<super::replace::Reidentified>,
    /// Set when the scores are of the candidate with the model's tables re-fitted beside it
    /// ([`super::learn::EffectScreen`]): fitted alone on top of them it lost.
    pub partialled: bool,
}

impl Evaluation {
    /// The check of `scheme`, if it ran.
    pub fn check(&self, scheme: Scheme) -> Option<&Score> {
        self.checks.iter().find(|s| s.scheme == scheme)
    }
}

/// The effects of `base` that the candidate `name` takes the place of: those that describe
/// only the rotation direction of axes whose direction the candidate describes
/// ([`Effect::direction_axes`](crate::model::Effect)). A gear play tried on a model with an
/// instant switch of sign must replace the switch: added to it at zero, the play's first
/// linearisation is the switch itself and the fit cannot leave it.
pub fn replaced(base: &Model, name: &EffectName) -> Vec<String> {
    let axes = name
        .create(&GridOptions::default(), &base.robot)
        .map(|e| e.direction_axes())
        .unwrap_or_default();
    if axes.is_empty() {
        return Vec::new();
    }
    base.effects()
        .iter()
        .filter(|e| {
            let own = e.direction_axes();
            !own.is_empty() && own.iter().all(|a| axes.contains(a))
        })
        .map(|e| e.name())
        .collect()
}

/// `base` with `name` added at zero in place of the effects it [`replaced`], and the number
/// of parameters that adds.
fn with_candidate(
    base: &Model,
    stops: &[Stop],
    name: &EffectName,
    grid: &GridChoice,
) -> Result<(Model, usize), NotEvaluated> {
    let gone = replaced(base, name);
    let mut with = Model::new(base.robot, base.payload, base.target_mm);
    for e in base.effects().iter().filter(|e| !gone.contains(&e.name())) {
        with.push(e.clone_model_effect());
    }
    add_effects(&mut with, &[*name], stops, grid)?;
    let canonical = name.to_string();
    let why = with
        .effects()
        .iter()
        .find(|e| e.name() == canonical)
        .and_then(|e| e.not_shown_by_data());
    if let Some(why) = why {
        return Err(NotEvaluated::NotShown(why));
    }
    let added = with.n_parameters() as isize - base.n_parameters() as isize;
    Ok((with, added.max(0) as usize))
}

/// Held-out predictions of `with` (fitting only `free`) under `plan`: the residual of every
/// held-out point, `None` elsewhere. An effect the training points do not observe stays at
/// zero for that fold when `unobserved_is_zero`; otherwise it is an error.
pub fn held_out(
    with: &Model,
    free: &[String],
    stops: &[Stop],
    plan: &Plan,
    max_iterations: usize,
    unobserved_is_zero: bool,
) -> Result<Vec<Option<Vector3<f64>>>, NotEvaluated> {
    let fallback = unobserved_is_zero.then_some(with);
    held_out_or(with, free, stops, plan, max_iterations, fallback)
}

/// [`held_out`], a fold whose training points do not observe the effect predicted by
/// `fallback` (the current model) when given, else an error.
fn held_out_or(
    with: &Model,
    free: &[String],
    stops: &[Stop],
    plan: &Plan,
    max_iterations: usize,
    fallback: Option<&Model>,
) -> Result<Vec<Option<Vector3<f64>>>, NotEvaluated> {
    let options = RefineOptions {
        free: Free::Effects(free.to_vec()),
        max_iterations,
        standard_errors: false,
        ..RefineOptions::default()
    };
    let mut after = vec![None; stops.len()];
    for (held, train) in plan.held.iter().zip(&plan.train) {
        let training = training(stops, train);
        let mut model = with.clone();
        let fit = refine(&mut model, &training, &options)?;
        if let Some(w) = fit
            .warnings
            .iter()
            .find(|w| matches!(w, Warning::Unobserved { .. }))
        {
            match fallback {
                Some(current) => model = current.clone(),
                None => return Err(NotEvaluated::Unobserved(w.clone())),
            }
        }
        for &i in held {
            if let Some(measured) = stops[i].measured_mm {
                after[i] = Some(measured - model.target_position(&stops[i].state));
            }
        }
    }
    Ok(after)
}

/// `stops` with the measurement of every point a fold may not learn from taken away.
pub fn training(stops: &[Stop], train: &[bool]) -> Vec<Stop> {
    stops
        .iter()
        .zip(train)
        .map(|(s, &t)| Stop {
            measured_mm: if t { s.measured_mm } else { None },
            ..s.clone()
        })
        .collect()
}

/// Evaluates `name` on top of `base` under `plan`. `stops` are the measured points in the
/// base frame (one per point, in order) and `before` the current residuals (measured −
/// predicted, mm).
pub fn evaluate(
    base: &Model,
    stops: &[Stop],
    before: &[Vector3<f64>],
    name: &EffectName,
    plan: &Plan,
    grid: &GridChoice,
) -> Evaluation {
    let mut result = Evaluation {
        name: *name,
        parameters: 0,
        explained: 0.0,
        rms_after_um: rms_um(before),
        t: 0.0,
        within: None,
        checks: Vec::new(),
        correction: vec![Vector3::zeros(); stops.len()],
        not_evaluated: None,
        reidentified: None,
        partialled: false,
    };
    let (with, added) = match with_candidate(base, stops, name, grid) {
        Ok(w) => w,
        Err(e) => {
            result.not_evaluated = Some(e);
            return result;
        }
    };
    result.parameters = added;
    let after = match held_out(
        &with,
        &[name.to_string()],
        stops,
        plan,
        MAX_ITERATIONS,
        false,
    ) {
        Ok(a) => a,
        Err(e) => {
            result.not_evaluated = Some(e);
            return result;
        }
    };
    for (i, a) in after.iter().enumerate() {
        if let Some(a) = a {
            result.correction[i] = before[i] - a;
        }
    }
    let score = Score::new(plan, before, &after);
    let full: Vec<Vector3<f64>> = after
        .iter()
        .zip(before)
        .map(|(a, b)| a.unwrap_or(*b))
        .collect();
    result.explained = score.explained;
    result.t = score.t;
    result.rms_after_um = rms_um(&full);
    result.within = Some(score);
    result
}

/// The score of `name` on top of `base` under another `plan` (a check of a candidate the main
/// plan found); folds whose training points do not observe it leave it at zero.
pub fn check(
    base: &Model,
    stops: &[Stop],
    before: &[Vector3<f64>],
    name: &EffectName,
    plan: &Plan,
    grid: &GridChoice,
) -> Result<Score, NotEvaluated> {
    let (with, _) = with_candidate(base, stops, name, grid)?;
    let after = held_out_or(
        &with,
        &[name.to_string()],
        stops,
        plan,
        MAX_ITERATIONS,
        Some(base),
    )?;
    Ok(Score::new(plan, before, &after))
}

pub fn rms_um(residuals: &[Vector3<f64>]) -> f64 {
    if residuals.is_empty() {
        return 0.0;
    }
    (residuals.iter().map(|r| r.norm_squared()).sum::<f64>() / residuals.len() as f64).sqrt()
        * 1000.0
}

/// `mean / (sd / √n)`; 0 for fewer than two values or no spread.
pub fn t_statistic(values: &[f64]) -> f64 {
    let n = values.len() as f64;
    if values.len() < 2 {
        return 0.0;
    }
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    if var > 0.0 {
        mean / (var / n).sqrt()
    } else {
        0.0
    }
}

/// Cosine similarity of two candidates' corrections over all points: near 1 when they
/// explain the same residual.
pub fn similarity(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(x, y)| x.dot(y)).sum();
    let na: f64 = a.iter().map(|x| x.norm_squared()).sum();
    let nb: f64 = b.iter().map(|x| x.norm_squared()).sum();
    if na > 0.0 && nb > 0.0 {
        dot / (na * nb).sqrt()
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_statistic_and_similarity_by_hand() {
        // mean 2, sample sd 1 (values 1, 2, 3), n = 3: t = 2 / (1/√3) = 2√3.
        assert!((t_statistic(&[1.0, 2.0, 3.0]) - 2.0 * 3f64.sqrt()).abs() < 1e-12);
        let a = [Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 1.0, 0.0)];
        let b = [Vector3::new(2.0, 0.0, 0.0), Vector3::new(0.0, 2.0, 0.0)];
        let c = [Vector3::new(0.0, 1.0, 0.0), Vector3::new(-1.0, 0.0, 0.0)];
        assert!((similarity(&a, &b) - 1.0).abs() < 1e-12);
        assert!(similarity(&a, &c).abs() < 1e-12);
    }

    #[test]
    fn score_per_fold_and_stability_by_hand() {
        // Two folds of two points; residual 2 mm along x everywhere (|r|² = 4). Fold 0 is
        // predicted to 1 mm (gain 3 per point), fold 1 to 2 mm (no gain).
        let plan = Plan {
            scheme: Scheme::Stretches,
            held: vec![vec![0, 1], vec![2, 3]],
            train: vec![
                vec![false, false, true, true],
                vec![true, true, false, false],
            ],
        };
        let before = vec![Vector3::new(2.0, 0.0, 0.0); 4];
        let after: Vec<Option<Vector3<f64>>> = vec![
            Some(Vector3::new(1.0, 0.0, 0.0)),
            Some(Vector3::new(1.0, 0.0, 0.0)),
            Some(Vector3::new(2.0, 0.0, 0.0)),
            Some(Vector3::new(2.0, 0.0, 0.0)),
        ];
        let s = Score::new(&plan, &before, &after);
        // Σ before 16, Σ after 4 + 8 = 10: explained 6/16.
        assert!((s.explained - 6.0 / 16.0).abs() < 1e-12);
        assert_eq!(s.fold_explained, [0.75, 0.0]);
        // All of the gain in one fold: not stable.
        assert_eq!(s.best_fold_share, 1.0);
        assert!(!s.stable());
        assert!((s.rms_before_um - 2000.0).abs() < 1e-9);
        assert!((s.rms_after_um - (10.0f64 / 4.0).sqrt() * 1000.0).abs() < 1e-9);
        // Both folds gain alike: stable.
        let even: Vec<Option<Vector3<f64>>> = vec![Some(Vector3::new(1.0, 0.0, 0.0)); 4];
        assert!(Score::new(&plan, &before, &even).stable());
        // Worse everywhere by a lot: worse.
        let bad: Vec<Option<Vector3<f64>>> = vec![Some(Vector3::new(3.0, 0.0, 0.0)); 4];
        assert!(Score::new(&plan, &before, &bad).worse());
    }
}
