//! # tribo-studies
//!
//! The studies users come for, as a library: law sets side by side against measured torque and
//! ranked by their out-of-sample error ([`study::compare`], [`score`], [`uncertainty`]) with a
//! one-sentence [`verdict`],
//! calibration of free parameters on one or several runs ([`fit`]), the response to a lighter
//! or heavier body ([`study::mass_response`]) and to oil temperature ([`study::sweep`]). Runs
//! go through `tribo_core`; rigs and law sets come from `tribo_config`. No printing, no files
//! written: results are plain data (serde) for any front end.

pub mod calibrate;
pub mod error;
pub mod fit;
pub mod inputs;
pub mod model;
pub mod score;
pub mod study;
pub mod uncertainty;
pub mod verdict;
