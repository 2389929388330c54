//! Reading and writing the measurement CSV (CONTRACTS.md "Measurement CSV"): header required,
//! columns found by name in any order, `x,y,z` empty on unmeasured rows, optional `t` and
//! `dir1..dir6`, unknown columns ignored and named once.

use super::{directions::infer_histories, Measurements, Stop};
use crate::model::{AxisState, Direction};
use nalgebra::Vector3;
use std::io::Write;
use std::path::Path;

/// A rejected measurement file, located at file:line:col with the offending line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}:{col}: {message}")]
pub struct MeasureError {
    /// The file, as given.
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based column (characters).
    pub col: usize,
    /// The offending source line (lossily decoded), empty when not applicable.
    pub source_line: String,
    /// What is wrong.
    pub message: String,
    /// What to do about it, if robopost knows.
    pub help: Option<String>,
}

impl MeasureError {
    /// A located error at `line:col` (1-based) of `file`, whose lines are `lines`.
    pub fn in_lines(
        file: &str,
        lines: &[String],
        (line, col): (usize, usize),
        message: String,
        help: Option<&str>,
    ) -> MeasureError {
        MeasureError {
            file: file.to_string(),
            line,
            col,
            source_line: lines.get(line.wrapping_sub(1)).cloned().unwrap_or_default(),
            message,
            help: help.map(str::to_string),
        }
    }

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

/// Characters of a field a message quotes (see [`crate::diagnostic::clip`]).
const MAX_QUOTED: usize = 40;

const AXES: [&str; 6] = ["a1", "a2", "a3", "a4", "a5", "a6"];
const DIRS: [&str; 6] = ["dir1", "dir2", "dir3", "dir4", "dir5", "dir6"];
const KNOWN: [&str; 17] = [
    "test", "a1", "a2", "a3", "a4", "a5", "a6", "x", "y", "z", "t", "dir1", "dir2", "dir3", "dir4",
    "dir5", "dir6",
];

/// The physical range of a command angle, degrees (two full turns either way: no joint
/// limit is wider), of a measured coordinate, mm (100 m from the tracker's origin), and of
/// the clock, seconds (30 years).
pub const ANGLE_RANGE_DEG: f64 = 720.0;
pub const POSITION_RANGE_MM: f64 = 100_000.0;
pub const TIME_RANGE_S: f64 = 1e9;

/// A command angle this far beyond a joint limit (degrees) is still taken as at the limit
/// (the decimals a controller writes).
const LIMIT_SLACK_DEG: f64 = 1e-6;

/// Reads a measurement file (`-` reads stdin).
pub fn read_csv(path: &Path) -> Result<Measurements, MeasureError> {
    read_csv_within(path, None)
}

/// [`read_csv`], refusing a row whose command angles lie outside `limits_deg` (the robot's
/// joint limits, `[min, max]` per axis) with the row's line and column.
pub fn read_csv_within(
    path: &Path,
    limits_deg: Option<&[[f64; 2]; 6]>,
) -> Result<Measurements, MeasureError> {
    let name = path.display().to_string();
    let bytes = if name == "-" {
        crate::input::stdin()
    } else {
        crate::input::read(path)
    };
    let bytes = bytes.map_err(|e| MeasureError {
        file: name.clone(),
        line: 0,
        col: 0,
        source_line: String::new(),
        message: format!("cannot read the measurement file: {e}"),
        help: None,
    })?;
    parse_csv_within(&bytes, &name, limits_deg)
}

struct Columns {
    test: usize,
    axes: [usize; 6],
    xyz: [usize; 3],
    t: Option<usize>,
    dirs: [Option<usize>; 6],
}

/// Parses measurement CSV bytes; `file` names the source in errors.
#[cfg(any(test, feature = "internals"))]
pub fn parse_csv(bytes: &[u8], file: &str) -> Result<Measurements, MeasureError> {
    parse_csv_within(bytes, file, None)
}

/// [`parse_csv`] within the joint limits `limits_deg` (see [`read_csv_within`]).
pub fn parse_csv_within(
    bytes: &[u8],
    file: &str,
    limits_deg: Option<&[[f64; 2]; 6]>,
) -> Result<Measurements, MeasureError> {
    // A UTF-8 byte-order mark (Excel's "CSV UTF-8") is not part of the first column's name.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    // Lines end with `\n`, `\r\n` or a lone `\r`, as the csv reader reads them. Their starts
    // are found once: looking a line up per row must not rescan the file (quadratic time).
    let ends_line = |i: usize| match bytes[i] {
        b'\n' => true,
        b'\r' => bytes.get(i + 1) != Some(&b'\n'),
        _ => false,
    };
    let line_starts: Vec<usize> = std::iter::once(0)
        .chain((0..bytes.len()).filter(|&i| ends_line(i)).map(|i| i + 1))
        .collect();
    // The csv reader's line count lags behind on CRLF files, and a record's position is
    // taken before the line ends, blank lines and comment lines in front of it are skipped:
    // the line is found from the byte offset, past those, instead.
    let line_at = |pos: Option<&csv::Position>| -> usize {
        let Some(pos) = pos else { return 0 };
        let mut at = pos.byte() as usize;
        loop {
            match bytes.get(at) {
                Some(b'\r' | b'\n') => at += 1,
                Some(b'#') if at == 0 || matches!(bytes[at - 1], b'\n' | b'\r') => {
                    at = (at..bytes.len())
                        .find(|&i| ends_line(i))
                        .map_or(bytes.len(), |i| i + 1);
                }
                _ => break,
            }
        }
        line_starts.partition_point(|&start| start <= at)
    };
    let line_of = |line: usize| -> String {
        let Some(&start) = line.checked_sub(1).and_then(|i| line_starts.get(i)) else {
            return String::new();
        };
        let end = line_starts.get(line).copied().unwrap_or(bytes.len());
        let text = &bytes[start..end];
        let text = text.strip_suffix(b"\n").unwrap_or(text);
        let text = text.strip_suffix(b"\r").unwrap_or(text);
        String::from_utf8_lossy(text).into_owned()
    };
    let error = |line: usize, col: usize, message: String, help: Option<&str>| MeasureError {
        file: file.to_string(),
        line,
        col,
        source_line: line_of(line),
        message,
        help: help.map(str::to_string),
    };
    // Text saved as UTF-16 (a tracker package's export) fails on its columns below, where the
    // message names the encoding and the separator seen and points to `robopost import`.
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
    // A column named twice is ambiguous (which `x` is the measured one?): refused.
    for (i, n) in names.iter().enumerate() {
        if KNOWN.contains(&n.as_str()) && names[..i].contains(n) {
            return Err(error(
                1,
                column_of_field(&line_of(1), i),
                format!("column `{n}` is named twice in the header"),
                Some("each column may appear once: remove or rename the other"),
            ));
        }
    }
    let find = |n: &str| names.iter().position(|h| h == n);
    let require = |n: &str| {
        find(n).ok_or_else(|| {
            error(
                1,
                1,
                format!("required column `{n}` is missing ({})", seen(bytes)),
                Some("required columns: test, a1..a6, x, y, z, `,`-separated (any order); a tracker package's export is joined to the campaign's plan by `robopost import EXPORT --plan PLAN.csv -o MEAS.csv`"),
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
    // The last time given (`t`) and its line.
    let mut last_time: Option<(f64, usize)> = None;
    loop {
        let more = reader.read_byte_record(&mut record).map_err(|e| {
            let line = line_at(e.position());
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
        let line = line_at(record.position());
        // The raw line only when an error needs its column (a million rows, no copies).
        let col_of = |field: usize| column_of_field(&line_of(line), field);
        let text =
            |i: usize| String::from_utf8_lossy(record.get(i).unwrap_or_default()).to_string();
        // A field as a message quotes it: clipped (a 50 MB field is not echoed whole).
        let quoted = |i: usize| crate::diagnostic::clip(&text(i), MAX_QUOTED);
        let number = |i: usize, what: &str| -> Result<Option<f64>, MeasureError> {
            let bytes = record.get(i).unwrap_or_default();
            if bytes.is_empty() {
                return Ok(None);
            }
            let (range, unit) = match what {
                "t" => (TIME_RANGE_S, "s"),
                "x" | "y" | "z" => (POSITION_RANGE_MM, "mm"),
                _ if what.starts_with('a') => (ANGLE_RANGE_DEG, "°"),
                _ => (f64::INFINITY, ""),
            };
            let value = std::str::from_utf8(bytes)
                .ok()
                .and_then(|s| s.parse::<f64>().ok());
            match value {
                Some(v) if v.abs() <= range => Ok(Some(v)),
                Some(v) if v.is_finite() => Err(error(
                    line,
                    col_of(i),
                    format!(
                        "{what} = {} is beyond any physical range (at most ±{range} {unit})",
                        quoted(i)
                    ),
                    Some(
                        "check the column's unit (mm, degrees, seconds) and the number's exponent",
                    ),
                )),
                _ => Err(error(
                    line,
                    col_of(i),
                    format!("`{}` is not a number ({what})", quoted(i)),
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
            if let Some([lo, hi]) = limits_deg.map(|l| l[k]) {
                if !(lo - LIMIT_SLACK_DEG..=hi + LIMIT_SLACK_DEG).contains(&axes[k]) {
                    return Err(error(
                        line,
                        col_of(c),
                        format!(
                            "{} = {}° is outside the robot's joint limits [{lo}, {hi}]°",
                            AXES[k].to_uppercase(),
                            axes[k]
                        ),
                        Some("the robot cannot have been commanded there: check the column and the robot's limits (robot.description.limits_deg of the calibration)"),
                    ));
                }
            }
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
            Some(c) => match number(c, "t")? {
                Some(t) => {
                    // The rows are in the order the robot visited them: the clock only
                    // goes on (drift is fitted over it).
                    if let Some((before, at)) = last_time.filter(|(before, _)| t < *before) {
                        return Err(error(
                            line,
                            col_of(c),
                            format!("time runs backwards: t = {t} s, after {before} s on line {at}"),
                            Some("rows are in the order the robot visited them; two campaigns go in two files"),
                        ));
                    }
                    last_time = Some((t, line));
                    t
                }
                None => 0.0,
            },
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
                time_s,
                ..AxisState::new(axes)
            },
            measured_mm,
            line,
        });
    }
    let mut states: Vec<AxisState> = stops.iter().map(|s| s.state).collect();
    infer_histories(&mut states, &explicit);
    for (stop, state) in stops.iter_mut().zip(states) {
        stop.state = state;
    }
    Ok(Measurements {
        source: file.to_string(),
        stops,
        ignored_columns,
    })
}

/// What the reader saw in a file whose columns are wrong: its encoding, the separator its
/// header row seems to use, and the names in it ("read as UTF-16 LE; the header row seems
/// `;`-separated: Punkt;X;Y;Z").
fn seen(bytes: &[u8]) -> String {
    let (text, encoding) = match super::text::decode(bytes) {
        Ok(t) => t,
        Err(e) => return format!("the file is not text: {e}"),
    };
    let header = super::text::lines(&text)
        .into_iter()
        .find(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .unwrap_or_default()
        .to_string();
    let count = |c: char| header.matches(c).count();
    let separator = [('\t', "tab"), (';', "`;`"), (',', "`,`")]
        .into_iter()
        .max_by_key(|(c, _)| count(*c))
        .filter(|(c, _)| count(*c) > 0)
        .map_or("not separated by tab, `;` or `,`", |(_, name)| name);
    let shown: String = header.chars().take(60).collect();
    format!(
        "the file reads as {encoding}; its header row is {separator}{}: {shown}",
        if separator.starts_with('n') {
            ""
        } else {
            "-separated"
        }
    )
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

/// Writes stops as a measurement CSV (with the `t` column). The rows carry every stop the
/// robot visited, in order, so the readers infer each axis's history from them; no `dirN`
/// column is written (an explicit direction would override the gear play's memory).
pub fn write_csv<W: Write>(out: W, stops: &[Stop]) -> std::io::Result<()> {
    let mut w = csv::Writer::from_writer(out);
    let header = [
        "test", "a1", "a2", "a3", "a4", "a5", "a6", "x", "y", "z", "t",
    ];
    w.write_record(header)?;
    for s in stops {
        let mut row: Vec<String> = vec![s.test.clone()];
        row.extend(s.state.axes_deg.iter().map(|a| format!("{a:.6}")));
        match s.measured_mm {
            Some(p) => row.extend([p.x, p.y, p.z].iter().map(|v| format!("{v:.4}"))),
            None => row.extend(["", "", ""].map(String::from)),
        }
        row.push(format!("{:.1}", s.state.time_s));
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
        let d1: Vec<_> = m.stops.iter().map(|s| s.state.directions()[0]).collect();
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
            assert_eq!(a.state.history, b.state.history);
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

    /// On a CRLF file the error names the row's own line (the csv reader's count lags one
    /// line behind there), with that line's text; comment and blank lines are counted too.
    #[test]
    fn errors_name_the_right_line_whatever_the_line_ends() {
        let rows = [
            "test,a1,a2,a3,a4,a5,a6,x,y,z",
            "p,0,-90,90,0,0,0,1,2,3",
            "# note",
            "",
            "p,0,-90,90,0,0,0,abc,2,3",
            "",
        ];
        for end in ["\n", "\r\n", "\r"] {
            // The csv reader ends a comment at `\n` only: a lone `\r` file has none here.
            let src = rows.join(end).replace("# note\r", "\r");
            let e = parse_csv(src.as_bytes(), "m.csv").unwrap_err();
            assert_eq!((e.line, e.col), (5, 18), "{end:?}: {}", e.message);
            assert_eq!(e.source_line, "p,0,-90,90,0,0,0,abc,2,3");
            let ok = src.replace("abc", "1");
            let m = parse_csv(ok.as_bytes(), "m.csv").unwrap();
            assert_eq!(m.stops.iter().map(|s| s.line).collect::<Vec<_>>(), [2, 5]);
        }
    }

    /// A header ended by a lone `\r` (found by the fuzzer: the row after it was placed on
    /// line 1, the header's).
    #[test]
    fn a_lone_carriage_return_ends_a_line() {
        let src = b"test,a1,a2,a3,a4,a5,a6,x,y,z,t,dir1\r\xf3\x87,0,-90,90,0,0,0,,,,0,1\r\n\
            # c\r\n\r\nx,1,-90,90,0,0,0,1340.1,23.4,1810.0,2.5,-1\r\n";
        let m = parse_csv(src, "m.csv").unwrap();
        assert_eq!(m.stops.iter().map(|s| s.line).collect::<Vec<_>>(), [2, 5]);
    }

    /// Numbers beyond any physical range, and angles outside the robot's limits, are located
    /// errors (an angle of 1e20 once reached a grid of 1e20 points).
    #[test]
    fn absurd_numbers_and_angles_outside_the_limits_are_located_errors() {
        let head = "test,a1,a2,a3,a4,a5,a6,x,y,z,t\n";
        let cases = [
            (
                "p,0,1e20,90,0,0,0,1,2,3,0",
                5,
                "a2 = 1e20 is beyond any physical range",
            ),
            ("p,0,0,90,0,0,0,1e308,2,3,0", 16, "x = 1e308 is beyond"),
            ("p,0,0,90,0,0,0,1,2,3,1e12", 22, "t = 1e12 is beyond"),
            ("p,0,0,90,0,0,0,1,2,inf,0", 20, "`inf` is not a number (z)"),
        ];
        for (row, col, message) in cases {
            let e = parse_csv(format!("{head}{row}\n").as_bytes(), "m.csv").unwrap_err();
            assert_eq!((e.line, e.col), (2, col), "{row}");
            assert!(e.message.contains(message), "{}", e.message);
        }
        let limits = crate::kinematics::RobotDescription::kr30ha().limits_deg;
        let row = format!("{head}p,0,-90,90,0,0,0,1,2,3,0\np,0,-136,90,0,0,0,1,2,3,0\n");
        assert!(parse_csv(row.as_bytes(), "m.csv").is_ok());
        let e = parse_csv_within(row.as_bytes(), "m.csv", Some(&limits)).unwrap_err();
        assert_eq!((e.line, e.col), (3, 5));
        assert!(
            e.message
                .contains("A2 = -136° is outside the robot's joint limits [-135, 35]°"),
            "{}",
            e.message
        );
        let at_limit = format!("{head}p,0,-135,90,0,0,0,1,2,3,0\n");
        assert!(parse_csv_within(at_limit.as_bytes(), "m.csv", Some(&limits)).is_ok());
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
