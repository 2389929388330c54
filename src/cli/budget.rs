//! What the error-budget options share: a calibration's parameter covariance from the
//! measurement files it was identified from (`--campaign` of the main job, the calibration
//! file of `compare --budget`), read with the usual located errors.

use std::path::PathBuf;
use std::sync::Arc;

use super::Exit;
use crate::calibration::Calibration;
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
