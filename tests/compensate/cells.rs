//! Files as real cells hold them (issue 37): a module whose name is the generator's path, a
//! tree without `$config.dat`, a station chosen at run time (`--assume`), and taught versus
//! offline points (`--points`) — through the command line, on temporary copies.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const CONFIG: &str = "fixtures/config/$config.dat";
const CAL: &str = "calibrations/kr30ha-example.json";

fn robopost(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_robopost"))
        .args(args)
        .output()
        .unwrap()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Copies `fixtures/DIR/NAME.src` and its `.dat` into `to`.
fn copy(dir: &str, name: &str, to: &Path) -> PathBuf {
    let src = Path::new("fixtures").join(dir).join(format!("{name}.src"));
    let dst = to.join(format!("{name}.src"));
    std::fs::copy(&src, &dst).unwrap();
    let dat = src.with_extension("dat");
    if dat.exists() {
        std::fs::copy(&dat, dst.with_extension("dat")).unwrap();
    }
    dst
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

// ---- a module named with the generator's path ------------------------------------------

/// `DEF Archivos_KRL/Contorno_KRL/cilindro( )` and `DEFDAT Archivos_KRL/…`: a warning located
/// on each name, and the program read, simulated and compensated as any other (it was
/// refused as "not a KRL file" before).
#[test]
fn a_module_named_with_its_path_is_a_warning_on_the_name() {
    let src = std::fs::read("fixtures/modules/cilindro.src").unwrap();
    let file = robopost::krl::parse(&src, robopost::krl::FileKind::Src).unwrap();
    assert_eq!(file.emit(), src, "lossless");
    let warnings: Vec<_> = file.problems().iter().filter(|p| !p.is_error()).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    // Line 4, from the column after `DEF ` over the 34 bytes of the path.
    let at = warnings[0].span;
    assert_eq!(file.line_col(at.start as usize), (4, 5));
    assert_eq!(&src[at.range()], b"Archivos_KRL/Contorno_KRL/cilindro");
    // The routine is there, its 31 motions in it (3 layers of 9, 3 PTP, 1 retract).
    assert_eq!(file.motions().count(), 31);
    let (_, h) = file.routines().next().unwrap();
    assert_eq!(file.text(h.name), b"Archivos_KRL/Contorno_KRL/cilindro");

    let out = robopost(&[
        "check",
        "--config",
        CONFIG,
        "-c",
        CAL,
        "fixtures/modules/cilindro.src",
    ]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains("not a KRL file"), "{err}");
    assert!(
        err.contains("the data list name `Archivos_KRL/Contorno_KRL/cilindro` is not a KRL name")
            && err.contains("--> fixtures/modules/cilindro.dat:1:8")
            && err.contains("--> fixtures/modules/cilindro.src:4:5"),
        "{err}"
    );
    assert!(
        text(&out.stdout).contains("31 of 31 targets compensated, 0 rejected"),
        "{}",
        text(&out.stdout)
    );
}

/// A KRL name stays without a warning; so do names with `$` and `_`.
#[test]
fn a_krl_module_name_has_no_warning() {
    for head in ["DEF prog( )", "DEF $my_prog_2( )", "GLOBAL DEF _x(a:IN)"] {
        let src = format!("{head}\nPTP {{A1 0}}\nEND\n");
        let file = robopost::krl::parse(src.as_bytes(), robopost::krl::FileKind::Src).unwrap();
        assert!(file.problems().is_empty(), "{head}: {:?}", file.problems());
    }
}

// ---- a tree without $config.dat -----------------------------------------------------------

/// The frames the program names are listed with the options that give them; given, the
/// program resolves.
#[test]
fn a_missing_config_names_the_frames_and_how_to_give_them() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("KRC/R1/Program");
    std::fs::create_dir_all(&prog).unwrap();
    let src = copy("points", "taught_pick", &prog);
    let cell = dir.path().to_str().unwrap();
    let out = robopost(&["check", "--cell", cell, src.to_str().unwrap()]);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no $config.dat was given or found in the cell, and this program needs TOOL_DATA[5], BASE_DATA[1]: give them with --tool 5=X,Y,Z,A,B,C --base 1=X,Y,Z,A,B,C, or the robot's $config.dat apart with --config FILE"),
        "{err}"
    );
    assert!(
        text(&out.stdout).contains("rejected"),
        "{}",
        text(&out.stdout)
    );
    // Given on the command line, as the message says.
    let out = robopost(&[
        "check",
        "--cell",
        cell,
        "--tool",
        "5=0,0,150,0,0,0",
        "--base",
        "1=0,0,0,0,0,0",
        src.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("8 of 8 targets resolved and compensable, 0 rejected"),
        "{}",
        text(&out.stdout)
    );
    // A $config.dat given apart.
    let out = robopost(&[
        "check",
        "--cell",
        cell,
        "--config",
        CONFIG,
        src.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
}

// ---- a station chosen at run time ---------------------------------------------------------

/// `station_pick` with its run-time choices written out: the base of `station` and the
/// approach move present or not — the program the controller runs for that variant.
fn written_out(station_base: u32, approach: bool) -> String {
    let src = read(Path::new("fixtures/runtime/station_pick.src"));
    let mut out = Vec::new();
    let mut lines = src.lines();
    while let Some(l) = lines.next() {
        if l.starts_with("IF lnUsedBase") {
            for _ in 0..4 {
                lines.next();
            }
            out.push(format!("$BASE = BASE_DATA[{station_base}]"));
        } else if l.starts_with("IF $IN[5]") {
            let inner = lines.next().unwrap();
            lines.next();
            if approach {
                out.push(inner.trim().to_string());
            }
        } else {
            out.push(l.to_string());
        }
    }
    out.join("\n") + "\n"
}

/// The motion lines of a program (what compensation changes).
fn motions(text: &str) -> Vec<String> {
    text.lines()
        .map(str::trim)
        .filter(|l| l.starts_with("PTP") || l.starts_with("LIN"))
        .map(str::to_string)
        .collect()
}

/// Each variant assumed gives exactly the program compensated with that variant written
/// out; the two stations differ; the summary and the report list the assumptions.
#[test]
fn each_assumed_station_is_compensated_as_written_out() {
    let dir = tempfile::tempdir().unwrap();
    let src = copy("runtime", "station_pick", dir.path());
    let mut variants = Vec::new();
    for (station, base) in [(1, 2), (2, 3)] {
        for approach in [true, false] {
            let out_path = dir.path().join(format!("out_{station}_{approach}.src"));
            let report = dir.path().join(format!("r_{station}_{approach}.json"));
            let out = robopost(&[
                src.to_str().unwrap(),
                "-c",
                CAL,
                "--config",
                CONFIG,
                "-o",
                out_path.to_str().unwrap(),
                "--report",
                report.to_str().unwrap(),
                "--assume",
                &format!("lnUsedBase={station}"),
                "--assume",
                &format!("$in[5]={}", if approach { "TRUE" } else { "FALSE" }),
            ]);
            let err = text(&out.stderr);
            assert_eq!(out.status.code(), Some(0), "{err}");
            assert!(
                err.contains(&format!(
                    "; assumed lnUsedBase={station} (used 1 time), $in[5]={} (used 1 time)",
                    if approach { "TRUE" } else { "FALSE" }
                )),
                "{err}"
            );
            let r: serde_json::Value = serde_json::from_str(&read(&report)).unwrap();
            assert_eq!(r["assumptions"][0]["uses"], 1);
            assert_eq!(
                r["assumptions"][1]["assumption"],
                format!("$in[5]={}", if approach { "TRUE" } else { "FALSE" })
            );
            assert_eq!(r["unresolved"], 0);
            assert_eq!(r["targets"], if approach { 6 } else { 5 });

            // The variant written out, compensated without assumptions.
            let plain = dir.path().join(format!("plain_{station}_{approach}.src"));
            std::fs::write(&plain, written_out(base, approach)).unwrap();
            std::fs::copy(src.with_extension("dat"), plain.with_extension("dat")).unwrap();
            let plain_out = dir
                .path()
                .join(format!("plain_out_{station}_{approach}.src"));
            let o = robopost(&[
                plain.to_str().unwrap(),
                "-c",
                CAL,
                "--config",
                CONFIG,
                "-o",
                plain_out.to_str().unwrap(),
            ]);
            assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
            let mut assumed = motions(&read(&out_path));
            if !approach {
                // The approach move is not executed: left as written.
                let skipped = "LIN {X 530, Y 150, Z 150, A 0, B 0, C 180}";
                let at = assumed.iter().position(|l| l == skipped).unwrap();
                assumed.remove(at);
            }
            let expected = motions(&read(&plain_out));
            assert_eq!(assumed, expected, "station {station}, approach {approach}");
            // Compensated: the written numbers changed.
            assert_ne!(assumed, motions(&written_out(base, approach)));
            variants.push(assumed);
        }
    }
    assert_ne!(
        variants[0], variants[2],
        "the two stations give other numbers"
    );
}

/// Without the assumption the base is unknown: the program is rejected, naming the line;
/// an assumption the walk never uses is a warning; `check` and `batch` take them too.
#[test]
fn assumptions_in_check_and_batch_and_an_unused_one() {
    let dir = tempfile::tempdir().unwrap();
    let src = copy("runtime", "station_pick", dir.path());
    let s = src.to_str().unwrap();
    let out = robopost(&["check", "--config", CONFIG, s]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).contains("IF depends on run time (LNUSEDBASE, declared without a value)"),
        "{}",
        text(&out.stderr)
    );
    let out = robopost(&[
        "check",
        "--config",
        CONFIG,
        s,
        "--assume",
        "LNUSEDBASE=2",
        "--assume",
        "nStation=4",
    ]);
    let (err, stdout) = (text(&out.stderr), text(&out.stdout));
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("--assume nStation=4: never used"), "{err}");
    // $IN[5] still unknown: the approach move is not resolved.
    assert!(
        stdout.contains("5 of 5 targets resolved and compensable, 0 rejected, 1 motion not resolved before run time (left unchanged); assumed LNUSEDBASE=2 (used 1 time), nStation=4 (used 0 times)"),
        "{stdout}"
    );

    let out_dir = dir.path().join("out");
    let in_dir = dir.path().join("in");
    std::fs::create_dir_all(&in_dir).unwrap();
    copy("runtime", "station_pick", &in_dir);
    let out = robopost(&[
        "batch",
        in_dir.to_str().unwrap(),
        "-c",
        CAL,
        "--config",
        CONFIG,
        "-o",
        out_dir.to_str().unwrap(),
        "--assume",
        "lnUsedBase=1",
        "--assume",
        "$IN[5]=TRUE",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("6 of 6 targets compensated, 0 rejected, 0 warnings; assumed lnUsedBase=1 (used 1 time), $IN[5]=TRUE (used 1 time)")
            || text(&out.stdout).contains("; assumed lnUsedBase=1 (used 1 time), $IN[5]=TRUE (used 1 time)"),
        "{}",
        text(&out.stdout)
    );
    assert!(out_dir.join("station_pick.src").exists());
    // A malformed assumption is a usage error, nothing written.
    let out = robopost(&["check", s, "--assume", "lnUsedBase"]);
    assert_eq!(out.status.code(), Some(2));
}

// ---- taught and offline points ----------------------------------------------------------

fn compensate(src: &Path, extra: &[&str]) -> (Output, PathBuf, serde_json::Value) {
    let dir = src.parent().unwrap();
    let stem = src.file_stem().unwrap().to_str().unwrap();
    let tag = extra.join("_").replace(['-', ' '], "");
    let out = dir.join(format!("{stem}_out{tag}.src"));
    let report = dir.join(format!("{stem}_r{tag}.json"));
    let mut args = vec![
        src.to_str().unwrap(),
        "-c",
        CAL,
        "--config",
        CONFIG,
        "-o",
        out.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = robopost(&args);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    let r = serde_json::from_str(&read(&report)).unwrap();
    (o, out, r)
}

/// A pick-and-place taught with the pendant's inline forms: every target is taken as taught
/// and left as it is (the files come out as they went in); `--points offline` compensates
/// them all.
#[test]
fn a_taught_program_is_left_as_taught() {
    let dir = tempfile::tempdir().unwrap();
    let src = copy("points", "taught_pick", dir.path());
    let (o, out, r) = compensate(&src, &[]);
    assert_eq!(read(&out), read(&src));
    assert_eq!(
        read(&out.with_extension("dat")),
        read(&src.with_extension("dat"))
    );
    // 8 motion inline forms: HOME, P1, P2, P1, P3, P4, P3, HOME.
    assert_eq!(r["points_taken"]["mode"], "auto");
    assert_eq!(r["points_taken"]["taught"], 8);
    assert_eq!(r["points_taken"]["offline"], 0);
    assert_eq!(r["compensated"], 0);
    let reasons = r["points_taken"]["reasons"].as_array().unwrap();
    assert_eq!(reasons.len(), 1);
    assert_eq!(reasons[0]["taken"], "taught");
    assert!(reasons[0]["why"].as_str().unwrap().contains("inline form"));
    let names: Vec<&str> = r["points_taken"]["taught_points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().rsplit(' ').next().unwrap())
        .collect();
    assert_eq!(names, ["XHOME", "XP1", "XP2", "XP3", "XP4"]);
    assert!(
        text(&o.stderr).contains("0 of 8 targets compensated, 0 rejected")
            && text(&o.stderr).contains("; 8 targets taken as taught (8 a teach-pendant inline form with its point in the .dat), 0 as offline"),
        "{}",
        text(&o.stderr)
    );

    let (_, out, r) = compensate(&src, &["--points", "offline"]);
    assert_eq!(r["points_taken"]["offline"], 8);
    assert!(
        r["compensated"].as_u64().unwrap() >= 7,
        "{}",
        r["compensated"]
    );
    assert_ne!(
        read(&out.with_extension("dat")),
        read(&src.with_extension("dat"))
    );
}

/// A CAM program (header of a post processor, literal path, a start point in its `.dat`):
/// every target offline, the `.dat` point by the header, the path by its literals.
#[test]
fn a_cam_program_is_compensated_as_offline() {
    let dir = tempfile::tempdir().unwrap();
    let src = copy("points", "cam_mill", dir.path());
    let (o, out, r) = compensate(&src, &[]);
    let total = r["targets"].as_u64().unwrap();
    // PTP XSTART twice, 1 + 6 facing + 13 contour + 1 retract literal LINs.
    assert_eq!(total, 23);
    assert_eq!(r["points_taken"]["taught"], 0);
    assert_eq!(r["points_taken"]["offline"], 23);
    let reasons = r["points_taken"]["reasons"].as_array().unwrap();
    let header = reasons
        .iter()
        .find(|x| {
            x["why"]
                .as_str()
                .unwrap()
                .contains("CAM/offline-programming header")
        })
        .expect("the header reason");
    assert_eq!(header["targets"], 2);
    assert!(
        header["why"]
            .as_str()
            .unwrap()
            .contains("cam_mill.src:6 (\"generated by\")"),
        "{header}"
    );
    let literal = reasons
        .iter()
        .find(|x| x["why"] == "a literal position in the motion statement")
        .unwrap();
    assert_eq!(literal["targets"], 21);
    assert_eq!(r["compensated"], 23);
    assert_ne!(
        read(&out.with_extension("dat")),
        read(&src.with_extension("dat"))
    );
    // Nothing taken as taught in auto: the summary says nothing of it.
    assert!(!text(&o.stderr).contains("taken as taught"));
}

/// Taught approach and retract (inline forms), a CAM path between them: the path is
/// compensated, the taught points are left; `--points taught` leaves all.
#[test]
fn a_mixed_program_compensates_only_its_cam_path() {
    let dir = tempfile::tempdir().unwrap();
    let src = copy("points", "mixed_deburr", dir.path());
    let (_, out, r) = compensate(&src, &[]);
    assert_eq!(r["points_taken"]["taught"], 5);
    assert_eq!(r["points_taken"]["offline"], 6);
    assert_eq!(r["compensated"], 6);
    // The .dat (the taught points) unchanged, the path's six lines changed.
    assert_eq!(
        read(&out.with_extension("dat")),
        read(&src.with_extension("dat"))
    );
    let (a, b) = (read(&src), read(&out));
    let changed: Vec<(&str, &str)> = a
        .lines()
        .zip(b.lines().skip(1))
        .filter(|(x, y)| x != y)
        .collect();
    // The header comment goes after the directives (line 5): compare after it.
    let header_at = b
        .lines()
        .position(|l| l.starts_with("; robopost:"))
        .unwrap();
    let b_lines: Vec<&str> = b
        .lines()
        .enumerate()
        .filter(|(i, _)| *i != header_at)
        .map(|(_, l)| l)
        .collect();
    let differing: Vec<usize> = a
        .lines()
        .zip(&b_lines)
        .enumerate()
        .filter(|(_, (x, y))| x != *y)
        .map(|(i, _)| i)
        .collect();
    assert_eq!(differing.len(), 6, "{changed:?}");
    for i in differing {
        assert!(
            a.lines().nth(i).unwrap().starts_with("LIN {X "),
            "line {}",
            i + 1
        );
    }
    let (_, out, r) = compensate(&src, &["--points", "taught"]);
    assert_eq!(r["points_taken"]["taught"], 11);
    assert_eq!(r["compensated"], 0);
    assert_eq!(read(&out), read(&src));
}

// ---- a program moved to another robot ---------------------------------------------------

/// The model of a truth file (`robopost-truth/1`: the robot as it really is).
fn truth_model(path: &str) -> robopost::model::Model {
    let v: serde_json::Value = serde_json::from_str(&read(Path::new(path))).unwrap();
    robopost::calibration::parse(&v["model"].to_string(), Path::new(path))
        .unwrap()
        .model()
}

/// The TCP every stop of `sim` reaches on robot `m`: its model at the commanded axes with the
/// gear-play history of the simulated motion (`program_states`), then the stop's tool.
fn reached(
    m: &robopost::model::Model,
    sim: &robopost::krl::interpret::Simulation,
) -> Vec<robopost::motion::frame::Frame> {
    let states = robopost::motion::program_states(&sim.stops, &sim.arcs);
    sim.stops
        .iter()
        .zip(&states)
        .map(|(s, st)| m.flange_pose(st).compose(&sim.frames[s.tool as usize]))
        .collect()
}

/// `--from A -c B` on the virtual robot: a pick-and-place taught on robot A (the hidden-effect
/// truth; the pendant stored the nominal poses of the taught axis angles) and moved to robot B
/// (the paper's truth, compensated with the calibration identified from B's campaign) reaches
/// on B the places A reached, within what B's identification leaves (B's calibration against
/// B's truth at the commands written) and the written decimals; run unchanged on B it misses
/// them by A's and B's errors together.
#[test]
fn a_program_taught_on_one_robot_reaches_its_places_on_another() {
    use robopost::krl::job::{files, program, Calibrated};
    let a_true = truth_model("fixtures/measurements/kr30ha-truth-hidden.json");
    let b_true = truth_model("fixtures/measurements/kr30ha-truth.json");
    let b_cal = robopost::calibration::load(Path::new(CAL)).unwrap().model();
    let dir = tempfile::tempdir().unwrap();
    let src = copy("points", "taught_pick", dir.path());
    let load = |p: &Path| {
        files::load_program(Some(p), &std::fs::read(p).unwrap(), Some(Path::new(CONFIG))).unwrap()
    };
    let ws = load(&src);
    let robot = b_cal.robot;
    let taught = robopost::krl::interpret::simulate(&ws, &robot, &[]);
    // The check of `reached` itself: the nominal model reaches the programmed poses.
    let nominal = robopost::calibration::load(Path::new("calibrations/kr30ha-nominal.json"))
        .unwrap()
        .model();
    for (s, r) in taught.stops.iter().zip(reached(&nominal, &taught)) {
        assert!((s.goal.position - r.position).norm() < 1e-6);
    }
    let places = reached(&a_true, &taught);
    let unmoved = reached(&b_true, &taught);

    let c = Calibrated::new(&b_cal, "b", b"");
    let options = program::Options {
        parallel: true,
        ..program::Options::default()
    };
    let result = robopost::krl::job::compensate_program_from(&ws, &c, Some(&a_true), &options);
    assert!(
        !result.rejected && result.target_errors == 0,
        "{:?}",
        result.report.errors
    );
    assert_eq!(result.report.points_taken.taught, 8);
    assert!(result.report.points_taken.moved_from);
    let out = dir.path().join("moved/taught_pick.src");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    files::write_atomic_pieces(&files::outputs(&ws, &result.files, &out)).unwrap();
    let written = load(&out);
    let moved = robopost::krl::interpret::simulate(&written, &robot, &[]);
    assert_eq!(moved.stops.len(), taught.stops.len());
    let on_b = reached(&b_true, &moved);
    let predicted_b = reached(&b_cal, &moved);
    let (mut worst, mut worst_before) = (0.0f64, 0.0f64);
    for k in 0..taught.stops.len() {
        if taught.stops[k].nominal_axes.0 == [0.0, -90.0, 90.0, 0.0, 0.0, 0.0] {
            // HOME, an axis target: the same axes on every robot, nothing to move.
            continue;
        }
        let miss = (on_b[k].position - places[k].position).norm() * 1e3;
        let floor = (on_b[k].position - predicted_b[k].position).norm() * 1e3;
        let before = (unmoved[k].position - places[k].position).norm() * 1e3;
        // B's identification error at the command, plus the written decimals (3 of a mm,
        // 4 of a degree) and the solver's tolerance.
        assert!(
            miss <= floor + 2.0,
            "stop {k}: {miss:.1} µm from A's place, B's identification leaves {floor:.1} µm"
        );
        eprintln!("stop {k}: {miss:.2} µm (floor {floor:.2} µm, unmoved {before:.1} µm)");
        worst = worst.max(miss);
        worst_before = worst_before.max(before);
    }
    eprintln!("moved: worst {worst:.1} µm from A's places; unmoved: {worst_before:.1} µm");
    assert!(worst_before > 100.0, "A and B differ: {worst_before:.1} µm");
    assert!(
        worst < worst_before / 3.0,
        "moved {worst:.1} µm, unmoved {worst_before:.1} µm"
    );
}

/// `--from` on the command line: the summary says the taught targets were moved; a
/// calibration of another robot type is refused before anything is written.
#[test]
fn from_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let src = copy("points", "taught_pick", dir.path());
    let (o, out, r) = compensate(&src, &["--from", "calibrations/kr30ha-handset.json"]);
    assert!(
        text(&o.stderr).contains("taken as taught (8 a teach-pendant inline form with its point in the .dat) and moved to where the robot of --from reaches them"),
        "{}",
        text(&o.stderr)
    );
    assert_eq!(r["points_taken"]["moved_from"], true);
    assert_ne!(
        read(&out.with_extension("dat")),
        read(&src.with_extension("dat"))
    );
    let bad = dir.path().join("bad.src");
    let o = robopost(&[
        src.to_str().unwrap(),
        "-c",
        CAL,
        "--config",
        CONFIG,
        "--from",
        "calibrations/kr16-2-nominal.json",
        "-o",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(!bad.exists());
}
