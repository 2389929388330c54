//! Whether an identification may be trusted: every test's residual (gross errors left out)
//! against the noise floor — from repeated points when the data hold enough, else from the
//! tracker's specification, as `diagnose` estimates it ([`crate::diagnose::noise`]). A test
//! whose RMS stays more than [`FAIL_RATIO`] times above the floor was not explained by the
//! model: the fit failed, and the verdict names the tests, the sizes and the likely causes.

use crate::diagnose::noise::NoiseFloor;

/// A test whose residual RMS exceeds this multiple of the noise floor failed: a wrong link, a
/// wrong frame or a wrong target leave hundreds of times the floor. A model that lacks an
/// effect of ordinary size stays below it (the README's hidden tilt of A1 and compliance of
/// A2/A3: 5× in the A1 test) and is written, with a note ([`NOTE_RATIO`]).
pub const FAIL_RATIO: f64 = 10.0;
/// A test above this multiple of the floor gets a note: the model may lack an effect.
pub const NOTE_RATIO: f64 = 3.0;

/// One test's residual after the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct TestResidual {
    /// The test (the CSV's `test` column).
    pub test: String,
    /// Points without gross errors, and the gross errors.
    pub points: usize,
    /// Its points left out as gross errors.
    pub gross: usize,
    /// RMS of the 3-D residual of the points without gross errors, µm.
    pub rms_um: f64,
}

impl TestResidual {
    /// Whether the test failed against `floor_um`.
    pub fn failed(&self, floor_um: f64) -> bool {
        self.rms_um > FAIL_RATIO * floor_um
    }
}

/// What the data and the request say about why a fit may have failed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Clues {
    /// Positions were taken to be in the robot base frame.
    pub base_frame: bool,
    /// RMS residual (µm) when the same model is compared with the measured points moved by
    /// the rigid transform that fits them best, if that is far lower than the fit's: the data
    /// are in another frame.
    pub rigid_rms_um: Option<f64>,
    /// The fit's overall RMS, µm.
    pub rms_um: f64,
    /// The target came from a `--target` hint (the data did not determine it).
    pub target_from_hint: Option<[f64; 3]>,
    /// Where the robot description came from (`the built-in KR 30 HA`, a file name).
    pub robot_from: String,
    /// Effects that were held, not identified.
    pub held: Vec<String>,
}

/// The verdict of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// The measurement noise the residual is judged against.
    pub noise: NoiseFloor,
    /// Each test's residual against that floor.
    pub tests: Vec<TestResidual>,
    /// When the fit failed: what to tell the user (several lines).
    pub failure: Option<String>,
    /// When it passed but some tests stay well above the floor: a hint to run `diagnose`.
    pub note: Option<String>,
}

impl Verdict {
    /// The fit is not good enough to use (`identify` writes nothing, unless asked to).
    pub fn failed(&self) -> bool {
        self.failure.is_some()
    }
}

/// Judges `tests` against `noise`.
pub fn judge(tests: Vec<TestResidual>, noise: NoiseFloor, clues: &Clues) -> Verdict {
    let floor = noise.rms_um;
    let failing: Vec<&TestResidual> = tests.iter().filter(|t| t.failed(floor)).collect();
    let failure = (!failing.is_empty()).then(|| explain(&failing, &noise, clues));
    let high: Vec<String> = tests
        .iter()
        .filter(|t| failure.is_none() && t.rms_um > NOTE_RATIO * floor)
        .map(|t| {
            format!(
                "{} {:.1} µm RMS ({:.1}×)",
                t.test,
                t.rms_um,
                t.rms_um / floor
            )
        })
        .collect();
    let note = (!high.is_empty()).then(|| {
        format!(
            "{} stay more than {NOTE_RATIO}× above the noise floor of {floor:.1} µm: the model \
             may lack an effect; `robopost diagnose -c CAL.json MEAS.csv...` names it",
            high.join(", ")
        )
    });
    Verdict {
        noise,
        tests,
        failure,
        note,
    }
}

fn explain(failing: &[&TestResidual], noise: &NoiseFloor, clues: &Clues) -> String {
    let floor = noise.rms_um;
    let mut worst: Vec<&&TestResidual> = failing.iter().collect();
    worst.sort_by(|a, b| b.rms_um.total_cmp(&a.rms_um));
    let named: Vec<String> = worst
        .iter()
        .take(8)
        .map(|t| {
            format!(
                "{} {:.1} µm RMS ({:.0}×)",
                t.test,
                t.rms_um,
                t.rms_um / floor
            )
        })
        .collect();
    let more = failing.len().saturating_sub(named.len());
    let mut text = format!(
        "the fit failed: {} of the tests stay far above the noise floor of {:.1} µm ({}), more \
         than {FAIL_RATIO}× it: {}{}.\nLikely causes:\n",
        failing.len(),
        floor,
        noise.source.describe(),
        named.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        }
    );
    let mut causes = Vec::new();
    if let Some(rigid) = clues.rigid_rms_um {
        causes.push(format!(
            "data in the wrong frame: the positions were taken as robot base coordinates, but \
             moved rigidly they fit the model at {rigid:.1} µm RMS instead of {:.1} µm — if \
             they are in the tracker's own frame, give `--frame tracker`",
            clues.rms_um
        ));
    }
    if let Some(t) = clues.target_from_hint {
        causes.push(format!(
            "a wrong target: the data hold no A5 and A6 indexing test to measure it, so the \
             `--target` hint ({}, {}, {} mm) was the start; check it",
            t[0], t[1], t[2]
        ));
    }
    let held = if clues.held.is_empty() {
        String::new()
    } else {
        format!(" (held, not identified: {})", clues.held.join(", "))
    };
    causes.push(format!(
        "a wrong robot description: the links and axis conventions come from {}; a link \
         length off by millimetres that no identified parameter takes up{held} leaves a \
         residual of that size",
        clues.robot_from
    ));
    causes.push(
        "a missing effect: write the calibration anyway with `--accept-poor-fit` and run \
         `robopost diagnose -c CAL.json MEAS.csv...`, which names the effect the model lacks"
            .to_string(),
    );
    if clues.base_frame && clues.rigid_rms_um.is_none() {
        causes.push(
            "data in another frame: the positions were taken as robot base coordinates \
             (`--frame base`); data in the tracker's own frame need `--frame tracker`"
                .to_string(),
        );
    }
    for (i, c) in causes.iter().enumerate() {
        text += &format!("  {}. {c}\n", i + 1);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::noise::NoiseSource;

    fn floor(rms_um: f64) -> NoiseFloor {
        NoiseFloor {
            rms_um,
            source: NoiseSource::Repeats { dof: 40 },
        }
    }

    fn test(name: &str, rms_um: f64, gross: usize) -> TestResidual {
        TestResidual {
            test: name.into(),
            points: 100,
            gross,
            rms_um,
        }
    }

    #[test]
    fn far_above_the_floor_fails() {
        let clues = Clues {
            base_frame: true,
            rigid_rms_um: Some(20.0),
            rms_um: 3000.0,
            robot_from: "the built-in KR 30 HA".into(),
            ..Clues::default()
        };
        let ok = judge(
            vec![test("A1", 99.0, 1), test("A2", 20.0, 5)],
            floor(10.0),
            &clues,
        );
        assert!(!ok.failed());
        let note = ok.note.unwrap();
        assert!(note.starts_with("A1 99.0 µm RMS (9.9×) stay") && note.contains("diagnose"));
        let bad = judge(
            vec![
                test("A1", 101.0, 0),
                test("A2", 1200.0, 6),
                test("A3", 20.0, 0),
            ],
            floor(10.0),
            &clues,
        );
        assert!(bad.note.is_none());
        let text = bad.failure.unwrap();
        assert!(text.contains("2 of the tests"), "{text}");
        assert!(
            text.contains("A2 1200.0 µm RMS (120×), A1 101.0 µm RMS (10×)"),
            "{text}"
        );
        assert!(text.contains("1. data in the wrong frame") && text.contains("20.0 µm RMS"));
        assert!(text.contains("robopost diagnose"));
        assert!(!text.contains("A3"));
    }
}
