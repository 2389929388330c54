//! Local (Newton) inverse kinematics on a kinematic chain: the axis angles near a starting set
//! whose TCP reaches a goal pose. The chain is anything that gives its TCP and the TCP's
//! Jacobian with respect to the axes ([`Arm`]): the nominal robot here (the controller's view,
//! for sampling interpolated paths), the calibrated error model in `compensate`.
//!
//! The Jacobian column of axis n is `[ω_n × (p − o_n); ω_n]` per degree, `ω_n` the world axis
//! of a positive KUKA rotation and `o_n` its centre (from the chain's frames). The first
//! Jacobian serves several steps (linear convergence at the rate of how much it changes, tiny
//! for the small corrections and path steps solved here); a step larger than
//! [`MAX_STEP_DEG`] means a near-singular Jacobian and is damped. An arm that also gives its
//! [`Curvature`] (the calibrated model) has the chain's second-order term added to the first
//! step after each linearisation. With held axes the solve is weighted least squares over the
//! free axes: position in mm, orientation in rad × [`LEVER_MM`].

use nalgebra::{Matrix3, Matrix6, Vector3, Vector6};

use super::frame::{self, Frame};
use super::lu6::Lu6;
use crate::kinematics::fk::{arm_plane, Geometry};
use crate::kinematics::{status_turn, RobotDescription};
use crate::model::chain::{self, a6_to_flange, AxisLines, JointTrig};
use crate::model::ChainErrors;

/// Orientation weight of least-squares solves and of error comparisons: 1 rad ≙ 100 mm (a
/// tool's length), so 1 mrad of tilt counts like 0.1 mm of displacement at the TCP.
pub const LEVER_MM: f64 = 100.0;
/// Iterations before giving up.
const MAX_ITERATIONS: u32 = 40;
/// A Newton step larger than this (deg, any axis) means a near-singular Jacobian: damp it.
pub const MAX_STEP_DEG: f64 = 2.0;

/// A kinematic chain as the solver sees it.
pub trait Arm {
    /// The TCP (flange · tool) in the robot base frame.
    fn tcp(&self, axes: &[f64; 6], tool: &Frame) -> Frame;
    /// The TCP and d(TCP)/d(axes) per degree.
    fn tcp_jacobian(&self, axes: &[f64; 6], tool: &Frame) -> (Frame, Matrix6<f64>);
    /// The TCP, its Jacobian and, where the arm provides it, its [`Curvature`] (which lets
    /// the first step land to third order), into `out` (in place: returned, its kilobyte was
    /// copied twice per target). By default [`Self::tcp_jacobian`] alone.
    fn linearize(&self, axes: &[f64; 6], tool: &Frame, out: &mut Linearized) {
        (out.tcp, out.jacobian) = self.tcp_jacobian(axes, tool);
        out.curved = false;
    }
}

/// An arm linearised at a command (see [`Arm::linearize`]).
#[derive(Clone, Copy, Debug)]
pub struct Linearized {
    pub tcp: Frame,
    /// d(TCP)/d(axes) per degree.
    pub jacobian: Matrix6<f64>,
    /// The chain's curvature, where `curved` (the arm provides it).
    pub curvature: Curvature,
    pub curved: bool,
}

impl Default for Linearized {
    fn default() -> Self {
        Linearized {
            tcp: Frame::identity(),
            jacobian: Matrix6::zeros(),
            curvature: Curvature {
                axis: [Vector3::zeros(); 6],
                velocity: [Vector3::zeros(); 6],
                turns: [[0.0; 6]; 6],
            },
            curved: false,
        }
    }
}

/// The second-order term of a serial chain's motion around a command. Joint k turns about
/// its world line (unit axis `ω_k` through `o_k`) by `u_k = Σ_n T_kn·dq_n` for a command step
/// `dq` (T: the identity, plus how the angle errors change with the command). Composing the
/// joint rotations (product of exponentials, the distal joint applied first) moves a point
/// `p` carried by the last body by
/// `Σ_k v_k u_k + ½ Σ_k ω_k×v_k u_k² + Σ_{i<j} ω_i×v_j u_i u_j + O(u³)`, `v_k = ω_k×(p − o_k)`,
/// and turns the orientation by `Σ_k ω_k u_k + ½ Σ_{i<j} ω_i×ω_j u_i u_j + O(u³)` (the
/// Baker–Campbell–Hausdorff series to its commutator term). The Jacobian is the linear part;
/// [`Self::second_order`] is the rest. For the corrections of compensation (u ≈ 10⁻³ rad)
/// that rest is ~0.5 µrad — above the 0.1 µrad tolerance, so a plain first step falls short.
#[derive(Clone, Copy, Debug)]
pub struct Curvature {
    /// `ω_k`, unit, world frame.
    axis: [Vector3<f64>; 6],
    /// `v_k = ω_k × (p − o_k)`, mm per rad.
    velocity: [Vector3<f64>; 6],
    /// `T_kn`, degrees of joint k per degree of command n.
    turns: [[f64; 6]; 6],
}

impl Curvature {
    /// From the chain's axis lines at the linearisation point and the TCP there, in place;
    /// `T = I + slopes` given the slopes of the angle errors (`slopes[k][n]`, rad per degree
    /// of command n).
    pub fn set(&mut self, lines: &AxisLines, tcp: &Vector3<f64>, slopes: &[[f64; 6]; 6]) {
        self.axis = lines.joint_axis;
        for (k, velocity) in self.velocity.iter_mut().enumerate() {
            *velocity = lines.joint_axis[k].cross(&(tcp - lines.origin[k]));
        }
        for (k, (turns, slopes)) in self.turns.iter_mut().zip(slopes).enumerate() {
            for (n, (t, s)) in turns.iter_mut().zip(slopes).enumerate() {
                *t = f64::from(u8::from(k == n)) + s.to_degrees();
            }
        }
    }

    /// The pose change `[Δp (mm); Δr (rad)]` of command step `dq` (deg) beyond the linear
    /// term: what is left after a step computed with the Jacobian alone.
    pub fn second_order(&self, dq: &[f64; 6]) -> Vector6<f64> {
        let u: [f64; 6] = std::array::from_fn(|k| {
            let row = &self.turns[k];
            (0..6).map(|n| row[n] * dq[n]).sum::<f64>().to_radians()
        });
        // Suffix sums over the distal joints j > i.
        let mut later_v = Vector3::zeros();
        let mut later_w = Vector3::zeros();
        let mut dp = Vector3::zeros();
        let mut dr = Vector3::zeros();
        for i in (0..6).rev() {
            let wu = self.axis[i] * u[i];
            dp += wu.cross(&(self.velocity[i] * (0.5 * u[i]) + later_v));
            dr += wu.cross(&later_w) * 0.5;
            later_v += self.velocity[i] * u[i];
            later_w += wu;
        }
        Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
    }
}

/// The TCP of a chain evaluated with `errors`.
pub fn tcp_of(
    robot: &RobotDescription,
    axes: &[f64; 6],
    errors: &ChainErrors,
    tool: &Frame,
    trig: &mut JointTrig,
) -> Frame {
    let (r6, p6) = chain::a6_frame_near(robot, axes, errors, trig);
    tcp_at_a6(&r6, &p6, tool)
}

/// The TCP carried by the A6 frame `(r6, p6)`.
pub fn tcp_at_a6(r6: &Matrix3<f64>, p6: &Vector3<f64>, tool: &Frame) -> Frame {
    tcp_at_a6_of(r6, p6, &tool.rotation, &tool.position)
}

/// [`tcp_at_a6`] of the tool `(rotation, position)` (a solver's tool position is the
/// model's, its rotation the programmed one's: no tool frame is put together per evaluation).
#[inline]
pub fn tcp_at_a6_of(
    r6: &Matrix3<f64>,
    p6: &Vector3<f64>,
    rotation: &Matrix3<f64>,
    position: &Vector3<f64>,
) -> Frame {
    let rf = r6 * a6_to_flange();
    Frame {
        rotation: rf * rotation,
        position: p6 + rf * position,
    }
}

/// The TCP and its axis Jacobian of a chain evaluated with `errors`.
pub fn tcp_jacobian_of(
    robot: &RobotDescription,
    axes: &[f64; 6],
    errors: &ChainErrors,
    tool: &Frame,
    trig: &mut JointTrig,
) -> (Frame, Matrix6<f64>) {
    let (tcp, lines) = tcp_lines_of(robot, axes, errors, tool, trig);
    (tcp, jacobian_of(&lines, &tcp))
}

/// The TCP of a chain evaluated with `errors`, with the chain's axis lines.
pub fn tcp_lines_of(
    robot: &RobotDescription,
    axes: &[f64; 6],
    errors: &ChainErrors,
    tool: &Frame,
    trig: &mut JointTrig,
) -> (Frame, AxisLines) {
    let lines = chain::axis_lines(robot, axes, errors, trig);
    (tcp_on(&lines, tool), lines)
}

/// The TCP of a chain evaluated to its axis lines.
pub fn tcp_on(lines: &AxisLines, tool: &Frame) -> Frame {
    let rf = lines.a6_rotation * a6_to_flange();
    Frame {
        rotation: rf * tool.rotation,
        position: lines.a6_origin + rf * tool.position,
    }
}

/// The axis Jacobian (per degree, errors frozen) at `tcp` from the chain's axis lines.
pub fn jacobian_of(lines: &AxisLines, tcp: &Frame) -> Matrix6<f64> {
    let mut j = Matrix6::zeros();
    for n in 0..6 {
        let w = lines.joint_axis[n] * std::f64::consts::PI / 180.0;
        let v = w.cross(&(tcp.position - lines.origin[n]));
        j.set_column(n, &Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z));
    }
    j
}

/// Quasi-Newton from a predicted command `q`: `q ← q − J₀⁻¹·(tcp(q) − goal)` with `lu`, a
/// Jacobian factored at a command nearby, for at most `evaluations` evaluations of the TCP;
/// `None` when that does not reach the goal's tolerance (the caller solves afresh). Each
/// step shrinks the error by the factor `‖I − J₀⁻¹·J‖`, a few per cent for a Jacobian taken
/// a hundred millimetres away; `initial` is the error at the nominal command, returned as
/// the solution's.
pub fn quasi_newton(
    arm: &impl Arm,
    goal: &Goal,
    mut q: [f64; 6],
    lu: &Lu6,
    initial: Vector6<f64>,
    evaluations: u32,
) -> Option<Solution> {
    for it in 1..=evaluations {
        let e = frame::error(&arm.tcp(&q, goal.tool), &goal.pose);
        if within(&e, goal.tol_mm, goal.tol_rad) {
            return Some(Solution {
                axes_deg: q,
                residual: e,
                iterations: it,
                initial,
            });
        }
        if it == evaluations {
            break;
        }
        let dq = lu.solve(&-e)?;
        if !dq.iter().all(|d| d.is_finite() && d.abs() <= MAX_STEP_DEG) {
            return None;
        }
        q.iter_mut().zip(dq.iter()).for_each(|(a, d)| *a += d);
    }
    None
}

/// The KUKA status and turn ([`status_turn`]) of a nominal command and of a solved command
/// near it, the second without trigonometry where it can. Of the bits only S bit 0 (wrist
/// point behind the A1 axis: `x < 0` in the arm plane) needs sines; `x` moves by at most
/// `(|l2| + k)·|Δθ2| + k·|Δθ3|` (k = |A3 → wrist point|, the bounds of ∂x/∂θ2 and ∂x/∂θ3 in
/// `arm_plane`), so where the nominal `|x|` exceeds that (plus a margin far above the
/// rounding of `x`) the solved command's bit is the nominal's; elsewhere (a target within
/// millimetres of the shoulder singularity) [`status_turn`] decides, so the result is always
/// `(status_turn(nominal), status_turn(solved))`.
pub fn status_turns(
    robot: &RobotDescription,
    nominal: &[f64; 6],
    solved: &[f64; 6],
) -> ((u8, u8), (u8, u8)) {
    let g = Geometry::new(robot);
    let (t2, t3) = (g.theta(1, nominal[1]), g.theta(2, nominal[2]));
    let (x, _, _, _) = arm_plane(&g, t2, t3);
    let of = |axes: &[f64; 6], behind: bool| {
        // As `status_turn`: A3 − A3(stretched) = sense3·e.
        let elbow = g.senses[2] * g.elbow(g.theta(2, axes[2]));
        let s = u8::from(behind) | u8::from(elbow >= 0.0) << 1 | u8::from(axes[4] < 0.0) << 2;
        let t = (0..6).fold(0u8, |t, i| t | u8::from(axes[i] < 0.0) << i);
        (s, t)
    };
    let (d2, d3) = (
        (g.theta(1, solved[1]) - t2).abs(),
        (g.theta(2, solved[2]) - t3).abs(),
    );
    let reach = (g.links.l2.abs() + g.k) * d2 + g.k * d3;
    let first = of(nominal, x < 0.0);
    if x.abs() > reach + 1e-6 {
        (first, of(solved, x < 0.0))
    } else {
        (first, status_turn(robot, solved))
    }
}

/// The nominal chain's errors (a static: no 360-byte zeroing per evaluation).
static NO_ERRORS: ChainErrors = ChainErrors([0.0; crate::model::N_SLOTS]);

/// The nominal robot (the controller's kinematics).
#[derive(Clone, Copy, Debug)]
pub struct Nominal<'a>(pub &'a RobotDescription);

impl Arm for Nominal<'_> {
    fn tcp(&self, axes: &[f64; 6], tool: &Frame) -> Frame {
        let (r6, p6) = chain::a6_frame_nominal(self.0, axes);
        tcp_at_a6(&r6, &p6, tool)
    }
    fn tcp_jacobian(&self, axes: &[f64; 6], tool: &Frame) -> (Frame, Matrix6<f64>) {
        tcp_jacobian_of(self.0, axes, &NO_ERRORS, tool, &mut JointTrig::default())
    }
}

/// One goal for [`newton`].
#[derive(Clone, Copy, Debug)]
pub struct Goal<'a> {
    /// The TCP pose to reach, robot base frame.
    pub pose: Frame,
    /// Flange → TCP.
    pub tool: &'a Frame,
    /// Starting axes (held axes carry their held value).
    pub start: [f64; 6],
    /// Axes kept at their `start` value (least squares over the others).
    pub hold: [bool; 6],
    /// Stop when the position error (mm) and rotation error (rad) are both below these.
    pub tol_mm: f64,
    pub tol_rad: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution {
    pub axes_deg: [f64; 6],
    /// TCP error left at the solution, `[Δp (mm); Δr (rad)]`.
    pub residual: Vector6<f64>,
    pub iterations: u32,
    /// TCP error at the start.
    pub initial: Vector6<f64>,
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("did not converge (left {position_um:.3} µm, {rotation_urad:.3} µrad after {iterations} iterations; near-singular pose?)")]
pub struct NotConverged {
    pub position_um: f64,
    pub rotation_urad: f64,
    pub iterations: u32,
    /// The best solution found (least squares where the goal cannot be reached exactly).
    pub best: Box<Solution>,
}

fn within(e: &Vector6<f64>, tol_p: f64, tol_r: f64) -> bool {
    let (p, r) = frame::norms(e);
    p < tol_p && r < tol_r
}

/// Newton iteration `q ← q − J⁻¹·(tcp(q) − goal)` from `goal.start`.
pub fn newton(arm: &impl Arm, goal: &Goal) -> Result<Solution, NotConverged> {
    newton_keeping(arm, goal, &mut None)
}

/// [`newton`], keeping in `first` the factored Jacobian at the start (left as it is when the
/// start is already on the goal, or the Jacobian is singular or held axes make it a least
/// squares problem): what [`quasi_newton`] steps with at the targets after it.
pub fn newton_keeping(
    arm: &impl Arm,
    goal: &Goal,
    first: &mut Option<Lu6>,
) -> Result<Solution, NotConverged> {
    let mut q = goal.start;
    // The Jacobian comes with the first evaluation: one chain evaluation for both.
    // Held in place (no copies of its kilobyte), replaced when the Jacobian is refreshed.
    let mut lin = Linearized::default();
    arm.linearize(&q, goal.tool, &mut lin);
    let mut e = frame::error(&lin.tcp, &goal.pose);
    let initial = e;
    if within(&e, goal.tol_mm, goal.tol_rad) {
        return Ok(Solution {
            axes_deg: q,
            residual: e,
            iterations: 0,
            initial,
        });
    }
    let weighted = |e: &Vector6<f64>| {
        let (p, r) = frame::norms(e);
        p + LEVER_MM * r
    };
    let mut best = Solution {
        axes_deg: q,
        residual: e,
        iterations: 0,
        initial,
    };
    let least_squares = goal.hold.iter().any(|&h| h);
    // Built in place (a `Stepper::new` returning it copied the factors).
    let mut stepper = Stepper {
        lu: Lu6::singular(),
        damped: true,
    };
    stepper.refactor(&lin.jacobian, &goal.hold);
    if !stepper.damped {
        *first = Some(stepper.lu);
    }
    let mut fresh = true;
    let mut it = 0;
    while it < MAX_ITERATIONS {
        it += 1;
        let mut dq = stepper.step(&lin.jacobian, &e, &goal.hold);
        // Right after a linearisation, the curvature's share of the step.
        if std::mem::take(&mut fresh) {
            let fix = lin.curved.then_some(&lin.curvature);
            if let Some(fix) = fix.and_then(|c| stepper.curvature_fix(c, &dq)) {
                dq.iter_mut().zip(fix).for_each(|(d, f)| *d += f);
            }
        }
        for (a, d) in q.iter_mut().zip(dq.iter()) {
            *a += d;
        }
        e = frame::error(&arm.tcp(&q, goal.tool), &goal.pose);
        if weighted(&e) < weighted(&best.residual) {
            best = Solution {
                axes_deg: q,
                residual: e,
                iterations: it,
                initial,
            };
        }
        let still = dq.iter().all(|d| d.abs() < 1e-11);
        if within(&e, goal.tol_mm, goal.tol_rad) || (least_squares && still) {
            return Ok(Solution {
                axes_deg: q,
                residual: e,
                iterations: it,
                initial,
            });
        }
        if still {
            // Stalled short of the goal: a singular direction (least squares reached).
            break;
        }
        // Refresh the Jacobian when progress is slow (large steps, strong table slopes).
        if it % 3 == 0 {
            arm.linearize(&q, goal.tool, &mut lin);
            fresh = true;
            stepper.refactor(&lin.jacobian, &goal.hold);
        }
    }
    let (p, r) = frame::norms(&best.residual);
    Err(NotConverged {
        position_um: p * 1e3,
        rotation_urad: r * 1e6,
        iterations: it,
        best: Box::new(best),
    })
}

/// Nominal IK near `start`: the axes whose nominal TCP is `goal`, to 1 pm / 1 prad.
pub fn local_ik(
    robot: &RobotDescription,
    goal: &Frame,
    tool: &Frame,
    start: &[f64; 6],
) -> Result<Solution, NotConverged> {
    newton(
        &Nominal(robot),
        &Goal {
            pose: *goal,
            tool,
            start: *start,
            hold: [false; 6],
            tol_mm: 1e-9,
            tol_rad: 1e-12,
        },
    )
}

/// Solves `J·dq = −e` (all axes free: LU, damped when near-singular) or the weighted least
/// squares over the free axes.
// The LU lives inline and is refactorised in place: boxing it cost one heap allocation per
// solved target, moving it two 384-byte copies.
struct Stepper {
    lu: Lu6,
    /// Least squares (held axes, or a singular `J`) instead of the LU.
    damped: bool,
}

impl Stepper {
    fn refactor(&mut self, j: &Matrix6<f64>, hold: &[bool; 6]) {
        self.damped = hold.iter().any(|&h| h);
        if !self.damped {
            self.lu.factor(j);
            self.damped = !self.lu.is_invertible();
        }
    }

    fn step(&self, j: &Matrix6<f64>, e: &Vector6<f64>, hold: &[bool; 6]) -> [f64; 6] {
        if !self.damped {
            if let Some(dq) = self.lu.solve(&-e) {
                if dq.iter().all(|d| d.is_finite() && d.abs() <= MAX_STEP_DEG) {
                    return dq.into();
                }
            }
        }
        damped_least_squares(j, e, hold)
    }

    /// The correction `c` with `J·c = −second_order(dq)`, so that `dq + c` leaves only third
    /// order terms; `None` for a least-squares step, and where `c` is not small against the
    /// step (a near-singular Jacobian, where the series says nothing).
    fn curvature_fix(&self, curvature: &Curvature, dq: &[f64; 6]) -> Option<[f64; 6]> {
        if self.damped {
            return None;
        }
        let fix: [f64; 6] = self.lu.solve(&-curvature.second_order(dq))?.into();
        let largest = |v: &[f64; 6]| v.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        let small = fix.iter().all(|f| f.is_finite()) && largest(&fix) <= 0.5 * largest(dq);
        small.then_some(fix)
    }
}

/// `min ‖W(J·dq + e)‖² + λ‖dq‖²` over the free axes, `W = diag(1,1,1,L,L,L)`; λ = 10⁻⁶ of
/// the largest diagonal entry, negligible for a regular Jacobian (whose squared singular
/// values are 10⁻³ of it or more) but enough to keep a singular wrist (A4 ∥ A6) from
/// producing a huge step; a step still larger than [`MAX_STEP_DEG`] is shortened.
#[allow(clippy::needless_range_loop)] // three arrays indexed alike
fn damped_least_squares(j: &Matrix6<f64>, e: &Vector6<f64>, hold: &[bool; 6]) -> [f64; 6] {
    let w = Vector6::new(1.0, 1.0, 1.0, LEVER_MM, LEVER_MM, LEVER_MM);
    let mut a = Matrix6::zeros();
    for c in 0..6 {
        if !hold[c] {
            a.set_column(c, &j.column(c).component_mul(&w));
        }
    }
    let b = -e.component_mul(&w);
    let mut n = a.transpose() * a;
    let scale = n.diagonal().max().max(1e-30);
    for c in 0..6 {
        n[(c, c)] += if hold[c] { 1.0 } else { 1e-6 * scale };
    }
    let rhs = a.transpose() * b;
    let dq = n
        .cholesky()
        .map(|ch| ch.solve(&rhs))
        .unwrap_or_else(Vector6::zeros);
    let mut out: [f64; 6] = dq.into();
    for c in 0..6 {
        if hold[c] || !out[c].is_finite() {
            out[c] = 0.0;
        }
    }
    let largest = out.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    if largest > MAX_STEP_DEG {
        out.iter_mut().for_each(|d| *d *= MAX_STEP_DEG / largest);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effect::N_SLOTS;
    use nalgebra::{Matrix3, Vector3};

    /// Every slot set to a small, distinct error: the chain as a calibrated model drives it.
    fn errors() -> ChainErrors {
        ChainErrors(std::array::from_fn(|i| {
            let x = ((i * 37 % N_SLOTS) as f64 / N_SLOTS as f64 - 0.5) * 2.0;
            if i % 7 < 3 || i >= 42 {
                0.3 * x // mm
            } else {
                2e-3 * x // rad
            }
        }))
    }

    fn tool() -> Frame {
        Frame {
            rotation: Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
            position: Vector3::new(-120.0, -80.0, 180.0),
        }
    }

    /// A goal out of reach is refused (`NotConverged`), with the least-squares best found,
    /// and a reachable one near a start is reached.
    #[test]
    fn newton_reaches_what_it_can_and_refuses_the_rest() {
        let robot = RobotDescription::kr30ha();
        let tool = tool();
        let start = [20.0, -70.0, 110.0, 15.0, 40.0, -30.0];
        let arm = Nominal(&robot);
        let reachable: [f64; 6] = std::array::from_fn(|n| start[n] + 0.3 * (n as f64 - 2.0));
        let goal = arm.tcp(&reachable, &tool);
        let sol = local_ik(&robot, &goal, &tool, &start).unwrap();
        for (got, want) in sol.axes_deg.iter().zip(reachable) {
            assert!((got - want).abs() < 1e-9);
        }
        let far = Frame {
            rotation: goal.rotation,
            position: goal.position * 4.0, // beyond the 3 m reach
        };
        let err = local_ik(&robot, &far, &tool, &start).unwrap_err();
        let initial = frame::norms(&err.best.initial).0;
        assert!(err.position_um > 1e5, "{err}");
        assert!(
            err.position_um * 1e-3 <= initial,
            "the best is no worse than the start"
        );
    }

    /// The analytic axis Jacobian against central differences of the TCP, with and without
    /// chain errors, at poses across the workspace.
    #[test]
    fn tcp_jacobian_matches_finite_differences() {
        let robot = RobotDescription::kr30ha();
        let tool = tool();
        let poses = [
            [0.0, -90.0, 90.0, 0.0, 30.0, 0.0],
            [20.0, -70.0, 110.0, 15.0, 40.0, -30.0],
            [-135.0, -40.0, 60.0, -170.0, -95.0, 250.0],
        ];
        for errors in [ChainErrors::default(), errors()] {
            for axes in poses {
                let trig = &mut JointTrig::default();
                let (tcp, j) = tcp_jacobian_of(&robot, &axes, &errors, &tool, trig);
                let at = tcp_of(&robot, &axes, &errors, &tool, trig);
                assert!((at.position - tcp.position).norm() < 1e-12);
                assert!((at.rotation - tcp.rotation).norm() < 1e-15);
                let h = 1e-4; // degrees
                for n in 0..6 {
                    let moved = |d: f64| {
                        let mut q = axes;
                        q[n] += d;
                        tcp_of(&robot, &q, &errors, &tool, &mut JointTrig::default())
                    };
                    let (plus, minus) = (moved(h), moved(-h));
                    let fd = frame::error(&plus, &minus) / (2.0 * h);
                    let col = j.column(n);
                    // Position mm/deg (values ~20), rotation rad/deg (0.017).
                    for r in 0..3 {
                        assert!((col[r] - fd[r]).abs() < 1e-6, "axis {n} row {r}");
                        assert!(
                            (col[r + 3] - fd[r + 3]).abs() < 1e-10,
                            "axis {n} row {}",
                            r + 3
                        );
                    }
                }
            }
        }
    }

    /// The status and turn of a solved command near the nominal one are [`status_turn`]'s,
    /// also across the shoulder singularity (x = 0), where the bound cannot decide.
    #[test]
    fn status_turns_are_status_turn() {
        let robot = RobotDescription::kr30ha();
        // A2 where the wrist point is over the A1 axis: x = 0 on the arm plane, found by
        // bisection on the library's `status_turn` (S bit 0 flips there).
        let behind = |a2: f64| status_turn(&robot, &[10.0, a2, 60.0, 5.0, 30.0, 0.0]).0 & 1;
        let (mut lo, mut hi) = (-135.0, 35.0);
        assert_ne!(behind(lo), behind(hi));
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if behind(mid) == behind(lo) {
                lo = mid
            } else {
                hi = mid
            }
        }
        let mut crossed = 0;
        for (a2, step) in [
            (lo, 1e-3),
            (lo - 1e-4, 2e-4),
            (hi + 1e-9, -1e-6),
            (-60.0, 0.05),
        ] {
            let nominal = [10.0, a2, 60.0, 5.0, 30.0, 0.0];
            for k in -3..=3 {
                let d = step * f64::from(k);
                let solved = [10.0 - d, a2 + d, 60.0 + 0.5 * d, -5.0, 30.0, -d];
                let got = status_turns(&robot, &nominal, &solved);
                let want = (status_turn(&robot, &nominal), status_turn(&robot, &solved));
                assert_eq!(got, want, "A2 {a2} step {d}");
                crossed += usize::from(want.0 .0 != want.1 .0);
            }
        }
        assert!(crossed > 0, "some pair crosses x = 0");
    }

    use proptest::prelude::*;

    proptest! {
        /// The TCP that comes with the Jacobian is the plain TCP bit for bit (the simulation
        /// hands it on as the next segment's start instead of evaluating the chain again).
        #[test]
        fn jacobian_tcp_is_the_tcp_exactly(
            axes in proptest::array::uniform6(-350.0f64..350.0),
            tool in proptest::array::uniform6(-200.0f64..200.0),
        ) {
            let robot = RobotDescription::kr30ha();
            let tool = Frame::from_kuka(&crate::kinematics::Pose::from_array(tool));
            let arm = Nominal(&robot);
            prop_assert_eq!(arm.tcp_jacobian(&axes, &tool).0, arm.tcp(&axes, &tool));
        }

        /// The nominal chain's own walk is the error chain's with every slot zero, bit for
        /// bit (signed zeros included: whole-degree and zero axes are common in programs).
        #[test]
        fn nominal_tcp_is_the_error_chain_at_zero(
            axes in proptest::array::uniform6(prop_oneof![
                -350.0f64..350.0,
                (-4i32..=4).prop_map(|k| f64::from(k) * 90.0),
                Just(-0.0f64),
            ]),
            tool in proptest::array::uniform6(-200.0f64..200.0),
        ) {
            let robot = RobotDescription::kr30ha();
            let tool = Frame::from_kuka(&crate::kinematics::Pose::from_array(tool));
            let slow = tcp_of(&robot, &axes, &NO_ERRORS, &tool, &mut JointTrig::default());
            let fast = Nominal(&robot).tcp(&axes, &tool);
            let bits = |f: &Frame| {
                f.rotation.iter().chain(f.position.iter()).map(|x| x.to_bits()).collect::<Vec<_>>()
            };
            prop_assert_eq!(bits(&fast), bits(&slow));
        }
    }
}
