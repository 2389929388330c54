//! `robopost identify` as a library call: build the model to identify (fresh effects with
//! grids from the data, or an existing calibration plus added effects), thin dense data to a
//! budget ([`super::thin`]), screen every indexing test for gross errors
//! ([`super::screen`]), find the target vector from the A5/A6 circles (or, lacking them, by
//! least squares over all points), start the tracker registration (one frame per file), run
//! the direct method when the model is fresh, refine globally while leaving out the points
//! the fitted model shows to be gross errors ([`super::robust`]), check every point against
//! the result, judge the fit against the noise floor ([`super::verdict`]) and wrap the result
//! as a calibration whose provenance says all of that.

use std::collections::BTreeMap;

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

use super::direct::{
    direct_method_grouped, effective_target_a6, indexing_tests_grouped, set_target_a6,
    target_from_circles, AxisLine, DirectResult, TARGET_HINT_TOLERANCE_MM,
};
use super::refine::{refine, Fit, IdentifyError, Progress, ProgressFn, RefineOptions, Status};
use super::register::rigid_fit;
use super::robust::{self, tracker_sigma_mm};
use super::screen::{pitch_deg, screen_test, systematic, Located, Structure, Suspect};
use super::setup::{add_effects, GridChoice};
use super::thin::{thin, Thinning, DEFAULT_MAX_POINTS};
use super::verdict::{judge, Clues, TestResidual, Verdict};
use crate::calibration::{Calibration, ExcludedPoint, MeasurementFrame, Provenance};
use crate::compare::Row;
use crate::diagnose::noise::{self, NoiseFloor, ASSUMED_STATION_MM};
use crate::kinematics::{Frame, Payload, RobotDescription};
use crate::measure::tracker::Tracker;
use crate::measure::Stop;
use crate::model::{EffectName, Model};
use crate::stats::{error_stats, ErrorStats};

/// The paper's full model, the default effect list.
pub use crate::model::registry::PAPER_EFFECTS;

/// Most fit-and-screen rounds (a round leaves out the points the last fit showed to be gross
/// errors and takes back those it cleared; on the campaigns tried the set settles in two).
const MAX_ROUNDS: usize = 5;
/// A noise floor from repeated points more than this many times the tracker specification's
/// is not believed (see [`noise_floor`]).
const REPEATS_BEYOND_SPEC: f64 = 3.0;

/// Which effects to identify.
#[derive(Clone, Debug, PartialEq)]
pub enum Effects {
    /// Exactly these (those the base calibration has start from its values).
    Exactly(Vec<EffectName>),
    /// The base calibration's effects plus these (`--effects +NAME`).
    Add(Vec<EffectName>),
}

/// Why an `--effects` list is not one.
#[derive(Debug)]
pub enum EffectsListError {
    /// Some names start with `+` and some do not.
    Mixed,
    /// A name that is not an effect's.
    Name(crate::model::NameError),
}

impl Effects {
    /// The `--effects` list (`NAME,…`, `map:A1..A6` expanded; every name with `+`: added to
    /// the base calibration's). Whether a base calibration is there to add to is the caller's
    /// to check ([`Effects::Add`]).
    pub fn parse(list: &str) -> Result<Effects, EffectsListError> {
        let items: Vec<&str> = list
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .collect();
        let adds = items.iter().filter(|s| s.starts_with('+')).count();
        if adds > 0 && adds < items.len() {
            return Err(EffectsListError::Mixed);
        }
        let stripped: Vec<&str> = items.iter().map(|s| s.trim_start_matches('+')).collect();
        let names =
            crate::model::expand_list(&stripped.join(",")).map_err(EffectsListError::Name)?;
        Ok(if adds > 0 {
            Effects::Add(names)
        } else {
            Effects::Exactly(names)
        })
    }
}

/// What to identify and from what.
#[derive(Clone, Default)]
pub struct Request {
    /// `None`: the paper's full model.
    pub effects: Option<Effects>,
    /// An existing calibration: robot, payload, target, frame and starting values.
    pub base: Option<Calibration>,
    /// Positions are in a tracker frame: identify its pose too (one per file).
    pub tracker_frame: bool,
    pub grid: GridChoice,
    /// A hint for the measurement target in the flange frame (mm) when there is no base
    /// calibration: the data's own target (A5/A6 circles) wins when they disagree by more
    /// than [`TARGET_HINT_TOLERANCE_MM`]; used as the start when the data hold no such tests.
    pub target_mm: Option<[f64; 3]>,
    pub robot_name: Option<String>,
    /// Measurement files, for the provenance and the list of gross errors.
    pub sources: Vec<String>,
    /// The file (index into `sources`) of every stop; empty: all from the first. With
    /// `tracker_frame` every file gets its own tracker frame (the tracker moved between them).
    pub file_of: Vec<usize>,
    /// Most measured points the fit uses ([`super::thin`]); `None`: [`DEFAULT_MAX_POINTS`],
    /// `Some(0)`: all.
    pub max_points: Option<usize>,
    /// The laser tracker's stated accuracy and station (`--tracker`, `--tracker-at`): the
    /// noise of each point in the gross-error test and the noise floor.
    pub tracker: Tracker,
    pub progress: Option<ProgressFn>,
}

/// A measured point left out as a gross error.
#[derive(Clone, Debug, PartialEq)]
pub struct GrossError {
    /// Index of the stop in the data.
    pub row: usize,
    /// Its file (as named in the request) and line.
    pub file: String,
    /// Its 1-based line in that file.
    pub line: usize,
    /// Its test's label.
    pub test: String,
    /// Its residual against the model fitted without it, µm.
    pub size_um: f64,
    /// Why it was judged gross, in words.
    pub why: String,
}

/// Where the target vector came from.
#[derive(Clone, Debug, PartialEq)]
pub enum TargetSource {
    /// The A5 and A6 circles (A6 frame, mm); `hint_off_mm`: how far a given hint was.
    Circles {
        /// The target in the A6 frame, mm.
        target_a6: [f64; 3],
        /// How far a given hint was from it, mm.
        hint_off_mm: Option<f64>,
    },
    /// A least-squares fit of the target to every point with the nominal model (no A5/A6
    /// indexing tests), from the hint or the flange origin.
    LeastSquares {
        /// The hint it started from (A6 frame, mm), if one was given.
        hint: Option<[f64; 3]>,
    },
    /// The base calibration's.
    Calibration,
}

/// The outcome: the new calibration, the fit, and what was found on the way.
#[derive(Clone, Debug)]
pub struct Identified {
    /// The identified calibration (`Calibration::save_atomic` writes it).
    pub calibration: Calibration,
    /// The last refinement (over the points of the fit, gross errors left out).
    pub fit: Fit,
    /// The direct method's result (per-axis tables read off the indexing tests), when it ran.
    pub direct: Option<DirectResult>,
    /// The effects identified (canonical names).
    pub effects: Vec<String>,
    /// Identified values brought into their physical range, and why (e.g. a gear play whose
    /// bidirectional difference came out leading).
    pub physical: Vec<String>,
    /// The gross errors, in data order.
    pub gross: Vec<GrossError>,
    /// Jumps of the residual that repeat (at one axis angle in both directions, in several
    /// tests or over neighbours): systematic, kept in the fit, and a sign of an effect the
    /// model lacks.
    pub structures: Vec<Structure>,
    /// How the points were thinned to the fit's budget, when they were.
    pub thinning: Option<Thinning>,
    /// Where the tracker's target (the TCP offset) came from.
    pub target: TargetSource,
    /// The residual of every measured point without gross errors (in the fit or thinned out).
    pub stats: ErrorStats,
    /// The same per indexing test (the CSV's `test` column).
    pub per_test: BTreeMap<String, ErrorStats>,
    /// Whether the fit is good enough to use, and why.
    pub verdict: Verdict,
    /// Fit-and-screen rounds before the set of gross errors settled.
    pub rounds: usize,
}

fn report(progress: &Option<ProgressFn>, stage: &'static str, step: usize, steps: usize) {
    if let Some(p) = progress {
        p(&Progress {
            stage,
            iteration: step,
            max_iterations: steps,
            rms_um: f64::NAN,
            lambda: f64::NAN,
        });
    }
}

/// Runs the identification (see the module documentation).
pub fn identify(stops: &[Stop], request: &Request) -> Result<Identified, IdentifyError> {
    if !stops.iter().any(|s| s.measured_mm.is_some()) {
        return Err(IdentifyError::NoMeasurements);
    }
    let progress = &request.progress;
    let (mut model, robot_name, old_frame) = match &request.base {
        Some(cal) => (cal.model(), cal.robot_name.clone(), Some(cal.frame)),
        None => (
            Model::new(
                RobotDescription::kr30ha(),
                Payload::default(),
                Vector3::from(request.target_mm.unwrap_or([0.0; 3])),
            ),
            "KR 30 HA".to_string(),
            None,
        ),
    };
    let robot_name = request.robot_name.clone().unwrap_or(robot_name);
    let paper = || crate::model::expand_list(PAPER_EFFECTS).unwrap_or_default();
    let fresh = request.base.is_none();
    match request
        .effects
        .clone()
        .unwrap_or_else(|| Effects::Exactly(paper()))
    {
        Effects::Exactly(names) => {
            // Keep the base's effects that are requested (with their values), in the base's order.
            let wanted: Vec<String> = names.iter().map(|n| n.to_string()).collect();
            let mut kept = Model::new(model.robot, model.payload, model.target_mm);
            for e in model.effects() {
                if wanted.contains(&e.name()) {
                    kept.push(e.clone_model_effect());
                }
            }
            model = kept;
            add_effects(&mut model, &names, stops, &request.grid)?;
        }
        Effects::Add(names) => {
            add_effects(&mut model, &names, stops, &request.grid)?;
        }
    }
    let effects: Vec<String> = model.effects().iter().map(|e| e.name()).collect();
    let tracker = request.tracker_frame;
    let file_of = |i: usize| request.file_of.get(i).copied().unwrap_or(0);
    let n_files = (0..stops.len()).map(|i| file_of(i) + 1).max().unwrap_or(1);

    // The points of the fit: all measured ones, or a spread-out subset of dense data.
    let budget = request.max_points.unwrap_or(DEFAULT_MAX_POINTS);
    let (fit_rows, thinning) = thin(
        stops,
        &request.file_of,
        budget,
        request.grid.map_pitch_deg / 4.0,
    );
    let fit_data: Vec<Stop> = fit_rows.iter().map(|&i| stops[i].clone()).collect();
    let fit_file: Vec<usize> = fit_rows.iter().map(|&i| file_of(i)).collect();
    let fit_test = test_ids(&fit_data, &fit_file);
    let n_measured = stops.iter().filter(|s| s.measured_mm.is_some()).count();

    // Gross errors each indexing test shows by itself, over every measured row (positions in
    // the tracker's frame are fine: a test only looks at its own circle). A point of an
    // indexing test is a gross error only if its test says so and the fitted model confirms
    // it: where tests share a table cell (the reference pose of the others), an effect the
    // model lacks makes that one point's residual jump though its position does not.
    report(progress, "screening the tests", 0, 1);
    let tests = indexing_tests_grouped(stops, &request.file_of);
    let assumed = request
        .tracker
        .station_mm
        .unwrap_or(Vector3::from(ASSUMED_STATION_MM));
    let spec_sigma = |i: usize| {
        let m = stops[i].measured_mm.unwrap_or_default();
        // In a tracker frame the head is at the origin; else where the user says it stands,
        // or assumed in front of the robot.
        let station = if tracker { Vector3::zeros() } else { assumed };
        tracker_sigma_mm(&m, &station, &request.tracker)
    };
    let located: Vec<Located> = tests
        .par_iter()
        .enumerate()
        .flat_map_iter(|(k, t)| {
            let pitch = pitch_deg(stops, &t.rows, t.axis);
            let n = t.axis as usize - 1;
            screen_test(stops, &t.rows, t.axis, &spec_sigma)
                .0
                .into_iter()
                .map(move |suspect| Located {
                    test: k,
                    axis: t.axis,
                    angle_deg: stops[suspect.row].state.axes_deg[n],
                    direction: stops[suspect.row].state.directions()[n],
                    pitch_deg: pitch,
                    suspect,
                })
        })
        .collect();
    // What repeats (both directions, several tests, a run) is the robot's, not the tracker's:
    // it stays in the fit and is reported.
    let mut tests_of_axis = [0; 6];
    for t in &tests {
        tests_of_axis[t.axis as usize - 1] += 1;
    }
    let (suspects, structures) = systematic(located, tests_of_axis);
    let mut in_indexing = vec![false; stops.len()];
    for t in &tests {
        for &i in &t.rows {
            in_indexing[i] = true;
        }
    }
    let mut suspect_of: BTreeMap<usize, &Suspect> = BTreeMap::new();
    for s in &suspects {
        suspect_of.insert(s.row, s);
    }
    // Per point of the fit: may the global check flag it (not in an indexing test, or a
    // suspect of its test)?
    let may_flag: Vec<bool> = fit_rows
        .iter()
        .map(|&i| !in_indexing[i] || suspect_of.contains_key(&i))
        .collect();
    let mut excluded: Vec<bool> = fit_rows
        .iter()
        .map(|i| suspect_of.contains_key(i))
        .collect();
    let masked = |excluded: &[bool]| -> Vec<Stop> {
        fit_data
            .iter()
            .zip(excluded)
            .map(|(s, &x)| Stop {
                measured_mm: if x { None } else { s.measured_mm },
                ..s.clone()
            })
            .collect()
    };
    let clean = masked(&excluded);

    // The target vector, before anything else that depends on it.
    let target = if fresh {
        report(progress, "finding the target", 0, 1);
        find_target(&mut model, &clean, &fit_file, request.target_mm, tracker)
    } else {
        TargetSource::Calibration
    };

    // Tracker frames: the base calibration's (one file), else the rigid best fit per file.
    let mut frames: Vec<Frame> = vec![Frame::identity(); n_files];
    if tracker {
        for (g, frame) in frames.iter_mut().enumerate() {
            *frame = match old_frame {
                Some(MeasurementFrame::Tracker(f)) if n_files == 1 => Frame::from_kuka(&f),
                _ => register(&model, &clean, &fit_file, g)?,
            };
        }
    }

    // The direct method reads circles in the base frame.
    let direct = if fresh {
        report(progress, "direct method", 0, 1);
        let in_base: Vec<Stop> = clean
            .iter()
            .zip(&fit_file)
            .map(|(s, &g)| Stop {
                measured_mm: s.measured_mm.map(|m| (frames[g] * Point3::from(m)).coords),
                ..s.clone()
            })
            .collect();
        direct_method_grouped(&mut model, &in_base, &fit_file)
    } else {
        None
    };

    // Refine, leave out what the fitted model shows to be gross errors, refine again.
    let station = |g: usize, frames: &[Frame]| {
        if tracker {
            frames[g].position
        } else {
            assumed
        }
    };
    let mut initial_stats = None;
    let mut screening = None;
    let (mut rounds, mut iterations) = (0, 0);
    // Standard errors cost a solve per block of columns: computed in a round expected to be
    // the last (no point left out yet), else once more at the end.
    let mut with_errors = !excluded.iter().any(|&x| x);
    let mut settled_fit = None;
    for round in 0..MAX_ROUNDS {
        let options = RefineOptions {
            tracker_frame: tracker,
            initial_frames: frames.clone(),
            frame_of: fit_file.clone(),
            standard_errors: with_errors,
            progress: progress.clone(),
            ..RefineOptions::default()
        };
        let f = refine(&mut model, &masked(&excluded), &options)?;
        initial_stats.get_or_insert(f.initial_stats);
        rounds += 1;
        iterations += f.iterations;
        if tracker {
            frames = f.tracker_frames.clone();
        }
        let residuals = residuals(&model, &fit_data, &fit_file, &frames);
        let sigma: Vec<f64> = fit_data
            .iter()
            .zip(&fit_file)
            .map(|(s, &g)| {
                let m = frames[g] * Point3::from(s.measured_mm.unwrap_or_default());
                tracker_sigma_mm(&m.coords, &station(g, &frames), &request.tracker)
            })
            .collect();
        let in_fit: Vec<bool> = excluded.iter().map(|x| !x).collect();
        let mut s = robust::screen(&residuals, &sigma, &in_fit, &fit_test, n_measured);
        for (g, may) in s.gross.iter_mut().zip(&may_flag) {
            *g &= may;
        }
        robust::limit_share(&mut s.gross, &fit_test);
        let settled = s.gross == excluded || round + 1 == MAX_ROUNDS;
        if s.gross != excluded {
            with_errors = false;
        }
        excluded = s.gross.clone();
        screening = Some(s);
        if settled {
            settled_fit = with_errors.then_some(f);
            break;
        }
    }
    let mut fit = match settled_fit {
        Some(f) => f,
        None => {
            // Standard errors once, at the final set of points.
            report(progress, "standard errors", 0, 1);
            let options = RefineOptions {
                tracker_frame: tracker,
                initial_frames: frames.clone(),
                frame_of: fit_file.clone(),
                progress: progress.clone(),
                ..RefineOptions::default()
            };
            let f = refine(&mut model, &masked(&excluded), &options)?;
            if tracker {
                frames = f.tracker_frames.clone();
            }
            iterations += f.iterations;
            f
        }
    };
    // "Before" is before the first refinement, not before the last (warm) one.
    if let Some(s) = initial_stats {
        fit.initial_stats = s;
    }
    fit.iterations = iterations;
    let physical = model.make_physical(&fit.standard_errors);
    let scale = screening.as_ref().map_or(1.0, |s| s.scale);
    let limit = screening.as_ref().map_or(robust::THRESHOLD, |s| s.limit);

    // Every measured point against the result (the thinned-out ones too).
    report(progress, "checking every point", 0, 1);
    let measured: Vec<usize> = (0..stops.len())
        .filter(|&i| stops[i].measured_mm.is_some())
        .collect();
    let files: Vec<usize> = measured.iter().map(|&i| file_of(i)).collect();
    let checked: Vec<(Vector3<f64>, Vector3<f64>, f64)> = measured
        .par_iter()
        .zip(&files)
        .map(|(&i, &g)| {
            let s = &stops[i];
            let m = (frames[g] * Point3::from(s.measured_mm.unwrap_or_default())).coords;
            let r = m - model.target_position(&s.state);
            (
                m,
                r,
                tracker_sigma_mm(&m, &station(g, &frames), &request.tracker),
            )
        })
        .collect();
    // Their residuals less their neighbours' (as in the rounds), over all measured points.
    let measured_stops: Vec<&Stop> = measured.iter().map(|&i| &stops[i]).collect();
    let all_tests = test_ids_of(&measured_stops, &files);
    let residual_all: Vec<Vector3<f64>> = checked.iter().map(|c| c.1).collect();
    let detrended = robust::detrended(&residual_all, &all_tests);
    let excluded_rows: Vec<usize> = fit_rows
        .iter()
        .zip(&excluded)
        .filter(|(_, &x)| x)
        .map(|(&i, _)| i)
        .collect();
    // Points of the fit keep the fit's verdict; the others are judged alike.
    let in_fit: Vec<bool> = measured
        .iter()
        .map(|i| fit_rows.binary_search(i).is_ok())
        .collect();
    // Points the fit did not use are predictions, not fitted values: judged against their own
    // robust scatter when that is the larger.
    let normalised: Vec<f64> = (0..measured.len())
        .map(|k| detrended[k].norm() / checked[k].2)
        .collect();
    let not_fitted: Vec<bool> = in_fit.iter().map(|f| !f).collect();
    let limit = robust::screen_normalised(normalised.clone(), &not_fitted, n_measured)
        .limit
        .max(limit);
    let mut others: Vec<bool> = (0..measured.len())
        .map(|k| {
            let i = measured[k];
            !in_fit[k] && (!in_indexing[i] || suspect_of.contains_key(&i)) && normalised[k] > limit
        })
        .collect();
    robust::limit_share(&mut others, &all_tests);
    let mut gross = Vec::new();
    let mut is_gross = vec![false; measured.len()];
    for (k, (&i, (_, r, sigma))) in measured.iter().zip(&checked).enumerate() {
        let u = detrended[k].norm() / sigma;
        let bad = others[k] || (in_fit[k] && excluded_rows.binary_search(&i).is_ok());
        if !bad {
            continue;
        }
        is_gross[k] = true;
        let residual = format!(
            "residual {:.3} mm against the model fitted without it ({:.3} mm off its \
             neighbours' residual), {:.0} σ of the tracker noise there ({:.0} µm{})",
            r.norm(),
            detrended[k].norm(),
            u,
            sigma * 1000.0,
            if scale > 1.0 {
                format!("; this fit's scatter is {scale:.1}× that")
            } else {
                String::new()
            }
        );
        let why = match suspect_of.get(&i) {
            Some(s) => format!("{}; {residual}", s.why),
            None => residual,
        };
        gross.push(GrossError {
            row: i,
            file: request.sources.get(file_of(i)).cloned().unwrap_or_default(),
            line: stops[i].line,
            test: stops[i].test.clone(),
            size_um: r.norm() * 1000.0,
            why,
        });
    }

    // Statistics of every point without gross errors, per test, and the noise floor.
    let mut by_test: BTreeMap<String, (Vec<Vector3<f64>>, usize)> = BTreeMap::new();
    for (k, &i) in measured.iter().enumerate() {
        let entry = by_test.entry(stops[i].test.clone()).or_default();
        if is_gross[k] {
            entry.1 += 1;
        } else {
            entry.0.push(checked[k].1);
        }
    }
    let good: Vec<Vector3<f64>> = checked
        .iter()
        .zip(&is_gross)
        .filter(|(_, &g)| !g)
        .map(|(c, _)| c.1)
        .collect();
    let stats = error_stats(&good);
    let per_test: BTreeMap<String, ErrorStats> = by_test
        .iter()
        .map(|(t, (e, _))| (t.clone(), error_stats(e)))
        .collect();
    // The floor from the points of the fit (all of them unless the data were thinned).
    let of_fit: Vec<bool> = (0..measured.len())
        .map(|k| in_fit[k] && !is_gross[k])
        .collect();
    let floor = noise_floor(
        stops,
        &measured,
        &files,
        &checked,
        &of_fit,
        &frames,
        (tracker, &request.tracker),
    );
    let residual_tests: Vec<TestResidual> = by_test
        .iter()
        .map(|(t, (e, g))| TestResidual {
            test: t.clone(),
            points: e.len(),
            gross: *g,
            rms_um: error_stats(e).rms_um,
        })
        .collect();
    let clues = clues(
        &model,
        stops,
        &measured,
        request,
        &target,
        &checked,
        &is_gross,
        &fit,
        stats.rms_um,
    );
    let verdict = judge(residual_tests, floor, &clues);

    let frame = if tracker {
        MeasurementFrame::Tracker(frames[0].to_pose())
    } else {
        MeasurementFrame::Base
    };
    let provenance = provenance(
        request,
        &fit,
        &stats,
        &verdict,
        &gross,
        &thinning,
        &target,
        direct.is_some(),
        &effects,
        &frames,
        measured.len(),
        &physical,
    );
    let calibration = Calibration::from_model(&robot_name, model, frame, provenance);
    Ok(Identified {
        calibration,
        fit,
        direct,
        effects,
        physical,
        gross,
        structures,
        thinning,
        target,
        stats,
        per_test,
        verdict,
        rounds,
    })
}

/// A number per (file, test label, rotation directions) for each stop of `data`: the
/// neighbours a point's residual is compared with ([`robust::detrended`]) approached it the
/// same way (an effect the model lacks may differ between a sweep up and the sweep down).
fn test_ids(data: &[Stop], file_of: &[usize]) -> Vec<usize> {
    let refs: Vec<&Stop> = data.iter().collect();
    test_ids_of(&refs, file_of)
}

fn test_ids_of(data: &[&Stop], file_of: &[usize]) -> Vec<usize> {
    let mut ids: std::collections::HashMap<(usize, &str, [i8; 6]), usize> = Default::default();
    let mut last = None;
    data.iter()
        .zip(file_of)
        .map(|(s, &f)| {
            let key = (
                f,
                s.test.as_str(),
                s.state.directions().map(|d| d.sign() as i8),
            );
            // Consecutive rows mostly share their key: look it up only when it changes.
            if let Some((k, id)) = last {
                if k == key {
                    return id;
                }
            }
            let next = ids.len();
            let id = *ids.entry(key).or_insert(next);
            last = Some((key, id));
            id
        })
        .collect()
}

/// `measured (base frame) − predicted` of every stop of `data` (zero where unmeasured).
fn residuals(
    model: &Model,
    data: &[Stop],
    file_of: &[usize],
    frames: &[Frame],
) -> Vec<Vector3<f64>> {
    data.par_iter()
        .zip(file_of)
        .map(|(s, &g)| match s.measured_mm {
            Some(m) => (frames[g] * Point3::from(m)).coords - model.target_position(&s.state),
            None => Vector3::zeros(),
        })
        .collect()
}

/// The rigid best fit of file `g`'s measured points onto the model's predictions.
fn register(
    model: &Model,
    data: &[Stop],
    file_of: &[usize],
    g: usize,
) -> Result<Frame, IdentifyError> {
    let (measured, predicted): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = data
        .iter()
        .zip(file_of)
        .filter(|(_, &f)| f == g)
        .filter_map(|(s, _)| s.measured_mm.map(|m| (m, model.target_position(&s.state))))
        .unzip();
    rigid_fit(&measured, &predicted).ok_or(IdentifyError::FrameStart)
}

/// Sets the model's target from the data (see [`TargetSource`]).
fn find_target(
    model: &mut Model,
    data: &[Stop],
    file_of: &[usize],
    hint: Option<[f64; 3]>,
    tracker: bool,
) -> TargetSource {
    let tests = indexing_tests_grouped(data, file_of);
    let lines: Vec<(usize, AxisLine)> = tests
        .iter()
        .enumerate()
        .filter(|(_, t)| t.axis >= 5)
        .filter_map(|(k, t)| {
            let circle = super::direct::measured_circle(data, t)?;
            Some((
                k,
                AxisLine {
                    test: t.test.clone(),
                    axis: t.axis,
                    reference_deg: t.reference_deg,
                    circle,
                    points: t
                        .rows
                        .iter()
                        .filter_map(|&i| {
                            Some((
                                i,
                                data[i].state.axes_deg[t.axis as usize - 1],
                                data[i].measured_mm?,
                            ))
                        })
                        .collect(),
                },
            ))
        })
        .collect();
    let chosen: Vec<_> = lines.iter().map(|(k, _)| tests[*k].clone()).collect();
    let circles: Vec<AxisLine> = lines.into_iter().map(|(_, l)| l).collect();
    if let Some(p) = target_from_circles(&model.robot, &chosen, &circles) {
        let hint_off_mm = hint.map(|_| (model.target_a6() - p).norm());
        set_target_a6(model, &p);
        return TargetSource::Circles {
            target_a6: p.into(),
            hint_off_mm,
        };
    }
    let p = least_squares_target(model, data, file_of, tracker);
    set_target_a6(model, &p);
    TargetSource::LeastSquares { hint }
}

/// The target (A6 frame) that best explains every measured point with the model as it is:
/// `m ≈ F·(O(q) + R(q)·p)` is linear in `p` for a known frame `F` (the mean of `R(q)ᵀ(F⁻¹…)`);
/// with tracker frames, frames and target are alternated from the model's current target.
fn least_squares_target(
    model: &Model,
    data: &[Stop],
    file_of: &[usize],
    tracker: bool,
) -> Vector3<f64> {
    let mut m = model.clone();
    let mut p = effective_target_a6(&m);
    let n_files = file_of.iter().map(|g| g + 1).max().unwrap_or(1);
    let mut frames = vec![Frame::identity(); n_files];
    for _ in 0..if tracker { 50 } else { 1 } {
        if tracker {
            for (g, f) in frames.iter_mut().enumerate() {
                if let Ok(found) = register(&m, data, file_of, g) {
                    *f = found;
                }
            }
        }
        let (mut sum, mut n) = (Vector3::zeros(), 0.0);
        for (s, g) in data.iter().zip(file_of.iter().chain(std::iter::repeat(&0))) {
            let Some(measured) = s.measured_mm else {
                continue;
            };
            let (frames_at, _) = m.frames(&s.state);
            let base = (frames[*g] * Point3::from(measured)).coords;
            let r = frames_at.flange_rotation() * crate::model::chain::a6_to_flange().transpose();
            sum += r.transpose() * (base - frames_at.flange_position());
            n += 1.0;
        }
        if n == 0.0 {
            break;
        }
        let next = sum / n;
        let moved = (next - p).norm();
        p = next;
        set_target_a6(&mut m, &p);
        if moved < 1e-4 {
            break;
        }
    }
    p
}

/// The noise floor of the `used` points, as `diagnose` estimates it (per file
/// with tracker frames: each has its own station; combined as an RMS).
fn noise_floor(
    stops: &[Stop],
    measured: &[usize],
    files: &[usize],
    checked: &[(Vector3<f64>, Vector3<f64>, f64)],
    used: &[bool],
    frames: &[Frame],
    (tracker, instrument): (bool, &Tracker),
) -> NoiseFloor {
    let mut floors: Vec<(NoiseFloor, usize)> = Vec::new();
    for (g, frame) in frames.iter().enumerate() {
        let rows: Vec<Row> = measured
            .iter()
            .enumerate()
            .filter(|(k, _)| files[*k] == g && used[*k])
            .map(|(k, &i)| Row {
                test: String::new(),
                source: String::new(),
                line: stops[i].line,
                state: stops[i].state,
                measured: checked[k].0,
                predicted: checked[k].0,
                nominal: checked[k].0,
            })
            .collect();
        if rows.is_empty() {
            continue;
        }
        let (f, station) = if tracker {
            (MeasurementFrame::Tracker(frame.to_pose()), frame.position)
        } else {
            let at = instrument.station_mm;
            (
                MeasurementFrame::Base,
                at.unwrap_or(ASSUMED_STATION_MM.into()),
            )
        };
        let mut floor = noise::estimate(&rows, &f, instrument);
        // "Repeats" scattering far beyond what a tracker does are not repeats of one pose
        // (the same campaign from another set-up, duplicated rows): judge by the tracker.
        let assumed = !tracker && instrument.station_mm.is_none();
        let spec = noise::from_spec(&rows, &station, assumed, instrument);
        if floor.rms_um > REPEATS_BEYOND_SPEC * spec.rms_um {
            floor = spec;
        }
        floors.push((floor, rows.len()));
    }
    let total: usize = floors.iter().map(|f| f.1).sum::<usize>().max(1);
    let rms = (floors
        .iter()
        .map(|(f, n)| f.rms_um.powi(2) * *n as f64)
        .sum::<f64>()
        / total as f64)
        .sqrt();
    let source = floors
        .iter()
        .max_by_key(|f| f.1)
        .map(|f| f.0.source.clone())
        .unwrap_or(noise::NoiseSource::TrackerSpec {
            mean_distance_m: 0.0,
            station_assumed: true,
            mpe: instrument.mpe_words(),
        });
    NoiseFloor {
        rms_um: rms,
        source,
    }
}

#[allow(clippy::too_many_arguments)]
fn clues(
    model: &Model,
    stops: &[Stop],
    measured_rows: &[usize],
    request: &Request,
    target: &TargetSource,
    checked: &[(Vector3<f64>, Vector3<f64>, f64)],
    is_gross: &[bool],
    fit: &Fit,
    rms_um: f64,
) -> Clues {
    // Would a rigid motion of the data fit the robot without any error effect far better than
    // the fit does? Then they are in another frame.
    let rigid_rms_um = if request.tracker_frame {
        None
    } else {
        // The target the data gave before any fit (a failed fit may have moved it anywhere).
        let t = match target {
            TargetSource::Circles { target_a6, .. } => Vector3::from(*target_a6),
            _ => model.target_a6(),
        };
        let nominal = Model::new(
            model.robot,
            model.payload,
            crate::model::chain::a6_to_flange().transpose() * t,
        );
        let (measured, predicted): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = measured_rows
            .iter()
            .zip(checked)
            .zip(is_gross)
            .filter(|(_, &g)| !g)
            .map(|((&i, c), _)| (c.0, nominal.target_position(&stops[i].state)))
            .unzip();
        rigid_fit(&measured, &predicted).and_then(|f| {
            let n = measured.len().max(1) as f64;
            let rms = (measured
                .iter()
                .zip(&predicted)
                .map(|(m, p)| ((f * Point3::from(*m)).coords - p).norm_squared())
                .sum::<f64>()
                / n)
                .sqrt()
                * 1000.0;
            (rms < rms_um / 5.0).then_some(rms)
        })
    };
    let mut held: Vec<String> = Vec::new();
    if super::direct::axis_lines(model).is_none() {
        held.push("the geometric errors (not in the effect list)".into());
    }
    for (e, effect) in model.effects().iter().enumerate() {
        let start = model.effect_start(e);
        let len = effect.values().len();
        if fit.status[start..start + len]
            .iter()
            .all(|s| *s == Status::Held)
        {
            held.push(effect.name());
        }
    }
    Clues {
        base_frame: !request.tracker_frame,
        rigid_rms_um,
        rms_um,
        target_from_hint: match target {
            TargetSource::LeastSquares { hint } => *hint,
            _ => None,
        },
        robot_from: if request.base.is_some() {
            "the calibration given with -c".into()
        } else {
            "the built-in KR 30 HA".into()
        },
        held,
    }
}

/// What the identified base frame is when the data are in a tracker frame, and how to tie
/// it to the robot's real base (the calibration's provenance and the README say it).
pub const TRACKER_BASE_FRAME: &str = "Base frame: the data were measured in a tracker frame, \
    so this calibration's base frame is the one the data define, not the robot's $ROBROOT: \
    its Z axis is the identified A1 axis line, its XY origin on that line, its origin height \
    l1z below the identified A2 axis, and its X axis where the arm points at A1 = 0 on average \
    (the mean of map:A1 is pinned). The A1 axis line, A1's zero and the A2 height are absorbed \
    by the tracker registration. Tie it to the real base by measuring the base's reference \
    marks in the same tracker set-up (the transform between them and this frame), or simply \
    calibrate $BASE (the workpiece frame) with the compensated robot: programs taught or \
    generated against that $BASE then need no tie to $ROBROOT.";

#[allow(clippy::too_many_arguments)]
fn provenance(
    request: &Request,
    fit: &Fit,
    stats: &ErrorStats,
    verdict: &Verdict,
    gross: &[GrossError],
    thinning: &Option<Thinning>,
    target: &TargetSource,
    direct: bool,
    effects: &[String],
    frames: &[Frame],
    measured: usize,
    physical: &[String],
) -> Provenance {
    let mut notes = vec![format!(
        "identified by robopost {} ({}global Levenberg–Marquardt refinement) with effects {}",
        env!("CARGO_PKG_VERSION"),
        if direct { "direct method, then " } else { "" },
        effects.join(",")
    )];
    notes.push(match target {
        TargetSource::Circles {
            target_a6,
            hint_off_mm,
        } => {
            let mut t = format!(
                "target vector from the A5/A6 circles: ({:.3}, {:.3}, {:.3}) mm in the A6 frame",
                target_a6[0], target_a6[1], target_a6[2]
            );
            if let Some(off) = hint_off_mm {
                t += &if *off > TARGET_HINT_TOLERANCE_MM {
                    format!("; the --target hint was {off:.1} mm away and not used")
                } else {
                    format!(
                        "; the --target hint is kept as target_mm ({:.3} mm away, in p6)",
                        off
                    )
                };
            }
            t
        }
        TargetSource::LeastSquares { hint } => format!(
            "target vector fitted to all points (no A5/A6 indexing tests) from {}",
            hint.map_or("the flange origin".to_string(), |h| format!(
                "the --target hint ({}, {}, {})",
                h[0], h[1], h[2]
            ))
        ),
        TargetSource::Calibration => "target vector from the base calibration".to_string(),
    });
    if let Some(t) = thinning {
        notes.push(t.describe());
    }
    if !gross.is_empty() {
        notes.push(format!(
            "{} gross error(s) left out of the fit (listed under `excluded`)",
            gross.len()
        ));
    }
    if request.tracker_frame {
        notes.push(TRACKER_BASE_FRAME.to_string());
        if frames.len() > 1 {
            notes.push(format!(
                "{} tracker set-ups, one frame per file (under `frames`); `frame` is the first's",
                frames.len()
            ));
        }
    }
    notes.extend(physical.iter().cloned());
    if !fit.warnings.is_empty() {
        notes.push(format!(
            "{} warning(s): {}",
            fit.warnings.len(),
            fit.warnings
                .iter()
                .map(|w| w.to_string())
                .collect::<Vec<_>>()
                .join(" | ")
        ));
    }
    let fit_stats = [
        ("points", stats.points as f64),
        ("points_measured", measured as f64),
        ("points_fitted", fit.stats.points as f64),
        ("gross_errors", gross.len() as f64),
        ("rms_um", stats.rms_um),
        ("xy_mean_um", stats.xy_mean_um),
        ("xy_2sigma_um", stats.xy_2sigma_um),
        ("z_mean_um", stats.z_mean_um),
        ("z_2sigma_um", stats.z_2sigma_um),
        ("d3_max_um", stats.d3_max_um),
        ("sigma_um", fit.sigma_mm * 1000.0),
        ("noise_floor_um", verdict.noise.rms_um),
        ("iterations", fit.iterations as f64),
    ];
    Provenance {
        sources: request.sources.clone(),
        date: Some(today_utc()),
        fit: fit_stats
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
        notes: Some(notes.join(". ")),
        excluded: gross
            .iter()
            .map(|g| ExcludedPoint {
                source: g.file.clone(),
                line: g.line,
                test: g.test.clone(),
                size_um: (g.size_um * 10.0).round() / 10.0,
                why: g.why.clone(),
            })
            .collect(),
        frames: if request.tracker_frame && frames.len() > 1 {
            frames
                .iter()
                .enumerate()
                .map(|(g, f)| {
                    (
                        request
                            .sources
                            .get(g)
                            .cloned()
                            .unwrap_or_else(|| g.to_string()),
                        f.to_pose(),
                    )
                })
                .collect()
        } else {
            BTreeMap::new()
        },
        failed: verdict.failure.clone(),
    }
}

/// Today's date (UTC) in ISO 8601, from the system clock (days to civil date: H. Hinnant's
/// `civil_from_days`).
pub fn today_utc() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let z = secs.div_euclid(86_400) + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}")
}
