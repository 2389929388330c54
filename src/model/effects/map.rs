//! `map:An` — the direction-independent angular positioning deviation of axis n as a function
//! of its own command angle (the paper's section 2.2, the mean of its two branches):
//! `dθ_n += map(A_n)`, linear interpolation, degrees in KUKA sign.

use super::axis_table::AxisTable;
use super::{EffectError, GridOptions, ToRecord};
use crate::kinematics::RobotDescription;
use crate::model::effect::{
    AxisSlopes, ChainErrors, Context, Effect, Parameter, Partial, RecordRange, RecordValue, Role,
};
use crate::model::merged::AxisFactor;
use crate::model::record::{EffectRecord, RecordError};
use crate::model::table::Table1;
use crate::model::AxisState;

#[derive(Clone, Debug, PartialEq)]
pub struct AngleMap(pub AxisTable);

impl AngleMap {
    pub fn zeros(
        axis: u8,
        options: &GridOptions,
        robot: &RobotDescription,
    ) -> Result<Self, EffectError> {
        AxisTable::zeros(axis, options, robot).map(AngleMap)
    }
    pub fn from_record(axis: u8, rec: &EffectRecord) -> Result<Self, RecordError> {
        AxisTable::from_record(axis, rec).map(AngleMap)
    }
}

impl Effect for AngleMap {
    fn name(&self) -> String {
        format!("map:A{}", self.0.axis)
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
        self.0.add_to(state, 1.0, errors);
    }
    fn add_with_axis_slopes(
        &self,
        state: &AxisState,
        _ctx: &Context,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        self.0.add_with_slopes(state, 1.0, errors, slopes);
    }
    fn jacobian(&self, state: &AxisState, _ctx: &Context, out: &mut Vec<Partial>) {
        self.0.jacobian(state, 1.0, out);
    }
    fn adds_angles_only(&self) -> bool {
        true
    }
    fn own_axis_table(&self) -> Option<(u8, &Table1, AxisFactor)> {
        Some((self.0.axis, &self.0.table, AxisFactor::One))
    }
    #[cfg(any(test, feature = "internals"))]
    fn clamped(&self, state: &AxisState) -> bool {
        self.0.clamped(state)
    }
    fn role(&self) -> Role {
        Role::OwnAngle { axis: self.0.axis }
    }
    fn record_range(&self, value: RecordValue) -> RecordRange {
        match value {
            RecordValue::Table => super::DEVIATION_RANGE,
            RecordValue::Parameter(_) => RecordRange::Finite,
        }
    }
    fn parameters_are_cells(&self) -> bool {
        true
    }
}

impl ToRecord for AngleMap {
    fn record(&self) -> EffectRecord {
        self.0.record(self.name())
    }
}
