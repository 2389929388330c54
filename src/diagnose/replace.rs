//! A candidate that takes the place of effects of the model (a gear play under load,
//! `loadplay:An`, for the play table `backlash:An` of the same axis) judged as its printed
//! command identifies it: the whole model re-identified with it in their place, against the
//! model re-identified alone, on the same points. Fitted alone on top of the held model, as
//! the cross-validation does, such a candidate loses: the held tables have taken up the
//! effect in the only shape the replaced effect could give it (a flank held by the torque is
//! an offset of the axis's own table in its indexing test), and counted twice it predicts
//! worse. Refitting those tables on part of a sweep does not help either — a table of
//! one-degree cells cannot predict the stretch it did not see, whatever else is in the model.
//!
//! The re-identified gain is measured on the points both fits learnt from, so it counts only
//! for a candidate with fewer parameters than the effects it replaces (its own values and
//! those it sets from the data, [`parameters_of`]): a smaller model that fits better is the
//! better model by any information criterion, and cannot have bought its fit with freedom.
//! The gain must be plain ([`super::MIN_REPLACING_EXPLAINED`] of the residual); the per-point
//! gains, grouped by whole tests, are reported but not required to spread: the effect lives
//! in the tests where its axis's torque changes sign. The advice is then identified as printed
//! (`diagnose::follow`) like any other.

use nalgebra::Vector3;

use super::blocks::Plan;
use super::crossval::{self, Evaluation, Score};
use crate::identify::setup::{add_effects, GridChoice};
use crate::identify::{refine, RefineOptions};
use crate::measure::Stop;
use crate::model::{EffectName, Model, ModelEffect};

/// Iterations of each re-identification: the model starts at its identified values and the
/// replacement enters almost linearly.
const MAX_ITERATIONS: usize = 4;

/// The values an effect carries: those a fit moves and those it sets from the data (a gear
/// play under load fits its width and searches its friction and counterbalance).
pub fn parameters_of(effect: &dyn ModelEffect) -> usize {
    let record = effect.record();
    let named = record.parameters.map_or(0, |p| p.len());
    effect.values().len().max(named)
}

/// Residuals (measured − predicted, mm) of `model` re-identified on `stops`, one per stop.
fn refit(model: &mut Model, stops: &[Stop]) -> Option<Vec<Vector3<f64>>> {
    let fit = refine(model, stops, &refit_options()).ok()?;
    (fit.residuals_mm.len() == stops.len()).then_some(fit.residuals_mm)
}

fn refit_options() -> RefineOptions {
    RefineOptions {
        standard_errors: false,
        max_iterations: MAX_ITERATIONS,
        ..RefineOptions::default()
    }
}

/// `model` with `name` in place of the effects it [`crossval::replaced`], the names of those,
/// the values they carried and the candidate's; `None` when it replaces nothing, is not shown
/// by `stops`, does not have fewer parameters than what it replaces, or cannot be set up.
fn replacing_model(
    model: &Model,
    stops: &[Stop],
    name: &EffectName,
    grid: &GridChoice,
) -> Option<(Model, Vec<String>, usize, usize)> {
    let gone = crossval::replaced(model, name);
    if gone.is_empty() {
        return None;
    }
    let mut with = Model::new(model.robot, model.payload, model.target_mm);
    for e in model.effects().iter().filter(|e| !gone.contains(&e.name())) {
        with.push(e.clone_model_effect());
    }
    add_effects(&mut with, &[*name], stops, grid).ok()?;
    let canonical = name.to_string();
    let added = with.effects().iter().find(|e| e.name() == canonical)?;
    if added.not_shown_by_data().is_some() {
        return None;
    }
    let removed: usize = model
        .effects()
        .iter()
        .filter(|e| gone.contains(&e.name()))
        .map(|e| parameters_of(e.as_ref()))
        .sum();
    let parameters = parameters_of(added.as_ref());
    if parameters >= removed {
        return None;
    }
    Some((with, gone, removed, parameters))
}

/// `name` re-identified in place of the effects of `model` it [`crossval::replaced`], scored
/// against `model` re-identified on the same `stops` (per-point gains grouped by the whole
/// tests of `tests`); `None` when it replaces nothing, does not have fewer parameters than
/// what it replaces, or a fit fails.
pub fn evaluate(
    model: &Model,
    stops: &[Stop],
    name: &EffectName,
    tests: &Plan,
    grid: &GridChoice,
) -> Option<Evaluation> {
    let (mut with, gone, removed, parameters) = replacing_model(model, stops, name, grid)?;
    let mut held = model.clone();
    let before = refit(&mut held, stops)?;
    let after = refit(&mut with, stops)?;
    let plan = Plan {
        scheme: tests.scheme,
        held: tests.held.clone(),
        train: vec![vec![true; stops.len()]; tests.held.len()],
    };
    let predicted: Vec<Option<Vector3<f64>>> = after.iter().copied().map(Some).collect();
    let score = Score::new(&plan, &before, &predicted);
    Some(Evaluation {
        name: *name,
        parameters,
        explained: score.explained,
        rms_after_um: crossval::rms_um(&after),
        t: score.t,
        within: Some(score),
        checks: Vec::new(),
        correction: before.iter().zip(&after).map(|(b, a)| b - a).collect(),
        not_evaluated: None,
        reidentified: Some(Reidentified {
            replaced: gone,
            removed_parameters: removed,
            rms_before_um: crossval::rms_um(&before),
        }),
        partialled: false,
    })
}

/// How a candidate was judged re-identified in place of what it replaces.
#[derive(Clone, Debug, PartialEq)]
pub struct Reidentified {
    /// The effects of the model it took the place of.
    pub replaced: Vec<String>,
    /// The values those carried.
    pub removed_parameters: usize,
    /// RMS 3-D residual of the model re-identified alone on the same points, µm.
    pub rms_before_um: f64,
}

/// Under `plan` (whole files: the latest learnt from the earlier ones), the model
/// re-identified with `name` in its place against the model re-identified alone, both on the
/// training points, scored on the held-out points; `None` as [`evaluate`].
pub fn on_plan(
    model: &Model,
    stops: &[Stop],
    name: &EffectName,
    plan: &Plan,
    grid: &GridChoice,
) -> Option<Score> {
    let (with, ..) = replacing_model(model, stops, name, grid)?;
    let mut before = vec![Vector3::zeros(); stops.len()];
    let mut after = vec![None; stops.len()];
    for (held, train) in plan.held.iter().zip(&plan.train) {
        let training = crossval::training(stops, train);
        let (mut alone, mut replaced) = (model.clone(), with.clone());
        refine(&mut alone, &training, &refit_options()).ok()?;
        refine(&mut replaced, &training, &refit_options()).ok()?;
        for &i in held {
            if let Some(m) = stops[i].measured_mm {
                before[i] = m - alone.target_position(&stops[i].state);
                after[i] = Some(m - replaced.target_position(&stops[i].state));
            }
        }
    }
    Some(Score::new(plan, &before, &after))
}
