//! # tribo (host)
//!
//! The Tribo host: the command-line tool and the pieces behind it. Laws are never linked in;
//! they are found and loaded through `tribo_plugin_api::loader`.
//!
//! - [`laws`]: listing of discovered laws (`tribo laws`);
//! - [`scaffold`]: generation of a new law crate (`tribo new-law`);
//! - [`rig`]: rig files (TOML, `extends`), `--set` overrides and validation;
//! - [`lawset`]: law sets (laws on joints, free parameters) usable with any rig;
//! - [`bundled`]: the rigs, law sets and data compiled into the binary;
//! - [`cycle`], [`oil`]: the test cycle's reference speed, oil viscosity;
//! - [`erk`]: embedded Runge-Kutta pairs and step control for the torque-driven crank;
//! - [`mechanics`]: planar rigid multibody model of the rig (positions to joint reactions);
//! - [`progress`]: progress display for long runs (stderr, terminals only);
//! - [`report`], [`output`]: tables, JSON and CSV; result files written atomically;
//! - [`timeseries`]: the per-step CSV of `tribo run --timeseries`, an observer of the run;
//! - [`fit`]: least-squares calibration of a law set's free parameters (one or several runs);
//! - [`score`], [`uncertainty`]: out-of-sample scores (leave-one-out, AICc, BIC, validation
//!   data) and the linearised parameter uncertainty with the 95% band of the torque;
//! - [`study`]: law-set comparisons against measured data, mass response, temperature sweep;
//! - [`sim`]: the run through the test cycle with laws on the joints, and plateau measurement.

pub mod laws;
pub mod output;
pub mod plots;
pub mod progress;
pub mod report;
pub mod scaffold;
pub mod timeseries;

// The layers below the CLI, under the names the binary, tests and benches use.
pub use tribo_config::{bundled, lawset, rig};
pub use tribo_core::{cycle, erk, mechanics, model, observe, oil, sim};
pub use tribo_studies::{fit, score, study, uncertainty};

pub use tribo_plugin_api as plugin_api;
