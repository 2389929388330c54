//! The play widths the re-check asks, kept at hand: an axis's width is asked at its commands, a
//! few millidegrees apart along a path, and at the turning points of its history, so nearly
//! every lookup falls in a cell of the width table looked up just before. [`WidthTable`]
//! keeps those cells in a few slots and interpolates with the table's own arithmetic, so a
//! width is the one [`Model::play_width_deg`](crate::model::Model::play_width_deg) gives, to
//! the bit.

use crate::model::table::Table1;
use std::cell::Cell;

/// An axis's play width table with the cells of it looked up recently: the re-check asks an
/// axis's width at its commands, a few millidegrees apart along a path, and at the turning
/// points of its history (a rippled path turns an axis round every few targets, within a
/// degree or two), so nearly every lookup falls in a cell looked up just before, where it
/// is the interpolation between two values kept at hand. The arithmetic is the table's own
/// ([`Grid::locate`](crate::model::table::Grid::locate), [`Table1::value_in`]), so a width is
/// the one [`Model::play_width_deg`] gives, to the bit.
pub(super) struct WidthTable<'a> {
    pub(super) table: &'a Table1,
    /// Cells looked up, each in the slot of its place on the grid (neighbouring cells in
    /// different slots).
    pub(super) cells: [Cell<WidthCell>; WIDTH_SLOTS],
    /// Cells per degree, about (a slot's index only: any value is correct).
    pub(super) per_deg: f64,
    /// The grid's ends and the widths held beyond them (an axis may work outside the grid
    /// the play was identified on).
    pub(super) ends: (f64, f64),
    pub(super) held: (f64, f64),
}

/// Slots of [`WidthTable::cells`] (a power of two).
pub(super) const WIDTH_SLOTS: usize = 8;

/// A cell of a width table: the angles `[lo, hi)` it answers and the values at its ends.
#[derive(Clone, Copy, Debug)]
pub(super) struct WidthCell {
    pub(super) lo: f64,
    pub(super) hi: f64,
    /// `1 / (hi − lo)`, as the grid computes it for the cell's weight.
    pub(super) inv_width: f64,
    pub(super) at_lo: f64,
    pub(super) at_hi: f64,
}

impl WidthCell {
    /// A cell that answers no angle.
    const NONE: WidthCell = WidthCell {
        lo: f64::NAN,
        hi: f64::NAN,
        inv_width: f64::NAN,
        at_lo: f64::NAN,
        at_hi: f64::NAN,
    };
}

impl<'a> WidthTable<'a> {
    pub(super) fn new(table: &'a Table1) -> WidthTable<'a> {
        let p = table.grid.points();
        let ends = (p[0], p[p.len() - 1]);
        let at = |x: f64| table.value_in(&table.grid.locate(x));
        WidthTable {
            table,
            cells: std::array::from_fn(|_| Cell::new(WidthCell::NONE)),
            per_deg: (p.len() - 1) as f64 / (ends.1 - ends.0),
            ends,
            held: (at(ends.0), at(ends.1)),
        }
    }

    /// The slot of the cells about `angle`.
    #[inline(always)]
    fn slot(&self, angle: f64) -> &Cell<WidthCell> {
        // Any slot is correct (an angle off the grid, or NaN, misses in any): the cheaper
        // conversion of the two.
        let place = ((angle - self.ends.0) * self.per_deg) as i32;
        &self.cells[place as usize % WIDTH_SLOTS]
    }

    /// The width at `angle` (`table.eval(angle).0`). Inlined where it is asked: most lookups
    /// are answered by a cell kept.
    #[inline(always)]
    pub(super) fn width(&self, angle: f64) -> f64 {
        let slot = self.slot(angle);
        let c = slot.get();
        if c.lo <= angle && angle < c.hi {
            let w = ((angle - c.lo) * c.inv_width).clamp(0.0, 1.0);
            (1.0 - w) * c.at_lo + w * c.at_hi
        } else {
            self.outside_cells(angle, slot)
        }
    }

    /// [`Self::width`] where `slot` does not hold the cell.
    #[inline(always)]
    fn outside_cells(&self, angle: f64, slot: &Cell<WidthCell>) -> f64 {
        if angle <= self.ends.0 {
            self.held.0
        } else if angle >= self.ends.1 {
            self.held.1
        } else {
            self.look_up(angle, slot)
        }
    }

    /// [`Self::width`] inside the grid where `slot` does not hold the cell: looked up in the
    /// table, its cell kept in `slot`.
    #[inline(never)]
    fn look_up(&self, angle: f64, slot: &Cell<WidthCell>) -> f64 {
        let (table, cell) = (self.table, self.table.grid.locate(angle));
        if !cell.clamped && cell.hi == cell.lo + 1 {
            let p = table.grid.points();
            let (lo, hi) = (p[cell.lo], p[cell.hi]);
            slot.set(WidthCell {
                lo,
                hi,
                inv_width: 1.0 / (hi - lo),
                at_lo: table.values[cell.lo],
                at_hi: table.values[cell.hi],
            });
        }
        table.value_in(&cell)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A width from a kept cell is the table's own, to the bit: along a path of small
        /// steps (inside a cell, onto and across its edges), jumps, and angles off the grid,
        /// on grids of uneven spacing.
        #[test]
        fn a_width_from_a_kept_cell_is_the_tables(
            first in -200.0f64..0.0,
            steps in prop::collection::vec(0.05f64..3.0, 1..8),
            values in prop::collection::vec(0.0f64..0.05, 8),
            start in -210.0f64..30.0,
            moves in prop::collection::vec(
                prop_oneof![
                    -1e-3f64..1e-3,
                    -0.7f64..0.7,
                    -40.0f64..40.0,
                    (0usize..8).prop_map(|i| i as f64 * 1e9),
                ],
                1..40,
            ),
        ) {
            let points: Vec<f64> = std::iter::once(first)
                .chain(steps.iter().scan(first, |x, d| {
                    *x += d;
                    Some(*x)
                }))
                .collect();
            let table = Table1 {
                values: values[..points.len()].to_vec(),
                grid: crate::model::table::Grid::new(points.clone()).unwrap(),
            };
            let play = WidthTable::new(&table);
            let mut angle = start;
            for m in moves {
                // Large moves land on a grid point (the edges of the cells).
                angle = if m >= 1e9 {
                    points[(m / 1e9) as usize % points.len()]
                } else {
                    angle + m
                };
                let (got, expected) = (play.width(angle), table.eval(angle).0);
                prop_assert_eq!(got.to_bits(), expected.to_bits(), "at {}", angle);
            }
        }

    }
}
