//! Reading and writing the measurement CSV (CONTRACTS.md "Measurement CSV"): header required,
//! columns found by name in any order, `x,y,z` empty on unmeasured rows, optional `t` and
//! `dir1..dir6`, unknown columns ignored and named once.

use super::{directions::infer_directions, Measurements, Stop};
use crate::model::{AxisState, Direction};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// A rejected measurement file, located at file:line:col with the offending line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}:{col}: {message}")]
pub struct MeasureError {
    pub file: String,
    pub line: usize,
    pub col: usize,
    /// The offending source line (lossily decoded), empty when not applicable.
    pub source_line: String,
    pub message: String,
    pub help: Option<String>,
}

impl MeasureError {
    /// The message with the source line and a caret under the column (the shared
    /// [`Diagnostic`](crate::diagnostic::Diagnostic) rendering; no location for a whole-file
    /// error such as a missing file).
    pub fn render(&self) -> String {
        crate::diagnostic::Diagnostic {
            line: self.line,
            col: self.col,
            source_line: self.source_line.clone(),
            help: self.help.clone(),
            ..crate::diagnostic::Diagnostic::new(
                crate::diagnostic::Severity::Error,
                &self.file,
                self.message.clone(),
            )
        }
        .render()
    }
}

const AXES: [&str; 6] = ["a1", "a2", "a3", "a4", "a5", "a6"];
const DIRS: [&str; 6] = ["dir1", "dir2", "dir3", "dir4", "dir5", "dir6"];
const KNOWN: [&str; 17] = [
    "test", "a1", "a2", "a3", "a4", "a5", "a6", "x", "y", "z", "t", "dir1", "dir2", "dir3", "dir4",
    "dir5", "dir6",
];

/// Reads a measurement file (`-` reads stdin).
pub fn read_csv(path: &Path) -> Result<Measurements, MeasureError> {
    let name = path.display().to_string();
    let bytes = if name == "-" {
        let mut buf = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin(), &mut buf).map(|_| buf)
    } else {
        std::fs::read(path)
    };
    let bytes = bytes.map_err(|e| MeasureError {
        file: name.clone(),
        line: 0,
        col: 0,
        source_line: String::new(),
        message: format!("cannot read the measurement file: {e}"),
        help: None,
    })?;
    parse_csv(&bytes, &name)
}

struct Columns {
    test: usize,
    axes: [usize; 6],
    xyz: [usize; 3],
    t: Option<usize>,
    dirs: [Option<usize>; 6],
}

/// Parses measurement CSV bytes; `file` names the source in errors.
pub fn parse_csv(bytes: &[u8], file: &str) -> Result<Measurements, MeasureError> {
    // Split once: looking a line up per row must not rescan the file (quadratic time).
    let raw_lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
    let line_of = |line: usize| -> String {
        raw_lines
            .get(line.saturating_sub(1))
            .map(|l| {
                String::from_utf8_lossy(l)
                    .trim_end_matches('\r')
                    .to_string()
            })
            .unwrap_or_default()
    };
    let error = |line: usize, col: usize, message: String, help: Option<&str>| MeasureError {
        file: file.to_string(),
        line,
        col,
        source_line: line_of(line),
        message,
        help: help.map(str::to_string),
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(bytes);
    let headers = reader
        .byte_headers()
        .map_err(|e| error(1, 1, format!("cannot read the header row: {e}"), None))?
        .clone();
    if headers.is_empty() || headers.iter().all(|h| h.is_empty()) {
        return Err(error(
            1,
            1,
            "the header row is missing".into(),
            Some("the first row names the columns: test,a1,...,a6,x,y,z"),
        ));
    }
    let names: Vec<String> = headers
        .iter()
        .map(|h| String::from_utf8_lossy(h).trim().to_ascii_lowercase())
        .collect();
    let find = |n: &str| names.iter().position(|h| h == n);
    let require = |n: &str| {
        find(n).ok_or_else(|| {
            error(
                1,
                1,
                format!("required column `{n}` is missing"),
                Some("required columns: test, a1..a6, x, y, z (any order)"),
            )
        })
    };
    let cols = Columns {
        test: require("test")?,
        axes: [
            require("a1")?,
            require("a2")?,
            require("a3")?,
            require("a4")?,
            require("a5")?,
            require("a6")?,
        ],
        xyz: [require("x")?, require("y")?, require("z")?],
        t: find("t"),
        dirs: DIRS.map(find),
    };
    let ignored_columns = names
        .iter()
        .filter(|n| !KNOWN.contains(&n.as_str()))
        .cloned()
        .collect::<Vec<_>>();

    let mut stops = Vec::new();
    let mut explicit = Vec::new();
    let mut record = csv::ByteRecord::new();
    loop {
        let more = reader.read_byte_record(&mut record).map_err(|e| {
            let line = e.position().map(|p| p.line() as usize).unwrap_or(0);
            error(
                line,
                1,
                format!("malformed row: {e}"),
                Some("every row needs as many fields as the header"),
            )
        })?;
        if !more {
            break;
        }
        let line = record.position().map(|p| p.line() as usize).unwrap_or(0);
        // The raw line only when an error needs its column (a million rows, no copies).
        let col_of = |field: usize| column_of_field(&line_of(line), field);
        let text =
            |i: usize| String::from_utf8_lossy(record.get(i).unwrap_or_default()).to_string();
        let number = |i: usize, what: &str| -> Result<Option<f64>, MeasureError> {
            let bytes = record.get(i).unwrap_or_default();
            if bytes.is_empty() {
                return Ok(None);
            }
            let value = std::str::from_utf8(bytes)
                .ok()
                .and_then(|s| s.parse::<f64>().ok());
            match value {
                Some(v) if v.is_finite() => Ok(Some(v)),
                _ => Err(error(
                    line,
                    col_of(i),
                    format!("`{}` is not a number ({what})", text(i)),
                    None,
                )),
            }
        };
        let mut axes = [0.0; 6];
        for (k, &c) in cols.axes.iter().enumerate() {
            axes[k] = number(c, AXES[k])?.ok_or_else(|| {
                error(
                    line,
                    col_of(c),
                    format!("command angle {} is empty", AXES[k].to_uppercase()),
                    Some("every row, measured or not, needs the six command angles"),
                )
            })?;
        }
        let xyz = [
            number(cols.xyz[0], "x")?,
            number(cols.xyz[1], "y")?,
            number(cols.xyz[2], "z")?,
        ];
        let measured_mm = match xyz {
            [Some(x), Some(y), Some(z)] => Some(Vector3::new(x, y, z)),
            [None, None, None] => None,
            _ => {
                let c = cols
                    .xyz
                    .iter()
                    .zip(xyz)
                    .find(|(_, v)| v.is_none())
                    .map(|(c, _)| *c)
                    .unwrap_or(0);
                return Err(error(
                    line,
                    col_of(c),
                    "x, y and z must all be given or all be empty".into(),
                    Some("leave all three empty on a row that was visited but not measured"),
                ));
            }
        };
        let time_s = match cols.t {
            Some(c) => number(c, "t")?.unwrap_or(0.0),
            None => 0.0,
        };
        let mut dirs = [None; 6];
        for (k, c) in cols.dirs.iter().enumerate() {
            if let Some(c) = *c {
                dirs[k] = match number(c, DIRS[k])? {
                    None => None,
                    Some(1.0) => Some(Direction::Positive),
                    Some(-1.0) => Some(Direction::Negative),
                    Some(v) => {
                        return Err(error(
                            line,
                            col_of(c),
                            format!("direction must be +1 or -1, found {v}"),
                            None,
                        ))
                    }
                };
            }
        }
        explicit.push(dirs);
        stops.push(Stop {
            test: text(cols.test),
            state: AxisState {
                axes_deg: axes,
                directions: [Direction::Unknown; 6],
                time_s,
            },
            measured_mm,
            line,
        });
    }
    let mut states: Vec<AxisState> = stops.iter().map(|s| s.state).collect();
    infer_directions(&mut states, &explicit);
    for (stop, state) in stops.iter_mut().zip(states) {
        stop.state = state;
    }
    Ok(Measurements {
        source: file.to_string(),
        stops,
        ignored_columns,
    })
}

/// 1-based byte column where field `index` starts in a raw CSV line (quote-aware).
fn column_of_field(raw: &str, index: usize) -> usize {
    let mut field = 0;
    let mut quoted = false;
    for (i, b) in raw.bytes().enumerate() {
        if field == index {
            return i + 1;
        }
        match b {
            b'"' => quoted = !quoted,
            b',' if !quoted => field += 1,
            _ => {}
        }
    }
    raw.len() + 1
}

/// Writes stops as a measurement CSV (with `t` and explicit `dir1..dir6` columns).
pub fn write_csv<W: Write>(out: W, stops: &[Stop]) -> std::io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    let mut header = vec![
        "test", "a1", "a2", "a3", "a4", "a5", "a6", "x", "y", "z", "t",
    ];
    header.extend(DIRS);
    w.write_record(&header)?;
    for s in stops {
        let mut row: Vec<String> = vec![s.test.clone()];
        row.extend(s.state.axes_deg.iter().map(|a| format!("{a:.6}")));
        match s.measured_mm {
            Some(p) => row.extend([p.x, p.y, p.z].iter().map(|v| format!("{v:.4}"))),
            None => row.extend(["", "", ""].map(String::from)),
        }
        row.push(format!("{:.1}", s.state.time_s));
        row.extend(s.state.directions.iter().map(|d| match d {
            Direction::Positive => "1".to_string(),
            Direction::Negative => "-1".to_string(),
            Direction::Unknown => String::new(),
        }));
        w.write_record(&row)?;
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "note,test,a1,a2,a3,a4,a5,a6,x,y,z,t\n\
        x,A1,0,-90,90,0,0,0,,,,0\n\
        x,A1,1,-90,90,0,0,0,1340.1,23.4,1810.0,2.5\n\
        x,A1,0.5,-90,90,0,0,0,1340.2,11.7,1810.0,5\n";

    #[test]
    fn columns_by_name_unmeasured_rows_and_directions() {
        let m = parse_csv(GOOD.as_bytes(), "m.csv").unwrap();
        assert_eq!(m.stops.len(), 3);
        assert_eq!(m.ignored_columns, vec!["note".to_string()]);
        assert_eq!(m.stops[0].measured_mm, None);
        assert_eq!(
            m.stops[1].measured_mm,
            Some(Vector3::new(1340.1, 23.4, 1810.0))
        );
        assert_eq!(m.stops[1].line, 3);
        assert_eq!(m.stops[2].state.time_s, 5.0);
        let d1: Vec<_> = m.stops.iter().map(|s| s.state.directions[0]).collect();
        assert_eq!(
            d1,
            vec![Direction::Unknown, Direction::Positive, Direction::Negative]
        );
        assert_eq!(m.measured().count(), 2);
    }

    #[test]
    fn round_trip_through_writer() {
        let m = parse_csv(GOOD.as_bytes(), "m.csv").unwrap();
        let mut buf = Vec::new();
        write_csv(&mut buf, &m.stops).unwrap();
        let back = parse_csv(&buf, "back.csv").unwrap();
        for (a, b) in m.stops.iter().zip(&back.stops) {
            assert_eq!(a.state.axes_deg, b.state.axes_deg);
            assert_eq!(a.state.directions, b.state.directions);
            assert_eq!(a.measured_mm, b.measured_mm);
        }
    }

    #[test]
    fn bad_number_names_line_and_column() {
        let src = "test,a1,a2,a3,a4,a5,a6,x,y,z\np,0,-90,9O,0,0,0,1,2,3\n";
        let e = parse_csv(src.as_bytes(), "bad.csv").unwrap_err();
        assert_eq!((e.line, e.col), (2, 9)); // `p,0,-90,` is 8 bytes
        assert_eq!(e.source_line, "p,0,-90,9O,0,0,0,1,2,3");
        assert!(
            e.message.contains("`9O` is not a number (a3)"),
            "{}",
            e.message
        );
        assert!(e.render().contains("bad.csv:2:9"));
    }

    #[test]
    fn missing_column_partial_xyz_and_bad_direction_are_errors() {
        let e = parse_csv(b"test,a1,a2,a3,a4,a5,x,y,z\n", "m.csv").unwrap_err();
        assert!(e.message.contains("`a6`"));
        let e = parse_csv(
            b"test,a1,a2,a3,a4,a5,a6,x,y,z\np,0,0,0,0,0,0,1,,3\n",
            "m.csv",
        )
        .unwrap_err();
        assert_eq!((e.line, e.col), (2, 17)); // the empty y field starts after 16 bytes
        let e = parse_csv(
            b"test,a1,a2,a3,a4,a5,a6,x,y,z,dir2\np,0,0,0,0,0,0,1,2,3,2\n",
            "m.csv",
        )
        .unwrap_err();
        assert!(e.message.contains("+1 or -1"));
        let e = parse_csv(b"test,a1,a2,a3,a4,a5,a6,x,y,z\np,0,0,0,0,0\n", "m.csv").unwrap_err();
        assert_eq!(e.line, 2);
    }
}
