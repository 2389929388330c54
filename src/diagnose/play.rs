//! Evidence for a gear play read off the residuals: the residual along an axis's motion,
//! signed by its rotation direction, against the command's travel since the axis's last
//! reversal. After a long travel a play and an instant switch of sign predict alike (the
//! output lags by half the width); after a reversal shorter than the play the output has not
//! moved, so a model that switches with the direction (or has no direction dependence) is off
//! by the width less the travel: a residual that falls linearly with the travel and vanishes
//! at the width. Only reversal tests (or programs that turn an axis round by less than its
//! play) hold such stops; the paper's campaign reaches every stop after a long motion.

use crate::compare::axis_residual::signed_by_direction;
use crate::compare::Row;
use crate::model::{AxisHistory, Direction, EffectName, GridOptions, Model};

/// A stop reached after a reversal shorter than this (degrees of command) may lie inside a
/// gear play: plays are hundredths of a degree, ten times the usual is still "small".
pub const SHORT_TRAVEL_DEG: f64 = 0.1;
/// A stop reached after this much travel since the reversal has the play engaged (any play
/// a calibration holds up to [`MAX_PLAY_DEG`](crate::model::history::MAX_PLAY_DEG) is half
/// of that at most in the typical case; the history calls 2° of run "long" anyway).
pub const LONG_TRAVEL_DEG: f64 = 0.5;
/// A short stop is compared with the long stops of its test within this angle, degrees.
const LOCAL_DEG: f64 = 0.5;
/// Fewest stops on each side for a statement.
const MIN_POINTS: usize = 3;
/// Resolution of the width estimate, degrees.
const WIDTH_STEP_DEG: f64 = 1e-4;

/// One stop seen from axis n's direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TravelPoint {
    /// Command travel since the axis's last reversal, degrees (infinite: long or unknown).
    pub travel_deg: f64,
    /// The residual along the axis's motion times the direction's sign, µm.
    pub signed_um: f64,
    /// The same as an angle of the axis, degrees.
    pub signed_deg: f64,
    /// The axis's history and command there, to evaluate a play of any width.
    history: AxisHistory,
    angle_deg: f64,
    sign: f64,
    /// Index of the row.
    row: usize,
}

impl TravelPoint {
    /// What a play of width `w` (degrees) puts this stop's output ahead of the flank a long
    /// motion in its direction would leave it on, in the direction of travel: 0 after a long
    /// travel, `w − travel` after a reversal shorter than the play that followed a long run.
    /// It is the part of the signed residual that a model which switches with the direction
    /// (or has none) leaves on top of what it leaves after long travel.
    pub fn dead_band_excess(&self, w: f64) -> f64 {
        self.sign * self.history.play(self.angle_deg, |_| w).lag_deg + 0.5 * w
    }
}

/// Every stop of `rows` at which axis `axis` has a known direction and moves the target.
pub fn points(model: &Model, rows: &[Row], axis: u8) -> Vec<TravelPoint> {
    let n = axis as usize - 1;
    rows.iter()
        .enumerate()
        .filter_map(|(row, r)| {
            let dir = r.state.directions()[n];
            if dir == Direction::Unknown {
                return None;
            }
            let (um, deg) = signed_by_direction(model, r, axis)?;
            let history = r.state.history[n];
            let angle_deg = r.state.axes_deg[n];
            Some(TravelPoint {
                travel_deg: history.travel_since_reversal(angle_deg),
                signed_um: um,
                signed_deg: deg,
                history,
                angle_deg,
                sign: dir.sign(),
                row,
            })
        })
        .collect()
}

/// Whether `rows` hold a stop of axis `axis` reached after a reversal shorter than
/// [`SHORT_TRAVEL_DEG`] (data that can tell a play from an instant switch).
pub fn has_short_reversals(rows: &[Row], axis: u8) -> bool {
    let n = axis as usize - 1;
    rows.iter().any(|r| {
        r.state.directions()[n] != Direction::Unknown
            && r.state.history[n].travel_since_reversal(r.state.axes_deg[n]) < SHORT_TRAVEL_DEG
    })
}

/// What the stops after short reversals say about a play of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlayEvidence {
    /// Stops after a reversal shorter than [`SHORT_TRAVEL_DEG`], and after long travel.
    pub short: usize,
    pub long: usize,
    /// The width of the play that fits the short stops best: their residual above the long
    /// stops' as [`TravelPoint::dead_band_excess`], degrees (0: no dead band).
    pub width_deg: f64,
    /// Stops whose output that play leaves behind (after a reversal inside it), and their mean
    /// residual above the long stops', µm.
    pub inside: usize,
    pub excess_um: f64,
}

/// The dead band of axis `axis` as the residuals show it; `None` when the data hold too few
/// stops after short reversals or after long travel.
pub fn evidence(model: &Model, rows: &[Row], axis: u8) -> Option<PlayEvidence> {
    let all = points(model, rows, axis);
    let short: Vec<&TravelPoint> = all
        .iter()
        .filter(|p| p.travel_deg < SHORT_TRAVEL_DEG)
        .collect();
    let long: Vec<&TravelPoint> = all
        .iter()
        .filter(|p| p.travel_deg >= LONG_TRAVEL_DEG)
        .collect();
    if short.len() < MIN_POINTS || long.len() < MIN_POINTS {
        return None;
    }
    let mean = |v: &[&TravelPoint], f: fn(&TravelPoint) -> f64| {
        v.iter().map(|p| f(p)).sum::<f64>() / v.len() as f64
    };
    // What a short stop is measured against: the long stops of its own test within
    // LOCAL_DEG of its angle (what a model without the play leaves after long travel varies
    // over the workspace), else all long stops.
    let (all_deg, all_um) = (mean(&long, |p| p.signed_deg), mean(&long, |p| p.signed_um));
    let baseline: Vec<(f64, f64)> = short
        .iter()
        .map(|p| {
            let near: Vec<&TravelPoint> = long
                .iter()
                .copied()
                .filter(|q| {
                    rows[q.row].test == rows[p.row].test
                        && (q.angle_deg - p.angle_deg).abs() <= LOCAL_DEG
                })
                .collect();
            if near.is_empty() {
                (all_deg, all_um)
            } else {
                (mean(&near, |q| q.signed_deg), mean(&near, |q| q.signed_um))
            }
        })
        .collect();
    // Least squares of the short stops' residual above the long stops' against what a play of
    // width b leaves there, over b on a grid of 10⁻⁴° (finer than any width worth telling;
    // the cost is not smooth in b where a stop enters the dead band).
    let cost = |b: f64| -> f64 {
        short
            .iter()
            .zip(&baseline)
            .map(|(p, base)| (p.signed_deg - base.0 - p.dead_band_excess(b)).powi(2))
            .sum()
    };
    let steps = (SHORT_TRAVEL_DEG / WIDTH_STEP_DEG).round() as usize;
    let width_deg = (0..=steps)
        .map(|k| k as f64 * WIDTH_STEP_DEG)
        .min_by(|a, b| cost(*a).total_cmp(&cost(*b)))
        .unwrap_or(0.0);
    // A play that lowers the short stops' sum of squares by less than MIN_T² times their
    // scatter about it is noise (one parameter: the t statistic of its width).
    let scatter = cost(width_deg) / (short.len() - 1) as f64;
    let gain = cost(0.0) - cost(width_deg);
    let real = gain > 0.0 && (scatter <= 0.0 || gain / scatter >= super::MIN_T.powi(2));
    // The stops whose output that play left behind by more than the grid's step.
    let inside: Vec<f64> = short
        .iter()
        .zip(&baseline)
        .filter(|(p, _)| real && p.dead_band_excess(width_deg) > WIDTH_STEP_DEG)
        .map(|(p, base)| p.signed_um - base.1)
        .collect();
    let excess_um = if inside.is_empty() {
        0.0
    } else {
        inside.iter().sum::<f64>() / inside.len() as f64
    };
    Some(PlayEvidence {
        short: short.len(),
        long: long.len(),
        width_deg: if real { width_deg } else { 0.0 },
        inside: inside.len(),
        excess_um,
    })
}

/// The evidence sentence for a play of axis `n` from stops after short reversals.
pub fn describe(e: &PlayEvidence, n: u8) -> String {
    if e.inside == 0 {
        return format!(
            "A{n} residual along its motion, signed by the rotation direction, does not depend \
             on the travel since the last reversal ({} stops after reversals shorter than \
             {SHORT_TRAVEL_DEG}°): no dead band of a play shows",
            e.short
        );
    }
    format!(
        "after the {} reversals of A{n} inside the play its residual along the motion, signed \
         by the rotation direction, is {:.0} µm above that after long travel and falls with \
         the travel since the reversal: the output stays put while the command reverses \
         inside a play of about {:.3}°",
        e.inside, e.excess_um, e.width_deg
    )
}

/// The axes whose rotation direction `model` already describes, that a candidate of the
/// direction (`candidates`: `(axes the candidate's direction dependence concerns, found
/// significant)`) was tried on without success, and whose stops in `rows` all come after
/// long travel: there a play and an instant switch of sign cannot be told apart.
pub fn undecided(model: &Model, candidates: &[(Vec<u8>, bool)], rows: &[Row]) -> Vec<u8> {
    let described: Vec<u8> = model
        .effects()
        .iter()
        .flat_map(|e| e.direction_axes())
        .collect();
    let mut out: Vec<u8> = candidates
        .iter()
        .filter(|(_, significant)| !significant)
        .flat_map(|(axes, _)| axes.iter().copied())
        .filter(|a| described.contains(a) && !has_short_reversals(rows, *a))
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// The axes whose rotation direction the candidate `name` describes (none for most).
pub fn candidate_direction_axes(name: &EffectName, model: &Model) -> Vec<u8> {
    name.create(&GridOptions::default(), &model.robot)
        .map(|e| e.direction_axes())
        .unwrap_or_default()
}

/// The verdict's sentence on [`undecided`] axes (empty when there are none).
pub fn undecided_sentence(axes: &[u8]) -> String {
    if axes.is_empty() {
        return String::new();
    }
    let names: Vec<String> = axes.iter().map(|a| format!("A{a}")).collect();
    format!(
        " Whether the rotation-direction dependence of {} is a gear play or an instant switch \
         of sign, these data cannot tell: every stop comes more than {SHORT_TRAVEL_DEG}° after \
         the axis's last reversal, where both predict alike; reversal tests (short moves back \
         and forth, as `robopost simulate campaign --reversal` adds) tell them apart.",
        names.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{Payload, RobotDescription};
    use crate::model::{AxisHistory, AxisState, Slot};
    use nalgebra::Vector3;

    /// A2 engaged upward at −60°, then stops after reversals of `travel` degrees, with the
    /// residual along A2's motion that a play of 0.012° leaves in a model that switches
    /// instantly: `max(0.012 − travel, 0)` degrees; plus long stops without residual.
    fn rows(model: &Model) -> Vec<Row> {
        let play = 0.012;
        let mut out = Vec::new();
        let mut push = |state: AxisState, residual_deg: f64| {
            let p = model.target_position(&state);
            let (frames, _) = model.frames(&state);
            let j = frames.point_partial(Slot::Angle { axis: 2 }, &p);
            out.push(Row {
                test: "A2 reversal".into(),
                source: "s".into(),
                line: 0,
                state,
                measured: p + j * residual_deg.to_radians(),
                predicted: p,
                nominal: p,
            });
        };
        let axes = |a2: f64| [0.0, a2, 100.0, 0.0, 45.0, 0.0];
        for travel in [0.002, 0.005, 0.008, 0.01, 0.02, 0.05] {
            // Up from −70° to −60° (engaged), then down by `travel`.
            let mut state = AxisState::with_directions(axes(-70.0), [Direction::Positive; 6]);
            state.history = [AxisHistory::unmoved(); 6];
            let at = state.then(axes(-60.0));
            push(at, 0.0);
            let back = at.then(axes(-60.0 - travel));
            assert!((back.history[1].travel_since_reversal(-60.0 - travel) - travel).abs() < 1e-9);
            // Signed by the (negative) direction: the residual along the motion is negative.
            push(back, -(play - travel).max(0.0));
        }
        out
    }

    #[test]
    fn the_dead_band_is_read_off_the_short_reversals() {
        let model = Model::new(
            RobotDescription::kr30ha(),
            Payload::default(),
            Vector3::zeros(),
        );
        let rows = rows(&model);
        let e = evidence(&model, &rows, 2).unwrap();
        assert_eq!((e.short, e.long), (6, 6));
        // Exact data: the fitted width is the play's, to the grid's resolution.
        assert!((e.width_deg - 0.012).abs() <= WIDTH_STEP_DEG, "{e:?}");
        // Inside: travels 0.002, 0.005, 0.008, 0.01: excess 0.010, 0.007, 0.004, 0.002°,
        // mean 0.00575° times A2's lever (the target's distance from the A2 axis).
        assert_eq!(e.inside, 4);
        let p = &rows[1];
        let (frames, _) = model.frames(&p.state);
        let lever = frames
            .point_partial(Slot::Angle { axis: 2 }, &p.predicted)
            .norm();
        let expected = 0.00575f64.to_radians() * lever * 1000.0;
        assert!(
            (e.excess_um - expected).abs() < 0.02 * expected,
            "{e:?} vs {expected}"
        );
        assert!(describe(&e, 2).contains("play of about 0.012°"));
        assert!(has_short_reversals(&rows, 2));
        assert!(!has_short_reversals(&rows, 1));
        // A residual that does not fall with the travel is no play.
        let flat: Vec<Row> = rows
            .iter()
            .map(|r| Row {
                measured: r.predicted,
                ..r.clone()
            })
            .collect();
        assert_eq!(evidence(&model, &flat, 2).unwrap().inside, 0);
    }
}
