//! The laser tracker's accuracy as its maker states it — a maximum permissible error (MPE)
//! of a constant plus a part per metre of distance, `±(c µm + m µm/m)` — and where it stands,
//! from which the noise floor, the gross-error test and the poor-fit refusal take the noise of
//! each point. Presets name common trackers (`docs/trackers.md` gives the sources); any other
//! is given by its numbers (`15+6/m`). The typical 3-D error is half the MPE (as the makers
//! say of their own instruments); the standard deviation per coordinate keeps the ratio to the
//! MPE that robopost has always used for the Leica AT960 (5 µm + 2.5 µm/m for ±(15 µm +
//! 6 µm/m)), so that the default tracker gives the results it always gave.

use nalgebra::Vector3;

/// A tracker's stated accuracy and, when known, its position in the measurement frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Tracker {
    /// The preset's name, or the numbers as given.
    pub name: String,
    /// MPE: constant part, µm, and part per metre of distance, µm/m.
    pub mpe_um: f64,
    /// The MPE's part per metre of distance, µm/m.
    pub mpe_um_per_m: f64,
    /// Where the tracker head stands in the robot base frame, mm (`--tracker-at`); `None`:
    /// from the identified tracker frame, else assumed.
    pub station_mm: Option<Vector3<f64>>,
}

/// A common tracker and its MPE as the maker states it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// The name on the command line (`--tracker at960`).
    pub key: &'static str,
    pub name: &'static str,
    pub mpe_um: f64,
    pub mpe_um_per_m: f64,
}

/// The presets (`docs/trackers.md` gives where each number comes from).
pub const PRESETS: [Preset; 5] = [
    Preset {
        key: "at960",
        name: "Leica AT960",
        mpe_um: 15.0,
        mpe_um_per_m: 6.0,
    },
    Preset {
        key: "at500",
        name: "Leica AT500",
        mpe_um: 15.0,
        mpe_um_per_m: 6.0,
    },
    Preset {
        key: "at403",
        name: "Leica AT403",
        mpe_um: 15.0,
        mpe_um_per_m: 6.0,
    },
    Preset {
        key: "vantage",
        name: "FARO Vantage",
        mpe_um: 20.0,
        mpe_um_per_m: 5.0,
    },
    Preset {
        key: "radian",
        name: "API Radian",
        mpe_um: 10.0,
        mpe_um_per_m: 5.0,
    },
];

/// The typical 3-D error as a share of the MPE.
pub const TYPICAL_FRACTION: f64 = 0.5;
/// The standard deviation per coordinate of the Leica AT960 (µm, µm/m) that robopost has
/// always used: each part of another tracker's MPE scales it in proportion.
pub const AT960_SIGMA_UM: f64 = 5.0;
pub const AT960_SIGMA_UM_PER_M: f64 = 2.5;

impl Default for Tracker {
    /// The Leica AT960, position unknown.
    fn default() -> Tracker {
        Tracker::preset(&PRESETS[0])
    }
}

impl Tracker {
    fn preset(p: &Preset) -> Tracker {
        Tracker {
            name: p.name.to_string(),
            mpe_um: p.mpe_um,
            mpe_um_per_m: p.mpe_um_per_m,
            station_mm: None,
        }
    }

    /// A preset's key (`at960`, case-insensitive) or an MPE as `C+M/m` in µm (`15+6/m`,
    /// `10`); `Err` says what is accepted.
    pub fn parse(spec: &str) -> Result<Tracker, String> {
        let s = spec.trim().to_ascii_lowercase();
        if let Some(p) = PRESETS.iter().find(|p| p.key == s) {
            return Ok(Tracker::preset(p));
        }
        let (c, m) = match s.split_once('+') {
            Some((c, m)) => (c, m.strip_suffix("/m").unwrap_or("")),
            None => (s.as_str(), "0"),
        };
        let num = |t: &str| {
            t.trim()
                .trim_end_matches("um")
                .trim_end_matches("µm")
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0)
        };
        match (num(c), num(m)) {
            (Some(c), Some(m)) if c + m > 0.0 => Ok(Tracker {
                name: format!("MPE ±({c} µm + {m} µm/m)"),
                mpe_um: c,
                mpe_um_per_m: m,
                station_mm: None,
            }),
            _ => Err(format!(
                "--tracker {spec}: expected a tracker ({}) or its MPE in µm as C+M/m (e.g. 15+6/m)",
                PRESETS.iter().map(|p| p.key).collect::<Vec<_>>().join(", ")
            )),
        }
    }

    /// The typical 3-D error at `distance_m` from the tracker, µm: half the MPE.
    pub fn typical_um(&self, distance_m: f64) -> f64 {
        TYPICAL_FRACTION * (self.mpe_um + self.mpe_um_per_m * distance_m)
    }

    /// The standard deviation per coordinate (mm) at `point` measured from `station` (mm,
    /// one frame).
    pub fn sigma_mm(&self, point: &Vector3<f64>, station: &Vector3<f64>) -> f64 {
        // Scaled as (σ · MPE) / MPE_AT960, so that the AT960 gets its σ bit for bit.
        let c = AT960_SIGMA_UM * self.mpe_um / PRESETS[0].mpe_um;
        let m = AT960_SIGMA_UM_PER_M * self.mpe_um_per_m / PRESETS[0].mpe_um_per_m;
        (c + m * (point - station).norm() / 1000.0) / 1000.0
    }

    /// "AT960 MPE ±(15 µm + 6 µm/m)" (the maker's name left out), or "MPE ±(…)" for numbers:
    /// the words of the noise floor's source.
    pub fn mpe_words(&self) -> String {
        let short = self.name.split_once(' ').map_or("", |(_, model)| model);
        if self.name.starts_with("MPE") {
            format!("stated {}", self.name)
        } else {
            format!(
                "{short} MPE ±({} µm + {} µm/m)",
                self.mpe_um, self.mpe_um_per_m
            )
        }
    }

    /// "Leica AT960, MPE ±(15 µm + 6 µm/m)".
    pub fn describe(&self) -> String {
        if self.name.starts_with("MPE") {
            self.name.clone()
        } else {
            format!(
                "{}, MPE ±({} µm + {} µm/m)",
                self.name, self.mpe_um, self.mpe_um_per_m
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_numbers_and_refusals() {
        let t = Tracker::parse("AT960").unwrap();
        assert_eq!((t.mpe_um, t.mpe_um_per_m), (15.0, 6.0));
        assert_eq!(t, Tracker::default());
        let t = Tracker::parse("30+12/m").unwrap();
        assert_eq!((t.mpe_um, t.mpe_um_per_m), (30.0, 12.0));
        assert_eq!(Tracker::parse("10").unwrap().mpe_um_per_m, 0.0);
        assert_eq!(Tracker::parse("10um+2um/m").unwrap().mpe_um_per_m, 2.0);
        for bad in ["", "laser", "15+6", "-1+2/m", "0+0/m", "nan"] {
            assert!(Tracker::parse(bad).is_err(), "{bad}");
        }
        // The AT960 at 3 m: σ 5 + 7.5 = 12.5 µm per coordinate; typical ½(15 + 18) = 16.5 µm.
        let at960 = Tracker::default();
        let s = at960.sigma_mm(&Vector3::new(3000.0, 0.0, 0.0), &Vector3::zeros());
        assert!((s - 0.0125).abs() < 1e-15);
        assert!((at960.typical_um(3.0) - 16.5).abs() < 1e-12);
        assert_eq!(at960.mpe_words(), "AT960 MPE ±(15 µm + 6 µm/m)");
    }
}
