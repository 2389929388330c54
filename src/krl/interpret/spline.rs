//! Spline blocks: once a CP `SPLINE … ENDSPLINE` block has been walked (every stop recorded
//! as for a LIN, CIRC or PTP), each `SPL` segment in it is replaced by the block's curve
//! ([`crate::motion::spline`]) and its stop's arrival is taken along that curve after the
//! walk (`finish`), in parallel. `SLIN`/`SCIRC` segments keep their line and arc, but the
//! spline's tangent at a point where they meet an `SPL` segment uses their end points as
//! neighbours. `PTP_SPLINE` blocks (`SPTP`) are axis-space motions and need nothing here.

use nalgebra::Vector3;

use super::*;
use crate::krl::MotionKind;
use crate::motion::spline;

/// An `SPL` segment: the stop it reaches and the curve's tangents (per unit chord length) at
/// its start and its end.
pub(super) struct SplineSegment {
    stop: u32,
    t0: Vector3<f64>,
    t1: Vector3<f64>,
}

impl Simulator<'_> {
    /// The stops from `first` on were recorded by a CP spline block: split them into chains of
    /// consecutive stops (each starting where the one before ended, with the same tool), each
    /// chain preceded by the point the robot left from, and record the curve of every `SPL`
    /// segment.
    pub(super) fn spline_block(&mut self, first: usize) {
        let end = self.out.stops.len();
        let mut k = first;
        while k < end {
            let tool = self.out.stops[k].tool;
            let mut j = k + 1;
            while j < end
                && self.out.stops[j].prev == Some(j as u32 - 1)
                && self.out.stops[j].tool == tool
            {
                j += 1;
            }
            let tool_frame = self.out.frames[tool as usize];
            let mut points = Vec::with_capacity(j - k + 1);
            let offset = match self.out.stops[k].prev {
                // The point it starts from, when that is the stop just before (always, unless
                // the position was lost in between).
                Some(p) if p as usize + 1 == k => {
                    let axes = self.out.stops[p as usize].nominal_axes;
                    points.push(Nominal(&self.robot).tcp(&axes, &tool_frame).position);
                    1
                }
                _ => 0,
            };
            points.extend(self.out.stops[k..j].iter().map(|s| s.goal.position));
            let t = spline::tangents(&points);
            let n = points.len();
            for i in k..j {
                let at = i - k + offset;
                let stop = &mut self.out.stops[i];
                if stop.handle.kind != MotionKind::Spl || stop.role != Role::Target || at == 0 {
                    continue;
                }
                stop.deferred = false;
                stop.spline = Some(SplineEnds {
                    first: at == 1,
                    last: at == n - 1,
                });
                self.splines.push(SplineSegment {
                    stop: i as u32,
                    t0: t[at - 1],
                    t1: t[at],
                });
            }
            k = j;
        }
    }
}

/// The arrival rates of the `SPL` stops along their curves, in parallel. Where the curve
/// cannot be followed (it passes a singularity the chord avoids), the straight segment's
/// arrival stands, or the axis steps where that fails too.
pub(super) fn finish_splines(
    sim: &mut Simulation,
    robot: &RobotDescription,
    splines: &[SplineSegment],
) {
    use rayon::prelude::*;
    let arrivals: Vec<([f64; 6], interpolate::Turns)> = splines
        .par_iter()
        .with_min_len(256)
        .map(|seg| {
            let stop = &sim.stops[seg.stop as usize];
            let prev = &sim.stops[stop.prev.expect("a spline segment has a start") as usize];
            let tool = &sim.frames[stop.tool as usize];
            let start = Nominal(robot).tcp(&prev.nominal_axes, tool);
            let (q0, q1) = (&prev.nominal_axes, &stop.nominal_axes);
            let curve = Cartesian::cubic(&start, &stop.goal, &seg.t0, &seg.t1);
            let along = |cart: &Cartesian| {
                interpolate::arrival_along(robot, tool, cart, 1.0, q0, q1)
                    .map(|a| (a.rate, a.turns))
            };
            along(&curve)
                .ok()
                .or(stop.arrival.map(|r| (r, stop.turns)))
                .or_else(|| {
                    let line = Cartesian::new(&start, &stop.goal, &Path::Lin).ok()?;
                    along(&line).ok()
                })
                .unwrap_or_else(|| {
                    let steps = std::array::from_fn(|i| q1[i] - q0[i]);
                    (steps, interpolate::NO_TURNS)
                })
        })
        .collect();
    for (seg, (rate, turns)) in splines.iter().zip(arrivals) {
        let stop = &mut sim.stops[seg.stop as usize];
        stop.arrival = Some(rate);
        stop.turns = turns;
    }
}
