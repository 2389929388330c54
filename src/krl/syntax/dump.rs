//! A compact, human-readable dump of what the parser understood: one line per statement with
//! its line number and nesting, motions with their targets, numbers printed as the values
//! read (not the text), binary operators parenthesised to show precedence, folds with their
//! inline-form parameters, then the problems. Used by snapshot tests and for debugging.

use super::decl::{Decl, DeclVar, ParamMode, RoutineHeader};
use super::expr::{Access, Expr, UnOp};
use super::fold::Ilf;
use super::motion::{ApproxKind, Motion, RelFrameKind, WithItem};
use super::stmt::{Action, Anout, ArmKind, Interrupt, Stmt, StmtKind, Trigger};
use super::tree::SourceFile;
use std::fmt::Write;

/// The dump of a whole file.
pub fn dump(file: &SourceFile) -> String {
    dump_limited(file, usize::MAX)
}

/// The dump with at most `max_lines` statement lines (the first ones and the last fifth),
/// so huge generated programs give readable snapshots.
pub fn dump_limited(file: &SourceFile, max_lines: usize) -> String {
    let st = file.stats();
    let mut out = format!(
        "{:?}: {} statements, {} routines, {} motions, {} declared points, {} opaque, {} invalid, {} folds ({} inline forms), {} errors, {} warnings\n",
        file.kind(),
        st.statements,
        st.routines,
        st.motions,
        st.declared_points,
        st.opaque,
        st.invalid,
        st.folds,
        st.inline_forms,
        st.errors,
        st.warnings
    );
    let mut lines = Vec::new();
    for s in file.body() {
        stmt_lines(file, s, 0, &mut lines);
    }
    if lines.len() > max_lines {
        let tail = max_lines / 5;
        let head = max_lines - tail;
        let skipped = lines.len() - head - tail;
        lines.splice(
            head..lines.len() - tail,
            [format!("… {skipped} lines not shown …")],
        );
    }
    for l in lines {
        out += &l;
        out.push('\n');
    }
    let folds = file.folds();
    if !folds.is_empty() {
        out += "folds:\n";
        for f in folds.iter().take(max_lines) {
            let close = f
                .close_line
                .map_or("unclosed".to_string(), |l| format!("L{l}"));
            let _ = write!(
                out,
                "  L{}-{} {:?}",
                f.open_line,
                close,
                file.text_lossy(f.title)
            );
            if let Some(ilf) = &f.ilf {
                out += " ";
                out += &ilf_text(file, ilf);
            }
            out.push('\n');
        }
        if folds.len() > max_lines {
            let _ = writeln!(out, "  … {} folds not shown …", folds.len() - max_lines);
        }
    }
    if !file.problems().is_empty() {
        out += "problems:\n";
        for p in file.problems() {
            let (l, c) = file.line_col(p.span.start as usize);
            let _ = writeln!(out, "  {l}:{c} {}: {}", p.severity, p.message);
        }
    }
    out
}

fn stmt_lines(file: &SourceFile, s: &Stmt, depth: usize, out: &mut Vec<String>) {
    let pad = "  ".repeat(depth);
    let mut line = format!("L{:<5} {pad}{}", s.line, stmt_text(file, s));
    if let Some((_, ilf)) = file.inline_form(s).filter(|_| s.as_motion().is_some()) {
        line += "  ⟨";
        line += &ilf_text(file, ilf);
        line += "⟩";
    }
    if s.block.as_ref().is_some_and(|b| b.end.is_none()) {
        line += "  (unclosed)";
    }
    out.push(line);
    if let Some(b) = &s.block {
        for c in &b.body {
            stmt_lines(file, c, depth + 1, out);
        }
        for a in &b.arms {
            let arm = match &a.kind {
                ArmKind::Else => "ELSE".to_string(),
                ArmKind::Default => "DEFAULT".to_string(),
                ArmKind::Case(v) => format!("CASE {}", list(file, v)),
            };
            out.push(format!("L{:<5} {pad}{arm}", a.clause.line));
            for c in &a.body {
                stmt_lines(file, c, depth + 1, out);
            }
        }
    }
}

fn stmt_text(f: &SourceFile, s: &Stmt) -> String {
    let t = |span| f.text_lossy(span).into_owned();
    let e = |x: &Expr| expr_text(f, x);
    match &s.kind {
        StmtKind::Directive(d) => format!("&{} {}", t(d.name), t(d.value)),
        StmtKind::Routine(h) => routine_text(f, h),
        StmtKind::DefDat(h) => format!(
            "DEFDAT {}{}",
            t(h.name),
            if h.public.is_some() { " PUBLIC" } else { "" }
        ),
        StmtKind::Decl(d) => decl_text(f, d),
        StmtKind::Struc(st) => {
            let fields: Vec<String> = st
                .fields
                .iter()
                .map(|(ty, vars)| format!("{} {}", t(ty.span), vars_text(f, vars)))
                .collect();
            format!("STRUC {} {}", t(st.name), fields.join("; "))
        }
        StmtKind::Enum(en) => {
            let v: Vec<String> = en.values.iter().map(|v| t(*v)).collect();
            format!("ENUM {} {}", t(en.name), v.join(", "))
        }
        StmtKind::Signal(sg) => format!(
            "SIGNAL {} {}{}",
            t(sg.name),
            e(&sg.from),
            sg.to
                .as_ref()
                .map_or(String::new(), |x| format!(" TO {}", e(x)))
        ),
        StmtKind::Ext(x) => format!(
            "{}{} {}{}",
            if x.function { "EXTFCT" } else { "EXT" },
            if x.protected { "P" } else { "" },
            t(x.name),
            t(x.params)
        ),
        StmtKind::Motion(m) => motion_text(f, f.motion(*m)),
        StmtKind::Spline(h) => format!(
            "{}{}",
            if h.ptp { "PTP_SPLINE" } else { "SPLINE" },
            with_text(f, &h.with)
        ),
        StmtKind::Assign(a) => format!("{} = {}", e(&a.lhs), e(&a.rhs)),
        StmtKind::Call(c) => format!("call {}", e(&Expr::Call(c.clone()))),
        StmtKind::If(c) => format!("IF {}", e(c)),
        StmtKind::Switch(c) => format!("SWITCH {}", e(c)),
        StmtKind::For(Some(fo)) => format!(
            "FOR {} = {} TO {}{}",
            t(fo.var),
            e(&fo.from),
            e(&fo.to),
            fo.step
                .as_ref()
                .map_or(String::new(), |x| format!(" STEP {}", e(x)))
        ),
        StmtKind::For(None) => format!("FOR ‹{}›", t(s.head)),
        StmtKind::While(c) => format!("WHILE {}", e(c)),
        StmtKind::Repeat(c) => format!(
            "REPEAT … UNTIL {}",
            c.as_ref().map_or("?".to_string(), |x| e(x))
        ),
        StmtKind::Loop => "LOOP".into(),
        StmtKind::Exit => "EXIT".into(),
        StmtKind::Halt => "HALT".into(),
        StmtKind::Continue => "CONTINUE".into(),
        StmtKind::OnErrorProceed => "ON_ERROR_PROCEED".into(),
        StmtKind::Resume => "RESUME".into(),
        StmtKind::Anout(a) => anout_text(f, a),
        StmtKind::Brake(fl) => format!("BRAKE{}", if fl.is_some() { " F" } else { "" }),
        StmtKind::Return(v) => format!(
            "RETURN{}",
            v.as_ref().map_or(String::new(), |x| format!(" {}", e(x)))
        ),
        StmtKind::Goto(l) => format!("GOTO {}", t(*l)),
        StmtKind::Label(l) => format!("label {}", t(*l)),
        StmtKind::WaitFor(c) => format!("WAIT FOR {}", e(c)),
        StmtKind::WaitSec(c) => format!("WAIT SEC {}", e(c)),
        StmtKind::Interrupt(i) => interrupt_text(f, i),
        StmtKind::Trigger(tr) => trigger_text(f, tr),
        StmtKind::Invalid => format!("invalid ‹{}›", t(s.head)),
        StmtKind::Opaque => format!("opaque ‹{}›", t(s.head)),
    }
}

fn anout_text(f: &SourceFile, a: &Anout) -> String {
    let t = |span| f.text_lossy(span).into_owned();
    let e = |x: &Expr| expr_text(f, x);
    format!(
        "{} {} {}{}{}",
        if a.input { "ANIN" } else { "ANOUT" },
        if a.on { "ON" } else { "OFF" },
        e(&a.signal),
        a.value
            .as_ref()
            .map_or(String::new(), |v| format!(" = {}", e(v))),
        a.options
            .iter()
            .map(|(n, v)| format!(" {}={}", t(*n), e(v)))
            .collect::<String>()
    )
}

fn interrupt_text(f: &SourceFile, i: &Interrupt) -> String {
    let t = |span| f.text_lossy(span).into_owned();
    let e = |x: &Expr| expr_text(f, x);
    match i {
        Interrupt::Decl {
            global,
            prio,
            cond,
            action,
        } => format!(
            "{}INTERRUPT DECL {} WHEN {} DO {}",
            if global.is_some() { "GLOBAL " } else { "" },
            e(prio),
            e(cond),
            action_text(f, action)
        ),
        Interrupt::Control { op, number } => format!(
            "INTERRUPT {}{}",
            t(*op).to_ascii_uppercase(),
            number
                .as_ref()
                .map_or(String::new(), |x| format!(" {}", e(x)))
        ),
    }
}

fn trigger_text(f: &SourceFile, tr: &Trigger) -> String {
    let e = |x: &Expr| expr_text(f, x);
    format!(
        "TRIGGER WHEN {:?} = {}{}{} DO {}{}",
        tr.when,
        e(&tr.value),
        if tr.onstart.is_some() { " ONSTART" } else { "" },
        tr.delay
            .as_ref()
            .map_or(String::new(), |x| format!(" DELAY = {}", e(x))),
        action_text(f, &tr.action),
        tr.prio
            .as_ref()
            .map_or(String::new(), |x| format!(" PRIO = {}", e(x)))
    )
}

fn action_text(f: &SourceFile, a: &Action) -> String {
    match a {
        Action::Call(c) => expr_text(f, c),
        Action::Assign(a) => format!("{} = {}", expr_text(f, &a.lhs), expr_text(f, &a.rhs)),
    }
}

fn routine_text(f: &SourceFile, h: &RoutineHeader) -> String {
    let params: Vec<String> = h
        .params
        .iter()
        .map(|p| {
            format!(
                "{}{}{}",
                f.text_lossy(p.name),
                p.array
                    .map_or(String::new(), |a| f.text_lossy(a).into_owned()),
                match p.mode {
                    ParamMode::In => ":IN",
                    ParamMode::Out => ":OUT",
                    ParamMode::Default => "",
                }
            )
        })
        .collect();
    format!(
        "{}{}{} {}({})",
        if h.global.is_some() { "GLOBAL " } else { "" },
        if h.function { "DEFFCT" } else { "DEF" },
        h.ret
            .map_or(String::new(), |r| format!(" {}", f.text_lossy(r.span))),
        f.text_lossy(h.name),
        params.join(", ")
    )
}

fn decl_text(f: &SourceFile, d: &Decl) -> String {
    format!(
        "decl {}{}{:?}({}) {}",
        if d.global.is_some() { "GLOBAL " } else { "" },
        if d.constant.is_some() { "CONST " } else { "" },
        d.ty.kind,
        f.text_lossy(d.ty.span),
        vars_text(f, &d.vars)
    )
}

fn vars_text(f: &SourceFile, vars: &[DeclVar]) -> String {
    let v: Vec<String> = vars
        .iter()
        .map(|v| {
            let mut s = f.text_lossy(v.name).into_owned();
            if let Some(d) = &v.dims {
                let sizes: Vec<String> = d
                    .sizes
                    .iter()
                    .map(|x| x.as_ref().map_or(String::new(), |x| expr_text(f, x)))
                    .collect();
                s += &format!("[{}]", sizes.join(","));
            }
            if let Some(init) = &v.init {
                s += " = ";
                s += &expr_text(f, init);
            }
            s
        })
        .collect();
    v.join(", ")
}

fn motion_text(f: &SourceFile, m: &Motion) -> String {
    let mut s = m.kind.keyword().to_string();
    if let Some(a) = m.aux() {
        s += &format!(" aux={}", expr_text(f, a));
    }
    s += &format!(" target={}", expr_text(f, &m.target));
    if let Some(ca) = m.angle() {
        s += &format!(" CA={}", expr_text(f, &ca.value));
    }
    for a in m.approx().iter() {
        s += match a.kind {
            ApproxKind::Dis => " C_DIS",
            ApproxKind::Ptp => " C_PTP",
            ApproxKind::Vel => " C_VEL",
            ApproxKind::Ori => " C_ORI",
            ApproxKind::Spl => " C_SPL",
        };
    }
    if let Some(fr) = m.frame() {
        s += match fr.kind {
            RelFrameKind::Base => " #BASE",
            RelFrameKind::Tool => " #TOOL",
        };
    }
    s += &with_text(f, m.with());
    s
}

fn with_text(f: &SourceFile, with: &[WithItem]) -> String {
    if with.is_empty() {
        return String::new();
    }
    let items: Vec<String> = with
        .iter()
        .map(|w| format!("{} = {}", expr_text(f, &w.lhs), expr_text(f, &w.value)))
        .collect();
    format!(" WITH {}", items.join(", "))
}

fn ilf_text(f: &SourceFile, ilf: &Ilf) -> String {
    let t = |s| f.text_lossy(s).into_owned();
    let mut out = String::from("ILF");
    if let (Some(c), Some(v)) = (ilf.command, ilf.variant) {
        out += &format!(" {}/{}", t(c), t(v));
    }
    if let Some(m) = &ilf.motion {
        out += &format!(" {}", m.kind.keyword());
        for p in &m.points {
            out += &format!(" {}", t(*p));
        }
        if m.cont.is_some() {
            out += " CONT";
        }
        if let Some(v) = &m.velocity {
            out += &format!(
                " vel={}{}",
                v.value,
                v.unit.map_or(String::new(), |u| format!(" {}", t(u)))
            );
        }
        if let Some(d) = m.data {
            out += &format!(" data={}", t(d));
        }
        for (name, fr) in [("tool", &m.tool), ("base", &m.base)] {
            if let Some(fr) = fr {
                out += &format!(
                    " {name}={}",
                    fr.index.map_or("?".to_string(), |i| i.to_string())
                );
                if let Some(n) = fr.name {
                    out += &format!(":{}", t(n));
                }
            }
        }
    }
    if !ilf.params.is_empty() {
        let p: Vec<String> = ilf
            .params
            .iter()
            .map(|(n, v)| format!("{n}:{}", t(*v)))
            .collect();
        out += &format!(" %P[{}]", p.join(", "));
    }
    if !ilf.settings.is_empty() {
        out += &format!(" settings={}", ilf.settings.len());
        if let Some(p) = ilf.setting(f.source(), "Kuka.PointName") {
            out += &format!(" PointName={}", String::from_utf8_lossy(p));
        }
    }
    out
}

fn list(f: &SourceFile, v: &[Expr]) -> String {
    v.iter()
        .map(|x| expr_text(f, x))
        .collect::<Vec<_>>()
        .join(", ")
}

/// An expression in canonical form.
pub fn expr_text(f: &SourceFile, e: &Expr) -> String {
    let t = |s| f.text_lossy(s).into_owned();
    match e {
        Expr::Number(n) => format!("{}", n.value),
        Expr::Str(s) | Expr::Bits(s) | Expr::Enum(s) => t(*s),
        Expr::Bool(_, v) => if *v { "TRUE" } else { "FALSE" }.into(),
        Expr::Path(p) => {
            let mut s = t(p.root);
            for a in &p.access {
                match a {
                    Access::Index {
                        span, slice: true, ..
                    } => s += &t(*span),
                    Access::Index { items, .. } => s += &format!("[{}]", list(f, items)),
                    Access::Field { name, .. } => s += &format!(".{}", t(*name)),
                }
            }
            s
        }
        Expr::Call(c) => {
            let args: Vec<String> = c
                .args
                .iter()
                .map(|a| a.as_ref().map_or(String::new(), |a| expr_text(f, a)))
                .collect();
            format!("{}({})", t(c.name), args.join(", "))
        }
        Expr::Aggregate(_, id) => {
            let a = f.aggregate(*id);
            let members: Vec<String> = f
                .members(a)
                .map(|m| {
                    format!(
                        "{}{} {}",
                        t(m.name),
                        f.member_index(&m).map_or(String::new(), t),
                        expr_text(f, &m.value)
                    )
                })
                .collect();
            format!(
                "{{{}{}}}",
                a.type_name()
                    .map_or(String::new(), |n| format!("{}: ", t(n))),
                members.join(", ")
            )
        }
        Expr::Unary(u) => {
            let op = match u.op {
                UnOp::Neg => "-",
                UnOp::Plus => "+",
                UnOp::Not => "NOT ",
                UnOp::BNot => "B_NOT ",
            };
            format!("{op}{}", expr_text(f, &u.operand))
        }
        Expr::Binary(b) => format!(
            "({} {} {})",
            expr_text(f, &b.lhs),
            b.op.symbol(),
            expr_text(f, &b.rhs)
        ),
        Expr::Paren(p) => format!("({})", expr_text(f, &p.inner)),
        Expr::Opaque(s) => format!("‹{}›", t(*s)),
    }
}
