//! The laser tracker: a distance scale error about its head, the frame it reports in, and a
//! random error that is not Gaussian — heavy-tailed (Student-t) with an occasional gross error
//! (a beam break, a dirty reflector). No random draw depends on where the target is, so two
//! runs over the same number of measured rows see the same draws whatever the robot does
//! (paired comparisons).

use nalgebra::{Isometry3, Point3, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal, StudentT};

use super::file::{Noise, Tracker};
use crate::kinematics::Frame;

/// Where the tracker stands when nothing says otherwise (the virtual robot's default).
const DEFAULT_STATION_MM: [f64; 3] = crate::simulate::truth::DEFAULT_STATION_MM;

/// The tracker of a physical truth, ready to measure.
#[derive(Clone, Debug)]
pub(super) struct Head {
    /// Pose of the tracker frame in the base frame; `None`: reports in the base frame.
    frame: Option<Isometry3<f64>>,
    station: Vector3<f64>,
    scale: f64,
    noise: Noise,
    /// Student-t scaled to unit variance, when the noise is heavy-tailed.
    student: Option<(StudentT<f64>, f64)>,
}

impl Head {
    pub fn new(t: &Tracker) -> Head {
        let frame = t.frame.map(|f| Frame::from_kuka(&f).to_isometry());
        let station = match (t.station_mm, &frame) {
            (Some(s), _) => Vector3::from(s),
            (None, Some(f)) => f.translation.vector,
            (None, None) => Vector3::from(DEFAULT_STATION_MM),
        };
        let student = t.noise.student_t_dof.and_then(|dof| {
            StudentT::new(dof)
                .ok()
                .map(|d| (d, ((dof - 2.0) / dof).sqrt()))
        });
        Head {
            frame,
            station,
            scale: t.scale_ppm * 1e-6,
            noise: t.noise,
            student,
        }
    }

    /// What the tracker reports for a target truly at `p` (base frame, mm), in its frame.
    pub fn measure(&self, p: &Vector3<f64>, rng: &mut ChaCha8Rng) -> Vector3<f64> {
        let radial = p - self.station;
        let seen = self.station + radial * (1.0 + self.scale);
        let sigma =
            (self.noise.sigma_um + self.noise.sigma_um_per_m * radial.norm() / 1000.0) / 1000.0;
        let mut unit = || -> f64 {
            match &self.student {
                Some((t, scale)) => t.sample(rng) * scale,
                None => StandardNormal.sample(rng),
            }
        };
        let random = Vector3::new(unit(), unit(), unit()) * sigma;
        let gross_draw: f64 = rng.gen();
        let size: f64 = rng.gen_range(0.0..=1.0);
        let direction = Vector3::new(
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
            StandardNormal.sample(rng),
        );
        let gross = if gross_draw < self.noise.gross_probability && direction.norm() > 0.0 {
            let [lo, hi] = self.noise.gross_mm;
            direction.normalize() * (lo + size * (hi - lo))
        } else {
            Vector3::zeros()
        };
        let reported = match &self.frame {
            Some(f) => f.inverse_transform_point(&Point3::from(seen)).coords,
            None => seen,
        };
        reported + random + gross
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::KukaFrame;
    use rand::SeedableRng;

    fn quiet() -> Tracker {
        Tracker {
            noise: Noise::NONE,
            ..Tracker::default()
        }
    }

    #[test]
    fn scale_error_stretches_distances_from_the_head() {
        let head = Head::new(&Tracker {
            station_mm: Some([3000.0, 0.0, 800.0]),
            scale_ppm: 10.0,
            ..quiet()
        });
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        // 2 m from the head: 20 µm further away, along the line of sight.
        let p = Vector3::new(1000.0, 0.0, 800.0);
        let m = head.measure(&p, &mut rng);
        assert!((m - Vector3::new(999.98, 0.0, 800.0)).norm() < 1e-12, "{m}");
    }

    #[test]
    fn reports_in_its_frame() {
        let frame = KukaFrame {
            x: 3200.0,
            y: -900.0,
            z: 150.0,
            a: 150.0,
            b: 0.4,
            c: -0.2,
        };
        let head = Head::new(&Tracker {
            frame: Some(frame),
            ..quiet()
        });
        let p = Vector3::new(1200.0, 300.0, 1000.0);
        let m = head.measure(&p, &mut ChaCha8Rng::seed_from_u64(0));
        let back = Frame::from_kuka(&frame)
            .to_isometry()
            .transform_point(&Point3::from(m))
            .coords;
        assert!((back - p).norm() < 1e-9);
    }

    #[test]
    fn heavy_tails_and_gross_errors_at_their_stated_rates() {
        let noise = Noise {
            sigma_um: 10.0,
            sigma_um_per_m: 0.0,
            student_t_dof: Some(4.0),
            gross_probability: 0.01,
            gross_mm: [0.3, 3.0],
        };
        let head = Head::new(&Tracker {
            station_mm: Some([0.0; 3]),
            noise,
            ..Tracker::default()
        });
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let p = Vector3::zeros();
        let n = 100_000;
        let (mut gross, mut sum2, mut core, mut beyond_4_sigma) = (0, 0.0, 0, 0);
        for _ in 0..n {
            let e = head.measure(&p, &mut rng);
            if e.norm() > 0.25 {
                gross += 1;
                assert!(e.norm() < 3.1);
            } else {
                sum2 += e.norm_squared();
                core += 3;
                beyond_4_sigma += e.iter().filter(|c| c.abs() > 0.04).count();
            }
        }
        // 1 % gross errors (binomial σ ≈ 0.03 %).
        assert!((900..1100).contains(&gross), "{gross}");
        // Unit variance times σ = 10 µm.
        let rms = (sum2 / core as f64).sqrt();
        assert!((rms - 0.010).abs() < 0.0003, "{rms}");
        // Heavier tails than a normal: P(|t4| > 4σ) with σ the t's standard deviation is
        // P(|t| > 4·√2) ≈ 0.0049, a normal's 6.3e-5.
        let rate = beyond_4_sigma as f64 / core as f64;
        assert!((0.003..0.007).contains(&rate), "{rate}");
    }
}
