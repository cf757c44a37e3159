//! # tribo-config
//!
//! Everything between a user's files and the solver core: rig files ([`rig`]: the TOML schema
//! of `tribo_core::model`, `extends`, `--set` overrides, `--law` attachment and validation with
//! errors that name the file, line, column and field), law sets ([`lawset`]: laws on joints and
//! free parameters), the files bundled into the binary ([`bundled`]) and the capped reading of
//! input files ([`files`]). It produces the plain model the core consumes ([`rig::Rig::model`])
//! and binds its laws ([`rig::simulation`]).

// Issue 28's rule for the core and the config crate: small named stages, no function over 80
// lines (the threshold is in the workspace's clippy.toml; CI denies clippy's warnings).
#![warn(clippy::too_many_lines)]

pub mod bundled;
pub mod files;
pub mod lawset;
pub mod rig;
