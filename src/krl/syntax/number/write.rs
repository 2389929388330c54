//! Writing a value into KRL text: in the style of the literal it replaces ([`format_like`]),
//! only when the written number changes ([`write_like`]), or plainly ([`write_fixed`]). Plain
//! literals (`-?digits[.digits]`, nearly every program's) are written by a digit writer of
//! their own ([`write_plain`]): a million targets' numbers are most of a rewrite's bytes.

use super::read::{scan, Literal};
use super::ten_to;

/// Writes `value` in the style of the literal `original`: the same number of decimals (never
/// fewer than `min_decimals`), the same exponent form, a leading `.` kept for values below 1,
/// an explicit `+` kept for non-negative values. Negative zero is written without a sign.
///
/// `original` should be a numeric literal; if it is not, the value is written plainly with
/// `min_decimals` decimals. A non-finite value is written as Rust spells it (`NaN`, `inf`),
/// which a controller rejects at load time: callers must not produce one.
///
/// ```
/// use robopost::krl::number::format_like;
/// assert_eq!(format_like(b"1.0", 1.23456, 3), "1.235");
/// assert_eq!(format_like(b"-2.5E+01", 25.37, 2), "2.537E+01");
/// assert_eq!(format_like(b".25", 0.5, 0), ".50");
/// ```
pub fn format_like(original: &[u8], value: f64, min_decimals: usize) -> String {
    let lit = scan(original).filter(|l| l.len == original.len());
    let Some(lit) = lit else {
        return plain(value, min_decimals, 0, false, false);
    };
    if !value.is_finite() {
        return format!("{value}");
    }
    match lit.exponent {
        None => plain(
            value,
            lit.frac_digits.max(min_decimals),
            lit.sign,
            lit.int_digits == 0,
            lit.has_dot,
        ),
        Some((letter, esign, edigits)) => {
            scientific(value, &lit, min_decimals, letter, esign, edigits)
        }
    }
}

/// Fixed-point form: `decimals` decimals, optional leading-dot and trailing-dot styles.
fn plain(value: f64, decimals: usize, sign: u8, leading_dot: bool, dot: bool) -> String {
    let mut body = format!("{:.*}", decimals, value.abs());
    let zero = body.bytes().all(|b| b == b'0' || b == b'.');
    if leading_dot && body.starts_with("0.") {
        body.remove(0);
    }
    if decimals == 0 && dot {
        body.push('.');
    }
    let prefix = if value < 0.0 && !zero {
        "-"
    } else if sign == b'+' {
        "+"
    } else {
        ""
    };
    format!("{prefix}{body}")
}

/// Exponent form with a one-digit mantissa; enough mantissa decimals that the absolute
/// resolution is at least `10^-min_decimals`, never fewer than the original's.
fn scientific(
    value: f64,
    lit: &Literal,
    min_decimals: usize,
    letter: u8,
    esign: u8,
    edigits: usize,
) -> String {
    let mut decimals = lit.frac_digits;
    let (mut mantissa, mut exp) = split_exp(value.abs(), decimals);
    for _ in 0..4 {
        let need = (min_decimals as i64 + exp).max(0) as usize;
        if decimals >= need {
            break;
        }
        decimals = need;
        (mantissa, exp) = split_exp(value.abs(), decimals);
    }
    let zero = mantissa.bytes().all(|b| b == b'0' || b == b'.');
    if lit.int_digits == 0 && mantissa.starts_with("0.") {
        mantissa.remove(0);
    }
    let prefix = if value < 0.0 && !zero {
        "-"
    } else if lit.sign == b'+' {
        "+"
    } else {
        ""
    };
    let exp_sign = if exp < 0 {
        "-"
    } else if esign == b'+' {
        "+"
    } else {
        ""
    };
    format!(
        "{prefix}{mantissa}{}{exp_sign}{:0w$}",
        letter as char,
        exp.unsigned_abs(),
        w = edigits
    )
}

/// `v` as (mantissa text with `decimals` decimals, exponent), mantissa in [1, 10).
fn split_exp(v: f64, decimals: usize) -> (String, i64) {
    let s = format!("{:.*e}", decimals, v);
    let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
    (m.to_string(), e.parse().unwrap_or(0))
}

/// Appends to `out` the new text of literal `original` (value `old`) for `value`, in its style
/// (see [`format_like`]); false, and nothing appended, when the written number would not
/// change (its bytes are then kept).
///
/// ```
/// use robopost::krl::number::write_like;
/// let mut out = Vec::new();
/// assert!(!write_like(b"1.000", 1.0, 1.0002, 3, &mut out)); // still 1.000: kept
/// assert!(write_like(b"1.000", 1.0, 1.0016, 3, &mut out));
/// assert_eq!(out, b"1.002");
/// ```
pub fn write_like(
    original: &[u8],
    old: f64,
    value: f64,
    min_decimals: usize,
    out: &mut Vec<u8>,
) -> bool {
    if let Some(own) = plain_decimals(original) {
        let decimals = own.max(min_decimals);
        if let (Some(new), Some(old)) = (units(value, decimals), units(old, decimals)) {
            if new == old {
                return false;
            }
            write_plain(new, decimals, out);
            return true;
        }
    }
    let new = format_like(original, value, min_decimals);
    if new == format_like(original, old, min_decimals) {
        return false;
    }
    out.extend_from_slice(new.as_bytes());
    true
}

/// Appends `value` written plainly with `decimals` decimals (`-0.000` written `0.000`), as a
/// number inserted where a literal had none to take the style from.
pub fn write_fixed(value: f64, decimals: usize, out: &mut Vec<u8>) {
    match units(value, decimals) {
        Some(u) => write_plain(u, decimals, out),
        None => out.extend_from_slice(format!("{:.*}", decimals, value).as_bytes()),
    }
}

/// The decimals of a literal written plainly: `-?digits[.digits]` (no exponent, sign `+` or
/// leading dot), the style of nearly every program; those are written by [`write_plain`], the
/// others (`None`) by [`format_like`].
fn plain_decimals(text: &[u8]) -> Option<usize> {
    let body = text.strip_prefix(b"-").unwrap_or(text);
    let int = body.iter().take_while(|b| b.is_ascii_digit()).count();
    if int == 0 {
        return None;
    }
    match &body[int..] {
        [] => Some(0),
        [b'.', rest @ ..] => rest.iter().all(u8::is_ascii_digit).then_some(rest.len()),
        _ => None,
    }
}

/// `value` rounded to `decimals` as an integer count of units (`None` beyond ±9·10^15): how
/// a number is written, and so how the compensation rounds a command it will write.
pub fn units(value: f64, decimals: usize) -> Option<i64> {
    let scaled = (value * ten_to(decimals)).round();
    (scaled.abs() < 9.0e15).then_some(scaled as i64)
}

/// Pairs of decimal digits `00`..`99`, for [`write_plain`].
const DIGIT_PAIRS: [u8; 200] = {
    let mut t = [0u8; 200];
    let mut i = 0;
    while i < 100 {
        t[2 * i] = b'0' + (i / 10) as u8;
        t[2 * i + 1] = b'0' + (i % 10) as u8;
        i += 1;
    }
    t
};

/// Appends the plain literal of `units` at `decimals` (`-0.000` written `0.000`): digits by
/// integer division, no formatting machinery. The digits go straight into `out`, over a
/// block of zeros appended at once and cut back: built in a stack buffer and copied as a
/// block, the wide load of bytes just stored one by one would stall on store forwarding.
fn write_plain(units: i64, decimals: usize, out: &mut Vec<u8>) {
    /// Fraction digits written this way (10^18 < 2^64); more go the long way.
    const MAX_DECIMALS: usize = 18;
    /// Bytes of zeros appended at once: every number up to this length.
    const BLOCK: usize = 24;
    if decimals > MAX_DECIMALS {
        return write_plain_long(units, decimals, out);
    }
    let n = units.unsigned_abs();
    // The usual decimals by constant divisors (a multiplication), the rest by a division.
    let (mut int, mut frac) = match decimals {
        3 => (n / 1_000, n % 1_000),
        4 => (n / 10_000, n % 10_000),
        _ => {
            let unit = 10u64.pow(decimals as u32);
            (n / unit, n % unit)
        }
    };
    let int_digits = int.checked_ilog10().map_or(1, |l| l as usize + 1);
    let sign = usize::from(units < 0);
    let point = usize::from(decimals > 0);
    let len = sign + int_digits + point + decimals;
    let start = out.len();
    if len <= BLOCK {
        out.extend_from_slice(&[b'0'; BLOCK]);
    } else {
        out.resize(start + len, b'0');
    }
    let text = &mut out[start..start + len];
    // Right to left: the fraction (its leading zeros are there already), point, integer.
    // Two digits a step (one division by 100 for two by 10).
    let mut at = len;
    while frac >= 10 {
        at -= 2;
        let d = (frac % 100) as usize * 2;
        text[at..at + 2].copy_from_slice(&DIGIT_PAIRS[d..d + 2]);
        frac /= 100;
    }
    if frac > 0 {
        text[at - 1] = b'0' + frac as u8;
    }
    at = len - decimals - point;
    if point == 1 {
        text[at] = b'.';
    }
    while int >= 100 {
        at -= 2;
        let d = (int % 100) as usize * 2;
        text[at..at + 2].copy_from_slice(&DIGIT_PAIRS[d..d + 2]);
        int /= 100;
    }
    if int >= 10 {
        at -= 2;
        let d = int as usize * 2;
        text[at..at + 2].copy_from_slice(&DIGIT_PAIRS[d..d + 2]);
    } else {
        text[at - 1] = b'0' + int as u8;
    }
    if sign == 1 {
        text[0] = b'-';
    }
    out.truncate(start + len);
}

/// [`write_plain`] for any number of decimals.
fn write_plain_long(units: i64, decimals: usize, out: &mut Vec<u8>) {
    let digits = units.unsigned_abs().to_string();
    if units < 0 {
        out.push(b'-');
    }
    if digits.len() <= decimals {
        out.extend_from_slice(b"0.");
        out.resize(out.len() + decimals - digits.len(), b'0');
        out.extend_from_slice(digits.as_bytes());
    } else {
        let (int, frac) = digits.as_bytes().split_at(digits.len() - decimals);
        out.extend_from_slice(int);
        out.push(b'.');
        out.extend_from_slice(frac);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A plain literal of `units` at `decimals` (see [`write_plain`]).
    fn plain_text(units: i64, decimals: usize) -> String {
        let mut out = Vec::with_capacity(24 + decimals);
        write_plain(units, decimals, &mut out);
        String::from_utf8(out).expect("digits, sign and dot are ASCII")
    }

    #[test]
    fn format_like_by_hand() {
        // Same decimals as the original unless more are asked for.
        assert_eq!(format_like(b"1.0", 1.23456, 0), "1.2");
        assert_eq!(format_like(b"1.0", 1.23456, 3), "1.235");
        assert_eq!(format_like(b"100.000", 100.0004, 3), "100.000");
        assert_eq!(format_like(b"100.000", -0.5, 3), "-0.500");
        assert_eq!(format_like(b"100", 100.5, 0), "100"); // ties to even on the exact binary value
        assert_eq!(format_like(b"100", 100.6, 0), "101");
        assert_eq!(format_like(b"100", 100.25, 2), "100.25");
        // Leading dot stays for values below 1, not above.
        assert_eq!(format_like(b".25", 0.3, 0), ".30");
        assert_eq!(format_like(b"-.25", -0.3, 0), "-.30");
        assert_eq!(format_like(b".25", 1.3, 0), "1.30");
        // Trailing dot.
        assert_eq!(format_like(b"1.", 2.4, 0), "2.");
        assert_eq!(format_like(b"1.", 2.4, 2), "2.40");
        // Explicit plus for non-negative values only.
        assert_eq!(format_like(b"+5.0", 6.25, 2), "+6.25");
        assert_eq!(format_like(b"+5.0", -6.25, 2), "-6.25");
        // No negative zero.
        assert_eq!(format_like(b"0.000", -0.0001, 3), "0.000");
        assert_eq!(format_like(b"1.5", -0.0, 1), "0.0");
        // Exponent form: letter case, explicit exponent sign, exponent width.
        assert_eq!(format_like(b"-2.5E+01", -25.0, 0), "-2.5E+01");
        assert_eq!(format_like(b"-2.5E+01", 25.37, 2), "2.537E+01");
        // The resolution of the value written is kept at 10^-min_decimals: 1500 with 0 decimals
        // needs three mantissa decimals in exponent form.
        assert_eq!(format_like(b"1e3", 1500.0, 0), "1.500e3");
        assert_eq!(format_like(b"1e3", 1500.0, 1), "1.5000e3");
        assert_eq!(format_like(b"1.0E-02", 0.0123, 4), "1.23E-02");
        assert_eq!(format_like(b"9.9E+00", 9.99, 1), "9.99E+00");
        assert_eq!(format_like(b"9.9E+00", 9.96, 0), "1.0E+01"); // carry into the exponent
        assert_eq!(format_like(b"1.5E+00", 0.0, 2), "0.00E+00");
        // Not a literal: plain with the minimum decimals.
        assert_eq!(format_like(b"X", 1.5, 2), "1.50");
    }

    /// The literal text by `format!` (the formatter the digit writer replaced): the integer
    /// count of units as a decimal string, the dot put in by hand.
    fn plain_by_format(units: i64, decimals: usize) -> String {
        let digits = units.unsigned_abs().to_string();
        let sign = if units < 0 { "-" } else { "" };
        if decimals == 0 {
            return format!("{sign}{digits}");
        }
        let padded = format!("{digits:0>width$}", width = decimals + 1);
        let (int, frac) = padded.split_at(padded.len() - decimals);
        format!("{sign}{int}.{frac}")
    }

    #[test]
    fn units_by_hand() {
        for (v, d, u) in [
            (0.5, 0, Some(1)),
            (-0.5, 0, Some(-1)),
            (1.5, 0, Some(2)),
            (2.5, 0, Some(3)),
            (-2.5, 0, Some(-3)),
            (0.49999999999999994, 0, Some(0)),
            (-0.0, 3, Some(0)),
            (1.0005, 3, Some(1001)), // the product is 1000.5: half away from zero
            (8.999_999_999_999_999e15, 0, Some(8_999_999_999_999_999)),
            (9.0e15, 0, None),
            (f64::NAN, 3, None),
            (f64::INFINITY, 3, None),
        ] {
            assert_eq!(units(v, d), u, "{v} at {d}");
        }
    }

    proptest! {
        #[test]
        fn digit_writer_matches_format(units in any::<i64>(), decimals in 0usize..30) {
            prop_assert_eq!(plain_text(units, decimals), plain_by_format(units, decimals));
        }

        /// A plain literal's new text equals `format_like` of the new value whenever the
        /// rounded number changes and the value is not a tie between two last digits.
        #[test]
        fn write_like_matches_format_like(
            orig_units in -10_000_000i64..10_000_000,
            delta in -5.0f64..5.0,
            decimals in 0usize..6,
            min in 3usize..5,
        ) {
            let orig_text = plain_by_format(orig_units, decimals);
            let orig: f64 = orig_text.parse().unwrap();
            let value = orig + delta;
            let d = decimals.max(min);
            let scaled = value * 10f64.powi(d as i32);
            prop_assume!((scaled.fract().abs() - 0.5).abs() > 1e-6);
            let mut out = Vec::new();
            let changed = write_like(orig_text.as_bytes(), orig, value, min, &mut out);
            let by_format = format_like(orig_text.as_bytes(), value, min);
            let unchanged = by_format == format_like(orig_text.as_bytes(), orig, min);
            prop_assert_eq!(changed, !unchanged);
            if changed {
                prop_assert_eq!(String::from_utf8(out).unwrap(), by_format);
            } else {
                prop_assert!(out.is_empty());
            }
        }
    }

    #[test]
    fn plain_literals_by_hand() {
        assert_eq!(plain_text(0, 3), "0.000");
        assert_eq!(plain_text(-5, 3), "-0.005");
        assert_eq!(plain_text(12345, 3), "12.345");
        assert_eq!(plain_text(-1234500, 4), "-123.4500");
        assert_eq!(plain_text(7, 0), "7");
        assert_eq!(plain_text(i64::MIN, 2), "-92233720368547758.08");
        assert_eq!(plain_text(-12, 18), "-0.000000000000000012");
        assert_eq!(plain_text(12, 20), "0.00000000000000000012");
        assert_eq!(plain_text(i64::MAX, 18), "9.223372036854775807");
    }
}
