//! The paper's 18 geometric parameters (and the target correction), one at a time, against
//! equation (2) evaluated by an independent implementation written here: plain 4×4
//! homogeneous matrices `D_x D_y D_z` (translations) and `D_a D_b D_c` (rotations about X, Y, Z)
//! composed exactly as `../shared/MODEL.md` writes the chain, with θ1 = −A1, θ2 = A2 + 90°,
//! θ3 = A3 − 90°, θ4 = −A4, θ5 = A5, θ6 = −A6 and the KUKA flange = A6 frame · Ry(90°).
//!
//! Each parameter is set alone in a calibration *file* with only `geometric` (so the name a
//! user reads in the file is checked too), and the calibrated model's flange pose, target
//! position and target Jacobian column are compared with equation (2) at several poses. A
//! swapped pair of slots (`a32 ↔ g32`, `dx54 ↔ dz54`), a parameter in the wrong frame or a
//! flipped sign changes the prediction by the size of the parameter's own effect (≥ 20 µm
//! here), far above the tolerance.

use std::path::Path;

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};
use robopost::calibration;
use robopost::model::{AxisState, Model};

/// The KR 30 HA's links (MODEL.md), mm.
const L1X: f64 = 350.0;
const L1Z: f64 = 815.0;
const L2: f64 = 850.0;
const L3Z: f64 = 145.0;
const L4X: f64 = 820.0;
const L5X: f64 = 170.0;

/// The retroreflector in the KUKA flange frame, off every axis so every error moves it.
const TARGET: [f64; 3] = [-120.0, -80.0, 180.0];

/// Poses at which every parameter is compared: HOME, all zero, MODEL.md's two general
/// reference poses and three more with every axis away from zero.
const POSES: [[f64; 6]; 7] = [
    [0.0, -90.0, 90.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [30.0, -60.0, 100.0, 20.0, 40.0, -50.0],
    [-45.0, -112.0, 153.0, 0.0, -30.0, 90.0],
    [12.0, -75.0, 60.0, -110.0, 70.0, 35.0],
    [-150.0, -20.0, 130.0, 160.0, -95.0, -200.0],
    [80.0, -120.0, 15.0, -40.0, 15.0, 300.0],
];

/// Size of each perturbation: 0.1 mm for lengths, 0.01° for angles. Every parameter moves the
/// target by at least 20 µm at one of the poses (checked), so a swap or a flipped sign shows
/// as a difference of that size.
const LENGTH_MM: f64 = 0.1;
const ANGLE_DEG: f64 = 0.01;

/// Tolerances of the comparison. The model and equation (2) are both exact rigid-body chains;
/// if either composes the small rotations to first order only, the two differ by second-order
/// terms: (1.75e-4 rad)² × 2.2 m ≈ 0.07 µm and (1.75e-4)² rad. Far below the ≥ 20 µm and
/// ≥ 1.7e-4 rad of a wrong slot or sign.
const POSITION_TOL_MM: f64 = 2e-4;
const ROTATION_TOL_RAD: f64 = 1e-7;

fn translation(x: f64, y: f64, z: f64) -> Matrix4<f64> {
    Matrix4::new(
        1.0, 0.0, 0.0, x, //
        0.0, 1.0, 0.0, y, //
        0.0, 0.0, 1.0, z, //
        0.0, 0.0, 0.0, 1.0,
    )
}
fn dx(d: f64) -> Matrix4<f64> {
    translation(d, 0.0, 0.0)
}
fn dy(d: f64) -> Matrix4<f64> {
    translation(0.0, d, 0.0)
}
fn dz(d: f64) -> Matrix4<f64> {
    translation(0.0, 0.0, d)
}
/// Rotation about X by `deg`.
fn da(deg: f64) -> Matrix4<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Matrix4::new(
        1.0, 0.0, 0.0, 0.0, //
        0.0, c, -s, 0.0, //
        0.0, s, c, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    )
}
/// Rotation about Y by `deg`.
fn db(deg: f64) -> Matrix4<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Matrix4::new(
        c, 0.0, s, 0.0, //
        0.0, 1.0, 0.0, 0.0, //
        -s, 0.0, c, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    )
}
/// Rotation about Z by `deg`.
fn dc(deg: f64) -> Matrix4<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Matrix4::new(
        c, -s, 0.0, 0.0, //
        s, c, 0.0, 0.0, //
        0.0, 0.0, 1.0, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    )
}

/// The 18 parameters and the target correction, by name; zero when absent.
#[derive(Default, Clone, Copy)]
struct Errors {
    dx21: f64,
    a21: f64,
    dth20: f64,
    dz32: f64,
    a32: f64,
    g32: f64,
    dth30: f64,
    dz43: f64,
    dy43: f64,
    g43: f64,
    dth40: f64,
    dx54: f64,
    dz54: f64,
    g54: f64,
    dth50: f64,
    dz65: f64,
    dy65: f64,
    g65: f64,
    p6: [f64; 3],
}

impl Errors {
    fn one(name: &str, value: f64) -> Errors {
        let mut e = Errors::default();
        let slot = match name {
            "dx21" => &mut e.dx21,
            "a21" => &mut e.a21,
            "dth20" => &mut e.dth20,
            "dz32" => &mut e.dz32,
            "a32" => &mut e.a32,
            "g32" => &mut e.g32,
            "dth30" => &mut e.dth30,
            "dz43" => &mut e.dz43,
            "dy43" => &mut e.dy43,
            "g43" => &mut e.g43,
            "dth40" => &mut e.dth40,
            "dx54" => &mut e.dx54,
            "dz54" => &mut e.dz54,
            "g54" => &mut e.g54,
            "dth50" => &mut e.dth50,
            "dz65" => &mut e.dz65,
            "dy65" => &mut e.dy65,
            "g65" => &mut e.g65,
            "p6x" => &mut e.p6[0],
            "p6y" => &mut e.p6[1],
            "p6z" => &mut e.p6[2],
            other => panic!("unknown parameter {other}"),
        };
        *slot = value;
        e
    }
}

/// Equation (2): the A6 frame in the base frame at KUKA axes `a` (degrees).
fn equation_2(a: [f64; 6], e: &Errors) -> Matrix4<f64> {
    let th = [-a[0], a[1] + 90.0, a[2] - 90.0, -a[3], a[4], -a[5]];
    let r_t1 = dc(th[0]);
    let t12 = dx(L1X + e.dx21) * dz(L1Z) * da(e.a21) * db(th[1] + e.dth20);
    let t23 = dz(L2 + e.dz32) * da(e.a32) * dc(e.g32) * db(th[2] + e.dth30);
    let t34 = dz(L3Z + e.dz43) * dy(e.dy43) * dc(e.g43) * da(th[3] + e.dth40);
    let t45 = dx(L4X + e.dx54) * dz(e.dz54) * dc(e.g54) * db(th[4] + e.dth50);
    let t56 = dx(L5X) * dz(e.dz65) * dy(e.dy65) * dc(e.g65) * da(th[5]);
    r_t1 * t12 * t23 * t34 * t45 * t56
}

/// The KUKA flange pose (A6 frame · Ry(90°)) and the target position: the target vector is
/// given in the flange frame and corrected by 6p along the A6 frame's axes (MODEL.md).
fn reference(a: [f64; 6], e: &Errors) -> (Matrix3<f64>, Vector3<f64>, Vector3<f64>) {
    let t06 = equation_2(a, e);
    let flange = t06 * db(90.0);
    let target_a6 = db(90.0) * Vector4::new(TARGET[0], TARGET[1], TARGET[2], 1.0)
        + Vector4::new(e.p6[0], e.p6[1], e.p6[2], 0.0);
    let p = t06 * target_a6;
    (
        flange.fixed_view::<3, 3>(0, 0).into_owned(),
        flange.fixed_view::<3, 1>(0, 3).into_owned(),
        Vector3::new(p.x, p.y, p.z),
    )
}

/// A calibration file with only `geometric` and `name = value`, read through the file format.
fn calibrated(name: &str, value: f64) -> Model {
    let text = format!(
        r#"{{
  "format": "robopost-calibration/1",
  "robot": {{ "name": "KR 30 HA", "description": {{
    "links": {{ "l1x": {L1X}, "l1z": {L1Z}, "l2": {L2}, "l3z": {L3Z}, "l4x": {L4X}, "l5x": {L5X} }},
    "limits_deg": [[-185, 185], [-135, 35], [-120, 158], [-350, 350], [-119, 119], [-350, 350]],
    "senses": [-1, 1, 1, -1, 1, -1],
    "offsets_deg": [0, 90, -90, 0, 0, 0] }} }},
  "target_mm": [{}, {}, {}],
  "effects": [ {{ "name": "geometric", "parameters": {{ "{name}": {value} }} }} ]
}}"#,
        TARGET[0], TARGET[1], TARGET[2]
    );
    calibration::parse(&text, Path::new("one_parameter.json"))
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .model()
}

const NAMES: [&str; 21] = [
    "dx21", "a21", "dth20", "dz32", "a32", "g32", "dth30", "dz43", "dy43", "g43", "dth40", "dx54",
    "dz54", "g54", "dth50", "dz65", "dy65", "g65", "p6x", "p6y", "p6z",
];

fn size_of(name: &str) -> f64 {
    if name.starts_with('d') && !name.starts_with("dth") || name.starts_with("p6") {
        LENGTH_MM
    } else {
        ANGLE_DEG
    }
}

/// One parameter: the model's prediction equals equation (2)'s at every pose, the parameter
/// visibly moves the target somewhere, and the identification Jacobian's column for it is the
/// derivative of equation (2) (central difference).
fn check(name: &str) {
    let value = size_of(name);
    let model = calibrated(name, value);
    let errors = Errors::one(name, value);
    let index = model
        .parameter_names()
        .iter()
        .position(|n| n == &format!("geometric.{name}") || n == name)
        .unwrap_or_else(|| panic!("{name} not among {:?}", model.parameter_names()));
    let mut largest_effect: f64 = 0.0;
    for axes in POSES {
        let state = AxisState::new(axes);
        let (r_ref, flange_ref, target_ref) = reference(axes, &errors);
        let (_, _, target_nominal) = reference(axes, &Errors::default());
        largest_effect = largest_effect.max((target_ref - target_nominal).norm());

        let pose = model.flange_pose(&state);
        let r = pose.rotation;
        let dp = (pose.position - flange_ref).norm();
        let dr = (r.transpose() * r_ref - Matrix3::identity()).norm();
        assert!(
            dp < POSITION_TOL_MM,
            "{name} = {value} at {axes:?}: flange position off equation (2) by {:.3} µm",
            dp * 1e3
        );
        assert!(
            dr < ROTATION_TOL_RAD,
            "{name} = {value} at {axes:?}: flange orientation off equation (2) by {dr:.2e} rad"
        );
        let target = model.target_position(&state);
        assert!(
            (target - target_ref).norm() < POSITION_TOL_MM,
            "{name} = {value} at {axes:?}: target {target} vs equation (2) {target_ref} \
             ({:.3} µm)",
            (target - target_ref).norm() * 1e3
        );

        // The identification's derivative: mm per stored unit (mm or degree).
        let (_, columns) = model.target_jacobian(&state);
        let column = columns
            .iter()
            .find(|(i, _)| *i == index)
            .map_or(Vector3::zeros(), |(_, c)| *c);
        let h = value;
        let plus = reference(axes, &Errors::one(name, value + h)).2;
        let minus = reference(axes, &Errors::one(name, value - h)).2;
        let numeric = (plus - minus) / (2.0 * h);
        // Central difference over ±0.1 mm / ±0.01°: exact for lengths, error (h²/6)·|∂³p| for
        // angles, below 1e-6 mm per degree.
        assert!(
            (column - numeric).norm() < 1e-3 * numeric.norm().max(1.0),
            "{name} at {axes:?}: Jacobian column {column} vs equation (2) {numeric}"
        );
    }
    assert!(
        largest_effect > 0.02,
        "{name} = {value} moves the target by at most {largest_effect} mm: the comparison \
         could not tell it from zero"
    );
}

#[test]
fn no_error_is_the_nominal_chain() {
    // Equation (2) with no errors gives MODEL.md's reference poses.
    let (_, p, _) = reference(POSES[0], &Errors::default());
    assert!((p - Vector3::new(1340.0, 0.0, 1810.0)).norm() < 1e-9);
    let (_, p, _) = reference(POSES[1], &Errors::default());
    assert!((p - Vector3::new(2190.0, 0.0, 960.0)).norm() < 1e-9);
    let (_, p, _) = reference(POSES[2], &Errors::default());
    assert!((p - Vector3::new(1306.433, -797.425, 972.743)).norm() < 1e-3);
    let (_, p, _) = reference(POSES[3], &Errors::default());
    assert!((p - Vector3::new(645.201, 645.201, 1142.133)).norm() < 1e-3);
}

#[test]
fn every_parameter_name_is_checked() {
    let model = calibrated("dx21", 0.0);
    let names: Vec<String> = model
        .parameter_names()
        .iter()
        .map(|n| n.trim_start_matches("geometric.").to_string())
        .collect();
    assert_eq!(
        names, NAMES,
        "the geometric parameters changed: extend this test"
    );
}

macro_rules! one_parameter {
    ($($name:ident),* $(,)?) => {$(
        #[test]
        fn $name() {
            check(stringify!($name));
        }
    )*};
}

one_parameter!(
    dx21, a21, dth20, dz32, a32, g32, dth30, dz43, dy43, g43, dth40, dx54, dz54, g54, dth50, dz65,
    dy65, g65, p6x, p6y, p6z,
);
