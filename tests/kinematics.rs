//! Nominal kinematics: MODEL.md's reference poses, the closed-form FK against the error
//! model's chain (two independent implementations), IK against FK over random poses for
//! every branch, selection by S/T and by nearness along paths, singular and unreachable
//! targets, KUKA poses, and the `fk`/`ik` commands.

use nalgebra::{Isometry3, Matrix3, Vector3};
use proptest::prelude::*;
use robopost::kinematics::{
    flange_frame, forward, inverse, inverse_all, singularity, singularity_distances, status_turn,
    wrist_point, Frame, IkError, Pose, RobotDescription, Select, SingularityKind,
};

fn robot() -> RobotDescription {
    RobotDescription::kr30ha()
}

/// φ = atan2(l3z, l4x): A3 of the stretched arm (MODEL.md: 10.028°).
fn phi() -> f64 {
    145f64.atan2(820.0).to_degrees()
}

/// Largest position (mm) and rotation-matrix entry differences of two transforms.
fn gap(a: &impl Rigid, b: &impl Rigid) -> (f64, f64) {
    let (a, b) = (a.frame(), b.frame());
    (
        (a.position - b.position).norm(),
        (a.rotation - b.rotation).abs().max(),
    )
}

/// A transform either way it is written here: the crate's or nalgebra's.
trait Rigid {
    fn frame(&self) -> Frame;
}

impl Rigid for Frame {
    fn frame(&self) -> Frame {
        *self
    }
}

impl Rigid for Isometry3<f64> {
    fn frame(&self) -> Frame {
        Frame::from_isometry(self)
    }
}

fn assert_same_pose(a: &impl Rigid, b: &impl Rigid, mm: f64, what: &str) {
    let (dp, dr) = gap(a, b);
    assert!(
        dp < mm && dr < mm * 1e-3,
        "{what}: position {dp:e} mm, rotation {dr:e}"
    );
}

mod reference {
    use super::*;

    /// MODEL.md's table: axes, X Y Z, A B C, S, T.
    pub const POSES: [([f64; 6], [f64; 6], u8, u8); 4] = [
        (
            [0.0, -90.0, 90.0, 0.0, 0.0, 0.0],
            [1340.0, 0.0, 1810.0, 0.0, 90.0, 0.0],
            2,
            2,
        ),
        (
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [2190.0, 0.0, 960.0, 0.0, 90.0, 0.0],
            0,
            0,
        ),
        (
            [30.0, -60.0, 100.0, 20.0, 40.0, -50.0],
            [1306.433, -797.425, 972.743, 114.8220, 16.8326, -176.2561],
            2,
            34,
        ),
        (
            [-45.0, -112.0, 153.0, 0.0, -30.0, 90.0],
            [645.201, 645.201, 1142.133, -45.0, 0.0, -101.0],
            6,
            19,
        ),
    ];

    #[test]
    fn forward_status_and_turn_match_the_table() {
        for (axes, xyzabc, s, t) in POSES {
            let pose = forward(&robot(), &axes).to_pose();
            let got = pose.to_array();
            // The table is printed to 1e-3 mm and 1e-4 deg.
            for k in 0..6 {
                let tol = if k < 3 { 5e-4 } else { 5e-5 };
                assert!(
                    (got[k] - xyzabc[k]).abs() <= tol,
                    "{axes:?} component {k}: {} vs {}",
                    got[k],
                    xyzabc[k]
                );
            }
            assert_eq!(status_turn(&robot(), &axes), (s, t), "{axes:?}");
        }
    }

    #[test]
    fn the_first_two_poses_are_exact_by_hand() {
        // HOME: upper arm up, forearm forward 145 above A3, flange 170 beyond the wrist.
        let home = forward(&robot(), &POSES[0].0).position;
        assert!(
            (home - Vector3::new(350.0 + 820.0 + 170.0, 0.0, 815.0 + 850.0 + 145.0)).norm() < 1e-12
        );
        // Zero: both arms forward.
        let zero = forward(&robot(), &POSES[1].0).position;
        assert!(
            (zero - Vector3::new(350.0 + 850.0 + 820.0 + 170.0, 0.0, 815.0 + 145.0)).norm() < 1e-12
        );
    }

    #[test]
    fn ik_gives_back_each_reference_axis_set_from_its_s_and_t() {
        for (axes, _, s, t) in POSES {
            let flange = forward(&robot(), &axes);
            if singularity_distances(&robot(), &axes)[0].distance < 1e-6 {
                // HOME and zero have A5 = 0: resolved by keeping A4.
                let sol =
                    inverse(&robot(), &flange, Select::StatusNearest { s, near: axes }).unwrap();
                assert!(close_axes(&sol.axes_deg, &axes, 1e-9), "{axes:?}: {sol:?}");
                continue;
            }
            let sol = inverse(&robot(), &flange, Select::Status { s, t: Some(t) }).unwrap();
            assert!(close_axes(&sol.axes_deg, &axes, 1e-9), "{axes:?}: {sol:?}");
            assert_eq!((sol.s, sol.t), (s, t));
        }
    }
}

fn close_axes(a: &[f64; 6], b: &[f64; 6], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

fn assert_close_axes(a: &[f64; 6], b: &[f64; 6], tol: f64) {
    assert!(close_axes(a, b, tol), "{a:?} vs {b:?}");
}

/// Axis sets within the KR 30 HA's limits.
fn axes_in_limits() -> impl Strategy<Value = [f64; 6]> {
    let l = robot().limits_deg;
    (
        l[0][0]..l[0][1],
        l[1][0]..l[1][1],
        l[2][0]..l[2][1],
        l[3][0]..l[3][1],
        l[4][0]..l[4][1],
        l[5][0]..l[5][1],
    )
        .prop_map(|(a, b, c, d, e, f)| [a, b, c, d, e, f])
}

mod forward_kinematics {
    use super::*;
    use robopost::model::{chain, ChainErrors};

    proptest! {
        /// The closed form of `kinematics::fk` and the error model's chain with zero errors are
        /// written independently (one formula vs. a product of elementary transforms in the
        /// paper's frames): they must agree everywhere, also outside the limits.
        #[test]
        fn closed_form_equals_the_zero_error_chain(axes in prop::array::uniform6(-400.0f64..400.0)) {
            let closed = forward(&robot(), &axes);
            let chain = chain::flange_pose(&robot(), &axes, &ChainErrors::default());
            let (dp, dr) = gap(&closed, &chain);
            prop_assert!(dp < 1e-9 && dr < 1e-13, "{:?}: {} mm, {}", axes, dp, dr);
        }

        /// The wrist point lies l5x behind the flange along the flange's Z.
        #[test]
        fn wrist_point_is_behind_the_flange(axes in axes_in_limits()) {
            let (r, p) = flange_frame(&robot(), &axes);
            let w = wrist_point(&robot(), &axes);
            prop_assert!((p - 170.0 * r.column(2) - w).norm() < 1e-9);
        }
    }

    #[test]
    fn turn_bits_are_the_signs_of_the_axes() {
        let (_, t) = status_turn(&robot(), &[-1.0, 2.0, -3.0, 4.0, -5.0, -6.0]);
        assert_eq!(t, 0b110101);
        // Zero counts as positive.
        assert_eq!(status_turn(&robot(), &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]).1, 0);
    }

    #[test]
    fn status_bit_0_is_the_wrist_point_behind_the_a1_axis() {
        // In the arm plane (MODEL.md senses): upper arm (cos A2, −sin A2), forearm
        // (cos ψ, −sin ψ) with ψ = A2 + A3, the 145 mm offset along (sin ψ, cos ψ).
        let x_by_hand = |a2: f64, a3: f64| {
            let (a2, psi) = (a2.to_radians(), (a2 + a3).to_radians());
            350.0 + 850.0 * a2.cos() + 820.0 * psi.cos() + 145.0 * psi.sin()
        };
        for axes in [
            [0.0, -90.0, 170.0, 0.0, 30.0, 0.0],
            [0.0, -130.0, 30.0, 0.0, 30.0, 0.0],
            [50.0, -130.0, 30.0, 0.0, 30.0, 0.0],
        ] {
            let x = x_by_hand(axes[1], axes[2]);
            let w = wrist_point(&robot(), &axes);
            let (s1, c1) = axes[0].to_radians().sin_cos();
            // A1 turns about −Z: the A1 frame's x axis is (cos A1, −sin A1, 0).
            assert!((w.x * c1 - w.y * s1 - x).abs() < 1e-9, "{axes:?}");
            assert_eq!(
                status_turn(&robot(), &axes).0 & 1,
                u8::from(x < 0.0),
                "{axes:?}"
            );
        }
        assert!(x_by_hand(-130.0, 30.0) < 0.0, "reaching back over the base");
    }

    #[test]
    fn singularity_warnings() {
        let near_wrist = singularity(&robot(), &[10.0, -80.0, 100.0, 35.0, 0.5, 20.0]).unwrap();
        assert_eq!(near_wrist.kind, SingularityKind::Wrist);
        assert!((near_wrist.distance - 0.5).abs() < 1e-12);
        let near_elbow = singularity(&robot(), &[0.0, -30.0, phi() - 0.3, 0.0, 40.0, 0.0]).unwrap();
        assert_eq!(near_elbow.kind, SingularityKind::Elbow);
        assert!((near_elbow.distance - 0.3).abs() < 1e-9);
        assert!(singularity(&robot(), &[30.0, -60.0, 100.0, 20.0, 40.0, -50.0]).is_none());
        // The shoulder distance is the wrist point's distance from the A1 axis.
        let axes = [25.0, -90.0, -60.0, 0.0, 40.0, 0.0];
        let d = singularity_distances(&robot(), &axes)[2].distance;
        let w = wrist_point(&robot(), &axes);
        assert!((d - w.x.hypot(w.y)).abs() < 1e-9);
    }
}

mod inverse_kinematics {
    use super::*;

    /// `result` is the singularity `kind`, closer than `within` (deg or mm).
    fn assert_singular<T: std::fmt::Debug>(
        result: Result<T, IkError>,
        kind: SingularityKind,
        within: f64,
    ) {
        match result {
            Err(IkError::Singular {
                kind: found,
                distance_deg_or_mm,
            }) if found == kind => assert!(distance_deg_or_mm < within, "{distance_deg_or_mm}"),
            other => panic!("expected {kind:?}: {other:?}"),
        }
    }

    /// What the rotation of an IK branch may be off by: 1e-12, or near the wrist singularity
    /// the rounding of A4 and A6, which are read off terms of size sin A5 (an error of a few
    /// ε / sin A5 each).
    fn rotation_tolerance(axes: &[f64; 6]) -> f64 {
        1e-12_f64.max(8.0 * f64::EPSILON / axes[4].to_radians().sin().abs())
    }

    /// A case proptest found 0.0077° from the wrist singularity: a rotation gap of 1.1e-12.
    #[test]
    fn a_branch_near_the_wrist_singularity_reaches_the_pose() {
        let axes = [
            49.21154955654655,
            -126.56551431749293,
            85.97525866566141,
            -208.82945081329174,
            -0.00767226150057942,
            -294.2900897467773,
        ];
        assert!(clear_of_singularities(&axes));
        let r = robot();
        let flange = forward(&r, &axes);
        for sol in &inverse_all(&r, &flange).unwrap() {
            let (dp, dr) = gap(&forward(&r, &sol.axes_deg), &flange);
            assert!(
                dp < 1e-8 && dr < rotation_tolerance(&axes),
                "{sol:?}: {dp} mm {dr}"
            );
        }
    }

    fn clear_of_singularities(axes: &[f64; 6]) -> bool {
        let d = singularity_distances(&robot(), axes);
        d[0].distance > 1e-3 && d[1].distance > 1e-3 && d[2].distance > 1e-2
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Every branch IK returns reaches the pose, lies within the limits, has the S and T
        /// its angles give, and the axes the pose came from are among them.
        #[test]
        fn every_branch_reaches_the_pose(axes in axes_in_limits()) {
            prop_assume!(clear_of_singularities(&axes));
            let r = robot();
            let flange = forward(&r, &axes);
            let all = inverse_all(&r, &flange).unwrap();
            for sol in &all {
                let (dp, dr) = gap(&forward(&r, &sol.axes_deg), &flange);
                prop_assert!(dp < 1e-8 && dr < rotation_tolerance(&axes), "{:?}: {} mm {}", sol, dp, dr);
                prop_assert!(r.within_limits(&sol.axes_deg), "{:?}", sol);
                prop_assert_eq!(status_turn(&r, &sol.axes_deg), (sol.s, sol.t));
            }
            prop_assert!(all.iter().any(|s| close_axes(&s.axes_deg, &axes, 1e-7)),
                "{:?} not among {:?}", axes, all);
            // No solution twice.
            for (i, a) in all.iter().enumerate() {
                for b in &all[i + 1..] {
                    prop_assert!(!close_axes(&a.axes_deg, &b.axes_deg, 1e-6));
                }
            }
        }

        /// Selecting by S and T gives the requested S and T and the original axes.
        #[test]
        fn status_and_turn_select_the_original_axes(axes in axes_in_limits()) {
            prop_assume!(clear_of_singularities(&axes));
            let r = robot();
            let (s, t) = status_turn(&r, &axes);
            let flange = forward(&r, &axes);
            let sol = inverse(&r, &flange, Select::Status { s, t: Some(t) }).unwrap();
            prop_assert_eq!((sol.s, sol.t), (s, t));
            prop_assert!(close_axes(&sol.axes_deg, &axes, 1e-7), "{:?} vs {:?}", sol, axes);
            // Every other (S, T) on offer is honoured too.
            for other in inverse_all(&r, &flange).unwrap() {
                let picked = inverse(&r, &flange, Select::Status { s: other.s, t: Some(other.t) }).unwrap();
                prop_assert_eq!((picked.s, picked.t), (other.s, other.t));
                prop_assert!(gap(&forward(&r, &picked.axes_deg), &flange).0 < 1e-8);
            }
        }

        /// Nearness to a slightly different axis state finds the original axes, with any S.
        #[test]
        fn nearest_to_a_nearby_state_is_the_original(axes in axes_in_limits(), nudge in prop::array::uniform6(-0.5f64..0.5)) {
            // Another branch lies at least 2·2° away in A3 (elbow) or A5 (wrist flip), more than
            // twice the nudge (|nudge| ≤ √6·0.5°).
            let d = singularity_distances(&robot(), &axes);
            prop_assume!(d[0].distance > 2.0 && d[1].distance > 2.0 && d[2].distance > 10.0);
            let r = robot();
            let near: [f64; 6] = std::array::from_fn(|i| axes[i] + nudge[i]);
            let flange = forward(&r, &axes);
            let sol = inverse(&r, &flange, Select::Nearest(near)).unwrap();
            prop_assert!(close_axes(&sol.axes_deg, &axes, 1e-7), "{:?} vs {:?}", sol, axes);
            let (s, _) = status_turn(&r, &axes);
            let sol = inverse(&r, &flange, Select::StatusNearest { s, near }).unwrap();
            prop_assert!(close_axes(&sol.axes_deg, &axes, 1e-7), "{:?} vs {:?}", sol, axes);
        }
    }

    /// A path whose A4 and A6 run past ±180° and whose A1 passes 180°: each step's nearest
    /// solution is the next axis state, where selection by S alone wraps.
    #[test]
    fn nearest_follows_a_path_past_half_turns() {
        let r = robot();
        let start = [170.0, -70.0, 95.0, 150.0, 35.0, 120.0];
        let step = [0.3, 0.3, -0.4, 2.0, -0.2, 3.5];
        let path: Vec<[f64; 6]> = (0..40)
            .map(|k| std::array::from_fn(|i| start[i] + k as f64 * step[i]))
            .collect();
        let (s, _) = status_turn(&r, &path[0]);
        let mut wrapped = 0;
        for w in path.windows(2) {
            let flange = forward(&r, &w[1]);
            let sol = inverse(&r, &flange, Select::Nearest(w[0])).unwrap();
            assert_close_axes(&sol.axes_deg, &w[1], 1e-8);
            let kept = inverse(&r, &flange, Select::StatusNearest { s, near: w[0] }).unwrap();
            assert_eq!(kept.axes_deg, sol.axes_deg);
            let by_status = inverse(&r, &flange, Select::Status { s, t: None }).unwrap();
            if !close_axes(&by_status.axes_deg, &w[1], 1e-6) {
                wrapped += 1;
            }
        }
        assert!(path[39][0] > 180.0 && path[39][3] > 180.0 && path[39][5] > 180.0);
        assert!(wrapped > 20, "selection by S alone wraps the angles");
    }

    /// MODEL.md: LIN/CIRC keep the start's configuration; a path through A5 = 0 with
    /// `StatusNearest` turns A4/A6 by 180° instead of letting A5 change sign, `Nearest` does not.
    #[test]
    fn a_path_through_the_wrist_singularity() {
        let r = robot();
        let path: Vec<[f64; 6]> = (0..=20)
            .map(|k| [10.0, -80.0, 100.0, 35.0, 10.0 - k as f64, 20.0])
            .collect();
        let s0 = status_turn(&r, &path[0]).0;
        for w in path.windows(2) {
            let flange = forward(&r, &w[1]);
            let sol = inverse(&r, &flange, Select::Nearest(w[0])).unwrap();
            assert_close_axes(&sol.axes_deg, &w[1], 1e-8);
            let kept = inverse(&r, &flange, Select::StatusNearest { s: s0, near: w[0] }).unwrap();
            assert!(gap(&forward(&r, &kept.axes_deg), &flange).0 < 1e-8);
            assert_eq!(kept.s, s0);
            if w[1][4] < 0.0 {
                assert!(kept.axes_deg[4] > 0.0 && (kept.axes_deg[3] - 35.0).abs() > 179.0);
            }
        }
    }

    #[test]
    fn at_a5_zero_the_previous_a4_is_kept_and_the_rest_goes_to_a6() {
        let r = robot();
        let axes = [10.0, -80.0, 100.0, 35.0, 0.0, 20.0];
        let flange = forward(&r, &axes);
        let (s, _) = status_turn(&r, &axes);
        // Strict selection reports the singularity and its distance.
        assert_singular(
            inverse(&r, &flange, Select::Status { s, t: None }),
            SingularityKind::Wrist,
            1e-7,
        );
        // A4 + A6 is what the pose fixes (both turn about the same line): 55°.
        let previous = [10.5, -80.0, 100.0, 50.0, 3.0, 0.0];
        for select in [
            Select::Nearest(previous),
            Select::StatusNearest { s, near: previous },
        ] {
            let sol = inverse(&r, &flange, select).unwrap();
            assert_eq!(sol.axes_deg[3], 50.0, "A4 kept");
            assert!(sol.axes_deg[4].abs() < 1e-7);
            assert!((sol.axes_deg[5] - 5.0).abs() < 1e-7, "{:?}", sol.axes_deg);
            assert!((sol.axes_deg[0] - 10.0).abs() < 1e-9);
            assert_same_pose(&forward(&r, &sol.axes_deg), &flange, 1e-8, "resolved");
        }
        // inverse_all leaves the undetermined configuration out and keeps the others.
        let all = inverse_all(&r, &flange).unwrap();
        assert!(!all
            .iter()
            .any(|x| x.s & 3 == s & 3 && x.axes_deg[4].abs() < 1e-6));
        for x in &all {
            assert_same_pose(&forward(&r, &x.axes_deg), &flange, 1e-8, "other branch");
        }
    }

    #[test]
    fn wrist_point_on_the_a1_axis() {
        let r = robot();
        // Flange Z up (A = B = C = 0), wrist point 170 mm below it on the A1 axis.
        let flange = Frame::from_kuka(&Pose::from_array([0.0, 0.0, 2170.0, 0.0, 0.0, 0.0]));
        assert_singular(inverse_all(&r, &flange), SingularityKind::Shoulder, 1e-9);
        let sol = inverse(
            &r,
            &flange,
            Select::Nearest([30.0, -100.0, 60.0, 0.0, 20.0, 0.0]),
        )
        .unwrap();
        assert_eq!(sol.axes_deg[0], 30.0, "A1 kept");
        assert_same_pose(&forward(&r, &sol.axes_deg), &flange, 1e-8, "resolved");
    }

    #[test]
    fn stretched_arm() {
        let r = robot();
        let axes = [0.0, -30.0, phi(), 0.0, 20.0, 0.0];
        let flange = forward(&r, &axes);
        for s in [0, 2] {
            assert_singular(
                inverse(&r, &flange, Select::Status { s, t: None }),
                SingularityKind::Elbow,
                1e-5,
            );
        }
        let sol = inverse(
            &r,
            &flange,
            Select::Nearest([0.0, -29.0, 12.0, 0.0, 20.0, 0.0]),
        )
        .unwrap();
        assert!(close_axes(&sol.axes_deg, &axes, 1e-5), "{:?}", sol.axes_deg);
        assert_same_pose(&forward(&r, &sol.axes_deg), &flange, 1e-6, "stretched");
    }

    #[test]
    fn beyond_the_reach_by_hand() {
        // Flange Z along +X (B = 90°): wrist point (2830, 0, 815), 2480 mm from the A2 axis.
        let flange = Frame::from_kuka(&Pose::from_array([3000.0, 0.0, 815.0, 0.0, 90.0, 0.0]));
        let reach = 850.0 + 145f64.hypot(820.0);
        match inverse_all(&robot(), &flange) {
            Err(IkError::Unreachable {
                distance_mm,
                too_far: true,
            }) => assert!((distance_mm - (2480.0 - reach)).abs() < 1e-9),
            other => panic!("{other:?}"),
        }
        let err = inverse(&robot(), &flange, Select::Nearest([0.0; 6])).unwrap_err();
        assert!(err.to_string().contains("beyond the arm's reach"), "{err}");
    }

    #[test]
    fn too_close_to_the_a2_axis_by_hand() {
        // Without the A1–A2 offset both shoulders see the same distance: wrist point 5 mm
        // from the A2 axis, the arm cannot fold closer than |l2 − K|.
        let mut r = robot();
        r.links.l1x = 0.0;
        let k = 145f64.hypot(820.0);
        let flange = Frame::from_kuka(&Pose::from_array([175.0, 0.0, 815.0, 0.0, 90.0, 0.0]));
        match inverse_all(&r, &flange) {
            Err(IkError::Unreachable {
                distance_mm,
                too_far: false,
            }) => assert!((distance_mm - ((850.0 - k) - 5.0)).abs() < 1e-9),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn out_of_limits_names_an_axis_outside_them() {
        let r = robot();
        // Reaching down in front of the base needs A2 beyond +35°.
        let axes = [0.0, 80.0, -30.0, 0.0, 40.0, 0.0];
        let flange = forward(&r, &axes);
        let mut free = r;
        free.limits_deg = [[-360.0, 360.0]; 6];
        let unlimited = inverse_all(&free, &flange).unwrap();
        assert!(unlimited.iter().all(|s| !r.within_limits(&s.axes_deg)));
        match inverse_all(&r, &flange) {
            Err(IkError::OutOfLimits {
                axis,
                value_deg,
                limits_deg,
            }) => {
                assert_eq!(limits_deg, r.limits_deg[axis as usize - 1]);
                assert!(value_deg < limits_deg[0] || value_deg > limits_deg[1]);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn non_finite_poses_are_errors_not_panics() {
        let r = robot();
        for bad in [f64::NAN, f64::INFINITY, 1e300] {
            let flange = Frame::from_kuka(&Pose::from_array([bad, 0.0, 1000.0, 0.0, 90.0, 0.0]));
            assert!(inverse_all(&r, &flange).is_err());
            assert!(inverse(&r, &flange, Select::Nearest([0.0; 6])).is_err());
            assert!(inverse(&r, &flange, Select::Status { s: 2, t: None }).is_err());
        }
    }

    #[test]
    fn a_turn_that_does_not_exist() {
        let r = robot();
        let flange = forward(&r, &[30.0, -60.0, 100.0, 20.0, 40.0, -50.0]);
        // T bit 0 asks for A1 < 0: 30° − 360° is beyond −185°.
        match inverse(&r, &flange, Select::Status { s: 2, t: Some(35) }) {
            Err(IkError::NoBranch {
                s: 2,
                t: Some(35),
                available,
            }) => {
                assert!(available.contains(&(2, 34)), "{available:?}");
            }
            other => panic!("{other:?}"),
        }
    }
}

mod poses {
    use super::*;

    fn angle() -> impl Strategy<Value = f64> {
        -179.9f64..179.9
    }

    proptest! {
        #[test]
        fn pose_to_transform_and_back(x in -3000.0f64..3000.0, a in angle(), b in -89.9f64..89.9, c in angle()) {
            let p = Pose { x, y: -x / 2.0, z: 1000.0, a, b, c };
            let back = Frame::from_kuka(&p).to_pose();
            for (u, v) in p.to_array().iter().zip(back.to_array()) {
                prop_assert!((u - v).abs() < 1e-9, "{:?} vs {:?}", p, back);
            }
        }

        #[test]
        fn composition_is_the_transform_product(a in angle(), b in -89.0f64..89.0, c in angle(), d in angle()) {
            let p = Pose { x: 100.0, y: 20.0, z: -5.0, a, b, c };
            let q = Pose { x: -7.0, y: 300.0, z: 40.0, a: d, b: b / 2.0, c: a };
            let product = Frame::from_kuka(&p).to_isometry() * Frame::from_kuka(&q).to_isometry();
            assert_same_pose(&Frame::from_kuka(&(p * q)), &product, 1e-9, "p : q");
            assert_same_pose(&Frame::from_kuka(&p.inverse().compose(&p)), &Isometry3::identity(), 1e-9, "inv(p) : p");
        }
    }

    #[test]
    fn composition_by_hand() {
        // Move 100 along X, turn 90° about Z, move 10 along the new X (= base Y).
        let p = Pose::from_array([100.0, 0.0, 0.0, 90.0, 0.0, 0.0]);
        let q = Pose::from_array([10.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let pq = p * q;
        assert!((pq.x - 100.0).abs() < 1e-12 && (pq.y - 10.0).abs() < 1e-12 && pq.z.abs() < 1e-12);
        assert!((pq.a - 90.0).abs() < 1e-12 && pq.b.abs() < 1e-12 && pq.c.abs() < 1e-12);
        // The inverse of a pure rotation about Y by 30° at (0, 0, 50).
        let inv = Pose::from_array([0.0, 0.0, 50.0, 0.0, 30.0, 0.0]).inverse();
        let (s, c) = 30f64.to_radians().sin_cos();
        // −Rᵀ·t with Rᵀ = Ry(−30°): (−(−s)·... ) = (50·s, 0, −50·c).
        assert!((inv.x - 50.0 * s).abs() < 1e-12 && (inv.z + 50.0 * c).abs() < 1e-12);
        assert!((inv.b + 30.0).abs() < 1e-12);
    }

    #[test]
    fn rotation_is_rz_ry_rx() {
        let p = Pose::from_array([0.0, 0.0, 0.0, 20.0, 30.0, 40.0]);
        let r = Frame::from_kuka(&p).rotation;
        let rz = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 20f64.to_radians());
        let ry = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), 30f64.to_radians());
        let rx = nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), 40f64.to_radians());
        let expected: Matrix3<f64> = (rz * ry * rx).into_inner();
        assert!((r - expected).abs().max() < 1e-15);
    }

    #[test]
    fn home_prints_with_the_b_90_convention() {
        let p = forward(&robot(), &[0.0, -90.0, 90.0, 0.0, 0.0, 0.0]).to_pose();
        assert_eq!((p.a, p.b, p.c), (0.0, 90.0, 0.0));
        // A1 = 30° at HOME turns about the flange X (pointing down): at B = 90° only A − C is
        // defined, and the convention puts it all in A.
        let axes = [30.0, -90.0, 90.0, 0.0, 0.0, 0.0];
        let p = forward(&robot(), &axes).to_pose();
        assert!(
            (p.a + 30.0).abs() < 1e-9 && p.b == 90.0 && p.c == 0.0,
            "{p:?}"
        );
        assert_same_pose(
            &Frame::from_kuka(&p),
            &forward(&robot(), &axes),
            1e-9,
            "B = 90",
        );
    }
}

mod cli {
    use super::*;
    use robopost::calibration::{Calibration, MeasurementFrame, Provenance};
    use robopost::kinematics::Payload;
    use robopost::model::{expand_list, AxisState, GridOptions, Model};
    use std::path::Path;
    use std::process::{Command, Output};

    fn run(args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_robopost"))
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("run robopost")
    }

    fn json(out: &Output) -> serde_json::Value {
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).expect("JSON on stdout")
    }

    fn text(out: &Output) -> String {
        String::from_utf8(out.stdout.clone()).unwrap()
    }

    #[test]
    fn fk_json_is_the_forward_kinematics() {
        let axes = [30.0, -60.0, 100.0, 20.0, 40.0, -50.0];
        let v = json(&run(&[
            "fk", "30", "-60", "100", "20", "40", "-50", "--json",
        ]));
        let p = forward(&robot(), &axes).to_pose();
        for (key, want) in ["x", "y", "z", "a", "b", "c"].iter().zip(p.to_array()) {
            assert_eq!(v[key].as_f64().unwrap(), want, "{key}");
        }
        assert_eq!((v["s"].as_u64(), v["t"].as_u64()), (Some(2), Some(34)));
        assert!(v.get("model").is_none());
    }

    #[test]
    fn fk_human_output() {
        let out = run(&["fk", "30", "-60", "100", "20", "40", "-50"]);
        assert!(out.status.success());
        insta::assert_snapshot!("fk_reference_3", text(&out));
        let out = run(&[
            "fk",
            "-45",
            "-112",
            "153",
            "0",
            "-30",
            "90",
            "-c",
            "calibrations/kr30ha-nominal.json",
        ]);
        assert!(out.status.success());
        insta::assert_snapshot!("fk_reference_4_nominal_calibration", text(&out));
    }

    /// A calibration with geometric errors and an A2 backlash table, saved in a temp dir.
    fn calibration_with_errors(dir: &Path) -> (std::path::PathBuf, Model) {
        let mut model = Model::new(robot(), Payload::default(), Vector3::zeros());
        for name in expand_list("geometric,map:A2,backlash:A2").unwrap() {
            model.push_named(&name, &GridOptions::default()).unwrap();
        }
        let values: Vec<f64> = (0..model.n_parameters())
            .map(|i| ((i as f64) * 0.37).sin() * 0.05)
            .collect();
        model.set_values(&values);
        model.make_physical(&[]); // gear plays have widths ≥ 0
        let path = dir.join("cal.json");
        Calibration::from_model(
            "test",
            model.clone(),
            MeasurementFrame::Base,
            Provenance::default(),
        )
        .save_atomic(&path)
        .unwrap();
        (path, model)
    }

    #[test]
    fn fk_with_a_calibration_prints_the_model_prediction() {
        let dir = tempfile::tempdir().unwrap();
        let (path, model) = calibration_with_errors(dir.path());
        let axes = [10.0, -70.0, 100.0, 20.0, 30.0, -40.0];
        let args = [
            "fk",
            "10",
            "-70",
            "100",
            "20",
            "30",
            "-40",
            "-c",
            path.to_str().unwrap(),
        ];
        let v = json(&run(&[&args[..], &["--json"]].concat()));
        // Unknown directions: the backlash branch mean, i.e. the map alone.
        let predicted = model.flange_pose(&AxisState::new(axes));
        let p = predicted.to_pose();
        for (key, want) in ["x", "y", "z", "a", "b", "c"].iter().zip(p.to_array()) {
            assert!(
                (v["model"][key].as_f64().unwrap() - want).abs() < 1e-12,
                "{key}"
            );
        }
        let nominal = forward(&robot(), &axes).position;
        let d = predicted.position - nominal;
        assert!(d.norm() > 0.01, "the errors move the flange");
        for (k, key) in ["x", "y", "z"].iter().enumerate() {
            assert!((v["difference"][key].as_f64().unwrap() - d[k]).abs() < 1e-12);
        }
        assert!(
            (v["difference"]["distance_um"].as_f64().unwrap() - d.norm() * 1000.0).abs() < 1e-9
        );
        let human = text(&run(&args));
        assert!(
            human.contains("model    {X ") && human.contains("model − nominal"),
            "{human}"
        );
    }

    #[test]
    fn ik_json_lists_branches_that_reach_the_pose() {
        let axes = [30.0, -60.0, 100.0, 20.0, 40.0, -50.0];
        let flange = forward(&robot(), &axes);
        let p = flange.to_pose().to_array().map(|v| format!("{v}"));
        let mut args = vec!["ik"];
        args.extend(p.iter().map(String::as_str));
        args.push("--json");
        let v = json(&run(&args));
        let solutions = v["solutions"].as_array().unwrap();
        assert_eq!(
            solutions.len(),
            inverse_all(&robot(), &flange).unwrap().len()
        );
        let mut found = false;
        for sol in solutions {
            let a: Vec<f64> = sol["axes"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            let a: [f64; 6] = a.try_into().unwrap();
            assert!(gap(&forward(&robot(), &a), &flange).0 < 1e-8);
            let (s, t) = status_turn(&robot(), &a);
            assert_eq!(
                (sol["s"].as_u64(), sol["t"].as_u64()),
                (Some(s as u64), Some(t as u64))
            );
            found |= close_axes(&a, &axes, 1e-8);
        }
        assert!(found);
        // Selected by binary S and decimal T.
        args.extend(["--s", "'B010'", "--t", "34"]);
        let v = json(&run(&args));
        let only = v["solutions"].as_array().unwrap();
        assert_eq!(only.len(), 1);
        let a: Vec<f64> = only[0]["axes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!(close_axes(&a.try_into().unwrap(), &axes, 1e-8));
    }

    #[test]
    fn ik_human_output_marks_the_singular_home_branch() {
        let out = run(&["ik", "1340", "0", "1810", "0", "90", "0"]);
        assert!(out.status.success());
        insta::assert_snapshot!("ik_home", text(&out));
    }

    #[test]
    fn errors_and_exit_codes() {
        let out = run(&["ik", "5000", "0", "0", "0", "0", "0"]);
        assert_eq!(out.status.code(), Some(1));
        assert!(String::from_utf8_lossy(&out.stderr).contains("unreachable"));
        assert!(out.stdout.is_empty());
        // Too few angles, a bad S literal, a missing calibration: usage errors.
        assert_eq!(run(&["fk", "0", "-90"]).status.code(), Some(2));
        assert_eq!(
            run(&["ik", "1", "2", "3", "4", "5", "6", "--s", "B102"])
                .status
                .code(),
            Some(2)
        );
        let out = run(&["fk", "0", "0", "0", "0", "0", "0", "-c", "no/such/cal.json"]);
        assert_eq!(out.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&out.stderr).contains("no/such/cal.json"));
    }
}

/// The shipped robot descriptions (`calibrations/*-nominal.json`) against an independent
/// chain written here from the public numbers they came from: each robot's URDF joints
/// (ROS-Industrial kuka_experimental: joint origins in the parent link, KUKA axis directions
/// A1 −Z, A2 +Y, A3 +Y, A4 −X, A5 +Y, A6 −X, the KUKA angle as the joint value, the flange
/// `tool0` frame turned +90° about Y), or, where no URDF is public, the machine data's
/// `$TIRORO`, `$LENGTH_A/B`, `$TX3P3`, `$TFLWP` laid out the same way. The flange pose of
/// robopost's closed-form FK must be the chain's at poses over the whole range.
#[test]
fn shipped_robots_match_their_public_chains() {
    use nalgebra::{Rotation3, Translation3, UnitQuaternion};
    use robopost::calibration::robots;
    // Joint origins (mm): A1 z; A2 x; A3 x; A4 (x, z); A5 x; A6 x; flange x.
    let chains: &[(&str, [f64; 8])] = &[
        (
            "KR 30 HA",
            [815.0, 350.0, 850.0, 820.0, 145.0, 0.0, 0.0, 170.0],
        ),
        (
            "KR 6 R700 sixx",
            [400.0, 25.0, 315.0, 0.0, 35.0, 365.0, 80.0, 0.0],
        ),
        (
            "KR 6 R900 sixx",
            [400.0, 25.0, 455.0, 0.0, 35.0, 420.0, 80.0, 0.0],
        ),
        (
            "KR 10 R1420",
            [450.0, 150.0, 610.0, 0.0, 20.0, 660.0, 80.0, 0.0],
        ),
        (
            "KR 16-2",
            [675.0, 260.0, 680.0, 670.0, -35.0, 0.0, 0.0, 158.0],
        ),
        (
            "KR 120 R2500 pro",
            [675.0, 350.0, 1150.0, 1000.0, -41.0, 0.0, 0.0, 215.0],
        ),
        (
            "KR 150 R3100-2",
            [645.0, 330.0, 1350.0, 1420.0, 115.0, 0.0, 215.0, 0.0],
        ),
        // Machine data: $TIRORO Z, $LENGTH_A, $LENGTH_B, $TX3P3 X and Z, $TFLWP Z.
        (
            "KR 120 R2700-2",
            [645.0, 330.0, 1150.0, 1220.0, 115.0, 0.0, 0.0, 215.0],
        ),
        (
            "KR 210 R2700 prime",
            [675.0, 350.0, 1150.0, 1200.0, -41.0, 0.0, 0.0, 240.0],
        ),
    ];
    assert_eq!(chains.len(), robots::ROBOTS.len());
    let rot = |axis: Vector3<f64>, deg: f64| {
        UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), deg.to_radians())
    };
    let joint = |origin: [f64; 3], axis: Vector3<f64>, deg: f64| {
        Isometry3::from_parts(
            Translation3::new(origin[0], origin[1], origin[2]),
            rot(axis, deg),
        )
    };
    for (name, o) in chains {
        let robot = robots::by_name(name)
            .unwrap()
            .calibration()
            .model_ref()
            .robot;
        let [lo, hi] = [0, 1].map(|k| robot.limits_deg.map(|l| l[k]));
        for k in 0..40 {
            // Poses spread over the range (deterministic), the limits included.
            let q: [f64; 6] = std::array::from_fn(|i| {
                let t = ((k * 7 + i * 13) % 41) as f64 / 40.0;
                lo[i] + t * (hi[i] - lo[i])
            });
            let chain = joint([0.0, 0.0, o[0]], -Vector3::z(), q[0])
                * joint([o[1], 0.0, 0.0], Vector3::y(), q[1])
                * joint([o[2], 0.0, 0.0], Vector3::y(), q[2])
                * joint([o[3], 0.0, o[4]], -Vector3::x(), q[3])
                * joint([o[5], 0.0, 0.0], Vector3::y(), q[4])
                * joint([o[6], 0.0, 0.0], -Vector3::x(), q[5])
                * Isometry3::from_parts(
                    Translation3::new(o[7], 0.0, 0.0),
                    UnitQuaternion::from_rotation_matrix(&Rotation3::from_axis_angle(
                        &Vector3::y_axis(),
                        90f64.to_radians(),
                    )),
                );
            assert_same_pose(&forward(&robot, &q), &chain, 1e-9, &format!("{name} {q:?}"));
        }
    }
}
