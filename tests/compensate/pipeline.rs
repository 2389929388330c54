//! The KRL pipeline: simulate, compensate, rewrite — on the fixtures and on small programs
//! written here.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use robopost::calibration;
use robopost::compensate::{self, files, program, Calibrated, ProgramResult};
use robopost::kinematics::RobotDescription;
use robopost::model::Model;
use robopost::motion::{self, Workspace};

pub const CONFIG: &str = "fixtures/config/$config.dat";

pub fn cal(name: &str) -> (Model, Vec<u8>) {
    let path = PathBuf::from(format!("calibrations/{name}"));
    let bytes = std::fs::read(&path).unwrap();
    let model = calibration::parse(&String::from_utf8_lossy(&bytes), &path)
        .unwrap()
        .model();
    (model, bytes)
}

/// Every program fixture (.src), with whether it needs the cell's `$config.dat`.
pub fn fixtures() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::from("fixtures/programs")];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("src")) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

pub fn load(path: &Path) -> Workspace {
    let bytes = std::fs::read(path).unwrap();
    files::load_program(Some(path), &bytes, Some(Path::new(CONFIG))).unwrap()
}

pub fn run(ws: &Workspace, cal_name: &str, method: compensate::Method) -> ProgramResult {
    let (model, bytes) = cal(cal_name);
    // The model must outlive the result only while compensating.
    let c = Calibrated::new(&model, cal_name, &bytes);
    compensate::compensate_program(
        ws,
        &c,
        &program::Options {
            method,
            parallel: true,
            frames: Vec::new(),
            points: true,
        },
    )
}

/// A zero-error calibration changes nothing: every file of every fixture is written back
/// byte for byte, without a header.
#[test]
fn nominal_calibration_is_the_identity_on_every_fixture() {
    let all = fixtures();
    assert!(all.len() >= 15, "the fixtures are there ({})", all.len());
    for path in all {
        let ws = load(&path);
        let result = run(&ws, "kr30ha-nominal.json", compensate::Method::Iterate);
        assert!(
            !result.rejected,
            "{}: {:?}",
            path.display(),
            result.report.errors
        );
        for f in &result.files {
            let original = ws.get(f.file).file.source();
            assert!(!f.changed, "{} changed", ws.get(f.file).name);
            assert!(
                f.bytes == original,
                "{} not byte-identical",
                ws.get(f.file).name
            );
        }
        assert_eq!(result.report.compensated, 0, "{}", path.display());
    }
}

/// The main job loads programs with their plain stretches streamed (`krl::parse_streaming`)
/// and compensates them window by window: on every fixture, cut into runs and windows as
/// small as possible, that gives exactly what the whole-tree walk gives — every output byte,
/// the report, the diagnostics.
#[test]
fn streamed_runs_give_the_whole_programs_result() {
    let mut windows = 0;
    for path in fixtures() {
        let ws = load(&path);
        let whole = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
        for (min_run, window) in [(1, 1), (1, 2), (3, 7)] {
            let bytes = std::fs::read(&path).unwrap();
            let opts = robopost::krl::StreamOptions { min_run, window };
            let streamed_ws = files::load_program_streaming(
                Some(&path),
                bytes,
                Some(Path::new(CONFIG)),
                Some(opts),
            )
            .unwrap();
            windows += streamed_ws
                .get(streamed_ws.main)
                .file
                .streamed_runs()
                .iter()
                .map(|r| r.windows().len())
                .sum::<usize>();
            let streamed = run(
                &streamed_ws,
                "kr30ha-handset.json",
                compensate::Method::Iterate,
            );
            let at = format!("{} streamed {min_run}/{window}", path.display());
            assert_eq!(streamed.rejected, whole.rejected, "{at}");
            assert_eq!(streamed.target_errors, whole.target_errors, "{at}");
            assert_eq!(streamed.files.len(), whole.files.len(), "{at}");
            for (a, b) in streamed.files.iter().zip(&whole.files) {
                assert_eq!((a.file, a.changed), (b.file, b.changed), "{at}");
                if a.bytes.to_vec() != b.bytes.to_vec() {
                    std::fs::write("/tmp/streamed.out", a.bytes.to_vec()).ok();
                    std::fs::write("/tmp/whole.out", b.bytes.to_vec()).ok();
                    panic!("{at}: file {} differs", a.file);
                }
            }
            let json = |r: &ProgramResult| {
                let mut v = serde_json::to_value(&r.report).unwrap();
                // Warnings and errors come in another order (windows are rewritten first).
                for key in ["warnings", "errors"] {
                    if let Some(list) = v[key].as_array_mut() {
                        list.sort_by_key(|x| x.to_string());
                    }
                }
                v
            };
            if json(&streamed) != json(&whole) {
                let pretty = |v| serde_json::to_string_pretty(&v).unwrap();
                std::fs::write("/tmp/streamed.json", pretty(json(&streamed))).ok();
                std::fs::write("/tmp/whole.json", pretty(json(&whole))).ok();
                panic!("{at}: report differs");
            }
            let diags = |r: &ProgramResult| {
                let mut d: Vec<String> = r.diagnostics.iter().map(|d| d.render()).collect();
                d.sort();
                d
            };
            assert_eq!(diags(&streamed), diags(&whole), "{at}: diagnostics");
        }
    }
    assert!(
        windows > 1000,
        "the fixtures were cut into {windows} windows"
    );
}

/// A main routine called again (here by a routine it calls, until the call depth runs out):
/// its streamed runs are not in the tree, so the main job walks the whole tree instead — the
/// same result as without streaming.
#[test]
fn main_routine_called_again_is_walked_whole() {
    let src = "DEF again( )\r\n$BASE = {X 900, Y 0, Z 600}\r\n$TOOL = {X 0, Y 0, Z 200}\r\nPTP {A1 0, A2 -80, A3 100, A4 0, A5 60, A6 0}\r\nLIN {X 10, Y 0, Z 0, A 0, B 90, C 0}\r\nLIN {X 20, Y 5, Z 0, A 0, B 90, C 0} C_DIS\r\nLIN {X 30, Y 5, Z 10, A 0, B 90, C 0}\r\nonce_more()\r\nEND\r\nDEF once_more( )\r\nLIN {X 0, Y 0, Z 50, A 0, B 90, C 0}\r\nagain()\r\nEND\r\n";
    let opts = robopost::krl::StreamOptions {
        min_run: 1,
        window: 2,
    };
    let streamed_ws =
        files::load_program_streaming(None, src.as_bytes().to_vec(), None, Some(opts)).unwrap();
    assert!(!streamed_ws.get(0).file.streamed_runs().is_empty());
    let whole_ws = files::load_program(None, src.as_bytes(), None).unwrap();
    let streamed = run(
        &streamed_ws,
        "kr30ha-handset.json",
        compensate::Method::Iterate,
    );
    let whole = run(
        &whole_ws,
        "kr30ha-handset.json",
        compensate::Method::Iterate,
    );
    assert!(
        whole.report.targets > 10,
        "the recursion is walked: {}",
        whole.report.targets
    );
    assert_eq!(streamed.report.targets, whole.report.targets);
    assert_eq!(
        streamed.files[0].bytes.to_vec(),
        whole.files[0].bytes.to_vec()
    );
    assert_eq!(
        serde_json::to_value(&streamed.report).unwrap(),
        serde_json::to_value(&whole.report).unwrap()
    );
}

/// Arbitrary aggregates in the styles controllers and CAM systems write: with the nominal
/// calibration nothing changes.
fn number() -> impl Strategy<Value = String> {
    (-1500.0..1500.0f64, 0usize..5, any::<bool>(), any::<bool>()).prop_map(|(v, d, exp, plus)| {
        if exp {
            format!("{:.*E}", d, v)
        } else if plus && v >= 0.0 {
            format!("+{:.*}", d, v)
        } else {
            format!("{:.*}", d, v)
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn nominal_identity_on_generated_programs(
        xs in prop::collection::vec((number(), number(), number(), 0usize..4, any::<bool>()), 1..8),
        crlf in any::<bool>(),
    ) {
        let nl = if crlf { "\r\n" } else { "\n" };
        let mut src = format!("DEF gen( ){nl}$BASE = {{X 900, Y 0, Z 600}}{nl}$TOOL = $NULLFRAME{nl}PTP {{A1 0, A2 -80, A3 100, A4 0, A5 60, A6 0}}{nl}");
        for (x, y, z, style, lin) in &xs {
            let kw = if *lin { "LIN" } else { "PTP" };
            let agg = match style {
                0 => format!("{{X {x},Y {y},Z {z},A 0,B 90,C 0}}"),
                1 => format!("{{ X {x}, Y {y} }}"),
                2 => format!("{{E6POS: X {x}, Z {z}, A 10.5, B 80, C -5}}"),
                _ => format!("{{Z {z}}} C_DIS ; comment {x}"),
            };
            src.push_str(&format!("  {kw} {agg}{nl}"));
        }
        src.push_str("END");
        let ws = files::load_program(None, src.as_bytes(), None).unwrap();
        let result = run(&ws, "kr30ha-nominal.json", compensate::Method::Iterate);
        prop_assert!(!result.rejected);
        for f in &result.files {
            prop_assert!(f.bytes == src.as_bytes());
        }
    }
}

/// The compensated program, simulated again as the controller would run it, commands axes at
/// which the model predicts the original program's TCP poses: checked independently of the
/// compensation's own bookkeeping (re-parsed output, the axis histories of the *compensated*
/// motion, `Model::flange_pose`), to the rounding of the written decimals.
#[test]
fn compensated_paths_reach_the_programmed_poses() {
    let (model, _) = cal("kr30ha-handset.json");
    for name in [
        "paper_path1",
        "paper_path2",
        "paper_path3",
        "vertical_segment",
        "spline/turn_at_spl",
    ] {
        let path = PathBuf::from(format!("fixtures/programs/{name}.src"));
        let ws = load(&path);
        let robot: RobotDescription = model.robot;
        let original = motion::simulate(&ws, &robot, &[]);
        let result = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
        assert!(!result.rejected && result.target_errors == 0, "{name}");
        // Write the outputs to a temporary directory and load them back.
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join(format!("{name}.src"));
        files::write_atomic_pieces(&files::outputs(&ws, &result.files, &out)).unwrap();
        let ws2 = load(&out);
        let again = motion::simulate(&ws2, &robot, &[]);
        assert_eq!(again.stops.len(), original.stops.len());
        // The compensated motion's axis histories (commands and the turning points of the
        // interpolated motions) from the re-simulated program, so every gear play is
        // evaluated where the compensated motion really leaves it.
        let states = motion::program_states(&again);
        let mut worst: f64 = 0.0;
        for (k, (a, o)) in again.stops.iter().zip(&original.stops).enumerate() {
            let axis_state = states[k];
            let tool = again.frames[a.tool as usize].to_isometry();
            let predicted = model.flange_pose(&axis_state) * tool;
            let goal = o.goal.to_isometry();
            let dp = (predicted.translation.vector - goal.translation.vector).norm();
            let dr = (predicted.rotation * goal.rotation.inverse()).angle();
            // XHOME (wrist singular) is compensated in the least-squares sense only, and so is
            // a target where an axis is held still (its output need not move by more than the
            // hold threshold): there the re-simulated error must be the residual the
            // compensation reported.
            let point = &result.report.points[k];
            if point.resolution.starts_with("held") {
                assert!(
                    (dp * 1000.0 - point.residual_um).abs() < 3.0,
                    "{name} target {k} (line {}): {dp} mm, reported {} µm",
                    a.stmt.line,
                    point.residual_um
                );
            } else if robopost::kinematics::singularity(&robot, &a.nominal_axes).is_none() {
                worst = worst.max(dp);
                assert!(
                    dp < 3e-3,
                    "{name} target {k} (line {}): {dp} mm",
                    a.stmt.line
                );
                assert!(dr < 5e-5, "{name} target {k}: {dr} rad");
            }
        }
        assert!(worst > 0.0);
        // And the original program is off by what compensation corrected.
        assert!(result.report.predicted_before.position_um.max > 100.0);
    }
}

/// Snapshots of the unified diff between each fixture and its compensation (reviewed by hand:
/// only numbers of motion targets change, in the original style; one header line).
#[test]
fn diff_snapshots() {
    for path in fixtures() {
        let ws = load(&path);
        let result = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
        let mut text = String::new();
        for f in &result.files {
            if !f.changed {
                continue;
            }
            let old = String::from_utf8_lossy(ws.get(f.file).file.source()).replace('\r', "␍");
            let new = String::from_utf8_lossy(&f.bytes.to_vec()).replace('\r', "␍");
            let name = ws.get(f.file).name.clone();
            let diff = similar::TextDiff::from_lines(&old, &new);
            text += &diff
                .unified_diff()
                .context_radius(1)
                .header(&name, &format!("{name} (compensated)"))
                .to_string();
        }
        // Long CAM programs: the head of the diff is enough to review.
        let lines: Vec<&str> = text.lines().collect();
        if lines.len() > 150 {
            text =
                lines[..150].join("\n") + &format!("\n… {} more diff lines\n", lines.len() - 150);
        }
        for d in &result.diagnostics {
            text += &format!("{:?} {}:{}: {}\n", d.severity, d.file, d.line, d.message);
        }
        text += &format!(
            "{} of {} targets compensated, correction max {:.1} µm, predicted error before max {:.1} µm, after max {:.3} µm\n",
            result.report.compensated,
            result.report.targets,
            result.report.correction.position_um.max,
            result.report.predicted_before.position_um.max,
            result.report.predicted_after.position_um.max
        );
        let snap = path
            .strip_prefix("fixtures/programs")
            .unwrap()
            .display()
            .to_string()
            .replace(['/', '\\'], "__");
        insta::assert_snapshot!(snap, text);
    }
}

fn compensate_text(src: &str, dat: Option<&str>) -> (String, Option<String>, ProgramResult) {
    let dir = tempfile::tempdir().unwrap();
    let sp = dir.path().join("prog.src");
    std::fs::write(&sp, src).unwrap();
    if let Some(d) = dat {
        std::fs::write(dir.path().join("prog.dat"), d).unwrap();
    }
    let ws = load(&sp);
    let r = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
    let main = r.files.iter().find(|f| f.file == ws.main).unwrap();
    let out = String::from_utf8(main.bytes.to_vec()).unwrap();
    let dat_out = ws.main_dat().map(|d| {
        String::from_utf8(r.files.iter().find(|f| f.file == d).unwrap().bytes.to_vec()).unwrap()
    });
    (out, dat_out, r)
}

const HEAD: &str = "DEF prog( )\n$BASE = {X 900, Y -300, Z 500}\n$TOOL = {X 0, Y 0, Z 200}\nPTP {A1 0, A2 -80, A3 100, A4 0, A5 60, A6 0}\n";

/// A `.dat` point reached from two places with opposite rotation directions is split: a copy
/// with a new name is declared next to it and the second place uses it.
#[test]
fn a_point_reached_with_different_directions_is_split() {
    let src = format!("{HEAD}LIN P1\nLIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nLIN {{X 0, Y 400, Z 0}}\nLIN P1\nEND\n");
    let dat =
        "DEFDAT prog\nDECL E6POS P1={X 100.0,Y 200.0,Z 0.0,A 0.0,B 0.0,C 180.0,S 2,T 34}\nENDDAT\n";
    let (out, dat_out, r) = compensate_text(&src, Some(dat));
    let dat_out = dat_out.unwrap();
    assert_eq!(r.report.split_points.len(), 1, "{:?}", r.report.warnings);
    let copy = &r.report.split_points[0].copies[0];
    assert_eq!(copy, "P1_2");
    assert!(
        out.contains("LIN P1\n") && out.contains("LIN P1_2\n"),
        "{out}"
    );
    let lines: Vec<&str> = dat_out.lines().collect();
    let at = lines
        .iter()
        .position(|l| l.contains("DECL E6POS P1="))
        .unwrap();
    assert!(
        lines[at + 1].starts_with("DECL E6POS P1_2={X "),
        "{dat_out}"
    );
    assert_ne!(lines[at], lines[at + 1].replace("P1_2", "P1"));
}

/// A point declared without a value and assigned by a statement in the `.src` (`XHOME` in
/// the paper's paths), reached from two places with different rotation directions, is split
/// too: a declaration and an assignment of the copy follow the original ones. The result is
/// exactly what compensating the program with the point split by hand gives.
#[test]
fn an_assigned_point_reached_with_different_directions_is_split() {
    let program = |split: bool| {
        let (decl2, assign2, second) = if split {
            (
                "DECL E6POS P1_2\n",
                "P1_2 = {X 100.0,Y 200.0,Z 0.0,A 0.0,B 0.0,C 180.0,S 2,T 34}\n",
                "P1_2",
            )
        } else {
            ("", "", "P1")
        };
        format!(
            "DEF prog( )\nDECL E6POS P1\n{decl2}$BASE = {{X 900, Y -300, Z 500}}\n$TOOL = {{X 0, Y 0, Z 200}}\n\
             P1 = {{X 100.0,Y 200.0,Z 0.0,A 0.0,B 0.0,C 180.0,S 2,T 34}}\n{assign2}\
             PTP {{A1 0, A2 -80, A3 100, A4 0, A5 60, A6 0}}\nLIN P1\n\
             LIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nLIN {{X 0, Y 400, Z 0}}\nLIN {second}\nEND\n"
        )
    };
    let (out, _, r) = compensate_text(&program(false), None);
    assert_eq!(r.report.split_points.len(), 1, "{:?}", r.report.warnings);
    assert_eq!(r.report.split_points[0].copies, ["P1_2"]);
    let (by_hand, _, _) = compensate_text(&program(true), None);
    assert_eq!(out, by_hand);
    // And the two uses really got different numbers.
    let assigned: Vec<&str> = out.lines().filter(|l| l.starts_with("P1")).collect();
    assert_eq!(assigned.len(), 2, "{out}");
    assert_ne!(
        assigned[0].replacen("P1 ", "", 1),
        assigned[1].replacen("P1_2 ", "", 1)
    );
}

/// A point of `$config.dat` is shared by every program of the cell, so it is never written
/// there: the program gets a copy under a new name at the end of its own data list, and its
/// use is renamed. The result is exactly what compensating the program with the copy made by
/// hand gives (the by-hand copy is compensated as any `.dat` point); the cell's file is not
/// among the outputs; a module without a data list leaves the use unchanged, with a warning.
#[test]
fn a_config_point_is_compensated_through_a_copy_in_the_programs_data_list() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("$config.dat");
    std::fs::write(
        &config,
        "DEFDAT $CONFIG PUBLIC\nDECL GLOBAL FRAME BASE_DATA[32]\n\
         DECL GLOBAL E6POS XAPPROACH={X 300.0,Y 200.0,Z 0.0,A 0.0,B 0.0,C 180.0,S 2,T 34}\nENDDAT\n",
    )
    .unwrap();
    let compensate_with = |name: &str, src: &str, dat: Option<&str>| {
        let sp = dir.path().join(format!("{name}.src"));
        std::fs::write(&sp, src.replace("prog", name)).unwrap();
        if let Some(d) = dat {
            std::fs::write(
                dir.path().join(format!("{name}.dat")),
                d.replace("prog", name),
            )
            .unwrap();
        }
        let ws = files::load_program(Some(&sp), src.as_bytes(), Some(&config)).unwrap();
        let r = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
        let text = |id| {
            let f = r.files.iter().find(|f| f.file == id).unwrap();
            String::from_utf8(f.bytes.to_vec())
                .unwrap()
                .replace(name, "prog")
        };
        let outs = (text(ws.main), ws.main_dat().map(text));
        assert_eq!(
            r.files.len(),
            ws.files.len() - 1,
            "the cell's file is no output"
        );
        (outs, r)
    };
    // (C 175: the orientation at HEAD's pose is a half turn from C 180, where the sense of
    // the orientation interpolation is a tie.)
    let program = |point: &str| {
        format!("{HEAD}LIN {{X 0, Y 400, Z 0, A 0, B 0, C 175}}\nLIN {point}\nLIN {{X 0, Y 400, Z 0}}\nEND\n")
    };
    let ((src, dat), r) = compensate_with(
        "mod_auto",
        &program("XAPPROACH"),
        Some("DEFDAT prog\nDECL E6POS XP1={X 1.0,Y 2.0,Z 3.0,A 0.0,B 0.0,C 180.0}\nENDDAT\n"),
    );
    assert_eq!(r.target_errors, 0, "{:?}", r.report.errors);
    assert!(r.report.warnings.is_empty(), "{:?}", r.report.warnings);
    assert_eq!(r.report.split_points[0].copies, ["XAPPROACH_2"]);
    let ((src_hand, dat_hand), _) = compensate_with(
        "mod_byhand",
        &program("XAPPROACH_2"),
        Some("DEFDAT prog\nDECL E6POS XP1={X 1.0,Y 2.0,Z 3.0,A 0.0,B 0.0,C 180.0}\n\
              DECL E6POS XAPPROACH_2={X 300.0,Y 200.0,Z 0.0,A 0.0,B 0.0,C 180.0,S 2,T 34}\nENDDAT\n"),
    );
    assert_eq!(src, src_hand);
    assert_eq!(dat, dat_hand);
    // The copy really carries a correction.
    let copy = dat.unwrap();
    assert!(!copy.contains("{X 300.0,Y 200.0,Z 0.0"), "{copy}");
    // Without a data list of its own, the module cannot hold a copy.
    let ((src, dat), r) = compensate_with("mod_bare", &program("XAPPROACH"), None);
    assert!(dat.is_none());
    assert!(src.contains("\nLIN XAPPROACH\n"), "{src}");
    assert!(
        r.report.warnings.iter().any(|w| w.contains("$config.dat")),
        "{:?}",
        r.report.warnings
    );
}

/// A straight motion whose orientation turns by exactly 180° (HEAD's pose `A 180, B 10,
/// C 180` to `A 0, B 0, C 180`) may turn either way: warned with its line; 5° less is not.
#[test]
fn a_half_turn_of_the_orientation_is_warned() {
    let half = |c: &str| {
        let src = format!("{HEAD}LIN {{X 300, Y 200, Z 0, A 0, B 0, C {c}}}\nEND\n");
        let (_, _, r) = compensate_text(&src, None);
        r.report
            .warnings
            .iter()
            .filter(|w| w.contains("turns by 180°") && w.contains("prog.src:5"))
            .count()
    };
    assert_eq!(half("180"), 1);
    assert_eq!(half("175"), 0);
}

/// An orientation type the walker does not simulate (`#CONSTANT`, `#JOINT`) is warned at every
/// Cartesian motion it applies to, however it is set: an assignment, a `WITH` clause, or an
/// inline form's motion data applied by `BAS(#CP_PARAMS…)`; `#VAR` (the default) is not.
#[test]
fn an_orientation_type_not_simulated_is_warned() {
    let warned = |src: &str, dat: Option<&str>| {
        let (_, _, r) = compensate_text(src, dat);
        let mut lines: Vec<String> = r
            .report
            .warnings
            .iter()
            .filter(|w| w.contains("$ORI_TYPE #"))
            .map(|w| {
                w.split(": ")
                    .next()
                    .unwrap()
                    .rsplit(':')
                    .nth(1)
                    .unwrap()
                    .to_string()
            })
            .collect();
        lines.sort();
        lines
    };
    let lin = "LIN {X 300, Y 200, Z 0, A 0, B 0, C 175}";
    let src = format!(
        "{HEAD}$ORI_TYPE = #CONSTANT\n{lin}\nPTP {{A1 0, A2 -80, A3 100, A4 0, A5 60, A6 0}}\n\
         $ORI_TYPE = #VAR\n{lin}\n{lin} WITH $ORI_TYPE = #JOINT\n{lin}\nEND\n"
    );
    // Lines 6 (assigned) and 10 (WITH, for that motion only); not the PTP, not #VAR.
    assert_eq!(warned(&src, None), ["10", "6"]);
    let with_ldat = |ori: &str| {
        let src = format!("{HEAD}LDAT_ACT = LCPDAT1\nBAS(#CP_PARAMS, 2)\n{lin}\nEND\n");
        let dat = format!(
            "DEFDAT prog\nDECL LDAT LCPDAT1={{VEL 2.0,ACC 100.0,APO_DIST 100.0,ORI_TYP {ori},CIRC_TYP #BASE}}\nENDDAT\n"
        );
        warned(&src, Some(&dat))
    };
    assert_eq!(with_ldat("#CONSTANT"), ["7"]);
    assert!(with_ldat("#VAR").is_empty());
}

/// A partial aggregate of a compensated target is completed: otherwise the missing
/// components would come from the compensated previous position.
#[test]
fn partial_aggregates_are_completed() {
    let src = format!("{HEAD}LIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nLIN {{Z -50}}\nEND\n");
    let (out, _, r) = compensate_text(&src, None);
    assert_eq!(r.target_errors, 0);
    let line = out.lines().find(|l| l.contains("Z -5")).unwrap();
    for name in ["X ", "Y ", "A ", "B ", "C "] {
        assert!(
            line.contains(&format!("{{{name}")) || line.contains(&format!(", {name}")),
            "{line}"
        );
    }
    // X, Y before Z, A..C after it, in the file's separator style.
    assert!(line.starts_with("LIN {X "), "{line}");
}

/// `LIN_REL` is rewritten relative to the compensated previous command.
#[test]
fn relative_motions_are_rewritten_relative_to_the_compensated_start() {
    let src = format!("{HEAD}LIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nLIN_REL {{Z -40}} #BASE\nLIN_REL {{X 10}} #TOOL\nEND\n");
    let (out, _, r) = compensate_text(&src, None);
    assert_eq!(r.target_errors, 0, "{:?}", r.report.errors);
    let rel: Vec<&str> = out.lines().filter(|l| l.contains("_REL")).collect();
    assert_eq!(rel.len(), 2);
    assert!(
        rel[0].contains("Z -39.") || rel[0].contains("Z -40."),
        "{}",
        rel[0]
    );
    assert!(rel[0].contains("#BASE") && rel[1].contains("#TOOL"));
}

#[test]
fn already_compensated_files_are_refused() {
    let src = format!("{HEAD}LIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nEND\n");
    let (out, _, _) = compensate_text(&src, None);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("again.src");
    std::fs::write(&p, &out).unwrap();
    let ws = load(&p);
    let r = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
    assert!(r.rejected);
    assert!(
        r.report.errors[0].contains("already compensated"),
        "{:?}",
        r.report.errors
    );
}

#[test]
fn external_tcp_is_refused_naming_the_line() {
    let src = format!("{HEAD}$IPO_MODE = #TCP\nLIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nEND\n");
    let (_, _, r) = compensate_text(&src, None);
    assert!(r.rejected);
    let e = r
        .diagnostics
        .iter()
        .find(|d| d.message.contains("#TCP"))
        .unwrap();
    assert_eq!(e.line, 5);
}

#[test]
fn an_unknown_frame_is_an_error_naming_its_line() {
    let src = "DEF prog( )\n$TOOL = $NULLFRAME\n$BASE = BASE_DATA[9]\nPTP {A1 0, A2 -80, A3 100, A4 0, A5 60, A6 0}\nLIN {X 1000, Y 0, Z 800, A 0, B 0, C 180}\nEND\n";
    let (_, _, r) = compensate_text(src, None);
    assert!(r.rejected);
    let e = r
        .diagnostics
        .iter()
        .find(|d| d.message.contains("BASE_DATA[9]"))
        .unwrap();
    assert_eq!((e.line, e.col), (3, 1));
    assert!(e.render().contains("--config"));
}

/// A branch on an input is reported with its line; the motions inside are left as written,
/// those before and after are compensated.
#[test]
fn run_time_branches_leave_their_motions_unchanged() {
    let src = format!("{HEAD}LIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nIF $IN[3] THEN\n  LIN {{X 300, Y 100, Z 0, A 0, B 0, C 180}}\nENDIF\nLIN {{X 200, Y 100, Z 0, A 0, B 0, C 180}}\nEND\n");
    let (out, _, r) = compensate_text(&src, None);
    let w = r
        .diagnostics
        .iter()
        .find(|d| d.message.contains("$IN[3]"))
        .unwrap();
    assert_eq!(w.line, 6);
    assert!(w.message.contains("line 7"));
    assert!(out.contains("  LIN {X 300, Y 100, Z 0, A 0, B 0, C 180}\n"));
    assert!(!out.contains("LIN {X 200, Y 100, Z 0, A 0, B 0, C 180}"));
}

/// Programs split over numbered modules (RoboDK) are followed into the modules, which are
/// compensated too.
#[test]
fn called_modules_are_compensated() {
    let ws = load(Path::new("fixtures/programs/robodk/drill_cell.src"));
    let r = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
    let changed: Vec<String> = r
        .files
        .iter()
        .filter(|f| f.changed)
        .map(|f| ws.get(f.file).name.clone())
        .collect();
    assert!(
        changed.iter().any(|n| n.ends_with("drill_cell1.src")),
        "{changed:?}"
    );
    assert!(
        changed.iter().any(|n| n.ends_with("drill_cell3.src")),
        "{changed:?}"
    );
}

/// One step leaves more error than the iteration (its residual is second order).
#[test]
fn one_step_versus_iteration() {
    let ws = load(Path::new("fixtures/programs/paper_path1.src"));
    let it = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
    let one = run(&ws, "kr30ha-handset.json", compensate::Method::OneStep);
    // Means over the targets compensated exactly: XHOME (wrist singular, lines 9 and 61) and
    // targets with an axis held still keep a least-squares residual in both.
    let exact = |p: &&robopost::compensate::program::PointReport| {
        !p.resolution.starts_with("held") && p.line != 9 && p.line != 61
    };
    let mean = |r: &ProgramResult, f: fn(&robopost::compensate::program::PointReport) -> f64| {
        let v: Vec<f64> = r.report.points.iter().filter(exact).map(f).collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let after = |r: &ProgramResult| mean(r, |p| p.residual_um);
    let before = mean(&one, |p| p.before_um);
    assert!(after(&it) < 0.02, "{}", after(&it));
    assert!(
        after(&one) > 2.0 * after(&it),
        "{} {}",
        after(&one),
        after(&it)
    );
    assert!(after(&one) < 0.05 * before, "{} of {before}", after(&one));
    // Point by point, the iteration meets 0.1 µm wherever the pose is regular.
    for p in &it.report.points {
        if exact(&p) {
            assert!(p.residual_um < 0.1, "line {}: {}", p.line, p.residual_um);
        }
    }
}
