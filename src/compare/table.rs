//! The terminal table of `robopost compare`: per test and overall, one line per model (the
//! nominal robot, then each calibration), the paper's Table 1 columns, and the change of the
//! RMS residual from the line above, so that the fall from one model to the next is read
//! down a column.

use std::fmt::Write;

use super::Summary;
use crate::stats::ErrorStats;

/// Below this RMS (µm, far under any tracker's noise) a relative change means nothing.
const MIN_REFERENCE_UM: f64 = 0.5;

/// One line of the table: a test (or `all`) seen through one model.
#[derive(Clone, Debug, PartialEq)]
pub struct Line {
    /// The test label on the first line of its group, empty on the others.
    pub test: String,
    pub label: String,
    pub stats: ErrorStats,
    /// Change of the RMS from the line above in the same group, as a fraction (−0.34).
    pub rms_change: Option<f64>,
}

/// The lines for `models` (label, statistics), all over the same rows: per test in file
/// order, then `all`.
pub fn lines(models: &[(&str, &Summary)]) -> Vec<Line> {
    let Some((_, first)) = models.first() else {
        return Vec::new();
    };
    let groups = first
        .order
        .iter()
        .map(|t| (t.as_str(), Some(t)))
        .chain([("all", None)]);
    let mut out = Vec::new();
    for (name, key) in groups {
        let mut previous: Option<f64> = None;
        for (i, (label, s)) in models.iter().enumerate() {
            let stats = match key {
                Some(k) => s.tests.get(k).copied().unwrap_or_default(),
                None => s.all,
            };
            out.push(Line {
                test: if i == 0 {
                    name.to_string()
                } else {
                    String::new()
                },
                label: label.to_string(),
                stats,
                rms_change: previous
                    .filter(|&p| p >= MIN_REFERENCE_UM)
                    .map(|p| (stats.rms_um - p) / p),
            });
            previous = Some(stats.rms_um);
        }
    }
    out
}

/// `-34%`, `+5%`.
pub fn percent(change: Option<f64>) -> String {
    change.map_or(String::new(), |c| format!("{:+.0}%", c * 100.0))
}

/// Test and model labels longer than this are shown clipped (`...` at the end): a table
/// column is as wide as its widest label, and a label of 65,536 characters is past what a
/// format width can be.
const MAX_LABEL_CHARS: usize = 60;

/// `text` clipped to [`MAX_LABEL_CHARS`] characters.
fn clipped(text: &str) -> String {
    crate::diagnostic::clip(text, MAX_LABEL_CHARS)
}

/// Renders the table for `models` (label, statistics) as fixed-width text.
pub fn render(models: &[(&str, &Summary)]) -> String {
    let mut lines = lines(models);
    for l in &mut lines {
        l.test = clipped(&l.test);
        l.label = clipped(&l.label);
    }
    let width = |f: fn(&Line) -> &str, min: usize| {
        lines
            .iter()
            .map(|l| f(l).chars().count())
            .chain([min])
            .max()
            .unwrap_or(min)
    };
    let (tw, lw) = (width(|l| &l.test, 4), width(|l| &l.label, 5));
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:tw$}  {:>6}  {:lw$}  {:>15}  {:>15}  {:>15}",
        "", "", "", "XY error (µm)", "Z error (µm)", "3-D error (µm)",
    );
    let _ = writeln!(
        out,
        "{:tw$}  {:>6}  {:lw$}  {:>7} {:>7}  {:>7} {:>7}  {:>7} {:>7}  {:>7}  {:>6}",
        "test", "points", "model", "mean", "2σ", "mean", "2σ", "mean", "max", "RMS", "ΔRMS",
    );
    for l in &lines {
        let s = &l.stats;
        let points = if l.test.is_empty() {
            String::new()
        } else {
            s.points.to_string()
        };
        let _ = writeln!(
            out,
            "{:tw$}  {:>6}  {:lw$}  {:>7.1} {:>7.1}  {:>7.1} {:>7.1}  {:>7.1} {:>7.1}  {:>7.1}  {:>6}",
            l.test,
            points,
            l.label,
            s.xy_mean_um,
            s.xy_2sigma_um,
            s.z_mean_um,
            s.z_2sigma_um,
            s.d3_mean_um,
            s.d3_max_um,
            s.rms_um,
            percent(l.rms_change),
        );
    }
    out
}
