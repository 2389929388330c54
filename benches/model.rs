//! Full-model prediction cost: the paper's model (geometric, six maps and six backlash tables
//! at 1° pitch, crosstalk A3->A2) predicting the target position at varied states.

use criterion::{black_box, criterion_group, criterion_main, Criterion};

#[path = "support/cpu_time.rs"]
mod cpu_time;
use cpu_time::ThreadCpuTime;
use nalgebra::Vector3;
use robopost::kinematics::{Payload, RobotDescription};
use robopost::model::{expand_list, AxisHistory, AxisState, Direction, GridOptions, Model};

fn paper_model() -> Model {
    let mut model = Model::new(
        RobotDescription::kr30ha(),
        Payload::default(),
        Vector3::new(0.0, 0.0, 150.0),
    );
    for name in expand_list("geometric,map:A1..A6,backlash:A1..A6,crosstalk:A3->A2").expect("names")
    {
        model
            .push_named(&name, &GridOptions::default())
            .expect("effect");
    }
    let values: Vec<f64> = (0..model.n_parameters())
        .map(|i| (i as f64 * 0.37).sin() * 0.01)
        .collect();
    model.set_values(&values);
    model
}

fn states() -> Vec<AxisState> {
    (0..256)
        .map(|i| {
            let t = i as f64;
            let mut s = AxisState::new([
                (t * 1.3) % 300.0 - 150.0,
                -120.0 + (t * 0.7) % 140.0,
                -100.0 + (t * 0.9) % 240.0,
                (t * 2.1) % 600.0 - 300.0,
                (t * 0.8) % 200.0 - 100.0,
                (t * 2.7) % 600.0 - 300.0,
            ]);
            let flank = if i % 2 == 0 {
                Direction::Positive
            } else {
                Direction::Negative
            };
            s.history = [AxisHistory::engaged(flank); 6];
            s
        })
        .collect()
}

fn prediction(c: &mut Criterion<ThreadCpuTime>) {
    let model = paper_model();
    let states = states();
    let mut i = 0;
    c.bench_function("target_position (paper model)", |b| {
        b.iter(|| {
            i = (i + 1) % states.len();
            black_box(model.target_position(black_box(&states[i])))
        })
    });
}

/// One target's compensation solve (the per-target work of the main job's first pass) with
/// the hand-set calibration (the paper's full model): the goal is the nominal TCP of a
/// state, the start its axes, so the correction is the model's whole error (~0.3 mm).
fn solve_one_target(c: &mut Criterion<ThreadCpuTime>) {
    use robopost::compensate::solve::{self, Problem};
    use robopost::motion::frame::Frame;
    use robopost::motion::nominal::{Arm, Nominal};
    let model =
        robopost::calibration::load(std::path::Path::new("calibrations/kr30ha-handset.json"))
            .expect("hand-set calibration")
            .model();
    let tool = Frame::from_kuka(&robopost::kinematics::Pose::from_array([
        12.0, -5.0, 180.0, 0.0, 20.0, 0.0,
    ]));
    let nominal = Nominal(&model.robot);
    // Away from the wrist singularity (|A5| ≥ 10°), as CAM paths are.
    let states = states();
    let problems: Vec<Problem> = states
        .iter()
        .filter(|s| s.axes_deg[4].abs() >= 10.0)
        .map(|s| Problem {
            goal: nominal.tcp(&s.axes_deg, &tool),
            tool: &tool,
            start: s.axes_deg.into(),
            histories: &s.history,
            hold: [false; 6],
        })
        .collect();
    let mut i = 0;
    c.bench_function("solve one target (hand-set model)", |b| {
        b.iter(|| {
            i = (i + 1) % problems.len();
            black_box(solve::solve(&model, black_box(&problems[i]), Default::default()).ok())
        })
    });
}

criterion_group! {
    name = benches;
    config = cpu_time::criterion(3);
    targets = prediction, solve_one_target
}
criterion_main!(benches);
