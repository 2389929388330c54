//! A new physical effect is one file plus one registry entry: this file defines an effect the
//! crate has never heard of — the radial error motion (run-out) of axis 1's bearing — and
//! registers it at run time ([`registry::register`]). Nothing else changes, and:
//!
//! - identification (`identify::pipeline::identify` with it in the effect list) recovers its
//!   eccentricity from virtual-robot data whose run-out is added by an independent formula;
//! - compensation (`compensate::compensate_program`) moves a program's targets by the
//!   displacement the formula gives, with the orientation untouched;
//! - diagnosis tries it among its candidates and names it when the calibration lacks it.
//!
//! The physics: the rotating ring of the A1 bearing is eccentric by `e = (ex, ey)` (mm), so
//! the axis line moves on a small circle as the axis turns: everything beyond A1 is displaced
//! by `Rz(θ1)·e` in the base frame, θ1 = sense1·A1 the physical rotation about the base Z.

#[path = "support/calibrate.rs"]
mod calibrate;

use nalgebra::Vector3;
use robopost::calibration::{Calibration, MeasurementFrame, Provenance};
use robopost::compensate::{files, program, Method};
use robopost::diagnose::{diagnose, DiagnoseOptions};
use robopost::identify::pipeline::PAPER_EFFECTS;
use robopost::kinematics::{Payload, RobotDescription};
use robopost::measure::{Measurements, Stop};
use robopost::model::effects::ToRecord;
use robopost::model::record::{self, EffectRecord, RecordError};
use robopost::model::registry::{self, Arity, Kind};
use robopost::model::{AxisState, ChainErrors, Context, Effect, EffectName, Parameter, Partial};
use robopost::model::{Model, Slot};
use robopost::motion;
use robopost::simulate::campaign::Campaign;
use robopost::simulate::paper;
use robopost::simulate::virtual_robot::VirtualRobot;

// ---- The effect: everything the crate learns about it is in this section. ----

/// `base_runout` — radial error motion of A1: `(ex, ey)` in mm, turning with the axis.
#[derive(Clone, Debug, Default, PartialEq)]
struct BaseRunout {
    values: [f64; 2],
}

const NAMES: [&str; 2] = ["ex", "ey"];

fn names() -> Vec<String> {
    NAMES.iter().map(|n| n.to_string()).collect()
}

impl BaseRunout {
    /// (cos θ1, sin θ1) of the physical rotation.
    fn turn(state: &AxisState, ctx: &Context) -> (f64, f64) {
        let theta = (ctx.robot.senses[0] * state.axes_deg[0]).to_radians();
        (theta.cos(), theta.sin())
    }
}

impl Effect for BaseRunout {
    fn name(&self) -> String {
        "base_runout".into()
    }
    fn parameters(&self) -> Vec<Parameter> {
        names()
            .into_iter()
            .map(|name| Parameter { name, unit: "mm" })
            .collect()
    }
    fn values(&self) -> &[f64] {
        &self.values
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.values
    }
    fn add_to(&self, state: &AxisState, ctx: &Context, errors: &mut ChainErrors) {
        let (c, s) = Self::turn(state, ctx);
        let [ex, ey] = self.values;
        errors.add(Slot::Offset { axis: 1, coord: 0 }, ex * c - ey * s);
        errors.add(Slot::Offset { axis: 1, coord: 1 }, ex * s + ey * c);
    }
    fn jacobian(&self, state: &AxisState, ctx: &Context, out: &mut Vec<Partial>) {
        let (c, s) = Self::turn(state, ctx);
        let (x, y) = (
            Slot::Offset { axis: 1, coord: 0 },
            Slot::Offset { axis: 1, coord: 1 },
        );
        for (param, slot, value) in [(0, x, c), (0, y, s), (1, x, -s), (1, y, c)] {
            out.push(Partial { param, slot, value });
        }
    }
    fn clone_box(&self) -> Box<dyn Effect> {
        Box::new(self.clone())
    }
}

impl ToRecord for BaseRunout {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&names(), &self.values)),
            table: None,
        }
    }
}

/// The one registry entry.
static BASE_RUNOUT: Kind = Kind {
    prefix: "base_runout",
    arity: Arity::Robot,
    meaning: "radial error motion of A1's bearing: the axis line turns on a small circle",
    create: |_, _, _| Ok(Box::new(BaseRunout::default())),
    decode: |_, rec, _| {
        let v = rec.named_values(&names())?;
        Ok(Box::new(BaseRunout {
            values: [v[0], v[1]],
        }))
    },
    upgrade_v1: None,
    look_alikes: |_| Vec::new(),
    in_time: false,
};

fn register() {
    registry::register(&BASE_RUNOUT).unwrap();
}

// ---- The test's own physics and data. ----

/// The eccentricity of the virtual robot's A1 bearing, mm.
const E_MM: [f64; 2] = [0.060, -0.040];

/// The displacement of everything beyond A1 at command angle `a1_deg`, by hand.
fn runout_mm(robot: &RobotDescription, a1_deg: f64, e: [f64; 2]) -> Vector3<f64> {
    let theta = (robot.senses[0] * a1_deg).to_radians();
    let (c, s) = (theta.cos(), theta.sin());
    Vector3::new(e[0] * c - e[1] * s, e[0] * s + e[1] * c, 0.0)
}

/// The paper's campaign at 2° pitch plus 200 random poses, measured on the virtual KR 30 HA of
/// the fixtures (the paper's effects, tracker noise), with the run-out added to every
/// measured position by [`runout_mm`].
fn measured() -> (Model, Vec<Stop>) {
    let mut truth = paper::truth_model(false);
    truth.payload = Payload {
        mass_kg: 30.0,
        cog_mm: [0.0, 0.0, 100.0],
    };
    let mut campaign = Campaign::paper();
    for t in &mut campaign.tests {
        t.pitch_deg = 2.0;
    }
    let mut plan = campaign.plan().unwrap();
    let end = plan.last().unwrap().time_s;
    plan.extend(robopost::simulate::poses::random_poses(
        7,
        200,
        end + 60.0,
        "poses",
    ));
    let mut data = VirtualRobot::new(truth.clone())
        .with_seed(1)
        .measure(&plan)
        .unwrap();
    for s in &mut data {
        if let Some(m) = &mut s.measured_mm {
            *m += runout_mm(&truth.robot, s.state.axes_deg[0], E_MM);
        }
    }
    (truth, data)
}

fn values_of(cal: &Calibration, name: &str) -> Vec<f64> {
    let model = cal.model();
    let e = model.effects().iter().find(|e| e.name() == name).unwrap();
    e.values().to_vec()
}

#[test]
fn the_registry_takes_a_new_kind_once_and_refuses_a_taken_prefix() {
    register();
    register(); // the same kind again: a no-op
    let name = EffectName::parse("BASE_RUNOUT").unwrap();
    assert_eq!(name.to_string(), "base_runout");
    assert_eq!(
        registry::kinds()
            .iter()
            .filter(|k| k.prefix == "base_runout")
            .count(),
        1
    );
    static IMPOSTOR: Kind = Kind {
        prefix: "map",
        arity: Arity::Axis,
        meaning: "",
        create: |_, _, _| Err("no".into()),
        decode: |_, _, _| Err(RecordError::new("", "", "")),
        upgrade_v1: None,
        look_alikes: |_| Vec::new(),
        in_time: false,
    };
    assert!(registry::register(&IMPOSTOR).is_err());
    // The calibration file carries it.
    let mut model = Model::new(
        RobotDescription::kr30ha(),
        Payload::default(),
        Vector3::zeros(),
    );
    model.push(Box::new(BaseRunout { values: E_MM }));
    let cal = Calibration::from_model(
        "KR 30 HA",
        model,
        MeasurementFrame::Base,
        Provenance::default(),
    );
    let path = std::path::Path::new("runout.json");
    let back = robopost::calibration::parse(&cal.to_json(path).unwrap(), path).unwrap();
    assert_eq!(values_of(&back, "base_runout"), E_MM);
}

#[test]
fn identification_recovers_the_eccentricity_and_diagnosis_names_the_run_out() {
    register();
    let (truth, data) = measured();

    // Identified with the paper's effects and the run-out: the eccentricity comes back.
    let with = calibrate::calibrate(&truth, &format!("{PAPER_EFFECTS},base_runout"), &data, 2.0);
    let e = values_of(&with, "base_runout");
    eprintln!("identified e = {e:?} mm, truth {E_MM:?}");
    for (got, want) in e.iter().zip(E_MM) {
        assert!((got - want).abs() < 0.005, "{e:?} against {E_MM:?}");
    }

    // Without it, diagnosis tries it and names it.
    let without = calibrate::calibrate(&truth, PAPER_EFFECTS, &data, 2.0);
    let m = Measurements {
        source: "data".into(),
        stops: data.clone(),
        ignored_columns: vec![],
    };
    let d = diagnose(&without, &[m], &DiagnoseOptions::default()).unwrap();
    assert!(
        d.considered.iter().any(|f| f.effect == "base_runout"),
        "{:#?}",
        d.considered
    );
    let named: Vec<&str> = d.candidates.iter().map(|f| f.effect.as_str()).collect();
    eprintln!("candidates {named:?}; verdict: {}", d.verdict);
    assert_eq!(named.first(), Some(&"base_runout"), "{:#?}", d.candidates);
}

const PROGRAM: &str = "DEF runout( )
$BASE={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}
$TOOL={X 0.0,Y 0.0,Z 200.0,A 0.0,B 0.0,C 0.0}
PTP {A1 20.0,A2 -80.0,A3 100.0,A4 0.0,A5 70.0,A6 0.0}
LIN {X 1300.0,Y 450.0,Z 1200.0,A 0.0,B 0.0,C 180.0}
LIN {X 1200.0,Y -300.0,Z 1100.0,A 30.0,B 10.0,C 170.0}
LIN {X 900.0,Y 800.0,Z 900.0,A 60.0,B 0.0,C 180.0}
END
";

/// The six numbers of a LIN target line.
fn lin_values(line: &str) -> [f64; 6] {
    let inner = line.split_once('{').unwrap().1.split_once('}').unwrap().0;
    let v: Vec<f64> = inner
        .split(',')
        .map(|kv| kv.trim().split_once(' ').unwrap().1.parse().unwrap())
        .collect();
    v.try_into().unwrap()
}

#[test]
fn compensation_moves_each_target_against_the_run_out() {
    register();
    let robot = RobotDescription::kr30ha();
    let mut model = Model::new(robot, Payload::default(), Vector3::zeros());
    let name = EffectName::parse("base_runout").unwrap();
    let mut effect = name.create(&Default::default(), &robot).unwrap();
    effect.values_mut().copy_from_slice(&E_MM);
    model.push(effect);

    let ws = files::load_program(None, PROGRAM.as_bytes(), None).unwrap();
    let sim = motion::simulate(&ws, &robot, &[]);
    let c = robopost::compensate::Calibrated::new(&model, "runout.json", b"runout");
    let options = program::Options {
        method: Method::Iterate,
        parallel: false,
        frames: Vec::new(),
        points: false,
    };
    let result = robopost::compensate::compensate_program(&ws, &c, &options);
    assert!(!result.rejected, "{:?}", result.report.errors);
    let written = String::from_utf8(result.files[0].bytes.to_vec()).unwrap();

    let before: Vec<&str> = PROGRAM.lines().filter(|l| l.starts_with("LIN")).collect();
    let after: Vec<&str> = written.lines().filter(|l| l.starts_with("LIN")).collect();
    assert_eq!(before.len(), 3);
    assert_eq!(after.len(), 3);
    let a1_of: Vec<f64> = sim
        .stops
        .iter()
        .filter(|s| !s.axis)
        .map(|s| s.nominal_axes[0])
        .collect();
    assert_eq!(a1_of.len(), 3);
    // Half the last written decimal (3 in mm) plus the run-out's change over the small
    // turn of A1 the compensation makes (e · |d|/reach, far below a nanometre).
    const HALF_MM: f64 = 0.5e-3;
    for ((b, a), a1) in before.iter().zip(&after).zip(&a1_of) {
        let (b, a) = (lin_values(b), lin_values(a));
        let d = runout_mm(&robot, *a1, E_MM);
        assert!(d.norm() > 0.05, "a check that can fail: {d}");
        for k in 0..3 {
            let want = b[k] - d[k];
            assert!(
                (a[k] - want).abs() <= HALF_MM + 1e-9,
                "{k}: written {} want {want} (moved {}, run-out {})",
                a[k],
                a[k] - b[k],
                d[k]
            );
        }
        for k in 3..6 {
            assert!(
                (a[k] - b[k]).abs() <= 0.5e-4 + 1e-12,
                "orientation {k}: {a:?} {b:?}"
            );
        }
    }
}
