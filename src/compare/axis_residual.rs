//! A residual seen from one axis: in an indexing test only axis n moves, so a missing
//! angular positioning deviation of n shows as residual along the target's circle about n.
//! Projecting the residual on the motion a unit rotation of n gives the target,
//! `Δθ = r·j / |j|²` with `j = ω_n × (p − o_n)` (the chain's slot Jacobian), turns it into
//! the angle the model is missing, in the units of the paper's Figs. 4, 5 and 7.

use crate::model::{Model, Slot};

use super::Row;

/// Arc seconds per radian.
pub const ARCSEC_PER_RAD: f64 = 180.0 * 3600.0 / std::f64::consts::PI;

/// The axis an indexing test sweeps: the only axis whose command angle changes over `rows`
/// (by more than 0.5°); `None` for a path on which several axes move, or none.
pub fn indexed_axis<'a>(rows: impl IntoIterator<Item = &'a Row>) -> Option<u8> {
    let mut lo = [f64::INFINITY; 6];
    let mut hi = [f64::NEG_INFINITY; 6];
    for r in rows {
        for k in 0..6 {
            lo[k] = lo[k].min(r.state.axes_deg[k]);
            hi[k] = hi[k].max(r.state.axes_deg[k]);
        }
    }
    let moving: Vec<usize> = (0..6).filter(|&k| hi[k] - lo[k] > 0.5).collect();
    let still = (0..6).all(|k| moving.contains(&k) || hi[k] - lo[k] < 1e-6);
    match (moving.as_slice(), still) {
        ([k], true) => Some(*k as u8 + 1),
        _ => None,
    }
}

/// The residual of `row` as an angular deviation of `axis` (arc seconds, KUKA sign), or
/// `None` when a rotation of that axis barely moves the target (under 1 mm per radian).
pub fn angular_residual(model: &Model, row: &Row, axis: u8) -> Option<f64> {
    let (frames, _) = model.frames(&row.state);
    let j = frames.point_partial(Slot::Angle { axis }, &row.predicted);
    let j2 = j.norm_squared();
    (j2 > 1.0).then(|| row.residual().dot(&j) / j2 * ARCSEC_PER_RAD)
}

/// The part of the residual perpendicular to that motion, µm (what an angle cannot explain).
pub fn off_motion_residual_um(model: &Model, row: &Row, axis: u8) -> f64 {
    let (frames, _) = model.frames(&row.state);
    let j = frames.point_partial(Slot::Angle { axis }, &row.predicted);
    let r = row.residual();
    let along = if j.norm_squared() > 1e-12 {
        j * (r.dot(&j) / j.norm_squared())
    } else {
        nalgebra::Vector3::zeros()
    };
    (r - along).norm() * 1000.0
}

/// The residual along the motion of `axis` signed by its rotation direction on arrival, as
/// (µm, degrees of the axis): positive where the output is ahead of the model in the
/// direction of travel (a gear play's output that stayed put after a short reversal is
/// ahead). `None` when the direction is unknown or the axis barely moves the target.
pub fn signed_by_direction(model: &Model, row: &Row, axis: u8) -> Option<(f64, f64)> {
    let sign = row.state.directions()[axis as usize - 1].sign();
    if sign == 0.0 {
        return None;
    }
    let (frames, _) = model.frames(&row.state);
    let j = frames.point_partial(Slot::Angle { axis }, &row.predicted);
    let j2 = j.norm_squared();
    (j2 > 1.0).then(|| {
        let along = row.residual().dot(&j);
        (
            sign * along / j2.sqrt() * 1000.0,
            (sign * along / j2).to_degrees(),
        )
    })
}
