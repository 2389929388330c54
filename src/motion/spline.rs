//! The shape of a CP spline block (`SPLINE … ENDSPLINE`) through its points: the tangent of
//! the curve at every point, from which each `SPL` segment becomes a cubic Hermite curve
//! ([`super::interpolate::Cartesian::cubic`]). KUKA does not publish the spline its
//! controllers interpolate (the KSS manuals only say that the path through `SPL` points is
//! smooth, and that `SLIN`/`SCIRC` segments keep their line/arc): we use the C1 cubic that
//! is the standard stand-in, the non-uniform Catmull–Rom spline with chord-length knots
//! (Barry & Goldman, "A recursive evaluation algorithm for a class of Catmull-Rom splines",
//! SIGGRAPH 1988; Yuksel, Schaefer & Keyser, "Parameterization and applications of
//! Catmull–Rom curves", CAD 43(7), 2011), with natural (zero-curvature) end conditions at the
//! block's first and last point. What matters here is only the sign of each axis's rate at
//! a point, which any smooth interpolant through the same points shares wherever the curve's
//! turn is not right at the point.

use nalgebra::Vector3;

/// Chords shorter than this (mm) are repeated points: they carry no direction.
const SAME_POINT_MM: f64 = 1e-9;

/// The tangents (derivative of position per unit chord length) of the spline through
/// `points` at each of them. Interior points take the Catmull–Rom tangent with chord-length
/// knots — the derivative at `P₁` of the parabola through `P₀`, `P₁`, `P₂` at knots
/// `0, d₀, d₀+d₁`: `(P₁−P₀)/d₀ − (P₂−P₀)/(d₀+d₁) + (P₂−P₁)/d₁`; the two ends the natural end
/// condition of the cubic Hermite segment there (zero second derivative):
/// `t_end = (3·chord/|chord| − t_neighbour)/2`. Two points give a straight line.
pub fn tangents(points: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let n = points.len();
    let mut t = vec![Vector3::zeros(); n];
    if n < 2 {
        return t;
    }
    let unit = |a: &Vector3<f64>, b: &Vector3<f64>| {
        let d = b - a;
        let l = d.norm();
        if l < SAME_POINT_MM {
            (Vector3::zeros(), 0.0)
        } else {
            (d / l, l)
        }
    };
    for k in 1..n - 1 {
        let (u0, d0) = unit(&points[k - 1], &points[k]);
        let (u1, d1) = unit(&points[k], &points[k + 1]);
        t[k] = if d0 == 0.0 {
            u1
        } else if d1 == 0.0 {
            u0
        } else {
            // (P₁−P₀)/d₀ + (P₂−P₁)/d₁ − (P₂−P₀)/(d₀+d₁), with P₂−P₀ = d₀·u₀ + d₁·u₁.
            u0 + u1 - (u0 * d0 + u1 * d1) / (d0 + d1)
        };
    }
    let (first, _) = unit(&points[0], &points[1]);
    let (last, _) = unit(&points[n - 2], &points[n - 1]);
    if n == 2 {
        t[0] = first;
        t[1] = last;
    } else {
        t[0] = (first * 3.0 - t[1]) / 2.0;
        t[n - 1] = (last * 3.0 - t[n - 2]) / 2.0;
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn points_on_a_line_give_its_direction() {
        let p = [0.0, 10.0, 40.0, 45.0].map(|x| Vector3::new(x, 2.0 * x, 0.0));
        let dir = Vector3::new(1.0, 2.0, 0.0).normalize();
        for t in tangents(&p) {
            assert_relative_eq!(t, dir, epsilon = 1e-12);
        }
    }

    #[test]
    fn interior_tangent_is_the_parabola_derivative() {
        // The parabola y = x² sampled at x = −1, 0, 2: chord lengths √2 and √20; the
        // derivative of the quadratic interpolant (in the chord-length knot) at the middle.
        let p = [
            Vector3::new(-1.0, 1.0, 0.0),
            Vector3::zeros(),
            Vector3::new(2.0, 4.0, 0.0),
        ];
        let (d0, d1) = (2f64.sqrt(), 20f64.sqrt());
        // Derivatives of the Lagrange basis polynomials at the middle knot.
        let (s0, s1, s2) = (0.0, d0, d0 + d1);
        let l0 = (s1 - s2) / ((s0 - s1) * (s0 - s2));
        let l1 = (2.0 * s1 - s0 - s2) / ((s1 - s0) * (s1 - s2));
        let l2 = (s1 - s0) / ((s2 - s0) * (s2 - s1));
        let expected = p[0] * l0 + p[1] * l1 + p[2] * l2;
        assert_relative_eq!(tangents(&p)[1], expected, epsilon = 1e-12);
    }

    proptest::proptest! {
        /// Consecutive cubic segments through the points meet at them with one tangent (C1 in
        /// the chord-length parameter), and the twist is the derivative of the pose.
        #[test]
        fn segments_join_smoothly(
            raw in proptest::collection::vec((-500.0..500.0f64, -500.0..500.0f64, -500.0..500.0f64), 3..7)
        ) {
            use crate::motion::frame::Frame;
            use crate::motion::interpolate::Cartesian;
            let points: Vec<Vector3<f64>> =
                raw.iter().map(|&(x, y, z)| Vector3::new(x, y, z)).collect();
            proptest::prop_assume!(points.windows(2).all(|w| (w[1] - w[0]).norm() > 1.0));
            let t = tangents(&points);
            let at = |p: &Vector3<f64>| Frame { rotation: nalgebra::Matrix3::identity(), position: *p };
            let segs: Vec<Cartesian> = (1..points.len())
                .map(|k| Cartesian::cubic(&at(&points[k - 1]), &at(&points[k]), &t[k - 1], &t[k]))
                .collect();
            for (k, seg) in segs.iter().enumerate() {
                let h = (points[k + 1] - points[k]).norm();
                assert_relative_eq!(seg.pose(0.0).position, points[k], epsilon = 1e-9);
                assert_relative_eq!(seg.pose(1.0).position, points[k + 1], epsilon = 1e-9);
                // Tangent per unit chord length at both ends.
                let v0 = seg.twist(0.0).fixed_rows::<3>(0) / h;
                let v1 = seg.twist(1.0).fixed_rows::<3>(0) / h;
                assert_relative_eq!(v0.into_owned(), t[k], epsilon = 1e-9);
                assert_relative_eq!(v1.into_owned(), t[k + 1], epsilon = 1e-9);
                // Central difference of the position.
                let d = 1e-6;
                let fd = (seg.pose(0.5 + d).position - seg.pose(0.5 - d).position) / (2.0 * d);
                let tw = seg.twist(0.5).fixed_rows::<3>(0).into_owned();
                assert_relative_eq!(fd, tw, epsilon = 1e-4 * (1.0 + tw.norm()));
            }
        }
    }
}
