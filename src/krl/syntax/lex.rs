//! The lexical layer of the KRL grammar as nom parsers over bytes: blanks, identifiers,
//! case-insensitive keywords, numbers, strings, bit literals, enum literals. Also the parser
//! plumbing shared by every grammar file: the error type carrying a label and a hint, the
//! `expect` combinator that turns a backtrack into a located failure, and `Cx`, which turns a
//! sub-slice of the source back into a byte span.

use super::nodes::Nodes;
use super::number;
use super::span::Span;
use nom::error::{ErrorKind, ParseError};
use nom::IResult;
use std::cell::RefCell;

/// Result of every grammar production (each `fn` returning it is named in `grammars/krl.ebnf`,
/// and a test keeps the two lists equal).
pub(crate) type PResult<'a, T> = IResult<&'a [u8], T, PErr<'a>>;

/// The same type for helpers that only build an error (not grammar productions).
pub(crate) type Fails<'a, T> = IResult<&'a [u8], T, PErr<'a>>;

/// What was expected and how to fix it (static: errors stay two words wide, which keeps
/// every parser's result small).
#[derive(Debug)]
pub(crate) struct Msg {
    pub label: &'static str,
    pub help: &'static str,
}

static NO_MSG: Msg = Msg {
    label: "",
    help: "",
};

/// A parse error: where (the remaining input) and the message.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PErr<'a> {
    pub at: &'a [u8],
    pub msg: &'static Msg,
}

impl PErr<'_> {
    pub fn label(&self) -> &'static str {
        self.msg.label
    }

    pub fn help(&self) -> &'static str {
        self.msg.help
    }
}

impl<'a> ParseError<&'a [u8]> for PErr<'a> {
    fn from_error_kind(input: &'a [u8], _kind: ErrorKind) -> Self {
        PErr {
            at: input,
            msg: &NO_MSG,
        }
    }

    fn append(_input: &'a [u8], _kind: ErrorKind, other: Self) -> Self {
        other
    }

    /// Of two failed alternatives keep the one that got further (the better message).
    fn or(self, other: Self) -> Self {
        if other.at.len() <= self.at.len() {
            other
        } else {
            self
        }
    }
}

/// Context of one file: turns sub-slices of the source back into spans, and holds the node
/// pools the parsers add motions and aggregates to.
#[derive(Clone, Copy)]
pub(crate) struct Cx<'a> {
    base: &'a [u8],
    pub nodes: &'a RefCell<Nodes>,
}

impl<'a> Cx<'a> {
    pub fn new(base: &'a [u8], nodes: &'a RefCell<Nodes>) -> Cx<'a> {
        Cx { base, nodes }
    }

    /// The whole source.
    pub fn base(self) -> &'a [u8] {
        self.base
    }

    /// Byte offset of a sub-slice of the source.
    pub fn off(self, s: &[u8]) -> usize {
        s.as_ptr() as usize - self.base.as_ptr() as usize
    }

    /// Span of the part of `before` that was consumed to leave `after`.
    pub fn span(self, before: &[u8], after: &[u8]) -> Span {
        Span::new(self.off(before), self.off(after))
    }

    /// Span of a slice of the source.
    pub fn span_of(self, s: &[u8]) -> Span {
        let o = self.off(s);
        Span::new(o, o + s.len())
    }
}

/// A backtracking error at `at`.
pub(crate) fn backtrack<T>(at: &[u8]) -> Fails<'_, T> {
    Err(nom::Err::Error(PErr { at, msg: &NO_MSG }))
}

/// A committed failure at `at` with a message.
pub(crate) fn fail_with<'a, T>(at: &'a [u8], msg: &'static Msg) -> Fails<'a, T> {
    Err(nom::Err::Failure(PErr { at, msg }))
}

/// `fail!(at, "label", "help")`: a committed failure (label and help are constants).
macro_rules! fail {
    ($at:expr, $label:expr, $help:expr $(,)?) => {
        $crate::krl::syntax::lex::fail_with(
            $at,
            &$crate::krl::syntax::lex::Msg {
                label: $label,
                help: $help,
            },
        )
    };
}
pub(crate) use fail;

/// Runs `p`; if it backtracks, fails here with `msg` (deeper failures pass through).
pub(crate) fn expect_with<'a, T>(
    msg: &'static Msg,
    mut p: impl FnMut(&'a [u8]) -> PResult<'a, T>,
) -> impl FnMut(&'a [u8]) -> PResult<'a, T> {
    move |i| match p(i) {
        Err(nom::Err::Error(_)) => fail_with(i, msg),
        other => other,
    }
}

/// `expecting!("label", "help", parser)`: the parser, or a committed failure where it started.
macro_rules! expecting {
    ($label:expr, $help:expr, $p:expr $(,)?) => {
        $crate::krl::syntax::lex::expect_with(
            &$crate::krl::syntax::lex::Msg {
                label: $label,
                help: $help,
            },
            $p,
        )
    };
}
pub(crate) use expecting;

/// `p` after optional blanks (blanks may stand between any two tokens of the grammar).
pub(crate) fn tok<'a, T>(
    p: impl FnMut(&'a [u8]) -> PResult<'a, T>,
) -> impl FnMut(&'a [u8]) -> PResult<'a, T> {
    nom::sequence::preceded(ws, p)
}

/// `p`, its failures turned into backtracks: an alternative whose failure must not stop the
/// next one from being tried.
pub(crate) fn only_backtracks<'a, T>(
    mut p: impl FnMut(&'a [u8]) -> PResult<'a, T>,
) -> impl FnMut(&'a [u8]) -> PResult<'a, T> {
    move |i| match p(i) {
        Err(nom::Err::Failure(e)) => Err(nom::Err::Error(e)),
        other => other,
    }
}

/// Byte classes, one table lookup per byte in the hot loops.
const BLANK: u8 = 1;
const IDENT_START: u8 = 2;
const IDENT_CHAR: u8 = 4;

static CLASS: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut b = 0;
    while b < 256 {
        let c = b as u8;
        if matches!(c, b' ' | b'\t' | b'\r' | 0x0b | 0x0c) {
            t[b] |= BLANK;
        }
        if c.is_ascii_alphabetic() || c == b'_' || c == b'$' {
            t[b] |= IDENT_START | IDENT_CHAR;
        }
        if c.is_ascii_digit() {
            t[b] |= IDENT_CHAR;
        }
        b += 1;
    }
    t
};

#[inline]
pub(crate) fn is_blank(b: u8) -> bool {
    CLASS[usize::from(b)] & BLANK != 0
}

#[inline]
pub(crate) fn is_ident_start(b: u8) -> bool {
    CLASS[usize::from(b)] & IDENT_START != 0
}

#[inline]
pub(crate) fn is_ident_char(b: u8) -> bool {
    CLASS[usize::from(b)] & IDENT_CHAR != 0
}

/// Number of blanks at the start of `i`.
#[inline]
pub(crate) fn blanks(i: &[u8]) -> usize {
    i.iter().take_while(|&&b| is_blank(b)).count()
}

/// Optional blanks (never a line end: the parser sees one line of code at a time).
pub(crate) fn ws(i: &[u8]) -> PResult<'_, &[u8]> {
    let n = i.iter().take_while(|&&b| is_blank(b)).count();
    Ok((&i[n..], &i[..n]))
}

/// After optional blanks, a `,` and optional blanks: the input after them, or `None` when no
/// comma comes next (the separator of every list in the grammar).
pub(crate) fn next_item(i: &[u8]) -> Option<&[u8]> {
    let skip = |s: &[u8]| s.iter().take_while(|&&b| is_blank(b)).count();
    let j = &i[skip(i)..];
    (j.first() == Some(&b',')).then(|| &j[1 + skip(&j[1..])..])
}

/// `item {, item}`: a comma-separated list (separators read by `next_item`); the first
/// failing item fails the list.
pub(crate) fn list<'a, T>(
    i: &'a [u8],
    mut item: impl FnMut(&'a [u8]) -> PResult<'a, T>,
) -> Fails<'a, Vec<T>> {
    let mut items = Vec::new();
    let mut j = i;
    loop {
        let (k, v) = item(j)?;
        items.push(v);
        match next_item(k) {
            Some(n) => j = n,
            None => return Ok((k, items)),
        }
    }
}

/// At least one blank, or the end of the code, or a punctuation byte (keywords end there).
pub(crate) fn sep(i: &[u8]) -> PResult<'_, &[u8]> {
    match i.first() {
        Some(&b) if is_ident_char(b) => backtrack(i),
        _ => ws(i),
    }
}

/// An identifier: a letter, `_` or `$`, then letters, digits, `_`, `$`.
pub(crate) fn ident(i: &[u8]) -> PResult<'_, &[u8]> {
    match i.first() {
        Some(&b) if is_ident_start(b) => {
            let n = 1 + i[1..].iter().take_while(|&&b| is_ident_char(b)).count();
            Ok((&i[n..], &i[..n]))
        }
        _ => backtrack(i),
    }
}

/// The keyword `word` in any case, as a whole identifier.
pub(crate) fn keyword<'a>(word: &'static str) -> impl Fn(&'a [u8]) -> PResult<'a, &'a [u8]> {
    move |i| {
        let (rest, id) = ident(i)?;
        if id.eq_ignore_ascii_case(word.as_bytes()) {
            Ok((rest, id))
        } else {
            backtrack(i)
        }
    }
}

/// The byte `c`.
pub(crate) fn punct<'a>(c: u8) -> impl Fn(&'a [u8]) -> PResult<'a, &'a [u8]> {
    move |i| match i.first() {
        Some(&b) if b == c => Ok((&i[1..], &i[..1])),
        _ => backtrack(i),
    }
}

/// A numeric literal with its optional sign glued to it: (text, parsed literal).
pub(crate) fn number_literal(i: &[u8]) -> PResult<'_, (&[u8], number::Literal)> {
    match number::scan(i) {
        // `1abc` is not a number followed by a name.
        Some(lit) if !i.get(lit.len).is_some_and(|&b| is_ident_char(b)) => {
            Ok((&i[lit.len..], (&i[..lit.len], lit)))
        }
        _ => backtrack(i),
    }
}

/// A string literal `"…"` (KRL strings have no escapes; any byte but `"` and a line end).
pub(crate) fn string(i: &[u8]) -> PResult<'_, &[u8]> {
    if i.first() != Some(&b'"') {
        return backtrack(i);
    }
    match i[1..].iter().position(|&b| b == b'"') {
        Some(p) => Ok((&i[p + 2..], &i[..p + 2])),
        None => fail!(
            i,
            "unterminated string",
            "close the string with a second \" on the same line",
        ),
    }
}

/// A bit or hex literal `'B0101'`, `'H1F'` (also any other single-quoted text).
pub(crate) fn bits(i: &[u8]) -> PResult<'_, &[u8]> {
    if i.first() != Some(&b'\'') {
        return backtrack(i);
    }
    match i[1..].iter().position(|&b| b == b'\'') {
        Some(p) => Ok((&i[p + 2..], &i[..p + 2])),
        None => fail!(
            i,
            "unterminated bit or hex literal",
            "write binary as 'B0101' and hexadecimal as 'H1F'",
        ),
    }
}

/// An enumeration literal `#BASE`.
pub(crate) fn enum_literal(i: &[u8]) -> PResult<'_, &[u8]> {
    if i.first() != Some(&b'#') {
        return backtrack(i);
    }
    let (rest, _) = expecting!(
        "expected an enumeration value after #",
        "enumeration values are written #NAME, e.g. #BASE",
        ident,
    )(&i[1..])?;
    Ok((rest, &i[..i.len() - rest.len()]))
}

/// The first identifier of a line, upper-cased into `buf` (for keyword dispatch), or empty.
pub(crate) fn first_word<'b>(code: &[u8], buf: &'b mut [u8; 16]) -> &'b [u8] {
    match ident(code) {
        Ok((_, w)) if w.len() <= buf.len() => {
            for (d, s) in buf.iter_mut().zip(w) {
                *d = s.to_ascii_uppercase();
            }
            &buf[..w.len()]
        }
        _ => &buf[..0],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lexemes() {
        assert_eq!(ident(b"$VEL.CP").unwrap(), (&b".CP"[..], &b"$VEL"[..]));
        assert!(ident(b"1x").is_err());
        assert_eq!(keyword("lin")(b"LIN P1").unwrap().0, b" P1");
        assert!(keyword("LIN")(b"LIN_REL").is_err());
        assert_eq!(string(b"\"a; b\" x").unwrap().1, b"\"a; b\"");
        assert!(matches!(string(b"\"open"), Err(nom::Err::Failure(_))));
        assert_eq!(bits(b"'B010',").unwrap().1, b"'B010'");
        assert_eq!(enum_literal(b"#BASE}").unwrap().1, b"#BASE");
        assert_eq!(number_literal(b"-2.5E+01,").unwrap().1 .0, b"-2.5E+01");
        assert!(number_literal(b"12ab").is_err());
        let mut buf = [0; 16];
        assert_eq!(first_word(b"Lin_Rel {", &mut buf), b"LIN_REL");
    }

    #[test]
    fn byte_classes_match_their_definitions() {
        for b in 0..=255u8 {
            assert_eq!(is_blank(b), b" \t\r\x0b\x0c".contains(&b), "{b}");
            let start = b.is_ascii_alphabetic() || b == b'_' || b == b'$';
            assert_eq!(is_ident_start(b), start, "{b}");
            assert_eq!(is_ident_char(b), start || b.is_ascii_digit(), "{b}");
        }
    }
}
