//! Rotation directions along the curve of a CP spline block, checked against finite
//! differences of the closed-form IK along the same curve evaluated by a different algorithm
//! (Barry & Goldman's pyramid for the chord-length Catmull–Rom spline).

use std::path::Path;

use nalgebra::Vector3;
use robopost::kinematics::{inverse, status_turn, RobotDescription, Select};
use robopost::krl::MotionKind;
use robopost::motion::frame::Frame;

use super::pipeline::{load, run};
use robopost::compensate::Method;

/// The chord-length Catmull–Rom segment from `p[1]` to `p[2]` at `u ∈ [0, 1]`, by the
/// Barry–Goldman recursion (three linear interpolations, then two, then one).
fn barry_goldman(p: &[Vector3<f64>; 4], u: f64) -> Vector3<f64> {
    let mut t = [0.0; 4];
    for i in 1..4 {
        t[i] = t[i - 1] + (p[i] - p[i - 1]).norm();
    }
    let s = t[1] + u * (t[2] - t[1]);
    let lerp = |a: &Vector3<f64>, b: &Vector3<f64>, ta: f64, tb: f64| {
        a * ((tb - s) / (tb - ta)) + b * ((s - ta) / (tb - ta))
    };
    let a1 = lerp(&p[0], &p[1], t[0], t[1]);
    let a2 = lerp(&p[1], &p[2], t[1], t[2]);
    let a3 = lerp(&p[2], &p[3], t[2], t[3]);
    let b1 = lerp(&a1, &a2, t[0], t[2]);
    let b2 = lerp(&a2, &a3, t[1], t[3]);
    lerp(&b1, &b2, t[1], t[2])
}

#[test]
fn an_axis_turning_round_at_an_spl_point_arrives_the_curve_s_way() {
    let robot = RobotDescription::kr30ha();
    let ws = load(Path::new("fixtures/programs/spline/turn_at_spl.src"));
    let sim = robopost::krl::interpret::simulate(&ws, &robot, &[]);
    assert!(!sim.rejected());
    let spl: Vec<_> = sim
        .stops
        .iter()
        .filter(|s| s.handle.kind == MotionKind::Spl)
        .collect();
    assert_eq!(spl.len(), 3);
    let stop = spl[1]; // SPL {X 1000, Y 300, …}
    let rate = stop.arrival.expect("a known arrival");

    // Independent: the TCP points of the program (tool pointing down, 200 mm), the curve by
    // Barry–Goldman, the flange by hand, the axes by the closed-form IK nearest to the stop's.
    let p = [-500.0, -300.0, 300.0, 300.0].map(|y| Vector3::new(1000.0, y, 800.0));
    let p = [p[0], p[1], p[2], Vector3::new(1100.0, 300.0, 800.0)];
    let down = Frame::from_kuka(&robopost::kinematics::Pose::from_array([
        0.0, 0.0, 0.0, 180.0, 0.0, 180.0,
    ]))
    .rotation;
    let s = status_turn(&robot, &stop.nominal_axes).0;
    let axes_at = |tcp: Vector3<f64>, near: [f64; 6]| {
        let flange = Frame {
            rotation: down,
            position: tcp - down * Vector3::new(0.0, 0.0, 200.0),
        };
        inverse(&robot, &flange, Select::StatusNearest { s, near })
            .unwrap()
            .axes_deg
    };
    let q1 = axes_at(barry_goldman(&p, 1.0), stop.nominal_axes.into());
    for (i, (a, b)) in q1.iter().zip(*stop.nominal_axes).enumerate() {
        assert!((a - b).abs() < 1e-6, "A{}", i + 1);
    }
    let h = 1e-5;
    let qh = axes_at(barry_goldman(&p, 1.0 - h), q1);
    let fd: [f64; 6] = std::array::from_fn(|i| (q1[i] - qh[i]) / h);
    // The chord from the previous point (what a straight segment gives).
    let q0 = axes_at(p[1], q1);
    let chord: [f64; 6] = std::array::from_fn(|i| q1[i] - q0[i]);

    // A1 turns round on the way: the chord and the curve disagree, the simulation follows
    // the curve.
    assert!(
        fd[0].abs() > 0.5 && chord[0].abs() > 0.5,
        "{fd:?} {chord:?}"
    );
    assert!(fd[0] * chord[0] < 0.0, "{fd:?} {chord:?}");
    for i in 0..6 {
        if fd[i].abs() > 0.05 {
            assert_eq!(rate[i] > 0.0, fd[i] > 0.0, "A{}: {rate:?} vs {fd:?}", i + 1);
            // The rate is exact (J⁻¹·ẋ on the same curve), not only its sign.
            assert!(
                (rate[i] - fd[i]).abs() < 1e-3 * fd[i].abs().max(1.0),
                "A{}: {rate:?} vs {fd:?}",
                i + 1
            );
        }
    }

    // The block's first SPL: the start and the first two points lie on a line, so the curve
    // is that line there and A1 arrives as its chord says.
    let first = spl[0].arrival.unwrap();
    let start = axes_at(p[0], spl[0].nominal_axes.into());
    assert!((spl[0].nominal_axes[0] - start[0]) * first[0] > 0.0);

    // Compensation re-checks the directions of the compensated motion along the same curve:
    // the target keeps the curve's A1 direction and nothing is reported flipped.
    let result = run(&ws, "kr30ha-handset.json", Method::Iterate);
    let point = result
        .report
        .points
        .iter()
        .find(|p| p.line == stop.handle.stmt.line)
        .expect("the SPL point is reported");
    assert!(point.compensated && point.flipped.is_empty(), "{point:?}");
    let a1 = point.directions.chars().next().unwrap();
    assert_eq!(a1, if fd[0] > 0.0 { '+' } else { '-' }, "{point:?}");
    assert_eq!(result.report.direction_flips, 0);
}
