//! Rig files: the TOML description of a motored rig, its overrides (`--set`), and validation
//! with errors that name the file, line, column and field.
//!
//! Split by concern: `error` (where a problem is: file, line, column, field), `load`
//! (`extends` chains, `--set`, deserialisation), `trace` (a cylinder-pressure CSV), `validate`
//! (physical ranges and sizes, one validator per part of the file), `laws` (`--law`) and
//! `oil_file` (`--oil`). This module holds the loaded [`Rig`] and binds its laws.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use tribo_core::sim::{SimError, Simulation};
use tribo_plugin_api::loader::LawRegistry;

mod error;
mod laws;
mod load;
mod oil_file;
mod trace;
mod validate;

use error::{field_error, location};
pub use error::{file_error, line_col, locate, RigError};
pub use laws::{attach_laws, parse_law_arg, LawArg};
pub use load::{load_rig, load_rig_text};
pub use oil_file::{oil_file_sets, OIL_FILE_KEYS};
pub use validate::{
    revalidate, MAX_CYCLE_S, MAX_DENSITY_KG_M3, MAX_INERTIA_KG_M2, MAX_LENGTH_M, MAX_MASS_KG,
    MAX_SCALE, MAX_SPEED_RPM, MAX_STEP_DEG_RANGE, MAX_VISCOSITY_CST, STEP_DEG_RANGE,
};

pub use tribo_core::model::*;
pub use tribo_core::sim::readable;

/// The most cylinders an engine rig may have.
pub use tribo_core::engine::MAX_CYLINDERS;

/// One file a rig was read from: the rig itself first, then each file it `extends`.
#[derive(Debug, Clone)]
pub struct Source {
    /// Path on disk, or the bundled name.
    pub path: PathBuf,
    /// Text, for locating fields in later errors.
    pub text: String,
}

/// Where a law on a joint was attached when not by the rig file itself, so that an error about
/// it (an unknown law, a misspelled or out-of-range parameter) is reported there.
#[derive(Debug, Clone)]
pub enum LawOrigin {
    /// Entry `entry` (0-based) of the `[[laws]]` of a law-set file.
    LawSet {
        /// The law-set file and its text.
        file: Arc<Source>,
        /// Index of the entry in the file's `laws`.
        entry: usize,
    },
    /// A `--law JOINT=LAW[:PARAMS.toml]` argument, with its parameter file if it names one.
    Arg {
        /// The argument as given.
        arg: String,
        /// The parameter file and its text.
        params: Option<Arc<Source>>,
    },
}

/// A rig loaded and checked: the merged content plus where it came from.
#[derive(Debug, Clone)]
pub struct Rig {
    /// The parsed, merged, overridden and validated content.
    pub file: RigFile,
    /// The rig file and the files it extends, child first.
    pub sources: Vec<Source>,
    /// Dotted paths changed by `--set` or `--law`.
    pub overridden: Vec<String>,
    /// The laws attached by a law set or `--law`, by (joint, index in the joint's laws);
    /// every other law is the rig file's own.
    pub law_origins: BTreeMap<(String, usize), LawOrigin>,
    /// Law-set entries that name no joint of this rig (`piston_5` on a twin), located at the
    /// entry: refused by [`check_laws`] and [`simulation`].
    pub unattached: Vec<RigError>,
}

impl Rig {
    /// The rig file's own path (or bundled name).
    pub fn path(&self) -> &Path {
        &self.sources[0].path
    }

    /// An error about `field`, located in the file that sets it (or attributed to `--set`); a
    /// field of a law attached by a law set or `--law` is located there.
    pub fn error(&self, field: &str, message: impl Into<String>) -> RigError {
        let message = message.into();
        match self.law_error(field, None, &message) {
            Some(e) => e,
            None => field_error(&self.sources, &self.overridden, field, message),
        }
    }

    /// An error about `field` of a law (`joints.J.laws[k]...`) with parameter `param`, if the
    /// law was attached by a law set or `--law`: at the law-set entry (`FILE:line:column`,
    /// field `laws[i] (joint J, law L)`), or at the parameter file of the `--law` argument
    /// (field `--law ARG`), or at `--law` itself. `None` for the rig file's own laws.
    fn law_error(&self, field: &str, param: Option<&str>, message: &str) -> Option<RigError> {
        let (joint, k, rest) = law_field(field)?;
        let origin = self.law_origins.get(&(joint.to_string(), k))?;
        let law = self
            .file
            .joints
            .named()
            .into_iter()
            .find(|(name, _)| *name == joint)
            .and_then(|(_, j)| j.laws.get(k))
            .map_or("", |l| l.law.as_str());
        let at = |src: &Source, paths: &[String]| {
            paths
                .iter()
                .find_map(|p| locate(&src.text, p))
                .map(|span| line_col(&src.text, span.start))
        };
        let (file, at, field) = match origin {
            LawOrigin::LawSet { file, entry } => {
                let path = format!("laws[{entry}]{rest}");
                let mut paths: Vec<String> =
                    param.map(|p| format!("{path}.{p}")).into_iter().collect();
                paths.extend([path, format!("laws[{entry}].law")]);
                (
                    file.path.clone(),
                    at(file, &paths),
                    if law.is_empty() {
                        format!("laws[{entry}] (joint {joint})")
                    } else {
                        format!("laws[{entry}] (joint {joint}, law {law})")
                    },
                )
            }
            LawOrigin::Arg {
                arg,
                params: Some(src),
            } => {
                let paths: Vec<String> = param.map(str::to_string).into_iter().collect();
                (src.path.clone(), at(src, &paths), format!("--law {arg}"))
            }
            LawOrigin::Arg { arg, params: None } => (PathBuf::from("--law"), None, arg.clone()),
        };
        Some(RigError {
            file,
            line: at.map(|a| a.0),
            column: at.map(|a| a.1),
            field,
            message: message.to_string(),
        })
    }

    /// The plain model the solver core consumes.
    pub fn model(&self) -> &RigFile {
        &self.file
    }

    /// Whether the user gave `field` (dotted): written in the rig file or a file it extends,
    /// or set by `--set` (the field or a table holding it), rather than left to its default.
    pub fn gives(&self, field: &str) -> bool {
        self.overridden.iter().any(|o| {
            field == o
                || field
                    .strip_prefix(o.as_str())
                    .is_some_and(|r| r.starts_with('.'))
        }) || self
            .sources
            .iter()
            .any(|s| locate(&s.text, field).is_some())
    }
}

/// A simulation of `rig` (the single-cylinder rig or an engine: one solver runs both) with its
/// laws bound from `registry`. A law that cannot be bound is reported at the file, line and
/// column that attach it.
///
/// ```
/// use std::path::Path;
/// use tribo_config::rig::{attach_laws, load_rig, simulation};
/// use tribo_core::plugin_api::loader::LawRegistry;
///
/// // The frictionless reference rig needs no law: an empty registry will do. (A program would
/// // use `tribo_plugin_api::loader::discover` to load the law plugins.)
/// let mut rig = load_rig(Path::new("reference-frictionless"), &[])?;
/// let registry = LawRegistry::new();
/// let mut sim = simulation(&rig, &registry)?;
/// let result = sim.run_steady()?;
/// // No friction: the mean motoring torque of every plateau is zero.
/// assert!(result.plateaus.iter().all(|p| p.motoring_torque_nm.abs() < 1e-6));
///
/// // A law the registry does not have is reported where it was attached: here the `--law`
/// // argument (a law set's would be at its file, line and column).
/// attach_laws(&mut rig, &["piston=coulomb".into()])?;
/// let err = simulation(&rig, &registry).err().expect("no such law loaded");
/// assert!(err.to_string().starts_with("--law: piston=coulomb: no law named `coulomb`"), "{err}");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn simulation(rig: &Rig, registry: &LawRegistry) -> Result<Simulation, SimError> {
    refuse_unattached(rig)?;
    let mut sim = Simulation::new(rig.model(), registry).map_err(|e| locate_setup(rig, e))?;
    // The core judged the settings by their values; the files say which the user wrote, so a
    // default written out is held to what it asks for too.
    sim.settings_given(|field| rig.gives(field))
        .map_err(|e| locate_setup(rig, e))?;
    Ok(sim)
}

/// The first law-set entry that names no joint of `rig`, as a setup error at the entry.
fn refuse_unattached(rig: &Rig) -> Result<(), SimError> {
    match rig.unattached.first() {
        None => Ok(()),
        Some(e) => Err(SimError::Setup {
            at: Some(location(&e.file, e.line, e.column)),
            field: e.field.clone(),
            law: None,
            param: None,
            message: e.message.clone(),
        }),
    }
}

/// Check `rig`'s laws against `registry` as [`simulation`] would bind them (each law known, its
/// parameters' names, types and ranges), errors located the same way, without creating an
/// instance: no law code beyond its description runs.
pub fn check_laws(rig: &Rig, registry: &LawRegistry) -> Result<(), SimError> {
    refuse_unattached(rig)?;
    Simulation::check_laws(rig.model(), registry).map_err(|e| locate_setup(rig, e))
}

/// A setup error of `rig`'s laws located in the file, law-set entry or `--law` argument that
/// attached the law.
fn locate_setup(rig: &Rig, e: SimError) -> SimError {
    match e {
        SimError::Setup {
            at: None,
            field,
            law,
            param,
            message,
        } => {
            if let Some(located) = rig.law_error(&field, param.as_deref(), &message) {
                // A law-set entry names its law in the field; a `--law` argument does too.
                let from_lawset = located.field.starts_with("laws[");
                return SimError::Setup {
                    at: Some(location(&located.file, located.line, located.column)),
                    field: located.field,
                    law: law.filter(|_| !from_lawset),
                    param,
                    message,
                };
            }
            // The rig file's own law: at the parameter if the file gives it, else the field.
            let located = param
                .as_deref()
                .map(|p| rig.error(&format!("{field}.{p}"), String::new()))
                .filter(|e| e.line.is_some())
                .unwrap_or_else(|| rig.error(&field, String::new()));
            SimError::Setup {
                at: Some(location(&located.file, located.line, located.column)),
                field,
                law,
                param,
                message,
            }
        }
        other => other,
    }
}

/// `joints.J.laws[k]REST` split into the joint, the index and the rest (`.params`, `.law`).
fn law_field(field: &str) -> Option<(&str, usize, &str)> {
    let (joint, rest) = field.strip_prefix("joints.")?.split_once(".laws[")?;
    let (k, rest) = rest.split_once(']')?;
    Some((joint, k.parse().ok()?, rest))
}
