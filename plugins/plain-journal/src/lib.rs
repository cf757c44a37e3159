//! `plain-journal`: a hydrodynamic plain journal bearing under dynamic load
//! (docs/laws/plain-journal.md). The law itself is wired to contract v3; these modules are its
//! mathematics.

pub mod bearing;
pub mod reynolds;
pub mod short;
pub mod table;
pub mod tables;
