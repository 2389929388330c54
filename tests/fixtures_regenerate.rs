//! The generated fixtures regenerate from the current code: every command of
//! `fixtures/measurements/make.sh` is run into a temporary directory and its output compared
//! with the shipped file — byte for byte for the truth files and the measurement CSVs, number
//! by number (within 1e-7 mm or degree: floating-point differences between the release build
//! make.sh uses and the test build) for the identified `calibrations/kr30ha-example.json`,
//! whose provenance date is the day it was made. (`validation-poses.csv` comes from an
//! example program and is checked by the paper experiment: the validation programs' axes are
//! its poses.) A stale fixture fails here: run `bash fixtures/measurements/make.sh`.

use std::path::Path;
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn robopost(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_robopost"))
        .current_dir(root())
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "robopost {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn same_bytes(made: &Path, shipped: &str) {
    let a = std::fs::read(made).unwrap();
    let b = std::fs::read(root().join(shipped)).unwrap();
    if a != b {
        let line = a
            .split(|&c| c == b'\n')
            .zip(b.split(|&c| c == b'\n'))
            .position(|(x, y)| x != y)
            .map_or(0, |l| l + 1);
        panic!(
            "{shipped} does not regenerate from this build (first difference on line {line}): \
             run `bash fixtures/measurements/make.sh`"
        );
    }
}

#[test]
fn measurement_fixtures_regenerate_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).display().to_string();
    let f = "fixtures/measurements";
    robopost(&["simulate", "truth", "--seed", "1", "-o", &out("t.json")]);
    robopost(&[
        "simulate",
        "truth",
        "--hidden",
        "--seed",
        "3",
        "-o",
        &out("th.json"),
    ]);
    robopost(&[
        "simulate",
        "truth",
        "--seed",
        "5",
        "--tracker",
        "3200,-900,150,150,0.4,-0.2",
        "-o",
        &out("tt.json"),
    ]);
    same_bytes(
        &dir.path().join("t.json"),
        &format!("{f}/kr30ha-truth.json"),
    );
    same_bytes(
        &dir.path().join("th.json"),
        &format!("{f}/kr30ha-truth-hidden.json"),
    );
    same_bytes(
        &dir.path().join("tt.json"),
        &format!("{f}/kr30ha-truth-tracker.json"),
    );
    let truth = format!("{f}/kr30ha-truth.json");
    let hidden = format!("{f}/kr30ha-truth-hidden.json");
    let tracker = format!("{f}/kr30ha-truth-tracker.json");
    let poses = format!("{f}/validation-poses.csv");
    let runs: [(&[&str], &str); 5] = [
        (&["campaign", "--truth", &truth], "campaign.csv"),
        (
            &["poses", "--truth", &truth, "--seed", "2", &poses],
            "validation.csv",
        ),
        (&["campaign", "--truth", &hidden], "campaign-hidden.csv"),
        (
            &["poses", "--truth", &hidden, "--seed", "4", &poses],
            "validation-hidden.csv",
        ),
        (&["campaign", "--truth", &tracker], "campaign-tracker.csv"),
    ];
    for (args, name) in runs {
        let mut all = vec!["simulate"];
        all.extend_from_slice(args);
        let path = out(name);
        all.extend(["-o", &path]);
        robopost(&all);
        same_bytes(Path::new(&path), &format!("{f}/{name}"));
    }
}

#[test]
fn example_calibration_regenerates() {
    let dir = tempfile::tempdir().unwrap();
    let made = dir.path().join("example.json");
    robopost(&[
        "identify",
        "fixtures/measurements/campaign.csv",
        "--robot-name",
        "KR 30 HA (virtual)",
        "-o",
        &made.display().to_string(),
    ]);
    let read = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (mut a, mut b) = (
        read(&made),
        read(&root().join("calibrations/kr30ha-example.json")),
    );
    for v in [&mut a, &mut b] {
        v["provenance"]["date"] = serde_json::Value::Null;
    }
    let mut worst: f64 = 0.0;
    compare(&a, &b, "", &mut worst);
    println!("kr30ha-example.json regenerates to {worst:.1e}");
}

/// Walks two JSON values together: the same structure and strings, numbers within 1e-7.
fn compare(a: &serde_json::Value, b: &serde_json::Value, path: &str, worst: &mut f64) {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            let d = (x - y).abs() / y.abs().max(1.0);
            *worst = worst.max(d);
            assert!(
                d < 1e-7,
                "calibrations/kr30ha-example.json{path}: {y} shipped, {x} made: run \
                 `bash fixtures/measurements/make.sh`"
            );
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "kr30ha-example.json{path}: length");
            for (i, (p, q)) in x.iter().zip(y).enumerate() {
                compare(p, q, &format!("{path}[{i}]"), worst);
            }
        }
        (Value::Object(x), Value::Object(y)) => {
            let keys = |m: &serde_json::Map<String, Value>| m.keys().cloned().collect::<Vec<_>>();
            assert_eq!(keys(x), keys(y), "kr30ha-example.json{path}: keys");
            for (k, v) in x {
                compare(v, &y[k], &format!("{path}.{k}"), worst);
            }
        }
        _ => assert_eq!(a, b, "kr30ha-example.json{path}"),
    }
}
