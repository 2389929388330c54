//! The physical layout of a line: indentation, code, trailing blanks, `;` comment, line ending.
//! KRL is line-oriented (one statement per line), so the parser first cuts the file into
//! lines here and hands only the code of each to the statement grammar; everything else is
//! trivia. A `;` inside a string literal (`"a; b"`) does not start a comment. A UTF-8 byte
//! order mark at the start of the file is trivia too.

use super::lex::is_blank;

/// Byte offsets of one line's parts (absolute offsets into the file).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RawLine {
    /// Start of the code (after indentation); equals `code_end` when there is no code.
    pub code_start: usize,
    /// End of the code (trailing blanks excluded).
    pub code_end: usize,
    /// The `;` comment without trailing blanks/CR, if any.
    pub comment: Option<(usize, usize)>,
    /// Offset of the `\n`, or the file length for a last line without one.
    pub newline: usize,
    /// Start of the next line.
    pub next: usize,
}

const BOM: &[u8] = b"\xEF\xBB\xBF";

/// Cuts the line starting at `start`.
pub(crate) fn split_line(src: &[u8], start: usize) -> RawLine {
    let mut p = start;
    if start == 0 && src.starts_with(BOM) {
        p = BOM.len();
    }
    while p < src.len() && is_blank(src[p]) {
        p += 1;
    }
    let code_start = p;
    let mut in_string = false;
    let mut comment_at = None;
    // On to the first `\n`, `;` or `"` (a vector search: a CAM line has none before its end).
    p = memchr::memchr3(b'\n', b';', b'"', &src[p..]).map_or(src.len(), |n| p + n);
    while p < src.len() {
        match src[p] {
            b'\n' => break,
            b'"' => in_string = !in_string,
            b';' if !in_string => {
                comment_at = Some(p);
                break;
            }
            _ => {}
        }
        p += 1;
    }
    let newline = match comment_at {
        Some(c) => memchr::memchr(b'\n', &src[c..]).map_or(src.len(), |n| c + n),
        None => p,
    };
    let code_limit = comment_at.unwrap_or(newline);
    let mut code_end = code_limit;
    while code_end > code_start && is_blank(src[code_end - 1]) {
        code_end -= 1;
    }
    let comment = comment_at.map(|c| {
        let mut e = newline;
        while e > c && is_blank(src[e - 1]) {
            e -= 1;
        }
        (c, e)
    });
    RawLine {
        code_start,
        code_end,
        comment,
        newline,
        next: (newline + 1).min(src.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_of_a_line() {
        let src = b"  LIN P1 ; go \r\nEND";
        let l = split_line(src, 0);
        assert_eq!(&src[l.code_start..l.code_end], b"LIN P1");
        let (c0, c1) = l.comment.unwrap();
        assert_eq!(&src[c0..c1], b"; go");
        assert_eq!((l.newline, l.next), (15, 16));
        let l = split_line(src, 16);
        assert_eq!(&src[l.code_start..l.code_end], b"END");
        assert_eq!((l.newline, l.next), (19, 19));
    }

    /// Where `split_line` ends the code and the line, found one byte at a time: the first
    /// `\n`, or the first `;` outside a string.
    fn code_and_line_end(src: &[u8], code_start: usize) -> (usize, usize) {
        let mut in_string = false;
        for (p, &b) in src.iter().enumerate().skip(code_start) {
            match b {
                b'\n' => return (p, p),
                b'"' => in_string = !in_string,
                b';' if !in_string => {
                    let nl = src[p..].iter().position(|&b| b == b'\n');
                    return (p, nl.map_or(src.len(), |n| p + n));
                }
                _ => {}
            }
        }
        (src.len(), src.len())
    }

    proptest::proptest! {
        /// The skip to the first byte looked for lands where the byte-by-byte scan does: lines of the bytes
        /// it looks for (and look-alikes: `:`, `#`, `\r`, bytes above 127) at any place.
        #[test]
        fn the_skip_finds_what_a_byte_scan_finds(
            text in proptest::collection::vec(
                proptest::sample::select(b"aZ0 \t;\"\n:#\r\xA2\x8a".to_vec()),
                0..60,
            ),
            start in 0usize..60,
        ) {
            let start = start.min(text.len());
            let l = split_line(&text, start);
            let (code_limit, newline) = code_and_line_end(&text, l.code_start);
            proptest::prop_assert_eq!(l.newline, newline);
            proptest::prop_assert_eq!(l.comment.map(|(c, _)| c).unwrap_or(newline), code_limit);
        }
    }

    #[test]
    fn a_long_line_is_cut_at_its_comment() {
        let long = b"LIN {X 1.000,Y 2.000,Z 3.000,A 0.000,B 90.000,C 0.000} C_DIS ; here\r\nEND";
        let l = split_line(long, 0);
        assert_eq!(&long[l.code_start..l.code_end], &long[..60]);
        assert_eq!(l.comment.map(|(a, b)| &long[a..b]), Some(&b"; here"[..]));
    }

    #[test]
    fn semicolon_in_string_is_code() {
        let src = b"MSG = \"a; b\" ; real comment\n";
        let l = split_line(src, 0);
        assert_eq!(&src[l.code_start..l.code_end], b"MSG = \"a; b\"");
        let src = b"\xEF\xBB\xBF\t;FOLD x\r\n";
        let l = split_line(src, 0);
        assert_eq!(l.code_start, l.code_end);
        let (c0, c1) = l.comment.unwrap();
        assert_eq!(&src[c0..c1], b";FOLD x");
    }
}
