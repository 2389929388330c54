//! The report's figures, each from the compared rows: the paper's Fig. 9 (errors along a
//! path in a plane, magnified, measured beside predicted and the residual), Fig. 10 (Z error
//! along a path, measured versus each model), Fig. 11 (histograms of XY and Z errors, the
//! robot's own error and each model's residual), per indexing test the residual as an angle
//! of the swept axis against its angle with one curve per rotation direction, the residual
//! against every candidate driver, and per axis the residual against the travel since its last
//! reversal (where a gear play shows).

use nalgebra::Vector3;

use super::plot::{self, Distribution, Series, Style, Trajectory};
use super::ReportModel;
use crate::compare::axis_residual::{angular_residual, indexed_axis, off_motion_residual_um};
use crate::compare::{Driver, Row, DRIVERS};
use crate::diagnose::play;
use crate::model::Direction;

/// One figure of the page.
#[derive(Clone, Debug)]
pub struct Figure {
    pub title: String,
    /// One or two sentences saying how to read it.
    pub caption: String,
    pub svg: String,
}

fn figure(title: String, caption: String, svg: plot::Svg) -> Figure {
    Figure {
        title,
        caption,
        svg: svg.unwrap_or_else(|e| format!("<p class=\"error\">{e}</p>")),
    }
}

const COORDS: [&str; 3] = ["X", "Y", "Z"];

/// The plane a path is best seen in: XY (the paper's Fig. 9) unless Z is one of the path's
/// two largest extents (an arm swinging in a vertical plane), then that vertical plane.
fn plane(rows: &[&Row]) -> (usize, usize) {
    let extent = |k: usize| {
        let (lo, hi) = rows
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
                (lo.min(r.nominal[k]), hi.max(r.nominal[k]))
            });
        hi - lo
    };
    let (ex, ey, ez) = (extent(0), extent(1), extent(2));
    if ez <= ex.min(ey) {
        (0, 1)
    } else if ex >= ey {
        (0, 2)
    } else {
        (1, 2)
    }
}

fn in_plane(v: &Vector3<f64>, (a, b): (usize, usize)) -> (f64, f64) {
    (v[a], v[b])
}

/// The paper's Fig. 9 for one test: measured error, each model's predicted error and the
/// main model's residual, magnified by one common factor.
pub fn trajectories(test: &str, models: &[ReportModel], idx: &[usize]) -> Figure {
    let main: Vec<&Row> = idx.iter().map(|&i| &models[0].rows[i]).collect();
    let pl = plane(&main);
    let path: Vec<(f64, f64)> = main.iter().map(|r| in_plane(&r.nominal, pl)).collect();
    let errors = |f: &dyn Fn(&Row) -> Vector3<f64>, m: &ReportModel| -> Vec<(f64, f64)> {
        idx.iter().map(|&i| in_plane(&f(&m.rows[i]), pl)).collect()
    };
    let mut panels = vec![Trajectory {
        title: "measured".into(),
        color: plot::MEASURED,
        errors: errors(&Row::measured_error, &models[0]),
    }];
    for (k, m) in models.iter().enumerate() {
        panels.push(Trajectory {
            title: format!("predicted by {}", m.label),
            color: plot::PALETTE[k % plot::PALETTE.len()],
            errors: errors(&Row::predicted_error, m),
        });
    }
    panels.push(Trajectory {
        title: format!("measured − predicted ({})", models[0].label),
        color: plot::NEGATIVE,
        errors: errors(&Row::residual, &models[0]),
    });
    let largest = panels
        .iter()
        .flat_map(|p| p.errors.iter().map(|e| e.0.hypot(e.1)))
        .fold(0.0, f64::max);
    let span = {
        let x = plot::padded(path.iter().map(|p| p.0));
        let y = plot::padded(path.iter().map(|p| p.1));
        (x.end - x.start).max(y.end - y.start).max(50.0)
    };
    let scale = plot::nice_scale(largest, 0.12 * span);
    let names = (COORDS[pl.0], COORDS[pl.1]);
    let title = format!(
        "{test}: errors in the {}{} plane, magnified ×{scale}",
        names.0, names.1
    );
    let svg = plot::trajectory_panels(&title, names, &path, &panels, scale, (340, 320));
    figure(
        title,
        format!(
            "Grey: the commanded path. Coloured: the path displaced by {scale} times the error \
             at each stop (the paper's Fig. 9). Where the measured and predicted shapes differ, \
             the model misses something; the last panel shows what."
        ),
        svg,
    )
}

/// The paper's Fig. 10: the Z error along the test's stops, measured against each model.
pub fn z_along_path(test: &str, models: &[ReportModel], idx: &[usize]) -> Figure {
    let at = |m: &ReportModel, f: fn(&Row) -> Vector3<f64>| -> Vec<(f64, f64)> {
        idx.iter()
            .enumerate()
            .map(|(k, &i)| ((k + 1) as f64, f(&m.rows[i]).z * 1000.0))
            .collect()
    };
    let mut series = vec![Series {
        label: Some("measured".into()),
        color: plot::MEASURED,
        style: Style::LineDots,
        points: at(&models[0], Row::measured_error),
    }];
    for (k, m) in models.iter().enumerate() {
        series.push(Series {
            label: Some(format!("predicted by {}", m.label)),
            color: plot::PALETTE[k % plot::PALETTE.len()],
            style: Style::Line { width: 2 },
            points: at(m, Row::predicted_error),
        });
    }
    let title = format!("{test}: Z error along the path");
    let svg = plot::xy_chart(&title, "stop", "Z error (µm)", &series, (680, 300));
    figure(
        title,
        "The robot's Z error from the command at each stop in visiting order (the paper's \
         Fig. 10), against what each model predicts."
            .into(),
        svg,
    )
}

/// The paper's Fig. 11: distributions of the XY-plane distance error and the Z error, for the
/// robot's own error (nominal model) and each model's residual.
pub fn histograms(models: &[ReportModel]) -> Vec<Figure> {
    let mut rows: Vec<(String, plot::RGBColor, Vec<Vector3<f64>>)> = vec![(
        "uncompensated: measured − nominal".into(),
        plot::MEASURED,
        models[0].rows.iter().map(Row::measured_error).collect(),
    )];
    // Baseline (against) above the main calibration, as in the paper's rows.
    for (k, m) in models.iter().enumerate().rev() {
        rows.push((
            format!("{}: measured − predicted", m.label),
            plot::PALETTE[k % plot::PALETTE.len()],
            m.rows.iter().map(Row::residual).collect(),
        ));
    }
    let make = |name: &str, f: fn(&Vector3<f64>) -> f64| {
        let d: Vec<Distribution> = rows
            .iter()
            .map(|(title, color, e)| {
                let values: Vec<f64> = e.iter().map(|v| f(v) * 1000.0).collect();
                let s = crate::stats::error_stats(e);
                let (mean, two_sigma) = if name == "XY" {
                    (s.xy_mean_um, s.xy_2sigma_um)
                } else {
                    (s.z_mean_um, s.z_2sigma_um)
                };
                Distribution {
                    title: format!("{title} (mean {mean:.1} µm, 2σ {two_sigma:.1} µm)"),
                    color: *color,
                    values,
                }
            })
            .collect();
        let title = format!("{name} error distribution");
        let x_desc = if name == "XY" {
            "XY-plane distance error (µm)"
        } else {
            "Z error (µm)"
        };
        figure(
            title.clone(),
            format!(
                "Histogram of the {name} error over every measured point (the paper's Fig. 11)."
            ),
            plot::histograms(&title, x_desc, &d, 40, (440, 150)),
        )
    };
    vec![make("XY", |v| v.x.hypot(v.y)), make("Z", |v| v.z)]
}

/// For an indexing test, the main model's residual as an angle of the swept axis and the part
/// an angle cannot explain, against the axis angle, one curve per rotation direction.
pub fn indexing(test: &str, models: &[ReportModel], idx: &[usize]) -> Vec<Figure> {
    let m = &models[0];
    let Some(axis) = indexed_axis(idx.iter().map(|&i| &m.rows[i])) else {
        return Vec::new();
    };
    let n = axis as usize - 1;
    let by_direction = |value: &dyn Fn(&Row) -> Option<f64>| -> Vec<Series> {
        [
            (Direction::Positive, "+ direction", plot::POSITIVE),
            (Direction::Negative, "− direction", plot::NEGATIVE),
            (Direction::Unknown, "direction unknown", plot::UNKNOWN),
        ]
        .into_iter()
        .filter_map(|(d, label, color)| {
            let mut points: Vec<(f64, f64)> = idx
                .iter()
                .map(|&i| &m.rows[i])
                .filter(|r| r.state.directions()[n] == d)
                .filter_map(|r| value(r).map(|v| (r.state.axes_deg[n], v)))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            (!points.is_empty()).then(|| Series {
                label: Some(label.into()),
                color,
                style: Style::LineDots,
                points,
            })
        })
        .collect()
    };
    let x_desc = format!("A{axis} command angle (°)");
    let mut figures = Vec::new();
    let angular = by_direction(&|r| angular_residual(m.model, r, axis));
    if !angular.is_empty() {
        let title = format!("{test}: residual as an A{axis} angle");
        figures.push(figure(
            title.clone(),
            format!(
                "The residual projected on the motion of A{axis}, as the angular positioning \
                 deviation the model ({}) is missing, per rotation direction. A shape here is a \
                 missing map; a gap between the curves is missing backlash.",
                m.label
            ),
            plot::xy_chart(
                &title,
                &x_desc,
                "missing angle (arcsec)",
                &angular,
                (520, 300),
            ),
        ));
    }
    let off = by_direction(&|r| Some(off_motion_residual_um(m.model, r, axis)));
    let title = format!("{test}: residual off the A{axis} motion");
    figures.push(figure(
        title.clone(),
        format!(
            "The part of the residual an A{axis} angle cannot explain (µm). A shape over the \
             angle here points at a tilt error motion or a geometric error."
        ),
        plot::xy_chart(
            &title,
            &x_desc,
            "off-motion residual (µm)",
            &off,
            (520, 300),
        ),
    ));
    figures
}

/// Where a stop reached after a long travel since the reversal (or an unknown one) is drawn
/// on the travel axis, degrees: past every finite travel a play cares about.
const LONG_TRAVEL_AT_DEG: f64 = 5.0;

/// Per axis whose data hold stops after short reversals (reversal tests, programs that turn
/// an axis round by little): each model's residual along the axis's motion, signed by its
/// rotation direction, against the command's travel since the last reversal (log scale;
/// long travel at the right edge). A model with a gear play is flat here; an instant switch
/// of sign (or none) leaves a residual that falls with the travel to zero at the play's width.
pub fn reversal_travel(models: &[ReportModel]) -> Vec<Figure> {
    let mut figures = Vec::new();
    for axis in 1..=6u8 {
        if !play::has_short_reversals(models[0].rows, axis) {
            continue;
        }
        let series: Vec<Series> = models
            .iter()
            .enumerate()
            .map(|(k, m)| Series {
                label: Some(m.label.to_string()),
                color: plot::PALETTE[k % plot::PALETTE.len()],
                style: Style::Dots { radius: 2 },
                points: play::points(m.model, m.rows, axis)
                    .into_iter()
                    .map(|p| {
                        let travel = p.travel_deg.clamp(1e-4, LONG_TRAVEL_AT_DEG);
                        (travel.log10(), p.signed_um)
                    })
                    .collect(),
            })
            .collect();
        let title = format!("A{axis}: residual against travel since the last reversal");
        figures.push(figure(
            title.clone(),
            format!(
                "The residual along the A{axis} motion, signed by its rotation direction (µm), \
                 against how far the command has travelled since A{axis} last reversed (°, log \
                 scale; {LONG_TRAVEL_AT_DEG}°: long travel). A gear play leaves the output where \
                 it was while the command reverses by less than the play: a model that switches \
                 with the direction (or has none) fails there, the residual falling with the \
                 travel to zero at the play's width. Flat: the model describes the play."
            ),
            plot::log_x_chart(
                &title,
                &format!("A{axis} travel since the last reversal (°)"),
                "signed residual along the motion (µm)",
                &series,
                (520, 300),
            ),
        ));
    }
    figures
}

/// Most rows a driver plot shows (every k-th row beyond that), to keep the page light.
const DRIVER_POINTS: usize = 900;
const DRIVER_BINS: usize = 24;

/// The main model's residual (X, Y, Z components) against each candidate driver that varies
/// in the data, with the mean per bin of the driver as a line; and the drivers that did not
/// vary (nothing can be learnt about them from these measurements).
pub fn drivers(models: &[ReportModel]) -> (Vec<Figure>, Vec<Driver>) {
    let m = &models[0];
    let step = m.rows.len().div_ceil(DRIVER_POINTS).max(1);
    let mut constant = Vec::new();
    let mut figures = Vec::new();
    for driver in DRIVERS {
        let values: Vec<(f64, Vector3<f64>)> = m
            .rows
            .iter()
            .filter_map(|r| {
                driver
                    .value(m.model, &r.state)
                    .map(|x| (x, r.residual() * 1000.0))
            })
            .collect();
        let range = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v.0), hi.max(v.0))
            });
        if values.is_empty() || range.1 - range.0 < 1e-6 {
            constant.push(driver);
            continue;
        }
        let mut series = Vec::new();
        for (c, &color) in plot::COMPONENTS.iter().enumerate() {
            series.push(Series {
                label: Some(format!("{} residual", COORDS[c])),
                color,
                style: Style::Dots { radius: 1 },
                points: values
                    .iter()
                    .step_by(step)
                    .map(|(x, r)| (*x, r[c]))
                    .collect(),
            });
            series.push(Series {
                label: None,
                color,
                style: Style::Line { width: 2 },
                points: binned_means(values.iter().map(|(x, r)| (*x, r[c]))),
            });
        }
        let title = format!("residual against {}", driver.phrase());
        figures.push(figure(
            title.clone(),
            driver_caption(&driver),
            plot::xy_chart(
                &title,
                &driver.label(),
                "residual (µm)",
                &series,
                (420, 280),
            ),
        ));
    }
    (figures, constant)
}

fn driver_caption(driver: &Driver) -> String {
    match driver {
        Driver::Angle(n) => format!(
            "A trend that the A{n} tests do not share points at a crosstalk onto another axis \
             (crosstalk:A{n}->An) or a tilt of A{n}."
        ),
        Driver::Torque(n) => format!("A trend here points at compliance:A{n}."),
        Driver::Time => "A trend over the campaign points at drift (thermal growth).".into(),
    }
}

/// The mean of y in equal bins of x (bins with fewer than three points are skipped).
fn binned_means(points: impl Iterator<Item = (f64, f64)> + Clone) -> Vec<(f64, f64)> {
    let range = plot::padded(points.clone().map(|p| p.0));
    let width = (range.end - range.start) / DRIVER_BINS as f64;
    let mut sums = vec![(0.0, 0.0, 0usize); DRIVER_BINS];
    for (x, y) in points {
        let i = (((x - range.start) / width) as usize).min(DRIVER_BINS - 1);
        sums[i].0 += x;
        sums[i].1 += y;
        sums[i].2 += 1;
    }
    sums.into_iter()
        .filter(|s| s.2 >= 3)
        .map(|(sx, sy, n)| (sx / n as f64, sy / n as f64))
        .collect()
}

/// The residual along the learned correction against the main learned driver, beside the
/// learned correction itself: where the dots follow the line, the learned effect explains
/// the residual.
pub fn learned(l: &crate::diagnose::LearnedDrivers) -> Figure {
    let c = &l.curve;
    let series = [
        Series {
            label: Some("residual along the correction".into()),
            color: plot::MEASURED,
            style: Style::Dots { radius: 1 },
            points: c.points.iter().map(|p| (p.0, p.1)).collect(),
        },
        Series {
            label: Some("learned correction".into()),
            color: plot::PALETTE[1],
            style: Style::Dots { radius: 2 },
            points: c.points.iter().map(|p| (p.0, p.2)).collect(),
        },
        Series {
            label: None,
            color: plot::MEASURED,
            style: Style::Line { width: 2 },
            points: binned_means(c.points.iter().map(|p| (p.0, p.1))),
        },
    ];
    let title = format!("learned: {}", l.effect);
    figure(
        title.clone(),
        format!(
            "The residual at each point projected on the direction the learned effect corrects \
             it (black; line: mean per bin) and the size of that correction (orange), against \
             {}. The residual {}.",
            c.driver, l.shape
        ),
        plot::xy_chart(&title, &c.driver, "µm", &series, (560, 320)),
    )
}
