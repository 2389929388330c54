//! Plot primitives of the report, drawn with plotters' SVG backend into strings that the page
//! inlines: an x–y chart of lines and dots, side-by-side trajectory panels at equal scale
//! with magnified errors (the paper's Fig. 9), and stacked histograms over a common axis (its
//! Fig. 11). Nothing here knows about robots; figures pass plain numbers.

use std::error::Error;
use std::ops::Range;

use plotters::coord::Shift;
use plotters::prelude::*;
pub use plotters::style::RGBColor;

/// Colours of the report: measured in black, models in distinct hues, direction curves in
/// blue (+) and red (−).
pub const MEASURED: RGBColor = RGBColor(20, 20, 20);
pub const PALETTE: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];
pub const POSITIVE: RGBColor = RGBColor(31, 119, 180);
pub const NEGATIVE: RGBColor = RGBColor(214, 39, 40);
pub const UNKNOWN: RGBColor = RGBColor(127, 127, 127);
/// X, Y, Z components.
pub const COMPONENTS: [RGBColor; 3] = [
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(31, 119, 180),
];
const GREY: RGBColor = RGBColor(170, 170, 170);
const FONT: &str = "sans-serif";

type Result<T> = std::result::Result<T, Box<dyn Error>>;

/// A chart plotters could not draw (the page shows the message in its place).
#[derive(Debug, thiserror::Error)]
#[error("plot failed: {0}")]
pub struct PlotError(Box<dyn Error>);

impl PlotError {
    fn from_drawing(e: impl Error + 'static) -> PlotError {
        PlotError(Box::new(e))
    }
}

/// An SVG document, or why it could not be drawn.
pub type Svg = std::result::Result<String, PlotError>;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Style {
    Line { width: u32 },
    Dots { radius: u32 },
    LineDots,
}

/// One series of an x–y chart.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend entry; `None` draws it without one.
    pub label: Option<String>,
    pub color: RGBColor,
    pub style: Style,
    pub points: Vec<(f64, f64)>,
}

/// Draws into an SVG string of `size` pixels.
fn render(
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<SVGBackend, Shift>) -> Result<()>,
) -> Svg {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(PlotError::from_drawing)?;
        draw(&root).map_err(PlotError)?;
        root.present().map_err(PlotError::from_drawing)?;
    }
    Ok(svg)
}

/// The range of `values` with 5 % padding; a unit range around a single value.
pub fn padded(values: impl IntoIterator<Item = f64>) -> Range<f64> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return -1.0..1.0;
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { 1.0 };
    (lo - pad)..(hi + pad)
}

/// Tick labels with as many decimals as the span of `range` needs (`150`, `2.5`, `0.05`).
fn ticks(range: &Range<f64>) -> impl Fn(&f64) -> String {
    let span = (range.end - range.start).abs();
    let decimals = match span {
        s if s >= 20.0 => 0,
        s if s >= 2.0 => 1,
        s if s >= 0.2 => 2,
        _ => 3,
    };
    move |v: &f64| format!("{v:.decimals$}")
}

/// An x–y chart with a legend when more than one series is labelled.
pub fn xy_chart(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    size: (u32, u32),
) -> Svg {
    let x = padded(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let fx = ticks(&x);
    chart(title, x_desc, y_desc, series, size, x, &fx)
}

/// [`xy_chart`] over a logarithmic x axis: the series' x are decimal logarithms, the ticks
/// show the values themselves.
pub fn log_x_chart(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    size: (u32, u32),
) -> Svg {
    let x = padded(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let fx = |v: &f64| {
        let value = 10f64.powf(*v);
        let decimals = (-v.floor()).max(0.0) as usize;
        format!("{value:.decimals$}")
    };
    chart(title, x_desc, y_desc, series, size, x, &fx)
}

fn chart(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    size: (u32, u32),
    x: Range<f64>,
    fx: &dyn Fn(&f64) -> String,
) -> Svg {
    let y = padded(series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let fy = ticks(&y);
    render(size, |root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, (FONT, 15))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(58)
            .build_cartesian_2d(x, y)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(fx)
            .y_label_formatter(&fy)
            .max_light_lines(2)
            .label_style((FONT, 11))
            .axis_desc_style((FONT, 12))
            .draw()?;
        let mut labelled = 0;
        for s in series {
            let color = s.color;
            let anno = match s.style {
                Style::Line { width } => chart.draw_series(LineSeries::new(
                    s.points.iter().copied(),
                    color.stroke_width(width),
                ))?,
                Style::Dots { radius } => chart.draw_series(
                    s.points
                        .iter()
                        .map(|&p| Circle::new(p, radius, color.mix(0.8).filled())),
                )?,
                Style::LineDots => chart.draw_series(
                    LineSeries::new(s.points.iter().copied(), color.stroke_width(1)).point_size(2),
                )?,
            };
            if let Some(label) = &s.label {
                labelled += 1;
                anno.label(label.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(3))
                });
            }
        }
        if labelled > 1 {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .label_font((FONT, 11))
                .background_style(WHITE.mix(0.6))
                .border_style(BLACK.mix(0.4))
                .draw()?;
        }
        Ok(())
    })
}

/// One panel of [`trajectory_panels`]: a path magnified by its own errors.
#[derive(Clone, Debug)]
pub struct Trajectory {
    pub title: String,
    pub color: RGBColor,
    /// Error at each stop in the plane (mm), drawn `scale` times enlarged.
    pub errors: Vec<(f64, f64)>,
}

/// The paper's Fig. 9: side by side at one scale, the commanded path (grey) and, per panel,
/// the path displaced by `scale` × its errors.
pub fn trajectory_panels(
    caption: &str,
    axes: (&str, &str),
    path: &[(f64, f64)],
    panels: &[Trajectory],
    scale: f64,
    panel_size: (u32, u32),
) -> Svg {
    let shifted: Vec<Vec<(f64, f64)>> = panels
        .iter()
        .map(|p| {
            path.iter()
                .zip(&p.errors)
                .map(|(&(x, y), &(ex, ey))| (x + scale * ex, y + scale * ey))
                .collect()
        })
        .collect();
    let all = || path.iter().chain(shifted.iter().flatten());
    let (x, y) = equal_aspect(
        padded(all().map(|p| p.0)),
        padded(all().map(|p| p.1)),
        (panel_size.0 - 70, panel_size.1 - 70),
    );
    let (fx, fy) = (ticks(&x), ticks(&y));
    let width = panel_size.0 * panels.len().max(1) as u32;
    render((width, panel_size.1 + 24), |root| {
        let root = root.titled(caption, (FONT, 15))?;
        for (area, (panel, moved)) in root
            .split_evenly((1, panels.len().max(1)))
            .iter()
            .zip(panels.iter().zip(&shifted))
        {
            let mut chart = ChartBuilder::on(area)
                .caption(&panel.title, (FONT, 13))
                .margin(6)
                .x_label_area_size(30)
                .y_label_area_size(50)
                .build_cartesian_2d(x.clone(), y.clone())?;
            chart
                .configure_mesh()
                .x_desc(format!("{} (mm)", axes.0))
                .y_desc(format!("{} (mm)", axes.1))
                .x_label_formatter(&fx)
                .y_label_formatter(&fy)
                .max_light_lines(1)
                .label_style((FONT, 10))
                .axis_desc_style((FONT, 11))
                .draw()?;
            chart.draw_series(LineSeries::new(path.iter().copied(), GREY.stroke_width(1)))?;
            let color = panel.color;
            chart.draw_series(
                LineSeries::new(moved.iter().copied(), color.stroke_width(1)).point_size(1),
            )?;
        }
        Ok(())
    })
}

/// Widens the shorter range so that one mm is as long in x as in y on `pixels`.
fn equal_aspect(x: Range<f64>, y: Range<f64>, pixels: (u32, u32)) -> (Range<f64>, Range<f64>) {
    let (w, h) = (pixels.0.max(1) as f64, pixels.1.max(1) as f64);
    let per_px = ((x.end - x.start) / w).max((y.end - y.start) / h);
    let widen = |r: Range<f64>, px: f64| {
        let mid = 0.5 * (r.start + r.end);
        (mid - 0.5 * per_px * px)..(mid + 0.5 * per_px * px)
    };
    (widen(x, w), widen(y, h))
}

/// One row of [`histograms`].
#[derive(Clone, Debug)]
pub struct Distribution {
    pub title: String,
    pub color: RGBColor,
    pub values: Vec<f64>,
}

/// The paper's Fig. 11: stacked histograms over one common axis and bin width.
pub fn histograms(
    caption: &str,
    x_desc: &str,
    rows: &[Distribution],
    bins: usize,
    row_size: (u32, u32),
) -> Svg {
    let x = padded(rows.iter().flat_map(|r| r.values.iter().copied()));
    let bins = bins.max(1);
    let width = (x.end - x.start) / bins as f64;
    let counts: Vec<Vec<usize>> = rows
        .iter()
        .map(|r| {
            let mut c = vec![0; bins];
            for v in r.values.iter().filter(|v| v.is_finite()) {
                let i = (((v - x.start) / width) as usize).min(bins - 1);
                c[i] += 1;
            }
            c
        })
        .collect();
    let top = counts.iter().flatten().copied().max().unwrap_or(1).max(1) as f64 * 1.1;
    let fx = ticks(&x);
    let height = row_size.1 * rows.len().max(1) as u32;
    render((row_size.0, height + 24), |root| {
        let root = root.titled(caption, (FONT, 15))?;
        for (area, (row, count)) in root
            .split_evenly((rows.len().max(1), 1))
            .iter()
            .zip(rows.iter().zip(&counts))
        {
            let mut chart = ChartBuilder::on(area)
                .caption(&row.title, (FONT, 12))
                .margin(4)
                .x_label_area_size(28)
                .y_label_area_size(44)
                .build_cartesian_2d(x.clone(), 0.0..top)?;
            chart
                .configure_mesh()
                .x_desc(x_desc)
                .y_desc("points")
                .x_label_formatter(&fx)
                .y_label_formatter(&|v| format!("{v:.0}"))
                .max_light_lines(1)
                .label_style((FONT, 10))
                .axis_desc_style((FONT, 11))
                .draw()?;
            let color = row.color;
            chart.draw_series(count.iter().enumerate().filter(|(_, &c)| c > 0).map(
                |(i, &c)| {
                    let x0 = x.start + i as f64 * width;
                    Rectangle::new(
                        [(x0, 0.0), (x0 + width, c as f64)],
                        color.mix(0.75).filled(),
                    )
                },
            ))?;
        }
        Ok(())
    })
}

/// A "nice" magnification 1, 2 or 5 × 10^k that draws `largest_mm` as about `target_mm`.
pub fn nice_scale(largest_mm: f64, target_mm: f64) -> f64 {
    if !(largest_mm > 0.0 && target_mm > 0.0) {
        return 1.0;
    }
    let raw = target_mm / largest_mm;
    let decade = 10f64.powf(raw.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&s| s <= raw)
        .unwrap_or(decade)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_scale_rounds_down_to_one_two_five() {
        // 0.1 mm drawn as about 100 mm: exactly 1000 (the paper's Fig. 9 magnification).
        assert_eq!(nice_scale(0.1, 100.0), 1000.0);
        assert_eq!(nice_scale(0.3, 100.0), 200.0); // 333 → 200
        assert_eq!(nice_scale(0.15, 100.0), 500.0); // 667 → 500
        assert_eq!(nice_scale(0.0, 100.0), 1.0);
    }

    #[test]
    fn equal_aspect_gives_equal_mm_per_pixel() {
        let (x, y) = equal_aspect(0.0..100.0, 0.0..10.0, (200, 100));
        let (sx, sy) = ((x.end - x.start) / 200.0, (y.end - y.start) / 100.0);
        assert!((sx - sy).abs() < 1e-12 && (sx - 0.5).abs() < 1e-12);
        assert!((y.start + y.end - 10.0).abs() < 1e-12); // centred
    }

    #[test]
    fn charts_are_svg_with_their_elements() {
        let s = Series {
            label: Some("a".into()),
            color: POSITIVE,
            style: Style::Dots { radius: 2 },
            points: vec![(0.0, 1.0), (1.0, 2.0), (2.0, 0.5)],
        };
        let svg = xy_chart("t", "x", "y", &[s], (300, 200)).unwrap();
        assert!(svg.starts_with("<svg"));
        assert_eq!(svg.matches("<circle").count(), 3);
        let h = histograms(
            "h",
            "v",
            &[Distribution {
                title: "d".into(),
                color: NEGATIVE,
                values: vec![0.0, 0.1, 0.9, 1.0],
            }],
            2,
            (300, 120),
        )
        .unwrap();
        // Two non-empty bins of two values each: two bars (plus the background rectangles).
        assert!(h.matches("<rect").count() >= 2);
    }
}
