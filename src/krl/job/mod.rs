//! A KRL program's compensation end to end: load its files ([`files`], [`batch`] for many),
//! walk it ([`super::interpret`]) and compensate every segment as the walk hands the stops over
//! ([`segments`], solving with `crate::compensate`), rewrite the files ([`super::rewrite`]),
//! and summarise what happened in a report ([`report`], [`taken`]).

pub mod batch;
pub mod files;
pub mod program;
pub mod report;
mod segments;
pub mod taken;

pub use program::{compensate_program, compensate_program_from, Calibrated, ProgramResult, Report};
pub use taken::Taken;
