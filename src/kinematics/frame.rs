//! The crate's rigid transform: a rotation matrix and a position, `x ↦ rotation · x +
//! position` (mm). Forward kinematics gives one, inverse kinematics takes one, the error model
//! gives the flange as one, and motion composes them in its inner loops (a matrix product is
//! cheaper than a quaternion's, and nothing is converted on the way). A KUKA record
//! (X, Y, Z, A, B, C) is a [`Pose`], converted at the edges ([`Frame::from_kuka`],
//! [`Frame::to_pose`]); nalgebra's `Isometry3` only where its algebra is wanted
//! ([`Frame::to_isometry`]).

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::pose::{abc_to_matrix, Pose};

/// A rigid frame: `x ↦ rotation · x + position`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The rotation.
    pub rotation: Matrix3<f64>,
    /// The position, mm.
    pub position: Vector3<f64>,
}

impl Frame {
    /// The identity: no rotation, at the origin.
    pub fn identity() -> Frame {
        Frame {
            rotation: Matrix3::identity(),
            position: Vector3::zeros(),
        }
    }

    /// A KUKA frame: X, Y, Z in mm, R = Rz(A)·Ry(B)·Rx(C) in degrees.
    pub fn from_kuka(pose: &Pose) -> Frame {
        Frame {
            rotation: abc_to_matrix(pose.a, pose.b, pose.c),
            position: Vector3::new(pose.x, pose.y, pose.z),
        }
    }

    /// The KUKA record of this frame: B in [−90°, 90°], A and C in (−180°, 180°], C = 0 at
    /// B = ±90° (MODEL.md); `motion::frame` writes one near given angles instead.
    pub fn to_pose(&self) -> Pose {
        Pose::from_parts(&self.rotation, &self.position)
    }

    /// The frame of nalgebra's isometry.
    pub fn from_isometry(iso: &Isometry3<f64>) -> Frame {
        Frame {
            rotation: *iso.rotation.to_rotation_matrix().matrix(),
            position: iso.translation.vector,
        }
    }

    /// The same transform as nalgebra's, for its algebra. The unit quaternion by the direct
    /// (Shepperd) conversion, the matrix being orthonormal to rounding: nalgebra's
    /// `UnitQuaternion::from_matrix` iterates from the identity and stays there for a rotation
    /// by a half turn (a flange pointing down with A ≈ 180°: its torque vanishes), whichever
    /// last bits the matrix has.
    pub fn to_isometry(&self) -> Isometry3<f64> {
        let q =
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(self.rotation));
        Isometry3::from_parts(Translation3::from(self.position), q)
    }

    /// `self · other`.
    pub fn compose(&self, other: &Frame) -> Frame {
        Frame {
            rotation: self.rotation * other.rotation,
            position: self.position + self.rotation * other.position,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Frame {
        let rt = self.rotation.transpose();
        Frame {
            rotation: rt,
            position: -(rt * self.position),
        }
    }

    /// The point `p` (this frame's coordinates) in the outer frame.
    pub fn transform_point(&self, p: &Point3<f64>) -> Point3<f64> {
        Point3::from(self.rotation * p.coords + self.position)
    }
}

/// `a * b` is `a.compose(&b)`.
impl std::ops::Mul for Frame {
    type Output = Frame;
    fn mul(self, rhs: Frame) -> Frame {
        self.compose(&rhs)
    }
}

/// `f * p` is `f.transform_point(&p)`.
impl std::ops::Mul<Point3<f64>> for Frame {
    type Output = Point3<f64>;
    fn mul(self, p: Point3<f64>) -> Point3<f64> {
        self.transform_point(&p)
    }
}
