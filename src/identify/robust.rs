//! Gross errors against the fitted model: after a fit, each point's residual — less the
//! running median of its neighbours' residuals (two before and two after it in the same test,
//! in visiting order), so that what an effect the model lacks leaves along a test (smooth, not
//! a gross error) does not count — is compared with the laser tracker's noise at that point:
//! σ = 5 µm + 2.5 µm/m per coordinate, the typical error of a Leica AT960 (about half its MPE
//! of ±(15 µm + 6 µm/m)), the distance taken from the tracker head, scaled up by the fit's own
//! robust scatter when that is larger (a set-up noisier than typical must not turn good points
//! into gross errors). A point beyond [`THRESHOLD`] such standard deviations is left out and
//! the model refitted without it, until the set of left-out points no longer changes: points
//! left out are judged by the model fitted without them (an honest prediction), points in the
//! fit by the model they helped fit (iterative reweighting with 0/1 weights, Tukey's biweight
//! at its limit). Gross errors are rare: where more than [`MAX_SHARE`] of a test's points would
//! be flagged, the model does not explain that test (scattered poses that an effect the model
//! lacks moves, a wrong frame, a wrong link) and none of them is left out — the least-squares
//! fit and the verdict against the noise floor must see that.

use nalgebra::Vector3;

use crate::measure::tracker::Tracker;

/// A residual beyond this many scaled standard deviations (3-D length / σ per coordinate) is
/// a gross error: for three normal coordinates the chance is 1.5·10⁻⁵ per point. With many
/// points the threshold rises so that noise alone flags fewer than half a point over all of
/// them (Chauvenet's criterion, [`threshold`]): 5.7 σ for a million.
pub const THRESHOLD: f64 = 5.0;
/// Most of a test's points that may be gross errors (see the module documentation).
pub const MAX_SHARE: f64 = 0.05;
/// Typical noise per coordinate of the default tracker (Leica AT960), µm, and its growth with
/// distance, µm/m.
#[cfg(any(test, feature = "internals"))]
pub const SIGMA_UM: f64 = 5.0;
#[cfg(any(test, feature = "internals"))]
pub const SIGMA_UM_PER_M: f64 = 2.5;
/// Median of the χ distribution with 3 degrees of freedom: the median length of a 3-D normal
/// vector with unit standard deviation per coordinate.
const CHI3_MEDIAN: f64 = 1.538_172_254_455_582;

/// Complementary error function (W. H. Press et al., Numerical Recipes, `erfcc`: relative
/// error below 1.2·10⁻⁷ everywhere).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// The chance that a vector of `dof` (1, 2 or 3) independent unit normals is longer than `x`.
pub fn tail(dof: u8, x: f64) -> f64 {
    let half = (-0.5 * x * x).exp();
    match dof {
        1 => erfc(x / std::f64::consts::SQRT_2),
        2 => half,
        _ => erfc(x / std::f64::consts::SQRT_2) + (2.0 / std::f64::consts::PI).sqrt() * x * half,
    }
}

/// The threshold (in σ) for `n` statistics of `dof` degrees of freedom: [`THRESHOLD`], or
/// where noise alone would exceed it at fewer than half a point of the `n` when that is
/// higher.
pub fn threshold(n: usize, dof: u8) -> f64 {
    let (mut lo, mut hi) = (THRESHOLD, 40.0);
    if n as f64 * tail(dof, lo) <= 0.5 {
        return lo;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if n as f64 * tail(dof, mid) > 0.5 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The tracker's typical standard deviation per coordinate (mm) at `point` measured from
/// `station` (both mm, one frame): [`SIGMA_UM`] + [`SIGMA_UM_PER_M`] for the default AT960,
/// in proportion to the stated MPE for another (`--tracker`).
pub fn tracker_sigma_mm(point: &Vector3<f64>, station: &Vector3<f64>, tracker: &Tracker) -> f64 {
    tracker.sigma_mm(point, station)
}

/// The outcome of one screening.
#[derive(Clone, Debug, PartialEq)]
pub struct Screening {
    /// Residual length over σ per point.
    pub normalised: Vec<f64>,
    /// The robust scale of the normalised residuals of the points in the fit (≥ 1).
    pub scale: f64,
    /// The threshold on the normalised residuals, scale included.
    pub limit: f64,
    /// Whether each point is a gross error.
    pub gross: Vec<bool>,
}

/// Screens residuals (`residuals[i]`, mm, points in visiting order, `test[i]` the test a
/// point belongs to) with the tracker's σ at each point (`sigma_mm[i]`); the scale comes from
/// the points with `in_fit[i]` (a fitted model shrinks their residuals alike; left-out points
/// would inflate it); the threshold is [`threshold`] for `population` points (all the data's,
/// when these are a subset).
pub fn screen(
    residuals: &[Vector3<f64>],
    sigma_mm: &[f64],
    in_fit: &[bool],
    test: &[usize],
    population: usize,
) -> Screening {
    let normalised: Vec<f64> = detrended(residuals, test)
        .iter()
        .zip(sigma_mm)
        .map(|(r, s)| r.norm() / s.max(1e-9))
        .collect();
    screen_normalised(normalised, in_fit, population)
}

/// [`screen`] of statistics already normalised.
pub fn screen_normalised(normalised: Vec<f64>, in_fit: &[bool], population: usize) -> Screening {
    let mut fitted: Vec<f64> = normalised
        .iter()
        .zip(in_fit)
        .filter(|(_, &f)| f)
        .map(|(u, _)| *u)
        .collect();
    let scale = if fitted.is_empty() {
        1.0
    } else {
        let mid = fitted.len() / 2;
        let (_, median, _) = fitted.select_nth_unstable_by(mid, f64::total_cmp);
        (*median / CHI3_MEDIAN).max(1.0)
    };
    let limit = threshold(population.max(normalised.len()), 3) * scale;
    let gross = normalised.iter().map(|u| *u > limit).collect();
    Screening {
        normalised,
        scale,
        limit,
        gross,
    }
}

/// Clears the flags of every test in which more than [`MAX_SHARE`] of the points
/// (`test[i]` per point) are flagged; returns those tests.
pub fn limit_share(gross: &mut [bool], test: &[usize]) -> Vec<usize> {
    let mut counts: std::collections::HashMap<usize, (usize, usize)> = Default::default();
    for (g, t) in gross.iter().zip(test) {
        let c = counts.entry(*t).or_default();
        c.0 += usize::from(*g);
        c.1 += 1;
    }
    let mut unexplained: Vec<usize> = counts
        .iter()
        .filter(|(_, (flagged, n))| *flagged as f64 > MAX_SHARE * *n as f64)
        .map(|(t, _)| *t)
        .collect();
    unexplained.sort_unstable();
    for (g, t) in gross.iter_mut().zip(test) {
        if unexplained.binary_search(t).is_ok() {
            *g = false;
        }
    }
    unexplained
}

/// Half-width of the neighbourhood whose median residual is taken off each point's.
const HALF_WINDOW: usize = 2;

/// Each residual less the coordinate-wise median of the residuals of its test's points from
/// `HALF_WINDOW` before to `HALF_WINDOW` after it (itself included; the window shifted
/// inwards at a test's ends; a test of fewer than five points is left as it is).
pub fn detrended(residuals: &[Vector3<f64>], test: &[usize]) -> Vec<Vector3<f64>> {
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); test.iter().max().map_or(0, |t| t + 1)];
    for (i, &t) in test.iter().enumerate() {
        members[t].push(i);
    }
    let mut out = residuals.to_vec();
    let width = 2 * HALF_WINDOW + 1;
    let mut window = [0.0; 2 * HALF_WINDOW + 1];
    for rows in &members {
        let n = rows.len();
        if n < width {
            continue;
        }
        for (k, &i) in rows.iter().enumerate() {
            let start = k.saturating_sub(HALF_WINDOW).min(n - width);
            for c in 0..3 {
                for (w, &j) in window.iter_mut().zip(&rows[start..start + width]) {
                    *w = residuals[j][c];
                }
                window.sort_by(f64::total_cmp);
                out[i][c] = residuals[i][c] - window[HALF_WINDOW];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tails_and_thresholds_by_hand() {
        // P(|z| > 1.96) = 0.05; χ₂: e^(−x²/2); χ₃ at x = 5 (χ²₃ > 25): 1.544·10⁻⁵.
        assert!((tail(1, 1.959_964) - 0.05).abs() < 1e-7);
        assert!((tail(2, 3.0) - (-4.5f64).exp()).abs() < 1e-15);
        assert!((tail(3, 5.0) - 1.5442e-5).abs() < 1e-8, "{}", tail(3, 5.0));
        // Few points: the floor; a million: where 10⁶·P = 0.5.
        assert_eq!(threshold(3232, 3), THRESHOLD);
        let t = threshold(1_000_000, 3);
        assert!(
            (1e6 * tail(3, t) - 0.5).abs() < 1e-6 && (5.6..5.7).contains(&t),
            "{t}"
        );
    }

    #[test]
    fn sigma_by_hand_and_scale_from_the_fitted_points() {
        // 3 m from the tracker: 5 + 7.5 = 12.5 µm.
        let s = tracker_sigma_mm(
            &Vector3::new(3000.0, 0.0, 0.0),
            &Vector3::zeros(),
            &Tracker::default(),
        );
        assert!((s - 0.0125).abs() < 1e-12);
        // Residuals of length exactly the χ₃ median (scale 1), one 6σ point and one 4σ point.
        let mut residuals = vec![Vector3::new(CHI3_MEDIAN * 0.01, 0.0, 0.0); 9];
        residuals.push(Vector3::new(0.06, 0.0, 0.0));
        residuals.push(Vector3::new(0.0, 0.04, 0.0));
        let sigma = vec![0.01; 11];
        let mut in_fit = vec![true; 11];
        // Each point its own test: nothing to take off.
        let alone: Vec<usize> = (0..11).collect();
        let s = screen(&residuals, &sigma, &in_fit, &alone, 0);
        assert_eq!(s.scale, 1.0);
        assert_eq!(s.gross.iter().filter(|&&g| g).count(), 1);
        assert!(s.gross[9] && !s.gross[10]);
        // A noisier set-up (everything twice as large) doubles the scale: same verdicts.
        let doubled: Vec<Vector3<f64>> = residuals.iter().map(|r| r * 2.0).collect();
        let s2 = screen(&doubled, &sigma, &in_fit, &alone, 0);
        assert!((s2.scale - 2.0).abs() < 1e-9);
        assert_eq!(s2.gross, s.gross);
        // Left-out points do not set the scale.
        in_fit[9] = false;
        assert_eq!(screen(&residuals, &sigma, &in_fit, &alone, 0).scale, 1.0);
    }

    #[test]
    fn a_smooth_misfit_is_not_a_gross_error_a_lone_jump_is() {
        // Test 0: 41 points whose residual drifts smoothly by 0.2 mm (an effect the model
        // lacks) with ±10 µm noise, and one point 0.2 mm off its neighbours; test 1: 80 points
        // of noise alone, which set the scale.
        let noise = |k: usize| 0.01 * (k as f64 * 2.3).sin();
        let mut residuals: Vec<Vector3<f64>> = (0..41)
            .map(|k| Vector3::new(0.2 * k as f64 / 40.0, 0.0, noise(k)))
            .collect();
        residuals[17].y += 0.2;
        residuals.extend((0..80).map(|k| Vector3::new(noise(k + 7), noise(k + 3), noise(k))));
        let test: Vec<usize> = (0..121).map(|i| usize::from(i >= 41)).collect();
        let sigma = vec![0.01; 121];
        let s = screen(&residuals, &sigma, &[true; 121], &test, 0);
        let flagged: Vec<usize> = (0..121).filter(|&i| s.gross[i]).collect();
        assert_eq!(flagged, vec![17]);
        // Taken point by point (no neighbours), the drift itself would be flagged.
        let alone: Vec<usize> = (0..121).collect();
        let plain = screen(&residuals, &sigma, &[true; 121], &alone, 0);
        assert!(plain.gross.iter().filter(|&&g| g).count() > 10);
        // With test 0 as one test again, that many flags in it are not gross errors.
        let mut gross = plain.gross.clone();
        assert_eq!(limit_share(&mut gross, &test), vec![0]);
        assert!(gross.iter().all(|g| !g));
    }
}
