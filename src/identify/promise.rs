//! The promise of `identify -c OLD --effects +X` checked: that the new model predicts data it
//! has not seen better than the old one. Under the blocked plans of diagnosis
//! (`diagnose::blocks`: held-out stretches of every test, whole tests, the latest data when
//! an added effect extrapolates in time, and with several files the latest file) each model re-fits, on the points a fold may learn
//! from, its axis geometry (`geometric`) and the added effects — the old one its geometry
//! alone — and predicts the points the fold holds out; both keep their tables as identified
//! (re-fitting a table with stretches of its own axis held out leaves cells that no fold
//! point determines, which says nothing about the added effect). An added effect that depends
//! on the clock learns its window from the fold's points only. Files named for validation are
//! predicted as they are, since neither fit saw them. Where the new model predicts worse, the
//! caller warns loudly.

use rayon::prelude::*;

use crate::calibration::Calibration;
use crate::compare::{self, Row};
use crate::diagnose::blocks::{self, Plan, Scheme};
use crate::diagnose::{crossval, learn};
use crate::measure::{Measurements, Stop};
use crate::model::effects::learned::Spec;
use crate::model::{EffectName, Model};

/// Re-fit iterations per fold (both models start at their identified values; what is re-fitted
/// enters almost linearly).
const ITERATIONS: usize = 4;
/// The new model predicts worse when its RMS exceeds the old one's by this fraction.
pub const WORSE: f64 = 0.01;

/// Old against new on one kind of held-out data.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    /// What was held out, in words.
    pub held_out: String,
    pub points: usize,
    pub old_rms_um: f64,
    pub new_rms_um: f64,
}

impl Comparison {
    pub fn change(&self) -> f64 {
        if self.old_rms_um > 0.0 {
            self.new_rms_um / self.old_rms_um - 1.0
        } else {
            0.0
        }
    }
    pub fn worse(&self) -> bool {
        self.change() > WORSE
    }
}

/// The measured rows of `data` in `cal`'s base frame as identification takes them.
fn stops_of(rows: &[Row]) -> Vec<Stop> {
    rows.iter()
        .map(|r| Stop {
            test: r.test.clone(),
            state: r.state,
            measured_mm: Some(r.measured),
            line: r.line,
        })
        .collect()
}

/// RMS (µm) over the held-out points of `plan` of `model` with `free` (and `geometric`)
/// re-fitted per fold; a learned effect on the clock gets the fold's window.
fn held_out_rms(
    model: &Model,
    rows: &[Row],
    stops: &[Stop],
    plan: &Plan,
    free: &[String],
) -> Option<(f64, usize)> {
    let rows: Vec<&Row> = rows.iter().collect();
    let mut held = Vec::new();
    for (h, train) in plan.held.iter().zip(&plan.train) {
        let mut fold_model = Model::new(model.robot, model.payload, model.target_mm);
        let mut fold_free: Vec<String> = Vec::new();
        for e in model.effects() {
            let name = e.name();
            let spec = name
                .strip_prefix("learned:")
                .and_then(|s| Spec::parse(s).ok())
                .filter(learn::uses_time);
            match spec {
                Some(spec) if free.contains(&name) => {
                    let text = learn::rewindowed(&spec, &rows, train).to_string();
                    let effect = EffectName::parse(&format!("learned:{text}")).ok()?;
                    fold_model.push(effect.create(&Default::default(), &model.robot).ok()?);
                    fold_free.push(effect.to_string());
                }
                _ => {
                    fold_model.push(e.clone_model_effect());
                    if free.contains(&name) || e.role() == crate::model::Role::AxisLines {
                        fold_free.push(name);
                    }
                }
            }
        }
        let one = Plan {
            scheme: plan.scheme,
            held: vec![h.clone()],
            train: vec![train.clone()],
        };
        let after =
            crossval::held_out(&fold_model, &fold_free, stops, &one, ITERATIONS, true).ok()?;
        held.extend(after.into_iter().flatten());
    }
    Some((crossval::rms_um(&held), held.len()))
}

/// Old against new on the fit's data (blocked folds) and on `validation` files.
/// `time`: an added effect extrapolates in time (then the latest data are checked too).
pub fn check(
    old: &Calibration,
    new: &Calibration,
    data: &[Measurements],
    validation: &[Measurements],
    folds: usize,
    time: bool,
) -> Vec<Comparison> {
    let (old_rows, new_rows) = (compare::compare(old, data), compare::compare(new, data));
    let (old_stops, new_stops) = (stops_of(&old_rows), stops_of(&new_rows));
    let groups = blocks::groups(
        old_rows
            .iter()
            .map(|r| (r.source.as_str(), r.test.as_str())),
    );
    let times: Vec<f64> = old_rows.iter().map(|r| r.state.time_s).collect();
    let mut plans = vec![
        blocks::stretches(&groups, folds),
        blocks::tests(&groups, folds),
    ];
    if time {
        plans.extend(blocks::latest(&groups, &times));
    }
    let files = blocks::groups(old_rows.iter().map(|r| (r.source.as_str(), "")));
    plans.extend(blocks::later_file(&files, &times));
    let added: Vec<String> = new
        .model_ref()
        .effects()
        .iter()
        .map(|e| e.name())
        .filter(|n| !old.model_ref().effects().iter().any(|o| o.name() == *n))
        .collect();
    let mut out: Vec<Comparison> = plans
        .par_iter()
        .filter_map(|plan| {
            let (o, n) = rayon::join(
                || held_out_rms(old.model_ref(), &old_rows, &old_stops, plan, &[]),
                || held_out_rms(new.model_ref(), &new_rows, &new_stops, plan, &added),
            );
            let ((old_rms_um, points), (new_rms_um, _)) = (o?, n?);
            Some(Comparison {
                held_out: format!("{} ({} folds)", words(plan.scheme), plan.folds()),
                points,
                old_rms_um,
                new_rms_um,
            })
        })
        .collect();
    for v in validation {
        let one = std::slice::from_ref(v);
        let (o, n) = (compare::compare(old, one), compare::compare(new, one));
        let rms =
            |rows: &[Row]| crossval::rms_um(&rows.iter().map(Row::residual).collect::<Vec<_>>());
        out.push(Comparison {
            held_out: format!("{} (named for validation, in neither fit)", v.source),
            points: o.len(),
            old_rms_um: rms(&o),
            new_rms_um: rms(&n),
        });
    }
    out
}

fn words(scheme: Scheme) -> &'static str {
    match scheme {
        Scheme::Stretches => "held-out stretches of every test",
        Scheme::Tests => "whole tests held out",
        Scheme::Latest => "the latest data from the earlier",
        Scheme::Files => "the latest file from the earlier ones",
    }
}

/// The check as the CLI runs it after `identify -c OLD --effects +NAMES`: its text and whether
/// the new model predicts worse anywhere.
pub fn run(
    old: &Calibration,
    new: &Calibration,
    data: &[Measurements],
    validation: &[Measurements],
    added: &[crate::model::EffectName],
    old_name: &str,
    new_name: &str,
) -> (String, bool) {
    let time = added.iter().any(crate::diagnose::extrapolates_in_time);
    let comparisons = check(old, new, data, validation, 4, time);
    report(&comparisons, old_name, new_name)
}

/// The printed check, with a loud warning when the new model predicts any held-out data worse.
pub fn report(comparisons: &[Comparison], old_name: &str, new_name: &str) -> (String, bool) {
    let mut out = format!(
        "promise check: {old_name} → {new_name}, RMS of data the models did not learn from (µm)\n"
    );
    for c in comparisons {
        out += &format!(
            "  {:<62} {:>6} {:>8.1} → {:>6.1} {:>+6.0}%{}\n",
            c.held_out,
            c.points,
            c.old_rms_um,
            c.new_rms_um,
            100.0 * c.change(),
            if c.worse() { "  WORSE" } else { "" }
        );
    }
    let worse: Vec<&Comparison> = comparisons.iter().filter(|c| c.worse()).collect();
    if !worse.is_empty() {
        out += &format!(
            "WARNING: {new_name} predicts data it did not learn from WORSE than {old_name} ({}). \
             The added effect does not generalise on these data: keep {old_name}, or measure \
             what would tell the effect apart.\n",
            worse
                .iter()
                .map(|c| format!("{}: {:+.0}%", c.held_out, 100.0 * c.change()))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    (out, !worse.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn worse_is_more_than_one_percent_and_warns_loudly() {
        let c = |old, new| Comparison {
            held_out: "x".into(),
            points: 10,
            old_rms_um: old,
            new_rms_um: new,
        };
        assert!(!c(20.0, 20.1).worse());
        assert!(c(20.0, 20.3).worse());
        let (text, worse) = report(&[c(20.0, 10.0), c(25.8, 40.4)], "old.json", "new.json");
        assert!(worse);
        assert!(
            text.contains("-50%") && text.contains("+57%  WORSE"),
            "{text}"
        );
        assert!(text.contains("WARNING: new.json predicts data it did not learn from WORSE"));
        let (_, fine) = report(&[c(20.0, 10.0)], "a", "b");
        assert!(!fine);
    }
}
