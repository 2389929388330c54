//! Identification: from laser-tracker measurements to a calibrated error model (the paper's
//! section 2.3 direct method, then a global sparse least-squares refinement over every
//! requested effect).

pub mod lsq;
