//! Reading a literal: its shape ([`scan`]) and its value ([`value`]), exact as written; and
//! the one pass that reads the plain literals of CAM programs ([`read_plain`]).

use super::POW10;

/// The shape of a numeric literal: `[+-] digits [. digits] [(e|E) [+-] digits]`, and what
/// is needed for its value, gathered in the same pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Literal {
    /// Total length in bytes.
    pub len: usize,
    /// `b'+'`, `b'-'` or 0.
    pub sign: u8,
    pub int_digits: usize,
    pub has_dot: bool,
    pub frac_digits: usize,
    /// Exponent letter (`b'e'`/`b'E'`) with its sign byte (or 0) and digit count.
    pub exponent: Option<(u8, u8, usize)>,
    /// The digits as an integer (exact when there are at most 19 of them).
    mantissa: u64,
    /// The exponent's value (clamped to ±1,000,000).
    exp_value: i64,
}

impl Literal {
    pub fn is_integer(&self) -> bool {
        !self.has_dot && self.exponent.is_none()
    }
}

/// Digits from `p`: (count, value of the first 19 as an integer appended to `m`).
fn digits(i: &[u8], mut p: usize, mut m: u64, mut taken: usize) -> (usize, u64, usize) {
    let start = p;
    while let Some(&b) = i.get(p) {
        if !b.is_ascii_digit() {
            break;
        }
        if taken < 19 {
            m = m * 10 + u64::from(b - b'0');
            taken += 1;
        }
        p += 1;
    }
    (p - start, m, taken)
}

/// Recognises a numeric literal at the start of `i` (no leading blanks), or `None`.
pub(crate) fn scan(i: &[u8]) -> Option<Literal> {
    let mut p = 0;
    let sign = match i.first() {
        Some(&s @ (b'+' | b'-')) => {
            p = 1;
            s
        }
        _ => 0,
    };
    let (int_digits, mut m, mut taken) = digits(i, p, 0, 0);
    p += int_digits;
    let mut has_dot = false;
    let mut frac_digits = 0;
    if i.get(p) == Some(&b'.') {
        let (f, m2, t2) = digits(i, p + 1, m, taken);
        // `1.` is a real, `.5` is a real, a lone `.` is not a number.
        if int_digits > 0 || f > 0 {
            has_dot = true;
            frac_digits = f;
            p += 1 + f;
            m = m2;
            taken = t2;
        }
    }
    if int_digits == 0 && frac_digits == 0 {
        return None;
    }
    let _ = taken;
    let mut exponent = None;
    let mut exp_value = 0;
    if let Some(&e @ (b'e' | b'E')) = i.get(p) {
        let mut q = p + 1;
        let esign = match i.get(q) {
            Some(&s @ (b'+' | b'-')) => {
                q += 1;
                s
            }
            _ => 0,
        };
        let start = q;
        while i.get(q).is_some_and(u8::is_ascii_digit) {
            exp_value = (exp_value * 10 + i64::from(i[q] - b'0')).min(1_000_000);
            q += 1;
        }
        if q > start {
            exponent = Some((e, esign, q - start));
            if esign == b'-' {
                exp_value = -exp_value;
            }
            p = q;
        } else {
            exp_value = 0;
        }
    }
    Some(Literal {
        len: p,
        sign,
        int_digits,
        has_dot,
        frac_digits,
        exponent,
        mantissa: m,
        exp_value,
    })
}

/// The value of a literal recognised by [`scan`], correctly rounded.
///
/// Short literals (≤ 19 digits, mantissa ≤ 2^53, |exponent| ≤ 22 — every number a controller
/// or CAM system writes) take Clinger's exact fast path: one exact integer, one exact power
/// of ten, one rounding. Anything else goes through the standard library parser.
pub(crate) fn value(text: &[u8], lit: &Literal) -> f64 {
    let negative = lit.sign == b'-';
    if lit.int_digits + lit.frac_digits <= 19 {
        let e10 = lit.exp_value - lit.frac_digits as i64;
        if let Some(v) = exact(negative, lit.mantissa, e10) {
            return v;
        }
    }
    std::str::from_utf8(&text[..lit.len])
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .unwrap_or(f64::NAN)
}

/// `±m·10^e10` by Clinger's fast path when it is exact (m ≤ 2^53, |e10| ≤ 22: one exact
/// integer, one exact power of ten, one rounding), else `None`. `m` must hold every digit.
#[inline]
fn exact(negative: bool, m: u64, e10: i64) -> Option<f64> {
    if m == 0 {
        return Some(if negative { -0.0 } else { 0.0 });
    }
    if m > (1u64 << 53) || !(-22..=22).contains(&e10) {
        return None;
    }
    let v = m as f64;
    let v = if e10 >= 0 {
        v * POW10[e10 as usize]
    } else {
        v / POW10[(-e10) as usize]
    };
    Some(if negative { -v } else { v })
}

/// The common literal in one pass: `[+-] digits [. digits]` with at most 19 digits and no
/// exponent, as CAM systems write coordinates. Gives (length, value, integer) when the
/// literal has that shape and its value is exact on Clinger's path, else `None` (then
/// [`scan`] and [`value`] read it; both give the same answer where both apply).
#[inline]
pub(crate) fn read_plain(i: &[u8]) -> Option<(usize, f64, bool)> {
    let p = scan_plain(i)?;
    let v = exact(p.negative, p.m, -(p.frac_digits as i64))?;
    Some((p.len, v, !p.dot))
}

/// A plain literal's parts as [`scan_plain`] reads them.
struct PlainParts {
    len: usize,
    negative: bool,
    /// Every digit, as one integer.
    m: u64,
    frac_digits: usize,
    dot: bool,
}

/// The shape check and digits of [`read_plain`], its value not computed.
#[inline]
fn scan_plain(i: &[u8]) -> Option<PlainParts> {
    let mut p = 0;
    let negative = match i.first() {
        Some(b'-') => {
            p = 1;
            true
        }
        Some(b'+') => {
            p = 1;
            false
        }
        _ => false,
    };
    // Digits from `p` appended to `m` (wrapping past 19 digits in all: declined below).
    let run = |mut p: usize, mut m: u64| -> (usize, u64) {
        while let Some(&b) = i.get(p) {
            let d = b.wrapping_sub(b'0');
            if d > 9 {
                break;
            }
            m = m.wrapping_mul(10).wrapping_add(u64::from(d));
            p += 1;
        }
        (p, m)
    };
    let (q, m) = run(p, 0);
    let int_digits = q - p;
    p = q;
    let dot = i.get(p) == Some(&b'.');
    let (m, frac_digits) = if dot {
        let (q, m) = run(p + 1, m);
        let frac_digits = q - (p + 1);
        p = q;
        (m, frac_digits)
    } else {
        (m, 0)
    };
    // No digit at all, or more than 19 (`m` would have overflowed).
    if !(1..=19).contains(&(int_digits + frac_digits)) {
        return None;
    }
    if matches!(i.get(p), Some(b'e' | b'E')) {
        return None;
    }
    Some(PlainParts {
        len: p,
        negative,
        m,
        frac_digits,
        dot,
    })
}

/// The length of the literal [`read_plain`] reads at the start of `i` (the same `None`s),
/// without computing its value: what the parser needs to record a member it reads later.
/// (The same test as [`exact`]'s, without its division.)
#[inline]
pub(crate) fn plain_len(i: &[u8]) -> Option<usize> {
    let p = scan_plain(i)?;
    (p.m == 0 || (p.m <= (1u64 << 53) && p.frac_digits <= 22)).then_some(p.len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The length-only reader declines exactly what the value reader declines (long
        /// mantissas, 23+ decimals, exponents, non-numbers) and agrees on the length.
        #[test]
        fn plain_len_is_read_plain_length(t in "[-+]?[0-9]{0,21}(\\.[0-9]{0,25})?([eE,} x][0-9]?)?") {
            prop_assert_eq!(plain_len(t.as_bytes()), read_plain(t.as_bytes()).map(|(len, _, _)| len));
        }
    }

    /// The edges, by hand: 2^53 is in, 2^53 + 1 out; 19 digits in all are read, 20 are not
    /// (so the 22-decimal limit of Clinger's path is never reached); zero is always exact.
    #[test]
    fn plain_len_at_the_exactness_edges() {
        assert_eq!(plain_len(b"9007199254740992"), Some(16));
        assert_eq!(plain_len(b"9007199254740993"), None);
        assert_eq!(plain_len(b"0.000000000000000001"), Some(20));
        assert_eq!(plain_len(b"0.0000000000000000001"), None);
        assert_eq!(plain_len(b"-0.000000000000000000"), Some(21));
        assert_eq!(plain_len(b"-1234567890123456789"), None);
        assert_eq!(plain_len(b"1.5e3"), None);
    }

    /// The one-pass reader agrees with scan + value wherever it accepts, bit for bit, and
    /// declines exponents, long mantissas and non-numbers.
    #[test]
    fn plain_agrees_with_scan_and_value() {
        for t in [
            "0",
            "-0",
            "+0",
            "-0.000",
            "1.",
            ".25",
            "-.5",
            "+3.75",
            "123.456",
            "-2.500",
            "9007199254740992",
            "9007199254740993",
            "1234567890123456789",
            "0.1",
            "0.3",
            "-1.000000000000000001",
            "300.125,",
            "12}",
            "7 ",
        ] {
            let lit = scan(t.as_bytes()).unwrap();
            let (len, v, integer) = match read_plain(t.as_bytes()) {
                Some(x) => x,
                None => {
                    // Declined only for values off Clinger's exact path.
                    assert!(
                        lit.int_digits + lit.frac_digits > 19 || lit.mantissa > 1 << 53,
                        "{t}"
                    );
                    continue;
                }
            };
            assert_eq!(len, lit.len, "{t}");
            assert_eq!(integer, lit.is_integer(), "{t}");
            let want = value(t.as_bytes(), &lit);
            assert_eq!(v.to_bits(), want.to_bits(), "{t}");
            assert_eq!(v, t[..len].parse::<f64>().unwrap(), "{t}");
        }
        for t in [
            "",
            "-",
            "+",
            ".",
            "-.",
            "1e3",
            "2.5E+01",
            "12345678901234567890",
            "x1",
            "- 1",
        ] {
            assert_eq!(read_plain(t.as_bytes()), None, "{t}");
        }
    }

    fn val(s: &str) -> f64 {
        let lit = scan(s.as_bytes()).unwrap();
        assert_eq!(lit.len, s.len(), "{s}");
        value(s.as_bytes(), &lit)
    }

    #[test]
    fn values_match_the_standard_parser() {
        for s in [
            "0",
            "1",
            "-1",
            "+7",
            "1.0",
            ".25",
            "-.5",
            "1.",
            "123.456",
            "-2.5E+01",
            "1e3",
            "1E-3",
            "0.1",
            "0.3",
            "9007199254740993",
            "12345678901234567890123",
            "1e300",
            "4.9e-324",
            "2.2250738585072014E-308",
            "0.000000000000000000000000001",
            "-0.0",
            "1234567.1234567",
            "99999999999999999999.5",
        ] {
            let want: f64 = s.parse().unwrap();
            assert_eq!(val(s).to_bits(), want.to_bits(), "{s}");
        }
    }

    #[test]
    fn literal_boundaries() {
        assert_eq!(scan(b"1.5,Y").unwrap().len, 3);
        assert_eq!(scan(b"10E").unwrap().len, 2); // no digits: not an exponent
        assert_eq!(scan(b"2e+").unwrap().len, 1);
        assert_eq!(scan(b"1.E5").unwrap().len, 4);
        assert!(scan(b".").is_none());
        assert!(scan(b"-x").is_none());
        assert!(scan(b"1").unwrap().is_integer());
        assert!(!scan(b"1.").unwrap().is_integer());
    }
}
