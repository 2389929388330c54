//! The language-neutral motion form: what a front end's interpreter yields for every executed
//! motion target, and all that the planning, the compensation and the model read of a
//! program. A [`Stop`] holds the target (as a pose in the robot base frame and as the values
//! programmed: axes or a pose), the interpolation into it, its tool and base, the
//! controller's nominal axes and each axis's arrival motion, and an opaque `handle` of the
//! front end's own type (for KRL: the statement, the aggregate holding the numbers, the
//! variable named), which only that front end's rewriter reads to place the new numbers.
//! Nothing here knows any robot language.

use crate::kinematics::{AxisAngles, Pose};

use super::frame::Frame;
use super::interpolate;

/// Stops executed before a cut that the segment after it needs: a circle's end looks back to
/// its start through its auxiliary point; the compensation carries as many.
pub const CARRIED_STOPS: usize = 2;

/// How the robot moves into a stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Axis-interpolated (KRL's `PTP`, `SPTP`).
    Joint,
    /// Along a straight line, or a spline's curve where [`Stop::spline`] says so (`LIN`,
    /// `SLIN`, `SPL`).
    Linear,
    /// Along a circle through an auxiliary point (`CIRC`, `SCIRC`).
    Circular,
}

/// What the target of a stop is relative to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rel {
    /// Relative in the base (KRL's `_REL … #BASE`, the default): offset along the base axes,
    /// rotation about them.
    Base,
    /// Relative in the tool (`_REL … #TOOL`): `current · offset`.
    Tool,
    /// Axis-specific (`PTP_REL {A1 …}`): added to the current axes.
    Axis,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Target,
    /// The auxiliary point of a circular motion.
    Aux,
    /// Where a circular motion with an angle ends when its numbers are compensated as a plain
    /// circle's (a whole turn, see [`CircularAngle`]): not written, there for the directions
    /// and the start of the next motion.
    End,
}

/// A circular motion with an angle (KRL's `CA`) whose end stop is compensated as a target of
/// its own and written by constructing the circle: the nominal circle through start S,
/// auxiliary point A and target T, right-hand `normal` (S → A → T turns positively), the
/// angles of A and T from S on it and the written angle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CircularAngle {
    /// Index of the end stop (its auxiliary point's is the one before).
    pub end: u32,
    pub angle_deg: f64,
    pub aux_deg: f64,
    pub target_deg: f64,
    pub normal: nalgebra::Vector3<f64>,
    /// The sign making `sense · (A − S) × (E − S)` point along `normal` (E the end).
    pub sense: f64,
    /// Whether S, A and E define their plane well (`interpolate::plane_well_defined`): the
    /// written circle then lies in the plane of their compensated positions, else in the
    /// nominal plane carried over.
    pub from_points: bool,
}

/// The circle with an angle ending at stop `end` among `arcs` (sorted by end stop).
pub fn arc_ending_at(arcs: &[CircularAngle], end: usize) -> Option<&CircularAngle> {
    arcs.binary_search_by_key(&(end as u32), |a| a.end)
        .ok()
        .map(|i| &arcs[i])
}

/// Whether the robot passes stop `i` by without visiting it: the auxiliary point of a
/// circle with an angle only sets the circle's plane (the circle starts from the stop before).
pub fn passes_by<H>(stops: &[Stop<H>], arcs: &[CircularAngle], i: usize) -> bool {
    stops[i].role == Role::Aux && arc_ending_at(arcs, i + 1).is_some()
}

/// What a motion target programs, as the controller completes it: axis angles or a pose,
/// never six numbers a reader must guess the meaning of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Programmed {
    /// An axis target: the axis angles, degrees (a relative target's: the start's plus the
    /// offsets).
    Axes(AxisAngles),
    /// A Cartesian target: the pose in the base, mm and degrees (a relative target's: where
    /// its offset takes the start).
    Pose(Pose),
}

impl Programmed {
    /// An axis target.
    #[cfg(any(test, feature = "internals"))]
    pub fn is_axes(&self) -> bool {
        matches!(self, Programmed::Axes(_))
    }

    /// The six numbers: the axes `A1..A6`, or the pose's `X Y Z A B C`.
    pub fn components(&self) -> [f64; 6] {
        match self {
            Programmed::Axes(q) => q.0,
            Programmed::Pose(p) => p.to_array(),
        }
    }
}

/// Where a spline segment lies in its chain of points: the curve's tangents at its ends
/// depend on the point before its start (none when the start is the chain's `first` point)
/// and on the point after its end (none when it is the `last`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SplineEnds {
    pub first: bool,
    pub last: bool,
}

/// One executed motion target; `H` is the front end's handle (opaque here).
#[derive(Clone, Copy, Debug)]
pub struct Stop<H> {
    pub interpolation: Interpolation,
    pub role: Role,
    /// The programmed TCP pose in the robot base frame.
    pub goal: Frame,
    /// Index in the walk's frames of the tool (flange → TCP) and of the base.
    pub tool: u32,
    pub base: u32,
    /// The controller's axes for the programmed target.
    pub nominal_axes: AxisAngles,
    /// Arrival motion of each axis (see `interpolate`); `None` after an unknown position.
    pub arrival: Option<[f64; 6]>,
    /// Each axis's last turning point inside the motion that reaches this stop (see
    /// `interpolate::Arrival::turns`).
    pub turns: interpolate::Turns,
    /// The programmed values as the controller completes them, absolute (missing components
    /// from the start; a relative target's missing offsets zero).
    pub programmed: Programmed,
    /// The configuration's turn bits are programmed and kept (a Cartesian joint motion with
    /// its turn given).
    pub keep_t: bool,
    pub rel: Option<Rel>,
    /// The stop this motion starts from.
    pub prev: Option<u32>,
    /// False when the target must be left as written (a warning says why).
    pub compensable: bool,
    /// The arrival is computed after the walk (a short linear segment, by the interpreter).
    pub(crate) deferred: bool,
    /// A spline segment that follows the block's curve: where it lies in its chain.
    pub spline: Option<SplineEnds>,
    /// A copy of a stop executed before a streamed segment began: there for continuity, not
    /// a target of this segment.
    pub ghost: bool,
    /// The front end's own record of where the stop comes from and where its numbers go.
    pub handle: H,
}

/// The commanded axis states of a program run, in execution order: every target's nominal
/// axes with each axis's history as the simulated motion leaves it (rotation direction on
/// arrival, the turning points inside the interpolated motions; see `model::AxisHistory`).
/// Histories start unmoved, and again after a position the simulation could not follow.
pub fn program_states<H>(
    stops: &[Stop<H>],
    arcs: &[CircularAngle],
) -> Vec<crate::model::AxisState> {
    let mut previous: Option<crate::model::AxisState> = None;
    stops
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let state = match (s.arrival, &previous) {
                (Some(_), Some(p)) => p.then_through(&s.turns.angle_deg, s.nominal_axes.into()),
                _ => crate::model::AxisState::new(s.nominal_axes.into()),
            };
            if !passes_by(stops, arcs, i) {
                previous = Some(state);
            }
            state
        })
        .collect()
}
