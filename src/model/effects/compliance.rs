//! `compliance:An` — elastic deflection of axis n proportional to the gravity torque it
//! carries: `dθ_n = c_n · τ_n(q)`, c_n in deg/kNm. τ_n is the moment about axis n's line of
//! the weights of every body beyond it (link masses at their centres of gravity from
//! `RobotDescription::gravity`, and the payload), `τ_n = u_n · Σ_k (c_k − o_n) × m_k·g`,
//! evaluated on the nominal chain at the command angles (the deflection is small, so the
//! errors do not change the lever arms to first order). τ_n is signed like the KUKA angle, so
//! a positive c means the axis gives way in the direction gravity pulls it.

use std::f64::consts::PI;

use nalgebra::Vector3;

use super::{EffectError, ToRecord};
use crate::kinematics::{Payload, RobotDescription};
use crate::model::chain::ChainFrames;
use crate::model::effect::{
    ChainErrors, Context, Effect, Parameter, Partial, RecordRange, RecordValue, Slot,
};
use crate::model::record::{self, EffectRecord, RecordError};
use crate::model::AxisState;

/// Standard gravity, m/s².
pub const STANDARD_GRAVITY: f64 = 9.80665;
/// N·mm per kN·m.
const NMM_PER_KNM: f64 = 1e6;

/// The gravity torque about each axis (kN·m, KUKA sign) at command angles `axes_deg`, or
/// `None` when the robot description has no mass data. The base frame's Z points up.
pub fn gravity_torques_knm(
    robot: &RobotDescription,
    payload: &Payload,
    axes_deg: &[f64; 6],
) -> Option<[f64; 6]> {
    let gravity = robot.gravity.as_ref()?;
    let chain = ChainFrames::new(robot, axes_deg, &ChainErrors::default());
    // Weights (N) and where they act (mm, base frame): links 1..6, then the payload.
    let mut loads = [(0.0, Vector3::zeros()); 7];
    for (k, load) in loads.iter_mut().take(6).enumerate() {
        let cog = Vector3::from(gravity.link_cog_mm[k]);
        let at = chain.axis_origin(k + 1) + chain.body_rotation(k + 1) * cog;
        *load = (gravity.link_mass_kg[k] * STANDARD_GRAVITY, at);
    }
    let payload_at =
        chain.flange_position() + chain.flange_rotation() * Vector3::from(payload.cog_mm);
    loads[6] = (payload.mass_kg * STANDARD_GRAVITY, payload_at);
    Some(std::array::from_fn(|n| {
        let origin = chain.axis_origin(n + 1);
        // Body k is moved by axes 1..=k, so axis n carries bodies n..6 and the payload.
        let moment: Vector3<f64> = loads[n..]
            .iter()
            .map(|(weight, at)| (at - origin).cross(&Vector3::new(0.0, 0.0, -weight)))
            .sum();
        chain.joint_axis(n + 1).dot(&moment) / NMM_PER_KNM
    }))
}

#[derive(Clone, Debug, PartialEq)]
pub struct Compliance {
    pub axis: u8,
    /// c_n in deg/kNm.
    pub compliance: [f64; 1],
}

/// The crosstalks from the arm axes (A2, A3) onto a compliant axis n: the gravity torque
/// they change makes the same residual (see `crosstalk::gravity_look_alikes`).
pub fn gravity_look_alikes(n: u8) -> Vec<String> {
    [2, 3]
        .into_iter()
        .filter(|&m| m != n)
        .map(|m| format!("crosstalk:A{m}->A{n}"))
        .collect()
}

impl Compliance {
    /// A zero compliance; an error when the robot has no mass data to compute torques from.
    pub fn zeros(axis: u8, robot: &RobotDescription) -> Result<Self, EffectError> {
        if robot.gravity.is_none() {
            return Err(EffectError::NeedsGravity {
                effect: format!("compliance:A{axis}"),
            });
        }
        Ok(Compliance {
            axis,
            compliance: [0.0],
        })
    }

    pub fn from_record(
        axis: u8,
        rec: &EffectRecord,
        robot: &RobotDescription,
    ) -> Result<Self, RecordError> {
        if robot.gravity.is_none() {
            return Err(RecordError::new(
                "name",
                "an effect the robot's data support (compliance needs robot.description.gravity)",
                format!("compliance:A{axis}"),
            ));
        }
        let values = rec.named_values(&["c".to_string()])?;
        Ok(Compliance {
            axis,
            compliance: [values[0]],
        })
    }

    /// Slot value (rad) per deg/kNm at `state`: the torque in kN·m, in radians.
    fn gain(&self, state: &AxisState, ctx: &Context) -> f64 {
        gravity_torques_knm(ctx.robot, ctx.payload, &state.axes_deg)
            .map_or(0.0, |t| t[self.axis as usize - 1] * PI / 180.0)
    }
}

/// The physical range of `c`, degrees per kN·m of gravity torque.
pub const COMPLIANCE_DEG_PER_KNM: f64 = 1.0;

impl Effect for Compliance {
    fn name(&self) -> String {
        format!("compliance:A{}", self.axis)
    }
    fn parameters(&self) -> Vec<Parameter> {
        vec![Parameter {
            name: self.name(),
            unit: "deg/kNm",
        }]
    }
    fn values(&self) -> &[f64] {
        &self.compliance
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.compliance
    }
    fn add_to(&self, state: &AxisState, ctx: &Context, errors: &mut ChainErrors) {
        errors.add(
            Slot::Angle { axis: self.axis },
            self.compliance[0] * self.gain(state, ctx),
        );
    }
    fn adds_angles_only(&self) -> bool {
        true
    }
    fn add_angles(&self, state: &AxisState, ctx: &Context, angles: &mut [f64; 6]) {
        angles[self.axis as usize - 1] += self.compliance[0] * self.gain(state, ctx);
    }
    fn jacobian(&self, state: &AxisState, ctx: &Context, out: &mut Vec<Partial>) {
        out.push(Partial {
            param: 0,
            slot: Slot::Angle { axis: self.axis },
            value: self.gain(state, ctx),
        });
    }
    fn record_range(&self, value: RecordValue) -> RecordRange {
        match value {
            RecordValue::Parameter(_) => RecordRange::Within {
                bound: COMPLIANCE_DEG_PER_KNM,
                unit: "degrees per kN·m",
            },
            RecordValue::Table => RecordRange::Finite,
        }
    }
}

impl ToRecord for Compliance {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&["c".to_string()], &self.compliance)),
            table: None,
        }
    }
}
