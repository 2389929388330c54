//! A gear play inverted: one axis's motion into a target ([`Segment`]: the output where it
//! starts, the turning point moved with the command, half the play's width) gives an output on
//! arrival that is monotone and piecewise linear in the command, so the command that puts the
//! output where the pose needs it is found between its breakpoints, without bisection, and
//! with it how the command reaches it ([`Reach`]: driving a flank, or inside the play).

use super::recheck::Recheck;
use super::Target;
use crate::model::{AxisState, Direction};
use crate::motion::interpolate;

/// One axis's motion into target `k`, compensated: from the command before (where the play's
/// output stood), through the motion's last turning point if it has one — the nominal turn
/// moved by the corrections interpolated to it, so it moves with the command — to the
/// command. The play's output on arrival is monotone in the command; [`Segment::command_for`]
/// inverts it.
pub(super) struct Segment {
    /// The play's output where the motion begins.
    pub(super) start_output: f64,
    /// The turning point at command `c`: `turn + at·c` (NaN: none).
    pub(super) turn: f64,
    pub(super) at: f64,
    /// Half the play's width.
    pub(super) half: f64,
}

impl Segment {
    /// Axis n's motion into `target` from `previous`, with `turns` those of the compensated
    /// motion commanded at `c` ([`compensated_turns`]).
    pub(super) fn of(
        ctx: &Recheck,
        target: &Target,
        previous: &AxisState,
        n: usize,
        (turns, c): (&interpolate::Turns, &[f64; 6]),
    ) -> Segment {
        let c0 = previous.axes_deg[n];
        let (t, u) = (turns.angle_deg[n], turns.at[n]);
        // The turn moves with the command by the share of the correction interpolated to it.
        let (turn, at) = if t.is_finite() {
            (t - u * c[n], u)
        } else {
            (f64::NAN, 0.0)
        };
        Segment {
            start_output: c0 + ctx.play_lag(previous, n),
            turn,
            at,
            half: 0.5 * ctx.play_width(n, target.nominal_axes[n]),
        }
    }

    /// The turning point when the command is `c` (NaN: none).
    #[inline]
    fn turn(&self, c: f64) -> f64 {
        self.turn + self.at * c
    }

    /// The play's output on arrival at command `c`.
    #[inline]
    pub(super) fn output(&self, c: f64) -> f64 {
        let clamp = |o: f64, x: f64| o.clamp(x - self.half, x + self.half);
        let t = self.turn(c);
        let o = if t.is_finite() {
            clamp(self.start_output, t)
        } else {
            self.start_output
        };
        clamp(o, c)
    }

    /// The output `(command, output)` at `lo`, `hi` and its breakpoints between them (where
    /// the turn's clamp or the arrival's clamp starts or stops acting), in order of the
    /// command, into `points`; returns how many there are. The output is linear between them.
    #[inline]
    fn breakpoints(&self, lo: f64, hi: f64, points: &mut [(f64, f64); 14]) -> usize {
        let (s, h, t0, a) = (self.start_output, self.half, self.turn, self.at);
        let mut xs = [0.0; 12];
        let mut n = 0;
        let mut add = |x: f64| {
            if x.is_finite() && x > lo && x < hi {
                xs[n] = x;
                n += 1;
            }
        };
        add(s - h);
        add(s + h);
        if t0.is_finite() {
            if a > 0.0 {
                add((s + h - t0) / a);
                add((s - h - t0) / a);
            }
            if a < 1.0 {
                for k in [-h, h] {
                    for m in [-h, h] {
                        add((t0 + k - m) / (1.0 - a));
                    }
                }
            }
        }
        points[0] = (lo, self.output(lo));
        for (i, &x) in xs[..n].iter().enumerate() {
            points[i + 1] = (x, 0.0);
        }
        points[n + 1] = (hi, 0.0);
        points[..n + 2].sort_by(|p, q| p.0.total_cmp(&q.0));
        for p in points[..n + 2].iter_mut() {
            p.1 = self.output(p.0);
        }
        n + 2
    }

    /// The flank [`Self::command_for`] finds driven, when it is certain without the search
    /// (`None`: search). On a motion without a turning point whose wanted output lies clearly
    /// above where the output starts, every command that reaches it lies past the band's
    /// upper edge `start_output + half`, where the output is the command less half the play:
    /// the positive flank; clearly below, the negative one. "Clearly" is by far more than the
    /// rounding of the breakpoints (a few ulps) and the search's tolerance, and the bracket
    /// is then found well within its 360° limit. Most moving axes of a path are settled here.
    pub(super) fn sure_flank(&self, wanted: f64, near: f64) -> Option<Direction> {
        const CLEAR_DEG: f64 = 1e-9;
        let (s, h) = (self.start_output, self.half);
        let certain = !self.turn.is_finite()
            && (1e-6..1.0).contains(&h)
            && s.is_finite()
            && (wanted - near).abs() < 90.0;
        if !certain {
            None
        } else if wanted > s + CLEAR_DEG {
            Some(Direction::Positive)
        } else if wanted < s - CLEAR_DEG {
            Some(Direction::Negative)
        } else {
            None
        }
    }

    /// The command whose arrival puts the play's output at `wanted`, nearest `near` where a
    /// range of commands does (inside the play), and how it does it.
    pub(super) fn command_for(&self, wanted: f64, near: f64) -> (f64, Reach) {
        // The output is monotone and piecewise linear in the command (slopes 0, `at` or 1):
        // bracket, then find the first and last command that reach it by interpolating
        // between its breakpoints (no bisection).
        let tol = 1e-12;
        let mut span = 4.0 * self.half + 1e-3;
        let (mut lo, mut hi) = (near - span, near + span);
        while self.output(lo) > wanted - tol || self.output(hi) < wanted + tol {
            span *= 2.0;
            (lo, hi) = (near - span, near + span);
            if span > 360.0 {
                return (near, Reach::Stuck);
            }
        }
        let mut points = [(0.0, 0.0); 14];
        let n = self.breakpoints(lo, hi, &mut points);
        let points = &points[..n];
        let cross = |(x0, y0): (f64, f64), (x1, y1): (f64, f64), y: f64| {
            if y1 > y0 {
                (x0 + (y - y0) * (x1 - x0) / (y1 - y0)).clamp(x0, x1)
            } else {
                x1
            }
        };
        // The first command whose output reaches `wanted` and the last that does not pass it.
        let i = points
            .iter()
            .position(|p| p.1 >= wanted - tol)
            .unwrap_or(points.len() - 1)
            .max(1);
        let first = cross(points[i - 1], points[i], wanted - tol);
        let j = points
            .iter()
            .rposition(|p| p.1 <= wanted + tol)
            .unwrap_or(0)
            .min(points.len() - 2);
        let last = cross(points[j], points[j + 1], wanted + tol);
        let c = near.clamp(first, last);
        let o = self.output(c);
        let reach = if (o - (c - self.half)).abs() <= 1e-9 && self.half > 0.0 {
            Reach::Flank(Direction::Positive)
        } else if (o - (c + self.half)).abs() <= 1e-9 && self.half > 0.0 {
            Reach::Flank(Direction::Negative)
        } else {
            Reach::Stuck
        };
        (c, reach)
    }
}

/// How a command puts the play's output where it must be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Reach {
    /// Driving the flank of a motion in this direction: the output follows the command.
    Flank(Direction),
    /// Inside the play: the output stays where the motion (or its turn) left it.
    Stuck,
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Where [`Segment::sure_flank`] answers, the search answers the same: a motion
        /// without a turning point, its output starting anywhere near the command, the wanted
        /// output near it too (down to the rounding of the breakpoints).
        #[test]
        fn a_sure_flank_is_the_one_the_search_finds(
            near in -350.0f64..350.0,
            start in -1.0f64..1.0,
            half in 0.0f64..0.6,
            wanted in -1.0f64..1.0,
            scale in 0usize..4,
        ) {
            // Offsets down to a few ulps of the angle.
            let shrink = [1.0, 1e-4, 1e-8, 1e-12][scale];
            let segment = Segment {
                start_output: near + start * shrink,
                turn: f64::NAN,
                at: 0.0,
                half,
            };
            let wanted = segment.start_output + wanted * shrink;
            if let Some(d) = segment.sure_flank(wanted, near) {
                prop_assert_eq!(segment.command_for(wanted, near).1, Reach::Flank(d));
            }
        }
    }
}
