//! The arm as it is built: a chain of joint frames, each placed relative to the one before at
//! the reference pose (where the KUKA angles make every model angle zero: HOME for a KR 30 HA,
//! upper arm vertical, forearm horizontal, every joint frame aligned with the base), each
//! displaced by its own small rigid error (3 translations, 3 rotations) and turned about its
//! own axis by the output angle. The nominal layout — joint points from the links, axis
//! directions from the senses, the reference pose from the offsets — is the family's physical
//! description (MODEL.md: A1 vertical through the origin, A2 and A3 horizontal across the arm,
//! A4 and A6 along the forearm, A5 across it), not the error model's chain.
//!
//! The same frames give the gravity torque about every axis (link masses at their centres of
//! gravity and the payload) and the moment of inertia every axis drives (point masses).

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};

use super::file::{Growth, JointError};
use crate::kinematics::{Payload, RobotDescription};

/// Standard gravity, m/s².
const G: f64 = 9.80665;

/// The built arm.
#[derive(Clone, Debug)]
pub(super) struct Arm {
    /// Offset into joint frame i from frame i−1 (index 6: into the flange), in frame i−1.
    offsets: [Vector3<f64>; 7],
    /// The rigid error of each joint frame.
    errors: [Isometry3<f64>; 6],
    /// Each joint's rotation axis in its own frame, KUKA positive sense.
    axes: [Unit<Vector3<f64>>; 6],
    /// KUKA angles of the reference pose.
    reference_deg: [f64; 6],
    growth: Vec<Growth>,
    description: RobotDescription,
    payload: Payload,
}

/// Where every body is: the frame of body k (moved by joints 1..=k), origin on joint k's axis,
/// and the flange.
pub(super) struct Bodies {
    pub frames: [Isometry3<f64>; 6],
    pub flange: Isometry3<f64>,
}

/// The frame rotation of the KUKA flange relative to the reference frames: flange Z along the
/// forearm (+X at the reference pose), flange X pointing down.
fn flange_rotation() -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2)
}

impl Arm {
    pub fn new(
        description: RobotDescription,
        payload: Payload,
        joints: &[JointError; 6],
        growth: &[Growth],
    ) -> Arm {
        let l = description.links;
        let offsets = [
            Vector3::zeros(),
            Vector3::new(l.l1x, 0.0, l.l1z),
            Vector3::new(0.0, 0.0, l.l2),
            Vector3::new(0.0, 0.0, l.l3z),
            Vector3::new(l.l4x, 0.0, 0.0),
            Vector3::new(l.l5x, 0.0, 0.0),
            Vector3::zeros(),
        ];
        // The right-handed axis of each joint in the family: A1 vertical, A2, A3, A5 across
        // the arm, A4, A6 along the forearm; the KUKA sense flips it where the pendant's
        // positive direction turns the other way.
        let family = [
            Vector3::z(),
            Vector3::y(),
            Vector3::y(),
            Vector3::x(),
            Vector3::y(),
            Vector3::x(),
        ];
        let axes = std::array::from_fn(|i| Unit::new_normalize(family[i] * description.senses[i]));
        let reference_deg =
            std::array::from_fn(|i| -description.offsets_deg[i] / description.senses[i]);
        let errors = std::array::from_fn(|i| {
            let e = &joints[i];
            let [rx, ry, rz] = e.rotation_deg.map(f64::to_radians);
            Isometry3::from_parts(
                Translation3::from(Vector3::from(e.translation_mm)),
                UnitQuaternion::from_euler_angles(rx, ry, rz),
            )
        });
        Arm {
            offsets,
            errors,
            axes,
            reference_deg,
            growth: growth.to_vec(),
            description,
            payload,
        }
    }

    pub fn reference_deg(&self) -> [f64; 6] {
        self.reference_deg
    }

    /// The bodies at KUKA output angles `output_deg` and campaign time `time_s`.
    pub fn bodies(&self, output_deg: &[f64; 6], time_s: f64) -> Bodies {
        let mut offsets = self.offsets;
        for g in &self.growth {
            let warm = 1.0 - (-time_s / (g.time_constant_h * 3600.0)).exp();
            offsets[g.joint as usize - 1] += Vector3::from(g.mm) * warm;
        }
        let mut frame = Isometry3::identity();
        let frames = std::array::from_fn(|i| {
            let turn = (output_deg[i] - self.reference_deg[i]).to_radians();
            frame = frame
                * Translation3::from(offsets[i])
                * self.errors[i]
                * UnitQuaternion::from_axis_angle(&self.axes[i], turn);
            frame
        });
        let flange = frame * Translation3::from(offsets[6]) * flange_rotation();
        Bodies { frames, flange }
    }

    /// Joint i's axis in the base frame: a point on it and its KUKA-positive direction.
    fn axis(&self, bodies: &Bodies, i: usize) -> (Point3<f64>, Vector3<f64>) {
        let f = &bodies.frames[i];
        (
            Point3::from(f.translation.vector),
            f.rotation * self.axes[i].into_inner(),
        )
    }

    /// The masses the arm carries beyond each joint: (kg, base-frame position mm) of links
    /// 1..6 at their centres of gravity, then the payload.
    fn masses(&self, bodies: &Bodies) -> Vec<(f64, Point3<f64>, usize)> {
        let Some(gravity) = &self.description.gravity else {
            return Vec::new();
        };
        let mut out: Vec<(f64, Point3<f64>, usize)> = (0..6)
            .map(|k| {
                let cog = Point3::from(Vector3::from(gravity.link_cog_mm[k]));
                (gravity.link_mass_kg[k], bodies.frames[k] * cog, k)
            })
            .collect();
        let payload = Point3::from(Vector3::from(self.payload.cog_mm));
        out.push((self.payload.mass_kg, bodies.flange * payload, 6));
        out
    }

    /// The gravity torque about each axis, kN·m, signed like the KUKA angle (positive: gravity
    /// turns the axis the positive way). Base Z points up.
    pub fn gravity_torques_knm(&self, bodies: &Bodies) -> [f64; 6] {
        let masses = self.masses(bodies);
        std::array::from_fn(|i| {
            let (point, direction) = self.axis(bodies, i);
            let moment: Vector3<f64> = masses
                .iter()
                .filter(|(_, _, body)| *body >= i)
                .map(|(m, at, _)| (at - point).cross(&Vector3::new(0.0, 0.0, -m * G)))
                .sum();
            // N·mm → kN·m
            direction.dot(&moment) * 1e-6
        })
    }

    /// The moment of inertia each axis drives, kg·m², of point masses at the centres of
    /// gravity of the bodies beyond it.
    pub fn inertia_kgm2(&self, bodies: &Bodies) -> [f64; 6] {
        let masses = self.masses(bodies);
        std::array::from_fn(|i| {
            let (point, direction) = self.axis(bodies, i);
            masses
                .iter()
                .filter(|(_, _, body)| *body >= i)
                .map(|(m, at, _)| {
                    let r = at - point;
                    let perpendicular = r - direction * direction.dot(&r);
                    m * perpendicular.norm_squared() * 1e-6
                })
                .sum()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nominal() -> Arm {
        Arm::new(
            RobotDescription::kr30ha(),
            Payload::default(),
            &[JointError::default(); 6],
            &[],
        )
    }

    #[test]
    fn nominal_arm_reaches_the_reference_poses() {
        // MODEL.md's table: flange positions and HOME's orientation (flange Z = +X, X down).
        let arm = nominal();
        let cases = [
            ([0.0, -90.0, 90.0, 0.0, 0.0, 0.0], [1340.0, 0.0, 1810.0]),
            ([0.0; 6], [2190.0, 0.0, 960.0]),
            (
                [30.0, -60.0, 100.0, 20.0, 40.0, -50.0],
                [1306.433, -797.425, 972.743],
            ),
            (
                [-45.0, -112.0, 153.0, 0.0, -30.0, 90.0],
                [645.201, 645.201, 1142.133],
            ),
        ];
        for (axes, xyz) in cases {
            let p = arm.bodies(&axes, 0.0).flange.translation.vector;
            assert!((p - Vector3::from(xyz)).norm() < 1e-3, "{axes:?}: {p}");
        }
        let home = arm.bodies(&[0.0, -90.0, 90.0, 0.0, 0.0, 0.0], 0.0).flange;
        assert!((home.rotation * Vector3::z() - Vector3::x()).norm() < 1e-12);
        assert!((home.rotation * Vector3::x() + Vector3::z()).norm() < 1e-12);
    }

    #[test]
    fn gravity_torque_of_a_point_mass_by_hand() {
        // Only a 10 kg payload at the flange centre, arm stretched forward (all zero): A2
        // carries 10 kg · g at the lever 2190 − 350 mm, pulling the arm down, i.e. towards
        // positive A2 (A2 = 0 is horizontal, −90° vertical).
        let mut robot = RobotDescription::kr30ha();
        let mut gravity = robot.gravity.unwrap();
        gravity.link_mass_kg = [0.0; 6];
        robot.gravity = Some(gravity);
        let arm = Arm::new(
            robot,
            Payload {
                mass_kg: 10.0,
                cog_mm: [0.0; 3],
            },
            &[JointError::default(); 6],
            &[],
        );
        let bodies = arm.bodies(&[0.0; 6], 0.0);
        let t = arm.gravity_torques_knm(&bodies);
        let expected = 10.0 * G * (2190.0 - 350.0) * 1e-6;
        assert!((t[1] - expected).abs() < 1e-12, "{t:?}");
        // A3 at 2190 − 1200 mm, A1 vertical carries nothing.
        assert!((t[2] - 10.0 * G * 990.0 * 1e-6).abs() < 1e-12);
        assert!(t[0].abs() < 1e-12);
        let j = arm.inertia_kgm2(&bodies);
        assert!(
            (j[1] - 10.0 * (1.84f64.powi(2) + 0.145f64.powi(2))).abs() < 1e-9,
            "{j:?}"
        );
    }

    #[test]
    fn a_joint_error_moves_what_lies_beyond_it() {
        // A3's frame 0.1 mm higher at HOME lifts the flange by 0.1 mm; at all-zero (upper arm
        // forward) the same error of the upper arm's far end moves it forward.
        let mut joints = [JointError::default(); 6];
        joints[2].translation_mm = [0.0, 0.0, 0.1];
        let arm = Arm::new(RobotDescription::kr30ha(), Payload::default(), &joints, &[]);
        let home = arm.bodies(&[0.0, -90.0, 90.0, 0.0, 0.0, 0.0], 0.0).flange;
        assert!((home.translation.vector - Vector3::new(1340.0, 0.0, 1810.1)).norm() < 1e-9);
        let zero = arm.bodies(&[0.0; 6], 0.0).flange;
        assert!((zero.translation.vector - Vector3::new(2190.1, 0.0, 960.0)).norm() < 1e-9);
    }

    #[test]
    fn growth_follows_the_warm_up() {
        let growth = [Growth {
            joint: 2,
            mm: [0.0, 0.0, 0.1],
            time_constant_h: 1.0,
        }];
        let arm = Arm::new(
            RobotDescription::kr30ha(),
            Payload::default(),
            &[JointError::default(); 6],
            &growth,
        );
        let home = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];
        let z = |t: f64| arm.bodies(&home, t).flange.translation.z;
        assert!((z(0.0) - 1810.0).abs() < 1e-12);
        assert!((z(3600.0) - 1810.0 - 0.1 * (1.0 - (-1.0f64).exp())).abs() < 1e-12);
        assert!((z(1e7) - 1810.1).abs() < 1e-9);
    }
}
