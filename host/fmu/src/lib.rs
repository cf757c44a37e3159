//! # tribo-fmu
//!
//! A Tribo rig with its laws as an FMI 2.0 Co-Simulation FMU for Linux x86_64
//! (`tribo fmu export`, `docs/fmu.md`). Two halves in one crate:
//!
//! - the FMU's library, built as this crate's cdylib and shipped as
//!   `binaries/linux64/tribo_fmu.so`: the FMI C API ([`fmi2`]) over an [`instance::Instance`]
//!   per importer instance, which starts a worker process and talks to it ([`process`],
//!   [`protocol`]); it runs no law code itself, so a law that crashes or hangs costs the
//!   importer an `fmi2Error`, never its process;
//! - what the `tribo` binary uses: the worker's request loop ([`worker`], run as
//!   `tribo __fmu-worker`) over a [`dynamic::Dynamic`] run of the rig (the core's stepping
//!   API), and the export
//!   ([`export`]): the variables ([`interface`]), `modelDescription.xml`
//!   ([`model_description`]) and the archive.

pub mod dynamic;
pub mod export;
pub mod fmi2;
pub mod instance;
pub mod interface;
pub mod log;
pub mod model_description;
pub mod process;
pub mod protocol;
pub mod stepping;
pub mod uri;
pub mod worker;

use std::fmt::Display;
use std::path::{Path, PathBuf};

/// Why an export, or a worker's reading of its resources, failed.
#[derive(Debug, thiserror::Error)]
pub enum FmuError {
    /// A resource file is missing or unreadable or says something wrong.
    #[error("{}: {message}", path.display())]
    Resource {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A law of the rig cannot be described or its parameters are refused.
    #[error("joint `{joint}`, law `{law}`: {message}")]
    Law {
        /// Joint.
        joint: String,
        /// Law.
        law: String,
        /// What is wrong.
        message: String,
    },
    /// A resource was read and found wrong; the message names the file (and line and column,
    /// and the field).
    #[error("{0}")]
    Invalid(String),
    /// The worker's channel to the FMU broke.
    #[error("the channel between the FMU and its worker process: {0}")]
    Channel(String),
    /// The export cannot be made as asked.
    #[error("{0}")]
    Export(String),
}

impl FmuError {
    /// A problem with the resource `path`.
    pub fn resource(path: &Path, e: impl Display) -> Self {
        Self::Resource {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }

    /// A broken channel.
    pub fn channel(e: impl Display) -> Self {
        Self::Channel(e.to_string())
    }
}
