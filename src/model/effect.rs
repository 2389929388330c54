//! The one trait every physical error effect implements, and the chain-error vector it writes.
//!
//! Chain errors are the common currency between effects and the error chain. For axis n
//! (index n-1) the chain is, in the paper's frames (MODEL.md):
//! `Trans(L_n + (dx, dy, dz)) · Rx(rx)·Ry(ry)·Rz(rz) · Rot_axis_n(sense_n·(A_n + dθ_n) + offset_n)`
//! where `L_n` is the nominal link vector before axis n. The paper's 18 geometric parameters
//! are exactly some of these slots (e.g. δx21 is axis 2's `dx`, α32 axis 3's `rx`, Δθ40 axis
//! 4's `dθ` in model sign); angular deviations (maps, backlash, crosstalk, compliance) write
//! `dθ`; tilt writes `rx/ry/rz`; drift writes link-length slots. The last three slots displace
//! the measurement target vector (in the A6 frame of the paper).
//!
//! Units: slots are mm and radians; `dθ` is in KUKA sign (actual KUKA angle = command + dθ).

use super::merged::AxisFactor;
use super::state::AxisState;
use super::table::Table1;
use crate::kinematics::RobotDescription;

/// Slots per axis: dx, dy, dz (mm), rx, ry, rz (rad), dθ (rad, KUKA sign).
pub const JOINT_SLOTS: usize = 7;
/// Six axes plus the three target-vector slots.
pub const N_SLOTS: usize = 6 * JOINT_SLOTS + 3;

/// One scalar slot of the chain-error vector.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Slot {
    /// Displacement of axis `axis` (1..=6) along model x/y/z (0, 1, 2), mm.
    Offset { axis: u8, coord: u8 },
    /// Small rotation of axis `axis` about model x/y/z (0, 1, 2), rad.
    Tilt { axis: u8, coord: u8 },
    /// Angular positioning deviation of axis `axis`, rad, KUKA sign.
    Angle { axis: u8 },
    /// Displacement of the measurement target along A6-frame x/y/z, mm.
    Target { coord: u8 },
}

impl Slot {
    /// Index into [`ChainErrors::0`].
    pub const fn index(self) -> usize {
        match self {
            Slot::Offset { axis, coord } => (axis as usize - 1) * JOINT_SLOTS + coord as usize,
            Slot::Tilt { axis, coord } => (axis as usize - 1) * JOINT_SLOTS + 3 + coord as usize,
            Slot::Angle { axis } => (axis as usize - 1) * JOINT_SLOTS + 6,
            Slot::Target { coord } => 6 * JOINT_SLOTS + coord as usize,
        }
    }
}

/// The additive error contributions of all effects at one state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainErrors(pub [f64; N_SLOTS]);

impl Default for ChainErrors {
    fn default() -> Self {
        ChainErrors([0.0; N_SLOTS])
    }
}

impl ChainErrors {
    pub fn add(&mut self, slot: Slot, value: f64) {
        self.0[slot.index()] += value;
    }
    pub fn get(&self, slot: Slot) -> f64 {
        self.0[slot.index()]
    }
}

/// How the chain errors change with the command angles at one state, in slot units (mm, rad)
/// per degree of axis n: what makes the Jacobian of a predicted pose with respect to the
/// command complete (a solver that froze the errors would step short by the table slopes).
/// The angle slots (maps, backlash, crosstalk, compliance) are dense; the rest (tilt …) a
/// short list, empty (and unallocated) for the paper's model.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AxisSlopes {
    /// `angle[k][n]`: d(dθ of axis k+1)/d(A_{n+1}), rad per degree.
    pub angle: [[f64; 6]; 6],
    /// Every other slot: `(slot, n, d slot / d A_{n+1} per degree)`.
    pub other: Vec<(Slot, usize, f64)>,
}

impl AxisSlopes {
    /// Adds d `slot` / d A_{n+1} = `value` (per degree).
    pub fn add(&mut self, slot: Slot, n: usize, value: f64) {
        if value == 0.0 {
            return;
        }
        match slot {
            Slot::Angle { axis } => self.angle[axis as usize - 1][n] += value,
            _ => self.other.push((slot, n, value)),
        }
    }
}

/// Step (degrees) of the central differences of [`Effect::add_with_axis_slopes`]'s default:
/// small against the 1° pitch of tables, large against rounding (errors ~10⁻⁴ rad).
pub const SLOPE_STEP_DEG: f64 = 1e-3;

/// One model parameter as users see it (in reports, calibration files, standard errors).
#[derive(Clone, Debug, PartialEq)]
pub struct Parameter {
    /// e.g. `dx21`, `map:A2[-45.0]`, `backlash:A1[12.0]`.
    pub name: String,
    /// Unit of the stored value: "mm", "deg", "mm/h", "deg/Nm" ...
    pub unit: &'static str,
}

/// One non-zero entry of an effect's Jacobian: d slot / d parameter `param` at a state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Partial {
    pub param: usize,
    pub slot: Slot,
    pub value: f64,
}

/// A measured point as an effect sees it when it sets itself up from the data
/// ([`Effect::start_from_data`]).
#[derive(Clone, Copy, Debug)]
pub struct Observed<'a> {
    /// The test the point belongs to: points of one test (one file's label) share it.
    pub test: usize,
    pub state: &'a AxisState,
    /// The measured target position, mm, in the frame of its file.
    pub measured_mm: nalgebra::Vector3<f64>,
}

/// Read-only data an effect may need besides the state (gravity data, payload).
#[derive(Clone, Copy, Debug)]
pub struct Context<'a> {
    pub robot: &'a RobotDescription,
    pub payload: &'a crate::kinematics::Payload,
}

/// The part an effect's values play for the steps that treat some effects specially:
/// identification's starting values from indexing tests (`identify::direct`), its gauge
/// constraints (`identify::refine`: a table's constant part that another effect also carries
/// is pinned), and the shapes a diagnosis knows the model can absorb (`diagnose::learn`). An
/// effect says what it is here; callers never match its name. Any other effect is `Other`:
/// identified from the data alone, through its Jacobian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Role {
    /// The axis lines' geometry and the target vector, constant over the state (`geometric`):
    /// fitted first, from the circles of indexing tests; its [`Effect::constant_in`]
    /// parameters carry the axes' angle offsets and the target correction.
    AxisLines,
    /// A table `f(A_n)` added to axis n's angle in both rotation directions (`map:An`). Its
    /// mean over the data is an angle offset of the axis: pinned when the offset is free.
    OwnAngle { axis: u8 },
    /// A table over A_n of the difference between axis n's rotation directions
    /// (`backlash:An`): after a motion longer than the effect's reach the deviation is
    /// `mean + direction · per_direction · value`. Told from the own-angle table only by data
    /// on both directions.
    DirectionDifference { axis: u8, per_direction: f64 },
    /// A table `g(A_to, A_from)` added to axis `to`'s angle, rows over A_to and columns over
    /// A_from (`crosstalk:Am->An`). Each row's mean is what the own-angle table of `to`
    /// carries: pinned per row when that table is free, as a whole when only the offset is.
    CrossAngle { from: u8, to: u8 },
    /// Anything else.
    Other,
}

impl Role {
    /// The axis whose angle slot this role's table writes, if any.
    pub fn angle_of(self) -> Option<u8> {
        match self {
            Role::OwnAngle { axis } | Role::DirectionDifference { axis, .. } => Some(axis),
            Role::CrossAngle { to, .. } => Some(to),
            Role::AxisLines | Role::Other => None,
        }
    }
}

/// A number of an effect's calibration record, as [`Effect::record_range`] is asked about it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordValue<'a> {
    /// The value of the record's parameter of this name (a key of its `parameters`).
    Parameter(&'a str),
    /// A value of the record's table (`table.values_deg`).
    Table,
}

/// The physical range of a number of an effect's calibration record. A value outside is not
/// a robot's error but a typing slip, a unit mix-up or a broken fit: the file is refused,
/// naming the key, the range and the value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RecordRange {
    /// From −`bound` to `bound`, in `unit` (as messages name it: "degrees", "mm", …).
    Within {
        /// The largest magnitude that is physical.
        bound: f64,
        /// The value's unit in words.
        unit: &'static str,
    },
    /// Any finite value: the quantity has no physical bound, or the effect's decoder checks
    /// it with its own message (a gear play's width).
    Finite,
}

/// A physical error effect of the contract table (`geometric`, `map:An`, `backlash:An`,
/// `crosstalk:Am->An`, `compliance:An`, `tilt:An`, `drift`).
pub trait Effect: Send + Sync + std::fmt::Debug {
    /// The contract name, e.g. `map:A2` or `crosstalk:A3->A2`.
    fn name(&self) -> String;
    /// Names and units of the parameters, in the order of [`Effect::values`].
    fn parameters(&self) -> Vec<Parameter>;
    /// Current parameter values, in their stored units (see [`Parameter::unit`]).
    fn values(&self) -> &[f64];
    fn values_mut(&mut self) -> &mut [f64];
    /// Adds this effect's contribution at `state` to `errors`.
    fn add_to(&self, state: &AxisState, ctx: &Context, errors: &mut ChainErrors);
    /// Pushes d(chain errors)/d(values) at `state` (stored units) as sparse entries.
    fn jacobian(&self, state: &AxisState, ctx: &Context, out: &mut Vec<Partial>);
    /// [`Self::add_to`] plus how the contribution changes with each axis angle at `state`
    /// (see [`AxisSlopes`]), for the complete Jacobian of a compensation solve. Effects whose
    /// contribution varies with the axes override this with their analytic slopes; the
    /// default differentiates [`Self::add_to`] numerically (central differences, 12 more
    /// evaluations), so that a new effect is right without it, only slower.
    fn add_with_axis_slopes(
        &self,
        state: &AxisState,
        ctx: &Context,
        errors: &mut ChainErrors,
        slopes: &mut AxisSlopes,
    ) {
        self.add_to(state, ctx, errors);
        if !self.varies_with_axes() {
            return;
        }
        for n in 0..6 {
            let at = |delta: f64| {
                let mut moved = *state;
                moved.axes_deg[n] += delta;
                let mut out = ChainErrors::default();
                self.add_to(&moved, ctx, &mut out);
                out
            };
            let (plus, minus) = (at(SLOPE_STEP_DEG), at(-SLOPE_STEP_DEG));
            for (i, (p, m)) in plus.0.iter().zip(&minus.0).enumerate() {
                let slot = crate::model::chain::slot_of_index(i);
                slopes.add(slot, n, (p - m) / (2.0 * SLOPE_STEP_DEG));
            }
        }
    }
    /// Whether the contribution depends on the axis angles or directions. Effects that answer
    /// `false` (the axis lines' geometry, drift) depend on the time at most and are summed once
    /// when a solver evaluates many commands ([`Model::fixed_errors`](super::Model::fixed_errors)).
    fn varies_with_axes(&self) -> bool {
        true
    }
    /// Whether the contribution, when it varies, goes to the axes' angle slots alone (maps,
    /// backlash, crosstalk, compliance): a solver then keeps the rest of the chain fixed per
    /// model ([`LinkBlocks`](super::chain::LinkBlocks)) and sums six angles per evaluation.
    /// `false` unless an effect says so, which is always right, only slower.
    fn adds_angles_only(&self) -> bool {
        false
    }
    /// [`Self::add_to`] into the angle slots alone (`angles[n]`: axis n+1's, rad), for an
    /// effect that [`adds_angles_only`](Self::adds_angles_only). The default goes through a
    /// whole error vector.
    fn add_angles(&self, state: &AxisState, ctx: &Context, angles: &mut [f64; 6]) {
        let mut errors = ChainErrors::default();
        self.add_to(state, ctx, &mut errors);
        for (n, a) in angles.iter_mut().enumerate() {
            *a += errors.get(Slot::Angle { axis: n as u8 + 1 });
        }
    }
    /// [`Self::add_angles`] of an effect that looks a table up, starting from the cells in
    /// `hints` (a hint only, see [`Grid::locate_near`](super::table::Grid::locate_near)),
    /// which then hold the cells used: a solver's commands lie millidegrees apart. The same
    /// sums, to the bit; by default the hint is not used.
    fn add_angles_near(
        &self,
        state: &AxisState,
        ctx: &Context,
        angles: &mut [f64; 6],
        _hints: &mut [usize; 2],
    ) {
        self.add_angles(state, ctx, angles);
    }
    /// `Some((n, table, factor))` when the whole contribution is `factor · table(A_n)` degrees
    /// added to axis n's own angle slot (`map`, `backlash`): a model merges such tables of one
    /// axis that share a grid into one lookup ([`Merged`](super::merged::Merged)).
    fn own_axis_table(&self) -> Option<(u8, &Table1, AxisFactor)> {
        None
    }
    /// Whether `state` lies outside this effect's table range (the value was clamped to the
    /// edge), so that reports can count such points.
    #[cfg(any(test, feature = "internals"))]
    fn clamped(&self, _state: &AxisState) -> bool {
        false
    }
    /// Brings identified values into the effect's physical range, with one sentence per
    /// problem worth telling (`standard_errors`: one per value, `None` where not identified).
    /// A fit is unconstrained; most effects have no physical bound and keep every value.
    fn make_physical(&mut self, _standard_errors: &[Option<f64>]) -> Vec<String> {
        Vec::new()
    }
    /// What the effect's values are for identification and diagnosis (see [`Role`]).
    fn role(&self) -> Role {
        Role::Other
    }
    /// The parameter (index into [`Self::values`]) that adds a constant to `slot` whatever
    /// the state, if the effect has one: the geometry's angle offsets and target correction,
    /// which direct identification sets and gauge fixing asks about.
    fn constant_in(&self, _slot: Slot) -> Option<usize> {
        None
    }
    /// The axes (1..=6) whose rotation direction — the history of the command: the direction
    /// of the last motion, the play — the contribution depends on. A diagnosis that tries an
    /// effect of one axis's direction fits it together with the model's other effects of that
    /// axis's direction, so that a better description of the direction dependence (a gear play
    /// for an instant switch of sign) can take their place rather than add to them.
    fn direction_axes(&self) -> Vec<u8> {
        Vec::new()
    }
    /// Sets what a least-squares fit cannot move (a threshold, a step's position) from the
    /// measured data, when the effect is added for identification; the values a fit moves
    /// may get starting values. Most effects need nothing.
    fn start_from_data(&mut self, _data: &[Observed], _ctx: &Context) {}
    /// After [`Self::start_from_data`]: why the data do not show this effect apart from a
    /// simpler one of the table, if they do not (a diagnosis then does not offer it).
    fn not_shown_by_data(&self) -> Option<String> {
        None
    }
    /// The physical range of a number of this effect's calibration record, which reading a
    /// calibration file checks. By default any finite value: an effect with physical bounds
    /// states them here.
    fn record_range(&self, _value: RecordValue) -> RecordRange {
        RecordRange::Finite
    }
    /// Whether the parameters are the cells of a table over the axes (maps, plays, crosstalk,
    /// a learned function's grid), which a report sums up per effect instead of listing each
    /// cell. `false` by default: each parameter is listed.
    fn parameters_are_cells(&self) -> bool {
        false
    }
}
