//! A tracker package's plain-text point export read into named points: the package's header
//! lines skipped (and searched for the unit they state), the column header found by what its
//! names mean (point name, X, Y, Z, time; units in brackets; measured columns preferred over
//! nominal ones), or without a header the fields of each row taken as a name followed by X, Y,
//! Z; numbers with a decimal point or comma; mm, m or inch converted to mm; a time of day or a
//! date-time turned into seconds. A stream (time, X, Y, Z at a fixed rate, no names) reads the
//! same way. Every row that is not a point is a located error: nothing is silently dropped.

use nalgebra::Vector3;

use super::text::{self, Encoding, Field, Separator};
use super::MeasureError;

/// A length unit of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    Mm,
    M,
    Inch,
}

impl Unit {
    /// Millimetres per unit.
    pub fn mm(self) -> f64 {
        match self {
            Unit::Mm => 1.0,
            Unit::M => 1000.0,
            Unit::Inch => 25.4,
        }
    }

    /// The unit a word names (`mm`, `millimeters`, `m`, `metre`, `in`, `inch`, `"`, `zoll`).
    pub fn parse(word: &str) -> Option<Unit> {
        match word.trim().to_lowercase().as_str() {
            "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres"
            | "millimeter(s)" => Some(Unit::Mm),
            "m" | "meter" | "meters" | "metre" | "metres" | "meter(s)" => Some(Unit::M),
            "in" | "inch" | "inches" | "\"" | "zoll" => Some(Unit::Inch),
            _ => None,
        }
    }
}

impl std::fmt::Display for Unit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Unit::Mm => "mm",
            Unit::M => "m",
            Unit::Inch => "inch",
        })
    }
}

/// One point of an export (or one sample of a stream).
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// The point's name (empty in a stream without names).
    pub name: String,
    /// Position, mm.
    pub mm: Vector3<f64>,
    /// Time stamp, seconds on the export's own clock (`None` when the export has none).
    pub time_s: Option<f64>,
    /// 1-based line, and the column of the name field.
    pub line: usize,
    pub name_col: usize,
}

/// A whole export as read.
#[derive(Clone, Debug)]
pub struct Export {
    pub source: String,
    pub encoding: Encoding,
    pub separator: Separator,
    pub decimal_comma: bool,
    pub unit: Unit,
    /// Where the unit came from: `column header`, `file header`, `--units` or `default`.
    pub unit_from: &'static str,
    /// Package header lines skipped before the data.
    pub skipped_lines: usize,
    pub points: Vec<Point>,
    /// The decoded lines, for errors that point into the export later (the join).
    pub lines: Vec<String>,
}

impl Export {
    /// A located error at `line:col` of this export.
    pub fn error(
        &self,
        line: usize,
        col: usize,
        message: String,
        help: Option<&str>,
    ) -> MeasureError {
        MeasureError::in_lines(&self.source, &self.lines, (line, col), message, help)
    }

    /// "UTF-16 LE, tab-separated, decimal comma, m" — what was seen, for the summary.
    pub fn describe(&self) -> String {
        format!(
            "{}, {}-separated{}, {} ({})",
            self.encoding,
            self.separator,
            if self.decimal_comma {
                ", decimal comma"
            } else {
                ""
            },
            self.unit,
            self.unit_from
        )
    }
}

/// What a header column holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Role {
    Name,
    Time,
    Axis(usize),
    Other,
}

/// Words that mark a column as not the measured coordinate (nominal, deviation, tolerance).
const NOT_MEASURED: [&str; 12] = [
    "nominal",
    "nom",
    "soll",
    "dev",
    "deviation",
    "delta",
    "d",
    "tol",
    "tolerance",
    "error",
    "abw",
    "abweichung",
];
/// Words that mark a column as the measured coordinate.
const MEASURED: [&str; 6] = ["actual", "meas", "measured", "ist", "gemessen", "act"];
const NAME_WORDS: [&str; 11] = [
    "name",
    "point",
    "pointname",
    "punkt",
    "punktname",
    "id",
    "label",
    "target",
    "feature",
    "bezeichnung",
    "object",
];
const TIME_WORDS: [&str; 8] = [
    "time",
    "timestamp",
    "date",
    "datetime",
    "zeit",
    "zeitstempel",
    "datum",
    "t",
];

/// The role of a header field, its unit (`[mm]`, `(m)`) and whether it is marked measured.
fn classify(header: &str) -> (Role, Option<Unit>, bool) {
    let lower = header.to_lowercase();
    let mut unit = None;
    let mut bare = String::new();
    let mut depth = 0;
    let mut inside = String::new();
    for c in lower.chars() {
        match c {
            '[' | '(' => {
                depth += 1;
                inside.clear();
            }
            ']' | ')' if depth > 0 => {
                depth -= 1;
                unit = unit.or(Unit::parse(&inside));
            }
            _ if depth > 0 => inside.push(c),
            _ => bare.push(c),
        }
    }
    let words: Vec<&str> = bare
        .split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty())
        .collect();
    // A trailing unit word: `X mm`.
    if unit.is_none() && words.len() > 1 {
        unit = words.last().and_then(|w| Unit::parse(w));
    }
    let measured = words.iter().any(|w| MEASURED.contains(w));
    let axis = words
        .iter()
        .filter_map(|w| ["x", "y", "z"].iter().position(|a| a == w))
        .collect::<Vec<_>>();
    let role = if words.iter().any(|w| NOT_MEASURED.contains(w)) {
        Role::Other
    } else if axis.len() == 1 {
        Role::Axis(axis[0])
    } else if words.iter().any(|w| TIME_WORDS.contains(w)) {
        Role::Time
    } else if words.iter().any(|w| NAME_WORDS.contains(w)) {
        Role::Name
    } else {
        Role::Other
    };
    (role, unit, measured)
}

/// The columns of a header row, when it names X, Y and Z.
struct Header {
    line: usize,
    name: Option<usize>,
    time: Option<usize>,
    xyz: [usize; 3],
    unit: Option<Unit>,
}

fn header_of(fields: &[Field], line: usize) -> Option<Header> {
    let roles: Vec<_> = fields.iter().map(|f| classify(f.text)).collect();
    let mut xyz: [Option<usize>; 3] = [None; 3];
    let mut unit = None;
    for (i, (role, u, measured)) in roles.iter().enumerate() {
        if let Role::Axis(a) = role {
            // The first such column, or a later one marked measured over an unmarked one.
            let better = match xyz[*a] {
                None => true,
                Some(j) => *measured && !roles[j].2,
            };
            if better {
                xyz[*a] = Some(i);
                unit = unit.or(*u);
            }
        }
    }
    let [Some(x), Some(y), Some(z)] = xyz else {
        return None;
    };
    let first = |r: Role| roles.iter().position(|(role, _, _)| *role == r);
    // A name column by its name, else the first column before X that is none of the others
    // (`Prüfpunkt`, `Merkmal`).
    let name = first(Role::Name).or_else(|| {
        roles[..x]
            .iter()
            .position(|(role, _, _)| *role == Role::Other)
    });
    Some(Header {
        line,
        name,
        time: first(Role::Time),
        xyz: [x, y, z],
        unit,
    })
}

/// A unit a package header line states (`// Units: Millimeters`, `Einheit: mm`, `Units = m`).
fn stated_unit(line: &str) -> Option<Unit> {
    let lower = line.to_lowercase();
    let at = ["units", "unit", "einheit", "längeneinheit"]
        .iter()
        .find_map(|k| lower.find(k).map(|i| i + k.len()))?;
    lower[at..]
        .split(|c: char| !(c.is_alphanumeric() || c == '"'))
        .filter(|w| !w.is_empty())
        .find_map(Unit::parse)
}

/// Reads an export's bytes. `unit` is the user's `--units` (refused when the file states
/// another); `stream` asks for time-stamped samples (no names needed, a time on every row).
pub fn parse_export(
    bytes: &[u8],
    file: &str,
    unit: Option<Unit>,
    stream: bool,
) -> Result<Export, MeasureError> {
    let whole = |message: String, help: Option<&str>| MeasureError {
        file: file.to_string(),
        line: 0,
        col: 0,
        source_line: String::new(),
        message,
        help: help.map(str::to_string),
    };
    let (decoded, encoding) = decode_or_error(bytes, file)?;
    let lines: Vec<&str> = text::lines(&decoded);
    let separator = text::sniff_separator(&lines);
    let mut export = Export {
        source: file.to_string(),
        encoding,
        separator,
        decimal_comma: false,
        unit: Unit::Mm,
        unit_from: "default",
        skipped_lines: 0,
        points: Vec::new(),
        lines: lines.iter().map(|l| l.to_string()).collect(),
    };
    let is_comment = |l: &str| {
        let t = l.trim_start();
        t.is_empty() || t.starts_with("//") || t.starts_with('#') || t.starts_with('!')
    };
    // The header row, if any, is the first line naming X, Y and Z; lines before it (or before
    // the first data row of a file without one) are the package's own.
    let mut header = None;
    let mut file_unit = None;
    let mut first_data = lines.len();
    for (i, l) in lines.iter().enumerate() {
        if let Some(u) = stated_unit(l) {
            file_unit = file_unit.or(Some(u));
        }
        if is_comment(l) {
            continue;
        }
        let f = text::fields(l, separator);
        if let Some(h) = header_of(&f, i + 1) {
            header = Some(h);
            first_data = i + 1;
            break;
        }
        if headerless_row(&f, separator, stream).is_some() {
            first_data = i;
            break;
        }
    }
    export.skipped_lines = first_data.saturating_sub(usize::from(header.is_some()));
    let column_unit = header.as_ref().and_then(|h| h.unit);
    let (found, from) = match (column_unit, file_unit) {
        (Some(u), _) => (Some(u), "column header"),
        (None, Some(u)) => (Some(u), "file header"),
        _ => (None, "default"),
    };
    match (found, unit) {
        (Some(f), Some(u)) if f != u => {
            return Err(whole(
                format!("the export states its unit as {f} ({from}), but --units says {u}"),
                Some("leave --units out, or correct it"),
            ))
        }
        (Some(f), _) => (export.unit, export.unit_from) = (f, from),
        (None, Some(u)) => (export.unit, export.unit_from) = (u, "--units"),
        (None, None) => {}
    }
    let scale = export.unit.mm();
    for (i, l) in lines.iter().enumerate().skip(first_data) {
        if is_comment(l) {
            continue;
        }
        let line = i + 1;
        let f = text::fields(l, separator);
        let row = match &header {
            Some(h) => header_row(&f, h, separator, stream),
            None => headerless_row(&f, separator, stream).ok_or_else(|| RowError {
                col: 1,
                message: if stream {
                    "not a sample: expected time, X, Y, Z".into()
                } else {
                    "not a point: expected a point name followed by X, Y, Z".into()
                },
            }),
        };
        let row = row.map_err(|e| {
            export.error(
                line,
                e.col,
                e.message,
                Some(
                    "every row after the header must be a point; comment lines start with // or #",
                ),
            )
        })?;
        if row.decimal_comma {
            export.decimal_comma = true;
        }
        if row
            .xyz
            .iter()
            .any(|v| (v * scale).abs() > super::POSITION_RANGE_MM)
        {
            return Err(export.error(
                line,
                f.get(row.xyz_col).map_or(1, |f| f.col),
                format!(
                    "a coordinate beyond {} mm in {}: a wrong unit?",
                    super::POSITION_RANGE_MM,
                    export.unit
                ),
                Some("state the unit with --units mm|m|inch"),
            ));
        }
        export.points.push(Point {
            name: row.name,
            mm: Vector3::from(row.xyz) * scale,
            time_s: row.time_s,
            line,
            name_col: row.name_col,
        });
    }
    if export.points.is_empty() {
        return Err(whole(
            format!(
                "no {} found (read as {}, {}-separated)",
                if stream { "samples" } else { "points" },
                encoding,
                separator
            ),
            Some("an export names each point and gives X, Y, Z; see docs/import.md"),
        ));
    }
    Ok(export)
}

/// Decodes, naming the file in the error.
fn decode_or_error(bytes: &[u8], file: &str) -> Result<(String, Encoding), MeasureError> {
    text::decode(bytes).map_err(|e| MeasureError {
        file: file.to_string(),
        line: 0,
        col: 0,
        source_line: String::new(),
        message: format!("cannot decode the export: {e}"),
        help: Some("save it as UTF-8 or UTF-16 text".into()),
    })
}

/// One row read.
struct Row {
    name: String,
    name_col: usize,
    xyz: [f64; 3],
    xyz_col: usize,
    time_s: Option<f64>,
    decimal_comma: bool,
}

struct RowError {
    col: usize,
    message: String,
}

fn header_row(f: &[Field], h: &Header, sep: Separator, stream: bool) -> Result<Row, RowError> {
    let get = |i: usize| -> Result<&Field, RowError> {
        f.get(i).ok_or_else(|| RowError {
            col: f.last().map_or(1, |l| l.col + l.text.chars().count()),
            message: format!(
                "{} fields, but the header (line {}) has more",
                f.len(),
                h.line
            ),
        })
    };
    let mut xyz = [0.0; 3];
    let mut decimal_comma = false;
    for (k, &c) in h.xyz.iter().enumerate() {
        let field = get(c)?;
        xyz[k] = text::number(field.text, sep).ok_or_else(|| RowError {
            col: field.col,
            message: format!("`{}` is not a number ({})", field.text, ["X", "Y", "Z"][k]),
        })?;
        decimal_comma |= field.text.contains(',');
    }
    let (name, name_col) = match h.name {
        Some(c) => {
            let field = get(c)?;
            (field.text.to_string(), field.col)
        }
        None => (String::new(), 1),
    };
    if !stream && name.is_empty() {
        return Err(RowError {
            col: name_col,
            message: "the point has no name".into(),
        });
    }
    let time_s = match h.time {
        Some(c) => {
            let field = get(c)?;
            Some(parse_time(field.text).ok_or_else(|| RowError {
                col: field.col,
                message: format!("`{}` is not a time stamp", field.text),
            })?)
        }
        None if stream => {
            return Err(RowError {
                col: 1,
                message: "a stream needs a time column".into(),
            })
        }
        None => None,
    };
    Ok(Row {
        name,
        name_col,
        xyz,
        xyz_col: h.xyz[0],
        time_s,
        decimal_comma,
    })
}

/// A row without a header: `name… X Y Z [time]` (the name is the last text field before the
/// three numbers: Spatial Analyzer writes `collection group target X Y Z`), or for a stream
/// `time X Y Z`.
fn headerless_row(f: &[Field], sep: Separator, stream: bool) -> Option<Row> {
    let decimal_comma = f
        .iter()
        .any(|x| x.text.contains(',') && sep != Separator::Comma);
    if stream {
        if f.len() < 4 {
            return None;
        }
        let time_s = parse_time(f[0].text)?;
        let xyz = [1, 2, 3].map(|i| text::number(f[i].text, sep));
        let [Some(x), Some(y), Some(z)] = xyz else {
            return None;
        };
        return Some(Row {
            name: String::new(),
            name_col: 1,
            xyz: [x, y, z],
            xyz_col: 1,
            time_s: Some(time_s),
            decimal_comma,
        });
    }
    let first_number = f.iter().position(|x| text::number(x.text, sep).is_some())?;
    if first_number == 0 || f.len() < first_number + 3 {
        return None;
    }
    let xyz = [0, 1, 2].map(|k| text::number(f[first_number + k].text, sep));
    let [Some(x), Some(y), Some(z)] = xyz else {
        return None;
    };
    let time_s = f[first_number + 3..]
        .iter()
        .find(|x| x.text.contains(':'))
        .and_then(|x| parse_time(x.text));
    let name = &f[first_number - 1];
    Some(Row {
        name: name.text.to_string(),
        name_col: name.col,
        xyz: [x, y, z],
        xyz_col: first_number,
        time_s,
        decimal_comma,
    })
}

/// Seconds of a time stamp: a number of seconds; `hh:mm:ss[.fff]`; a date before it as
/// `YYYY-MM-DD` (with ` ` or `T`), `DD.MM.YYYY` or `MM/DD/YYYY`; a decimal comma in the
/// seconds; `AM`/`PM`. Dates count days from 1970-01-01.
pub fn parse_time(text: &str) -> Option<f64> {
    let t = text.trim();
    if let Some(v) = text::number(t, Separator::Semicolon) {
        return Some(v);
    }
    let (t, pm) = match t.rsplit_once(' ') {
        Some((rest, "PM" | "pm")) => (rest.trim(), Some(true)),
        Some((rest, "AM" | "am")) => (rest.trim(), Some(false)),
        _ => (t, None),
    };
    let (date, clock) = match t.rsplit_once([' ', 'T']) {
        Some((d, c)) => (Some(d.trim()), c),
        None => (None, t),
    };
    let days = match date {
        None => 0,
        Some(d) => date_days(d)?,
    };
    let parts: Vec<&str> = clock.split(':').collect();
    if !(2..=3).contains(&parts.len()) {
        return None;
    }
    let int = |s: &str| -> Option<i64> {
        (!s.is_empty() && s.len() <= 2 && s.bytes().all(|b| b.is_ascii_digit()))
            .then(|| s.parse().ok())
            .flatten()
    };
    let mut h = int(parts[0])?;
    let m = int(parts[1])?;
    let s = match parts.get(2) {
        Some(s) => {
            let v = text::number(s, Separator::Semicolon)?;
            (0.0..61.0).contains(&v).then_some(v)?
        }
        None => 0.0,
    };
    match pm {
        Some(true) if h < 12 => h += 12,
        Some(false) if h == 12 => h = 0,
        _ => {}
    }
    if h > 23 || m > 59 {
        return None;
    }
    Some(days as f64 * 86_400.0 + (h * 3600 + m * 60) as f64 + s)
}

/// Days from 1970-01-01 of `YYYY-MM-DD`, `DD.MM.YYYY` or `MM/DD/YYYY`.
fn date_days(d: &str) -> Option<i64> {
    let num = |s: &str| -> Option<i64> {
        (!s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
            .then(|| s.parse().ok())
            .flatten()
    };
    let p: Vec<&str> = d.split(['-', '.', '/']).collect();
    if p.len() != 3 {
        return None;
    }
    let (y, m, day) = if d.contains('-') {
        (num(p[0])?, num(p[1])?, num(p[2])?)
    } else if d.contains('.') {
        (num(p[2])?, num(p[1])?, num(p[0])?)
    } else {
        (num(p[2])?, num(p[0])?, num(p[1])?)
    };
    if !(1..=12).contains(&m) || !(1..=31).contains(&day) || y < 1900 {
        return None;
    }
    // Days from civil (H. Hinnant's algorithm).
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    Some(era * 146_097 + doe - 719_468)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_names_by_meaning() {
        assert_eq!(classify("Point Name"), (Role::Name, None, false));
        assert_eq!(classify("X [mm]"), (Role::Axis(0), Some(Unit::Mm), false));
        assert_eq!(classify("Meas Y (m)"), (Role::Axis(1), Some(Unit::M), true));
        assert_eq!(classify("Nominal Z").0, Role::Other);
        assert_eq!(classify("dZ").0, Role::Other);
        assert_eq!(classify("Zeitstempel").0, Role::Time);
        assert_eq!(classify("Time Stamp").0, Role::Time);
        assert_eq!(classify("Punkt").0, Role::Name);
    }

    #[test]
    fn time_stamps_by_hand() {
        assert_eq!(parse_time("12,5"), Some(12.5));
        assert_eq!(parse_time("10:15:30.25"), Some(36_930.25));
        // 1970-01-02 is day 1; 2000-03-01 is day 11,017.
        assert_eq!(parse_time("1970-01-02 00:00:01"), Some(86_401.0));
        assert_eq!(
            parse_time("01.03.2000 00:00:00,5"),
            Some(11_017.0 * 86_400.0 + 0.5)
        );
        assert_eq!(
            parse_time("2000-03-01T00:01:00"),
            parse_time("03/01/2000 12:01:00 AM")
        );
        assert_eq!(
            parse_time("03/01/2000 1:00:00 PM"),
            Some(11_017.0 * 86_400.0 + 46_800.0)
        );
        assert_eq!(parse_time("25:00:00"), None);
        assert_eq!(parse_time("P1"), None);
    }

    #[test]
    fn units_stated_in_the_file_or_its_columns() {
        let e = parse_export(b"// Units: Meters\nP1 1.5 2 3\n", "a.txt", None, false).unwrap();
        assert_eq!((e.unit, e.unit_from), (Unit::M, "file header"));
        assert_eq!(e.points[0].mm, Vector3::new(1500.0, 2000.0, 3000.0));
        assert_eq!(e.skipped_lines, 1);
        let e = parse_export(
            b"Name,X [in],Y [in],Z [in]\nP1,1,2,3\n",
            "a.csv",
            None,
            false,
        )
        .unwrap();
        assert!((e.points[0].mm - Vector3::new(25.4, 50.8, 76.2)).norm() < 1e-12);
        let e = parse_export(
            b"Name,X [in],Y,Z\nP1,1,2,3\n",
            "a.csv",
            Some(Unit::Mm),
            false,
        )
        .unwrap_err();
        assert!(e.message.contains("inch"), "{}", e.message);
    }

    #[test]
    fn a_row_that_is_not_a_point_is_located() {
        let src = "Name;X;Y;Z\nP1;1,5;2;3\nP2;1,5;zwei;3\n";
        let e = parse_export(src.as_bytes(), "g.csv", None, false).unwrap_err();
        assert_eq!((e.line, e.col), (3, 8));
        assert!(
            e.message.contains("`zwei` is not a number (Y)"),
            "{}",
            e.message
        );
        let e = parse_export(b"Name;X;Y;Z\nP1;1;2\n", "g.csv", None, false).unwrap_err();
        assert_eq!(e.line, 2);
    }
}
