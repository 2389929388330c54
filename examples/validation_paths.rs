//! Writes `fixtures/measurements/validation-poses.csv`: the axis angles of the paper's three
//! validation paths (Fig. 8) — rectangles of X 400 × Y 2000 mm at Z 500, 1000 and 1500 mm
//! (over X400 × Y2000 × Z1000 mm), stops every 100 mm, the measurement target (the TCP,
//! `simulate::paper::TARGET_MM` on the flange) commanded with the flange pointing down
//! (A 180, B 0, C 180).
//!
//! Run: `cargo run --release --example validation_paths [OUT.csv]` (default: the fixture).
//! The axes are the controller's: `kinematics::inverse` with S 2 (elbow up, wrist not
//! flipped), each point nearest the previous one, as a LIN path continues.

use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6};
use robopost::kinematics::{inverse, Frame, Payload, RobotDescription, Select};
use robopost::model::{AxisState, Model};
use robopost::simulate::paper::TARGET_MM;

/// The validation paths: (label, commanded TCP positions in mm).
fn paths() -> Vec<(String, Vec<Vector3<f64>>)> {
    let (x0, x1, y0, y1): (f64, f64, f64, f64) = (1000.0, 1400.0, -1000.0, 1000.0);
    let mut out = Vec::new();
    for (k, z) in [500.0, 1000.0, 1500.0].into_iter().enumerate() {
        let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)];
        let mut points = Vec::new();
        for w in corners.windows(2) {
            let ((xa, ya), (xb, yb)) = (w[0], w[1]);
            let steps = ((xb - xa).abs().max((yb - ya).abs()) / 100.0).round() as usize;
            for i in 0..steps {
                let t = i as f64 / steps as f64;
                points.push(Vector3::new(xa + (xb - xa) * t, ya + (yb - ya) * t, z));
            }
        }
        out.push((format!("path{}", k + 1), points));
    }
    out
}

/// Pose error (position mm, rotation vector in mrad) of `axes` against `goal`.
fn error(model: &Model, axes: &[f64; 6], goal: &Isometry3<f64>) -> Vector6<f64> {
    let (frames, _) = model.frames(&AxisState::new(*axes));
    let dp = goal.translation.vector - frames.flange_position();
    // Twice the vector part of the relative quaternion (shortest way round): smooth, zero only
    // at the goal orientation, the rotation vector when small. Closed-form conversion of the
    // matrix (no iteration).
    let relative =
        goal.rotation.to_rotation_matrix().matrix() * frames.flange_rotation().transpose();
    let qe = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(relative));
    let dr = qe.imag() * 2.0 * if qe.w < 0.0 { -1.0 } else { 1.0 };
    Vector6::new(
        dp.x,
        dp.y,
        dp.z,
        dr.x * 1000.0,
        dr.y * 1000.0,
        dr.z * 1000.0,
    )
}

fn main() {
    let robot = RobotDescription::kr30ha();
    let model = Model::new(robot, Payload::default(), Vector3::zeros());
    let tool = Vector3::from(TARGET_MM);
    // Flange pointing down, its X towards −X: A 180, B 0, C 180 (R = Rz(A)·Ry(B)·Rx(C)).
    let pi = std::f64::consts::PI;
    let rotation = UnitQuaternion::from_euler_angles(pi, 0.0, pi);
    let mut previous: Option<[f64; 6]> = None;
    let mut rows = String::from("test,a1,a2,a3,a4,a5,a6\n");
    for (label, points) in paths() {
        for p in points {
            // The TCP (target) at p: flange origin = p − R·tool.
            let goal = Isometry3::from_parts(Translation3::from(p - rotation * tool), rotation);
            // S 2: elbow up, wrist not flipped. The first point nearest the pose with A1 = A6
            // turned towards it (A4 is 0 to rounding on these paths, so T would not decide).
            let near = previous.unwrap_or([46.0, -58.0, 123.0, 0.0, 25.0, 46.0]);
            let select = Select::StatusNearest { s: 2, near };
            let q = inverse(&robot, &Frame::from_isometry(&goal), select)
                .unwrap_or_else(|e| panic!("{label} {p}: {e}"))
                .axes_deg;
            // Independent check: the model's forward kinematics puts the flange on the goal.
            let e = error(&model, &q, &goal);
            assert!(e.norm() < 1e-8, "{label} {p}: error {}", e.transpose());
            assert!(
                robot.within_limits(&q),
                "{label} {p}: {q:?} outside the limits"
            );
            previous = Some(q);
            rows += &format!(
                "{label},{}\n",
                q.iter()
                    .map(|a| format!("{:.6}", (a * 1e6).round() / 1e6 + 0.0))
                    .collect::<Vec<_>>()
                    .join(",")
            );
        }
    }
    let out = std::env::args_os().nth(1).map_or_else(
        || {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("fixtures/measurements/validation-poses.csv")
        },
        std::path::PathBuf::from,
    );
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).expect("mkdir");
    }
    std::fs::write(&out, rows).expect("write");
    println!("wrote {}", out.display());
}
