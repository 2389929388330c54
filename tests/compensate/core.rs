//! The solver and the sequence logic on targets built from axis angles (no KRL).

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use robopost::compensate::{
    compensate, Frame, Interp, Keep, Method, Options, Resolution, Target, TOL_POSITION_MM,
    TOL_ROTATION_RAD,
};
use robopost::kinematics::Payload;
use robopost::model::{AxisHistory, AxisState, Direction, Model};
use robopost::motion::nominal::local_ik;

use super::{handset, nominal};

fn tool() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(12.0, -5.0, 180.0),
        UnitQuaternion::from_euler_angles(0.0, 0.3, 0.1),
    )
}

/// The nominal TCP of `axes`, through the model API with no effects (a path independent of
/// the solver's own chain evaluation).
fn nominal_tcp(model: &Model, axes: [f64; 6]) -> Isometry3<f64> {
    let bare = Model::new(model.robot, Payload::default(), Vector3::zeros());
    bare.flange_pose(&AxisState::new(axes)).to_isometry() * tool()
}

fn predicted_tcp(model: &Model, axes: [f64; 6], dirs: [Direction; 6]) -> Isometry3<f64> {
    model
        .flange_pose(&AxisState::with_directions(axes, dirs))
        .to_isometry()
        * tool()
}

fn pose_gap(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let dp = (a.translation.vector - b.translation.vector).norm();
    let dr = (a.rotation * b.rotation.inverse()).angle();
    (dp, dr)
}

fn target(model: &Model, axes: [f64; 6], arrival: Option<[f64; 6]>) -> Target {
    Target {
        goal: Frame::from_isometry(&nominal_tcp(model, axes)),
        tool: 0,
        nominal_axes: axes.into(),
        arrival,
        turns: robopost::motion::interpolate::NO_TURNS,
        interp: Interp::Joint,
        written_base: None,
        compensate: true,
        keep: Keep::default(),
    }
}

fn dir(positive: bool) -> Direction {
    if positive {
        Direction::Positive
    } else {
        Direction::Negative
    }
}

const ITERATE: Options = Options {
    method: Method::Iterate,
    parallel: false,
    stretching: robopost::compensate::sequence::Stretching::DEFAULT,
};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The model predicts the programmed TCP at the compensated command, checked through
    /// `Model::flange_pose` (quaternion path) rather than the solver's own evaluation.
    #[test]
    fn iterated_command_reaches_the_goal(
        a1 in -150.0..150.0f64, a2 in -120.0..-20.0f64, a3 in 20.0..130.0f64,
        a4 in -150.0..150.0f64, a5 in prop_oneof![-100.0..-15.0f64, 15.0..100.0f64],
        a6 in -300.0..300.0f64, signs in prop::array::uniform6(any::<bool>()),
    ) {
        let model = handset();
        let axes = [a1, a2, a3, a4, a5, a6];
        // Near a singularity the solver returns the least-squares command and reports its
        // residual (sequence.rs); the exact-reach property holds away from them.
        prop_assume!(robopost::kinematics::singularity(&model.robot, &axes).is_none());
        let arrival: [f64; 6] = std::array::from_fn(|i| if signs[i] { 1.0 } else { -1.0 });
        let tools = [Frame::from_isometry(&tool())];
        let out = compensate(&model, &tools, &[target(&model, axes, Some(arrival))],
            [Direction::Unknown; 6], &ITERATE);
        let o = &out[0];
        prop_assert!(o.error.is_none(), "{:?}", o.error);
        let dirs: [Direction; 6] = std::array::from_fn(|i| dir(signs[i]));
        prop_assert_eq!(o.directions, dirs);
        let goal = nominal_tcp(&model, axes);
        let (p0, _) = pose_gap(&predicted_tcp(&model, axes, dirs), &goal);
        prop_assume!(p0 > 1e-3, "the hand-set model moves the TCP here");
        let (dp, dr) = pose_gap(&predicted_tcp(&model, o.axes_deg.into(), dirs), &goal);
        prop_assert!(dp < TOL_POSITION_MM && dr < TOL_ROTATION_RAD, "{dp} mm {dr} rad");
        prop_assert!(o.iterations <= 6, "{} iterations", o.iterations);
    }
}

#[test]
fn one_step_is_equation_3() {
    let model = handset();
    let axes = [30.0, -60.0, 100.0, 20.0, 40.0, -50.0];
    let dirs = [Direction::Positive; 6];
    let tools = [Frame::from_isometry(&tool())];
    let t = target(&model, axes, Some([1.0; 6]));
    let one = compensate(
        &model,
        &tools,
        &[t],
        [Direction::Unknown; 6],
        &Options {
            method: Method::OneStep,
            parallel: false,
            stretching: robopost::compensate::sequence::Stretching::DEFAULT,
        },
    )[0];
    let goal = nominal_tcp(&model, axes);
    let predicted = predicted_tcp(&model, axes, dirs);
    // p_c = p* − (p̂ − p*), R_c = (R̂ R*⁻¹)⁻¹ R*, computed here with isometries.
    let p_c = goal.translation.vector * 2.0 - predicted.translation.vector;
    let r_c = (predicted.rotation * goal.rotation.inverse()).inverse() * goal.rotation;
    let command = nominal_tcp(&model, one.axes_deg.into());
    assert_relative_eq!(command.translation.vector, p_c, epsilon = 1e-8);
    assert!((command.rotation * r_c.inverse()).angle() < 1e-11);
    // One step leaves a second-order error, the iteration none.
    let (before, _) = pose_gap(&predicted, &goal);
    let (after, _) = pose_gap(&predicted_tcp(&model, one.axes_deg.into(), dirs), &goal);
    assert!(after < before / 50.0, "{before} → {after}");
    assert!(
        after > TOL_POSITION_MM / 100.0,
        "one step is not already exact here: {after}"
    );
    let it = compensate(&model, &tools, &[t], [Direction::Unknown; 6], &ITERATE)[0];
    let (iterated, _) = pose_gap(&predicted_tcp(&model, it.axes_deg.into(), dirs), &goal);
    assert!(iterated < TOL_POSITION_MM && iterated < after);
}

#[test]
fn nominal_calibration_changes_nothing() {
    let model = nominal();
    let tools = [Frame::from_isometry(&tool())];
    let targets: Vec<Target> = (0..50)
        .map(|i| {
            let t = i as f64;
            target(
                &model,
                [
                    t - 25.0,
                    -80.0 + t * 0.5,
                    70.0 + t,
                    10.0,
                    30.0 + t * 0.3,
                    -20.0,
                ],
                Some([1.0, 0.5, 1.0, 0.0, 0.3, 0.0]),
            )
        })
        .collect();
    for o in compensate(&model, &tools, &targets, [Direction::Unknown; 6], &ITERATE) {
        assert!(!o.changed && o.error.is_none() && o.iterations == 0);
    }
}

#[test]
fn leaving_the_limits_is_an_error_for_that_target() {
    // A2 at its lower limit on a robot whose A2 turns 0.01° further than commanded, everywhere
    // (a direction-independent map): reaching the nominal pose needs A2 = −135.01°, beyond the
    // limit, and nothing else can make up for it (six axes, six degrees of freedom, far from
    // any singularity). The target must be rejected naming A2 and keep its command.
    let base = handset();
    let mut model = Model::new(base.robot, Payload::default(), Vector3::zeros());
    let name = robopost::model::EffectName::parse("map:A2").unwrap();
    let mut map = name
        .create(&robopost::model::GridOptions::default(), &model.robot)
        .unwrap();
    map.values_mut().iter_mut().for_each(|v| *v = 0.01);
    model.push(map);
    let tools = [Frame::from_isometry(&tool())];
    let at_limit = [0.0, -135.0, 100.0, 0.0, 40.0, 0.0];
    let t = target(&model, at_limit, Some([0.0, -1.0, 0.0, 0.0, 0.0, 0.0]));
    let o = compensate(&model, &tools, &[t], [Direction::Unknown; 6], &ITERATE)[0];
    match o.error {
        Some(robopost::compensate::TargetError::OutOfLimits {
            axis, value, lo, ..
        }) => {
            assert_eq!(axis, 2);
            assert_eq!(lo, -135.0);
            assert!((value - -135.01).abs() < 1e-4, "{value}");
        }
        other => panic!("expected A2 out of its limits, got {other:?}"),
    }
    assert_eq!(o.axes_deg, at_limit, "a rejected target keeps its command");
    // The same target 1° inside the limit is compensated by exactly −0.01° of A2.
    let inside = [0.0, -134.0, 100.0, 0.0, 40.0, 0.0];
    let t = target(&model, inside, Some([0.0, -1.0, 0.0, 0.0, 0.0, 0.0]));
    let o = compensate(&model, &tools, &[t], [Direction::Unknown; 6], &ITERATE)[0];
    assert!(o.error.is_none(), "{:?}", o.error);
    assert!((o.axes_deg[1] - -134.01).abs() < 1e-6, "{:?}", o.axes_deg);
}

/// Targets on a vertical LIN line below (or above) `top`, flange pointing down, with the LIN
/// arrival motions `dq/du` (finite difference of the nominal IK along the line).
fn vertical_line(model: &Model, step_mm: f64) -> Vec<Target> {
    let tools = [Frame::identity()];
    let bare = Model::new(model.robot, Payload::default(), Vector3::zeros());
    let top = [20.0, -75.0, 95.0, 0.0, 70.0, 10.0];
    let top_pose = bare.flange_pose(&AxisState::new(top));
    let mut targets = vec![target(model, top, Some([1.0, 1.0, -1.0, 0.0, 1.0, 1.0]))];
    targets[0].goal = top_pose;
    let mut previous = top;
    for k in 1..15 {
        let mut goal = top_pose;
        goal.position.z += step_mm * k as f64;
        let q = local_ik(&model.robot, &goal, &tools[0], &previous)
            .expect("reachable")
            .axes_deg;
        let mut near = goal;
        near.position.z -= step_mm * 1e-4;
        let qn = local_ik(&model.robot, &near, &tools[0], &q)
            .unwrap()
            .axes_deg;
        let arrival: [f64; 6] = std::array::from_fn(|i| {
            let v = (q[i] - qn[i]) / 1e-4;
            if v.abs() < 1e-6 {
                0.0
            } else {
                v
            }
        });
        assert_eq!(arrival[0], 0.0, "A1 rests on a vertical line");
        let mut t = target(model, q, Some(arrival));
        t.goal = goal;
        t.interp = Interp::Line;
        targets.push(t);
        previous = q;
    }
    targets
}

/// The states the compensated commands really arrive with: each axis's history advanced
/// through the commands one after the other and, for a LIN motion, through the turning points
/// of the straight line between the commanded flange poses (walked by `motion::interpolate`,
/// as the controller interpolates it), the first target reached after long motions in its
/// nominal directions. Built from the commands alone, not from what the solver assumed.
fn arrivals(targets: &[Target], out: &[robopost::compensate::Outcome]) -> Vec<AxisState> {
    use robopost::motion::interpolate::{arrival, Path};
    let robot = robopost::kinematics::RobotDescription::kr30ha();
    let bare = Model::new(robot, Payload::default(), Vector3::zeros());
    let flange = |q: &[f64; 6]| bare.flange_pose(&AxisState::new(*q));
    let mut states: Vec<AxisState> = Vec::new();
    for (t, o) in targets.iter().zip(out) {
        let state = match states.last() {
            Some(p) if t.interp == Interp::Line => {
                let (q0, q1) = (p.axes_deg, o.axes_deg.into());
                let walked = arrival(
                    &robot,
                    &Frame::identity(),
                    &Path::Lin,
                    (&flange(&q0), &q0),
                    (&flange(&q1), &q1),
                );
                p.then_through(&walked.unwrap().turns.angle_deg, q1)
            }
            Some(p) => p.then(o.axes_deg.into()),
            None => AxisState {
                axes_deg: o.axes_deg.into(),
                history: o.nominal_directions.map(AxisHistory::engaged),
                time_s: 0.0,
            },
        };
        states.push(state);
    }
    states
}

/// Every compensated target's TCP, as the model predicts it with the gear plays evaluated from
/// the commands' own history, within `tol_mm` of its goal (flange as the tool).
fn assert_reaches_goals(
    model: &Model,
    targets: &[Target],
    out: &[robopost::compensate::Outcome],
    tol_mm: f64,
) {
    for (k, (state, t)) in arrivals(targets, out).iter().zip(targets).enumerate() {
        assert!(out[k].error.is_none(), "{k}: {:?}", out[k].error);
        let reached = model.flange_pose(state);
        let (p, r) =
            robopost::compensate::pose::norms(&robopost::motion::frame::error(&reached, &t.goal));
        assert!(
            p < tol_mm && r < 1e-6,
            "target {k}: {:.4} µm, {:.3} µrad off ({:?})",
            p * 1e3,
            r * 1e6,
            out[k].resolution
        );
    }
}

/// A vertical LIN segment: the TCP goes straight down (or up) at fixed orientation, so A1
/// does not move in the nominal motion. The model's corrections change with height, so the
/// output of A1 must move a little at some targets and not at others. Evaluated with the
/// gear plays the commands themselves leave, every target reaches its goal: A1 is held
/// exactly where its output need not move (never jittering inside its play), and where the
/// output must move back the command travels the play.
#[test]
fn vertical_segment_reaches_every_goal_with_the_play() {
    let model = handset();
    let tools = [Frame::identity()];
    let (mut held, mut travelled, mut exactly) = (0, 0, 0);
    for step_mm in [-40.0, 40.0] {
        let targets = vertical_line(&model, step_mm);
        let out = compensate(&model, &tools, &targets, [Direction::Unknown; 6], &ITERATE);
        for (k, o) in out.iter().enumerate() {
            if let Resolution::Held(axes) = o.resolution {
                held += 1;
                // An axis the program holds is kept exactly (others are held where the
                // output stays inside the play, at the command that puts it there).
                let resting = |i: &usize| targets[k].arrival.unwrap()[*i] == 0.0;
                for i in (0..6).filter(|&i| axes[i]).filter(resting) {
                    exactly += (o.axes_deg[i] == out[k - 1].axes_deg[i]) as usize;
                }
            }
            travelled += o.travels_play.contains(&true) as usize;
        }
        // Held axes leave what the others cannot make up: at most the hold's own threshold
        // over a 2.2 m lever.
        let hold_tol = robopost::compensate::sequence::HOLD_DEG.to_radians() * 2200.0;
        assert_reaches_goals(&model, &targets, &out, TOL_POSITION_MM + hold_tol);
    }
    eprintln!("held {held} ({exactly} resting axes exactly), travelled the play {travelled}");
}

/// A reversal shorter than the play: A1 moves up 5° and then back by 0.002° (the hand-set
/// play of A1 is 0.006–0.01°). A gear play leaves the output where it was; the output must
/// still go back, so the command travels the play, and the target is reported.
#[test]
fn a_reversal_inside_the_play_travels_it() {
    let model = handset();
    let tools = [Frame::from_isometry(&tool())];
    let a = [10.0, -80.0, 100.0, 10.0, 40.0, 20.0];
    let mut b = a;
    b[0] += 5.0;
    let mut c = b;
    c[0] -= 0.002;
    let targets = vec![
        target(&model, a, Some([1.0; 6])),
        target(&model, b, Some([5.0, 0.0, 0.0, 0.0, 0.0, 0.0])),
        target(&model, c, Some([-0.002, 0.0, 0.0, 0.0, 0.0, 0.0])),
    ];
    let out = compensate(&model, &tools, &targets, [Direction::Unknown; 6], &ITERATE);
    assert!(out[2].travels_play[0], "{:?}", out[2]);
    // The command of A1 went back by more than the play's half width (the output only by
    // 0.002° give or take the correction's change).
    let back = out[1].axes_deg[0] - out[2].axes_deg[0];
    let b1 = model.play_width_deg(0, c[0]);
    assert!(back > 0.5 * b1, "A1 back by {back}°, play {b1}°");
    // Evaluated with the play from the commands, with the tool: every target at its goal.
    for (k, state) in arrivals(&targets, &out).iter().enumerate() {
        let reached = Frame::from_isometry(&(model.flange_pose(state).to_isometry() * tool()));
        let (p, r) = robopost::compensate::pose::norms(&robopost::motion::frame::error(
            &reached,
            &targets[k].goal,
        ));
        assert!(
            p < TOL_POSITION_MM && r < TOL_ROTATION_RAD,
            "{k}: {p} mm {r} rad"
        );
    }
}
