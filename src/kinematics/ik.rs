//! Inverse kinematics with every branch — the 8 configurations of the S bits (shoulder
//! front/back, elbow, wrist flip), each with the ±360° variants its limits allow — and the
//! controller's ways of picking one: by S and T, by nearness to the previous axis state
//! (paths), or by S and nearness. The closed-form solution itself is in `branches.rs`.
//!
//! Singular targets: with the wrist point on the A1 axis A1 is free, with A5 = 0 only A4 + A6
//! is defined, with the arm stretched the two elbow branches meet. Strict selection
//! ([`inverse_all`], [`Select::Status`]) reports them as [`IkError::Singular`]; selection by
//! nearness resolves them as the controller does with `$SINGUL_POS[] = 1` (keep A1 / A4 of the
//! previous state, the rest in A6). The tolerances (`branches.rs`) are where the answer stops
//! being determined by the target to better than 1e-6 mm; use [`super::singularity`] to warn
//! earlier.

use nalgebra::{Matrix3, Vector3};

use super::Frame;

// What only robopost's own tests name through this path.
#[cfg(any(test, feature = "internals"))]
pub use super::{
    branches::{ELBOW_SINGULAR_DEG, REACH_TOLERANCE_MM, SHOULDER_SINGULAR_MM, WRIST_SINGULAR_SIN},
    turns::LIMIT_TOLERANCE_DEG,
};

use super::branches::{a3, arm, join, shoulder, wrist, OutOfReach, Shoulder, Target};
use super::fk::{Singularity, SingularityKind};
use super::robot::RobotDescription;
use super::turns::{
    each_variant, first_outside, nearest as nearest_variant, nearest_all, turn, with_turn,
};

/// One IK solution: the axis angles (KUKA degrees) and its status and turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkSolution {
    pub axes_deg: [f64; 6],
    pub s: u8,
    pub t: u8,
}

/// How [`inverse`] picks one of the solutions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Select {
    /// The configuration `s`; with `t`, the ±360° variant whose signs `t` gives, otherwise the
    /// variant with every axis nearest to zero. Fails at a singularity.
    Status { s: u8, t: Option<u8> },
    /// The solution of any configuration nearest the previous axis state (sum of squared axis
    /// differences); resolves singularities by keeping the previous A1 / A4.
    Nearest([f64; 6]),
    /// Configuration `s` (LIN/CIRC keep the start point's S), the variant nearest `near`;
    /// resolves singularities like [`Select::Nearest`].
    StatusNearest { s: u8, near: [f64; 6] },
}

/// Why a flange pose has no (selected) solution.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum IkError {
    /// No configuration reaches the wrist point.
    #[error(
        "target unreachable: the wrist point is {distance_mm:.3} mm {}",
        if *too_far { "beyond the arm's reach" } else { "too close to the A2 axis" }
    )]
    Unreachable { distance_mm: f64, too_far: bool },
    /// Every configuration that reaches the target (or the selected one) is singular.
    #[error("target singular: {kind}, {distance_deg_or_mm:.3e} {} from it", kind.unit())]
    Singular {
        kind: SingularityKind,
        distance_deg_or_mm: f64,
    },
    /// The target is reached only with an axis outside its software limits.
    #[error("A{axis} would be {value_deg:.3}°, outside its limits [{}, {}]°", limits_deg[0], limits_deg[1])]
    OutOfLimits {
        axis: u8,
        value_deg: f64,
        limits_deg: [f64; 2],
    },
    /// The requested S (and T) is not among the solutions.
    #[error("no solution with S {s}{}; available (S, T): {}", t.map(|t| format!(" T {t}")).unwrap_or_default(), list(available))]
    NoBranch {
        s: u8,
        t: Option<u8>,
        available: Vec<(u8, u8)>,
    },
}

fn list(available: &[(u8, u8)]) -> String {
    if available.is_empty() {
        return "none".to_string();
    }
    let items: Vec<String> = available
        .iter()
        .map(|(s, t)| format!("({s}, {t})"))
        .collect();
    items.join(", ")
}

/// One configuration (S value) of a target before the ±360° variants.
#[derive(Clone, Copy, Debug)]
enum Config {
    /// Axis angles in (−180°, 180°] (a resolved singular axis keeps its hint instead).
    Solved {
        axes: [f64; 6],
        singular: Option<Singularity>,
    },
    Unreachable(OutOfReach),
}

/// Configuration `s` (bits: back shoulder, elbow, A5 < 0).
fn config(t: &Target, s: u8) -> Config {
    match shoulder(t, s & 1 == 1) {
        Ok(sh) => {
            let arm = arm(t, &sh, s & 2 == 2);
            let w = wrist(t, &arm);
            let axes = join(
                &arm.axes,
                if s & 4 == 4 { &w.negative } else { &w.positive },
            );
            Config::Solved {
                axes,
                singular: arm.singular.or(w.singular),
            }
        }
        Err(out) => Config::Unreachable(out),
    }
}

/// All eight configurations, each shoulder and arm branch solved once.
fn configs(t: &Target) -> [Config; 8] {
    let mut out = [Config::Unreachable(OutOfReach {
        distance_mm: f64::INFINITY,
        too_far: true,
    }); 8];
    for back in [false, true] {
        let sh = match shoulder(t, back) {
            Ok(sh) => sh,
            Err(e) => {
                for s in [0, 2, 4, 6] {
                    out[s | usize::from(back)] = Config::Unreachable(e);
                }
                continue;
            }
        };
        for up in [false, true] {
            let arm = arm(t, &sh, up);
            let w = wrist(t, &arm);
            let singular = arm.singular.or(w.singular);
            let s = arm.bits as usize;
            out[s] = Config::Solved {
                axes: join(&arm.axes, &w.positive),
                singular,
            };
            out[s | 4] = Config::Solved {
                axes: join(&arm.axes, &w.negative),
                singular,
            };
        }
    }
    out
}

fn singular_error(s: Singularity) -> IkError {
    IkError::Singular {
        kind: s.kind,
        distance_deg_or_mm: s.distance,
    }
}

fn limits_error(robot: &RobotDescription, axes: &[f64; 6]) -> Option<IkError> {
    first_outside(robot, axes).map(|(axis, value_deg)| IkError::OutOfLimits {
        axis,
        value_deg,
        limits_deg: robot.limits_deg[axis as usize - 1],
    })
}

/// The error for a target none of whose configurations gave a solution, by precedence:
/// singular, out of limits, unreachable.
fn failure(robot: &RobotDescription, configs: &[Config]) -> IkError {
    let mut singular: Option<Singularity> = None;
    let mut limits = None;
    let mut reach: Option<OutOfReach> = None;
    for c in configs {
        match *c {
            Config::Solved {
                singular: Some(s), ..
            } => {
                if singular.map_or(true, |best| s.distance < best.distance) {
                    singular = Some(s);
                }
            }
            Config::Solved { axes, .. } => {
                limits = limits.or_else(|| limits_error(robot, &axes));
            }
            Config::Unreachable(out) => {
                if reach.map_or(true, |r| out.distance_mm < r.distance_mm) {
                    reach = Some(out);
                }
            }
        }
    }
    if let Some(s) = singular {
        return singular_error(s);
    }
    if let Some(e) = limits {
        return e;
    }
    let out = reach.unwrap_or(OutOfReach {
        distance_mm: f64::INFINITY,
        too_far: true,
    });
    IkError::Unreachable {
        distance_mm: out.distance_mm,
        too_far: out.too_far,
    }
}

fn parts(flange: &Frame) -> (Matrix3<f64>, Vector3<f64>) {
    (flange.rotation, flange.position)
}

/// Every solution within the joint limits: each non-singular configuration with every
/// combination of ±360° variants, sorted by S then T. Fails when there is none (singular,
/// out of limits or unreachable, in that order of precedence); a singular configuration is
/// left out while others solve the target.
pub fn inverse_all(robot: &RobotDescription, flange: &Frame) -> Result<Vec<IkSolution>, IkError> {
    let mut out = Vec::with_capacity(32);
    inverse_all_into(robot, flange, &mut out)?;
    Ok(out)
}

/// [`inverse_all`] into a reused buffer (cleared first).
pub fn inverse_all_into(
    robot: &RobotDescription,
    flange: &Frame,
    out: &mut Vec<IkSolution>,
) -> Result<(), IkError> {
    let (r, p) = parts(flange);
    let configs = configs(&Target::new(robot, &r, &p, None));
    out.clear();
    for (s, c) in configs.iter().enumerate() {
        if let Config::Solved {
            axes,
            singular: None,
        } = c
        {
            each_variant(robot, axes, |axes_deg, t| {
                out.push(IkSolution {
                    axes_deg,
                    s: s as u8,
                    t,
                })
            });
        }
    }
    if out.is_empty() {
        return Err(failure(robot, &configs));
    }
    Ok(())
}

fn squared_distance(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The selected solution of `flange` (see [`Select`]).
pub fn inverse(
    robot: &RobotDescription,
    flange: &Frame,
    select: Select,
) -> Result<IkSolution, IkError> {
    let (r, p) = parts(flange);
    match select {
        Select::Status { s, t } => {
            let s = s & 7;
            let target = Target::new(robot, &r, &p, None);
            let axes = match config(&target, s) {
                Config::Solved {
                    singular: Some(sing),
                    ..
                } => return Err(singular_error(sing)),
                Config::Solved { axes, .. } => axes,
                Config::Unreachable(_) => return Err(no_branch(robot, flange, s, t)),
            };
            let picked = match t {
                Some(t) => with_turn(robot, &axes, t),
                None => nearest_all(robot, &axes, &[0.0; 6]),
            };
            match picked {
                Some(axes_deg) => Ok(IkSolution {
                    axes_deg,
                    s,
                    t: turn(&axes_deg),
                }),
                None => {
                    Err(limits_error(robot, &axes)
                        .unwrap_or_else(|| no_branch(robot, flange, s, t)))
                }
            }
        }
        Select::StatusNearest { s, near } => {
            let s = s & 7;
            let target = Target::new(robot, &r, &p, Some(&near));
            let axes = match config(&target, s) {
                Config::Solved { axes, .. } => axes,
                Config::Unreachable(_) => return Err(no_branch(robot, flange, s, None)),
            };
            match nearest_all(robot, &axes, &near) {
                Some(axes_deg) => Ok(IkSolution {
                    axes_deg,
                    s,
                    t: turn(&axes_deg),
                }),
                None => {
                    Err(limits_error(robot, &axes)
                        .unwrap_or_else(|| no_branch(robot, flange, s, None)))
                }
            }
        }
        Select::Nearest(near) => nearest(robot, &Target::new(robot, &r, &p, Some(&near)), &near),
    }
}

/// Squared distance of the variant of axis `i` at `a` nearest `near[i]`; infinite when no
/// variant is within limits.
fn axis_distance(robot: &RobotDescription, i: usize, a: f64, near: &[f64; 6]) -> f64 {
    nearest_variant(robot, i, a, near[i]).map_or(f64::INFINITY, |v| (v - near[i]) * (v - near[i]))
}

/// The solution nearest `near` over all configurations, best first with lower bounds: A1 of
/// both shoulders and A3 of both elbows are known before any per-arm `atan2`, and a partial
/// sum of squared axis differences bounds the total. A shoulder, an arm or a wrist is solved
/// only while its bound can still beat the best total, so a path point usually costs what
/// one configuration costs.
fn nearest(
    robot: &RobotDescription,
    target: &Target,
    near: &[f64; 6],
) -> Result<IkSolution, IkError> {
    let mut best: Option<(f64, IkSolution)> = None;
    let beaten = |best: &Option<(f64, IkSolution)>, bound: f64| {
        bound.is_infinite() || best.as_ref().is_some_and(|(d, _)| *d <= bound)
    };
    let mut shoulders =
        [false, true].map(|back| (axis_distance(robot, 0, target.a1(back), near), back));
    if shoulders[1].0 < shoulders[0].0 {
        shoulders.swap(0, 1);
    }
    let mut failures: Vec<Config> = Vec::new();
    for (d1, back) in shoulders {
        if beaten(&best, d1) {
            continue;
        }
        let sh: Shoulder = match shoulder(target, back) {
            Ok(sh) => sh,
            Err(e) => {
                failures.push(Config::Unreachable(e));
                continue;
            }
        };
        let mut elbows =
            [false, true].map(|up| (d1 + axis_distance(robot, 2, a3(target, &sh, up), near), up));
        if elbows[1].0 < elbows[0].0 {
            elbows.swap(0, 1);
        }
        for (d13, up) in elbows {
            if beaten(&best, d13) {
                continue;
            }
            let arm = arm(target, &sh, up);
            if beaten(&best, d13 + axis_distance(robot, 1, arm.axes[1], near)) {
                continue;
            }
            let w = wrist(target, &arm);
            for (bit2, half) in [(0u8, &w.positive), (4, &w.negative)] {
                let axes = join(&arm.axes, half);
                let Some(axes_deg) = nearest_all(robot, &axes, near) else {
                    failures.push(Config::Solved {
                        axes,
                        singular: None,
                    });
                    continue;
                };
                let d = squared_distance(&axes_deg, near);
                if best.as_ref().map_or(true, |(b, _)| d < *b) {
                    let sol = IkSolution {
                        axes_deg,
                        s: arm.bits | bit2,
                        t: turn(&axes_deg),
                    };
                    best = Some((d, sol));
                }
            }
        }
    }
    match best {
        Some((_, sol)) => Ok(sol),
        // Nothing within limits (singularities are resolved here). Branches skipped for an
        // infinite bound have an axis out of limits: solve them all to say which.
        None => {
            for back in [false, true] {
                if let Ok(sh) = shoulder(target, back) {
                    for up in [false, true] {
                        let arm = arm(target, &sh, up);
                        let w = wrist(target, &arm);
                        for half in [w.positive, w.negative] {
                            failures.push(Config::Solved {
                                axes: join(&arm.axes, &half),
                                singular: None,
                            });
                        }
                    }
                }
            }
            Err(failure(robot, &failures))
        }
    }
}

/// The error for a configuration that is not available: unreachable as a whole, or the list
/// of what is.
fn no_branch(robot: &RobotDescription, flange: &Frame, s: u8, t: Option<u8>) -> IkError {
    match inverse_all(robot, flange) {
        Ok(all) => {
            let mut available: Vec<(u8, u8)> = all.iter().map(|x| (x.s, x.t)).collect();
            available.dedup();
            IkError::NoBranch { s, t, available }
        }
        Err(e) => e,
    }
}
