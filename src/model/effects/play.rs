//! `backlash:An` — the rotation-direction part of axis n's angular positioning deviation, as
//! the gear play (lost motion) it physically is: a width table b(A_n) ≥ 0 over the command
//! angle; the output lags the command by b/2 after a motion longer than the play and stays
//! put while the command reverses inside it (the play operator, evaluated from the axis's
//! [`AxisHistory`](crate::model::AxisHistory)): `dθ_n += lag`, degrees in KUKA sign. After
//! a motion longer than the play this is the paper's two-branch model (section 2.2) with the
//! positive branch b below the negative one, so the paper's indexing campaign identifies it
//! unchanged; a reversal shorter than the play moves the command but not the output.
//!
//! Files of format `robopost-calibration/1` stored the signed half difference `v` of the
//! instant-switch model (`dθ += dir·v`); they are read as widths `b = −2v`, and a table with
//! `v > 0` (the output *leading* the command, which no play produces) is refused.

use std::f64::consts::PI;

use super::axis_table::AxisTable;
use super::{EffectError, GridOptions, ToRecord};
use crate::kinematics::RobotDescription;
use crate::model::effect::{
    AxisSlopes, ChainErrors, Context, Effect, Parameter, Partial, Role, Slot,
};
use crate::model::history::{PlayAt, MAX_PLAY_DEG};
use crate::model::merged::AxisFactor;
use crate::model::record::{EffectRecord, RecordError};
use crate::model::table::Table1;
use crate::model::AxisState;

/// The gear play of one axis: its width over the command angle.
#[derive(Clone, Debug, PartialEq)]
pub struct GearPlay(pub AxisTable);

impl GearPlay {
    pub fn zeros(
        axis: u8,
        options: &GridOptions,
        robot: &RobotDescription,
    ) -> Result<Self, EffectError> {
        AxisTable::zeros(axis, options, robot).map(GearPlay)
    }

    /// The play a calibration record describes: widths in `[0, MAX_PLAY_DEG]`.
    pub fn from_record(axis: u8, rec: &EffectRecord) -> Result<Self, RecordError> {
        let table = AxisTable::from_record(axis, rec)?;
        for (i, &b) in table.table.values.iter().enumerate() {
            if !(0.0..=MAX_PLAY_DEG).contains(&b) {
                return Err(RecordError::PlayWidth {
                    axis,
                    index: i,
                    width_deg: b,
                    max_deg: MAX_PLAY_DEG,
                });
            }
        }
        Ok(GearPlay(table))
    }

    /// A record of format `robopost-calibration/1` (signed half difference of the instant
    /// switch) rewritten as this format's widths; a leading table is refused.
    pub fn upgrade_v1(rec: &mut EffectRecord) -> Result<(), RecordError> {
        let Some(table) = rec.table.as_mut() else {
            return Ok(());
        };
        if let Some((i, v)) = table.values_deg.iter().enumerate().find(|(_, &v)| v > 1e-9) {
            return Err(RecordError::new(
                format!("table.values_deg[{i}]"),
                "a lagging backlash (format /1 stored dθ = dir·v: v ≤ 0 for a gear play)",
                format!("{v} (the output would lead the command, which no gear play does: a servo overshoot, a sign error of the axis or data in the wrong order produce such a table)"),
            ));
        }
        for v in &mut table.values_deg {
            *v = (-2.0 * *v).max(0.0);
        }
        Ok(())
    }

    fn width_deg(&self, angle: f64) -> f64 {
        self.0.table.eval(angle).0
    }

    /// The play at `state` (degrees).
    pub fn at(&self, state: &AxisState) -> PlayAt {
        let n = self.0.axis as usize - 1;
        state.history[n].play(state.axes_deg[n], |x| self.width_deg(x))
    }

    fn slot(&self) -> Slot {
        Slot::Angle { axis: self.0.axis }
    }
}

impl Effect for GearPlay {
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
        errors.add(self.slot(), self.at(state).lag_deg.to_radians());
    }
    fn add_with_axis_slopes(
        &self,
        state: &AxisState,
        _ctx: &Context,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        let play = self.at(state);
        errors.add(self.slot(), play.lag_deg.to_radians());
        let n = self.0.axis as usize - 1;
        // Engaged, the lag follows the width's slope along the flank; inside the play the
        // output stands still, so the lag takes back every degree of command.
        let slope = match play.edge {
            Some((_, side)) if play.engaged => {
                0.5 * side * self.0.table.eval_slope(state.axes_deg[n]).1
            }
            _ if state.history[n].is_simple() => 0.0,
            _ => -1.0,
        };
        slopes.add(self.slot(), n, slope.to_radians());
    }
    fn jacobian(&self, state: &AxisState, _ctx: &Context, out: &mut Vec<Partial>) {
        let Some((angle, side)) = self.at(state).edge else {
            return;
        };
        let cell = self.0.table.grid.locate(angle);
        for (param, w) in [(cell.lo, 1.0 - cell.w), (cell.hi, cell.w)] {
            if w != 0.0 {
                out.push(Partial {
                    param,
                    slot: self.slot(),
                    value: 0.5 * side * w * PI / 180.0,
                });
            }
        }
    }
    fn adds_angles_only(&self) -> bool {
        true
    }
    fn own_axis_table(&self) -> Option<(u8, &Table1, AxisFactor)> {
        Some((self.0.axis, &self.0.table, AxisFactor::Play))
    }
    #[cfg(any(test, feature = "internals"))]
    fn clamped(&self, state: &AxisState) -> bool {
        self.0.clamped(state)
    }
    /// A width below zero is a bidirectional difference of the leading sign (the positive
    /// branch above the negative one), which no gear play produces. Cells below zero are set
    /// to zero (single cells are noise: a 1° table of a wrist axis has hundreds, a few beyond
    /// 3σ); a table whose weighted mean leads beyond twice its standard error is physically
    /// suspect and said so.
    fn make_physical(&mut self, standard_errors: &[Option<f64>]) -> Vec<String> {
        let name = self.name();
        let values = &mut self.0.table.values;
        let (mut sum, mut weight) = (0.0, 0.0);
        for (v, se) in values.iter().zip(standard_errors) {
            if let Some(se) = se.filter(|s| *s > 0.0) {
                sum += v / (se * se);
                weight += 1.0 / (se * se);
            }
        }
        let negative = values.iter().filter(|v| **v < 0.0).count();
        values.iter_mut().for_each(|v| *v = v.max(0.0));
        if weight == 0.0 || negative == 0 {
            return Vec::new();
        }
        let (mean, se) = (sum / weight, weight.sqrt().recip());
        if mean < -2.0 * se {
            vec![format!(
                "{name}: the identified bidirectional difference has the leading sign, {:.4}° (± {se:.4}°) on average over the table: the output would be ahead of the command after a motion, which no gear play does; set to zero. A servo overshoot on stopping, a wrong axis sense in the robot description, a drift that follows the order of the campaign's sweeps, or the tracker's own lag produce a direction-dependent deviation of that sign",
                -mean
            )]
        } else {
            Vec::new()
        }
    }
    /// Engaged, the output lags by half the width against the direction of motion.
    fn role(&self) -> Role {
        Role::DirectionDifference {
            axis: self.0.axis,
            per_direction: -0.5,
        }
    }
    fn direction_axes(&self) -> Vec<u8> {
        vec![self.0.axis]
    }
    fn parameters_are_cells(&self) -> bool {
        true
    }
}

impl ToRecord for GearPlay {
    fn record(&self) -> EffectRecord {
        self.0.record(self.name())
    }
}
