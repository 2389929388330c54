//! The command trajectory the physical robot runs: axis command angles sampled along the
//! motion in time order, each sample a point the axes pass through, a stop the robot visits
//! without a measurement, or a measured stop. Campaign and pose stops are joined by PTP
//! motion, which is linear in axis space, so sampling it is exact; program runs are sampled
//! here the same way between their targets, with each axis's turning point inside a
//! LIN/CIRC/SPL segment (from the walker) as a sample of its own.

use super::super::campaign::PlannedStop;
use super::super::program::ProgramVisit;

/// What happens at a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleKind {
    /// The axes pass through here (no row in the measurement file).
    Pass,
    /// The robot stops (or passes an auxiliary point) and the file gets a row, unmeasured.
    Visit,
    /// The robot stops and the tracker measures: a row with a position.
    Measure,
}

/// One sample of the command trajectory.
#[derive(Clone, Debug, PartialEq)]
pub struct CommandSample {
    /// Command angles A1..A6, degrees (KUKA).
    pub axes_deg: [f64; 6],
    /// Seconds since the start of the campaign.
    pub time_s: f64,
    pub kind: SampleKind,
    /// Test label of the row (unused on `Pass`).
    pub test: String,
    /// Source line of the motion (programs; 0 otherwise), for error messages.
    pub line: u32,
}

/// The largest axis step between samples of a PTP motion, degrees.
pub const PTP_STEP_DEG: f64 = 1.0;

/// Samples of `stops` joined by PTP motion (linear in axis space, synchronous), at most
/// `step_deg` of the farthest-moving axis apart; time linear between the stops' times.
pub fn from_stops(stops: &[PlannedStop], step_deg: f64) -> Vec<CommandSample> {
    let kinds = stops.iter().map(|s| {
        if s.measured {
            SampleKind::Measure
        } else {
            SampleKind::Visit
        }
    });
    linear(stops.iter().zip(kinds).map(|(s, k)| (s, k, 0)), step_deg)
}

/// Samples of a program run: its visits joined by motion linear in axis space (see the module
/// documentation), auxiliary points as unmeasured rows, each sample carrying its motion's line.
/// Where an axis turns round inside an interpolated motion, the turning point is a passed
/// sample (the other axes halfway), so the gear plays see the reversal; a `CA` circle's
/// auxiliary point, passed by rather than visited, is a passed sample too.
pub fn from_program(visits: &[ProgramVisit], step_deg: f64) -> Vec<CommandSample> {
    let mut planned: Vec<(PlannedStop, SampleKind, u32)> = Vec::with_capacity(visits.len());
    let mut from: Option<[f64; 6]> = None;
    for v in visits {
        if let (Some(from), false) = (from, v.from_unknown) {
            if v.turns.iter().any(|t| t.is_finite()) {
                let turn = PlannedStop {
                    axes_deg: std::array::from_fn(|n| {
                        if v.turns[n].is_finite() {
                            v.turns[n]
                        } else {
                            0.5 * (from[n] + v.stop.axes_deg[n])
                        }
                    }),
                    measured: false,
                    test: String::new(),
                    time_s: v.stop.time_s,
                };
                planned.push((turn, SampleKind::Pass, v.line));
            }
        }
        let kind = if v.passed_by {
            SampleKind::Pass
        } else if v.stop.measured {
            SampleKind::Measure
        } else {
            SampleKind::Visit
        };
        planned.push((v.stop.clone(), kind, v.line));
        if !v.passed_by {
            from = Some(v.stop.axes_deg);
        }
    }
    linear(planned.iter().map(|(s, k, l)| (s, *k, *l)), step_deg)
}

fn linear<'a>(
    stops: impl Iterator<Item = (&'a PlannedStop, SampleKind, u32)>,
    step_deg: f64,
) -> Vec<CommandSample> {
    let mut out: Vec<CommandSample> = Vec::new();
    let mut previous: Option<(&PlannedStop, u32)> = None;
    for (stop, kind, line) in stops {
        if let Some((from, _)) = previous {
            let travel = (0..6)
                .map(|k| (stop.axes_deg[k] - from.axes_deg[k]).abs())
                .fold(0.0, f64::max);
            let steps = (travel / step_deg).ceil() as usize;
            for i in 1..steps {
                let f = i as f64 / steps as f64;
                out.push(CommandSample {
                    axes_deg: std::array::from_fn(|k| {
                        from.axes_deg[k] + f * (stop.axes_deg[k] - from.axes_deg[k])
                    }),
                    time_s: from.time_s + f * (stop.time_s - from.time_s),
                    kind: SampleKind::Pass,
                    test: String::new(),
                    line,
                });
            }
        }
        out.push(CommandSample {
            axes_deg: stop.axes_deg,
            time_s: stop.time_s,
            kind,
            test: stop.test.clone(),
            line,
        });
        previous = Some((stop, line));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ptp_is_sampled_linearly_between_stops() {
        let stop = |a1: f64, t: f64, measured: bool| PlannedStop {
            test: "t".into(),
            axes_deg: [a1, -90.0, 90.0, 0.0, 0.0, 0.0],
            measured,
            time_s: t,
        };
        let s = from_stops(&[stop(0.0, 0.0, false), stop(2.5, 10.0, true)], 1.0);
        let a1: Vec<f64> = s.iter().map(|x| x.axes_deg[0]).collect();
        for (a, b) in a1.iter().zip([0.0, 2.5 / 3.0, 5.0 / 3.0, 2.5]) {
            assert!((a - b).abs() < 1e-12, "{a1:?}");
        }
        assert_eq!(a1.len(), 4);
        assert_eq!(s[0].kind, SampleKind::Visit);
        assert_eq!(s[1].kind, SampleKind::Pass);
        assert_eq!(s[3].kind, SampleKind::Measure);
        assert!((s[2].time_s - 20.0 / 3.0).abs() < 1e-12);
    }
}
