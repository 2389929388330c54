//! The per-target solver: the command axis angles for which the error model predicts the goal
//! TCP pose.
//!
//! The iteration `p_c ← p_c − (p̂(p_c) − p*)` maps a Cartesian command to axis angles
//! with the controller's nominal IK, predicts the pose there and subtracts the error. We carry
//! it out in axis space: one step is `q ← q − J⁻¹·(p̂(q) − p*)`, where `J` is the chain's
//! Jacobian with respect to the axes at the TCP — the linearisation of "nominal IK of the
//! corrected pose" around the current command (the two differ by the model's error
//! gradient, ~10⁻³, so both converge to the same fixed point `p̂(q) = p*` and at almost the
//! same rate). This avoids a closed-form IK per iteration, never leaves the branch the
//! nominal solution is on, and treats axis-space targets (`PTP {A1 …}`, E6AXIS) and Cartesian
//! ones alike: both are a goal pose plus a starting command. The final Cartesian command is
//! the nominal FK of the solved axes, which the controller's IK maps back to them.
//! `--one-step` is the paper's equation (3) literally: `p_c = p* − (p̂(p*) − p*)` (orientation
//! likewise, as a world-frame rotation) followed by an exact (iterated) nominal IK.
//!
//! Holding axes (the oscillation resolution) turns the solve into weighted least squares over
//! the free axes: position error in mm, orientation error in rad times [`LEVER_MM`].

use nalgebra::{Matrix6, Vector6};

use super::pose::{self, Frame};
use crate::model::chain::{self, a6_to_flange, ChainFrames};
use crate::model::{AxisState, ChainErrors, Direction, Model};

/// Convergence: 0.1 µm and 0.1 µrad on the TCP pose (the requirement).
pub const TOL_POSITION_MM: f64 = 1e-4;
pub const TOL_ROTATION_RAD: f64 = 1e-7;
/// Orientation weight of least-squares solves and of error comparisons: 1 rad ≙ 100 mm (a
/// tool's length), so 1 mrad of tilt counts like 0.1 mm of displacement at the TCP.
pub const LEVER_MM: f64 = 100.0;
/// Iterations before giving up (convergence is linear with a rate of the model's gradient,
/// ~10⁻³: three or four steps suffice when the target is regular).
const MAX_ITERATIONS: u32 = 40;
/// A Newton step larger than this (deg, any axis) means a near-singular Jacobian: damp it.
const MAX_STEP_DEG: f64 = 2.0;

/// Which chain predicts: the calibrated model, or the nominal robot (the controller's view).
#[derive(Clone, Copy)]
pub enum Chain<'a> {
    Model(&'a Model),
    Nominal(&'a crate::kinematics::RobotDescription),
}

impl Chain<'_> {
    fn robot(&self) -> &crate::kinematics::RobotDescription {
        match self {
            Chain::Model(m) => &m.robot,
            Chain::Nominal(r) => r,
        }
    }

    fn errors(&self, axes: &[f64; 6], directions: &[Direction; 6]) -> ChainErrors {
        match self {
            Chain::Model(m) => m.chain_errors(&AxisState {
                axes_deg: *axes,
                directions: *directions,
                time_s: 0.0,
            }),
            Chain::Nominal(_) => ChainErrors::default(),
        }
    }

    /// The TCP (flange · tool) in the robot base frame.
    pub fn tcp(&self, axes: &[f64; 6], directions: &[Direction; 6], tool: &Frame) -> Frame {
        let (r6, p6) = chain::a6_frame(self.robot(), axes, &self.errors(axes, directions));
        let rf = r6 * a6_to_flange();
        Frame {
            rotation: rf * tool.rotation,
            position: p6 + rf * tool.position,
        }
    }

    /// The TCP and d(TCP)/d(axes): column n is `[ω_n × (p − o_n); ω_n]` per degree, with
    /// `ω_n` the world axis of a positive KUKA rotation and `o_n` its centre.
    pub fn tcp_jacobian(
        &self,
        axes: &[f64; 6],
        directions: &[Direction; 6],
        tool: &Frame,
    ) -> (Frame, Matrix6<f64>) {
        let frames = ChainFrames::new(self.robot(), axes, &self.errors(axes, directions));
        let rf = frames.flange_rotation();
        let tcp = Frame {
            rotation: rf * tool.rotation,
            position: frames.flange_position() + rf * tool.position,
        };
        let mut j = Matrix6::zeros();
        for n in 1..=6 {
            let w = frames.joint_axis(n) * std::f64::consts::PI / 180.0;
            let v = w.cross(&(tcp.position - frames.axis_origin(n)));
            j.set_column(n - 1, &Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z));
        }
        (tcp, j)
    }
}

/// One target to solve.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    /// The programmed TCP pose in the robot base frame.
    pub goal: Frame,
    /// Flange → TCP.
    pub tool: &'a Frame,
    /// Starting command (the nominal axes; held axes carry their held value).
    pub start: [f64; 6],
    /// Rotation direction of each axis on arrival (the backlash branch).
    pub directions: [Direction; 6],
    /// Axes kept at their `start` value.
    pub hold: [bool; 6],
}

/// How the command was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// The fixed-point iteration to 0.1 µm / 0.1 µrad.
    #[default]
    Iterate,
    /// The paper's equation (3) alone.
    OneStep,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution {
    pub axes_deg: [f64; 6],
    /// Predicted TCP error left at the command: `[Δp (mm); Δr (rad)]`.
    pub residual: Vector6<f64>,
    pub iterations: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error("the compensation did not converge (left {position_um:.3} µm, {rotation_urad:.3} µrad after {iterations} iterations; near-singular pose?)")]
    NotConverged {
        position_um: f64,
        rotation_urad: f64,
        iterations: u32,
    },
}

pub fn converged(e: &Vector6<f64>) -> bool {
    let (p, r) = pose::norms(e);
    p < TOL_POSITION_MM && r < TOL_ROTATION_RAD
}

/// One scalar for comparing errors of different solutions: mm plus [`LEVER_MM`]·rad.
pub fn weighted_norm(e: &Vector6<f64>) -> f64 {
    let (p, r) = pose::norms(e);
    p + LEVER_MM * r
}

/// Solves `problem` with the calibrated model.
pub fn solve(model: &Model, problem: &Problem, method: Method) -> Result<Solution, SolveError> {
    let chain = Chain::Model(model);
    match method {
        Method::OneStep if !problem.hold.iter().any(|&h| h) => one_step(model, problem),
        _ => iterate(chain, problem, TOL_POSITION_MM, TOL_ROTATION_RAD),
    }
}

/// Nominal IK near `start`: the axes whose nominal TCP is `goal`, to 1 pm / 1 prad.
pub fn local_ik(
    robot: &crate::kinematics::RobotDescription,
    goal: &Frame,
    tool: &Frame,
    start: &[f64; 6],
) -> Result<Solution, SolveError> {
    let problem = Problem {
        goal: *goal,
        tool,
        start: *start,
        directions: [Direction::Unknown; 6],
        hold: [false; 6],
    };
    iterate(Chain::Nominal(robot), &problem, 1e-9, 1e-12)
}

fn one_step(model: &Model, problem: &Problem) -> Result<Solution, SolveError> {
    let chain = Chain::Model(model);
    let e0 = pose::error(
        &chain.tcp(&problem.start, &problem.directions, problem.tool),
        &problem.goal,
    );
    if converged(&e0) {
        return Ok(Solution {
            axes_deg: problem.start,
            residual: e0,
            iterations: 0,
        });
    }
    // Equation (3): p_c = p* − (p̂ − p*), applied to the whole pose.
    let command = problem.goal.moved_by(&-e0);
    let q = local_ik(&model.robot, &command, problem.tool, &problem.start)?;
    let residual = pose::error(
        &chain.tcp(&q.axes_deg, &problem.directions, problem.tool),
        &problem.goal,
    );
    Ok(Solution {
        axes_deg: q.axes_deg,
        residual,
        iterations: 1,
    })
}

fn within(e: &Vector6<f64>, tol_p: f64, tol_r: f64) -> bool {
    let (p, r) = pose::norms(e);
    p < tol_p && r < tol_r
}

fn iterate(
    chain: Chain,
    problem: &Problem,
    tol_p: f64,
    tol_r: f64,
) -> Result<Solution, SolveError> {
    let dirs = &problem.directions;
    let mut q = problem.start;
    let e = pose::error(&chain.tcp(&q, dirs, problem.tool), &problem.goal);
    if within(&e, tol_p, tol_r) {
        return Ok(Solution {
            axes_deg: q,
            residual: e,
            iterations: 0,
        });
    }
    let least_squares = problem.hold.iter().any(|&h| h);
    let (_, mut j) = chain.tcp_jacobian(&q, dirs, problem.tool);
    let mut stepper = Stepper::new(&j, &problem.hold);
    let mut e = e;
    for it in 1..=MAX_ITERATIONS {
        let dq = stepper.step(&j, &e, &problem.hold);
        for (a, d) in q.iter_mut().zip(dq.iter()) {
            *a += d;
        }
        e = pose::error(&chain.tcp(&q, dirs, problem.tool), &problem.goal);
        let still = dq.iter().all(|d| d.abs() < 1e-11);
        if within(&e, tol_p, tol_r) || (least_squares && still) {
            return Ok(Solution {
                axes_deg: q,
                residual: e,
                iterations: it,
            });
        }
        // The first Jacobian serves while it converges; refresh it when progress is slow
        // (large corrections, strong table slopes).
        if it % 3 == 0 {
            j = chain.tcp_jacobian(&q, dirs, problem.tool).1;
            stepper = Stepper::new(&j, &problem.hold);
        }
    }
    let (p, r) = pose::norms(&e);
    Err(SolveError::NotConverged {
        position_um: p * 1e3,
        rotation_urad: r * 1e6,
        iterations: MAX_ITERATIONS,
    })
}

/// Solves `J·dq = −e` (all axes free, LU, damped when near-singular) or the weighted least
/// squares over the free axes.
enum Stepper {
    Lu(nalgebra::LU<f64, nalgebra::U6, nalgebra::U6>),
    Damped,
}

impl Stepper {
    fn new(j: &Matrix6<f64>, hold: &[bool; 6]) -> Stepper {
        if hold.iter().any(|&h| h) {
            return Stepper::Damped;
        }
        let lu = j.lu();
        if lu.is_invertible() {
            Stepper::Lu(lu)
        } else {
            Stepper::Damped
        }
    }

    fn step(&self, j: &Matrix6<f64>, e: &Vector6<f64>, hold: &[bool; 6]) -> [f64; 6] {
        if let Stepper::Lu(lu) = self {
            if let Some(dq) = lu.solve(&-e) {
                if dq.iter().all(|d| d.is_finite() && d.abs() <= MAX_STEP_DEG) {
                    return dq.into();
                }
            }
        }
        damped_least_squares(j, e, hold)
    }
}

/// `min ‖W(J·dq + e)‖² + λ‖dq‖²` over the free axes, `W = diag(1,1,1,L,L,L)`; λ is tiny,
/// only to keep a singular wrist (A4 ∥ A6) from producing a huge step.
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
        n[(c, c)] += if hold[c] { 1.0 } else { 1e-12 * scale };
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
    out
}
