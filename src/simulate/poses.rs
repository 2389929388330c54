//! A list of axis sets for the virtual robot to visit (`robopost simulate poses`): a CSV with
//! columns `test, a1..a6` found by name and an optional `measured` column (`1`/`0`,
//! `true`/`false`, `yes`/`no`; empty or absent means measured), one row per stop in visiting
//! order. A measurement CSV is accepted too: its `x,y,z` are ignored and unknown columns
//! skipped, so a real campaign's file can be replayed on the virtual robot.

use std::path::Path;

use super::campaign::{paced, PlannedStop};
use crate::measure::MeasureError;

/// The axis ranges the paper's campaign covers (degrees): A1 ±60, A2 and A3 between the
/// indexing tests' extremes, the wrist ±90/±90/±180.
#[cfg(any(test, feature = "internals"))]
pub const CAMPAIGN_RANGES_DEG: [[f64; 2]; 6] = [
    [-60.0, 60.0],
    [-112.0, -19.0],
    [20.0, 150.0],
    [-90.0, 90.0],
    [-90.0, 90.0],
    [-180.0, 180.0],
];

/// `count` poses drawn uniformly inside [`CAMPAIGN_RANGES_DEG`] (seeded), all measured, labelled
/// `label` and visited in order from `t0_s` (3.2 s dwell, 30°/s): the workspace poses with every
/// axis moving that tell effects apart which one indexing pose cannot.
#[cfg(any(test, feature = "internals"))]
pub fn random_poses(seed: u64, count: usize, t0_s: f64, label: &str) -> Vec<PlannedStop> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let visits: Vec<_> = (0..count)
        .map(|_| {
            let axes = std::array::from_fn(|k| {
                rng.gen_range(CAMPAIGN_RANGES_DEG[k][0]..CAMPAIGN_RANGES_DEG[k][1])
            });
            (label.to_string(), axes, true)
        })
        .collect();
    let mut stops = paced(visits, 3.2, 30.0);
    for s in &mut stops {
        s.time_s += t0_s;
    }
    stops
}

/// The visits of a poses file, time-stamped at `dwell_s` per stop and `axis_speed_deg_s`.
pub fn read_poses(
    path: &Path,
    dwell_s: f64,
    axis_speed_deg_s: f64,
) -> Result<Vec<PlannedStop>, MeasureError> {
    let name = path.display().to_string();
    let bytes = crate::input::read(path).map_err(|e| MeasureError {
        file: name.clone(),
        line: 0,
        col: 0,
        source_line: String::new(),
        message: format!("cannot read the poses file: {e}"),
        help: None,
    })?;
    parse_poses(&bytes, &name, dwell_s, axis_speed_deg_s)
}

/// Parses poses CSV bytes; `file` names the source in errors.
pub fn parse_poses(
    bytes: &[u8],
    file: &str,
    dwell_s: f64,
    axis_speed_deg_s: f64,
) -> Result<Vec<PlannedStop>, MeasureError> {
    let text = String::from_utf8_lossy(bytes);
    let lines: Vec<&str> = text.lines().collect();
    let error = |line: usize, col: usize, message: String| MeasureError {
        file: file.to_string(),
        line,
        col,
        source_line: lines
            .get(line.saturating_sub(1))
            .map_or(String::new(), |l| l.to_string()),
        message,
        help: None,
    };
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(bytes);
    let headers: Vec<String> = reader
        .headers()
        .map_err(|e| error(1, 1, format!("cannot read the header row: {e}")))?
        .iter()
        .map(|h| h.to_ascii_lowercase())
        .collect();
    let find = |n: &str| headers.iter().position(|h| h == n);
    let require = |n: &str| {
        find(n).ok_or_else(|| {
            error(
                1,
                1,
                format!("required column `{n}` is missing (columns: test, a1..a6[, measured])"),
            )
        })
    };
    let test = require("test")?;
    let axes = ["a1", "a2", "a3", "a4", "a5", "a6"]
        .iter()
        .map(|n| require(n))
        .collect::<Result<Vec<_>, _>>()?;
    let measured_col = find("measured");
    let mut visits = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line() as usize);
            error(line, 1, format!("malformed row: {e}"))
        })?;
        let line = record.position().map_or(0, |p| p.line() as usize);
        let col_of = |field: usize| {
            let raw = lines.get(line.saturating_sub(1)).copied().unwrap_or("");
            raw.split(',')
                .take(field)
                .map(|f| f.len() + 1)
                .sum::<usize>()
                + 1
        };
        let mut angles = [0.0; 6];
        for (k, &c) in axes.iter().enumerate() {
            let s = record.get(c).unwrap_or("");
            angles[k] = s
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    error(
                        line,
                        col_of(c),
                        format!("`{s}` is not a number (a{})", k + 1),
                    )
                })?;
        }
        let measured = match measured_col.map(|c| (c, record.get(c).unwrap_or(""))) {
            None | Some((_, "")) => true,
            Some((c, s)) => match s.to_ascii_lowercase().as_str() {
                "1" | "true" | "yes" => true,
                "0" | "false" | "no" => false,
                _ => {
                    return Err(error(
                        line,
                        col_of(c),
                        format!("`{s}` is not 1/0, true/false or yes/no (measured)"),
                    ))
                }
            },
        };
        visits.push((record.get(test).unwrap_or("").to_string(), angles, measured));
    }
    Ok(paced(visits, dwell_s, axis_speed_deg_s))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_by_name_measured_flag_and_pace() {
        let src = "a1,a2,a3,a4,a5,a6,measured,test\n0,-90,90,0,0,0,0,p\n30,-90,90,0,0,0,,p\n";
        let stops = parse_poses(src.as_bytes(), "p.csv", 2.0, 10.0).unwrap();
        assert_eq!(stops.len(), 2);
        assert!(!stops[0].measured && stops[1].measured);
        assert_eq!(stops[1].axes_deg[0], 30.0);
        // 2 s dwell + 30° at 10 °/s
        assert_eq!(stops[1].time_s, 5.0);
    }

    #[test]
    fn bad_angle_is_located() {
        let src = "test,a1,a2,a3,a4,a5,a6\np,0,x,0,0,0,0\n";
        let e = parse_poses(src.as_bytes(), "p.csv", 1.0, 1.0).unwrap_err();
        assert_eq!((e.line, e.col), (2, 5));
        assert!(e.message.contains("`x` is not a number (a2)"));
    }
}
