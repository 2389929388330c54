//! The virtual robot: a truth [`Model`] driven through a sequence of stops as a controller
//! would visit them, measured by a simulated laser tracker. Rotation directions come from the
//! real visiting sequence (approach moves included) through the same [`infer_histories`] that
//! reads measurement files, so that where an axis's gear play stands is what identification
//! will infer from the CSV. Noise is drawn from a ChaCha8
//! generator seeded by the truth file's seed: the same truth, stops and seed always give the
//! same file.

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::campaign::PlannedStop;
use super::program::ProgramVisit;
use super::truth::{TrackerNoise, TruthFile};
use crate::calibration::{CalError, MeasurementFrame};
use crate::kinematics::Frame;
use crate::measure::{infer_histories, Stop};
use crate::model::{AxisState, Model};

/// A stop the virtual robot refuses, as a controller would.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SimulateError {
    #[error(
        "stop {index} (test `{test}`): A{axis} = {angle_deg}° is outside its limits [{lo}°, {hi}°]"
    )]
    OutOfLimits {
        index: usize,
        test: String,
        axis: usize,
        angle_deg: f64,
        lo: f64,
        hi: f64,
    },
}

/// A robot whose errors are known, and the tracker that measures it.
#[derive(Clone, Debug)]
pub struct VirtualRobot {
    /// What the robot really does (every effect of the truth file).
    pub truth: Model,
    /// Pose of the tracker frame in the base frame (`p_base = F · p_tracker`); `None`: the
    /// tracker reports in the base frame.
    pub tracker_frame: Option<Frame>,
    pub noise: TrackerNoise,
    /// Tracker head in the base frame, mm (the noise grows with the distance to it).
    pub station_mm: Vector3<f64>,
    pub seed: u64,
}

impl VirtualRobot {
    /// A robot measured in its base frame with the default tracker noise and seed 0.
    #[cfg(any(test, feature = "internals"))]
    pub fn new(truth: Model) -> VirtualRobot {
        VirtualRobot {
            truth,
            tracker_frame: None,
            noise: TrackerNoise::default(),
            station_mm: Vector3::from(super::truth::DEFAULT_STATION_MM),
            seed: 0,
        }
    }

    /// The robot a validated truth file describes.
    pub fn from_truth(file: &TruthFile, path: &std::path::Path) -> Result<VirtualRobot, CalError> {
        let calibration = file.validate(path)?;
        let tracker_frame = match calibration.frame {
            MeasurementFrame::Base => None,
            MeasurementFrame::Tracker(f) => Some(Frame::from_kuka(&f)),
        };
        Ok(VirtualRobot {
            truth: calibration.model(),
            tracker_frame,
            noise: file.tracker,
            station_mm: file.station_mm(),
            seed: file.seed,
        })
    }

    /// Reads a truth file.
    #[cfg(any(test, feature = "internals"))]
    pub fn load(path: &std::path::Path) -> Result<VirtualRobot, CalError> {
        Self::from_truth(&super::truth::load(path)?, path)
    }

    pub fn with_seed(mut self, seed: u64) -> VirtualRobot {
        self.seed = seed;
        self
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn with_noise(mut self, noise: TrackerNoise) -> VirtualRobot {
        self.noise = noise;
        self
    }

    /// Reports positions in a tracker frame whose pose in the base frame is `frame`.
    #[cfg(any(test, feature = "internals"))]
    pub fn with_tracker_frame(mut self, frame: Option<Frame>) -> VirtualRobot {
        self.tracker_frame = frame;
        self
    }

    /// Where the target really is at `state`, base frame, mm (no noise).
    pub fn true_position(&self, state: &AxisState) -> Vector3<f64> {
        self.truth.target_position(state)
    }

    /// A base-frame position as the tracker reports it (its frame), without noise.
    pub fn to_tracker(&self, p_base: &Vector3<f64>) -> Vector3<f64> {
        match &self.tracker_frame {
            // Through the unit quaternion: the readings keep the bits of the shipped
            // measurement fixtures, which `tests/fixtures_regenerate.rs` compares byte for byte.
            Some(f) => {
                f.to_isometry()
                    .inverse_transform_point(&(*p_base).into())
                    .coords
            }
            None => *p_base,
        }
    }

    /// Runs `stops` in order and measures the stops marked `measured`.
    ///
    /// Every stop (measured or not) becomes a [`Stop`] with the command angles, the rotation
    /// directions inferred from the whole sequence and the stop's time; measured stops get the
    /// true target position plus tracker noise, in the tracker's frame. A stop outside the
    /// joint limits is refused (a controller would not go there).
    pub fn measure(&self, stops: &[PlannedStop]) -> Result<Vec<Stop>, SimulateError> {
        self.check_limits(stops)?;
        let mut states: Vec<AxisState> = stops
            .iter()
            .map(|s| AxisState {
                time_s: s.time_s,
                ..AxisState::new(s.axes_deg)
            })
            .collect();
        infer_histories(&mut states, &[]);
        Ok(self.measure_states(stops, states))
    }

    /// Runs the stops of a program ([`program_visits`](super::program::program_visits)) and
    /// measures them as [`measure`](Self::measure) does, with the axis histories the
    /// simulated motion arrives with instead of those inferred from the stops alone (a path
    /// motion may turn an axis round between two targets).
    pub fn run_program(&self, visits: &[ProgramVisit]) -> Result<Vec<Stop>, SimulateError> {
        let stops: Vec<PlannedStop> = visits.iter().map(|v| v.stop.clone()).collect();
        self.check_limits(&stops)?;
        let states = super::program::visit_states(visits);
        Ok(self.measure_states(&stops, states))
    }

    fn check_limits(&self, stops: &[PlannedStop]) -> Result<(), SimulateError> {
        let robot = &self.truth.robot;
        for (index, s) in stops.iter().enumerate() {
            for (k, &angle) in s.axes_deg.iter().enumerate() {
                let [lo, hi] = robot.limits_deg[k];
                if !(lo..=hi).contains(&angle) {
                    return Err(SimulateError::OutOfLimits {
                        index,
                        test: s.test.clone(),
                        axis: k + 1,
                        angle_deg: angle,
                        lo,
                        hi,
                    });
                }
            }
        }
        Ok(())
    }

    /// The measured stops: `states` (one per stop) with noisy true positions where measured.
    fn measure_states(&self, stops: &[PlannedStop], states: Vec<AxisState>) -> Vec<Stop> {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        stops
            .iter()
            .zip(states)
            .map(|(planned, state)| {
                let measured_mm = planned.measured.then(|| {
                    let p = self.true_position(&state);
                    let sigma = self.noise.sigma_mm((p - self.station_mm).norm());
                    let mut draw = || -> f64 { StandardNormal.sample(&mut rng) };
                    let noise = Vector3::new(draw(), draw(), draw()) * sigma;
                    self.to_tracker(&p) + noise
                });
                Stop {
                    test: planned.test.clone(),
                    state,
                    measured_mm,
                    line: 0,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::KukaFrame;
    use crate::kinematics::{Payload, RobotDescription};
    use crate::model::{Direction, EffectName, GridOptions};

    fn nominal() -> Model {
        Model::new(
            RobotDescription::kr30ha(),
            Payload::default(),
            Vector3::zeros(),
        )
    }

    fn stop(a1: f64, measured: bool) -> PlannedStop {
        PlannedStop {
            test: "t".into(),
            axes_deg: [a1, -90.0, 90.0, 0.0, 0.0, 0.0],
            measured,
            time_s: 0.0,
        }
    }

    #[test]
    fn noise_free_nominal_robot_measures_the_reference_pose() {
        let robot = VirtualRobot::new(nominal()).with_noise(TrackerNoise::NONE);
        let out = robot.measure(&[stop(0.0, true)]).unwrap();
        // MODEL.md reference pose: HOME flange at (1340, 0, 1810).
        let p = out[0].measured_mm.unwrap();
        assert!((p - Vector3::new(1340.0, 0.0, 1810.0)).norm() < 1e-9);
    }

    #[test]
    fn directions_follow_the_visiting_sequence_including_approach_rows() {
        let mut truth = nominal();
        let name = EffectName::parse("backlash:A1").unwrap();
        truth.push_named(&name, &GridOptions::default()).unwrap();
        let n = truth.n_parameters();
        // A play of 0.01°: the output lags by 0.005° after a motion in either direction.
        truth.set_values(&vec![0.01; n]);
        let robot = VirtualRobot::new(truth).with_noise(TrackerNoise::NONE);
        let out = robot
            .measure(&[
                stop(-2.0, false),
                stop(0.0, true),
                stop(2.0, false),
                stop(0.0, true),
            ])
            .unwrap();
        assert!(out[0].measured_mm.is_none() && out[2].measured_mm.is_none());
        assert_eq!(out[1].state.directions()[0], Direction::Positive);
        assert_eq!(out[3].state.directions()[0], Direction::Negative);
        // The same command angle, 0.01° apart (−0.005° arriving upward, +0.005° arriving
        // downward): A1 turns the target at radius 1340 mm by 0.01° → chord 1340·0.01·π/180
        // mm, along Y.
        let d = out[1].measured_mm.unwrap() - out[3].measured_mm.unwrap();
        let expected = 1340.0 * 0.01f64.to_radians();
        assert!((d.norm() - expected).abs() < 1e-6, "{d}");
        assert!(d.x.abs() < 1e-6 && d.z.abs() < 1e-9);
    }

    #[test]
    fn tracker_frame_and_seeded_noise() {
        let frame = KukaFrame {
            x: 3000.0,
            y: -500.0,
            z: 100.0,
            a: 150.0,
            b: 1.0,
            c: -2.0,
        };
        let frame = Frame::from_kuka(&frame).to_isometry();
        let exact = VirtualRobot::new(nominal())
            .with_noise(TrackerNoise::NONE)
            .with_tracker_frame(Some(Frame::from_isometry(&frame)));
        let m = exact.measure(&[stop(10.0, true)]).unwrap()[0]
            .measured_mm
            .unwrap();
        let back = frame.transform_point(&m.into()).coords;
        let truth = exact.true_position(&AxisState::new(stop(10.0, true).axes_deg));
        assert!((back - truth).norm() < 1e-9);

        // Seeded noise: reproducible, different for another seed, of the stated size.
        let stops: Vec<PlannedStop> = (0..2000)
            .map(|i| stop(-60.0 + i as f64 * 0.06, true))
            .collect();
        let noisy = VirtualRobot::new(nominal()).with_seed(7);
        let a = noisy.measure(&stops).unwrap();
        assert_eq!(a, noisy.measure(&stops).unwrap());
        assert_ne!(a, noisy.clone().with_seed(8).measure(&stops).unwrap());
        let exact = VirtualRobot::new(nominal()).with_noise(TrackerNoise::NONE);
        let b = exact.measure(&stops).unwrap();
        let (mut sum2, mut expected2) = (0.0, 0.0);
        for (x, y) in a.iter().zip(&b) {
            let p = y.measured_mm.unwrap();
            sum2 += (x.measured_mm.unwrap() - p).norm_squared();
            let s = noisy.noise.sigma_mm((p - noisy.station_mm).norm());
            expected2 += 3.0 * s * s;
        }
        let ratio = (sum2 / expected2).sqrt();
        assert!((ratio - 1.0).abs() < 0.05, "noise ratio {ratio}");
    }

    #[test]
    fn out_of_limits_stop_is_refused() {
        let robot = VirtualRobot::new(nominal());
        let e = robot.measure(&[stop(200.0, true)]).unwrap_err();
        assert!(e.to_string().contains("A1 = 200°"), "{e}");
    }
}
