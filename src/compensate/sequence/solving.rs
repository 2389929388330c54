//! One target solved for the model, as both the first pass and the re-check solve it: the
//! solver warm-started along a chain where one is given, the least-squares command taken near
//! a singularity, an axis that the correction moves across 0° held on the side the program's
//! status S or turn T puts it, and the result checked against the joint limits and the
//! configuration the target keeps.

use super::{Target, TargetError};
use crate::compensate::solve::{self, Method, Problem};
use crate::kinematics::{status_turn, RobotDescription};
use crate::model::{AxisHistory, Model};
use crate::motion::frame::Frame;
use crate::motion::nominal::status_turns;
use nalgebra::Vector6;

pub(super) fn tcp_error(
    model: &Model,
    tool: &Frame,
    axes: &[f64; 6],
    histories: &[AxisHistory; 6],
    goal: &Frame,
) -> Vector6<f64> {
    solve::predicted_error(model, histories, axes, tool, goal)
}

/// Solves one target with given directions and holds, checking limits and configuration.
/// An axis that the correction moves across 0° where the program's turn T fixes its sign
/// (typically A4 or A6 at exactly 0°) is held at 0° on its side — the rest of the pose
/// solved in the least-squares sense — rather than rejecting the target. Returns the axes
/// held so.
/// The first solve is warm-started along `chain` where one is given (see [`solve::Chain`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn solve_target(
    model: &Model,
    tool: &Frame,
    target: &Target,
    histories: &[AxisHistory; 6],
    start: [f64; 6],
    hold: [bool; 6],
    method: Method,
    chain: Option<&mut solve::Along>,
) -> Result<(solve::Solution, [bool; 6]), TargetError> {
    // Equation (3) is taken at the programmed (nominal) command, whatever the start.
    let start = if method == Method::OneStep && !hold.iter().any(|&h| h) {
        *target.nominal_axes
    } else {
        start
    };
    let problem = Problem {
        goal: target.goal,
        tool,
        start: start.into(),
        histories,
        hold,
    };
    let robot = &model.robot;
    // Near a singularity the goal may be out of reach in one direction: take the least-squares
    // command there (reported by its residual) rather than rejecting the target.
    // (Checked only on failure: the check costs as much as a chain evaluation.)
    let near_singular = || crate::kinematics::singularity(robot, &target.nominal_axes).is_some();
    let solve_or_best = |p: &Problem, m: Method| match solve::solve(model, p, m) {
        Ok(s) => Ok(s),
        Err(e) if near_singular() => Ok(*e.best),
        Err(e) => Err(e),
    };
    let mut sol = match chain {
        Some(chain) if method == Method::Iterate && !hold.contains(&true) => {
            match chain.solve(&problem) {
                Ok(s) => s,
                Err(e) if near_singular() => *e.best,
                Err(e) => return Err(e.into()),
            }
        }
        _ => solve_or_best(&problem, method)?,
    };
    let mut turn_held = [false; 6];
    let ((s0, t0), (mut s1, mut t1)) = status_turns(robot, &target.nominal_axes, &sol.axes_deg);
    // The solution's status and turn, known unless it is solved again.
    let mut solved = Some((s1, t1));
    let mut problem = problem;
    // A5 moved across 0° (the wrist singularity): the configuration S changes with its sign,
    // and a later Cartesian motion without S takes the configuration of this position. Held
    // on its programmed side, as a turn is.
    if target.keep.s && s0 ^ s1 == WRIST_BIT {
        (problem, turn_held) = turn_kept(&problem, WRIST_TURN_BIT, t0);
        sol = solve_or_best(&problem, Method::Iterate)?;
        (s1, t1) = status_turn(robot, &sol.axes_deg);
        solved = Some((s1, t1));
    }
    if target.keep.t && t0 != t1 && s0 == s1 {
        let retry;
        let held;
        (retry, held) = turn_kept(&problem, t0 ^ t1, t0);
        turn_held = std::array::from_fn(|i| turn_held[i] || held[i]);
        sol = solve_or_best(&retry, Method::Iterate)?;
        solved = None;
    }
    within_limits_and_configuration(robot, target, (s0, t0), &sol.axes_deg, solved)?;
    Ok((sol, turn_held))
}

/// `problem` with the axes of `changed` (bits of T) held just inside the side of zero the
/// programmed turn `t0` puts them on, and the axes held so.
pub(super) fn turn_kept<'p>(
    problem: &Problem<'p>,
    changed: u8,
    t0: u8,
) -> (Problem<'p>, [bool; 6]) {
    let mut turn_held = [false; 6];
    let mut start = problem.start;
    let mut hold = problem.hold;
    for i in 0..6 {
        if changed >> i & 1 == 1 {
            turn_held[i] = true;
            hold[i] = true;
            // Held just inside its side of zero, by more than the written decimals can
            // move it back: held at zero, the rounded target lands on the other side,
            // where the programmed T has no solution within the limits.
            start[i] = if t0 >> i & 1 == 1 {
                -TURN_MARGIN_DEG
            } else {
                TURN_MARGIN_DEG
            };
        }
    }
    let retry = Problem {
        start,
        hold,
        ..*problem
    };
    (retry, turn_held)
}

/// A solution's axes within the joint limits, and its S and T (`status`, [`status_turn`]'s
/// when not given) those of the programmed target where the target keeps them.
pub(super) fn within_limits_and_configuration(
    robot: &RobotDescription,
    target: &Target,
    (s0, t0): (u8, u8),
    axes: &[f64; 6],
    status: Option<(u8, u8)>,
) -> Result<(), TargetError> {
    for (n, (a, [lo, hi])) in axes.iter().zip(robot.limits_deg.iter()).enumerate() {
        if a < lo || a > hi {
            return Err(TargetError::OutOfLimits {
                axis: n as u8 + 1,
                value: *a,
                lo: *lo,
                hi: *hi,
            });
        }
    }
    let (s1, t1) = status.unwrap_or_else(|| status_turn(robot, axes));
    let s_bad = target.keep.s && s0 != s1;
    let t_bad = target.keep.t && t0 != t1;
    if s_bad || t_bad {
        return Err(TargetError::Configuration {
            s_from: s0,
            t_from: t0,
            s_to: s1,
            t_to: t1,
        });
    }
    Ok(())
}

/// The status bit S of A5's sign (`kinematics::status_turn`), and A5's bit of the turn T.
pub(super) const WRIST_BIT: u8 = 1 << 2;
pub(super) const WRIST_TURN_BIT: u8 = 1 << 4;

/// How far inside its programmed side of zero an axis is held to keep the target's T: ten
/// times what the written decimals (1e-4° of an orientation, 1e-3 mm) move a wrist axis.
pub(super) const TURN_MARGIN_DEG: f64 = 1e-3;
