//! The plain text of a tracker package's export, as it comes: its encoding (UTF-8 with or
//! without a byte-order mark, UTF-16 little- or big-endian, or a Windows code page read
//! byte per character), its lines, the separator of its fields (tab, `;`, `,`, or runs of
//! spaces) and whether its numbers use a decimal comma. Decoded here once, so that the
//! export reader sees fields and the error messages can name what was seen.

use std::fmt;

/// How the bytes of a text file were decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    Utf8,
    Utf8Bom,
    Utf16Le,
    Utf16Be,
    /// Not UTF-8: read one byte per character (ISO 8859-1, close to the Windows code page a
    /// German Excel saves).
    Latin1,
}

impl fmt::Display for Encoding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Encoding::Utf8 => "UTF-8",
            Encoding::Utf8Bom => "UTF-8 with BOM",
            Encoding::Utf16Le => "UTF-16 LE",
            Encoding::Utf16Be => "UTF-16 BE",
            Encoding::Latin1 => "Latin-1 (not UTF-8)",
        })
    }
}

/// The separator between the fields of a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Separator {
    Tab,
    Semicolon,
    Comma,
    /// One or more spaces (Spatial Analyzer's space-delimited export).
    Spaces,
}

impl fmt::Display for Separator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Separator::Tab => "tab",
            Separator::Semicolon => "`;`",
            Separator::Comma => "`,`",
            Separator::Spaces => "space",
        })
    }
}

/// Decodes `bytes`: by their byte-order mark, else UTF-16 when every other byte of the start
/// is zero (an export without a mark), else UTF-8, else Latin-1. `Err` names the byte where
/// UTF-16 breaks (an unpaired surrogate, an odd length).
pub fn decode(bytes: &[u8]) -> Result<(String, Encoding), String> {
    if let Some(rest) = bytes.strip_prefix(b"\xEF\xBB\xBF") {
        return match std::str::from_utf8(rest) {
            Ok(s) => Ok((s.to_string(), Encoding::Utf8Bom)),
            Err(e) => Err(format!(
                "a UTF-8 byte-order mark, but byte {} is not UTF-8",
                e.valid_up_to() + 3
            )),
        };
    }
    if let Some(rest) = bytes.strip_prefix(b"\xFF\xFE") {
        return utf16(rest, Encoding::Utf16Le, 2);
    }
    if let Some(rest) = bytes.strip_prefix(b"\xFE\xFF") {
        return utf16(rest, Encoding::Utf16Be, 2);
    }
    let head = &bytes[..bytes.len().min(512)];
    let zeros = |parity: usize| {
        head.iter()
            .enumerate()
            .filter(|(i, b)| i % 2 == parity && **b == 0)
            .count()
    };
    let half = head.len() / 2;
    if half >= 2 && zeros(1) * 4 >= half * 3 && zeros(0) == 0 {
        return utf16(bytes, Encoding::Utf16Le, 0);
    }
    if half >= 2 && zeros(0) * 4 >= half * 3 && zeros(1) == 0 {
        return utf16(bytes, Encoding::Utf16Be, 0);
    }
    match std::str::from_utf8(bytes) {
        Ok(s) => Ok((s.to_string(), Encoding::Utf8)),
        Err(_) => Ok((bytes.iter().map(|&b| b as char).collect(), Encoding::Latin1)),
    }
}

/// UTF-16 code units of `bytes` (after a mark of `offset` bytes) decoded with std.
fn utf16(bytes: &[u8], encoding: Encoding, offset: usize) -> Result<(String, Encoding), String> {
    if bytes.len() % 2 != 0 {
        return Err(format!(
            "{encoding}, but the file has an odd number of bytes ({})",
            bytes.len() + offset
        ));
    }
    let units = bytes.chunks_exact(2).map(|p| match encoding {
        Encoding::Utf16Be => u16::from_be_bytes([p[0], p[1]]),
        _ => u16::from_le_bytes([p[0], p[1]]),
    });
    let mut text = String::with_capacity(bytes.len() / 2);
    for (k, c) in char::decode_utf16(units).enumerate() {
        match c {
            Ok(c) => text.push(c),
            Err(_) => {
                return Err(format!(
                    "{encoding}, but byte {} is an unpaired surrogate",
                    offset + 2 * k
                ))
            }
        }
    }
    Ok((text, encoding))
}

/// The lines of `text` (`\n`, `\r\n` or a lone `\r` end one), numbered from 1.
pub fn lines(text: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut rest = text;
    while !rest.is_empty() {
        match rest.find(['\n', '\r']) {
            Some(i) => {
                out.push(&rest[..i]);
                let skip = if rest[i..].starts_with("\r\n") { 2 } else { 1 };
                rest = &rest[i + skip..];
            }
            None => {
                out.push(rest);
                rest = "";
            }
        }
    }
    out
}

/// The separator of `lines`: tab, `;` or `,` when it appears on most of the lines that hold
/// numbers (in that order of preference: a `;` or tab file may still have decimal commas),
/// else spaces.
pub fn sniff_separator(lines: &[&str]) -> Separator {
    let numeric: Vec<&&str> = lines
        .iter()
        .filter(|l| l.chars().filter(char::is_ascii_digit).count() >= 3)
        .take(200)
        .collect();
    let most = |c: char| {
        let n = numeric.iter().filter(|l| l.contains(c)).count();
        !numeric.is_empty() && n * 2 > numeric.len()
    };
    if most('\t') {
        Separator::Tab
    } else if most(';') {
        Separator::Semicolon
    } else if most(',') {
        Separator::Comma
    } else {
        Separator::Spaces
    }
}

/// One field of a line: its text (trimmed, outer quotes removed) and its 1-based column in
/// characters.
#[derive(Clone, Debug, PartialEq)]
pub struct Field<'a> {
    pub text: &'a str,
    pub col: usize,
}

/// The fields of `line` split at `sep` (quote-aware: a separator inside `"…"` does not split).
pub fn fields(line: &str, sep: Separator) -> Vec<Field<'_>> {
    let mut out = Vec::new();
    if sep == Separator::Spaces {
        let mut start = None;
        for (i, c) in line
            .char_indices()
            .chain(std::iter::once((line.len(), ' ')))
        {
            match (c.is_whitespace(), start) {
                (false, None) => start = Some(i),
                (true, Some(s)) => {
                    out.push(field(line, s, i));
                    start = None;
                }
                _ => {}
            }
        }
        return out;
    }
    let sep = match sep {
        Separator::Tab => '\t',
        Separator::Semicolon => ';',
        _ => ',',
    };
    let (mut start, mut quoted) = (0, false);
    for (i, c) in line.char_indices() {
        if c == '"' {
            quoted = !quoted;
        } else if c == sep && !quoted {
            out.push(field(line, start, i));
            start = i + 1;
        }
    }
    out.push(field(line, start, line.len()));
    out
}

/// The field of `line[start..end]`, trimmed and unquoted, with its character column.
fn field(line: &str, start: usize, end: usize) -> Field<'_> {
    let raw = &line[start..end];
    let lead = raw.len() - raw.trim_start().len();
    let text = raw.trim();
    let text = text
        .strip_prefix('"')
        .and_then(|t| t.strip_suffix('"'))
        .unwrap_or(text);
    Field {
        text,
        col: line[..start + lead].chars().count() + 1,
    }
}

/// A number as packages write it: a decimal point, or (when the separator is not `,`) a
/// decimal comma; `None` for anything else (thousands separators, units, `NaN`, `inf`).
pub fn number(text: &str, sep: Separator) -> Option<f64> {
    let t = text.trim();
    if t.is_empty() || !t.bytes().any(|b| b.is_ascii_digit()) {
        return None;
    }
    if !t
        .bytes()
        .all(|b| b.is_ascii_digit() || matches!(b, b'+' | b'-' | b'.' | b',' | b'e' | b'E'))
    {
        return None;
    }
    let owned;
    let t = if t.contains(',') {
        if sep == Separator::Comma || t.contains('.') || t.matches(',').count() > 1 {
            return None;
        }
        owned = t.replace(',', ".");
        owned.as_str()
    } else {
        t
    };
    t.parse::<f64>().ok().filter(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encodings_by_mark_and_by_zero_bytes() {
        let text = "Name;X\r\nP1;1,5\r\n";
        let le: Vec<u8> = text.encode_utf16().flat_map(u16::to_le_bytes).collect();
        let be: Vec<u8> = text.encode_utf16().flat_map(u16::to_be_bytes).collect();
        let marked = |mark: &[u8], body: &[u8]| [mark, body].concat();
        assert_eq!(
            decode(&marked(b"\xFF\xFE", &le)).unwrap(),
            (text.into(), Encoding::Utf16Le)
        );
        assert_eq!(
            decode(&marked(b"\xFE\xFF", &be)).unwrap(),
            (text.into(), Encoding::Utf16Be)
        );
        assert_eq!(decode(&le).unwrap(), (text.into(), Encoding::Utf16Le));
        assert_eq!(decode(&be).unwrap(), (text.into(), Encoding::Utf16Be));
        assert_eq!(
            decode(&marked(b"\xEF\xBB\xBF", text.as_bytes())).unwrap(),
            (text.into(), Encoding::Utf8Bom)
        );
        // "Höhe" saved by a Windows code page: 0xF6 is ö in Latin-1.
        assert_eq!(
            decode(b"H\xF6he").unwrap(),
            ("Höhe".into(), Encoding::Latin1)
        );
        // An unpaired high surrogate (0xD800) after "A".
        let e = decode(b"\xFF\xFEA\x00\x00\xD8").unwrap_err();
        assert!(e.contains("byte 4"), "{e}");
        assert!(decode(b"\xFF\xFEA").unwrap_err().contains("odd number"));
    }

    #[test]
    fn separators_fields_and_decimal_commas() {
        let german = ["Punkt;X;Y;Z", "P1;1234,5;-0,25;3", "P2;1;2;3"];
        assert_eq!(sniff_separator(&german), Separator::Semicolon);
        assert_eq!(
            sniff_separator(&["// v", "P1,1.5,2,3", "P2,1,2,3"]),
            Separator::Comma
        );
        assert_eq!(sniff_separator(&["P1\t1,5\t2\t3"]), Separator::Tab);
        assert_eq!(sniff_separator(&["A G P1  1.5 2 3"]), Separator::Spaces);
        let f = fields("P1; \"a;b\" ;1,5", Separator::Semicolon);
        let texts: Vec<_> = f.iter().map(|f| (f.text, f.col)).collect();
        assert_eq!(texts, [("P1", 1), ("a;b", 5), ("1,5", 12)]);
        let f = fields("  A  Gr P1 1.5", Separator::Spaces);
        let texts: Vec<_> = f.iter().map(|f| (f.text, f.col)).collect();
        assert_eq!(texts, [("A", 3), ("Gr", 6), ("P1", 9), ("1.5", 12)]);
        assert_eq!(number("1234,5", Separator::Semicolon), Some(1234.5));
        assert_eq!(number("-0,25", Separator::Tab), Some(-0.25));
        assert_eq!(number("1,234.5", Separator::Semicolon), None);
        assert_eq!(number("1,5", Separator::Comma), None);
        assert_eq!(number("1.5e3", Separator::Comma), Some(1500.0));
        assert_eq!(number("NaN", Separator::Comma), None);
        assert_eq!(number("12mm", Separator::Comma), None);
        assert_eq!(lines("a\r\nb\rc\n\nd"), ["a", "b", "c", "", "d"]);
    }
}
