//! The solver's linearisation of the predicted pose: the complete Jacobian (the chain's plus
//! how the angle-dependent errors change with the axes) against central differences of the
//! predicted TCP, the chain's second-order term against the chain itself, and the first
//! step that together they make exact enough to need no second.

use nalgebra::{Matrix3, Vector3, Vector6};
use robopost::compensate::solve::{self, Predicted, Problem};
use robopost::compensate::Method;
use robopost::model::chain::JointTrig;
use robopost::model::effects::compliance::Compliance;
use robopost::model::effects::tilt::Tilt;
use robopost::model::{AxisHistory, AxisState, Direction, Model};
use robopost::motion::frame::{self, Frame};
use robopost::motion::nominal::{self, Arm, Nominal};

use super::handset;

fn tool() -> Frame {
    Frame {
        rotation: Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
        position: Vector3::new(-120.0, -80.0, 180.0),
    }
}

/// Poses away from the tables' grid points (5° and 10° pitches, crosstalk columns 58/105/153°
/// for A3), where every map, backlash and crosstalk slope is that of one cell.
const POSES: [[f64; 6]; 3] = [
    [21.3, -72.4, 108.6, 16.2, 41.7, -31.1],
    [-133.7, -41.2, 63.3, -167.9, -93.6, 247.2],
    [3.1, -97.8, 121.4, 2.6, 58.3, 7.9],
];

/// Axis histories to evaluate at pose `axes`: gears engaged on either flank or unknown, and
/// gears of A1, A3 and A6 inside their play (the command went back by less than the play
/// lately), where the output stands still and the command's slope is the play's.
fn histories(axes: &[f64; 6]) -> [[AxisHistory; 6]; 4] {
    let mut inside = [AxisHistory::engaged(Direction::Positive); 6];
    for n in [0, 2, 5] {
        inside[n].push(axes[n] + 0.002);
    }
    let [a, b, c] = flanks();
    [a, b, c, inside]
}

/// Gears engaged on either flank, or unknown: what a solve assumes for a moving axis.
fn flanks() -> [[AxisHistory; 6]; 3] {
    use Direction::*;
    [
        [AxisHistory::engaged(Positive); 6],
        [AxisHistory::engaged(Negative); 6],
        [Positive, Negative, Positive, Negative, Unknown, Positive].map(AxisHistory::engaged),
    ]
}

/// The hand-set model plus a tilt effect (slopes in slots other than the angles) and a
/// compliance effect (slopes by the trait's numerical default).
fn full_model() -> Model {
    let mut model = handset();
    let mut tilt = Tilt::zeros(2);
    tilt.values = [0.004, -0.003, 0.002, 0.001, -0.002, 0.003, -0.001, 0.002];
    model.push(Box::new(tilt));
    model.push(Box::new(Compliance {
        axis: 3,
        compliance: [0.02],
    }));
    model
}

/// d(TCP)/d(axes) per degree by central differences (h in degrees).
fn finite_differences(arm: &impl Arm, axes: &[f64; 6], tool: &Frame, h: f64) -> [Vector6<f64>; 6] {
    std::array::from_fn(|n| {
        let moved = |d: f64| {
            let mut q = *axes;
            q[n] += d;
            arm.tcp(&q, tool)
        };
        frame::error(&moved(h), &moved(-h)) / (2.0 * h)
    })
}

/// The complete Jacobian is the derivative of the predicted TCP, for both backlash branches,
/// with crosstalk, tilt and compliance; the chain's Jacobian alone (errors frozen) is not:
/// it misses the tables' slopes by far more than the tolerance.
#[test]
fn complete_jacobian_matches_finite_differences_of_the_prediction() {
    let tool = tool();
    for model in [handset(), full_model()] {
        for axes in POSES {
            for dirs in histories(&axes) {
                let arm = Predicted::new(&model, dirs);
                let (tcp, j) = arm.tcp_jacobian(&axes, &tool);
                let plain = arm.tcp(&axes, &tool);
                assert!((tcp.position - plain.position).norm() < 1e-12);
                let fd = finite_differences(&arm, &axes, &tool, 1e-4);
                let frozen = frozen_jacobian(&model, dirs, &axes, &tool);
                let mut missed = 0.0f64;
                for n in 0..6 {
                    for r in 0..6 {
                        // Position mm/deg (values ~20), rotation rad/deg (0.017).
                        let tol = if r < 3 { 2e-7 } else { 2e-11 };
                        let (got, want) = (j[(r, n)], fd[n][r]);
                        assert!(
                            (got - want).abs() < tol,
                            "axes {axes:?} dirs {dirs:?} column {n} row {r}: {got} vs {want}"
                        );
                        if r < 3 {
                            missed = missed.max((frozen[(r, n)] - want).abs());
                        }
                    }
                }
                assert!(missed > 1e-4, "the slopes matter here: {missed}");
            }
        }
    }
}

/// The chain's Jacobian with the errors of `axes` held fixed (the frozen-error
/// linearisation the solver used before).
fn frozen_jacobian(
    model: &Model,
    dirs: [AxisHistory; 6],
    axes: &[f64; 6],
    tool: &Frame,
) -> nalgebra::Matrix6<f64> {
    let state = AxisState {
        axes_deg: *axes,
        history: dirs,
        time_s: 0.0,
    };
    let errors = model.chain_errors(&state);
    let tool = Frame {
        rotation: tool.rotation,
        position: model.tool_as_identified(&tool.position, &errors),
    };
    nominal::tcp_jacobian_of(
        &model.robot,
        axes,
        &errors,
        &tool,
        &mut JointTrig::default(),
    )
    .1
}

/// The second-order term of the linearisation is what a step really adds beyond the
/// Jacobian's linear part: the left-over after subtracting it is third order (~100 times
/// smaller for a 1 mrad step).
#[test]
fn curvature_is_the_chains_second_order_term() {
    let tool = tool();
    let model = full_model();
    for axes in POSES {
        let arm = Predicted::new(&model, [AxisHistory::engaged(Direction::Positive); 6]);
        let mut lin = nominal::Linearized::default();
        arm.linearize(&axes, &tool, &mut lin);
        assert!(lin.curved, "the model arm gives its curvature");
        let curvature = lin.curvature;
        for step in [0.06, -0.04] {
            let dq: [f64; 6] = std::array::from_fn(|n| step * (1.0 + 0.3 * n as f64));
            let q: [f64; 6] = std::array::from_fn(|n| axes[n] + dq[n]);
            let moved = arm.tcp(&q, &tool);
            let actual = frame::error(&moved, &lin.tcp);
            let linear = lin.jacobian * Vector6::from(dq);
            let second = curvature.second_order(&dq);
            let left = actual - linear - second;
            let (sp, sr) = frame::norms(&second);
            let (lp, lr) = frame::norms(&left);
            assert!(sp > 1e-4 && sr > 1e-7, "a visible second order: {sp} {sr}");
            assert!(lp < 0.03 * sp, "position: {lp} of {sp}");
            assert!(lr < 0.03 * sr, "rotation: {lr} of {sr}");
        }
    }
}

/// With the complete Jacobian and the curvature, one step meets the tolerance (the plain
/// chain Jacobian needed two): the goal is the nominal pose of a command, so the correction
/// is the model's whole error (~0.3 mm, ~1 mrad).
#[test]
fn one_step_reaches_the_tolerance() {
    let tool = tool();
    let model = handset();
    let nominal = Nominal(&model.robot);
    for axes in POSES {
        for dirs in flanks() {
            let problem = Problem {
                goal: nominal.tcp(&axes, &tool),
                tool: &tool,
                start: axes.into(),
                histories: &dirs,
                hold: [false; 6],
            };
            let sol = solve::solve(&model, &problem, Method::Iterate).unwrap();
            let (p0, _) = frame::norms(&sol.initial);
            assert!(p0 > 0.1, "a real correction: {p0} mm");
            assert_eq!(sol.iterations, 1, "{axes:?} {dirs:?}: {sol:?}");
            let left = solve::predicted_error(&model, &dirs, &sol.axes_deg, &tool, &problem.goal);
            assert!(solve::converged(&left));
            // Far below the tolerance, not just under it: third-order terms only.
            let (p, r) = frame::norms(&left);
            assert!(p < 1e-5 && r < 1e-8, "{p} mm {r} rad");
        }
    }
}

/// Smooth effects only (geometry, tilt of three axes, compliance of two by the numerical
/// default), so that central differences hold at any pose.
fn smooth_model() -> Model {
    let mut model = super::nominal();
    for (axis, scale) in [(2, 1.0), (3, -0.7), (5, 0.5)] {
        let mut tilt = Tilt::zeros(axis);
        tilt.values =
            [0.004, -0.003, 0.002, 0.001, -0.002, 0.003, -0.001, 0.002].map(|v| v * scale);
        model.push(Box::new(tilt));
    }
    for axis in [2, 3] {
        model.push(Box::new(Compliance {
            axis,
            compliance: [0.03],
        }));
    }
    model
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config::with_cases(64))]
    /// The complete Jacobian is the derivative of the prediction anywhere in the workspace.
    #[test]
    fn complete_jacobian_is_the_derivative_anywhere(
        a1 in -180.0f64..180.0, a2 in -130.0f64..30.0, a3 in -110.0f64..150.0,
        a4 in -340.0f64..340.0, a5 in -115.0f64..115.0, a6 in -340.0f64..340.0,
    ) {
        let model = smooth_model();
        let tool = tool();
        let axes = [a1, a2, a3, a4, a5, a6];
        let arm = Predicted::new(&model, [AxisHistory::engaged(Direction::Positive); 6]);
        let (_, j) = arm.tcp_jacobian(&axes, &tool);
        let fd = finite_differences(&arm, &axes, &tool, 1e-4);
        for n in 0..6 {
            for r in 0..6 {
                let tol = if r < 3 { 2e-7 } else { 2e-11 };
                proptest::prop_assert!((j[(r, n)] - fd[n][r]).abs() < tol, "column {} row {}", n, r);
            }
        }
    }
}

/// Along a path at a CAM program's 2 mm pitch, the chain's warm starts ([`solve::Chain`])
/// reach the tolerance at every target (checked by evaluating the model again at the
/// result), land within the tolerance's reach of the solve from scratch, and take one
/// evaluation at most targets; where the backlash branch switches mid-path they still
/// converge.
#[test]
fn warm_starts_along_a_path_meet_the_tolerance() {
    use Direction::{Negative, Positive};
    let tool = tool();
    let model = handset();
    let nominal = Nominal(&model.robot);
    let start = POSES[0];
    let origin = nominal.tcp(&start, &tool);
    let mut chain = solve::Chain::default();
    let mut axes = start;
    let (mut single, n) = (0, 150);
    for k in 0..n {
        let goal = Frame {
            rotation: origin.rotation,
            position: origin.position + Vector3::new(2.0, 0.6, -0.9) * k as f64,
        };
        axes = nominal::local_ik(&model.robot, &goal, &tool, &axes)
            .unwrap()
            .axes_deg;
        // A1 turns back two thirds of the way: its backlash branch switches.
        let mut dirs = [Positive; 6];
        if k >= 100 {
            dirs[0] = Negative;
        }
        let histories = dirs.map(AxisHistory::engaged);
        let problem = Problem {
            goal,
            tool: &tool,
            start: axes.into(),
            histories: &histories,
            hold: [false; 6],
        };
        let warm = solve::solve_in_chain(&model, &problem, &mut chain).unwrap();
        let cold = solve::solve(&model, &problem, Method::Iterate).unwrap();
        chain.record(
            std::array::from_fn(|i| warm.axes_deg[i] - axes[i]),
            warm.initial,
            warm.residual,
        );
        let left = solve::predicted_error(&model, &histories, &warm.axes_deg, &tool, &goal);
        assert!(solve::converged(&left), "target {k}: {left:?}");
        assert!(
            (left - warm.residual).norm() < 1e-9,
            "target {k}: the residual is the model's"
        );
        assert_eq!(warm.initial, cold.initial, "target {k}");
        // Both within 0.1 µm of the goal: the commands differ by what that allows at the
        // TCP (the wrist's lever turns 0.2 µm into some 10⁻⁵ degrees at most).
        let apart = warm
            .axes_deg
            .iter()
            .zip(cold.axes_deg)
            .fold(0.0f64, |m, (w, c)| m.max((w - c).abs()));
        assert!(apart < 1e-4, "target {k}: {apart}°");
        single += usize::from(warm.iterations == 1);
    }
    assert!(single * 10 >= n * 7, "{single} of {n} in one evaluation");
}

/// The solver's fast path (only the angle slots vary: the chain's fixed part multiplied out
/// once per model, six angles summed per evaluation) predicts the TCP the model's whole error
/// vector gives (`Model::flange_pose`, every effect summed afresh), for the paper's model; a
/// model with a tilt effect (which moves tilt slots with the axes) takes the general path.
#[test]
fn the_angle_only_fast_path_predicts_the_whole_model() {
    let tool = tool();
    let model = handset();
    assert!(!model.tool_is_target(&tool.position));
    assert!(
        model.link_blocks().is_some(),
        "maps, backlash and crosstalk move angles only"
    );
    for axes in POSES {
        for dirs in flanks() {
            let state = AxisState {
                axes_deg: axes,
                history: dirs,
                time_s: 0.0,
            };
            let flange = model.flange_pose(&state);
            let want = flange.rotation * tool.position + flange.position;
            let goal = Frame {
                rotation: flange.rotation * tool.rotation,
                position: want,
            };
            let e = solve::predicted_error(&model, &dirs, &axes, &tool, &goal);
            let (p, r) = frame::norms(&e);
            assert!(p < 1e-9 && r < 1e-12, "{axes:?} {dirs:?}: {p} mm {r} rad");
            // And the model's errors are real there: the nominal TCP is far off.
            let nominal = Nominal(&model.robot).tcp(&axes, &tool);
            assert!((nominal.position - want).norm() > 0.05);
        }
    }
    assert!(
        smooth_model().link_blocks().is_none(),
        "a tilt effect moves tilt slots"
    );
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config::with_cases(24))]
    /// A chain worked on one evaluator ([`solve::Along`], which keeps its table cells and tool
    /// from one target to the next) solves every target as a new evaluator per target does
    /// ([`solve::solve_in_chain`]), to the bit: along a random path, with the backlash
    /// branches switching, the tool changing and targets forgotten, on the paper's model
    /// (its fast path) and on a model with a tilt and compliance (the general path).
    #[test]
    fn one_evaluator_along_a_chain_solves_as_new_ones(
        pose in 0usize..3,
        step in proptest::array::uniform3(-3.0f64..3.0),
        turn in 0.0f64..2e-3,
        events in proptest::collection::vec(0u8..8, 40),
        full in proptest::bool::ANY,
    ) {
        use Direction::{Negative, Positive};
        let model = if full { full_model() } else { handset() };
        let tools = [tool(), Frame { position: Vector3::new(30.0, 10.0, 250.0), ..tool() }];
        let origin = Nominal(&model.robot).tcp(&POSES[pose], &tools[0]);
        let (mut fresh, mut along) = (solve::Chain::default(), solve::Along::new(&model, solve::Chain::default()));
        let (mut axes, mut dirs, mut t) = (POSES[pose], [Positive; 6], 0usize);
        for (k, &event) in events.iter().enumerate() {
            match event {
                0 => dirs[k % 6] = if dirs[k % 6] == Positive { Negative } else { Positive },
                1 => t = 1 - t,
                _ => {}
            }
            let goal = Frame {
                rotation: origin.rotation * nalgebra::Rotation3::from_euler_angles(turn * k as f64, 0.0, 0.0).into_inner(),
                position: origin.position + Vector3::from(step) * k as f64,
            };
            let Ok(ik) = nominal::local_ik(&model.robot, &goal, &tools[t], &axes) else { break };
            axes = ik.axes_deg;
            let histories = dirs.map(AxisHistory::engaged);
            let problem = Problem { goal, tool: &tools[t], start: axes.into(), histories: &histories, hold: [false; 6] };
            fresh.follow_tool(t as u32);
            along.chain.follow_tool(t as u32);
            let a = solve::solve_in_chain(&model, &problem, &mut fresh);
            let b = along.solve(&problem);
            let (a, b) = match (a, b) {
                (Ok(a), Ok(b)) => (a, b),
                (a, b) => {
                    proptest::prop_assert_eq!(a.is_ok(), b.is_ok(), "target {}", k);
                    fresh.forget();
                    along.chain.forget();
                    continue;
                }
            };
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            proptest::prop_assert_eq!(bits(&a.axes_deg), bits(&b.axes_deg), "target {}", k);
            proptest::prop_assert_eq!(bits(a.residual.as_slice()), bits(b.residual.as_slice()));
            proptest::prop_assert_eq!(bits(a.initial.as_slice()), bits(b.initial.as_slice()));
            proptest::prop_assert_eq!(a.iterations, b.iterations);
            if event == 2 {
                fresh.forget();
                along.chain.forget();
            } else {
                let dq: [f64; 6] = std::array::from_fn(|i| a.axes_deg[i] - axes[i]);
                fresh.record(dq, a.initial, a.residual);
                along.chain.record(dq, b.initial, b.residual);
            }
        }
    }
}
