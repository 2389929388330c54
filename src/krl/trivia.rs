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
        Some(c) => src[c..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(src.len(), |n| c + n),
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
