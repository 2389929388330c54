//! The per-target solver: the command axis angles for which the error model predicts the goal
//! TCP pose.
//!
//! The iteration `p_c ← p_c − (p̂(p_c) − p*)` maps a Cartesian command to axis angles
//! with the controller's nominal IK, predicts the pose there and subtracts the error. We carry
//! it out in axis space: one step is `q ← q − J⁻¹·(p̂(q) − p*)`, where `J` is the complete
//! Jacobian of the predicted TCP with respect to the axes: the error chain's, plus how the
//! command-dependent errors change with the axes (the tables' slopes, crosstalk, tilt;
//! `Effect::add_with_axis_slopes`). The chain's second-order term ([`Curvature`]) is added
//! to the first step, which then lands to third order (~10⁻³ µm for a 0.3 mm, 1 mrad
//! correction): one Jacobian and one verifying evaluation per target, unless the step
//! crosses a table's grid point. (With the errors frozen in `J` the first step missed by
//! ~0.3 µm; with the slopes but no curvature by up to 0.5 µrad: two steps, three
//! evaluations.) This avoids a closed-form IK per iteration, never leaves the branch the
//! nominal solution is on, and treats axis-space targets (`PTP {A1 …}`, E6AXIS) and Cartesian
//! ones alike: both are a goal pose plus a starting command. The final Cartesian command is
//! the nominal FK of the solved axes, which the controller's IK maps back to them.
//! `--one-step` is the paper's equation (3) literally: `p_c = p* − (p̂(p*) − p*)` (orientation
//! likewise, as a world-frame rotation) followed by an exact (iterated) nominal IK.

use std::cell::{Cell, RefCell};

use nalgebra::{Matrix6, Vector6};

use std::ops::AddAssign;

use crate::model::chain::{axis_lines, ChainFrames, JointTrig};
use crate::model::{AxisSlopes, AxisState, ChainErrors, Direction, Model, Slot};
use crate::motion::frame::{self as pose, Frame};
use crate::motion::nominal::{self, Arm, Goal, Linearized, NotConverged, LEVER_MM};

/// Convergence: 0.1 µm and 0.1 µrad on the TCP pose (the requirement).
pub const TOL_POSITION_MM: f64 = 1e-4;
pub const TOL_ROTATION_RAD: f64 = 1e-7;

/// The calibrated model with the rotation directions it is evaluated at.
pub struct Predicted<'a> {
    pub model: &'a Model,
    pub directions: [Direction; 6],
    /// The errors that do not change with the command (time 0), summed once per model.
    fixed: &'a ChainErrors,
    /// The joint sines and cosines of the first evaluation: the solve's later commands are
    /// millidegrees away (see [`JointTrig`]). Borrowed in place (a `Cell` copied its 150
    /// bytes in and out at every evaluation).
    trig: RefCell<JointTrig>,
    /// The merged tables' cells of the last lookup, likewise (see `Grid::locate_near`).
    cells: Cell<[usize; 6]>,
}

impl<'a> Predicted<'a> {
    pub fn new(model: &'a Model, directions: [Direction; 6]) -> Self {
        Predicted {
            model,
            directions,
            fixed: model.fixed_errors_at_time_zero(),
            trig: RefCell::default(),
            cells: Cell::new([0; 6]),
        }
    }

    /// The tool as the model has it: the measurement target carries its identified correction.
    fn tool(&self, tool: &Frame, errors: &ChainErrors) -> Frame {
        Frame {
            rotation: tool.rotation,
            position: self.model.tool_as_identified(&tool.position, errors),
        }
    }

    fn state(&self, axes: &[f64; 6]) -> AxisState {
        AxisState {
            axes_deg: *axes,
            directions: self.directions,
            time_s: 0.0,
        }
    }

    fn errors(&self, axes: &[f64; 6]) -> ChainErrors {
        let mut errors = *self.fixed;
        let mut cells = self.cells.get();
        self.model
            .add_varying_errors_near(&self.state(axes), &mut errors, &mut cells);
        self.cells.set(cells);
        errors
    }

    /// The errors at `axes` and how they change with the axes, into `errors` (the fixed
    /// errors on entry) and `slopes` (zero on entry): written in place, not returned in a
    /// 700-byte pair.
    fn add_errors_with_slopes(
        &self,
        axes: &[f64; 6],
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        let mut cells = self.cells.get();
        self.model.add_varying_errors_with_slopes_near(
            &self.state(axes),
            errors,
            slopes,
            &mut cells,
        );
        self.cells.set(cells);
    }
}

/// Completes the chain's axis Jacobian `j` (errors frozen) with the errors' own change: by
/// the chain rule `dp/dA_n = ∂p/∂A_n + Σ_slots ∂p/∂slot · d slot/dA_n`. An angle slot dθ_k
/// turns axis k exactly as its command does (`θ_k = sense·(A_k + dθ_k) + offset`), so its
/// partial is column k per radian; other slots take their motion from the evaluated chain.
fn complete_jacobian(
    arm: &Predicted,
    axes: &[f64; 6],
    errors: &ChainErrors,
    slopes: &AxisSlopes,
    tcp: &Frame,
    tool: &Frame,
    j: &mut Matrix6<f64>,
) {
    let frozen = *j;
    for (k, row) in slopes.angle.iter().enumerate() {
        for (n, &s) in row.iter().enumerate() {
            if s != 0.0 {
                let column = frozen.column(k) * s.to_degrees();
                j.column_mut(n).add_assign(&column);
            }
        }
    }
    if slopes.other.is_empty() {
        return;
    }
    let frames = ChainFrames::new(&arm.model.robot, axes, errors);
    let carries_target = arm.model.tool_is_target(&tool.position);
    for &(slot, n, value) in &slopes.other {
        // The target slots move the TCP only when the tool is the measurement target.
        if matches!(slot, Slot::Target { .. }) && !carries_target {
            continue;
        }
        let partial = frames.pose_partial(slot, &tcp.position) * value;
        j.column_mut(n).add_assign(&partial);
    }
}

impl Arm for Predicted<'_> {
    fn tcp(&self, axes: &[f64; 6], tool: &Frame) -> Frame {
        let errors = self.errors(axes);
        let tool = self.tool(tool, &errors);
        nominal::tcp_of(
            &self.model.robot,
            axes,
            &errors,
            &tool,
            &mut self.trig.borrow_mut(),
        )
    }
    /// The complete Jacobian: the chain's, plus how the angle-dependent errors change with
    /// the axes (table slopes, crosstalk), so that one step lands on the fixed point up to
    /// the chain's curvature.
    fn tcp_jacobian(&self, axes: &[f64; 6], tool: &Frame) -> (Frame, Matrix6<f64>) {
        let mut lin = Linearized::default();
        self.linearize(axes, tool, &mut lin);
        (lin.tcp, lin.jacobian)
    }
    /// The complete Jacobian and the chain's curvature, the joints turning by the command
    /// plus the angle errors' change (`I + slopes`).
    fn linearize(&self, axes: &[f64; 6], tool: &Frame, out: &mut Linearized) {
        let mut errors = *self.fixed;
        let mut slopes = AxisSlopes::default();
        self.add_errors_with_slopes(axes, &mut errors, &mut slopes);
        let model_tool = self.tool(tool, &errors);
        // The lines in place, not moved out of a (TCP, lines) pair.
        let lines = axis_lines(
            &self.model.robot,
            axes,
            &errors,
            &mut self.trig.borrow_mut(),
        );
        out.tcp = nominal::tcp_on(&lines, &model_tool);
        out.jacobian = nominal::jacobian_of(&lines, &out.tcp);
        complete_jacobian(
            self,
            axes,
            &errors,
            &slopes,
            &out.tcp,
            tool,
            &mut out.jacobian,
        );
        out.curvature.set(&lines, &out.tcp.position, &slopes.angle);
        out.curved = true;
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

/// How the command is found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// The fixed-point iteration to 0.1 µm / 0.1 µrad.
    #[default]
    Iterate,
    /// The paper's equation (3) alone.
    OneStep,
}

pub use nominal::Solution;

/// The solver did not reach the tolerance (near-singular pose).
pub type SolveError = NotConverged;

pub fn converged(e: &Vector6<f64>) -> bool {
    let (p, r) = pose::norms(e);
    p < TOL_POSITION_MM && r < TOL_ROTATION_RAD
}

/// One scalar for comparing errors of different solutions: mm plus [`LEVER_MM`]·rad.
pub fn weighted_norm(e: &Vector6<f64>) -> f64 {
    let (p, r) = pose::norms(e);
    p + LEVER_MM * r
}

/// The predicted TCP error of `axes`.
pub fn predicted_error(
    model: &Model,
    directions: &[Direction; 6],
    axes: &[f64; 6],
    tool: &Frame,
    goal: &Frame,
) -> Vector6<f64> {
    let arm = Predicted::new(model, *directions);
    pose::error(&arm.tcp(axes, tool), goal)
}

/// Solves `problem` with the calibrated model.
pub fn solve(model: &Model, problem: &Problem, method: Method) -> Result<Solution, SolveError> {
    let arm = Predicted::new(model, problem.directions);
    if method == Method::OneStep && !problem.hold.iter().any(|&h| h) {
        return one_step(&arm, problem);
    }
    nominal::newton(
        &arm,
        &Goal {
            pose: problem.goal,
            tool: problem.tool,
            start: problem.start,
            hold: problem.hold,
            tol_mm: TOL_POSITION_MM,
            tol_rad: TOL_ROTATION_RAD,
        },
    )
}

fn one_step(arm: &Predicted, problem: &Problem) -> Result<Solution, SolveError> {
    let e0 = pose::error(&arm.tcp(&problem.start, problem.tool), &problem.goal);
    if converged(&e0) {
        return Ok(Solution {
            axes_deg: problem.start,
            residual: e0,
            iterations: 0,
            initial: e0,
        });
    }
    // Equation (3): p_c = p* − (p̂ − p*), applied to the whole pose.
    let command = problem.goal.moved_by(&-e0);
    let q = nominal::local_ik(&arm.model.robot, &command, problem.tool, &problem.start)?;
    let residual = pose::error(&arm.tcp(&q.axes_deg, problem.tool), &problem.goal);
    Ok(Solution {
        axes_deg: q.axes_deg,
        residual,
        iterations: 1,
        initial: e0,
    })
}
