//! The part `map:An` and `backlash:An` share: a deviation table over axis n's own command
//! angle (degrees, KUKA sign) that writes axis n's angle slot, scaled by a factor the caller
//! chooses (1 for the map, the rotation direction for backlash).

use std::f64::consts::PI;

use crate::model::effect::{AxisSlopes, ChainErrors, Parameter, Partial, Slot};
use crate::model::record::{self, EffectRecord, RecordError, TableRecord};
use crate::model::table::{Grid, Table1};
use crate::model::AxisState;

use super::{grid_label, EffectError, GridOptions};
use crate::kinematics::RobotDescription;

#[derive(Clone, Debug, PartialEq)]
pub struct AxisTable {
    /// 1..=6.
    pub axis: u8,
    pub table: Table1,
}

impl AxisTable {
    /// A zero table over the options' grid (default: joint limits at 1°).
    pub fn zeros(
        axis: u8,
        options: &GridOptions,
        robot: &RobotDescription,
    ) -> Result<Self, EffectError> {
        let [lo, hi] = options
            .range_deg
            .unwrap_or(robot.limits_deg[axis as usize - 1]);
        let pitch = options.pitch_deg.unwrap_or(1.0);
        let grid = Grid::from_range(lo, hi, pitch).map_err(|source| EffectError::Grid {
            axis,
            lo_deg: lo,
            hi_deg: hi,
            pitch_deg: pitch,
            source,
        })?;
        Ok(AxisTable {
            axis,
            table: Table1::zeros(grid),
        })
    }

    pub fn from_record(axis: u8, rec: &EffectRecord) -> Result<Self, RecordError> {
        let t = rec.require_table()?;
        if t.other_grid_deg.is_some() {
            return Err(RecordError::new(
                "table.other_grid_deg",
                "no other grid (a 1-D table)",
                "a grid",
            ));
        }
        let grid = record::grid(&t.grid_deg, "table.grid_deg")?;
        let values = record::table_values(&t.values_deg, grid.len(), "one per grid point")?;
        Ok(AxisTable {
            axis,
            table: Table1 { grid, values },
        })
    }

    pub fn record(&self, name: String) -> EffectRecord {
        EffectRecord {
            name,
            parameters: None,
            table: Some(TableRecord {
                grid_deg: self.table.grid.points().to_vec(),
                other_grid_deg: None,
                values_deg: self.table.values.clone(),
            }),
        }
    }

    pub fn parameters(&self, name: &str) -> Vec<Parameter> {
        let points = self.table.grid.points();
        points
            .iter()
            .map(|&x| Parameter {
                name: format!("{name}[{}]", grid_label(x)),
                unit: "deg",
            })
            .collect()
    }

    fn command(&self, state: &AxisState) -> f64 {
        state.axes_deg[self.axis as usize - 1]
    }

    pub fn add_to(&self, state: &AxisState, factor: f64, errors: &mut ChainErrors) {
        if factor == 0.0 {
            return;
        }
        let (value, _) = self.table.eval(self.command(state));
        // `to_radians` multiplies by π/180 where `· π / 180` divided: the hot path of a solve.
        errors.add(Slot::Angle { axis: self.axis }, factor * value.to_radians());
    }

    /// [`Self::add_to`] with the table's slope along its own axis.
    pub fn add_with_slopes(
        &self,
        state: &AxisState,
        factor: f64,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        if factor == 0.0 {
            return;
        }
        let (value, slope) = self.table.eval_slope(self.command(state));
        let slot = Slot::Angle { axis: self.axis };
        errors.add(slot, factor * value.to_radians());
        slopes.add(slot, self.axis as usize - 1, factor * slope.to_radians());
    }

    pub fn jacobian(&self, state: &AxisState, factor: f64, out: &mut Vec<Partial>) {
        if factor == 0.0 {
            return;
        }
        let cell = self.table.grid.locate(self.command(state));
        let slot = Slot::Angle { axis: self.axis };
        for (param, w) in [(cell.lo, 1.0 - cell.w), (cell.hi, cell.w)] {
            if w != 0.0 {
                out.push(Partial {
                    param,
                    slot,
                    value: factor * w * PI / 180.0,
                });
            }
        }
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn clamped(&self, state: &AxisState) -> bool {
        self.table.grid.outside(self.command(state))
    }
}
