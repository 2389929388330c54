//! The controller's interpolation between two targets, sampled to find how every axis arrives
//! at the end: PTP is linear in axis space (no axis can reverse inside it), LIN a straight
//! line with the orientation turning at a constant rate about a fixed axis (slerp), CIRC the
//! arc through the auxiliary point with the same orientation law, an `SPL` segment of a spline
//! block the cubic Hermite curve of [`super::spline`] with the same orientation law. A
//! Cartesian segment is
//! walked with local IK at a pitch fine enough for the axes to move nearly linearly between
//! samples (so that a reversal inside it shows as a sign change of the differences), the end
//! is checked against the controller's end axes (a mismatch means the path crosses a
//! singularity), and the arrival rate `dq/du` at the end is exact: `J⁻¹·ẋ(1)` with `ẋ` the
//! path's twist per unit of the segment parameter. An axis with no motion at the end (a
//! turning point right at the target) takes the sign of its last sampled motion; one that
//! does not move at all rests. An axis that turns round inside a segment has its last turning
//! point located (the command angle there): from a sample whose motion opposes the arrival,
//! refined by the parabola through the samples around it, or — between two samples or inside
//! a segment too short for samples — by the cubic through the ends and their exact rates. A
//! gear play's state on arrival depends on it (`model::history`).

use nalgebra::{Vector3, Vector6};

use super::frame::{self, exp_so3, Frame};
use super::nominal;
use crate::kinematics::RobotDescription;

/// An axis whose arrival rate is below this (degrees per segment) is at rest: it keeps its
/// direction. 10⁻⁴° is the resolution of the numbers a program is written with (1 µm and
/// 0.1 mdeg move an axis by about that much), far below any backlash: a motion the program
/// cannot even express does not decide which branch a gear sits on.
pub const REST_DEG: f64 = 1e-4;
/// An axis that moves by less than this (degrees) between two samples stands still there: the
/// rounding of axis angles computed through the kinematics.
const STILL_DEG: f64 = 1e-9;
/// Sample pitch of Cartesian paths: a sample every this many mm of TCP travel …
const PITCH_MM: f64 = 20.0;
/// … and every this many degrees of orientation change.
const PITCH_DEG: f64 = 5.0;
/// At most this many samples per segment.
const MAX_SAMPLES: usize = 2000;
/// The walked end may differ from the controller's end axes by this much (deg).
const END_MATCH_DEG: f64 = 1e-6;

/// The geometric path of one motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Path {
    /// Linear in axis space.
    Ptp,
    /// Straight line, orientation by slerp.
    Lin,
    /// Arc through the auxiliary TCP position (robot base frame), orientation by slerp.
    Circ { aux: Vector3<f64> },
}

/// Why a path could not be followed.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum PathError {
    #[error("the path cannot be followed near u = {at:.3}: {reason}")]
    Lost { at: f64, reason: &'static str },
    #[error("the path reaches the target with other axis angles than the controller's (A{axis} differs by {by_deg:.4}°): it crosses a singularity or changes configuration")]
    EndMismatch { axis: u8, by_deg: f64 },
    #[error("the auxiliary point lies on the line through start and end: no circle")]
    DegenerateCircle,
}

/// A TCP pose along a Cartesian path, `u ∈ [0, 1]`.
#[derive(Clone, Copy, Debug)]
pub struct Cartesian {
    start: Frame,
    /// World rotation vector from the start to the end orientation.
    omega: Vector3<f64>,
    shape: Shape,
}

#[derive(Clone, Copy, Debug)]
enum Shape {
    Line {
        from: Vector3<f64>,
        delta: Vector3<f64>,
    },
    Arc {
        centre: Vector3<f64>,
        axis: Vector3<f64>,
        radius0: Vector3<f64>,
        angle: f64,
    },
    /// Cubic Hermite from `from` to `to` with end derivatives `d0`, `d1` (per unit of `u`).
    Cubic {
        from: Vector3<f64>,
        to: Vector3<f64>,
        d0: Vector3<f64>,
        d1: Vector3<f64>,
        length: f64,
    },
}

impl Cartesian {
    pub fn new(start: &Frame, end: &Frame, path: &Path) -> Result<Cartesian, PathError> {
        let omega = frame::log_so3(&(end.rotation * start.rotation.transpose()));
        let shape = match path {
            Path::Ptp | Path::Lin => Shape::Line {
                from: start.position,
                delta: end.position - start.position,
            },
            Path::Circ { aux } => arc(&start.position, aux, &end.position)?,
        };
        Ok(Cartesian {
            start: *start,
            omega,
            shape,
        })
    }

    /// The cubic Hermite segment from `start` to `end` whose position leaves `start` along
    /// `t0` and reaches `end` along `t1` (derivatives per unit chord length, as
    /// [`super::spline::tangents`] gives them); orientation by slerp as for LIN.
    pub fn cubic(start: &Frame, end: &Frame, t0: &Vector3<f64>, t1: &Vector3<f64>) -> Cartesian {
        let omega = frame::log_so3(&(end.rotation * start.rotation.transpose()));
        let (from, to) = (start.position, end.position);
        let h = (to - from).norm();
        let (d0, d1) = (t0 * h, t1 * h);
        // Arc length from a 32-piece polyline: only the sample count depends on it.
        let mut length = 0.0;
        let mut prev = from;
        for j in 1..=32 {
            let p = hermite(&from, &to, &d0, &d1, j as f64 / 32.0);
            length += (p - prev).norm();
            prev = p;
        }
        Cartesian {
            start: *start,
            omega,
            shape: Shape::Cubic {
                from,
                to,
                d0,
                d1,
                length,
            },
        }
    }

    pub fn pose(&self, u: f64) -> Frame {
        let rotation = exp_so3(&(self.omega * u)) * self.start.rotation;
        let position = match self.shape {
            Shape::Line { from, delta } => from + delta * u,
            Shape::Arc {
                centre,
                axis,
                radius0,
                angle,
            } => centre + exp_so3(&(axis * (angle * u))) * radius0,
            Shape::Cubic {
                from, to, d0, d1, ..
            } => hermite(&from, &to, &d0, &d1, u),
        };
        Frame { rotation, position }
    }

    /// d(pose)/du at `u`: `[dp/du; ω]`.
    pub fn twist(&self, u: f64) -> Vector6<f64> {
        let v = match self.shape {
            Shape::Line { delta, .. } => delta,
            Shape::Arc {
                axis,
                radius0,
                angle,
                ..
            } => (axis * angle).cross(&(exp_so3(&(axis * (angle * u))) * radius0)),
            Shape::Cubic {
                from, to, d0, d1, ..
            } => {
                // d/du of the Hermite basis.
                let u2 = u * u;
                from * (6.0 * u2 - 6.0 * u)
                    + d0 * (3.0 * u2 - 4.0 * u + 1.0)
                    + to * (6.0 * u - 6.0 * u2)
                    + d1 * (3.0 * u2 - 2.0 * u)
            }
        };
        let w = self.omega;
        Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
    }

    /// The arc from the same start about the same centre turned by `angle_deg` (a circular
    /// motion with `CA`: it ends there, with the end orientation `rotation`); `None` for a line.
    pub fn with_arc_angle(
        &self,
        angle_deg: f64,
        rotation: &nalgebra::Matrix3<f64>,
    ) -> Option<Cartesian> {
        match self.shape {
            Shape::Line { .. } | Shape::Cubic { .. } => None,
            Shape::Arc {
                centre,
                axis,
                radius0,
                ..
            } => Some(Cartesian {
                start: self.start,
                omega: frame::log_so3(&(rotation * self.start.rotation.transpose())),
                shape: Shape::Arc {
                    centre,
                    axis,
                    radius0,
                    angle: angle_deg.to_radians(),
                },
            }),
        }
    }

    /// The axis and turn (rad, positive about the axis) of an arc; `None` for a line or a
    /// cubic.
    pub fn arc_turn(&self) -> Option<(Vector3<f64>, f64)> {
        match self.shape {
            Shape::Arc { axis, angle, .. } => Some((axis, angle)),
            _ => None,
        }
    }

    /// The path parameter at which an arc passes `point` (its angle from the start over the
    /// arc's angle); for a line, the projection onto it (for a cubic, onto its chord).
    pub fn fraction_at(&self, point: &Vector3<f64>) -> f64 {
        match self.shape {
            Shape::Cubic { from, to, .. } => {
                let delta = to - from;
                let l2 = delta.norm_squared();
                if l2 == 0.0 {
                    0.0
                } else {
                    (point - from).dot(&delta) / l2
                }
            }
            Shape::Line { from, delta } => {
                let l2 = delta.norm_squared();
                if l2 == 0.0 {
                    0.0
                } else {
                    (point - from).dot(&delta) / l2
                }
            }
            Shape::Arc {
                centre,
                axis,
                radius0,
                angle,
            } => {
                let r = point - centre;
                let mut a = axis.dot(&radius0.cross(&r)).atan2(radius0.dot(&r));
                if a < 0.0 {
                    a += 2.0 * std::f64::consts::PI;
                }
                a / angle
            }
        }
    }

    /// TCP travel (mm) and orientation change (deg).
    pub fn extent(&self) -> (f64, f64) {
        let length = match self.shape {
            Shape::Line { delta, .. } => delta.norm(),
            Shape::Arc { radius0, angle, .. } => radius0.norm() * angle.abs(),
            Shape::Cubic { length, .. } => length,
        };
        (length, self.omega.norm().to_degrees())
    }
}

/// The cubic Hermite interpolant at `u ∈ [0, 1]` (basis h₀₀ = 2u³−3u²+1, h₁₀ = u³−2u²+u,
/// h₀₁ = −2u³+3u², h₁₁ = u³−u²).
fn hermite(
    p0: &Vector3<f64>,
    p1: &Vector3<f64>,
    d0: &Vector3<f64>,
    d1: &Vector3<f64>,
    u: f64,
) -> Vector3<f64> {
    let (u2, u3) = (u * u, u * u * u);
    p0 * (2.0 * u3 - 3.0 * u2 + 1.0)
        + d0 * (u3 - 2.0 * u2 + u)
        + p1 * (3.0 * u2 - 2.0 * u3)
        + d1 * (u3 - u2)
}

/// The circle through `a`, `b`, `c` traversed a → b → c.
fn arc(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Result<Shape, PathError> {
    let ab = b - a;
    let ac = c - a;
    let n = ab.cross(&ac);
    let n2 = n.norm_squared();
    if n2 <= 1e-12 * ab.norm_squared() * ac.norm_squared() || n2 == 0.0 {
        return Err(PathError::DegenerateCircle);
    }
    let centre =
        a + (n.cross(&ab) * ac.norm_squared() + ac.cross(&n) * ab.norm_squared()) / (2.0 * n2);
    let axis = n / n2.sqrt();
    let r0 = a - centre;
    let r1 = c - centre;
    let mut angle = axis.dot(&r0.cross(&r1)).atan2(r0.dot(&r1));
    if angle <= 0.0 {
        angle += 2.0 * std::f64::consts::PI;
    }
    Ok(Shape::Arc {
        centre,
        axis,
        radius0: r0,
        angle,
    })
}

/// The circle a controller follows for `CIRC aux, target, CA angle` when its start and end
/// are given: the arc from `start` that turns by `angle_deg` about the unit `normal` (right
/// hand; a negative angle turns the other way) and ends exactly at `end`, orientation slerped
/// from the start's to the end's. `None` when no such circle exists: the chord vanishes or
/// the turn is a whole number of turns (a full circle fixes no radius).
///
/// With chord `c = E − S`, midpoint `M` and turn `θ`, the centre lies in the plane ⟂ `normal`
/// on the chord's bisector: `O = M + (n × c)·cot(θ/2)/2`, radius `|c| / (2|sin(θ/2)|)` (the
/// isosceles triangle S O E with apex angle θ; cot changes sign past θ = 180°, putting the
/// centre beyond the chord for the major arc, and with θ for the other sense).
pub fn arc_about(
    start: &Frame,
    end: &Frame,
    angle_deg: f64,
    normal: &Vector3<f64>,
) -> Option<Cartesian> {
    let theta = angle_deg.to_radians();
    let half = 0.5 * theta;
    let c = end.position - start.position;
    // Within 1e-9 of a whole turn the centre is at infinity (or undefined): no circle.
    if c.norm() < 1e-9 || half.sin().abs() < 1e-9 {
        return None;
    }
    let n = normal.normalize();
    // The chord must lie in the plane (it does when the normal was made from it).
    let c = c - n * n.dot(&c);
    let centre = start.position + 0.5 * c + n.cross(&c) * (0.5 * half.cos() / half.sin());
    Some(Cartesian {
        start: *start,
        omega: frame::log_so3(&(end.rotation * start.rotation.transpose())),
        shape: Shape::Arc {
            centre,
            axis: n,
            radius0: start.position - centre,
            angle: theta,
        },
    })
}

/// The normal of the plane through `start`, `aux` and `end` (positions), `sense` (±1) giving
/// its sign: `sense · (A − S) × (E − S)` normalised; `None` when the three points are on a
/// line (the plane is not defined by them).
pub fn plane_normal(
    start: &Vector3<f64>,
    aux: &Vector3<f64>,
    end: &Vector3<f64>,
    sense: f64,
) -> Option<Vector3<f64>> {
    let (a, e) = (aux - start, end - start);
    let n = a.cross(&e);
    // Degenerate below 1e-6 rad between the two legs (µm over metres).
    (n.norm() > 1e-6 * a.norm() * e.norm() && n.norm() > 0.0)
        .then(|| n.normalize() * sense.signum())
}

/// The plane a circle by its angle ([`circle_by_angle`]) lies in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ArcPlane {
    /// Through the start, this auxiliary point and the end, `sense` signing the normal
    /// ([`plane_normal`]).
    Points { aux: Vector3<f64>, sense: f64 },
    /// The plane through the chord nearest to the one with this normal: the normal less its
    /// component along the chord (a plane carried over and tilted as little as the chord
    /// requires).
    Near(Vector3<f64>),
}

/// The least sine of the angle between the legs S → A and S → E for the plane through the
/// three to be taken from their compensated positions. By the inscribed-angle theorem that
/// angle is half the arc between A and E: below 0.1 (A within 11.5° of the end on the
/// circle, or of the start), corrections δ would tilt the plane by up to δ / (0.1·|A − S|)
/// — noise — and the nominal plane is carried over instead ([`ArcPlane::Near`]).
pub const PLANE_MIN_SINE: f64 = 0.1;

/// Whether the plane through `start`, `aux`, `end` is well defined by them
/// ([`PLANE_MIN_SINE`]).
pub fn plane_well_defined(start: &Vector3<f64>, aux: &Vector3<f64>, end: &Vector3<f64>) -> bool {
    let (a, e) = (aux - start, end - start);
    a.cross(&e).norm() >= PLANE_MIN_SINE * a.norm() * e.norm() && a.norm() * e.norm() > 0.0
}

/// The circle a controller follows for `CIRC aux, target, CA angle_deg` started at `start`
/// when it must end at `end`: [`arc_about`] the normal of `plane` (`None` where that plane is
/// not defined or holds no such arc).
pub fn circle_by_angle(
    start: &Frame,
    end: &Frame,
    angle_deg: f64,
    plane: ArcPlane,
) -> Option<Cartesian> {
    let normal = match plane {
        ArcPlane::Points { aux, sense } => {
            plane_normal(&start.position, &aux, &end.position, sense)?
        }
        ArcPlane::Near(n) => {
            let c = end.position - start.position;
            let c = c / c.norm();
            let m = n - c * c.dot(&n);
            if m.norm().is_nan() || m.norm() <= 1e-9 {
                return None;
            }
            m.normalize()
        }
    };
    arc_about(start, end, angle_deg, &normal)
}

/// The course of a Cartesian motion between two stops: which path the controller interpolates
/// for each kind of motion ([`course`]).
#[derive(Clone, Copy, Debug)]
pub enum Course<'p> {
    /// LIN: the straight line.
    Line,
    /// An `SPL` segment: the curve whose ends' tangents are those of the spline through
    /// `points` ([`super::spline::tangents`]) at the segment's ends; the segment ends at the
    /// first of them at the end's position.
    Spline { points: &'p [Vector3<f64>] },
    /// CIRC: the arc through the auxiliary position `aux`.
    Circle { aux: Vector3<f64> },
    /// CIRC with `CA`: the circle by its angle ([`circle_by_angle`]).
    CircleByAngle { angle_deg: f64, plane: ArcPlane },
}

/// The path of a motion from `start` to `end` along `course` (`None` where it has none: a
/// circle through points on a line, a spline whose points do not hold the end after another).
pub fn course(start: &Frame, end: &Frame, course: Course) -> Option<Cartesian> {
    match course {
        Course::Line => Cartesian::new(start, end, &Path::Lin).ok(),
        Course::Spline { points } => {
            let at = points.iter().position(|q| *q == end.position)?;
            let before = at.checked_sub(1)?;
            let tangents = super::spline::tangents(points);
            Some(Cartesian::cubic(
                start,
                end,
                &tangents[before],
                &tangents[at],
            ))
        }
        Course::Circle { aux } => Cartesian::new(start, end, &Path::Circ { aux }).ok(),
        Course::CircleByAngle { angle_deg, plane } => circle_by_angle(start, end, angle_deg, plane),
    }
}

/// How a segment arrives at its end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arrival {
    /// `dq/du` at the end in degrees per segment (the whole step for PTP), 0 for an axis at
    /// rest.
    pub rate: [f64; 6],
    /// The end axes the controller reaches by following the path: the given ones, or their
    /// ±360° variant where the path turns an axis past the nearest one (continuity).
    pub end: [f64; 6],
    /// Each axis's last turning point inside the segment: where the run that arrives began.
    pub turns: Turns,
}

/// The last turning point of each axis inside a motion: the command angle there and where
/// along the motion (u ∈ (0, 1)); NaN where the axis does not turn round.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Turns {
    pub angle_deg: [f64; 6],
    pub at: [f64; 6],
}

impl Turns {
    /// The turns after `u` along the motion, with their places rescaled to the rest of it
    /// (a circle's end: the turns before its auxiliary point belong to the auxiliary point).
    pub fn after(mut self, u: f64) -> Turns {
        for n in 0..6 {
            // A turn at NaN (none) is not after `u` either.
            if self.at[n] <= u || self.at[n].is_nan() {
                self.angle_deg[n] = f64::NAN;
                self.at[n] = f64::NAN;
            } else if u > 0.0 {
                self.at[n] = (self.at[n] - u) / (1.0 - u);
            }
        }
        self
    }
}

/// No turning point inside a segment (see [`Arrival::turns`]).
pub const NO_TURNS: Turns = Turns {
    angle_deg: [f64::NAN; 6],
    at: [f64::NAN; 6],
};

/// Whether a straight segment is short enough to need no samples inside it (the arrival rate
/// at its end then depends on its two ends only, so it can be computed later, in parallel).
pub fn lin_needs_no_samples(start: &Frame, end: &Frame) -> bool {
    let length = (end.position - start.position).norm();
    if length.is_nan() || length > PITCH_MM {
        return false;
    }
    let r = end.rotation * start.rotation.transpose();
    // The turn is atan2(s, c) (see `log_so3`): far from the pitch, the sine alone decides
    // (sin 4.59° = 0.08, sin 5.16° = 0.09, rounding is 1e-15 of that); near it, and for
    // anything odd, the exact angle.
    let s = 0.5
        * ((r[(2, 1)] - r[(1, 2)]).powi(2)
            + (r[(0, 2)] - r[(2, 0)]).powi(2)
            + (r[(1, 0)] - r[(0, 1)]).powi(2))
        .sqrt();
    let c = (r.trace() - 1.0) * 0.5;
    if c > 0.9 && s < 0.08 {
        return true;
    }
    if c <= 0.0 || (c > 0.0 && s > 0.09) {
        return false;
    }
    frame::log_so3(&r).norm().to_degrees() <= PITCH_DEG
}

/// How every axis arrives at the end of a segment from `start` to `end` (TCP, axes).
pub fn arrival(
    robot: &RobotDescription,
    tool: &Frame,
    path: &Path,
    start: (&Frame, &[f64; 6]),
    end: (&Frame, &[f64; 6]),
) -> Result<Arrival, PathError> {
    let (q0, q1) = (start.1, end.1);
    if *path == Path::Ptp {
        return Ok(Arrival {
            rate: std::array::from_fn(|i| rest(q1[i] - q0[i])),
            end: *q1,
            turns: NO_TURNS,
        });
    }
    let cart = Cartesian::new(start.0, end.0, path)?;
    arrival_along(robot, tool, &cart, 1.0, q0, q1)
}

/// How every axis arrives at parameter `u_end` of `cart` (whose start the robot leaves at
/// axes `q0`), reaching axes `q1` there: `dq/du` scaled to the sub-segment `[0, u_end]`.
pub fn arrival_along(
    robot: &RobotDescription,
    tool: &Frame,
    cart: &Cartesian,
    u_end: f64,
    q0: &[f64; 6],
    q1: &[f64; 6],
) -> Result<Arrival, PathError> {
    arrival_and_end(robot, tool, cart, u_end, (q0, None), q1).map(|(a, _)| a)
}

/// The arm at axes where a segment ends: its closed-form state and nominal TCP ([`end_tcp`]
/// bit for bit). The next segment, when it starts at the same axes with the same tool, takes
/// it for its start instead of evaluating the arm there again.
#[derive(Clone, Copy, Debug)]
pub struct ArmAt {
    pub arm: crate::kinematics::ArmState,
    pub tcp: Frame,
}

impl ArmAt {
    pub fn new(robot: &RobotDescription, tool: &Frame, q: &[f64; 6]) -> ArmAt {
        let arm = crate::kinematics::ArmState::new(robot, q);
        ArmAt {
            tcp: tcp_of_arm(&arm, tool),
            arm,
        }
    }

    /// Becomes [`ArmAt::new`]'s arm, written where it lies (a 500-byte record, which a walk
    /// refills once per segment).
    fn set(&mut self, robot: &RobotDescription, tool: &Frame, q: &[f64; 6]) {
        self.arm = crate::kinematics::ArmState::new(robot, q);
        self.tcp = tcp_of_arm(&self.arm, tool);
    }

    /// The axis rates `J(q)⁻¹·twist` (`None` where the Jacobian is singular).
    fn rates(&self, twist: &Vector6<f64>) -> Option<[f64; 6]> {
        let v = Vector3::new(twist[0], twist[1], twist[2]);
        let w = Vector3::new(twist[3], twist[4], twist[5]);
        self.arm.rates(&self.tcp.position, &v, &w)
    }
}

/// [`arrival_along`], with the arm at the arrival's end axes (`Arrival::end`; its TCP bit for
/// bit [`end_tcp`]'s: it comes from the same evaluation as the rates), which the next
/// segment's start may reuse; `start` is the arm at `q0` where the segment before left it.
pub fn arrival_and_end(
    robot: &RobotDescription,
    tool: &Frame,
    cart: &Cartesian,
    u_end: f64,
    from: (&[f64; 6], Option<&ArmAt>),
    q1: &[f64; 6],
) -> Result<(Arrival, ArmAt), PathError> {
    let mut end = None;
    let arrival = arrival_into(robot, tool, cart, u_end, from, q1, &mut end)?;
    Ok((arrival, end.expect("an arrival sets its end")))
}

/// [`arrival_and_end`], the arm at the end put in `end` (a 430-byte record: a walker that
/// keeps the last one for the next start fills it in place rather than moving it out).
pub fn arrival_into(
    robot: &RobotDescription,
    tool: &Frame,
    cart: &Cartesian,
    u_end: f64,
    (q0, start): (&[f64; 6], Option<&ArmAt>),
    q1: &[f64; 6],
    end: &mut Option<ArmAt>,
) -> Result<Arrival, PathError> {
    let mut q1 = *q1;
    let (length, turn) = cart.extent();
    let n = ((length * u_end / PITCH_MM)
        .max(turn * u_end / PITCH_DEG)
        .ceil() as usize)
        .clamp(1, MAX_SAMPLES);
    // Walk the path, keeping the samples. (The start is a sample too; a short segment has no
    // other and allocates nothing.)
    let mut q = *q0;
    let mut samples = Vec::with_capacity(n - 1);
    for j in 1..n {
        let u = u_end * j as f64 / n as f64;
        q = nominal::local_ik(robot, &cart.pose(u), tool, &q)
            .map_err(|_| PathError::Lost {
                at: u,
                reason: "no nearby axis solution (singularity or out of reach)",
            })?
            .axes_deg;
        samples.push((q, u / u_end));
    }
    if n > 1 {
        let walked = nominal::local_ik(robot, &cart.pose(u_end), tool, &q)
            .map_err(|_| PathError::Lost {
                at: u_end,
                reason: "no nearby axis solution at the end",
            })?
            .axes_deg;
        for i in 0..6 {
            let d = walked[i] - q1[i];
            let turns = (d / 360.0).round();
            if (d - 360.0 * turns).abs() > END_MATCH_DEG {
                return Err(PathError::EndMismatch {
                    axis: i as u8 + 1,
                    by_deg: d.abs(),
                });
            }
            q1[i] += 360.0 * turns;
        }
    }
    let q1 = &q1;
    // Axis `i` at the last sample at which it still differed from its end (the start last of
    // all), and where: asked only for an axis whose exact rate is not used.
    let last_moving = |i: usize| {
        let moved = |q: f64| (q1[i] - q).abs() >= REST_DEG;
        match samples.iter().rev().find(|(qs, _)| moved(qs[i])) {
            Some((qs, u)) => Some((qs[i], *u)),
            None => moved(q0[i]).then_some((q0[i], 0.0)),
        }
    };
    // The exact rate at the end, where the Jacobian is regular.
    let end = match end {
        Some(at) => {
            at.set(robot, tool, q1);
            at
        }
        None => end.insert(ArmAt::new(robot, tool, q1)),
    };
    let rate = end.rates(&(cart.twist(u_end) * u_end));
    let rate: [f64; 6] = std::array::from_fn(|i| {
        let r = rate.map_or(0.0, |r| r[i]);
        if r.is_finite() && r.abs() >= REST_DEG && r.abs() < 1e6 {
            return r;
        }
        match last_moving(i) {
            Some((q, u)) => rest((q1[i] - q) / (1.0 - u)),
            None => 0.0,
        }
    });
    // The rate at the start too: an axis leaving against its arrival turned round inside.
    let start_twist = cart.twist(0.0) * u_end;
    let start_rate = match start {
        Some(at) => at.rates(&start_twist),
        None => ArmAt::new(robot, tool, q0).rates(&start_twist),
    };
    let n = samples.len() + 2;
    let mut turns = NO_TURNS;
    for i in 0..6 {
        let point = |j: usize| match j {
            0 => (q0[i], 0.0),
            j if j == n - 1 => (q1[i], 1.0),
            j => (samples[j - 1].0[i], samples[j - 1].1),
        };
        let r0 = start_rate.map_or(f64::NAN, |r| r[i]);
        if let Some((angle, u)) = last_turn(&point, n, r0, rate[i]) {
            turns.angle_deg[i] = angle;
            turns.at[i] = u;
        }
    }
    Ok(Arrival {
        rate,
        end: *q1,
        turns,
    })
}

/// The last turning point of one axis along `points` (`(angle, u)` from the start at u = 0 to
/// the end at u = 1) whose rates per unit of u are `rate0` at the start and `rate1` at the
/// end: `(angle there, u there)`; `None` when it does not turn round.
fn last_turn(
    points: &dyn Fn(usize) -> (f64, f64),
    n: usize,
    rate0: f64,
    rate1: f64,
) -> Option<(f64, f64)> {
    // Motion below the numbers' own rounding (an axis the path holds, computed to 1e-15) is
    // no motion.
    let diffs = |j: usize| {
        let d = points(j + 1).0 - points(j).0;
        if d.abs() < STILL_DEG {
            0.0
        } else {
            d
        }
    };
    // The direction of the run that arrives.
    let d = if rate1 != 0.0 {
        rate1.signum()
    } else {
        (0..n - 1).rev().map(diffs).find(|&x| x != 0.0)?.signum()
    };
    let deeper = |a: (f64, f64), b: (f64, f64)| if (a.0 - b.0) * d < 0.0 { a } else { b };
    // The last interval that moves against the arrival: the turn follows it.
    if let Some(j) = (0..n - 1).rev().find(|&j| diffs(j) * d < 0.0) {
        let at = points(j + 1);
        if j + 2 < n {
            // The parabola through the three samples around the turn.
            let vertex = parabola_extremum(points(j), at, points(j + 2));
            return Some(vertex.map_or(at, |v| deeper(v, at)));
        }
        // The last interval itself moves against the arrival: the turn is inside it.
        let p0 = points(j);
        let du = at.1 - p0.1;
        let m0 = if j > 0 {
            let before = points(j - 1);
            (p0.0 - before.0) / (p0.1 - before.1) * du
        } else {
            rate0 * du
        };
        let inside = hermite_extremum(p0.0, at.0, m0, rate1 * du, d);
        return Some(inside.map_or(at, |(v, s)| (v, p0.1 + s * du)));
    }
    // Every interval moves with the arrival: a turn can only lie before the first sample.
    if rate0.is_finite() && rate0 * d < 0.0 {
        let (p0, p1) = (points(0), points(1));
        let du = p1.1 - p0.1;
        let m1 = if n > 2 {
            let after = points(2);
            (after.0 - p0.0) / (after.1 - p0.1) * du
        } else {
            rate1 * du
        };
        let (v, s) = hermite_extremum(p0.0, p1.0, rate0 * du, m1, d)?;
        return Some((v, p0.1 + s * du));
    }
    None
}

/// The extremum `(value, u)` of the parabola through three points `(value, u)`, when it lies
/// between the outer two.
fn parabola_extremum(a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> Option<(f64, f64)> {
    let (y0, x0) = a;
    let (y1, x1) = b;
    let (y2, x2) = c;
    let d01 = (y1 - y0) / (x1 - x0);
    let d12 = (y2 - y1) / (x2 - x1);
    let curvature = (d12 - d01) / (x2 - x0);
    if !(curvature.is_finite()) || curvature == 0.0 {
        return None;
    }
    // y = y1 + s·(x − x1) + curvature·(x − x1)² with s the slope at x1.
    let s = d01 + curvature * (x1 - x0);
    let x = x1 - s / (2.0 * curvature);
    (x > x0 && x < x2).then_some((y1 + s * (x - x1) + curvature * (x - x1) * (x - x1), x))
}

/// The extremum `(value, t)`, inside the interval (t ∈ (0, 1)), of the cubic Hermite from
/// `p0` to `p1` with end derivatives `m0`, `m1` (per unit of the interval) that turns the run
/// round into direction `d` (a minimum for d > 0, a maximum for d < 0).
fn hermite_extremum(p0: f64, p1: f64, m0: f64, m1: f64, d: f64) -> Option<(f64, f64)> {
    // h'(t) = a·t² + b·t + c.
    let a = 6.0 * p0 + 3.0 * m0 - 6.0 * p1 + 3.0 * m1;
    let b = -6.0 * p0 - 4.0 * m0 + 6.0 * p1 - 2.0 * m1;
    let c = m0;
    let h = |t: f64| {
        let (t2, t3) = (t * t, t * t * t);
        p0 * (2.0 * t3 - 3.0 * t2 + 1.0)
            + m0 * (t3 - 2.0 * t2 + t)
            + p1 * (-2.0 * t3 + 3.0 * t2)
            + m1 * (t3 - t2)
    };
    let roots: [Option<f64>; 2] = if a.abs() < 1e-300 {
        [(b != 0.0).then(|| -c / b), None]
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            [None, None]
        } else {
            let s = disc.sqrt();
            [Some((-b - s) / (2.0 * a)), Some((-b + s) / (2.0 * a))]
        }
    };
    roots
        .into_iter()
        .flatten()
        .filter(|t| *t > 0.0 && *t < 1.0)
        .map(|t| (h(t), t))
        .reduce(|x, y| if (x.0 - y.0) * d < 0.0 { x } else { y })
        .filter(|(v, _)| (v - p1) * d < 0.0)
}

/// The nominal TCP at axes `q` (the closed form of `kinematics`; agrees with
/// `Nominal::tcp` to rounding): where [`arrival_and_end`] says a segment ends.
pub fn end_tcp(robot: &RobotDescription, q: &[f64; 6], tool: &Frame) -> Frame {
    let (r, p) = crate::kinematics::flange_frame(robot, q);
    tcp_of_flange(&r, &p, tool)
}

fn tcp_of_flange(r: &nalgebra::Matrix3<f64>, p: &Vector3<f64>, tool: &Frame) -> Frame {
    Frame {
        rotation: r * tool.rotation,
        position: p + r * tool.position,
    }
}

/// The nominal TCP of the arm at `arm` with `tool` ([`end_tcp`] bit for bit).
pub fn tcp_of_arm(arm: &crate::kinematics::ArmState, tool: &Frame) -> Frame {
    tcp_of_flange(&arm.flange_rotation, &arm.flange_position, tool)
}

/// The nominal TCP at `q` ([`end_tcp`], bit for bit) and the axis rates `J(q)⁻¹·twist`
/// (`None` where the Jacobian is singular).
#[cfg(test)]
fn end_rate(
    robot: &RobotDescription,
    tool: &Frame,
    q: &[f64; 6],
    twist: &Vector6<f64>,
) -> (Frame, Option<[f64; 6]>) {
    let at = ArmAt::new(robot, tool, q);
    (at.tcp, at.rates(twist))
}

fn rest(d: f64) -> f64 {
    if d.abs() < REST_DEG {
        0.0
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{inverse, Select};
    use crate::motion::nominal::{Arm, Nominal};
    use approx::assert_relative_eq;

    fn robot() -> RobotDescription {
        RobotDescription::kr30ha()
    }

    /// The nominal IK with S = 2 nearest to `near` (the independent closed form).
    fn ik_near(pose: &Frame, near: [f64; 6]) -> [f64; 6] {
        inverse(&robot(), pose, Select::StatusNearest { s: 2, near })
            .unwrap()
            .axes_deg
    }

    fn fk(q: &[f64; 6]) -> Frame {
        Nominal(&robot()).tcp(q, &Frame::identity())
    }

    proptest::proptest! {
        /// The shortcut decides like the exact angle, on both sides of the pitch.
        #[test]
        fn short_segment_test_matches_the_exact_angle(
            axis in proptest::array::uniform3(-1.0f64..1.0),
            angle_deg in proptest::prop_oneof![0.0f64..200.0, 4.4f64..5.3, 4.99999f64..5.00001],
            length in 0.0f64..40.0,
            start in proptest::array::uniform3(-3.0f64..3.0),
        ) {
            let w = Vector3::from(axis);
            proptest::prop_assume!(w.norm() > 1e-3);
            let a = Frame {
                rotation: exp_so3(&Vector3::from(start)),
                position: Vector3::new(100.0, -50.0, 800.0),
            };
            let b = Frame {
                rotation: exp_so3(&(w.normalize() * angle_deg.to_radians())) * a.rotation,
                position: a.position + Vector3::new(length, 0.0, 0.0),
            };
            let exact = (b.position - a.position).norm() <= PITCH_MM
                && frame::log_so3(&(b.rotation * a.rotation.transpose()))
                    .norm()
                    .to_degrees()
                    <= PITCH_DEG;
            proptest::prop_assert_eq!(lin_needs_no_samples(&a, &b), exact);
        }
    }

    proptest::proptest! {
        /// The arc of a given turn between two points: it starts and ends there, turns by
        /// the angle about the normal, and has the chord's radius |c| / (2|sin(θ/2)|); given
        /// three points of a known circle (start, a point, the end at the turn) it is that
        /// circle.
        #[test]
        fn an_arc_by_its_angle_joins_its_ends(
            centre in proptest::array::uniform3(-500.0f64..500.0),
            radius in 1.0f64..300.0,
            tilt in proptest::array::uniform3(-3.0f64..3.0),
            angle in proptest::prop_oneof![-354.0f64..-6.0, 6.0f64..354.0],
            aux_at in 0.05f64..0.95,
        ) {
            let centre = Vector3::from(centre);
            let r = exp_so3(&Vector3::from(tilt));
            let normal = r * Vector3::z();
            let on = |deg: f64| {
                let a = deg.to_radians();
                centre + r * Vector3::new(radius * a.cos(), radius * a.sin(), 0.0)
            };
            let frame = |p: Vector3<f64>| Frame { rotation: r, position: p };
            let (s, e) = (frame(on(0.0)), frame(on(angle)));
            let arc = arc_about(&s, &e, angle, &normal).unwrap();
            proptest::prop_assert!((arc.pose(0.0).position - s.position).norm() < 1e-9);
            proptest::prop_assert!((arc.pose(1.0).position - e.position).norm() < 1e-8);
            proptest::prop_assert!((arc.pose(0.5).position - on(angle / 2.0)).norm() < 1e-8);
            let chord = (e.position - s.position).norm();
            let expected = chord / (2.0 * (angle.to_radians() / 2.0).sin().abs());
            proptest::prop_assert!((arc.extent().0 / angle.to_radians().abs() - expected).abs() < 1e-8 * expected.max(1.0));
            // Through a third point of the circle, the sense from it.
            let aux = on(angle * aux_at);
            let sense = plane_normal(&s.position, &aux, &e.position, 1.0).unwrap().dot(&normal).signum();
            let again = circle_by_angle(&s, &e, angle, ArcPlane::Points { aux, sense }).unwrap();
            // … and a normal carried over tilted along the chord gives the plane through it.
            let tilted = (normal + (e.position - s.position).normalize() * 0.3).normalize();
            let near = circle_by_angle(&s, &e, angle, ArcPlane::Near(tilted)).unwrap();
            for u in [0.25, 0.5, 0.75] {
                proptest::prop_assert!((again.pose(u).position - on(angle * u)).norm() < 1e-7);
                proptest::prop_assert!((near.pose(u).position - on(angle * u)).norm() < 1e-7);
            }
        }
    }

    /// The closed-form end rates are the error-model chain's `J⁻¹·twist` (LU of its 6×6
    /// nominal Jacobian, an independent evaluation), and the end TCP its TCP, to rounding.
    #[test]
    fn end_rates_match_the_chains_jacobian() {
        let r = robot();
        let tool = Frame::from_kuka(&crate::kinematics::Pose::from_array([
            12.0, -30.0, 245.3, 10.0, -90.0, 5.0,
        ]));
        for q in [
            [10.0, -80.0, 100.0, 20.0, 50.0, -30.0],
            [-120.0, -45.0, 70.0, -160.0, -80.0, 200.0],
            [0.0, -90.0, 90.0, 0.0, 30.0, 0.0],
        ] {
            let twist = Vector6::new(3.0, -1.5, 0.7, 0.01, -0.02, 0.005);
            let (tcp, rates) = end_rate(&r, &tool, &q, &twist);
            let (chain_tcp, jac) = Nominal(&r).tcp_jacobian(&q, &tool);
            let expected = jac.lu().solve(&twist).unwrap();
            let rates = rates.unwrap();
            for i in 0..6 {
                assert_relative_eq!(rates[i], expected[i], max_relative = 1e-9, epsilon = 1e-12);
            }
            assert_relative_eq!(tcp.position, chain_tcp.position, epsilon = 1e-9);
            assert_relative_eq!(tcp.rotation, chain_tcp.rotation, epsilon = 1e-12);
            assert_eq!(tcp, end_tcp(&r, &q, &tool));
        }
    }

    #[test]
    fn arc_passes_through_its_three_points() {
        let a = Vector3::new(1000.0, 0.0, 1000.0);
        let b = Vector3::new(1100.0, 100.0, 1000.0);
        let c = Vector3::new(1200.0, 0.0, 1000.0);
        let f = |p: Vector3<f64>| Frame {
            rotation: nalgebra::Matrix3::identity(),
            position: p,
        };
        let cart = Cartesian::new(&f(a), &f(c), &Path::Circ { aux: b }).unwrap();
        assert_relative_eq!(cart.pose(0.0).position, a, epsilon = 1e-9);
        assert_relative_eq!(cart.pose(1.0).position, c, epsilon = 1e-9);
        // Half circle of radius 100 about (1100, 0): b at the middle.
        assert_relative_eq!(cart.pose(0.5).position, b, epsilon = 1e-9);
        assert_relative_eq!(
            cart.extent().0,
            100.0 * std::f64::consts::PI,
            epsilon = 1e-9
        );
        // Tangent at the end points along −X … (c → beyond, turning about −Z).
        let t = cart.twist(1.0);
        assert!(t[0].abs() < 1e-9 && t[1] < 0.0);
        assert!(Cartesian::new(&f(a), &f(c), &Path::Circ { aux: (a + c) / 2.0 }).is_err());
    }

    #[test]
    fn lin_arrival_matches_finite_differences_and_rests() {
        let r = robot();
        let tool = Frame::identity();
        let q0 = [10.0, -80.0, 100.0, 20.0, 50.0, -30.0];
        let start = fk(&q0);
        let mut end = start;
        end.position += Vector3::new(-150.0, 80.0, -60.0);
        end.rotation = exp_so3(&Vector3::new(0.1, -0.05, 0.2)) * end.rotation;
        let q1 = ik_near(&end, q0);
        let v = arrival(&r, &tool, &Path::Lin, (&start, &q0), (&end, &q1))
            .unwrap()
            .rate;
        // Independent: nominal IK a little before the end, by the closed form.
        let cart = Cartesian::new(&start, &end, &Path::Lin).unwrap();
        let h = 1e-5;
        let qh = ik_near(&cart.pose(1.0 - h), q1);
        for i in 0..6 {
            assert_relative_eq!(
                v[i],
                (q1[i] - qh[i]) / h,
                max_relative = 1e-3,
                epsilon = 1e-3
            );
        }
        // A vertical line at fixed orientation: A1 rests.
        let mut down = start;
        down.position.z -= 200.0;
        let qd = ik_near(&down, q0);
        let v = arrival(&r, &tool, &Path::Lin, (&start, &q0), (&down, &qd))
            .unwrap()
            .rate;
        assert_eq!(v[0], 0.0);
        assert!(v[1].abs() > 1.0 && v[2].abs() > 1.0);
    }

    #[test]
    fn reversal_inside_a_segment_gives_the_last_direction() {
        // A LIN passing the A1 axis's nearest point: A1 turns one way, the line continues …
        // Here: a line along Y in front of the robot, A1 moves monotonically; and a circle
        // whose tangent at the end reverses A2 relative to its net step.
        let r = robot();
        let tool = Frame::identity();
        let q0 = [0.0, -60.0, 80.0, 0.0, 70.0, 0.0];
        let start = fk(&q0);
        // Arc going up and coming back down: net Z change 0, A2 first up then down.
        let mut end = start;
        end.position.x += 200.0;
        let aux = start.position + Vector3::new(100.0, 0.0, 100.0);
        let q1 = ik_near(&end, q0);
        let v = arrival(&r, &tool, &Path::Circ { aux }, (&start, &q0), (&end, &q1))
            .unwrap()
            .rate;
        // On arrival the TCP moves down and forward (the arc's far side): compare with the
        // sign of the nominal motion over the last 10⁻⁶ of the arc by closed-form IK.
        let cart = Cartesian::new(&start, &end, &Path::Circ { aux }).unwrap();
        let qh = ik_near(&cart.pose(1.0 - 1e-6), q1);
        for i in [1, 2, 4] {
            assert_eq!(v[i] > 0.0, q1[i] > qh[i], "A{}", i + 1);
        }
        // A2's net step and its arrival direction differ somewhere among A2, A3, A5: the
        // arc's reversal is caught.
        assert!((0..6).any(|i| (q1[i] - q0[i]).abs() > 0.01 && (q1[i] - q0[i]) * v[i] < 0.0));
    }
}
