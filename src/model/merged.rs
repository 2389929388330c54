//! The solver's fast path through the angle tables: the effects that add `factor · table(A_n)`
//! to axis n's own angle slot (`map:An`, and the gear play `backlash:An`, which on an engaged
//! flank adds ∓ half its width) are merged, per flank, into one table — one lookup per axis
//! where there were two, and no dynamic dispatch. A history with a memory (the command
//! reversed recently, so the play may be inside its band) takes the flank-free table plus the
//! play evaluated from the history. The merged table lives on the union of the grids: a sum
//! of piecewise-linear functions (each held constant beyond its grid) is piecewise linear with
//! breakpoints among theirs, so interpolating the sum sampled there is the sum of the
//! separate interpolations (to rounding).

use std::f64::consts::PI;

use super::chain::LinkBlocks;
use super::effect::{AxisSlopes, ChainErrors, Slot};
use super::effects::ModelEffect;
use super::history::AxisHistory;
use super::state::Direction;
use super::table::{Grid, Piece, Table1};

/// How an own-axis table's contribution scales with the axis's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisFactor {
    /// Added as it is (`map`).
    One,
    /// A gear play's width: −½ / +½ / 0 of it on the flank of a positive / negative / unknown
    /// direction (`backlash`), and the play operator when the history has a memory.
    Play,
}

impl AxisFactor {
    fn at(self, d: Direction) -> f64 {
        match self {
            AxisFactor::One => 1.0,
            AxisFactor::Play => -0.5 * d.sign(),
        }
    }
}

/// One axis's merged tables: values in radians on the negative, unknown and positive flank,
/// and the play's width (degrees) for histories with a memory.
#[derive(Clone, Debug)]
struct AxisSum {
    axis: u8,
    tables: [Table1; 3],
    play: Option<Table1>,
}

impl AxisSum {
    /// The merged value (rad) at `x` for `history`, from the cell near `hint`.
    #[inline(always)]
    fn value_near(&self, x: f64, history: &AxisHistory, hint: &mut usize) -> f64 {
        if history.is_simple() {
            let table = &self.tables[direction_index(history.simple_direction())];
            let cell = table.grid.locate_near(x, hint);
            return table.value_in(&cell);
        }
        let table = &self.tables[1];
        let cell = table.grid.locate_near(x, hint);
        table.value_in(&cell) + self.lag_rad(x, history)
    }

    /// [`Self::value_near`] from `piece` where it holds `x` (a history without memory),
    /// which otherwise becomes the cell looked up.
    #[inline(always)]
    fn value_in_piece(
        &self,
        x: f64,
        history: &AxisHistory,
        hint: &mut usize,
        piece: &mut Piece,
    ) -> f64 {
        if history.is_simple() {
            let flank = direction_index(history.simple_direction());
            // Keys from 1: a default piece is none.
            let key = flank as u8 + 1;
            if let Some(value) = piece.value(key, x) {
                return value;
            }
            let table = &self.tables[flank];
            let cell = table.grid.locate_near(x, hint);
            *piece = table.piece(key, cell.lo);
            return table.value_in(&cell);
        }
        self.value_near(x, history, hint)
    }

    fn lag_rad(&self, x: f64, history: &AxisHistory) -> f64 {
        match &self.play {
            Some(width) => history.play(x, |a| width.eval(a).0).lag_deg.to_radians(),
            None => 0.0,
        }
    }
}

/// Where a solver's last evaluation found its table cells, for the next to try first (hints
/// only: a lookup finds the same cell from any): the merged table of each axis, and those of
/// the first [`REST_HINTS`] effects left to evaluate one by one (`Merged::rest`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Cells {
    pub axes: [usize; 6],
    pub rest: [[usize; 2]; REST_HINTS],
    /// The merged tables' cells of the last [`Merged::add_angles_near`], with their values.
    pub pieces: [Piece; 6],
}

/// Effects outside the merged tables whose cells a [`Cells`] keeps (a model has a crosstalk
/// or two; any further ones look their tables up afresh).
pub const REST_HINTS: usize = 4;

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
            // One play per axis at most (the registry allows each effect once).
            let play = tables
                .iter()
                .find(|(_, _, f)| *f == AxisFactor::Play)
                .map(|(_, t, _)| (*t).clone());
            merged.axes.push(AxisSum {
                axis,
                tables: sums,
                play,
            });
        }
        merged.rest = varying.iter().copied().filter(|&i| !taken[i]).collect();
        merged
    }

    /// The width table (degrees) of axis n+1's gear play, if the model has one.
    pub fn play_width(&self, n: usize) -> Option<&Table1> {
        self.axes
            .iter()
            .find(|s| s.axis as usize == n + 1)
            .and_then(|s| s.play.as_ref())
    }

    /// Adds the merged tables' values at `axes_deg` with `histories`.
    #[cfg(any(test, feature = "internals"))]
    pub fn add_to(
        &self,
        axes_deg: &[f64; 6],
        histories: &[AxisHistory; 6],
        errors: &mut ChainErrors,
    ) {
        self.add_near(axes_deg, histories, errors, &mut [0; 6]);
    }

    /// [`Self::add_to`] looking each axis's table up from the cell in `cells` (see
    /// [`Grid::locate_near`]), which then holds the cells used.
    pub fn add_near(
        &self,
        axes_deg: &[f64; 6],
        histories: &[AxisHistory; 6],
        errors: &mut ChainErrors,
        cells: &mut [usize; 6],
    ) {
        self.each_near(axes_deg, histories, cells, |n, value| {
            errors.0[Slot::Angle { axis: n as u8 + 1 }.index()] += value
        });
    }

    /// [`Self::add_near`] into the angle slots alone (`angles[n]`: axis n+1's, rad), from the
    /// pieces of `cells` where they hold the axes (see [`Piece`]).
    pub fn add_angles_near(
        &self,
        axes_deg: &[f64; 6],
        histories: &[AxisHistory; 6],
        angles: &mut [f64; 6],
        cells: &mut Cells,
    ) {
        for sum in &self.axes {
            let n = sum.axis as usize - 1;
            let (hint, piece) = (&mut cells.axes[n], &mut cells.pieces[n]);
            angles[n] += sum.value_in_piece(axes_deg[n], &histories[n], hint, piece);
        }
    }

    /// Each merged axis's table value at `axes_deg`, as `(n, rad)` for axis n+1.
    #[inline(always)]
    fn each_near(
        &self,
        axes_deg: &[f64; 6],
        histories: &[AxisHistory; 6],
        cells: &mut [usize; 6],
        mut add: impl FnMut(usize, f64),
    ) {
        for sum in &self.axes {
            let n = sum.axis as usize - 1;
            add(n, sum.value_near(axes_deg[n], &histories[n], &mut cells[n]));
        }
    }

    /// [`Self::add_to`] with each table's slope along its axis (rad per degree); `cells`
    /// receives the cells used.
    pub fn add_with_slopes(
        &self,
        axes_deg: &[f64; 6],
        histories: &[AxisHistory; 6],
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
        cells: &mut [usize; 6],
    ) {
        for sum in &self.axes {
            let n = sum.axis as usize - 1;
            let history = &histories[n];
            let flank = if history.is_simple() {
                history.simple_direction()
            } else {
                Direction::Unknown
            };
            let table = &sum.tables[direction_index(flank)];
            let cell = table.grid.locate(axes_deg[n]);
            cells[n] = cell.lo;
            let (mut value, mut slope) = table.value_slope_in(&cell);
            if let (false, Some(width)) = (history.is_simple(), &sum.play) {
                let play = history.play(axes_deg[n], |a| width.eval(a).0);
                value += play.lag_deg.to_radians();
                // See `GearPlay::add_with_axis_slopes`.
                slope += match play.edge {
                    Some((_, side)) if play.engaged => {
                        (0.5 * side * width.eval_slope(axes_deg[n]).1).to_radians()
                    }
                    _ => -(1.0f64.to_radians()),
                };
            }
            let slot = Slot::Angle { axis: sum.axis };
            errors.add(slot, value);
            slopes.add(slot, n, slope);
        }
    }
}
