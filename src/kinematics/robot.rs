//! The robot description: link lengths, joint limits, axis senses and (optionally) the mass
//! data needed for gravity torques. Plain `Copy + Sync` data so that FK can be a pure function
//! and rayon workers can share it freely. Other robots of the same kinematic family differ only
//! in these numbers (see `../shared/MODEL.md`).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Link lengths in mm (KUKA "KR 30 HA" naming of `../shared/MODEL.md`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Links {
    /// A1 axis to A2 axis, horizontal (negative: behind the A1 axis).
    #[schemars(range(min = -5000, max = 5000))]
    pub l1x: f64,
    /// Base ($ROBROOT) to A2 axis, vertical.
    #[schemars(range(min = 0, max = 5000))]
    pub l1z: f64,
    /// A2 axis to A3 axis.
    #[schemars(range(min = 1, max = 5000))]
    pub l2: f64,
    /// A3 axis to the A4 axis (offset, wrist above A3 at HOME; negative below, as on the
    /// KR 16's A3).
    #[schemars(range(min = -5000, max = 5000))]
    pub l3z: f64,
    /// A3 to the wrist point along A4.
    #[schemars(range(min = 1, max = 5000))]
    pub l4x: f64,
    /// Wrist point to flange.
    #[schemars(range(min = 0, max = 5000))]
    pub l5x: f64,
}

impl Links {
    /// Every link with its name in calibration files, in order.
    pub fn named(&self) -> [(&'static str, f64); 6] {
        [
            ("l1x", self.l1x),
            ("l1z", self.l1z),
            ("l2", self.l2),
            ("l3z", self.l3z),
            ("l4x", self.l4x),
            ("l5x", self.l5x),
        ]
    }
}

/// Mass data of the moving links, for gravity torques (compliance effect).
///
/// Link `n` (index n-1) is the body moved by axis n; its centre of gravity is given in the
/// paper's frame of axis n (the model frames that coincide with the base frame at HOME,
/// origin at the point where the nominal chain places axis n).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// Mass of each moving link in kg (link 1 = turntable ... link 6 = flange).
    #[schemars(inner(range(min = 0, max = 10000)))]
    pub link_mass_kg: [f64; 6],
    /// Centre of gravity of each link in its own axis frame, mm.
    #[schemars(inner(inner(range(min = -5000, max = 5000))))]
    pub link_cog_mm: [[f64; 3]; 6],
}

/// The payload carried at the flange (tool, spindle, workpiece).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Payload {
    /// The payload's mass, kg.
    #[schemars(range(min = 0, max = 10000))]
    pub mass_kg: f64,
    /// Centre of gravity in the KUKA flange frame, mm.
    #[schemars(inner(range(min = -5000, max = 5000)))]
    pub cog_mm: [f64; 3],
}

impl Default for Payload {
    fn default() -> Self {
        Payload {
            mass_kg: 0.0,
            cog_mm: [0.0; 3],
        }
    }
}

/// A six-axis arm of the KUKA "offset wrist" family as plain data.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RobotDescription {
    /// The link lengths and offsets of the nominal kinematics, mm.
    pub links: Links,
    /// Software limits per axis, [min, max] in degrees (KUKA command angles), min < max.
    #[schemars(inner(inner(range(min = -720, max = 720))))]
    pub limits_deg: [[f64; 2]; 6],
    /// Sign relating each KUKA axis angle to a right-handed rotation about the model axis
    /// (A1 −Z, A2 +Y, A3 +Y, A4 −X, A5 +Y, A6 −Z of the flange): `θ_model = sense·A + offset`.
    pub senses: [f64; 6],
    /// Offsets in degrees of the same relation (KUKA: A2 +90°, A3 −90°).
    #[schemars(inner(range(min = -360, max = 360)))]
    pub offsets_deg: [f64; 6],
    /// Link masses for gravity torques; `None` when unknown (compliance then unavailable).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<Gravity>,
}

impl RobotDescription {
    /// KUKA KR 30 HA (same geometry as the KR 30-3), reach 2033 mm.
    ///
    /// Masses are rounded public figures (robot ≈ 665 kg total) spread over the links so that
    /// gravity torques are of the right size; they only scale the compliance effect.
    pub const fn kr30ha() -> Self {
        RobotDescription {
            links: Links {
                l1x: 350.0,
                l1z: 815.0,
                l2: 850.0,
                l3z: 145.0,
                l4x: 820.0,
                l5x: 170.0,
            },
            limits_deg: [
                [-185.0, 185.0],
                [-135.0, 35.0],
                [-120.0, 158.0],
                [-350.0, 350.0],
                [-119.0, 119.0],
                [-350.0, 350.0],
            ],
            senses: [-1.0, 1.0, 1.0, -1.0, 1.0, -1.0],
            offsets_deg: [0.0, 90.0, -90.0, 0.0, 0.0, 0.0],
            gravity: Some(Gravity {
                link_mass_kg: [240.0, 110.0, 95.0, 25.0, 12.0, 3.0],
                link_cog_mm: [
                    [120.0, 0.0, 300.0],
                    [0.0, 0.0, 400.0],
                    [250.0, 0.0, 120.0],
                    [350.0, 0.0, 0.0],
                    [60.0, 0.0, 0.0],
                    [20.0, 0.0, 0.0],
                ],
            }),
        }
    }

    /// Is every axis angle inside its software limits?
    pub fn within_limits(&self, axes_deg: &[f64; 6]) -> bool {
        axes_deg
            .iter()
            .zip(self.limits_deg.iter())
            .all(|(a, [lo, hi])| *a >= *lo && *a <= *hi)
    }
}

impl Default for RobotDescription {
    fn default() -> Self {
        Self::kr30ha()
    }
}
