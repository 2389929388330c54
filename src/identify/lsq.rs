//! Sparse linear least squares, the inner step of Gauss–Newton / Levenberg–Marquardt
//! identification: rows of the measurement Jacobian (a few dozen non-zeros each: the geometric
//! parameters plus two interpolation weights per table) are gathered by rows, the normal
//! matrix AᵀA is formed sparse and factored by faer's sparse Cholesky (with its fill-reducing
//! ordering), which also yields covariance columns for standard errors.
//! Damping (λ·I rows) and regularisation (smoothness rows) are ordinary extra rows.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::matmul::sparse_sparse_matmul;
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Mat, Par, Side};

/// Why a least-squares system could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LsqError {
    /// The normal matrix is singular: parameters the data do not determine.
    #[error("the normal matrix is not positive definite: some parameters are not determined by the data (add damping or pin them)")]
    Singular,
    #[error("least-squares system too large for memory")]
    /// The system does not fit in memory.
    OutOfMemory,
    #[error("row entry refers to parameter {index}, but the system has {n} parameters")]
    /// A row names a parameter the system does not have.
    BadIndex {
        /// The parameter named.
        index: usize,
        /// The system's parameters.
        n: usize,
    },
}

/// A sparse system `min ‖A x − b‖²` assembled row by row, stored by rows (CSR), which is
/// exactly Aᵀ by columns: no triplet sorting when the normal matrix is formed.
#[derive(Debug, Clone)]
pub struct SparseLsq {
    n: usize,
    /// Start of each row in `cols`/`vals`, plus the end.
    row_ptr: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
    rhs: Vec<f64>,
    /// Scratch for sorting and merging a row's entries.
    scratch: Vec<(usize, f64)>,
}

impl Default for SparseLsq {
    fn default() -> Self {
        SparseLsq::new(0)
    }
}

/// The solution and the factorisation of the normal matrix it came from.
pub struct LsqSolution {
    pub x: Vec<f64>,
    /// Residual sum of squares ‖A x − b‖² at the solution (only the tests read it).
    #[cfg(any(test, feature = "internals"))]
    pub rss: f64,
    llt: faer::sparse::linalg::solvers::Llt<usize, f64>,
    n: usize,
}

impl SparseLsq {
    /// An empty system over `n` parameters.
    pub fn new(n: usize) -> Self {
        SparseLsq {
            n,
            row_ptr: vec![0],
            cols: Vec::new(),
            vals: Vec::new(),
            rhs: Vec::new(),
            scratch: Vec::new(),
        }
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn parameters(&self) -> usize {
        self.n
    }

    pub fn rows(&self) -> usize {
        self.rhs.len()
    }

    /// Appends the row `Σ value·x[index] ≈ rhs` (zero entries are skipped, repeated indices
    /// summed).
    pub fn push_row(&mut self, entries: &[(usize, f64)], rhs: f64) -> Result<(), LsqError> {
        self.scratch.clear();
        for &(index, value) in entries {
            if index >= self.n {
                return Err(LsqError::BadIndex { index, n: self.n });
            }
            if value != 0.0 {
                self.scratch.push((index, value));
            }
        }
        self.scratch.sort_unstable_by_key(|e| e.0);
        let mut last = None;
        for &(index, value) in &self.scratch {
            if last == Some(index) {
                if let Some(v) = self.vals.last_mut() {
                    *v += value;
                }
            } else {
                self.cols.push(index);
                self.vals.push(value);
                last = Some(index);
            }
        }
        self.row_ptr.push(self.cols.len());
        self.rhs.push(rhs);
        Ok(())
    }

    /// Appends `sqrt(weight)·x[index] ≈ 0` for every parameter: Levenberg–Marquardt damping /
    /// Tikhonov regularisation towards the current estimate.
    pub fn push_damping(&mut self, weights: &[f64]) -> Result<(), LsqError> {
        for (i, w) in weights.iter().enumerate() {
            if *w > 0.0 {
                self.push_row(&[(i, w.sqrt())], 0.0)?;
            }
        }
        Ok(())
    }

    /// Solves the normal equations AᵀA x = Aᵀb by sparse Cholesky.
    pub fn solve(&self) -> Result<LsqSolution, LsqError> {
        let oom = |_| LsqError::OutOfMemory;
        let rows = self.rows();
        // The rows of A are the columns of Aᵀ (indices sorted and unique per row).
        let symbolic = SymbolicSparseColMat::new_checked(
            self.n,
            rows,
            self.row_ptr.clone(),
            None,
            self.cols.clone(),
        );
        let at = SparseColMat::<usize, f64>::new(symbolic, self.vals.clone());
        let a = at.as_ref().transpose().to_col_major().map_err(oom)?;
        let ata = sparse_sparse_matmul(at.as_ref(), a.as_ref(), 1.0, Par::Seq).map_err(oom)?;
        let llt = ata
            .sp_cholesky(Side::Lower)
            .map_err(|_| LsqError::Singular)?;
        let mut atb = Mat::<f64>::zeros(self.n, 1);
        for r in 0..rows {
            for k in self.row_ptr[r]..self.row_ptr[r + 1] {
                atb[(self.cols[k], 0)] += self.vals[k] * self.rhs[r];
            }
        }
        llt.solve_in_place(atb.as_mut());
        let x: Vec<f64> = (0..self.n).map(|i| atb[(i, 0)]).collect();
        if x.iter().any(|v| !v.is_finite()) {
            return Err(LsqError::Singular);
        }
        #[cfg(any(test, feature = "internals"))]
        let rss = (0..rows)
            .map(|r| {
                let ax: f64 = (self.row_ptr[r]..self.row_ptr[r + 1])
                    .map(|k| self.vals[k] * x[self.cols[k]])
                    .sum();
                (ax - self.rhs[r]).powi(2)
            })
            .sum();
        Ok(LsqSolution {
            x,
            #[cfg(any(test, feature = "internals"))]
            rss,
            llt,
            n: self.n,
        })
    }
}

impl LsqSolution {
    /// Columns `columns` of (AᵀA)⁻¹ at once (n × k, one column per entry): a multi-column
    /// solve with the factor, much cheaper per column than [`Self::inverse_normal_column`].
    pub fn inverse_normal_columns(&self, columns: &[usize]) -> Mat<f64> {
        let mut e = Mat::<f64>::zeros(self.n, columns.len());
        for (k, &i) in columns.iter().enumerate() {
            if i < self.n {
                e[(i, k)] = 1.0;
            }
        }
        self.llt.solve_in_place(e.as_mut());
        e
    }

    /// Solves (AᵀA) Z = H in place for the columns of `h` (n × k): the inverse normal
    /// matrix applied to a few vectors, e.g. the sensitivities of one predicted position.
    pub fn solve_normal_in_place(&self, h: faer::MatMut<'_, f64>) {
        self.llt.solve_in_place(h);
    }

    /// Column `i` of (AᵀA)⁻¹: multiplied by σ² it is the covariance of parameter `i` with all
    /// others (σ² = rss / (rows − parameters) for unit-weight measurement rows).
    #[cfg(any(test, feature = "internals"))]
    pub fn inverse_normal_column(&self, i: usize) -> Vec<f64> {
        let mut e = Mat::<f64>::zeros(self.n, 1);
        if i < self.n {
            e[(i, 0)] = 1.0;
        }
        self.llt.solve_in_place(e.as_mut());
        (0..self.n).map(|k| e[(k, 0)]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// A deterministic pseudo-random sparse over-determined system.
    fn system(m: usize, n: usize) -> (SparseLsq, DMatrix<f64>, DVector<f64>) {
        let mut seed = 12345u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut lsq = SparseLsq::new(n);
        let mut dense = DMatrix::zeros(m, n);
        let mut b = DVector::zeros(m);
        for r in 0..m {
            let cols = [r % n, (r * 7 + 3) % n, (r * 13 + 5) % n];
            let mut row = Vec::new();
            for &c in &cols {
                let v = next();
                dense[(r, c)] += v;
                row.push((c, v));
            }
            b[r] = next();
            lsq.push_row(&row, b[r]).unwrap();
        }
        (lsq, dense, b)
    }

    #[test]
    fn matches_dense_svd_least_squares() {
        let (lsq, a, b) = system(200, 30);
        let sol = lsq.solve().unwrap();
        let reference = a.clone().svd(true, true).solve(&b, 1e-14).unwrap();
        for i in 0..30 {
            assert!(
                (sol.x[i] - reference[i]).abs() < 1e-9,
                "x[{i}] {} vs {}",
                sol.x[i],
                reference[i]
            );
        }
        let rss = (&a * &reference - &b).norm_squared();
        assert!((sol.rss - rss).abs() < 1e-9 * rss.max(1.0));
        // Covariance column equals the column of the dense inverse normal matrix.
        let inv = (a.transpose() * &a).try_inverse().unwrap();
        let col = sol.inverse_normal_column(4);
        for k in 0..30 {
            assert!((col[k] - inv[(k, 4)]).abs() < 1e-9 * inv[(4, 4)].abs());
        }
    }

    #[test]
    fn damping_rows_make_an_underdetermined_system_solvable() {
        // x0 + x1 = 2 alone is singular; with unit damping the minimum-norm-like answer is 2/3.
        let mut lsq = SparseLsq::new(2);
        lsq.push_row(&[(0, 1.0), (1, 1.0)], 2.0).unwrap();
        assert_eq!(lsq.solve().err(), Some(LsqError::Singular));
        lsq.push_damping(&[1.0, 1.0]).unwrap();
        let sol = lsq.solve().unwrap();
        assert!((sol.x[0] - 2.0 / 3.0).abs() < 1e-12 && (sol.x[1] - 2.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn bad_index_is_an_error() {
        let mut lsq = SparseLsq::new(2);
        assert_eq!(
            lsq.push_row(&[(2, 1.0)], 0.0),
            Err(LsqError::BadIndex { index: 2, n: 2 })
        );
    }
}
