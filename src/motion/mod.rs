//! Motion, language-neutral: the motion form a front end's interpreter yields ([`form`]: for
//! every executed motion, its target as a TCP pose in the robot base frame or an axis set,
//! the interpolation into it, the nominal axis angles the controller computes for it and the
//! arrival motion of every axis, with an opaque handle the front end's rewriter places the
//! new numbers with), and the planning the interpreter computes them with: frames and poses
//! ([`frame`]), the controller's nominal axes ([`nominal`]), the sampled interpolation
//! ([`interpolate`], [`spline`]). Knows nothing of error models nor of any robot language:
//! KRL's interpreter is `krl::interpret`; `compensate` consumes what it yields.

pub mod form;
pub mod frame;
pub mod interpolate;
pub mod lu6;
pub mod nominal;
pub mod spline;

pub use form::{program_states, CircularAngle, Interpolation, Programmed, Rel, Role};
// What only robopost's own tests, benches and fuzz targets name through this path.
#[cfg(any(test, feature = "internals"))]
pub use form::{SplineEnds, Stop};
