//! Pose arithmetic shared by motion simulation and compensation, on the crate's rigid
//! transform [`Frame`] (`kinematics::Frame`, re-exported here): pose errors as six-vectors
//! `[Δp (mm); Δr (rad)]` with the rotation error as the rotation vector of `R_actual · R_goalᵀ`
//! (a world-frame error, the frame in which the paper writes `p̂ − p*`), and its inverse, the
//! exponential; a frame written as KUKA X/Y/Z/A/B/C (a `kinematics::Pose`) near the numbers it
//! replaces (`to_kuka_near`), continuous near gimbal lock (`abc_continuous`).

use nalgebra::{Matrix3, Vector3, Vector6};

use crate::kinematics::{abc_to_matrix, matrix_to_abc, Pose};

pub use crate::kinematics::Frame;

/// Writing a frame near the numbers it replaces, and moving it by a pose error.
impl Frame {
    /// X, Y, Z, A, B, C of this frame, the angles chosen nearest to `near` (A, B, C of the
    /// value being replaced): of the two Euler triples of a rotation and their ±360° copies,
    /// the one a user would expect next to the original; at B = ±90° (where only A∓C is
    /// defined) C is kept.
    pub fn to_kuka_near(&self, near: &[f64; 3]) -> Pose {
        let [a, b, c] = abc_near(&self.rotation, near);
        self.kuka_with(a, b, c)
    }

    /// This frame's X, Y, Z with the angles A, B, C.
    fn kuka_with(&self, a: f64, b: f64, c: f64) -> Pose {
        let p = self.position;
        Pose {
            x: p.x,
            y: p.y,
            z: p.z,
            a,
            b,
            c,
        }
    }

    /// What [`Self::to_kuka_near`] chooses from, for any `near`: the position and the Euler
    /// triple of [`matrix_to_abc`]; `None` at gimbal lock, where the choice needs the matrix.
    /// Worked out once where a pose is written near two different references (the
    /// compensation's re-check near zero, the rewrite near the original numbers).
    pub fn to_kuka_unchosen(&self) -> Option<Pose> {
        let r = &self.rotation;
        if gimbal_locked(r) {
            return None;
        }
        let [a, b, c] = matrix_to_abc(r);
        Some(self.kuka_with(a, b, c))
    }

    /// The frame moved by the world-frame error `e` (`[Δp; Δr]`): position `p + Δp`,
    /// rotation `exp(Δr) · R`.
    pub fn moved_by(&self, e: &Vector6<f64>) -> Frame {
        Frame {
            rotation: exp_so3(&Vector3::new(e[3], e[4], e[5])) * self.rotation,
            position: self.position + Vector3::new(e[0], e[1], e[2]),
        }
    }
}

/// The nearest representation to `near` (see [`Frame::to_kuka_near`]).
pub fn abc_near(r: &Matrix3<f64>, near: &[f64; 3]) -> [f64; 3] {
    if gimbal_locked(r) {
        // Gimbal lock: keep C; R·Rx(C)ᵀ = Rz(A)·Ry(±90°) has r01 = −sin A, r11 = cos A.
        let b = if r[(2, 0)] < 0.0 { 90.0 } else { -90.0 };
        let c = near[2];
        let rc = r * abc_to_matrix(0.0, 0.0, c).transpose();
        let a = (-rc[(0, 1)]).atan2(rc[(1, 1)]).to_degrees();
        return [wrap(a, near[0]), b, c];
    }
    choose_abc(matrix_to_abc(r), near)
}

/// [`Frame::to_kuka_near`] of the frame whose [`Frame::to_kuka_unchosen`] is `unchosen`, to
/// the bit.
pub fn kuka_near(unchosen: &Pose, near: &[f64; 3]) -> Pose {
    let [a, b, c] = choose_abc(unchosen.abc(), near);
    Pose {
        a,
        b,
        c,
        ..*unchosen
    }
}

/// Whether `abc_near` must keep C (B = ±90° to 10⁻⁹).
fn gimbal_locked(r: &Matrix3<f64>) -> bool {
    let cb = (r[(0, 0)] * r[(0, 0)] + r[(1, 0)] * r[(1, 0)]).sqrt();
    cb < 1e-9
}

/// `x` moved by whole turns to within a half turn of `to`. Within a half turn already (nearly
/// always) the quotient `d/360` rounds to zero with the sign of `d`, so `x − 360·round(d/360)`
/// is `x − (±0)`, taken here without the division and the rounding, to the bit (a −0 `x`
/// included).
fn wrap(x: f64, to: f64) -> f64 {
    let d = x - to;
    if d.abs() < 180.0 {
        return x - 0.0f64.copysign(d);
    }
    x - 360.0 * (d / 360.0).round()
}

/// Of the two Euler triples of `[a, b, c]`'s rotation and their ±360° copies, the nearest to
/// `near`.
fn choose_abc([a, b, c]: [f64; 3], near: &[f64; 3]) -> [f64; 3] {
    let first = [wrap(a, near[0]), wrap(b, near[1]), wrap(c, near[2])];
    let second = [
        wrap(a + 180.0, near[0]),
        wrap(180.0 - b, near[1]),
        wrap(c + 180.0, near[2]),
    ];
    let dist = |t: &[f64; 3]| -> f64 { t.iter().zip(near).map(|(x, y)| (x - y).abs()).sum() };
    if dist(&second) < dist(&first) {
        second
    } else {
        first
    }
}

/// Within this many degrees of B = ±90° a written orientation is near gimbal lock.
const NEAR_LOCK_DEG: f64 = 3.0;
/// The Euler triple jumping by more than this (degrees, A or C) is not written there.
const JUMP_DEG: f64 = 1.0;

/// Whether the Euler triple `chosen` jumps from the written `near` near B = ±90°: where
/// [`abc_continuous`] looks for a continuous one (it needs the rotation only then).
pub fn abc_jumps(chosen: [f64; 3], near: &[f64; 3]) -> bool {
    if (near[1].abs() - 90.0).abs() > NEAR_LOCK_DEG {
        return false;
    }
    let jump = (chosen[0] - near[0]).abs().max((chosen[2] - near[2]).abs());
    if jump <= JUMP_DEG {
        return false;
    }
    true
}

/// Near B = ±90° (gimbal lock) the Euler triple of a rotation a hundredth of a degree away
/// from the written one can be tens of degrees from it in A and C (`A 0, B 90, C 0` →
/// `A -37.3, B 89.988, C -37.3`): exact, but not what the program wrote. There the angles
/// cannot express one direction of rotation (about the axis A and C both turn about at
/// B = ±90°) with small changes. Where the exact triple `chosen` jumps by more than a degree
/// from the written `near` (B within 3° of ±90°), this gives the triple nearest `near` that
/// turns by as much of the rotation as small changes of A, B and C can (damped least squares
/// from `near`), and the rotation left out (rad). `None`: `chosen` is continuous, keep it.
pub fn abc_continuous(
    rotation: &Matrix3<f64>,
    chosen: [f64; 3],
    near: &[f64; 3],
) -> Option<([f64; 3], f64)> {
    if !abc_jumps(chosen, near) {
        return None;
    }
    // Damping in rad per rad: directions the angles turn about by more than it are solved
    // exactly; the one they cannot reach near the lock is left.
    const LAMBDA: f64 = 0.02;
    let mut abc = Vector3::new(near[0], near[1], near[2]).map(f64::to_radians);
    let start = abc;
    for _ in 0..6 {
        let r = abc_to_matrix(
            abc[0].to_degrees(),
            abc[1].to_degrees(),
            abc[2].to_degrees(),
        );
        // World rotation still needed: from the current triple to the target.
        let w = log_so3(&(rotation * r.transpose()));
        // World angular velocity per radian of A, B, C (R = Rz(A)·Ry(B)·Rx(C)).
        let (sa, ca) = abc[0].sin_cos();
        let (sb, cb) = abc[1].sin_cos();
        let j = Matrix3::from_columns(&[
            Vector3::z(),
            Vector3::new(-sa, ca, 0.0),
            Vector3::new(ca * cb, sa * cb, -sb),
        ]);
        // Minimise |J·d − w|² + λ²|abc + d − start|².
        let lhs = j.transpose() * j + Matrix3::identity() * LAMBDA * LAMBDA;
        let rhs = j.transpose() * w - (abc - start) * LAMBDA * LAMBDA;
        let d = lhs.lu().solve(&rhs)?;
        abc += d;
        if d.norm() < 1e-15 {
            break;
        }
    }
    let abc = abc.map(f64::to_degrees);
    let r = abc_to_matrix(abc[0], abc[1], abc[2]);
    let left = log_so3(&(rotation * r.transpose())).norm();
    Some(([abc[0], abc[1], abc[2]], left))
}

/// `actual − goal` as a world-frame six-vector: `[p_a − p_g; log(R_a · R_gᵀ)]`.
pub fn error(actual: &Frame, goal: &Frame) -> Vector6<f64> {
    let dp = actual.position - goal.position;
    let dr = log_so3(&(actual.rotation * goal.rotation.transpose()));
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// Position (mm) and rotation (rad) norms of a pose error.
pub fn norms(e: &Vector6<f64>) -> (f64, f64) {
    (
        (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt(),
        (e[3] * e[3] + e[4] * e[4] + e[5] * e[5]).sqrt(),
    )
}

/// Whether rotations `a` and `b` are a half turn apart (to 10⁻⁶ rad, 0.00006°): the
/// interpolation between them may turn either way, and which way follows from the last bits
/// of the numbers. The angle θ of `aᵀb` from its trace, `tr = Σ aᵢⱼ·bᵢⱼ = 1 + 2 cos θ`, and
/// `1 + cos θ ≈ (π − θ)²/2`: nine products, no inverse trigonometry, on every straight
/// segment of a program.
pub fn half_turn_apart(a: &Matrix3<f64>, b: &Matrix3<f64>) -> bool {
    const HALF_DELTA_SQUARED: f64 = 0.5 * 1e-6 * 1e-6;
    let trace = a.component_mul(b).sum();
    1.0 + 0.5 * (trace - 1.0) < HALF_DELTA_SQUARED
}

/// The rotation vector of `r`. Uses `atan2(|v|, (tr − 1)/2)` with `v` the axial vector of the
/// skew part, exact for the micro-radian angles of compensation where `acos` of the trace
/// loses half the digits.
pub fn log_so3(r: &Matrix3<f64>) -> Vector3<f64> {
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    ) * 0.5;
    let c = (r.trace() - 1.0) * 0.5;
    let ss = v.norm_squared();
    if ss < 1e-6 * c * c && c > 0.0 {
        // Small angle (every pose error of a solve): angle/s = atan(t)/(t·c), t = s/c below
        // 10⁻³, whose series `t − t³/3 + t⁵/5 − t⁷/7` leaves out less than t⁹/9 < 10⁻²⁷·t:
        // no square root, no library atan2, one division.
        let inv_c = 1.0 / c;
        let t2 = ss * inv_c * inv_c;
        return v * (inv_c * (1.0 - t2 * (1.0 / 3.0 - t2 * (0.2 - t2 * (1.0 / 7.0)))));
    }
    if ss < 1e-2 * c * c && c > 0.0 {
        // Up to t = 0.1 (5.7°, the turn between two targets of a path): the series to t¹⁵
        // leaves out less than t¹⁷/17 < 10⁻¹⁷·t, below the rounding.
        let inv_c = 1.0 / c;
        let t2 = ss * inv_c * inv_c;
        let series = 1.0
            - t2 * (1.0 / 3.0
                - t2 * (1.0 / 5.0
                    - t2 * (1.0 / 7.0
                        - t2 * (1.0 / 9.0
                            - t2 * (1.0 / 11.0 - t2 * (1.0 / 13.0 - t2 * (1.0 / 15.0)))))));
        return v * (inv_c * series);
    }
    let s = ss.sqrt();
    if s < 1e-300 {
        if c > 0.0 {
            return Vector3::zeros();
        }
        // Half-turn: axis from the symmetric part.
        let b = (r + Matrix3::identity()) * 0.5;
        let i = (0..3)
            .max_by(|&i, &j| b[(i, i)].total_cmp(&b[(j, j)]))
            .unwrap_or(0);
        let axis = b.column(i) / b[(i, i)].max(1e-300).sqrt();
        return axis.normalize() * std::f64::consts::PI;
    }
    v * (s.atan2(c) / s)
}

/// Rodrigues' formula: the rotation by `w` (rad).
pub fn exp_so3(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = w.norm_squared();
    let (a, b) = if theta2 < 1e-12 {
        // sin θ/θ and (1 − cos θ)/θ² to well below an ulp at θ < 1e-6.
        (1.0 - theta2 / 6.0, 0.5 - theta2 / 24.0)
    } else {
        let theta = theta2.sqrt();
        (theta.sin() / theta, (1.0 - theta.cos()) / theta2)
    };
    let k = w.cross_matrix();
    Matrix3::identity() + k * a + k * k * b
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Rotation3};

    /// Half turns recognised against angles built by hand: a rotation about any axis by π, by
    /// π less 10⁻⁷ rad (within) and less 10⁻⁵ rad (not); the orientation change of HEAD's pose
    /// in the compensate tests (`A 180, B 10, C 180` to `A 0, B 0, C 180`), whose angle
    /// `log_so3` gives as π.
    #[test]
    fn half_turns_apart() {
        let a = Frame::from_kuka(&Pose::from_array([0.0, 0.0, 0.0, 30.0, -20.0, 75.0])).rotation;
        let axis = nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8));
        let turned =
            |angle: f64| a * nalgebra::Rotation3::from_axis_angle(&axis, angle).into_inner();
        let pi = std::f64::consts::PI;
        assert!(half_turn_apart(&a, &turned(pi)));
        assert!(half_turn_apart(&a, &turned(pi - 1e-7)));
        assert!(!half_turn_apart(&a, &turned(pi - 1e-5)));
        assert!(!half_turn_apart(&a, &turned(0.5)));
        assert!(!half_turn_apart(&a, &a));
        let start =
            Frame::from_kuka(&Pose::from_array([0.0, 0.0, 0.0, 180.0, 10.0, 180.0])).rotation;
        let goal = Frame::from_kuka(&Pose::from_array([0.0, 0.0, 0.0, 0.0, 0.0, 180.0])).rotation;
        assert!((log_so3(&(goal * start.transpose())).norm() - pi).abs() < 1e-7);
        assert!(half_turn_apart(&start, &goal));
    }
    use approx::assert_relative_eq;

    #[test]
    fn log_exp_round_trip_small_and_large() {
        for w in [
            Vector3::new(1e-9, -2e-9, 3e-9),
            Vector3::new(0.3, -0.2, 0.1),
            Vector3::new(0.0, 3.0, 0.0),
        ] {
            let r = exp_so3(&w);
            assert_relative_eq!(log_so3(&r), w, epsilon = 1e-15, max_relative = 1e-12);
            // Against nalgebra's own exponential.
            let r2 = Rotation3::from_scaled_axis(w);
            assert_relative_eq!(r, *r2.matrix(), epsilon = 1e-15);
        }
    }

    #[test]
    fn kuka_angles_nearest_the_original() {
        for (abc, near) in [
            ([10.0, 20.0, 30.0], [10.0, 20.0, 30.0]),
            ([180.0, 0.0, 180.0], [-180.0, 0.0, -180.0]),
            ([-179.9999, 45.0, 0.0], [180.0, 45.0, 0.0]),
            ([30.0, 90.0, 40.0], [30.0, 90.0, 40.0]),
            ([30.0, -90.0, -40.0], [30.0, -90.0, -40.0]),
            ([0.0, 0.0, 350.0], [0.0, 0.0, 350.0]),
        ] {
            let f = Frame::from_kuka(&Pose::from_array([1.0, 2.0, 3.0, abc[0], abc[1], abc[2]]));
            let out = f.to_kuka_near(&near);
            for (got, want) in out.abc().iter().zip(&near) {
                assert!((got - want).abs() < 1e-3, "{abc:?} → {out:?}");
            }
            let back = Frame::from_kuka(&out);
            assert_relative_eq!(back.rotation, f.rotation, epsilon = 1e-12);
        }
    }

    /// The shortcut of `wrap` within a half turn gives the formula's bits, signed zeros
    /// included.
    #[test]
    fn wrap_is_the_formula() {
        let formula = |x: f64, to: f64| x - 360.0 * ((x - to) / 360.0).round();
        let values = [
            0.0,
            -0.0,
            1e-300,
            -1e-300,
            5.0,
            -179.999,
            179.99999999999997,
            180.0,
            -180.0,
            359.5,
            -540.25,
            720.0,
            1e-9,
        ];
        for &x in &values {
            for &to in &values {
                assert_eq!(
                    wrap(x, to).to_bits(),
                    formula(x, to).to_bits(),
                    "{x} near {to}"
                );
            }
        }
    }

    /// The rewrite writes the re-check's unchosen pose near the original numbers: that must
    /// be the numbers `to_kuka_near` gives for the frame itself, to the bit, for any
    /// reference, and the gimbal lock (where C is kept) must be left to `to_kuka_near`.
    #[test]
    fn unchosen_pose_is_chosen_like_the_frame() {
        let nears = [
            [0.0, 0.0, 0.0],
            [179.0, -5.0, -179.0],
            [-170.0, 100.0, 10.0],
            [400.0, 0.0, -400.0],
        ];
        let mut checked = 0;
        for a in (-180..=180).step_by(45) {
            for b in [-90.0, -89.99, -60.0, 0.0, 45.5, 89.9999, 90.0] {
                for c in (-180..=180).step_by(60) {
                    let f = Frame::from_kuka(&Pose::from_array([
                        5.0,
                        -6.0,
                        7.0,
                        a as f64 + 0.3,
                        b,
                        c as f64,
                    ]));
                    match f.to_kuka_unchosen() {
                        Some(u) => {
                            for near in &nears {
                                let (x, y) = (kuka_near(&u, near), f.to_kuka_near(near));
                                let bits = |p: Pose| p.to_array().map(f64::to_bits);
                                assert_eq!(bits(x), bits(y));
                                checked += 1;
                            }
                        }
                        None => assert!(f64::abs(b) == 90.0, "locked at B = {b}"),
                    }
                }
            }
        }
        assert!(checked > 800);
    }

    #[test]
    fn small_rotation_vectors_match_the_atan2_formula() {
        // Both series: below 10⁻³ rad and up to 0.1 rad (and a little beyond, where the
        // library's atan2 takes over).
        for k in 0..6000 {
            let angle = match k {
                0..3000 => 1.2e-3 * (k as f64 / 3000.0).powi(3),
                _ => 1e-3 + 0.11 * ((k - 3000) as f64 / 3000.0).powi(2),
            };
            let axis = Vector3::new(0.3, -0.8, 0.5 + k as f64 * 1e-3).normalize();
            let r = exp_so3(&(axis * angle));
            let v = Vector3::new(
                r[(2, 1)] - r[(1, 2)],
                r[(0, 2)] - r[(2, 0)],
                r[(1, 0)] - r[(0, 1)],
            ) * 0.5;
            let (s, c) = (v.norm(), (r.trace() - 1.0) * 0.5);
            let reference = if s == 0.0 {
                Vector3::zeros()
            } else {
                v * (s.atan2(c) / s)
            };
            let ours = log_so3(&r);
            assert!(
                (ours - reference).norm() <= 4.0 * f64::EPSILON * angle,
                "{angle}"
            );
            assert!(
                (ours.norm() - angle).abs() <= 1e-15 + 1e-9 * angle,
                "{angle}"
            );
        }
    }

    #[test]
    fn error_of_moved_frame_is_the_move() {
        let f = Frame::from_isometry(&Isometry3::new(
            Vector3::new(1000.0, -200.0, 800.0),
            Vector3::new(0.2, 1.0, -0.4),
        ));
        let e = Vector6::new(0.01, -0.02, 0.003, 1e-5, -3e-6, 2e-6);
        let g = f.moved_by(&e);
        assert_relative_eq!(error(&g, &f), e, epsilon = 1e-12);
        let back = f.compose(&f.inverse());
        assert_relative_eq!(back.rotation, Matrix3::identity(), epsilon = 1e-15);
        assert_relative_eq!(back.position, Vector3::zeros(), epsilon = 1e-12);
        assert_relative_eq!(
            Frame::from_isometry(&f.to_isometry()).rotation,
            f.rotation,
            epsilon = 1e-15
        );
    }
}
