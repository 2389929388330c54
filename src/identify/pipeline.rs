//! `robopost identify` as a library call: build the model to identify (fresh effects with
//! grids from the data, or an existing calibration plus added effects), start the tracker
//! registration, run the direct method when the data hold indexing tests and the model is
//! fresh, refine globally, and wrap the result as a calibration with its provenance.

use nalgebra::{Point3, Vector3};

use super::direct::{direct_method, DirectResult};
use super::refine::{refine, Fit, IdentifyError, ProgressFn, RefineOptions};
use super::register::rigid_fit;
use super::setup::{add_effects, GridChoice};
use crate::calibration::{Calibration, KukaFrame, MeasurementFrame, Provenance};
use crate::kinematics::{Payload, RobotDescription};
use crate::measure::Stop;
use crate::model::{EffectName, Model};

/// The paper's full model, the default effect list.
pub const PAPER_EFFECTS: &str = "geometric,map:A1..A6,backlash:A1..A6,crosstalk:A3->A2";

/// Which effects to identify.
#[derive(Clone, Debug, PartialEq)]
pub enum Effects {
    /// Exactly these (those the base calibration has start from its values).
    Exactly(Vec<EffectName>),
    /// The base calibration's effects plus these (`--effects +NAME`).
    Add(Vec<EffectName>),
}

/// What to identify and from what.
#[derive(Clone, Default)]
pub struct Request {
    /// `None`: the paper's full model.
    pub effects: Option<Effects>,
    /// An existing calibration: robot, payload, target, frame and starting values.
    pub base: Option<Calibration>,
    /// Positions are in a tracker frame: identify its pose too.
    pub tracker_frame: bool,
    pub grid: GridChoice,
    /// Measurement target in the flange frame (mm) when there is no base calibration.
    pub target_mm: Option<[f64; 3]>,
    pub robot_name: Option<String>,
    /// Measurement files, for the provenance.
    pub sources: Vec<String>,
    pub progress: Option<ProgressFn>,
}

/// The outcome: the new calibration, the fit, and what the direct method found.
#[derive(Clone, Debug)]
pub struct Identified {
    pub calibration: Calibration,
    pub fit: Fit,
    pub direct: Option<DirectResult>,
    /// The effects identified (canonical names).
    pub effects: Vec<String>,
    /// Identified values brought into their physical range, and why (e.g. a gear play whose
    /// bidirectional difference came out leading).
    pub physical: Vec<String>,
}

/// Runs the identification (see the module documentation).
pub fn identify(stops: &[Stop], request: &Request) -> Result<Identified, IdentifyError> {
    if !stops.iter().any(|s| s.measured_mm.is_some()) {
        return Err(IdentifyError::NoMeasurements);
    }
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
                    kept.push(e.clone());
                }
            }
            model = kept;
            add_effects(&mut model, &names, stops, &request.grid).map_err(IdentifyError::Setup)?;
        }
        Effects::Add(names) => {
            add_effects(&mut model, &names, stops, &request.grid).map_err(IdentifyError::Setup)?;
        }
    }
    let effects: Vec<String> = model.effects().iter().map(|e| e.name()).collect();

    // Tracker frame: the base calibration's, else the rigid best fit onto the start model.
    let initial_frame = if request.tracker_frame {
        match old_frame {
            Some(MeasurementFrame::Tracker(f)) => Some(f.to_isometry()),
            _ => {
                let (measured, predicted): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = stops
                    .iter()
                    .filter_map(|s| s.measured_mm.map(|m| (m, model.target_position(&s.state))))
                    .unzip();
                Some(rigid_fit(&measured, &predicted).ok_or(IdentifyError::FrameStart)?)
            }
        }
    } else {
        None
    };

    // The direct method reads circles in the base frame.
    let direct = if fresh {
        let in_base: Vec<Stop> = match initial_frame {
            Some(f) => stops
                .iter()
                .map(|s| Stop {
                    measured_mm: s.measured_mm.map(|m| (f * Point3::from(m)).coords),
                    ..s.clone()
                })
                .collect(),
            None => stops.to_vec(),
        };
        direct_method(&mut model, &in_base)
    } else {
        None
    };

    let options = RefineOptions {
        tracker_frame: request.tracker_frame,
        initial_frame,
        progress: request.progress.clone(),
        ..RefineOptions::default()
    };
    let fit = refine(&mut model, stops, &options)?;
    let physical = model.make_physical(&fit.standard_errors);
    let frame = match fit.tracker_frame {
        Some(f) => MeasurementFrame::Tracker(KukaFrame::from_isometry(&f)),
        None => MeasurementFrame::Base,
    };
    let provenance = Provenance {
        sources: request.sources.clone(),
        date: Some(today_utc()),
        fit: [
            ("points", fit.stats.points as f64),
            ("rms_um", fit.stats.rms_um),
            ("xy_mean_um", fit.stats.xy_mean_um),
            ("xy_2sigma_um", fit.stats.xy_2sigma_um),
            ("z_mean_um", fit.stats.z_mean_um),
            ("z_2sigma_um", fit.stats.z_2sigma_um),
            ("d3_max_um", fit.stats.d3_max_um),
            ("sigma_um", fit.sigma_mm * 1000.0),
            ("iterations", fit.iterations as f64),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect(),
        notes: Some(format!(
            "identified by robopost {} ({}global Levenberg–Marquardt refinement) with effects {}{}{}",
            env!("CARGO_PKG_VERSION"),
            if direct.is_some() {
                "direct method, then "
            } else {
                ""
            },
            effects.join(","),
            if physical.is_empty() {
                String::new()
            } else {
                format!("; {}", physical.join(" | "))
            },
            if fit.warnings.is_empty() {
                String::new()
            } else {
                format!(
                    "; {} warning(s): {}",
                    fit.warnings.len(),
                    fit.warnings
                        .iter()
                        .map(|w| w.to_string())
                        .collect::<Vec<_>>()
                        .join(" | ")
                )
            }
        )),
    };
    let calibration = Calibration::from_model(&robot_name, model, frame, provenance);
    Ok(Identified {
        calibration,
        fit,
        direct,
        effects,
        physical,
    })
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
