//! A physical truth robot, independent of the error model: the arm written from its joint
//! frames (each with a full 6-DOF error), gears with smooth transmission errors and a play run
//! over the commanded trajectory, deflection under gravity from link masses, a deviation that
//! follows the moment of inertia an axis drives (the paper's A3 → A2 crosstalk), links that
//! grow as the robot warms up, and a laser tracker with a scale error, a frame of its own and
//! heavy-tailed noise with gross errors. It shares no code with `model/` (its own chain, its
//! own gravity torques, no tables, no direction inference), so identification, compensation
//! and diagnosis tested on it are tested against something that is not themselves: what the
//! model cannot represent shows as a floor above the noise.
//!
//! [`PhysicalRobot::measure`] is a pure function of a command trajectory (`&[CommandSample]`,
//! see [`samples`]) that returns the rows of a measurement file ([`Stop`]s, written with
//! [`crate::measure::write_csv`]), so every command reads its output unchanged. The file
//! format `robopost-physical-truth/1` is documented in `docs/physical-truth.md`.

mod arm;
mod file;
mod gears;
pub mod samples;
mod tracker;

use std::path::Path;

use nalgebra::{Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use file::{parse, PhysicalTruthFile, PHYSICAL_FORMAT};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use file::{Counterbalance, Gear, Growth, Harmonic, JointError, Noise, Tracker};
pub use samples::{from_program, from_stops, CommandSample, SampleKind, PTP_STEP_DEG};

use crate::calibration::CalError;
use crate::kinematics::RobotDescription;
use crate::measure::Stop;
use crate::model::AxisState;
use arm::Arm;
use gears::Play;
use tracker::Head;

/// A sample the robot refuses, as a controller would.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PhysicalError {
    #[error(
        "sample {index} (test `{test}`, line {line}): A{axis} = {angle_deg}° is outside its \
         limits [{lo}°, {hi}°]"
    )]
    OutOfLimits {
        index: usize,
        test: String,
        line: u32,
        axis: usize,
        angle_deg: f64,
        lo: f64,
        hi: f64,
    },
}

/// A physical robot and the tracker that measures it.
#[derive(Clone, Debug)]
pub struct PhysicalRobot {
    file: PhysicalTruthFile,
    arm: Arm,
    head: Head,
    /// The moment of inertia each axis drives at the reference pose, kg·m².
    reference_inertia: [f64; 6],
}

impl PhysicalRobot {
    /// The robot a physical truth file describes (validated; `path` names it in errors).
    pub fn new(file: PhysicalTruthFile, path: &Path) -> Result<PhysicalRobot, CalError> {
        file.validate(path)?;
        let arm = Arm::new(
            file.robot.description,
            file.payload,
            &file.joints,
            &file.thermal,
        );
        let reference = arm.bodies(&arm.reference_deg(), 0.0);
        let reference_inertia = arm.inertia_kgm2(&reference);
        let head = Head::new(&file.tracker);
        Ok(PhysicalRobot {
            file,
            arm,
            head,
            reference_inertia,
        })
    }

    /// Reads a physical truth file.
    #[cfg(any(test, feature = "internals"))]
    pub fn load(path: &Path) -> Result<PhysicalRobot, CalError> {
        let text = crate::input::read_to_string(path).map_err(|source| CalError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        PhysicalRobot::new(parse(&text, path)?, path)
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn file(&self) -> &PhysicalTruthFile {
        &self.file
    }

    pub fn robot(&self) -> &RobotDescription {
        &self.file.robot.description
    }

    /// The measurement target in the KUKA flange frame, mm.
    pub fn target_mm(&self) -> Vector3<f64> {
        Vector3::from(self.file.target_mm)
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn seed(&self) -> u64 {
        self.file.seed
    }

    pub fn with_seed(mut self, seed: u64) -> PhysicalRobot {
        self.file.seed = seed;
        self
    }

    /// A robot built without any error (nominal joint frames, perfect gears without play, rigid,
    /// no growth), with the same target, payload and tracker (frame, scale, noise, seed): the
    /// "tracker alone" reference of an experiment.
    #[cfg(any(test, feature = "internals"))]
    pub fn error_free(&self) -> PhysicalRobot {
        let file = PhysicalTruthFile {
            joints: Default::default(),
            gears: Default::default(),
            compliance_deg_per_knm: [0.0; 6],
            inertia_deg_per_kgm2: [0.0; 6],
            thermal: Vec::new(),
            ..self.file.clone()
        };
        PhysicalRobot::new(file, Path::new("error-free")).expect("a valid truth stays valid")
    }

    /// The output angles of the axes (degrees) at command `command_deg`, with the play's lag
    /// `lag_deg`, at time `time_s`.
    pub fn output_deg(&self, command_deg: &[f64; 6], lag_deg: &[f64; 6], time_s: f64) -> [f64; 6] {
        let geared: [f64; 6] = std::array::from_fn(|k| {
            command_deg[k] + self.file.gears[k].transmission_error_deg(command_deg[k]) + lag_deg[k]
        });
        let loads = self
            .file
            .compliance_deg_per_knm
            .iter()
            .chain(&self.file.inertia_deg_per_kgm2)
            .any(|&c| c != 0.0);
        if !loads {
            return geared;
        }
        // The loads follow the pose to first order; the deflection they cause is far too small
        // to change them.
        let bodies = self.arm.bodies(&geared, time_s);
        let torque = self.arm.gravity_torques_knm(&bodies);
        let inertia = self.arm.inertia_kgm2(&bodies);
        std::array::from_fn(|k| {
            geared[k]
                + self.file.compliance_deg_per_knm[k] * torque[k]
                + self.file.inertia_deg_per_kgm2[k] * (inertia[k] - self.reference_inertia[k])
        })
    }

    /// Where the target truly is (base frame, mm) when the axes' outputs are at `output_deg`.
    pub fn target_at(&self, output_deg: &[f64; 6], time_s: f64) -> Vector3<f64> {
        let bodies = self.arm.bodies(output_deg, time_s);
        (bodies.flange * Point3::from(self.target_mm())).coords
    }

    /// The flange pose of the arm (no tracker) at output angles `output_deg`.
    #[cfg(any(test, feature = "internals"))]
    pub fn flange_at(&self, output_deg: &[f64; 6], time_s: f64) -> crate::kinematics::Frame {
        crate::kinematics::Frame::from_isometry(&self.arm.bodies(output_deg, time_s).flange)
    }

    /// Runs the command trajectory `samples` in order and returns one row per `Visit` and
    /// `Measure` sample: its command angles, the direction of each axis's last command motion,
    /// its time, and on `Measure` the tracker's reading of the target. The play starts centred.
    /// A sample outside the joint limits is refused.
    pub fn measure(&self, samples: &[CommandSample]) -> Result<Vec<Stop>, PhysicalError> {
        self.check_limits(samples)?;
        let widths = self.file.gears.each_ref().map(|g| g.play_deg);
        let mut rng = ChaCha8Rng::seed_from_u64(self.file.seed);
        let mut play = Play::default();
        let mut previous: Option<&[f64; 6]> = None;
        let mut state: Option<AxisState> = None;
        let mut rows = Vec::new();
        for sample in samples {
            if let Some(p) = previous {
                let delta: [f64; 6] = std::array::from_fn(|k| sample.axes_deg[k] - p[k]);
                play.advance(&delta, &widths);
            }
            self.press_flanks(&sample.axes_deg, sample.time_s, &widths, &mut play);
            previous = Some(&sample.axes_deg);
            // The model's view of the same command trajectory: every sample (passes included,
            // so a turn inside a motion is in the history) continues each axis's history.
            let mut next = match state {
                None => AxisState::new(sample.axes_deg),
                Some(s) => s.then(sample.axes_deg),
            };
            next.time_s = sample.time_s;
            state = Some(next);
            let measured_mm = match sample.kind {
                SampleKind::Pass => continue,
                SampleKind::Visit => None,
                SampleKind::Measure => {
                    let output = self.output_deg(&sample.axes_deg, &play.lag_deg, sample.time_s);
                    let p = self.target_at(&output, sample.time_s);
                    Some(self.head.measure(&p, &mut rng))
                }
            };
            rows.push(Stop {
                test: sample.test.clone(),
                state: next,
                measured_mm,
                line: 0,
            });
        }
        Ok(rows)
    }

    /// The net torque about each axis at command `command_deg` (kN·m, KUKA sign): gravity,
    /// and on A2 the counterbalance spring.
    pub fn net_torques_knm(&self, command_deg: &[f64; 6], time_s: f64) -> [f64; 6] {
        let bodies = self.arm.bodies(command_deg, time_s);
        let mut torque = self.arm.gravity_torques_knm(&bodies);
        if let Some(c) = &self.file.counterbalance {
            torque[1] += c.torque_knm(command_deg[1]);
        }
        torque
    }

    /// Where an axis's net torque beats the friction of its train, the output rests on the
    /// flank the torque pushes it to (leading the command when the torque is positive).
    fn press_flanks(
        &self,
        command_deg: &[f64; 6],
        time_s: f64,
        widths: &[f64; 6],
        play: &mut Play,
    ) {
        let frictions = self.file.gears.each_ref().map(|g| g.flank_friction_knm);
        if frictions.iter().all(Option::is_none) || self.robot().gravity.is_none() {
            return;
        }
        let torque = self.net_torques_knm(command_deg, time_s);
        for k in 0..6 {
            if let Some(f) = frictions[k] {
                if torque[k].abs() > f {
                    play.lag_deg[k] = torque[k].signum() * widths[k] / 2.0;
                }
            }
        }
    }

    fn check_limits(&self, samples: &[CommandSample]) -> Result<(), PhysicalError> {
        let limits = &self.robot().limits_deg;
        for (index, s) in samples.iter().enumerate() {
            for (k, &angle) in s.axes_deg.iter().enumerate() {
                let [lo, hi] = limits[k];
                if !(lo..=hi).contains(&angle) {
                    return Err(PhysicalError::OutOfLimits {
                        index,
                        test: s.test.clone(),
                        line: s.line,
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::RobotRecord;
    use crate::kinematics::Payload;
    use crate::model::Direction;

    fn robot(gears: [Gear; 6]) -> PhysicalRobot {
        let file = PhysicalTruthFile {
            format: PHYSICAL_FORMAT.into(),
            robot: RobotRecord {
                name: "t".into(),
                description: RobotDescription::kr30ha(),
            },
            payload: Payload::default(),
            target_mm: [0.0; 3],
            joints: Default::default(),
            gears,
            compliance_deg_per_knm: [0.0; 6],
            inertia_deg_per_kgm2: [0.0; 6],
            counterbalance: None,
            thermal: Vec::new(),
            tracker: Tracker {
                noise: Noise::NONE,
                ..Tracker::default()
            },
            seed: 0,
            notes: None,
        };
        PhysicalRobot::new(file, Path::new("t")).unwrap()
    }

    fn at(a1: f64, kind: SampleKind) -> CommandSample {
        CommandSample {
            axes_deg: [a1, -90.0, 90.0, 0.0, 0.0, 0.0],
            time_s: 0.0,
            kind,
            test: "t".into(),
            line: 0,
        }
    }

    #[test]
    fn play_holds_the_output_through_a_short_reversal() {
        let mut gears: [Gear; 6] = Default::default();
        gears[0].play_deg = 0.02;
        let r = robot(gears);
        use SampleKind::*;
        let rows = r
            .measure(&[
                at(-1.0, Visit),
                at(0.0, Measure),    // after +1°: lags by 0.01°
                at(-0.015, Measure), // back 0.015° < 0.02°: the output has not moved
                at(-1.0, Pass),
                at(0.0, Measure), // reached from below again
                at(1.0, Pass),
                at(0.0, Measure), // reached from above: leads by 0.01°
            ])
            .unwrap();
        let p: Vec<Vector3<f64>> = rows.iter().filter_map(|s| s.measured_mm).collect();
        assert_eq!(rows.len(), 5, "Pass samples are not rows");
        assert!((p[0] - p[1]).norm() < 1e-9, "{} {}", p[0], p[1]);
        assert!((p[0] - p[2]).norm() < 1e-9);
        // From above vs from below: 0.02° of A1 at the HOME radius 1340 mm.
        let chord = 1340.0 * 0.02f64.to_radians();
        assert!(((p[3] - p[2]).norm() - chord).abs() < 1e-6);
        assert_eq!(rows[2].state.directions()[0], Direction::Negative);
        assert_eq!(rows[3].state.directions()[0], Direction::Positive);
        assert_eq!(rows[4].state.directions()[0], Direction::Negative);
        assert_eq!(rows[0].state.directions()[1], Direction::Unknown);
        // The nominal robot (no play): the HOME flange.
        let nominal = robot(Default::default());
        let p = nominal.measure(&[at(0.0, Measure)]).unwrap()[0]
            .measured_mm
            .unwrap();
        assert!((p - Vector3::new(1340.0, 0.0, 1810.0)).norm() < 1e-9);
    }

    #[test]
    fn out_of_limits_sample_names_its_line() {
        let r = robot(Default::default());
        let mut s = at(190.0, SampleKind::Pass);
        s.line = 12;
        let e = r.measure(&[at(0.0, SampleKind::Visit), s]).unwrap_err();
        assert!(e.to_string().contains("line 12") && e.to_string().contains("A1 = 190°"));
    }

    #[test]
    fn inertia_crosstalk_is_of_the_papers_size() {
        // The fixture's A2 coefficient turns the moment of inertia's change between A3 = 58°
        // and 153° (the paper's Fig. 5 tests) into about two hundredths of a degree.
        let text = include_str!("../../../fixtures/measurements/kr30ha-physical.json");
        let r = PhysicalRobot::new(parse(text, Path::new("f")).unwrap(), Path::new("f")).unwrap();
        let a2 = |a3: f64| {
            let out = r.output_deg(&[0.0, -60.0, a3, 0.0, 45.0, 0.0], &[0.0; 6], 0.0);
            out[1] + 60.0 - r.file.gears[1].transmission_error_deg(-60.0)
        };
        let change = a2(153.0) - a2(58.0);
        assert!((0.005..0.04).contains(&change.abs()), "{change}");
    }
}
