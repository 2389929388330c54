//! What a residual may depend on: the quantities that drive the physical effects of the
//! contract table — each axis's command angle (maps, backlash, tilt, crosstalk), the gravity
//! torque on A2 and A3 (compliance) and the campaign clock (drift). The report plots residuals
//! against each; diagnosis words its evidence in them.

use crate::model::effects::compliance::gravity_torques_knm;
use crate::model::{AxisState, Model};

/// One candidate driver of a residual.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Driver {
    /// Command angle of axis n (1..=6), degrees.
    Angle(u8),
    /// Gravity torque on axis n, kN·m (KUKA sign).
    Torque(u8),
    /// Seconds since the start of the campaign, shown in hours.
    Time,
}

/// Every driver the report plots against, in display order.
pub const DRIVERS: [Driver; 9] = [
    Driver::Angle(1),
    Driver::Angle(2),
    Driver::Angle(3),
    Driver::Angle(4),
    Driver::Angle(5),
    Driver::Angle(6),
    Driver::Torque(2),
    Driver::Torque(3),
    Driver::Time,
];

impl Driver {
    /// Its value at `state` in display units (°, kN·m, h); `None` for a torque when the robot
    /// has no mass data.
    pub fn value(&self, model: &Model, state: &AxisState) -> Option<f64> {
        match *self {
            Driver::Angle(n) => Some(state.axes_deg[n as usize - 1]),
            Driver::Torque(n) => gravity_torques_knm(&model.robot, &model.payload, &state.axes_deg)
                .map(|t| t[n as usize - 1]),
            Driver::Time => Some(state.time_s / 3600.0),
        }
    }

    /// Axis label as a user reads it: `A3 angle (°)`, `A2 gravity torque (kN·m)`, `time (h)`.
    pub fn label(&self) -> String {
        match self {
            Driver::Angle(n) => format!("A{n} angle (°)"),
            Driver::Torque(n) => format!("A{n} gravity torque (kN·m)"),
            Driver::Time => "time (h)".to_string(),
        }
    }

    /// The driver's name in a sentence: `the A3 angle`, `the A2 gravity torque`, `time`.
    pub fn phrase(&self) -> String {
        match self {
            Driver::Angle(n) => format!("the A{n} angle"),
            Driver::Torque(n) => format!("the A{n} gravity torque"),
            Driver::Time => "time".to_string(),
        }
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn unit(&self) -> &'static str {
        match self {
            Driver::Angle(_) => "°",
            Driver::Torque(_) => "kN·m",
            Driver::Time => "h",
        }
    }
}
