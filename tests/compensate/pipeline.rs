//! The KRL pipeline: simulate, compensate, rewrite.

use std::path::Path;

use robopost::compensate::files;
use robopost::motion;

#[test]
#[ignore]
fn debug_stops() {
    let name = std::env::var("PROG").unwrap_or("fixtures/programs/paper_path2.src".into());
    let p = Path::new(&name);
    let bytes = std::fs::read(p).unwrap();
    let cfg = std::env::var("CFG").ok();
    let ws = files::load_program(Some(p), &bytes, cfg.as_deref().map(Path::new)).unwrap();
    let robot = robopost::kinematics::RobotDescription::kr30ha();
    let sim = motion::simulate(&ws, &robot, &[]);
    for d in &sim.diagnostics {
        eprintln!("{}", d.render());
    }
    for s in &sim.stops {
        eprintln!(
            "L{} {:?} q {:?} arr {:?}",
            s.stmt.line,
            s.kind,
            s.nominal_axes.map(|x| (x * 1000.0).round() / 1000.0),
            s.arrival.map(|a| a.map(|x| (x * 1000.0).round() / 1000.0))
        );
    }
}

#[test]
#[ignore]
fn debug_placement() {
    use robopost::kinematics::{inverse, Select};
    use robopost::motion::frame::Frame;
    let robot = robopost::kinematics::RobotDescription::kr30ha();
    for x0 in [900.0, 950.0, 1000.0, 1050.0, 1100.0] {
        for z0 in [-100.0, 0.0, 100.0, 200.0, 300.0, 400.0] {
            let mut min_a5 = f64::MAX;
            let mut ok = true;
            let mut min_el = f64::MAX;
            for z in [0.0, 500.0, 1000.0] {
                let mut pts = vec![];
                for k in 0..=200 {
                    let t = k as f64 * 10.0;
                    pts.push((0.0, t));
                    pts.push((400.0, t));
                }
                for k in 0..=40 {
                    pts.push((k as f64 * 10.0, 0.0));
                    pts.push((k as f64 * 10.0, 2000.0));
                }
                for (x, y) in pts {
                    let f =
                        Frame::from_kuka(&[x0 + x, y - 1000.0, z0 + z + 200.0, 0.0, 0.0, 180.0]);
                    match inverse(&robot, &f.to_isometry(), Select::Status { s: 2, t: None }) {
                        Ok(s) => {
                            min_a5 = min_a5.min(s.axes_deg[4].abs());
                            min_el = min_el.min(s.axes_deg[2] - 10.03);
                        }
                        Err(_) => ok = false,
                    }
                }
            }
            eprintln!("x0 {x0} z0 {z0} ok {ok} minA5 {min_a5:.2} elbow {min_el:.2}");
        }
    }
}
