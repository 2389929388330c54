//! The error chain against MODEL.md's reference poses and against an independent forward
//! kinematics (product of exponentials about the joint axes at HOME), and single geometric
//! parameters against hand-computed displacements.

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use robopost::kinematics::{Payload, RobotDescription};
use robopost::model::effects::geometric::Geometric;
use robopost::model::{AxisState, Effect, Model};

fn nominal() -> Model {
    Model::new(
        RobotDescription::kr30ha(),
        Payload::default(),
        Vector3::zeros(),
    )
}

/// KUKA A, B, C (deg) of R = Rz(A)·Ry(B)·Rx(C); at B = ±90° the convention C = 0.
fn abc(r: &Matrix3<f64>) -> [f64; 3] {
    let b = (-r[(2, 0)]).atan2((r[(0, 0)].powi(2) + r[(1, 0)].powi(2)).sqrt());
    if r[(0, 0)].hypot(r[(1, 0)]) < 1e-12 {
        return [
            (-r[(0, 1)]).atan2(r[(1, 1)]).to_degrees(),
            b.to_degrees(),
            0.0,
        ];
    }
    let a = r[(1, 0)].atan2(r[(0, 0)]);
    let c = r[(2, 1)].atan2(r[(2, 2)]);
    [a.to_degrees(), b.to_degrees(), c.to_degrees()]
}

/// Product-of-exponentials FK written from MODEL.md's facts only: at HOME the joint axes (in
/// the KUKA positive sense) are A1 −Z through the origin, A2 +Y and A3 +Y through the A2 and
/// A3 centres, A4 −X, A5 +Y, A6 −X through the wrist line, and the flange is at
/// (1340, 0, 1810) with Z pointing +X and X pointing down.
fn poe_fk(axes: [f64; 6]) -> (Matrix3<f64>, Vector3<f64>) {
    let home = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];
    let joints: [(Vector3<f64>, Vector3<f64>); 6] = [
        (-Vector3::z(), Vector3::zeros()),
        (Vector3::y(), Vector3::new(350.0, 0.0, 815.0)),
        (Vector3::y(), Vector3::new(350.0, 0.0, 1665.0)),
        (-Vector3::x(), Vector3::new(0.0, 0.0, 1810.0)),
        (Vector3::y(), Vector3::new(1170.0, 0.0, 1810.0)),
        (-Vector3::x(), Vector3::new(0.0, 0.0, 1810.0)),
    ];
    let mut r = Matrix3::identity();
    let mut p = Vector3::zeros();
    for (i, (axis, point)) in joints.iter().enumerate() {
        let rot = Rotation3::from_axis_angle(
            &Unit::new_normalize(*axis),
            (axes[i] - home[i]).to_radians(),
        );
        // Compose with the rotation about a line through `point`: x ↦ R(x − point) + point.
        let step_p = point - rot * point;
        p += r * step_p;
        r *= rot.matrix();
    }
    let flange_r = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0);
    (r * flange_r, p + r * Vector3::new(1340.0, 0.0, 1810.0))
}

/// MODEL.md's table: axes, X Y Z, A B C.
const REFERENCE: [([f64; 6], [f64; 3], [f64; 3]); 4] = [
    (
        [0.0, -90.0, 90.0, 0.0, 0.0, 0.0],
        [1340.0, 0.0, 1810.0],
        [0.0, 90.0, 0.0],
    ),
    (
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [2190.0, 0.0, 960.0],
        [0.0, 90.0, 0.0],
    ),
    (
        [30.0, -60.0, 100.0, 20.0, 40.0, -50.0],
        [1306.433, -797.425, 972.743],
        [114.8220, 16.8326, -176.2561],
    ),
    (
        [-45.0, -112.0, 153.0, 0.0, -30.0, 90.0],
        [645.201, 645.201, 1142.133],
        [-45.0, 0.0, -101.0],
    ),
];

#[test]
fn zero_error_chain_reproduces_the_reference_poses() {
    let model = nominal();
    for (axes, xyz, angles) in REFERENCE {
        let pose = model.flange_pose(&AxisState::new(axes));
        let r = pose.rotation;
        let p = pose.position;
        // The table is printed to 1e-3 mm and 1e-4 deg.
        for k in 0..3 {
            assert!(
                (p[k] - xyz[k]).abs() <= 5e-4,
                "{axes:?} coordinate {k}: {} vs {}",
                p[k],
                xyz[k]
            );
            let got = abc(&r)[k];
            assert!(
                (got - angles[k]).abs() <= 5e-5,
                "{axes:?} angle {k}: {got} vs {}",
                angles[k]
            );
        }
        // Full precision against the independent algorithm.
        let (r_ref, p_ref) = poe_fk(axes);
        assert!((p - p_ref).norm() < 1e-9, "{axes:?}: {p} vs {p_ref}");
        assert!((r - r_ref).norm() < 1e-12, "{axes:?}: rotation");
    }
}

#[test]
fn the_first_two_reference_poses_are_exact() {
    let model = nominal();
    let home = model.flange_pose(&AxisState::new(REFERENCE[0].0)).position;
    assert!((home - Vector3::new(1340.0, 0.0, 1810.0)).norm() < 1e-9);
    let zero = model.flange_pose(&AxisState::new(REFERENCE[1].0)).position;
    assert!((zero - Vector3::new(2190.0, 0.0, 960.0)).norm() < 1e-9);
}

fn with_geometric(name: &str, value: f64, target_mm: Vector3<f64>) -> Model {
    let mut model = Model::new(RobotDescription::kr30ha(), Payload::default(), target_mm);
    let mut g = Geometric::default();
    let i = g
        .parameters()
        .iter()
        .position(|p| p.name == name)
        .expect("known parameter");
    g.values[i] = value;
    model.push(Box::new(g));
    model
}

const HOME: [f64; 6] = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];

fn flange_at(model: &Model, axes: [f64; 6]) -> Vector3<f64> {
    model.flange_pose(&AxisState::new(axes)).position
}

#[test]
fn dz32_lengthens_the_upper_arm() {
    // At HOME the upper arm is vertical: +0.1 mm in z. At A2 = 0 it points forward: +0.1 in x.
    let model = with_geometric("dz32", 0.1, Vector3::zeros());
    let d_home = flange_at(&model, HOME) - Vector3::new(1340.0, 0.0, 1810.0);
    assert!(
        (d_home - Vector3::new(0.0, 0.0, 0.1)).norm() < 1e-9,
        "{d_home}"
    );
    let d_zero = flange_at(&model, [0.0; 6]) - Vector3::new(2190.0, 0.0, 960.0);
    assert!(
        (d_zero - Vector3::new(0.1, 0.0, 0.0)).norm() < 1e-9,
        "{d_zero}"
    );
}

#[test]
fn g65_turns_the_a6_axis_about_z_at_the_flange() {
    // In 5T6 = Dx(l5x)·…·Dc(γ65)·Da(θ6) the rotation acts at the flange centre: the flange
    // stays, a 100 mm tool along flange Z (+X at HOME) swings by γ65 about z.
    let eps = 0.01_f64.to_radians();
    let model = with_geometric("g65", 0.01, Vector3::new(0.0, 0.0, 100.0));
    assert!((flange_at(&model, HOME) - Vector3::new(1340.0, 0.0, 1810.0)).norm() < 1e-9);
    let expected = Vector3::new(1340.0 + 100.0 * eps.cos(), 100.0 * eps.sin(), 1810.0);
    assert!((model.target_position(&AxisState::new(HOME)) - expected).norm() < 1e-9);
}

#[test]
fn zero_offsets_rotate_about_their_axis_in_model_sign() {
    let eps = 0.01_f64.to_radians();
    // Δθ20: rotation about +y through (350, 0, 815) of the lever (990, 0, 995).
    let model = with_geometric("dth20", 0.01, Vector3::zeros());
    let (x, z) = (990.0, 995.0);
    let expected = Vector3::new(
        350.0 + x * eps.cos() + z * eps.sin(),
        0.0,
        815.0 - x * eps.sin() + z * eps.cos(),
    );
    assert!((flange_at(&model, HOME) - expected).norm() < 1e-9);
    // Δθ40 (axis sense −1): the flange orientation becomes Rx(+ε)·Ry(90°) in model sign.
    let model = with_geometric("dth40", 0.01, Vector3::zeros());
    let r = model.flange_pose(&AxisState::new(HOME)).rotation;
    let expected = Rotation3::from_axis_angle(&Vector3::x_axis(), eps).matrix()
        * Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0);
    assert!((r - expected).norm() < 1e-12);
}

#[test]
fn target_vector_is_given_in_the_flange_frame_and_corrected_in_the_a6_frame() {
    // Flange Z points +X at HOME, so a 100 mm tool along flange Z ends at x = 1440; the
    // correction p6z is along the A6 frame's z, which is the base z at HOME.
    let model = with_geometric("p6z", 0.05, Vector3::new(0.0, 0.0, 100.0));
    let p = model.target_position(&AxisState::new(HOME));
    assert!(
        (p - Vector3::new(1440.0, 0.0, 1810.05)).norm() < 1e-9,
        "{p}"
    );
}
