//! Best-fit circle in space, the paper's tool for the axis average line (section 2.3: "the
//! center of the best-fit circle to the measured trajectory and its orientation define the
//! axis average line"). Three steps:
//! 1. the plane by total least squares — the normal is the right singular vector of the
//!    smallest singular value of the centred points (Pearson's orthogonal regression);
//! 2. the circle in that plane by Kåsa's algebraic fit, linear in (D, E, F) of
//!    `x² + y² + D·x + E·y + F = 0` (I. Kåsa, "A circle fitting procedure and its error
//!    analysis", IEEE Trans. Instrum. Meas. IM-25(1), 1976);
//! 3. Gauss–Newton on the geometric distances `|p − c| − r` from Kåsa's start (the
//!    orthogonal-distance fit of S. J. Ahn, W. Rauh, H.-J. Warnecke, Pattern Recognition
//!    34(12), 2001), which removes Kåsa's bias on short arcs.

use nalgebra::{Matrix3, Unit, Vector2, Vector3};

/// A circle in space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle3 {
    /// The centre, mm.
    pub centre: Vector3<f64>,
    /// Unit normal of the circle's plane (sign as the points' sense of rotation is unknown
    /// here: callers orient it).
    pub normal: Unit<Vector3<f64>>,
    /// The radius, mm.
    pub radius: f64,
    /// RMS of the points' distances from the circle (in-plane and out-of-plane), mm.
    pub rms: f64,
}

impl Circle3 {
    /// The signed angle (radians) of `p` about the normal, measured from `reference`
    /// (both projected onto the plane).
    pub fn angle_of(&self, p: &Vector3<f64>, reference: &Vector3<f64>) -> f64 {
        let n = self.normal.into_inner();
        let project = |v: &Vector3<f64>| {
            let d = v - self.centre;
            d - n * n.dot(&d)
        };
        let (a, b) = (project(reference), project(p));
        n.dot(&a.cross(&b)).atan2(a.dot(&b))
    }
}

/// The best-fit circle through `points`; `None` for fewer than three points or points that
/// are (nearly) collinear.
pub fn fit_circle(points: &[Vector3<f64>]) -> Option<Circle3> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let centroid = points.iter().sum::<Vector3<f64>>() / n as f64;
    let mut scatter = Matrix3::zeros();
    for p in points {
        let d = p - centroid;
        scatter += d * d.transpose();
    }
    let eig = scatter.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let normal = Unit::new_normalize(eig.eigenvectors.column(order[0]).into_owned());
    let u = eig.eigenvectors.column(order[2]).into_owned();
    let v = normal.cross(&u);
    if eig.eigenvalues[order[1]] <= 1e-18 * eig.eigenvalues[order[2]].max(1e-300) {
        return None;
    }
    let flat: Vec<Vector2<f64>> = points
        .iter()
        .map(|p| {
            let d = p - centroid;
            Vector2::new(u.dot(&d), v.dot(&d))
        })
        .collect();

    // Kåsa: least squares of D·x + E·y + F = −(x² + y²).
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for q in &flat {
        let row = Vector3::new(q.x, q.y, 1.0);
        ata += row * row.transpose();
        atb -= row * q.norm_squared();
    }
    let sol = ata.lu().solve(&atb)?;
    let mut c = Vector2::new(-sol.x / 2.0, -sol.y / 2.0);
    let mut r = (c.norm_squared() - sol.z).max(0.0).sqrt();

    // Geometric refinement: residual |q − c| − r, Jacobian (−(q−c)/|q−c|, −1).
    for _ in 0..20 {
        let mut jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        for q in &flat {
            let d = q - c;
            let dist = d.norm();
            if dist == 0.0 {
                continue;
            }
            let j = Vector3::new(-d.x / dist, -d.y / dist, -1.0);
            let res = dist - r;
            jtj += j * j.transpose();
            jtr += j * res;
        }
        let Some(step) = jtj.lu().solve(&(-jtr)) else {
            break;
        };
        c += Vector2::new(step.x, step.y);
        r += step.z;
        if step.norm() < 1e-12 * r.max(1.0) {
            break;
        }
    }
    let centre = centroid + u * c.x + v * c.y;
    let rms = (points
        .iter()
        .map(|p| {
            let d = p - centre;
            let axial = normal.dot(&d);
            let radial = (d - normal.into_inner() * axial).norm() - r;
            axial * axial + radial * radial
        })
        .sum::<f64>()
        / n as f64)
        .sqrt();
    Some(Circle3 {
        centre,
        normal,
        radius: r,
        rms,
    })
}
