//! # tribo (host)
//!
//! The `tribo` command-line tool's library: everything between the studies and a terminal or a
//! results directory. It adds no physics; programs that want to embed the solver or run a
//! study use the layers below directly (`tribo_core`, `tribo_config`, `tribo_studies`).
//!
//! Its own modules:
//!
//! - [`report`]: tables for people, CSV tables (through the `csv` writer);
//! - [`results`]: the result directories of `run`, `compare`, `mass-response` and `sweep`:
//!   report's tables, the plots and the correlation files put together, swapped in whole;
//! - [`plots`]: SVG plots of comparisons, mass responses and sweeps, with the files beside them;
//! - [`beside`]: the Sandoval-Heywood correlation beside the laws' FMEP (tables, CSV, plots);
//! - [`output`]: results written atomically: a result directory swapped in whole, a single
//!   file renamed into place;
//! - [`timeseries`]: the per-step CSV of `tribo run --timeseries`, an observer of the run;
//! - [`progress`]: a progress display for long runs (stderr, terminals only);
//! - [`laws`]: the listing of discovered laws (`tribo laws`);
//! - [`check`]: a law by path or name checked against the contract (`tribo check-law`) and
//!   sampled for its force-velocity plot (`tribo plot-law`);
//! - [`scaffold`]: generation of a new law crate (`tribo new-law`).
//!
//! The layers are re-exported under the names the binary, tests and benches have always used:
//! [`rig`], [`lawset`], [`bundled`] from `tribo_config`; [`model`], [`cycle`], [`oil`],
//! [`mechanics`], [`erk`], [`observe`], [`sim`], [`correlation`] from `tribo_core`; [`study`], [`fit`],
//! [`score`], [`uncertainty`] from `tribo_studies`. Laws are never linked in; they are found and
//! loaded through `tribo_plugin_api::loader`.

pub mod beside;
pub mod check;
pub mod isolate;
pub mod laws;
pub mod modes;
pub mod output;
pub mod plots;
pub mod progress;
pub mod report;
pub mod results;
pub mod scaffold;
pub mod timeseries;
pub mod torque_run;

// The layers below the CLI, under the names the binary, tests and benches use.
pub use tribo_config::{bundled, lawset, rig};
pub use tribo_core::{
    correlation, cycle, drivetrain, engine, erk, gas, mechanics, model, observe, oil, sim,
};
pub use tribo_studies::{fit, score, study, uncertainty};

pub use tribo_plugin_api as plugin_api;
