//! The identification's parameter covariance and what it means for a predicted position: the
//! tracker noise of the campaign carried through the least-squares fit (σ² (JᵀJ)⁻¹, σ the
//! fit's residual scatter per coordinate) and then through the model's position Jacobian at
//! any axis state, `Σ_p = G Σ_θ Gᵀ`. The covariance is never formed: the refinement's sparse
//! Cholesky factor of the normal matrix is kept, and each position needs one solve with the
//! three columns of its sensitivities. Constraint rows of the fit (pins, the smoothness of
//! unobserved and thin table cells) are part of the normal matrix, so a smoothed cell carries
//! the uncertainty of the neighbours it follows; the columns of the tracker frames are too,
//! so a model identified in a tracker frame carries the registration's uncertainty.

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};

use super::lsq::LsqSolution;
use super::refine::{refine, IdentifyError, RefineOptions};
use crate::calibration::{Calibration, MeasurementFrame};
use crate::kinematics::Frame;
use crate::measure::Measurements;
use crate::model::{AxisState, JacobianScratch, Model};

/// The parameter covariance of one fit, for the model it was fitted to (same parameter
/// layout).
pub struct Covariance {
    solution: LsqSolution,
    /// The system's column of each flat model parameter (`None`: held by the fit).
    col_of: Vec<Option<usize>>,
    /// Each column's scale (the system solves for `parameter · scale`).
    col_scale: Vec<f64>,
    /// The fit's residual standard deviation per coordinate, mm.
    pub sigma_mm: f64,
    /// Parameters the data determine (free columns less the smoothed table cells).
    in_fit: usize,
}

impl std::fmt::Debug for Covariance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Covariance")
            .field("columns", &self.col_scale.len())
            .field("sigma_mm", &self.sigma_mm)
            .finish_non_exhaustive()
    }
}

impl Covariance {
    /// From the refinement's factored normal matrix (scaled columns; `col_of` maps flat
    /// model parameters to columns, the remaining columns are the tracker frames').
    pub(super) fn new(
        solution: LsqSolution,
        col_of: Vec<Option<usize>>,
        col_scale: Vec<f64>,
        sigma_mm: f64,
        in_fit: usize,
    ) -> Covariance {
        Covariance {
            solution,
            col_of,
            col_scale,
            sigma_mm,
            in_fit,
        }
    }

    /// Parameters the fit's data determine (its residual has this many fewer degrees of
    /// freedom than coordinates).
    pub fn parameters_in_fit(&self) -> usize {
        self.in_fit
    }

    /// Number of flat model parameters this covariance belongs to.
    #[cfg(any(test, feature = "internals"))]
    pub fn parameters(&self) -> usize {
        self.col_of.len()
    }

    /// The parameters' sensitivities `partials` as scaled columns of the system (`None` when
    /// the fit holds every parameter they touch).
    fn columns(&self, partials: &[(usize, Vector3<f64>)]) -> Option<faer::Mat<f64>> {
        let n = self.col_scale.len();
        let mut h = faer::Mat::<f64>::zeros(n, 3);
        let mut any = false;
        for (i, d) in partials {
            if let Some(Some(c)) = self.col_of.get(*i) {
                for k in 0..3 {
                    h[(*c, k)] += d[k] / self.col_scale[*c];
                }
                any = true;
            }
        }
        any.then_some(h)
    }

    /// The covariance (mm²) of a position whose derivative with respect to each flat model
    /// parameter is `partials` (mm per stored unit, as [`Model::target_jacobian`] gives).
    pub fn of_partials(&self, partials: &[(usize, Vector3<f64>)]) -> Matrix3<f64> {
        self.between_partials(partials, partials)
    }

    /// The cross-covariance (mm²) of two positions with sensitivities `a` and `b`: how the
    /// identification's errors at the two go together (`E[δa δbᵀ]`).
    pub fn between_partials(
        &self,
        a: &[(usize, Vector3<f64>)],
        b: &[(usize, Vector3<f64>)],
    ) -> Matrix3<f64> {
        let (Some(ha), Some(hb)) = (self.columns(a), self.columns(b)) else {
            return Matrix3::zeros();
        };
        let mut z = hb;
        self.solution.solve_normal_in_place(z.as_mut());
        let mut out = Matrix3::zeros();
        for r in 0..3 {
            for c in 0..3 {
                out[(r, c)] = (0..ha.nrows()).map(|k| ha[(k, r)] * z[(k, c)]).sum::<f64>();
            }
        }
        out * self.sigma_mm.powi(2)
    }

    /// The cross-covariance (mm²) of the measurement target's positions `model` predicts at
    /// two states (the identification's errors at two poses, e.g. neighbouring stops).
    pub fn between_targets(&self, model: &Model, a: &AxisState, b: &AxisState) -> Matrix3<f64> {
        let partials = |s: &AxisState| {
            let mut p = Vec::new();
            model.target_jacobian_into(s, &mut JacobianScratch::default(), &mut p);
            p
        };
        self.between_partials(&partials(a), &partials(b))
    }

    /// The covariance (mm²) of the measurement target's position that `model` predicts at
    /// `state`.
    pub fn target(&self, model: &Model, state: &AxisState) -> Matrix3<f64> {
        let mut partials = Vec::new();
        model.target_jacobian_into(state, &mut JacobianScratch::default(), &mut partials);
        self.of_partials(&partials)
    }

    /// The covariance (mm²) of a TCP's position at `state`: the measurement target's when the
    /// tool is it (its identified vector then belongs to the model), else the flange's pose
    /// carried to the tool's point (`δp + δω × R·t`).
    pub fn tcp(&self, model: &Model, state: &AxisState, tool: &Frame) -> Matrix3<f64> {
        if model.tool_is_target(&tool.position) {
            return self.target(model, state);
        }
        let (flange, partials) = model.flange_jacobian(state);
        let arm = flange.rotation * tool.position;
        let at_tool: Vec<(usize, Vector3<f64>)> = partials
            .iter()
            .map(|(i, d)| {
                let position = Vector3::new(d[0], d[1], d[2]);
                let rotation = Vector3::new(d[3], d[4], d[5]);
                (*i, position + rotation.cross(&arm))
            })
            .collect();
        self.of_partials(&at_tool)
    }
}

/// One standard deviation per coordinate (µm) of a position covariance in mm².
pub fn sigma_um(covariance: &Matrix3<f64>) -> [f64; 3] {
    std::array::from_fn(|k| covariance[(k, k)].max(0.0).sqrt() * 1e3)
}

/// The covariance of a calibration, from the measurement files it was identified from: the
/// fit's normal matrix rebuilt at the calibration's values (no iteration), every effect free
/// as `identify` leaves it, the gross errors it left out (`provenance.excluded`) left out
/// again, and with tracker-frame data each file's registration (`provenance.frames`) free as
/// well. With other files the covariance is that of a fit to them, not the calibration's.
pub fn of_calibration(
    cal: &Calibration,
    files: &[Measurements],
) -> Result<Arc<Covariance>, IdentifyError> {
    let mut data = Vec::new();
    let mut frame_of = Vec::new();
    let mut initial_frames = Vec::new();
    let tracker = matches!(cal.frame, MeasurementFrame::Tracker(_));
    let per_file = !cal.provenance.frames.is_empty();
    for (k, m) in files.iter().enumerate() {
        let excluded: std::collections::HashSet<usize> = cal
            .provenance
            .excluded
            .iter()
            .filter(|e| crate::compare::same_file(&e.source, &m.source))
            .map(|e| e.line)
            .collect();
        for s in &m.stops {
            let mut s = s.clone();
            if excluded.contains(&s.line) {
                s.measured_mm = None;
            }
            data.push(s);
            // One registration per file where `identify` found one per file.
            frame_of.push(if per_file { k } else { 0 });
        }
        if k > 0 && !per_file {
            continue;
        }
        if let MeasurementFrame::Tracker(own) = cal.frame {
            let listed = cal
                .provenance
                .frames
                .iter()
                .find(|(source, _)| crate::compare::same_file(source, &m.source))
                .map_or(own, |(_, f)| *f);
            initial_frames.push(Frame::from_kuka(&listed));
        }
    }
    let options = RefineOptions {
        tracker_frame: tracker,
        initial_frames,
        frame_of,
        max_iterations: 0,
        standard_errors: true,
        ..RefineOptions::default()
    };
    let mut model = cal.model();
    let fit = refine(&mut model, &data, &options)?;
    fit.covariance.ok_or(IdentifyError::NoMeasurements)
}
