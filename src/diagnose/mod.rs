//! Diagnosis: which physical effect is the model missing? From the current calibration's
//! residuals it estimates the noise floor ([`noise`], exact copies of rows left out), tries every
//! effect of the contract table the calibration lacks ([`candidates`]) by fitting it alone on
//! top of the current model and scoring it on data the fit has not seen ([`crossval`] under the
//! blocked plans of [`blocks`]: held-out stretches of every test; a finding is then checked on
//! whole tests it did not learn from, an effect that extrapolates in time on the latest
//! data — advised only where the data tell time from pose ([`clock`]) — and, given several
//! files, every finding on the latest file learnt from the earlier ones: advice that does not
//! lower the error on data measured later is not given), ranks them by how much of the residual they explain, words the evidence from the data
//! ([`evidence`]) with the command that adds the effect, and learns from the residual which
//! generic drivers carry what the table cannot explain ([`learn`]), as an effect the user can
//! add (`learned:…`). A finding must be significant, stable across the folds and no worse
//! elsewhere; when none is, the verdict says whether the residual is at the noise floor or
//! where it lives. Large campaigns are screened on a sample ([`sample`]).

pub mod blocks;
pub mod candidates;
pub mod clock;
pub mod crossval;
pub mod evidence;
pub mod learn;
pub mod noise;
pub mod play;
pub mod replace;
pub mod sample;
pub mod twins;
pub mod validate;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use crate::calibration::Calibration;
use crate::compare::{self, Row};
use crate::identify::setup::GridChoice;
use crate::measure::{Measurements, Stop};
use crate::model::{EffectName, Model};

use blocks::{Plan, Scheme};
pub use crossval::{Evaluation, Score};
pub use learn::LearnedDrivers;
pub use noise::{NoiseFloor, NoiseSource};

/// A progress callback: (stage, done, of).
pub type ProgressFn = dyn Fn(&str, usize, usize) + Send + Sync;

/// Reports progress: (stage, done, of).
#[derive(Clone)]
pub struct ProgressSink(pub Arc<ProgressFn>);

impl std::fmt::Debug for ProgressSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ProgressSink")
    }
}

impl PartialEq for ProgressSink {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Choices of a diagnosis.
#[derive(Clone, Debug, PartialEq)]
pub struct DiagnoseOptions {
    /// Folds of the cross-validation.
    pub folds: usize,
    /// Effects to try; `None`: every effect of the table the calibration lacks.
    pub only: Option<Vec<EffectName>>,
    /// Learn the drivers of the residual (a `learned:` effect).
    pub learn: bool,
    /// Most points the candidates are screened on (default 6,000).
    pub max_screened: usize,
    /// Called as the work goes on (the command line's progress bar); `None`: silent.
    pub progress: Option<ProgressSink>,
    /// The laser tracker's stated accuracy and station (`--tracker`, `--tracker-at`).
    pub tracker: crate::measure::tracker::Tracker,
    /// Validation files measured elsewhere and later (`--validate`): the first advice is
    /// credited with its gain on them and not given where it does not lower their error.
    pub validate: Vec<Measurements>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            folds: 4,
            only: None,
            learn: true,
            max_screened: sample::MAX_SCREENED,
            progress: None,
            tracker: Default::default(),
            validate: Vec::new(),
        }
    }
}

/// A finding must remove at least this fraction of the held-out residual sum of squares …
pub const MIN_EXPLAINED: f64 = 0.01;
/// … with a paired t statistic of the per-point gains at least this large (a missing effect
/// on a campaign gives 7 to 20; on data without one every candidate stays under 2) …
pub const MIN_T: f64 = 5.0;
/// … and lower the RMS by at least this much, µm …
pub const MIN_RMS_GAIN_UM: f64 = 0.1;
/// … and, for an effect that extrapolates in time, predict the latest data better by this
/// t statistic.
pub const MIN_LATEST_T: f64 = 2.0;
/// A candidate re-identified in place of effects it replaces, with fewer parameters, must
/// remove at least this share of the residual the model re-identified alone leaves.
pub const MIN_REPLACING_EXPLAINED: f64 = 0.05;
/// Most parameters of a candidate scored with the model's tables re-fitted beside it: a
/// physical law with a few values (a compliance, a wobble, a drift) whose shape a table can
/// half take up; a table of its own is judged fitted on top.
pub const MAX_PARTIALLED_PARAMETERS: usize = 12;
/// Two findings whose corrections agree this closely (cosine) explain the same residual.
pub const SAME_RESIDUAL: f64 = 0.9;
/// A significant candidate scoring at least this share of the best's `explained` on top of
/// the held model may be its twin once both are re-identified.
pub const TWIN_CLOSE: f64 = 0.5;
/// Most candidates re-identified as possible twins of the best (the close ones and the
/// gravity partners, strongest first): each is a full identification.
pub const MAX_TWIN_FITS: usize = 4;
/// A residual within this factor of the noise floor is "at the noise floor" (the tracker's
/// specification is a rough guide to one set-up's noise, good to some tens of percent).
pub const AT_FLOOR: f64 = 1.5;
/// Tests named as where the residual lives: those carrying this share of it, at most three.
const WHERE_SHARE: f64 = 0.5;

/// One evaluated effect (CONTRACTS.md keys first).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// The effect (contract name, e.g. `crosstalk:A3>A2`).
    pub effect: String,
    /// Fraction of the held-out residual sum of squares it removes (0..1; negative: worse).
    pub explained: f64,
    /// RMS 3-D residual of the held-out predictions with it, µm.
    pub rms_after_um: f64,
    /// What in the residual points to it, in words (the effect's own evidence sentence).
    pub evidence: String,
    /// The `identify` option that adds it.
    pub add: String,
    /// It passes every test a finding must pass (gain, t statistic, stability, checks).
    pub significant: bool,
    /// t statistic of its gain over the held-out stretches.
    pub t_statistic: f64,
    /// Parameters it adds to the model.
    pub parameters: usize,
    /// The gain holds in every fold but at most one, no fold carrying most of it.
    pub stable: bool,
    /// Per fold of the held-out stretches, the fraction of its residual removed.
    pub fold_explained: Vec<f64>,
    /// The checks it went through: whole tests held out, the latest data.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub checks: Vec<Score>,
    /// Why it is not a finding although it explains part of the held-out stretches.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vetoed: Option<String>,
    /// Effects that explain the same residual on these data (physically indistinguishable
    /// here); either may be the cause.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub indistinguishable_from: Vec<String>,
    /// Why it could not be evaluated (then it is not significant).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_evaluated: Option<String>,
    /// With `--validate`: the advice identified as printed, on the validation files.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation: Option<validate::ValidationGain>,
}

/// One test's part of the residual.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TestShare {
    /// The test's label (the CSV's `test` column).
    pub test: String,
    /// Its measured points.
    pub points: usize,
    /// Its RMS 3-D residual, µm.
    pub rms_um: f64,
    /// Its share of the residual sum of squares.
    pub share: f64,
}

/// The result of [`crate::diagnose()`] (`diagnose --json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnosis {
    /// RMS 3-D residual of the current model, µm.
    pub rms_um: f64,
    /// The noise floor as an RMS 3-D residual, µm.
    pub noise_um: f64,
    /// Where the noise floor comes from (repeated points, or the tracker's stated noise).
    pub noise_source: NoiseSource,
    /// Measured points diagnosed (duplicates left out).
    pub points: usize,
    /// Rows left out as exact copies of another row (not repeated measurements).
    pub duplicates: usize,
    /// How the candidates were screened when not on every point.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub screened: Option<String>,
    /// Significant findings, best first; empty at the noise floor.
    pub candidates: Vec<Finding>,
    /// Every effect evaluated, best first.
    pub considered: Vec<Finding>,
    /// What the residual follows, learned from it (`None` when it was not asked for or the
    /// data teach nothing).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub learned: Option<LearnedDrivers>,
    /// The tests by their share of the residual, largest first.
    pub residual_by_test: Vec<TestShare>,
    /// With `--validate`: the drivers where the validation data leave the campaign's range.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub extrapolation: Vec<String>,
    /// The conclusion in one sentence, as the command line prints it.
    pub verdict: String,
}

/// Why a diagnosis could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiagnoseError {
    #[error("the measurement files hold no measured row")]
    /// No file holds a measured row.
    NoMeasurements,
}

/// The `--effects` value that adds `name` (quoted: `>` is a shell redirection).
pub fn add_option(name: &str) -> String {
    format!("--effects '+{name}'")
}

/// The `--effects` value that identifies the model's effects with `name` in place of
/// `replaced` (with `-c`, the kept effects start from their values).
pub fn replace_option(model: &Model, replaced: &[String], name: &str) -> String {
    let mut list: Vec<String> = model
        .effects()
        .iter()
        .map(|e| e.name())
        .filter(|n| !replaced.contains(n))
        .collect();
    list.push(name.to_string());
    format!("--effects '{}'", list.join(","))
}

/// Whether the effect extrapolates in time (validated on the latest data).
pub fn extrapolates_in_time(name: &EffectName) -> bool {
    match name.axes {
        crate::model::registry::Axes::Spec(s) => {
            learn_spec(s).is_some_and(|s| learn::uses_time(&s))
        }
        _ => name.kind.in_time,
    }
}

fn learn_spec(text: &str) -> Option<crate::model::effects::learned::Spec> {
    crate::model::effects::learned::Spec::parse(text).ok()
}

/// The plans of one diagnosis.
struct Plans {
    within: Plan,
    tests: Plan,
    latest: Option<Plan>,
    /// With several files, the latest learnt from the earlier ones.
    files: Option<Plan>,
    /// The data tell time from pose ([`clock`]).
    tells_time: bool,
}

/// What a finding must pass on the held-out stretches.
fn passes_within(e: &Evaluation, rms: f64) -> bool {
    if let Some(r) = &e.reidentified {
        // Judged on the points both fits learnt from, with fewer parameters than what it
        // replaces ([`replace`]): the gain must be plain; per-point t statistics and the
        // spread over tests say nothing of an effect that lives where its axis's torque
        // changes sign.
        return e.explained >= MIN_REPLACING_EXPLAINED
            && r.rms_before_um - e.rms_after_um >= MIN_RMS_GAIN_UM;
    }
    e.not_evaluated.is_none()
        && e.explained >= MIN_EXPLAINED
        && e.t >= MIN_T
        && rms - e.rms_after_um >= MIN_RMS_GAIN_UM
        && e.within.as_ref().is_some_and(Score::stable)
}

/// The gain on the latest file is plain: advice that does not lower the error on data
/// measured later, elsewhere, is not given.
fn lowers_later(s: &Score) -> bool {
    s.explained >= MIN_EXPLAINED && s.rms_before_um - s.rms_after_um >= MIN_RMS_GAIN_UM
}

/// What a candidate gains on the latest file learnt from the earlier ones, or without that
/// check its held-out score.
fn later_gain(e: &Evaluation) -> f64 {
    e.check(Scheme::Files).map_or(e.explained, |f| f.explained)
}

/// Why a candidate that passes on the stretches is not a finding, if it is not.
fn veto(e: &Evaluation, time: bool, plans: &Plans) -> Option<String> {
    if time && !plans.tells_time {
        return Some(clock::cannot_tell());
    }
    if let Some(f) = e.check(Scheme::Files) {
        if !lowers_later(f) {
            return Some(format!(
                "it does not lower the error on data measured later: {}",
                f.describe()
            ));
        }
    }
    if let Some(t) = e.check(Scheme::Tests) {
        if t.worse() {
            return Some(format!(
                "it predicts whole tests it did not learn from worse: {}",
                t.describe()
            ));
        }
    }
    if time {
        match e.check(Scheme::Latest) {
            Some(l) if l.explained >= MIN_EXPLAINED && l.t >= MIN_LATEST_T => {}
            Some(l) => {
                return Some(format!(
                    "it extrapolates in time and does not predict the latest data better: {}",
                    l.describe()
                ))
            }
            None => {}
        }
    }
    None
}

/// A candidate that loses fitted alone on top of the model — where the model's tables have
/// taken up part of its shape in the tests that sweep their axes — scored with the tables
/// re-fitted beside it ([`learn::EffectScreen`]), as its printed command will identify it:
/// on the held-out stretches, and where that passes, on whole tests, the latest data (an
/// effect of the clock) and the latest file. Only given several files.
fn partialled(
    model: &Model,
    screen: &[&Row],
    plans: &Plans,
    rms: f64,
    evaluations: &mut [Evaluation],
    options: &DiagnoseOptions,
) {
    // The linear score partials the model's columns out over every point, held-out ones
    // included, and so flatters: it is trusted only where a later file can confirm it (on a
    // single campaign it found A2's compliance on clean data of the virtual robot).
    let Some(files_plan) = plans.files.as_ref() else {
        return;
    };
    let losing: Vec<usize> = (0..evaluations.len())
        .filter(|&i| {
            let e = &evaluations[i];
            !passes_within(e, rms)
                && e.not_evaluated.is_none()
                && e.parameters <= MAX_PARTIALLED_PARAMETERS
                && e.reidentified.is_none()
                && crossval::replaced(model, &e.name).is_empty()
        })
        .collect();
    if losing.is_empty() {
        return;
    }
    tick(options, "re-fitting the tables beside", 0, 1);
    let effects = learn::EffectScreen::new(model, screen);
    let names: Vec<EffectName> = losing.iter().map(|&i| evaluations[i].name).collect();
    let within = effects.scores(model, &names, &plans.within);
    let passing: Vec<(usize, Score)> = losing
        .iter()
        .zip(within)
        .filter_map(|(&i, s)| {
            let s = s?;
            let passes = s.explained >= MIN_EXPLAINED
                && s.t >= MIN_T
                && rms - s.rms_after_um >= MIN_RMS_GAIN_UM
                && s.stable();
            passes.then_some((i, s))
        })
        .collect();
    if passing.is_empty() {
        return;
    }
    let names: Vec<EffectName> = passing.iter().map(|(i, _)| evaluations[*i].name).collect();
    let tests = effects.scores(model, &names, &plans.tests);
    let files = effects.scores(model, &names, files_plan);
    for (k, (i, s)) in passing.into_iter().enumerate() {
        // Promoted only with the later file's score to judge it by.
        let Some(f) = files[k].clone() else {
            continue;
        };
        let e = &mut evaluations[i];
        e.explained = s.explained;
        e.t = s.t;
        e.rms_after_um = s.rms_after_um;
        e.within = Some(s);
        e.partialled = true;
        e.checks = tests[k].clone().into_iter().collect();
        if extrapolates_in_time(&e.name) {
            if let Some(plan) = &plans.latest {
                e.checks.extend(effects.score(model, &e.name, plan));
            }
        }
        e.checks.push(f);
    }
}

/// Most candidates identified as their printed command would, looking for the first one
/// that can be followed (each is a full identification on all the data).
pub const MAX_FOLLOW_FITS: usize = 3;

/// Identifies `name` on top of `cal` as the command a finding prints does (`identify -c CAL
/// FILES --effects …`: the same files, effects and defaults); why it cannot be followed, if it
/// cannot: the identification fails, its fit fails, or its values leave their physical range.
/// A fit still poor after the addition does not count against it where `cal` itself is a poor
/// fit of these data (`base_poor`: the user is adding the missing effects one by one, each
/// written with `--accept-poor-fit` as `cal` was).
pub fn follow(
    cal: &Calibration,
    data: &[Measurements],
    name: &EffectName,
    base_poor: bool,
) -> Result<Calibration, String> {
    use crate::identify::pipeline::{identify, Effects, Request};
    let model = cal.model_ref();
    let replaced = crossval::replaced(model, name);
    let effects = if replaced.is_empty() {
        Effects::Add(vec![*name])
    } else {
        let mut list: Vec<EffectName> = model
            .effects()
            .iter()
            .filter(|e| !replaced.contains(&e.name()))
            .filter_map(|e| EffectName::parse(&e.name()).ok())
            .collect();
        list.push(*name);
        Effects::Exactly(list)
    };
    let mut stops = Vec::new();
    let mut file_of = Vec::new();
    for (k, m) in data.iter().enumerate() {
        file_of.resize(file_of.len() + m.stops.len(), k);
        stops.extend(m.stops.iter().cloned());
    }
    let request = Request {
        effects: Some(effects),
        base: Some(cal.clone()),
        sources: data.iter().map(|m| m.source.clone()).collect(),
        file_of,
        max_points: Some(crate::identify::thin::DEFAULT_MAX_POINTS),
        ..Request::default()
    };
    let identified = identify(&stops, &request)
        .map_err(|e| format!("identified as its command prints, it fails: {e}"))?;
    if let Some(failure) = identified.verdict.failure.as_ref().filter(|_| !base_poor) {
        return Err(format!(
            "identified as its command prints, the fit fails: {}",
            failure.trim_end()
        ));
    }
    identified
        .calibration
        .to_json(std::path::Path::new("NEW.json"))
        .map(|_| identified.calibration.clone())
        .map_err(|e| {
            format!(
                "identified as its command prints, the calibration is not physical ({e}): \
                 `identify` would refuse to write it"
            )
        })
}

/// The checks of a candidate that passes on the stretches.
fn run_checks(
    model: &Model,
    stops: &[Stop],
    rows: &[&Row],
    before: &[Vector3<f64>],
    name: &EffectName,
    plans: &Plans,
    grid: &GridChoice,
) -> Vec<Score> {
    let mut out = Vec::new();
    if let Ok(s) = crossval::check(model, stops, before, name, &plans.tests, grid) {
        out.push(s);
    }
    if extrapolates_in_time(name) {
        if let Some(plan) = &plans.latest {
            out.extend(learn::latest_effect_score(model, rows, name, plan));
        }
    }
    if let Some(plan) = &plans.files {
        out.extend(crossval::check(model, stops, before, name, plan, grid).ok());
    }
    out
}

fn tick(options: &DiagnoseOptions, stage: &str, done: usize, of: usize) {
    if let Some(p) = &options.progress {
        (p.0)(stage, done, of);
    }
}

/// Diagnoses `cal` against `data`.
pub fn diagnose(
    cal: &Calibration,
    data: &[Measurements],
    options: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    tick(options, "comparing", 0, 1);
    let all_rows = compare::compare(cal, data);
    if all_rows.is_empty() {
        return Err(DiagnoseError::NoMeasurements);
    }
    // The points `identify` left out of this calibration's fit as gross errors are left out
    // here too: a millimetre of a broken beam must not outweigh the residual a diagnosis is
    // about.
    let gross = compare::gross_errors(cal, data);
    let all_rows: Vec<Row> = if gross.iter().all(Option::is_none) {
        all_rows
    } else {
        all_rows
            .into_iter()
            .zip(&gross)
            .filter(|(_, g)| g.is_none())
            .map(|(r, _)| r)
            .collect()
    };
    // Exact copies are not repeated measurements: out, before anything is estimated.
    let copies = noise::duplicates(&all_rows);
    let duplicates = copies.iter().filter(|c| **c).count();
    let rows: Vec<Row> = if duplicates == 0 {
        all_rows
    } else {
        all_rows
            .into_iter()
            .zip(copies)
            .filter(|(_, c)| !c)
            .map(|(r, _)| r)
            .collect()
    };
    let model = cal.model_ref();
    let floor = noise::estimate(&rows, &cal.frame, &options.tracker);
    let all_before: Vec<Vector3<f64>> = rows.iter().map(Row::residual).collect();
    let rms = crossval::rms_um(&all_before);
    let residual_by_test = shares(&rows);
    // Whether `cal` is itself a poor fit of these data: some test's residual beyond the ratio
    // at which `identify` refuses to write a calibration (see [`follow`]).
    let base_poor = {
        let mut by_test: std::collections::HashMap<&str, (f64, usize)> = Default::default();
        for (r, e) in rows.iter().zip(&all_before) {
            let t = by_test.entry(r.test.as_str()).or_default();
            t.0 += e.norm_squared();
            t.1 += 1;
        }
        by_test.values().any(|&(sum, n)| {
            (sum / n as f64).sqrt() * 1e3 > crate::identify::verdict::FAIL_RATIO * floor.rms_um
        })
    };

    // The points the candidates are screened on.
    let all_groups = blocks::groups(rows.iter().map(|r| (r.source.as_str(), r.test.as_str())));
    let (screen, screened): (Vec<&Row>, Option<String>) =
        match sample::subsample(&all_groups, options.max_screened.max(100)) {
            None => (rows.iter().collect(), None),
            Some((kept, why)) => (kept.iter().map(|&i| &rows[i]).collect(), Some(why)),
        };
    let before: Vec<Vector3<f64>> = screen.iter().map(|r| r.residual()).collect();
    let screen_rms = crossval::rms_um(&before);
    // The measured points in the base frame, as identification takes them.
    let stops: Vec<Stop> = screen
        .iter()
        .map(|r| Stop {
            test: r.test.clone(),
            state: r.state,
            measured_mm: Some(r.measured),
            line: r.line,
        })
        .collect();
    let groups = blocks::groups(screen.iter().map(|r| (r.source.as_str(), r.test.as_str())));
    let times: Vec<f64> = screen.iter().map(|r| r.state.time_s).collect();
    let latest = blocks::latest(&groups, &times);
    let grid = grid_choice(model);
    let files = blocks::groups(screen.iter().map(|r| (r.source.as_str(), "")));
    let plans = Plans {
        within: blocks::stretches(&groups, options.folds),
        tests: blocks::tests(&groups, options.folds),
        latest,
        files: blocks::later_file(&files, &times),
        tells_time: clock::tells_time_from_pose(&rows),
    };

    let names = options
        .only
        .clone()
        .unwrap_or_else(|| candidates::missing(model));
    let done = AtomicUsize::new(0);
    let mut evaluations: Vec<Evaluation> = names
        .par_iter()
        .map(|name| {
            let e = crossval::evaluate(model, &stops, &before, name, &plans.within, &grid);
            tick(
                options,
                "candidates",
                done.fetch_add(1, Ordering::Relaxed) + 1,
                names.len(),
            );
            e
        })
        .collect();
    // A candidate that takes the place of effects of the model and loses fitted alone on top
    // of it is judged as its printed command identifies it: the model re-identified with it
    // in their place, where it has fewer parameters than they ([`replace`]).
    let replacing: Vec<usize> = (0..evaluations.len())
        .filter(|&i| {
            let e = &evaluations[i];
            !passes_within(e, screen_rms)
                && !matches!(e.not_evaluated, Some(crossval::NotEvaluated::NotShown(_)))
                && !crossval::replaced(model, &e.name).is_empty()
        })
        .collect();
    if !replacing.is_empty() {
        tick(options, "re-identifying replacements", 0, replacing.len());
    }
    let judged: Vec<(usize, Evaluation)> = replacing
        .par_iter()
        .filter_map(|&i| {
            let name = evaluations[i].name;
            let mut e = replace::evaluate(model, &stops, &name, &plans.tests, &grid)?;
            // Judged on the latest file as its printed command identifies it.
            if let Some(plan) = plans
                .files
                .as_ref()
                .filter(|_| passes_within(&e, screen_rms))
            {
                e.checks
                    .extend(replace::on_plan(model, &stops, &name, plan, &grid));
            }
            Some((i, e))
        })
        .collect();
    for (i, e) in judged {
        if passes_within(&e, screen_rms) {
            evaluations[i] = e;
        }
    }
    partialled(
        model,
        &screen,
        &plans,
        screen_rms,
        &mut evaluations,
        options,
    );
    evaluations.sort_by(|a, b| b.explained.total_cmp(&a.explained));

    // Checks of those that pass on the stretches (a re-identified replacement has been
    // judged on all the data: fitted alone on top of the model it is known to lose).
    let to_check: Vec<usize> = (0..evaluations.len())
        .filter(|&i| {
            let e = &evaluations[i];
            passes_within(e, screen_rms) && e.reidentified.is_none() && !e.partialled
        })
        .collect();
    tick(options, "checks", 0, to_check.len());
    let checked: Vec<(usize, Vec<Score>)> = to_check
        .par_iter()
        .map(|&i| {
            let e = &evaluations[i];
            (
                i,
                run_checks(model, &stops, &screen, &before, &e.name, &plans, &grid),
            )
        })
        .collect();
    for (i, checks) in checked {
        evaluations[i].checks = checks;
    }
    // With a later file, candidates are credited with what they gain there: data from another
    // part of the workspace, measured later, as the user's programs will run.
    if plans.files.is_some() {
        evaluations.sort_by(|a, b| later_gain(b).total_cmp(&later_gain(a)));
    }
    let mut vetoes: Vec<Option<String>> = evaluations
        .iter()
        .map(|e| {
            passes_within(e, screen_rms)
                .then(|| veto(e, extrapolates_in_time(&e.name), &plans))
                .flatten()
        })
        .collect();
    // Advice the user can follow: the first finding is identified as its printed command will
    // identify it (the same calibration, files and effects); one whose identification fails
    // or leaves its physical range is not advised, and the next is tried.
    let mut tried = 0;
    let mut validations: Vec<Option<validate::ValidationGain>> = vec![None; evaluations.len()];
    for i in 0..evaluations.len() {
        if tried == MAX_FOLLOW_FITS {
            break;
        }
        if !(passes_within(&evaluations[i], screen_rms) && vetoes[i].is_none()) {
            continue;
        }
        tick(options, "following the advice", tried, MAX_FOLLOW_FITS);
        tried += 1;
        match follow(cal, data, &evaluations[i].name, base_poor) {
            Ok(followed) if !options.validate.is_empty() => {
                let g = validate::gain(cal, &followed, &options.validate);
                let lowers = g.as_ref().is_some_and(|g| g.rms_after_um < g.rms_before_um);
                if let Some(g) = g.as_ref().filter(|_| !lowers) {
                    vetoes[i] = Some(format!(
                        "identified as printed, it does not lower the error on the validation \
                         data ({:.1} → {:.1} µm RMS)",
                        g.rms_before_um, g.rms_after_um
                    ));
                }
                validations[i] = g;
                if lowers {
                    break;
                }
            }
            Ok(_) => break,
            Err(why) => vetoes[i] = Some(why),
        }
    }
    let significant = |i: usize| passes_within(&evaluations[i], screen_rms) && vetoes[i].is_none();

    // Twins of the best significant candidate: significant candidates that correct the
    // points the same way, and candidates close to it or that gravity makes look alike that
    // explain as much once the model is re-identified around them. Of twins, the one that
    // explains most once re-identified comes first.
    let mut best = (0..evaluations.len()).find(|&i| significant(i));
    let twins_of_best: Vec<String> = match best {
        None => Vec::new(),
        Some(bi) => {
            tick(options, "twins", 0, 1);
            let b = &evaluations[bi];
            let similar = (0..evaluations.len()).filter(|&o| {
                o != bi
                    && significant(o)
                    && crossval::similarity(&b.correction, &evaluations[o].correction)
                        >= SAME_RESIDUAL
            });
            let partners = twins::gravity_partners(&b.name);
            let mut plausible: Vec<&Evaluation> = (0..evaluations.len())
                .filter(|&o| {
                    let e = &evaluations[o];
                    let close = significant(o) && e.explained >= TWIN_CLOSE * b.explained;
                    e.not_evaluated.is_none() && (close || partners.contains(&e.name))
                })
                .map(|o| &evaluations[o])
                .collect();
            plausible.sort_by(|x, y| y.t.total_cmp(&x.t));
            plausible.truncate(MAX_TWIN_FITS);
            let plausible: Vec<EffectName> = plausible.iter().map(|o| o.name).collect();
            let mut names: Vec<String> = similar.map(|o| evaluations[o].name.to_string()).collect();
            let found = twins::twins(model, &stops, &b.name, &plausible, &grid);
            // A significant twin that explains more than the best once re-identified leads.
            let stronger = found
                .iter()
                .filter(|(_, share)| *share > 1.0)
                .filter_map(|(t, share)| {
                    let i = evaluations.iter().position(|e| e.name.to_string() == *t)?;
                    significant(i).then_some((i, *share))
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            for (t, _) in found {
                if !names.contains(&t) {
                    names.push(t);
                }
            }
            if let Some((i, _)) = stronger {
                let old = b.name.to_string();
                let new = evaluations[i].name.to_string();
                names.retain(|n| *n != new);
                names.insert(0, old);
                best = Some(i);
            }
            names
        }
    };
    let considered: Vec<Finding> = evaluations
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let same = if best == Some(i) {
                twins_of_best.clone()
            } else if twins_of_best.contains(&e.name.to_string()) {
                best.map(|b| vec![evaluations[b].name.to_string()])
                    .unwrap_or_default()
            } else {
                Vec::new()
            };
            let mut f = finding(
                e,
                significant(i),
                vetoes[i].clone(),
                same,
                model,
                &rows,
                screen_rms,
            );
            f.validation = validations[i].clone();
            f
        })
        .collect();
    let mut candidates: Vec<Finding> = considered
        .iter()
        .filter(|f| f.significant)
        .cloned()
        .collect();
    // The best first (a twin may have overtaken the best on the held-out score).
    if let Some(b) = best {
        let name = evaluations[b].name.to_string();
        if let Some(k) = candidates.iter().position(|f| f.effect == name) {
            let first = candidates.remove(k);
            candidates.insert(0, first);
        }
    }

    let learned = if options.learn {
        tick(options, "learning drivers", 0, 1);
        learned_drivers(model, &screen, &plans, screen_rms)
    } else {
        None
    };
    let direction_tries: Vec<(Vec<u8>, bool)> = (0..evaluations.len())
        .filter(|&i| evaluations[i].not_evaluated.is_none())
        .map(|i| {
            let axes = play::candidate_direction_axes(&evaluations[i].name, model);
            (axes, significant(i))
        })
        .collect();
    let mut verdict = verdict(
        rms,
        &floor,
        &candidates,
        learned.as_ref(),
        &residual_by_test,
    );
    verdict += &play::undecided_sentence(&play::undecided(model, &direction_tries, &rows));
    if let Some(g) = candidates.first().and_then(|f| f.validation.as_ref()) {
        verdict += &format!(
            " On the validation data ({} points) it lowers the error {:.1} → {:.1} µm RMS.",
            g.points, g.rms_before_um, g.rms_after_um
        );
    }
    let extrapolation = if options.validate.is_empty() {
        Vec::new()
    } else {
        validate::extrapolation(&rows, &compare::compare(cal, &options.validate))
    };
    if !extrapolation.is_empty() {
        verdict += &format!(
            " The validation data leave the campaign's range ({}): there every effect \
             extrapolates.",
            extrapolation.join("; ")
        );
    }
    Ok(Diagnosis {
        rms_um: rms,
        noise_um: floor.rms_um,
        noise_source: floor.source,
        points: rows.len(),
        duplicates,
        screened,
        candidates,
        considered,
        learned,
        residual_by_test,
        extrapolation,
        verdict,
    })
}

/// The drivers learned from `cal`'s residual on `data` alone (no candidate of the table), for
/// the report.
pub fn learned_only(cal: &Calibration, data: &[Measurements]) -> Option<LearnedDrivers> {
    let options = DiagnoseOptions {
        only: Some(Vec::new()),
        ..DiagnoseOptions::default()
    };
    diagnose(cal, data, &options).ok()?.learned
}

/// The drivers learned from the residual, checked like a candidate: scored (in [`learn`]) on
/// held-out stretches, on whole tests and, on the clock, on the latest data, with what the
/// model can take up partialled out.
fn learned_drivers(
    model: &Model,
    screen: &[&Row],
    plans: &Plans,
    rms: f64,
) -> Option<LearnedDrivers> {
    let (spec, mut found) = learn::screen_drivers(
        model,
        screen,
        &plans.within,
        &plans.tests,
        plans.latest.as_ref(),
        plans.files.as_ref(),
    )?;
    let passes = found.explained >= MIN_EXPLAINED
        && found.t_statistic >= MIN_T
        && found.stable
        && rms * (1.0 - found.explained).max(0.0).sqrt() <= rms - MIN_RMS_GAIN_UM;
    if !passes {
        found.vetoed = Some(format!(
            "it explains {:.0}% of held-out stretches (t = {:.1}{}), short of a finding",
            100.0 * found.explained.max(0.0),
            found.t_statistic,
            if found.stable {
                ""
            } else {
                ", not stable across the folds"
            }
        ));
        return Some(found);
    }
    if learn::uses_time(&spec) && !plans.tells_time {
        found.vetoed = Some(clock::cannot_tell());
        return Some(found);
    }
    if let Some(f) = found.checks.iter().find(|c| c.scheme == Scheme::Files) {
        if !lowers_later(f) {
            found.vetoed = Some(format!(
                "it does not lower the error on data measured later: {}",
                f.describe()
            ));
            return Some(found);
        }
    }
    if let Some(t) = found.checks.iter().find(|c| c.scheme == Scheme::Tests) {
        if t.worse() {
            found.vetoed = Some(format!(
                "it predicts whole tests it did not learn from worse: {}",
                t.describe()
            ));
            return Some(found);
        }
    }
    if let Some(l) = found.checks.iter().find(|c| c.scheme == Scheme::Latest) {
        if !(l.explained >= MIN_EXPLAINED && l.t >= MIN_LATEST_T) {
            found.vetoed = Some(format!(
                "it extrapolates in time and does not predict the latest data better: {}",
                l.describe()
            ));
        }
    }
    found.significant = found.vetoed.is_none();
    Some(found)
}

/// The tests by their share of the residual sum of squares.
fn shares(rows: &[Row]) -> Vec<TestShare> {
    let mut order: Vec<(String, usize, f64)> = Vec::new();
    for r in rows {
        let ss = r.residual().norm_squared();
        match order.iter_mut().find(|o| o.0 == r.test) {
            Some(o) => {
                o.1 += 1;
                o.2 += ss;
            }
            None => order.push((r.test.clone(), 1, ss)),
        }
    }
    let total: f64 = order.iter().map(|o| o.2).sum();
    let mut out: Vec<TestShare> = order
        .into_iter()
        .map(|(test, points, ss)| TestShare {
            test,
            points,
            rms_um: (ss / points as f64).sqrt() * 1000.0,
            share: if total > 0.0 { ss / total } else { 0.0 },
        })
        .collect();
    out.sort_by(|a, b| b.share.total_cmp(&a.share));
    out
}

/// Grids of candidate tables: the pitch of the calibration's own tables over one axis angle
/// (map and backlash: the pitch its campaign was measured at), else the defaults.
pub fn grid_choice(model: &Model) -> GridChoice {
    let pitch = model
        .effects()
        .iter()
        .filter(|e| {
            matches!(
                e.role(),
                crate::model::Role::OwnAngle { .. }
                    | crate::model::Role::DirectionDifference { .. }
            )
        })
        .find_map(|e| {
            let points = e.record().table?.grid_deg;
            (points.len() >= 2)
                .then(|| (points[points.len() - 1] - points[0]) / (points.len() - 1) as f64)
        });
    GridChoice {
        map_pitch_deg: pitch.unwrap_or(GridChoice::default().map_pitch_deg),
        ..GridChoice::default()
    }
}

fn finding(
    e: &Evaluation,
    significant: bool,
    vetoed: Option<String>,
    same: Vec<String>,
    model: &Model,
    rows: &[Row],
    rms: f64,
) -> Finding {
    let name = e.name.to_string();
    let replaced = crossval::replaced(model, &e.name);
    let evidence = match (&e.not_evaluated, &e.reidentified) {
        (Some(why), _) => format!("not evaluated: {why}"),
        (None, Some(r)) => {
            let mut s = evidence::describe(&e.name, model, rows);
            s += &format!(
                "; re-identified with the model in place of {} ({} values for their {}), it \
                 fits better than the model re-identified alone on the same points and \
                 explains {:.0}% of that residual ({:.1} → {:.1} µm RMS)",
                r.replaced.join(", "),
                e.parameters,
                r.removed_parameters,
                100.0 * e.explained.max(0.0),
                r.rms_before_um,
                e.rms_after_um
            );
            if let Some(why) = &vetoed {
                s += &format!(", but {why}");
            }
            if !same.is_empty() {
                s += &format!("; indistinguishable on these data from {}", same.join(", "));
            }
            s
        }
        (None, None) => {
            let mut s = evidence::describe(&e.name, model, rows);
            if !replaced.is_empty() {
                s += &format!(
                    "; tried in place of {}, which describe the same rotation direction",
                    replaced.join(", ")
                );
            }
            s += &format!(
                "; fitted without the stretches of the tests it is scored on{}, it explains \
                 {:.0}% of their residual ({rms:.1} → {:.1} µm RMS)",
                if e.partialled {
                    " (the model's tables re-fitted beside it)"
                } else {
                    ""
                },
                100.0 * e.explained.max(0.0),
                e.rms_after_um
            );
            if let Some(why) = &vetoed {
                s += &format!(", but {why}");
            }
            if !same.is_empty() {
                s += &format!("; indistinguishable on these data from {}", same.join(", "));
            }
            s
        }
    };
    let evidence = match e.check(Scheme::Files).filter(|_| vetoed.is_none()) {
        Some(f) => format!(
            "{evidence}; learnt from the earlier files it lowers the latest one's error \
             {:.1} → {:.1} µm RMS ({:+.0}%)",
            f.rms_before_um,
            f.rms_after_um,
            100.0 * f.explained
        ),
        None => evidence,
    };
    let within = e.within.as_ref();
    Finding {
        add: if replaced.is_empty() {
            add_option(&name)
        } else {
            replace_option(model, &replaced, &name)
        },
        effect: name,
        explained: e.explained,
        rms_after_um: e.rms_after_um,
        evidence,
        significant,
        t_statistic: e.t,
        parameters: e.parameters,
        stable: within.is_some_and(Score::stable),
        fold_explained: within.map(|w| w.fold_explained.clone()).unwrap_or_default(),
        checks: e.checks.clone(),
        vetoed,
        indistinguishable_from: same,
        not_evaluated: e.not_evaluated.as_ref().map(ToString::to_string),
        validation: None,
    }
}

/// Where the residual lives: the largest tests carrying half of it (at most three).
fn where_it_lives(shares: &[TestShare]) -> String {
    let mut named = Vec::new();
    let mut carried = 0.0;
    for s in shares.iter().take(3) {
        named.push(format!(
            "{} ({:.0}%, {:.1} µm RMS)",
            s.test,
            100.0 * s.share,
            s.rms_um
        ));
        carried += s.share;
        if carried >= WHERE_SHARE {
            break;
        }
    }
    named.join(", ")
}

fn verdict(
    rms: f64,
    floor: &NoiseFloor,
    candidates: &[Finding],
    learned: Option<&LearnedDrivers>,
    shares: &[TestShare],
) -> String {
    let at = format!(
        "{rms:.1} µm RMS against a noise floor of {:.1} µm ({})",
        floor.rms_um,
        floor.source.describe()
    );
    let above = rms > AT_FLOOR * floor.rms_um;
    match candidates.first() {
        None if !above => format!(
            "Nothing significant is missing: no effect of the table explains any of the \
             residual on held-out data, and the residual is at the noise floor ({at})."
        ),
        None => {
            let mut s = format!(
                "None of my candidates: no effect of the table removes a meaningful, stable part \
                 of the residual on data it did not learn from, yet the residual is well above \
                 the noise floor ({at}). Most of it lives in {}.",
                where_it_lives(shares)
            );
            match learned {
                Some(l) if l.significant => {
                    s += &format!(
                        " Learned from the residual: it {}; as an effect it explains {:.0}% on \
                         held-out stretches ({rms:.1} → {:.1} µm RMS). Add it with `robopost \
                         identify -c CAL.json MEAS.csv {} -o NEW.json`.",
                        l.shape,
                        100.0 * l.explained,
                        l.rms_after_um,
                        l.add
                    );
                }
                Some(l) => {
                    s += &format!(
                        " No smooth function of the generic drivers explains it either (best: it \
                         {}, {:.0}% on held-out stretches); look at the report (`robopost \
                         compare --report`) for outliers or a set-up problem.",
                        l.shape,
                        100.0 * l.explained.max(0.0)
                    );
                }
                None => {
                    s += " Look at the report (`robopost compare --report`) for outliers or a \
                          set-up problem.";
                }
            }
            s
        }
        Some(best) => {
            let mut s = format!(
                "Missing: {} — it explains {:.0}% of the residual ({rms:.1} → {:.1} µm RMS; \
                 noise floor {:.1} µm). Add it with `robopost identify -c CAL.json MEAS.csv {} -o NEW.json`.",
                best.effect,
                100.0 * best.explained,
                best.rms_after_um,
                floor.rms_um,
                best.add
            );
            if !best.indistinguishable_from.is_empty() {
                s +=
                    &format!(
                    " On these data it cannot be told apart from {}: {} may be the physical cause.",
                    best.indistinguishable_from.join(" or "),
                    if best.indistinguishable_from.len() > 1 { "any of them" } else { "either" }
                );
            }
            s
        }
    }
}
