//! Nominal forward kinematics of the offset-wrist family as one closed formula, the S/T bits
//! of an axis set, and the distance of an axis set to each of the three singularities.
//!
//! The formula is the ortho-parallel-basis form of Brandstötter, Angerer & Hofbaur, "An
//! analytical solution of the inverse kinematics problem of industrial serial manipulators with
//! an ortho-parallel basis and a spherical wrist" (Austrian Robotics Workshop 2014, eqs. 1–4),
//! written in the paper frames of MODEL.md (all frames equal to the base at HOME, model angles
//! θ_n = sense_n·A_n + offset_n): the wrist point is the A1 rotation of a planar two-link arm,
//! `C = Rz(θ1)·[(l1x, 0, l1z) + Ry(θ2)·(0, 0, l2) + Ry(θ2+θ3)·(l4x, 0, l3z)]`, the wrist
//! orientation `R06 = Rz(θ1)·Ry(θ2+θ3)·Rx(θ4)·Ry(θ5)·Rx(θ6)`, the flange
//! `(R06·Ry(90°), C + l5x·R06·x̂)`. It shares no code with the error model's chain
//! (`model::chain`), so the two check each other.

use nalgebra::{Matrix3, Vector3};

use super::Frame;

use super::robot::{Links, RobotDescription};
use super::trig::sin_cos;

/// What the closed forms need of a robot, in radians and mm.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Geometry {
    pub links: Links,
    /// Distance A3 axis → wrist point, `hypot(l3z, l4x)`.
    pub k: f64,
    pub senses: [f64; 6],
    pub offsets: [f64; 6],
}

impl Geometry {
    #[inline]
    pub fn new(robot: &RobotDescription) -> Geometry {
        let l = robot.links;
        Geometry {
            links: l,
            k: (l.l3z * l.l3z + l.l4x * l.l4x).sqrt(),
            senses: robot.senses,
            offsets: robot.offsets_deg.map(f64::to_radians),
        }
    }

    /// Model angle θ_n (rad) of KUKA angle `a` (deg) of axis index `i`.
    #[inline]
    pub fn theta(&self, i: usize, a_deg: f64) -> f64 {
        self.senses[i] * a_deg.to_radians() + self.offsets[i]
    }

    /// KUKA angle (deg) of model angle `theta` (rad); senses are ±1.
    #[inline]
    pub fn kuka(&self, i: usize, theta: f64) -> f64 {
        (self.senses[i] * (theta - self.offsets[i])).to_degrees()
    }

    /// The elbow angle `e = θ3 + ψ`, ψ = atan2(l4x, l3z): zero with the arm stretched (wrist
    /// point on the line A2–A3), ±180° folded.
    #[inline]
    pub fn elbow(&self, theta3: f64) -> f64 {
        theta3 + self.psi()
    }

    /// ψ = atan2(l4x, l3z), remembered per thread for the last robot asked about: the
    /// library `atan2` of two constants cost as much as the rest of `status_turn`, which the
    /// walk calls for every path target.
    #[inline]
    pub fn psi(&self) -> f64 {
        use std::cell::Cell;
        thread_local! {
            static LAST: Cell<(u64, u64, f64)> = const { Cell::new((u64::MAX, u64::MAX, f64::NAN)) };
        }
        let (y, x) = (self.links.l4x, self.links.l3z);
        let key = (y.to_bits(), x.to_bits());
        LAST.with(|last| {
            let (ky, kx, psi) = last.get();
            if (ky, kx) == key {
                return psi;
            }
            let psi = y.atan2(x);
            last.set((key.0, key.1, psi));
            psi
        })
    }
}

/// Planar arm coordinates of the wrist point in the A1 frame: (x', z'), and the angle θ2+θ3.
#[inline]
pub(crate) fn arm_plane(g: &Geometry, t2: f64, t3: f64) -> (f64, f64, f64, f64) {
    let (x, z, s23, c23, _) = arm_plane_sc(g, t2, t3);
    (x, z, s23, c23)
}

/// [`arm_plane`] with `(sin θ2, cos θ2)` as well (the rate solver needs them too).
#[inline]
fn arm_plane_sc(g: &Geometry, t2: f64, t3: f64) -> (f64, f64, f64, f64, (f64, f64)) {
    let (s2, c2) = sin_cos(t2);
    let (s23, c23) = sin_cos(t2 + t3);
    let x = g.links.l1x + g.links.l2 * s2 + g.links.l4x * c23 + g.links.l3z * s23;
    let z = g.links.l1z + g.links.l2 * c2 - g.links.l4x * s23 + g.links.l3z * c23;
    (x, z, s23, c23, (s2, c2))
}

/// The nominal arm's frames at one axis set, the steps of its forward kinematics that
/// [`flange_frame`] and the rate solver (`rates::ArmState`) share.
pub(crate) struct ArmFrames {
    pub s1: f64,
    pub c1: f64,
    /// sin/cos θ2 (the A3 axis's position).
    pub s2: f64,
    pub c2: f64,
    /// sin/cos θ4 (A5's axis turns with it).
    pub s4: f64,
    pub c4: f64,
    /// The wrist point (on A4, A5 and A6).
    pub wrist: Vector3<f64>,
    /// R03 = Rz(θ1)·Ry(θ2+θ3) and R06 = R03·Rx(θ4)·Ry(θ5)·Rx(θ6).
    pub r03: Matrix3<f64>,
    pub r06: Matrix3<f64>,
}

impl ArmFrames {
    pub fn new(g: &Geometry, axes_deg: &[f64; 6]) -> ArmFrames {
        let t: [f64; 6] = std::array::from_fn(|i| g.theta(i, axes_deg[i]));
        let (s1, c1) = sin_cos(t[0]);
        let (x, z, s23, c23, (s2, c2)) = arm_plane_sc(g, t[1], t[2]);
        let wrist = Vector3::new(c1 * x, s1 * x, z);
        let r03 = Matrix3::new(
            c1 * c23,
            -s1,
            c1 * s23,
            s1 * c23,
            c1,
            s1 * s23,
            -s23,
            0.0,
            c23,
        );
        // Rx(α)·Ry(β)·Rx(γ), α = θ4, β = θ5, γ = θ6.
        let (sa, ca) = sin_cos(t[3]);
        let (sb, cb) = sin_cos(t[4]);
        let (sg, cg) = sin_cos(t[5]);
        let wrist_rotation = Matrix3::new(
            cb,
            sb * sg,
            sb * cg,
            sa * sb,
            ca * cg - sa * cb * sg,
            -ca * sg - sa * cb * cg,
            -ca * sb,
            sa * cg + ca * cb * sg,
            -sa * sg + ca * cb * cg,
        );
        ArmFrames {
            s1,
            c1,
            s2,
            c2,
            s4: sa,
            c4: ca,
            wrist,
            r03,
            r06: r03 * wrist_rotation,
        }
    }

    /// The flange (rotation, position): R06·Ry(90°) — its Z is the A6 axis x̂, its X the A6
    /// frame's −ẑ — at the wrist point plus `l5x` along A6.
    pub fn flange(&self, g: &Geometry) -> (Matrix3<f64>, Vector3<f64>) {
        let approach = self.r06.column(0).into_owned();
        let flange = Matrix3::from_columns(&[
            -self.r06.column(2),
            self.r06.column(1).into_owned(),
            approach,
        ]);
        (flange, self.wrist + g.links.l5x * approach)
    }
}

/// The flange of `axes_deg` as (rotation, position) in the base frame (mm).
pub fn flange_frame(robot: &RobotDescription, axes_deg: &[f64; 6]) -> (Matrix3<f64>, Vector3<f64>) {
    let g = Geometry::new(robot);
    ArmFrames::new(&g, axes_deg).flange(&g)
}

/// The nominal flange frame of `axes_deg` (KUKA degrees) in the robot base frame.
pub fn forward(robot: &RobotDescription, axes_deg: &[f64; 6]) -> Frame {
    let (rotation, position) = flange_frame(robot, axes_deg);
    Frame { rotation, position }
}

/// The wrist point (intersection of A4, A5, A6) of `axes_deg`, base frame, mm.
#[cfg(any(test, feature = "internals"))]
pub fn wrist_point(robot: &RobotDescription, axes_deg: &[f64; 6]) -> Vector3<f64> {
    let g = Geometry::new(robot);
    let (s1, c1) = sin_cos(g.theta(0, axes_deg[0]));
    let (x, z, _, _) = arm_plane(&g, g.theta(1, axes_deg[1]), g.theta(2, axes_deg[2]));
    Vector3::new(c1 * x, s1 * x, z)
}

/// The KUKA status and turn of an axis set (MODEL.md): S bit 0 = wrist point behind the A1
/// axis (x < 0 in the A1 frame), bit 1 = A3 at or beyond the stretched position (A3 ≥ φ, φ =
/// atan2(l3z, l4x) on the KR 30 HA), bit 2 = A5 < 0; T bit i = axis i+1 negative.
pub fn status_turn(robot: &RobotDescription, axes_deg: &[f64; 6]) -> (u8, u8) {
    let g = Geometry::new(robot);
    let (x, _, _, _) = arm_plane(&g, g.theta(1, axes_deg[1]), g.theta(2, axes_deg[2]));
    // A3 − A3(stretched) = sense3·e.
    let elbow = g.senses[2] * g.elbow(g.theta(2, axes_deg[2]));
    let s = u8::from(x < 0.0) | u8::from(elbow >= 0.0) << 1 | u8::from(axes_deg[4] < 0.0) << 2;
    let t = axes_deg
        .iter()
        .enumerate()
        .fold(0u8, |t, (i, a)| t | u8::from(*a < 0.0) << i);
    (s, t)
}

/// The three singular configurations of the offset-wrist arm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SingularityKind {
    /// A5 = 0 (or ±180°): A4 and A6 are parallel, only their sum is defined. Degrees of A5.
    Wrist,
    /// Arm stretched (A3 = φ) or folded: the wrist point on the edge of the workspace.
    /// Degrees of A3.
    Elbow,
    /// The wrist point on the A1 axis ("overhead"): A1 undefined. Millimetres.
    Shoulder,
}

impl SingularityKind {
    pub fn unit(self) -> &'static str {
        match self {
            SingularityKind::Wrist | SingularityKind::Elbow => "deg",
            SingularityKind::Shoulder => "mm",
        }
    }
}

impl std::fmt::Display for SingularityKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SingularityKind::Wrist => "wrist singularity (A5 = 0, A4 and A6 parallel)",
            SingularityKind::Elbow => "elbow singularity (arm stretched, A3 = φ)",
            SingularityKind::Shoulder => "shoulder singularity (wrist point on the A1 axis)",
        })
    }
}

/// How far an axis set is from one singularity (`kind.unit()`: degrees or mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Singularity {
    pub kind: SingularityKind,
    pub distance: f64,
}

impl std::fmt::Display for Singularity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} at {:.4} {}",
            self.kind,
            self.distance,
            self.kind.unit()
        )
    }
}

/// Warning distances of [`singularity`]: closer than this, a small Cartesian change (such as
/// a compensation) can move A4/A6, A1 or A2/A3 a lot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SingularityThresholds {
    pub wrist_deg: f64,
    pub elbow_deg: f64,
    pub shoulder_mm: f64,
}

impl Default for SingularityThresholds {
    /// 1° of A5: an orientation change δ there turns A4 and A6 by about δ/sin(A5) ≈ 57·δ.
    /// 1° of elbow: the reach changes only as 1 − cos(e) there, so a radial move of δ needs
    /// an elbow move of about δ/(l2·K/|D|·sin e), some 40 times more than at 45°. 10 mm of
    /// wrist point radius: a 0.1 mm lateral move already turns A1 by 0.6°.
    fn default() -> Self {
        SingularityThresholds {
            wrist_deg: 1.0,
            elbow_deg: 1.0,
            shoulder_mm: 10.0,
        }
    }
}

/// The distance of `axes_deg` to each singularity: wrist (|A5| to the nearest multiple of
/// 180°), elbow (the elbow angle to stretched or folded), shoulder (wrist point to the A1 axis).
pub fn singularity_distances(robot: &RobotDescription, axes_deg: &[f64; 6]) -> [Singularity; 3] {
    let g = Geometry::new(robot);
    let to_half_turn = |rad: f64| {
        let d = rad.to_degrees().rem_euclid(180.0);
        d.min(180.0 - d)
    };
    let (x, _, _, _) = arm_plane(&g, g.theta(1, axes_deg[1]), g.theta(2, axes_deg[2]));
    [
        Singularity {
            kind: SingularityKind::Wrist,
            distance: to_half_turn(g.theta(4, axes_deg[4])),
        },
        Singularity {
            kind: SingularityKind::Elbow,
            distance: to_half_turn(g.elbow(g.theta(2, axes_deg[2]))),
        },
        Singularity {
            kind: SingularityKind::Shoulder,
            distance: x.abs(),
        },
    ]
}

/// The singularity `axes_deg` is near (default [`SingularityThresholds`]), the closest
/// relative to its threshold; `None` when clear of all three.
pub fn singularity(robot: &RobotDescription, axes_deg: &[f64; 6]) -> Option<Singularity> {
    singularity_with(robot, axes_deg, &SingularityThresholds::default())
}

/// [`singularity`] with chosen thresholds.
pub fn singularity_with(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    thresholds: &SingularityThresholds,
) -> Option<Singularity> {
    let limit = |k: SingularityKind| match k {
        SingularityKind::Wrist => thresholds.wrist_deg,
        SingularityKind::Elbow => thresholds.elbow_deg,
        SingularityKind::Shoulder => thresholds.shoulder_mm,
    };
    singularity_distances(robot, axes_deg)
        .into_iter()
        .filter(|s| s.distance < limit(s.kind))
        .min_by(|a, b| (a.distance / limit(a.kind)).total_cmp(&(b.distance / limit(b.kind))))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn home_by_hand() {
        // Upper arm up (850), forearm forward (820) 145 above A3, flange 170 further.
        let robot = RobotDescription::kr30ha();
        let home = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];
        let (r, p) = flange_frame(&robot, &home);
        assert!((p - Vector3::new(1340.0, 0.0, 1810.0)).norm() < 1e-12);
        assert!(
            (r.column(2) - Vector3::x()).norm() < 1e-15,
            "flange Z along +X"
        );
        assert!((r.column(0) + Vector3::z()).norm() < 1e-15, "flange X down");
        assert!((wrist_point(&robot, &home) - Vector3::new(1170.0, 0.0, 1810.0)).norm() < 1e-12);
    }

    #[test]
    fn stretched_elbow_is_at_phi() {
        let robot = RobotDescription::kr30ha();
        let phi = 145f64.atan2(820.0).to_degrees();
        assert!((phi - 10.028).abs() < 1e-3);
        let d = singularity_distances(&robot, &[0.0, -30.0, phi + 0.25, 0.0, 10.0, 0.0]);
        assert!((d[1].distance - 0.25).abs() < 1e-9);
        assert_eq!(
            status_turn(&robot, &[0.0, -30.0, phi + 1e-9, 0.0, 0.0, 0.0]).0,
            2
        );
        assert_eq!(
            status_turn(&robot, &[0.0, -30.0, phi - 1e-9, 0.0, 0.0, 0.0]).0,
            0
        );
    }
}
