//! Motion targets: completes a programmed position as the controller does, chooses the
//! controller's axes (IK with S/T or nearness), samples the interpolation for the arrival
//! motion and records the [`Stop`]s of a motion (and of a circle's auxiliary point).

use crate::kinematics::{self, status_turn, AxisAngles, Pose, Select};
use crate::krl::{Expr, Motion, RelFrameKind, Stmt};

use super::eval::reason;
use super::*;
use crate::krl::interpret::value::{Components, Pos, Value};
use crate::krl::interpret::workspace::FileId;
use crate::motion::frame::Frame;
use crate::motion::interpolate::{self, Cartesian, Path};
use crate::motion::nominal::Nominal;

impl<'f> Simulator<'f> {
    // ---- motions ---------------------------------------------------------------------------

    pub(super) fn frames_index(&mut self, f: &Frame) -> u32 {
        if let Some(i) = self.out.frames.iter().rposition(|g| g == f) {
            return i as u32;
        }
        self.out.frames.push(*f);
        (self.out.frames.len() - 1) as u32
    }

    /// A stop of motion statement `s` in the given base and tool (interned), as a target left
    /// unchanged until the caller says otherwise.
    fn stop_of(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        kind: MotionKind,
        rel: Option<Rel>,
        (base, tool): (&Frame, &Frame),
    ) -> Stop<'f> {
        let tool = self.frames_index(tool);
        let base = self.frames_index(base);
        blank_stop(file, s, kind, rel, (base, tool))
    }

    /// [`Self::stop_of`] pushed ([`Self::push_stop`]), for the caller to fill in where it
    /// lies: a stop is 430 bytes, built in its place rather than moved there twice.
    fn push_stop_of(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        kind: MotionKind,
        rel: Option<Rel>,
        (base, tool): (&Frame, &Frame),
    ) -> u32 {
        let tool = self.frames_index(tool);
        let base = self.frames_index(base);
        self.reserve_stop();
        let stops = &mut self.out.stops;
        stops.push(blank_stop(file, s, kind, rel, (base, tool)));
        (stops.len() - 1) as u32
    }

    /// The position `e` of motion `s`, or `None` (the motion lost, saying why) when it is not
    /// known before run time.
    fn position(
        &mut self,
        file: FileId,
        s: &Stmt,
        e: &'f Expr,
        scope: &Scope<'f>,
        what: &str,
    ) -> Option<Pos<'f>> {
        match self.eval(file, e, scope) {
            Value::Pos(pos) => Some(pos),
            other => {
                let why = reason(&other, what);
                self.lost(
                    file,
                    s,
                    format!("{what} is not known before run time ({why})"),
                );
                None
            }
        }
    }

    fn push_stop(&mut self, stop: Stop<'f>) -> u32 {
        self.reserve_stop();
        self.out.stops.push(stop);
        (self.out.stops.len() - 1) as u32
    }

    /// Room for the next stop.
    #[inline]
    fn reserve_stop(&mut self) {
        if self.out.stops.len() == self.out.stops.capacity() && self.out.stops.capacity() < 64 {
            // A streamed window's walker starts with room for its history only: one stop per
            // top-level statement (a window is a flat list of them) saves regrowing a few MB
            // of stops per window; loops beyond that grow as usual.
            let statements: usize = self.ws.files.iter().map(|f| f.file.body().len()).sum();
            self.out.stops.reserve(statements);
        }
    }

    /// The base and tool for a Cartesian motion, or an error naming where the frame was lost.
    pub(super) fn motion_frames(&mut self, file: FileId, s: &Stmt) -> Option<(Frame, Frame)> {
        // Both known (nearly every motion): nothing to say, no state cloned.
        if let (FrameState::Known(base), FrameState::Known(tool)) =
            (&self.state.base, &self.state.tool)
        {
            return Some((*base, *tool));
        }
        let mut out = [Frame::identity(); 2];
        for (k, st) in [self.state.base.clone(), self.state.tool.clone()]
            .iter()
            .enumerate()
        {
            match st {
                FrameState::Known(f) => out[k] = *f,
                FrameState::Unset => {
                    if !self.warned_frames {
                        self.warned_frames = true;
                        self.warn(
                            file,
                            s.head,
                            format!(
                                "{} is not set before this motion: assuming $NULLFRAME (set it in the program, or the compensation uses the wrong TCP)",
                                if k == 0 { "$BASE" } else { "$TOOL" }
                            ),
                        );
                    }
                }
                FrameState::Unknown(f, span, why, hint) => {
                    let msg = if why.is_empty() {
                        "unknown frame".to_string()
                    } else {
                        why.clone()
                    };
                    let (f, span) = if span.is_empty() && *f == 0 {
                        (file, s.head)
                    } else {
                        (*f, *span)
                    };
                    let hint = self
                        .frames_without_config()
                        .unwrap_or_else(|| hint.to_string());
                    self.error(f, span, format!("{msg}: {hint}"));
                    return None;
                }
            }
        }
        Some((out[0], out[1]))
    }

    pub(super) fn lost(&mut self, file: FileId, s: &Stmt, why: String) {
        self.out.lost += 1;
        self.warn(
            file,
            s.head,
            format!(
                "{why}: this motion is left unchanged and the robot's position after it is unknown"
            ),
        );
        self.state.current = None;
    }

    /// Executes motion statement `s` (`m`). Not inlined into [`Self::stmt`]: every statement
    /// enters that frame, only motions need this one's (a few kB of poses and records).
    #[inline(never)]
    pub(super) fn motion(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        m: &'f Motion,
        scope: &mut Scope<'f>,
    ) {
        let saved = self.apply_with(file, m.with(), scope);
        self.motion_inner(file, s, m, scope);
        if let Some(saved) = saved {
            self.restore(saved);
        }
    }

    pub(super) fn motion_inner(
        &mut self,
        file: FileId,
        s: &'f Stmt,
        m: &'f Motion,
        scope: &mut Scope<'f>,
    ) {
        if let Some((f, span)) = self.state.external_tcp {
            self.error(
                f,
                span,
                "$IPO_MODE #TCP (external TCP, the workpiece carried by the robot) is not supported: the program is refused",
            );
            self.state.current = None;
            return;
        }
        let (pos, reference) = match self.offset_point(file, &m.target, scope) {
            Some(found) => found,
            None => {
                let Some(pos) = self.position(file, s, &m.target, scope, "the target") else {
                    return;
                };
                (pos, geometric_operand(&m.target))
            }
        };
        if pos.s.is_some_and(|st| st & ABSOLUTELY_ACCURATE != 0) {
            self.error(
                file,
                s.head,
                "this point's Status S has bit 4 set: it was taught on an absolutely accurate robot, whose positionally accurate model corrects it already; compensating it again would apply a correction twice, so the program is refused (give the points as taught with the nominal model)",
            );
            self.state.current = None;
            return;
        }
        if pos.origin.is_some_and(|o| o.external) && !self.noted_external {
            self.noted_external = true;
            self.warn(
                file,
                s.head,
                "the target moves external axes (E1…E6 not all zero): they are passed through unchanged, and the robot's six axes are compensated for the TCP pose in $BASE as the program sets it (an external axis that carries the robot or the base is not simulated)",
            );
        }
        let rel = m.kind.is_relative().then(|| {
            if pos.v.is_axes() {
                Rel::Axis
            } else if m.frame().is_some_and(|f| f.kind == RelFrameKind::Tool) {
                Rel::Tool
            } else {
                Rel::Base
            }
        });
        // An axis target of a PTP needs no frame (the tool only weighs orientation errors).
        let needs_frames = !pos.v.is_axes() || !m.kind.is_joint() || m.aux().is_some();
        let (base, tool) = if needs_frames {
            match self.motion_frames(file, s) {
                Some(f) => f,
                None => {
                    self.state.current = None;
                    return;
                }
            }
        } else {
            (
                self.known(&self.state.base).unwrap_or_else(Frame::identity),
                self.known(&self.state.tool).unwrap_or_else(Frame::identity),
            )
        };
        let current = self.state.current;
        // Where the TCP starts: the previous target's goal when it was reached with the same
        // tool (the controller's axes there reproduce it), else the FK of the axes.
        let start_tcp = current.map(|c| {
            let same_tool = c
                .stop
                .map(|i| &self.out.stops[i as usize])
                .filter(|p| p.role == Role::Target && self.out.frames[p.tool as usize] == tool);
            match same_tool {
                Some(p) if p.nominal_axes == c.axes => p.goal,
                _ => Nominal(&self.robot).tcp(&c.axes, &tool),
            }
        });
        // The programmed position, completed as the controller does.
        let Some((programmed, goal, s_t)) =
            self.complete(&pos, rel, current, &base, &tool, start_tcp.as_ref())
        else {
            self.lost(
                file,
                s,
                "a partial or relative position whose start is unknown".into(),
            );
            return;
        };
        // Circular motions: the auxiliary point first.
        let (aux_stop, circle) = if m.aux().is_some() {
            let frames = (&base, &tool);
            let start = (current, start_tcp);
            let Some((i, cart)) = self.aux_point((file, s, m), scope, start, rel, frames, &goal)
            else {
                return;
            };
            (Some(i), Some(cart))
        } else {
            (None, None)
        };
        // The controller's axes for the target.
        let q = if let Programmed::Axes(q) = programmed {
            q.into()
        } else {
            let (s_given, t_given) = s_t;
            let select = match (m.kind.is_joint(), current) {
                (true, _) if s_given.is_some() && t_given.is_some() => Select::Status {
                    s: s_given.unwrap_or(0),
                    t: t_given,
                },
                (true, Some(c)) => Select::StatusNearest {
                    s: s_given.unwrap_or_else(|| status_turn(&self.robot, &c.axes).0),
                    near: c.axes,
                },
                (true, None) => match s_given {
                    Some(s) => Select::Status { s, t: None },
                    None => Select::Nearest(HOME),
                },
                (false, Some(c)) => Select::StatusNearest {
                    s: status_turn(&self.robot, &c.axes).0,
                    near: c.axes,
                },
                (false, None) => match s_given {
                    Some(s) => Select::Status { s, t: t_given },
                    None => Select::Nearest(HOME),
                },
            };
            let flange = goal.compose(&tool.inverse());
            match kinematics::inverse(&self.robot, &flange, select) {
                Ok(sol) => sol.axes_deg,
                Err(e) => {
                    self.unreachable(file, s, format!("the target cannot be reached: {e}"));
                    return;
                }
            }
        };
        if pos.v.is_axes() && !self.robot.within_limits(&q) {
            // The controller refuses it: an error of this target, as an unreachable one.
            let beyond = (0..6)
                .find(|&i| q[i] < self.robot.limits_deg[i][0] || q[i] > self.robot.limits_deg[i][1])
                .map(|i| {
                    format!(
                        "A{} = {}° is outside its limits [{}, {}]°",
                        i + 1,
                        q[i],
                        self.robot.limits_deg[i][0],
                        self.robot.limits_deg[i][1]
                    )
                })
                .unwrap_or_default();
            self.unreachable(
                file,
                s,
                format!("the axis target is beyond the joint limits ({beyond}), which the controller refuses"),
            );
            return;
        }
        let goal = if pos.v.is_axes() {
            Nominal(&self.robot).tcp(&q, &tool)
        } else {
            goal
        };
        if let (Some(t), false) = (&self.state.ori_type, m.kind.is_joint()) {
            let t = String::from_utf8_lossy(t).into_owned();
            self.warn(
                file,
                s.head,
                format!("$ORI_TYPE #{t} is not simulated: the orientation is taken as interpolated from the start to the target (#VAR), so the wrist axes' rotation directions and the orientation compensated for this target may not be the robot's"),
            );
        }
        // `CA`: the motion ends on the circle at that angle from the start (towards the
        // auxiliary point when positive), with the target's orientation, not at the target.
        // Two ways to compensate it (`ArcMode`): the end as a target of its own, the circle
        // written through it (`crate::krl::rewrite`); or, where the end is (nearly) the start
        // again, the auxiliary point and target as a plain circle's, the end recorded after
        // them for the directions and the next motion's start.
        let mut through = None;
        if let (Some(ca), Some(cart), Some(cur), Some(aux_i)) =
            (m.angle(), &circle, current, aux_stop)
        {
            let circle = (&ca.value, cart, start_tcp, cur, aux_i);
            let target = (&goal, programmed, &pos, reference);
            match self.arc_end((file, s, m), scope, circle, target, rel, (&base, &tool)) {
                ArcEnd::Done => return,
                ArcEnd::Through(end) => through = Some(end),
            }
        }
        let path = if m.kind.is_joint() {
            Path::Ptp
        } else if let (Some(_), Some(aux_i)) = (&circle, aux_stop) {
            Path::Circ {
                aux: self.out.stops[aux_i as usize].goal.position,
            }
        } else {
            Path::Lin
        };
        // A short straight segment: its arrival rate is computed after the walk, in parallel
        // with all the others (`finish`). It turns by 5° at most, so never by the half turn
        // warned of below.
        let short_lin = current.is_some()
            && path == Path::Lin
            && start_tcp.is_some_and(|start| interpolate::lin_needs_no_samples(&start, &goal));
        if let (Some(start), false, false) = (start_tcp, path == Path::Ptp, short_lin) {
            if crate::motion::frame::half_turn_apart(&start.rotation, &goal.rotation) {
                self.warn(
                    file,
                    s.head,
                    "the orientation turns by 180° here: which way it turns is a tie the controller decides, so the rotation directions assumed for this target may not be the robot's — give the target an orientation less than 180° from the previous one",
                );
            }
        }
        let mut q = q;
        let mut deferred = false;
        let mut turns = interpolate::NO_TURNS;
        let arrival = match (current, start_tcp) {
            (Some(_), Some(_)) if short_lin => {
                deferred = true;
                None
            }
            (Some(cur), Some(start)) => {
                let (rate, end, arrived) =
                    self.sampled_arrival((file, s), &path, &tool, (&start, &cur.axes), (&goal, &q));
                (q, turns) = (end, arrived);
                Some(rate)
            }
            _ => None,
        };
        let in_config = pos.origin.is_some_and(|o| {
            self.ws.get(o.file).role == crate::krl::interpret::workspace::Role::Config
        });
        // A point of `$config.dat` is shared by every program of the cell: its compensated
        // copy goes into this module's data list under a new name (see `crate::krl::rewrite`),
        // which needs a data list and a point named here.
        let localizable = in_config
            && self.ws.get(file).partner.is_some_and(|d| {
                self.ws.get(d).role != crate::krl::interpret::workspace::Role::Config
            })
            && reference.is_some()
            && pos.origin.and_then(|o| o.var).is_some_and(|v| !v.element);
        let compensable = pos.origin.is_some() && (!in_config || localizable);
        let shared = pos
            .origin
            .filter(|_| in_config && !localizable)
            .map(|o| o.file);
        self.warn_unwritable(file, s, pos.origin.is_none(), shared);
        let idx = self.push_stop_of(file, s, m.kind, rel, (&base, &tool));
        let stop = &mut self.out.stops[idx as usize];
        stop.goal = goal;
        stop.nominal_axes = q.into();
        stop.arrival = arrival;
        stop.turns = turns;
        stop.programmed = programmed;
        stop.keep_t = !pos.v.is_axes() && m.kind.is_joint() && s_t.1.is_some();
        stop.handle.origin = pos.origin;
        stop.handle.reference = reference;
        stop.prev = aux_stop.or(current.and_then(|c| c.stop));
        stop.compensable = compensable;
        stop.deferred = deferred;
        if let (None, Programmed::Pose(p)) = (rel, programmed) {
            self.state.last_abc = [p.a, p.b, p.c];
        }
        self.state.current = Some(Current {
            axes: q,
            stop: Some(idx),
        });
        // A circle compensated through its points ends after its target.
        if let Some(mut end) = through {
            let axes = end.nominal_axes.into();
            end.prev = Some(idx);
            let idx = self.push_stop(*end);
            self.state.current = Some(Current {
                axes,
                stop: Some(idx),
            });
        }
    }

    /// The auxiliary point of circular motion `m` recorded as a stop before its target `goal`,
    /// with the circle; `None` when `m` is not a circle or (the motion lost, saying why) the
    /// point is not known. Apart from the motion's body, whose frame every motion enters: its records
    /// (a stop, the circle) are there only for the rare circle.
    #[inline(never)]
    fn aux_point(
        &mut self,
        (file, s, m): (FileId, &'f Stmt, &'f Motion),
        scope: &Scope<'f>,
        (current, start_tcp): (Option<Current>, Option<Frame>),
        rel: Option<Rel>,
        (base, tool): (&Frame, &Frame),
        goal: &Frame,
    ) -> Option<(u32, Cartesian)> {
        let aux_expr = m.aux()?;
        let aux = self.position(file, s, aux_expr, scope, "the auxiliary point")?;
        let (Some(cur), Some(start)) = (current, start_tcp) else {
            self.lost(file, s, "a circular motion whose start is unknown".into());
            return None;
        };
        let Some((aux_prog, aux_goal, _)) =
            self.complete(&aux, rel, current, base, tool, start_tcp.as_ref())
        else {
            self.lost(file, s, "an auxiliary point whose start is unknown".into());
            return None;
        };
        let cart = match Cartesian::new(
            &start,
            goal,
            &Path::Circ {
                aux: aux_goal.position,
            },
        ) {
            Ok(c) => c,
            Err(e) => {
                self.lost(file, s, e.to_string());
                return None;
            }
        };
        let u_aux = cart.fraction_at(&aux_goal.position);
        let aux_pose = Frame {
            rotation: cart.pose(u_aux).rotation,
            position: aux_goal.position,
        };
        let s_cur = status_turn(&self.robot, &cur.axes).0;
        let q_aux = match kinematics::inverse(
            &self.robot,
            &aux_pose.compose(&tool.inverse()),
            Select::StatusNearest {
                s: s_cur,
                near: cur.axes,
            },
        ) {
            Ok(sol) => sol.axes_deg,
            Err(e) => {
                self.unreachable(
                    file,
                    s,
                    format!("the auxiliary point cannot be reached: {e}"),
                );
                return None;
            }
        };
        let mut q_aux = q_aux;
        let mut turns = interpolate::NO_TURNS;
        let arrival =
            match interpolate::arrival_along(&self.robot, tool, &cart, u_aux, &cur.axes, &q_aux) {
                Ok(a) => {
                    q_aux = a.end;
                    turns = a.turns;
                    Some(a.rate)
                }
                Err(e) => {
                    self.warn(
                        file,
                        s.head,
                        format!("auxiliary point: {e}; directions from the axis steps"),
                    );
                    Some(std::array::from_fn(|i| q_aux[i] - cur.axes[i]))
                }
            };
        let aux_ref = aux_expr.as_path().filter(|p| p.is_simple()).map(|p| p.root);
        let stop = Stop {
            role: Role::Aux,
            goal: aux_pose,
            nominal_axes: q_aux.into(),
            arrival,
            turns,
            programmed: aux_prog,
            prev: cur.stop,
            compensable: aux.origin.is_some(),
            ..with_place(
                self.stop_of(file, s, m.kind, rel, (base, tool)),
                aux.origin,
                aux_ref,
            )
        };
        Some((self.push_stop(stop), cart))
    }

    /// Where circular motion `m` with `CA` (`angle_expr`) ends: recorded as a target of its
    /// own, or, compensated through the circle's points, the end stop to record after the
    /// target (see [`ArcMode`]). Apart from the motion's body, like [`Self::aux_point`].
    #[inline(never)]
    fn arc_end(
        &mut self,
        (file, s, m): (FileId, &'f Stmt, &'f Motion),
        scope: &Scope<'f>,
        (angle_expr, cart, start_tcp, cur, aux_i): (
            &'f Expr,
            &Cartesian,
            Option<Frame>,
            Current,
            u32,
        ),
        (goal, programmed, pos, reference): (&Frame, Programmed, &Pos<'f>, Option<Span>),
        rel: Option<Rel>,
        (base, tool): (&Frame, &Frame),
    ) -> ArcEnd<'f> {
        let angle = self.eval(file, angle_expr, scope).as_f64();
        let ended = angle.and_then(|a| Some((a, cart.with_arc_angle(a, &goal.rotation)?)));
        let Some((angle, arc)) = ended else {
            self.lost(
                file,
                s,
                "a circular angle CA not known before run time".into(),
            );
            return ArcEnd::Done;
        };
        let end = arc.pose(1.0);
        let s_cur = status_turn(&self.robot, &cur.axes).0;
        let flange = end.compose(&tool.inverse());
        let select = Select::StatusNearest {
            s: s_cur,
            near: cur.axes,
        };
        let q_end = match kinematics::inverse(&self.robot, &flange, select) {
            Ok(sol) => sol.axes_deg,
            Err(e) => {
                self.unreachable(
                    file,
                    s,
                    format!("the end of the circle (CA) cannot be reached: {e}"),
                );
                return ArcEnd::Done;
            }
        };
        let walked = interpolate::arrival_along(&self.robot, tool, &arc, 1.0, &cur.axes, &q_end);
        let (q_end, arrival, turns) = match walked {
            Ok(a) => (a.end, Some(a.rate), a.turns),
            Err(e) => {
                self.warn(file, s.head, format!("{e}; directions from the axis steps"));
                let steps = std::array::from_fn(|i| q_end[i] - cur.axes[i]);
                (q_end, Some(steps), interpolate::NO_TURNS)
            }
        };
        let end_stop = Stop {
            goal: end,
            nominal_axes: q_end.into(),
            arrival,
            turns,
            programmed,
            prev: Some(aux_i),
            ..self.stop_of(file, s, m.kind, rel, (base, tool))
        };
        match ArcMode::of(angle) {
            ArcMode::Through { whole } => {
                let why = if whole {
                    format!("a whole circle (CA {angle}) ends where it starts: its auxiliary point and target are compensated as a plain circle's, its end keeps the start's command (compensated for the motion into the start, not for the circle's own rotation directions)")
                } else {
                    format!("CA {angle} is within {THROUGH_DEG}° of a whole turn: compensated through the circle's points (auxiliary point and target as a plain circle's), its end only as closely as that circle passes it")
                };
                self.warn(file, s.head, why);
                ArcEnd::Through(Box::new(Stop {
                    role: Role::End,
                    ..end_stop
                }))
            }
            ArcMode::Construct => {
                let (normal, turn) = cart.arc_turn().expect("a circle");
                let aux_at = self.out.stops[aux_i as usize].goal.position;
                let start = start_tcp.expect("a circle has a start").position;
                let sense = interpolate::plane_normal(&start, &aux_at, &end.position, 1.0)
                    .map_or(1.0, |n| n.dot(&normal).signum());
                let in_config = pos.origin.is_some_and(|o| {
                    self.ws.get(o.file).role == crate::krl::interpret::workspace::Role::Config
                });
                let shared = pos.origin.filter(|_| in_config).map(|o| o.file);
                self.warn_unwritable(file, s, pos.origin.is_none(), shared);
                // The written circle needs its auxiliary point moved onto it.
                let aux_written = self.out.stops[aux_i as usize].compensable;
                if !aux_written {
                    self.warn(
                        file,
                        s.head,
                        "the auxiliary point of this circle (CA) cannot be rewritten, and the circle's end cannot move without it: left unchanged",
                    );
                }
                let stop = Stop {
                    compensable: pos.origin.is_some() && !in_config && aux_written,
                    handle: Handle {
                        origin: pos.origin,
                        reference,
                        ..end_stop.handle
                    },
                    ..end_stop
                };
                let idx = self.push_stop(stop);
                self.out.arcs.push(crate::motion::CircularAngle {
                    end: idx,
                    angle_deg: angle,
                    aux_deg: (cart.fraction_at(&aux_at) * turn).to_degrees(),
                    target_deg: turn.to_degrees(),
                    normal,
                    sense,
                    from_points: interpolate::plane_well_defined(&start, &aux_at, &end.position),
                });
                if let (None, Programmed::Pose(p)) = (rel, programmed) {
                    self.state.last_abc = [p.a, p.b, p.c];
                }
                self.state.current = Some(Current {
                    axes: q_end,
                    stop: Some(idx),
                });
                ArcEnd::Done
            }
        }
    }

    /// How the axes arrive at `goal` along `path` from `start` (TCP, axes): the rates, the
    /// end axes reached by following the path and the turns inside; from the axis steps
    /// (saying so) where the path cannot be followed. Apart from the motion's body, like
    /// [`Self::aux_point`]: most path segments are short and take their arrival after the walk.
    #[inline(never)]
    fn sampled_arrival(
        &mut self,
        (file, s): (FileId, &Stmt),
        path: &Path,
        tool: &Frame,
        start: (&Frame, &[f64; 6]),
        (goal, q): (&Frame, &[f64; 6]),
    ) -> ([f64; 6], [f64; 6], interpolate::Turns) {
        match interpolate::arrival(&self.robot, tool, path, start, (goal, q)) {
            Ok(a) => {
                // A circle's end: the turns before its auxiliary point are that point's (the
                // robot passes it on the arc).
                let turns = match *path {
                    Path::Circ { aux } => Cartesian::new(start.0, goal, path)
                        .map_or(a.turns, |arc| a.turns.after(arc.fraction_at(&aux))),
                    _ => a.turns,
                };
                (a.rate, a.end, turns)
            }
            Err(e) => {
                self.warn(file, s.head, format!("{e}; directions from the axis steps"));
                let steps = std::array::from_fn(|i| q[i] - start.1[i]);
                (steps, *q, interpolate::NO_TURNS)
            }
        }
    }

    /// Warns that a target is left as written because its numbers are not literal or are in
    /// data every program of the cell shares (`$config.dat`, a public data list).
    fn warn_unwritable(&mut self, file: FileId, s: &Stmt, computed: bool, shared: Option<FileId>) {
        if computed {
            self.warn(
                file,
                s.head,
                "the target is computed in the program (not a literal position): left unchanged",
            );
        }
        if let Some(f) = shared {
            let name = std::path::Path::new(&self.ws.get(f).name)
                .file_name()
                .map_or_else(
                    || self.ws.get(f).name.clone(),
                    |n| n.to_string_lossy().into_owned(),
                );
            self.warn(
                file,
                s.head,
                format!("the target is declared in {name}, data every program of the cell shares, which robopost does not rewrite, and this program cannot hold a copy of it (that needs a .dat of its own and the point named in the motion): left unchanged"),
            );
        }
    }

    /// The absolute programmed values (in the base, or axes), the goal TCP in the robot base
    /// and the given S/T; `None` when a missing component needs an unknown start.
    #[allow(clippy::type_complexity)]
    pub(super) fn complete(
        &self,
        pos: &Pos<'f>,
        rel: Option<Rel>,
        current: Option<Current>,
        base: &Frame,
        tool: &Frame,
        start_tcp: Option<&Frame>,
    ) -> Option<(Programmed, Frame, (Option<u8>, Option<u8>))> {
        let st = (pos.s, pos.t);
        let v = match pos.v {
            Components::Axes(v) => {
                let q: [f64; 6] = match rel {
                    Some(_) => {
                        let c = current?;
                        std::array::from_fn(|i| c.axes[i] + v[i].unwrap_or(0.0))
                    }
                    None => {
                        if pos.is_complete() {
                            v.map(|x| x.unwrap_or(0.0))
                        } else {
                            let c = current?;
                            std::array::from_fn(|i| v[i].unwrap_or(c.axes[i]))
                        }
                    }
                };
                let goal = Nominal(&self.robot).tcp(&q, tool);
                return Some((Programmed::Axes(q.into()), goal, st));
            }
            Components::Pose(v) => v,
        };
        match rel {
            Some(kind) => {
                let start = start_tcp?;
                let r = Frame::from_kuka(&pos.frame_pose());
                let start_in_base = base.inverse().compose(start);
                let p = match kind {
                    Rel::Tool => start_in_base.compose(&r),
                    _ => Frame {
                        rotation: r.rotation * start_in_base.rotation,
                        position: start_in_base.position + r.position,
                    },
                };
                let near = start_in_base.to_kuka_near(&self.state.last_abc);
                let programmed = p.to_kuka_near(&near.abc());
                Some((Programmed::Pose(programmed), base.compose(&p), st))
            }
            None => {
                let v = if pos.is_complete() {
                    pos.frame_pose()
                } else {
                    let start = start_tcp?;
                    let _ = current?;
                    let last = self.state.last_abc;
                    let here = base.inverse().compose(start).to_kuka_near(&[
                        v[3].unwrap_or(last[0]),
                        v[4].unwrap_or(last[1]),
                        v[5].unwrap_or(last[2]),
                    ]);
                    let here = here.to_array();
                    Pose::from_array(std::array::from_fn(|i| v[i].unwrap_or(here[i])))
                };
                let p = Frame::from_kuka(&v);
                let table = self.prefixes.borrow();
                let mut goal = match pos.origin.and_then(|o| o.prefix) {
                    Some(i) => base.compose(&table[i as usize]).compose(&p),
                    None => base.compose(&p),
                };
                if let Some(i) = pos.origin.and_then(|o| o.suffix) {
                    goal = goal.compose(&table[i as usize]);
                }
                Some((Programmed::Pose(v), goal, st))
            }
        }
    }
}

/// Status bit 4: the point was taught on an absolutely accurate robot (KSS 8 operating and
/// programming instructions for system integrators, the bits of Status `S`).
const ABSOLUTELY_ACCURATE: u8 = 0b1_0000;

impl<'f> Simulator<'f> {
    /// A target `P : offset` whose left operand is a declared point: the point is what is
    /// compensated for this use (the offset applied after it, `Origin::suffix`), named at
    /// its place in the expression — so a point also used alone, and compensated
    /// differently there, is split into a copy for each use like a point reached with
    /// different rotation directions. `None`: not such a target.
    fn offset_point(
        &mut self,
        file: FileId,
        e: &'f Expr,
        scope: &Scope<'f>,
    ) -> Option<(Pos<'f>, Option<Span>)> {
        let Expr::Binary(b) = strip_parens(e) else {
            return None;
        };
        let left = b.lhs.as_path().filter(|p| p.is_simple())?;
        if b.op != crate::krl::BinOp::Geo {
            return None;
        }
        let Value::Pos(mut point) = self.eval(file, &b.lhs, scope) else {
            return None;
        };
        let named = point
            .origin
            .is_some_and(|o| o.var.is_some() && o.prefix.is_none());
        if point.v.is_axes() || !point.is_complete() || !named {
            return None;
        }
        let Value::Pos(offset) = self.eval(file, &b.rhs, scope) else {
            return None;
        };
        if offset.v.is_axes() {
            return None;
        }
        // A declared point as the offset keeps its numbers here (see `Simulation::pinned`).
        if let (Some(o), Some(p)) = (
            offset.origin.filter(|o| o.var.is_some()),
            b.rhs.as_path().filter(|p| p.is_simple()),
        ) {
            self.out.pinned.push(super::Pinned {
                origin: o,
                site: (file, p.root),
            });
        }
        // Components the offset does not give are zero (a frame).
        let frame = Frame::from_kuka(&offset.frame_pose());
        let mut table = self.prefixes.borrow_mut();
        table.push(frame);
        let at = (table.len() - 1) as u32;
        if let Some(o) = point.origin.as_mut() {
            o.suffix = Some(at);
        }
        Some((point, Some(left.root)))
    }
}

fn strip_parens(e: &Expr) -> &Expr {
    match e {
        Expr::Paren(p) => strip_parens(&p.inner),
        e => e,
    }
}

/// The name a target is written through: a plain variable (`XP1`), or the right operand of a
/// geometric operator (`BASE_DATA[2] : XP1`), whose number the rewrite may rename.
fn geometric_operand(e: &Expr) -> Option<Span> {
    match strip_parens(e) {
        Expr::Path(p) if p.is_simple() => Some(p.root),
        Expr::Binary(b) if b.op == crate::krl::BinOp::Geo => {
            b.rhs.as_path().filter(|p| p.is_simple()).map(|p| p.root)
        }
        _ => None,
    }
}

/// Where `CA` is within this many degrees of a whole number of turns (0 included), the end is
/// compensated through the circle's points ([`ArcMode::Through`]): constructing the circle
/// through the compensated start and end would change its radius by the chord's change over
/// `2|sin(CA/2)|` — more than 10 times it, there (sin 2.866° = 0.05) — and at a whole turn
/// the chord vanishes and fixes nothing.
pub const THROUGH_DEG: f64 = 5.73;

/// How a circular motion with `CA` ends (see `Simulator::arc_end`).
enum ArcEnd<'f> {
    /// Recorded, or the motion lost: nothing more to record for it.
    Done,
    /// Compensated through the circle's points: the end, recorded after the target (boxed:
    /// a rare record kept off the motion's frame).
    Through(Box<Stop<'f>>),
}

/// How a circular motion with `CA` is compensated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ArcMode {
    /// The end as a target, the circle written through it.
    Construct,
    /// The auxiliary point and target as a plain circle's; `whole`: `CA` is a whole number of
    /// turns (the end is the start).
    Through { whole: bool },
}

impl ArcMode {
    fn of(angle_deg: f64) -> ArcMode {
        let turns = (angle_deg / 360.0).round();
        let off = (angle_deg - 360.0 * turns).abs();
        if off <= THROUGH_DEG {
            ArcMode::Through {
                whole: off < 1e-9 && turns != 0.0,
            }
        } else {
            ArcMode::Construct
        }
    }
}

/// `stop` with its numbers written at `origin`, its target naming variable `reference`.
fn with_place<'f>(stop: Stop<'f>, origin: Option<Origin<'f>>, reference: Option<Span>) -> Stop<'f> {
    Stop {
        handle: Handle {
            origin,
            reference,
            ..stop.handle
        },
        ..stop
    }
}

/// A stop of motion statement `s` in the interned base and tool `(base, tool)`, as a target
/// left unchanged until the caller says otherwise.
#[inline]
fn blank_stop<'f>(
    file: FileId,
    s: &'f Stmt,
    kind: MotionKind,
    rel: Option<Rel>,
    (base, tool): (u32, u32),
) -> Stop<'f> {
    Stop {
        interpolation: interpolation(kind),
        role: Role::Target,
        goal: Frame::identity(),
        tool,
        base,
        nominal_axes: AxisAngles::default(),
        arrival: None,
        turns: interpolate::NO_TURNS,
        programmed: Programmed::Pose(Pose::IDENTITY),
        keep_t: false,
        rel,
        prev: None,
        compensable: false,
        deferred: false,
        spline: None,
        ghost: false,
        handle: Handle {
            file,
            stmt: s,
            kind,
            origin: None,
            reference: None,
        },
    }
}
