//! Effects that are physically indistinguishable on the data. Two candidates that both act
//! through axis n's angle (backlash, crosstalk onto n, compliance of n, map) are twins when,
//! with the whole model re-identified around each, the one removes about as much residual as
//! the other: `gain(B) ≥ TWIN_SHARE · gain(A)`, `gain(X) = rms²(model) − rms²(model + X)`,
//! both fits over all parameters on the same data. (Fitted on top of a held model, as the
//! cross-validation does, they can differ more, because the held tables have already taken up
//! part of the effect in a shape only one of them can undo.) The case the physics predicts:
//! the gravity torque on A3 is a function of A2 and A3, so `compliance:A3` and
//! `crosstalk:A2->A3` explain the same residual.

use crate::identify::setup::{add_effects, GridChoice};
use crate::identify::{refine, RefineOptions};
use crate::measure::Stop;
use crate::model::registry::Axes;
use crate::model::{EffectName, Model};

/// Share of the best candidate's gain a twin must reach.
pub const TWIN_SHARE: f64 = 0.8;

/// The axis whose angle an effect moves, for the kinds that act only through it.
pub fn angle_axis(name: &EffectName) -> Option<u8> {
    match (name.kind.prefix, name.axes) {
        ("map" | "backlash" | "compliance", Axes::One(n)) => Some(n),
        ("crosstalk", Axes::Pair { to, .. }) => Some(to),
        _ => None,
    }
}

/// Sum of squared residuals (mm²) after re-identifying every parameter of `model` plus
/// `extra` on `stops`; `None` when the fit fails.
fn refit_rss(model: &Model, stops: &[Stop], extra: Option<&EffectName>) -> Option<f64> {
    let mut m = model.clone();
    if let Some(name) = extra {
        add_effects(&mut m, &[*name], stops, &GridChoice::default()).ok()?;
    }
    let options = RefineOptions {
        standard_errors: false,
        max_iterations: 10,
        ..RefineOptions::default()
    };
    let fit = refine(&mut m, stops, &options).ok()?;
    Some(fit.residuals_mm.iter().map(|r| r.norm_squared()).sum())
}

/// Those of `others` that are twins of `best` on `stops` (measured, base frame).
pub fn twins(
    model: &Model,
    stops: &[Stop],
    best: &EffectName,
    others: &[EffectName],
) -> Vec<String> {
    let Some(n) = angle_axis(best) else {
        return Vec::new();
    };
    let same_axis: Vec<&EffectName> = others
        .iter()
        .filter(|o| *o != best && angle_axis(o) == Some(n))
        .collect();
    if same_axis.is_empty() {
        return Vec::new();
    }
    let (Some(base), Some(with_best)) = (
        refit_rss(model, stops, None),
        refit_rss(model, stops, Some(best)),
    ) else {
        return Vec::new();
    };
    let gain = base - with_best;
    if gain <= 0.0 {
        return Vec::new();
    }
    same_axis
        .into_iter()
        .filter(|o| {
            refit_rss(model, stops, Some(o)).is_some_and(|rss| base - rss >= TWIN_SHARE * gain)
        })
        .map(|o| o.to_string())
        .collect()
}
