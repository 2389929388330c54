use robopost::compensate::files;
use robopost::motion;
use std::path::Path;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cal = robopost::calibration::load(Path::new("/tmp/truthcal.json")).unwrap();
    let model = cal.model();
    let load = |p: &str| {
        let b = std::fs::read(p).unwrap();
        files::load_program(Some(Path::new(p)), &b, None).unwrap()
    };
    let orig = load(&args[1]);
    let comp = load(&args[2]);
    let so = motion::simulate(&orig, &model.robot, &[]);
    let sc = motion::simulate(&comp, &model.robot, &[]);
    let states = motion::program_states(&sc);
    let from: usize = args[3].parse().unwrap();
    let to: usize = args[4].parse().unwrap();
    for k in from..=to {
        let goal = so.stops[k].goal.position;
        let s = states[k];
        let p = model.target_position(&s);
        let mut line = format!("stop {k}: err {:.2} µm |", (p - goal).norm() * 1e3);
        for n in 0..6 {
            let play = model.play(&s, n).unwrap();
            let b = model.play_width_deg(n, s.axes_deg[n]);
            line += &format!(
                " A{} {:?} lag {:+.5} (b/2 {:.5}) eng {} turn {:.4} c-nom {:+.5}|",
                n + 1,
                s.directions()[n],
                play.lag_deg,
                b / 2.0,
                play.engaged as u8,
                sc.stops[k].turns.angle_deg[n],
                s.axes_deg[n] - so.stops[k].nominal_axes[n]
            );
        }
        println!("{line}");
    }
}
