//! LU factorisation with partial pivoting of a 6×6 matrix, the axis Jacobian of a 6-axis arm.
//! The factorisation is exactly nalgebra's `Matrix::lu` (same pivot choice, same operations
//! in the same order: bit-identical factors and the same "exactly zero pivot" notion of
//! singular), on fixed-size arrays the compiler unrolls: the generic version walks matrix
//! views and cost a quarter of the per-target solve. The solve multiplies by the pivots'
//! reciprocals, kept from the factorisation, where nalgebra divides: a chain of six
//! divisions was most of a solve's latency (results differ from nalgebra's in the last bits).

use nalgebra::{Matrix6, Vector6};

/// `P·J = L·U`, L unit lower triangular, stored as nalgebra stores it.
#[derive(Clone, Copy, Debug)]
pub struct Lu6 {
    /// Row-major: `a[r][c]`; U on and above the diagonal, L's multipliers below it.
    a: [[f64; 6]; 6],
    /// Row `i` of `P·J` is row `perm[i]` of `J` (the row swaps of the pivoting composed:
    /// the solve gathers `P·b` at once instead of swapping through memory).
    perm: [usize; 6],
    /// No pivot is exactly zero.
    invertible: bool,
    /// `1 / a[i][i]` (infinite for a zero pivot).
    inv_diag: [f64; 6],
}

impl Lu6 {
    #[cfg(any(test, feature = "internals"))]
    pub fn new(m: &Matrix6<f64>) -> Lu6 {
        let mut lu = Lu6::singular();
        lu.factor(m);
        lu
    }

    /// The factors of the zero matrix: a place to [`Self::factor`] into.
    pub fn singular() -> Lu6 {
        Lu6 {
            a: [[0.0; 6]; 6],
            perm: [0, 1, 2, 3, 4, 5],
            inv_diag: [f64::INFINITY; 6],
            invertible: false,
        }
    }

    /// Factorises `m` in place of the factors held (a solver refactorising at every
    /// linearisation moves no 384-byte factorisation around).
    pub fn factor(&mut self, m: &Matrix6<f64>) {
        let Lu6 {
            a,
            perm,
            inv_diag,
            invertible,
        } = self;
        *a = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]));
        *perm = [0, 1, 2, 3, 4, 5];
        *inv_diag = [f64::INFINITY; 6];
        for i in 0..6 {
            // The first row holding the largest magnitude (nalgebra's `icamax`).
            let mut piv = i;
            let mut largest = a[i][i].abs();
            for (r, row) in a.iter().enumerate().skip(i + 1) {
                if row[i].abs() > largest {
                    largest = row[i].abs();
                    piv = r;
                }
            }
            let diag = a[piv][i];
            if diag == 0.0 {
                continue;
            }
            if piv != i {
                a.swap(i, piv);
                perm.swap(i, piv);
            }
            let inv = 1.0 / diag;
            inv_diag[i] = inv;
            let pivot_row = a[i];
            for row in a.iter_mut().skip(i + 1) {
                row[i] *= inv;
                let coeff = row[i];
                for k in i + 1..6 {
                    row[k] += -pivot_row[k] * coeff;
                }
            }
        }
        *invertible = (0..6).all(|i| a[i][i] != 0.0);
    }

    /// Whether no pivot is exactly zero.
    pub fn is_invertible(&self) -> bool {
        self.invertible
    }

    /// `x` with `J·x = b`, or `None` when a pivot is zero.
    #[allow(clippy::needless_range_loop)] // x and the factors indexed alike, as in the formulas
    pub fn solve(&self, b: &Vector6<f64>) -> Option<Vector6<f64>> {
        let mut x: [f64; 6] = std::array::from_fn(|i| b[self.perm[i]]);
        // L·y = P·b, unit diagonal.
        for i in 0..5 {
            let coeff = x[i];
            for r in i + 1..6 {
                x[r] += -coeff * self.a[r][i];
            }
        }
        // U·x = y.
        if !self.is_invertible() {
            return None;
        }
        for i in (0..6).rev() {
            let coeff = x[i] * self.inv_diag[i];
            x[i] = coeff;
            for r in 0..i {
                x[r] += -coeff * self.a[r][i];
            }
        }
        Some(Vector6::from(x))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic spread of matrices: well conditioned, with ties and zeros in the pivot
    /// columns, rank-deficient.
    fn matrices() -> Vec<Matrix6<f64>> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x2545_f491_4f6c_dd1d);
        let mut next = move || rng.gen_range(-1.0..1.0);
        let mut out: Vec<Matrix6<f64>> =
            (0..200).map(|_| Matrix6::from_fn(|_, _| next())).collect();
        // Equal magnitudes in a column (pivot ties), an exact zero column, a repeated row.
        out.push(Matrix6::from_fn(|r, c| {
            if c == 0 {
                [1.0, -1.0][r % 2]
            } else {
                next()
            }
        }));
        out.push(Matrix6::from_fn(|_, c| if c == 2 { 0.0 } else { next() }));
        let mut repeated = Matrix6::from_fn(|_, _| next());
        let row = repeated.row(1).into_owned();
        repeated.set_row(4, &row);
        out.push(repeated);
        out.push(Matrix6::zeros());
        out
    }

    /// What nalgebra's LU gives (to rounding: it divides where we multiply by reciprocals),
    /// including which matrices count as singular.
    #[test]
    fn same_as_nalgebra() {
        for m in matrices() {
            let ours = Lu6::new(&m);
            let theirs = m.lu();
            assert_eq!(ours.is_invertible(), theirs.is_invertible(), "{m}");
            let b = Vector6::new(0.3, -1.0, 2.0, 1e-3, -4e-4, 7.0);
            let (x, y) = (ours.solve(&b), theirs.solve(&b));
            assert_eq!(x.is_some(), y.is_some());
            if let (Some(x), Some(y)) = (x, y) {
                let scale = y.amax().max(1.0);
                assert!((x - y).amax() <= 1e-12 * scale, "{m}: {x} vs {y}");
            }
        }
    }

    /// And it solves: `J·x = b` back to rounding on a regular matrix.
    #[test]
    fn solves() {
        let m = matrices()[3];
        let b = Vector6::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0);
        let x = Lu6::new(&m).solve(&b).unwrap();
        assert!((m * x - b).norm() < 1e-10);
    }
}
