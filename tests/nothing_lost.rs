//! Nothing lost, round two (issue 38): each case a new user met, through the binary. A batch
//! never replaces a good output with a rejected program; counted loops have a limit; a
//! failed write to standard output is an error, not a panic; `-o -` never prints a program
//! without the `.dat` it needs; ambiguous input (a key, a column, an aggregate member given
//! twice) is refused where it is; a program none of whose targets is known is refused;
//! inputs have a size limit and messages quote long fields clipped; UTF-16, a full disk, a
//! calibration of another robot and a clock running backwards are named as such.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn fixture(rel: &str) -> Vec<u8> {
    std::fs::read(repo(rel)).unwrap()
}

fn robopost(dir: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_robopost"));
    c.args(args).current_dir(dir).stdin(Stdio::null());
    c
}

/// Exit status, standard output and standard error.
fn run_cmd(mut c: Command) -> (i32, String, String) {
    let out = c.output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn run(dir: &Path, args: &[&str]) -> (i32, String, String) {
    run_cmd(robopost(dir, args))
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) {
    let p = dir.join(name);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    std::fs::write(p, bytes).unwrap();
}

/// Every file under `dir` with its bytes.
fn files(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                todo.push(p);
            } else {
                out.insert(
                    p.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&p).unwrap(),
                );
            }
        }
    }
    out
}

fn no_panic(stderr: &str) {
    assert!(
        !stderr.contains("panicked") && !stderr.contains("RUST_BACKTRACE"),
        "{stderr}"
    );
}

/// The first `rows` lines of the shipped campaign (a KR 30 HA's).
fn campaign(rows: usize) -> String {
    String::from_utf8(fixture("fixtures/measurements/campaign.csv"))
        .unwrap()
        .lines()
        .take(rows)
        .map(|l| format!("{l}\n"))
        .collect()
}

const CONFIG: &str = "fixtures/config/$config.dat";

/// The teach-pendant program (a `.src` and a `.dat` of points), the calibration, the cell.
/// Its points are taught: the jobs that must change them say `--points offline`.
fn teach(dir: &Path) {
    write(
        dir,
        "pp.src",
        fixture("fixtures/programs/teach/pick_place.src"),
    );
    write(
        dir,
        "pp.dat",
        fixture("fixtures/programs/teach/pick_place.dat"),
    );
    write(dir, "cal.json", fixture("calibrations/kr30ha-example.json"));
    write(dir, "config.dat", fixture(CONFIG));
}

// ---- 1. a batch never destroys a good earlier output --------------------------------------

/// Batch a library of `n` copies of the paper's path (with its `.dat`), then break every
/// seventh program and batch again into the same output: the broken ones are reported (exit
/// 1) and every output the first run wrote is byte for byte as it was (the broken programs'
/// too: a rejected program writes nothing over them, only its note). A library of 1000
/// programs, as a CAM programmer's is.
#[test]
fn a_rejected_program_leaves_the_earlier_good_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 1000;
    let src = fixture("fixtures/programs/paper_path1.src");
    let dat = fixture("fixtures/programs/paper_path1.dat");
    for i in 0..n {
        write(d, &format!("lib/p{i:04}.src"), &src);
        write(d, &format!("lib/p{i:04}.dat"), &dat);
    }
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    let (exit, _, stderr) = run(d, &["batch", "lib", "-c", "cal.json", "-o", "out"]);
    assert_eq!(exit, 0, "{stderr}");
    let good = files(&d.join("out"));
    assert_eq!(good.len(), 2 * n);
    let broken: Vec<usize> = (0..n).step_by(7).collect();
    for &i in &broken {
        // Cut short inside a motion, as a truncated copy is.
        let cut = &src[..src.len() / 2 + 7];
        write(d, &format!("lib/p{i:04}.src"), cut);
    }
    let (exit, stdout, stderr) = run(d, &["batch", "lib", "-c", "cal.json", "-o", "out"]);
    assert_eq!(exit, 1, "{stderr}");
    no_panic(&stderr);
    assert_eq!(
        stdout
            .matches("rejected, the earlier output left as it was")
            .count(),
        broken.len(),
        "{stdout}"
    );
    let after = files(&d.join("out"));
    for (path, bytes) in &good {
        assert!(after.get(path) == Some(bytes), "{} changed", path.display());
    }
    // Besides them, only the notes of the rejected programs.
    let notes: Vec<&PathBuf> = after.keys().filter(|p| !good.contains_key(*p)).collect();
    assert_eq!(notes.len(), broken.len());
    assert!(notes
        .iter()
        .all(|p| p.to_string_lossy().ends_with(".src.robopost-rejected.txt")));
}

/// A rejected program with no earlier output is still copied unchanged with its note, its
/// `.src` and `.dat` together.
#[test]
fn a_rejected_program_without_an_earlier_output_is_copied_whole() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "lib/p.src", b"DEF p( )\nLIN {X 1,,Y 2}\nEND\n");
    write(d, "lib/p.dat", b"DEFDAT p\nENDDAT\n");
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    let (exit, stdout, _) = run(d, &["batch", "lib", "-c", "cal.json", "-o", "out"]);
    assert_eq!(exit, 1);
    assert!(stdout.contains("rejected, copied unchanged"), "{stdout}");
    assert_eq!(
        std::fs::read(d.join("out/p.src")).unwrap(),
        fixture_bytes(d, "lib/p.src")
    );
    assert_eq!(
        std::fs::read(d.join("out/p.dat")).unwrap(),
        fixture_bytes(d, "lib/p.dat")
    );
}

fn fixture_bytes(d: &Path, rel: &str) -> Vec<u8> {
    std::fs::read(d.join(rel)).unwrap()
}

// ---- 2. counted loops have a limit --------------------------------------------------------

/// A program moving between two axis positions inside `head … tail`, a billion times.
fn looping(head: &str, tail: &str) -> String {
    format!(
        "DEF loopy( )\nDECL INT I\n$BASE=$NULLFRAME\n$TOOL={{X 0,Y 0,Z 200,A 0,B 0,C 0}}\n\
         PTP {{A1 20,A2 -80,A3 100,A4 0,A5 70,A6 0}}\n\
         LIN {{X 1300,Y 450,Z 1200,A 0,B 0,C 180}}\nI=0\n{head}\n\
         PTP {{A1 20,A2 -80,A3 100,A4 0,A5 70,A6 0}}\n\
         PTP {{A1 25,A2 -80,A3 100,A4 0,A5 70,A6 0}}\n{tail}\nEND\n"
    )
}

/// `FOR … TO 1e9` and a `WHILE` counting to 1e9, with motions inside: the main job, `check
/// -c` and `simulate program` end (without the limit each runs for hours, holding a stop
/// per iteration), with a warning at the loop's line; the targets before it are compensated.
#[test]
fn counted_loops_have_a_limit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    write(
        d,
        "truth.json",
        fixture("fixtures/measurements/kr30ha-truth.json"),
    );
    write(d, "for.src", looping("FOR I=1 TO 1000000000", "ENDFOR"));
    write(
        d,
        "while.src",
        looping("WHILE I<1000000000\nI=I+1", "ENDWHILE"),
    );
    for (name, line) in [("for", 8), ("while", 8)] {
        let src = format!("{name}.src");
        let out = format!("{name}_out.src");
        let (exit, _, stderr) = run(d, &[&src, "-c", "cal.json", "-o", &out]);
        assert_eq!(exit, 0, "{stderr}");
        assert!(stderr.contains("1000 of them moving the robot"), "{stderr}");
        assert!(stderr.contains(&format!("--> {src}:{line}:1")), "{stderr}");
        assert!(d.join(&out).is_file());
        let (exit, _, stderr) = run(d, &["check", &src, "-c", "cal.json"]);
        assert_eq!(exit, 0, "{stderr}");
        assert!(stderr.contains("followed 1000 times"), "{stderr}");
    }
    let (exit, _, stderr) = run(
        d,
        &[
            "simulate",
            "program",
            "--truth",
            "truth.json",
            "for.src",
            "-o",
            "m.csv",
        ],
    );
    no_panic(&stderr);
    assert!(stderr.contains("followed 1000 times"), "{stderr}");
    assert!(exit == 0 || exit == 1, "{stderr}");
}

// ---- 3. a failed write to standard output ---------------------------------------------------

fn into_dev_full(mut c: Command) -> (i32, String) {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap();
    c.stdout(Stdio::from(full));
    let out = c.output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Every command printing on standard output, into `/dev/full`: an error naming standard
/// output and exit 2 (no panic, exit 101); a batch still writes its outputs and `--report`,
/// exit 1.
#[test]
fn a_full_standard_output_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    teach(d);
    write(d, "m.csv", campaign(60));
    write(
        d,
        "whole.csv",
        fixture("fixtures/measurements/campaign.csv"),
    );
    write(d, "lib/p.src", fixture("fixtures/programs/paper_path1.src"));
    let commands: Vec<Vec<&str>> = vec![
        vec!["fk", "0", "-90", "90", "0", "0", "0"],
        vec!["ik", "1000", "0", "1500", "0", "90", "0"],
        vec!["check", "pp.src"],
        vec!["compare", "-c", "cal.json", "m.csv"],
        vec!["diagnose", "-c", "cal.json", "m.csv"],
        vec![
            "identify",
            "whole.csv",
            "-o",
            "-",
            "--effects",
            "geometric",
            "--accept-poor-fit",
        ],
        vec!["lib/p.src", "-c", "cal.json", "-o", "-"],
    ];
    for args in &commands {
        let (exit, stderr) = into_dev_full(robopost(d, args));
        no_panic(&stderr);
        assert_eq!(exit, 2, "{args:?}: {stderr}");
        assert!(
            stderr.contains("error: writing standard output")
                || stderr.contains("error: <stdout>")
                || stderr.contains("standard output cannot carry"),
            "{args:?}: {stderr}"
        );
    }
    let (exit, stderr) = into_dev_full(robopost(
        d,
        &[
            "batch", "lib", "-c", "cal.json", "-o", "out", "--report", "r.json",
        ],
    ));
    no_panic(&stderr);
    assert_eq!(exit, 1, "{stderr}");
    assert!(
        stderr.contains("error: writing standard output"),
        "{stderr}"
    );
    assert!(d.join("out/p.src").is_file() && d.join("r.json").is_file());
}

/// A test label of 65,536 characters: the table shows it clipped (a format width that large
/// panicked).
#[test]
fn compare_clips_a_huge_test_label() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    let label = "L".repeat(65_536);
    let text: String = campaign(40)
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l}\n")
            } else {
                let rest = l.split_once(',').unwrap().1;
                format!("{label},{rest}\n")
            }
        })
        .collect();
    write(d, "m.csv", text);
    let (exit, stdout, stderr) = run(d, &["compare", "-c", "cal.json", "m.csv"]);
    no_panic(&stderr);
    assert_eq!(exit, 0, "{stderr}");
    assert!(stdout.contains("LLL..."), "{stdout}");
    assert!(stdout.len() < 4000, "{} bytes", stdout.len());
}

// ---- 4. `-o -` and a changed `.dat` --------------------------------------------------------

/// A program whose compensation changes its `.dat` (its points, and `XHOME_2`… for a point
/// reached with different corrections) cannot go to standard output alone: refused, exit 2,
/// nothing printed. One whose `.dat` does not change still can.
#[test]
fn standard_output_never_carries_a_program_without_its_changed_dat() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    teach(d);
    let (exit, stdout, stderr) = run(
        d,
        &[
            "pp.src",
            "-c",
            "cal.json",
            "--config",
            "config.dat",
            // Taught points are left as they are: offline, they change the `.dat`.
            "--points",
            "offline",
            "-o",
            "-",
        ],
    );
    assert_eq!(exit, 2, "{stderr}");
    assert!(stdout.is_empty());
    assert!(
        stderr.contains("changes pp.dat too") && stderr.contains("nothing written"),
        "{stderr}"
    );
    // Through a file, the pair is written.
    let (exit, _, stderr) = run(
        d,
        &[
            "pp.src",
            "-c",
            "cal.json",
            "--config",
            "config.dat",
            "-o",
            "out/pp.src",
        ],
    );
    assert_eq!(exit, 0, "{stderr}");
    let src = String::from_utf8(std::fs::read(d.join("out/pp.src")).unwrap()).unwrap();
    let dat = String::from_utf8(std::fs::read(d.join("out/pp.dat")).unwrap()).unwrap();
    for name in ["XHOME_2", "XHOME_3"] {
        if src.contains(name) {
            assert!(dat.contains(&format!("{name}=")), "{name} not declared");
        }
    }
    // The paper's path keeps its (empty) .dat unchanged: standard output is fine.
    write(d, "pa.src", fixture("fixtures/programs/paper_path1.src"));
    write(d, "pa.dat", fixture("fixtures/programs/paper_path1.dat"));
    let (exit, stdout, stderr) = run(d, &["pa.src", "-c", "cal.json", "-o", "-"]);
    assert_eq!(exit, 0, "{stderr}");
    assert!(stdout.contains("; robopost: compensated with cal.json"));
}

// ---- 5. two runs writing the same output at once --------------------------------------------

/// Two main jobs with different calibrations writing the same `-o` at the same time, 20
/// times: each pair left is one run's whole pair (the runs commit one after the other).
#[test]
fn two_runs_writing_one_output_leave_one_runs_pair() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    teach(d);
    write(d, "cal2.json", fixture("calibrations/kr30ha-handset.json"));
    let job = |cal: &str, out: &str| {
        robopost(
            d,
            &[
                "pp.src",
                "-c",
                cal,
                "--config",
                "config.dat",
                "--points",
                "offline",
                "-o",
                out,
            ],
        )
    };
    let pair = |out: &str| {
        let src = std::fs::read(d.join(out)).unwrap();
        let dat = std::fs::read(d.join(out).with_extension("dat")).unwrap();
        (src, dat)
    };
    assert_eq!(run_cmd(job("cal.json", "a/pp.src")).0, 0);
    assert_eq!(run_cmd(job("cal2.json", "b/pp.src")).0, 0);
    let (a, b) = (pair("a/pp.src"), pair("b/pp.src"));
    assert!(
        a.0 != b.0 && a.1 != b.1,
        "the calibrations give different pairs"
    );
    for _ in 0..20 {
        let mut one = job("cal.json", "c/pp.src");
        let mut two = job("cal2.json", "c/pp.src");
        one.stderr(Stdio::null());
        two.stderr(Stdio::null());
        let (mut one, mut two) = (one.spawn().unwrap(), two.spawn().unwrap());
        assert!(one.wait().unwrap().success() && two.wait().unwrap().success());
        let c = pair("c/pp.src");
        assert!(c == a || c == b, "a pair from two runs");
    }
}

/// The state a run killed between its two renames leaves (its `.dat` renamed, its `.src`
/// still a temporary file, its commit record naming both): `check` says the pair is being
/// written, and the next run writing into the directory (here another program's) completes
/// it before anything else: the killed run's whole pair, not a mix.
#[test]
fn a_killed_runs_decided_pair_is_detected_and_completed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    teach(d);
    write(d, "cal2.json", fixture("calibrations/kr30ha-handset.json"));
    let job = |cal: &str, out: &str| {
        run(
            d,
            &[
                "pp.src",
                "-c",
                cal,
                "--config",
                "config.dat",
                "--points",
                "offline",
                "-o",
                out,
            ],
        )
    };
    assert_eq!(job("cal.json", "old/pp.src").0, 0);
    assert_eq!(job("cal2.json", "new/pp.src").0, 0);
    let read = |p: &str| std::fs::read(d.join(p)).unwrap();
    // Killed after renaming the .dat: the old .src beside the new .dat.
    write(d, "out/pp.src", read("old/pp.src"));
    write(d, "out/pp.dat", read("new/pp.dat"));
    write(d, "out/.robopost-Ab12Cd", read("new/pp.src"));
    write(
        d,
        "out/.robopost-commit-Zz99Yy",
        b".robopost-Ef34Gh\0pp.dat\0.robopost-Ab12Cd\0pp.src\0end\n",
    );
    let (_, _, stderr) = run(d, &["check", "out/pp.src"]);
    assert!(
        stderr.contains("was killed while writing this program"),
        "{stderr}"
    );
    write(d, "pa.src", fixture("fixtures/programs/paper_path1.src"));
    let (exit, _, stderr) = run(d, &["pa.src", "-c", "cal.json", "-o", "out/pa.src"]);
    assert_eq!(exit, 0, "{stderr}");
    assert!(read("out/pp.src") == read("new/pp.src"));
    assert!(read("out/pp.dat") == read("new/pp.dat"));
    let mut left: Vec<String> = std::fs::read_dir(d.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["pa.src", "pp.dat", "pp.src"]);
}

// ---- 6. ambiguous input ---------------------------------------------------------------------

/// A key given twice in a calibration (inside `parameters`, or anywhere else): refused with
/// its JSON path, line and column, exit 2, nothing written.
#[test]
fn a_calibration_key_given_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "p.src", fixture("fixtures/programs/paper_path1.src"));
    let cal = String::from_utf8(fixture("calibrations/kr30ha-example.json")).unwrap();
    let at = cal.find("\"dx21\"").expect("the example has dx21");
    let twice = format!("{}\"dx21\": 40,\n{}", &cal[..at], &cal[at..]);
    write(d, "cal.json", &twice);
    let line = twice[..at].lines().count() + 1;
    let (exit, _, stderr) = run(d, &["p.src", "-c", "cal.json", "-o", "out.src"]);
    assert_eq!(exit, 2, "{stderr}");
    assert!(
        stderr.contains(".parameters.dx21` is given twice"),
        "{stderr}"
    );
    assert!(stderr.contains(&format!("cal.json:{line}:")), "{stderr}");
    assert!(!d.join("out.src").exists());
    // Elsewhere: the robot's name.
    let twice = cal.replacen("\"robot\": {", "\"robot\": {\"name\": \"KR 16\", ", 1);
    assert_ne!(twice, cal);
    write(d, "cal.json", &twice);
    let (exit, _, stderr) = run(d, &["check", "p.src", "-c", "cal.json"]);
    assert_eq!(exit, 2, "{stderr}");
    assert!(stderr.contains("`robot.name` is given twice"), "{stderr}");
}

/// A column named twice in a measurement file: refused at the second, exit 2.
#[test]
fn a_csv_column_given_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    let text = campaign(30).replacen(
        "test,a1,a2,a3,a4,a5,a6,x,y,z,t",
        "test,a1,a2,a3,a4,a5,a6,x,y,z,t,x",
        1,
    );
    let text: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l}\n")
            } else {
                format!("{l},1\n")
            }
        })
        .collect();
    write(d, "m.csv", text);
    let (exit, _, stderr) = run(d, &["compare", "-c", "cal.json", "m.csv"]);
    assert_eq!(exit, 2, "{stderr}");
    assert!(stderr.contains("column `x` is named twice"), "{stderr}");
    // The second `x` is the 12th field: column 32 of the header.
    assert!(stderr.contains("--> m.csv:1:32"), "{stderr}");
}

/// A member given twice in a motion's aggregate (`{X 1200, …, X 1300}`): `check` reports it
/// at the second one (exit 1); the main job refuses the program and writes nothing.
#[test]
fn an_aggregate_member_given_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    write(
        d,
        "p.src",
        "DEF p( )\n$BASE=$NULLFRAME\n$TOOL={X 0,Y 0,Z 200,A 0,B 0,C 0}\n\
         PTP {A1 20,A2 -80,A3 100,A4 0,A5 70,A6 0}\n\
         LIN {X 1200,Y 450,Z 1200,A 0,B 0,C 180,X 1300}\nEND\n",
    );
    let (exit, _, stderr) = run(d, &["check", "p.src"]);
    assert_eq!(exit, 1, "{stderr}");
    assert!(stderr.contains("given twice in the aggregate"), "{stderr}");
    assert!(stderr.contains("--> p.src:5:40"), "{stderr}");
    let (exit, _, stderr) = run(d, &["p.src", "-c", "cal.json", "-o", "out.src"]);
    assert_eq!(exit, 1, "{stderr}");
    assert!(stderr.contains("given twice in the aggregate"), "{stderr}");
    assert!(!d.join("out.src").exists());
    // Lower and upper case name one member; distinct members are fine.
    write(d, "q.src", "DEF q( )\nLIN {x 1,Y 2,X 3}\nEND\n");
    assert_eq!(run(d, &["check", "q.src"]).0, 1);
    write(d, "r.src", "DEF r( )\nLIN {X 1,Y 2,Z 3,E1 0,E2 0}\nEND\n");
    let (exit, _, stderr) = run(d, &["check", "r.src"]);
    assert!(!stderr.contains("given twice"), "{exit} {stderr}");
}

// ---- 7. nothing compensated ------------------------------------------------------------------

/// A program whose points are in its `.dat`, without it (missing, or the program given on
/// standard input): no target can be compensated; refused with the reason, exit 1, nothing
/// written (it was written back unchanged, exit 0).
#[test]
fn a_program_none_of_whose_targets_is_known_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    teach(d);
    std::fs::remove_file(d.join("pp.dat")).unwrap();
    let (exit, _, stderr) = run(
        d,
        &[
            "pp.src",
            "-c",
            "cal.json",
            "--config",
            "config.dat",
            "-o",
            "out.src",
        ],
    );
    assert_eq!(exit, 1, "{stderr}");
    assert!(
        stderr.contains("no target could be compensated"),
        "{stderr}"
    );
    assert!(stderr.contains("no .dat beside it"), "{stderr}");
    assert!(!d.join("out.src").exists());
    let mut c = robopost(
        d,
        &["-", "-c", "cal.json", "--config", "config.dat", "-o", "-"],
    );
    c.stdin(Stdio::from(std::fs::File::open(d.join("pp.src")).unwrap()));
    let (exit, stdout, stderr) = run_cmd(c);
    assert_eq!(exit, 1, "{stderr}");
    assert!(stdout.is_empty());
    assert!(
        stderr.contains("standard input comes without its .dat"),
        "{stderr}"
    );
}

// ---- 8. resource limits -------------------------------------------------------------------

/// `/dev/zero` (never ends) as a program, a measurement file and a calibration: refused at
/// the input limit (set low here), exit 2, quickly and without reading it all.
#[test]
fn an_endless_input_is_refused_at_the_size_limit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    for args in [
        vec!["check", "/dev/zero"],
        vec!["/dev/zero", "-c", "cal.json", "-o", "out.src"],
        vec!["compare", "-c", "cal.json", "/dev/zero"],
        vec!["compare", "-c", "/dev/zero", "m.csv"],
    ] {
        let mut c = robopost(d, &args);
        c.env("ROBOPOST_MAX_INPUT_MB", "8");
        let (exit, _, stderr) = run_cmd(c);
        assert_eq!(exit, 2, "{args:?}: {stderr}");
        assert!(stderr.contains("larger than 8 MiB"), "{args:?}: {stderr}");
    }
    // A regular file past the limit is refused before it is read.
    write(d, "big.src", vec![b';'; 9 << 20]);
    let mut c = robopost(d, &["check", "big.src"]);
    c.env("ROBOPOST_MAX_INPUT_MB", "8");
    let (exit, _, stderr) = run_cmd(c);
    assert_eq!(exit, 2, "{stderr}");
    assert!(stderr.contains("larger than 8 MiB"), "{stderr}");
}

/// A 5 MB field that is not a number: the message quotes it clipped, and the whole of
/// standard error stays a few hundred bytes (it was echoed whole).
#[test]
fn a_long_csv_field_is_quoted_clipped() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    let mut text = campaign(11);
    text.push_str(&format!(
        "A1,-51,-60,100,0,45,0,{},1229.2,796.7,32.4\n",
        "q".repeat(5 << 20)
    ));
    write(d, "m.csv", text);
    let (exit, _, stderr) = run(d, &["compare", "-c", "cal.json", "m.csv"]);
    assert_eq!(exit, 2, "{stderr}");
    assert!(stderr.contains("is not a number (x)"), "{stderr}");
    assert!(stderr.contains("qqq..."), "{stderr}");
    assert!(stderr.len() < 2000, "{} bytes of stderr", stderr.len());
}

// ---- 9. messages ------------------------------------------------------------------------

/// A program saved as UTF-16 is named so (not "binary data"), exit 2; so are a measurement
/// file and a calibration.
#[test]
fn utf16_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let utf16 = |text: &[u8]| -> Vec<u8> {
        let mut v = vec![0xff, 0xfe];
        for &b in text {
            v.extend([b, 0]);
        }
        v
    };
    write(
        d,
        "p.src",
        utf16(&fixture("fixtures/programs/paper_path1.src")),
    );
    write(d, "m.csv", utf16(campaign(20).as_bytes()));
    write(
        d,
        "u.json",
        utf16(&fixture("calibrations/kr30ha-example.json")),
    );
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    for args in [
        vec!["check", "p.src"],
        vec!["p.src", "-c", "cal.json", "-o", "out.src"],
        vec!["compare", "-c", "cal.json", "m.csv"],
        vec!["compare", "-c", "u.json", "m.csv"],
    ] {
        let (exit, _, stderr) = run(d, &args);
        assert_eq!(exit, 2, "{args:?}: {stderr}");
        assert!(stderr.contains("UTF-16"), "{args:?}: {stderr}");
        assert!(!stderr.contains("binary"), "{args:?}: {stderr}");
    }
    // Without the byte order mark too.
    write(
        d,
        "q.src",
        &utf16(&fixture("fixtures/programs/paper_path1.src"))[2..],
    );
    let (exit, _, stderr) = run(d, &["check", "q.src"]);
    assert_eq!(exit, 2, "{stderr}");
    assert!(stderr.contains("UTF-16"), "{stderr}");
}

/// A disk too small for the `.dat` (a file size limit between the two files' sizes): the
/// error names the `.dat`, not the `.src`, and neither is written.
#[test]
fn a_full_disk_names_the_file_that_did_not_fit() {
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    teach(d);
    // A .dat far larger than its .src (a long comment in it) and a limit between the two.
    let mut dat = fixture("fixtures/programs/teach/pick_place.dat");
    let defdat = dat.windows(6).position(|w| w == b"DEFDAT").unwrap();
    let after = defdat + dat[defdat..].iter().position(|&b| b == b'\n').unwrap() + 1;
    let pad = format!(";{}\n", "-".repeat(200_000));
    dat.splice(after..after, pad.bytes());
    write(d, "pp.dat", &dat);
    let src_len = fixture("fixtures/programs/teach/pick_place.src").len() as u64;
    assert!(src_len * 2 < 150_000);
    let mut c = robopost(
        d,
        &[
            "pp.src",
            "-c",
            "cal.json",
            "--config",
            "config.dat",
            "-o",
            "out/o.src",
        ],
    );
    // SAFETY: between fork and exec only async-signal-safe calls (setrlimit, signal).
    unsafe {
        c.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: 150_000,
                rlim_max: 150_000,
            };
            libc::setrlimit(libc::RLIMIT_FSIZE, &lim);
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let (exit, _, stderr) = run_cmd(c);
    assert_eq!(exit, 2, "{stderr}");
    assert!(stderr.contains("writing out/o.dat:"), "{stderr}");
    let left: Vec<String> = std::fs::read_dir(d.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// A KR 16 calibration compared with a KR 30's measurements: a clear warning (half a metre
/// off); the KR 30's own calibration gives none.
#[test]
fn compare_warns_of_a_calibration_of_another_robot() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "kr16.json", fixture("calibrations/kr16-2-nominal.json"));
    write(d, "kr30.json", fixture("calibrations/kr30ha-example.json"));
    write(d, "m.csv", campaign(120));
    let (exit, _, stderr) = run(d, &["compare", "-c", "kr16.json", "m.csv"]);
    assert_eq!(exit, 0, "{stderr}");
    assert!(
        stderr.contains("warning: kr16.json: the model predicts the measured positions")
            && stderr.contains("is it a calibration of this robot"),
        "{stderr}"
    );
    let (exit, _, stderr) = run(d, &["compare", "-c", "kr30.json", "m.csv"]);
    assert_eq!(exit, 0, "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
}

/// Time running backwards in a measurement file: refused at the row, exit 2.
#[test]
fn time_running_backwards_is_refused_at_its_row() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "cal.json", fixture("calibrations/kr30ha-example.json"));
    let mut text = campaign(11);
    let last_t: f64 = text
        .lines()
        .last()
        .unwrap()
        .rsplit(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(last_t > 5.0);
    text.push_str("A1,-51,-60,100,0,45,0,1229.0,796.7,32.4,1.0\n");
    write(d, "m.csv", text);
    let (exit, _, stderr) = run(d, &["compare", "-c", "cal.json", "m.csv"]);
    assert_eq!(exit, 2, "{stderr}");
    assert!(stderr.contains("time runs backwards"), "{stderr}");
    assert!(stderr.contains("--> m.csv:12:"), "{stderr}");
}
