//! The model an identification starts from: the requested effects at zero, with table grids
//! chosen from the data — each table spans the range of command angles the measured stops
//! visited (rounded out to the pitch), so no parameter exists only to be regularised, and a
//! crosstalk table's other-axis grid is the few angles at which the data held that axis while
//! sweeping the affected one (the paper: A3 at 58°, 105°, 153° for the A2 tests), or a 15°
//! grid over its range when there are none or many (path data).

use std::collections::BTreeMap;

use crate::measure::Stop;
use crate::model::{EffectName, GridOptions, Model, Observed};

/// Most distinct angles of the influencing axis used directly as crosstalk columns.
const MAX_DISTINCT_COLUMNS: usize = 8;

/// Grid choices of an identification.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridChoice {
    /// Pitch of `map` and `backlash` tables, degrees (the paper: 1°).
    pub map_pitch_deg: f64,
    /// Pitch of crosstalk tables along their own axis, degrees.
    pub crosstalk_pitch_deg: f64,
    /// Pitch along the influencing axis when the data visit it at many angles, degrees.
    pub crosstalk_other_pitch_deg: f64,
}

impl Default for GridChoice {
    fn default() -> Self {
        GridChoice {
            map_pitch_deg: 1.0,
            crosstalk_pitch_deg: 5.0,
            crosstalk_other_pitch_deg: 15.0,
        }
    }
}

/// The range of axis n (1..=6) over the measured stops, rounded out to multiples of `pitch`.
pub fn data_range(data: &[Stop], axis: u8, pitch: f64) -> Option<[f64; 2]> {
    let angles = data
        .iter()
        .filter(|s| s.measured_mm.is_some())
        .map(|s| s.state.axes_deg[axis as usize - 1]);
    let (lo, hi) = angles.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), a| {
        (lo.min(a), hi.max(a))
    });
    lo.is_finite().then(|| {
        [
            (lo / pitch + 1e-9).floor() * pitch,
            (hi / pitch - 1e-9).ceil() * pitch,
        ]
    })
}

/// The distinct angles (to 1e-6°) at which axis `held` stood during sweeps of axis `swept`:
/// tests (rows with the same label) in which `swept` visits at least three angles while
/// `held` stays put. For the paper's campaign and crosstalk A3→A2 these are the A3 angles of
/// the repeated A2 tests (58°, 105°, 153°). Sorted.
pub fn sweep_angles(data: &[Stop], swept: u8, held: u8) -> Vec<f64> {
    let (s, h) = (swept as usize - 1, held as usize - 1);
    let round = |a: f64| (a * 1e6).round() / 1e6;
    // Per test: the held axis's distinct angles in visiting order (consecutive repeats
    // merged), and the swept axis's angles.
    let mut tests: BTreeMap<&str, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
    for st in data.iter().filter(|st| st.measured_mm.is_some()) {
        let (held_angles, swept_angles) = tests.entry(st.test.as_str()).or_default();
        let a = round(st.state.axes_deg[h]);
        if held_angles.last() != Some(&a) {
            held_angles.push(a);
        }
        swept_angles.push(round(st.state.axes_deg[s]));
    }
    let mut out = Vec::new();
    for (held_angles, mut swept_angles) in tests.into_values() {
        swept_angles.sort_by(f64::total_cmp);
        swept_angles.dedup();
        if held_angles.len() == 1 && swept_angles.len() >= 3 {
            out.push(held_angles[0]);
        }
    }
    out.sort_by(f64::total_cmp);
    out.dedup();
    out
}

/// Grid options for a zero effect `name` fitted to `data`.
pub fn grid_options(name: &EffectName, data: &[Stop], choice: &GridChoice) -> GridOptions {
    use crate::model::registry::Axes;
    match name.axes {
        Axes::One(n) => GridOptions {
            pitch_deg: Some(choice.map_pitch_deg),
            range_deg: data_range(data, n, choice.map_pitch_deg),
            ..GridOptions::default()
        },
        Axes::Pair { from, to } => {
            let distinct = sweep_angles(data, to, from);
            let (other_grid_deg, other_range_deg) =
                if !distinct.is_empty() && distinct.len() <= MAX_DISTINCT_COLUMNS {
                    (Some(distinct), None)
                } else {
                    (
                        None,
                        data_range(data, from, choice.crosstalk_other_pitch_deg),
                    )
                };
            GridOptions {
                pitch_deg: Some(choice.crosstalk_pitch_deg),
                range_deg: data_range(data, to, choice.crosstalk_pitch_deg),
                other_pitch_deg: Some(choice.crosstalk_other_pitch_deg),
                other_range_deg,
                other_grid_deg,
            }
        }
        Axes::None | Axes::Spec(_) => GridOptions::default(),
    }
}

/// Appends the effects `names` (at zero, grids from the data) to `model`; effects the model
/// already has are left as they are. Returns the canonical names appended.
/// An effect that cannot be set up on the data (its grid, its robot data).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{effect}: {source}")]
pub struct SetupError {
    /// The effect's name.
    pub effect: String,
    /// Why.
    pub source: crate::model::EffectError,
}

pub fn add_effects(
    model: &mut Model,
    names: &[EffectName],
    data: &[Stop],
    choice: &GridChoice,
) -> Result<Vec<String>, SetupError> {
    let mut added = Vec::new();
    for name in names {
        let canonical = name.to_string();
        if model.effects().iter().any(|e| e.name() == canonical) || added.contains(&canonical) {
            continue;
        }
        let mut effect = name
            .create(&grid_options(name, data, choice), &model.robot)
            .map_err(|source| SetupError {
                effect: canonical.clone(),
                source,
            })?;
        effect.start_from_data(&observed(data), &model.context());
        model.push(effect);
        added.push(canonical);
    }
    Ok(added)
}

/// The measured points of `data` as effects see them when they set themselves up
/// ([`Effect::start_from_data`](crate::model::Effect::start_from_data)): tests numbered by
/// label in order of appearance.
fn observed(data: &[Stop]) -> Vec<Observed<'_>> {
    let mut labels: Vec<&str> = Vec::new();
    data.iter()
        .filter_map(|s| {
            let m = s.measured_mm?;
            let test = match labels.iter().position(|l| *l == s.test) {
                Some(t) => t,
                None => {
                    labels.push(&s.test);
                    labels.len() - 1
                }
            };
            Some(Observed {
                test,
                state: &s.state,
                measured_mm: m,
            })
        })
        .collect()
}
