//! Rigid registration of two point sets: the rotation and translation that best map one onto
//! the other in the least-squares sense, by the SVD of the cross-covariance matrix (Arun,
//! Huang and Blostein, "Least-squares fitting of two 3-D point sets", IEEE PAMI 9(5), 1987,
//! with Umeyama's sign correction against reflections, IEEE PAMI 13(4), 1991). It gives the
//! tracker frame's starting value before the Levenberg–Marquardt refinement.

use nalgebra::{Matrix3, Vector3};

use crate::kinematics::Frame;

/// The rigid transform `T` minimising `Σ |T·from_i − to_i|²`; `None` for fewer than three
/// points or collinear points (the rotation is then not determined).
pub fn rigid_fit(from: &[Vector3<f64>], to: &[Vector3<f64>]) -> Option<Frame> {
    let n = from.len().min(to.len());
    if n < 3 {
        return None;
    }
    let mean = |v: &[Vector3<f64>]| v[..n].iter().sum::<Vector3<f64>>() / n as f64;
    let (cf, ct) = (mean(from), mean(to));
    let mut h = Matrix3::zeros();
    for (a, b) in from.iter().zip(to).take(n) {
        h += (a - cf) * (b - ct).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut s = svd.singular_values;
    s.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    if s[1] <= 1e-12 * s[0].max(1e-300) {
        return None;
    }
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    Some(Frame {
        rotation: r,
        position: ct - r * cf,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Isometry3;

    #[test]
    fn recovers_a_known_transform() {
        let truth = Isometry3::new(
            Vector3::new(3000.0, -500.0, 120.0),
            Vector3::new(0.1, -0.2, 2.5),
        );
        let from: Vec<Vector3<f64>> = (0..20)
            .map(|i| {
                let t = i as f64;
                Vector3::new(t.sin() * 900.0, (1.7 * t).cos() * 700.0, t * 40.0)
            })
            .collect();
        let to: Vec<Vector3<f64>> = from
            .iter()
            .map(|p| truth.transform_point(&(*p).into()).coords)
            .collect();
        let fit = rigid_fit(&from, &to).unwrap();
        assert!((fit.position - truth.translation.vector).norm() < 1e-8);
        assert!(fit.to_isometry().rotation.angle_to(&truth.rotation) < 1e-12);
        assert!(rigid_fit(&from[..2], &to[..2]).is_none());
    }
}
