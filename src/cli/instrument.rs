//! `--tracker NAME|C+M/m` and `--tracker-at X,Y,Z`: the laser tracker's stated accuracy and
//! where it stands, shared by `identify` and `diagnose` (docs/trackers.md).

use nalgebra::Vector3;

use super::Exit;
use crate::measure::tracker::Tracker;

#[derive(clap::Args, Debug, Clone, Default)]
pub struct TrackerArgs {
    /// The laser tracker: a preset (at960, at500, at403, vantage, radian) or its MPE in µm as
    /// `C+M/m` (e.g. `15+6/m`). Sets the noise of each point: the noise floor, the gross-error
    /// test and the poor-fit refusal. Default: at960.
    #[arg(long = "tracker", value_name = "NAME|C+M/m")]
    pub tracker: Option<String>,
    /// Where the tracker head stands in the robot base frame, mm (`X,Y,Z`), when the
    /// positions are in the base frame (with `--frame tracker` the identified frame says it).
    /// Default: assumed 3 m in front of the robot.
    #[arg(
        long = "tracker-at",
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_negative_numbers = true
    )]
    pub tracker_at: Option<Vec<f64>>,
}

impl TrackerArgs {
    /// The tracker, or the usage error.
    pub fn tracker(&self) -> Result<Tracker, Exit> {
        let mut t = match &self.tracker {
            Some(spec) => Tracker::parse(spec).map_err(super::usage)?,
            None => Tracker::default(),
        };
        if let Some(at) = &self.tracker_at {
            match at.as_slice() {
                [x, y, z] if at.iter().all(|v| v.is_finite()) => {
                    t.station_mm = Some(Vector3::new(*x, *y, *z))
                }
                _ => return Err(super::usage("--tracker-at takes X,Y,Z in mm")),
            }
        }
        Ok(t)
    }
}
