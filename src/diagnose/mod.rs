//! Diagnosis: which physical effect is the model missing? From the current calibration's
//! residuals it estimates the noise floor ([`noise`]), tries every effect of the contract
//! table the calibration lacks ([`candidates`]) by fitting it alone on top of the current
//! model and scoring it on held-out points ([`crossval`], candidates in parallel), ranks them
//! by how much of the residual they explain, and words the evidence from the data
//! ([`evidence`]) with the command that adds the effect. A finding must be significant on the
//! held-out points; when none is, the residual is at what the data can tell apart from noise
//! and the verdict says that nothing significant is missing.

pub mod candidates;
pub mod crossval;
pub mod evidence;
pub mod noise;
pub mod twins;

use rayon::prelude::*;
use serde::Serialize;

use crate::calibration::Calibration;
use crate::compare::{self, Row};
use crate::identify::setup::GridChoice;
use crate::measure::{Measurements, Stop};
use crate::model::{EffectName, Model};

pub use crossval::Evaluation;
pub use noise::{NoiseFloor, NoiseSource};

/// Choices of a diagnosis.
#[derive(Clone, Debug, PartialEq)]
pub struct DiagnoseOptions {
    /// Folds of the cross-validation.
    pub folds: usize,
    /// Effects to try; `None`: every effect of the table the calibration lacks.
    pub only: Option<Vec<EffectName>>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            folds: 4,
            only: None,
        }
    }
}

/// A finding must remove at least this fraction of the held-out residual sum of squares …
pub const MIN_EXPLAINED: f64 = 0.01;
/// … with a paired t statistic of the per-point gains at least this large (a missing effect
/// on a campaign gives 7 to 20; on data without one every candidate stays under 1) …
pub const MIN_T: f64 = 5.0;
/// … and lower the RMS by at least this much, µm.
pub const MIN_RMS_GAIN_UM: f64 = 0.1;
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

/// One evaluated effect (CONTRACTS.md keys first).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    pub effect: String,
    /// Fraction of the held-out residual sum of squares it removes (0..1; negative: worse).
    pub explained: f64,
    /// RMS 3-D residual of the held-out predictions with it, µm.
    pub rms_after_um: f64,
    pub evidence: String,
    /// The `identify` option that adds it.
    pub add: String,
    pub significant: bool,
    pub t_statistic: f64,
    pub parameters: usize,
    /// Effects that explain the same residual on these data (physically indistinguishable
    /// here); either may be the cause.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub indistinguishable_from: Vec<String>,
    /// Why it could not be evaluated (then it is not significant).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_evaluated: Option<String>,
}

/// The result of [`diagnose`] (`diagnose --json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnosis {
    /// RMS 3-D residual of the current model, µm.
    pub rms_um: f64,
    /// The noise floor as an RMS 3-D residual, µm.
    pub noise_um: f64,
    pub noise_source: NoiseSource,
    pub points: usize,
    /// Significant findings, best first; empty at the noise floor.
    pub candidates: Vec<Finding>,
    /// Every effect evaluated, best first.
    pub considered: Vec<Finding>,
    pub verdict: String,
}

/// Why a diagnosis could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiagnoseError {
    #[error("the measurement files hold no measured row")]
    NoMeasurements,
}

/// The `--effects` value that adds `name` (quoted: `>` is a shell redirection).
pub fn add_option(name: &str) -> String {
    format!("--effects '+{name}'")
}

/// Diagnoses `cal` against `data`.
pub fn diagnose(
    cal: &Calibration,
    data: &[Measurements],
    options: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    let rows = compare::compare(cal, data);
    if rows.is_empty() {
        return Err(DiagnoseError::NoMeasurements);
    }
    let model = cal.model_ref();
    let floor = noise::estimate(&rows, &cal.frame);
    let before: Vec<_> = rows.iter().map(Row::residual).collect();
    let rms = crossval::rms_um(&before);
    // The measured points in the base frame, as identification takes them.
    let stops: Vec<Stop> = rows
        .iter()
        .map(|r| Stop {
            test: r.test.clone(),
            state: r.state,
            measured_mm: Some(r.measured),
            line: r.line,
        })
        .collect();
    let grid = grid_choice(model);
    let names = options
        .only
        .clone()
        .unwrap_or_else(|| candidates::missing(model));
    let mut evaluations: Vec<Evaluation> = names
        .par_iter()
        .map(|name| crossval::evaluate(model, &stops, &before, name, options.folds, &grid))
        .collect();
    evaluations.sort_by(|a, b| b.explained.total_cmp(&a.explained));

    let significant = |e: &Evaluation| {
        e.not_evaluated.is_none()
            && e.explained >= MIN_EXPLAINED
            && e.t >= MIN_T
            && rms - e.rms_after_um >= MIN_RMS_GAIN_UM
    };
    // Twins of the best significant candidate: significant candidates that correct the
    // points the same way, and candidates close to it or that gravity makes look alike that
    // explain as much once the model is re-identified around them.
    let best = evaluations.iter().find(|e| significant(e));
    let twins_of_best: Vec<String> = match best {
        None => Vec::new(),
        Some(b) => {
            let similar = evaluations.iter().filter(|o| {
                o.name != b.name
                    && significant(o)
                    && crossval::similarity(&b.correction, &o.correction) >= SAME_RESIDUAL
            });
            let partners = twins::gravity_partners(&b.name);
            let mut plausible: Vec<&Evaluation> = evaluations
                .iter()
                .filter(|o| {
                    let close = significant(o) && o.explained >= TWIN_CLOSE * b.explained;
                    o.not_evaluated.is_none() && (close || partners.contains(&o.name))
                })
                .collect();
            plausible.sort_by(|x, y| y.t.total_cmp(&x.t));
            plausible.truncate(MAX_TWIN_FITS);
            let plausible: Vec<EffectName> = plausible.iter().map(|o| o.name).collect();
            let mut names: Vec<String> = similar.map(|o| o.name.to_string()).collect();
            for t in twins::twins(model, &stops, &b.name, &plausible, &grid) {
                if !names.contains(&t) {
                    names.push(t);
                }
            }
            names
        }
    };
    let considered: Vec<Finding> = evaluations
        .iter()
        .map(|e| {
            let same = if best.is_some_and(|b| b.name == e.name) {
                twins_of_best.clone()
            } else if twins_of_best.contains(&e.name.to_string()) {
                best.map(|b| vec![b.name.to_string()]).unwrap_or_default()
            } else {
                Vec::new()
            };
            finding(e, significant(e), same, model, &rows, rms)
        })
        .collect();
    let candidates: Vec<Finding> = considered
        .iter()
        .filter(|f| f.significant)
        .cloned()
        .collect();
    let verdict = verdict(rms, &floor, &candidates);
    Ok(Diagnosis {
        rms_um: rms,
        noise_um: floor.rms_um,
        noise_source: floor.source,
        points: rows.len(),
        candidates,
        considered,
        verdict,
    })
}

/// Grids of candidate tables: the pitch of the calibration's own map and backlash tables
/// (the pitch its campaign was measured at), else the defaults.
pub fn grid_choice(model: &Model) -> GridChoice {
    let pitch = model
        .effects()
        .iter()
        .filter(|e| {
            let name = e.name();
            name.starts_with("map:") || name.starts_with("backlash:")
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
    same: Vec<String>,
    model: &Model,
    rows: &[Row],
    rms: f64,
) -> Finding {
    let name = e.name.to_string();
    let evidence = match &e.not_evaluated {
        Some(why) => format!("not evaluated: {why}"),
        None => {
            let mut s = evidence::describe(&e.name, model, rows);
            s += &format!(
                "; fitted without the points it is scored on, it explains {:.0}% of their \
                 residual ({rms:.1} → {:.1} µm RMS)",
                100.0 * e.explained.max(0.0),
                e.rms_after_um
            );
            if !same.is_empty() {
                s += &format!("; indistinguishable on these data from {}", same.join(", "));
            }
            s
        }
    };
    Finding {
        add: add_option(&name),
        effect: name,
        explained: e.explained,
        rms_after_um: e.rms_after_um,
        evidence,
        significant,
        t_statistic: e.t,
        parameters: e.parameters,
        indistinguishable_from: same,
        not_evaluated: e.not_evaluated.clone(),
    }
}

fn verdict(rms: f64, floor: &NoiseFloor, candidates: &[Finding]) -> String {
    let at = format!(
        "{rms:.1} µm RMS against a noise floor of {:.1} µm ({})",
        floor.rms_um,
        floor.source.describe()
    );
    match candidates.first() {
        None if rms <= AT_FLOOR * floor.rms_um => format!(
            "Nothing significant is missing: no effect of the table explains any of the \
             residual on held-out points, and the residual is at the noise floor ({at})."
        ),
        None => format!(
            "Nothing the table offers is missing: no effect of it explains the residual on \
             held-out points, yet the residual is well above the noise floor ({at}); look at \
             the report (`robopost compare --report`) for outliers or a set-up problem."
        ),
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
