//! The per-target solver: the command axis angles for which the error model predicts the goal
//! TCP pose.
//!
//! The iteration `p_c ← p_c − (p̂(p_c) − p*)` maps a Cartesian command to axis angles
//! with the controller's nominal IK, predicts the pose there and subtracts the error. We carry
//! it out in axis space: one step is `q ← q − J⁻¹·(p̂(q) − p*)`, where `J` is the complete
//! Jacobian of the predicted TCP with respect to the axes: the error chain's, plus how the
//! command-dependent errors change with the axes (the tables' slopes, crosstalk, tilt;
//! `Effect::add_with_axis_slopes`). The chain's second-order term ([`Curvature`](crate::motion::nominal::Curvature)) is added
//! to the first step, which then lands to third order (~10⁻³ µm for a 0.3 mm, 1 mrad
//! correction): one Jacobian and one verifying evaluation per target, unless the step
//! crosses a table's grid point. (With the errors frozen in `J` the first step missed by
//! ~0.3 µm; with the slopes but no curvature by up to 0.5 µrad: two steps, three
//! evaluations.) This avoids a closed-form IK per iteration, never leaves the branch the
//! nominal solution is on, and treats axis-space targets (`PTP {A1 …}`, E6AXIS) and Cartesian
//! ones alike: both are a goal pose plus a starting command. The final Cartesian command is
//! the nominal FK of the solved axes, which the controller's IK maps back to them.
//! Along a path most targets skip the linearisation: the correction of the targets before
//! them predicts theirs ([`Chain`]), and two evaluations of the prediction (at the nominal
//! command, at the predicted one) usually settle it, within the tolerance rather than far
//! below it.
//! `--one-step` is the paper's equation (3) literally: `p_c = p* − (p̂(p*) − p*)` (orientation
//! likewise, as a world-frame rotation) followed by an exact (iterated) nominal IK.

use std::cell::RefCell;

use nalgebra::{Matrix6, Vector3, Vector6};

use std::ops::AddAssign;

use crate::kinematics::AxisAngles;
use crate::model::chain::{self, axis_lines, ChainFrames, JointTrig, LinkBlocks};
use crate::model::merged::Cells;
use crate::model::{AxisHistory, AxisSlopes, AxisState, ChainErrors, Model, Slot};
use crate::motion::frame::{self as pose, Frame};
use crate::motion::lu6::Lu6;
use crate::motion::nominal::{self, Arm, Goal, Linearized, NotConverged, LEVER_MM};

/// Convergence: 0.1 µm and 0.1 µrad on the TCP pose (the requirement).
pub const TOL_POSITION_MM: f64 = 1e-4;
pub const TOL_ROTATION_RAD: f64 = 1e-7;

/// The calibrated model with the axis histories it is evaluated at (the flank each gear play
/// is engaged on, or for an axis held still the history that says where its play stands).
pub struct Predicted<'a> {
    pub model: &'a Model,
    /// The state evaluated last: the histories stay, each evaluation writes its axes (the
    /// 400-byte state is not built again per evaluation).
    state: RefCell<AxisState>,
    /// The errors that do not change with the command (time 0), summed once per model.
    fixed: &'a ChainErrors,
    /// The joint sines and cosines of the first evaluation: the solve's later commands are
    /// millidegrees away (see [`JointTrig`]). Borrowed in place: each evaluation updates it
    /// where it stands.
    trig: RefCell<JointTrig>,
    /// The tables' cells of the last lookup, likewise (see `Grid::locate_near`); borrowed in
    /// place as `trig` is.
    cells: RefCell<Cells>,
    /// The chain's fixed part, when only the angle slots vary (see [`LinkBlocks`]).
    blocks: Option<&'a LinkBlocks>,
    /// The last tool position (its bits) with the fixed errors' tool (see [`Self::tool`]):
    /// a solve evaluates one tool at every command. Compared where it is kept: a `Cell`'s
    /// copy of it, read back in wider loads than it was stored with, stalled every evaluation.
    fixed_tool: RefCell<Option<([u64; 3], Vector3<f64>)>>,
}

impl<'a> Predicted<'a> {
    pub fn new(model: &'a Model, histories: [AxisHistory; 6]) -> Self {
        Predicted::at(model, &histories)
    }

    /// [`Self::new`] from borrowed histories (copied once, into the state).
    fn at(model: &'a Model, histories: &[AxisHistory; 6]) -> Self {
        Predicted {
            model,
            state: RefCell::new(AxisState {
                axes_deg: [0.0; 6],
                history: *histories,
                time_s: 0.0,
            }),
            fixed: model.fixed_errors_at_time_zero(),
            trig: RefCell::default(),
            cells: RefCell::default(),
            blocks: model.link_blocks(),
            fixed_tool: RefCell::new(None),
        }
    }

    /// The model at the histories of the next target of a chain, as a new one would be but
    /// for what only speeds it up (the tables' cells, the tool's position): the joint sines
    /// and cosines are set again at its first evaluation, as a new one's are, so that its
    /// results are a new one's to the bit.
    fn renew(&self, histories: &[AxisHistory; 6]) {
        self.state.borrow_mut().history = *histories;
        *self.trig.borrow_mut() = JointTrig::default();
    }

    /// The position of [`Self::tool`] with the fixed errors, kept for the next evaluation.
    fn fixed_tool_position(&self, tool: &Frame) -> Vector3<f64> {
        // Bit by bit against the tool's own numbers (a key array built here stalled likewise).
        let same = |k: &[u64; 3]| (0..3).all(|i| k[i] == tool.position[i].to_bits());
        let mut kept = self.fixed_tool.borrow_mut();
        match &*kept {
            Some((k, position)) if same(k) => *position,
            _ => {
                let position = self.model.tool_as_identified(&tool.position, self.fixed);
                let key = tool.position.map(f64::to_bits).into();
                *kept = Some((key, position));
                position
            }
        }
    }

    /// The tool as the model has it: the measurement target carries its identified correction.
    fn tool(&self, tool: &Frame, errors: &ChainErrors) -> Frame {
        Frame {
            rotation: tool.rotation,
            position: self.model.tool_as_identified(&tool.position, errors),
        }
    }

    /// The state at `axes`.
    fn state(&self, axes: &[f64; 6]) -> std::cell::Ref<'_, AxisState> {
        self.state.borrow_mut().axes_deg = *axes;
        self.state.borrow()
    }

    fn errors(&self, axes: &[f64; 6]) -> ChainErrors {
        let mut errors = *self.fixed;
        let cells = &mut self.cells.borrow_mut().axes;
        self.model
            .add_varying_errors_near(&self.state(axes), &mut errors, cells);
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
        let cells = &mut self.cells.borrow_mut().axes;
        self.model
            .add_varying_errors_with_slopes_near(&self.state(axes), errors, slopes, cells);
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
        if let Some(blocks) = self.blocks {
            // Only the angle slots vary: six sums instead of the whole error vector.
            let cells = &mut self.cells.borrow_mut();
            let angles = self.model.angle_errors_near(&self.state(axes), cells);
            let robot = &self.model.robot;
            let mut trig = self.trig.borrow_mut();
            let (r6, p6) = chain::a6_frame_blocks(robot, axes, blocks, &angles, &mut trig);
            let position = self.fixed_tool_position(tool);
            return nominal::tcp_at_a6_of(&r6, &p6, &tool.rotation, &position);
        }
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
        // The lines in place, not moved out of a (TCP, lines) pair; by the fast path's chain
        // where there is one, so that a linearisation's TCP is the one `tcp` gives, bit for bit.
        let robot = &self.model.robot;
        let mut trig = self.trig.borrow_mut();
        let lines = match self.blocks {
            Some(blocks) => {
                let angles = std::array::from_fn(|n| errors.get(Slot::Angle { axis: n as u8 + 1 }));
                chain::axis_lines_blocks(robot, axes, blocks, &angles, &mut trig)
            }
            None => axis_lines(robot, axes, &errors, &mut trig),
        };
        drop(trig);
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
    pub start: AxisAngles,
    /// Each axis's history on arrival: the flank its gear play is engaged on
    /// ([`AxisHistory::engaged`]), or, for an axis held still, where its play stands.
    pub histories: &'a [AxisHistory; 6],
    /// Axes kept at their `start` value.
    pub hold: [bool; 6],
}

impl Problem<'_> {
    /// The problem for [`nominal::newton`] at the tolerance.
    fn newton_goal(&self) -> Goal<'_> {
        Goal {
            pose: self.goal,
            tool: self.tool,
            start: *self.start,
            hold: self.hold,
            tol_mm: TOL_POSITION_MM,
            tol_rad: TOL_ROTATION_RAD,
        }
    }
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
    histories: &[AxisHistory; 6],
    axes: &[f64; 6],
    tool: &Frame,
    goal: &Frame,
) -> Vector6<f64> {
    let arm = Predicted::at(model, histories);
    pose::error(&arm.tcp(axes, tool), goal)
}

/// Solves `problem` with the calibrated model.
pub fn solve(model: &Model, problem: &Problem, method: Method) -> Result<Solution, SolveError> {
    let arm = Predicted::at(model, problem.histories);
    if method == Method::OneStep && !problem.hold.iter().any(|&h| h) {
        return one_step(&arm, problem);
    }
    nominal::newton(&arm, &problem.newton_goal())
}

/// Evaluations a warm start may take before the target is solved afresh.
const WARM_EVALUATIONS: u32 = 3;

/// What the solves along a path carry from one target to the next, so that most targets are
/// solved from a prediction instead of a linearisation: the Jacobian factored at the last
/// target solved afresh, and the last two targets solved. Along a path the correction
/// `Δq = q − q_nominal` changes smoothly: extrapolated from the two before, `2·Δq₁ − Δq₂`,
/// and what the error at the nominal command does beyond its own extrapolation (a backlash
/// branch switched, a table's grid point crossed) taken out with the stale Jacobian,
/// `−J₀⁻¹·(e − 2·e₁ + e₂)`. On the 1M-point program (2 mm pitch) the prediction lands a
/// median 0.05 µm from the goal, mostly the goals' own rounding to the written decimals, and
/// a few tenths of a micrometre after a grid point. [`nominal::quasi_newton`] finishes from
/// there; a target it does not settle within `WARM_EVALUATIONS` is solved afresh, so the
/// result always meets the tolerance. A chain is worked in order, so its results are the
/// same whoever works it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Chain {
    jacobian: Option<Lu6>,
    /// The last two targets solved, the newest at `newest` (each recorded in place: they
    /// are 150-byte records).
    recent: [Option<Solved>; 2],
    newest: usize,
    /// The tool of the targets (another tool moves the TCP elsewhere: the chain starts over).
    tool: Option<u32>,
}

/// A target solved along a [`Chain`].
#[derive(Clone, Copy, Debug)]
struct Solved {
    /// `q − q_nominal`.
    correction: [f64; 6],
    /// The error at the nominal command.
    initial: Vector6<f64>,
    /// The error left at the solution.
    residual: Vector6<f64>,
}

impl Chain {
    /// Starts the chain over where the targets change tools.
    pub fn follow_tool(&mut self, tool: u32) {
        if self.tool != Some(tool) {
            *self = Chain {
                tool: Some(tool),
                ..Chain::default()
            };
        }
    }

    /// Records the target just solved, `correction` its `q − q_nominal`, `initial` its error
    /// at the nominal command and `residual` at the solution.
    pub fn record(&mut self, correction: [f64; 6], initial: Vector6<f64>, residual: Vector6<f64>) {
        self.newest ^= 1;
        self.recent[self.newest] = Some(Solved {
            correction,
            initial,
            residual,
        });
    }

    /// The last two targets solved, newest first.
    fn last_two(&self) -> (Option<&Solved>, Option<&Solved>) {
        let (a, b) = (&self.recent[self.newest], &self.recent[self.newest ^ 1]);
        (a.as_ref(), b.as_ref())
    }

    /// A target not solved plainly: the next prediction starts over (the Jacobian stays).
    pub fn forget(&mut self) {
        self.recent = [None; 2];
    }

    /// The predicted command of a target at `nominal` whose error there is `e0`. A recorded
    /// correction is taken with its residual's share out (`Δq − J₀⁻¹·r`): a solution
    /// anywhere within the tolerance would otherwise pass its 0.1 µm on, tripled by the
    /// extrapolation. All of the Jacobian's shares are taken in one solve.
    fn predict(&self, lu: &Lu6, nominal: &[f64; 6], e0: &Vector6<f64>) -> Option<[f64; 6]> {
        let (a, b) = self.last_two();
        let a = a?;
        let (dq, de): ([f64; 6], Vector6<f64>) = match b {
            Some(b) => (
                std::array::from_fn(|i| 2.0 * a.correction[i] - b.correction[i]),
                e0 - 2.0 * a.initial + b.initial + 2.0 * a.residual - b.residual,
            ),
            None => (a.correction, e0 - a.initial + a.residual),
        };
        let fix = lu.solve(&-de)?;
        Some(std::array::from_fn(|i| nominal[i] + dq[i] + fix[i]))
    }
}

/// [`solve`] of a target along a path, from the [`Chain`]'s prediction where it has one.
#[cfg(any(test, feature = "internals"))]
pub fn solve_in_chain(
    model: &Model,
    problem: &Problem,
    chain: &mut Chain,
) -> Result<Solution, SolveError> {
    let arm = Predicted::at(model, problem.histories);
    solve_warm_or_afresh(&arm, problem, chain)
}

/// A [`Chain`] worked in order on one model evaluator, which carries from one target to the
/// next the tables' cells of the last evaluation (the next target is nearby, its first
/// lookup starts from them; a hint only: `Grid::locate_near` finds the same cell from any):
/// [`solve_in_chain`] target after target, without a new evaluator for each.
pub struct Along<'a> {
    pub chain: Chain,
    arm: Predicted<'a>,
}

impl<'a> Along<'a> {
    /// `chain` continued on `model`.
    pub fn new(model: &'a Model, chain: Chain) -> Along<'a> {
        Along {
            chain,
            arm: Predicted::new(model, [AxisHistory::unmoved(); 6]),
        }
    }

    /// [`solve_in_chain`] of the chain's next target.
    pub fn solve(&mut self, problem: &Problem) -> Result<Solution, SolveError> {
        self.arm.renew(problem.histories);
        solve_warm_or_afresh(&self.arm, problem, &mut self.chain)
    }
}

/// [`solve_in_chain`] with the model at the target's histories.
fn solve_warm_or_afresh(
    arm: &Predicted,
    problem: &Problem,
    chain: &mut Chain,
) -> Result<Solution, SolveError> {
    let goal = problem.newton_goal();
    let warm = chain.last_two().0.is_some() && !problem.hold.contains(&true);
    if let Some(lu) = chain.jacobian.as_ref().filter(|_| warm) {
        let e0 = match at_start(arm, problem) {
            Ok(there) => return Ok(there),
            Err(e0) => e0,
        };
        if let Some(q) = chain.predict(lu, &problem.start, &e0) {
            if let Some(sol) = nominal::quasi_newton(arm, &goal, q, lu, e0, WARM_EVALUATIONS) {
                return Ok(sol);
            }
        }
    }
    let mut first = None;
    let solved = nominal::newton_keeping(arm, &goal, &mut first);
    if first.is_some() {
        chain.jacobian = first;
    }
    solved
}

/// The solution at the start when the start already meets the goal, else the error there.
/// Inlined: returned through memory, the error was read back in wider loads than the
/// callee stored it with (a store-forwarding stall at every warm start).
#[inline(always)]
fn at_start(arm: &Predicted, problem: &Problem) -> Result<Solution, Vector6<f64>> {
    let e0 = pose::error(&arm.tcp(&problem.start, problem.tool), &problem.goal);
    if converged(&e0) {
        Ok(Solution {
            axes_deg: *problem.start,
            residual: e0,
            iterations: 0,
            initial: e0,
        })
    } else {
        Err(e0)
    }
}

fn one_step(arm: &Predicted, problem: &Problem) -> Result<Solution, SolveError> {
    let e0 = match at_start(arm, problem) {
        Ok(there) => return Ok(there),
        Err(e0) => e0,
    };
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
