//! The plan of a campaign (`docs/plan.md`): one row per stop the robot visits, in visiting
//! order — the test it belongs to, the name of the point the tracker records there (empty on
//! an approach stop, visited but not measured), the six command angles and, optionally, the
//! planned time. `campaign` writes it beside the program; `import` joins a tracker's export
//! to it, by point name or in order.

use std::io::Write;

use super::MeasureError;

/// The version line that opens a plan file (a comment to the readers).
pub const PLAN_VERSION: &str = "# robopost-plan/1";

/// One planned stop.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanStop {
    pub test: String,
    /// The point name the tracker records here; empty on an approach stop.
    pub point: String,
    pub axes_deg: [f64; 6],
    /// Planned seconds since the start of the campaign, when the plan gives them.
    pub time_s: Option<f64>,
    /// 1-based line in the plan file (0 when not read from one) and the point's column.
    pub line: usize,
    pub point_col: usize,
}

/// A plan as read.
#[derive(Clone, Debug, Default)]
pub struct Plan {
    pub source: String,
    pub stops: Vec<PlanStop>,
    lines: Vec<String>,
}

impl Plan {
    /// A located error at `line:col` of the plan.
    pub fn error(
        &self,
        line: usize,
        col: usize,
        message: String,
        help: Option<&str>,
    ) -> MeasureError {
        MeasureError::in_lines(&self.source, &self.lines, (line, col), message, help)
    }

    /// The measured stops (those with a point name).
    #[cfg(any(test, feature = "internals"))]
    pub fn measured(&self) -> impl Iterator<Item = &PlanStop> {
        self.stops.iter().filter(|s| !s.point.is_empty())
    }
}

/// Reads a plan: a header naming `test`, `point` (or `point name`, `name`), `a1`..`a6` and
/// optionally `t`, any order; `#` lines are comments. Point names must be unique.
pub fn parse_plan(bytes: &[u8], file: &str) -> Result<Plan, MeasureError> {
    let text = String::from_utf8_lossy(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes));
    let mut plan = Plan {
        source: file.to_string(),
        stops: Vec::new(),
        lines: super::text::lines(&text)
            .iter()
            .map(|l| l.to_string())
            .collect(),
    };
    let mut rows = plan
        .lines
        .iter()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((h, header)) = rows.next() else {
        return Err(plan.error(0, 0, "the plan is empty".into(), None));
    };
    let names: Vec<String> = super::text::fields(header, super::text::Separator::Comma)
        .iter()
        .map(|f| f.text.to_ascii_lowercase())
        .collect();
    let find = |n: &[&str]| names.iter().position(|h| n.contains(&h.as_str()));
    let missing = |n: &str| {
        plan.error(
            h + 1,
            1,
            format!("required column `{n}` is missing from the plan"),
            Some(
                "a plan's columns: test, point, a1..a6 [, t] (as `robopost campaign` writes them)",
            ),
        )
    };
    let test = find(&["test"]).ok_or_else(|| missing("test"))?;
    let point = find(&["point", "point name", "name"]).ok_or_else(|| missing("point"))?;
    let mut axes = [0; 6];
    for (k, a) in axes.iter_mut().enumerate() {
        let n = format!("a{}", k + 1);
        *a = find(&[n.as_str()]).ok_or_else(|| missing(&n))?;
    }
    let t = find(&["t"]);
    let rows: Vec<(usize, String)> = rows.map(|(i, l)| (i + 1, l.clone())).collect();
    let mut seen: std::collections::HashMap<String, usize> = Default::default();
    for (line, raw) in rows {
        let f = super::text::fields(&raw, super::text::Separator::Comma);
        if f.len() != names.len() {
            return Err(plan.error(
                line,
                1,
                format!("{} fields, the header has {}", f.len(), names.len()),
                None,
            ));
        }
        let number = |i: usize, what: &str| -> Result<f64, MeasureError> {
            f[i].text
                .parse::<f64>()
                .ok()
                .filter(|v| v.abs() <= super::TIME_RANGE_S)
                .ok_or_else(|| {
                    plan.error(
                        line,
                        f[i].col,
                        format!("`{}` is not a number ({what})", f[i].text),
                        None,
                    )
                })
        };
        let mut axes_deg = [0.0; 6];
        for k in 0..6 {
            axes_deg[k] = number(axes[k], &format!("a{}", k + 1))?;
            if axes_deg[k].abs() > super::ANGLE_RANGE_DEG {
                return Err(plan.error(line, f[axes[k]].col, "an angle beyond ±720°".into(), None));
            }
        }
        let time_s = match t {
            Some(c) if !f[c].text.is_empty() => Some(number(c, "t")?),
            _ => None,
        };
        let name = f[point].text.to_string();
        if !name.is_empty() {
            if let Some(first) = seen.insert(name.clone(), line) {
                return Err(plan.error(
                    line,
                    f[point].col,
                    format!("point `{name}` is planned twice (first on line {first})"),
                    Some("each measured stop needs its own point name"),
                ));
            }
        }
        plan.stops.push(PlanStop {
            test: f[test].text.to_string(),
            point: name,
            axes_deg,
            time_s,
            line,
            point_col: f[point].col,
        });
    }
    Ok(plan)
}

/// Writes a plan (with its version line and the `t` column).
pub fn write_plan<W: Write>(mut out: W, stops: &[PlanStop]) -> std::io::Result<()> {
    writeln!(out, "{PLAN_VERSION}")?;
    writeln!(out, "test,point,a1,a2,a3,a4,a5,a6,t")?;
    for s in stops {
        write!(out, "{},{}", s.test, s.point)?;
        for a in s.axes_deg {
            write!(out, ",{a:.6}")?;
        }
        match s.time_s {
            Some(t) => writeln!(out, ",{t:.1}")?,
            None => writeln!(out, ",")?,
        }
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_doubled_names() {
        let stops = vec![
            PlanStop {
                test: "A1".into(),
                point: String::new(),
                axes_deg: [-62.0, -60.0, 100.0, 0.0, 45.0, 0.0],
                time_s: Some(0.0),
                line: 0,
                point_col: 0,
            },
            PlanStop {
                test: "A1".into(),
                point: "P0001".into(),
                axes_deg: [-60.0, -60.0, 100.0, 0.0, 45.0, 0.0],
                time_s: Some(3.3),
                line: 0,
                point_col: 0,
            },
        ];
        let mut buf = Vec::new();
        write_plan(&mut buf, &stops).unwrap();
        let back = parse_plan(&buf, "p.csv").unwrap();
        assert_eq!(back.stops.len(), 2);
        assert_eq!(back.stops[1].point, "P0001");
        assert_eq!(back.stops[1].axes_deg, stops[1].axes_deg);
        assert_eq!((back.stops[1].line, back.stops[1].point_col), (4, 4));
        assert_eq!(back.measured().count(), 1);
        let twice = String::from_utf8(buf).unwrap() + "A1,P0001,0,0,0,0,0,0,9\n";
        let e = parse_plan(twice.as_bytes(), "p.csv").unwrap_err();
        assert_eq!((e.line, e.col), (5, 4));
        assert!(e.message.contains("first on line 4"), "{}", e.message);
        let e = parse_plan(b"test,a1,a2,a3,a4,a5,a6\n", "p.csv").unwrap_err();
        assert!(e.message.contains("`point`"));
    }
}
