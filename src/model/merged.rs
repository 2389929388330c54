//! The solver's fast path through the angle tables: the effects that add `factor · table(A_n)`
//! to axis n's own angle slot (`map:An`, and `backlash:An` whose factor is the rotation
//! direction) are merged, per direction, into one table — one lookup per axis where there
//! were two, and no dynamic dispatch. The merged table lives on the union of the grids: a sum
//! of piecewise-linear functions (each held constant beyond its grid) is piecewise linear with
//! breakpoints among theirs, so interpolating the sum sampled there is the sum of the
//! separate interpolations (to rounding).

use std::f64::consts::PI;

use super::chain::LinkBlocks;
use super::effect::{AxisSlopes, ChainErrors, Slot};
use super::effects::ModelEffect;
use super::state::Direction;
use super::table::{Grid, Table1};

/// How an own-axis table's contribution scales with the axis's rotation direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisFactor {
    /// Added as it is (`map`).
    One,
    /// Times +1 / −1 / 0 for a positive / negative / unknown direction (`backlash`).
    Direction,
}

impl AxisFactor {
    fn at(self, d: Direction) -> f64 {
        match self {
            AxisFactor::One => 1.0,
            AxisFactor::Direction => d.sign(),
        }
    }
}

/// One axis's merged tables: values in radians for a negative, unknown and positive direction.
#[derive(Clone, Debug)]
struct AxisSum {
    axis: u8,
    tables: [Table1; 3],
}

/// The merged tables of a model and the varying effects left to evaluate one by one.
#[derive(Clone, Debug, Default)]
pub struct Merged {
    axes: Vec<AxisSum>,
    /// Indices of the varying effects not merged.
    pub rest: Vec<usize>,
    /// The sum of the effects that vary neither with the axes nor the directions, at time 0.
    pub fixed_at_time_zero: ChainErrors,
    /// The fixed part of the chain at time 0 when every varying effect moves the angle slots
    /// alone (see [`super::Effect::adds_angles_only`]); `None` otherwise.
    pub link_blocks: Option<LinkBlocks>,
}

fn direction_index(d: Direction) -> usize {
    match d {
        Direction::Negative => 0,
        Direction::Unknown => 1,
        Direction::Positive => 2,
    }
}

impl Merged {
    /// Merges the own-axis tables among `varying` (indices into `effects`), axis by axis.
    pub fn new(effects: &[Box<dyn ModelEffect>], varying: &[usize]) -> Merged {
        let mut merged = Merged::default();
        let mut taken = vec![false; effects.len()];
        for axis in 1..=6u8 {
            let tables: Vec<(usize, &Table1, AxisFactor)> = varying
                .iter()
                .filter_map(|&i| match effects[i].own_axis_table() {
                    Some((a, t, f)) if a == axis => Some((i, t, f)),
                    _ => None,
                })
                .collect();
            if tables.is_empty() {
                continue;
            }
            let mut points: Vec<f64> = tables
                .iter()
                .flat_map(|(_, t, _)| t.grid.points().iter().copied())
                .collect();
            points.sort_by(f64::total_cmp);
            points.dedup();
            let Ok(grid) = Grid::new(points) else {
                continue; // grids are checked on loading; never here
            };
            let table_at = |d: Direction| {
                let values = grid
                    .points()
                    .iter()
                    .map(|&x| {
                        let sum: f64 = tables.iter().map(|(_, t, f)| f.at(d) * t.eval(x).0).sum();
                        sum * (PI / 180.0)
                    })
                    .collect();
                Table1 {
                    grid: grid.clone(),
                    values,
                }
            };
            let sums = [Direction::Negative, Direction::Unknown, Direction::Positive].map(table_at);
            tables.iter().for_each(|(i, _, _)| taken[*i] = true);
            merged.axes.push(AxisSum { axis, tables: sums });
        }
        merged.rest = varying.iter().copied().filter(|&i| !taken[i]).collect();
        merged
    }

    /// Adds the merged tables' values at `axes_deg` with `directions`.
    pub fn add_to(
        &self,
        axes_deg: &[f64; 6],
        directions: &[Direction; 6],
        errors: &mut ChainErrors,
    ) {
        self.add_near(axes_deg, directions, errors, &mut [0; 6]);
    }

    /// [`Self::add_to`] looking each axis's table up from the cell in `cells` (see
    /// [`Grid::locate_near`]), which then holds the cells used.
    pub fn add_near(
        &self,
        axes_deg: &[f64; 6],
        directions: &[Direction; 6],
        errors: &mut ChainErrors,
        cells: &mut [usize; 6],
    ) {
        self.each_near(axes_deg, directions, cells, |n, value| {
            errors.0[Slot::Angle { axis: n as u8 + 1 }.index()] += value
        });
    }

    /// [`Self::add_near`] into the angle slots alone (`angles[n]`: axis n+1's, rad).
    pub fn add_angles_near(
        &self,
        axes_deg: &[f64; 6],
        directions: &[Direction; 6],
        angles: &mut [f64; 6],
        cells: &mut [usize; 6],
    ) {
        self.each_near(axes_deg, directions, cells, |n, value| angles[n] += value);
    }

    /// Each merged axis's table value at `axes_deg`, as `(n, rad)` for axis n+1.
    #[inline(always)]
    fn each_near(
        &self,
        axes_deg: &[f64; 6],
        directions: &[Direction; 6],
        cells: &mut [usize; 6],
        mut add: impl FnMut(usize, f64),
    ) {
        for sum in &self.axes {
            let n = sum.axis as usize - 1;
            let table = &sum.tables[direction_index(directions[n])];
            let cell = table.grid.locate_near(axes_deg[n], &mut cells[n]);
            add(n, table.value_in(&cell));
        }
    }

    /// [`Self::add_to`] with each table's slope along its axis (rad per degree); `cells`
    /// receives the cells used.
    pub fn add_with_slopes(
        &self,
        axes_deg: &[f64; 6],
        directions: &[Direction; 6],
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
        cells: &mut [usize; 6],
    ) {
        for sum in &self.axes {
            let n = sum.axis as usize - 1;
            let table = &sum.tables[direction_index(directions[n])];
            let cell = table.grid.locate(axes_deg[n]);
            cells[n] = cell.lo;
            let (value, slope) = table.value_slope_in(&cell);
            let slot = Slot::Angle { axis: sum.axis };
            errors.add(slot, value);
            slopes.add(slot, n, slope);
        }
    }
}
