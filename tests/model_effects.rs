//! Tables, gear-play branches, crosstalk, compliance torques, tilt, drift and effect names
//! against hand calculations.

use std::f64::consts::PI;

use robopost::kinematics::{Gravity, Payload, RobotDescription};
use robopost::model::effects::axis_table::AxisTable;
use robopost::model::effects::compliance::{gravity_torques_knm, Compliance, STANDARD_GRAVITY};
use robopost::model::effects::crosstalk::Crosstalk;
use robopost::model::effects::drift::Drift;
use robopost::model::effects::learned::{Learned, SpecError};
use robopost::model::effects::map::AngleMap;
use robopost::model::effects::play::GearPlay;
use robopost::model::effects::tilt::Tilt;
use robopost::model::table::{Grid, GridError, Table1, Table2};
use robopost::model::{
    expand_list, AxisHistory, AxisState, ChainErrors, Context, Direction, Effect, EffectError,
    EffectName, GridOptions, Slot,
};

const DEG: f64 = PI / 180.0;

#[test]
fn linear_interpolation_on_uniform_and_irregular_grids() {
    let uniform = Table1 {
        grid: Grid::new(vec![-10.0, 0.0, 10.0, 20.0]).unwrap(),
        values: vec![1.0, 3.0, -1.0, 0.0],
    };
    // 2.5 lies a quarter into [0, 10]: 3 + 0.25·(−1 − 3) = 2.
    let (v, cell) = uniform.eval(2.5);
    assert!((v - 2.0).abs() < 1e-15 && cell.lo == 1 && cell.hi == 2 && !cell.clamped);
    // Exactly on a node.
    assert_eq!(uniform.eval(10.0).0, -1.0);
    let irregular = Table1 {
        grid: Grid::new(vec![0.0, 1.0, 5.0, 6.0]).unwrap(),
        values: vec![0.0, 2.0, 10.0, 0.0],
    };
    // 4 lies 3/4 into [1, 5]: 2 + 0.75·8 = 8.
    let (v, cell) = irregular.eval(4.0);
    assert!((v - 8.0).abs() < 1e-15 && cell.lo == 1, "{v} {cell:?}");
    assert!((irregular.eval(5.5).0 - 5.0).abs() < 1e-15);
}

#[test]
fn uniform_cell_lookup_agrees_with_a_linear_scan() {
    // 1.1° pitch: not exactly representable, so node hits land on either side of a cell edge.
    let points: Vec<f64> = (0..=336).map(|i| -185.0 + i as f64 * 1.1).collect();
    let values: Vec<f64> = (0..points.len())
        .map(|i| ((i * 37) % 11) as f64 - 5.0)
        .collect();
    let table = Table1 {
        grid: Grid::new(points.clone()).unwrap(),
        values: values.clone(),
    };
    for k in 0..1900 {
        let x = -185.0 + k as f64 * 0.187 + if k % 7 == 0 { 0.0 } else { 1e-3 };
        let i = points
            .windows(2)
            .position(|w| w[0] <= x && x <= w[1])
            .unwrap();
        let by_scan =
            values[i] + (x - points[i]) / (points[i + 1] - points[i]) * (values[i + 1] - values[i]);
        let (v, cell) = table.eval(x);
        assert!((v - by_scan).abs() < 1e-9, "x = {x}: {v} vs {by_scan}");
        assert!(points[cell.lo] <= x + 1e-9 && x <= points[cell.hi] + 1e-9);
    }
}

#[test]
fn outside_the_grid_values_are_held_and_flagged() {
    let t = Table1 {
        grid: Grid::new(vec![0.0, 10.0]).unwrap(),
        values: vec![4.0, 6.0],
    };
    let (low, cell) = t.eval(-3.0);
    assert_eq!((low, cell.clamped), (4.0, true));
    let (high, cell) = t.eval(12.0);
    assert_eq!((high, cell.clamped), (6.0, true));
    assert!(!t.eval(10.0).1.clamped && !t.eval(0.0).1.clamped);
    let map = AngleMap(AxisTable { axis: 2, table: t });
    let mut axes = [0.0; 6];
    axes[1] = 11.0;
    assert!(map.clamped(&AxisState::new(axes)));
    axes[1] = 9.0;
    assert!(!map.clamped(&AxisState::new(axes)));
}

#[test]
fn bilinear_interpolation_by_hand() {
    let t = Table2 {
        rows: Grid::new(vec![0.0, 10.0]).unwrap(),
        columns: Grid::new(vec![0.0, 20.0, 40.0]).unwrap(),
        values: vec![0.0, 1.0, 2.0, 10.0, 11.0, 12.0],
    };
    // (2.5, 30): row weight 0.25, column cell [20, 40] at 0.5:
    // 0.75·(1 + 2)/2 + 0.25·(11 + 12)/2 = 1.125 + 2.875 = 4.
    let (v, corners, clamped) = t.eval(2.5, 30.0);
    assert!((v - 4.0).abs() < 1e-14 && !clamped);
    assert!((corners.iter().map(|c| c.1).sum::<f64>() - 1.0).abs() < 1e-15);
    assert!(t.eval(2.5, 45.0).2);
}

fn ctx_parts() -> (RobotDescription, Payload) {
    (RobotDescription::kr30ha(), Payload::default())
}

fn angle_slot(effect: &dyn Effect, state: &AxisState, axis: u8) -> f64 {
    let (robot, payload) = ctx_parts();
    let mut errors = ChainErrors::default();
    effect.add_to(
        state,
        &Context {
            robot: &robot,
            payload: &payload,
        },
        &mut errors,
    );
    errors.get(Slot::Angle { axis })
}

#[test]
fn play_branches_lag_by_half_the_width_and_unknown_is_their_mean() {
    let grid = Grid::new(vec![0.0, 10.0]).unwrap();
    let map = AngleMap(AxisTable {
        axis: 3,
        table: Table1 {
            grid: grid.clone(),
            values: vec![0.02, 0.04],
        },
    });
    let play = GearPlay(AxisTable {
        axis: 3,
        table: Table1 {
            grid,
            values: vec![0.01, 0.03],
        },
    });
    let total =
        |state: &AxisState| (angle_slot(&map, state, 3) + angle_slot(&play, state, 3)) / DEG;
    let at = |d: Direction| AxisState::with_directions([0.0, 0.0, 5.0, 0.0, 0.0, 0.0], [d; 6]);
    let plus = total(&at(Direction::Positive));
    let minus = total(&at(Direction::Negative));
    let unknown = total(&at(Direction::Unknown));
    // At 5°: map 0.03, width 0.02: the output lags by 0.01 after a motion either way.
    assert!(
        (plus - 0.02).abs() < 1e-15 && (minus - 0.04).abs() < 1e-15,
        "{plus} {minus}"
    );
    assert!((unknown - (plus + minus) / 2.0).abs() < 1e-15);
    // Up from 0° to 6°, then back to 5.995°: inside the play (width 0.022 at 6°), the output
    // stays where the upward motion left it, 6 − 0.011; the map is read at the command.
    let mut state = AxisState::new([0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    state = state.then([0.0, 0.0, 6.0, 0.0, 0.0, 0.0]);
    state = state.then([0.0, 0.0, 5.995, 0.0, 0.0, 0.0]);
    let output = 5.995 + angle_slot(&play, &state, 3) / DEG;
    assert!((output - (6.0 - 0.011)).abs() < 1e-13, "{output}");
}

#[test]
fn crosstalk_reads_its_own_axis_along_rows_and_the_other_along_columns() {
    let mut c = Crosstalk::zeros(3, 2, &Default::default(), &RobotDescription::kr30ha()).unwrap();
    assert_eq!(c.table.rows.points()[0], -135.0);
    assert_eq!(c.table.rows.points()[1] - c.table.rows.points()[0], 5.0);
    assert_eq!(
        c.table.columns.points()[1] - c.table.columns.points()[0],
        15.0
    );
    c.table = Table2 {
        rows: Grid::new(vec![-100.0, -50.0]).unwrap(),
        columns: Grid::new(vec![58.0, 105.0, 153.0]).unwrap(),
        values: vec![0.0, 0.1, 0.2, 0.0, 0.3, 0.6],
    };
    // A2 = −75 (half-way), A3 = 129 (half-way between 105 and 153): mean of 0.1, 0.2, 0.3, 0.6.
    let state = AxisState::new([0.0, -75.0, 129.0, 0.0, 0.0, 0.0]);
    assert!((angle_slot(&c, &state, 2) / DEG - 0.3).abs() < 1e-14);
    assert_eq!(angle_slot(&c, &state, 3), 0.0);
}

#[test]
fn crosstalk_outside_the_other_grid_is_held_and_counted_per_table() {
    let table = Table2 {
        rows: Grid::new(vec![-100.0, -50.0]).unwrap(),
        columns: Grid::new(vec![58.0, 105.0, 153.0]).unwrap(),
        values: vec![0.0, 0.1, 0.2, 0.0, 0.3, 0.6],
    };
    let mut c = Crosstalk::zeros(3, 2, &Default::default(), &RobotDescription::kr30ha()).unwrap();
    c.table = table;
    // A3 = 30 lies below the other grid: held at the A3 = 58 column, mean of 0.0 and 0.0 at
    // A2 = −75; A3 = 170 above it: the 153 column, mean of 0.2 and 0.6.
    let low = AxisState::new([0.0, -75.0, 30.0, 0.0, 0.0, 0.0]);
    let high = AxisState::new([0.0, -75.0, 170.0, 0.0, 0.0, 0.0]);
    let inside = AxisState::new([0.0, -75.0, 129.0, 0.0, 0.0, 0.0]);
    assert!(angle_slot(&c, &low, 2).abs() < 1e-15 && c.clamped(&low));
    assert!((angle_slot(&c, &high, 2) / DEG - 0.4).abs() < 1e-14 && c.clamped(&high));
    assert!(!c.clamped(&inside));
    // The model says which table held a point: A2 = −120 is outside the crosstalk rows only,
    // A2 = 40 (beyond the A2 limit of 35) outside the map too.
    let mut model = robopost::model::Model::new(
        RobotDescription::kr30ha(),
        Payload::default(),
        nalgebra::Vector3::zeros(),
    );
    model
        .push_named(&EffectName::parse("map:A2").unwrap(), &Default::default())
        .unwrap();
    model.push(Box::new(c));
    let states = [
        inside,
        AxisState::new([0.0, -120.0, 129.0, 0.0, 0.0, 0.0]),
        AxisState::new([0.0, 40.0, 129.0, 0.0, 0.0, 0.0]),
        low,
    ];
    let mut counts = [0; 2];
    for s in &states {
        for i in model.clamped_effects(s) {
            counts[i] += 1;
        }
    }
    assert_eq!(counts, [1, 3]);
    assert_eq!(
        states.iter().filter(|s| model.clamped(s)).count(),
        3,
        "points held at some table edge"
    );
}

/// KR 30 HA geometry with one 10 kg point mass on link 3, 500 mm along its x (forward at HOME).
fn one_mass_robot() -> RobotDescription {
    let mut robot = RobotDescription::kr30ha();
    let mut link_mass_kg = [0.0; 6];
    link_mass_kg[2] = 10.0;
    let mut link_cog_mm = [[0.0; 3]; 6];
    link_cog_mm[2] = [500.0, 0.0, 0.0];
    robot.gravity = Some(Gravity {
        link_mass_kg,
        link_cog_mm,
    });
    robot
}

#[test]
fn gravity_torque_of_a_point_mass_by_hand() {
    let robot = one_mass_robot();
    let home = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];
    let t = gravity_torques_knm(&robot, &Payload::default(), &home).unwrap();
    // The mass hangs 500 mm in front of the A2 and A3 centres; gravity pulls the arm down,
    // i.e. towards positive A2/A3: τ = 10 kg · g · 0.5 m.
    let expected = 10.0 * STANDARD_GRAVITY * 0.5 / 1000.0;
    assert!(
        (t[1] - expected).abs() < 1e-15 && (t[2] - expected).abs() < 1e-15,
        "{t:?}"
    );
    assert_eq!([t[0], t[3], t[4], t[5]], [0.0; 4]);
    // A2 = 0, A3 = 90: upper arm horizontal forward, forearm hanging down, so the mass is
    // 500 mm below the A3 centre (no lever about A3) and 850 mm in front of A2.
    let t = gravity_torques_knm(
        &robot,
        &Payload::default(),
        &[0.0, 0.0, 90.0, 0.0, 0.0, 0.0],
    )
    .unwrap();
    assert!(
        (t[1] - 10.0 * STANDARD_GRAVITY * 0.85 / 1000.0).abs() < 1e-15,
        "{t:?}"
    );
    assert!(t[2].abs() < 1e-15);
    // A 5 kg payload 100 mm along flange Z (+X at HOME) adds a 270 mm lever about A5.
    let payload = Payload {
        mass_kg: 5.0,
        cog_mm: [0.0, 0.0, 100.0],
    };
    let t = gravity_torques_knm(&robot, &payload, &home).unwrap();
    assert!(
        (t[4] - 5.0 * STANDARD_GRAVITY * 0.27 / 1000.0).abs() < 1e-15,
        "{t:?}"
    );
    assert!((t[1] - (10.0 * 0.5 + 5.0 * 1.09) * STANDARD_GRAVITY / 1000.0).abs() < 1e-15);
}

#[test]
fn compliance_deflects_by_c_times_torque_and_needs_mass_data() {
    let robot = one_mass_robot();
    let mut c = Compliance::zeros(2, &robot).unwrap();
    c.compliance = [2.0];
    let payload = Payload::default();
    let mut errors = ChainErrors::default();
    let state = AxisState::new([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]);
    c.add_to(
        &state,
        &Context {
            robot: &robot,
            payload: &payload,
        },
        &mut errors,
    );
    // 2 deg/kNm · 0.04903325 kNm.
    assert!((errors.get(Slot::Angle { axis: 2 }) / DEG - 0.0980665).abs() < 1e-14);
    let mut bare = RobotDescription::kr30ha();
    bare.gravity = None;
    let refused = Compliance::zeros(2, &bare).unwrap_err();
    assert_eq!(
        refused,
        EffectError::NeedsGravity {
            effect: "compliance:A2".into()
        }
    );
    assert_eq!(
        refused.to_string(),
        "compliance:A2 needs the link masses (robot.gravity) to compute gravity torques"
    );
}

/// A zero effect that cannot be built says which axis and which grid, as values a caller can
/// match on: a play table at a pitch finer than the finest grid, a crosstalk whose explicit
/// grid of the influencing axis goes backwards, a learned driver without its axis.
#[test]
fn constructors_refuse_with_typed_errors_naming_the_axis() {
    let robot = RobotDescription::kr30ha();
    let fine = GridOptions {
        pitch_deg: Some(1e-4),
        ..GridOptions::default()
    };
    let play = EffectName::parse("backlash:A3").unwrap();
    let Err(refused) = play.create(&fine, &robot) else {
        panic!("a pitch of 1e-4° is refused")
    };
    let [lo, hi] = robot.limits_deg[2];
    match &refused {
        EffectError::Grid {
            axis: 3,
            lo_deg,
            hi_deg,
            pitch_deg,
            source: GridError::TooFine { .. },
        } => assert_eq!((*lo_deg, *hi_deg, *pitch_deg), (lo, hi, 1e-4)),
        other => panic!("{other:?}"),
    }
    assert!(
        refused.to_string().starts_with(&format!(
            "grid {lo}..{hi} step 0.0001: a grid from {lo}° to {hi}°"
        )),
        "{refused}"
    );

    let backwards = GridOptions {
        other_grid_deg: Some(vec![60.0, 10.0]),
        ..GridOptions::default()
    };
    let refused = Crosstalk::zeros(3, 2, &backwards, &robot).unwrap_err();
    assert_eq!(
        refused,
        EffectError::PairGrid {
            axis: 3,
            source: GridError::NotIncreasing {
                index: 1,
                previous: 60.0,
                found: 10.0
            }
        }
    );
    assert_eq!(
        refused.to_string(),
        "grid of A3: grid point 1 is 10, not greater than the previous point 60"
    );

    let refused = Learned::zeros("angle@A2(torque:A9)", &robot).unwrap_err();
    assert_eq!(
        refused,
        EffectError::Spec(SpecError::DriverAxis {
            driver: "torque:A9".into(),
            prefix: "torque:".into()
        })
    );
    assert_eq!(
        refused.to_string(),
        "`torque:A9`: expected torque:An with n in 1..6"
    );
}

#[test]
fn tilt_harmonics_and_drift_rates_by_hand() {
    // A2 turns about y: its perpendicular axes are x and z; parameter 1 is x.sin1, 6 is z.cos2.
    let mut t = Tilt::zeros(2);
    t.values[1] = 0.01;
    t.values[6] = 0.02;
    let (robot, payload) = ctx_parts();
    let ctx = Context {
        robot: &robot,
        payload: &payload,
    };
    let mut errors = ChainErrors::default();
    t.add_to(
        &AxisState::new([0.0, 30.0, 0.0, 0.0, 0.0, 0.0]),
        &ctx,
        &mut errors,
    );
    assert!((errors.get(Slot::Tilt { axis: 2, coord: 0 }) / DEG - 0.01 * 0.5).abs() < 1e-15);
    assert!((errors.get(Slot::Tilt { axis: 2, coord: 2 }) / DEG - 0.02 * 0.5).abs() < 1e-15);
    assert_eq!(errors.get(Slot::Tilt { axis: 2, coord: 1 }), 0.0);

    let mut d = Drift::default();
    d.rates_mm_per_h[0] = 0.012; // l1z
    let mut state = AxisState::new([0.0; 6]);
    state.time_s = 5400.0;
    let mut errors = ChainErrors::default();
    d.add_to(&state, &ctx, &mut errors);
    assert!((errors.get(Slot::Offset { axis: 2, coord: 2 }) - 0.018).abs() < 1e-15);
}

#[test]
fn effect_names_parse_case_insensitively_and_expand_ranges() {
    let names: Vec<String> = expand_list("geometric,MAP:a1..A6,backlash:A1..A6,crosstalk:A3->A2")
        .unwrap()
        .iter()
        .map(|n| n.to_string())
        .collect();
    assert_eq!(names.len(), 14);
    assert_eq!(names[1], "map:A1");
    assert_eq!(names[6], "map:A6");
    assert_eq!(names[13], "crosstalk:A3->A2");
    assert!(EffectName::parse("map:A7").is_err());
    assert!(EffectName::parse("crosstalk:A2->A2").is_err());
    assert!(EffectName::parse("mapp:A2").is_err());
    assert!(EffectName::parse("geometric:A1").is_err());
}

mod grid_lookup {
    use super::Grid;
    use proptest::prelude::*;

    /// Grids of every kind the cell guess meets: uniform, uniform with a cut last cell (a
    /// joint limit off the pitch), the union of two pitches, irregular.
    fn grid() -> impl Strategy<Value = Vec<f64>> {
        let uniform = (-200.0..0.0f64, 0.5..10.0f64, 2usize..80)
            .prop_map(|(lo, pitch, n)| (0..n).map(|i| lo + i as f64 * pitch).collect());
        let cut = (-200.0..0.0f64, 1.0..10.0f64, 3usize..80, 0.05..0.95f64).prop_map(
            |(lo, pitch, n, f)| {
                let mut p: Vec<f64> = (0..n).map(|i| lo + i as f64 * pitch).collect();
                let last = p[n - 2] + f * pitch;
                p[n - 1] = last;
                p
            },
        );
        let irregular = prop::collection::vec(0.01..20.0f64, 1..40).prop_map(|steps| {
            let mut x = -50.0;
            let mut p = vec![x];
            for s in steps {
                x += s;
                p.push(x);
            }
            p
        });
        prop_oneof![uniform, cut, irregular]
    }

    proptest! {
        /// The cell holds x (`p[lo] ≤ x < p[lo+1]` inside the grid) and its weight
        /// interpolates x, as a linear scan finds it.
        #[test]
        fn cell_is_found(points in grid(), f in -0.1..1.1f64) {
            let (first, last) = (points[0], points[points.len() - 1]);
            let x = first + f * (last - first);
            let grid = Grid::new(points.clone()).unwrap();
            let cell = grid.locate(x);
            if x > first && x < last {
                let scan = points.iter().rposition(|&p| p <= x).unwrap();
                prop_assert_eq!(cell.lo, scan);
                prop_assert_eq!(cell.hi, scan + 1);
                let back = points[cell.lo] + cell.w * (points[cell.hi] - points[cell.lo]);
                prop_assert!((back - x).abs() <= 1e-12 * (1.0 + x.abs()));
            }
            prop_assert_eq!(cell.clamped, x < first || x > last);
        }

        /// Starting from any hint (right, wrong, past the end), the lookup near a cell is the
        /// plain lookup, bit for bit, and leaves the hint on the cell found.
        #[test]
        fn cell_near_a_hint_is_the_cell(
            points in grid(),
            f in -0.1..1.1f64,
            on_point in any::<bool>(),
            hint in 0usize..45,
        ) {
            let (first, last) = (points[0], points[points.len() - 1]);
            let mut x = first + f * (last - first);
            if on_point {
                x = points[hint % points.len()]; // grid points and the edges themselves
            }
            let grid = Grid::new(points.clone()).unwrap();
            let mut near = hint;
            let got = grid.locate_near(x, &mut near);
            let want = grid.locate(x);
            prop_assert_eq!(got.lo, want.lo);
            prop_assert_eq!(got.hi, want.hi);
            prop_assert_eq!(got.w.to_bits(), want.w.to_bits());
            prop_assert_eq!(got.clamped, want.clamped);
            prop_assert_eq!(near, want.lo);
        }
    }
}

/// The solver's merged map + backlash table of an axis equals the two looked up separately,
/// also when their grids differ in pitch and range (each held at its own edges) and for every
/// direction.
#[test]
fn merged_map_and_backlash_on_different_grids() {
    let robot = RobotDescription::kr30ha();
    let mut model = robopost::model::Model::new(robot, Payload::default(), Default::default());
    let map = Table1 {
        grid: Grid::new(vec![-10.0, 0.0, 10.0, 20.0]).unwrap(),
        values: vec![0.01, 0.03, -0.01, 0.0],
    };
    let backlash = Table1 {
        grid: Grid::new(vec![-5.0, 2.5, 15.0]).unwrap(),
        values: vec![0.004, 0.002, 0.006],
    };
    model.push(Box::new(AngleMap(AxisTable {
        axis: 2,
        table: map.clone(),
    })));
    model.push(Box::new(GearPlay(AxisTable {
        axis: 2,
        table: backlash.clone(),
    })));
    for k in 0..=400 {
        let a2 = -15.0 + k as f64 * 0.1;
        for dir in [Direction::Negative, Direction::Unknown, Direction::Positive] {
            let state = AxisState::with_directions([0.0, a2, 90.0, 0.0, 30.0, 0.0], [dir; 6]);
            let mut errors = model.fixed_errors(&state);
            model.add_varying_errors(&state, &mut errors);
            // By hand: map(A2) − dir·width(A2)/2, degrees → radians.
            let expected = (map.eval(a2).0 - 0.5 * dir.sign() * backlash.eval(a2).0) * DEG;
            let got = errors.get(Slot::Angle { axis: 2 });
            assert!(
                (got - expected).abs() < 1e-17,
                "A2 {a2} {dir:?}: {got} vs {expected}"
            );
        }
        // Arriving upward at A2 + 0.003, then back down to A2: the play's output stays where
        // the upward motion left it (A2 + 0.003 − w(A2 + 0.003)/2) unless the band at A2
        // drags it.
        let mut h = AxisHistory::engaged(Direction::Positive);
        h.push(a2 + 0.003);
        let mut state = AxisState::new([0.0, a2, 90.0, 0.0, 30.0, 0.0]);
        state.history[1] = h;
        let mut errors = model.fixed_errors(&state);
        model.add_varying_errors(&state, &mut errors);
        let w = |x: f64| backlash.eval(x).0;
        let lag = (0.003 - 0.5 * w(a2 + 0.003)).clamp(-0.5 * w(a2), 0.5 * w(a2));
        let expected = (map.eval(a2).0 + lag) * DEG;
        let got = errors.get(Slot::Angle { axis: 2 });
        assert!(
            (got - expected).abs() < 1e-15,
            "A2 {a2} reversed: {got} vs {expected}"
        );
    }
}
