//! `loadplay:An` — axis n's gear play under load. Where the axis's net torque beats the
//! friction in its train, the torque presses the output onto one flank whatever the direction
//! of motion: the output leads the command by b/2 when the torque pulls the axis in its
//! positive direction, lags by b/2 when it pulls the other way. Only near zero torque (inside
//! the friction band) does the direction of motion choose the flank, as a gear play does
//! (`backlash:An`, evaluated from the axis's [`AxisHistory`](crate::model::AxisHistory)).
//!
//! The net torque is the gravity torque of the bodies beyond the axis and the payload
//! (`compliance::gravity_torques_knm`, kN·m, KUKA sign) less, for A2, a counterbalance spring
//! written as `k_0 + k_c·cos A2 + k_s·sin A2` (kN·m): `τ = τ_g − τ_cb`. The effect writes
//! `dθ_n += sign(τ)·b/2` where `|τ| > τ_f`, else the play's lag.
//!
//! Its values — what a least-squares fit moves — are the width b alone (degrees): the flank a
//! point sits on is a step in the friction and the counterbalance, which have no useful
//! derivative. Those are set from the data when the effect is added
//! ([`Effect::start_from_data`]): at every command angle an indexing test of axis n visits in
//! both directions, the difference between the two measured positions along the test's own
//! motion (read off the neighbouring points, so no model and no frame is needed) is the
//! play's width inside the friction band and zero where the torque holds the flank; the band
//! (friction and counterbalance) that explains those differences best is searched over a
//! grid. They are written to the calibration file beside b.

use nalgebra::Vector3;

use super::compliance::gravity_torques_knm;
use super::{EffectError, ToRecord};
use crate::kinematics::RobotDescription;
use crate::model::effect::{
    AxisSlopes, ChainErrors, Context, Effect, Observed, Parameter, Partial, Slot,
};
use crate::model::history::PlayAt;
use crate::model::history::MAX_PLAY_DEG;
use crate::model::record::{self, EffectRecord, RecordError};
use crate::model::{AxisState, Direction};

/// The axis whose net torque has a counterbalance spring (A2 on a KUKA arm).
pub const BALANCED_AXIS: u8 = 2;
/// The largest friction or counterbalance torque a calibration may hold, kN·m (a robot's
/// gravity torques are a few kN·m).
pub const MAX_TORQUE_KNM: f64 = 100.0;
/// Steps of the counterbalance grid per coordinate (coarse, then as many around the best).
const BALANCE_STEPS: usize = 21;
/// Grids searched, each around the best of the one before and two of its steps wide.
const BALANCE_PASSES: usize = 3;
/// The first grid around the least-squares counterbalance spans ± this share of that span.
const BALANCE_LOCAL: f64 = 0.15;
/// Ridge weight per pair on the counterbalance's angle terms (kN·m² per unit of cos, sin).
const RIDGE: f64 = 0.01;
/// The counterbalance grid's scale: this many times the largest gravity torque seen.
const BALANCE_SPAN: f64 = 1.5;
/// Farthest a neighbour (degrees of axis n) may be to give a test's direction of motion.
const MAX_TANGENT_STEP_DEG: f64 = 10.0;

/// Where a point's flank comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Flank {
    /// The net torque holds the output on the flank of this sign (+1: output ahead).
    Loaded(f64),
    /// Inside the friction band: the play, evaluated from the history.
    Free,
}

/// The gear play of one axis under load (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct LoadPlay {
    pub axis: u8,
    /// The play's width b, degrees (the fitted value).
    pub width_deg: [f64; 1],
    /// The friction threshold τ_f, kN·m (≥ 0).
    pub friction_knm: f64,
    /// The counterbalance `[k_0, k_c, k_s]`, kN·m (A2 only; zero elsewhere).
    pub balance_knm: [f64; 3],
    /// Once started from data ([`Effect::start_from_data`]): how many of the indexing tests'
    /// pairs lie outside the friction band, where the torque and not the direction chooses
    /// the flank. None of them: the data show a plain gear play.
    pub loaded_pairs: Option<usize>,
}

impl LoadPlay {
    /// A play of width zero with no friction band; an error without mass data.
    pub fn zeros(axis: u8, robot: &RobotDescription) -> Result<Self, EffectError> {
        if robot.gravity.is_none() {
            return Err(EffectError::NeedsGravity {
                effect: format!("loadplay:A{axis}"),
            });
        }
        Ok(LoadPlay {
            axis,
            width_deg: [0.0],
            friction_knm: 0.0,
            balance_knm: [0.0; 3],
            loaded_pairs: None,
        })
    }

    /// The record's names, in order: `b`, `friction`, and on A2 `balance_const`,
    /// `balance_cos`, `balance_sin`.
    fn names(axis: u8) -> Vec<String> {
        let mut names = vec!["b".to_string(), "friction".to_string()];
        if axis == BALANCED_AXIS {
            names.extend(["balance_const", "balance_cos", "balance_sin"].map(String::from));
        }
        names
    }

    pub fn from_record(
        axis: u8,
        rec: &EffectRecord,
        robot: &RobotDescription,
    ) -> Result<Self, RecordError> {
        if robot.gravity.is_none() {
            return Err(RecordError::new(
                "name",
                "an effect the robot's data support (loadplay needs robot.description.gravity)",
                format!("loadplay:A{axis}"),
            ));
        }
        let v = rec.named_values(&Self::names(axis))?;
        if !(0.0..=MAX_PLAY_DEG).contains(&v[0]) {
            return Err(RecordError::new(
                "parameters.b",
                format!("a play width in [0, {MAX_PLAY_DEG}]°"),
                v[0].to_string(),
            ));
        }
        if !(0.0..=MAX_TORQUE_KNM).contains(&v[1]) {
            return Err(RecordError::new(
                "parameters.friction",
                format!("a friction torque from 0 to {MAX_TORQUE_KNM} kN·m"),
                v[1].to_string(),
            ));
        }
        for (k, name) in [(2, "balance_const"), (3, "balance_cos"), (4, "balance_sin")] {
            if v.get(k).is_some_and(|x| x.abs() > MAX_TORQUE_KNM) {
                return Err(RecordError::new(
                    format!("parameters.{name}"),
                    format!("a torque from -{MAX_TORQUE_KNM} to {MAX_TORQUE_KNM} kN·m"),
                    v[k].to_string(),
                ));
            }
        }
        Ok(LoadPlay {
            axis,
            width_deg: [v[0]],
            friction_knm: v[1],
            balance_knm: std::array::from_fn(|k| v.get(2 + k).copied().unwrap_or(0.0)),
            loaded_pairs: None,
        })
    }

    /// The counterbalance torque at `axes_deg` (kN·m, KUKA sign).
    fn balance(&self, axes_deg: &[f64; 6]) -> f64 {
        if self.axis != BALANCED_AXIS {
            return 0.0;
        }
        let a = axes_deg[BALANCED_AXIS as usize - 1].to_radians();
        let [k0, kc, ks] = self.balance_knm;
        k0 + kc * a.cos() + ks * a.sin()
    }

    /// The net torque about the axis at `axes_deg`, kN·m; `None` without mass data.
    pub fn net_torque_knm(&self, axes_deg: &[f64; 6], ctx: &Context) -> Option<f64> {
        let g = gravity_torques_knm(ctx.robot, ctx.payload, axes_deg)?;
        Some(g[self.axis as usize - 1] - self.balance(axes_deg))
    }

    fn flank(&self, state: &AxisState, ctx: &Context) -> Flank {
        match self.net_torque_knm(&state.axes_deg, ctx) {
            Some(t) if t.abs() > self.friction_knm => Flank::Loaded(t.signum()),
            _ => Flank::Free,
        }
    }

    fn play(&self, state: &AxisState) -> PlayAt {
        let n = self.axis as usize - 1;
        let b = self.width_deg[0];
        state.history[n].play(state.axes_deg[n], |_| b)
    }

    /// The lag (degrees) and its derivative with respect to b.
    fn lag(&self, state: &AxisState, ctx: &Context) -> (f64, f64) {
        match self.flank(state, ctx) {
            Flank::Loaded(side) => (0.5 * side * self.width_deg[0], 0.5 * side),
            Flank::Free => {
                let p = self.play(state);
                (p.lag_deg, p.edge.map_or(0.0, |(_, side)| 0.5 * side))
            }
        }
    }

    fn slot(&self) -> Slot {
        Slot::Angle { axis: self.axis }
    }

    /// Sets friction, counterbalance and a starting width from the direction differences of
    /// `data`'s indexing tests of this axis (see the module documentation); unchanged when
    /// the data hold no such differences.
    pub fn search(&mut self, data: &[Observed], ctx: &Context) {
        let pairs = direction_differences(self.axis, data);
        self.loaded_pairs = Some(0);
        if pairs.is_empty() {
            return;
        }
        let Some(torques): Option<Vec<f64>> = pairs
            .iter()
            .map(|p| gravity_torques_knm(ctx.robot, ctx.payload, &p.axes_deg))
            .map(|g| g.map(|g| g[self.axis as usize - 1]))
            .collect()
        else {
            return;
        };
        let diffs: Vec<f64> = pairs.iter().map(|p| p.difference_deg).collect();
        let angles: Vec<f64> = pairs
            .iter()
            .map(|p| p.axes_deg[BALANCED_AXIS as usize - 1].to_radians())
            .collect();
        let band = |balance: [f64; 3]| -> Band {
            let net: Vec<f64> = torques
                .iter()
                .zip(&angles)
                .map(|(t, a)| {
                    if self.axis == BALANCED_AXIS {
                        t - balance[0] - balance[1] * a.cos() - balance[2] * a.sin()
                    } else {
                        *t
                    }
                })
                .collect();
            best_band(&net, &diffs)
        };
        let mut best = (band([0.0; 3]), [0.0; 3]);
        if self.axis == BALANCED_AXIS {
            // Inside the band the net torque is near zero: the counterbalance that cancels the
            // gravity torque at the pairs whose difference shows the play (linear least
            // squares), then the best band on grids around it.
            let widest = diffs.iter().fold(0.0, |m: f64, d| m.max(*d));
            let rows: Vec<usize> = (0..diffs.len())
                .filter(|&i| diffs[i] > 0.5 * widest)
                .collect();
            // Ridge on the angle terms: the band's pairs cluster where the torque crosses
            // zero, where a constant, cos A2 and sin A2 are nearly collinear.
            let ridge = RIDGE * rows.len() as f64;
            let mut normal = nalgebra::Matrix3::<f64>::zeros();
            let mut rhs = nalgebra::Vector3::<f64>::zeros();
            for &r in &rows {
                let a = angles[r];
                let x = nalgebra::Vector3::new(1.0, a.cos(), a.sin());
                normal += x * x.transpose();
                rhs += x * torques[r];
            }
            normal[(1, 1)] += ridge;
            normal[(2, 2)] += ridge;
            let start = normal.try_inverse().map_or([0.0; 3], |inv| {
                let x = inv * rhs;
                [x[0], x[1], x[2]]
            });
            let found = band(start);
            if found.sse < best.0.sse {
                best = (found, start);
            }
            let span = BALANCE_SPAN * torques.iter().fold(0.0, |m: f64, t| m.max(t.abs()));
            let mut step = 2.0 * span * BALANCE_LOCAL / (BALANCE_STEPS - 1) as f64;
            let half = (BALANCE_STEPS / 2) as f64;
            let at = |i: usize, centre: f64, step: f64| centre + (i as f64 - half) * step;
            for _ in 0..BALANCE_PASSES {
                let centre = best.1;
                for i in 0..BALANCE_STEPS {
                    for j in 0..BALANCE_STEPS {
                        for k in 0..BALANCE_STEPS {
                            let b = [
                                at(i, centre[0], step),
                                at(j, centre[1], step),
                                at(k, centre[2], step),
                            ];
                            let found = band(b);
                            if found.sse < best.0.sse - 1e-15 {
                                best = (found, b);
                            }
                        }
                    }
                }
                // The next grid spans two of this grid's steps either side of the best.
                step *= 4.0 / (BALANCE_STEPS - 1) as f64;
            }
        }
        let (band, balance) = best;
        self.loaded_pairs = Some(
            torques
                .iter()
                .zip(&angles)
                .filter(|(t, a)| {
                    let net = if self.axis == BALANCED_AXIS {
                        *t - balance[0] - balance[1] * a.cos() - balance[2] * a.sin()
                    } else {
                        **t
                    };
                    net.abs() > band.friction_knm
                })
                .count(),
        );
        self.friction_knm = band.friction_knm;
        self.balance_knm = if self.axis == BALANCED_AXIS {
            balance
        } else {
            [0.0; 3]
        };
        self.width_deg = [band.width_deg.clamp(0.0, MAX_PLAY_DEG)];
    }
}

/// A command angle an indexing test of the axis visits in both directions.
#[derive(Clone, Debug, PartialEq)]
struct PairDifference {
    axes_deg: [f64; 6],
    /// Output arriving in the negative direction minus output arriving in the positive one,
    /// degrees of the axis: the play's width where the direction chooses the flank.
    difference_deg: f64,
}

/// The direction differences of axis `axis` in `data` (see [`LoadPlay::search`]).
fn direction_differences(axis: u8, data: &[Observed]) -> Vec<PairDifference> {
    let n = axis as usize - 1;
    let same_others =
        |a: &[f64; 6], b: &[f64; 6]| (0..6).all(|k| k == n || (a[k] - b[k]).abs() < 1e-9);
    let mut tests: std::collections::BTreeMap<usize, Vec<(Direction, &Observed)>> =
        Default::default();
    for o in data {
        let d = o.state.history[n].direction(o.state.axes_deg[n]);
        tests.entry(o.test).or_default().push((d, o));
    }
    let mut out = Vec::new();
    for points in tests.values() {
        for (i, &(d, neg)) in points.iter().enumerate() {
            if d != Direction::Negative {
                continue;
            }
            let a = &neg.state.axes_deg;
            let partner = points.iter().find(|(d, p)| {
                *d == Direction::Positive
                    && (p.state.axes_deg[n] - a[n]).abs() < 1e-9
                    && same_others(&p.state.axes_deg, a)
            });
            let Some((_, pos)) = partner else {
                continue;
            };
            // The test's motion at this angle: the nearest point of the same direction.
            let neighbour = points
                .iter()
                .enumerate()
                .filter(|(j, (d, p))| {
                    *j != i && *d == Direction::Negative && same_others(&p.state.axes_deg, a)
                })
                .map(|(_, (_, p))| (p.state.axes_deg[n] - a[n], p.measured_mm))
                .filter(|(step, _)| step.abs() > 1e-9 && step.abs() <= MAX_TANGENT_STEP_DEG)
                .min_by(|x, y| x.0.abs().total_cmp(&y.0.abs()));
            let Some((step, at)) = neighbour else {
                continue;
            };
            let tangent: Vector3<f64> = (at - neg.measured_mm) / step;
            let t2 = tangent.norm_squared();
            if t2 == 0.0 {
                continue;
            }
            out.push(PairDifference {
                axes_deg: *a,
                difference_deg: (neg.measured_mm - pos.measured_mm).dot(&tangent) / t2,
            });
        }
    }
    out
}

/// The friction band that explains direction differences best.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Band {
    friction_knm: f64,
    width_deg: f64,
    /// Sum of squared misfits of the differences, degrees².
    sse: f64,
}

/// The friction `τ_f` (and width b, the band's mean difference) minimising
/// `Σ (d_i − b·[|τ_i| < τ_f])²` over the net torques `net` and differences `diffs`: thresholds
/// half-way between sorted |τ|, and none (every point loaded).
fn best_band(net: &[f64], diffs: &[f64]) -> Band {
    let mut order: Vec<(f64, f64)> = net
        .iter()
        .map(|t| t.abs())
        .zip(diffs.iter().copied())
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = diffs.iter().map(|d| d * d).sum();
    let mut best = Band {
        friction_knm: 0.0,
        width_deg: 0.0,
        sse: total,
    };
    let mut sum = 0.0;
    for (k, &(t, d)) in order.iter().enumerate() {
        sum += d;
        let count = (k + 1) as f64;
        let sse = total - sum * sum / count;
        let next = order.get(k + 1).map_or(2.0 * t + 1e-6, |o| o.0);
        if sum > 0.0 && sse < best.sse - 1e-15 && next > t {
            best = Band {
                friction_knm: 0.5 * (t + next),
                width_deg: sum / count,
                sse,
            };
        }
    }
    best
}

impl Effect for LoadPlay {
    fn name(&self) -> String {
        format!("loadplay:A{}", self.axis)
    }
    fn parameters(&self) -> Vec<Parameter> {
        vec![Parameter {
            name: self.name(),
            unit: "deg",
        }]
    }
    fn values(&self) -> &[f64] {
        &self.width_deg
    }
    fn values_mut(&mut self) -> &mut [f64] {
        &mut self.width_deg
    }
    fn add_to(&self, state: &AxisState, ctx: &Context, errors: &mut ChainErrors) {
        errors.add(self.slot(), self.lag(state, ctx).0.to_radians());
    }
    /// Loaded, the output sits on one flank (no slope); inside the band, as `backlash`: an
    /// engaged gear follows the command, a command inside the play leaves the output still.
    fn add_with_axis_slopes(
        &self,
        state: &AxisState,
        ctx: &Context,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        let n = self.axis as usize - 1;
        let (slope, lag) = match self.flank(state, ctx) {
            Flank::Loaded(side) => (0.0, 0.5 * side * self.width_deg[0]),
            Flank::Free => {
                let p = self.play(state);
                let slope = if p.engaged || state.history[n].is_simple() {
                    0.0
                } else {
                    -1.0
                };
                (slope, p.lag_deg)
            }
        };
        errors.add(self.slot(), lag.to_radians());
        slopes.add(self.slot(), n, f64::to_radians(slope));
    }
    fn jacobian(&self, state: &AxisState, ctx: &Context, out: &mut Vec<Partial>) {
        let (_, d) = self.lag(state, ctx);
        if d != 0.0 {
            out.push(Partial {
                param: 0,
                slot: self.slot(),
                value: d.to_radians(),
            });
        }
    }
    fn adds_angles_only(&self) -> bool {
        true
    }
    fn add_angles(&self, state: &AxisState, ctx: &Context, angles: &mut [f64; 6]) {
        angles[self.axis as usize - 1] += self.lag(state, ctx).0.to_radians();
    }
    /// A negative width is no play: set to zero.
    fn make_physical(&mut self, _standard_errors: &[Option<f64>]) -> Vec<String> {
        let b = self.width_deg[0];
        if b < 0.0 {
            self.width_deg[0] = 0.0;
            return vec![format!(
                "{}: the identified play width is negative ({b:.4}°), which no gear play has; set to zero",
                self.name()
            )];
        }
        Vec::new()
    }
    fn direction_axes(&self) -> Vec<u8> {
        vec![self.axis]
    }
    fn start_from_data(&mut self, data: &[Observed], ctx: &Context) {
        self.search(data, ctx);
    }
    fn not_shown_by_data(&self) -> Option<String> {
        (self.loaded_pairs == Some(0)).then(|| {
            format!(
                "no pair of the A{n} indexing tests lies where the torque beats the friction: the \
                 data show a plain gear play (backlash:A{n})",
                n = self.axis
            )
        })
    }
}

impl ToRecord for LoadPlay {
    fn record(&self) -> EffectRecord {
        let mut values = vec![self.width_deg[0], self.friction_knm];
        if self.axis == BALANCED_AXIS {
            values.extend(self.balance_knm);
        }
        EffectRecord {
            name: self.name(),
            parameters: Some(record::named_map(&Self::names(self.axis), &values)),
            table: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn best_band_by_hand() {
        // Differences 0.02° at |τ| 0.1 and 0.2, zero at 0.5 and 0.9: the band ends between
        // 0.2 and 0.5 (at 0.35), width 0.02°, no misfit.
        let net = [0.9, -0.1, 0.5, 0.2];
        let diffs = [0.0, 0.02, 0.0, 0.02];
        let b = best_band(&net, &diffs);
        assert!((b.friction_knm - 0.35).abs() < 1e-12, "{b:?}");
        assert!((b.width_deg - 0.02).abs() < 1e-12);
        assert!(b.sse.abs() < 1e-15);
        // No difference anywhere: no band.
        let b = best_band(&net, &[0.0; 4]);
        assert_eq!(b.width_deg, 0.0);
    }
}
