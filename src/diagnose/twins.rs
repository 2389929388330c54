//! Effects that are physically indistinguishable on the data: the best candidate's twins are
//! the candidates that, with the whole model re-identified around each, remove about as much
//! residual as it does: `gain(B) ≥ TWIN_SHARE · gain(A)`, `gain(X) = rss(model) −
//! rss(model + X)`, both fits over all parameters on the same data. (Fitted on top of a held
//! model, as the cross-validation does, two twins can score differently, because the held
//! tables have already taken up part of the effect in a shape only one of them can undo.)
//! The case the physics predicts: the gravity torque on A2 and A3 is a function of A2 and A3,
//! so the compliance of either and the crosstalks between them explain the same residual on a
//! campaign at one payload (the paper, section 3.2, suspects gravity behind its crosstalk).

use rayon::prelude::*;

use crate::identify::setup::{add_effects, GridChoice};
use crate::identify::{refine, RefineOptions};
use crate::measure::Stop;
use crate::model::{EffectName, Model};

/// Share of the best candidate's gain a twin must reach.
pub const TWIN_SHARE: f64 = 0.8;

/// Effects that physics makes look like `best` (its kind's
/// [`look_alikes`](crate::model::registry::Kind::look_alikes): for gravity, the compliance
/// of the axes a crosstalk joins, or the crosstalks from the arm axes onto a compliant axis).
pub fn gravity_partners(best: &EffectName) -> Vec<EffectName> {
    (best.kind.look_alikes)(best.axes)
        .iter()
        .filter_map(|n| EffectName::parse(n).ok())
        .collect()
}

/// Sum of squared residuals (mm²) after re-identifying every parameter of `model` plus
/// `extra` on `stops`; `None` when the fit fails.
fn refit_rss(
    model: &Model,
    stops: &[Stop],
    extra: Option<&EffectName>,
    grid: &GridChoice,
) -> Option<f64> {
    let mut m = model.clone();
    if let Some(name) = extra {
        add_effects(&mut m, &[*name], stops, grid).ok()?;
    }
    let options = RefineOptions {
        standard_errors: false,
        // The model starts at its identified values and the added effect enters almost
        // linearly: a few steps reach the minimum.
        max_iterations: 4,
        ..RefineOptions::default()
    };
    let fit = refine(&mut m, stops, &options).ok()?;
    Some(fit.residuals_mm.iter().map(|r| r.norm_squared()).sum())
}

/// Those of `others` that are twins of `best` on `stops` (measured, base frame), each with its
/// gain relative to `best`'s (`gain(X) / gain(best)`, once the model is re-identified around
/// each). The fits run in parallel.
pub fn twins(
    model: &Model,
    stops: &[Stop],
    best: &EffectName,
    others: &[EffectName],
    grid: &GridChoice,
) -> Vec<(String, f64)> {
    let others: Vec<&EffectName> = others.iter().filter(|o| *o != best).collect();
    if others.is_empty() {
        return Vec::new();
    }
    let mut fits: Vec<Option<&EffectName>> = vec![None, Some(best)];
    fits.extend(others.iter().map(|o| Some(*o)));
    let rss: Vec<Option<f64>> = fits
        .par_iter()
        .map(|extra| refit_rss(model, stops, *extra, grid))
        .collect();
    let (Some(base), Some(with_best)) = (rss[0], rss[1]) else {
        return Vec::new();
    };
    let gain = base - with_best;
    if gain <= 0.0 {
        return Vec::new();
    }
    others
        .iter()
        .zip(&rss[2..])
        .filter_map(|(o, r)| {
            let g = base - (*r)?;
            (g >= TWIN_SHARE * gain).then(|| (o.to_string(), g / gain))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: Vec<EffectName>) -> Vec<String> {
        v.iter().map(|n| n.to_string()).collect()
    }

    #[test]
    fn gravity_partners_of_crosstalk_and_compliance() {
        let p = |s: &str| names(gravity_partners(&EffectName::parse(s).unwrap()));
        assert_eq!(p("crosstalk:A2->A3"), ["compliance:A3", "compliance:A2"]);
        assert_eq!(p("compliance:A2"), ["crosstalk:A3->A2"]);
        assert_eq!(p("compliance:A5"), ["crosstalk:A2->A5", "crosstalk:A3->A5"]);
        assert!(p("tilt:A1").is_empty());
    }
}
