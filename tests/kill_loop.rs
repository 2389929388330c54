//! A program's `.src` and `.dat` are one unit, under SIGKILL: main jobs and batches with two
//! calibrations write into one output, killed at random moments (60 runs killed before their
//! end). After every
//! kill each program's pair is one run's whole pair (or absent), unless a killed run's
//! commit record names it (the run had decided to write it); then `check` says so and the
//! next run completes it before writing — checked too.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn robopost(dir: &Path, args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_robopost"));
    c.args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    c
}

/// The programs of the library: the teach-pendant program (points in its `.dat`) under
/// three names, its points taken as offline (`--points offline`: taught, they would be left
/// as they are and both calibrations would write the same pair).
const NAMES: [&str; 3] = ["pa", "pb", "pc"];

fn pair(dir: &Path, name: &str) -> (Option<Vec<u8>>, Option<Vec<u8>>) {
    (
        std::fs::read(dir.join(format!("{name}.src"))).ok(),
        std::fs::read(dir.join(format!("{name}.dat"))).ok(),
    )
}

/// Whether a commit record in `dir` names `name.src` (its files are being written).
fn pending(dir: &Path) -> bool {
    std::fs::read_dir(dir).unwrap().any(|e| {
        e.unwrap()
            .file_name()
            .to_string_lossy()
            .starts_with(".robopost-commit-")
    })
}

#[test]
fn killed_runs_never_leave_a_pair_from_two_runs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let src = std::fs::read(repo("fixtures/programs/teach/pick_place.src")).unwrap();
    let dat = std::fs::read(repo("fixtures/programs/teach/pick_place.dat")).unwrap();
    std::fs::create_dir_all(d.join("lib")).unwrap();
    for n in NAMES {
        std::fs::write(d.join(format!("lib/{n}.src")), &src).unwrap();
        std::fs::write(d.join(format!("lib/{n}.dat")), &dat).unwrap();
    }
    std::fs::copy(repo("calibrations/kr30ha-example.json"), d.join("a.json")).unwrap();
    std::fs::copy(repo("calibrations/kr30ha-handset.json"), d.join("b.json")).unwrap();
    std::fs::copy(repo("fixtures/config/$config.dat"), d.join("config.dat")).unwrap();
    let main_job = |cal: &str, name: &str| {
        robopost(
            d,
            &[
                &format!("lib/{name}.src"),
                "-c",
                cal,
                "--config",
                "config.dat",
                "--points",
                "offline",
                "-o",
                &format!("out/{name}.src"),
            ],
        )
    };
    let batch = |cal: &str| {
        robopost(
            d,
            &[
                "batch",
                "lib",
                "-c",
                cal,
                "--config",
                "config.dat",
                "--points",
                "offline",
                "-o",
                "out",
                "--jobs",
                "2",
            ],
        )
    };
    // Each calibration's whole pair, written undisturbed (and how long a run takes).
    let started = Instant::now();
    assert!(batch("a.json").status().unwrap().success());
    let run_time = started.elapsed();
    let a = pair(&d.join("out"), "pa");
    assert!(batch("b.json").status().unwrap().success());
    let b = pair(&d.join("out"), "pa");
    assert!(a.0.is_some() && a.1.is_some() && a != b);
    for n in NAMES {
        assert_eq!(pair(&d.join("out"), n), b);
    }
    let whole = |p: &(Option<Vec<u8>>, Option<Vec<u8>>)| *p == a || *p == b;
    let started = Instant::now();
    assert!(main_job("a.json", "pa").status().unwrap().success());
    let job_time = started.elapsed();

    // A small xorshift: random moments, the same on every run of the test.
    let mut x = 0x9E3779B97F4A7C15u64;
    let mut random = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut kills = 0;
    let mut decided = 0;
    let mut round = 0;
    while kills < 60 && round < 400 {
        round += 1;
        let cal = if round % 2 == 0 { "a.json" } else { "b.json" };
        let (mut c, time) = if round % 3 == 0 {
            (main_job(cal, NAMES[round % NAMES.len()]), job_time)
        } else {
            (batch(cal), run_time)
        };
        // Anywhere in the run, mostly before its end.
        let wait = Duration::from_micros(random() % (time.as_micros() as u64 * 9 / 10 + 1));
        let mut child = c.spawn().unwrap();
        std::thread::sleep(wait);
        if child.try_wait().unwrap().is_none() {
            kills += 1;
        }
        let _ = child.kill();
        child.wait().unwrap();
        let out = d.join("out");
        if pending(&out) {
            // Decided but not all renamed: a reader is told, the next run completes it.
            decided += 1;
            let (status, stderr) = {
                let o = Command::new(env!("CARGO_BIN_EXE_robopost"))
                    .args(["check", "out/pa.src", "out/pb.src", "out/pc.src"])
                    .current_dir(d)
                    .output()
                    .unwrap();
                (o.status, String::from_utf8_lossy(&o.stderr).into_owned())
            };
            assert!(status.code().is_some());
            assert!(
                stderr.contains("was killed while writing this program"),
                "{stderr}"
            );
            continue;
        }
        for n in NAMES {
            let p = pair(&out, n);
            assert!(
                whole(&p),
                "round {round}: {n} is not one run's pair (.src {}, .dat {})",
                p.0.is_some(),
                p.1.is_some()
            );
        }
    }
    assert!(
        kills >= 50,
        "only {kills} of {round} runs were killed before they ended"
    );
    // A last undisturbed run completes anything decided and leaves its own pairs.
    assert!(batch("a.json").status().unwrap().success());
    for n in NAMES {
        assert_eq!(pair(&d.join("out"), n), a, "{n}");
    }
    assert!(!pending(&d.join("out")));
    eprintln!("{kills} runs killed, {decided} left a decided unit that the next run completed");
}
