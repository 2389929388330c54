//! The command line on temporary copies: the main job, `-` for stdin/stdout, refusals,
//! `batch` with a broken file, `check -c`.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn robopost() -> Command {
    Command::new(env!("CARGO_BIN_EXE_robopost"))
}

/// The command of the main job, `robopost IN -c CAL -o OUT`.
fn main_job_command(input: &Path, cal: &str, out: &Path) -> Command {
    let mut c = robopost();
    c.args([
        input.to_str().unwrap(),
        "-c",
        cal,
        "-o",
        out.to_str().unwrap(),
    ]);
    c
}

/// The main job, run.
fn main_job(input: &Path, cal: &str, out: &Path) -> std::process::Output {
    main_job_command(input, cal, out).output().unwrap()
}

fn copy_fixture(dir: &Path, name: &str) -> PathBuf {
    let src = Path::new("fixtures/programs").join(name);
    let to = dir.join(src.file_name().unwrap());
    std::fs::copy(&src, &to).unwrap();
    if let Some(dat) = robopost::krl::companion_dat(&src) {
        std::fs::copy(&dat, to.with_extension("dat")).unwrap();
    }
    to
}

const CAL: &str = "calibrations/kr30ha-handset.json";

#[test]
fn main_job_writes_src_dat_and_report_and_leaves_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_fixture(dir.path(), "paper_path2.src");
    let before = std::fs::read(&input).unwrap();
    let dat_before = std::fs::read(input.with_extension("dat")).unwrap();
    let out = dir.path().join("out/p2.src");
    let report = dir.path().join("p2.json");
    let st = robopost()
        .args([
            input.to_str().unwrap(),
            "-c",
            CAL,
            "-o",
            out.to_str().unwrap(),
            "--report",
        ])
        .arg(&report)
        .output()
        .unwrap();
    assert_eq!(
        st.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
    assert_eq!(std::fs::read(&input).unwrap(), before, "input untouched");
    assert_eq!(
        std::fs::read(input.with_extension("dat")).unwrap(),
        dat_before
    );
    let dat_out = std::fs::read_to_string(dir.path().join("out/p2.dat")).unwrap();
    assert!(dat_out.contains("; robopost: compensated with kr30ha-handset.json (sha256 "));
    assert_ne!(dat_out.as_bytes(), dat_before.as_slice());
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for key in [
        "targets",
        "compensated",
        "correction",
        "direction_flips",
        "warnings",
        "points",
    ] {
        assert!(r.get(key).is_some(), "report key {key}");
    }
    assert!(r["correction"]["position_um"]["max"].as_f64().unwrap() > 100.0);
    assert_eq!(
        r["points"].as_array().unwrap().len(),
        r["targets"].as_u64().unwrap() as usize
    );
    // No temporary files left behind.
    let left: Vec<_> = std::fs::read_dir(dir.path().join("out")).unwrap().collect();
    assert_eq!(left.len(), 2);
}

#[test]
fn stdin_to_stdout() {
    let src = std::fs::read("fixtures/programs/vertical_segment.src").unwrap();
    let mut child = robopost()
        .args(["-", "-c", CAL, "-o", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    child.stdin.take().unwrap().write_all(&src).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The same as through files.
    let dir = tempfile::tempdir().unwrap();
    let input = copy_fixture(dir.path(), "vertical_segment.src");
    let o = dir.path().join("o.src");
    let st = main_job(&input, CAL, &o);
    assert_eq!(st.status.code(), Some(0));
    assert_eq!(out.stdout, std::fs::read(&o).unwrap());
}

#[test]
fn refusals_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_fixture(dir.path(), "paper_path1.src");
    let before = std::fs::read(&input).unwrap();
    // Output onto the input.
    let st = main_job(&input, CAL, &input);
    assert_eq!(st.status.code(), Some(2));
    assert_eq!(std::fs::read(&input).unwrap(), before);
    // Unreadable calibration.
    let out = dir.path().join("x.src");
    let st = main_job(&input, "nope.json", &out);
    assert_eq!(st.status.code(), Some(2));
    assert!(!out.exists());
    // A rejected program (external TCP).
    let tcp = dir.path().join("tcp.src");
    std::fs::write(&tcp, "DEF tcp( )\n$IPO_MODE = #TCP\nPTP {A1 0, A2 -90, A3 90, A4 0, A5 30, A6 0}\nLIN {X 1000, Y 0, Z 900, A 0, B 0, C 180}\nEND\n").unwrap();
    let st = main_job(&tcp, CAL, &out);
    assert_eq!(st.status.code(), Some(1));
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(err.contains("tcp.src:2:1") && err.contains("#TCP"), "{err}");
    assert!(!out.exists());
}

#[test]
fn batch_mirrors_the_tree_and_survives_a_broken_file() {
    let dir = tempfile::tempdir().unwrap();
    let lib = dir.path().join("lib");
    std::fs::create_dir_all(lib.join("cell_a")).unwrap();
    std::fs::create_dir_all(lib.join("cell_b/robodk")).unwrap();
    copy_fixture(&lib.join("cell_a"), "paper_path1.src");
    copy_fixture(&lib.join("cell_a"), "paper_path3.src");
    for f in [
        "drill_cell.src",
        "drill_cell1.src",
        "drill_cell2.src",
        "drill_cell3.src",
    ] {
        copy_fixture(&lib.join("cell_b/robodk"), &format!("robodk/{f}"));
    }
    std::fs::write(
        lib.join("cell_b/broken.src"),
        "DEF broken( )\nLIN {X 1, Y\nEND\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let st = robopost()
        .args([
            "batch",
            lib.to_str().unwrap(),
            "-c",
            CAL,
            "-o",
            out.to_str().unwrap(),
            "--jobs",
            "2",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&st.stderr);
    assert_eq!(st.status.code(), Some(1), "{err}");
    let stdout = String::from_utf8_lossy(&st.stdout);
    assert!(
        err.contains("broken.src") && err.contains("rejected"),
        "{err}"
    );
    assert!(
        err.contains("batch: 3 of 4 programs written, 1 rejected"),
        "{err}"
    );
    // One line per program on standard output, the rejected one flagged.
    assert_eq!(stdout.lines().count(), 4, "{stdout}");
    assert!(
        stdout
            .lines()
            .any(|l| l.contains("broken.src: rejected, copied unchanged")),
        "{stdout}"
    );
    assert!(
        stdout
            .lines()
            .any(|l| l.contains("paper_path1.src: 53 of 53 targets compensated, 0 rejected")),
        "{stdout}"
    );
    for f in [
        "cell_a/paper_path1.src",
        "cell_a/paper_path1.dat",
        "cell_a/paper_path3.src",
        "cell_a/paper_path3.dat",
        "cell_b/robodk/drill_cell.src",
        "cell_b/robodk/drill_cell1.src",
        "cell_b/robodk/drill_cell3.src",
    ] {
        assert!(out.join(f).is_file(), "{f} written");
    }
    // The rejected program is in the tree unchanged, with the note of why beside it.
    assert_eq!(
        std::fs::read(out.join("cell_b/broken.src")).unwrap(),
        std::fs::read(lib.join("cell_b/broken.src")).unwrap()
    );
    let note =
        std::fs::read_to_string(out.join("cell_b/broken.src.robopost-rejected.txt")).unwrap();
    assert!(note.contains("expected a value for the member"), "{note}");
    // The module is compensated as part of its caller.
    let m = std::fs::read_to_string(out.join("cell_b/robodk/drill_cell1.src")).unwrap();
    assert!(m.starts_with("; robopost: compensated with"));
    // No progress bar when stderr is not a terminal.
    assert!(!err.contains('\u{2588}') && !err.contains("\r"));
}

#[test]
fn check_reports_without_writing() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_fixture(dir.path(), "encodings/palletize_cp1252.src");
    let st = robopost()
        .args(["check", input.to_str().unwrap(), "-c", CAL])
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(1));
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        err.contains("cannot be reached") && err.contains("palletize_cp1252.src:9:3"),
        "{err}"
    );
    let files: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(files.len(), 1, "nothing written");
    let ok = robopost()
        .args(["check", "fixtures/programs/paper_path1.src", "-c", CAL])
        .output()
        .unwrap();
    assert_eq!(ok.status.code(), Some(0));
    assert!(
        String::from_utf8_lossy(&ok.stdout).contains("53 of 53 targets compensated, 0 rejected"),
        "{}",
        String::from_utf8_lossy(&ok.stdout)
    );
    // A bad calibration: a usage error, reported before any summary.
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, "{ not json").unwrap();
    let st = robopost()
        .args([
            "check",
            "fixtures/programs/paper_path1.src",
            "-c",
            bad.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(st.status.code(), Some(2));
    assert!(
        st.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&st.stdout)
    );
    assert!(String::from_utf8_lossy(&st.stderr).contains("bad.json"));
}

#[test]
fn a_compensated_program_is_refused_naming_the_header_line() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_fixture(dir.path(), "paper_path2.src");
    let once = dir.path().join("once/p2.src");
    let st = main_job(&input, CAL, &once);
    assert_eq!(st.status.code(), Some(0));
    // The header in another case is still the header (the mark is compared ignoring case).
    let text = std::fs::read_to_string(&once).unwrap().replace(
        "; robopost: compensated with",
        "; ROBOPOST: Compensated with",
    );
    std::fs::write(&once, &text).unwrap();
    let line = 1 + text
        .lines()
        .position(|l| l.starts_with("; ROBOPOST: Compensated with"))
        .expect("a header line");
    let twice = dir.path().join("twice/p2.src");
    let st = main_job(&once, CAL, &twice);
    assert_ne!(st.status.code(), Some(0));
    let err = String::from_utf8_lossy(&st.stderr);
    assert!(
        err.contains("already compensated") && err.contains(&format!("p2.src:{line}:1")),
        "{err}"
    );
    assert!(!twice.exists(), "nothing written");
}

/// A long CAM program (streamed in windows) compensated with a pool of one thread gives the
/// file of the default pool, and does not hang: the windows are taken on the pool's thread
/// only when another is left for the walker's parsing.
#[test]
fn a_streamed_program_on_one_thread_gives_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let input = copy_fixture(dir.path(), "cam/pocket_milling.src");
    let (one, many) = (dir.path().join("one.src"), dir.path().join("many.src"));
    let mut child = main_job_command(&input, CAL, &one)
        .env("RAYON_NUM_THREADS", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            panic!("one thread: no end after 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    assert_eq!(status.code(), Some(0));
    let st = main_job(&input, CAL, &many);
    assert_eq!(st.status.code(), Some(0));
    let (a, b) = (std::fs::read(&one).unwrap(), std::fs::read(&many).unwrap());
    assert!(
        a == b,
        "one thread and the default pool write different files"
    );
    assert!(a != std::fs::read(&input).unwrap(), "compensated");
}

/// An axis target beyond the joint limits: the controller refuses it, so the main job and
/// `simulate program` both reject it — exit 1, the target left as written, named with its line.
#[test]
fn an_axis_target_beyond_the_limits_is_rejected_by_the_main_job_and_the_virtual_robot() {
    let dir = tempfile::tempdir().unwrap();
    let prog = dir.path().join("limits.src");
    // KR 30 HA: A2 −135…35°; the second target asks for −150°.
    let text = "DEF limits( )\n$BASE = {X 0,Y 0,Z 0,A 0,B 0,C 0}\n$TOOL = {X 0,Y 0,Z 0,A 0,B 0,C 0}\nPTP {A1 0, A2 -90, A3 90, A4 0, A5 30, A6 0}\nPTP {A1 10, A2 -150, A3 100, A4 0, A5 30, A6 0}\nPTP {A1 0, A2 -80, A3 90, A4 0, A5 30, A6 0}\nEND\n";
    std::fs::write(&prog, text).unwrap();
    let out = dir.path().join("out.src");
    let st = main_job(&prog, CAL, &out);
    let err = String::from_utf8_lossy(&st.stderr);
    assert_eq!(st.status.code(), Some(1), "{err}");
    assert!(
        err.contains("limits.src:5:1") && err.contains("beyond the joint limits (A2 = -150°"),
        "{err}"
    );
    assert!(
        err.contains("2 of 3 targets compensated, 1 rejected"),
        "{err}"
    );
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(written.contains("PTP {A1 10, A2 -150, A3 100, A4 0, A5 30, A6 0}"));
    let csv = dir.path().join("m.csv");
    let sim = robopost()
        .args([
            "simulate",
            "program",
            "--truth",
            "fixtures/measurements/kr30ha-truth.json",
        ])
        .arg(&prog)
        .arg("-o")
        .arg(&csv)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&sim.stderr);
    assert_eq!(sim.status.code(), Some(1), "{err}");
    assert!(
        err.contains("limits.src:5:1") && err.contains("beyond the joint limits (A2 = -150°"),
        "{err}"
    );
    assert!(!csv.exists());
}
