//! Property tests: any bytes round-trip; generated programs round-trip and every generated
//! motion is read back with the kind, member names and values that were written.

use proptest::prelude::*;
use robopost::krl::{self, FileKind, MotionKind};

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_bytes_round_trip(bytes in proptest::collection::vec(any::<u8>(), 0..3000), dat in any::<bool>()) {
        let kind = if dat { FileKind::Dat } else { FileKind::Src };
        let f = krl::parse_recovering(&bytes, kind);
        prop_assert_eq!(f.emit(), bytes);
    }

    #[test]
    fn krl_like_token_soup_round_trips(tokens in proptest::collection::vec(token(), 0..400)) {
        let bytes: Vec<u8> = tokens.concat();
        let f = krl::parse_recovering(&bytes, FileKind::Src);
        prop_assert_eq!(f.emit(), bytes.clone());
        for p in f.problems() {
            // Every problem renders without panicking.
            let _ = f.diagnostic(p, "soup.src").render();
        }
    }

    #[test]
    fn generated_programs_round_trip_and_read_back(lines in proptest::collection::vec(line(), 1..60),
                                                   crlf in any::<bool>(), final_newline in any::<bool>()) {
        let eol: &[u8] = if crlf { b"\r\n" } else { b"\n" };
        let mut src = b"DEF generated ( )".to_vec();
        let mut expected = Vec::new();
        for l in &lines {
            src.extend_from_slice(eol);
            src.extend_from_slice(&l.text);
            if let Some(m) = &l.motion {
                expected.push(m.clone());
            }
        }
        src.extend_from_slice(eol);
        src.extend_from_slice(b"END");
        if final_newline {
            src.extend_from_slice(eol);
        }
        let f = krl::parse(&src, FileKind::Src).map_err(|e| TestCaseError::fail(e.render("gen.src")))?;
        prop_assert_eq!(f.emit(), src.clone());
        let got: Vec<Gen> = f
            .motions()
            .map(|(_, m)| Gen {
                kind: m.kind,
                members: f
                    .members(f.aggregate_of(&m.target).unwrap())
                    .map(|mem| {
                        let n = mem.value.as_number().unwrap();
                        (f.text(mem.name).to_ascii_uppercase(), f.text(n.span()).to_vec(), n.value)
                    })
                    .collect(),
            })
            .collect();
        prop_assert_eq!(got, expected);
    }
}

fn token() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        Just(b"LIN ".to_vec()),
        Just(b"PTP".to_vec()),
        Just(b"CIRC ".to_vec()),
        Just(b"DECL E6POS ".to_vec()),
        Just(b"DEF x()".to_vec()),
        Just(b"END".to_vec()),
        Just(b"IF ".to_vec()),
        Just(b" THEN".to_vec()),
        Just(b"ENDIF".to_vec()),
        Just(b"SPLINE".to_vec()),
        Just(b"ENDSPLINE".to_vec()),
        Just(b";FOLD PTP P1 Vel=100 % PDAT1 Tool[1] Base[0];%{PE}%P 1:PTP, 2:P1".to_vec()),
        Just(b";FOLD Parameters ;%{h}".to_vec()),
        Just(b";Params Kuka.PointName=P1; x=".to_vec()),
        Just(b";ENDFOLD".to_vec()),
        Just(b"{".to_vec()),
        Just(b"}".to_vec()),
        Just(b"X ".to_vec()),
        Just(b",".to_vec()),
        Just(b":".to_vec()),
        Just(b"\"".to_vec()),
        Just(b"'".to_vec()),
        Just(b"#".to_vec()),
        Just(b"(".to_vec()),
        Just(b")".to_vec()),
        Just(b"[".to_vec()),
        Just(b"]".to_vec()),
        Just(b"=".to_vec()),
        Just(b" C_DIS".to_vec()),
        Just(b" WITH $VEL.CP = ".to_vec()),
        Just(b"\r\n".to_vec()),
        Just(b"\n".to_vec()),
        Just(b"\r".to_vec()),
        Just(b" ".to_vec()),
        Just(b"\t".to_vec()),
        Just(b";".to_vec()),
        (-1e6f64..1e6).prop_map(|v| format!("{v}").into_bytes()),
        "[a-zA-Z_$][a-zA-Z0-9_]{0,8}".prop_map(|s| s.into_bytes()),
        any::<u8>().prop_map(|b| vec![b]),
    ]
}

/// A generated motion: kind and members (upper-case name, number text, value of the text).
#[derive(Clone, Debug, PartialEq)]
struct Gen {
    kind: MotionKind,
    members: Vec<(Vec<u8>, Vec<u8>, f64)>,
}

#[derive(Clone, Debug)]
struct GenLine {
    text: Vec<u8>,
    motion: Option<Gen>,
}

fn number_text() -> impl Strategy<Value = String> {
    (-5000.0f64..5000.0, 0usize..7, 0u8..4).prop_map(|(v, d, style)| match style {
        0 => format!("{v:.d$}"),
        1 => {
            let t = format!("{:.d$}", v.abs() / 1000.0);
            let t = t.trim_start_matches('0');
            if t.is_empty() {
                "0".to_string()
            } else {
                t.to_string()
            }
        }
        2 => format!("{v:.d$E}"),
        _ => format!("{}", v.round() as i64),
    })
}

fn case(word: &str, mix: u8) -> String {
    match mix % 3 {
        0 => word.to_string(),
        1 => word.to_ascii_lowercase(),
        _ => word
            .chars()
            .enumerate()
            .map(|(i, c)| {
                if i % 2 == 0 {
                    c.to_ascii_lowercase()
                } else {
                    c
                }
            })
            .collect(),
    }
}

fn motion_line() -> impl Strategy<Value = GenLine> {
    let kinds = prop_oneof![
        Just(MotionKind::Ptp),
        Just(MotionKind::Lin),
        Just(MotionKind::Slin),
        Just(MotionKind::Sptp),
        Just(MotionKind::Spl),
        Just(MotionKind::LinRel),
    ];
    let names = proptest::sample::subsequence(vec!["X", "Y", "Z", "A", "B", "C", "E1", "A1"], 1..8);
    (
        kinds,
        names,
        proptest::collection::vec(number_text(), 8),
        proptest::collection::vec(0u8..4, 10),
        any::<u8>(),
        prop_oneof![
            Just(""),
            Just(" C_DIS"),
            Just(" C_PTP C_DIS"),
            Just(" ; comment {X 1"),
            Just("\t")
        ],
        proptest::option::of(prop_oneof![Just("FRAME"), Just("E6POS"), Just("POS")]),
    )
        .prop_map(|(kind, names, values, spaces, mix, tail, prefix)| {
            let sp = |k: usize| " ".repeat(spaces[k % spaces.len()] as usize);
            let mut text = format!("{}{} {{{}", sp(9), case(kind.keyword(), mix), sp(0));
            if let Some(p) = prefix {
                text += &format!("{p}:{}", sp(8));
            }
            let mut members = Vec::new();
            for (k, (name, value)) in names.iter().zip(&values).enumerate() {
                if k > 0 {
                    text += &format!("{},{}", sp(k), sp(k + 1));
                }
                let name = case(name, mix.wrapping_add(k as u8));
                text += &format!("{name} {value}");
                members.push((
                    name.to_ascii_uppercase().into_bytes(),
                    value.clone().into_bytes(),
                    value.parse::<f64>().unwrap(),
                ));
            }
            text += &format!("{}}}{tail}", sp(7));
            GenLine {
                text: text.into_bytes(),
                motion: Some(Gen { kind, members }),
            }
        })
}

fn other_line() -> impl Strategy<Value = GenLine> {
    prop_oneof![
        Just("; just a comment with { and \" and ;"),
        Just(""),
        Just("   \t"),
        Just(";FOLD LIN P1 Vel=2 m/s CPDAT1 Tool[1] Base[0];%{PE}%R 8.3.43,%MKUKATPBASIS,%CMOVE,%VLIN,%P 1:LIN, 2:P1, 3:, 5:2, 7:CPDAT1"),
        Just(";ENDFOLD"),
        Just("$VEL.CP = 0.2"),
        Just("msg[] = \"a; b\""),
        Just("BAS (#INITMOV,0 )"),
        Just("WAIT SEC 0.5"),
        Just("some opaque stuff ^^"),
    ]
    .prop_map(|t| GenLine {
        text: t.as_bytes().to_vec(),
        motion: None,
    })
}

fn line() -> impl Strategy<Value = GenLine> {
    prop_oneof![3 => motion_line(), 1 => other_line()]
}
