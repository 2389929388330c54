//! Bad input, end to end through the binary: each case lays out files in an empty directory,
//! runs one command line there, and checks the exit status, a fragment of the message and
//! that every file is byte for byte as before, with no file added or removed (nothing
//! written, nothing lost). A property test then tries every way of naming an input as an
//! output (the same path, `./x`, `d/../x`, a symbolic link, a hard link) in every command
//! that writes: each is refused.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use proptest::prelude::*;

fn fixture(rel: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)).unwrap()
}

/// What a directory entry holds before the run.
#[derive(Clone)]
enum Entry {
    File(Vec<u8>),
    Dir,
    /// A symbolic link to this target.
    Link(&'static str),
    /// A second name of this (earlier) file.
    HardLink(&'static str),
}

fn file(bytes: impl Into<Vec<u8>>) -> Entry {
    Entry::File(bytes.into())
}

/// The first `rows` lines of the shipped campaign.
fn campaign(rows: usize) -> Vec<u8> {
    let text = String::from_utf8(fixture("fixtures/measurements/campaign.csv")).unwrap();
    text.lines()
        .take(rows)
        .map(|l| format!("{l}\n"))
        .collect::<String>()
        .into_bytes()
}

fn program() -> Vec<(&'static str, Entry)> {
    vec![
        ("p.src", file(fixture("fixtures/programs/paper_path1.src"))),
        ("p.dat", file(fixture("fixtures/programs/paper_path1.dat"))),
        (
            "cal.json",
            file(fixture("calibrations/kr30ha-example.json")),
        ),
    ]
}

fn lay_out(dir: &Path, entries: &[(&str, Entry)]) {
    for (name, entry) in entries {
        let path = dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        match entry {
            Entry::File(bytes) => std::fs::write(&path, bytes).unwrap(),
            Entry::Dir => std::fs::create_dir_all(&path).unwrap(),
            Entry::Link(target) => std::os::unix::fs::symlink(target, &path).unwrap(),
            Entry::HardLink(target) => std::fs::hard_link(dir.join(target), &path).unwrap(),
        }
    }
}

/// Every entry under `dir`: files with their bytes, directories, links with their targets.
fn tree(dir: &Path) -> BTreeMap<PathBuf, String> {
    let mut out = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let meta = std::fs::symlink_metadata(&p).unwrap();
            let key = p.strip_prefix(dir).unwrap().to_path_buf();
            let what = if meta.file_type().is_symlink() {
                format!("link to {}", std::fs::read_link(&p).unwrap().display())
            } else if meta.is_dir() {
                todo.push(p);
                "dir".to_string()
            } else {
                let bytes = std::fs::read(&p).unwrap();
                format!("{} bytes, {:x}", bytes.len(), fnv(&bytes))
            };
            out.insert(key, what);
        }
    }
    out
}

/// A content hash good enough to tell files apart.
fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf29ce484222325, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x100000001b3)
    })
}

/// Runs `args` in `dir`: exit status and standard error.
fn run(dir: &Path, args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_robopost"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

struct Case {
    name: &'static str,
    files: Vec<(&'static str, Entry)>,
    args: &'static [&'static str],
    exit: i32,
    message: &'static str,
}

fn with(
    mut base: Vec<(&'static str, Entry)>,
    more: Vec<(&'static str, Entry)>,
) -> Vec<(&'static str, Entry)> {
    base.extend(more);
    base
}

fn cases() -> Vec<Case> {
    let csv = || ("m.csv", file(campaign(30)));
    let truth = || {
        (
            "t.json",
            file(fixture("fixtures/measurements/kr30ha-truth.json")),
        )
    };
    let cal = || {
        (
            "cal.json",
            file(fixture("calibrations/kr30ha-example.json")),
        )
    };
    let row = |line: &str| {
        let mut bytes = campaign(11);
        bytes.extend_from_slice(line.as_bytes());
        bytes.extend_from_slice(b"\n");
        bytes
    };
    let map = |value: &str| {
        let text = String::from_utf8(fixture("calibrations/kr30ha-nominal.json")).unwrap();
        text.replace(
            "\"effects\": []",
            &format!(r#""effects": [{{"name": "map:A2", "table": {{"grid_deg": [-135, 35], "values_deg": [{value}, 0]}}}}]"#),
        )
        .into_bytes()
    };
    let mut noise = vec![0u8; 1 << 20];
    let mut x = 0x2545F4914F6CDD1Du64;
    for b in noise.iter_mut() {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        *b = x as u8;
    }
    vec![
        // Data lost: every output against every input.
        Case {
            name: "report onto the program",
            files: program(),
            args: &[
                "p.src", "-c", "cal.json", "-o", "out.src", "--report", "p.src",
            ],
            exit: 2,
            message: "the output p.src is the input p.src",
        },
        Case {
            name: "report onto the .dat",
            files: program(),
            args: &[
                "p.src", "-c", "cal.json", "-o", "out.src", "--report", "p.dat",
            ],
            exit: 2,
            message: "is the input p.dat",
        },
        Case {
            name: "report onto the calibration",
            files: program(),
            args: &[
                "p.src",
                "-c",
                "cal.json",
                "-o",
                "out.src",
                "--report",
                "./cal.json",
            ],
            exit: 2,
            message: "names the same file as the input cal.json",
        },
        Case {
            name: "report onto the new program",
            files: program(),
            args: &[
                "p.src", "-c", "cal.json", "-o", "out.src", "--report", "out.src",
            ],
            exit: 2,
            message: "is the same file as the other output out.src",
        },
        Case {
            name: "output through a symbolic link",
            files: with(program(), vec![("link.src", Entry::Link("p.src"))]),
            args: &["p.src", "-c", "cal.json", "-o", "link.src"],
            exit: 2,
            message: "names the same file as the input p.src",
        },
        Case {
            name: "output's .dat a hard link of the input's",
            files: with(program(), vec![("q.dat", Entry::HardLink("p.dat"))]),
            args: &["p.src", "-c", "cal.json", "-o", "q.src"],
            exit: 2,
            message: "is a hard link to the input p.dat",
        },
        Case {
            name: "output through a directory that does not exist yet",
            files: program(),
            args: &["p.src", "-c", "cal.json", "-o", "new/../p.src"],
            exit: 2,
            message: "names the same file as the input p.src",
        },
        Case {
            name: "identify onto its measurements",
            files: vec![csv()],
            args: &["identify", "m.csv", "-o", "m.csv"],
            exit: 2,
            message: "the output m.csv is the input m.csv",
        },
        Case {
            name: "identify onto its starting calibration",
            files: vec![csv(), cal()],
            args: &[
                "identify",
                "m.csv",
                "-c",
                "cal.json",
                "--effects",
                "+drift",
                "-o",
                "cal.json",
            ],
            exit: 2,
            message: "is the input cal.json",
        },
        Case {
            name: "simulate campaign onto the truth",
            files: vec![truth()],
            args: &["simulate", "campaign", "--truth", "t.json", "-o", "t.json"],
            exit: 2,
            message: "is the input t.json",
        },
        Case {
            name: "simulate poses onto the poses",
            files: vec![
                truth(),
                (
                    "poses.csv",
                    file(fixture("fixtures/measurements/validation-poses.csv")),
                ),
            ],
            args: &[
                "simulate",
                "poses",
                "--truth",
                "t.json",
                "poses.csv",
                "-o",
                "poses.csv",
            ],
            exit: 2,
            message: "is the input poses.csv",
        },
        Case {
            name: "simulate program onto its .dat",
            files: with(program(), vec![truth()]),
            args: &[
                "simulate", "program", "--truth", "t.json", "p.src", "-o", "p.dat",
            ],
            exit: 2,
            message: "is the input p.dat",
        },
        Case {
            name: "compare's report page onto the measurements",
            files: vec![csv(), cal(), ("rep/index.html", Entry::Link("../m.csv"))],
            args: &["compare", "-c", "cal.json", "m.csv", "--report", "rep"],
            exit: 2,
            message: "names the same file as the input m.csv",
        },
        Case {
            name: "batch output inside the library",
            files: vec![
                (
                    "lib/cell/p.src",
                    file(fixture("fixtures/programs/paper_path1.src")),
                ),
                cal(),
            ],
            args: &["batch", "lib", "-c", "cal.json", "-o", "lib/out"],
            exit: 2,
            message: "lies inside the input directory lib",
        },
        Case {
            name: "batch report onto a program of the library",
            files: vec![
                (
                    "lib/cell/p.src",
                    file(fixture("fixtures/programs/paper_path1.src")),
                ),
                cal(),
            ],
            args: &[
                "batch",
                "lib",
                "-c",
                "cal.json",
                "-o",
                "out",
                "--report",
                "lib/cell/p.src",
            ],
            exit: 2,
            message: "lies inside the input directory lib",
        },
        Case {
            name: "batch output holding the input",
            files: vec![
                (
                    "lib/cell/p.src",
                    file(fixture("fixtures/programs/paper_path1.src")),
                ),
                cal(),
            ],
            args: &["batch", "lib/cell/p.src", "-c", "cal.json", "-o", "lib"],
            exit: 2,
            message: "holds the input lib/cell/p.src",
        },
        Case {
            name: "batch output linked back into the library",
            files: vec![
                (
                    "lib/cell/p.src",
                    file(fixture("fixtures/programs/paper_path1.src")),
                ),
                ("out/cell", Entry::Link("../lib/cell")),
                cal(),
            ],
            args: &["batch", "lib", "-c", "cal.json", "-o", "out"],
            exit: 2,
            message: "lies inside the input directory lib",
        },
        Case {
            name: "a .dat of the output name left beside a program without one",
            files: vec![
                ("p.src", file(fixture("fixtures/programs/paper_path1.src"))),
                cal(),
                (
                    "out.dat",
                    file(fixture("fixtures/programs/paper_path1.dat")),
                ),
            ],
            args: &["p.src", "-c", "cal.json", "-o", "out.src"],
            exit: 2,
            message: "out.dat exists beside the output out.src, but p.src has no .dat",
        },
        // Absurd numbers.
        Case {
            name: "an axis angle of 1e20",
            files: vec![(
                "m.csv",
                file(row("A1,-51,1e20,100,0,45,0,1098.3,1229.2,796.7,32.4")),
            )],
            args: &["identify", "m.csv", "-o", "cal.json"],
            exit: 2,
            message: "m.csv:12:",
        },
        Case {
            name: "an axis angle of 1e12 in diagnose",
            files: vec![
                cal(),
                (
                    "m.csv",
                    file(row("A1,1e12,-60,100,0,45,0,1098.3,1229.2,796.7,32.4")),
                ),
            ],
            args: &["diagnose", "-c", "cal.json", "m.csv"],
            exit: 2,
            message: "a1 = 1e12 is beyond any physical range",
        },
        Case {
            name: "a position of 1e308 in compare",
            files: vec![
                cal(),
                (
                    "m.csv",
                    file(row("A1,-51,-60,100,0,45,0,1e308,1229.2,796.7,32.4")),
                ),
            ],
            args: &["compare", "-c", "cal.json", "m.csv"],
            exit: 2,
            message: "x = 1e308 is beyond any physical range",
        },
        Case {
            name: "an angle outside the joint limits",
            files: vec![
                cal(),
                (
                    "m.csv",
                    file(row("A1,-51,-150,100,0,45,0,1098.3,1229.2,796.7,32.4")),
                ),
            ],
            args: &["compare", "-c", "cal.json", "m.csv"],
            exit: 2,
            message: "A2 = -150° is outside the robot's joint limits [-135, 35]°",
        },
        Case {
            name: "a map pitch of 1e-9",
            files: vec![csv()],
            args: &["identify", "m.csv", "--map-pitch", "1e-9", "-o", "cal.json"],
            exit: 2,
            message: "the table pitch must be at least 0.001 degrees",
        },
        Case {
            name: "a 45° map",
            files: with(program(), vec![("bad.json", file(map("45")))]),
            args: &["p.src", "-c", "bad.json", "-o", "out.src"],
            exit: 2,
            message:
                "effects[0].table.values_deg[0]: expected a value from -1 to 1 degrees, found 45",
        },
        // Not KRL.
        Case {
            name: "a megabyte of noise as a program",
            files: vec![cal(), ("noise.src", file(noise))],
            args: &["noise.src", "-c", "cal.json", "-o", "out.src"],
            exit: 2,
            message: "not a KRL file: it holds NUL bytes",
        },
        Case {
            name: "a measurement file as a program",
            files: vec![cal(), ("m.src", file(campaign(5)))],
            args: &["check", "m.src"],
            exit: 2,
            message: "not a KRL file: no line of it is a KRL statement",
        },
        Case {
            name: "a .dat that is a directory",
            files: vec![
                ("p.src", file(fixture("fixtures/programs/paper_path1.src"))),
                ("p.dat", Entry::Dir),
                cal(),
            ],
            args: &["p.src", "-c", "cal.json", "-o", "out.src"],
            exit: 2,
            message: "p.dat: Is a directory",
        },
        Case {
            name: "a .dat of junk",
            files: vec![
                ("p.src", file(fixture("fixtures/programs/paper_path1.src"))),
                ("p.dat", file("this is not\na data list\n")),
                cal(),
            ],
            args: &["p.src", "-c", "cal.json", "-o", "out.src"],
            exit: 2,
            message: "p.dat:1:1",
        },
        // Reports that tell the truth.
        Case {
            name: "a mistyped subcommand",
            files: vec![csv()],
            args: &["identfy", "m.csv", "-o", "cal.json"],
            exit: 2,
            message: "a similar subcommand exists: 'identify'",
        },
        Case {
            name: "a bad number on line 12 of a CRLF file",
            files: vec![
                cal(),
                (
                    "m.csv",
                    file(
                        String::from_utf8(row("A1,-51,-60,100,0,45,0,abc,1229.2,796.7,32.4"))
                            .unwrap()
                            .replace('\n', "\r\n"),
                    ),
                ),
            ],
            args: &["compare", "-c", "cal.json", "m.csv"],
            exit: 2,
            message: "--> m.csv:12:23",
        },
    ]
}

#[test]
fn bad_input_is_refused_and_nothing_is_touched() {
    let mut failures = Vec::new();
    for case in cases() {
        let dir = tempfile::tempdir().unwrap();
        lay_out(dir.path(), &case.files);
        let before = tree(dir.path());
        let (exit, stderr) = run(dir.path(), case.args);
        let after = tree(dir.path());
        if exit != case.exit || !stderr.contains(case.message) || before != after {
            failures.push(format!(
                "{}: exit {exit} (expected {}), files {}\n{stderr}",
                case.name,
                case.exit,
                if before == after {
                    "unchanged"
                } else {
                    "CHANGED"
                }
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n---\n"));
}

/// `check -c` reports a parse error once (it was printed by the parse and again by the
/// simulation).
#[test]
fn check_with_a_calibration_prints_each_parse_error_once() {
    let dir = tempfile::tempdir().unwrap();
    let src = b"DEF bad()\nLIN {X 1,,Y 2}\nEND\n";
    lay_out(
        dir.path(),
        &[
            ("bad.src", file(src.to_vec())),
            (
                "cal.json",
                file(fixture("calibrations/kr30ha-example.json")),
            ),
        ],
    );
    let (exit, stderr) = run(dir.path(), &["check", "bad.src", "-c", "cal.json"]);
    assert_eq!(exit, 1, "{stderr}");
    assert_eq!(stderr.matches("--> bad.src:2:").count(), 1, "{stderr}");
}

/// A second batch into an output directory another batch holds is refused before writing.
#[test]
fn a_locked_output_directory_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    lay_out(
        dir.path(),
        &[
            (
                "lib/p.src",
                file(fixture("fixtures/programs/paper_path1.src")),
            ),
            (
                "cal.json",
                file(fixture("calibrations/kr30ha-example.json")),
            ),
            ("out", Entry::Dir),
        ],
    );
    let held = std::fs::File::open(dir.path().join("out")).unwrap();
    let flock = |op| {
        use std::os::unix::io::AsRawFd;
        // SAFETY: `flock` on a descriptor the test owns.
        assert_eq!(unsafe { libc::flock(held.as_raw_fd(), op) }, 0);
    };
    flock(libc::LOCK_EX | libc::LOCK_NB);
    let before = tree(dir.path());
    let (exit, stderr) = run(dir.path(), &["batch", "lib", "-c", "cal.json", "-o", "out"]);
    assert_eq!(exit, 2, "{stderr}");
    assert!(
        stderr.contains("another robopost batch is writing into this directory"),
        "{stderr}"
    );
    assert_eq!(tree(dir.path()), before);
    flock(libc::LOCK_UN);
    let (exit, stderr) = run(dir.path(), &["batch", "lib", "-c", "cal.json", "-o", "out"]);
    assert_eq!(exit, 0, "{stderr}");
    assert!(dir.path().join("out/p.src").is_file());
}

/// A library with a link back up its tree is walked once; temporary files a killed run left
/// in the output are removed (only robopost's own, only older than the run), and a program
/// of the library is written once.
#[test]
fn batch_walks_a_looping_library_once_and_cleans_stale_temporary_files() {
    let dir = tempfile::tempdir().unwrap();
    let program = fixture("fixtures/programs/paper_path1.src");
    lay_out(
        dir.path(),
        &[
            ("lib/a/p.src", file(program.clone())),
            ("lib/b/q.src", file(program)),
            ("lib/a/loop", Entry::Link("..")),
            ("lib/b/again", Entry::Link("../a")),
            (
                "cal.json",
                file(fixture("calibrations/kr30ha-example.json")),
            ),
            ("out/a/.robopost-Ab12Cd", file("half a program")),
            ("out/a/.robopost-notOurs1", file("someone else's")),
            ("out/a/.robopost-Young1", file("a live run's")),
        ],
    );
    let old = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
    let f = std::fs::File::options()
        .write(true)
        .open(dir.path().join("out/a/.robopost-Ab12Cd"))
        .unwrap();
    f.set_modified(old).unwrap();
    let young = std::time::SystemTime::now() + std::time::Duration::from_secs(3600);
    let f = std::fs::File::options()
        .write(true)
        .open(dir.path().join("out/a/.robopost-Young1"))
        .unwrap();
    f.set_modified(young).unwrap();
    let (exit, stderr) = run(dir.path(), &["batch", "lib", "-c", "cal.json", "-o", "out"]);
    assert_eq!(exit, 0, "{stderr}");
    assert!(
        stderr.contains("batch: 2 of 2 programs written"),
        "{stderr}"
    );
    assert!(
        stderr.contains("note: removed 1 temporary file(s)"),
        "{stderr}"
    );
    let written: Vec<PathBuf> = tree(&dir.path().join("out")).into_keys().collect();
    let expected: Vec<PathBuf> = [
        "a",
        "a/.robopost-Young1",
        "a/.robopost-notOurs1",
        "a/p.src",
        "b",
        "b/q.src",
    ]
    .iter()
    .map(PathBuf::from)
    .collect();
    assert_eq!(written, expected);
}

/// Ways of naming the file `name` of `dir` again.
#[derive(Clone, Copy, Debug)]
enum Alias {
    Same,
    Dot,
    UpAndBack,
    MissingUpAndBack,
    Symlink,
    HardLink,
}

fn alias(dir: &Path, name: &str, how: Alias) -> String {
    match how {
        Alias::Same => name.to_string(),
        Alias::Dot => format!("./{name}"),
        Alias::UpAndBack => {
            std::fs::create_dir_all(dir.join("sub")).unwrap();
            format!("sub/../{name}")
        }
        Alias::MissingUpAndBack => format!("nowhere/../{name}"),
        Alias::Symlink => {
            let link = format!("link-{name}");
            std::os::unix::fs::symlink(name, dir.join(&link)).unwrap();
            link
        }
        Alias::HardLink => {
            let link = format!("hard-{name}");
            std::fs::hard_link(dir.join(name), dir.join(&link)).unwrap();
            link
        }
    }
}

/// A command that writes, its inputs, and how its command line names an output.
#[derive(Clone, Copy, Debug)]
enum Writer {
    ProgramOut,
    ProgramReport,
    Identify,
    SimulateCampaign,
    SimulateProgram,
    BatchReport,
}

impl Writer {
    fn inputs(self) -> &'static [&'static str] {
        match self {
            Writer::ProgramOut | Writer::ProgramReport => &["p.src", "p.dat", "cal.json"],
            Writer::Identify => &["m.csv", "cal.json"],
            Writer::SimulateCampaign => &["t.json"],
            Writer::SimulateProgram => &["t.json", "p.src", "p.dat"],
            Writer::BatchReport => &["cal.json", "p.src", "p.dat"],
        }
    }

    fn args(self, out: &str) -> Vec<String> {
        let s = |v: &[&str]| v.iter().map(|a| a.to_string()).collect::<Vec<_>>();
        let mut args = match self {
            Writer::ProgramOut => s(&["p.src", "-c", "cal.json", "-o"]),
            Writer::ProgramReport => s(&["p.src", "-c", "cal.json", "-o", "fresh.src", "--report"]),
            Writer::Identify => s(&[
                "identify",
                "m.csv",
                "-c",
                "cal.json",
                "--effects",
                "+drift",
                "-o",
            ]),
            Writer::SimulateCampaign => s(&["simulate", "campaign", "--truth", "t.json", "-o"]),
            Writer::SimulateProgram => {
                s(&["simulate", "program", "--truth", "t.json", "p.src", "-o"])
            }
            Writer::BatchReport => s(&[
                "batch", "p.src", "-c", "cal.json", "-o", "fresh", "--report",
            ]),
        };
        args.push(out.to_string());
        args
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// No command writes to a path it read, however the path is spelled or linked.
    #[test]
    fn no_command_writes_a_path_it_read(
        writer in prop::sample::select(vec![
            Writer::ProgramOut, Writer::ProgramReport, Writer::Identify,
            Writer::SimulateCampaign, Writer::SimulateProgram, Writer::BatchReport,
        ]),
        how in prop::sample::select(vec![
            Alias::Same, Alias::Dot, Alias::UpAndBack, Alias::MissingUpAndBack,
            Alias::Symlink, Alias::HardLink,
        ]),
        pick in 0usize..3,
    ) {
        let dir = tempfile::tempdir().unwrap();
        let mut files = program();
        files.push(("m.csv", file(campaign(30))));
        files.push(("t.json", file(fixture("fixtures/measurements/kr30ha-truth.json"))));
        lay_out(dir.path(), &files);
        let inputs = writer.inputs();
        let target = inputs[pick % inputs.len()];
        let out = alias(dir.path(), target, how);
        let before = tree(dir.path());
        let args = writer.args(&out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (exit, stderr) = run(dir.path(), &args);
        prop_assert_eq!(exit, 2, "{:?} {:?}: {}", writer, args, stderr);
        prop_assert!(stderr.contains("nothing written, choose another output"), "{}", stderr);
        prop_assert_eq!(tree(dir.path()), before);
    }
}
