//! Why a study failed: one error type for every study, and the sweep's input errors it wraps.

use std::path::PathBuf;

use tribo_config::rig::RigError;
use tribo_core::sim::SimError;

/// Why a study failed.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// A rig or law-set problem.
    #[error(transparent)]
    Rig(#[from] Box<RigError>),
    /// A run failed.
    // The run's message is part of this one and not also a `source`: the CLI prints the
    // chain of sources, which repeated it.
    #[error("law set `{lawset}`: {error}")]
    Run {
        /// Law set.
        lawset: String,
        /// The failure.
        error: Box<SimError>,
    },
    /// A law set's laws cannot be bound on the rig (an unknown law, a misspelled or
    /// out-of-range parameter): found by [`crate::inputs::check_lawsets`] before any run starts.
    #[error("law set `{lawset}`: {error}")]
    Laws {
        /// Law set.
        lawset: String,
        /// Where and what (the law-set file's line and column, or the `--law` argument).
        error: Box<SimError>,
    },
    /// A sweep's temperatures or speeds are unusable.
    #[error(transparent)]
    Input(#[from] SweepInputError),
    /// Two law sets of one study share a name (their results and plots would overwrite each
    /// other).
    #[error("two law sets are named `{name}` ({} and {}); every law set in one run needs its own name, as it names the result rows and plot files: rename one (its `name = ...` line)", first.display(), second.display())]
    DuplicateLawSet {
        /// The shared name.
        name: String,
        /// The first file with it.
        first: PathBuf,
        /// The second file with it.
        second: PathBuf,
    },
    /// A data file problem.
    #[error("{file}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Data {
        /// File.
        file: PathBuf,
        /// Line, if known.
        line: Option<u64>,
        /// What is wrong.
        message: String,
    },
}

/// Why a sweep's temperatures or speeds are unusable; names the command-line option.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{option}: {message}")]
pub struct SweepInputError {
    /// The option, e.g. `--temps`.
    pub option: String,
    /// What is wrong and what is allowed.
    pub message: String,
}
