//! `crosstalk:Am->An` — axis n's angular positioning deviation also depends on the angle of
//! axis m (the paper's section 2.4: A2's deviation changes with A3 because the arm's inertia
//! and gravity load change). `dθ_n += t(A_n, A_m)`, bilinear over a table whose rows follow
//! A_n and columns A_m, degrees in KUKA sign. It adds to `map:An`; the paper's
//! `Δθ_2,map(i_2, ±1, i_3)` is map + backlash + this table.

use std::f64::consts::PI;

use super::{grid_label, EffectError, GridOptions, ToRecord};
use crate::kinematics::RobotDescription;
use crate::model::effect::{
    AxisSlopes, ChainErrors, Context, Effect, Parameter, Partial, RecordRange, RecordValue, Role,
    Slot,
};
use crate::model::record::{self, EffectRecord, RecordError, TableRecord};
use crate::model::table::{Grid, Table2};
use crate::model::AxisState;

/// The gravity torque on A2 and A3 is a function of A2 and A3, so on a campaign at one
/// payload the compliance of either axis a crosstalk joins explains the same residual (the
/// paper, section 3.2, suspects gravity behind its crosstalk).
pub fn gravity_look_alikes(from: u8, to: u8) -> Vec<String> {
    vec![format!("compliance:A{to}"), format!("compliance:A{from}")]
}

#[derive(Clone, Debug, PartialEq)]
pub struct Crosstalk {
    /// The influencing axis m (1..=6).
    pub from: u8,
    /// The affected axis n (1..=6).
    pub to: u8,
    /// Rows over A_n, columns over A_m.
    pub table: Table2,
}

impl Crosstalk {
    /// A zero table: A_n over its range at the pitch (default 5°), A_m over the explicit
    /// (data-driven) grid or its range at the other pitch (default 15°); see [`GridOptions`].
    pub fn zeros(
        from: u8,
        to: u8,
        options: &GridOptions,
        robot: &RobotDescription,
    ) -> Result<Self, EffectError> {
        let [lo, hi] = options
            .range_deg
            .unwrap_or(robot.limits_deg[to as usize - 1]);
        let pitch = options.pitch_deg.unwrap_or(5.0);
        let rows = Grid::from_range(lo, hi, pitch)
            .map_err(|source| EffectError::PairGrid { axis: to, source })?;
        let columns = match &options.other_grid_deg {
            Some(points) => Grid::new(points.clone()),
            None => {
                let [lo, hi] = options
                    .other_range_deg
                    .unwrap_or(robot.limits_deg[from as usize - 1]);
                Grid::from_range(lo, hi, options.other_pitch_deg.unwrap_or(15.0))
            }
        }
        .map_err(|source| EffectError::PairGrid { axis: from, source })?;
        Ok(Crosstalk {
            from,
            to,
            table: Table2::zeros(rows, columns),
        })
    }

    pub fn from_record(from: u8, to: u8, rec: &EffectRecord) -> Result<Self, RecordError> {
        let t = rec.require_table()?;
        let rows = record::grid(&t.grid_deg, "table.grid_deg")?;
        let Some(other) = &t.other_grid_deg else {
            return Err(RecordError::new(
                "table.other_grid_deg",
                format!("the grid of the influencing axis A{from}"),
                "nothing",
            ));
        };
        let columns = record::grid(other, "table.other_grid_deg")?;
        let what = format!("{} × {}, row-major", rows.len(), columns.len());
        let values = record::table_values(&t.values_deg, rows.len() * columns.len(), &what)?;
        Ok(Crosstalk {
            from,
            to,
            table: Table2 {
                rows,
                columns,
                values,
            },
        })
    }

    fn lookup(&self, state: &AxisState) -> (f64, crate::model::table::Corners, bool) {
        let (own, other) = (
            state.axes_deg[self.to as usize - 1],
            state.axes_deg[self.from as usize - 1],
        );
        self.table.eval(own, other)
    }
}

impl Effect for Crosstalk {
    fn name(&self) -> String {
        format!("crosstalk:A{}->A{}", self.from, self.to)
    }
    fn parameters(&self) -> Vec<Parameter> {
        let name = self.name();
        let columns = self.table.columns.points();
        self.table
            .rows
            .points()
            .iter()
            .flat_map(|&r| {
                let name = &name;
                columns.iter().map(move |&c| Parameter {
                    name: format!("{name}[{},{}]", grid_label(r), grid_label(c)),
                    unit: "deg",
                })
            })
            .collect()
    }
    fn values(&self) -> &[f64] {
        &self.table.values
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.table.values
    }
    fn add_to(&self, state: &AxisState, _ctx: &Context, errors: &mut ChainErrors) {
        errors.add(
            Slot::Angle { axis: self.to },
            self.lookup(state).0.to_radians(),
        );
    }
    fn adds_angles_only(&self) -> bool {
        true
    }
    fn add_angles(&self, state: &AxisState, _ctx: &Context, angles: &mut [f64; 6]) {
        angles[self.to as usize - 1] += self.lookup(state).0.to_radians();
    }
    fn add_angles_near(
        &self,
        state: &AxisState,
        _ctx: &Context,
        angles: &mut [f64; 6],
        hints: &mut [usize; 2],
    ) {
        let (own, other) = (
            state.axes_deg[self.to as usize - 1],
            state.axes_deg[self.from as usize - 1],
        );
        angles[self.to as usize - 1] += self.table.eval_near(own, other, hints).to_radians();
    }
    fn add_with_axis_slopes(
        &self,
        state: &AxisState,
        _ctx: &Context,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        let (own, other) = (
            state.axes_deg[self.to as usize - 1],
            state.axes_deg[self.from as usize - 1],
        );
        let (value, d_own, d_other) = self.table.eval_slopes(own, other);
        let slot = Slot::Angle { axis: self.to };
        errors.add(slot, value.to_radians());
        slopes.add(slot, self.to as usize - 1, d_own.to_radians());
        slopes.add(slot, self.from as usize - 1, d_other.to_radians());
    }
    fn jacobian(&self, state: &AxisState, _ctx: &Context, out: &mut Vec<Partial>) {
        let (_, corners, _) = self.lookup(state);
        let slot = Slot::Angle { axis: self.to };
        for (param, w) in corners {
            if w != 0.0 {
                out.push(Partial {
                    param,
                    slot,
                    value: w * PI / 180.0,
                });
            }
        }
    }
    #[cfg(any(test, feature = "internals"))]
    fn clamped(&self, state: &AxisState) -> bool {
        self.lookup(state).2
    }
    fn role(&self) -> Role {
        Role::CrossAngle {
            from: self.from,
            to: self.to,
        }
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

impl ToRecord for Crosstalk {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: None,
            table: Some(TableRecord {
                grid_deg: self.table.rows.points().to_vec(),
                other_grid_deg: Some(self.table.columns.points().to_vec()),
                values_deg: self.table.values.clone(),
            }),
        }
    }
}
