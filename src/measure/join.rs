//! A tracker's points joined to the campaign's plan, into the rows of the measurement CSV:
//! by point name (each planned name measured once, each measured name planned), or for a
//! continuous stream by its dwells — the reflector still, within a radius, for at least a set
//! time — matched in order to the plan's measured stops. Approach stops of the plan become
//! unmeasured rows; the time of a measured row is the export's clock shifted to the plan's
//! (the plan's own time where the export has none). Every point left over, doubled or missing
//! is a located error in the file it is in.

use super::export::{Export, Point};
use super::plan::Plan;
use super::{directions::infer_histories, MeasureError, Stop};
use crate::model::AxisState;

/// The rows of the measurement CSV and what the join did.
#[derive(Clone, Debug)]
pub struct Joined {
    pub stops: Vec<Stop>,
    /// Measured rows written.
    pub matched: usize,
    /// Approach stops of the plan (unmeasured rows).
    pub approach: usize,
    /// Planned points the export lacks, written as unmeasured rows (only with
    /// `allow_missing`).
    pub missing: Vec<String>,
}

/// Joins `exports` to `plan` by point name. A name of an export that the plan lacks, or
/// that is measured twice, is an error in the export; a planned point no export has is an
/// error in the plan unless `allow_missing` (then an unmeasured row, named in `missing`).
pub fn join_by_name(
    plan: &Plan,
    exports: &[Export],
    allow_missing: bool,
) -> Result<Joined, Vec<MeasureError>> {
    let mut errors = Vec::new();
    let planned: std::collections::HashMap<&str, usize> = plan
        .stops
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.point.is_empty())
        .map(|(i, s)| (s.point.as_str(), i))
        .collect();
    // For each planned stop, the export point measured there (export, point).
    let mut found: Vec<Option<(usize, usize)>> = vec![None; plan.stops.len()];
    for (e, export) in exports.iter().enumerate() {
        for (k, p) in export.points.iter().enumerate() {
            match planned.get(p.name.as_str()) {
                None => errors.push(export.error(
                    p.line,
                    p.name_col,
                    format!("point `{}` is not in the plan {}", p.name, plan.source),
                    Some("the point names must be those of the plan (as the campaign program names its stops)"),
                )),
                Some(&i) => match found[i] {
                    Some((fe, fk)) => {
                        let first = &exports[fe];
                        errors.push(export.error(
                            p.line,
                            p.name_col,
                            format!(
                                "point `{}` is measured twice (first at {}:{})",
                                p.name, first.source, first.points[fk].line
                            ),
                            Some("remove the repeated measurement, or give it its own name in the plan"),
                        ))
                    }
                    None => found[i] = Some((e, k)),
                },
            }
        }
    }
    let mut missing = Vec::new();
    for (i, s) in plan.stops.iter().enumerate() {
        if !s.point.is_empty() && found[i].is_none() {
            if allow_missing {
                missing.push(s.point.clone());
            } else {
                errors.push(plan.error(
                    s.line,
                    s.point_col,
                    format!("planned point `{}` is in no export", s.point),
                    Some("give the export that has it, or --allow-missing to write it as visited but not measured"),
                ));
            }
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    let measured: Vec<Option<&Point>> = found
        .iter()
        .map(|f| f.map(|(e, k)| &exports[e].points[k]))
        .collect();
    let mut joined = rows(plan, &measured);
    joined.missing = missing;
    Ok(joined)
}

/// How a stream's dwells are found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DwellRule {
    /// The shortest time the reflector must stay still, seconds.
    pub min_s: f64,
    /// How far from the dwell's running mean a sample may lie and still be still, mm.
    pub radius_mm: f64,
}

/// One dwell of a stream: the mean position of its samples, when it started, how long it
/// lasted, and where its first sample is.
#[derive(Clone, Debug, PartialEq)]
pub struct Dwell {
    pub point: Point,
    pub samples: usize,
    pub duration_s: f64,
}

/// The dwells of `samples` (time-ordered): each maximal run of samples within `radius_mm` of
/// the run's running mean that lasts at least `min_s`. Its position is the mean of the run,
/// its time the run's first sample's. `Err` names a sample whose time goes backwards.
pub fn dwells(export: &Export, rule: DwellRule) -> Result<Vec<Dwell>, MeasureError> {
    let s = &export.points;
    for w in s.windows(2) {
        if w[1].time_s < w[0].time_s {
            return Err(export.error(
                w[1].line,
                1,
                "the time goes backwards: a stream's samples must be in time order".into(),
                None,
            ));
        }
    }
    let time = |i: usize| s[i].time_s.unwrap_or(0.0);
    let mut out = Vec::new();
    let mut i = 0;
    while i < s.len() {
        let mut sum = s[i].mm;
        let mut j = i;
        while j + 1 < s.len() {
            let mean = sum / (j - i + 1) as f64;
            if (s[j + 1].mm - mean).norm() > rule.radius_mm {
                break;
            }
            j += 1;
            sum += s[j].mm;
        }
        let duration_s = time(j) - time(i);
        if duration_s >= rule.min_s {
            let n = j - i + 1;
            out.push(Dwell {
                point: Point {
                    mm: sum / n as f64,
                    ..s[i].clone()
                },
                samples: n,
                duration_s,
            });
            i = j + 1;
        } else {
            i += 1;
        }
    }
    Ok(out)
}

/// Joins the dwells of a stream to the plan's measured stops, in order; a count that differs
/// is an error at the first dwell or planned stop left over.
pub fn join_in_order(
    plan: &Plan,
    stream: &Export,
    found: &[Dwell],
) -> Result<Joined, Vec<MeasureError>> {
    let stops: Vec<usize> = (0..plan.stops.len())
        .filter(|&i| !plan.stops[i].point.is_empty())
        .collect();
    let help = "stops closer together than --radius merge, a dwell shorter than --dwell is motion: adjust them, or capture by point name";
    if found.len() > stops.len() {
        let d = &found[stops.len()];
        return Err(vec![stream.error(
            d.point.line,
            1,
            format!(
                "{} dwells in the stream, but the plan has {} measured stops: this one (t = {:.3} s, {:.3} s still) is left over",
                found.len(),
                stops.len(),
                d.point.time_s.unwrap_or(0.0),
                d.duration_s
            ),
            Some(help),
        )]);
    }
    if found.len() < stops.len() {
        let s = &plan.stops[stops[found.len()]];
        return Err(vec![plan.error(
            s.line,
            s.point_col,
            format!(
                "{} dwells in the stream {}, but the plan has {} measured stops: none is left for `{}`",
                found.len(),
                stream.source,
                stops.len(),
                s.point
            ),
            Some(help),
        )]);
    }
    let mut measured: Vec<Option<&Point>> = vec![None; plan.stops.len()];
    for (&i, d) in stops.iter().zip(found) {
        measured[i] = Some(&d.point);
    }
    Ok(rows(plan, &measured))
}

/// The measurement rows of `plan` with `measured[i]` at stop i; times from the export's clock
/// shifted so that the first measured stop has its planned time (0 without one).
fn rows(plan: &Plan, measured: &[Option<&Point>]) -> Joined {
    let offset = plan.stops.iter().zip(measured).find_map(|(s, p)| {
        p.and_then(|p| p.time_s)
            .map(|t| s.time_s.unwrap_or(0.0) - t)
    });
    let mut stops = Vec::with_capacity(plan.stops.len());
    let mut last_t = 0.0;
    let (mut matched, mut approach) = (0, 0);
    for (s, p) in plan.stops.iter().zip(measured) {
        let time_s = match (p.and_then(|p| p.time_s), offset) {
            (Some(t), Some(o)) => t + o,
            _ => s.time_s.unwrap_or(last_t),
        };
        last_t = time_s;
        if p.is_some() {
            matched += 1;
        } else if s.point.is_empty() {
            approach += 1;
        }
        stops.push(Stop {
            test: s.test.clone(),
            state: AxisState {
                time_s,
                ..AxisState::new(s.axes_deg)
            },
            measured_mm: p.map(|p| p.mm),
            line: s.line,
        });
    }
    let mut states: Vec<AxisState> = stops.iter().map(|s| s.state).collect();
    infer_histories(&mut states, &[]);
    for (stop, state) in stops.iter_mut().zip(states) {
        stop.state = state;
    }
    Joined {
        stops,
        matched,
        approach,
        missing: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::export::parse_export;
    use crate::measure::plan::parse_plan;
    use nalgebra::Vector3;

    const PLAN: &str = "test,point,a1,a2,a3,a4,a5,a6,t\n\
        A1,,-2,-60,100,0,45,0,0\n\
        A1,P1,0,-60,100,0,45,0,3.0\n\
        A1,P2,1,-60,100,0,45,0,6.0\n";

    #[test]
    fn by_name_in_any_order_with_the_plans_clock() {
        let plan = parse_plan(PLAN.as_bytes(), "plan.csv").unwrap();
        let export = parse_export(
            "Name;X;Y;Z;Time\nP2;4;5;6;10:00:03,5\nP1;1;2;3;10:00:00\n".as_bytes(),
            "e.csv",
            None,
            false,
        )
        .unwrap();
        let j = join_by_name(&plan, &[export], false).unwrap();
        assert_eq!((j.matched, j.approach), (2, 1));
        assert_eq!(j.stops[0].measured_mm, None);
        assert_eq!(j.stops[1].measured_mm, Some(Vector3::new(1.0, 2.0, 3.0)));
        assert_eq!(j.stops[2].measured_mm, Some(Vector3::new(4.0, 5.0, 6.0)));
        // P1 at its planned 3.0 s; P2 3.5 s later on the tracker's clock.
        let t: Vec<f64> = j.stops.iter().map(|s| s.state.time_s).collect();
        assert_eq!(t, [0.0, 3.0, 6.5]);
    }

    #[test]
    fn unknown_doubled_and_missing_points_are_located() {
        let plan = parse_plan(PLAN.as_bytes(), "plan.csv").unwrap();
        let export = parse_export(
            b"Name,X,Y,Z\nP1,1,2,3\nP9,1,2,3\nP1,1,2,3.1\n",
            "e.csv",
            None,
            false,
        )
        .unwrap();
        let errors = join_by_name(&plan, &[export.clone()], false).unwrap_err();
        let at: Vec<_> = errors
            .iter()
            .map(|e| (e.file.as_str(), e.line, e.col))
            .collect();
        assert_eq!(at, [("e.csv", 3, 1), ("e.csv", 4, 1), ("plan.csv", 4, 4)]);
        assert!(errors[1]
            .message
            .contains("measured twice (first at e.csv:2)"));
        assert!(errors[2].message.contains("`P2` is in no export"));
        let only_p1 = parse_export(b"Name,X,Y,Z\nP1,1,2,3\n", "e.csv", None, false).unwrap();
        let j = join_by_name(&plan, &[only_p1], true).unwrap();
        assert_eq!(j.missing, ["P2"]);
        assert_eq!(j.stops[2].measured_mm, None);
    }

    #[test]
    fn dwells_of_a_stream_by_hand() {
        // 10 Hz: still at (0,0,0) for 1.5 s, moving 2 mm per sample for 0.5 s, still at
        // (10,0,0) for 1.2 s with ±0.01 mm noise, moving again, a 0.4 s pause (too short).
        let mut rows = String::from("time,x,y,z\n");
        let mut t = 0.0;
        let mut push = |x: f64| {
            rows.push_str(&format!("{t:.1},{x},0,0\n"));
            t += 0.1;
        };
        for _ in 0..16 {
            push(0.0);
        }
        for k in 1..5 {
            push(2.0 * k as f64);
        }
        for k in 0..13 {
            push(10.0 + if k % 2 == 0 { 0.01 } else { -0.01 });
        }
        for k in 1..5 {
            push(10.0 + 3.0 * k as f64);
        }
        for _ in 0..5 {
            push(30.0);
        }
        let stream = parse_export(rows.as_bytes(), "s.csv", None, true).unwrap();
        let rule = DwellRule {
            min_s: 1.0,
            radius_mm: 0.05,
        };
        let d = dwells(&stream, rule).unwrap();
        assert_eq!(d.len(), 2);
        assert_eq!((d[0].samples, d[0].point.time_s), (16, Some(0.0)));
        assert!((d[0].duration_s - 1.5).abs() < 1e-9);
        // 7 samples at +0.01 and 6 at -0.01: mean 10 + 0.01/13.
        assert!((d[1].point.mm.x - (10.0 + 0.01 / 13.0)).abs() < 1e-12);
        assert_eq!(d[1].point.line, 22);
        let plan = parse_plan(PLAN.as_bytes(), "plan.csv").unwrap();
        let j = join_in_order(&plan, &stream, &d).unwrap();
        assert_eq!(j.stops[1].measured_mm, Some(Vector3::zeros()));
        assert_eq!(j.stops[2].state.time_s, 3.0 + 2.0);
        let e = join_in_order(&plan, &stream, &d[..1]).unwrap_err();
        assert_eq!((e[0].file.as_str(), e[0].line), ("plan.csv", 4));
        let three = [d.clone(), vec![d[1].clone()]].concat();
        let e = join_in_order(&plan, &stream, &three).unwrap_err();
        assert_eq!((e[0].file.as_str(), e[0].line), ("s.csv", 22));
    }
}
