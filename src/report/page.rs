//! The page around the figures: header, the statistics table, the worst tests and points,
//! the figures in sections, a table of contents. Plain HTML and CSS; every text from the data
//! is escaped.

use std::fmt::Write;

use super::figures::{self, Figure};
use super::ReportInput;
use crate::compare::{table, test_order, Row, Summary};

const STYLE: &str = "body{font-family:sans-serif;margin:24px auto;max-width:1500px;color:#222}\
h1{font-size:1.6em}h2{margin-top:2em;border-bottom:1px solid #ccc}\
table{border-collapse:collapse;font-size:.9em}td,th{padding:2px 8px;text-align:right}\
th{background:#f0f0f0}td.l,th.l{text-align:left}tr.first td{border-top:1px solid #ddd}\
.fall{color:#1a7f37}.rise{color:#b42318}figure{display:inline-block;margin:8px;vertical-align:top}\
figcaption{max-width:660px;font-size:.85em;color:#555}.grid{display:flex;flex-wrap:wrap}\
.error{color:#b42318}nav a{margin-right:12px}tr.gross td{color:#b42318;background:#fdecea}";

/// Escapes text for HTML.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn anchor(test: &str) -> String {
    let slug: String = test
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    format!("test-{slug}")
}

fn figure_html(out: &mut String, f: &Figure) {
    let _ = writeln!(
        out,
        "<figure>{}<figcaption><b>{}</b>. {}</figcaption></figure>",
        f.svg,
        escape(&f.title),
        escape(&f.caption)
    );
}

pub fn render(input: &ReportInput) -> String {
    let models = &input.models;
    let main = &models[0];
    let order = test_order(main.rows);
    let mut out = String::new();
    let _ = write!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>robopost — model versus measurement</title><style>{STYLE}</style></head><body>\n\
         <h1>Model versus measurement</h1>\n"
    );
    let _ = write!(
        out,
        "<p>{} measured points in {} tests from {}.</p>\n<ul>",
        main.rows.len(),
        order.len(),
        escape(&input.sources.join(", "))
    );
    for m in models.iter() {
        let effects: Vec<String> = m.model.effects().iter().map(|e| e.name()).collect();
        let effects = if effects.is_empty() {
            "none (the nominal robot)".to_string()
        } else {
            effects.join(", ")
        };
        let _ = write!(
            out,
            "<li><b>{}</b>: {}</li>",
            escape(m.label),
            escape(&effects)
        );
    }
    out.push_str(
        "</ul>\n<nav><a href=\"#stats\">statistics</a><a href=\"#worst\">where it fails</a>\
                  <a href=\"#dist\">distributions</a><a href=\"#drivers\">drivers</a>",
    );
    for t in &order {
        let _ = write!(out, "<a href=\"#{}\">{}</a>", anchor(t), escape(t));
    }
    out.push_str("</nav>\n");

    statistics(&mut out, input);
    worst(&mut out, input, &order);
    gross_errors(&mut out, input);

    out.push_str("<h2 id=\"dist\">Error distributions</h2>\n<div class=\"grid\">");
    for f in figures::histograms(models) {
        figure_html(&mut out, &f);
    }
    out.push_str(
        "</div>\n<h2 id=\"drivers\">Residual against candidate drivers</h2>\n<p>What the \
                  model leaves (measured − predicted) against each quantity a missing effect \
                  would follow. Dots: points; lines: mean per bin.</p>\n<div class=\"grid\">",
    );
    let (plots, constant) = figures::drivers(models);
    for f in &plots {
        figure_html(&mut out, f);
    }
    out.push_str("</div>\n");
    let reversals = figures::reversal_travel(models);
    if !reversals.is_empty() {
        out.push_str(
            "<h2 id=\"reversals\">Residual against the travel since the last reversal</h2>\n\
             <p>Where an axis reversed by less than a gear play could be wide (reversal tests), \
             the play shows: an instant switch of direction fails there.</p>\n<div class=\"grid\">",
        );
        for f in &reversals {
            figure_html(&mut out, f);
        }
        out.push_str("</div>\n");
    }
    if let Some(l) = input.learned {
        learned(&mut out, l);
    }
    if !constant.is_empty() {
        let names: Vec<String> = constant.iter().map(|d| d.phrase()).collect();
        let _ = writeln!(
            out,
            "<p>Not plotted, because they did not vary in these measurements (nothing can be \
             learnt about them here): {}.</p>",
            escape(&names.join(", "))
        );
    }

    for t in &order {
        let idx: Vec<usize> = (0..main.rows.len())
            .filter(|&i| &main.rows[i].test == t)
            .collect();
        let _ = write!(
            out,
            "<h2 id=\"{}\">Test {}</h2>\n<div class=\"grid\">",
            anchor(t),
            escape(t)
        );
        figure_html(&mut out, &figures::trajectories(t, models, &idx));
        figure_html(&mut out, &figures::z_along_path(t, models, &idx));
        for f in figures::indexing(t, models, &idx) {
            figure_html(&mut out, &f);
        }
        out.push_str("</div>\n");
    }
    out.push_str("</body></html>\n");
    out
}

/// The drivers learned from the residual: what they are, how well they predict held-out data,
/// the command that adds them, and the plot.
fn learned(out: &mut String, l: &crate::diagnose::LearnedDrivers) {
    let _ = write!(
        out,
        "<h3 id=\"learned\">Learned from the residual</h3>\n<p>Fitted against generic drivers \
         (axis angles, reach, height, orientation to gravity, gravity torques, time, rotation \
         directions) and scored on held-out stretches of every test: the residual {}. As the \
         effect <code>{}</code> ({} parameters) it explains {:.0}% of held-out data ({:.1} µm \
         RMS after){}.</p>\n",
        escape(&l.shape),
        escape(&l.effect),
        l.parameters,
        100.0 * l.explained.max(0.0),
        l.rms_after_um,
        if l.stable {
            ", the same in every fold"
        } else {
            ", not stable across the folds"
        }
    );
    match &l.vetoed {
        None => {
            let _ = writeln!(
                out,
                "<p>Add it: <code>robopost identify -c CAL.json MEAS.csv {} -o NEW.json</code></p>",
                escape(&l.add)
            );
        }
        Some(why) => {
            let _ = writeln!(out, "<p>Not a finding: {}.</p>", escape(why));
        }
    }
    out.push_str("<div class=\"grid\">");
    figure_html(out, &figures::learned(l));
    out.push_str("</div>\n");
}

/// The paper's Table 1 per test: the nominal robot, the baseline, the calibration.
fn statistics(out: &mut String, input: &ReportInput) {
    let main = &input.models[0];
    let nominal = Summary::uncompensated(&unmarked(input, main.rows));
    let summaries: Vec<Summary> = input
        .models
        .iter()
        .map(|m| Summary::residuals(&unmarked(input, m.rows)))
        .collect();
    let mut columns: Vec<(&str, &Summary)> = vec![("nominal", &nominal)];
    for (m, s) in input.models.iter().zip(&summaries).rev() {
        columns.push((m.label, s));
    }
    out.push_str(
        "<h2 id=\"stats\">Statistics (the paper's Table 1)</h2>\n<p>µm. For the nominal line \
         the error is measured − nominal (the robot uncompensated), for a calibration it is \
         measured − predicted (what its model leaves). ΔRMS: change from the line above.</p>\n\
         <table><tr><th class=\"l\">test</th><th class=\"l\">model</th><th>points</th>\
         <th>XY mean</th><th>XY 2σ</th><th>Z mean</th><th>Z 2σ</th><th>3-D mean</th>\
         <th>3-D max</th><th>RMS</th><th>ΔRMS</th></tr>\n",
    );
    for l in table::lines(&columns) {
        let s = &l.stats;
        let class = match l.rms_change {
            Some(c) if c < 0.0 => "fall",
            Some(_) => "rise",
            None => "",
        };
        let _ = writeln!(
            out,
            "<tr{}><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{:.1}</td>\
             <td>{:.1}</td><td>{:.1}</td><td>{:.1}</td><td>{:.1}</td><td>{:.1}</td>\
             <td>{:.1}</td><td class=\"{class}\">{}</td></tr>",
            if l.test.is_empty() {
                ""
            } else {
                " class=\"first\""
            },
            escape(&l.test),
            escape(&l.label),
            s.points,
            s.xy_mean_um,
            s.xy_2sigma_um,
            s.z_mean_um,
            s.z_2sigma_um,
            s.d3_mean_um,
            s.d3_max_um,
            s.rms_um,
            table::percent(l.rms_change),
        );
    }
    out.push_str("</table>\n");
}

/// The rows not marked as gross errors.
fn unmarked(input: &ReportInput, rows: &[Row]) -> Vec<Row> {
    rows.iter()
        .enumerate()
        .filter(|(i, _)| gross_mark(input, *i).is_none())
        .map(|(_, r)| r.clone())
        .collect()
}

fn gross_mark<'a>(input: &'a ReportInput, row: usize) -> Option<&'a str> {
    input.gross_errors.get(row).and_then(|m| m.as_deref())
}

/// The points `identify` left out as gross errors, marked in red with the reason.
fn gross_errors(out: &mut String, input: &ReportInput) {
    let main = &input.models[0];
    let marked: Vec<usize> = (0..main.rows.len())
        .filter(|&i| gross_mark(input, i).is_some())
        .collect();
    if marked.is_empty() {
        return;
    }
    let _ = write!(
        out,
        "<h2 id=\"gross\">Gross errors</h2>\n<p>{} measured points were left out of the fit \
         by <code>identify</code> as gross errors (a broken beam, a stray reflection). They are \
         shown in red here and in the table above, and are not in the statistics.</p>\n\
         <table><tr><th class=\"l\">test</th><th class=\"l\">row</th><th>|residual| µm</th>\
         <th class=\"l\">why</th></tr>\n",
        marked.len()
    );
    for &i in &marked {
        let r = &main.rows[i];
        let _ = writeln!(
            out,
            "<tr class=\"gross\"><td class=\"l\">{}</td><td class=\"l\">{}:{}</td>\
             <td>{:.1}</td><td class=\"l\">{}</td></tr>",
            escape(&r.test),
            escape(&r.source),
            r.line,
            r.residual().norm() * 1000.0,
            escape(gross_mark(input, i).unwrap_or_default())
        );
    }
    out.push_str("</table>\n");
}

/// Tests ranked by the main model's RMS residual, and its ten worst points.
fn worst(out: &mut String, input: &ReportInput, order: &[String]) {
    let main = &input.models[0];
    let summary = Summary::residuals(&unmarked(input, main.rows));
    let mut ranked: Vec<(&String, f64)> = order
        .iter()
        .map(|t| (t, summary.tests.get(t).map_or(0.0, |s| s.rms_um)))
        .collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
    let _ = write!(
        out,
        "<h2 id=\"worst\">Where {} fails</h2>\n<p>Tests by RMS residual: ",
        escape(main.label)
    );
    let list: Vec<String> = ranked
        .iter()
        .map(|(t, rms)| format!("<a href=\"#{}\">{}</a> {rms:.1} µm", anchor(t), escape(t)))
        .collect();
    out.push_str(&list.join(", "));
    out.push_str(
        ".</p>\n<table><tr><th class=\"l\">test</th><th class=\"l\">row</th><th>A1</th>\
         <th>A2</th><th>A3</th><th>A4</th><th>A5</th><th>A6</th><th>residual X</th>\
         <th>Y</th><th>Z</th><th>|residual| µm</th></tr>\n",
    );
    let mut rows: Vec<(usize, &Row)> = main.rows.iter().enumerate().collect();
    rows.sort_by(|a, b| b.1.residual().norm().total_cmp(&a.1.residual().norm()));
    for (i, r) in rows.iter().take(10) {
        let e = r.residual() * 1000.0;
        let (class, flag) = match gross_mark(input, *i) {
            Some(_) => (" class=\"gross\"", " (gross error, left out)"),
            None => ("", ""),
        };
        let _ = write!(
            out,
            "<tr{class}><td class=\"l\">{}{flag}</td><td class=\"l\">{}:{}</td>",
            escape(&r.test),
            escape(&r.source),
            r.line
        );
        for a in r.state.axes_deg {
            let _ = write!(out, "<td>{a:.1}</td>");
        }
        let _ = writeln!(
            out,
            "<td>{:.1}</td><td>{:.1}</td><td>{:.1}</td><td>{:.1}</td></tr>",
            e.x,
            e.y,
            e.z,
            e.norm()
        );
    }
    out.push_str("</table>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Text from the data (test labels, file names) can never open a tag or an attribute.
        #[test]
        fn escaped_text_has_no_markup(text in ".*") {
            let e = escape(&text);
            prop_assert!(!e.contains('<') && !e.contains('>') && !e.contains('"'));
            let back = e.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&amp;", "&");
            prop_assert_eq!(back, text);
        }
    }
}
