//! The turning points of the compensated motion into a target: the nominal motion's, moved by
//! the corrections interpolated to them, or — where an axis moves by a few plays or less, so
//! that the way the correction bends along the motion decides whether and where it turns
//! round — the motion walked as the controller interpolates it between the compensated
//! commands ([`crate::motion::interpolate`]). A target's turns are kept while it is settled
//! ([`super::recheck::TurnsKept`]): nothing they read changes within one settling.

use super::recheck::{Recheck, TurnsKept};
use super::{Ctx, Interp, Outcome, Target};
use crate::kinematics::AxisAngles;
use crate::model::AxisState;
use crate::motion::interpolate;
use crate::motion::nominal::{Arm, Nominal};

/// A motion that moves an axis by less than this many of its play's widths (degrees, plus
/// 0.001°) may turn it round by an amount that matters to the play.
pub(super) const SENSITIVE_PLAYS: f64 = 4.0;
/// A correction changing along a motion by more than this share of the nominal move may turn
/// the axis round inside it (the nominal rate along a short motion varies far less).
pub(super) const CORRECTION_SHARE: f64 = 10.0;

/// The turning points of the compensated motion into target `k` (from `previous`, commanded
/// at `c`, where the plays' widths are `widths`). The compensated motion is the nominal one moved by the corrections; where an axis
/// moves little, the way the correction bends along the motion decides whether and where it
/// turns round, so the motion is walked as the controller interpolates it between the
/// compensated commands (samples, exact rates at the ends). Elsewhere — and where the path
/// cannot be built — the nominal turns, moved by the corrections interpolated to them.
pub(super) fn compensated_turns(
    ctx: &Recheck,
    k: usize,
    previous: &AxisState,
    (c, widths): (&[f64; 6], &[f64; 6]),
    outcomes: &[Outcome],
) -> interpolate::Turns {
    let bits = |a: &[f64; 6]| a.map(f64::to_bits);
    let (from, command, width_bits) = (bits(&previous.axes_deg), bits(c), bits(widths));
    if let Some(kept) = ctx.turns.get() {
        if kept.k == k && kept.from == from && kept.command == command && kept.widths == width_bits
        {
            return kept.turns;
        }
    }
    let turns = compensated_turns_walked(ctx, k, previous, (c, widths), outcomes);
    ctx.turns.set(Some(TurnsKept {
        k,
        from,
        command,
        widths: width_bits,
        turns,
    }));
    turns
}

/// [`compensated_turns`], worked out.
pub(super) fn compensated_turns_walked(
    ctx: &Recheck,
    k: usize,
    previous: &AxisState,
    (c, widths): (&[f64; 6], &[f64; 6]),
    outcomes: &[Outcome],
) -> interpolate::Turns {
    let target = ctx.target(k);
    let prev = previous.axes_deg;
    // An axis can turn round inside the compensated motion where the nominal one does, or
    // where the correction changes along the motion by a fair part of the nominal move (a
    // resting axis, a slow one): only there does the walk decide anything.
    let nominal_prev = (k > 0).then(|| &ctx.target(k - 1).nominal_axes);
    let sensitive = (0..6).any(|n| {
        let b = widths[n];
        if !(b > 0.0 && (c[n] - prev[n]).abs() < SENSITIVE_PLAYS * b + 1e-3) {
            return false;
        }
        let Some(np) = nominal_prev else { return true };
        let nominal_move = target.nominal_axes[n] - np[n];
        let correction_change = (c[n] - target.nominal_axes[n]) - (prev[n] - np[n]);
        target.turns.angle_deg[n].is_finite()
            || correction_change.abs() * CORRECTION_SHARE > nominal_move.abs()
    });
    if sensitive && k > 0 {
        if let Some(turns) = walk_compensated(ctx, k, c, outcomes) {
            return turns;
        }
    }
    let mut turns = target.turns;
    for n in 0..6 {
        turns.angle_deg[n] = nominal_turn_moved(target, nominal_prev, prev[n], n, c[n]);
    }
    turns
}

/// Axis n's last nominal turning point inside the motion into `target` (NaN: none), moved by
/// the corrections interpolated to it: the command before at `c0` (the nominal one
/// `nominal_prev`, none for the first target), the target's at `c`.
pub(super) fn nominal_turn_moved(
    target: &Target,
    nominal_prev: Option<&AxisAngles>,
    c0: f64,
    n: usize,
    c: f64,
) -> f64 {
    let (t, u) = (target.turns.angle_deg[n], target.turns.at[n]);
    let (turn, at) = match nominal_prev.filter(|_| t.is_finite()) {
        Some(np) => {
            let before = c0 - np[n];
            (t + (1.0 - u) * before - u * target.nominal_axes[n], u)
        }
        None => (f64::NAN, 0.0),
    };
    turn + at * c
}

/// The compensated motion into target `k` walked as the controller interpolates it (the
/// targets before at their commands in `outcomes`, target k at `c`, the one after — the end of
/// a circle whose auxiliary point k is — at its first-pass command): its turning points after
/// the stop before; `None` for a PTP motion (linear in the axes: none) or a path that cannot
/// be followed.
pub(super) fn walk_compensated(
    ctx: &Ctx,
    k: usize,
    c: &[f64; 6],
    outcomes: &[Outcome],
) -> Option<interpolate::Turns> {
    use interpolate::{course, Course};
    let target = ctx.target(k);
    let robot = &ctx.model.robot;
    let tool = ctx.tool(k);
    let cmd = |j: usize| if j == k { *c } else { *outcomes[j].axes_deg };
    let tcp = |j: usize| Nominal(robot).tcp(&cmd(j), ctx.tool(j));
    // The path, where it starts (its command) and the share of it before the stop before.
    let (path, from, before) = match target.interp {
        Interp::Joint | Interp::CircAngleAux => return None,
        Interp::Line => (course(&tcp(k - 1), &tcp(k), Course::Line)?, k - 1, 0.0),
        Interp::Curve { first, last } => {
            let mut points = Vec::with_capacity(4);
            if !first && k >= 2 {
                points.push(tcp(k - 2).position);
            }
            let (a, b) = (tcp(k - 1), tcp(k));
            points.push(a.position);
            points.push(b.position);
            if !last && k + 1 < ctx.len() {
                // The next point moved by this one's correction (it is not settled yet).
                let shift = b.position - target.goal.position;
                points.push(ctx.target(k + 1).goal.position + shift);
            }
            let curve = course(&a, &b, Course::Spline { points: &points })?;
            (curve, k - 1, 0.0)
        }
        Interp::CircEnd if k >= 2 => {
            let (start, aux, end) = (tcp(k - 2), tcp(k - 1).position, tcp(k));
            let arc = course(&start, &end, Course::Circle { aux })?;
            let u_aux = arc.fraction_at(&aux);
            (arc, k - 2, u_aux)
        }
        // The auxiliary point of a circle written by construction is not on the path.
        Interp::CircAngle(a) if k >= 2 => {
            let (start, aux, end) = (tcp(k - 2), tcp(k - 1).position, tcp(k));
            let by_angle = Course::CircleByAngle {
                angle_deg: a.degrees(),
                plane: a.plane(aux),
            };
            (course(&start, &end, by_angle)?, k - 2, 0.0)
        }
        Interp::CircAux if k + 1 < ctx.len() => {
            let (start, aux, end) = (tcp(k - 1), tcp(k).position, tcp(k + 1));
            let arc = course(&start, &end, Course::Circle { aux })?;
            let u_aux = arc.fraction_at(&aux);
            let (arrival, _) =
                interpolate::arrival_and_end(robot, tool, &arc, u_aux, (&cmd(k - 1), None), c)
                    .ok()?;
            return Some(arrival.turns);
        }
        _ => return None,
    };
    let (arrival, _) =
        interpolate::arrival_and_end(robot, tool, &path, 1.0, (&cmd(from), None), c).ok()?;
    // Only the turns after the stop before count (the ones before it are in its history).
    Some(arrival.turns.after(before))
}
