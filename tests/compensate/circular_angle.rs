//! Circular motions with a circular angle `CA`: the controller stops on the circle through
//! start, auxiliary point and target after turning by `CA`, with the target's orientation.
//! Compensated, the written program must make the model predict the nominal end: checked by
//! simulating the *written* text again (where does the controller end, with which axes and
//! directions?) and evaluating the calibrated model there, and the written circle checked
//! against an independent circumcircle computation.

use nalgebra::{Rotation3, Unit, Vector3};
use robopost::compensate::{solve, Method};
use robopost::kinematics::RobotDescription;
use robopost::krl::interpret::{Simulation, Workspace};
use robopost::krl::job::{files, program};
use robopost::model::Model;
use robopost::motion::{self, frame::Frame, Role};

use super::pipeline::{cal, run};

/// Tool 200 mm along the flange's Z, pointing down; circles of radius 50 mm and a tilted
/// relative one, CA 90, −45, 120 (`CIRC_REL`), 90 again ending on the auxiliary point (its
/// plane carried over) and a full circle (CA 360) with a retract.
const PROGRAM: &str = "DEF ca_test( )
$BASE={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}
$TOOL={X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}
PTP {A1 20.0,A2 -80.0,A3 100.0,A4 0.0,A5 70.0,A6 0.0}
LIN {X 1300.0,Y 450.0,Z 1200.0,A 0.0,B 0.0,C 180.0}
CIRC {X 1314.645,Y 485.355,Z 1200.0}, {X 1400.0,Y 450.0,Z 1200.0,A 10.0,B 0.0,C 180.0}, CA 90
LIN {X 1350.0,Y 500.0,Z 1100.0,A 0.0,B 0.0,C 180.0}
CIRC {X 1400.0,Y 550.0,Z 1100.0}, {X 1450.0,Y 500.0,Z 1100.0,A 0.0,B 5.0,C 180.0}, CA -45
CIRC_REL {X 30.0,Y 30.0,Z 0.0}, {X 60.0,Y 0.0,Z 20.0}, CA 120
LIN {X 1300.0,Y 450.0,Z 1150.0,A 0.0,B 0.0,C 180.0}
CIRC {X 1350.0,Y 500.0,Z 1150.0}, {X 1400.0,Y 450.0,Z 1150.0,A 0.0,B 0.0,C 180.0}, CA 90
LIN {X 1300.0,Y 400.0,Z 1000.0,A 0.0,B 0.0,C 180.0}
CIRC {X 1340.0,Y 440.0,Z 1000.0}, {X 1380.0,Y 400.0,Z 1000.0,A 0.0,B 0.0,C 180.0}, CA 360
LIN {Z 1100.0}
END
";

fn load(text: &[u8]) -> Workspace {
    files::load_program(None, text, None).expect("loads")
}

/// Indices of the stops of the circular motions (auxiliary point, last stop) in order.
fn circles(sim: &Simulation) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (i, s) in sim.stops.iter().enumerate() {
        if s.role == Role::Aux {
            // The last stop of the same statement: the end (or a full circle's End).
            let mut j = i + 1;
            while j + 1 < sim.stops.len()
                && std::ptr::eq(sim.stops[j + 1].handle.stmt, s.handle.stmt)
            {
                j += 1;
            }
            out.push((i, j));
        }
    }
    out
}

/// Directions of every stop's arrival, as the compensation derives them.
/// The model's error (position mm, rotation rad) at stop `k` of `sim` — its axes and tool,
/// the directions `dirs` — against the pose `goal`.
fn error_at(
    model: &Model,
    sim: &Simulation,
    histories: &[robopost::model::AxisState],
    k: usize,
    goal: &Frame,
) -> (f64, f64) {
    let tool = sim.frames[sim.stops[k].tool as usize];
    let e = solve::predicted_error(
        model,
        &histories[k].history,
        &sim.stops[k].nominal_axes,
        &tool,
        goal,
    );
    robopost::compensate::pose::norms(&e)
}

/// Every stop's axis histories as the simulated motion leaves them (turning points inside the
/// interpolated motions included): where each gear play really stands.
fn directions(sim: &Simulation) -> Vec<robopost::model::AxisState> {
    motion::program_states(&sim.stops, &sim.arcs)
}

/// The position a Cartesian stop programs (in its base).
fn programmed_position(stop: &robopost::krl::interpret::Stop) -> Vector3<f64> {
    match stop.programmed {
        motion::Programmed::Pose(p) => p.position(),
        motion::Programmed::Axes(_) => panic!("a circle's target is Cartesian"),
    }
}

/// The circle through `a`, `b`, `c` (circumcentre by the perpendicular bisectors solved as a
/// 3×3 linear system: an independent construction), and the point reached from `a` after
/// turning by `angle_deg` in the sense a → b → c.
fn turned(a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>, angle_deg: f64) -> Vector3<f64> {
    let n = (b - a).cross(&(c - a));
    let m =
        nalgebra::Matrix3::from_rows(&[(b - a).transpose(), (c - a).transpose(), n.transpose()]);
    let rhs = Vector3::new(
        0.5 * (b.norm_squared() - a.norm_squared()),
        0.5 * (c.norm_squared() - a.norm_squared()),
        n.dot(&a),
    );
    let centre = m.lu().solve(&rhs).expect("not collinear");
    let axis = Unit::new_normalize(n);
    centre + Rotation3::from_axis_angle(&axis, angle_deg.to_radians()) * (a - centre)
}

/// How far the end of the circle through `pts` (start, aux, target) moves, to first order,
/// when every written coordinate moves by up to `half_unit` (half the last written decimal):
/// Σ |∂end/∂x| · half_unit over the nine coordinates, by central differences.
fn rounding_bound(pts: [Vector3<f64>; 3], angle_deg: f64, half_unit: f64) -> f64 {
    let h = 1e-4;
    let mut bound = 0.0;
    for p in 0..3 {
        for k in 0..3 {
            let mut plus = pts;
            let mut minus = pts;
            plus[p][k] += h;
            minus[p][k] -= h;
            let d = (turned(plus[0], plus[1], plus[2], angle_deg)
                - turned(minus[0], minus[1], minus[2], angle_deg))
                / (2.0 * h);
            bound += d.norm() * half_unit;
        }
    }
    bound
}

/// Half the last written decimal: 3 decimals in mm (`rewrite::MIN_DECIMALS_MM`), 4 in degrees.
const HALF_MM: f64 = 0.5e-3;
const HALF_DEG: f64 = 0.5e-4;

fn compensated(text: &[u8], stream: Option<robopost::krl::StreamOptions>) -> Vec<u8> {
    let (model, bytes) = cal("kr30ha-example.json");
    let ws = files::load_program_streaming(None, text.to_vec(), None, stream).unwrap();
    let c = robopost::krl::job::Calibrated::new(&model, "kr30ha-example.json", &bytes);
    let options = program::Options {
        method: Method::Iterate,
        parallel: true,
        stretching: robopost::compensate::sequence::Stretching::DEFAULT,
        frames: Vec::new(),
        points: false,
        ..program::Options::default()
    };
    let result = robopost::krl::job::compensate_program(&ws, &c, &options);
    assert!(!result.rejected, "{:?}", result.report.errors);
    result.files[0].bytes.to_vec()
}

#[test]
fn circles_with_ca_end_where_the_model_predicts_the_nominal_end() {
    let robot = RobotDescription::kr30ha();
    let (model, _) = cal("kr30ha-example.json");
    let ws = load(PROGRAM.as_bytes());
    let result = run(&ws, "kr30ha-example.json", Method::Iterate);
    assert!(!result.rejected, "{:?}", result.report.errors);
    // Only the whole circle is reported (its end cannot be compensated).
    let ca_warnings: Vec<String> = result
        .diagnostics
        .iter()
        .map(|d| d.render())
        .filter(|w| w.contains("CA"))
        .collect();
    assert_eq!(ca_warnings.len(), 1, "{ca_warnings:#?}");
    assert!(ca_warnings[0].contains("a whole circle (CA 360) ends where it starts"));
    let written = result.files[0].bytes.to_vec();
    let text = String::from_utf8(written.clone()).unwrap();

    // The written CA numbers are the user's.
    let ca_of = |t: &str| -> Vec<String> {
        t.lines()
            .filter_map(|l| l.split_once(", CA ").map(|(_, ca)| ca.to_string()))
            .collect()
    };
    assert_eq!(ca_of(&text), ca_of(PROGRAM));
    assert_eq!(ca_of(&text), ["90", "-45", "120", "90", "360"]);

    let sim0 = robopost::krl::interpret::simulate(&ws, &robot, &[]);
    let out = load(&written);
    let sim1 = robopost::krl::interpret::simulate(&out, &robot, &[]);
    assert!(!sim1.rejected());
    let (dirs0, dirs1) = (directions(&sim0), directions(&sim1));
    let (c0, c1) = (circles(&sim0), circles(&sim1));
    assert_eq!((c0.len(), c1.len()), (5, 5));
    // The model's error at stop k1 of a program against stop k0's nominal pose.
    let predicted =
        |k0: usize, k1: usize, sim: &Simulation, dirs: &[robopost::model::AxisState]| {
            error_at(&model, sim, dirs, k1, &sim0.stops[k0].goal)
        };
    let angles = [90.0, -45.0, 120.0, 90.0, 360.0];
    for (((a0, e0), (a1, e1)), angle) in c0.iter().zip(&c1).zip(angles) {
        let (a0, e0, a1, e1) = (*a0, *e0, *a1, *e1);
        // Uncompensated: the model's error at the end of the original program.
        let (bp, br) = predicted(e0, e0, &sim0, &dirs0);
        assert!(bp > 0.1, "CA {angle}: {bp} mm: a check that can fail");
        // The written circle: start (the previous stop, as written), aux', target'.
        let start = sim1.stops[sim1.stops[a1].prev.unwrap() as usize]
            .goal
            .position;
        let aux = sim1.stops[a1].goal.position;
        let whole = angle == 360.0;
        let target_stop = if whole { e1 - 1 } else { e1 };
        // The target as written: absolute in the base (`programmed` completes a relative
        // one), the base the robot's.
        assert_eq!(
            sim1.frames[sim1.stops[target_stop].base as usize],
            Frame::identity()
        );
        let target = programmed_position(&sim1.stops[target_stop]);
        // Where the controller ends with the written numbers, by the independent circle.
        let end = sim1.stops[e1].goal.position;
        let independent = turned(start, aux, target, angle);
        assert!(
            (end - independent).norm() < 1e-6,
            "CA {angle}: walker {end:?} vs circumcircle {independent:?}"
        );
        // The written circle's plane is the nominal one up to the correction's tilt.
        if !whole {
            let normal = |sim: &Simulation, a: usize, target: Vector3<f64>| {
                let s = sim.stops[sim.stops[a].prev.unwrap() as usize].goal.position;
                (sim.stops[a].goal.position - s)
                    .cross(&(target - s))
                    .normalize()
            };
            let target0 = programmed_position(&sim0.stops[e0]);
            let tilt = normal(&sim0, a0, target0).angle(&normal(&sim1, a1, target));
            assert!(tilt < 0.01, "CA {angle}: the plane tilts by {tilt} rad");
        }
        // Rounding the written numbers moves the end by at most `bound` (first order, the
        // start's, aux''s and target''s coordinates each by half a unit; a relative circle's
        // start shifts all three alike, at most half a unit per coordinate more); the model
        // moves the predicted TCP with it (its Jacobian is 1 to 10⁻³), the solver leaves
        // 0.1 µm. The orientation is the target's A, B, C, each rounded by half a unit.
        let bound_mm =
            rounding_bound([start, aux, target], angle, HALF_MM) * 1.01 + 3f64.sqrt() * HALF_MM;
        let bound_rad = 3.0 * HALF_DEG.to_radians() + 0.1e-6;
        if whole {
            // The end is the start again, with the start's command: only the circle's
            // points are compensated. The target as a plain circle's end.
            assert!((end - start).norm() < 1e-9);
            let (tp, tr) = predicted(e0 - 1, e1 - 1, &sim1, &dirs1);
            let tb = 3f64.sqrt() * HALF_MM + 0.1e-3;
            eprintln!(
                "CA 360: target {:.3} µm {:.3} µrad (bound {:.3} µm)",
                tp * 1e3,
                tr * 1e6,
                tb * 1e3
            );
            assert!(tp < tb && tr < bound_rad, "CA 360 target: {tp} mm {tr} rad");
            let (ep, _) = predicted(e0, e1, &sim1, &dirs1);
            eprintln!("CA 360: end {:.1} µm (before {:.1} µm)", ep * 1e3, bp * 1e3);
            continue;
        }
        let (ap, ar) = predicted(e0, e1, &sim1, &dirs1);
        eprintln!(
            "CA {angle}: before {:.1} µm {:.1} µrad, after {:.3} µm {:.3} µrad (bound {:.3} µm {:.3} µrad)",
            bp * 1e3,
            br * 1e6,
            ap * 1e3,
            ar * 1e6,
            bound_mm * 1e3,
            bound_rad * 1e6
        );
        assert!(ap < bound_mm, "CA {angle}: {ap} mm > {bound_mm} mm");
        assert!(ar < bound_rad, "CA {angle}: {ar} rad > {bound_rad} rad");
        assert!(bound_mm < 5e-3, "µm-level: {bound_mm} mm");
    }
}

/// The program cut into streamed windows (every plain line a run) compensates alike.
#[test]
fn circles_with_ca_compensate_alike_streamed() {
    let whole = compensated(PROGRAM.as_bytes(), None);
    let streamed = compensated(
        PROGRAM.as_bytes(),
        Some(robopost::krl::StreamOptions {
            min_run: 1,
            window: 1,
        }),
    );
    assert_eq!(
        String::from_utf8_lossy(&whole),
        String::from_utf8_lossy(&streamed)
    );
}

/// A relative circle's auxiliary point and target are both relative to where the motion
/// starts: written so, the controller reaches the compensated target (the model predicts the
/// nominal one there), with or without `CA`.
#[test]
fn a_relative_circle_is_written_relative_to_its_start() {
    let program = "DEF rel_circle( )
$BASE={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}
$TOOL={X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}
PTP {A1 20.0,A2 -80.0,A3 100.0,A4 0.0,A5 70.0,A6 0.0}
LIN {X 1300.0,Y 450.0,Z 1200.0,A 30.0,B 20.0,C 160.0}
CIRC_REL {X 40.0,Y 40.0,Z 0.0}, {X 80.0,Y 0.0,Z -10.0,A 5.0,B 3.0}
END
";
    let robot = RobotDescription::kr30ha();
    let (model, _) = cal("kr30ha-example.json");
    let ws = load(program.as_bytes());
    let written = compensated(program.as_bytes(), None);
    let out = load(&written);
    let (sim0, sim1) = (
        robopost::krl::interpret::simulate(&ws, &robot, &[]),
        robopost::krl::interpret::simulate(&out, &robot, &[]),
    );
    let dirs1 = directions(&sim1);
    let end = sim0.stops.len() - 1;
    assert_eq!(sim1.stops.len(), sim0.stops.len());
    let goal = &sim0.stops[end].goal;
    let (p, r) = error_at(&model, &sim1, &dirs1, end, goal);
    let dirs0 = directions(&sim0);
    assert!(error_at(&model, &sim0, &dirs0, end, goal).0 > 0.1);
    eprintln!("CIRC_REL: after {:.3} µm {:.3} µrad", p * 1e3, r * 1e6);
    // The start's and the offset's rounding, half a unit per coordinate each, and the
    // solver's 0.1 µm; the start's and the offset's A, B, C half a unit each. (Written
    // relative to the auxiliary point instead, the end was 56 mm off.)
    assert!(p < 2.0 * 3f64.sqrt() * HALF_MM + 0.1e-3, "{} µm", p * 1e3);
    assert!(r < 6.0 * HALF_DEG.to_radians() + 0.1e-6, "{} µrad", r * 1e6);
}

/// Plain circles (no `CA`) whose orientation turns by up to 45° between start and end: an
/// auxiliary point is written in position only and its compensation assumes the orientation
/// the nominal circle passes it with. Simulating the written program again (the controller
/// interpolates the orientation between the compensated start and end) and evaluating the
/// model there shows what that leaves at the auxiliary points: no more than the written
/// decimals allow (half a unit in X, Y and Z: 0.87 µm).
#[test]
fn plain_circles_reach_their_auxiliary_points() {
    const CIRCLES: &str = "DEF aux_test( )
$BASE={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}
$TOOL={X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}
PTP {A1 20.0,A2 -80.0,A3 100.0,A4 0.0,A5 70.0,A6 0.0}
LIN {X 1300.0,Y 450.0,Z 1200.0,A 0.0,B 0.0,C 180.0}
CIRC {X 1335.355,Y 485.355,Z 1200.0}, {X 1385.355,Y 485.355,Z 1200.0,A 30.0,B 10.0,C 170.0}
CIRC {X 1420.0,Y 450.0,Z 1150.0}, {X 1385.355,Y 400.0,Z 1100.0,A -20.0,B 0.0,C 180.0}
LIN {X 1200.0,Y 300.0,Z 1000.0,A 0.0,B 0.0,C 180.0}
CIRC {X 1150.0,Y 350.0,Z 1000.0}, {X 1200.0,Y 400.0,Z 1000.0,A 0.0,B 0.0,C 180.0}
CIRC {X 1250.0,Y 350.0,Z 1000.0}, {X 1200.0,Y 300.0,Z 1000.0,A 45.0,B -5.0,C 175.0}
END
";
    let robot = RobotDescription::kr30ha();
    let (model, _) = cal("kr30ha-example.json");
    let ws = load(CIRCLES.as_bytes());
    let result = run(&ws, "kr30ha-example.json", Method::Iterate);
    assert!(!result.rejected, "{:?}", result.report.errors);
    let out = load(&result.files[0].bytes.to_vec());
    let (sim0, sim1) = (
        robopost::krl::interpret::simulate(&ws, &robot, &[]),
        robopost::krl::interpret::simulate(&out, &robot, &[]),
    );
    let (dirs0, dirs1) = (directions(&sim0), directions(&sim1));
    let (c0, c1) = (circles(&sim0), circles(&sim1));
    assert_eq!((c0.len(), c1.len()), (4, 4));
    let (mut worst, mut below) = (0.0f64, 0);
    for ((a0, _), (a1, _)) in c0.into_iter().zip(c1) {
        let goal = &sim0.stops[a0].goal;
        let (before, _) = error_at(&model, &sim0, &dirs0, a0, goal);
        let (after, _) = error_at(&model, &sim1, &dirs1, a1, goal);
        assert!(before > 0.1, "aux {a0}: {before} mm uncompensated");
        eprintln!(
            "aux {a0}: {:.2} µm left (before {:.1} µm)",
            after * 1e3,
            before * 1e3
        );
        worst = worst.max(after);
        below += (after < 0.87e-3) as usize;
    }
    // Most auxiliary points within what the written decimals allow; where a wrist axis nearly
    // rests inside its gear play, the orientation the compensated circle really passes with
    // (not the nominal one the compensation assumes) puts the play on its other side: a few
    // tens of µm on this point passed, not stopped at (README, known limits).
    assert!(
        below >= 3,
        "{below} of 4 auxiliary points within the decimals"
    );
    assert!(worst < 25e-3, "worst auxiliary point {:.1} µm", worst * 1e3);
}
