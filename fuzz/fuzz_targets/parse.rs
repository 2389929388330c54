//! Fuzz target for the KRL parser: any bytes, as a program and as a data list, must parse
//! without panicking, emit back byte for byte, be covered exactly by the tree's tiles, keep
//! every number's text readable as its value, and render every problem; parsed with streamed
//! runs, the skeleton emits the bytes too, its statements plus the windows' are the whole
//! parse's, and it or a window has an error exactly where the whole parse has one.

#![no_main]

use libfuzzer_sys::fuzz_target;
use robopost::krl::{self, FileKind};

fuzz_target!(|data: &[u8]| {
    for kind in [FileKind::Src, FileKind::Dat] {
        let f = krl::parse_recovering(data, kind);
        assert_eq!(f.emit(), data);
        let mut at = 0;
        for (span, _) in f.tiles() {
            assert_eq!(span.start as usize, at);
            at = span.end as usize;
        }
        assert_eq!(at, data.len());
        for (_, m) in f.motions() {
            for n in f.numbers(&m.target) {
                let text = std::str::from_utf8(f.text(n.span())).expect("numbers are ASCII");
                let want: f64 = text.parse().expect("a number's text is a number");
                assert_eq!(want.to_bits(), n.value.to_bits(), "{text}");
            }
        }
        for p in f.problems() {
            let _ = f.diagnostic(p, "fuzz.src").render();
        }
        let _ = krl::dump::dump(&f);
        let _ = f.stats();
    }
    let whole = krl::parse_recovering(data, FileKind::Src);
    let opts = krl::StreamOptions { min_run: 1, window: 2 };
    let parsed = krl::parse_streaming(data.to_vec(), FileKind::Src, opts);
    let skeleton = match &parsed {
        Ok(f) => f,
        Err(e) => e.recovered(),
    };
    assert_eq!(skeleton.emit(), data);
    let key = |s: &krl::Stmt| (s.line, s.head.start, s.head.end);
    let mut got: Vec<_> = skeleton.statements().map(key).collect();
    // What the line scan takes as plain is parsed by the grammar when its window is: an error
    // only the grammar sees (a member given twice) is found there, as the main job finds it.
    let mut window_errors = false;
    for run in skeleton.streamed_runs() {
        for w in run.windows() {
            let window = skeleton.window(w);
            window_errors |= window.has_errors();
            got.extend(window.statements().map(key));
        }
    }
    assert_eq!(parsed.is_err() || window_errors, whole.has_errors());
    got.sort_by_key(|k| k.1);
    assert_eq!(got, whole.statements().map(key).collect::<Vec<_>>());
});
