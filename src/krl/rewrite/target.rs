//! What a target's numbers become: the new component values of its command in the frame and
//! form its aggregate is written in (absolute, relative, before a geometric operator), and
//! the auxiliary point and end of a `CA` circle written by construction.

use crate::kinematics::{AxisAngles, Pose};
use crate::krl::interpret::{Simulation, Stop};
use crate::motion::frame::{abc_continuous, abc_jumps, kuka_near, Frame};
use crate::motion::nominal::{Arm, Nominal};
use crate::motion::{Programmed, Rel, Role};

use super::{Commanded, Writer};
use crate::compensate::sequence::Outcome;

/// The most orientation an Euler triple kept continuous near B = ±90° may leave out: what the
/// written decimals (1e-4° in A, B and C) leave anyway.
pub(super) const CONTINUITY_LEFT_RAD: f64 = 3.0 * 0.5e-4 * std::f64::consts::PI / 180.0;

impl Writer<'_> {
    /// The new values of `stop` commanded at `axes` (`None`: nothing can be written): axis
    /// angles or a pose as the target programs (a relative target's: its offsets), with the
    /// orientation left out near B = ±90° (see `abc_continuous`), if any.
    pub(super) fn new_values(
        &self,
        stop: &Stop,
        axes: &[f64; 6],
        command: &Commanded,
        original: &[Option<f64>; 6],
    ) -> Option<(Programmed, Option<f64>)> {
        let sim = self.sim;
        // A relative circle's points are both relative to where the motion starts: the
        // target's `prev` is its auxiliary point, whose own `prev` is the start.
        let start_stop = match stop.prev {
            Some(p) if stop.role != Role::Aux && sim.stops[p as usize].role == Role::Aux => {
                sim.stops[p as usize].prev
            }
            p => p,
        };
        let prev_cmd = start_stop.map(|p| self.outcomes[p as usize].axes_deg);
        let programmed = match &stop.programmed {
            Programmed::Axes(_) => {
                return match stop.rel {
                    Some(_) => {
                        let prev = prev_cmd?;
                        let offsets = std::array::from_fn(|i| axes[i] - prev[i]);
                        Some((Programmed::Axes(AxisAngles(offsets)), None))
                    }
                    None => Some((Programmed::Axes(AxisAngles(*axes)), None)),
                }
            }
            Programmed::Pose(p) => p,
        };
        let tool = &sim.frames[stop.tool as usize];
        let base = &sim.frames[stop.base as usize];
        let abc_near = [3, 4, 5].map(|k| original[k].unwrap_or(0.0));
        match stop.rel {
            None => {
                let (pose, left) = self.absolute_values(stop, programmed, base, command, original);
                Some((Programmed::Pose(pose), left))
            }
            Some(rel) => {
                let in_base = base.inverse().compose(&command.tcp);
                let start = base
                    .inverse()
                    .compose(&Nominal(self.robot).tcp(&*prev_cmd?, tool));
                let moved = match rel {
                    Rel::Tool => start.inverse().compose(&in_base),
                    _ => Frame {
                        rotation: in_base.rotation * start.rotation.transpose(),
                        position: in_base.position - start.position,
                    },
                };
                Some((Programmed::Pose(moved.to_kuka_near(&abc_near)), None))
            }
        }
    }

    /// [`Self::new_values`] of an absolute Cartesian target `programmed` in `base`. The
    /// command in the base is worked out only where its [`Commanded::unchosen`] does not do.
    fn absolute_values(
        &self,
        stop: &Stop,
        programmed: &Pose,
        base: &Frame,
        command: &Commanded,
        original: &[Option<f64>; 6],
    ) -> (Pose, Option<f64>) {
        let near_abc = [
            original[3].unwrap_or(programmed.a),
            original[4].unwrap_or(programmed.b),
            original[5].unwrap_or(programmed.c),
        ];
        let operators = stop
            .handle
            .origin
            .as_ref()
            .map_or((None, None), |o| (o.prefix, o.suffix));
        let mut v = match (operators, &command.unchosen) {
            ((None, None), Some(u)) => kuka_near(u, &near_abc),
            _ => self
                .written_frame(operators, base, &command.tcp)
                .to_kuka_near(&near_abc),
        };
        // Near B = ±90° the angles stay continuous with the program's (`abc_continuous`)
        // where that costs no more than the written decimals; beyond, the exact triple is
        // written (A and C turn together there, A ∓ C stays continuous): an orientation
        // correction left out would leave the TCP off by it times the tool's lever.
        let mut euler_left = None;
        if stop.role == Role::Target && abc_jumps(v.abc(), &near_abc) {
            let written = self.written_frame(operators, base, &command.tcp);
            if let Some(([a, b, c], left)) = abc_continuous(&written.rotation, v.abc(), &near_abc)
                .filter(|(_, left)| *left <= CONTINUITY_LEFT_RAD)
            {
                (v.a, v.b, v.c) = (a, b, c);
                euler_left = Some(left);
            }
        }
        (v, euler_left)
    }

    /// The pose written for the command `tcp` of a target in `base` whose geometric operators
    /// are `(prefix, suffix)`: the command in the base, or before the prefix frame, or after
    /// the suffix (`P : offset`: the point is what puts the TCP there once offset).
    fn written_frame(
        &self,
        (prefix, suffix): (Option<u32>, Option<u32>),
        base: &Frame,
        tcp: &Frame,
    ) -> Frame {
        let in_base = base.inverse().compose(tcp);
        match (prefix, suffix) {
            (Some(i), _) => self.sim.prefixes[i as usize].inverse().compose(&in_base),
            (None, Some(i)) => in_base.compose(&self.sim.prefixes[i as usize].inverse()),
            (None, None) => in_base,
        }
    }
}

/// Whether stop `i`'s numbers are rewritten: a compensated target that changed, and the
/// auxiliary point of a `CA` circle written by construction exactly when its end is (it is
/// moved onto that circle).
pub(super) fn written(sim: &Simulation, outcomes: &[Outcome], i: usize) -> bool {
    let done = |i: usize| {
        let (stop, o) = (&sim.stops[i], &outcomes[i]);
        stop.compensable && o.changed && o.error.is_none()
    };
    let stop = &sim.stops[i];
    if stop.role == Role::Aux && i + 1 < outcomes.len() && sim.arc_ending_at(i + 1).is_some() {
        return stop.compensable && done(i + 1);
    }
    done(i)
}

impl Writer<'_> {
    /// For the auxiliary point and end of a `CA` circle written by construction, the pose to
    /// write (`Some(None)`: no such circle; `None`: not such a stop).
    ///
    /// The controller moves on the circle through the start S', the written auxiliary point A'
    /// and target T' (S' → A' → T'), and stops after turning by `CA` from S', with T''s
    /// orientation. `CA` is the user's number and stays; S' is the previous target's command;
    /// the end must be E_c, the compensated end. So the written circle C' is the one through S'
    /// and E_c turning by exactly `CA` between them (radius |E_c − S'| / (2|sin(CA/2)|)), in the
    /// plane through S', the compensated auxiliary point A_c and E_c — or, where the nominal
    /// points define their plane poorly (A near the start or the end, see
    /// `interpolate::PLANE_MIN_SINE`), the nominal plane carried over, tilted as little as the
    /// chord S'E_c requires — turning the nominal way (`CircularAngle::sense`); A' and T'
    /// are its points at the angles A and T had on the nominal circle — any two points of C'
    /// beyond S' define it, these keep the written circle's points where the nominal ones were
    /// up to the correction (the nominal S, A, E give back the nominal circle exactly). T' takes
    /// E_c's orientation (the controller ends with the target's); A''s orientation is not
    /// written.
    pub(super) fn circular_angle(&self, i: usize) -> Option<Option<Frame>> {
        let (sim, outcomes) = (self.sim, self.outcomes);
        let stop = &sim.stops[i];
        let (end, aux) = match stop.role {
            Role::Aux => (i + 1, i),
            _ => (i, i.checked_sub(1)?),
        };
        let arc = sim.arc_ending_at(end).filter(|_| end < outcomes.len())?;
        let tool = &sim.frames[sim.stops[end].tool as usize];
        let Some(start) = sim.stops[aux].prev else {
            return Some(None);
        };
        // Where the controller starts: the previous command's axes with this motion's tool.
        let s_c = Nominal(self.robot).tcp(&outcomes[start as usize].axes_deg, tool);
        let a_c = match outcomes[aux].error {
            None => self.commanded(aux).tcp,
            Some(_) => sim.stops[aux].goal,
        };
        let e_c = self.commanded(end).tcp;
        use crate::motion::interpolate::{circle_by_angle, ArcPlane};
        let near = ArcPlane::Near(arc.normal);
        let plane = if arc.from_points {
            ArcPlane::Points {
                aux: a_c.position,
                sense: arc.sense,
            }
        } else {
            near
        };
        let circle = circle_by_angle(&s_c, &e_c, arc.angle_deg, plane)
            .or_else(|| circle_by_angle(&s_c, &e_c, arc.angle_deg, near));
        let Some(circle) = circle else {
            return Some(None);
        };
        let at = |deg: f64| circle.pose(deg / arc.angle_deg).position;
        Some(Some(if i == aux {
            Frame {
                rotation: a_c.rotation,
                position: at(arc.aux_deg),
            }
        } else {
            Frame {
                rotation: e_c.rotation,
                position: at(arc.target_deg),
            }
        }))
    }
}
