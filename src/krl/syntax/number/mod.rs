//! KRL numeric literals: a literal's shape, its value read exactly as written (correctly
//! rounded to f64), and a new value written in the style of the literal it replaces, so a
//! rewritten program keeps the look of the original (`1.0` stays one decimal unless more are
//! needed, `.25` keeps its leading dot, `-2.5E+01` keeps its exponent form). Every number the
//! crate reads from or writes into KRL text goes through here; the compensation rounds its
//! commands with [`units`] (by [`ten_to`]) exactly as they will be written.
//!
//! - `read`: the shape of a literal (`scan`) and its value, and the one-pass reader of the
//!   plain literals CAM systems write (`read_plain`, `plain_len`).
//! - `write`: a value in a literal's style ([`format_like`], [`write_like`]), and the digit
//!   writer of plain literals ([`write_fixed`]).

mod read;
mod write;

pub(crate) use read::{plain_len, read_plain, scan, value, Literal};
pub use write::{write_fixed, write_like};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use write::{format_like, units};

/// Exact powers of ten representable in f64: 10^22 = 2^22·5^22 and 5^22 < 2^53, so every
/// power up to it is a double (Clinger's fast path works up to there), and so is every
/// product `powi` forms on the way.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `10f64.powi(decimals)`, from the table where that is exact (`POW10`).
pub fn ten_to(decimals: usize) -> f64 {
    match POW10.get(decimals) {
        Some(&p) => p,
        None => 10f64.powi(decimals as i32),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn powers_of_ten_from_the_table_are_powi() {
        for d in 0..40 {
            assert_eq!(
                super::ten_to(d).to_bits(),
                10f64.powi(d as i32).to_bits(),
                "10^{d}"
            );
        }
    }
}
