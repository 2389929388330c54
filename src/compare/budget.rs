//! An error budget of a calibration on validation measurements: what each source
//! contributes to the residual `measured − predicted`, each measured from the data, in mean
//! square 3-D error (µm², so that independent parts add; shown as root-sum-square µm):
//!
//! - **tracker**: the validation measurement's own noise, from the instrument's accuracy at
//!   each point's distance from its station (`Tracker::sigma_mm`, per coordinate);
//! - **identification**: the calibration campaign's tracker noise carried through the fit
//!   to each validation point (the parameter covariance, [`crate::identify::covariance`]);
//! - **model form**: what the model cannot represent, measured as the campaign fit's lack of
//!   fit — its residual mean square less what the tracker's noise leaves in a least-squares
//!   residual (`3σ²(1 − p/3n)`), the same at every validation point;
//! - **unexplained**: the measured mean square less the parts (negative when the parts
//!   over-explain it). The validation's mean residual (a constant offset: drift since the
//!   campaign, a frame) is shown beside it, as part of what is measured.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::Serialize;

use super::Row;
use crate::identify::covariance::Covariance;
use crate::measure::tracker::Tracker;
use crate::model::Model;

/// The parts of one set of points (all of them, or one test), µm RMS (3-D).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Parts {
    pub points: usize,
    /// The measured residual's 3-D RMS.
    pub measured_um: f64,
    pub tracker_um: f64,
    pub identification_um: f64,
    pub model_form_um: f64,
    /// Root-sum-square of the three parts above.
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
    pub model_form_um: f64,
}

/// The budget: overall, per test (by label), per point.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Budget {
    #[serde(flatten)]
    pub all: Parts,
    /// The campaign fit's residual 3-D RMS and the tracker's share of it, µm, from which the
    /// model form is measured.
    pub campaign_rms_um: f64,
    pub campaign_tracker_um: f64,
    pub tests: BTreeMap<String, Parts>,
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

/// The model-form mean square (mm², 3-D) from the campaign fit's residuals: their mean
/// square less the tracker's noise left in a least-squares residual with `parameters` free
/// parameters; also the campaign's measured and tracker mean squares.
fn model_form_mm2(campaign: &[Row], instrument: &Instrument, parameters: usize) -> [f64; 3] {
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
    [(measured - tracker * kept).max(0.0), measured, tracker * kept]
}

fn signed_root(v: f64) -> f64 {
    v.signum() * v.abs().sqrt()
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
        model_form_mm2(campaign, instrument, covariance.parameters_in_fit());
    let points: Vec<(f64, f64, f64)> = validation
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
    let parts = |select: &dyn Fn(&Row) -> bool| -> Parts {
        let chosen: Vec<(usize, &Row)> = validation
            .iter()
            .enumerate()
            .filter(|(_, r)| select(r))
            .collect();
        let n = chosen.len().max(1) as f64;
        let mean = |f: &dyn Fn(usize) -> f64| chosen.iter().map(|(i, _)| f(*i)).sum::<f64>() / n;
        let measured = mean(&|i| points[i].0);
        let tracker = mean(&|i| points[i].1);
        let identification = mean(&|i| points[i].2);
        let explained = tracker + identification + form;
        let offset = chosen
            .iter()
            .map(|(_, r)| r.residual())
            .sum::<Vector3<f64>>()
            / n;
        Parts {
            points: chosen.len(),
            measured_um: measured.sqrt() * 1e3,
            tracker_um: tracker.sqrt() * 1e3,
            identification_um: identification.sqrt() * 1e3,
            model_form_um: form.sqrt() * 1e3,
            explained_um: explained.sqrt() * 1e3,
            unexplained_um: signed_root(measured - explained) * 1e3,
            offset_um: offset.norm() * 1e3,
        }
    };
    let tests = super::test_order(validation)
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
        tests,
        points: validation
            .iter()
            .zip(&points)
            .map(|(r, p)| PointParts {
                test: r.test.clone(),
                source: r.source.clone(),
                line: r.line,
                measured_um: p.0.sqrt() * 1e3,
                tracker_um: p.1.sqrt() * 1e3,
                identification_um: p.2.sqrt() * 1e3,
                model_form_um: form.sqrt() * 1e3,
            })
            .collect(),
    }
}
