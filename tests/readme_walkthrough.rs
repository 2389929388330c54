//! The README's walk-through "find the missing effect, add it, watch the error fall", run as
//! written: the same commands, from a directory where `fixtures/` is the repository's, and every
//! output block and figure of the README compared with what this build prints (README blocks
//! `walkthrough-*`, `hidden-*`; numbers within 0.1 of the printed last digit, i.e. one unit,
//! words exactly).

#[path = "support/readme.rs"]
mod readme;

use std::path::Path;
use std::process::Command;

use robopost::read_measurements;

const F: &str = "fixtures/measurements";

fn robopost(dir: &Path, args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_robopost"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "robopost {args:?}: {}\n{text}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// A number printed with one decimal: one unit of its last digit.
const ONE_DECIMAL: f64 = 0.1;

#[test]
fn hidden_effect_walkthrough_prints_what_the_readme_says() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(root.join("fixtures"), dir.path().join("fixtures")).unwrap();
    let d = dir.path();
    let campaign = format!("{F}/campaign-hidden.csv");
    let validation = format!("{F}/validation-hidden.csv");

    // The data as the introduction describes them.
    let count = |file: &str| {
        read_measurements(&root.join(file))
            .unwrap()
            .stops
            .iter()
            .filter(|s| s.measured_mm.is_some())
            .count() as f64
    };
    let (n_campaign, n_validation) = (count(&campaign), count(&validation));
    readme::assert_prose("hidden-campaign-size", &[n_campaign], 0.0);
    readme::assert_prose("hidden-validation-size", &[n_validation], 0.0);

    // 1. and 2.
    robopost(d, &["identify", &campaign, "-o", "paper.json"]);
    let compare = robopost(
        d,
        &[
            "compare",
            "-c",
            "paper.json",
            &validation,
            "--report",
            "report",
        ],
    );
    readme::assert_output("walkthrough-compare", &compare, ONE_DECIMAL);
    assert!(d.join("report/index.html").exists());
    let json: serde_json::Value = serde_json::from_str(&robopost(
        d,
        &["compare", "-c", "paper.json", &validation, "--json"],
    ))
    .unwrap();
    let rms = json["rms_um"].as_f64().unwrap();

    // 3.
    let diagnose = robopost(d, &["diagnose", "-c", "paper.json", &campaign, &validation]);
    readme::assert_output("walkthrough-diagnose", &diagnose, ONE_DECIMAL);
    let diagnosis: serde_json::Value = serde_json::from_str(&robopost(
        d,
        &[
            "diagnose",
            "--json",
            "-c",
            "paper.json",
            &campaign,
            &validation,
        ],
    ))
    .unwrap();
    let considered = diagnosis["considered"].as_array().unwrap().len() as f64;
    readme::assert_prose("walkthrough-tried", &[considered], 0.0);
    let noise = diagnosis["noise_um"].as_f64().unwrap();
    let before = diagnosis["rms_um"].as_f64().unwrap();
    let after = diagnosis["candidates"][0]["rms_after_um"].as_f64().unwrap();
    readme::assert_prose("walkthrough-cv", &[before, after], ONE_DECIMAL);

    // 4. and 5.
    robopost(
        d,
        &[
            "identify",
            "-c",
            "paper.json",
            &campaign,
            &validation,
            "--effects",
            "+tilt:A1",
            "-o",
            "tilt.json",
        ],
    );
    let compare_tilt = robopost(
        d,
        &[
            "compare",
            "-c",
            "tilt.json",
            "--against",
            "paper.json",
            &validation,
        ],
    );
    readme::assert_output("walkthrough-compare-tilt", &compare_tilt, ONE_DECIMAL);
    let tilt: serde_json::Value = serde_json::from_str(&robopost(
        d,
        &["compare", "-c", "tilt.json", &validation, "--json"],
    ))
    .unwrap();
    let rms_tilt = tilt["rms_um"].as_f64().unwrap();
    readme::assert_prose("walkthrough-fall", &[rms, rms_tilt], ONE_DECIMAL);
    readme::assert_prose(
        "walkthrough-share",
        &[n_validation, n_validation + n_campaign],
        0.0,
    );

    // "removes 77 % of the robot's error, but 85.6 µm RMS … (about 13 µm)": the all-row's
    // ΔRMS against the nominal model, the RMS, and diagnose's noise floor to the micrometre.
    let removed = removed_percent(&compare);
    readme::assert_prose("walkthrough-removes", &[removed, rms, noise], 0.5);

    // 6.
    let again = robopost(d, &["diagnose", "-c", "tilt.json", &campaign, &validation]);
    readme::assert_output("walkthrough-diagnose-again", &again, ONE_DECIMAL);
}

/// The ΔRMS of the `all` row of the calibration against nominal, as a positive percentage.
fn removed_percent(compare: &str) -> f64 {
    let lines: Vec<&str> = compare.lines().collect();
    let all = lines.iter().position(|l| l.starts_with("all")).unwrap();
    let last = lines[all + 1].split_whitespace().last().unwrap();
    -readme::parse_number(last).unwrap()
}
