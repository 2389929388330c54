//! Analytic Jacobians against central finite differences: every effect's sparse Jacobian
//! against `add_to`, and the Model's target and flange Jacobians against `target_position`
//! and `flange_pose`, with random parameter values at random states (both directions and
//! unknown).

use nalgebra::Vector3;
use robopost::kinematics::{Payload, RobotDescription};
use robopost::model::effects::loadplay::LoadPlay;
use robopost::model::{
    expand_list, AxisHistory, AxisState, ChainErrors, Direction, GridOptions, Model, N_SLOTS,
};

/// A small deterministic generator (the tests must not depend on a seed-less RNG).
struct Lcg(u64);
impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

fn random_state(rng: &mut Lcg, robot: &RobotDescription) -> AxisState {
    let mut state = AxisState::new(std::array::from_fn(|n| {
        let [lo, hi] = robot.limits_deg[n];
        rng.range(lo, hi)
    }));
    // Every kind of history: engaged on a flank, unmoved, or reversed lately by less than a
    // play (its memory holds turning points a few hundredths of a degree away).
    for n in 0..6 {
        let c = state.axes_deg[n];
        state.history[n] = match (rng.unit() * 4.0) as usize % 4 {
            0 => AxisHistory::engaged(Direction::Negative),
            1 => AxisHistory::unmoved(),
            2 => AxisHistory::engaged(Direction::Positive),
            _ => {
                let mut h = AxisHistory::engaged(Direction::Positive);
                h.push(c + rng.range(-0.03, 0.03));
                h.push(c + rng.range(-0.03, 0.03));
                h
            }
        };
    }
    state.time_s = rng.range(0.0, 7200.0);
    state
}

/// Every kind of effect, with coarse grids so the test stays fast.
fn full_model(rng: &mut Lcg) -> Model {
    let robot = RobotDescription::kr30ha();
    let payload = Payload {
        mass_kg: 12.0,
        cog_mm: [10.0, -5.0, 80.0],
    };
    let mut model = Model::new(robot, payload, Vector3::new(20.0, 30.0, 150.0));
    let list = "geometric,map:A1..A6,backlash:A1..A6,crosstalk:A3->A2,crosstalk:A2->A3,compliance:A2..A3,tilt:A1..A6,drift";
    let options = GridOptions {
        pitch_deg: Some(10.0),
        ..GridOptions::default()
    };
    for name in expand_list(list).expect("valid list") {
        model.push_named(&name, &options).expect("constructible");
    }
    // The play under load on A2 (counterbalanced) and A3, with friction bands that the random
    // states fall in and out of.
    for (axis, friction_knm, balance_knm) in [(2, 0.6, [0.2, 1.2, -0.4]), (3, 0.15, [0.0; 3])] {
        model.push(Box::new(LoadPlay {
            axis,
            width_deg: [0.0],
            friction_knm,
            balance_knm,
            loaded_pairs: None,
        }));
    }
    let mut values: Vec<f64> = (0..model.n_parameters())
        .map(|_| rng.range(-0.05, 0.05))
        .collect();
    // Gear plays have widths, not signs.
    for (e, effect) in model.effects().iter().enumerate() {
        if effect.name().starts_with("backlash") || effect.name().starts_with("loadplay") {
            let start = model.effect_start(e);
            for v in &mut values[start..start + effect.values().len()] {
                *v = v.abs() + 0.001;
            }
        }
    }
    model.set_values(&values);
    model
}

#[test]
fn every_effect_jacobian_matches_finite_differences_of_add_to() {
    let mut rng = Lcg(7);
    let mut model = full_model(&mut rng);
    let robot = model.robot;
    let h = 1e-4;
    for _ in 0..20 {
        let state = random_state(&mut rng, &robot);
        for e in 0..model.effects().len() {
            let start = model.effect_start(e);
            let ctx_model = model.clone();
            let ctx = ctx_model.context();
            let mut partials = Vec::new();
            model.effects()[e].jacobian(&state, &ctx, &mut partials);
            let mut analytic = vec![[0.0; N_SLOTS]; model.effects()[e].values().len()];
            for p in &partials {
                analytic[p.param][p.slot.index()] += p.value;
            }
            for (k, analytic_k) in analytic.iter().enumerate() {
                let base = model.values();
                let errors_at = |model: &mut Model, delta: f64| {
                    let mut v = base.clone();
                    v[start + k] += delta;
                    model.set_values(&v);
                    let mut errors = ChainErrors::default();
                    model.effects()[e].add_to(&state, &ctx, &mut errors);
                    errors
                };
                let plus = errors_at(&mut model, h);
                let minus = errors_at(&mut model, -h);
                model.set_values(&base);
                for (s, &analytic_ks) in analytic_k.iter().enumerate() {
                    let numeric = (plus.0[s] - minus.0[s]) / (2.0 * h);
                    assert!(
                        (numeric - analytic_ks).abs() < 1e-9 * (1.0 + numeric.abs()),
                        "{} param {k} slot {s}: {numeric} vs {}",
                        model.effects()[e].name(),
                        analytic_ks
                    );
                }
            }
        }
    }
}

#[test]
fn model_target_jacobian_matches_finite_differences() {
    let mut rng = Lcg(11);
    let mut model = full_model(&mut rng);
    let robot = model.robot;
    let base = model.values();
    let h = 1e-5;
    let mut checked_nonzero = 0;
    for _ in 0..8 {
        let state = random_state(&mut rng, &robot);
        let (p, sparse) = model.target_jacobian(&state);
        assert!((p - model.target_position(&state)).norm() < 1e-12);
        let mut dense = vec![Vector3::zeros(); model.n_parameters()];
        for (i, d) in sparse {
            dense[i] += d;
        }
        for (i, analytic) in dense.iter().enumerate() {
            let mut v = base.clone();
            v[i] = base[i] + h;
            model.set_values(&v);
            let plus = model.target_position(&state);
            v[i] = base[i] - h;
            model.set_values(&v);
            let minus = model.target_position(&state);
            model.set_values(&base);
            let numeric = (plus - minus) / (2.0 * h);
            // Second-order FD error: h² times the chain's curvature (≤ 1e-6 mm here).
            assert!(
                (numeric - analytic).norm() < 1e-6 * (1.0 + numeric.norm()),
                "param {i}: {numeric} vs {analytic}"
            );
            if numeric.norm() > 1e-6 {
                checked_nonzero += 1;
            }
        }
    }
    assert!(
        checked_nonzero > 100,
        "the comparison exercised few parameters: {checked_nonzero}"
    );
}

#[test]
fn model_flange_jacobian_matches_finite_differences() {
    let mut rng = Lcg(13);
    let mut model = full_model(&mut rng);
    let robot = model.robot;
    let base = model.values();
    let h = 1e-5;
    for _ in 0..5 {
        let state = random_state(&mut rng, &robot);
        let (pose, sparse) = model.flange_jacobian(&state);
        assert!((pose.position - model.flange_pose(&state).position).norm() < 1e-12);
        let mut dense = vec![nalgebra::Vector6::zeros(); model.n_parameters()];
        for (i, d) in sparse {
            dense[i] += d;
        }
        for (i, analytic) in dense.iter().enumerate() {
            let mut v = base.clone();
            v[i] = base[i] + h;
            model.set_values(&v);
            let plus = model.flange_pose(&state);
            v[i] = base[i] - h;
            model.set_values(&v);
            let minus = model.flange_pose(&state);
            model.set_values(&base);
            let dp = (plus.position - minus.position) / (2.0 * h);
            // R+ = exp(ω·2h)·R−, so the rotation vector of R+·R−ᵀ over 2h is ω.
            // (By the quaternions: a rotation matrix's angle by the trace loses half the digits
            // of these 1e-8 rad.)
            let (plus, minus) = (plus.to_isometry(), minus.to_isometry());
            let dw: Vector3<f64> =
                (plus.rotation * minus.rotation.inverse()).scaled_axis() / (2.0 * h);
            let dp_a = analytic.fixed_rows::<3>(0).into_owned();
            let dw_a = analytic.fixed_rows::<3>(3).into_owned();
            assert!(
                (dp - dp_a).norm() < 1e-6 * (1.0 + dp.norm()),
                "param {i}: {dp} vs {dp_a}"
            );
            assert!(
                (dw - dw_a).norm() < 1e-9 * (1.0 + dw.norm()),
                "param {i}: {dw} vs {dw_a}"
            );
        }
    }
}

/// Summing the axis-independent effects once and the others per command is the same sum
/// (to rounding: the order differs when an axis-dependent effect comes between fixed ones),
/// and the effects declared axis-independent really are.
#[test]
fn fixed_plus_varying_errors_are_the_chain_errors() {
    let mut rng = Lcg(11);
    let model = full_model(&mut rng);
    for k in 0..50 {
        let mut state = random_state(&mut rng, &model.robot);
        if k % 2 == 0 {
            state.time_s = 0.0; // the model's cached sum
        }
        let mut split = model.fixed_errors(&state);
        model.add_varying_errors(&state, &mut split);
        let whole = model.chain_errors(&state);
        for i in 0..N_SLOTS {
            assert!((split.0[i] - whole.0[i]).abs() < 1e-15, "slot {i}");
        }
        let mut elsewhere = random_state(&mut rng, &model.robot);
        elsewhere.history = state.history;
        elsewhere.time_s = state.time_s;
        assert_eq!(model.fixed_errors(&state), model.fixed_errors(&elsewhere));
        // The fixed part is not empty here: the geometry.
        assert!(model.fixed_errors(&state).0.iter().any(|&e| e != 0.0));
    }
    // The split really merged the six map and six backlash tables.
    let varying: Vec<usize> = (0..model.effects().len())
        .filter(|&i| model.effects()[i].varies_with_axes())
        .collect();
    let merged = robopost::model::merged::Merged::new(model.effects(), &varying);
    assert_eq!(merged.rest.len(), varying.len() - 12);
}

/// `loadplay`'s slopes along the axes (what a compensation solve steps with) against central
/// differences of `add_to`, at states away from the edge of the friction band (where the flank
/// jumps and no derivative exists); and both branches are exercised.
#[test]
fn loadplay_axis_slopes_match_finite_differences() {
    use robopost::model::{AxisSlopes, Effect, Slot};
    let mut rng = Lcg(17);
    let robot = RobotDescription::kr30ha();
    let payload = Payload {
        mass_kg: 12.0,
        cog_mm: [10.0, -5.0, 80.0],
    };
    let model = Model::new(robot, payload, Vector3::zeros());
    let ctx = model.context();
    let effect = LoadPlay {
        axis: 2,
        width_deg: [0.03],
        friction_knm: 0.6,
        balance_knm: [0.2, 1.2, -0.4],
        loaded_pairs: None,
    };
    let h = 1e-6;
    let (mut loaded, mut free) = (0, 0);
    for _ in 0..400 {
        let state = random_state(&mut rng, &robot);
        let torque = |s: &AxisState| effect.net_torque_knm(&s.axes_deg, &ctx).unwrap();
        let t = torque(&state);
        if (t.abs() - effect.friction_knm).abs() < 0.05 {
            continue;
        }
        if t.abs() > effect.friction_knm {
            loaded += 1;
        } else {
            free += 1;
        }
        let mut errors = ChainErrors::default();
        let mut slopes = AxisSlopes::default();
        effect.add_with_axis_slopes(&state, &ctx, &mut errors, &mut slopes);
        let slot = Slot::Angle { axis: 2 };
        let mut plain = ChainErrors::default();
        effect.add_to(&state, &ctx, &mut plain);
        assert_eq!(plain.get(slot), errors.get(slot));
        for n in 0..6 {
            let at = |d: f64| {
                let mut s = state;
                s.axes_deg[n] += d;
                let mut e = ChainErrors::default();
                effect.add_to(&s, &ctx, &mut e);
                e.get(slot)
            };
            let numeric = (at(h) - at(-h)) / (2.0 * h);
            assert!(
                (numeric - slopes.angle[1][n]).abs() < 1e-9,
                "A{}: {numeric} vs {}",
                n + 1,
                slopes.angle[1][n]
            );
        }
    }
    assert!(loaded > 20 && free > 20, "loaded {loaded}, free {free}");
}

/// The physics by hand: where the net torque beats friction, both directions sit on the
/// torque's flank (+b/2 for a positive torque); inside the band, the direction decides as a
/// play does (−b/2 arriving from below, +b/2 from above).
#[test]
fn loadplay_flank_follows_the_torque_beyond_friction() {
    use robopost::model::{Effect, Slot};
    let robot = RobotDescription::kr30ha();
    let model = Model::new(robot, Payload::default(), Vector3::zeros());
    let ctx = model.context();
    let mut effect = LoadPlay {
        axis: 2,
        width_deg: [0.04],
        friction_knm: 0.0,
        balance_knm: [0.0; 3],
        loaded_pairs: None,
    };
    let lag = |e: &LoadPlay, axes: [f64; 6], d: Direction| {
        let mut errors = ChainErrors::default();
        e.add_to(&AxisState::with_directions(axes, [d; 6]), &ctx, &mut errors);
        errors.get(Slot::Angle { axis: 2 }).to_degrees()
    };
    // Upper arm forward and down a little, forearm horizontal: gravity pulls A2 towards
    // positive angles (A2 turns about +Y; the arm's weight ahead of the axis turns it down).
    let axes = [0.0, -20.0, 20.0, 0.0, 0.0, 0.0];
    let t = effect.net_torque_knm(&axes, &ctx).unwrap();
    assert!(t > 0.5, "gravity torque about A2 at {axes:?}: {t}");
    for d in [Direction::Positive, Direction::Negative] {
        assert!((lag(&effect, axes, d) - 0.02).abs() < 1e-12);
    }
    // A counterbalance larger than gravity there turns the flank over.
    effect.balance_knm = [2.0 * t, 0.0, 0.0];
    for d in [Direction::Positive, Direction::Negative] {
        assert!((lag(&effect, axes, d) + 0.02).abs() < 1e-12);
    }
    // Friction beyond the torque: the motion chooses.
    effect.friction_knm = 10.0;
    assert!((lag(&effect, axes, Direction::Positive) + 0.02).abs() < 1e-12);
    assert!((lag(&effect, axes, Direction::Negative) - 0.02).abs() < 1e-12);
}
