//! `geometric` — the paper's 18 errors of the axis average lines (equation 2, MODEL.md: the
//! position and orientation of each axis line and the zero offsets Δθ20..Δθ50) plus the three
//! components of the target-vector correction. Lengths in mm, angles in degrees, signs as in
//! the paper; a zero offset Δθ is in model sign and enters the KUKA-sign angle slot divided by
//! the axis sense (θ_n = sense·(A_n + dθ_n) + offset, so Δθ_model = sense·dθ). The target
//! correction is along the A6-frame axes (the paper's 6p), not the flange's.

use std::f64::consts::PI;

use super::ToRecord;
use crate::model::effect::{
    ChainErrors, Context, Effect, Parameter, Partial, RecordRange, RecordValue, Role, Slot,
};
use crate::model::record::{self, EffectRecord, RecordError};
use crate::model::AxisState;

/// How a parameter enters its slot.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Length,
    /// A small rotation of an axis line (α, γ), degrees.
    Rotation,
    /// A zero offset Δθ, degrees, model sign.
    ZeroOffset,
}

const fn off(axis: u8, coord: u8) -> Slot {
    Slot::Offset { axis, coord }
}
const fn tilt(axis: u8, coord: u8) -> Slot {
    Slot::Tilt { axis, coord }
}

/// (name, slot, kind) in the paper's order; x, y, z = coord 0, 1, 2.
const PARAMETERS: [(&str, Slot, Kind); 21] = [
    ("dx21", off(2, 0), Kind::Length),
    ("a21", tilt(2, 0), Kind::Rotation),
    ("dth20", Slot::Angle { axis: 2 }, Kind::ZeroOffset),
    ("dz32", off(3, 2), Kind::Length),
    ("a32", tilt(3, 0), Kind::Rotation),
    ("g32", tilt(3, 2), Kind::Rotation),
    ("dth30", Slot::Angle { axis: 3 }, Kind::ZeroOffset),
    ("dz43", off(4, 2), Kind::Length),
    ("dy43", off(4, 1), Kind::Length),
    ("g43", tilt(4, 2), Kind::Rotation),
    ("dth40", Slot::Angle { axis: 4 }, Kind::ZeroOffset),
    ("dx54", off(5, 0), Kind::Length),
    ("dz54", off(5, 2), Kind::Length),
    ("g54", tilt(5, 2), Kind::Rotation),
    ("dth50", Slot::Angle { axis: 5 }, Kind::ZeroOffset),
    ("dz65", off(6, 2), Kind::Length),
    ("dy65", off(6, 1), Kind::Length),
    ("g65", tilt(6, 2), Kind::Rotation),
    ("p6x", Slot::Target { coord: 0 }, Kind::Length),
    ("p6y", Slot::Target { coord: 1 }, Kind::Length),
    ("p6z", Slot::Target { coord: 2 }, Kind::Length),
];

/// The geometric parameter names, in order (`dx21`, `a21`, `dth20`, …, `p6x`, `p6y`, `p6z`).
pub fn parameter_names() -> Vec<String> {
    PARAMETERS.iter().map(|(n, _, _)| n.to_string()).collect()
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Geometric {
    pub values: [f64; 21],
}

impl Geometric {
    pub fn from_record(rec: &EffectRecord) -> Result<Self, RecordError> {
        let values = rec.named_values(&parameter_names())?;
        let mut g = Geometric::default();
        g.values.copy_from_slice(&values);
        Ok(g)
    }

    /// Slot value per unit of parameter `i`.
    fn gain(i: usize, ctx: &Context) -> f64 {
        let (_, slot, kind) = PARAMETERS[i];
        match (kind, slot) {
            (Kind::Length, _) => 1.0,
            (Kind::Rotation, _) => PI / 180.0,
            (Kind::ZeroOffset, Slot::Angle { axis }) => {
                PI / 180.0 / ctx.robot.senses[axis as usize - 1]
            }
            (Kind::ZeroOffset, _) => PI / 180.0,
        }
    }
}

/// The physical range of the position errors and the target correction, mm …
pub const GEOMETRIC_MM: f64 = 50.0;
/// … and of the angular errors, degrees.
pub const GEOMETRIC_DEG: f64 = 2.0;

impl Effect for Geometric {
    fn name(&self) -> String {
        "geometric".to_string()
    }
    fn parameters(&self) -> Vec<Parameter> {
        PARAMETERS
            .iter()
            .map(|&(name, _, kind)| Parameter {
                name: name.to_string(),
                unit: if kind == Kind::Length { "mm" } else { "deg" },
            })
            .collect()
    }
    fn values(&self) -> &[f64] {
        &self.values
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }
    fn add_to(&self, _state: &AxisState, ctx: &Context, errors: &mut ChainErrors) {
        for (i, &(_, slot, _)) in PARAMETERS.iter().enumerate() {
            errors.add(slot, self.values[i] * Self::gain(i, ctx));
        }
    }
    fn varies_with_axes(&self) -> bool {
        false
    }
    fn jacobian(&self, _state: &AxisState, ctx: &Context, out: &mut Vec<Partial>) {
        for (i, &(_, slot, _)) in PARAMETERS.iter().enumerate() {
            out.push(Partial {
                param: i,
                slot,
                value: Self::gain(i, ctx),
            });
        }
    }
    fn role(&self) -> Role {
        Role::AxisLines
    }
    /// The zero offsets Δθ20..Δθ50 and the target correction p6x, p6y, p6z.
    fn constant_in(&self, slot: Slot) -> Option<usize> {
        PARAMETERS.iter().position(|&(_, s, _)| s == slot)
    }
    /// Angles (`dth…`, `alpha…`, …) in degrees; offsets (`d…`) and the target correction
    /// (`p6…`) in mm.
    fn record_range(&self, value: RecordValue) -> RecordRange {
        let RecordValue::Parameter(name) = value else {
            return RecordRange::Finite;
        };
        let p = name.to_ascii_lowercase();
        let mm = !p.starts_with("dth") && (p.starts_with('d') || p.starts_with("p6"));
        if mm {
            RecordRange::Within {
                bound: GEOMETRIC_MM,
                unit: "mm",
            }
        } else {
            RecordRange::Within {
                bound: GEOMETRIC_DEG,
                unit: "degrees",
            }
        }
    }
}

impl ToRecord for Geometric {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&parameter_names(), &self.values)),
            table: None,
        }
    }
}
