//! Measurement campaigns (the paper's section 2.3): each axis indexed over a grid of command
//! angles in both directions while the others stay at reference angles, with unmeasured
//! approach moves that put the axis on the wanted backlash branch before each sweep, and
//! repeats of a test at several angles of another axis to expose crosstalk. Optionally,
//! reversal tests (as ISO 230-2 measures an axis's reversal value): at a few angles, short
//! moves back and forth, shorter and longer than a gear play, each stop measured — the only
//! data in which a play's dead band shows (the sweeps' 1° steps engage it every time).

use serde::{Deserialize, Serialize};

/// Repeat a test at several angles of another axis (crosstalk: A2 tested at A3 = 58°, 105°, 153°).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Repeat {
    /// The other axis (1..=6).
    pub axis: u8,
    pub angles_deg: Vec<f64>,
}

/// One indexing test: axis `axis` swept from `from_deg` to `to_deg` and back.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IndexingTest {
    /// The indexed axis (1..=6).
    pub axis: u8,
    pub from_deg: f64,
    pub to_deg: f64,
    #[serde(default = "default_pitch")]
    pub pitch_deg: f64,
    /// Angles of all six axes during the test (the indexed one is overridden).
    pub reference_deg: [f64; 6],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repeat: Option<Repeat>,
    /// Over-travel of the unmeasured approach move before each sweep, degrees.
    #[serde(default = "default_approach")]
    pub approach_deg: f64,
}

fn default_pitch() -> f64 {
    1.0
}
fn default_approach() -> f64 {
    2.0
}

/// A reversal test of one axis: at each angle of `at_deg`, approached from below, the axis
/// moves back by each step of `steps_deg` and forward again, every stop measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReversalTest {
    /// The tested axis (1..=6).
    pub axis: u8,
    pub at_deg: Vec<f64>,
    /// The back-and-forth moves, degrees (> 0).
    pub steps_deg: Vec<f64>,
    /// Angles of all six axes during the test (the tested one is overridden).
    pub reference_deg: [f64; 6],
}

/// A reference pose measured at the start of the campaign, before every test and at its end,
/// each time approached the same way (every axis from 2° below, so that every gear play is
/// engaged on the same flank) and measured `repeats` times: the one pose whose measurements
/// differ only by the time they were taken, from which the robot's drift between the
/// campaign and its use is measured (`compare --budget`, when the validation starts with it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferencePose {
    pub axes_deg: [f64; 6],
    #[serde(default = "default_repeats")]
    pub repeats: usize,
}

fn default_repeats() -> usize {
    1
}

/// The test label of a reference pose's stops (as the real cell's campaign labels them).
pub const REFERENCE_TEST: &str = "REF";

impl ReferencePose {
    /// The pose's visits `(test, axes, measured)`: the approach from below, then `repeats`
    /// measurements.
    pub fn visits(&self) -> Vec<(String, [f64; 6], bool)> {
        let below = self.axes_deg.map(|a| a - 2.0);
        std::iter::once((REFERENCE_TEST.to_string(), below, false))
            .chain((0..self.repeats).map(|_| (REFERENCE_TEST.to_string(), self.axes_deg, true)))
            .collect()
    }
}

/// A whole campaign and the pace of the robot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Campaign {
    pub tests: Vec<IndexingTest>,
    /// Reversal tests (none in the paper's campaign).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub reversals: Vec<ReversalTest>,
    /// A reference pose measured through the campaign (none in the paper's campaign).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<ReferencePose>,
    /// Dwell per stop (settling + tracker measurement), seconds: the paper measured 186 points
    /// in about 10 minutes, i.e. about 3.2 s per stop.
    #[serde(default = "default_dwell")]
    pub dwell_s: f64,
    /// Axis speed for travel time between stops, degrees per second.
    #[serde(default = "default_speed")]
    pub axis_speed_deg_s: f64,
}

fn default_dwell() -> f64 {
    DEFAULT_DWELL_S
}
fn default_speed() -> f64 {
    DEFAULT_AXIS_SPEED_DEG_S
}

/// The A3 angles at which [`Campaign::recommended`] repeats the A2 test: the paper's three,
/// the halfway angles between them and the lower end of the A3 test's range, so that no
/// column is more than 24° from the next and none of the calibrated range is extrapolated
/// (within 2° of its upper end).
#[cfg(any(test, feature = "internals"))]
pub const RECOMMENDED_CROSSTALK_A3_DEG: [f64; 7] = [10.0, 34.0, 58.0, 82.0, 105.0, 129.0, 153.0];

/// How many times [`Campaign::recommended`] runs the paper's tests.
#[cfg(any(test, feature = "internals"))]
pub const RECOMMENDED_RUNS: usize = 3;

/// One planned stop of a campaign, in the order the robot visits them.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedStop {
    /// Test label, e.g. `A2@A3=58`.
    pub test: String,
    pub axes_deg: [f64; 6],
    /// False on approach moves (visited, not measured).
    pub measured: bool,
    /// Seconds since the start of the campaign.
    pub time_s: f64,
}

/// Error in a campaign description.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CampaignError {
    #[error("tests[{test}].{key}: expected {expected}, found {found}")]
    Invalid {
        test: usize,
        key: &'static str,
        expected: &'static str,
        found: String,
    },
}

impl Campaign {
    /// The paper's campaign on a KR 30 HA: every axis at 1°, both directions; A2 repeated at
    /// A3 = 58°, 105°, 153° and A3 at A2 = −112°, −65°, −19° (Figs. 5 and 7); about 3,000
    /// measured points. A2 spans the paper's −112°..−19°; the other ranges (not given in the
    /// paper) cover what the validation paths of Fig. 8 visit (A3 10°..155°, A5 ±116°).
    pub fn paper() -> Campaign {
        let reference = [0.0, -60.0, 100.0, 0.0, 45.0, 0.0];
        let test = |axis: u8, from: f64, to: f64, repeat: Option<Repeat>| IndexingTest {
            axis,
            from_deg: from,
            to_deg: to,
            pitch_deg: 1.0,
            reference_deg: reference,
            repeat,
            approach_deg: 2.0,
        };
        Campaign {
            tests: vec![
                test(1, -60.0, 60.0, None),
                test(
                    2,
                    -112.0,
                    -19.0,
                    Some(Repeat {
                        axis: 3,
                        angles_deg: vec![58.0, 105.0, 153.0],
                    }),
                ),
                test(
                    3,
                    10.0,
                    155.0,
                    Some(Repeat {
                        axis: 2,
                        angles_deg: vec![-112.0, -65.0, -19.0],
                    }),
                ),
                test(4, -90.0, 90.0, None),
                test(5, -116.0, 116.0, None),
                test(6, -180.0, 180.0, None),
            ],
            reversals: Vec::new(),
            reference: None,
            dwell_s: default_dwell(),
            axis_speed_deg_s: default_speed(),
        }
    }

    /// The paper's campaign followed by a reversal test of every axis at five angles of its
    /// sweep, with moves of 0.001° to 0.05° (gear plays are hundredths of a degree): what a
    /// real campaign needs to measure the plays' dead band, not only their two branches. A
    /// play's dead band shows only at the stops inside it, so they must be many: a diagnosis
    /// weighs a gain carried by k stops with a t statistic of at most about √k, and asks for 5
    /// (`diagnose::MIN_T`); a play of 0.016° holds 50 of these stops per axis.
    pub fn paper_with_reversals() -> Campaign {
        let mut campaign = Campaign::paper();
        let steps = vec![
            0.001, 0.002, 0.003, 0.004, 0.005, 0.006, 0.008, 0.01, 0.012, 0.015, 0.02, 0.03, 0.05,
        ];
        campaign.reversals = campaign
            .tests
            .iter()
            .map(|t| {
                let span = t.to_deg - t.from_deg;
                ReversalTest {
                    axis: t.axis,
                    at_deg: [0.1, 0.3, 0.5, 0.7, 0.9]
                        .map(|f| (t.from_deg + f * span).round())
                        .to_vec(),
                    steps_deg: steps.clone(),
                    reference_deg: t.reference_deg,
                }
            })
            .collect();
        campaign
    }

    /// The paper's campaign as a metrology engineer would complete it for the paper's
    /// validation paths, in two ways. The A2 test is repeated at A3 angles spanning the A3
    /// range the campaign calibrates ([`RECOMMENDED_CROSSTALK_A3_DEG`]): with the paper's three
    /// (58°, 105°, 153°) the crosstalk is held at its 58° column below it, where path 3 goes down
    /// to A3 = 15°, and interpolated linearly over 47° where it curves. And the whole campaign
    /// is run [`RECOMMENDED_RUNS`] times, as ISO 230-2 measures a positioning error over
    /// repeated runs (it prescribes five), so the tracker's noise in a 1° cell averages down.
    /// About 12,000 measured points, 11 hours at the paper's pace: an overnight campaign, over
    /// which a real robot's warm-up must be modelled (`drift`) or waited out.
    #[cfg(any(test, feature = "internals"))]
    pub fn recommended() -> Campaign {
        let mut campaign = Campaign::paper();
        for t in campaign.tests.iter_mut().filter(|t| t.axis == 2) {
            t.repeat = Some(Repeat {
                axis: 3,
                angles_deg: RECOMMENDED_CROSSTALK_A3_DEG.to_vec(),
            });
        }
        let run = campaign.tests.clone();
        campaign.tests = (0..RECOMMENDED_RUNS).flat_map(|_| run.clone()).collect();
        campaign
    }

    /// Checks axes, ranges and pitches.
    pub fn validate(&self) -> Result<(), CampaignError> {
        for (i, t) in self.tests.iter().enumerate() {
            let bad = |key, expected, found: String| {
                Err(CampaignError::Invalid {
                    test: i,
                    key,
                    expected,
                    found,
                })
            };
            if !(1..=6).contains(&t.axis) {
                return bad("axis", "an axis number 1..6", t.axis.to_string());
            }
            if !(t.pitch_deg.is_finite() && t.pitch_deg > 0.0) {
                return bad("pitch_deg", "a positive number", t.pitch_deg.to_string());
            }
            if !(t.from_deg.is_finite() && t.to_deg.is_finite() && t.from_deg < t.to_deg) {
                return bad(
                    "to_deg",
                    "a number greater than from_deg",
                    t.to_deg.to_string(),
                );
            }
            if !(t.approach_deg.is_finite() && t.approach_deg >= 0.0) {
                return bad(
                    "approach_deg",
                    "a non-negative number",
                    t.approach_deg.to_string(),
                );
            }
            if let Some(r) = &t.repeat {
                if !(1..=6).contains(&r.axis) || r.axis == t.axis {
                    return bad(
                        "repeat.axis",
                        "another axis number 1..6",
                        r.axis.to_string(),
                    );
                }
            }
        }
        for (i, r) in self.reversals.iter().enumerate() {
            let bad = |key, expected, found: String| {
                Err(CampaignError::Invalid {
                    test: i,
                    key,
                    expected,
                    found,
                })
            };
            if !(1..=6).contains(&r.axis) {
                return bad("reversals.axis", "an axis number 1..6", r.axis.to_string());
            }
            if let Some(s) = r
                .steps_deg
                .iter()
                .find(|s| !(s.is_finite() && **s > 0.0 && **s <= 10.0))
            {
                return bad("reversals.steps_deg", "steps in (0, 10]°", s.to_string());
            }
            if let Some(a) = r.at_deg.iter().find(|a| !a.is_finite()) {
                return bad("reversals.at_deg", "finite angles", a.to_string());
            }
        }
        Ok(())
    }

    /// The stops in visiting order, with approach moves and time stamps.
    pub fn plan(&self) -> Result<Vec<PlannedStop>, CampaignError> {
        self.validate()?;
        let mut visits: Vec<(String, [f64; 6], bool)> = Vec::new();
        let reference = |visits: &mut Vec<(String, [f64; 6], bool)>| {
            if let Some(r) = &self.reference {
                visits.extend(r.visits());
            }
        };
        for t in &self.tests {
            reference(&mut visits);
            let n = t.axis as usize - 1;
            let others: Vec<(String, [f64; 6])> = match &t.repeat {
                None => vec![(format!("A{}", t.axis), t.reference_deg)],
                Some(r) => r
                    .angles_deg
                    .iter()
                    .map(|&a| {
                        let mut reference = t.reference_deg;
                        reference[r.axis as usize - 1] = a;
                        (format!("A{}@A{}={}", t.axis, r.axis, a), reference)
                    })
                    .collect(),
            };
            let steps = ((t.to_deg - t.from_deg) / t.pitch_deg + 1e-9).floor() as usize;
            let grid: Vec<f64> = (0..=steps)
                .map(|i| t.from_deg + i as f64 * t.pitch_deg)
                .collect();
            for (label, reference) in others {
                let mut push = |angle: f64, measured: bool| {
                    let mut axes = reference;
                    axes[n] = angle;
                    visits.push((label.clone(), axes, measured));
                };
                // Approach from below so the first measured stop is already on the + branch.
                push(t.from_deg - t.approach_deg, false);
                for &a in &grid {
                    push(a, true);
                }
                let last = *grid.last().unwrap_or(&t.to_deg);
                push(last + t.approach_deg, false);
                for &a in grid.iter().rev() {
                    push(a, true);
                }
            }
        }
        for r in &self.reversals {
            let n = r.axis as usize - 1;
            let label = format!("A{} reversal", r.axis);
            for &at in &r.at_deg {
                let mut push = |angle: f64, measured: bool| {
                    let mut axes = r.reference_deg;
                    axes[n] = angle;
                    visits.push((label.clone(), axes, measured));
                };
                // Approached from below over more than any play: engaged upward at `at`.
                push(at - 1.0, false);
                push(at, true);
                for &s in &r.steps_deg {
                    push(at - s, true);
                    push(at, true);
                }
            }
        }
        reference(&mut visits);
        Ok(paced(visits, self.dwell_s, self.axis_speed_deg_s))
    }
}

/// Time-stamps a sequence of visits `(test, axes, measured)`: between consecutive stops the
/// clock advances by the dwell (settling and tracker measurement) plus the travel time of the
/// axis that moves farthest at `axis_speed_deg_s` (axes move synchronously, as PTP motion).
pub fn paced(
    visits: impl IntoIterator<Item = (String, [f64; 6], bool)>,
    dwell_s: f64,
    axis_speed_deg_s: f64,
) -> Vec<PlannedStop> {
    let mut stops: Vec<PlannedStop> = Vec::new();
    let mut clock = 0.0;
    for (test, axes_deg, measured) in visits {
        if let Some(prev) = stops.last() {
            let travel = (0..6)
                .map(|k| (axes_deg[k] - prev.axes_deg[k]).abs())
                .fold(0.0, f64::max);
            clock += dwell_s + travel / axis_speed_deg_s;
        }
        stops.push(PlannedStop {
            test,
            axes_deg,
            measured,
            time_s: clock,
        });
    }
    stops
}

/// The default pace of a robot stop: dwell per stop, seconds (see [`Campaign::dwell_s`]).
pub const DEFAULT_DWELL_S: f64 = 3.2;
/// The default axis speed between stops, degrees per second.
pub const DEFAULT_AXIS_SPEED_DEG_S: f64 = 30.0;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measure::infer_histories;
    use crate::model::{AxisState, Direction};

    #[test]
    fn paper_campaign_has_about_three_thousand_points_within_limits() {
        let stops = Campaign::paper().plan().unwrap();
        let measured = stops.iter().filter(|s| s.measured).count();
        // 121·2 + 94·2·3 + 146·2·3 + 181·2 + 233·2 + 361·2 = 3232
        assert_eq!(measured, 3232);
        let robot = crate::kinematics::RobotDescription::kr30ha();
        assert!(stops.iter().all(|s| robot.within_limits(&s.axes_deg)));
        // ~3.2 s per stop: the paper's 186 A2 points took about 10 minutes.
        let a2: Vec<_> = stops.iter().filter(|s| s.test == "A2@A3=58").collect();
        let minutes = (a2.last().unwrap().time_s - a2[0].time_s) / 60.0;
        assert!((9.0..12.0).contains(&minutes), "{minutes} min");
    }

    #[test]
    fn sweeps_are_bidirectional_and_approach_sets_the_branch() {
        let c = Campaign {
            tests: vec![IndexingTest {
                axis: 2,
                from_deg: -10.0,
                to_deg: -8.0,
                pitch_deg: 1.0,
                reference_deg: [0.0, 0.0, 90.0, 0.0, 0.0, 0.0],
                repeat: None,
                approach_deg: 2.0,
            }],
            reversals: Vec::new(),
            reference: None,
            dwell_s: 1.0,
            axis_speed_deg_s: 1.0,
        };
        let stops = c.plan().unwrap();
        let a2: Vec<f64> = stops.iter().map(|s| s.axes_deg[1]).collect();
        assert_eq!(a2, vec![-12.0, -10.0, -9.0, -8.0, -6.0, -8.0, -9.0, -10.0]);
        let measured: Vec<bool> = stops.iter().map(|s| s.measured).collect();
        assert_eq!(
            measured,
            vec![false, true, true, true, false, true, true, true]
        );
        let mut states: Vec<AxisState> = stops.iter().map(|s| AxisState::new(s.axes_deg)).collect();
        infer_histories(&mut states, &[]);
        let d: Vec<Direction> = states.iter().map(|s| s.directions()[1]).collect();
        use Direction::*;
        assert_eq!(d[1..4], [Positive, Positive, Positive]);
        assert_eq!(d[5..8], [Negative, Negative, Negative]);
        // time: dwell 1 s + travel |Δ| / 1 °/s between consecutive stops
        assert_eq!(stops[1].time_s, 1.0 + 2.0);
    }

    #[test]
    fn a_reference_pose_is_measured_at_the_start_before_every_test_and_at_the_end() {
        let reference = [0.0, -60.0, 100.0, 0.0, 45.0, 0.0];
        let mut c = Campaign::paper();
        c.reference = Some(ReferencePose {
            axes_deg: reference,
            repeats: 2,
        });
        let stops = c.plan().unwrap();
        let refs: Vec<usize> = (0..stops.len())
            .filter(|&i| stops[i].test == REFERENCE_TEST && stops[i].measured)
            .collect();
        // Six tests: before each of them and at the end, two readings each.
        assert_eq!(refs.len(), 7 * 2);
        assert_eq!(refs[..2], [1, 2]);
        assert_eq!(refs[12..], [stops.len() - 2, stops.len() - 1]);
        for &i in &refs {
            assert_eq!(stops[i].axes_deg, reference);
        }
        // Each visit approached with every axis from 2° below, unmeasured.
        for &i in refs.iter().step_by(2) {
            assert!(!stops[i - 1].measured);
            assert_eq!(stops[i - 1].axes_deg, reference.map(|a| a - 2.0));
        }
        // The paper's own stops are unchanged, in order.
        let own: Vec<_> = stops
            .iter()
            .filter(|s| s.test != REFERENCE_TEST)
            .map(|s| s.axes_deg)
            .collect();
        let paper: Vec<_> = Campaign::paper()
            .plan()
            .unwrap()
            .into_iter()
            .map(|s| s.axes_deg)
            .collect();
        assert_eq!(own, paper);
    }

    #[test]
    fn bad_campaigns_name_the_key() {
        let mut c = Campaign::paper();
        c.tests[1].pitch_deg = 0.0;
        assert_eq!(
            c.plan().unwrap_err().to_string(),
            "tests[1].pitch_deg: expected a positive number, found 0"
        );
        let mut c = Campaign::paper();
        c.tests[0].repeat = Some(Repeat {
            axis: 1,
            angles_deg: vec![],
        });
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("tests[0].repeat.axis"));
    }
}
