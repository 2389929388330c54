//! The KRL pipeline: simulate, compensate, rewrite — on the fixtures and on small programs
//! written here.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use robopost::calibration;
use robopost::compensate::{self};
use robopost::kinematics::{Payload, RobotDescription};
use robopost::krl::interpret::Workspace;
use robopost::krl::job::{files, program, Calibrated, ProgramResult};
use robopost::model::{AxisState, Model};
use robopost::motion::{self};

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
    // `modules`: a module whose name holds its path (a generator's), a milling program.
    let mut stack = vec![
        PathBuf::from("fixtures/programs"),
        PathBuf::from("fixtures/modules"),
    ];
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
    robopost::krl::job::compensate_program(
        ws,
        &c,
        &program::Options {
            method,
            parallel: true,
            stretching: robopost::compensate::sequence::Stretching::DEFAULT,
            frames: Vec::new(),
            points: true,
            assumptions: Vec::new(),
            // The points of every fixture rewritten, taught ones too: these tests are of
            // the walk and the rewrite (`taken.rs` tests which points `auto` leaves).
            taken: robopost::krl::job::Taken::Offline,
            uncertainty: None,
        },
    )
}

/// A zero-error calibration changes nothing: every file of every fixture is written back
/// byte for byte, without a header. (A fixture whose motions all go to names declared
/// nowhere, `language/no_header.src`, is refused as nothing can be compensated, its files
/// kept as they are.)
#[test]
fn nominal_calibration_is_the_identity_on_every_fixture() {
    let all = fixtures();
    assert!(all.len() >= 15, "the fixtures are there ({})", all.len());
    for path in all {
        let ws = load(&path);
        let result = run(&ws, "kr30ha-nominal.json", compensate::Method::Iterate);
        let nothing_known = result.report.errors.len() == 1
            && result.report.errors[0].contains("no target could be compensated");
        assert!(
            !result.rejected || nothing_known,
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
    let mut checked = 0;
    let mut violations: Vec<String> = Vec::new();
    for path in fixtures() {
        let name = path.display().to_string();
        let ws = load(&path);
        let robot: RobotDescription = model.robot;
        let original = robopost::krl::interpret::simulate(&ws, &robot, &[]);
        let result = run(&ws, "kr30ha-handset.json", compensate::Method::Iterate);
        if original.rejected() || original.unreachable > 0 || result.report.compensated == 0 {
            // The parser's fixtures (encodings, line endings, language coverage) hold targets
            // the arm cannot reach or whose start is unknown: nothing to re-simulate.
            assert!(
                ["encodings", "endings", "language"]
                    .iter()
                    .any(|d| name.contains(&format!("/{d}/"))),
                "{name}: unreachable targets"
            );
            continue;
        }
        checked += 1;
        assert!(!result.rejected && result.target_errors == 0, "{name}");
        // Write the outputs to a temporary directory and load them back.
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join(path.file_name().unwrap());
        files::write_atomic_pieces(&files::outputs(&ws, &result.files, &out)).unwrap();
        let ws2 = load(&out);
        let again = robopost::krl::interpret::simulate(&ws2, &robot, &[]);
        assert_eq!(again.stops.len(), original.stops.len());
        // The compensated motion's axis histories (commands and the turning points of the
        // interpolated motions) from the re-simulated program, so every gear play is
        // evaluated where the compensated motion really leaves it.
        let states = motion::program_states(&again.stops, &again.arcs);
        // Points written for their last use only: (name, line of that use).
        let last_use: Vec<(String, usize)> = result
            .diagnostics
            .iter()
            .filter_map(|d| {
                let (_, after) = d
                    .message
                    .split_once("it is written for its last use (line ")?;
                let line = after.split(')').next()?.parse().ok()?;
                let name = d.source_line.split('=').next()?.trim();
                let name = name.rsplit(' ').next()?.to_string();
                Some((name, line))
            })
            .collect();
        let mut written_for_another_use = 0;
        let mut unsettled_targets = 0;
        let mut worst: f64 = 0.0;
        for (k, (a, o)) in again.stops.iter().zip(&original.stops).enumerate() {
            let axis_state = states[k];
            let tool = again.frames[a.tool as usize].to_isometry();
            let predicted = model.flange_pose(&axis_state).to_isometry() * tool;
            let goal = o.goal.to_isometry();
            let dp = (predicted.translation.vector - goal.translation.vector).norm();
            let dr = (predicted.rotation * goal.rotation.inverse()).angle();
            // XHOME (wrist singular) is compensated in the least-squares sense only, and so is
            // a target where an axis is held still (its output need not move by more than the
            // hold threshold): there the re-simulated error must be the residual the
            // compensation reported.
            let point = &result.report.points[k];
            // A point reached with different directions where it cannot be split (an array
            // element, `CNC1[1]`) is written for its last use and warned: its other uses are
            // off by their difference, reported, not silent.
            let statement = if last_use.is_empty() {
                String::new()
            } else {
                let source = ws.get(o.handle.file).file.source();
                let text = String::from_utf8_lossy(source);
                text.lines()
                    .nth(o.handle.stmt.line as usize - 1)
                    .unwrap_or("")
                    .to_string()
            };
            let shared = last_use.iter().find(|(point, _)| {
                statement.contains(point.as_str())
                    && !statement[statement.find(point.as_str()).unwrap() + point.len()..]
                        .starts_with(|c: char| c.is_alphanumeric() || c == '_')
            });
            if let Some((_, last)) = shared {
                if o.handle.stmt.line as usize != *last {
                    written_for_another_use += 1;
                    continue;
                }
            }
            // A target the settling could not bring to the solver's tolerance (an axis
            // reversing inside its play on both sides) reports its residual: it must be
            // the one the re-simulation finds, and such targets stay rare.
            let unsettled = point.compensated && point.residual_um > 1.0;
            // (A wrist-singular target, XHOME, is reached in the least-squares sense only.)
            let singular = robopost::kinematics::singularity(&robot, &a.nominal_axes).is_some();
            if unsettled && !point.resolution.starts_with("held") && !singular {
                unsettled_targets += 1;
            }
            if point.resolution.starts_with("held") || unsettled {
                assert!(
                    (dp * 1000.0 - point.residual_um).abs() < 3.0,
                    "{name} target {k} (line {}): {dp} mm, reported {} µm",
                    a.handle.stmt.line,
                    point.residual_um
                );
            } else if point.compensated
                && point.role == "target"
                && robopost::kinematics::singularity(&robot, &a.nominal_axes).is_none()
            {
                worst = worst.max(dp);
                // The written decimals (at least 3 in mm, 4 in degrees), on top of the solver's
                // tolerance: a Cartesian target half a unit in X, Y, Z and in A, B, C; an axis
                // target half a unit of every axis, each moving the TCP by its lever.
                let half_mm = 0.5e-3;
                let half_deg = 0.5e-4;
                let (bound_mm, bound_rad) = if a.programmed.is_axes() {
                    let bare = Model::new(robot, Payload::default(), nalgebra::Vector3::zeros());
                    let tcp = |axes: [f64; 6]| {
                        (bare.flange_pose(&AxisState::new(axes)).to_isometry() * tool)
                            .translation
                            .vector
                    };
                    let lever: f64 = (0..6)
                        .map(|j| {
                            let (mut up, mut down) = (a.nominal_axes.0, a.nominal_axes.0);
                            up[j] += 1e-3;
                            down[j] -= 1e-3;
                            (tcp(up) - tcp(down)).norm() / 2e-3
                        })
                        .sum();
                    (lever * half_deg, 6.0 * half_deg.to_radians())
                } else {
                    (3f64.sqrt() * half_mm, 3.0 * half_deg.to_radians())
                };
                let bound_mm = bound_mm + robopost::compensate::TOL_POSITION_MM;
                let bound_rad = bound_rad + robopost::compensate::TOL_ROTATION_RAD;
                if dp >= bound_mm || dr >= bound_rad {
                    violations.push(format!("{name} target {k}: pose"));
                    eprintln!(
                        "{name} target {k} (line {}): {:.3} µm (bound {:.3}), {dr:.2e} rad \
                         (bound {bound_rad:.2e})",
                        a.handle.stmt.line,
                        dp * 1e3,
                        bound_mm * 1e3
                    );
                }
            }
        }
        assert!(
            written_for_another_use <= last_use.len() * 4,
            "{name}: {written_for_another_use} uses skipped for {last_use:?}"
        );
        assert!(worst > 0.0, "{name}: no target checked");
        assert!(
            unsettled_targets <= 1,
            "{name}: {unsettled_targets} targets left unsettled"
        );
        // And the original program is off by what compensation corrected.
        assert!(result.report.predicted_before.position_um.max > 100.0);
    }
    assert!(checked >= 15, "{checked} fixtures re-simulated");
    // Known disagreements, each a robopost limitation reported to the lead (not silenced: if
    // one goes away or a new one appears, this fails and the list is updated):
    // - glue_lid's `SLIN_REL {X 10}` loop starts at `start_pos : lid_offset`, a computed target
    //   left unchanged (warned): the relative targets inherit its uncompensated error, yet
    //   the report counts them compensated;
    // - inside spline blocks the compensation's arrival direction of an axis can differ from
    //   the re-simulated compensated motion's (glue_lid A4, weld_seam A6), and after
    //   `SPTP $AXIS_ACT` (a computed target) directions are unknown to the re-simulation.
    let known = [
        "fixtures/programs/spline/glue_lid.src target 11: pose",
        "fixtures/programs/spline/glue_lid.src target 12: pose",
        "fixtures/programs/spline/glue_lid.src target 13: pose",
    ];
    violations.sort();
    let mut known: Vec<String> = known.iter().map(|s| s.to_string()).collect();
    known.sort();
    assert_eq!(violations, known, "re-simulated compensated fixtures");
}

/// Every digit of a number on an added line (`+…`, but the header) as `#`: the snapshots show which lines
/// change and in which style (the count of decimals, the spacing), not the compensated values,
/// which no reader can check by eye — `compensated_paths_reach_the_programmed_poses`
/// re-simulates every fixture and checks the values instead.
fn mask_added_numbers(diff: &str) -> String {
    diff.lines()
        .map(|line| {
            let header = line.contains(robopost::krl::job::program::HEADER_MARK);
            if !line.starts_with('+') || line.starts_with("+++") || header {
                return line.to_string();
            }
            // A number starts at a digit not glued to a name (`A1`, `E6AXIS`, `XHOME_2`).
            let mut out = String::new();
            let mut previous = ' ';
            let mut in_number = false;
            for c in line.chars() {
                let starts = c.is_ascii_digit() && !(previous.is_alphanumeric() || previous == '_');
                in_number = if in_number {
                    c.is_ascii_digit() || c == '.'
                } else {
                    starts
                };
                out.push(if in_number && c.is_ascii_digit() {
                    '#'
                } else {
                    c
                });
                previous = c;
            }
            out
        })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

/// Snapshots of the unified diff between each fixture and its compensation, numbers masked
/// (reviewed by hand: only numbers of motion targets change, in the original style; one header
/// line).
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
        let mut text = mask_added_numbers(&text);
        // Long CAM programs: the head of the diff is enough to review.
        let lines: Vec<&str> = text.lines().collect();
        if lines.len() > 150 {
            text =
                lines[..150].join("\n") + &format!("\n… {} more diff lines\n", lines.len() - 150);
        }
        for d in &result.diagnostics {
            text += &format!("{:?} {}:{}: {}\n", d.severity, d.file, d.line, d.message);
        }
        // The counts; the sizes are checked by re-simulation, not by a snapshot.
        text += &format!(
            "{} of {} targets compensated\n",
            result.report.compensated, result.report.targets,
        );
        let snap = path
            .strip_prefix("fixtures/programs")
            .or_else(|_| path.strip_prefix("fixtures"))
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

/// A stop says what its target programs: an axis target's angles (a relative one's added to
/// the start's), a Cartesian target's pose in the base, completed from the start where
/// components are missing.
#[test]
fn programmed_values_are_axis_angles_or_a_pose() {
    use robopost::kinematics::Pose;
    use robopost::motion::Programmed;
    let src = format!(
        "{HEAD}LIN {{X 300, Y 200, Z 0, A 0, B 0, C 180}}\nLIN {{Z -50}}\nPTP_REL {{A1 5}}\nEND\n"
    );
    let ws = files::load_program(None, src.as_bytes(), None).expect("loads");
    let sim = robopost::krl::interpret::simulate(&ws, &RobotDescription::kr30ha(), &[]);
    assert_eq!(sim.stops.len(), 4);
    let home = [0.0, -80.0, 100.0, 0.0, 60.0, 0.0];
    assert_eq!(sim.stops[0].programmed, Programmed::Axes(home.into()));
    assert_eq!(sim.stops[0].nominal_axes, home);
    let written = Pose {
        x: 300.0,
        y: 200.0,
        z: 0.0,
        a: 0.0,
        b: 0.0,
        c: 180.0,
    };
    assert_eq!(sim.stops[1].programmed, Programmed::Pose(written));
    let Programmed::Pose(completed) = sim.stops[2].programmed else {
        panic!("a Cartesian target: {:?}", sim.stops[2].programmed);
    };
    let want = Pose {
        z: -50.0,
        ..written
    };
    for (got, want) in completed.to_array().iter().zip(want.to_array()) {
        assert!((got - want).abs() < 1e-9, "{completed:?}");
    }
    let mut moved: [f64; 6] = sim.stops[2].nominal_axes.into();
    moved[0] += 5.0;
    assert_eq!(sim.stops[3].programmed, Programmed::Axes(moved.into()));
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
    // Targets at a singularity (here XHOME, A5 = 0, at the start and the end) are compensated
    // in the least-squares sense only, and so is a target with an axis held to end a backlash
    // oscillation ("held…"): both keep a residual whatever the method. Found by their nominal
    // axes and the report's resolution, not by line.
    let (model, _) = cal("kr30ha-handset.json");
    let sim = robopost::krl::interpret::simulate(&ws, &model.robot, &[]);
    assert_eq!(sim.stops.len(), it.report.points.len());
    let exact: Vec<bool> = sim
        .stops
        .iter()
        .zip(&it.report.points)
        .map(|(s, p)| {
            assert_eq!(s.handle.stmt.line, p.line);
            !p.resolution.starts_with("held")
                && robopost::kinematics::singularity(&model.robot, &s.nominal_axes).is_none()
        })
        .collect();
    let excluded: Vec<u32> = it
        .report
        .points
        .iter()
        .zip(&exact)
        .filter(|(_, e)| !**e)
        .map(|(p, _)| p.line)
        .collect();
    assert!(
        excluded.len() * 4 < exact.len(),
        "three quarters of the targets are checked: excluded lines {excluded:?}"
    );
    let mean = |r: &ProgramResult, f: fn(&robopost::krl::job::program::PointReport) -> f64| {
        let v: Vec<f64> = r
            .report
            .points
            .iter()
            .zip(&exact)
            .filter(|(_, e)| **e)
            .map(|(p, _)| f(p))
            .collect();
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
    // Point by point, the iteration meets the solver's tolerance wherever the pose is regular.
    for (p, e) in it.report.points.iter().zip(&exact) {
        if *e {
            assert!(
                p.residual_um < robopost::compensate::TOL_POSITION_MM * 1e3,
                "line {}: {}",
                p.line,
                p.residual_um
            );
        }
    }
}

/// A rippled LIN path for the stretches' proptest: along X, Z stepping by `ripple` (µm, signed,
/// per point), so that the arm's axes turn round inside and outside their plays at random.
fn rippled_program(ripple: &[i32], reach: f64) -> String {
    let mut src = String::from(
        "DEF ripple( )\n$BASE = {X 900, Y -200, Z 500}\n$TOOL = {X 0, Y 0, Z 200, A 0, B -90, C 0}\n\
         PTP {A1 -10, A2 -80, A3 100, A4 0, A5 60, A6 0}\n",
    );
    let mut z = 0.0;
    for (k, dz) in ripple.iter().enumerate() {
        z += *dz as f64 * 1e-3;
        let x = reach * k as f64;
        src.push_str(&format!(
            "LIN {{X {x:.3},Y 0.000,Z {z:.3},A 0.000,B 90.000,C 0.000}} C_DIS\n"
        ));
    }
    src.push_str("END\n");
    src
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// The re-check walked in stretches beside each other (guessed walks, adopted where they
    /// meet the real one) gives, to the bit, what one sequential walk gives: the written
    /// program and the report — for random ripples inside and outside the plays, random
    /// stretch lengths, warm-ups and rounds, with the identified and the hand-set calibration.
    #[test]
    fn stretches_give_the_sequential_walk_to_the_bit(
        ripple in prop::collection::vec(prop_oneof![
            -60i32..60,            // inside the play, mostly
            -2000i32..2000,        // outside it
        ], 40..240),
        reach in prop_oneof![Just(0.02f64), Just(0.1), Just(1.0)],
        targets in 3usize..60,
        warm_up in 0usize..8,
        per_round in 2usize..6,
        identified in any::<bool>(),
    ) {
        let src = rippled_program(&ripple, reach);
        let ws = files::load_program(None, src.as_bytes(), None).unwrap();
        let cal_name = if identified { "kr30ha-example.json" } else { "kr30ha-handset.json" };
        let (model, bytes) = cal(cal_name);
        let c = Calibrated::new(&model, cal_name, &bytes);
        let with = |parallel: bool, stretching| {
            robopost::krl::job::compensate_program(&ws, &c, &program::Options {
                method: compensate::Method::Iterate,
                parallel,
                stretching,
                points: true,
                ..program::Options::default()
            })
        };
        let stretching = robopost::compensate::sequence::Stretching { targets, warm_up, per_round };
        let sequential = with(false, stretching);
        let stretched = with(true, stretching);
        prop_assert_eq!(sequential.rejected, stretched.rejected);
        prop_assert_eq!(sequential.files.len(), stretched.files.len());
        for (a, b) in sequential.files.iter().zip(&stretched.files) {
            prop_assert!(a.bytes.to_vec() == b.bytes.to_vec(), "the written program differs");
        }
        let json = |r: &ProgramResult| serde_json::to_string(&r.report).unwrap();
        prop_assert_eq!(json(&sequential), json(&stretched));
        // The path does turn the axes round inside their plays (the case the guesses are for).
        prop_assert!(sequential.report.compensated > 0);
    }
}
