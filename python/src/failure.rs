//! Failures as the Python side sees them: each error of the layers below mapped to the
//! exception class of `tribo.errors` that reports it, and raised in the interpreter.

use std::path::PathBuf;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use serde::Deserialize;
use tribo_config::rig::RigError;
use tribo_core::sim::SimError;
use tribo_plugin_api::loader::LawError;
use tribo_studies::study::{StudyError, SweepInputError};

/// What went wrong, as the Python exception class of `tribo.errors` that reports it.
#[derive(Debug, Clone, Copy, serde::Serialize, Deserialize)]
pub(crate) enum Kind {
    /// A rig, law set, data file, parameter or option the user gave is wrong.
    Input,
    /// A law library cannot be loaded.
    Plugin,
    /// A run failed (a law's fault, the solver did not converge, ...).
    Simulation,
}

impl Kind {
    /// The class name in `tribo.errors`.
    pub(crate) fn class(self) -> &'static str {
        match self {
            Kind::Input => "InputError",
            Kind::Plugin => "PluginError",
            Kind::Simulation => "SimulationError",
        }
    }
}

/// An error on its way to Python: the exception class and the CLI's message.
#[derive(Debug, serde::Serialize, Deserialize)]
pub(crate) struct Failure {
    /// Which exception.
    kind: Kind,
    /// The message as the CLI prints it after `error: `.
    message: String,
}

impl Failure {
    pub(crate) fn new(kind: Kind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
}

/// `e` and its causes joined by `: `, as the CLI prints an error chain (`{:#}` of anyhow).
pub(crate) fn chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text.push_str(": ");
        text.push_str(&s.to_string());
        source = s.source();
    }
    text
}

impl From<RigError> for Failure {
    fn from(e: RigError) -> Self {
        Self::new(Kind::Input, chain(&pythonic(e)))
    }
}

impl From<Box<RigError>> for Failure {
    fn from(e: Box<RigError>) -> Self {
        Self::new(Kind::Input, chain(&pythonic(*e)))
    }
}

/// A rig error located where a Python user put the value: an override the CLI calls `--set`
/// is the `set=` of `Rig(...)`, `Rig.set` or a study function.
pub(crate) fn pythonic(mut e: RigError) -> RigError {
    if e.file.as_os_str() == "--set" {
        e.file = PathBuf::from("set=");
    }
    e
}

impl From<SimError> for Failure {
    fn from(e: SimError) -> Self {
        let kind = match e {
            SimError::Setup { .. } => Kind::Input,
            _ => Kind::Simulation,
        };
        Self::new(kind, chain(&e))
    }
}

impl From<StudyError> for Failure {
    fn from(e: StudyError) -> Self {
        let kind = match &e {
            StudyError::Run { error, .. } if !matches!(**error, SimError::Setup { .. }) => {
                Kind::Simulation
            }
            _ => Kind::Input,
        };
        Self::new(kind, chain(&e))
    }
}

impl From<SweepInputError> for Failure {
    fn from(e: SweepInputError) -> Self {
        Self::new(Kind::Input, chain(&e))
    }
}

impl From<LawError> for Failure {
    fn from(e: LawError) -> Self {
        // The CLI's context for the same failure.
        Self::new(Kind::Plugin, format!("loading law plugins: {}", chain(&e)))
    }
}

impl From<serde_json::Error> for Failure {
    fn from(e: serde_json::Error) -> Self {
        Self::new(Kind::Input, format!("the job handed to tribo._native: {e}"))
    }
}

/// Raise `f` as its `tribo.errors` class (a `RuntimeError` if that module cannot be imported).
pub(crate) fn raise(py: Python<'_>, f: Failure) -> PyErr {
    let class = py
        .import("tribo.errors")
        .and_then(|m| m.getattr(f.kind.class()));
    match class {
        Ok(class) => match class.call1((f.message.clone(),)) {
            Ok(value) => PyErr::from_value(value),
            Err(e) => e,
        },
        Err(_) => PyRuntimeError::new_err(f.message),
    }
}

/// Run `work` without the GIL and turn its failure into the Python exception.
pub(crate) fn detached<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> Result<T, Failure> + Send,
) -> PyResult<T> {
    py.detach(work).map_err(|f| raise(py, f))
}
