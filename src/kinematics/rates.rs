//! Axis rates from a tool twist: the axis velocities that move a point rigid with the flange
//! at velocity `v` while the flange turns at angular velocity `ω`, on the nominal arm of
//! `fk.rs`. The Jacobian's column n is `[ω_n × (p − o_n); ω_n]` (ω_n the world axis of a
//! positive KUKA degree of axis n, o_n a point on it); the three wrist axes meet at the wrist
//! point C, so the 6×6 system splits into two 3×3 ones (kinematic decoupling, Siciliano et al.,
//! *Robotics*, 2009, §3.5): the arm axes alone move C, `Σₙ₌₁³ ω_n × (C − o_n)·q̇_n = v − ω × (p − C)`,
//! and the wrist axes make up the rest of the turn, `Σₙ₌₄⁶ ω_n·q̇_n = ω − Σₙ₌₁³ ω_n·q̇_n`. Each is
//! solved by Cramer's rule: a few dozen products, where a pivoted LU of the 6×6 Jacobian costs
//! a chain of six divisions and the frames of the general error-model chain.

use nalgebra::{Matrix3, Vector3};

use super::fk::{ArmFrames, Geometry};
use super::robot::RobotDescription;

/// The nominal arm at one axis set: its flange and the lines of its axes, with the parts of
/// the two 3×3 systems that do not depend on the twist (a walk asks each state for two
/// rates: at the end of one segment and at the start of the next).
#[derive(Clone, Copy, Debug)]
pub struct ArmState {
    /// Flange rotation and position in the robot base frame (`fk::flange_frame`).
    pub flange_rotation: Matrix3<f64>,
    pub flange_position: Vector3<f64>,
    /// The wrist point (on A4, A5 and A6).
    wrist: Vector3<f64>,
    /// World direction of a positive KUKA degree of each arm axis (radians per degree).
    arm_axis: [Vector3<f64>; 3],
    /// The arm axes' system: ω_n × (C − o_n), o_n a point on axis n (n = 1..3).
    arm: Cramer,
    /// The wrist axes' system: ω_n (n = 4..6).
    wrist_axes: Cramer,
}

/// The columns of a 3×3 system with the parts of Cramer's rule that do not depend on the
/// right-hand side.
#[derive(Clone, Copy, Debug)]
struct Cramer {
    c: [Vector3<f64>; 3],
    /// c₁ × c₂ and the determinant c₀ · (c₁ × c₂).
    c12: Vector3<f64>,
    det: f64,
}

impl ArmState {
    pub fn new(robot: &RobotDescription, axes_deg: &[f64; 6]) -> ArmState {
        let g = Geometry::new(robot);
        let l = g.links;
        let f = ArmFrames::new(&g, axes_deg);
        let (flange_rotation, flange_position) = f.flange(&g);
        let (s1, c1) = (f.s1, f.c1);
        let (s2, c2) = (f.s2, f.c2);
        // Model axes: A1 about ẑ, A2 and A3 about Rz(θ1)·ŷ, A4 about R03·x̂, A5 about
        // R03·Rx(θ4)·ŷ, A6 about R06·x̂; a KUKA degree turns θ_n by sense_n·π/180.
        let per_degree =
            |n: usize, a: Vector3<f64>| a * (g.senses[n] * std::f64::consts::PI / 180.0);
        let shoulder = Vector3::new(-s1, c1, 0.0);
        let axis = [
            per_degree(0, Vector3::z()),
            per_degree(1, shoulder),
            per_degree(2, shoulder),
            per_degree(3, f.r03.column(0).into_owned()),
            per_degree(4, f.r03.column(1) * f.c4 + f.r03.column(2) * f.s4),
            per_degree(5, f.r06.column(0).into_owned()),
        ];
        let a2 = Vector3::new(c1 * l.l1x, s1 * l.l1x, l.l1z);
        let a3 = a2 + Vector3::new(c1 * l.l2 * s2, s1 * l.l2 * s2, l.l2 * c2);
        let origin = [Vector3::zeros(), a2, a3];
        let wrist = f.wrist;
        ArmState {
            flange_rotation,
            flange_position,
            wrist,
            arm_axis: [axis[0], axis[1], axis[2]],
            arm: Cramer::new(std::array::from_fn(|n| axis[n].cross(&(wrist - origin[n])))),
            wrist_axes: Cramer::new([axis[3], axis[4], axis[5]]),
        }
    }

    /// Axis rates (degrees per unit of whatever `v` and `w` are per) that move point `p`
    /// (rigid with the flange, base frame) at `v` and turn the flange at `w` (rad); `None`
    /// where either 3×3 system is singular (a zero determinant).
    pub fn rates(&self, p: &Vector3<f64>, v: &Vector3<f64>, w: &Vector3<f64>) -> Option<[f64; 6]> {
        let at_wrist = v - w.cross(&(p - self.wrist));
        let [q1, q2, q3] = self.arm.solve(&at_wrist)?;
        let axis = &self.arm_axis;
        let rest = w - axis[0] * q1 - axis[1] * q2 - axis[2] * q3;
        let [q4, q5, q6] = self.wrist_axes.solve(&rest)?;
        Some([q1, q2, q3, q4, q5, q6])
    }
}

impl Cramer {
    fn new(c: [Vector3<f64>; 3]) -> Cramer {
        let c12 = c[1].cross(&c[2]);
        Cramer {
            c,
            c12,
            det: c[0].dot(&c12),
        }
    }

    /// `x` with `x₀·c₀ + x₁·c₁ + x₂·c₂ = b`, by Cramer's rule with triple products; `None`
    /// for a zero determinant.
    fn solve(&self, b: &Vector3<f64>) -> Option<[f64; 3]> {
        let (c, det) = (&self.c, self.det);
        if det == 0.0 {
            return None;
        }
        Some([
            b.dot(&self.c12) / det,
            c[0].dot(&b.cross(&c[2])) / det,
            c[0].dot(&c[1].cross(b)) / det,
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::flange_frame;

    fn robot() -> RobotDescription {
        RobotDescription::kr30ha()
    }

    /// The flange is `fk::flange_frame`'s, bit for bit (the same formula).
    #[test]
    fn flange_is_forward_kinematics() {
        for q in [
            [0.0, -90.0, 90.0, 0.0, 30.0, 0.0],
            [20.0, -70.0, 110.0, 15.0, 40.0, -30.0],
            [-135.0, -40.0, 60.0, -170.0, -95.0, 250.0],
        ] {
            let s = ArmState::new(&robot(), &q);
            let (r, p) = flange_frame(&robot(), &q);
            assert_eq!((s.flange_rotation, s.flange_position), (r, p));
        }
    }

    /// The rates as first written: both systems built and solved for each twist.
    fn rates_solved_whole(
        robot: &RobotDescription,
        q: &[f64; 6],
        p: &Vector3<f64>,
        v: &Vector3<f64>,
        w: &Vector3<f64>,
    ) -> Option<[f64; 6]> {
        let g = Geometry::new(robot);
        let l = g.links;
        let f = ArmFrames::new(&g, q);
        let (s1, c1, s2, c2) = (f.s1, f.c1, f.s2, f.c2);
        let per_degree =
            |n: usize, a: Vector3<f64>| a * (g.senses[n] * std::f64::consts::PI / 180.0);
        let shoulder = Vector3::new(-s1, c1, 0.0);
        let axis = [
            per_degree(0, Vector3::z()),
            per_degree(1, shoulder),
            per_degree(2, shoulder),
            per_degree(3, f.r03.column(0).into_owned()),
            per_degree(4, f.r03.column(1) * f.c4 + f.r03.column(2) * f.s4),
            per_degree(5, f.r06.column(0).into_owned()),
        ];
        let a2 = Vector3::new(c1 * l.l1x, s1 * l.l1x, l.l1z);
        let a3 = a2 + Vector3::new(c1 * l.l2 * s2, s1 * l.l2 * s2, l.l2 * c2);
        let origin = [Vector3::zeros(), a2, a3];
        let cramer = |c: &[Vector3<f64>; 3], b: &Vector3<f64>| {
            let c12 = c[1].cross(&c[2]);
            let det = c[0].dot(&c12);
            (det != 0.0).then(|| {
                [
                    b.dot(&c12) / det,
                    c[0].dot(&b.cross(&c[2])) / det,
                    c[0].dot(&c[1].cross(b)) / det,
                ]
            })
        };
        let at_wrist = v - w.cross(&(p - f.wrist));
        let arm: [Vector3<f64>; 3] = std::array::from_fn(|n| axis[n].cross(&(f.wrist - origin[n])));
        let [q1, q2, q3] = cramer(&arm, &at_wrist)?;
        let rest = w - axis[0] * q1 - axis[1] * q2 - axis[2] * q3;
        let [q4, q5, q6] = cramer(&[axis[3], axis[4], axis[5]], &rest)?;
        Some([q1, q2, q3, q4, q5, q6])
    }

    proptest::proptest! {
        /// The rates from the state's stored parts are the rates solved whole, to the bit, at
        /// any axes and twist (singular ones included: both give `None` there).
        #[test]
        fn stored_parts_give_the_rates_solved_whole(
            q in proptest::array::uniform6(-360.0f64..360.0),
            p in proptest::array::uniform3(-3000.0f64..3000.0),
            v in proptest::array::uniform3(-500.0f64..500.0),
            w in proptest::array::uniform3(-2.0f64..2.0),
            stretched_wrist in proptest::bool::weighted(0.2),
        ) {
            let r = robot();
            let mut q = q;
            // Now and then A5 = 0, where the wrist system is singular.
            if stretched_wrist {
                q[4] = 0.0;
            }
            let (p, v, w) = (Vector3::from(p), Vector3::from(v), Vector3::from(w));
            let bits = |x: Option<[f64; 6]>| x.map(|x| x.map(f64::to_bits));
            let s = ArmState::new(&r, &q);
            proptest::prop_assert_eq!(
                bits(s.rates(&p, &v, &w)),
                bits(rates_solved_whole(&r, &q, &p, &v, &w))
            );
        }
    }

    proptest::proptest! {
        /// The rates move the arm as asked: the flange point and rotation after a small step
        /// `h·q̇` (by forward kinematics, central differences) match `h·v` and `h·ω`.
        #[test]
        fn rates_reproduce_the_twist(
            q in proptest::array::uniform6(-150.0f64..150.0),
            lever in proptest::array::uniform3(-200.0f64..200.0),
            v in proptest::array::uniform3(-50.0f64..50.0),
            w in proptest::array::uniform3(-0.2f64..0.2),
        ) {
            let r = robot();
            let mut q = q;
            q[1] = q[1].clamp(-130.0, 30.0);
            q[2] = q[2].clamp(-110.0, 150.0);
            // Away from the singularities, where the rates are large and differences poor.
            proptest::prop_assume!(q[4].abs() > 10.0 && q[4].abs() < 170.0);
            let d = crate::kinematics::singularity_distances(&r, &q);
            proptest::prop_assume!(d.iter().all(|s| match s.kind {
                crate::kinematics::SingularityKind::Shoulder => s.distance > 100.0,
                _ => s.distance > 10.0,
            }));
            let s = ArmState::new(&r, &q);
            let lever = Vector3::from(lever);
            let p = s.flange_position + s.flange_rotation * lever;
            let (v, w) = (Vector3::from(v), Vector3::from(w));
            let rates = s.rates(&p, &v, &w).unwrap();
            let h = 1e-6;
            let at = |sign: f64| {
                let qh: [f64; 6] = std::array::from_fn(|i| q[i] + sign * h * rates[i]);
                flange_frame(&r, &qh)
            };
            let ((r1, p1), (r0, p0)) = (at(1.0), at(-1.0));
            let dp = (p1 + r1 * lever - (p0 + r0 * lever)) / (2.0 * h);
            let dr = r1 * r0.transpose();
            let dw = Vector3::new(dr[(2, 1)] - dr[(1, 2)], dr[(0, 2)] - dr[(2, 0)], dr[(1, 0)] - dr[(0, 1)])
                / (4.0 * h);
            let scale = 1.0 + rates.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            proptest::prop_assert!((dp - v).norm() < 1e-5 * scale, "{dp} vs {v}");
            proptest::prop_assert!((dw - w).norm() < 1e-8 * scale, "{dw} vs {w}");
        }
    }
}
