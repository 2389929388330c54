//! `tilt:An` — tilt error motion (wobble) of axis n's axis of rotation: the axis line turns
//! about the two model axes perpendicular to it by angles that vary with the axis's own
//! command angle A_n as first and second harmonics,
//! `ε_p(A_n) = c1·cos A_n + s1·sin A_n + c2·cos 2A_n + s2·sin 2A_n` for each perpendicular
//! axis p (8 parameters, degrees), written to axis n's rotation slots before its joint
//! rotation. A constant tilt is not modelled here: it is the geometric effect's job.

use std::f64::consts::PI;

use super::ToRecord;
use crate::model::chain::AXIS_COORD;
use crate::model::effect::{
    AxisSlopes, ChainErrors, Context, Effect, Parameter, Partial, RecordRange, RecordValue, Slot,
};
use crate::model::record::{self, EffectRecord, RecordError};
use crate::model::AxisState;

const HARMONICS: [&str; 4] = ["cos1", "sin1", "cos2", "sin2"];
const COORD_NAMES: [&str; 3] = ["x", "y", "z"];

#[derive(Clone, Debug, PartialEq)]
pub struct Tilt {
    pub axis: u8,
    /// For each perpendicular model axis (increasing x, y, z order): cos1, sin1, cos2, sin2.
    pub values: [f64; 8],
}

impl Tilt {
    pub fn zeros(axis: u8) -> Self {
        Tilt {
            axis,
            values: [0.0; 8],
        }
    }

    pub fn from_record(axis: u8, rec: &EffectRecord) -> Result<Self, RecordError> {
        let mut t = Tilt::zeros(axis);
        let values = rec.named_values(&t.local_names())?;
        t.values.copy_from_slice(&values);
        Ok(t)
    }

    /// The two model axes perpendicular to this axis's rotation axis.
    fn perpendicular(&self) -> [u8; 2] {
        match AXIS_COORD[self.axis as usize - 1] {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        }
    }

    /// `x.cos1`, …, as written in the calibration file.
    fn local_names(&self) -> Vec<String> {
        self.perpendicular()
            .iter()
            .flat_map(|&p| {
                HARMONICS
                    .iter()
                    .map(move |h| format!("{}.{h}", COORD_NAMES[p as usize]))
            })
            .collect()
    }

    /// The 8 (slot, slot value per degree of parameter) pairs at `state`.
    fn gains(&self, state: &AxisState) -> [(Slot, f64); 8] {
        let a = state.axes_deg[self.axis as usize - 1].to_radians();
        let (s1, c1) = a.sin_cos();
        let (s2, c2) = (2.0 * a).sin_cos();
        let harmonics = [c1, s1, c2, s2];
        let perp = self.perpendicular();
        std::array::from_fn(|i| {
            (
                Slot::Tilt {
                    axis: self.axis,
                    coord: perp[i / 4],
                },
                harmonics[i % 4] * PI / 180.0,
            )
        })
    }
}

/// The physical range of the harmonic amplitudes, degrees.
pub const TILT_DEG: f64 = 1.0;

impl Effect for Tilt {
    fn name(&self) -> String {
        format!("tilt:A{}", self.axis)
    }
    fn parameters(&self) -> Vec<Parameter> {
        let name = self.name();
        self.local_names()
            .into_iter()
            .map(|n| Parameter {
                name: format!("{name}[{n}]"),
                unit: "deg",
            })
            .collect()
    }
    fn values(&self) -> &[f64] {
        &self.values
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }
    fn add_to(&self, state: &AxisState, _ctx: &Context, errors: &mut ChainErrors) {
        for ((slot, gain), value) in self.gains(state).into_iter().zip(self.values) {
            errors.add(slot, gain * value);
        }
    }
    fn add_with_axis_slopes(
        &self,
        state: &AxisState,
        ctx: &Context,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        self.add_to(state, ctx, errors);
        // d/dA (per degree) of cos A, sin A, cos 2A, sin 2A.
        let a = state.axes_deg[self.axis as usize - 1].to_radians();
        let (s1, c1) = a.sin_cos();
        let (s2, c2) = (2.0 * a).sin_cos();
        let rate = PI / 180.0;
        let harmonics = [-s1 * rate, c1 * rate, -2.0 * s2 * rate, 2.0 * c2 * rate];
        let perp = self.perpendicular();
        for (i, value) in self.values.iter().enumerate() {
            let slot = Slot::Tilt {
                axis: self.axis,
                coord: perp[i / 4],
            };
            let d = harmonics[i % 4] * PI / 180.0 * value;
            slopes.add(slot, self.axis as usize - 1, d);
        }
    }
    fn jacobian(&self, state: &AxisState, _ctx: &Context, out: &mut Vec<Partial>) {
        for (param, (slot, value)) in self.gains(state).into_iter().enumerate() {
            out.push(Partial { param, slot, value });
        }
    }
    fn record_range(&self, value: RecordValue) -> RecordRange {
        match value {
            RecordValue::Parameter(_) => RecordRange::Within {
                bound: TILT_DEG,
                unit: "degrees",
            },
            RecordValue::Table => RecordRange::Finite,
        }
    }
}

impl ToRecord for Tilt {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&self.local_names(), &self.values)),
            table: None,
        }
    }
}
