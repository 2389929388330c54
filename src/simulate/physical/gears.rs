//! The gears: a smooth transmission error of the command angle (harmonics and a slow trend,
//! closed form, no table) and a play run as a play operator over the commanded trajectory —
//! the output lags the command by up to half the play and stays where it is while the command
//! turns back by less than the play.

use std::f64::consts::TAU;

use super::file::Gear;

impl Gear {
    /// The transmission error at command angle `a` (degrees): output − command, without play.
    pub fn transmission_error_deg(&self, a: f64) -> f64 {
        let u = a / 100.0;
        let periodic: f64 = self
            .harmonics
            .iter()
            .map(|h| h.amplitude_deg * (TAU * a / h.period_deg + h.phase_deg.to_radians()).sin())
            .sum();
        periodic + self.trend_deg[0] * u + self.trend_deg[1] * u * u
    }
}

/// The play state of the six axes: the lag of each output behind its command, degrees.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Play {
    pub lag_deg: [f64; 6],
}

impl Play {
    /// The command moved by `delta_deg`: `lag ← clamp(lag − Δ, −b/2, +b/2)` per axis. Exact for
    /// a motion that does not turn back, so a trajectory must be sampled at every reversal.
    pub fn advance(&mut self, delta_deg: &[f64; 6], widths_deg: &[f64; 6]) {
        for k in 0..6 {
            let half = widths_deg[k] / 2.0;
            self.lag_deg[k] = (self.lag_deg[k] - delta_deg[k]).clamp(-half, half);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::file::Harmonic;
    use super::*;

    #[test]
    fn transmission_error_by_hand() {
        let gear = Gear {
            harmonics: vec![Harmonic {
                amplitude_deg: 0.004,
                period_deg: 7.3,
                phase_deg: 90.0,
            }],
            trend_deg: [0.002, -0.001],
            play_deg: 0.0,
            flank_friction_knm: None,
        };
        // At 0: cos(0)·0.004; at 7.3/4: sin(π/2 + π/2) = 0, plus the trend.
        assert!((gear.transmission_error_deg(0.0) - 0.004).abs() < 1e-15);
        let a = 7.3 / 4.0;
        let u = a / 100.0;
        let expected = 0.002 * u - 0.001 * u * u;
        assert!((gear.transmission_error_deg(a) - expected).abs() < 1e-15);
    }

    #[test]
    fn play_lags_after_long_moves_and_holds_inside_the_play() {
        let widths = [0.02, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut play = Play::default();
        let step = |play: &mut Play, d: f64| {
            play.advance(&[d, 0.0, 0.0, 0.0, 0.0, 0.0], &widths);
            play.lag_deg[0]
        };
        // A positive move longer than the play: the output lags by b/2.
        assert_eq!(step(&mut play, 1.0), -0.01);
        // Back by less than the play: the output has not moved (command + lag constant).
        let lag = step(&mut play, -0.005);
        assert!((lag - -0.005).abs() < 1e-15);
        // Further back: dragged along on the other flank.
        assert_eq!(step(&mut play, -1.0), 0.01);
    }
}
