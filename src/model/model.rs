//! The calibrated robot as one object: robot description, payload, measurement target and the
//! list of effects. It sums the effects' chain errors, runs the error chain to predict the
//! flange pose and target position, exposes all effect parameters as one flat vector (for
//! Levenberg–Marquardt identification) and composes the chain's slot Jacobian with the
//! effects' sparse Jacobians (chain rule: d p/d value = Σ_slots d p/d slot · d slot/d value).

use std::sync::OnceLock;

use nalgebra::{Vector3, Vector6};

use super::chain::{self, a6_to_flange, flange_to_a6, ChainFrames};
use super::effect::{AxisSlopes, ChainErrors, Context, Parameter, Partial, Slot};
use super::effects::ModelEffect;
#[cfg(any(test, feature = "internals"))]
use super::effects::{EffectError, GridOptions};
use super::merged::{Cells, Merged};
#[cfg(any(test, feature = "internals"))]
use super::registry::EffectName;
use super::AxisState;
use crate::kinematics::{Frame, Payload, RobotDescription};

/// A tool within this distance of the measurement target (mm) is the target: the rounding of
/// a `$TOOL` written to the micrometre.
pub const TOOL_MATCH_MM: f64 = 0.001;

/// A robot with its error effects. `Send + Sync`: share one across rayon workers.
#[derive(Debug)]
pub struct Model {
    pub robot: RobotDescription,
    pub payload: Payload,
    /// The measurement target (retroreflector) in the KUKA flange frame, mm.
    pub target_mm: Vector3<f64>,
    effects: Vec<Box<dyn ModelEffect>>,
    /// Start of each effect's parameters in the flat vector, plus the total at the end.
    starts: Vec<usize>,
    /// Indices of the effects whose contribution depends on the axis angles.
    varying: Vec<usize>,
    /// The solver's merged angle tables, built on first use after any change.
    merged: OnceLock<Merged>,
}

/// By hand because a boxed effect clones through [`ModelEffect::clone_model_effect`]: a
/// `Clone` impl on `Box<dyn ModelEffect>` would make the effect traits part of the library's
/// public interface (lib.rs keeps it nameable).
impl Clone for Model {
    fn clone(&self) -> Model {
        Model {
            robot: self.robot,
            payload: self.payload,
            target_mm: self.target_mm,
            effects: self
                .effects
                .iter()
                .map(|e| e.clone_model_effect())
                .collect(),
            starts: self.starts.clone(),
            varying: self.varying.clone(),
            merged: self.merged.clone(),
        }
    }
}

impl Model {
    /// A model without effects: the nominal robot.
    pub fn new(robot: RobotDescription, payload: Payload, target_mm: Vector3<f64>) -> Model {
        Model {
            robot,
            payload,
            target_mm,
            effects: Vec::new(),
            starts: vec![0],
            varying: Vec::new(),
            merged: OnceLock::new(),
        }
    }

    /// Appends an effect; its parameters go to the end of the flat vector.
    pub fn push(&mut self, effect: Box<dyn ModelEffect>) {
        let end = self.n_parameters() + effect.values().len();
        if effect.varies_with_axes() {
            self.varying.push(self.effects.len());
        }
        self.effects.push(effect);
        self.starts.push(end);
        self.merged = OnceLock::new();
    }

    /// Appends a zero effect of `name` for identification.
    #[cfg(any(test, feature = "internals"))]
    pub fn push_named(
        &mut self,
        name: &EffectName,
        options: &GridOptions,
    ) -> Result<(), EffectError> {
        let effect = name.create(options, &self.robot)?;
        self.push(effect);
        Ok(())
    }

    pub fn effects(&self) -> &[Box<dyn ModelEffect>] {
        &self.effects
    }

    /// Index in the flat vector of effect `i`'s first parameter.
    pub fn effect_start(&self, i: usize) -> usize {
        self.starts[i]
    }

    pub fn context(&self) -> Context<'_> {
        Context {
            robot: &self.robot,
            payload: &self.payload,
        }
    }

    /// The target vector in the paper's A6 frame.
    pub fn target_a6(&self) -> Vector3<f64> {
        flange_to_a6(&self.target_mm)
    }

    pub fn chain_errors(&self, state: &AxisState) -> ChainErrors {
        let ctx = self.context();
        let mut errors = ChainErrors::default();
        for effect in &self.effects {
            effect.add_to(state, &ctx, &mut errors);
        }
        errors
    }

    /// The errors of the effects that depend neither on the axis angles nor on the directions,
    /// at `state`'s time: a solver evaluating many commands sums them once and adds
    /// [`Self::add_varying_errors`] per command. At time 0 (compensation) they are summed once
    /// per model.
    #[cfg(any(test, feature = "internals"))]
    pub fn fixed_errors(&self, state: &AxisState) -> ChainErrors {
        if state.time_s == 0.0 {
            return self.merged().fixed_at_time_zero;
        }
        self.sum_fixed_errors(state)
    }

    /// [`Self::fixed_errors`] at time 0 (compensation), by reference: summed once per model.
    pub fn fixed_errors_at_time_zero(&self) -> &ChainErrors {
        &self.merged().fixed_at_time_zero
    }

    fn sum_fixed_errors(&self, state: &AxisState) -> ChainErrors {
        let ctx = self.context();
        let mut errors = ChainErrors::default();
        for effect in self.effects.iter().filter(|e| !e.varies_with_axes()) {
            effect.add_to(state, &ctx, &mut errors);
        }
        errors
    }

    /// The solver's precomputed sums, built on first use after any change.
    fn merged(&self) -> &Merged {
        self.merged.get_or_init(|| {
            let mut merged = Merged::new(&self.effects, &self.varying);
            merged.fixed_at_time_zero = self.sum_fixed_errors(&AxisState::default());
            let angles_only = merged
                .rest
                .iter()
                .all(|&i| self.effects[i].adds_angles_only());
            merged.link_blocks = angles_only
                .then(|| chain::LinkBlocks::new(&self.robot, &merged.fixed_at_time_zero));
            merged
        })
    }

    /// Adds the errors of the effects that depend on the axis angles: `fixed_errors(s)` plus
    /// these is `chain_errors(s)` to rounding (the `map` and `backlash` tables of an axis are
    /// looked up merged, see [`Merged`]).
    #[cfg(any(test, feature = "internals"))]
    pub fn add_varying_errors(&self, state: &AxisState, errors: &mut ChainErrors) {
        self.add_varying_errors_near(state, errors, &mut [0; 6]);
    }

    /// [`Self::add_varying_errors`] looking the merged tables up from the cells in `cells`
    /// (see [`Merged::add_near`]): the same sums, found faster near the last lookup.
    pub fn add_varying_errors_near(
        &self,
        state: &AxisState,
        errors: &mut ChainErrors,
        cells: &mut [usize; 6],
    ) {
        let merged = self.merged();
        merged.add_near(&state.axes_deg, &state.history, errors, cells);
        let ctx = self.context();
        for &i in &merged.rest {
            self.effects[i].add_to(state, &ctx, errors);
        }
    }

    /// The fixed part of the chain when the varying effects move the angle slots alone (see
    /// [`chain::LinkBlocks`]), with [`Self::angle_errors_near`] the rest.
    pub fn link_blocks(&self) -> Option<&chain::LinkBlocks> {
        self.merged().link_blocks.as_ref()
    }

    /// The angle slots of `chain_errors(state)` at time 0 (`angles[n]`: axis n+1's, rad), for
    /// a model with [`Self::link_blocks`]: the fixed angles plus the varying effects', summed
    /// in the order of [`Self::add_varying_errors_near`], so to the same bits.
    pub fn angle_errors_near(&self, state: &AxisState, cells: &mut Cells) -> [f64; 6] {
        let merged = self.merged();
        let fixed = &merged.fixed_at_time_zero;
        let mut angles = std::array::from_fn(|n| fixed.get(Slot::Angle { axis: n as u8 + 1 }));
        merged.add_angles_near(&state.axes_deg, &state.history, &mut angles, cells);
        let ctx = self.context();
        for (j, &i) in merged.rest.iter().enumerate() {
            match cells.rest.get_mut(j) {
                Some(hints) => self.effects[i].add_angles_near(state, &ctx, &mut angles, hints),
                None => self.effects[i].add_angles(state, &ctx, &mut angles),
            }
        }
        angles
    }

    /// [`Self::add_varying_errors`] with how those errors change with the axes (see
    /// [`AxisSlopes`]): the fixed errors do not change, so these are the slopes of the whole
    /// model.
    #[cfg(any(test, feature = "internals"))]
    pub fn add_varying_errors_with_slopes(
        &self,
        state: &AxisState,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        self.add_varying_errors_with_slopes_near(state, errors, slopes, &mut [0; 6]);
    }

    /// [`Self::add_varying_errors_with_slopes`], leaving in `cells` the merged tables' cells
    /// for [`Self::add_varying_errors_near`].
    pub fn add_varying_errors_with_slopes_near(
        &self,
        state: &AxisState,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
        cells: &mut [usize; 6],
    ) {
        let merged = self.merged();
        merged.add_with_slopes(&state.axes_deg, &state.history, errors, slopes, cells);
        let ctx = self.context();
        for &i in &merged.rest {
            self.effects[i].add_with_axis_slopes(state, &ctx, errors, slopes);
        }
    }

    /// The gear play of axis n+1 (index `n`) at `state`, when the model has one: where its
    /// output stands against the command (see [`AxisHistory::play`](super::AxisHistory::play)).
    #[cfg(any(test, feature = "internals"))]
    pub fn play(&self, state: &AxisState, n: usize) -> Option<super::PlayAt> {
        let width = self.merged().play_width(n)?;
        Some(state.history[n].play(state.axes_deg[n], |a| width.eval(a).0))
    }

    /// The width table (degrees over the command angle) of axis n+1's gear play, if the model
    /// has one: for callers that look many widths up.
    pub fn play_width_table(&self, n: usize) -> Option<&super::table::Table1> {
        self.merged().play_width(n)
    }

    /// The width (degrees) of axis n+1's gear play at command `angle_deg` (0 without one).
    #[cfg(any(test, feature = "internals"))]
    pub fn play_width_deg(&self, n: usize, angle_deg: f64) -> f64 {
        self.merged()
            .play_width(n)
            .map_or(0.0, |w| w.eval(angle_deg).0)
    }

    /// The evaluated chain, for callers that need several outputs of one state.
    pub fn frames(&self, state: &AxisState) -> (ChainFrames, ChainErrors) {
        let errors = self.chain_errors(state);
        (
            ChainFrames::new(&self.robot, &state.axes_deg, &errors),
            errors,
        )
    }

    /// The KUKA flange frame the robot actually reaches at `state`, in the base frame.
    pub fn flange_pose(&self, state: &AxisState) -> Frame {
        chain::flange_pose(&self.robot, &state.axes_deg, &self.chain_errors(state))
    }

    /// Where the measurement target actually is at `state`, base frame, mm.
    pub fn target_position(&self, state: &AxisState) -> Vector3<f64> {
        chain::target_position(
            &self.robot,
            &state.axes_deg,
            &self.chain_errors(state),
            &self.target_a6(),
        )
    }

    /// The tool (flange → TCP, KUKA flange frame, mm) the robot really carries, for a tool
    /// programmed as `tool_mm`: when the tool is the measurement target (within
    /// [`TOOL_MATCH_MM`]), the identified target-vector correction (the paper's ⁶p, the
    /// target slots of `errors`) is where the TCP really is; any other tool is taken as
    /// programmed (the target's correction says nothing about it).
    pub fn tool_as_identified(&self, tool_mm: &Vector3<f64>, errors: &ChainErrors) -> Vector3<f64> {
        if !self.tool_is_target(tool_mm) {
            return *tool_mm;
        }
        let t = Vector3::from_fn(|c, _| errors.get(Slot::Target { coord: c as u8 }));
        tool_mm + a6_to_flange().transpose() * t
    }

    /// Whether a tool (flange → TCP, mm) is the measurement target (see
    /// [`Self::tool_as_identified`]).
    pub fn tool_is_target(&self, tool_mm: &Vector3<f64>) -> bool {
        (tool_mm - self.target_mm).norm() <= TOOL_MATCH_MM
    }

    /// Whether any table effect held `state` at its edge.
    #[cfg(any(test, feature = "internals"))]
    pub fn clamped(&self, state: &AxisState) -> bool {
        self.effects.iter().any(|e| e.clamped(state))
    }

    /// Indices (into [`Self::effects`]) of the table effects that held `state` at a table
    /// edge, so that a report can count the points outside each table's range.
    #[cfg(any(test, feature = "internals"))]
    pub fn clamped_effects<'a>(&'a self, state: &'a AxisState) -> impl Iterator<Item = usize> + 'a {
        self.effects
            .iter()
            .enumerate()
            .filter(move |(_, e)| e.clamped(state))
            .map(|(i, _)| i)
    }

    pub fn n_parameters(&self) -> usize {
        self.starts[self.starts.len() - 1]
    }

    /// Every parameter with its qualified name (`dx21`, `map:A2[-45]`, …), flat order.
    pub fn parameters(&self) -> Vec<Parameter> {
        self.effects.iter().flat_map(|e| e.parameters()).collect()
    }

    pub fn parameter_names(&self) -> Vec<String> {
        self.parameters().into_iter().map(|p| p.name).collect()
    }

    pub fn values(&self) -> Vec<f64> {
        self.effects
            .iter()
            .flat_map(|e| e.values().iter().copied())
            .collect()
    }

    /// Sets every parameter from the flat vector.
    ///
    /// # Panics
    /// When `values.len() != self.n_parameters()`: a programming error, never user input.
    pub fn set_values(&mut self, values: &[f64]) {
        assert_eq!(
            values.len(),
            self.n_parameters(),
            "flat parameter vector of the wrong length"
        );
        for (i, effect) in self.effects.iter_mut().enumerate() {
            effect
                .values_mut()
                .copy_from_slice(&values[self.starts[i]..self.starts[i + 1]]);
        }
        self.merged = OnceLock::new();
    }

    /// Brings every effect's identified values into its physical range
    /// ([`Effect::make_physical`](super::Effect::make_physical)), `standard_errors` in flat
    /// order; the sentences of what was changed and why.
    pub fn make_physical(&mut self, standard_errors: &[Option<f64>]) -> Vec<String> {
        let mut said = Vec::new();
        for (i, effect) in self.effects.iter_mut().enumerate() {
            let se = standard_errors
                .get(self.starts[i]..self.starts[i + 1])
                .unwrap_or(&[]);
            said.extend(effect.make_physical(se));
        }
        self.merged = OnceLock::new();
        said
    }

    /// Every effect's sparse Jacobian at `state`, with flat parameter indices.
    fn partials(&self, state: &AxisState, scratch: &mut Vec<Partial>, out: &mut Vec<Partial>) {
        let ctx = self.context();
        out.clear();
        for (i, effect) in self.effects.iter().enumerate() {
            scratch.clear();
            effect.jacobian(state, &ctx, scratch);
            out.extend(scratch.iter().map(|p| Partial {
                param: p.param + self.starts[i],
                ..*p
            }));
        }
    }

    /// The target position and its derivative with respect to each parameter that moves it
    /// (flat index, mm per stored unit), sorted by index.
    pub fn target_jacobian(&self, state: &AxisState) -> (Vector3<f64>, Vec<(usize, Vector3<f64>)>) {
        let mut out = Vec::new();
        let p = self.target_jacobian_into(state, &mut JacobianScratch::default(), &mut out);
        (p, out)
    }

    /// [`Self::target_jacobian`] reusing buffers (no allocation once they have grown).
    pub fn target_jacobian_into(
        &self,
        state: &AxisState,
        scratch: &mut JacobianScratch,
        out: &mut Vec<(usize, Vector3<f64>)>,
    ) -> Vector3<f64> {
        let (frames, errors) = self.frames(state);
        let p = frames.target_position(&self.target_a6(), &errors);
        let slots = frames.target_jacobian(&p);
        self.partials(state, &mut scratch.effect, &mut scratch.all);
        compose(&scratch.all, &slots, out);
        p
    }

    /// The flange pose and its derivative with respect to each parameter: position (mm) on
    /// top of the small rotation vector in the base frame (rad), per stored unit.
    pub fn flange_jacobian(&self, state: &AxisState) -> (Frame, Vec<(usize, Vector6<f64>)>) {
        let (frames, _) = self.frames(state);
        let slots = frames.flange_jacobian();
        let mut scratch = JacobianScratch::default();
        self.partials(state, &mut scratch.effect, &mut scratch.all);
        let mut out = Vec::new();
        compose(&scratch.all, &slots, &mut out);
        (frames.flange_pose(), out)
    }
}

/// Reusable buffers of [`Model::target_jacobian_into`].
#[derive(Clone, Debug, Default)]
pub struct JacobianScratch {
    effect: Vec<Partial>,
    all: Vec<Partial>,
}

/// Chain rule over slots, summing entries of the same parameter.
fn compose<V>(partials: &[Partial], slots: &[V], out: &mut Vec<(usize, V)>)
where
    V: Copy + std::ops::Mul<f64, Output = V> + std::ops::AddAssign,
{
    out.clear();
    out.extend(
        partials
            .iter()
            .map(|p| (p.param, slots[p.slot.index()] * p.value)),
    );
    out.sort_by_key(|&(i, _)| i);
    out.dedup_by(|later, kept| {
        let same = later.0 == kept.0;
        if same {
            kept.1 += later.1;
        }
        same
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::geometric::Geometric;

    /// With the measurement target as the tool, the TCP the model predicts is the target
    /// position it was identified on (⁶p included); any other tool is left as programmed.
    #[test]
    fn the_target_as_tool_carries_the_identified_target_vector() {
        let target = Vector3::new(-120.0, -80.0, 180.0);
        let mut model = Model::new(RobotDescription::kr30ha(), Payload::default(), target);
        let mut g = Geometric::default();
        let n = g.values.len();
        g.values[n - 3..].copy_from_slice(&[0.024, -0.015, 0.018]);
        model.push(Box::new(g));
        let state = AxisState::new([20.0, -70.0, 110.0, 15.0, 40.0, -30.0]);
        let errors = model.chain_errors(&state);
        let tool = model.tool_as_identified(&target, &errors);
        let tcp = model.flange_pose(&state) * nalgebra::Point3::from(tool);
        assert!((tcp.coords - model.target_position(&state)).norm() < 1e-9);
        // The correction is 0.034 mm, a real change.
        assert!((tool - target).norm() > 0.03);
        let other = Vector3::new(0.0, 0.0, 200.0);
        assert_eq!(model.tool_as_identified(&other, &errors), other);
    }
}
