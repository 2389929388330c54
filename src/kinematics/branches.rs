//! The closed-form solution of one flange pose, in stages so that selection pays only for what
//! it uses: the target (wrist point, A1), a shoulder (front/back: the elbow angle), an arm
//! branch (A1..A3 and the wrist rotation left to A4..A6), a wrist (A4..A6 and its flip).
//!
//! Method (Brandstötter, Angerer & Hofbaur 2014, OPW; see `fk.rs`): the wrist point
//! `C = p − l5x·ẑ_flange` gives θ1 = atan2(Cy, Cx) (front) or +180° (back); in the arm plane the
//! wrist point relative to A2 is `D = l2·e^{iθ2} + K·e^{i(θ2+θ3+ψ)}` (complex numbers z + i·x,
//! `K·e^{iψ} = l3z + i·l4x`), so the elbow angle e = θ3 + ψ follows from |D| by the law of
//! cosines — here in its half-angle form `tan²(e/2) = ((l2+K)² − |D|²) / (|D|² − (l2−K)²)`,
//! which stays accurate at the stretched arm where `acos` loses half the digits — and
//! θ2 = arg D − arg(l2 + K·e^{ie}). The wrist rotation `Rx(θ4)·Ry(θ5)·Rx(θ6) = R03ᵀ·R06` is
//! read as X-Y-X Euler angles, with the flip (θ4+180°, −θ5, θ6+180°). Every sine and cosine
//! the frames need comes from these complex numbers; only the output angles cost an `atan2`
//! (20 for all eight configurations, 7 for one).

use std::f64::consts::PI;

use nalgebra::{Matrix3, RowVector3, Vector3};

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

/// Angle in (−180°, 180°]. The inputs are sums of a few half turns at most, so a loop is
/// cheaper than `floor` (a library call on baseline x86-64).
#[inline]
pub(crate) fn wrap_deg(mut a: f64) -> f64 {
    if !a.is_finite() {
        return a;
    }
    while a > 180.0 {
        a -= 360.0;
    }
    while a <= -180.0 {
        a += 360.0;
    }
    a
}

/// `sqrt(x² + y²)`: the values here are mm and direction cosines, far from overflow, and
/// `hypot`'s extra care costs more than the rest of a branch.
#[inline]
fn norm2(x: f64, y: f64) -> f64 {
    (x * x + y * y).sqrt()
}

/// What every configuration of one flange pose shares.
pub(crate) struct Target<'h> {
    g: Geometry,
    /// A6 frame rotation: flange · Ry(90°)ᵀ, columns (ẑ, ŷ, −x̂) of the flange.
    r06: Matrix3<f64>,
    wrist: Vector3<f64>,
    radius: f64,
    /// cos θ1, sin θ1 of the front shoulder (from the hint on the A1 axis).
    c1: f64,
    s1: f64,
    /// The wrist point's x in the front A1 frame (the radius, or ~0 on the axis).
    x_front: f64,
    a1_front: f64,
    /// ψ = atan2(l4x, l3z): θ3 = e − ψ.
    psi: f64,
    /// Previous axes: resolve undetermined A1 / A4 with them (else 0°, `$SINGUL_POS[] = 0`).
    hint: Option<&'h [f64; 6]>,
}

impl<'h> Target<'h> {
    pub fn new(
        robot: &RobotDescription,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
        hint: Option<&'h [f64; 6]>,
    ) -> Target<'h> {
        let g = Geometry::new(robot);
        let approach = r.column(2).into_owned();
        let r06 = Matrix3::from_columns(&[approach, r.column(1).into_owned(), -r.column(0)]);
        let wrist = p - g.links.l5x * approach;
        let radius = norm2(wrist.x, wrist.y);
        let (s1, c1, a1_front) = if radius < SHOULDER_SINGULAR_MM {
            let a1 = hint.map_or(0.0, |h| h[0]);
            let (s, c) = g.theta(0, a1).sin_cos();
            (s, c, a1)
        } else {
            let (s, c) = (wrist.y / radius, wrist.x / radius);
            (s, c, wrap_deg(g.kuka(0, s.atan2(c))))
        };
        Target {
            g,
            r06,
            wrist,
            radius,
            c1,
            s1,
            x_front: wrist.x * c1 + wrist.y * s1,
            a1_front,
            psi: g.psi(),
            hint,
        }
    }

    fn shoulder_singular(&self) -> bool {
        self.radius < SHOULDER_SINGULAR_MM
    }

    /// A1 of the front or back shoulder (known before the shoulder is solved).
    pub fn a1(&self, back: bool) -> f64 {
        if back {
            wrap_deg(self.a1_front + 180.0)
        } else {
            self.a1_front
        }
    }
}

/// One shoulder (front or back) that reaches the wrist point.
pub(crate) struct Shoulder {
    back: bool,
    c1: f64,
    s1: f64,
    a1: f64,
    /// Wrist point relative to the A2 axis in the arm plane.
    dx: f64,
    dz: f64,
    /// |e|, sin|e|, cos e.
    e_abs: f64,
    sin_abs: f64,
    cos_e: f64,
    /// Degrees to the stretched or folded arm.
    elbow_distance: f64,
}

/// Why a shoulder does not reach: the wrist point's distance outside the annulus the arm
/// sweeps, and on which side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct OutOfReach {
    pub distance_mm: f64,
    pub too_far: bool,
}

#[inline]
pub(crate) fn shoulder(t: &Target, back: bool) -> Result<Shoulder, OutOfReach> {
    let g = &t.g;
    let sigma = if back { -1.0 } else { 1.0 };
    let (c1, s1, x) = (sigma * t.c1, sigma * t.s1, sigma * t.x_front);
    let a1 = t.a1(back);
    let (dx, dz) = (x - g.links.l1x, t.wrist.z - g.links.l1z);
    let dn = norm2(dx, dz);
    let (sum, diff) = (g.links.l2 + g.k, (g.links.l2 - g.k).abs());
    let (outer, inner) = (sum - dn, dn - diff);
    if outer < -REACH_TOLERANCE_MM {
        return Err(OutOfReach {
            distance_mm: -outer,
            too_far: true,
        });
    }
    if inner < -REACH_TOLERANCE_MM {
        return Err(OutOfReach {
            distance_mm: -inner,
            too_far: false,
        });
    }
    // Half-angle law of cosines with both factors as differences (accurate at the edges).
    let sh = (outer.max(0.0) * (sum + dn)).sqrt();
    let ch = (inner.max(0.0) * (dn + diff)).sqrt();
    let h = norm2(sh, ch);
    let (sh, ch) = (sh / h, ch / h);
    let e_abs = 2.0 * sh.atan2(ch);
    Ok(Shoulder {
        back,
        c1,
        s1,
        a1,
        dx,
        dz,
        e_abs,
        sin_abs: 2.0 * sh * ch,
        cos_e: ch * ch - sh * sh,
        elbow_distance: e_abs.min(PI - e_abs).to_degrees(),
    })
}

/// The elbow angle e of the elbow branch `up` (S bit 1 is A3 ≥ A3(stretched), i.e.
/// sense3·e ≥ 0), with its sine.
#[inline]
fn elbow(t: &Target, sh: &Shoulder, up: bool) -> (f64, f64) {
    let sign = if up { t.g.senses[2] } else { -t.g.senses[2] };
    (sign * sh.e_abs, sign * sh.sin_abs)
}

/// A3 of an elbow branch (known before the arm is solved).
pub(crate) fn a3(t: &Target, sh: &Shoulder, up: bool) -> f64 {
    wrap_deg(t.g.kuka(2, elbow(t, sh, up).0 - t.psi))
}

/// One arm branch: A1..A3 and the wrist rotation M = Rx(θ4)·Ry(θ5)·Rx(θ6) left to solve.
pub(crate) struct Arm {
    /// S bits 0 and 1 of this branch.
    pub bits: u8,
    pub axes: [f64; 3],
    /// Rows of M.
    m: [RowVector3<f64>; 3],
    pub singular: Option<Singularity>,
}

#[inline]
pub(crate) fn arm(t: &Target, sh: &Shoulder, up: bool) -> Arm {
    let g = &t.g;
    let (l2, k) = (g.links.l2, g.k);
    let (e, sin_e) = elbow(t, sh, up);
    let cos_e = sh.cos_e;
    let (dx, dz) = (sh.dx, sh.dz);
    // θ2 = arg(D·conj(l2 + K·e^{ie})), D = dz + i·dx.
    let (qr, qi) = (l2 + k * cos_e, k * sin_e);
    let t2 = (dx * qr - dz * qi).atan2(dz * qr + dx * qi);
    // e^{i(θ2+θ3)} = D·(l2·e^{ie} + K)·(l3z − i·l4x) / (K·|D|²).
    let (ar, ai) = (l2 * cos_e + k, l2 * sin_e);
    let (br, bi) = (dz * ar - dx * ai, dz * ai + dx * ar);
    let (cr, ci) = (
        br * g.links.l3z + bi * g.links.l4x,
        bi * g.links.l3z - br * g.links.l4x,
    );
    let norm = norm2(cr, ci);
    let (c23, s23) = (cr / norm, ci / norm);
    // G = Rz(θ1)ᵀ·R06, then M = Ry(θ2+θ3)ᵀ·G.
    let r = &t.r06;
    let g0 = sh.c1 * r.row(0) + sh.s1 * r.row(1);
    let g1 = sh.c1 * r.row(1) - sh.s1 * r.row(0);
    let g2 = r.row(2).into_owned();
    let m = [c23 * g0 - s23 * g2, g1, s23 * g0 + c23 * g2];
    let singular = if t.shoulder_singular() {
        Some(Singularity {
            kind: SingularityKind::Shoulder,
            distance: t.radius,
        })
    } else if sh.elbow_distance < ELBOW_SINGULAR_DEG {
        Some(Singularity {
            kind: SingularityKind::Elbow,
            distance: sh.elbow_distance,
        })
    } else {
        None
    };
    Arm {
        bits: u8::from(sh.back) | u8::from(up) << 1,
        axes: [
            sh.a1,
            wrap_deg(g.kuka(1, t2)),
            wrap_deg(g.kuka(2, e - t.psi)),
        ],
        m,
        singular,
    }
}

/// The two wrist solutions of an arm branch: A4..A6 with A5 ≥ 0 and with A5 < 0 (S bit 2),
/// and the wrist singularity if A5 is undetermined (both are then the same resolution).
pub(crate) struct Wrist {
    pub positive: [f64; 3],
    pub negative: [f64; 3],
    pub singular: Option<Singularity>,
}

#[inline]
pub(crate) fn wrist(t: &Target, arm: &Arm) -> Wrist {
    let g = &t.g;
    let [m0, m1, m2] = &arm.m;
    let sb = norm2(m0[1], m0[2]);
    if sb < WRIST_SINGULAR_SIN {
        // Only θ4 ± θ6 is defined: Rx(θ4 + θ6) at θ5 = 0, Rx(θ4 − θ6)·Ry(π) at π. Keep A4.
        let spin = m2[1].atan2(m1[1]);
        let a4 = t.hint.map_or(0.0, |h| h[3]);
        let t4 = g.theta(3, a4);
        let (t5, t6) = if m0[0] > 0.0 {
            (0.0, spin - t4)
        } else {
            (PI, t4 - spin)
        };
        let axes = [a4, wrap_deg(g.kuka(4, t5)), wrap_deg(g.kuka(5, t6))];
        return Wrist {
            positive: axes,
            negative: axes,
            singular: Some(Singularity {
                kind: SingularityKind::Wrist,
                distance: sb.atan2(m0[0].abs()).to_degrees(),
            }),
        };
    }
    let (t4, t5, t6) = (m1[0].atan2(-m2[0]), sb.atan2(m0[0]), m0[1].atan2(m0[2]));
    let plain = [
        wrap_deg(g.kuka(3, t4)),
        wrap_deg(g.kuka(4, t5)),
        wrap_deg(g.kuka(5, t6)),
    ];
    let flipped = [
        wrap_deg(plain[0] + 180.0),
        wrap_deg(-plain[1]),
        wrap_deg(plain[2] + 180.0),
    ];
    let (positive, negative) = if plain[1] < 0.0 {
        (flipped, plain)
    } else {
        (plain, flipped)
    };
    Wrist {
        positive,
        negative,
        singular: None,
    }
}

/// A1..A6 of an arm branch and one of its wrist solutions.
pub(crate) fn join(arm: &[f64; 3], wrist: &[f64; 3]) -> [f64; 6] {
    [arm[0], arm[1], arm[2], wrist[0], wrist[1], wrist[2]]
}
