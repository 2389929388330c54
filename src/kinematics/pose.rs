//! KUKA poses and axis sets as plain numbers: a FRAME/POS (X, Y, Z in mm; A, B, C in degrees
//! with R = Rz(A)·Ry(B)·Rx(C)) and its rigid transform, the KRL geometric operator `:`
//! (`a : b` is the transform product a·b), the inverse frame, and E6POS/E6AXIS-style records
//! that carry S/T and the external axes beside the six robot axes.

use nalgebra::{Matrix3, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::trig::sin_cos;
use super::Frame;

/// Below this `cos B` the orientation is taken as B = ±90° exactly, where only A − C (B = +90°)
/// or A + C (B = −90°) is defined; MODEL.md's convention then puts everything in A (C = 0).
/// 1e-10 rad of B is far below any printed KRL digit and below 1e-6 mm over 10 m.
const GIMBAL_COS_B: f64 = 1e-10;

/// A KUKA FRAME (or the geometric part of a POS/E6POS): X, Y, Z in mm and A, B, C in
/// degrees, R = Rz(A)·Ry(B)·Rx(C).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// X, mm.
    pub x: f64,
    /// Y, mm.
    pub y: f64,
    /// Z, mm.
    pub z: f64,
    /// A: rotation about Z, degrees.
    pub a: f64,
    /// B: rotation about the new Y, degrees.
    pub b: f64,
    /// C: rotation about the newest X, degrees.
    pub c: f64,
}

impl Pose {
    /// No rotation, at the origin.
    pub const IDENTITY: Pose = Pose {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        a: 0.0,
        b: 0.0,
        c: 0.0,
    };

    /// From `[X, Y, Z, A, B, C]`.
    pub fn from_array(v: [f64; 6]) -> Pose {
        Pose {
            x: v[0],
            y: v[1],
            z: v[2],
            a: v[3],
            b: v[4],
            c: v[5],
        }
    }

    /// `[X, Y, Z, A, B, C]`.
    pub fn to_array(&self) -> [f64; 6] {
        [self.x, self.y, self.z, self.a, self.b, self.c]
    }

    /// `[A, B, C]`, degrees.
    pub fn abc(&self) -> [f64; 3] {
        [self.a, self.b, self.c]
    }

    /// R = Rz(A)·Ry(B)·Rx(C) (KUKA's ZYX Euler angles, degrees).
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        abc_to_matrix(self.a, self.b, self.c)
    }

    /// From a rotation matrix and a translation: B in [−90°, 90°], A and C in (−180°, 180°];
    /// at B = ±90° C = 0 (MODEL.md). A [`Frame`]'s is [`Frame::to_pose`].
    pub fn from_parts(r: &Matrix3<f64>, p: &Vector3<f64>) -> Pose {
        let [a, b, c] = matrix_to_abc(r);
        Pose {
            x: p.x,
            y: p.y,
            z: p.z,
            a,
            b,
            c,
        }
    }

    /// X, Y, Z as a vector, mm.
    pub fn position(&self) -> Vector3<f64> {
        Vector3::new(self.x, self.y, self.z)
    }

    /// The KRL geometric operator `self : rhs` (first `self`, then `rhs` in `self`'s frame).
    pub fn compose(&self, rhs: &Pose) -> Pose {
        Frame::from_kuka(self)
            .compose(&Frame::from_kuka(rhs))
            .to_pose()
    }

    /// The inverse frame (KRL `INV_POS`): `p.inverse().compose(&p)` is the identity.
    pub fn inverse(&self) -> Pose {
        Frame::from_kuka(self).inverse().to_pose()
    }
}

/// `a * b` is the KRL `a : b`.
impl std::ops::Mul for Pose {
    type Output = Pose;
    fn mul(self, rhs: Pose) -> Pose {
        self.compose(&rhs)
    }
}

/// Rz(A)·Ry(B)·Rx(C), angles in degrees, written out.
pub fn abc_to_matrix(a: f64, b: f64, c: f64) -> Matrix3<f64> {
    let (sa, ca) = sin_cos(a.to_radians());
    let (sb, cb) = sin_cos(b.to_radians());
    let (sc, cc) = sin_cos(c.to_radians());
    Matrix3::new(
        ca * cb,
        ca * sb * sc - sa * cc,
        ca * sb * cc + sa * sc,
        sa * cb,
        sa * sb * sc + ca * cc,
        sa * sb * cc - ca * sc,
        -sb,
        cb * sc,
        cb * cc,
    )
}

/// The inverse of [`abc_to_matrix`] (degrees), with C = 0 at B = ±90°.
pub fn matrix_to_abc(r: &Matrix3<f64>) -> [f64; 3] {
    // Direction cosines: no overflow or underflow for `hypot`'s care to guard against.
    let cb = (r[(0, 0)] * r[(0, 0)] + r[(1, 0)] * r[(1, 0)]).sqrt();
    let b = (-r[(2, 0)]).atan2(cb);
    if cb < GIMBAL_COS_B {
        // B = +90°: R = Rz(A − C)·Ry(90°), r01 = −sin(A − C), r11 = cos(A − C);
        // B = −90°: R = Rz(A + C)·Ry(−90°), same entries. With C = 0 both give A.
        let b = if r[(2, 0)] < 0.0 { 90.0 } else { -90.0 };
        let a = (-r[(0, 1)]).atan2(r[(1, 1)]).to_degrees();
        return [tidy(a), b, 0.0];
    }
    let a = r[(1, 0)].atan2(r[(0, 0)]).to_degrees();
    let c = r[(2, 1)].atan2(r[(2, 2)]).to_degrees();
    [tidy(a), tidy(b.to_degrees()), tidy(c)]
}

/// Maps −180° to 180° and −0 to 0 so that printed angles are canonical.
fn tidy(angle: f64) -> f64 {
    if angle == -180.0 {
        180.0
    } else {
        angle + 0.0
    }
}

/// The angles of the six robot axes A1..A6, degrees: what the controller commands and an
/// axis target programs, never a pose's X, Y, Z, A, B, C. It dereferences to the `[f64; 6]`
/// the numeric code works on (index it, pass `&axes` where `&[f64; 6]` is taken), so the type
/// costs nothing in a loop; convert with `From` at a module's edge.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(transparent)]
pub struct AxisAngles(pub [f64; 6]);

impl std::ops::Deref for AxisAngles {
    type Target = [f64; 6];
    fn deref(&self) -> &[f64; 6] {
        &self.0
    }
}

impl std::ops::DerefMut for AxisAngles {
    fn deref_mut(&mut self) -> &mut [f64; 6] {
        &mut self.0
    }
}

impl From<[f64; 6]> for AxisAngles {
    fn from(deg: [f64; 6]) -> AxisAngles {
        AxisAngles(deg)
    }
}

impl From<AxisAngles> for [f64; 6] {
    fn from(axes: AxisAngles) -> [f64; 6] {
        axes.0
    }
}

impl PartialEq<[f64; 6]> for AxisAngles {
    fn eq(&self, other: &[f64; 6]) -> bool {
        self.0 == *other
    }
}

impl PartialEq<AxisAngles> for [f64; 6] {
    fn eq(&self, other: &AxisAngles) -> bool {
        *self == other.0
    }
}

/// An E6POS: a pose with the optional status and turn bits and the external axes E1..E6.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg(any(test, feature = "internals"))]
pub struct E6Pos {
    pub pose: Pose,
    pub s: Option<u8>,
    pub t: Option<u8>,
    /// External axes E1..E6 (mm or degrees, as configured), carried unchanged by the
    /// kinematics of the six robot axes.
    pub external: [f64; 6],
}

/// An E6AXIS: the robot axes A1..A6 and the external axes E1..E6, degrees (or mm).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg(any(test, feature = "internals"))]
pub struct E6Axis {
    pub axes_deg: AxisAngles,
    pub external: [f64; 6],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elementary_rotations_by_hand() {
        // A = 90°: x → y. B = 90°: x → −z. C = 90°: y → z.
        let close = |m: Matrix3<f64>, v: Vector3<f64>, w: Vector3<f64>| (m * v - w).norm() < 1e-15;
        assert!(close(
            abc_to_matrix(90.0, 0.0, 0.0),
            Vector3::x(),
            Vector3::y()
        ));
        assert!(close(
            abc_to_matrix(0.0, 90.0, 0.0),
            Vector3::x(),
            -Vector3::z()
        ));
        assert!(close(
            abc_to_matrix(0.0, 0.0, 90.0),
            Vector3::y(),
            Vector3::z()
        ));
    }

    #[test]
    fn gimbal_lock_puts_everything_in_a() {
        // Rz(30)·Ry(90)·Rx(10) = Rz(20)·Ry(90).
        let r = abc_to_matrix(30.0, 90.0, 10.0);
        let [a, b, c] = matrix_to_abc(&r);
        assert!(
            (a - 20.0).abs() < 1e-9 && b == 90.0 && c == 0.0,
            "{a} {b} {c}"
        );
        // Rz(30)·Ry(−90)·Rx(10) = Rz(40)·Ry(−90).
        let [a, b, c] = matrix_to_abc(&abc_to_matrix(30.0, -90.0, 10.0));
        assert!(
            (a - 40.0).abs() < 1e-9 && b == -90.0 && c == 0.0,
            "{a} {b} {c}"
        );
    }

    #[test]
    fn minus_180_and_minus_zero_print_canonically() {
        let [a, _, c] = matrix_to_abc(&abc_to_matrix(-180.0, 0.0, -0.0));
        assert_eq!((a, c), (180.0, 0.0));
        assert!(c.is_sign_positive());
    }
}
