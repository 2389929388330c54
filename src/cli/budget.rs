//! What the error-budget options share: a calibration's parameter covariance from the
//! measurement files it was identified from (`--campaign` of the main job, the calibration
//! file of `compare --budget`), read with the usual located errors; and the budget itself
//! (`compare --budget`), as JSON or a table.

use std::path::PathBuf;
use std::sync::Arc;

use super::Exit;
use crate::calibration::{Calibration, MeasurementFrame};
use crate::identify::covariance::{self, Covariance};
use crate::measure;

/// The covariance of `cal` from `campaign` (`None` when no file is given); an unreadable file
/// or a fit that cannot be set up is a usage error (exit 2), reported here.
pub fn covariance_of(
    cal: &Calibration,
    campaign: &[PathBuf],
) -> Result<Option<Arc<Covariance>>, Exit> {
    if campaign.is_empty() {
        return Ok(None);
    }
    let limits = cal.model_ref().robot.limits_deg;
    let mut files = Vec::new();
    for path in campaign {
        match measure::read_csv_within(path, Some(&limits)) {
            Ok(m) => files.push(m),
            Err(e) => {
                eprint!("{}", e.render());
                return Err(Exit::Usage);
            }
        }
    }
    covariance::of_calibration(cal, &files)
        .map(Some)
        .map_err(|e| {
            let names: Vec<String> = campaign.iter().map(|p| p.display().to_string()).collect();
            eprintln!(
                "error: the calibration's uncertainty from {}: {e}",
                names.join(", ")
            );
            Exit::Usage
        })
}

/// `compare --budget CAMPAIGN.csv`: the error budget of the calibration on the validation
/// rows (gross errors left out), as JSON or as a table on standard output. `None`: the
/// error was printed, exit 2.
pub fn budget(
    cal: &Calibration,
    campaign: &[PathBuf],
    tracker: &super::instrument::TrackerArgs,
    validation: &[crate::compare::Row],
) -> Result<crate::compare::budget::Budget, Exit> {
    let tracker = tracker.tracker()?;
    let limits = cal.model_ref().robot.limits_deg;
    let mut files = Vec::new();
    for path in campaign {
        match measure::read_csv_within(path, Some(&limits)) {
            Ok(m) => files.push(m),
            Err(e) => {
                eprint!("{}", e.render());
                return Err(Exit::Usage);
            }
        }
    }
    let covariance = covariance_of_files(cal, campaign, &files)?;
    let marks = crate::compare::gross_errors(cal, &files);
    let rows: Vec<crate::compare::Row> = crate::compare::compare(cal, &files)
        .into_iter()
        .zip(&marks)
        .filter(|(_, m)| m.is_none())
        .map(|(r, _)| r)
        .collect();
    let station = match (tracker.station_mm, cal.frame) {
        (Some(at), _) => at,
        (None, MeasurementFrame::Tracker(f)) => crate::kinematics::Frame::from_kuka(&f).position,
        (None, MeasurementFrame::Base) => {
            nalgebra::Vector3::from(crate::diagnose::noise::ASSUMED_STATION_MM)
        }
    };
    let instrument = crate::compare::budget::Instrument {
        tracker,
        station_mm: station,
    };
    Ok(crate::compare::budget::budget(
        cal.model_ref(),
        &covariance,
        &rows,
        validation,
        &instrument,
    ))
}

fn covariance_of_files(
    cal: &Calibration,
    campaign: &[PathBuf],
    files: &[measure::Measurements],
) -> Result<Arc<Covariance>, Exit> {
    let names: Vec<String> = campaign.iter().map(|p| p.display().to_string()).collect();
    let covariance = covariance::of_calibration(cal, files).map_err(|e| {
        eprintln!(
            "error: the calibration's uncertainty from {}: {e}",
            names.join(", ")
        );
        Exit::Usage
    })?;
    // Other files than the calibration's give the covariance of another fit: said when the
    // fit's scatter is not the one `identify` recorded.
    if let Some(recorded) = cal.provenance.fit.get("sigma_um") {
        let rebuilt = covariance.sigma_mm * 1e3;
        if !(0.9..=1.1).contains(&(rebuilt / recorded)) {
            eprintln!(
                "warning: the calibration fitted to {} scatters by {rebuilt:.1} µm per coordinate, where identify recorded {recorded:.1} µm: these may not be the files it was identified from, and the uncertainty is that of a fit to them",
                names.join(", ")
            );
        }
    }
    Ok(covariance)
}

/// The budget as a table: overall, then per test, then where the time part comes from.
pub fn render(b: &crate::compare::budget::Budget) -> String {
    let mut out = String::from(
        "error budget (3-D RMS, µm; tracker, identification, time and model form add in mean \
         square to explained; systematic: what neighbouring stops share, of which model form is \
         the part the identification's errors do not share):\n\
         | test | points | measured | tracker | time | systematic | identification | model form | explained | unexplained | offset |\n\
         |---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let line = |name: &str, p: &crate::compare::budget::Parts| {
        format!(
            "| {name} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |\n",
            p.points,
            p.measured_um,
            p.tracker_um,
            p.time_um,
            p.systematic_um,
            p.identification_um,
            p.model_form_um,
            p.explained_um,
            p.unexplained_um,
            p.offset_um
        )
    };
    out += &line("all", &b.all);
    for (name, p) in &b.tests {
        out += &line(name, p);
    }
    out += &match &b.time_reference {
        Some(t) => format!(
            "(time: the reference pose {:?}, measured {} times in the campaign and {} in the \
             validation, moved by ({:.1}, {:.1}, {:.1}) µm; ",
            t.axes_deg,
            t.campaign_repeats,
            t.validation_repeats,
            t.drift_um[0],
            t.drift_um[1],
            t.drift_um[2]
        ),
        None => "(time: not measured — no pose the campaign measured at least 3 times is in the \
                 validation; start the validation at the campaign's reference pose; "
            .to_string(),
    };
    out += &format!(
        "systematic: the mean product of consecutive stops' residuals; the campaign fit's lack \
         of fit, the model form the campaign sees: {:.1} µm of {:.1} µm RMS, the tracker {:.1} µm; \
         unexplained: measured less the parts, negative when they exceed it; offset: the mean \
         residual's length)\n",
        b.campaign_model_form_um, b.campaign_rms_um, b.campaign_tracker_um
    );
    out
}
