//! What the parser understood of each program style, checked against values read off the
//! fixtures by hand (or, for generated fixtures, recomputed from the generator's formulas).

use super::fixture;
use robopost::krl::{
    self, Access, ApproxKind, ArmKind, BinOp, Expr, MotionKind, ParamMode, RelFrameKind,
    SourceFile, StmtKind, Symbols, TypeKind,
};

fn text(f: &SourceFile, span: krl::Span) -> String {
    f.text_lossy(span).into_owned()
}

fn motions(f: &SourceFile) -> Vec<&krl::Motion> {
    f.motions().map(|(_, m)| m).collect()
}

fn path_text(f: &SourceFile, e: &Expr) -> String {
    text(f, e.span())
}

#[test]
fn teach_pendant_inline_forms_resolve_through_the_dat() {
    let (_, src) = fixture("teach/pick_place.src");
    let (_, dat) = fixture("teach/pick_place.dat");
    let syms = Symbols::new(&[&dat, &src]);
    let ms: Vec<_> = src.motions().collect();
    let summary: Vec<String> = ms
        .iter()
        .map(|(s, m)| {
            format!(
                "{} {} {}",
                s.line,
                m.kind.keyword(),
                path_text(&src, &m.target)
            )
        })
        .collect();
    assert_eq!(
        summary,
        [
            "24 PTP XHOME",
            "32 PTP XP1",
            "40 LIN XP2",
            "55 LIN XP3",
            "63 CIRC XP5",
            "76 PTP XHOME"
        ]
    );
    // PTP P1 CONT Vel=100 % PDAT1 Tool[1]:Gripper Base[2]:Table
    let (stmt, m) = ms[1];
    assert_eq!(m.approx().len(), 1);
    assert_eq!(m.approx().get(0).unwrap().kind, ApproxKind::Ptp);
    let (fold, ilf) = src.inline_form(stmt).expect("inside an ILF fold");
    assert_eq!(fold.open_line, 27);
    assert_eq!(fold.close_line, Some(33));
    assert_eq!(text(&src, ilf.module.unwrap()), "KUKATPBASIS");
    assert_eq!(text(&src, ilf.command.unwrap()), "MOVE");
    assert_eq!(text(&src, ilf.variant.unwrap()), "PTP");
    let params: Vec<(u32, String)> = ilf
        .params
        .iter()
        .map(|(n, v)| (*n, text(&src, *v)))
        .collect();
    assert_eq!(
        params,
        [
            (1, "PTP".into()),
            (2, "P1".into()),
            (3, "C_PTP".into()),
            (5, "100".into()),
            (7, "PDAT1".into())
        ]
    );
    let im = ilf.motion.as_ref().unwrap();
    assert_eq!(im.kind, MotionKind::Ptp);
    assert!(im.cont.is_some());
    let v = im.velocity.unwrap();
    assert_eq!(
        (v.value, text(&src, v.unit.unwrap())),
        (100.0, "%".to_string())
    );
    assert_eq!(text(&src, im.data.unwrap()), "PDAT1");
    let tool = im.tool.unwrap();
    assert_eq!(
        (tool.index, text(&src, tool.name.unwrap())),
        (Some(1), "Gripper".into())
    );
    let base = im.base.unwrap();
    assert_eq!(
        (base.index, text(&src, base.name.unwrap())),
        (Some(2), "Table".into())
    );
    // Names KUKA gives the data, resolved in the .dat.
    let x = im.position_var(src.source(), 0).unwrap();
    assert_eq!(x, b"XP1");
    let sym = syms.get(&x).expect("XP1 declared in the .dat");
    assert_eq!(sym.decl.ty.kind, TypeKind::E6Pos);
    let agg = dat.aggregate_of(sym.var.init.as_ref().unwrap()).unwrap();
    let xn = dat.member_number(agg, "X").unwrap();
    assert_eq!((xn.value, dat.text(xn.span())), (812.441, &b"812.441"[..]));
    assert_eq!(dat.member_number(agg, "A").unwrap().value, -172.25);
    let pd = syms
        .get(&im.motion_data_var(src.source()).unwrap())
        .unwrap();
    assert_eq!(pd.decl.ty.kind, TypeKind::Pdat);
    let fd = syms.get(&im.frame_data_var(src.source()).unwrap()).unwrap();
    let fa = dat.aggregate_of(fd.var.init.as_ref().unwrap()).unwrap();
    assert_eq!(dat.member_number(fa, "BASE_NO").unwrap().value, 2.0);
    assert!(matches!(
        *dat.member(fa, "IPO_FRAME").unwrap().value,
        Expr::Enum(_)
    ));
    // LIN P2 Vel=0.5 m/s CPDAT1: path motion data is LDAT L + name.
    let (s2, _) = ms[2];
    let im2 = src.inline_form(s2).unwrap().1.motion.as_ref().unwrap();
    assert_eq!(im2.velocity.unwrap().value, 0.5);
    assert_eq!(im2.motion_data_var(src.source()).unwrap(), b"LCPDAT1");
    assert!(syms.get(b"lcpdat1").is_some(), "names are case-insensitive");
    // CIRC P4 P5: auxiliary point and target.
    let (s4, circ) = ms[4];
    assert_eq!(path_text(&src, circ.aux().unwrap()), "XP4");
    assert_eq!(circ.approx().len(), 2);
    let im4 = src.inline_form(s4).unwrap().1.motion.as_ref().unwrap();
    let pts: Vec<String> = im4.points.iter().map(|p| text(&src, *p)).collect();
    assert_eq!(pts, ["P4", "P5"]);
    assert_eq!(ms[4].1.kind, MotionKind::Circ);
    // Old form with `Vel= 100` and no %R.
    let im0 = src.inline_form(ms[0].0).unwrap().1.motion.as_ref().unwrap();
    assert_eq!(im0.velocity.unwrap().value, 100.0);
    assert_eq!(text(&src, im0.data.unwrap()), "DEFAULT");
    // Folds nest: BASISTECH INI and USER INI inside INI.
    let folds = src.folds();
    assert_eq!(text(&src, folds[0].title), "INI");
    assert_eq!(folds[1].parent, Some(krl::FoldId(0)));
    assert_eq!(folds[2].parent, Some(krl::FoldId(0)));
    assert!(folds.iter().all(|f| f.close.is_some()));
    // The OUT form is an inline form without a motion.
    let out = folds
        .iter()
        .find(|f| text(&src, f.title).starts_with("OUT 17"))
        .unwrap();
    assert!(out.ilf.as_ref().unwrap().motion.is_none());
    assert_eq!(src.stats().inline_forms, 10);
    assert_eq!(dat.stats().declared_points, 5);
}

#[test]
fn spline_inline_forms_with_parameter_folds() {
    let (_, src) = fixture("teach_spline/weld_seam.src");
    let ms: Vec<_> = src.motions().collect();
    let kinds: Vec<_> = ms.iter().map(|(_, m)| m.kind).collect();
    use MotionKind::*;
    assert_eq!(kinds, [Sptp, Sptp, Slin, Scirc, Sptp]);
    let (s, sc) = ms[3];
    assert_eq!(path_text(&src, sc.aux().unwrap()), "XS3");
    assert_eq!(path_text(&src, &sc.target), "XS4");
    assert_eq!(sc.angle().unwrap().value.as_number().unwrap().value, 180.0);
    assert_eq!(sc.approx().get(0).unwrap().kind, ApproxKind::Spl);
    assert_eq!(sc.with().len(), 12);
    let vel = &sc.with()[0];
    assert_eq!(path_text(&src, &vel.lhs), "$VEL");
    let Expr::Call(c) = &vel.value else { panic!() };
    assert_eq!(text(&src, c.name), "SVEL_CP");
    assert_eq!(c.args.len(), 3);
    assert!(
        c.args[1].is_none(),
        "the empty argument of SVEL_CP(0.012, , LCPDAT5)"
    );
    let (_, ilf) = src.inline_form(s).unwrap();
    assert_eq!(
        ilf.setting(src.source(), "Kuka.PointName"),
        Some(&b"S4"[..])
    );
    assert_eq!(
        ilf.setting(src.source(), "kuka.auxpointname"),
        Some(&b"S3"[..])
    );
    assert_eq!(ilf.setting(src.source(), "IlfCommand"), Some(&b"SCIRC"[..]));
    let im = ilf.motion.as_ref().unwrap();
    assert_eq!(im.kind, Scirc);
    assert_eq!(im.velocity.unwrap().value, 0.012);
    assert_eq!(im.motion_data_var(src.source()).unwrap(), b"LCPDAT5");
    // SPTP S1 CONT … C_SPL: ILF says CONT, the motion says C_SPL.
    let (s1, m1) = ms[1];
    assert_eq!(m1.approx().get(0).unwrap().kind, ApproxKind::Spl);
    let im1 = src.inline_form(s1).unwrap().1.motion.as_ref().unwrap();
    assert!(im1.cont.is_some());
    assert_eq!(im1.motion_data_var(src.source()).unwrap(), b"PPDAT2");
    assert_eq!(im1.tool.unwrap().index, Some(3));
}

#[test]
fn cam_frame_array_driven_by_a_for_loop() {
    let (_, src) = fixture("cam_frame_array/contour_cnc.src");
    let (_, dat) = fixture("cam_frame_array/contour_cnc.dat");
    let syms = Symbols::new(&[&dat, &src]);
    let for_stmt = src
        .statements()
        .find(|s| matches!(s.kind, StmtKind::For(_)))
        .unwrap();
    let StmtKind::For(Some(f)) = &for_stmt.kind else {
        panic!()
    };
    assert_eq!(text(&src, f.var), "I");
    assert_eq!(f.from.as_number().unwrap().value, 2.0);
    assert_eq!(path_text(&src, &f.to), "NPTS");
    let body: Vec<_> = for_stmt.children().collect();
    assert_eq!(body.len(), 1);
    let m = src.motion_of(body[0]).unwrap();
    let p = m.target.as_path().unwrap();
    assert_eq!(text(&src, p.root), "CNC1");
    let Access::Index { items, .. } = &p.access[0] else {
        panic!()
    };
    assert_eq!(path_text(&src, &items[0]), "I");
    // The array and element 17 (generator: t = 2π·16/240, x = 400 + 150 cos t + 12 cos 5t …).
    let decl = syms.get(b"CNC1").unwrap();
    assert_eq!(decl.decl.ty.kind, TypeKind::Frame);
    let (file, e) = syms.element(b"cnc1", &[17]).unwrap();
    let a = file.aggregate_of(e).unwrap();
    let t = 2.0 * std::f64::consts::PI * 16.0 / 240.0;
    let want = [
        ("X", 400.0 + 150.0 * t.cos() + 12.0 * (5.0 * t).cos()),
        ("Y", 90.0 * t.sin() + 12.0 * (5.0 * t).sin()),
        ("Z", 35.0 + 4.0 * (3.0 * t).sin()),
        ("A", t.to_degrees() - 180.0),
        ("B", 15.0 * t.sin()),
        ("C", 180.0 - 10.0 * t.cos()),
    ];
    for (name, v) in want {
        let got = file.member_number(a, name).unwrap().value;
        assert!((got - v).abs() <= 0.5e-4 + 1e-12, "{name}: {got} vs {v}");
    }
    assert!(syms.element(b"CNC1", &[241]).is_none());
    let npts = syms.get(b"NPTS").unwrap().var.init.as_ref().unwrap();
    assert_eq!(npts.as_number().unwrap().value, 240.0);
    assert_eq!(dat.stats().declared_points, 240);
}

#[test]
fn generated_cam_program_has_every_lin() {
    let (bytes, f) = fixture("cam/pocket_milling.src");
    let lines_with_lin = bytes
        .split(|&b| b == b'\n')
        .filter(|l| l.starts_with(b"LIN {"))
        .count();
    let lins = motions(&f)
        .iter()
        .filter(|m| m.kind == MotionKind::Lin && m.target.as_aggregate().is_some())
        .count();
    assert_eq!(lins, lines_with_lin);
    assert!(lins >= 20_000);
    // First LIN of layer 1 (after the start PTP and the approach LIN), pass 0, k = 0: x = 0, y = 0, z = -1 + 0.35 sin 0 cos 0 = -1,
    // b = 90 + 4.5 cos 0 = 94.5, c = 2 sin 0 = 0.
    let first = motions(&f)
        .into_iter()
        .filter_map(|m| f.aggregate_of(&m.target))
        .nth(2)
        .unwrap();
    let v = |n| f.member_number(first, n).unwrap().value;
    assert_eq!(
        (v("X"), v("Y"), v("Z"), v("B"), v("C")),
        (0.0, 0.0, -1.0, 94.5, 0.0)
    );
}

#[test]
fn robodk_style_split_program() {
    let (_, main) = fixture("robodk/drill_cell.src");
    let calls: Vec<String> = main
        .statements()
        .filter_map(|s| match &s.kind {
            StmtKind::Call(c) => Some(text(&main, c.name)),
            _ => None,
        })
        .collect();
    assert_eq!(calls, ["BAS", "drill_cell1", "drill_cell2", "drill_cell3"]);
    let (_, p1) = fixture("robodk/drill_cell1.src");
    let base = p1
        .statements()
        .find_map(|s| match &s.kind {
            StmtKind::Assign(a) if path_text(&p1, &a.lhs) == "$BASE" => Some(a),
            _ => None,
        })
        .unwrap();
    let agg = p1.aggregate_of(&base.rhs).unwrap();
    assert_eq!(text(&p1, agg.type_name().unwrap()), "FRAME");
    assert_eq!(p1.member_number(agg, "X").unwrap().value, 1200.0);
    let ms = motions(&p1);
    assert_eq!(ms.len(), 7);
    let axis = p1.aggregate_of(&ms[1].target).unwrap();
    assert_eq!(text(&p1, axis.type_name().unwrap()), "AXIS");
    assert_eq!(p1.member_number(axis, "A2").unwrap().value, -78.4);
    assert_eq!(ms[6].approx().get(0).unwrap().kind, ApproxKind::Dis);
    let z = p1
        .member_number(p1.aggregate_of(&ms[4].target).unwrap(), "Z")
        .unwrap();
    assert_eq!((z.value, p1.text(z.span())), (-12.5, &b"-12.500"[..]));
}

#[test]
fn every_language_construct() {
    let (_, f) = fixture("language/coverage.src");
    let routines: Vec<String> = f
        .routines()
        .map(|(_, h)| {
            let ps: Vec<String> = h
                .params
                .iter()
                .map(|p| {
                    format!(
                        "{}{}{:?}",
                        text(&f, p.name),
                        p.array.map_or(String::new(), |a| text(&f, a)),
                        p.mode
                    )
                })
                .collect();
            format!("{}{} {}", h.global.is_some(), h.function, ps.join(","))
        })
        .collect();
    assert_eq!(
        routines,
        [
            "truefalse countIn,table[,]Out",
            "falsetrue valueIn",
            "falsefalse "
        ]
    );
    let (_, fct) = f.routines().nth(1).unwrap();
    assert_eq!(fct.ret.unwrap().kind, TypeKind::Real);
    assert_eq!(fct.params[0].mode, ParamMode::In);

    let all: Vec<_> = f.statements().collect();
    let find = |pred: &dyn Fn(&krl::Stmt) -> bool| *all.iter().find(|s| pred(s)).unwrap();
    // $BASE = BASE_DATA[2] : {X 10}
    let s = find(&|s| f.text(s.head).starts_with(b"$BASE"));
    let StmtKind::Assign(a) = &s.kind else {
        panic!()
    };
    let Expr::Binary(b) = &a.rhs else { panic!() };
    assert_eq!(b.op, BinOp::Geo);
    assert_eq!(path_text(&f, &b.lhs), "BASE_DATA[2]");
    assert!(b.rhs.as_aggregate().is_some());
    // Motions.
    let ms = motions(&f);
    let kinds: Vec<&str> = ms.iter().map(|m| m.kind.keyword()).collect();
    assert_eq!(
        kinds,
        [
            "PTP", "PTP", "PTP", "LIN", "LIN", "LIN", "LIN", "LIN", "CIRC", "CIRC", "LIN_REL",
            "LIN_REL", "PTP_REL", "CIRC_REL", "LIN", "PTP", "LIN"
        ]
    );
    let e6 = f.aggregate_of(&ms[2].target).unwrap();
    assert_eq!(text(&f, e6.type_name().unwrap()), "E6POS");
    assert_eq!(f.member_number(e6, "Y").unwrap().value, -25.0);
    assert_eq!(f.member_number(e6, "Z").unwrap().value, 0.25);
    assert!(matches!(*f.member(e6, "S").unwrap().value, Expr::Bits(_)));
    assert_eq!(ms[3].approx().get(0).unwrap().kind, ApproxKind::Vel);
    let Expr::Binary(g) = &ms[4].target else {
        panic!()
    };
    assert_eq!(
        (g.op, path_text(&f, &g.lhs), path_text(&f, &g.rhs)),
        (BinOp::Geo, "pickPos".into(), "offset".into())
    );
    assert_eq!(ms[6].approx().get(0).unwrap().kind, ApproxKind::Ori);
    let p = ms[7].target.as_path().unwrap();
    let Access::Index { items, .. } = &p.access[0] else {
        panic!()
    };
    assert_eq!(items.len(), 2);
    assert_eq!(
        ms[8].angle().unwrap().value.as_number().unwrap().value,
        90.0
    );
    assert!(ms[9].angle().is_none());
    assert_eq!(ms[10].frame().unwrap().kind, RelFrameKind::Tool);
    assert_eq!(ms[11].frame().unwrap().kind, RelFrameKind::Base);
    assert_eq!(ms[11].approx().get(0).unwrap().kind, ApproxKind::Dis);
    assert_eq!(
        ms[13].angle().unwrap().value.as_number().unwrap().value,
        -45.5
    );
    assert_eq!(ms[15].approx().get(0).unwrap().kind, ApproxKind::Ptp);
    // Control flow.
    let ifs: Vec<_> = all
        .iter()
        .filter(|s| matches!(s.kind, StmtKind::If(_)))
        .collect();
    assert_eq!(ifs.len(), 3);
    let b0 = ifs[0].block.as_ref().unwrap();
    assert_eq!((b0.body.len(), b0.arms.len()), (1, 1));
    assert_eq!(b0.arms[0].kind, ArmKind::Else);
    assert_eq!(b0.end.unwrap().line, ifs[0].line + 4);
    let StmtKind::If(c) = &ifs[0].kind else {
        panic!()
    };
    let Expr::Binary(and) = &**c else { panic!() };
    assert_eq!(and.op, BinOp::And);
    let sw = find(&|s| matches!(s.kind, StmtKind::Switch(_)));
    let arms: Vec<String> = sw
        .block
        .as_ref()
        .unwrap()
        .arms
        .iter()
        .map(|a| match &a.kind {
            ArmKind::Case(v) => format!("case{}", v.len()),
            k => format!("{k:?}"),
        })
        .collect();
    assert_eq!(arms, ["case2", "case1", "Default"]);
    let fors: Vec<_> = all
        .iter()
        .filter_map(|s| match &s.kind {
            StmtKind::For(Some(f)) => Some(f),
            _ => None,
        })
        .collect();
    assert_eq!(fors.len(), 2);
    assert_eq!(
        fors[0].step.as_ref().unwrap().as_number().unwrap().value,
        2.0
    );
    assert_eq!(
        fors[1].step.as_ref().unwrap().as_number().unwrap().value,
        -1.0
    );
    let rep = find(&|s| matches!(s.kind, StmtKind::Repeat(_)));
    let StmtKind::Repeat(Some(u)) = &rep.kind else {
        panic!()
    };
    let Expr::Binary(ge) = &**u else { panic!() };
    assert_eq!(ge.op, BinOp::Ge);
    let lp = find(&|s| matches!(s.kind, StmtKind::Loop));
    let inner: Vec<_> = lp.children().collect();
    assert!(matches!(inner[0].kind, StmtKind::If(_)));
    assert!(matches!(
        inner[0].children().next().unwrap().kind,
        StmtKind::Exit
    ));
    for kind in [
        "Label",
        "Goto",
        "WaitFor",
        "WaitSec",
        "Brake",
        "Trigger",
        "Interrupt",
        "Return",
        "Halt",
        "Continue",
    ] {
        assert!(
            all.iter()
                .any(|s| format!("{:?}", s.kind).starts_with(kind)),
            "{kind}"
        );
    }
    let trig: Vec<_> = all
        .iter()
        .filter_map(|s| match &s.kind {
            StmtKind::Trigger(t) => Some(t),
            _ => None,
        })
        .collect();
    assert_eq!(
        trig[0].delay.as_ref().unwrap().as_number().unwrap().value,
        20.0
    );
    assert_eq!(
        trig[1].prio.as_ref().unwrap().as_number().unwrap().value,
        -1.0
    );
    let st = f.stats();
    // `IMPORT` alone stays opaque (ANIN and ON_ERROR_PROCEED are understood).
    assert_eq!((st.opaque, st.routines, st.motions), (1, 3, 17));
    // The string with a semicolon is code, not a comment.
    let lt = find(&|s| f.text(s.head).starts_with(b"label_text"));
    let StmtKind::Assign(a) = &lt.kind else {
        panic!()
    };
    assert_eq!(f.text(a.rhs.span()), b"\"start; go\"");
}

#[test]
fn data_list_declarations() {
    let (_, d) = fixture("language/coverage.dat");
    let syms = Symbols::new(&[&d]);
    assert_eq!(
        syms.get(b"xHomePose").unwrap().decl.ty.kind,
        TypeKind::E6Axis
    );
    assert!(
        syms.get(b"xHomePose").unwrap().decl.decl.is_none(),
        "DECL is optional"
    );
    assert!(syms.get(b"TOLERANCE").unwrap().decl.constant.is_some());
    assert!(syms.get(b"P_ARRAY").unwrap().decl.global.is_some());
    let (_, e) = syms.element(b"P_TABLE", &[1, 2]).unwrap();
    assert_eq!(d.members(d.aggregate_of(e).unwrap()).len(), 3);
    let job = d
        .aggregate_of(syms.get(b"job").unwrap().var.init.as_ref().unwrap())
        .unwrap();
    let inner = d
        .aggregate_of(&d.member(job, "fCnC").unwrap().value)
        .unwrap();
    assert_eq!(d.member_number(inner, "Z").unwrap().value, 3.5);
    assert_eq!(
        d.member_index(&d.member(job, "sName").unwrap())
            .map(|s| d.text(s)),
        Some(&b"[]"[..])
    );
    let spacing = syms.get(b"spacing").unwrap().var.init.as_ref().unwrap();
    assert_eq!(spacing.as_number().unwrap().value, 1.25);
    let strucs: Vec<_> = d
        .statements()
        .filter_map(|s| match &s.kind {
            StmtKind::Struc(st) => Some(st),
            _ => None,
        })
        .collect();
    assert_eq!(strucs[0].fields.len(), 3);
    assert!(d
        .statements()
        .any(|s| matches!(&s.kind, StmtKind::Signal(sg) if sg.to.is_some())));
    // P_ARRAY[1], [2] and P_TABLE[1,2] are initialised elements; P_AUX, P_END, xHomePose.
    assert_eq!(d.stats().declared_points, 6);
}

#[test]
fn code_pages_and_line_endings_are_kept() {
    let (bytes, f) = fixture("encodings/palletize_cp1252.src");
    assert!(bytes.contains(&0xDF) && bytes.contains(&0xF1)); // ß, ñ in Windows-1252
    assert_eq!(f.emit(), bytes);
    let msg = f
        .statements()
        .find_map(|s| match &s.kind {
            StmtKind::Assign(a) if path_text(&f, &a.lhs) == "msg[]" => Some(a),
            _ => None,
        })
        .unwrap();
    assert_eq!(
        f.text(msg.rhs.span()),
        b"\"Dr\xfccken Sie Start; Teil fertig\""
    );
    assert_eq!(f.stats().motions, 2);
    let (bytes, f) = fixture("encodings/spawanie_cp1250.src");
    assert!(bytes.contains(&0xB9)); // ą in Windows-1250
    assert_eq!(f.stats().motions, 2);
    let (bytes, f) = fixture("encodings/utf8_bom.src");
    assert!(bytes.starts_with(b"\xEF\xBB\xBF"));
    assert_eq!(f.routines().count(), 1);

    let (bytes, f) = fixture("endings/mixed_endings.src");
    assert!(!bytes.ends_with(b"\n"));
    let lines: Vec<u32> = f.statements().map(|s| s.line).collect();
    assert_eq!(lines, [1, 2, 3, 7, 8]);
    let (def, _) = f.routines().next().unwrap();
    assert_eq!(def.block.as_ref().unwrap().end.unwrap().line, 10);
    assert!(f.trailing().is_empty());
    assert_eq!(f.line_col(bytes.len() - 1), (10, 3));
    let (_, d) = fixture("endings/no_final_newline.dat");
    assert_eq!(d.stats().declared_points, 1);
}

#[test]
fn long_data_lines() {
    let (bytes, d) = fixture("long_lines/weld_table.dat");
    assert!(bytes.split(|&b| b == b'\n').any(|l| l.len() > 1300));
    let syms = Symbols::new(&[&d]);
    let wtab = d
        .aggregate_of(syms.get(b"WTAB").unwrap().var.init.as_ref().unwrap())
        .unwrap();
    assert_eq!(wtab.len(), 39);
    let w39 = d
        .aggregate_of(&d.member(wtab, "W39").unwrap().value)
        .unwrap();
    // Generator: CUR 100+i .5, VOLT 18 + i%7 .25 → i = 39: 139.5, 22.25.
    assert_eq!(d.member_number(w39, "CUR").unwrap().value, 139.5);
    assert_eq!(d.member_number(w39, "VOLT").unwrap().value, 22.25);
    let p = d
        .aggregate_of(syms.get(b"XSEAM_START").unwrap().var.init.as_ref().unwrap())
        .unwrap();
    assert_eq!(d.member_number(p, "C").unwrap().value, 179.9999);
}

#[test]
fn spline_blocks() {
    let (_, f) = fixture("spline/glue_lid.src");
    let blocks: Vec<_> = f
        .statements()
        .filter_map(|s| match &s.kind {
            StmtKind::Spline(h) => Some((s, h)),
            _ => None,
        })
        .collect();
    assert_eq!(blocks.len(), 2);
    assert!(blocks[0].1.ptp);
    assert_eq!(blocks[0].1.with.len(), 2);
    let seg: Vec<String> = blocks[1]
        .0
        .children()
        .map(|s| match &s.kind {
            StmtKind::Motion(m) => f.motion(*m).kind.keyword().to_string(),
            StmtKind::Trigger(t) => format!(
                "TRIGGER {:?}{}",
                t.when,
                if t.onstart.is_some() { " ONSTART" } else { "" }
            ),
            k => format!("{k:?}"),
        })
        .collect();
    assert_eq!(
        seg,
        [
            "SPL",
            "TRIGGER Path ONSTART",
            "SLIN",
            "SCIRC",
            "SPL",
            "SLIN",
            "TRIGGER Path"
        ]
    );
    let ms = motions(&f);
    let rel = ms.iter().find(|m| m.kind == MotionKind::SlinRel).unwrap();
    assert_eq!(rel.frame().unwrap().kind, RelFrameKind::Tool);
    let chained = ms
        .iter()
        .find(|m| matches!(m.target, Expr::Binary(_)) && m.kind == MotionKind::Slin)
        .unwrap();
    assert_eq!(
        chained.approx().get(0).unwrap().kind,
        ApproxKind::Spl,
        "lower-case c_spl"
    );
    assert_eq!(chained.with().len(), 1);
    assert_eq!(path_text(&f, &ms.last().unwrap().target), "$AXIS_ACT");
    assert!(f.problems().is_empty(), "{:?}", f.problems());
}

#[test]
fn rewriting_every_number_of_the_cam_program_changes_nothing_else() {
    let (bytes, f) = fixture("cam/pocket_milling.src");
    let mut edits = krl::Edits::new();
    let mut want = Vec::new();
    for (_, m) in f.motions() {
        for n in f.numbers(&m.target) {
            let new = n.value + 0.0125;
            edits.replace(n.span(), krl::number::format_like(f.text(n.span()), new, 3));
            want.push(new);
        }
    }
    let out = edits.apply(&bytes).unwrap();
    let g = krl::parse(&out, krl::FileKind::Src).unwrap();
    let got: Vec<f64> = g
        .motions()
        .flat_map(|(_, m)| g.numbers(&m.target))
        .map(|n| n.value)
        .collect();
    assert_eq!(got.len(), want.len());
    for (a, b) in got.iter().zip(&want) {
        assert!((a - b).abs() <= 0.0005 + 1e-9, "{a} {b}");
    }
    // Outside the numbers, the bytes are the same.
    let skeleton = |file: &SourceFile| {
        let mut e = krl::Edits::new();
        for (_, m) in file.motions() {
            for n in file.numbers(&m.target) {
                e.replace(n.span(), "#");
            }
        }
        e.apply(file.source()).unwrap()
    };
    assert_eq!(skeleton(&f), skeleton(&g));
}

/// What system files (bas.src, kuka_internals, $config.dat) write: protected externals, string
/// results, sized array parameters, slices, `; FOLD` with a blank, `ON_ERROR_PROCEED`,
/// `ANOUT`/`ANIN` — each understood (not opaque), the blocks closed.
#[test]
fn system_file_forms() {
    let src = b"DEF sys( )\r\n\
EXTP  IR_STOPM ( )\r\n\
EXTFCTP CHAR[15] PLC_NAME (INT:IN )\r\n\
; FOLD INI\r\n\
  BAS (#INITMOV,0 )\r\n\
; ENDFOLD (INI)\r\n\
BASE_NAME[1,] = \"Table\"\r\n\
MatrixToRpy (lrT[,], f.A)\r\n\
ON_ERROR_PROCEED\r\n\
ANOUT ON $ANOUT[2] = 0.5 * $VEL_ACT DELAY=-0.1\r\n\
ANIN OFF rLevel\r\n\
END\r\n\
GLOBAL DEFFCT CHAR[15] K_ADDR(BASE_NO :IN)\r\n\
  RETURN \" \"\r\n\
ENDFCT\r\n\
DEFFCT INT INTERIMENERGY(STRVAR[256] :IN)\r\n\
ENDFCT\r\n";
    let f = krl::parse(src, krl::FileKind::Src).unwrap();
    assert!(f.problems().is_empty(), "{:?}", f.problems());
    assert_eq!(f.stats().opaque, 0);
    assert_eq!(f.stats().routines, 3);
    let heads: Vec<(String, String)> = f
        .routines()
        .map(|(_, h)| {
            (
                text(&f, h.name),
                h.params
                    .iter()
                    .map(|p| text(&f, p.span))
                    .collect::<Vec<_>>()
                    .join(","),
            )
        })
        .collect();
    assert_eq!(heads[1], ("K_ADDR".into(), "BASE_NO :IN".into()));
    assert_eq!(heads[2], ("INTERIMENERGY".into(), "STRVAR[256] :IN".into()));
    let exts: Vec<_> = f
        .statements()
        .filter_map(|s| match &s.kind {
            StmtKind::Ext(e) => Some((e.function, e.protected, text(&f, e.name))),
            _ => None,
        })
        .collect();
    assert_eq!(
        exts,
        [
            (false, true, "IR_STOPM".into()),
            (true, true, "PLC_NAME".into())
        ]
    );
    assert_eq!(f.folds().len(), 1);
    assert_eq!(text(&f, f.folds()[0].title), "INI");
    // Slices: a row (`[1,]`) and a whole array (`[,]`), kept apart from elements.
    let slices: Vec<(usize, bool)> = f
        .statements()
        .flat_map(|s| {
            let mut v = Vec::new();
            f.visit_stmt_exprs(s, &mut |e| {
                if let Expr::Path(p) = e {
                    for a in &p.access {
                        if let Access::Index { items, slice, .. } = a {
                            v.push((items.len(), *slice));
                        }
                    }
                }
            });
            v
        })
        .collect();
    assert_eq!(slices, [(1, true), (0, true), (1, false)]);
    let analog: Vec<(bool, bool)> = f
        .statements()
        .filter_map(|s| match &s.kind {
            StmtKind::Anout(a) => Some((a.input, a.on)),
            _ => None,
        })
        .collect();
    assert_eq!(analog, [(false, true), (true, false)]);
    assert_eq!(f.emit(), src);
}
