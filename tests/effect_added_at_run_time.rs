//! A new physical effect is one file plus one registry entry: this file defines an effect the
//! crate has never heard of — the axial error motion of axis 1's bearing — and
//! registers it at run time ([`registry::register`]). Nothing else changes, and:
//!
//! - identification (`identify::pipeline::identify` with it in the effect list) recovers its
//!   amplitude from virtual-robot data whose error motion is added by an independent formula;
//! - compensation (`robopost::krl::job::compensate_program`) moves a program's targets by the
//!   displacement the formula gives, with the orientation untouched;
//! - diagnosis tries it among its candidates and names it when the calibration lacks it.
//!
//! The physics: the raceway of the A1 bearing is wavy, so the turning part rises and falls
//! along the axis twice per turn (ISO 230-7's axial error motion, second harmonic; a
//! once-per-turn part would be a tilt of the axis line, a `geometric` parameter): everything
//! beyond A1 is displaced along the base Z by `a·cos 2θ1 + b·sin 2θ1` (mm), θ1 = sense1·A1 the
//! physical rotation. No effect of the contract table moves the arm along Z with A1 alone.

#[path = "support/calibrate.rs"]
mod calibrate;

use nalgebra::Vector3;
use robopost::calibration::{Calibration, MeasurementFrame, Provenance};
use robopost::compensate::Method;
use robopost::diagnose::{diagnose, DiagnoseOptions};
use robopost::identify::pipeline::PAPER_EFFECTS;
use robopost::kinematics::{Payload, RobotDescription};
use robopost::krl::job::{files, program};
use robopost::measure::{Measurements, Stop};
use robopost::model::effects::{EffectError, ToRecord};
use robopost::model::record::{self, EffectRecord, RecordError};
use robopost::model::registry::{self, Arity, Evidence, Kind, RegisterError};
use robopost::model::{AxisState, ChainErrors, Context, Effect, EffectName, Parameter, Partial};
use robopost::model::{Model, Slot};
use robopost::simulate::campaign::Campaign;
use robopost::simulate::paper;
use robopost::simulate::virtual_robot::VirtualRobot;

// ---- The effect: everything the crate learns about it is in this section. ----

/// `wavy_bearing` — axial error motion of A1 twice per turn: `(a, b)` in mm.
#[derive(Clone, Debug, Default, PartialEq)]
struct WavyBearing {
    values: [f64; 2],
}

const NAMES: [&str; 2] = ["a", "b"];

fn names() -> Vec<String> {
    NAMES.iter().map(|n| n.to_string()).collect()
}

impl WavyBearing {
    /// (cos 2θ1, sin 2θ1) of the physical rotation θ1.
    fn turn(state: &AxisState, ctx: &Context) -> (f64, f64) {
        let theta = 2.0 * (ctx.robot.senses[0] * state.axes_deg[0]).to_radians();
        (theta.cos(), theta.sin())
    }
}

impl Effect for WavyBearing {
    fn name(&self) -> String {
        "wavy_bearing".into()
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
        let [a, b] = self.values;
        errors.add(Slot::Offset { axis: 1, coord: 2 }, a * c + b * s);
    }
    fn jacobian(&self, state: &AxisState, ctx: &Context, out: &mut Vec<Partial>) {
        let (c, s) = Self::turn(state, ctx);
        let slot = Slot::Offset { axis: 1, coord: 2 };
        for (param, value) in [(0, c), (1, s)] {
            out.push(Partial { param, slot, value });
        }
    }
}

impl ToRecord for WavyBearing {
    fn record(&self) -> EffectRecord {
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&names(), &self.values)),
            table: None,
        }
    }
}

/// The one registry entry.
static WAVY_BEARING: Kind = Kind {
    prefix: "wavy_bearing",
    arity: Arity::Robot,
    meaning: "axial error motion of A1's bearing: the arm rises and falls twice per turn",
    create: |_, _, _| Ok(Box::new(WavyBearing::default())),
    decode: |_, rec, _| {
        let v = rec.named_values(&names())?;
        Ok(Box::new(WavyBearing {
            values: [v[0], v[1]],
        }))
    },
    upgrade_v1: None,
    look_alikes: |_| Vec::new(),
    in_time: false,
    evidence: Evidence::Meaning,
};

fn register() {
    registry::register(&WAVY_BEARING).unwrap();
}

// ---- The test's own physics and data. ----

/// The axial error motion of the virtual robot's A1 bearing, mm.
const E_MM: [f64; 2] = [0.060, -0.040];

/// The displacement of everything beyond A1 at command angle `a1_deg`, by hand.
fn bearing_motion_mm(robot: &RobotDescription, a1_deg: f64, e: [f64; 2]) -> Vector3<f64> {
    let theta = 2.0 * robot.senses[0] * a1_deg.to_radians();
    Vector3::new(0.0, 0.0, e[0] * theta.cos() + e[1] * theta.sin())
}

/// The paper's campaign at 2° pitch plus 200 random poses, measured on the virtual KR 30 HA of
/// the fixtures (the paper's effects, tracker noise), with the error motion added to every
/// measured position by [`bearing_motion_mm`].
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
            *m += bearing_motion_mm(&truth.robot, s.state.axes_deg[0], E_MM);
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
    let name = EffectName::parse("WAVY_BEARING").unwrap();
    assert_eq!(name.to_string(), "wavy_bearing");
    assert_eq!(
        registry::kinds()
            .iter()
            .filter(|k| k.prefix == "wavy_bearing")
            .count(),
        1
    );
    static IMPOSTOR: Kind = Kind {
        prefix: "map",
        arity: Arity::Axis,
        meaning: "",
        create: |_, _, _| {
            Err(EffectError::NeedsGravity {
                effect: "map".into(),
            })
        },
        decode: |_, _, _| Err(RecordError::new("", "", "")),
        upgrade_v1: None,
        look_alikes: |_| Vec::new(),
        in_time: false,
        evidence: Evidence::Meaning,
    };
    assert_eq!(
        registry::register(&IMPOSTOR),
        Err(RegisterError::Taken { prefix: "map" })
    );
    static SHOUTING: Kind = Kind {
        prefix: "Wavy",
        arity: Arity::Robot,
        meaning: "",
        create: |_, _, _| Ok(Box::new(WavyBearing::default())),
        decode: |_, _, _| Err(RecordError::new("", "", "")),
        upgrade_v1: None,
        look_alikes: |_| Vec::new(),
        in_time: false,
        evidence: Evidence::Meaning,
    };
    let refused = registry::register(&SHOUTING).unwrap_err();
    assert_eq!(refused, RegisterError::BadPrefix { prefix: "Wavy" });
    assert_eq!(
        refused.to_string(),
        "an effect prefix of lowercase letters, digits and `_`, found `Wavy`"
    );
    // The calibration file carries it.
    let mut model = Model::new(
        RobotDescription::kr30ha(),
        Payload::default(),
        Vector3::zeros(),
    );
    model.push(Box::new(WavyBearing { values: E_MM }));
    let cal = Calibration::from_model(
        "KR 30 HA",
        model,
        MeasurementFrame::Base,
        Provenance::default(),
    );
    let path = std::path::Path::new("wavy.json");
    let back = robopost::calibration::parse(&cal.to_json(path).unwrap(), path).unwrap();
    assert_eq!(values_of(&back, "wavy_bearing"), E_MM);
}

#[test]
fn identification_recovers_the_motion_and_diagnosis_names_the_new_effect() {
    register();
    let (truth, data) = measured();

    // Identified with the paper's effects and the new one: the amplitude comes back.
    let with = calibrate::calibrate(&truth, &format!("{PAPER_EFFECTS},wavy_bearing"), &data, 2.0);
    let e = values_of(&with, "wavy_bearing");
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
        d.considered.iter().any(|f| f.effect == "wavy_bearing"),
        "{:#?}",
        d.considered
    );
    let named: Vec<&str> = d.candidates.iter().map(|f| f.effect.as_str()).collect();
    eprintln!("candidates {named:?}; verdict: {}", d.verdict);
    for f in d.considered.iter().take(5) {
        eprintln!(
            "{} {:.3} {:.2}: {}",
            f.effect, f.explained, f.rms_after_um, f.evidence
        );
    }
    assert_eq!(named.first(), Some(&"wavy_bearing"), "{:#?}", d.candidates);
    // Its evidence sentence is the one its registry entry chose: what the kind means.
    assert!(
        d.candidates[0].evidence.contains(WAVY_BEARING.meaning),
        "{}",
        d.candidates[0].evidence
    );
}

const PROGRAM: &str = "DEF wavy( )
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
fn compensation_moves_each_target_against_the_bearing_motion() {
    register();
    let robot = RobotDescription::kr30ha();
    let mut model = Model::new(robot, Payload::default(), Vector3::zeros());
    let name = EffectName::parse("wavy_bearing").unwrap();
    let mut effect = name.create(&Default::default(), &robot).unwrap();
    effect.values_mut().copy_from_slice(&E_MM);
    model.push(effect);

    let ws = files::load_program(None, PROGRAM.as_bytes(), None).unwrap();
    let sim = robopost::krl::interpret::simulate(&ws, &robot, &[]);
    let c = robopost::krl::job::Calibrated::new(&model, "wavy.json", b"wavy");
    let options = program::Options {
        method: Method::Iterate,
        parallel: false,
        stretching: robopost::compensate::sequence::Stretching::DEFAULT,
        frames: Vec::new(),
        points: false,
        ..program::Options::default()
    };
    let result = robopost::krl::job::compensate_program(&ws, &c, &options);
    assert!(!result.rejected, "{:?}", result.report.errors);
    let written = String::from_utf8(result.files[0].bytes.to_vec()).unwrap();

    let before: Vec<&str> = PROGRAM.lines().filter(|l| l.starts_with("LIN")).collect();
    let after: Vec<&str> = written.lines().filter(|l| l.starts_with("LIN")).collect();
    assert_eq!(before.len(), 3);
    assert_eq!(after.len(), 3);
    let a1_of: Vec<f64> = sim
        .stops
        .iter()
        .filter(|s| !s.programmed.is_axes())
        .map(|s| s.nominal_axes[0])
        .collect();
    assert_eq!(a1_of.len(), 3);
    // Half the last written decimal (3 in mm) plus the motion's change over the small turn
    // of A1 the compensation makes (2·e · |d|/reach, far below a nanometre).
    const HALF_MM: f64 = 0.5e-3;
    for ((b, a), a1) in before.iter().zip(&after).zip(&a1_of) {
        let (b, a) = (lin_values(b), lin_values(a));
        let d = bearing_motion_mm(&robot, *a1, E_MM);
        assert!(d.norm() > 0.01, "a check that can fail: {d}");
        assert!(d.x == 0.0 && d.y == 0.0);
        for k in 0..3 {
            let want = b[k] - d[k];
            assert!(
                (a[k] - want).abs() <= HALF_MM + 1e-9,
                "{k}: written {} want {want} (moved {}, motion {})",
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
