//! Cross-validated worth of one candidate effect: the measured points are dealt into `k`
//! interleaved folds (point i in fold i mod k, so every stretch of every sweep is in every
//! fold); for each fold the candidate is added at zero to a copy of the current model and
//! fitted with only its own parameters free (`identify::refine`) on the other folds, then
//! scored on the held-out fold. Each point is predicted once by a fit that never saw it, so
//! a table with many parameters that only follows the noise predicts worse than the current
//! model, and cannot win by overfitting.
//!
//! Score: `explained = 1 − Σ|r_after|² / Σ|r_before|²` over the held-out predictions, and a
//! paired t statistic of the per-point gains `|r_before|² − |r_after|²`.

use nalgebra::Vector3;

use crate::identify::setup::{add_effects, GridChoice};
use crate::identify::{refine, Free, RefineOptions, Warning};
use crate::measure::Stop;
use crate::model::{EffectName, Model};

/// The cross-validated result for one candidate.
#[derive(Clone, Debug)]
pub struct Evaluation {
    pub name: EffectName,
    /// Parameters the candidate adds.
    pub parameters: usize,
    /// Fraction of the held-out residual sum of squares the candidate removes (negative when
    /// it makes predictions worse).
    pub explained: f64,
    /// RMS 3-D residual of the held-out predictions with the candidate, µm.
    pub rms_after_um: f64,
    /// Paired t statistic of the per-point gains.
    pub t: f64,
    /// What the candidate changes at each measured point (held-out prediction − current
    /// prediction, mm): its signature, to tell which candidates explain the same residual.
    pub correction: Vec<Vector3<f64>>,
    /// Why it could not be evaluated (no measured point depends on it, or the fit failed).
    pub not_evaluated: Option<String>,
}

/// Iterations of each fit: the candidate enters linearly to first order, so a few suffice.
const MAX_ITERATIONS: usize = 3;

/// Evaluates `name` on top of `base`. `stops` are the measured points in the base frame (one
/// per point, in order) and `before` the current residuals (measured − predicted, mm).
pub fn evaluate(
    base: &Model,
    stops: &[Stop],
    before: &[Vector3<f64>],
    name: &EffectName,
    folds: usize,
    grid: &GridChoice,
) -> Evaluation {
    let folds = folds.max(2);
    let mut result = Evaluation {
        name: *name,
        parameters: 0,
        explained: 0.0,
        rms_after_um: rms_um(before),
        t: 0.0,
        correction: vec![Vector3::zeros(); stops.len()],
        not_evaluated: None,
    };
    let mut with = base.clone();
    if let Err(e) = add_effects(&mut with, &[*name], stops, grid) {
        result.not_evaluated = Some(e);
        return result;
    }
    result.parameters = with.n_parameters() - base.n_parameters();
    let options = RefineOptions {
        free: Free::Effects(vec![name.to_string()]),
        max_iterations: MAX_ITERATIONS,
        standard_errors: false,
        ..RefineOptions::default()
    };
    let mut after = before.to_vec();
    for fold in 0..folds {
        let train: Vec<Stop> = stops
            .iter()
            .enumerate()
            .map(|(i, s)| Stop {
                measured_mm: if i % folds == fold {
                    None
                } else {
                    s.measured_mm
                },
                ..s.clone()
            })
            .collect();
        let mut model = with.clone();
        match refine(&mut model, &train, &options) {
            Ok(fit) => {
                if let Some(w) = fit
                    .warnings
                    .iter()
                    .find(|w| matches!(w, Warning::Unobserved { .. }))
                {
                    result.not_evaluated = Some(w.to_string());
                    return result;
                }
            }
            Err(e) => {
                result.not_evaluated = Some(e.to_string());
                return result;
            }
        }
        for i in (fold..stops.len()).step_by(folds) {
            let Some(measured) = stops[i].measured_mm else {
                continue;
            };
            after[i] = measured - model.target_position(&stops[i].state);
            result.correction[i] = before[i] - after[i];
        }
    }
    let gains: Vec<f64> = before
        .iter()
        .zip(&after)
        .map(|(b, a)| b.norm_squared() - a.norm_squared())
        .collect();
    let total: f64 = before.iter().map(|b| b.norm_squared()).sum();
    result.explained = if total > 0.0 {
        gains.iter().sum::<f64>() / total
    } else {
        0.0
    };
    result.rms_after_um = rms_um(&after);
    result.t = t_statistic(&gains);
    result
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
}
