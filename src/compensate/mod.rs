//! Compensation: for every target of a simulated program, the command for which the error
//! model predicts the programmed TCP pose, with the rotation directions of the compensated
//! motion. This module owns the solver ([`solve`]: the paper's equation (3) iterated to a
//! fixed point, or one step of it), the sequence logic ([`sequence`]: nominal directions,
//! parallel solving, the sequential direction re-check and the resolution of backlash-branch
//! oscillation). It knows no robot language: its input is a list of goal poses with nominal
//! axes and arrival motions (built from the motion form, `motion::form`), its output the
//! command axes per target, which a front end's rewriter places back into the program (KRL's:
//! `krl::rewrite`; the program job that drives both is `krl::job`).

pub mod sequence;
pub mod solve;

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
