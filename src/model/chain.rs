//! The paper's error chain, equation (2) as written out in MODEL.md: for each axis n
//! `Trans(L_n + (dx,dy,dz)) · Rx(rx)·Ry(ry)·Rz(rz) · Rot_axis_n(θ_n)` with
//! `θ_n = sense_n·(A_n + dθ_n) + offset_n`, in frames that coincide with the base frame at
//! HOME; the KUKA flange frame is the A6 frame `· Ry(90°)` and the measured target is
//! `A6 frame · (6p + target slots)` (equation 1). Besides the pose, [`ChainFrames`] keeps
//! the world axis and centre of every small motion a chain slot stands for, which gives the
//! analytic Jacobian of the target and the flange with respect to every slot: a translation
//! `t` moves every later point by `t`, a rotation about axis `ω` through `o` moves `p` by
//! `ω × (p − o)` and the orientation by the rotation vector `ω`.

use nalgebra::{Matrix3, Vector3, Vector6};

use super::effect::{ChainErrors, Slot, JOINT_SLOTS, N_SLOTS};
use crate::kinematics::{trig, Frame, RobotDescription};

/// Model rotation axis of A1..A6 (0 = x, 1 = y, 2 = z): z, y, y, x, y, x (MODEL.md).
pub const AXIS_COORD: [usize; 6] = [2, 1, 1, 0, 1, 0];

/// Nominal link vector `L_n` before axis n, in the frame of axis n−1 (mm).
pub fn link_vectors(robot: &RobotDescription) -> [Vector3<f64>; 6] {
    let l = &robot.links;
    [
        Vector3::zeros(),
        Vector3::new(l.l1x, 0.0, l.l1z),
        Vector3::new(0.0, 0.0, l.l2),
        Vector3::new(0.0, 0.0, l.l3z),
        Vector3::new(l.l4x, 0.0, 0.0),
        Vector3::new(l.l5x, 0.0, 0.0),
    ]
}

/// Rotation from the A6 frame to the KUKA flange frame: Ry(+90°), so that the flange Z is the
/// A6 x axis (pointing +X at HOME) and the flange X points down at HOME.
pub fn a6_to_flange() -> Matrix3<f64> {
    Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0)
}

/// A vector given in the KUKA flange frame, expressed in the A6 frame.
pub fn flange_to_a6(v_flange: &Vector3<f64>) -> Vector3<f64> {
    a6_to_flange() * v_flange
}

/// `sin_cos` with a Taylor series for the small angles of tilt slots: below 1e-3 rad the
/// dropped terms (x⁷/5040, x⁸/40320) are under 1e-24, far below an f64 ulp of the result,
/// and the polynomial costs a fraction of the library call. The coefficients multiply:
/// divisions by 6, 20, 12 and 30 (no exact reciprocals, so the compiler keeps them) were five
/// divider passes per call, some twenty calls per solved target.
fn sin_cos(x: f64) -> (f64, f64) {
    if x.abs() < 1e-3 {
        let x2 = x * x;
        (
            x + x * x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0)),
            1.0 - x2 * (0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0))),
        )
    } else {
        trig::sin_cos(x)
    }
}

/// `r ← r · Rot_coord(angle)`: post-multiplying by an elementary rotation only mixes the two
/// columns perpendicular to `coord` (12 products instead of a 27-product matrix product).
fn rotate(r: &mut Matrix3<f64>, coord: usize, angle: f64) {
    let (s, c) = sin_cos(angle);
    rotate_sc(r, coord, s, c);
}

/// `r ← r · Rot_coord(θ)` given `(sin θ, cos θ)`.
#[inline(always)]
fn rotate_sc(r: &mut Matrix3<f64>, coord: usize, s: f64, c: f64) {
    // Columns (i, j) such that Rot_coord maps e_i → c·e_i + s·e_j; constant indices per
    // branch, so that the elements stay in registers (column copies through the stack cost
    // store-forwarding stalls).
    match coord {
        0 => rotate_columns::<1, 2>(r, s, c),
        1 => rotate_columns::<2, 0>(r, s, c),
        _ => rotate_columns::<0, 1>(r, s, c),
    }
}

/// Columns `(I, J) ← (c·I + s·J, c·J − s·I)`, element by element (the operations of the
/// column expressions, in their order).
#[inline(always)]
fn rotate_columns<const I: usize, const J: usize>(r: &mut Matrix3<f64>, s: f64, c: f64) {
    for k in 0..3 {
        let (a, b) = (r[(k, I)], r[(k, J)]);
        r[(k, I)] = a * c + b * s;
        r[(k, J)] = b * c - a * s;
    }
}

/// The sines and cosines of the joint angles at a reference command, so that a solver
/// evaluating the chain at commands a few millidegrees apart gets each joint's sine and
/// cosine by the addition theorem with a small-angle series (`sin(θ₀+δ) = sin θ₀·cos δ +
/// cos θ₀·sin δ`, |δ| < 10⁻³ rad, exact to a couple of ulps) instead of a library call.
/// The first evaluation (and any farther than 10⁻³ rad on an axis) sets the reference.
#[derive(Clone, Copy, Debug, Default)]
pub struct JointTrig {
    set: [bool; 6],
    theta: [f64; 6],
    sin: [f64; 6],
    cos: [f64; 6],
}

impl JointTrig {
    /// Inlined into the chain's joints, which call it at every evaluation; the library's
    /// path, taken once per solve and axis, is kept out of line.
    #[inline(always)]
    fn sin_cos(&mut self, n: usize, theta: f64) -> (f64, f64) {
        if self.set[n] {
            let d = theta - self.theta[n];
            if d.abs() < 1e-3 {
                let (sd, cd) = sin_cos(d);
                let (s0, c0) = (self.sin[n], self.cos[n]);
                return (s0 * cd + c0 * sd, c0 * cd - s0 * sd);
            }
        }
        self.set_reference(n, theta)
    }

    /// Makes `theta` axis n's reference.
    #[inline(never)]
    fn set_reference(&mut self, n: usize, theta: f64) -> (f64, f64) {
        let (s, c) = trig::sin_cos(theta);
        self.set[n] = true;
        self.theta[n] = theta;
        self.sin[n] = s;
        self.cos[n] = c;
        (s, c)
    }
}

/// Multiplies by a small-rotation slot, skipping the work when it is zero (most slots are).
fn rotate_by(r: &mut Matrix3<f64>, coord: usize, angle: f64) {
    if angle != 0.0 {
        rotate(r, coord, angle);
    }
}

/// What [`walk`] reports about axis n on its way (for the Jacobian's bookkeeping).
enum Step<'a> {
    /// The frame the link vector is given in (R_{n−1}).
    Link(&'a Matrix3<f64>),
    /// The axis's centre of rotation.
    Origin(&'a Vector3<f64>),
    /// The frame just before the tilt slot `coord` is applied.
    Tilt(usize, &'a Matrix3<f64>),
    /// The world direction of a positive KUKA rotation.
    Joint(&'a Vector3<f64>),
}

/// Runs the chain and returns the A6 frame (rotation, origin); `visit` sees every
/// intermediate frame. The prediction path passes a no-op and the stores compile away.
#[inline(always)]
fn walk(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    errors: &ChainErrors,
    trig: &mut JointTrig,
    mut visit: impl FnMut(usize, Step),
) -> (Matrix3<f64>, Vector3<f64>) {
    let links = link_vectors(robot);
    let e = &errors.0;
    let mut r = Matrix3::identity();
    let mut p = Vector3::zeros();
    for n in 0..6 {
        let s = &e[n * JOINT_SLOTS..(n + 1) * JOINT_SLOTS];
        visit(n, Step::Link(&r));
        p += r * (links[n] + Vector3::new(s[0], s[1], s[2]));
        visit(n, Step::Origin(&p));
        for (coord, &angle) in s[3..6].iter().enumerate() {
            visit(n, Step::Tilt(coord, &r));
            rotate_by(&mut r, coord, angle);
        }
        let axis = AXIS_COORD[n];
        let sense = robot.senses[n];
        visit(n, Step::Joint(&(sense * r.column(axis))));
        let theta = sense * (axes_deg[n].to_radians() + s[6]) + robot.offsets_deg[n].to_radians();
        let (sin, cos) = trig.sin_cos(n, theta);
        rotate_sc(&mut r, axis, sin, cos);
    }
    (r, p)
}

/// The A6 frame (rotation, origin) only: the fast path of a prediction.
pub fn a6_frame(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    errors: &ChainErrors,
) -> (Matrix3<f64>, Vector3<f64>) {
    a6_frame_near(robot, axes_deg, errors, &mut JointTrig::default())
}

/// [`a6_frame`] near the reference of `trig` (see [`JointTrig`]).
pub fn a6_frame_near(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    errors: &ChainErrors,
    trig: &mut JointTrig,
) -> (Matrix3<f64>, Vector3<f64>) {
    walk(robot, axes_deg, errors, trig, |_, _| {})
}

/// [`a6_frame`] of the nominal chain (every slot zero): the controller's forward kinematics,
/// evaluated for every command written. The same sums as the error chain's, to the bit (the
/// zero slots are still added, so that a `-0.0` becomes what the error chain makes it), without
/// looking the eighteen zero tilts up or keeping a reference for [`JointTrig`].
pub fn a6_frame_nominal(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
) -> (Matrix3<f64>, Vector3<f64>) {
    let links = link_vectors(robot);
    let mut r = Matrix3::identity();
    let mut p = Vector3::zeros();
    nominal_joint::<0>(robot, axes_deg, &links, (&mut r, &mut p));
    nominal_joint::<1>(robot, axes_deg, &links, (&mut r, &mut p));
    nominal_joint::<2>(robot, axes_deg, &links, (&mut r, &mut p));
    nominal_joint::<3>(robot, axes_deg, &links, (&mut r, &mut p));
    nominal_joint::<4>(robot, axes_deg, &links, (&mut r, &mut p));
    nominal_joint::<5>(robot, axes_deg, &links, (&mut r, &mut p));
    (r, p)
}

/// Joint `N` of [`a6_frame_nominal`], its index a constant (see [`block_joint`]).
#[inline(always)]
fn nominal_joint<const N: usize>(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    links: &[Vector3<f64>; 6],
    (r, p): (&mut Matrix3<f64>, &mut Vector3<f64>),
) {
    *p += *r * (links[N] + Vector3::zeros());
    let sense = robot.senses[N];
    let theta = sense * (axes_deg[N].to_radians() + 0.0) + robot.offsets_deg[N].to_radians();
    let (sin, cos) = trig::sin_cos(theta);
    rotate_sc(r, AXIS_COORD[N], sin, cos);
}

/// The part of the chain that a model keeps fixed while only the axes' angle slots vary (the
/// paper's model: the geometric errors are constant, the maps, backlash and crosstalk move
/// `dθ_n` alone): per axis the link vector with its offsets and the product of its three tilt
/// rotations, multiplied out once per model instead of at every evaluation.
#[derive(Clone, Copy, Debug)]
pub struct LinkBlocks {
    link: [Vector3<f64>; 6],
    tilt: [Matrix3<f64>; 6],
    /// Whether axis n has a tilt at all (most do not in a nominal model: no product).
    tilted: [bool; 6],
    /// The frame after A1's link and tilts: they act on the identity, so their products are
    /// made here once (the same operations as in [`block_joint`], so the same bits).
    base: (Matrix3<f64>, Vector3<f64>),
}

impl LinkBlocks {
    /// The fixed blocks of `errors` (their angle and target slots are not used).
    pub fn new(robot: &RobotDescription, errors: &ChainErrors) -> LinkBlocks {
        let links = link_vectors(robot);
        let e = &errors.0;
        let mut blocks = LinkBlocks {
            link: [Vector3::zeros(); 6],
            tilt: [Matrix3::identity(); 6],
            tilted: [false; 6],
            base: (Matrix3::identity(), Vector3::zeros()),
        };
        for n in 0..6 {
            let s = &e[n * JOINT_SLOTS..(n + 1) * JOINT_SLOTS];
            blocks.link[n] = links[n] + Vector3::new(s[0], s[1], s[2]);
            for (coord, &angle) in s[3..6].iter().enumerate() {
                rotate_by(&mut blocks.tilt[n], coord, angle);
            }
            blocks.tilted[n] = s[3..6].iter().any(|&a| a != 0.0);
        }
        let (r, p) = &mut blocks.base;
        blocks_link::<0>(&blocks.link, &blocks.tilt, &blocks.tilted, (r, p));
        blocks
    }
}

/// [`a6_frame_near`] of a chain whose errors are `blocks` plus the angle slots `angles` (rad,
/// KUKA sign): the same sums, with each axis's tilts applied as one product (the results
/// agree to rounding, ~10⁻¹⁶ relative).
pub fn a6_frame_blocks(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    blocks: &LinkBlocks,
    angles: &[f64; 6],
    trig: &mut JointTrig,
) -> (Matrix3<f64>, Vector3<f64>) {
    walk_blocks(robot, axes_deg, blocks, angles, trig, |_, _, _| {})
}

/// [`axis_lines`] of a chain given as [`LinkBlocks`] and angle slots (see
/// [`a6_frame_blocks`], whose A6 frame it ends on, to the bit).
pub fn axis_lines_blocks(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    blocks: &LinkBlocks,
    angles: &[f64; 6],
    trig: &mut JointTrig,
) -> AxisLines {
    let mut joint_axis = [Vector3::zeros(); 6];
    let mut origin = [Vector3::zeros(); 6];
    let (a6_rotation, a6_origin) =
        walk_blocks(robot, axes_deg, blocks, angles, trig, |n, p, axis| {
            origin[n] = *p;
            joint_axis[n] = axis;
        });
    AxisLines {
        a6_rotation,
        a6_origin,
        joint_axis,
        origin,
    }
}

/// Runs the chain of [`a6_frame_blocks`]; `visit(n, centre, axis)` sees each axis's centre
/// and the world direction of its positive KUKA rotation (a no-op compiles away).
#[inline(always)]
fn walk_blocks(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    blocks: &LinkBlocks,
    angles: &[f64; 6],
    trig: &mut JointTrig,
    mut visit: impl FnMut(usize, &Vector3<f64>, Vector3<f64>),
) -> (Matrix3<f64>, Vector3<f64>) {
    let (mut r, mut p) = blocks.base;
    let chain = (robot, axes_deg, blocks, angles);
    block_joint::<0>(chain, trig, (&mut r, &mut p), &mut visit);
    block_joint::<1>(chain, trig, (&mut r, &mut p), &mut visit);
    block_joint::<2>(chain, trig, (&mut r, &mut p), &mut visit);
    block_joint::<3>(chain, trig, (&mut r, &mut p), &mut visit);
    block_joint::<4>(chain, trig, (&mut r, &mut p), &mut visit);
    block_joint::<5>(chain, trig, (&mut r, &mut p), &mut visit);
    (r, p)
}

/// Joint `N` of [`walk_blocks`] on the frame `(r, p)` so far (A1's link and tilts are the
/// blocks' `base`). The index is a constant, so that the joint's coordinate — which columns
/// turn, which one is visited — is known where it is compiled: looped over, each joint went
/// through a runtime match and a bounds-checked column (kept for its panic even where the
/// visit is a no-op).
#[inline(always)]
fn block_joint<const N: usize>(
    (robot, axes_deg, blocks, angles): (&RobotDescription, &[f64; 6], &LinkBlocks, &[f64; 6]),
    trig: &mut JointTrig,
    (r, p): (&mut Matrix3<f64>, &mut Vector3<f64>),
    visit: &mut impl FnMut(usize, &Vector3<f64>, Vector3<f64>),
) {
    if N > 0 {
        blocks_link::<N>(&blocks.link, &blocks.tilt, &blocks.tilted, (r, p));
    }
    let axis = AXIS_COORD[N];
    let sense = robot.senses[N];
    visit(N, p, sense * r.column(axis));
    let theta = sense * (axes_deg[N].to_radians() + angles[N]) + robot.offsets_deg[N].to_radians();
    let (sin, cos) = trig.sin_cos(N, theta);
    rotate_sc(r, axis, sin, cos);
}

/// Axis `N`'s link vector and tilts of [`LinkBlocks`] on the frame `(r, p)` so far.
#[inline(always)]
fn blocks_link<const N: usize>(
    link: &[Vector3<f64>; 6],
    tilt: &[Matrix3<f64>; 6],
    tilted: &[bool; 6],
    (r, p): (&mut Matrix3<f64>, &mut Vector3<f64>),
) {
    *p += *r * link[N];
    if tilted[N] {
        *r *= tilt[N];
    }
}

/// The A6 frame with every axis's world line (direction of a positive KUKA rotation, centre):
/// all an axis Jacobian needs, without the slot bookkeeping of [`ChainFrames`].
#[derive(Clone, Copy, Debug)]
pub struct AxisLines {
    pub a6_rotation: Matrix3<f64>,
    pub a6_origin: Vector3<f64>,
    pub joint_axis: [Vector3<f64>; 6],
    pub origin: [Vector3<f64>; 6],
}

/// The chain evaluated for an axis Jacobian (see [`AxisLines`]).
pub fn axis_lines(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    errors: &ChainErrors,
    trig: &mut JointTrig,
) -> AxisLines {
    let mut joint_axis = [Vector3::zeros(); 6];
    let mut origin = [Vector3::zeros(); 6];
    let (a6_rotation, a6_origin) = walk(robot, axes_deg, errors, trig, |n, step| match step {
        Step::Origin(p) => origin[n] = *p,
        Step::Joint(axis) => joint_axis[n] = *axis,
        _ => {}
    });
    AxisLines {
        a6_rotation,
        a6_origin,
        joint_axis,
        origin,
    }
}

/// The KUKA flange frame in the base frame, fast path.
pub fn flange_pose(robot: &RobotDescription, axes_deg: &[f64; 6], errors: &ChainErrors) -> Frame {
    let (r, p) = a6_frame(robot, axes_deg, errors);
    Frame {
        rotation: r * a6_to_flange(),
        position: p,
    }
}

/// The target position (`target_a6` plus the target slots, carried by the A6 frame), fast path.
pub fn target_position(
    robot: &RobotDescription,
    axes_deg: &[f64; 6],
    errors: &ChainErrors,
    target_a6: &Vector3<f64>,
) -> Vector3<f64> {
    let (r, p) = a6_frame(robot, axes_deg, errors);
    let t = &errors.0[6 * JOINT_SLOTS..];
    p + r * (target_a6 + Vector3::new(t[0], t[1], t[2]))
}

/// The evaluated chain at one state: the A6 frame and, per axis, the motions of its slots.
#[derive(Clone, Copy, Debug)]
pub struct ChainFrames {
    /// Rotation of the frame in which axis n's link vector and offsets are given (R_{n−1}).
    link_frame: [Matrix3<f64>; 6],
    /// Axis n's centre of rotation in the base frame (mm).
    origin: [Vector3<f64>; 6],
    /// World axes of the rx, ry, rz slots of axis n (each rotation follows the previous one).
    tilt_axis: [[Vector3<f64>; 3]; 6],
    /// World axis of a positive KUKA `dθ_n` (the model axis times the sense).
    joint_axis: [Vector3<f64>; 6],
    a6_rotation: Matrix3<f64>,
    a6_origin: Vector3<f64>,
}

impl ChainFrames {
    /// Evaluates the chain at command angles `axes_deg` (KUKA, degrees) with `errors`.
    pub fn new(robot: &RobotDescription, axes_deg: &[f64; 6], errors: &ChainErrors) -> Self {
        let mut frames = ChainFrames {
            link_frame: [Matrix3::identity(); 6],
            origin: [Vector3::zeros(); 6],
            tilt_axis: [[Vector3::zeros(); 3]; 6],
            joint_axis: [Vector3::zeros(); 6],
            a6_rotation: Matrix3::identity(),
            a6_origin: Vector3::zeros(),
        };
        let trig = &mut JointTrig::default();
        let (r, p) = walk(robot, axes_deg, errors, trig, |n, step| match step {
            Step::Link(r) => frames.link_frame[n] = *r,
            Step::Origin(p) => frames.origin[n] = *p,
            Step::Tilt(coord, r) => frames.tilt_axis[n][coord] = r.column(coord).into_owned(),
            Step::Joint(axis) => frames.joint_axis[n] = *axis,
        });
        frames.a6_rotation = r;
        frames.a6_origin = p;
        frames
    }

    /// Rotation of the body moved by axis n (1..=6): its frame after the joint rotation.
    pub fn body_rotation(&self, axis: usize) -> Matrix3<f64> {
        if axis < 6 {
            self.link_frame[axis]
        } else {
            self.a6_rotation
        }
    }

    /// Axis n's (1..=6) centre of rotation in the base frame, mm.
    pub fn axis_origin(&self, axis: usize) -> Vector3<f64> {
        self.origin[axis - 1]
    }

    /// The world direction of a positive KUKA rotation of axis n (1..=6).
    pub fn joint_axis(&self, axis: usize) -> Vector3<f64> {
        self.joint_axis[axis - 1]
    }

    /// The KUKA flange frame in the base frame.
    pub fn flange_pose(&self) -> Frame {
        Frame {
            rotation: self.flange_rotation(),
            position: self.a6_origin,
        }
    }

    /// The flange rotation.
    pub fn flange_rotation(&self) -> Matrix3<f64> {
        self.a6_rotation * a6_to_flange()
    }

    pub fn flange_position(&self) -> Vector3<f64> {
        self.a6_origin
    }

    /// The world position of `target_a6` (A6 frame, mm) plus the target slots of `errors`.
    pub fn target_position(&self, target_a6: &Vector3<f64>, errors: &ChainErrors) -> Vector3<f64> {
        let t = &errors.0[6 * JOINT_SLOTS..];
        self.a6_origin + self.a6_rotation * (target_a6 + Vector3::new(t[0], t[1], t[2]))
    }

    /// World motion of a slot: `(translation, rotation axis, centre)`; a pure translation has a
    /// zero axis.
    fn slot_motion(&self, slot: Slot) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let zero = Vector3::zeros();
        match slot {
            Slot::Offset { axis, coord } => {
                let n = axis as usize - 1;
                (
                    self.link_frame[n].column(coord as usize).into_owned(),
                    zero,
                    zero,
                )
            }
            Slot::Tilt { axis, coord } => {
                let n = axis as usize - 1;
                (zero, self.tilt_axis[n][coord as usize], self.origin[n])
            }
            Slot::Angle { axis } => {
                let n = axis as usize - 1;
                (zero, self.joint_axis[n], self.origin[n])
            }
            Slot::Target { coord } => (
                self.a6_rotation.column(coord as usize).into_owned(),
                zero,
                zero,
            ),
        }
    }

    /// d(point)/d(slot) for a point `p` carried by the A6 frame (the target, the flange).
    pub fn point_partial(&self, slot: Slot, p: &Vector3<f64>) -> Vector3<f64> {
        let (t, w, o) = self.slot_motion(slot);
        t + w.cross(&(p - o))
    }

    /// d(pose)/d(slot) of a frame carried by the A6 frame with origin `p`: the point's motion
    /// (mm per unit) on top of the orientation's small rotation vector (rad per unit).
    pub fn pose_partial(&self, slot: Slot, p: &Vector3<f64>) -> Vector6<f64> {
        let (t, w, o) = self.slot_motion(slot);
        let dp = t + w.cross(&(p - o));
        Vector6::new(dp.x, dp.y, dp.z, w.x, w.y, w.z)
    }

    /// d(target position)/d(slot) for every slot, indexed by [`Slot::index`].
    pub fn target_jacobian(&self, target_world: &Vector3<f64>) -> [Vector3<f64>; N_SLOTS] {
        std::array::from_fn(|i| self.point_partial(slot_of_index(i), target_world))
    }

    /// d(flange pose)/d(slot) for every slot: the flange origin's motion (mm per unit) stacked
    /// on the small rotation vector of its orientation in the base frame (rad per unit). The
    /// target slots do not move the flange.
    pub fn flange_jacobian(&self) -> [Vector6<f64>; N_SLOTS] {
        std::array::from_fn(|i| {
            let slot = slot_of_index(i);
            if matches!(slot, Slot::Target { .. }) {
                return Vector6::zeros();
            }
            self.pose_partial(slot, &self.a6_origin)
        })
    }
}

/// The slot stored at `index` of [`ChainErrors`] (inverse of [`Slot::index`]).
pub fn slot_of_index(index: usize) -> Slot {
    if index >= 6 * JOINT_SLOTS {
        return Slot::Target {
            coord: (index - 6 * JOINT_SLOTS) as u8,
        };
    }
    let axis = (index / JOINT_SLOTS + 1) as u8;
    match index % JOINT_SLOTS {
        k @ 0..=2 => Slot::Offset {
            axis,
            coord: k as u8,
        },
        k @ 3..=5 => Slot::Tilt {
            axis,
            coord: (k - 3) as u8,
        },
        _ => Slot::Angle { axis },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The flange pose's quaternion is the chain's rotation, also a half turn from the
    /// identity (flange down, the arm's A rotation near 180°), where nalgebra's iterative
    /// `from_matrix` stayed at the identity.
    #[test]
    fn flange_pose_keeps_half_turn_rotations() {
        let robot = RobotDescription::kr30ha();
        let errors = ChainErrors(std::array::from_fn(|i| 1e-4 * ((i % 3) as f64 - 1.0)));
        for axes in [
            [20.0, -75.0, 95.0, 0.0, 70.0, 10.0],
            [0.0, -90.0, 90.0, 0.0, 90.0, 0.0],
            [-135.0, -40.0, 60.0, -170.0, -95.0, 250.0],
        ] {
            for e in [ChainErrors::default(), errors] {
                let (r, p) = a6_frame(&robot, &axes, &e);
                let pose = flange_pose(&robot, &axes, &e);
                let want = r * a6_to_flange();
                let got = pose
                    .to_isometry()
                    .rotation
                    .to_rotation_matrix()
                    .into_inner();
                assert!((got - want).amax() < 1e-15, "{axes:?}: {got} vs {want}");
                assert_eq!(pose.position, p);
                let frames = ChainFrames::new(&robot, &axes, &e).flange_pose();
                assert_eq!(frames.rotation, pose.rotation);
            }
        }
    }

    /// The chain with each axis's tilts multiplied out once ([`LinkBlocks`]) and the angle
    /// slots given apart is the chain of the whole error vector, to rounding; a block without
    /// tilts is skipped, not multiplied by the identity.
    #[test]
    fn link_blocks_give_the_chain_of_the_whole_error_vector() {
        let robot = RobotDescription::kr30ha();
        let mut errors = ChainErrors(std::array::from_fn(|i| 1e-3 * ((i % 5) as f64 - 2.0)));
        // Axis 4 without tilts.
        errors.0[3 * JOINT_SLOTS + 3..3 * JOINT_SLOTS + 6].fill(0.0);
        let blocks = LinkBlocks::new(&robot, &errors);
        assert_eq!(blocks.tilted, [true, true, true, false, true, true]);
        let angles: [f64; 6] = std::array::from_fn(|n| errors.0[n * JOINT_SLOTS + 6]);
        for axes in [
            [20.0, -70.0, 110.0, 15.0, 40.0, -30.0],
            [-135.0, -40.0, 60.0, -170.0, -95.0, 250.0],
        ] {
            let (r0, p0) = a6_frame(&robot, &axes, &errors);
            let mut trig = JointTrig::default();
            let (r1, p1) = a6_frame_blocks(&robot, &axes, &blocks, &angles, &mut trig);
            assert!(
                (r1 - r0).amax() < 8.0 * f64::EPSILON,
                "{}",
                (r1 - r0).amax()
            );
            assert!((p1 - p0).amax() < 4e-12, "{}", (p1 - p0).amax());
            let lines = axis_lines_blocks(&robot, &axes, &blocks, &angles, &mut trig);
            assert_eq!((lines.a6_rotation, lines.a6_origin), (r1, p1));
            let whole = axis_lines(&robot, &axes, &errors, &mut JointTrig::default());
            for n in 0..6 {
                assert!((lines.origin[n] - whole.origin[n]).amax() < 4e-12);
                assert!((lines.joint_axis[n] - whole.joint_axis[n]).amax() < 8.0 * f64::EPSILON);
            }
            // The angle slots do matter: 1 mrad more on A2 moves the A6 origin.
            let mut more = angles;
            more[1] += 1e-3;
            let (_, p2) = a6_frame_blocks(&robot, &axes, &blocks, &more, &mut trig);
            assert!((p2 - p0).norm() > 0.5, "{}", (p2 - p0).norm());
        }
    }

    /// Sines and cosines by the addition theorem from a reference give the chain the library
    /// calls give, to a few ulps, for commands near the reference and (re-anchored) far away.
    #[test]
    fn joint_trig_near_a_reference_is_the_direct_chain() {
        let robot = RobotDescription::kr30ha();
        let errors = ChainErrors(std::array::from_fn(|i| 1e-3 * ((i % 5) as f64 - 2.0)));
        let start = [20.0, -70.0, 110.0, 15.0, 40.0, -30.0];
        let mut trig = JointTrig::default();
        let steps = [0.0, 0.03, -0.05, 0.0571, -0.0571, 0.5, 30.0];
        for (k, &step) in steps.iter().enumerate() {
            let axes: [f64; 6] = std::array::from_fn(|n| start[n] + step * (n as f64 - 2.5));
            let (r0, p0) = a6_frame(&robot, &axes, &errors);
            let (r1, p1) = a6_frame_near(&robot, &axes, &errors, &mut trig);
            assert!(
                (r1 - r0).amax() < 8.0 * f64::EPSILON,
                "step {k}: {}",
                (r1 - r0).amax()
            );
            assert!((p1 - p0).amax() < 4e-12, "step {k}: {}", (p1 - p0).amax());
        }
    }
}
