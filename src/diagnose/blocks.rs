//! Blocked cross-validation: which measured points a fit may learn from when it is scored on
//! others. Points measured close together share what no model explains (a test's set-up, the
//! robot's temperature at the time), so a fit that saw a point's neighbours in time scores it
//! too well; the folds here hold out whole blocks instead of interleaved points:
//!
//! - [`Scheme::Stretches`]: every test (a `test` label within one file) is cut into contiguous
//!   stretches of its visiting order of [`STRETCH`] points (at least `k`), stretch j held out
//!   in fold j mod k, so every fold holds pieces of every test (the score of effects that are
//!   local in an axis angle, like tables, which only points at nearby angles can check: a
//!   stretch is a few table cells of one sweep);
//! - [`Scheme::Tests`]: whole tests (and with them whole files of one test) held out, dealt
//!   into `k` folds of about equal size: an effect must predict poses no test it learnt from
//!   visited;
//! - [`Scheme::Latest`]: the latest data predicted from the earlier only (forward chaining at
//!   the half and at three quarters of the points in time): an effect that extrapolates in
//!   time (drift) must predict what comes after what it learnt from;
//! - [`Scheme::Files`]: with several files, the latest (by its median time) predicted from the
//!   earlier ones: whole files from another part of the workspace and later in time, as the
//!   user's programs will run after the campaign — advice that does not lower that error is
//!   not given.

/// How the folds are cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Held-out stretches of every test.
    Stretches,
    /// Whole tests held out.
    Tests,
    /// The latest data, learnt from the earlier.
    Latest,
    /// The latest file, learnt from the earlier ones.
    Files,
}

impl Scheme {
    /// In words, for evidence sentences.
    pub fn describe(&self) -> &'static str {
        match self {
            Scheme::Stretches => "held-out stretches of every test",
            Scheme::Tests => "whole tests it did not learn from",
            Scheme::Latest => "the latest data, learnt from the earlier",
            Scheme::Files => "the latest file, learnt from the earlier ones",
        }
    }
}

/// The folds of one scheme: per fold the points held out and the points it may learn from.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub scheme: Scheme,
    pub held: Vec<Vec<usize>>,
    pub train: Vec<Vec<bool>>,
}

impl Plan {
    pub fn folds(&self) -> usize {
        self.held.len()
    }
}

/// Group of each point: the same (file, test) pair, numbered in order of first appearance.
pub fn groups<'a>(keys: impl Iterator<Item = (&'a str, &'a str)>) -> Vec<usize> {
    let mut seen: Vec<(&str, &str)> = Vec::new();
    keys.map(|k| match seen.iter().position(|s| *s == k) {
        Some(i) => i,
        None => {
            seen.push(k);
            seen.len() - 1
        }
    })
    .collect()
}

/// Indices of each group's points, in order.
fn members(groups: &[usize]) -> Vec<Vec<usize>> {
    let n = groups.iter().max().map_or(0, |m| m + 1);
    let mut out = vec![Vec::new(); n];
    for (i, &g) in groups.iter().enumerate() {
        out[g].push(i);
    }
    out
}

fn plan(scheme: Scheme, n: usize, held: Vec<Vec<usize>>) -> Plan {
    let held: Vec<Vec<usize>> = held.into_iter().filter(|h| !h.is_empty()).collect();
    let train = held
        .iter()
        .map(|h| {
            let mut t = vec![true; n];
            for &i in h {
                t[i] = false;
            }
            t
        })
        .collect();
    Plan {
        scheme,
        held,
        train,
    }
}

/// Points per stretch of [`Scheme::Stretches`]: a few table cells of one sweep.
pub const STRETCH: usize = 12;

/// [`Scheme::Stretches`] with `k` folds.
pub fn stretches(groups: &[usize], k: usize) -> Plan {
    let k = k.max(2);
    let mut held = vec![Vec::new(); k];
    for (g, points) in members(groups).iter().enumerate() {
        let cuts = if points.len() >= k {
            (points.len() / STRETCH).max(k)
        } else {
            // Too short to cut: the whole test goes to one fold.
            held[g % k].extend(points);
            continue;
        };
        for (j, chunk) in chunks(points, cuts).into_iter().enumerate() {
            held[j % k].extend(chunk);
        }
    }
    for h in &mut held {
        h.sort_unstable();
    }
    plan(Scheme::Stretches, groups.len(), held)
}

/// `points` cut into `n` contiguous pieces of (almost) equal length.
fn chunks(points: &[usize], n: usize) -> Vec<&[usize]> {
    (0..n)
        .map(|j| &points[j * points.len() / n..(j + 1) * points.len() / n])
        .collect()
}

/// [`Scheme::Tests`] with `k` folds: whole groups dealt largest first into the fold with the
/// fewest points. With a single group, its `k` contiguous stretches in time.
pub fn tests(groups: &[usize], k: usize) -> Plan {
    let k = k.max(2);
    let members = members(groups);
    if members.len() < 2 {
        let held = members
            .first()
            .map(|p| chunks(p, k).into_iter().map(<[usize]>::to_vec).collect())
            .unwrap_or_default();
        return plan(Scheme::Tests, groups.len(), held);
    }
    let mut order: Vec<&Vec<usize>> = members.iter().collect();
    order.sort_by_key(|m| std::cmp::Reverse(m.len()));
    let mut held: Vec<Vec<usize>> = vec![Vec::new(); k.min(members.len())];
    for m in order {
        if let Some(lightest) = held.iter_mut().min_by_key(|h| h.len()) {
            lightest.extend(m);
        }
    }
    for h in &mut held {
        h.sort_unstable();
    }
    plan(Scheme::Tests, groups.len(), held)
}

/// [`Scheme::Latest`]: points ordered by time (ties in file order), the third quarter
/// predicted from the first half and the last quarter from the first three; whole tests stay
/// on one side of a cut where they can (a cut moves to the nearest start of a test within an
/// eighth of the points). `None` when the clock does not advance.
pub fn latest(groups: &[usize], times_s: &[f64]) -> Option<Plan> {
    let n = times_s.len();
    let (lo, hi) = times_s
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
    if n < 8 || hi - lo <= 0.0 {
        return None;
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| times_s[a].total_cmp(&times_s[b]).then(a.cmp(&b)));
    let cut = |fraction: f64| {
        let target = (fraction * n as f64) as usize;
        let starts = (1..n).filter(|&j| groups[order[j]] != groups[order[j - 1]]);
        starts
            .filter(|&j| j.abs_diff(target) <= n / 8)
            .min_by_key(|&j| j.abs_diff(target))
            .unwrap_or(target)
    };
    let (half, three) = (cut(0.5), cut(0.75));
    if !(0 < half && half < three && three < n) {
        return None;
    }
    let fold = |learn: usize, end: usize| {
        let mut train = vec![false; n];
        for &i in &order[..learn] {
            train[i] = true;
        }
        let mut held: Vec<usize> = order[learn..end].to_vec();
        held.sort_unstable();
        (held, train)
    };
    let (h1, t1) = fold(half, three);
    let (h2, t2) = fold(three, n);
    Some(Plan {
        scheme: Scheme::Latest,
        held: vec![h1, h2],
        train: vec![t1, t2],
    })
}

/// Fewest points the held-out latest file and the earlier files must each have.
const MIN_FILE_POINTS: usize = 8;

/// [`Scheme::Files`]: `files[i]` is point i's file, `times_s[i]` its time; the file with the
/// latest median time held out, learnt from the others. `None` with fewer than two files or
/// too few points on either side.
pub fn later_file(files: &[usize], times_s: &[f64]) -> Option<Plan> {
    let members = members(files);
    if members.len() < 2 {
        return None;
    }
    let median = |m: &Vec<usize>| {
        let mut t: Vec<f64> = m.iter().map(|&i| times_s[i]).collect();
        t.sort_by(f64::total_cmp);
        t.get(t.len() / 2).copied().unwrap_or(f64::NEG_INFINITY)
    };
    let last = (0..members.len()).max_by(|&a, &b| {
        median(&members[a])
            .total_cmp(&median(&members[b]))
            .then(a.cmp(&b))
    })?;
    let held = members[last].clone();
    if held.len() < MIN_FILE_POINTS || files.len() - held.len() < MIN_FILE_POINTS {
        return None;
    }
    Some(plan(Scheme::Files, files.len(), vec![held]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_are_file_and_test_pairs() {
        let keys = [
            ("a", "t1"),
            ("a", "t1"),
            ("a", "t2"),
            ("b", "t1"),
            ("a", "t1"),
        ];
        assert_eq!(groups(keys.into_iter()), [0, 0, 1, 2, 0]);
    }

    #[test]
    fn stretches_are_contiguous_and_every_fold_has_a_piece_of_every_test() {
        // Tests of 96 and 9 points, k = 4: 8 stretches of 12 in the first (96 / STRETCH), 4
        // of 2–3 in the second (at least k), and a test of 3 points goes whole to one fold.
        let mut g = vec![0; 96];
        g.extend([1; 9]);
        g.extend([2; 3]);
        let p = stretches(&g, 4);
        assert_eq!(p.folds(), 4);
        let f0: Vec<usize> = (0..12).chain(48..60).chain(96..98).collect();
        assert_eq!(p.held[0], f0);
        assert_eq!(p.held[1][..12], (12..24).collect::<Vec<_>>()[..]);
        for (f, h) in p.held.iter().enumerate() {
            assert!(h.iter().any(|&i| i < 96) && h.iter().any(|&i| (96..105).contains(&i)));
            for &i in h {
                assert!(!p.train[f][i]);
            }
            assert_eq!(p.train[f].iter().filter(|t| **t).count(), g.len() - h.len());
        }
        // Each point is held out exactly once.
        let mut all: Vec<usize> = p.held.concat();
        all.sort_unstable();
        assert_eq!(all, (0..g.len()).collect::<Vec<_>>());
        // The short test went whole to fold 2 % 4.
        assert!([105, 106, 107].iter().all(|i| p.held[2].contains(i)));
    }

    #[test]
    fn tests_are_held_out_whole_and_balanced() {
        // Tests of 10, 6, 5, 4, 1 points into 2 folds: 10 | 6, then 5 → the 6-fold (11), 4 →
        // the 10-fold (14), 1 → the 11-fold (12).
        let mut g = vec![0; 10];
        for (k, n) in [(1, 6), (2, 5), (3, 4), (4, 1)] {
            g.extend(std::iter::repeat_n(k, n));
        }
        let p = tests(&g, 2);
        let sizes: Vec<usize> = p.held.iter().map(Vec::len).collect();
        assert_eq!(sizes, [14, 12]);
        for h in &p.held {
            let gs: Vec<usize> = h.iter().map(|&i| g[i]).collect();
            for k in 0..5 {
                let n = gs.iter().filter(|&&x| x == k).count();
                assert!(n == 0 || n == g.iter().filter(|&&x| x == k).count());
            }
        }
        // One test only: k contiguous stretches.
        let p = tests(&[0; 8], 4);
        assert_eq!(p.held, [vec![0, 1], vec![2, 3], vec![4, 5], vec![6, 7]]);
    }

    #[test]
    fn latest_learns_from_the_earlier_only() {
        // 16 points, one test each of 4 points, times increasing: the cuts fall at 8 and 12.
        let g: Vec<usize> = (0..16).map(|i| i / 4).collect();
        let t: Vec<f64> = (0..16).map(|i| i as f64 * 10.0).collect();
        let p = latest(&g, &t).unwrap();
        assert_eq!(p.held, [(8..12).collect::<Vec<_>>(), (12..16).collect()]);
        assert_eq!(p.train[0].iter().filter(|x| **x).count(), 8);
        assert!(p.train[1][..12].iter().all(|x| *x) && !p.train[1][12]);
        // No clock: no plan.
        assert!(latest(&g, &[0.0; 16]).is_none());
    }

    #[test]
    fn the_latest_file_is_held_out_whole() {
        // File 0 (a campaign, times 0..20), file 1 (paths, times 100..110), file 2 (earlier
        // than file 1 although listed after it).
        let mut files = vec![0; 20];
        files.extend([1; 10]);
        files.extend([2; 10]);
        let times: Vec<f64> = (0..20)
            .map(f64::from)
            .chain((100..110).map(f64::from))
            .chain((50..60).map(f64::from))
            .collect();
        let p = later_file(&files, &times).unwrap();
        assert_eq!(p.scheme, Scheme::Files);
        assert_eq!(p.held, vec![(20..30).collect::<Vec<_>>()]);
        assert_eq!(p.train[0].iter().filter(|t| **t).count(), 30);
        assert!(later_file(&[0; 40], &times).is_none());
        // Too few points in the latest file.
        let mut few = vec![0; 36];
        few.extend([1; 4]);
        assert!(later_file(&few, &times).is_none());
    }
}
