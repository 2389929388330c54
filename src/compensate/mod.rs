//! Compensation: for every target of a simulated program, the command for which the error
//! model predicts the programmed TCP pose, with the rotation directions of the compensated
//! motion. This module owns the solver ([`solve`]: the paper's equation (3) iterated to a
//! fixed point, or one step of it), the sequence logic ([`sequence`]: nominal directions,
//! parallel solving, the sequential direction re-check and the resolution of backlash-branch
//! oscillation), the program pipeline ([`program`]: compensated segment by segment as the walk
//! hands over the stops — the whole program at once, or a streamed run window by window) and
//! the rewrite. The solver and sequence logic know nothing of KRL: their
//! input is a list of goal poses with nominal axes and arrival motions (from `motion`), its
//! output the command axes per target (turned into KRL edits by `rewrite`).

pub mod sequence;
pub mod solve;

// Moved to the KRL front end (`krl::job`, `krl::rewrite`); named here until the seam's next
// commit.
pub use crate::krl::job::{batch, files, program, report};

pub use crate::krl::job::{
    compensate_program, compensate_program_from, Calibrated, ProgramResult, Report, Taken,
};
pub use solve::Method;
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use {
    crate::motion::frame::{self as pose, Frame},
    sequence::{
        compensate, nominal_directions, Interp, Keep, Options, Outcome, Resolution, Target,
        TargetError, REST_DEG,
    },
    solve::{SolveError, TOL_POSITION_MM, TOL_ROTATION_RAD},
};
