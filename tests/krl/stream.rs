//! Streamed runs (`krl::parse_streaming`): the skeleton still emits the file byte for byte,
//! and the skeleton's statements plus those of every window are exactly the statements of
//! the whole-file parse, with the same spans, lines and kinds.

use robopost::krl::{self, FileKind, SourceFile, StreamOptions};

/// (line, head, kind) of every statement, nested ones included.
fn statements(f: &SourceFile) -> Vec<(u32, krl::Span, String)> {
    f.statements()
        .map(|s| {
            let kind = format!("{:?}", s.kind);
            let kind = kind
                .split(['(', ' '])
                .next()
                .unwrap_or_default()
                .to_string();
            (s.line, s.head, kind)
        })
        .collect()
}

fn check(path: &std::path::Path, opts: StreamOptions) -> usize {
    let bytes = std::fs::read(path).unwrap();
    let whole = krl::parse_recovering(&bytes, FileKind::Src);
    let Ok(skeleton) = krl::parse_streaming(bytes.clone(), FileKind::Src, opts) else {
        assert!(
            whole.has_errors(),
            "{}: only a file with errors fails",
            path.display()
        );
        return 0;
    };
    assert_eq!(
        skeleton.emit(),
        bytes,
        "{}: skeleton round trip",
        path.display()
    );
    let mut got = statements(&skeleton);
    let mut covered = 0;
    for run in skeleton.streamed_runs() {
        let mut at = run.range.start;
        for w in run.windows() {
            assert_eq!(w.0.start, at, "windows tile their run");
            at = w.0.end;
            let window = skeleton.window(w);
            assert_eq!(window.extent(), w.0);
            assert!(window.problems().is_empty(), "{:?}", window.problems());
            for s in window.body() {
                assert_eq!(window.line_col(s.head.start as usize).0, s.line as usize);
                assert_eq!(whole.line_col(s.head.start as usize).0, s.line as usize);
            }
            got.extend(statements(&window));
        }
        assert_eq!(at, run.range.end);
        covered += run.range.len();
    }
    got.sort_by_key(|s| s.1.start);
    assert_eq!(got, statements(&whole), "{}: statements", path.display());
    covered
}

#[test]
fn skeleton_and_windows_are_the_whole_parse() {
    let tiny = StreamOptions {
        min_run: 1,
        window: 2,
    };
    let mut covered = 0;
    for path in super::files_under("programs") {
        if FileKind::from_path(&path) == FileKind::Src {
            covered += check(&path, tiny);
            check(
                &path,
                StreamOptions {
                    min_run: 3,
                    window: 5,
                },
            );
        }
    }
    assert!(
        covered > 100_000,
        "runs cover {covered} bytes of the fixtures"
    );
}

#[test]
fn only_plain_lines_of_the_main_routine_stream() {
    let src = b"DEF m()\r\n  DECL E6POS P\r\n  LIN {X 1, Y 2}\r\n  $VEL.CP = 0.2 ; slow\r\n\r\n  PTP {A1 1}\r\n  LIN P\r\n  LIN {X 3} C_DIS\r\n  $BASE = {X 1}\r\n  CIRC {X 1,Y 2}, {X 3,Y 4}\r\n  CIRC {X 1,Y 2}, {X 3,Y 4}, CA 90\r\n  WAIT SEC 1\r\n;FOLD x\r\n  LIN {X 4}\r\n;ENDFOLD\r\nEND\r\nDEF sub()\r\n  LIN {X 5}\r\n  LIN {X 6}\r\nEND\r\n";
    let opts = StreamOptions {
        min_run: 1,
        window: 2,
    };
    let f = krl::parse_streaming(src.to_vec(), FileKind::Src, opts).unwrap();
    let runs: Vec<(String, u32)> = f
        .streamed_runs()
        .iter()
        .map(|r| {
            (
                String::from_utf8_lossy(&src[r.range.range()]).into_owned(),
                r.before,
            )
        })
        .collect();
    assert_eq!(
        runs,
        [
            (
                "  LIN {X 1, Y 2}\r\n  $VEL.CP = 0.2 ; slow\r\n\r\n  PTP {A1 1}\r\n".to_string(),
                1
            ),
            ("  LIN {X 3} C_DIS\r\n".to_string(), 2),
            ("  CIRC {X 1,Y 2}, {X 3,Y 4}\r\n".to_string(), 3),
            ("  WAIT SEC 1\r\n".to_string(), 4),
        ]
    );
    let w: Vec<_> = f.streamed_runs()[0]
        .windows()
        .map(|(s, l)| (s.start, l))
        .collect();
    assert_eq!(w.len(), 2, "two plain lines per window: {w:?}");
    assert_eq!(w[1].1, 6, "the second window starts at line 6 (PTP)");
    // Runs shorter than `min_run` stay in the tree.
    let f = krl::parse_streaming(
        src.to_vec(),
        FileKind::Src,
        StreamOptions {
            min_run: 3,
            window: 2,
        },
    )
    .unwrap();
    assert_eq!(f.streamed_runs().len(), 1);
    assert_eq!(f.emit(), src);
}

/// A line the parser rejects is never streamed: a motion with three approximation keywords or
/// a member given twice fails the streamed parse as it fails the whole one (the old streaming
/// look took both for plain lines, and the streamed job then left them uncompensated).
#[test]
fn malformed_motions_are_not_streamed() {
    let opts = StreamOptions {
        min_run: 1,
        window: 2,
    };
    for bad in ["LIN {X 1, Y 2} C_DIS C_DIS C_DIS", "LIN {X 1, x 2} C_DIS"] {
        let src = format!("DEF m()\r\n  LIN {{X 0}}\r\n  {bad}\r\n  LIN {{X 3}}\r\nEND\r\n");
        assert!(krl::parse(src.as_bytes(), FileKind::Src).is_err(), "{bad}");
        let streamed = krl::parse_streaming(src.into_bytes(), FileKind::Src, opts);
        assert!(streamed.is_err(), "{bad}");
    }
}
