//! `robopost check`: summary lines, problems, exit status per CONTRACTS.md.

use super::root;
use std::process::Command;

fn check(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_robopost"))
        .arg("check")
        .args(args)
        .current_dir(root())
        .output()
        .unwrap();
    (
        out.status.code().unwrap(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

#[test]
fn a_good_program_with_its_dat() {
    let (code, out, err) = check(&[
        "fixtures/programs/teach/pick_place.src",
        "fixtures/programs/teach/pick_place.dat",
    ]);
    assert_eq!(code, 0, "{err}");
    // The .dat given after its .src is checked with it, not twice.
    assert_eq!(
        out,
        "fixtures/programs/teach/pick_place.src (+ pick_place.dat): 6 motions, 5 declared points, 0 opaque statements, 1 warning\n"
    );
    assert!(
        err.contains(
            "`XHOME` is declared neither in the program nor in its data list (used 2 times)"
        ),
        "{err}"
    );
    assert!(
        err.contains("--> fixtures/programs/teach/pick_place.src:24:6"),
        "{err}"
    );
}

#[test]
fn opaque_statements_are_counted() {
    let (code, out, _) = check(&["fixtures/programs/language/coverage.src"]);
    assert_eq!(code, 0);
    assert_eq!(
        out,
        "fixtures/programs/language/coverage.src (+ coverage.dat): 17 motions, 9 declared points, 1 opaque statement\n"
    );
}

#[test]
fn a_bad_file_is_rejected_with_status_1() {
    let (code, out, err) = check(&[
        "fixtures/bad/two_errors.src",
        "fixtures/programs/robodk/drill_cell1.src",
    ]);
    assert_eq!(code, 1);
    assert!(out.contains("fixtures/bad/two_errors.src: 0 motions, 0 declared points, 0 opaque statements, 2 errors"), "{out}");
    assert!(out.contains("drill_cell1.src: 7 motions"), "{out}");
    assert!(
        err.contains("--> fixtures/bad/two_errors.src:2:21"),
        "{err}"
    );
    assert!(
        err.contains("--> fixtures/bad/two_errors.src:3:13"),
        "{err}"
    );
}

#[test]
fn an_unreadable_file_is_status_2() {
    let (code, out, err) = check(&[
        "fixtures/programs/robodk/drill_cell.src",
        "no/such/file.src",
    ]);
    assert_eq!(code, 2);
    assert!(out.contains("drill_cell.src: 0 motions"));
    assert!(err.contains("cannot read no/such/file.src"), "{err}");
}
