//! Closed-form inverse kinematics of the offset-wrist arm with every branch: the 8
//! configurations of the S bits (shoulder front/back, elbow, wrist flip), each with the ±360°
//! variants of every axis its limits allow, and the controller's ways of picking one — by S
//! and T, by nearness to the previous axis state (paths), or by S and nearness.
//!
//! Method (Brandstötter, Angerer & Hofbaur 2014, OPW; see `fk.rs`): the wrist point
//! `C = p − l5x·ẑ_flange` gives θ1 = atan2(Cy, Cx) (front) or +180° (back); in the arm plane the
//! wrist point relative to A2 is `D = l2·e^{iθ2} + K·e^{i(θ2+θ3+ψ)}` (complex numbers z + i·x,
//! `K·e^{iψ} = l3z + i·l4x`), so the elbow angle e = θ3 + ψ follows from |D| by the law of
//! cosines — here in its half-angle form `tan²(e/2) = ((l2+K)² − |D|²) / (|D|² − (l2−K)²)`,
//! which stays accurate at the stretched arm where `acos` loses half the digits — and
//! θ2 = arg D − arg(l2 + K·e^{ie}). The wrist rotation `Rx(θ4)·Ry(θ5)·Rx(θ6) = R03ᵀ·R06` is
//! read as X-Y-X Euler angles, with the flip (θ4+180°, −θ5, θ6+180°). Every sine and cosine
//! the frames need comes from these complex numbers; only the angles cost an `atan2`.
//!
//! Singular targets: with the wrist point on the A1 axis A1 is free, with A5 = 0 only A4 + A6
//! is defined, with the arm stretched the two elbow branches meet. Strict selection
//! ([`inverse_all`], [`Select::Status`]) reports them as [`IkError::Singular`]; selection by
//! nearness resolves them as the controller does with `$SINGUL_POS[] = 1` (keep A1 / A4 of the
//! previous state, the rest in A6). The tolerances below are where the answer stops being
//! determined by the target to better than 1e-6 mm; use [`super::singularity`] to warn earlier.

use nalgebra::{Isometry3, Matrix3, Vector3};

use super::fk::{Geometry, Singularity, SingularityKind};
use super::robot::RobotDescription;

/// |sin A5| below which A4 and A6 are treated as undetermined (1e-9: the flange moves by
/// less than l5x·1e-9 ≈ 2e-7 mm when the wrist is resolved by keeping A4).
pub const WRIST_SINGULAR_SIN: f64 = 1e-9;
/// Elbow angle (deg) within which the arm counts as stretched (or folded): the elbow angle
/// itself is only known to about 2e-6° there.
pub const ELBOW_SINGULAR_DEG: f64 = 1e-5;
/// Wrist point distance (mm) from the A1 axis below which A1 is undetermined.
pub const SHOULDER_SINGULAR_MM: f64 = 1e-6;
/// A wrist point this far (mm) beyond the reach still counts as reached (rounding of a pose
/// computed from a stretched arm).
pub const REACH_TOLERANCE_MM: f64 = 1e-9;
/// Angles this far (deg) outside a joint limit are taken as on it (rounding).
pub const LIMIT_TOLERANCE_DEG: f64 = 1e-9;

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
    Unreachable {
        distance_mm: f64,
        too_far: bool,
    },
    /// Not computed (another S was asked for).
    Skipped,
}

/// Angle in (−180°, 180°].
#[inline]
fn wrap_deg(a: f64) -> f64 {
    let w = a - 360.0 * ((a + 180.0) / 360.0).floor();
    if w == -180.0 {
        180.0
    } else {
        w
    }
}

/// All configurations of the flange `(r, p)`, or only `only`. `hint` (previous axes) resolves
/// singular axes; without it they are set to 0 (the controller's `$SINGUL_POS[] = 0`) and the
/// configuration is flagged singular.
fn configurations(
    robot: &RobotDescription,
    r: &Matrix3<f64>,
    p: &Vector3<f64>,
    hint: Option<&[f64; 6]>,
    only: Option<u8>,
) -> [Config; 8] {
    let g = Geometry::new(robot);
    let mut out = [Config::Skipped; 8];
    // A6 frame rotation of the target: flange · Ry(90°)ᵀ, columns (ẑ, ŷ, −x̂) of the flange.
    let approach = r.column(2).into_owned();
    let r06 = Matrix3::from_columns(&[approach, r.column(1).into_owned(), -r.column(0)]);
    let wrist = p - g.l5x * approach;
    let radius = wrist.x.hypot(wrist.y);
    let shoulder_singular = radius < SHOULDER_SINGULAR_MM;
    let (s1, c1) = if shoulder_singular {
        g.theta(0, hint.map_or(0.0, |h| h[0])).sin_cos()
    } else {
        (wrist.y / radius, wrist.x / radius)
    };
    let x_front = wrist.x * c1 + wrist.y * s1;
    let a1_front = if shoulder_singular {
        hint.map_or(0.0, |h| h[0])
    } else {
        wrap_deg(g.kuka(0, s1.atan2(c1)))
    };
    let psi = g.l4x.atan2(g.l3z);
    let (l2, k) = (g.l2, g.k);
    let (sum, diff) = (l2 + k, (l2 - k).abs());
    for back in [false, true] {
        if only.is_some_and(|s| (s & 1 == 1) != back) {
            continue;
        }
        let sigma = if back { -1.0 } else { 1.0 };
        let (c1, s1, x) = (sigma * c1, sigma * s1, sigma * x_front);
        let a1 = if back {
            wrap_deg(a1_front + 180.0)
        } else {
            a1_front
        };
        let (dx, dz) = (x - g.l1x, wrist.z - g.l1z);
        let dn = dx.hypot(dz);
        let (outer, inner) = (sum - dn, dn - diff);
        if outer < -REACH_TOLERANCE_MM || inner < -REACH_TOLERANCE_MM {
            let c = if outer < inner {
                Config::Unreachable {
                    distance_mm: -outer,
                    too_far: true,
                }
            } else {
                Config::Unreachable {
                    distance_mm: -inner,
                    too_far: false,
                }
            };
            for (s, slot) in out.iter_mut().enumerate() {
                if (s & 1 == 1) == back {
                    *slot = c;
                }
            }
            continue;
        }
        // Half-angle law of cosines with both factors as differences (accurate at the edges).
        let sh = (outer.max(0.0) * (sum + dn)).sqrt();
        let ch = (inner.max(0.0) * (dn + diff)).sqrt();
        let h = sh.hypot(ch);
        let (sh, ch) = (sh / h, ch / h);
        let e_abs = 2.0 * sh.atan2(ch);
        let (sin_abs, cos_e) = (2.0 * sh * ch, ch * ch - sh * sh);
        let elbow_distance = e_abs.min(std::f64::consts::PI - e_abs).to_degrees();
        // G = Rz(θ1)ᵀ·R06.
        let gm = Matrix3::from_rows(&[
            (c1 * r06.row(0) + s1 * r06.row(1)),
            (c1 * r06.row(1) - s1 * r06.row(0)),
            r06.row(2).into_owned(),
        ]);
        for up in [false, true] {
            let bit1 = u8::from(up) << 1;
            if only.is_some_and(|s| s & 2 != bit1) {
                continue;
            }
            // S bit 1 is A3 ≥ A3(stretched), i.e. sense3·e ≥ 0.
            let sign = if up { g.senses[2] } else { -g.senses[2] };
            let (e, sin_e) = (sign * e_abs, sign * sin_abs);
            // θ2 = arg(D·conj(l2 + K·e^{ie})), D = dz + i·dx.
            let (qr, qi) = (l2 + k * cos_e, k * sin_e);
            let t2 = (dx * qr - dz * qi).atan2(dz * qr + dx * qi);
            let t3 = e - psi;
            // e^{i(θ2+θ3)} = D·(l2·e^{ie} + K)·(l3z − i·l4x) / (K·|D|²).
            let (ar, ai) = (l2 * cos_e + k, l2 * sin_e);
            let (br, bi) = (dz * ar - dx * ai, dz * ai + dx * ar);
            let (cr, ci) = (br * g.l3z + bi * g.l4x, bi * g.l3z - br * g.l4x);
            let norm = cr.hypot(ci);
            let (c23, s23) = (cr / norm, ci / norm);
            // M = Ry(θ2+θ3)ᵀ·G = Rx(θ4)·Ry(θ5)·Rx(θ6).
            let m0 = c23 * gm.row(0) - s23 * gm.row(2);
            let m1 = gm.row(1);
            let m2 = s23 * gm.row(0) + c23 * gm.row(2);
            let sb = m0[1].hypot(m0[2]);
            let (t4, t5, t6, wrist_singular) = if sb < WRIST_SINGULAR_SIN {
                // Only θ4 ± θ6 is defined: Rx(θ4 + θ6) at θ5 = 0, Rx(θ4 − θ6)·Ry(π) at π.
                let spin = m2[1].atan2(m1[1]);
                let t4 = g.theta(3, hint.map_or(0.0, |h| h[3]));
                if m0[0] > 0.0 {
                    (t4, 0.0, spin - t4, true)
                } else {
                    (t4, std::f64::consts::PI, t4 - spin, true)
                }
            } else {
                (
                    m1[0].atan2(-m2[0]),
                    sb.atan2(m0[0]),
                    m0[1].atan2(m0[2]),
                    false,
                )
            };
            let singular = if shoulder_singular {
                Some(Singularity {
                    kind: SingularityKind::Shoulder,
                    distance: radius,
                })
            } else if elbow_distance < ELBOW_SINGULAR_DEG {
                Some(Singularity {
                    kind: SingularityKind::Elbow,
                    distance: elbow_distance,
                })
            } else if wrist_singular {
                Some(Singularity {
                    kind: SingularityKind::Wrist,
                    distance: sb.atan2(m0[0].abs()).to_degrees(),
                })
            } else {
                None
            };
            let a2 = wrap_deg(g.kuka(1, t2));
            let a3 = wrap_deg(g.kuka(2, t3));
            let base = [a1, a2, a3];
            let a5 = wrap_deg(g.kuka(4, t5));
            let (a4, a6) = if wrist_singular {
                let a4 = hint.map_or(0.0, |h| h[3]);
                (a4, wrap_deg(g.kuka(5, t6)))
            } else {
                (wrap_deg(g.kuka(3, t4)), wrap_deg(g.kuka(5, t6)))
            };
            let plain = [base[0], base[1], base[2], a4, a5, a6];
            let flipped = if wrist_singular {
                plain
            } else {
                [
                    base[0],
                    base[1],
                    base[2],
                    wrap_deg(a4 + 180.0),
                    wrap_deg(-a5),
                    wrap_deg(a6 + 180.0),
                ]
            };
            // S bit 2 is A5 < 0: the flip that makes A5 negative.
            let (pos, neg) = if a5 < 0.0 {
                (flipped, plain)
            } else {
                (plain, flipped)
            };
            let s = usize::from(back) | bit1 as usize;
            for (bit2, axes) in [(0, pos), (4, neg)] {
                if only.map_or(true, |o| o as usize == s | bit2) {
                    out[s | bit2] = Config::Solved { axes, singular };
                }
            }
        }
    }
    out
}

/// Every value `a + 360°·k` of axis `i` within its limits.
fn variants(robot: &RobotDescription, i: usize, a: f64) -> impl Iterator<Item = f64> {
    let [lo, hi] = robot.limits_deg[i];
    let (lo, hi) = (lo - LIMIT_TOLERANCE_DEG, hi + LIMIT_TOLERANCE_DEG);
    let first = ((lo - a) / 360.0).ceil() as i64;
    let last = ((hi - a) / 360.0).floor() as i64;
    (first..=last.max(first - 1)).map(move |k| a + 360.0 * k as f64)
}

/// The turn bits of an axis set.
fn turn(axes: &[f64; 6]) -> u8 {
    axes.iter()
        .enumerate()
        .fold(0u8, |t, (i, a)| t | u8::from(*a < 0.0) << i)
}

/// The first axis with no value within limits: (axis, nearest variant to the limits).
fn out_of_limits(robot: &RobotDescription, axes: &[f64; 6]) -> Option<IkError> {
    (0..6).find_map(|i| {
        if variants(robot, i, axes[i]).next().is_some() {
            return None;
        }
        let [lo, hi] = robot.limits_deg[i];
        let mid = 0.5 * (lo + hi);
        let value = axes[i] + 360.0 * ((mid - axes[i]) / 360.0).round();
        Some(IkError::OutOfLimits {
            axis: i as u8 + 1,
            value_deg: value,
            limits_deg: [lo, hi],
        })
    })
}

/// Per axis, the variant within limits nearest `target` (and with sign bit `want` of `t`
/// when given); `None` if an axis has none.
fn pick(
    robot: &RobotDescription,
    axes: &[f64; 6],
    target: &[f64; 6],
    t: Option<u8>,
) -> Option<[f64; 6]> {
    let mut out = [0.0; 6];
    for i in 0..6 {
        let want_negative = t.map(|t| t >> i & 1 == 1);
        out[i] = variants(robot, i, axes[i])
            .filter(|a| want_negative.map_or(true, |neg| (*a < 0.0) == neg))
            .min_by(|a, b| (a - target[i]).abs().total_cmp(&(b - target[i]).abs()))?;
    }
    Some(out)
}

/// The error for a target none of whose configurations gave a solution, by precedence:
/// singular, out of limits, unreachable.
fn failure(robot: &RobotDescription, configs: &[Config; 8]) -> IkError {
    let mut singular: Option<Singularity> = None;
    let mut limits = None;
    let mut unreachable: Option<(f64, bool)> = None;
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
                limits = limits.or_else(|| out_of_limits(robot, &axes));
            }
            Config::Unreachable {
                distance_mm,
                too_far,
            } => {
                if unreachable.map_or(true, |(d, _)| distance_mm < d) {
                    unreachable = Some((distance_mm, too_far));
                }
            }
            Config::Skipped => {}
        }
    }
    if let Some(s) = singular {
        return IkError::Singular {
            kind: s.kind,
            distance_deg_or_mm: s.distance,
        };
    }
    if let Some(e) = limits {
        return e;
    }
    let (distance_mm, too_far) = unreachable.unwrap_or((f64::INFINITY, true));
    IkError::Unreachable {
        distance_mm,
        too_far,
    }
}

fn parts(flange: &Isometry3<f64>) -> (Matrix3<f64>, Vector3<f64>) {
    (
        flange.rotation.to_rotation_matrix().into_inner(),
        flange.translation.vector,
    )
}

/// Every solution within the joint limits: each non-singular configuration with every
/// combination of ±360° variants, sorted by S then T. Fails when there is none (singular,
/// out of limits or unreachable, in that order of precedence); a singular configuration is
/// left out while others solve the target.
pub fn inverse_all(
    robot: &RobotDescription,
    flange: &Isometry3<f64>,
) -> Result<Vec<IkSolution>, IkError> {
    let mut out = Vec::with_capacity(32);
    inverse_all_into(robot, flange, &mut out)?;
    Ok(out)
}

/// [`inverse_all`] into a reused buffer (cleared first).
pub fn inverse_all_into(
    robot: &RobotDescription,
    flange: &Isometry3<f64>,
    out: &mut Vec<IkSolution>,
) -> Result<(), IkError> {
    let (r, p) = parts(flange);
    let configs = configurations(robot, &r, &p, None, None);
    out.clear();
    for (s, c) in configs.iter().enumerate() {
        let Config::Solved {
            axes,
            singular: None,
        } = c
        else {
            continue;
        };
        let start = out.len();
        let mut axes_out = [0.0; 6];
        for_each_variant(robot, axes, 0, &mut axes_out, &mut |a| {
            out.push(IkSolution {
                axes_deg: *a,
                s: s as u8,
                t: turn(a),
            })
        });
        out[start..].sort_by_key(|sol| sol.t);
    }
    if out.is_empty() {
        return Err(failure(robot, &configs));
    }
    Ok(())
}

/// Calls `f` with every combination of variants of axes `i..6`.
fn for_each_variant(
    robot: &RobotDescription,
    axes: &[f64; 6],
    i: usize,
    current: &mut [f64; 6],
    f: &mut impl FnMut(&[f64; 6]),
) {
    if i == 6 {
        f(current);
        return;
    }
    for a in variants(robot, i, axes[i]) {
        current[i] = a;
        for_each_variant(robot, axes, i + 1, current, f);
    }
}

fn squared_distance(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The selected solution of `flange` (see [`Select`]).
pub fn inverse(
    robot: &RobotDescription,
    flange: &Isometry3<f64>,
    select: Select,
) -> Result<IkSolution, IkError> {
    let (r, p) = parts(flange);
    match select {
        Select::Status { s, t } => {
            let s = s & 7;
            let configs = configurations(robot, &r, &p, None, Some(s));
            match configs[s as usize] {
                Config::Solved {
                    singular: Some(sing),
                    ..
                } => Err(IkError::Singular {
                    kind: sing.kind,
                    distance_deg_or_mm: sing.distance,
                }),
                Config::Solved { axes, .. } => match pick(robot, &axes, &[0.0; 6], t) {
                    Some(axes_deg) => Ok(IkSolution {
                        axes_deg,
                        s,
                        t: turn(&axes_deg),
                    }),
                    None => match out_of_limits(robot, &axes) {
                        Some(e) => Err(e),
                        None => Err(no_branch(robot, flange, s, t)),
                    },
                },
                Config::Unreachable { .. } => Err(no_branch(robot, flange, s, t)),
                Config::Skipped => unreachable!("the selected configuration is computed"),
            }
        }
        Select::StatusNearest { s, near } => {
            let s = s & 7;
            let configs = configurations(robot, &r, &p, Some(&near), Some(s));
            match configs[s as usize] {
                Config::Solved { axes, .. } => match pick(robot, &axes, &near, None) {
                    Some(axes_deg) => Ok(IkSolution {
                        axes_deg,
                        s,
                        t: turn(&axes_deg),
                    }),
                    None => Err(out_of_limits(robot, &axes)
                        .unwrap_or_else(|| no_branch(robot, flange, s, None))),
                },
                _ => Err(no_branch(robot, flange, s, None)),
            }
        }
        Select::Nearest(near) => {
            let configs = configurations(robot, &r, &p, Some(&near), None);
            let best = configs
                .iter()
                .enumerate()
                .filter_map(|(s, c)| match c {
                    Config::Solved { axes, .. } => pick(robot, axes, &near, None).map(|a| (s, a)),
                    _ => None,
                })
                .min_by(|(_, a), (_, b)| {
                    squared_distance(a, &near).total_cmp(&squared_distance(b, &near))
                });
            match best {
                Some((s, axes_deg)) => Ok(IkSolution {
                    axes_deg,
                    s: s as u8,
                    t: turn(&axes_deg),
                }),
                None => {
                    // Resolved singular configurations only fail by limits or reach.
                    let configs = configs.map(|c| match c {
                        Config::Solved { axes, .. } => Config::Solved {
                            axes,
                            singular: None,
                        },
                        other => other,
                    });
                    Err(failure(robot, &configs))
                }
            }
        }
    }
}

/// The error for a configuration that is not available: unreachable as a whole, or the list
/// of what is.
fn no_branch(robot: &RobotDescription, flange: &Isometry3<f64>, s: u8, t: Option<u8>) -> IkError {
    match inverse_all(robot, flange) {
        Ok(all) => {
            let mut available: Vec<(u8, u8)> = all.iter().map(|x| (x.s, x.t)).collect();
            available.dedup();
            IkError::NoBranch { s, t, available }
        }
        Err(e) => e,
    }
}
