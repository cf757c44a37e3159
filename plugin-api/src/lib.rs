//! # tribo-plugin-api
//!
//! The contract between Tribo's solver and friction/damping laws, and everything on both sides
//! of it:
//!
//! - [`contract`]: the `#[repr(C)]` input and output of one evaluation ([`LawInput`],
//!   [`LawOutput`]), mirrored by `include/tribo_law.h` for C, C++ and Fortran laws;
//! - [`Law`] and [`export_law!`]: what a Rust law author writes (a struct, a serde parameter type,
//!   the physics), with all FFI done by the macro;
//! - [`describe`](mod@describe): parameter descriptions and their checking;
//! - `loader` (feature `loader`): discovery and loading of both kinds of library into one handle;
//! - `conformance` (feature `conformance`): the checks of `tribo check-law` as a library, so a
//!   law's own `cargo test` runs them in one line.
//!
//! `abi_stable` is used only inside this crate, so it can be replaced without touching the
//! host or any law.

#[cfg(feature = "conformance")]
pub mod conformance;
pub mod contract;
pub mod describe;
mod law;
#[cfg(feature = "loader")]
pub mod loader;
#[doc(hidden)]
pub mod rust_abi;
pub mod tribology;

pub use contract::{
    smooth_sign, suits, suits_text, suits_words, BadDiagnostic, BearingType, InnerBody, JointKind,
    LawInput, LawOutput, Regime, AFFINE_IN_LOAD, CONTRACT_VERSION, DIAGNOSTIC_FLAGS,
    HAS_ASPERITY_SHARE, HAS_COEFFICIENT, HAS_DERIVATIVE, HAS_DUTY_PARAMETER, HAS_ECCENTRICITY,
    HAS_LOAD_DERIVATIVE, HAS_MIN_FILM, HAS_PEAK_PRESSURE, SUITS_PLAIN, SUITS_ROLLING, SUITS_SLIDE,
};
pub use describe::{LawDescription, ParamError, ParamSpec, ParamValue};
pub use law::{assert_law_is_consistent, create_from_table, describe as describe_law, Law};

/// Re-exported so law crates need no direct serde dependency for their parameter type.
pub use serde;
pub use toml;
