//! Programs in the robot's cell (`fixtures/cells/kr16_line`, a KR 16-2 backup written for these
//! tests after what real cells hold): the cell as context (`$config.dat`, public data lists,
//! modules anywhere, machine data), and the KRL semantics real programs use — one fixture
//! program per item of issue 20 (`KRC/R1/Program/Items/itemNN_*.src`). Expected values are
//! worked out by hand from the fixtures' numbers (frames composed in the test), not read back
//! from robopost.

use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::{Rotation3, Vector3};
use robopost::calibration;
use robopost::compensate::{self};
use robopost::diagnostic::Severity;
use robopost::kinematics::RobotDescription;
use robopost::krl::interpret::{Cell, Simulation, Workspace};
use robopost::krl::job::{files, program, Calibrated, ProgramResult};
use robopost::model::Model;

pub const CELL: &str = "fixtures/cells/kr16_line";

fn items(name: &str) -> PathBuf {
    Path::new(CELL).join("KRC/R1/Program/Items").join(name)
}

/// The hand-set error model of the KR 30 HA on the KR 16-2's geometry: a calibration of the
/// cell's robot (written to `dir`).
pub fn kr16_calibration(dir: &Path) -> PathBuf {
    let mut cal: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string("calibrations/kr30ha-handset.json").unwrap())
            .unwrap();
    let kr16: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string("calibrations/kr16-2-nominal.json").unwrap())
            .unwrap();
    cal["robot"] = kr16["robot"].clone();
    let path = dir.join("kr16-handset.json");
    std::fs::write(&path, serde_json::to_string_pretty(&cal).unwrap()).unwrap();
    path
}

fn model(path: &Path) -> (Model, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let m = calibration::parse(&String::from_utf8_lossy(&bytes), path)
        .unwrap()
        .model();
    (m, bytes)
}

fn cell() -> Cell {
    Cell::scan(Some(Path::new(CELL)), &[]).unwrap()
}

fn load(path: &Path, cell: &Cell) -> Workspace {
    let bytes = std::fs::read(path).unwrap();
    files::load_program_in(Some(path), bytes, Some(cell), None).unwrap()
}

fn kr16() -> RobotDescription {
    calibration::robots::by_name("KR 16")
        .unwrap()
        .calibration()
        .model_ref()
        .robot
}

fn simulate(ws: &Workspace) -> Simulation<'_> {
    robopost::krl::interpret::simulate(ws, &kr16(), &[])
}

fn compensate_with(ws: &Workspace, model: &Model, bytes: &[u8]) -> ProgramResult {
    let c = Calibrated::new(model, "kr16-handset.json", bytes);
    robopost::krl::job::compensate_program(
        ws,
        &c,
        &program::Options {
            method: compensate::Method::Iterate,
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

fn messages(sim: &Simulation) -> Vec<String> {
    sim.diagnostics
        .iter()
        .map(|d| format!("{}:{}: {}", d.line, d.severity, d.message))
        .collect()
}

/// World position of a point given in a base `X Y Z A` (B = C = 0), by hand: the base's
/// rotation about Z applied to the point, then its origin added.
fn in_base(base: [f64; 4], p: [f64; 3]) -> Vector3<f64> {
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), base[3].to_radians());
    Vector3::new(base[0], base[1], base[2]) + r * Vector3::new(p[0], p[1], p[2])
}

/// `BASE_DATA[1]` and `[2]` of the cell's `$config.dat`.
const BASE1: [f64; 4] = [1200.0, -300.0, 400.0, 90.0];
const BASE2: [f64; 4] = [900.0, 450.0, 250.0, -30.0];

fn close(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
    (a - b).norm() < 1e-9
}

#[test]
fn the_cell_finds_config_data_modules_and_machine_data() {
    let c = cell();
    let root = Path::new(CELL);
    assert_eq!(
        c.config.as_deref(),
        Some(root.join("KRC/R1/System/$config.dat").as_path())
    );
    // The robot's machine data, not the controller's (STEU/Mada).
    assert_eq!(
        c.machine.as_deref(),
        Some(root.join("KRC/R1/Mada/$machine.dat").as_path())
    );
    assert!(c
        .data
        .contains(&root.join("KRC/R1/Program/Lib/cell_data.dat")));
    // A module by the routines it defines, whatever its file name.
    let lib = root.join("KRC/R1/Program/Lib/robot_lib.src");
    for r in ["SETBASETOOL", "LIFTED", "BOXPLACE", "ROBOT_LIB"] {
        assert_eq!(c.routines[r.as_bytes()], vec![lib.clone()], "{r}");
    }
    // The machine data describe the KR 16-2 of the shipped description.
    let (name, robot) =
        robopost::krl::interpret::cell::machine_robot(c.machine.as_deref().unwrap()).unwrap();
    assert_eq!(name, "KR16_2 C4 FLR ZH16");
    assert_eq!(robot.links, kr16().links);
    assert_eq!(robot.limits_deg, kr16().limits_deg);
}

#[test]
fn a_palletiser_s_machine_data_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(Path::new(CELL).join("KRC/R1/Mada/$machine.dat"))
        .unwrap()
        .replace("#KR16_2 C4 FLR ZH16", "#KR120R3200PA C4 FLR")
        .replace(
            "$DH_5={DHART_A 0.0,DHART_D 0.0",
            "$DH_5={DHART_A 265.0,DHART_D 0.0",
        );
    let path = dir.path().join("$machine.dat");
    std::fs::write(&path, text).unwrap();
    let err = robopost::krl::interpret::cell::machine_robot(&path).unwrap_err();
    match &err {
        robopost::krl::interpret::cell::MachineDataError::NotModelled { robot, why, .. } => {
            assert_eq!(robot, "KR120R3200PA C4 FLR");
            assert!(why.contains("offset ($DH_5 = A 265"), "{why}");
        }
        other => panic!("{other:?}"),
    }
    let text = err.to_string();
    assert!(
        text.contains("KR120R3200PA") && text.contains("offset") && text.contains("palletiser"),
        "{text}"
    );
}

/// Item 1: `:IN` parameters keep their value through the body's declarations, `:OUT` ones go
/// back to the caller's variable.
#[test]
fn item01_routine_parameters_in_and_out() {
    let c = cell();
    let ws = load(&items("item01_params.src"), &c);
    let sim = simulate(&ws);
    assert!(!sim.rejected(), "{:?}", messages(&sim));
    let drops: Vec<_> = sim
        .stops
        .iter()
        .filter(|s| s.handle.stmt.line == 22)
        .collect();
    assert_eq!(drops.len(), 6, "{:?}", messages(&sim));
    let mut k = 0;
    for row in 1..=2 {
        for col in 1..=3 {
            // xDropBase = {X 100, Y 0, Z 80} shifted by the column and row pitches.
            let p = [
                100.0 + (col - 1) as f64 * 120.0,
                (row - 1) as f64 * 150.0,
                80.0,
            ];
            let want = in_base(BASE1, p);
            assert!(close(&drops[k].goal.position, &want), "row {row} col {col}");
            // Computed in the program: the walk knows it, the rewrite leaves it.
            assert!(!drops[k].compensable);
            k += 1;
        }
    }
    assert!(!messages(&sim).iter().any(|m| m.contains("no value")));
}

/// Item 2: members of array elements and of points are assigned (no longer ignored): the
/// robot goes where the program says, and the `.dat` point is not rewritten for a pose the
/// robot never reaches.
#[test]
fn item02_member_assignments_move_the_target() {
    let c = cell();
    let ws = load(&items("item02_members.src"), &c);
    let sim = simulate(&ws);
    let at = |line: u32| {
        sim.stops
            .iter()
            .find(|s| s.handle.stmt.line == line)
            .unwrap()
    };
    // xPick[2] = {X 150, Y 190, Z 60} raised by 40.
    assert!(close(
        &at(21).goal.position,
        &in_base(BASE1, [150.0, 190.0, 100.0])
    ));
    assert!(!at(21).compensable);
    // xAbove = xPick[3] with Z 200.
    assert!(close(
        &at(24).goal.position,
        &in_base(BASE1, [300.0, 40.0, 200.0])
    ));
    // The plain uses are compensable.
    assert!(at(20).compensable && at(25).compensable);
    let (m, bytes) = model(&kr16_calibration(tempfile::tempdir().unwrap().path()));
    let r = compensate_with(&ws, &m, &bytes);
    let dat = r
        .files
        .iter()
        .find(|f| ws.get(f.file).name.ends_with(".dat"))
        .unwrap();
    let text = String::from_utf8(dat.bytes.to_vec()).unwrap();
    // xPick[2]'s numbers stay as written; xPick[1] and [3] are compensated.
    assert!(
        text.contains("xPick[2]={X 150.000,Y 190.000,Z 60.000,"),
        "{text}"
    );
    assert!(
        !text.contains("xPick[1]={X 150.000,Y 40.000,Z 60.000,"),
        "{text}"
    );
}

/// Item 3: a member set from a value known only at run time makes the point unknown, said
/// where, and the robot's position unknown until a known target follows.
#[test]
fn item03_a_member_set_at_run_time_makes_the_position_unknown() {
    let c = cell();
    let ws = load(&items("item03_runtime_member.src"), &c);
    let sim = simulate(&ws);
    let msgs = messages(&sim).join("\n");
    assert!(
        msgs.contains("21:warning: the target is not known before run time (xProbe.Z set at line 20 from the function SensorHeight"),
        "{msgs}"
    );
    // The partial target after it needs the position: left unchanged.
    assert!(
        msgs.contains("22:warning: a partial or relative position whose start is unknown"),
        "{msgs}"
    );
    // A member set in a branch on an input: unknown as well.
    assert!(
        msgs.contains("26:warning: the target is not known before run time (xBack.Z may be set"),
        "{msgs}"
    );
    let lines: Vec<u32> = sim.stops.iter().map(|s| s.handle.stmt.line).collect();
    assert_eq!(lines, [18, 19, 27, 28, 29], "{msgs}");
    // After the known xSafe = {X 250, Y 100, Z 200} the partial {Z 300} is its X, Y.
    let last = sim.stops.iter().find(|s| s.handle.stmt.line == 28).unwrap();
    assert!(close(
        &last.goal.position,
        &in_base(BASE1, [250.0, 100.0, 300.0])
    ));
    assert_eq!(sim.lost, 3);
}

/// Item 4: user functions returning a position (`Lifted`) and a frame (`BoxPlace`), from the
/// cell's library module.
#[test]
fn item04_user_functions_give_positions_and_frames() {
    let c = cell();
    let ws = load(&items("item04_functions.src"), &c);
    let sim = simulate(&ws);
    assert!(!sim.rejected(), "{:?}", messages(&sim));
    let at = |line: u32| {
        sim.stops
            .iter()
            .filter(|s| s.handle.stmt.line == line)
            .collect::<Vec<_>>()
    };
    // Lifted(xPlace, 100): xPlace = {X 220, Y 60, Z 40} raised by 100, computed.
    let lifted = at(19)[0];
    assert!(close(
        &lifted.goal.position,
        &in_base(BASE1, [220.0, 60.0, 140.0])
    ));
    assert!(!lifted.compensable);
    // $BASE = BoxPlace(BASE_DATA[2], n): BASE_DATA[2] moved by 220 (n − 1) along world X;
    // xInBox = {X 60, Y 30, Z 120} in it, compensable (its numbers are the .dat's).
    let boxes = at(23);
    assert_eq!(boxes.len(), 3);
    for (n, s) in boxes.iter().enumerate() {
        let base = [BASE2[0] + 220.0 * n as f64, BASE2[1], BASE2[2], BASE2[3]];
        assert!(
            close(&s.goal.position, &in_base(base, [60.0, 30.0, 120.0])),
            "box {}",
            n + 1
        );
        assert!(s.compensable);
    }
}

/// Item 5: targets that are members of structures, in the program's data list (compensated in
/// place) and in a data list the cell shares (left as written, said so).
#[test]
fn item05_structure_member_targets() {
    let dir = tempfile::tempdir().unwrap();
    let c = cell();
    let ws = load(&items("item05_struc.src"), &c);
    let sim = simulate(&ws);
    let tops: Vec<_> = sim
        .stops
        .iter()
        .filter(|s| s.handle.stmt.line == 20)
        .collect();
    assert_eq!(tops.len(), 3);
    for (k, s) in tops.iter().enumerate() {
        let want = in_base(BASE1, [120.0 + 100.0 * k as f64, 60.0, 90.0]);
        assert!(
            close(&s.goal.position, &want) && s.compensable,
            "box {}",
            k + 1
        );
    }
    let shared = sim.stops.iter().find(|s| s.handle.stmt.line == 22).unwrap();
    assert!(close(
        &shared.goal.position,
        &in_base(BASE1, [150.0, 40.0, 60.0])
    ));
    assert!(!shared.compensable);
    assert!(messages(&sim).iter().any(|m| m.starts_with("22:")
        && m.contains("cell_data.dat, data every program of the cell shares")));
    let (m, bytes) = model(&kr16_calibration(dir.path()));
    let r = compensate_with(&ws, &m, &bytes);
    assert_eq!(
        r.report.compensated,
        r.report.targets - 1,
        "{:?}",
        r.report.warnings
    );
    let dat = r
        .files
        .iter()
        .find(|f| ws.get(f.file).name.ends_with("item05_struc.dat"))
        .unwrap();
    let text = String::from_utf8(dat.bytes.to_vec()).unwrap();
    // The nested aggregates' numbers changed in place, the rest of the line kept.
    for (k, line) in text.lines().filter(|l| l.starts_with("sBox[")).enumerate() {
        assert!(
            line.starts_with(&format!("sBox[{}]={{pTop {{X ", k + 1)),
            "{line}"
        );
        assert!(
            !line.contains(&format!("X {}.000,Y 60.000,Z 90.000", 120 + 100 * k)),
            "{line}"
        );
        assert!(line.ends_with(",fLift {Z 50.0},iTool 1}"), "{line}");
    }
    assert!(!r
        .files
        .iter()
        .any(|f| ws.get(f.file).name.ends_with("cell_data.dat")));
}

/// Item 6: frames set by a routine whose module is not there are unknown (not $NULLFRAME):
/// the program is refused, naming the routine and what to give.
#[test]
fn item06_frames_of_a_missing_routine_are_unknown() {
    let c = cell();
    let ws = load(&items("item06_missing_frames.src"), &c);
    let sim = simulate(&ws);
    assert!(sim.rejected());
    let msgs = messages(&sim).join("\n");
    assert!(
        msgs.contains("error: $BASE is not set in the program, and routine SetTcp, which may set it, is not found"),
        "{msgs}"
    );
    assert!(sim.needs.contains("routine SetTcp"));
    // The same routine found in the cell: the frames are its.
    let ws = load(&items("item04_functions.src"), &c);
    assert!(!simulate(&ws).rejected());
}

/// The model's predicted TCP of every stop of `again` (a compensated program re-walked)
/// against the goal of the same stop of `original`: largest position (mm) and rotation (rad)
/// errors over the stops not near a singularity.
fn reached(
    model: &Model,
    original: &Simulation,
    again: &Simulation,
    result: &ProgramResult,
) -> (f64, f64) {
    assert_eq!(again.stops.len(), original.stops.len());
    // The compensated motion's own axis histories (turning points included).
    let states = robopost::motion::program_states(&again.stops, &again.arcs);
    let (mut dp, mut dr) = (0.0f64, 0.0f64);
    for (k, (a, o)) in again.stops.iter().zip(&original.stops).enumerate() {
        let point = &result.report.points[k];
        if robopost::kinematics::singularity(&model.robot, &a.nominal_axes).is_some()
            || point.resolution.starts_with("held")
            || point.residual_um > 1.0
        {
            continue;
        }
        let state = states[k];
        let tool = again.frames[a.tool as usize].to_isometry();
        let predicted = model.flange_pose(&state).to_isometry() * tool;
        let goal = o.goal.to_isometry();
        dp = dp.max((predicted.translation.vector - goal.translation.vector).norm());
        dr = dr.max((predicted.rotation * goal.rotation.inverse()).angle());
    }
    (dp, dr)
}

/// Writes a compensated program beside `dir` and walks it again (in the same cell).
fn rewalk(ws: &Workspace, result: &ProgramResult, dir: &Path, c: &Cell) -> Workspace {
    let name = Path::new(&ws.get(ws.main).name)
        .file_name()
        .unwrap()
        .to_owned();
    let out = dir.join(name);
    files::write_atomic_pieces(&files::outputs(ws, &result.files, &out)).unwrap();
    load(&out, c)
}

/// Item 7: a point used alone and with an offset (`P : offset`) is compensated for each use
/// with a point of its own (split like a point reached with different directions); every
/// target then reaches its programmed pose.
#[test]
fn item07_a_point_used_alone_and_with_an_offset_gets_a_copy_per_use() {
    let dir = tempfile::tempdir().unwrap();
    let c = cell();
    let ws = load(&items("item07_offsets.src"), &c);
    let (m, bytes) = model(&kr16_calibration(dir.path()));
    let r = compensate_with(&ws, &m, &bytes);
    assert!(!r.rejected && r.target_errors == 0, "{:?}", r.report.errors);
    let src = String::from_utf8(r.files[0].bytes.to_vec()).unwrap();
    assert!(
        src.contains("LIN xPlace_2 : {X 0.0,Y 0.0,Z 50.0,A 0.0,B 0.0,C 0.0}"),
        "{src}"
    );
    assert!(r.report.split_points.iter().any(|s| s.point == "xPlace"));
    let original = simulate(&ws);
    let ws2 = rewalk(&ws, &r, dir.path(), &c);
    let again = robopost::krl::interpret::simulate(&ws2, &m.robot, &[]);
    let (dp, dr) = reached(&m, &original, &again, &r);
    assert!(dp < 3e-3 && dr < 5e-5, "{dp} mm, {dr} rad");
}

/// Item 8: loops that end on a signal are followed twice, as a cycle, and left with the robot's
/// position unknown — not walked until the statement budget runs out.
#[test]
fn item08_loops_on_signals_are_followed_twice() {
    let c = cell();
    let ws = load(&items("item08_signal_loops.src"), &c);
    let sim = simulate(&ws);
    let msgs = messages(&sim).join("\n");
    assert!(
        msgs.contains("19:warning: this loop ends on a condition known only at run time (line 22): it is followed 2 times"),
        "{msgs}"
    );
    // `WHILE bRun` (only an interrupt would end it): nothing in it changes what ends it.
    assert!(
        msgs.contains("30:warning: nothing in this loop changes what ends it"),
        "{msgs}"
    );
    let lines: Vec<u32> = sim.stops.iter().map(|s| s.handle.stmt.line).collect();
    assert_eq!(lines, [18, 20, 21, 20, 21, 33, 34], "{msgs}");
}

/// Item 9: targets at B = 90°: the Euler triple stays continuous with what the program wrote
/// where that costs nothing; where the orientation correction needs it, A and C turn together
/// (B = +90°: only A − C is defined there, and it stays continuous) and the target is reached
/// exactly — never an orientation left out.
#[test]
fn item09_euler_angles_stay_continuous_at_b_90() {
    let dir = tempfile::tempdir().unwrap();
    let c = cell();
    let ws = load(&items("item09_euler.src"), &c);
    let (m, bytes) = model(&kr16_calibration(dir.path()));
    let r = compensate_with(&ws, &m, &bytes);
    assert!(!r.rejected);
    let dat = r
        .files
        .iter()
        .find(|f| ws.get(f.file).name.ends_with(".dat"))
        .unwrap();
    let text = String::from_utf8(dat.bytes.to_vec()).unwrap();
    let mut seen = 0;
    for line in text.lines().filter(|l| l.contains("xSide")) {
        let num = |k: &str| -> f64 {
            let at = line.find(&format!(",{k} ")).unwrap() + k.len() + 2;
            line[at..].split(',').next().unwrap().parse().unwrap()
        };
        assert!((num("A") - num("C")).abs() < 0.1, "{line}");
        assert!((num("B") - 90.0).abs() < 0.1, "{line}");
        seen += 1;
    }
    assert_eq!(seen, 3);
    let original = simulate(&ws);
    let ws2 = rewalk(&ws, &r, dir.path(), &c);
    let again = robopost::krl::interpret::simulate(&ws2, &m.robot, &[]);
    let (dp, dr) = reached(&m, &original, &again, &r);
    assert!(dp < 3e-3, "{dp} mm");
    // The orientation to the written decimals (3 × 0.5e-4° in A, B, C) and the solver's.
    assert!(dr < 3.0 * 0.5e-4f64.to_radians() + 1e-6, "{dr} rad");
}

/// Item 10: the byte order mark stays first; a point taught on an absolutely accurate robot is
/// refused; external axes pass through with a note.
#[test]
fn item10_bom_absolute_accuracy_and_external_axes() {
    let dir = tempfile::tempdir().unwrap();
    let c = cell();
    let (m, bytes) = model(&kr16_calibration(dir.path()));
    let ws = load(&items("item10_bom.src"), &c);
    let r = compensate_with(&ws, &m, &bytes);
    assert_eq!(r.report.compensated, 3, "{:?}", r.report.warnings);
    for f in r.files.iter().filter(|f| f.changed) {
        let b = f.bytes.to_vec();
        assert!(b.starts_with(b"\xEF\xBB\xBF"), "{}", ws.get(f.file).name);
        assert!(
            b[3..].starts_with(b"&ACCESS") || b[3..].starts_with(program::HEADER_MARK.as_bytes())
        );
        assert!(String::from_utf8_lossy(&b).contains(program::HEADER_MARK));
    }
    let ws = load(&items("item10_aa_status.src"), &c);
    let r = compensate_with(&ws, &m, &bytes);
    assert!(r.rejected);
    assert!(r
        .report
        .errors
        .iter()
        .any(|e| e.contains("bit 4 set") && e.contains("absolutely accurate")));
    let ws = load(&items("item10_track.src"), &c);
    let r = compensate_with(&ws, &m, &bytes);
    assert!(!r.rejected);
    assert!(r
        .report
        .warnings
        .iter()
        .any(|w| w.contains("external axes (E1…E6")));
    let dat = r
        .files
        .iter()
        .find(|f| ws.get(f.file).name.ends_with(".dat"))
        .unwrap();
    let text = String::from_utf8(dat.bytes.to_vec()).unwrap();
    let line = text.lines().find(|l| l.contains("xOnTrack")).unwrap();
    assert!(
        !line.contains("X 150.0,") && line.contains(",E1 850.0,E2 0.0"),
        "{line}"
    );
}

/// Item 11: the forms system files write parse and walk: `EXTP`/`EXTFCTP`, array slices
/// (an `:OUT` array filled by a routine), `ANOUT`, `ON_ERROR_PROCEED`, `; FOLD`.
#[test]
fn item11_system_forms() {
    use robopost::krl::{self, FileKind, StmtKind};
    let path = items("item11_system_forms.src");
    let f = krl::parse(&std::fs::read(&path).unwrap(), FileKind::Src).unwrap();
    assert_eq!(f.stats().opaque, 0);
    assert!(f.problems().is_empty(), "{:?}", f.problems());
    let kinds: Vec<&StmtKind> = f.statements().map(|s| &s.kind).collect();
    assert_eq!(
        kinds
            .iter()
            .filter(|k| matches!(k, StmtKind::Ext(e) if e.protected))
            .count(),
        3
    );
    assert_eq!(
        kinds
            .iter()
            .filter(|k| matches!(k, StmtKind::Anout(_)))
            .count(),
        2
    );
    assert!(kinds.iter().any(|k| matches!(k, StmtKind::OnErrorProceed)));
    // `; FOLD` with a blank: two folds, closed.
    assert_eq!(f.folds().len(), 2);
    assert!(f.folds().iter().all(|x| x.close.is_some()));
    let c = cell();
    let ws = load(&path, &c);
    let sim = simulate(&ws);
    assert!(sim.diagnostics.is_empty(), "{:?}", messages(&sim));
    // FillMatrix filled nMatrix through its `:OUT` array: the IF on nMatrix[2,3] = 23 holds.
    assert!(sim.stops.iter().any(|s| s.handle.stmt.line == 23));
}

fn robopost() -> Command {
    Command::new(env!("CARGO_BIN_EXE_robopost"))
}

/// The cell on the command line: a program named without a directory finds its sibling module,
/// `--cell` its modules elsewhere and the robot of the machine data — which must be the
/// calibration's.
#[test]
fn cell_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let cal = kr16_calibration(dir.path());
    let pallet = std::fs::canonicalize(Path::new(CELL).join("KRC/R1/Program/Pallet")).unwrap();
    let cell = std::fs::canonicalize(CELL).unwrap();
    let out = dir.path().join("out/palletize.src");
    let run = |extra: &[&str]| {
        let mut c = robopost();
        c.current_dir(&pallet)
            .args(["palletize.src", "-c"])
            .arg(&cal)
            .arg("-o")
            .arg(&out);
        c.args(extra);
        c.output().unwrap()
    };
    // Without the cell: the sibling module is found by its file name; the library is not.
    let o = run(&[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("routine pallet_pick is not found"), "{err}");
    assert!(err.contains("routine SetBaseTool is not found"), "{err}");
    // With it: everything resolves; the summary is the one count (every point compensated:
    // its three inline-form points are taken as taught by default, see `cells.rs`).
    let o = run(&["--cell", cell.to_str().unwrap(), "--points", "offline"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(!err.contains("is not found"), "{err}");
    assert!(
        err.contains("palletize.src: 12 of 15 targets compensated, 0 rejected"),
        "{err}"
    );
    // A calibration of another robot than the machine data's: refused before anything.
    let o = robopost()
        .current_dir(&pallet)
        .args(["palletize.src", "-c"])
        .arg(std::fs::canonicalize("calibrations/kr30ha-handset.json").unwrap())
        .arg("-o")
        .arg(dir.path().join("other.src"))
        .args(["--cell", cell.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("describes a KR 30 HA") && err.contains("KR16_2 C4 FLR ZH16"),
        "{err}"
    );
    assert!(!dir.path().join("other.src").exists());
}

/// Counts: one definition of targets and rejected ones (unreachable, beyond the joint limits)
/// in the summary, the report and `check`; exit 1 when any is rejected; a line inside a loop
/// said once with its count.
#[test]
fn rejected_targets_are_counted_once_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let cal = kr16_calibration(dir.path());
    let input = items("counts.src");
    let report = dir.path().join("r.json");
    let o = robopost()
        .arg(&input)
        .arg("-c")
        .arg(&cal)
        .arg("-o")
        .arg(dir.path().join("counts.src"))
        .arg("--report")
        .arg(&report)
        .args(["--cell", CELL])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let (targets, rejected, compensated) = (
        r["targets"].as_u64().unwrap(),
        r["rejected"].as_u64().unwrap(),
        r["compensated"].as_u64().unwrap(),
    );
    // xFar three times (unreachable) and xTooLow (A2 −160°, beyond −155°).
    assert_eq!(rejected, 4, "{err}");
    let line = format!("{compensated} of {targets} targets compensated, {rejected} rejected");
    assert!(err.contains(&line), "{line} in {err}");
    assert!(
        err.contains("(robot: KR 16-2 (kr16-handset.json))"),
        "{err}"
    );
    assert!(
        err.contains("(this line, 3 times: the first is shown)"),
        "{err}"
    );
    assert_eq!(err.matches("cannot be reached").count(), 1, "{err}");
    assert!(err.contains("the axis target is beyond the joint limits (A2 = -160° is outside its limits [-155, 35]°)"), "{err}");
    // `check` says the same count.
    let o = robopost()
        .args(["check"])
        .arg(&input)
        .arg("-c")
        .arg(&cal)
        .args(["--cell", CELL])
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1));
    assert!(out.contains(&line), "{out}");
    // The undeclared point: the walk says it for each motion it leaves, the parse does not
    // say it again, and the needs name it once.
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.matches("(XMISSING, not declared)").count(), 2, "{err}");
    assert!(!err.contains("declared neither"), "{err}");
    assert!(out.contains("needs: XMISSING (declared nowhere)"), "{out}");
}

/// `check --cell` without a calibration: the robot of the machine data is walked, and each
/// program's line says what was resolved and what is missing.
#[test]
fn check_cell_reports_what_each_program_needs() {
    let o = robopost()
        .args(["check", "--cell", CELL])
        .arg(items("item06_missing_frames.src"))
        .arg(items("item01_params.src"))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.lines()
            .any(|l| l.ends_with("item06_missing_frames.src: rejected")),
        "{out}"
    );
    assert!(
        out.contains("item01_params.src: 2 of 8 targets resolved and compensable, 0 rejected"),
        "{out}"
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("routine SetTcp"), "{err}");
    assert_eq!(o.status.code(), Some(1));
}

/// Without the cell, the fixtures of the cell fall back as before: an honest report of what is
/// missing, never a silent default frame after a routine that may set it.
#[test]
fn without_the_cell_the_missing_pieces_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let (m, bytes) = model(&kr16_calibration(dir.path()));
    let path = items("item04_functions.src");
    let ws = files::load_program(Some(&path), &std::fs::read(&path).unwrap(), None).unwrap();
    let r = compensate_with(&ws, &m, &bytes);
    assert!(r.rejected);
    assert!(r.diagnostics.iter().any(|d| d.severity == Severity::Error
        && d.message
            .contains("routine SetBaseTool, which may set it, is not found")));
}

/// Item 7, the other operand: a point that is a target of its own and the offset of a
/// geometric operator (`xLevel : xCorner`) keeps its written numbers in the operator, through
/// an unchanged copy; the left operand is compensated for the operator's target.
#[test]
fn item07_an_offset_that_is_also_a_target_keeps_its_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let c = cell();
    let ws = load(&items("item07_offset_points.src"), &c);
    let (m, bytes) = model(&kr16_calibration(dir.path()));
    let r = compensate_with(&ws, &m, &bytes);
    assert!(!r.rejected && r.target_errors == 0, "{:?}", r.report.errors);
    let src = String::from_utf8(r.files[0].bytes.to_vec()).unwrap();
    assert!(src.contains("LIN xLevel : xCorner_2"), "{src}");
    let dat = String::from_utf8(r.files[1].bytes.to_vec()).unwrap();
    // The copy has xCorner's written numbers; xCorner and xLevel are compensated.
    assert!(
        dat.contains(
            "DECL E6POS xCorner_2={X 150.000,Y 40.000,Z 60.000,A 0.0000,B 0.0000,C 180.0000,"
        ),
        "{dat}"
    );
    assert!(
        !dat.contains("DECL E6POS xCorner={X 150.000,Y 40.000,Z 60.000,"),
        "{dat}"
    );
    assert!(
        !dat.contains("DECL FRAME xLevel={X 0.0,Y 0.0,Z 300.0,"),
        "{dat}"
    );
    let original = simulate(&ws);
    let ws2 = rewalk(&ws, &r, dir.path(), &c);
    let again = robopost::krl::interpret::simulate(&ws2, &m.robot, &[]);
    let (dp, dr) = reached(&m, &original, &again, &r);
    assert!(dp < 3e-3 && dr < 5e-5, "{dp} mm, {dr} rad");
}
