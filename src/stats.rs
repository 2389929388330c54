//! The paper's Table 1 statistics of positioning errors: mean and 2σ of the XY-plane distance
//! error and of the signed Z error, plus 3-D distance mean/max and RMS (CONTRACTS.md keys).
//! Errors come in mm (predicted − measured or measured − commanded); statistics are in µm.

use nalgebra::Vector3;
use serde::Serialize;

/// Error statistics of a set of points, in µm (keys per CONTRACTS.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Points the statistics are over.
    pub points: usize,
    /// Mean of the distance error in the XY plane.
    pub xy_mean_um: f64,
    /// Twice the standard deviation of the XY distance error.
    pub xy_2sigma_um: f64,
    /// Mean of the signed Z error.
    pub z_mean_um: f64,
    /// Twice the standard deviation of the signed Z error.
    pub z_2sigma_um: f64,
    /// Mean of the 3-D distance error.
    pub d3_mean_um: f64,
    /// Largest 3-D distance error.
    pub d3_max_um: f64,
    /// Root mean square of the 3-D distance error.
    pub rms_um: f64,
}

/// Mean and sample standard deviation (n − 1; 0 for fewer than two values).
fn mean_std(values: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = values.clone().count();
    if n == 0 {
        return (0.0, 0.0);
    }
    let mean = values.clone().sum::<f64>() / n as f64;
    if n < 2 {
        return (mean, 0.0);
    }
    let var = values.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    (mean, var.sqrt())
}

/// Statistics of error vectors given in mm.
pub fn error_stats(errors_mm: &[Vector3<f64>]) -> ErrorStats {
    let um = |v: f64| v * 1000.0;
    let xy = errors_mm.iter().map(|e| um(e.x.hypot(e.y)));
    let z = errors_mm.iter().map(|e| um(e.z));
    let d3 = errors_mm.iter().map(|e| um(e.norm()));
    let (xy_mean, xy_std) = mean_std(xy);
    let (z_mean, z_std) = mean_std(z);
    let (d3_mean, _) = mean_std(d3.clone());
    let n = errors_mm.len();
    let rms = if n == 0 {
        0.0
    } else {
        (d3.clone().map(|d| d * d).sum::<f64>() / n as f64).sqrt()
    };
    ErrorStats {
        points: n,
        xy_mean_um: xy_mean,
        xy_2sigma_um: 2.0 * xy_std,
        z_mean_um: z_mean,
        z_2sigma_um: 2.0 * z_std,
        d3_mean_um: d3_mean,
        d3_max_um: d3.fold(0.0, f64::max),
        rms_um: rms,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_table_one_statistics() {
        // Errors (mm): (0.003, 0.004, 0.012) → xy 5 µm, z 12 µm, 3-D 13 µm;
        //              (0.006, 0.008, -0.012) → xy 10 µm, z −12 µm, 3-D sqrt(100+144) µm.
        let s = error_stats(&[
            Vector3::new(0.003, 0.004, 0.012),
            Vector3::new(0.006, 0.008, -0.012),
        ]);
        let d2 = 244f64.sqrt();
        assert_eq!(s.points, 2);
        assert!((s.xy_mean_um - 7.5).abs() < 1e-9);
        // sample std of {5, 10} = sqrt(12.5) → 2σ = 7.0711
        assert!((s.xy_2sigma_um - 2.0 * 12.5f64.sqrt()).abs() < 1e-9);
        assert!(s.z_mean_um.abs() < 1e-9);
        assert!((s.z_2sigma_um - 2.0 * (288.0f64).sqrt()).abs() < 1e-9);
        assert!((s.d3_mean_um - (13.0 + d2) / 2.0).abs() < 1e-9);
        assert!((s.d3_max_um - d2).abs() < 1e-9);
        assert!((s.rms_um - ((169.0 + 244.0) / 2.0f64).sqrt()).abs() < 1e-9);
    }

    #[test]
    fn empty_and_single_point() {
        assert_eq!(error_stats(&[]).points, 0);
        let s = error_stats(&[Vector3::new(0.0, 0.0, -0.002)]);
        assert_eq!((s.z_mean_um, s.z_2sigma_um), (-2.0, 0.0));
    }
}
