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
