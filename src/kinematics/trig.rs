//! Sines, cosines and `atan2` of joint angles, the most frequent library calls of a
//! compensation run (forward and inverse kinematics, the axis rates, the error chain, A/B/C:
//! some thirty per target). Each is a table of the library's values and an addition theorem
//! with a short series, to about an ulp of the library (tested), at a third (sin/cos) and a
//! half (atan2) of its cost when several are computed side by side: no range reduction, no
//! branches on the argument's size.
//! - [`sin_cos`]: the values at every 1/128 rad over ±[`RANGE_RAD`] and
//!   `sin(θ₀ + d) = sin θ₀·cos d + cos θ₀·sin d`, |d| ≤ 1/256.
//! - [`atan2`]: the octant's ratio `t ∈ [0, 1]`, `atan t_k` at every 1/64 and
//!   `atan t = atan t_k + atan((t − t_k)/(1 + t·t_k))`, the second argument below 1/128.
//!
//! Arguments outside the tables (and zeros, infinities, NaN for `atan2`) go to the library.

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

/// Table spacing of [`atan2`]'s ratio: 2⁻⁶, so that `t − t_k` is exact (Sterbenz).
const ATAN_PER: f64 = 64.0;
/// `atan(k/64)`, k = 0..=64.
static ATAN: LazyLock<[f64; 65]> =
    LazyLock::new(|| std::array::from_fn(|k| (k as f64 / ATAN_PER).atan()));
/// π/2 and π as the sum of their nearest f64 and the rest (for `π/2 − a`, `π − a` to an ulp).
const HALF_PI: (f64, f64) = (std::f64::consts::FRAC_PI_2, 6.123_233_995_736_766e-17);
const PI: (f64, f64) = (std::f64::consts::PI, 1.224_646_799_147_353_2e-16);

/// `y.atan2(x)` to within 3 ulps (see the module doc).
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    // Zeros (signed results), infinities, NaN and extreme magnitudes: the library.
    if !(ax > 1e-150 && ay > 1e-150 && ax < 1e150 && ay < 1e150) {
        return y.atan2(x);
    }
    // The octant: t = min/max, atan2 = atan t or π/2 − atan t, then mirrored for x < 0.
    let swap = ay > ax;
    let (num, den) = if swap { (ax, ay) } else { (ay, ax) };
    let t = num / den;
    let shifted = t * ATAN_PER + ROUND;
    // 0 ≤ t·64 ≤ 64: the rounded integer is the mantissa's low seven bits.
    let k = (shifted.to_bits() & 127) as usize;
    let tk = (shifted - ROUND) * (1.0 / ATAN_PER);
    // |u| ≤ 1/128: the series' next term (u⁹/9) is below 10⁻¹⁶ of u's ulp.
    let u = (t - tk) / (1.0 + t * tk);
    let u2 = u * u;
    let a = ATAN[k] + (u + u * u2 * (-1.0 / 3.0 + u2 * (0.2 - u2 * (1.0 / 7.0))));
    let r = if swap { (HALF_PI.0 - a) + HALF_PI.1 } else { a };
    let r = if x < 0.0 { (PI.0 - r) + PI.1 } else { r };
    r.copysign(y)
}

/// `v.round()` (half away from zero), bit for bit, without the library call the build's
/// baseline x86-64 makes of it (no `roundsd` before SSE4.1): the wrap of angles by whole turns
/// rounds a dozen times per target.
#[inline]
pub fn round(v: f64) -> f64 {
    // From 2⁵² on every f64 is an integer; NaN and infinities go to the library too.
    let fractional = v.abs() < 4_503_599_627_370_496.0;
    if !fractional {
        return v.round();
    }
    // The truncation keeps v's sign (−0.3 → −0); v − t, the fraction, is exact.
    let t = (v as i64 as f64).copysign(v);
    if (v - t).abs() >= 0.5 {
        t + 1f64.copysign(v)
    } else {
        t
    }
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

    /// Against the library: within 3 ulps of the result, in every octant, at the table's
    /// points and between them, for tiny and huge ratios; the library's own special cases.
    #[test]
    fn atan2_within_three_ulps_of_the_library() {
        let check = |y: f64, x: f64| {
            let (ours, lib) = (atan2(y, x), y.atan2(x));
            assert!(
                (ours - lib).abs() <= 3.0 * f64::EPSILON * lib.abs(),
                "atan2({y}, {x}) = {ours} vs {lib}"
            );
        };
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x2545_f491_4f6c_dd1d);
        let mut next = move || rng.gen_range(-1.0..1.0);
        for _ in 0..200_000 {
            let (y, x) = (next() * 1500.0, next() * 1500.0);
            check(y, x);
            check(y * 1e-9, x);
        }
        for k in 0..=64 {
            let t = k as f64 / 64.0;
            for dt in [0.0, 0.5 / 64.0, -0.5 / 64.0, 1e-13] {
                let r = t + dt;
                for (y, x) in [(r, 1.0), (1.0, r), (-r, 1.0), (r, -1.0), (-1.0, -r)] {
                    check(y * 820.0, x * 820.0);
                }
            }
        }
        for (y, x) in [(1e-200, 1.0), (1.0, 1e-200), (1e200, 3.0)] {
            check(y, x);
        }
        assert_eq!(atan2(0.0, -1.0), std::f64::consts::PI);
        assert_eq!(atan2(-0.0, 1.0).to_bits(), (-0.0f64).to_bits());
        assert_eq!(atan2(1.0, 1.0), std::f64::consts::FRAC_PI_4);
        assert!(atan2(f64::NAN, 1.0).is_nan());
    }

    /// The library's `round`, bit for bit: halves, their neighbours, signed zeros, the
    /// largest fractions, integers beyond 2⁵², non-finite values.
    #[test]
    fn round_is_the_library_round() {
        let same = |v: f64| assert_eq!(round(v).to_bits(), v.round().to_bits(), "{v}");
        for k in -2000..=2000 {
            let h = k as f64 * 0.5;
            for v in [h, h.next_up(), h.next_down(), h / 360.0, k as f64 * 0.1] {
                same(v);
                same(-v);
            }
        }
        let big = 4_503_599_627_370_496.0f64;
        for v in [
            0.0,
            -0.0,
            0.499_999_999_999_999_94,
            big - 0.5,
            big - 1.5,
            big,
            big * 3.0 + 2.0,
            1e300,
            f64::INFINITY,
            f64::MIN_POSITIVE,
        ] {
            same(v);
            same(-v);
        }
        assert!(round(f64::NAN).is_nan());
    }

    proptest::proptest! {
        /// `round` is the library's for any value.
        #[test]
        fn round_matches_anywhere(v in proptest::num::f64::ANY) {
            proptest::prop_assert!(round(v).to_bits() == v.round().to_bits() || v.is_nan());
        }

        /// sin² + cos² = 1 to rounding, anywhere.
        #[test]
        fn on_the_unit_circle(x in -20.0f64..20.0) {
            let (s, c) = sin_cos(x);
            proptest::prop_assert!((s * s + c * c - 1.0).abs() <= 4.0 * f64::EPSILON);
        }
    }
}
