//! `diagnose --validate FILE`: the advice judged where programs run. The validation files are
//! measured elsewhere in the workspace and later than the campaign (as `identify --validate`
//! takes them); the first advice is identified as its printed command will, and credited with
//! what it gains on them — advice that does not lower their error is not given. What the
//! validation data ask of the model beyond the campaign is reported: the drivers (axis angles,
//! the arm's reach, the time) where they leave the campaign's range, where any effect is an
//! extrapolation.

use serde::Serialize;

use crate::calibration::Calibration;
use crate::compare::{self, Row};
use crate::measure::Measurements;

/// What the first advice does on the validation files.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ValidationGain {
    /// RMS 3-D residual of the current calibration on the validation files, µm.
    pub rms_before_um: f64,
    /// The same with the advice identified as printed, µm.
    pub rms_after_um: f64,
    /// Measured points of the validation files.
    pub points: usize,
}

impl ValidationGain {
    /// Fraction of the validation residual sum of squares the advice removes.
    pub fn explained(&self) -> f64 {
        if self.rms_before_um > 0.0 {
            1.0 - (self.rms_after_um / self.rms_before_um).powi(2)
        } else {
            0.0
        }
    }
}

/// RMS 3-D residual of `cal` on `files`, µm, and the points; `None` without a measured row.
pub fn rms_on(cal: &Calibration, files: &[Measurements]) -> Option<(f64, usize)> {
    let rows = compare::compare(cal, files);
    if rows.is_empty() {
        return None;
    }
    let ss: f64 = rows.iter().map(|r| r.residual().norm_squared()).sum();
    Some(((ss / rows.len() as f64).sqrt() * 1000.0, rows.len()))
}

/// `cal` and `followed` (the advice identified) on the validation `files`.
pub fn gain(
    cal: &Calibration,
    followed: &Calibration,
    files: &[Measurements],
) -> Option<ValidationGain> {
    let (before, points) = rms_on(cal, files)?;
    let (after, _) = rms_on(followed, files)?;
    Some(ValidationGain {
        rms_before_um: before,
        rms_after_um: after,
        points,
    })
}

/// Share of a driver's campaign span the validation data must pass its ends by to be named.
const MARGIN: f64 = 0.02;

/// The drivers of `validation` rows outside the range `campaign` rows covered, in words
/// ("A2 −95.0..−10.0° against the campaign's −80.0..−10.0°"), axis angles first, then the
/// reach (the measured point's distance from the A1 axis) and the time.
pub fn extrapolation(campaign: &[Row], validation: &[Row]) -> Vec<String> {
    type Driver = (String, &'static str, fn(&Row) -> f64);
    let mut drivers: Vec<Driver> = vec![
        ("A1".into(), "°", |r| r.state.axes_deg[0]),
        ("A2".into(), "°", |r| r.state.axes_deg[1]),
        ("A3".into(), "°", |r| r.state.axes_deg[2]),
        ("A4".into(), "°", |r| r.state.axes_deg[3]),
        ("A5".into(), "°", |r| r.state.axes_deg[4]),
        ("A6".into(), "°", |r| r.state.axes_deg[5]),
    ];
    drivers.push(("the reach".into(), " mm", |r| r.measured.xy().norm()));
    drivers.push(("the time".into(), " h", |r| r.state.time_s / 3600.0));
    let range = |rows: &[Row], f: fn(&Row) -> f64| {
        rows.iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x), hi.max(x))
            })
    };
    let mut out = Vec::new();
    if campaign.is_empty() || validation.is_empty() {
        return out;
    }
    for (name, unit, f) in drivers {
        let (clo, chi) = range(campaign, f);
        let (vlo, vhi) = range(validation, f);
        let margin = MARGIN * (chi - clo).abs().max(1e-9);
        if vlo < clo - margin || vhi > chi + margin {
            out.push(format!(
                "{name} {vlo:.1}..{vhi:.1}{unit} against the campaign's {clo:.1}..{chi:.1}{unit}"
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::AxisState;
    use nalgebra::Vector3;

    fn row(a2: f64, x_mm: f64, t_s: f64) -> Row {
        let mut state = AxisState::new([0.0, a2, 90.0, 0.0, 0.0, 0.0]);
        state.time_s = t_s;
        Row {
            test: "t".into(),
            source: "f".into(),
            line: 1,
            state,
            measured: Vector3::new(x_mm, 0.0, 0.0),
            predicted: Vector3::zeros(),
            nominal: Vector3::zeros(),
        }
    }

    #[test]
    fn drivers_beyond_the_campaign_are_named() {
        // Campaign: A2 −80..−10°, reach 1000..1500 mm, 0..1 h. Validation: A2 −95..−20°
        // (below by 15°, beyond 2% of the 70° span), reach inside, 2..3 h (later).
        let campaign = [row(-80.0, 1000.0, 0.0), row(-10.0, 1500.0, 3600.0)];
        let validation = [row(-95.0, 1100.0, 7200.0), row(-20.0, 1400.0, 10800.0)];
        let named = extrapolation(&campaign, &validation);
        assert_eq!(
            named,
            [
                "A2 -95.0..-20.0° against the campaign's -80.0..-10.0°",
                "the time 2.0..3.0 h against the campaign's 0.0..1.0 h"
            ]
        );
        // Inside every range: nothing.
        assert!(extrapolation(&campaign, &campaign).is_empty());
    }

    #[test]
    fn explained_by_hand() {
        let g = ValidationGain {
            rms_before_um: 20.0,
            rms_after_um: 10.0,
            points: 4,
        };
        // 1 − (10/20)² = 0.75.
        assert!((g.explained() - 0.75).abs() < 1e-12);
    }
}
