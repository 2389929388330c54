//! Thinning dense data before the fit. A campaign of a whole cell, or a tracker streaming
//! along slow paths, holds millions of rows that say the same thing many times over: a fit
//! through all of them costs minutes and gigabytes and determines the parameters no better
//! than it needs to (the noise of a 1° table cell seen by hundreds of points is far below the
//! tracker's). So beyond a budget of measured points the fit keeps a spread-out subset:
//! points are put in cells — same file, test, rotation directions, and the same bin of every
//! axis angle, a quarter of the table pitch wide — and every cell keeps at most `cap` points
//! (evenly spaced in visiting order), `cap` the largest that fits the budget, so sparse
//! regions keep everything and dense ones are thinned. When even one point per cell is too
//! many (scattered poses, or a budget near the data's own density) the cells are widened, in
//! steps of two, until it is not: coverage stays even instead of whole regions dropping out.
//! Every point, kept or not, is still checked against the fitted model afterwards (gross
//! errors, statistics, the verdict).

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use crate::measure::Stop;

/// Default budget of measured points for the fit.
pub const DEFAULT_MAX_POINTS: usize = 20_000;

/// What thinning did, for the output and the provenance.
#[derive(Clone, Debug, PartialEq)]
pub struct Thinning {
    /// Measured points in the data.
    pub measured: usize,
    /// Points the fit uses.
    pub kept: usize,
    /// Most points kept per cell.
    pub cap: usize,
    /// Width of a cell in every axis angle, degrees.
    pub cell_deg: f64,
}

impl Thinning {
    /// The decision in one sentence.
    pub fn describe(&self) -> String {
        format!(
            "{} measured points thinned to {} for the fit: at most {} per file, test, rotation \
             directions and {}° cell of every axis angle; every point is still checked against \
             the fitted model",
            self.measured, self.kept, self.cap, self.cell_deg
        )
    }
}

/// The measured rows of `stops` the fit uses (indices, in order) and what thinning did
/// (`None`: all of them, the data are within `budget`). `file_of[i]` is the file of stop `i`
/// (empty: one file). `budget` 0 means no limit.
pub fn thin(
    stops: &[Stop],
    file_of: &[usize],
    budget: usize,
    cell_deg: f64,
) -> (Vec<usize>, Option<Thinning>) {
    let measured: Vec<usize> = (0..stops.len())
        .filter(|&i| stops[i].measured_mm.is_some())
        .collect();
    if budget == 0 || measured.len() <= budget {
        return (measured, None);
    }
    // Cells, each with its rows in visiting order; wider (by powers of two, the smallest that
    // works) until one point each fits.
    let groups = group_ids(stops, file_of, &measured);
    let cells_at = |k: i32| cells_of(stops, &measured, &groups, cell_deg * 2f64.powi(k));
    let (mut lo, mut hi) = (0, 24);
    let mut cells = cells_at(0);
    if cells.len() > budget {
        while lo < hi {
            let mid = (lo + hi) / 2;
            if cells_at(mid).len() <= budget {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        cells = cells_at(lo);
    }
    let cell_deg = cell_deg * 2f64.powi(lo);
    // The largest cap that fits the budget (the kept count grows with the cap).
    let kept_with = |cap: usize| cells.iter().map(|c| c.len().min(cap)).sum::<usize>();
    let (mut lo, mut hi) = (1, cells.iter().map(Vec::len).max().unwrap_or(1));
    while lo < hi {
        let mid = (lo + hi).div_ceil(2);
        if kept_with(mid) <= budget {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    let cap = lo;
    let mut kept: Vec<usize> = Vec::with_capacity(kept_with(cap));
    for cell in &cells {
        let n = cell.len();
        if n <= cap {
            kept.extend_from_slice(cell);
        } else {
            kept.extend((0..cap).map(|j| cell[j * n / cap]));
        }
    }
    kept.sort_unstable();
    let thinning = Thinning {
        measured: measured.len(),
        kept: kept.len(),
        cap,
        cell_deg,
    };
    (kept, Some(thinning))
}

/// A number per (file, test, rotation directions) for each of the `measured` rows.
fn group_ids(stops: &[Stop], file_of: &[usize], measured: &[usize]) -> Vec<u32> {
    // (file, test, rotation directions)
    type Group<'s> = (usize, &'s str, [i8; 6]);
    let mut ids: HashMap<Group, u32> = HashMap::new();
    let mut last: Option<(Group, u32)> = None;
    measured
        .iter()
        .map(|&i| {
            let s = &stops[i];
            let key = (
                file_of.get(i).copied().unwrap_or(0),
                s.test.as_str(),
                s.state.directions().map(|d| d.sign() as i8),
            );
            // Consecutive rows mostly share their key: look it up only when it changes.
            if let Some((k, id)) = last {
                if k == key {
                    return id;
                }
            }
            let next = ids.len() as u32;
            let id = *ids.entry(key).or_insert(next);
            last = Some((key, id));
            id
        })
        .collect()
}

/// The rows of `measured` grouped by cell of `cell_deg` (in order of first appearance).
fn cells_of(stops: &[Stop], measured: &[usize], groups: &[u32], cell_deg: f64) -> Vec<Vec<usize>> {
    let mut index: HashMap<(u32, [i64; 6]), usize, BuildHasherDefault<Mix>> =
        HashMap::with_capacity_and_hasher(measured.len().min(1 << 20), Default::default());
    let mut cells: Vec<Vec<usize>> = Vec::new();
    for (&i, &g) in measured.iter().zip(groups) {
        let bins = stops[i]
            .state
            .axes_deg
            .map(|a| (a / cell_deg).floor() as i64);
        let c = *index.entry((g, bins)).or_insert_with(|| {
            cells.push(Vec::new());
            cells.len() - 1
        });
        cells[c].push(i);
    }
    cells
}

/// A multiply-rotate hash of integer keys (the keys here are not chosen by an adversary;
/// SipHash over a million keys, ten times, was most of the thinning's time).
#[derive(Default)]
struct Mix(u64);

impl Hasher for Mix {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_u32(&mut self, v: u32) {
        self.write_u64(u64::from(v));
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
    fn finish(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::AxisState;
    use nalgebra::Vector3;

    fn stop(a1: f64) -> Stop {
        Stop {
            test: "A1".into(),
            state: AxisState::new([a1, 0.0, 0.0, 0.0, 0.0, 0.0]),
            measured_mm: Some(Vector3::zeros()),
            line: 0,
        }
    }

    #[test]
    fn dense_cells_are_capped_sparse_ones_kept() {
        // 1,000 points in [0°, 1°) and 10 points at 10°..19°: a budget of 50 keeps the 10
        // lone points and 40 of the dense ones, 10 per 0.25° cell.
        let mut stops: Vec<Stop> = (0..1000).map(|i| stop(i as f64 / 1000.0)).collect();
        stops.extend((10..20).map(|a| stop(a as f64)));
        let (kept, t) = thin(&stops, &[], 50, 0.25);
        let t = t.unwrap();
        assert_eq!(
            (t.measured, t.kept, t.cap, t.cell_deg),
            (1010, 50, 10, 0.25)
        );
        assert_eq!(kept.len(), 50);
        assert!((1000..1010).all(|i| kept.contains(&i)));
        // Evenly spread inside a cell: the first cell [0, 0.25) keeps rows 0, 25, 50, …
        assert!(kept.contains(&0) && kept.contains(&25) && !kept.contains(&1));
        // Within the budget nothing happens.
        let (all, none) = thin(&stops, &[], 2000, 0.25);
        assert!(none.is_none() && all.len() == 1010);
    }

    #[test]
    fn scattered_points_widen_the_cells() {
        // 100 points 1° apart, budget 30: cells of 0.25°, 0.5°, 1°, 2° hold one point each,
        // 4° cells hold four (25 cells): one point each, every 4th degree.
        let stops: Vec<Stop> = (0..100).map(|i| stop(i as f64)).collect();
        let (kept, t) = thin(&stops, &[], 30, 0.25);
        let t = t.unwrap();
        assert_eq!((t.cap, t.cell_deg, kept.len()), (1, 4.0, 25));
        assert_eq!(kept[..3], [0, 4, 8]);
        assert!(t.describe().contains("4° cell"));
    }
}
