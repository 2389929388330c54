//! `robopost simulate campaign` run from a test, as a user runs it.

use std::path::Path;

/// Runs `robopost simulate campaign --truth TRUTH --campaign CAMPAIGN -o OUT` (with `--seed`
/// when given) and asserts that it succeeded, showing its stderr if not.
pub fn simulate_campaign(truth: &Path, campaign: &Path, seed: Option<u64>, out: &Path) {
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_robopost"));
    command.args(["simulate", "campaign"]);
    if let Some(seed) = seed {
        command.args(["--seed", &seed.to_string()]);
    }
    let run = command
        .arg("--truth")
        .arg(truth)
        .arg("--campaign")
        .arg(campaign)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}
