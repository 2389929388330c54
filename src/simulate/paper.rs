//! The virtual KR 30 HA of the shipped fixtures: the paper's effects at the sizes the paper
//! reports (section 3 and Figs. 4, 5, 7) — axis average lines off by tenths of a millimetre
//! and hundredths of a degree, angular positioning deviations periodic with the gear pitch
//! with amplitudes of a few thousandths of a degree, gear plays of 0.005–0.01°, and the
//! A3 → A2 crosstalk of Fig. 5 (A2's deviation shifting by about two hundredths of a degree
//! between A3 = 58° and 153°). Written in closed form (no random numbers) so the truth is the
//! same on every machine; `hidden` adds effects outside the paper's model (compliance of A2
//! and A3 under gravity, tilt of A1) for diagnosis to find.

use std::f64::consts::PI;

use nalgebra::Vector3;

use super::truth::TruthFile;
use crate::calibration::{Calibration, MeasurementFrame, Provenance};
use crate::kinematics::{Payload, RobotDescription};
use crate::model::effects::{crosstalk::Crosstalk, geometric::Geometric, tilt::Tilt};
use crate::model::{EffectName, GridOptions, Model};

/// The retroreflector of the virtual campaign, KUKA flange frame (mm): off the A6 axis so
/// that A6's angle moves it (144 mm from the A6 axis).
pub const TARGET_MM: [f64; 3] = [-120.0, -80.0, 180.0];

/// The geometric errors (paper order and units: mm, degrees).
const GEOMETRIC: [(&str, f64); 21] = [
    ("dx21", 0.063),
    ("a21", 0.0018),
    ("dth20", 0.0033),
    ("dz32", -0.054),
    ("a32", -0.0015),
    ("g32", 0.0012),
    ("dth30", -0.0027),
    ("dz43", 0.036),
    ("dy43", -0.045),
    ("g43", 0.0021),
    ("dth40", 0.0042),
    ("dx54", 0.048),
    ("dz54", -0.027),
    ("g54", -0.0024),
    ("dth50", 0.0036),
    ("dz65", 0.015),
    ("dy65", -0.021),
    ("g65", 0.0027),
    ("p6x", 0.024),
    ("p6y", -0.015),
    ("p6z", 0.018),
];

/// Gear pitch (degrees of axis rotation per period) and amplitudes (degrees) per axis:
/// (pitch, periodic amplitude, slow cumulative amplitude, half the gear play's width).
const AXES: [(f64, f64, f64, f64); 6] = [
    (12.0, 0.0030, 0.0040, 0.0025),
    (9.0, 0.0035, 0.0050, 0.0030),
    (10.0, 0.0030, 0.0045, 0.0030),
    (15.0, 0.0040, 0.0030, 0.0035),
    (15.0, 0.0040, 0.0030, 0.0035),
    (20.0, 0.0050, 0.0030, 0.0040),
];

/// The direction-independent deviation of axis n (1..=6) at command angle `a` (degrees).
pub fn map_deg(n: usize, a: f64) -> f64 {
    let (pitch, periodic, slow, _) = AXES[n - 1];
    let phase = 0.7 * n as f64;
    periodic * (2.0 * PI * a / pitch + phase).sin()
        + 0.4 * periodic * (4.0 * PI * a / pitch + 2.0 * phase).sin()
        + slow * (a.to_radians() * 0.8 + phase).sin()
}

/// The gear play's width of axis n at command angle `a` (degrees): the output lags the
/// command by half of it; larger where the gravity load is small (the gears float),
/// modelled as a mild angle dependence.
pub fn play_width_deg(n: usize, a: f64) -> f64 {
    let (_, _, _, half) = AXES[n - 1];
    2.0 * half * (1.0 + 0.25 * (a.to_radians() + 0.3 * n as f64).cos())
}

/// The A3 → A2 crosstalk (degrees) at (A2, A3): the load on A2's gears changes with the
/// forearm's angle; zero at A3 = 105°, about ±0.012° at 58° and 153° (Fig. 5).
pub fn crosstalk_deg(a2: f64, a3: f64) -> f64 {
    let x = (a3 - 105.0) / 48.0;
    (0.012 * x + 0.003 * x * x) * (1.0 + 0.5 * (a2 + 60.0).to_radians().sin())
}

fn table_grid(lo: f64, hi: f64, pitch: f64) -> Vec<f64> {
    let n = ((hi - lo) / pitch).round() as usize;
    (0..=n).map(|i| lo + i as f64 * pitch).collect()
}

/// The paper-effects truth model (and, with `hidden`, the extra effects) of the virtual KR 30 HA.
pub fn truth_model(hidden: bool) -> Model {
    let robot = RobotDescription::kr30ha();
    let payload = Payload {
        mass_kg: 5.0,
        cog_mm: [0.0, 0.0, 60.0],
    };
    let mut model = Model::new(robot, payload, Vector3::from(TARGET_MM));
    let mut geometric = Geometric::default();
    for (i, (_, v)) in GEOMETRIC.iter().enumerate() {
        geometric.values[i] = *v;
    }
    model.push(Box::new(geometric));
    // Maps and backlash at 0.5° over the joint limits: finer than any identification grid,
    // so the identified tables approximate the truth as a real robot's would.
    let fine = |n: usize| GridOptions {
        pitch_deg: Some(0.5),
        range_deg: Some(robot.limits_deg[n - 1]),
        ..GridOptions::default()
    };
    for (prefix, f) in [
        ("map", map_deg as fn(usize, f64) -> f64),
        ("backlash", play_width_deg),
    ] {
        for n in 1..=6 {
            let name = EffectName::parse(&format!("{prefix}:A{n}")).expect("effect name");
            let mut effect = name.create(&fine(n), &robot).expect("table effect");
            let [lo, hi] = robot.limits_deg[n - 1];
            let grid = table_grid(lo, hi, 0.5);
            for (v, a) in effect.values_mut().iter_mut().zip(grid) {
                *v = f(n, a);
            }
            model.push(effect);
        }
    }
    let [lo2, hi2] = robot.limits_deg[1];
    let [lo3, hi3] = robot.limits_deg[2];
    let options = GridOptions {
        pitch_deg: Some(2.0),
        range_deg: Some([lo2, hi2]),
        other_grid_deg: Some(table_grid(lo3, hi3, 5.0)),
        ..GridOptions::default()
    };
    let mut crosstalk = Crosstalk::zeros(3, 2, &options, &robot).expect("crosstalk grid");
    let columns = crosstalk.table.columns.points().to_vec();
    let rows = crosstalk.table.rows.points().to_vec();
    for (i, a2) in rows.iter().enumerate() {
        for (j, a3) in columns.iter().enumerate() {
            crosstalk.table.values[i * columns.len() + j] = crosstalk_deg(*a2, *a3);
        }
    }
    model.push(Box::new(crosstalk));
    if hidden {
        for (name, value) in [("compliance:A2", 0.004), ("compliance:A3", 0.006)] {
            let name = EffectName::parse(name).expect("effect name");
            let mut effect = name
                .create(&GridOptions::default(), &robot)
                .expect("effect");
            effect.values_mut()[0] = value;
            model.push(effect);
        }
        let mut tilt = Tilt::zeros(1);
        tilt.values = [0.003, -0.002, 0.001, 0.0, 0.002, 0.003, 0.0, -0.001];
        model.push(Box::new(tilt));
    }
    model
}

/// The truth file of the virtual KR 30 HA measured in its base frame.
pub fn truth_file(hidden: bool, seed: u64) -> TruthFile {
    let notes = if hidden {
        "Virtual KR 30 HA: the paper's effects plus compliance of A2/A3 and tilt of A1, which \
         the paper's model does not contain (for diagnosis)."
    } else {
        "Virtual KR 30 HA with the paper's effects at realistic sizes: 18 axis-line errors, \
         gear-pitch periodic angular deviations, gear plays (the output lags), crosstalk A3->A2."
    };
    let calibration = Calibration::from_model(
        "KR 30 HA (virtual)",
        truth_model(hidden),
        MeasurementFrame::Base,
        Provenance::default(),
    );
    let mut file = TruthFile::new(calibration.to_file());
    file.seed = seed;
    file.notes = Some(notes.to_string());
    file
}
