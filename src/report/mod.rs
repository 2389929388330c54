//! The HTML report of `robopost compare --report DIR`: one self-contained page
//! (`DIR/index.html`, inline SVG, no script, no external file) that shows a user where the
//! model fails — the paper's Table 1 per test, the tests and points the model explains worst,
//! its Figs. 9–11, per indexing test the residual over the swept angle by rotation direction,
//! the residual against every candidate driver, per axis that reversed by little the residual
//! against the travel since its last reversal (where a gear play shows), and the drivers
//! learned from the residual
//! (what a `learned:` effect would add, with its plot) when a diagnosis found them. Written
//! atomically.

pub mod figures;
mod page;
pub mod plot;

use std::path::{Path, PathBuf};

use crate::compare::Row;
use crate::model::Model;

/// One model in the report with its rows (all models over the same measured rows, in order).
#[derive(Clone, Copy, Debug)]
pub struct ReportModel<'a> {
    /// How the page names it (the calibration's file name).
    pub label: &'a str,
    pub model: &'a Model,
    pub rows: &'a [Row],
}

/// What the report shows: the main calibration first, then the one it is compared against.
#[derive(Clone, Debug)]
pub struct ReportInput<'a> {
    pub models: Vec<ReportModel<'a>>,
    /// The measurement files, as the user named them.
    pub sources: Vec<String>,
    /// Per row (the models' common order): why `identify` left it out as a gross error, if it
    /// did. Such rows are marked and kept out of the statistics; empty: none.
    pub gross_errors: Vec<Option<String>>,
    /// The drivers a diagnosis learned from the main model's residual.
    pub learned: Option<&'a crate::diagnose::LearnedDrivers>,
}

/// The page as a string.
pub fn html(input: &ReportInput) -> String {
    page::render(input)
}

/// The page written into the report directory.
pub const INDEX: &str = "index.html";

/// Writes `dir/index.html` atomically (creating `dir`) and returns its path.
pub fn write(dir: &Path, input: &ReportInput) -> std::io::Result<PathBuf> {
    if input.models.is_empty() {
        return Err(std::io::Error::other("no model to report on"));
    }
    let text = html(input);
    std::fs::create_dir_all(dir)?;
    let path = dir.join(INDEX);
    crate::atomic_file::write(&path, text.as_bytes())?;
    Ok(path)
}
