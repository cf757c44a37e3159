//! # tribo-core
//!
//! The solver any program can embed: a rig described as plain data ([`model`]), its planar
//! multibody mechanics ([`mechanics`]), the test cycle ([`cycle`]), oil viscosity ([`oil`]), gas pressures on the piston ([`gas`]),
//! embedded Runge-Kutta pairs ([`erk`]) and the simulation that runs the cycle with friction
//! laws on the joints ([`sim`]). It reads no file and writes nothing but what the caller hands
//! it; progress is reported through [`observe`]. Laws come through `tribo_plugin_api`.

// Issue 28's rule for the core and the config crate: small named stages, no function over 80
// lines (the threshold is in the workspace's clippy.toml; CI denies clippy's warnings).
#![warn(clippy::too_many_lines)]

pub mod correlation;
pub mod cycle;
pub mod drivetrain;
pub mod engine;
pub mod erk;
pub mod gas;
pub mod mechanics;
pub mod model;
pub mod observe;
pub mod oil;
pub mod sim;

pub use tribo_plugin_api as plugin_api;
