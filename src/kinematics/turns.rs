//! The ±360° variants of an axis within its joint limits, the turn bits T (sign of each axis)
//! that tell them apart, and the choice of one variant per axis: nearest a previous angle, or
//! with a given sign.

use super::robot::RobotDescription;

/// Angles this far (deg) outside a joint limit are taken as on it (rounding).
pub const LIMIT_TOLERANCE_DEG: f64 = 1e-9;

/// Turns per degree. Counting turns by this product instead of a division (whose latency
/// dominated the enumeration of variants) is off by an ulp at most, far inside the limit
/// tolerance, so a limit never falls on a rounding edge.
const PER_TURN: f64 = 1.0 / 360.0;

fn limits(robot: &RobotDescription, i: usize) -> (f64, f64) {
    let [lo, hi] = robot.limits_deg[i];
    (lo - LIMIT_TOLERANCE_DEG, hi + LIMIT_TOLERANCE_DEG)
}

/// The values `a + 360°·k` of one axis within its limits, ascending: `first + 360°·j` for
/// `j < len` (kept as two numbers: they are copied around in the hot loops).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Variants {
    first: f64,
    len: usize,
}

impl Variants {
    pub fn of(robot: &RobotDescription, i: usize, a: f64) -> Variants {
        let (lo, hi) = limits(robot, i);
        let q = (a - lo) * PER_TURN;
        // Also refuses NaN and infinities.
        if q.is_nan() || q.abs() >= 1e6 {
            return Variants { first: a, len: 0 };
        }
        // The lowest value ≥ lo is a − 360°·⌊q⌋; floor by a truncating cast (no libm call).
        let mut k = q as i64;
        if (k as f64) > q {
            k -= 1;
        }
        let first = a - 360.0 * k as f64;
        if first > hi {
            return Variants { first, len: 0 };
        }
        // Joint ranges are a few turns at most; the cast truncates toward zero (≥ 0 here).
        // Through i64: a float → unsigned cast is a branchy instruction sequence on x86-64.
        let len = 1 + (((hi - first) * PER_TURN) as i64).clamp(0, 64) as usize;
        Variants { first, len }
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The `j`-th value, ascending.
    #[inline]
    pub fn get(&self, j: usize) -> f64 {
        // j ≤ 64: through u32, whose conversion to f64 is one instruction (usize's is not).
        self.first + 360.0 * f64::from(j as u32)
    }

    pub fn values(&self) -> impl Iterator<Item = f64> + '_ {
        (0..self.len).map(|j| self.get(j))
    }
}

/// The turn bits of an axis set: bit i = axis i+1 negative.
pub(crate) fn turn(axes: &[f64; 6]) -> u8 {
    axes.iter()
        .enumerate()
        .fold(0u8, |t, (i, a)| t | u8::from(*a < 0.0) << i)
}

/// The variant of axis `i` at `a` within limits nearest `target`.
#[inline]
pub(crate) fn nearest(robot: &RobotDescription, i: usize, a: f64, target: f64) -> Option<f64> {
    let (lo, hi) = limits(robot, i);
    // Round (target − a)/360 half away from zero with a truncating cast (no libm call).
    let q = (target - a) * PER_TURN;
    if q.abs() < 1e6 {
        let v = a + 360.0 * ((q + 0.5f64.copysign(q)) as i64) as f64;
        if v >= lo && v <= hi {
            return Some(v);
        }
        // The nearest lies outside: the next one inward is the nearest inside, if any.
        let w = if v > hi { v - 360.0 } else { v + 360.0 };
        if w >= lo && w <= hi {
            return Some(w);
        }
    }
    let mut best: Option<f64> = None;
    for v in Variants::of(robot, i, a).values() {
        if best.map_or(true, |b| (v - target).abs() < (b - target).abs()) {
            best = Some(v);
        }
    }
    best
}

/// Per axis the variant nearest `target`; `None` if an axis has none within limits.
#[inline]
pub(crate) fn nearest_all(
    robot: &RobotDescription,
    axes: &[f64; 6],
    target: &[f64; 6],
) -> Option<[f64; 6]> {
    let mut out = [0.0; 6];
    for i in 0..6 {
        out[i] = nearest(robot, i, axes[i], target[i])?;
    }
    Some(out)
}

/// Per axis the variant nearest zero whose sign is bit i of `t`; `None` if there is none.
pub(crate) fn with_turn(robot: &RobotDescription, axes: &[f64; 6], t: u8) -> Option<[f64; 6]> {
    let mut out = [0.0; 6];
    for i in 0..6 {
        let negative = t >> i & 1 == 1;
        // The variants nearest zero on each side are a and a ∓ 360° for a in (−360°, 360°).
        let a = axes[i];
        let quick = match (a < 0.0, negative) {
            (true, false) => a + 360.0,
            (false, true) => a - 360.0,
            _ => a,
        };
        let (lo, hi) = limits(robot, i);
        out[i] = if a.abs() < 360.0 && quick >= lo && quick <= hi {
            quick
        } else {
            Variants::of(robot, i, a)
                .values()
                .filter(|v| (*v < 0.0) == negative)
                .min_by(|x, y| x.abs().total_cmp(&y.abs()))?
        };
    }
    Some(out)
}

/// Calls `f` with every combination of the axes' variants and its turn bits, in increasing
/// T: A6 (T bit 5) varies slowest, A1 fastest, and each axis runs from its largest value
/// down, so non-negative (bit 0) before negative (bit 1). Nothing when an axis has no variant.
pub(crate) fn each_variant(
    robot: &RobotDescription,
    axes: &[f64; 6],
    mut f: impl FnMut([f64; 6], u8),
) {
    let mut v = [Variants { first: 0.0, len: 0 }; 6];
    for i in 0..6 {
        v[i] = Variants::of(robot, i, axes[i]);
        if v[i].is_empty() {
            return;
        }
    }
    let mut index = [0usize; 6];
    loop {
        let a: [f64; 6] = std::array::from_fn(|i| v[i].get(v[i].len - 1 - index[i]));
        f(a, turn(&a));
        // Next combination, A1 fastest.
        let mut i = 0;
        loop {
            index[i] += 1;
            if index[i] < v[i].len {
                break;
            }
            index[i] = 0;
            i += 1;
            if i == 6 {
                return;
            }
        }
    }
}

/// The first axis with no variant within limits, and its variant nearest the limits' middle.
pub(crate) fn first_outside(robot: &RobotDescription, axes: &[f64; 6]) -> Option<(u8, f64)> {
    (0..6).find_map(|i| {
        if !Variants::of(robot, i, axes[i]).is_empty() {
            return None;
        }
        let [lo, hi] = robot.limits_deg[i];
        let mid = 0.5 * (lo + hi);
        Some((
            i as u8 + 1,
            axes[i] + 360.0 * ((mid - axes[i]) / 360.0).round(),
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_and_nearest_by_hand() {
        let robot = RobotDescription::kr30ha();
        // A4 within ±350: 100 and −260.
        let a4: Vec<f64> = Variants::of(&robot, 3, 100.0).values().collect();
        assert_eq!(a4, [-260.0, 100.0]);
        // A2 within −135..35: 170 has none.
        assert!(Variants::of(&robot, 1, 170.0).is_empty());
        assert_eq!(nearest(&robot, 3, 100.0, -200.0), Some(-260.0));
        assert_eq!(
            nearest(&robot, 3, 100.0, 500.0),
            Some(100.0),
            "460 is beyond 350"
        );
        assert_eq!(nearest(&robot, 0, 179.0, -170.0), Some(-181.0));
        assert_eq!(nearest(&robot, 1, 170.0, 0.0), None);
        assert_eq!(
            with_turn(&robot, &[0.0, 0.0, 0.0, 100.0, 0.0, 0.0], 0b1000).map(|a| a[3]),
            Some(-260.0)
        );
        let mut ts = Vec::new();
        each_variant(&robot, &[179.0, -30.0, 20.0, 100.0, 40.0, -10.0], |a, t| {
            assert_eq!(t, turn(&a));
            ts.push(t)
        });
        assert_eq!(ts.len(), 8);
        assert!(ts.windows(2).all(|w| w[0] <= w[1]), "{ts:?}");
    }
}
