//! The streamed parse against the whole one.

use super::*;

/// Looking at the lines in parallel first changes nothing of a streamed parse: the same
/// runs and windows, the same tree (emitted byte for byte), the same problems — on a
/// program with folds, comments, blank lines, non-plain lines between plain ones and a
/// run cut into windows.
#[test]
fn the_parallel_look_parses_alike() {
    let mut text = String::from("DEF p( )\r\n;FOLD INI\r\nBAS(#INITMOV,0)\r\n;ENDFOLD\r\n");
    for i in 0..400 {
        match i % 37 {
            5 => text.push_str("; a comment\r\n\r\n"),
            11 => text.push_str("IF $IN[3] THEN\r\n  LIN {X 1}\r\nENDIF\r\n"),
            23 => text.push_str("$VEL.CP = 0.1\n"),
            _ => text.push_str(&format!("LIN {{X {i}.5,Y -2,Z 3}} C_DIS\r\n")),
        }
    }
    text.push_str("END\r\n");
    let src = text.as_bytes();
    let opts = StreamOptions {
        min_run: 3,
        window: 7,
    };
    let parse = |parallel_look| {
        let opts = BuildOptions {
            stream: Some(opts),
            parallel_look,
            keep_values: false,
        };
        let mut file = build_in(src, FileKind::Src, 0..src.len(), 1, opts);
        file.src = Arc::new(src.to_vec());
        file
    };
    let (plain, looked) = (parse(usize::MAX), parse(0));
    assert!(plain.runs.len() > 5, "{} runs", plain.runs.len());
    assert_eq!(looked.runs, plain.runs);
    assert_eq!(looked.emit(), plain.emit());
    assert_eq!(
        format!("{:?}", looked.problems),
        format!("{:?}", plain.problems)
    );
    assert_eq!(format!("{:?}", looked.body), format!("{:?}", plain.body));
}

/// A streamed window keeps its plain members' values as the parser read them, so that
/// the walk does not read them again: each must be the number read back from the bytes,
/// to the bit; a whole-file tree keeps none.
#[test]
fn windows_keep_the_values_read() {
    let mut text = String::from("DEF p( )\n");
    let numbers = [
        "0",
        "-0.000",
        "+12.5",
        "123456.789012",
        ".5",
        "1E3",
        "-7.",
        "99999999999999999999.5",
        "0.1",
        "-1234.5678",
    ];
    for i in 0..60 {
        let (a, b) = (
            numbers[i % numbers.len()],
            numbers[(i * 7 + 3) % numbers.len()],
        );
        text.push_str(&format!("LIN {{X {a}, Y {b},Z {i}.25, A -{i}.5}} C_DIS\n"));
    }
    text.push_str("END\n");
    let src = text.as_bytes();
    let opts = StreamOptions {
        min_run: 3,
        window: 7,
    };
    let file = parse_streaming(src.to_vec(), FileKind::Src, opts).expect("parses");
    assert!(!file.streamed_runs().is_empty());
    let plain_members = |f: &SourceFile| {
        let mut out = Vec::new();
        for a in f.nodes.aggregates.iter().filter(|a| !a.nested()) {
            for m in f.raw_members(a) {
                if let super::super::nodes::RawMember::Plain { number, kept, .. } = m {
                    out.push((
                        super::super::nodes::RawMember::plain_value(f.source(), number),
                        kept,
                    ));
                }
            }
        }
        out
    };
    assert!(plain_members(&file).iter().all(|(_, kept)| kept.is_none()));
    let (mut kept_count, mut windows) = (0, 0);
    for run in file.streamed_runs() {
        for w in run.windows() {
            windows += 1;
            for (read, kept) in plain_members(&file.window(w)) {
                assert_eq!(kept.map(f64::to_bits), read.map(f64::to_bits));
                kept_count += 1;
            }
        }
    }
    assert!(
        windows > 5 && kept_count > 150,
        "{windows} windows, {kept_count} kept"
    );
}
