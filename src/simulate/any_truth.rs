//! Either kind of truth behind one interface, for the command line: a model truth
//! (`robopost-truth/1`, the [`VirtualRobot`]) or a physical one
//! (`robopost-physical-truth/1`, the [`PhysicalRobot`]), told apart by the file's `format`.

use std::path::Path;

use nalgebra::Vector3;

use super::campaign::PlannedStop;
use super::physical::{self, PhysicalError, PhysicalRobot, PHYSICAL_FORMAT, PTP_STEP_DEG};
use super::program::ProgramVisit;
use super::virtual_robot::{SimulateError, VirtualRobot};
use crate::calibration::CalError;
use crate::kinematics::RobotDescription;
use crate::measure::Stop;

/// A truth read from a file.
#[derive(Clone, Debug)]
pub enum Truth {
    Model(Box<VirtualRobot>),
    Physical(Box<PhysicalRobot>),
}

impl Truth {
    /// Reads a truth file of either format.
    pub fn load(path: &Path) -> Result<Truth, CalError> {
        let text = crate::input::read_to_string(path).map_err(|source| CalError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let format = serde_json::from_str::<serde_json::Value>(&text)
            .ok()
            .and_then(|v| v.get("format").and_then(|f| f.as_str().map(String::from)));
        if format.as_deref() == Some(PHYSICAL_FORMAT) {
            let file = physical::parse(&text, path)?;
            return Ok(Truth::Physical(Box::new(PhysicalRobot::new(file, path)?)));
        }
        let file = super::truth::parse(&text, path)?;
        Ok(Truth::Model(Box::new(VirtualRobot::from_truth(
            &file, path,
        )?)))
    }

    pub fn with_seed(self, seed: u64) -> Truth {
        match self {
            Truth::Model(r) => Truth::Model(Box::new((*r).with_seed(seed))),
            Truth::Physical(r) => Truth::Physical(Box::new((*r).with_seed(seed))),
        }
    }

    /// The robot's nominal description.
    pub fn robot(&self) -> &RobotDescription {
        match self {
            Truth::Model(r) => &r.truth.robot,
            Truth::Physical(r) => r.robot(),
        }
    }

    /// The measurement target in the KUKA flange frame, mm.
    pub fn target_mm(&self) -> Vector3<f64> {
        match self {
            Truth::Model(r) => r.truth.target_mm,
            Truth::Physical(r) => r.target_mm(),
        }
    }

    /// Visits `stops` (joined by PTP motion) and measures the measured ones.
    pub fn measure(&self, stops: &[PlannedStop]) -> Result<Vec<Stop>, SimulateError> {
        match self {
            Truth::Model(r) => r.measure(stops),
            Truth::Physical(r) => {
                let samples = physical::from_stops(stops, PTP_STEP_DEG);
                r.measure(&samples).map_err(|e| at_stop(e, &samples))
            }
        }
    }

    /// Runs the visits of a program.
    pub fn run_program(&self, visits: &[ProgramVisit]) -> Result<Vec<Stop>, SimulateError> {
        match self {
            Truth::Model(r) => r.run_program(visits),
            Truth::Physical(r) => {
                let samples = physical::from_program(visits, PTP_STEP_DEG);
                r.measure(&samples).map_err(|e| at_stop(e, &samples))
            }
        }
    }
}

/// A refused sample as the stop it belongs to (the stops are the rows: samples between two
/// stops within the limits are within them too, the limits being a box).
fn at_stop(e: PhysicalError, samples: &[physical::CommandSample]) -> SimulateError {
    let PhysicalError::OutOfLimits {
        index,
        test,
        axis,
        angle_deg,
        lo,
        hi,
        ..
    } = e;
    let stop = samples[..index]
        .iter()
        .filter(|s| s.kind != physical::SampleKind::Pass)
        .count();
    SimulateError::OutOfLimits {
        index: stop,
        test,
        axis,
        angle_deg,
        lo,
        hi,
    }
}
