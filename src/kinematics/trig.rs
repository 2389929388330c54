//! Sines and cosines of joint angles, the most frequent library calls of a compensation run
//! (forward and inverse kinematics, the axis rates, the error chain, several per target).
//! A table of the library's values at every 1/128 rad over ±[`RANGE_RAD`] and the addition
//! theorem `sin(θ₀ + d) = sin θ₀·cos d + cos θ₀·sin d` with a short series (|d| ≤ 1/256), to
//! about an ulp of the library (tested), at a third of its cost when several are computed side
//! by side: no range reduction, no branches on the argument's size. Arguments outside the table
//! go to the library. (`atan2` and `round` are the library's: a table `atan2` measured inside
//! the noise of the benchmark, BENCH.md.)

use std::sync::LazyLock;

/// Table spacing: 2⁻⁷ rad, a power of two, so that the table's abscissae are exact and the
/// reduced argument `d = θ − k/128` is computed without rounding (Sterbenz).
const PER_RAD: f64 = 128.0;
/// The table covers `[−RANGE_RAD, RANGE_RAD]`: joint angles with their offsets (±350° plus a
/// half turn is 9.2 rad).
pub const RANGE_RAD: f64 = 10.0;
const HALF: usize = (RANGE_RAD * PER_RAD) as usize;

/// Adding this to `y` (|y| < 2⁵¹) rounds it to an integer `n`, whose bits are the mantissa's
/// low bits (two's complement, modulo 2⁵²).
const ROUND: f64 = 1.5 * 4_503_599_627_370_496.0;
/// `n + HALF` is the table index; the mask keeps it from the mantissa's other bits.
const INDEX_MASK: usize = (1 << 20) - 1;

/// `(sin, cos)` of `(k − HALF)/128`, k = 0..=2·HALF (41 KB).
static TABLE: LazyLock<Box<[(f64, f64)]>> = LazyLock::new(|| {
    (0..=2 * HALF)
        .map(|k| ((k as f64 - HALF as f64) / PER_RAD).sin_cos())
        .collect()
});

/// `(sin x, cos x)` to about an ulp (see the module doc).
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    // Also false for NaN, which the library turns into NaN.
    let in_table = x.abs() <= RANGE_RAD;
    if !in_table {
        return x.sin_cos();
    }
    // Nearest table point: adding 1.5·2⁵² rounds x·128 to an integer, held in the low bits
    // (no float-integer conversions on the latency path).
    let shifted = x * PER_RAD + ROUND;
    let k = (shifted.to_bits() as usize).wrapping_add(HALF) & INDEX_MASK;
    let (s0, c0) = TABLE[k];
    // Exact: x and k/128 agree to within 1/256 and a factor of two (or k/128 is 0).
    let d = x - (shifted - ROUND) * (1.0 / PER_RAD);
    // |d| ≤ 1/256: the terms left out (d⁹/9!, d⁸/8!) are below 10⁻²⁰ of the result's ulp.
    // Multiplications by the coefficients (divisions would be a chain of 15-cycle latencies).
    let d2 = d * d;
    let sd = d + d * d2 * (-1.0 / 6.0 + d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0)));
    let cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)));
    (s0 * cd + c0 * sd, c0 * cd - s0 * sd)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the library: within 2 ε absolute (the values are at most 1) over the table and
    /// beyond it, at the table's points and half-way between them, and exact at 0.
    #[test]
    fn within_two_epsilon_of_the_library() {
        let mut worst = 0.0f64;
        let mut check = |x: f64| {
            let (s, c) = sin_cos(x);
            let (s1, c1) = x.sin_cos();
            worst = worst.max((s - s1).abs()).max((c - c1).abs());
            assert!(
                (s - s1).abs() <= 2.0 * f64::EPSILON && (c - c1).abs() <= 2.0 * f64::EPSILON,
                "{x}: ({s}, {c}) vs ({s1}, {c1})"
            );
        };
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x9e37_79b9_7f4a_7c15);
        for _ in 0..200_000 {
            check(rng.gen_range(-12.0..12.0));
        }
        for k in -1300..=1300 {
            let x = k as f64 / PER_RAD;
            for dx in [0.0, 0.5 / PER_RAD, -0.5 / PER_RAD, 1e-12, -3e-9] {
                check(x + dx);
            }
        }
        for x in [
            std::f64::consts::PI,
            -std::f64::consts::FRAC_PI_2,
            RANGE_RAD,
            -RANGE_RAD,
        ] {
            check(x);
        }
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        assert!(sin_cos(f64::NAN).0.is_nan());
        assert!(worst <= 2.0 * f64::EPSILON);
    }

    proptest::proptest! {
        /// sin² + cos² = 1 to rounding, anywhere.
        #[test]
        fn on_the_unit_circle(x in -20.0f64..20.0) {
            let (s, c) = sin_cos(x);
            proptest::prop_assert!((s * s + c * c - 1.0).abs() <= 4.0 * f64::EPSILON);
        }
    }
}
