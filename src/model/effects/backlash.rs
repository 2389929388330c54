//! `backlash:An` — the rotation-direction part of axis n's angular positioning deviation
//! (gear backlash): `dθ_n += dir_n · b(A_n)` with dir = +1 / −1 after a positive / negative
//! move and 0 when unknown, so that an unknown direction gives the mean of the paper's two
//! branches `map ± backlash` (section 2.2). Linear interpolation, degrees in KUKA sign.

use super::axis_table::AxisTable;
use super::{GridOptions, ToRecord};
use crate::kinematics::RobotDescription;
use crate::model::effect::{AxisSlopes, ChainErrors, Context, Effect, Parameter, Partial};
use crate::model::merged::AxisFactor;
use crate::model::record::{EffectRecord, RecordError};
use crate::model::table::Table1;
use crate::model::AxisState;

#[derive(Clone, Debug, PartialEq)]
pub struct Backlash(pub AxisTable);

impl Backlash {
    pub fn zeros(
        axis: u8,
        options: &GridOptions,
        robot: &RobotDescription,
    ) -> Result<Self, String> {
        AxisTable::zeros(axis, options, robot).map(Backlash)
    }
    pub fn from_record(axis: u8, rec: &EffectRecord) -> Result<Self, RecordError> {
        AxisTable::from_record(axis, rec).map(Backlash)
    }
    fn direction(&self, state: &AxisState) -> f64 {
        state.directions[self.0.axis as usize - 1].sign()
    }
}

impl Effect for Backlash {
    fn name(&self) -> String {
        format!("backlash:A{}", self.0.axis)
    }
    fn parameters(&self) -> Vec<Parameter> {
        self.0.parameters(&self.name())
    }
    fn values(&self) -> &[f64] {
        &self.0.table.values
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.0.table.values
    }
    fn add_to(&self, state: &AxisState, _ctx: &Context, errors: &mut ChainErrors) {
        self.0.add_to(state, self.direction(state), errors);
    }
    fn add_with_axis_slopes(
        &self,
        state: &AxisState,
        _ctx: &Context,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        self.0
            .add_with_slopes(state, self.direction(state), errors, slopes);
    }
    fn jacobian(&self, state: &AxisState, _ctx: &Context, out: &mut Vec<Partial>) {
        self.0.jacobian(state, self.direction(state), out);
    }
    fn adds_angles_only(&self) -> bool {
        true
    }
    fn own_axis_table(&self) -> Option<(u8, &Table1, AxisFactor)> {
        Some((self.0.axis, &self.0.table, AxisFactor::Direction))
    }
    fn clamped(&self, state: &AxisState) -> bool {
        self.0.clamped(state)
    }
    fn clone_box(&self) -> Box<dyn Effect> {
        Box::new(self.clone())
    }
}

impl ToRecord for Backlash {
    fn record(&self) -> EffectRecord {
        self.0.record(self.name())
    }
}
