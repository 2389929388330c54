//! Malformed motions, declarations and aggregates: each bad fixture is rejected, the tree
//! still round-trips, and the rendered message (file:line:col, source line, caret, hint) is
//! snapshotted.

use robopost::krl::{self, FileKind};

#[test]
fn bad_inputs_are_rejected_with_located_messages() {
    insta::glob!("../../fixtures/bad", "*.{src,dat}", |path| {
        let bytes = std::fs::read(path).unwrap();
        let err = krl::parse(&bytes, FileKind::from_path(path)).expect_err("must be rejected");
        assert_eq!(err.partial().emit(), bytes);
        let name = format!("bad/{}", path.file_name().unwrap().to_string_lossy());
        insta::assert_snapshot!(err.render(&name));
    });
}

#[test]
fn garbage_is_opaque_not_an_error() {
    let src = b"DEF g()\n%%% ^^^ garbage\nFOO BAR BAZ\n12 34\n}{\nEND\n";
    let file = krl::parse(src, FileKind::Src).expect("opaque lines are not errors");
    assert_eq!(file.stats().opaque, 4);
    assert_eq!(file.emit(), src);
}

/// 10⁵ nested blocks: the blocks past the depth limit are kept as written with one warning,
/// their closers are theirs (no "ENDIF without an open IF"), the motion inside is still
/// found once the limit is passed the other way, and the file round-trips. (It once took
/// `check` minutes: a warning per line, each counting the lines before it.)
#[test]
fn deep_nesting_gives_one_warning_and_no_false_strays() {
    let n = 100_000;
    let mut src = b"DEF nest()\n".to_vec();
    for i in 0..n {
        src.extend_from_slice(if i % 3 == 2 {
            b"WHILE TRUE\n"
        } else {
            b"IF $IN[1] THEN\n"
        });
    }
    src.extend_from_slice(b"LIN {X 1000,Y 0,Z 1000,A 0,B 90,C 0}\nELSE\n");
    for i in (0..n).rev() {
        src.extend_from_slice(if i % 3 == 2 {
            b"ENDWHILE\n"
        } else {
            b"ENDIF\n"
        });
    }
    src.extend_from_slice(b"PTP {A1 0,A2 -90,A3 90,A4 0,A5 0,A6 0}\nEND\n");
    let file = krl::parse(&src, FileKind::Src).expect("deep nesting is not an error");
    assert_eq!(file.emit(), src);
    let messages: Vec<&str> = file.problems().iter().map(|p| p.message.as_str()).collect();
    assert_eq!(
        messages.len(),
        1,
        "{:?}",
        &messages[..messages.len().min(5)]
    );
    assert!(
        messages[0].contains("nested more than 200 deep"),
        "{}",
        messages[0]
    );
    assert_eq!(file.line_col(file.problems()[0].span.start as usize).0, 201);
    // The motion after the nest is in the routine's own body again.
    assert_eq!(file.motions().count(), 2);
    let d = file.diagnostic(&file.problems()[0], "nest.src");
    assert_eq!((d.line, d.col), (201, 1));
}
