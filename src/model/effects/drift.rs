//! `drift` — slow change of the robot's geometry over time (thermal growth of the column and
//! arms), linear in the campaign clock `t` (column `t`, `AxisState::time_s`): each link length
//! grows at its own rate (mm/h), written to the offset slot along that link.

use super::ToRecord;
use crate::model::effect::{
    ChainErrors, Context, Effect, Parameter, Partial, RecordRange, RecordValue, Slot,
};
use crate::model::record::{self, EffectRecord, RecordError};
use crate::model::AxisState;

/// (link name, the offset slot along that link in MODEL.md's chain).
const LINKS: [(&str, Slot); 6] = [
    ("l1z", Slot::Offset { axis: 2, coord: 2 }),
    ("l1x", Slot::Offset { axis: 2, coord: 0 }),
    ("l2", Slot::Offset { axis: 3, coord: 2 }),
    ("l3z", Slot::Offset { axis: 4, coord: 2 }),
    ("l4x", Slot::Offset { axis: 5, coord: 0 }),
    ("l5x", Slot::Offset { axis: 6, coord: 0 }),
];

const SECONDS_PER_HOUR: f64 = 3600.0;

fn names() -> Vec<String> {
    LINKS.iter().map(|(n, _)| n.to_string()).collect()
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Drift {
    /// Growth rates in mm/h, in the order l1z, l1x, l2, l3z, l4x, l5x.
    pub rates_mm_per_h: [f64; 6],
}

impl Drift {
    pub fn from_record(rec: &EffectRecord) -> Result<Self, RecordError> {
        let values = rec.named_values(&names())?;
        let mut d = Drift::default();
        d.rates_mm_per_h.copy_from_slice(&values);
        Ok(d)
    }
}

/// The physical range of the growth rates, mm per hour.
pub const DRIFT_MM_PER_H: f64 = 10.0;

impl Effect for Drift {
    fn name(&self) -> String {
        "drift".to_string()
    }
    fn parameters(&self) -> Vec<Parameter> {
        LINKS
            .iter()
            .map(|(n, _)| Parameter {
                name: format!("drift:{n}"),
                unit: "mm/h",
            })
            .collect()
    }
    fn values(&self) -> &[f64] {
        &self.rates_mm_per_h
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.rates_mm_per_h
    }
    fn add_to(&self, state: &AxisState, _ctx: &Context, errors: &mut ChainErrors) {
        let hours = state.time_s / SECONDS_PER_HOUR;
        for (&(_, slot), rate) in LINKS.iter().zip(self.rates_mm_per_h) {
            errors.add(slot, rate * hours);
        }
    }
    fn varies_with_axes(&self) -> bool {
        false
    }
    fn jacobian(&self, state: &AxisState, _ctx: &Context, out: &mut Vec<Partial>) {
        let hours = state.time_s / SECONDS_PER_HOUR;
        for (param, &(_, slot)) in LINKS.iter().enumerate() {
            out.push(Partial {
                param,
                slot,
                value: hours,
            });
        }
    }
    fn record_range(&self, value: RecordValue) -> RecordRange {
        match value {
            RecordValue::Parameter(_) => RecordRange::Within {
                bound: DRIFT_MM_PER_H,
                unit: "mm per hour",
            },
            RecordValue::Table => RecordRange::Finite,
        }
    }
}

impl ToRecord for Drift {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&names(), &self.rates_mm_per_h)),
            table: None,
        }
    }
}
