//! An error budget of a calibration on validation measurements: what each source
//! contributes to the residual `measured − predicted`, each measured from its own data, in
//! mean square 3-D error (µm², so that independent parts add; shown as root-sum-square µm):
//!
//! - **tracker**: the validation measurement's own noise, from the instrument's accuracy at
//!   each point's distance from its station (`Tracker::sigma_mm`, per coordinate);
//! - **time**: the robot's drift between the campaign and the validation, measured at a
//!   reference pose the campaign measured repeatedly (the pose it measured most often, at
//!   least [`MIN_REFERENCE_REPEATS`] times) and the validation measured too: the mean
//!   residual there in the validation less its mean in the campaign (the pose's own model
//!   error cancels; only what changed with time is left), less the tracker noise of the two
//!   means; taken as the same shift at every validation point;
//! - **model form**, measured at the validation poses, where the campaign may not see it: the
//!   residuals of neighbouring stops of a test share what is systematic (their mean product,
//!   the time shift taken off: the tracker's noise, independent from stop to stop, cancels in
//!   it — `systematic`), less what the identification's errors are predicted to share between
//!   the same stops (their cross-covariance). The campaign fit's lack of fit (its residual mean
//!   square less what the tracker's noise leaves in a least-squares residual) is given beside
//!   it: the model form the campaign sees;
//! - **identification**: the campaign's tracker noise carried through the fit to each point
//!   (the parameter covariance, [`crate::identify::covariance`]);
//! - **unexplained**: the measured mean square less the four parts (negative when they exceed
//!   it): what changes from stop to stop beyond the tracker's noise and the identification's,
//!   or a drift the reference pose does not show. Unlike the parts it is a remainder, and the
//!   check: it is small when the parts account for the error.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::Serialize;

use super::Row;
use crate::identify::covariance::Covariance;
use crate::measure::tracker::Tracker;
use crate::model::Model;

/// How often the campaign must have measured a pose for it to serve as the time reference.
pub const MIN_REFERENCE_REPEATS: usize = 3;

/// The parts of one set of points (all of them, or one test), µm RMS (3-D).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Parts {
    pub points: usize,
    /// The measured residual's 3-D RMS.
    pub measured_um: f64,
    pub tracker_um: f64,
    /// The drift between the campaign and the validation (the same at every point).
    pub time_um: f64,
    /// Signed root of the mean product of consecutive stops' residuals (time shift taken off).
    pub systematic_um: f64,
    /// The identification's predicted error (its mean square at the points).
    pub identification_um: f64,
    /// Signed root of the identification's predicted share of `systematic_um` (the mean
    /// cross-covariance of its errors at consecutive stops).
    pub identification_shared_um: f64,
    /// Signed root of systematic less the identification's share of it (mean products).
    pub model_form_um: f64,
    /// Root-sum-square of tracker, identification, model form (when positive) and time.
    pub explained_um: f64,
    /// `√|measured² − explained²|`, negative when the parts exceed the measured error.
    pub unexplained_um: f64,
    /// Length of the mean residual vector (a constant offset of these points).
    pub offset_um: f64,
}

/// One validation point's parts, µm (3-D).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PointParts {
    pub test: String,
    pub source: String,
    pub line: usize,
    pub measured_um: f64,
    pub tracker_um: f64,
    pub identification_um: f64,
    pub time_um: f64,
}

/// The reference pose that measures the time part.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimeReference {
    pub axes_deg: [f64; 6],
    /// Its measurements in the campaign and in the validation.
    pub campaign_repeats: usize,
    pub validation_repeats: usize,
    /// The drift: the validation's mean residual there less the campaign's, µm (x, y, z).
    pub drift_um: [f64; 3],
}

/// The budget: overall, per test (by label), per point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Budget {
    #[serde(flatten)]
    pub all: Parts,
    /// The campaign fit's residual 3-D RMS, the tracker's share of it and what is left (the
    /// campaign's lack of fit: the model form the campaign sees), µm.
    pub campaign_rms_um: f64,
    pub campaign_tracker_um: f64,
    pub campaign_model_form_um: f64,
    /// The reference pose, when the campaign measured one repeatedly and the validation
    /// measured it too (else no time part is measured).
    pub time_reference: Option<TimeReference>,
    pub tests: BTreeMap<String, Parts>,
    /// The validation points budgeted (the reference pose's measurements are the time probe,
    /// not among them).
    pub points: Vec<PointParts>,
}

/// Where the tracker stood (base frame, mm) and how accurate it is.
#[derive(Clone, Debug)]
pub struct Instrument {
    pub tracker: Tracker,
    pub station_mm: Vector3<f64>,
}

impl Instrument {
    /// The 3-D mean square noise (mm²) of a point measured at `p` (base frame).
    fn mean_square_mm2(&self, p: &Vector3<f64>) -> f64 {
        3.0 * self.tracker.sigma_mm(p, &self.station_mm).powi(2)
    }
}

/// The campaign's lack of fit (mm², 3-D) from its fit residuals: their mean square less the
/// tracker's noise left in a least-squares residual with `parameters` free parameters; also
/// the campaign's measured and tracker mean squares.
fn campaign_lack_of_fit_mm2(
    campaign: &[Row],
    instrument: &Instrument,
    parameters: usize,
) -> [f64; 3] {
    let n = campaign.len().max(1) as f64;
    let measured = campaign
        .iter()
        .map(|r| r.residual().norm_squared())
        .sum::<f64>()
        / n;
    let tracker = campaign
        .iter()
        .map(|r| instrument.mean_square_mm2(&r.measured))
        .sum::<f64>()
        / n;
    let kept = (1.0 - parameters as f64 / (3.0 * n)).max(0.0);
    [
        (measured - tracker * kept).max(0.0),
        measured,
        tracker * kept,
    ]
}

fn signed_root(v: f64) -> f64 {
    v.signum() * v.abs().sqrt()
}

/// A pose as a key, to 0.0001° (the measurement files' decimals and more).
fn pose_key(axes: &[f64; 6]) -> [i64; 6] {
    axes.map(|a| (a * 1e4).round() as i64)
}

/// The pose the campaign measured most often, if at least [`MIN_REFERENCE_REPEATS`] times.
fn reference_pose(campaign: &[Row]) -> Option<[i64; 6]> {
    let mut counts: BTreeMap<[i64; 6], usize> = BTreeMap::new();
    for r in campaign {
        *counts.entry(pose_key(&r.state.axes_deg)).or_default() += 1;
    }
    counts
        .into_iter()
        .filter(|(_, n)| *n >= MIN_REFERENCE_REPEATS)
        .max_by_key(|(_, n)| *n)
        .map(|(k, _)| k)
}

/// The drift vector (mm) at the reference pose `key` and its noise-corrected mean square:
/// the validation's mean residual there less the campaign's, less the tracker noise of the
/// two means. `None` when the validation did not measure the pose.
fn drift(
    key: &[i64; 6],
    campaign: &[Row],
    validation: &[Row],
    instrument: &Instrument,
) -> Option<(TimeReference, Vector3<f64>, f64)> {
    let at = |rows: &[Row]| -> Vec<(Vector3<f64>, f64)> {
        rows.iter()
            .filter(|r| pose_key(&r.state.axes_deg) == *key)
            .map(|r| (r.residual(), instrument.mean_square_mm2(&r.measured)))
            .collect()
    };
    let (c, v) = (at(campaign), at(validation));
    if c.is_empty() || v.is_empty() {
        return None;
    }
    // The mean residual and the mean square noise of that mean.
    let mean = |s: &[(Vector3<f64>, f64)]| {
        let n = s.len() as f64;
        (
            s.iter().map(|(r, _)| r).sum::<Vector3<f64>>() / n,
            s.iter().map(|(_, m)| m).sum::<f64>() / (n * n),
        )
    };
    let ((rc, nc), (rv, nv)) = (mean(&c), mean(&v));
    let d = rv - rc;
    let reference = TimeReference {
        axes_deg: key.map(|k| k as f64 * 1e-4),
        campaign_repeats: c.len(),
        validation_repeats: v.len(),
        drift_um: [d.x * 1e3, d.y * 1e3, d.z * 1e3],
    };
    Some((reference, d, (d.norm_squared() - nc - nv).max(0.0)))
}

/// The budget of `validation` (rows of the calibration's model against validation
/// measurements, gross errors left out) given the calibration `campaign`'s rows (same model,
/// the points `identify` fitted), the model's parameter `covariance` and the instrument.
pub fn budget(
    model: &Model,
    covariance: &Covariance,
    campaign: &[Row],
    validation: &[Row],
    instrument: &Instrument,
) -> Budget {
    use rayon::prelude::*;
    let [form, campaign_ms, campaign_tracker] =
        campaign_lack_of_fit_mm2(campaign, instrument, covariance.parameters_in_fit());
    let key = reference_pose(campaign);
    let time = key
        .as_ref()
        .and_then(|k| drift(k, campaign, validation, instrument));
    let (shift, time_ms) = time
        .as_ref()
        .map_or((Vector3::zeros(), 0.0), |(_, d, ms)| (*d, *ms));
    // The budgeted points: the validation less its measurements of the reference pose.
    let points: Vec<&Row> = validation
        .iter()
        .filter(|r| time.is_none() || Some(pose_key(&r.state.axes_deg)) != key)
        .collect();
    let each: Vec<(f64, f64, f64)> = points
        .par_iter()
        .map(|r| {
            let identification = covariance.target(model, &r.state).trace().max(0.0);
            (
                r.residual().norm_squared(),
                instrument.mean_square_mm2(&r.measured),
                identification,
            )
        })
        .collect();
    // The identification errors' cross-covariance between each point and the next.
    let neighbours: Vec<f64> = (0..points.len())
        .into_par_iter()
        .map(|i| match points.get(i + 1) {
            Some(next) if next.test == points[i].test && next.source == points[i].source => {
                covariance
                    .between_targets(model, &points[i].state, &next.state)
                    .trace()
            }
            _ => 0.0,
        })
        .collect();
    let parts = |select: &dyn Fn(&Row) -> bool| -> Parts {
        let chosen: Vec<usize> = (0..points.len()).filter(|&i| select(points[i])).collect();
        let n = chosen.len().max(1) as f64;
        let mean = |f: &dyn Fn(usize) -> f64| chosen.iter().map(|&i| f(i)).sum::<f64>() / n;
        let measured = mean(&|i| each[i].0);
        let tracker = mean(&|i| each[i].1);
        let identification = mean(&|i| each[i].2);
        // Consecutive stops of one test of one file (one after the other in the file), time
        // shift taken off.
        let pairs: Vec<usize> = chosen
            .windows(2)
            .filter(|w| {
                let (a, b) = (points[w[0]], points[w[1]]);
                w[1] == w[0] + 1 && a.test == b.test && a.source == b.source
            })
            .map(|w| w[0])
            .collect();
        let products: Vec<f64> = pairs
            .iter()
            .map(|&i| (points[i].residual() - shift).dot(&(points[i + 1].residual() - shift)))
            .collect();
        let systematic = products.iter().sum::<f64>() / products.len().max(1) as f64;
        // What the identification's errors share between the same neighbours (predicted).
        let identification_shared =
            pairs.iter().map(|&i| neighbours[i]).sum::<f64>() / pairs.len().max(1) as f64;
        let form = systematic - identification_shared;
        let explained = tracker + identification + form + time_ms;
        let offset = chosen
            .iter()
            .map(|&i| points[i].residual())
            .sum::<Vector3<f64>>()
            / n;
        Parts {
            points: chosen.len(),
            measured_um: measured.sqrt() * 1e3,
            tracker_um: tracker.sqrt() * 1e3,
            time_um: time_ms.sqrt() * 1e3,
            systematic_um: signed_root(systematic) * 1e3,
            identification_um: identification.sqrt() * 1e3,
            identification_shared_um: signed_root(identification_shared) * 1e3,
            model_form_um: signed_root(form) * 1e3,
            explained_um: signed_root(explained) * 1e3,
            unexplained_um: signed_root(measured - explained) * 1e3,
            offset_um: offset.norm() * 1e3,
        }
    };
    let owned: Vec<Row> = points.iter().map(|r| (*r).clone()).collect();
    let tests = super::test_order(&owned)
        .into_iter()
        .map(|t| {
            let p = parts(&|r: &Row| r.test == t);
            (t, p)
        })
        .collect();
    Budget {
        all: parts(&|_| true),
        campaign_rms_um: campaign_ms.sqrt() * 1e3,
        campaign_tracker_um: campaign_tracker.sqrt() * 1e3,
        campaign_model_form_um: form.sqrt() * 1e3,
        time_reference: time.map(|(t, _, _)| t),
        tests,
        points: points
            .iter()
            .zip(&each)
            .map(|(r, p)| PointParts {
                test: r.test.clone(),
                source: r.source.clone(),
                line: r.line,
                measured_um: p.0.sqrt() * 1e3,
                tracker_um: p.1.sqrt() * 1e3,
                identification_um: p.2.sqrt() * 1e3,
                time_um: time_ms.sqrt() * 1e3,
            })
            .collect(),
    }
}
