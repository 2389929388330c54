//! Lookup tables of the error model: 1-D linear interpolation over an increasing grid (the
//! paper's section 2.2, "linearly interpolating Δθ_n,map") and 2-D bilinear interpolation (its
//! section 2.4, crosstalk). Outside the grid the value is held at the edge and the lookup says
//! so. Lookups return the interpolation weights, which are also the Jacobian of the value with
//! respect to the table entries. The cell is guessed from the mean pitch and corrected by a
//! step or two, so uniform grids (the common case) and nearly uniform ones (a last cell cut
//! at a joint limit, merged grids) find it in O(1); others fall back to binary search.

/// A strictly increasing grid of abscissae (degrees in this crate).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    points: Vec<f64>,
    /// `1 / (points[i+1] − points[i])`: a lookup's weight and slope multiply by the cell's
    /// reciprocal width (a division's latency was a third of a table lookup).
    inv_width: Vec<f64>,
    /// `(first point, 1 / mean pitch)`: where the cell of an abscissa is guessed.
    guess: (f64, f64),
}

/// Where an abscissa falls on a grid: `value = (1 − w)·v[lo] + w·v[hi]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    pub lo: usize,
    pub hi: usize,
    /// Weight of `hi`, in [0, 1].
    pub w: f64,
    /// The abscissa lay outside the grid and was held at the edge.
    pub clamped: bool,
}

/// Why a list of numbers is not a grid.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GridError {
    /// No point.
    #[error("a grid needs at least one point")]
    Empty,
    /// A point that is not a finite number.
    #[error("grid point {index} is {found}, not finite")]
    NotFinite {
        /// The point's index.
        index: usize,
        /// Its value.
        found: f64,
    },
    /// A point not above the one before.
    #[error("grid point {index} is {found}, not greater than the previous point {previous}")]
    NotIncreasing {
        /// The point's index.
        index: usize,
        /// The point before it, degrees.
        previous: f64,
        /// Its value, degrees.
        found: f64,
    },
    /// More points than a table may have, or a pitch finer than the finest.
    #[error("a grid from {lo}° to {hi}° every {pitch}° would have {points} points; at most {MAX_POINTS} are allowed and the pitch must be at least {MIN_PITCH_DEG}°")]
    TooFine {
        /// The range's start, degrees.
        lo: f64,
        /// The range's end, degrees.
        hi: f64,
        /// The pitch asked for, degrees.
        pitch: f64,
        /// The points it would have.
        points: f64,
    },
}

/// The finest pitch [`Grid::from_range`] lays out, degrees (a gear error does not vary over a
/// thousandth of a degree, and a finer grid would only be memory).
pub const MIN_PITCH_DEG: f64 = 1e-3;
/// The most points [`Grid::from_range`] lays out (a whole turn at 0.004°).
pub const MAX_POINTS: usize = 100_000;

impl Grid {
    /// Checks the points (finite, strictly increasing) and detects equal spacing.
    pub fn new(points: Vec<f64>) -> Result<Grid, GridError> {
        if points.is_empty() {
            return Err(GridError::Empty);
        }
        for (index, &found) in points.iter().enumerate() {
            if !found.is_finite() {
                return Err(GridError::NotFinite { index, found });
            }
            if index > 0 && found <= points[index - 1] {
                return Err(GridError::NotIncreasing {
                    index,
                    previous: points[index - 1],
                    found,
                });
            }
        }
        let guess = mean_spacing(&points);
        let inv_width = points.windows(2).map(|w| 1.0 / (w[1] - w[0])).collect();
        Ok(Grid {
            points,
            inv_width,
            guess,
        })
    }

    /// `lo, lo + pitch, …` up to the first point ≥ `hi` (so the range is covered and the
    /// spacing stays uniform even when the pitch does not divide the range).
    pub fn from_range(lo: f64, hi: f64, pitch: f64) -> Result<Grid, GridError> {
        if !(pitch > 0.0 && pitch.is_finite() && lo.is_finite() && hi.is_finite()) {
            return Err(GridError::NotFinite {
                index: 0,
                found: pitch,
            });
        }
        // The small tolerance keeps a pitch that divides the range from adding a spare point.
        let cells = ((hi - lo) / pitch - 1e-9).ceil().max(0.0);
        if pitch < MIN_PITCH_DEG || cells >= MAX_POINTS as f64 {
            return Err(GridError::TooFine {
                lo,
                hi,
                pitch,
                points: cells + 1.0,
            });
        }
        let cells = cells as usize;
        Grid::new((0..=cells).map(|i| lo + i as f64 * pitch).collect())
    }

    pub fn points(&self) -> &[f64] {
        &self.points
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Whether `x` lies outside `[first, last]`.
    #[cfg(any(test, feature = "internals"))]
    pub fn outside(&self, x: f64) -> bool {
        x < self.points[0] || x > self.points[self.points.len() - 1]
    }

    /// The cell holding `x` and the linear weight inside it.
    #[inline]
    pub fn locate(&self, x: f64) -> Cell {
        let n = self.points.len();
        let (first, last) = (self.points[0], self.points[n - 1]);
        if n == 1 {
            return Cell {
                lo: 0,
                hi: 0,
                w: 0.0,
                clamped: x != first,
            };
        }
        if x <= first {
            return Cell {
                lo: 0,
                hi: 1,
                w: 0.0,
                clamped: x < first,
            };
        }
        if x >= last {
            return Cell {
                lo: n - 2,
                hi: n - 1,
                w: 1.0,
                clamped: x > last,
            };
        }
        let p = &self.points;
        let (start, per_pitch) = self.guess;
        let mut lo = (((x - start) * per_pitch) as usize).min(n - 2);
        // x lies in [p[lo], p[lo+1]): on a uniform grid the guess itself, else at most two
        // steps from a good guess.
        if !(p[lo] <= x && x < p[lo + 1]) {
            for _ in 0..2 {
                if p[lo] > x {
                    lo -= 1; // p[0] < x here, so lo > 0
                } else if p[lo + 1] <= x {
                    lo += 1; // x < p[n-1], so lo + 1 < n - 1
                }
            }
            if !(p[lo] <= x && x < p[lo + 1]) {
                // First point greater than x, minus one.
                lo = p.partition_point(|&q| q <= x).saturating_sub(1).min(n - 2);
            }
        }
        Cell {
            lo,
            hi: lo + 1,
            w: ((x - self.points[lo]) * self.inv_width[lo]).clamp(0.0, 1.0),
            clamped: false,
        }
    }
}

impl Grid {
    /// [`Self::locate`] trying the cell `hint` first, which then holds the cell found: a
    /// solver evaluating commands millidegrees apart finds them in the cell of the first.
    /// The same cell as [`Self::locate`]'s, since an inner abscissa lies in exactly one (a
    /// cell that holds `x` lies inside the grid: only `x` on the first point is not inner,
    /// and there both give cell 0 at weight 0).
    #[inline]
    pub fn locate_near(&self, x: f64, hint: &mut usize) -> Cell {
        let lo = *hint;
        if let Some(&[a, b]) = self.points.get(lo..lo + 2) {
            if a <= x && x < b {
                return Cell {
                    lo,
                    hi: lo + 1,
                    w: ((x - a) * self.inv_width[lo]).clamp(0.0, 1.0),
                    clamped: false,
                };
            }
        }
        let cell = self.locate(x);
        *hint = cell.lo;
        cell
    }
}

/// `(first point, 1 / mean pitch)` of a grid (a single point: any finite pair).
fn mean_spacing(points: &[f64]) -> (f64, f64) {
    if points.len() < 2 {
        return (points[0], 0.0);
    }
    let pitch = (points[points.len() - 1] - points[0]) / (points.len() - 1) as f64;
    (points[0], 1.0 / pitch)
}

/// One cell of a [`Table1`] with what an interpolation inside it needs: a solver whose
/// evaluations stay in one cell interpolates from it without indexing the table (no bounds
/// checks, no loads through the grid's and the values' vectors). Inside the cell the value is
/// [`Table1::value_in`]'s of the cell [`Grid::locate`] finds, to the bit: the same operations
/// on the same numbers.
#[derive(Clone, Copy, Debug, Default)]
pub struct Piece {
    /// Which table the piece is of (its owner's numbering, from 1); 0: none.
    key: u8,
    a: f64,
    b: f64,
    inv_width: f64,
    at_a: f64,
    at_b: f64,
}

impl Piece {
    /// The value at `x` if the piece is of table `key` and holds `x`.
    #[inline(always)]
    pub fn value(&self, key: u8, x: f64) -> Option<f64> {
        if self.key == key && self.a <= x && x < self.b {
            let w = ((x - self.a) * self.inv_width).clamp(0.0, 1.0);
            Some((1.0 - w) * self.at_a + w * self.at_b)
        } else {
            None
        }
    }
}

/// A 1-D table: one value per grid point, linearly interpolated.
#[derive(Clone, Debug, PartialEq)]
pub struct Table1 {
    pub grid: Grid,
    pub values: Vec<f64>,
}

impl Table1 {
    /// A table of zeros over `grid`.
    pub fn zeros(grid: Grid) -> Table1 {
        let values = vec![0.0; grid.len()];
        Table1 { grid, values }
    }

    /// The interpolated value at `x` and where it came from.
    pub fn eval(&self, x: f64) -> (f64, Cell) {
        let cell = self.grid.locate(x);
        (self.value_in(&cell), cell)
    }

    /// Cell `lo` as a [`Piece`] of table `key` (none for a grid of one point, which has no
    /// cell).
    pub fn piece(&self, key: u8, lo: usize) -> Piece {
        match self.grid.points.get(lo..lo + 2) {
            Some(&[a, b]) => Piece {
                key,
                a,
                b,
                inv_width: self.grid.inv_width[lo],
                at_a: self.values[lo],
                at_b: self.values[lo + 1],
            },
            _ => Piece::default(),
        }
    }

    /// The interpolated value in a located cell.
    #[inline]
    pub fn value_in(&self, cell: &Cell) -> f64 {
        (1.0 - cell.w) * self.values[cell.lo] + cell.w * self.values[cell.hi]
    }

    /// The interpolated value at `x` and its slope d value / d x: the slope of the cell
    /// holding `x` (on a grid point, the cell to its right; at the last point the last cell),
    /// zero outside the grid where the value is held.
    pub fn eval_slope(&self, x: f64) -> (f64, f64) {
        self.value_slope_in(&self.grid.locate(x))
    }

    /// [`Self::eval_slope`] in a located cell.
    #[inline]
    pub fn value_slope_in(&self, cell: &Cell) -> (f64, f64) {
        let slope = self
            .grid
            .slope(cell, self.values[cell.lo], self.values[cell.hi]);
        (self.value_in(cell), slope)
    }
}

impl Grid {
    /// d value / d x in `cell` from the values at its ends (zero when clamped or one point).
    fn slope(&self, cell: &Cell, at_lo: f64, at_hi: f64) -> f64 {
        if cell.clamped || cell.lo == cell.hi {
            return 0.0;
        }
        (at_hi - at_lo) * self.inv_width[cell.lo]
    }
}

/// A 2-D table over `rows × columns`, stored row-major: `values[i·columns + j]` belongs to
/// `(rows[i], columns[j])`; bilinear interpolation.
#[derive(Clone, Debug, PartialEq)]
pub struct Table2 {
    pub rows: Grid,
    pub columns: Grid,
    pub values: Vec<f64>,
}

/// The four corners of a bilinear lookup: `(index into values, weight)`.
pub type Corners = [(usize, f64); 4];

impl Table2 {
    pub fn zeros(rows: Grid, columns: Grid) -> Table2 {
        let values = vec![0.0; rows.len() * columns.len()];
        Table2 {
            rows,
            columns,
            values,
        }
    }

    /// The bilinear value at `(r, c)`, its four weighted corners, and whether it was clamped.
    pub fn eval(&self, r: f64, c: f64) -> (f64, Corners, bool) {
        self.eval_in(&self.rows.locate(r), &self.columns.locate(c))
    }

    /// [`Self::eval`]'s value, looking the cells up from `hints` (row, column; see
    /// [`Grid::locate_near`]), which then hold the cells used.
    #[inline]
    pub fn eval_near(&self, r: f64, c: f64, hints: &mut [usize; 2]) -> f64 {
        let (cr, cc) = (
            self.rows.locate_near(r, &mut hints[0]),
            self.columns.locate_near(c, &mut hints[1]),
        );
        self.eval_in(&cr, &cc).0
    }

    #[inline]
    fn eval_in(&self, cr: &Cell, cc: &Cell) -> (f64, Corners, bool) {
        let width = self.columns.len();
        let corners = [
            (cr.lo * width + cc.lo, (1.0 - cr.w) * (1.0 - cc.w)),
            (cr.lo * width + cc.hi, (1.0 - cr.w) * cc.w),
            (cr.hi * width + cc.lo, cr.w * (1.0 - cc.w)),
            (cr.hi * width + cc.hi, cr.w * cc.w),
        ];
        let value = corners.iter().map(|&(i, w)| w * self.values[i]).sum();
        (value, corners, cr.clamped || cc.clamped)
    }

    /// The bilinear value at `(r, c)` (as [`Self::eval`]) and its slopes `(d/dr, d/dc)`:
    /// along each grid as [`Table1::eval_slope`], interpolated across the other grid.
    pub fn eval_slopes(&self, r: f64, c: f64) -> (f64, f64, f64) {
        let (cr, cc) = (self.rows.locate(r), self.columns.locate(c));
        let width = self.columns.len();
        let v = |i: usize, j: usize| self.values[i * width + j];
        let (ll, lh, hl, hh) = (
            v(cr.lo, cc.lo),
            v(cr.lo, cc.hi),
            v(cr.hi, cc.lo),
            v(cr.hi, cc.hi),
        );
        let value = (1.0 - cr.w) * (1.0 - cc.w) * ll
            + (1.0 - cr.w) * cc.w * lh
            + cr.w * (1.0 - cc.w) * hl
            + cr.w * cc.w * hh;
        let lerp = |a: f64, b: f64, w: f64| (1.0 - w) * a + w * b;
        let d_row = self.rows.slope(&cr, lerp(ll, lh, cc.w), lerp(hl, hh, cc.w));
        let d_column = self
            .columns
            .slope(&cc, lerp(ll, hl, cr.w), lerp(lh, hh, cr.w));
        (value, d_row, d_column)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A range of 1e20° or a pitch of 1e-9° is an error, not an allocation of terabytes.
    #[test]
    fn absurd_ranges_and_pitches_are_errors() {
        assert!(matches!(
            Grid::from_range(-135.0, 1e20, 1.0),
            Err(GridError::TooFine { .. })
        ));
        assert!(matches!(
            Grid::from_range(-135.0, 35.0, 1e-9),
            Err(GridError::TooFine { .. })
        ));
        let finest = Grid::from_range(0.0, 1.0, MIN_PITCH_DEG).unwrap();
        assert_eq!(finest.len(), 1001);
        let most = Grid::from_range(0.0, (MAX_POINTS - 1) as f64 * 0.01, 0.01).unwrap();
        assert_eq!(most.len(), MAX_POINTS);
        assert!(Grid::from_range(0.0, MAX_POINTS as f64 * 0.01, 0.01).is_err());
    }

    use proptest::prelude::*;

    /// Grid points from `first` on, `steps` apart.
    fn grid_points(first: f64, steps: &[f64]) -> Vec<f64> {
        std::iter::once(first)
            .chain(steps.iter().scan(first, |x, d| {
                *x += d;
                Some(*x)
            }))
            .collect()
    }

    proptest! {
        /// A lookup from any hint finds [`Grid::locate`]'s cell, bit for bit, and leaves it
        /// as the hint: abscissae inside cells, on grid points (the first and last too),
        /// outside the grid; grids of one point, uneven ones.
        #[test]
        fn locate_near_is_locate(
            steps in proptest::collection::vec(0.01f64..20.0, 0..12),
            first in -200.0f64..200.0,
            at in prop_oneof![-250.0f64..250.0, (0usize..13).prop_map(|i| -1000.0 - i as f64)],
            hint in 0usize..15,
        ) {
            let points = grid_points(first, &steps);
            let grid = Grid::new(points.clone()).unwrap();
            // A negative `at` below -999 names a grid point (clamped to the last).
            let x = if at <= -1000.0 {
                points[((-1000.0 - at) as usize).min(points.len() - 1)]
            } else {
                at
            };
            let mut h = hint;
            let near = grid.locate_near(x, &mut h);
            let plain = grid.locate(x);
            prop_assert_eq!((near.lo, near.hi, near.w.to_bits(), near.clamped),
                (plain.lo, plain.hi, plain.w.to_bits(), plain.clamped));
            prop_assert_eq!(h, plain.lo);
        }

        /// A piece gives the value of the table's lookup wherever it answers (inside its
        /// cell, on its first point), to the bit, and answers inside its cell: pieces of every
        /// cell, abscissae inside, on and beyond the grid.
        #[test]
        fn piece_is_the_lookup(
            steps in proptest::collection::vec(0.01f64..20.0, 0..12),
            values in proptest::collection::vec(-1.0f64..1.0, 13),
            first in -200.0f64..200.0,
            at in prop_oneof![-250.0f64..250.0, (0usize..13).prop_map(|i| -1000.0 - i as f64)],
            lo in 0usize..13,
        ) {
            let points = grid_points(first, &steps);
            let x = if at <= -1000.0 {
                points[((-1000.0 - at) as usize).min(points.len() - 1)]
            } else {
                at
            };
            let n = points.len();
            let table = Table1 { grid: Grid::new(points.clone()).unwrap(), values: values[..n].to_vec() };
            let lo = lo.min(n - 1);
            let piece = table.piece(7, lo);
            let inside = lo + 1 < n && points[lo] <= x && x < points[lo + 1];
            match piece.value(7, x) {
                Some(v) => {
                    let cell = table.grid.locate(x);
                    prop_assert_eq!(v.to_bits(), table.value_in(&cell).to_bits());
                }
                None => prop_assert!(!inside),
            }
            prop_assert_eq!(piece.value(7, x).is_some(), inside);
            prop_assert!(piece.value(6, x).is_none(), "another table's");
        }

        /// A 2-D lookup from any hints gives [`Table2::eval`]'s value to the bit, inside the
        /// grid, on its lines and beyond its edges.
        #[test]
        fn eval_near_is_eval(
            rows in 1usize..6,
            columns in 1usize..6,
            values in proptest::collection::vec(-1.0f64..1.0, 36),
            r in -30.0f64..80.0,
            c in prop_oneof![-40.0f64..100.0, (0i32..5).prop_map(|k| f64::from(k) * 15.0)],
            hints in proptest::array::uniform2(0usize..7),
        ) {
            let rows = Grid::from_range(0.0, 10.0 * (rows - 1) as f64, 10.0).unwrap();
            let columns = Grid::from_range(0.0, 15.0 * (columns - 1) as f64, 15.0).unwrap();
            let n = rows.len() * columns.len();
            let table = Table2 { rows, columns, values: values[..n].to_vec() };
            let mut h = hints;
            prop_assert_eq!(table.eval_near(r, c, &mut h).to_bits(), table.eval(r, c).0.to_bits());
        }
    }
}
