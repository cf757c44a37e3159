//! Rig files: the TOML description of a motored rig, its overrides (`--set`), and validation
//! with errors that name the file, line, column and field.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use tribo_core::cycle::Segment;
use tribo_core::oil::{ViscosityModel, VALID_RANGE_C};
use tribo_core::sim::{EngineSimulation, RigSimulation, SimError, Simulation};
use tribo_plugin_api::loader::LawRegistry;

use crate::files::{read_text, ReadError};

pub use tribo_core::model::*;

/// A rig problem with where it is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {field}: {message}", location(file, *line, *column))]
pub struct RigError {
    /// File (or `--set` for an override).
    pub file: PathBuf,
    /// 1-based line, if known.
    pub line: Option<usize>,
    /// 1-based column, if known.
    pub column: Option<usize>,
    /// Dotted path of the field.
    pub field: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl RigError {
    /// An error about `field` of the TOML `text` read from `path`, located at the field's line
    /// and column when it can be found there.
    pub fn at(path: &Path, text: &str, field: &str, message: String) -> Self {
        let at = locate(text, field).map(|s| line_col(text, s.start));
        Self {
            file: path.to_path_buf(),
            line: at.map(|a| a.0),
            column: at.map(|a| a.1),
            field: field.into(),
            message,
        }
    }
}

fn location(file: &Path, line: Option<usize>, col: Option<usize>) -> String {
    match (line, col) {
        (Some(l), Some(c)) => format!("{}:{l}:{c}", file.display()),
        _ => file.display().to_string(),
    }
}

/// Line and column (1-based) of byte `offset` in `text`.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Byte span of the value at dotted `path` (`joints.big_end.laws[0].law`) in a TOML text.
pub fn locate(text: &str, path: &str) -> Option<std::ops::Range<usize>> {
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    let mut item: &toml_edit::Item = doc.as_item();
    let mut span = None;
    for part in path.split('.') {
        let (key, index) = match part.split_once('[') {
            Some((k, rest)) => (k, rest.trim_end_matches(']').parse::<usize>().ok()),
            None => (part, None),
        };
        item = item.get(key)?;
        span = item.span().or(span);
        if let Some(i) = index {
            item = item.get(i)?;
            span = item.span().or(span);
        }
    }
    span
}

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
}

/// A simulation of `rig` with its laws bound from `registry`. A law that cannot be bound is
/// reported at the file, line and column that attach it.
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
    Simulation::new(rig.model(), registry).map_err(|e| locate_setup(rig, e))
}

/// Any rig's simulation: the single-cylinder rig's or an engine's ([`RigSimulation`]), with
/// its laws bound from `registry`; errors located as by [`simulation`].
pub fn any_simulation(rig: &Rig, registry: &LawRegistry) -> Result<RigSimulation, SimError> {
    refuse_unattached(rig)?;
    RigSimulation::new(rig.model(), registry).map_err(|e| locate_setup(rig, e))
}

/// An engine rig's simulation (`docs/engines.md`) with its laws bound from
/// `registry`; errors located as by [`simulation`].
pub fn engine_simulation(rig: &Rig, registry: &LawRegistry) -> Result<EngineSimulation, SimError> {
    refuse_unattached(rig)?;
    EngineSimulation::new(rig.model(), registry).map_err(|e| locate_setup(rig, e))
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
    RigSimulation::check_laws(rig.model(), registry).map_err(|e| locate_setup(rig, e))
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

fn field_error(
    sources: &[Source],
    overridden: &[String],
    field: &str,
    message: String,
) -> RigError {
    if overridden
        .iter()
        .any(|o| field.starts_with(o.as_str()) || o.starts_with(field))
    {
        return RigError {
            file: PathBuf::from("--set"),
            line: None,
            column: None,
            field: field.into(),
            message,
        };
    }
    for src in sources {
        if let Some(span) = locate(&src.text, field) {
            let (l, c) = line_col(&src.text, span.start);
            return RigError {
                file: src.path.clone(),
                line: Some(l),
                column: Some(c),
                field: field.into(),
                message,
            };
        }
    }
    RigError {
        file: sources.first().map(|s| s.path.clone()).unwrap_or_default(),
        line: None,
        column: None,
        field: field.into(),
        message,
    }
}

/// Parse `KEY=VALUE` overrides into the table; VALUE is read as TOML, or as a string if it is
/// not valid TOML.
fn apply_set(table: &mut toml::Table, assignment: &str) -> Result<String, RigError> {
    let err = |field: &str, message: String| RigError {
        file: PathBuf::from("--set"),
        line: None,
        column: None,
        field: field.into(),
        message,
    };
    let (key, value) = assignment.split_once('=').ok_or_else(|| {
        err(
            assignment,
            "expected KEY=VALUE, e.g. bodies.rod.mass_scale=0.6".into(),
        )
    })?;
    let key = key.trim();
    let parsed = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"));
    // A number too large for a double (`1e400`) is not valid TOML; it is a number out of
    // range, not a string.
    if parsed.is_none() && value.trim().parse::<f64>().is_ok_and(|x| !x.is_finite()) {
        return Err(err(
            key,
            format!(
                "{} is not a finite number (the largest is about 1.8e308)",
                value.trim()
            ),
        ));
    }
    let value = parsed.unwrap_or_else(|| toml::Value::String(value.trim().to_string()));
    let parts: Vec<&str> = key.split('.').collect();
    let (last, parents) = parts
        .split_last()
        .ok_or_else(|| err(key, "empty key".into()))?;
    let mut cur = table;
    for (i, p) in parents.iter().enumerate() {
        cur = match cur
            .entry((*p).to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        {
            toml::Value::Table(t) => t,
            _ => {
                return Err(err(
                    key,
                    format!("`{}` is not a table", parts[..=i].join(".")),
                ))
            }
        };
    }
    cur.insert((*last).to_string(), value);
    Ok(key.to_string())
}

/// A deserialisation error of one file read as written; `field` is the dotted path serde was
/// at (empty when unknown).
fn serde_error(path: &Path, text: &str, e: &toml::de::Error, field: &str) -> RigError {
    let message = e.message().to_string();
    let (line, column, field) = match e.span() {
        Some(span) => {
            let (l, c) = line_col(text, span.start);
            // An unknown key is named by the message (`unknown field `x``); any other error
            // is at the path serde was deserialising; failing both, the key written on the
            // offending line, else the line itself is the best description.
            let unknown = message.starts_with("unknown field");
            let at_path =
                (!unknown && !field.is_empty() && field != ".").then(|| field.to_string());
            let named = message.split('`').nth(1).filter(|k| {
                unknown
                    && !k.is_empty()
                    && k.chars()
                        .all(|c| c.is_alphanumeric() || c == '_' || c == '-')
            });
            let line_key = text
                .lines()
                .nth(l - 1)
                .and_then(|t| t.split_once('='))
                .map(|(k, _)| k.trim().to_string())
                .filter(|k| !k.is_empty());
            let field = at_path
                .or(named.map(str::to_string))
                .or(line_key)
                .unwrap_or_else(|| "(syntax)".into());
            (Some(l), Some(c), field)
        }
        None => (None, None, "(file)".into()),
    };
    RigError {
        file: path.to_path_buf(),
        line,
        column,
        field,
        message,
    }
}

/// Where a key named in a serde message (`unknown field `x``) is written, for errors found
/// after merging, when toml's own spans are gone.
fn locate_key(sources: &[Source], message: &str, overridden: &[String]) -> RigError {
    let key = message.split('`').nth(1).unwrap_or("");
    if !key.is_empty() {
        for src in sources {
            for (i, line) in src.text.lines().enumerate() {
                let t = line.trim_start();
                let hit = t
                    .strip_prefix('[')
                    .map(|h| {
                        h.trim_start_matches('[')
                            .split(['.', ']'])
                            .any(|p| p.trim() == key)
                    })
                    .unwrap_or_else(|| {
                        t.split('=')
                            .next()
                            .is_some_and(|k| k.trim() == key && t.contains('='))
                    });
                if hit {
                    return RigError {
                        file: src.path.clone(),
                        line: Some(i + 1),
                        column: Some(line.len() - t.len() + 1),
                        field: key.into(),
                        message: message.into(),
                    };
                }
            }
        }
    }
    RigError {
        file: if overridden.is_empty() {
            sources.first().map(|s| s.path.clone()).unwrap_or_default()
        } else {
            PathBuf::from("--set")
        },
        line: None,
        column: None,
        field: if key.is_empty() {
            overridden.join(", ")
        } else {
            key.into()
        },
        message: message.into(),
    }
}

/// Overlay `child` on `base`: tables merge key by key, anything else replaces.
fn merge(base: &mut toml::Table, child: toml::Table) {
    for (k, v) in child {
        match (base.get_mut(&k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(c)) => merge(b, c),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// The oil's descriptive keys: they describe one viscosity curve, so they do not survive a
/// change of `oil.viscosity` that does not restate them.
const OIL_DESCRIPTION: [&str; 3] = ["name", "grade", "source"];

/// Remove the oil's name, grade and source from a rig table (its viscosity is being replaced).
fn forget_oil_description(table: &mut toml::Table) {
    if let Some(toml::Value::Table(oil)) = table.get_mut("oil") {
        for k in OIL_DESCRIPTION {
            oil.remove(k);
        }
    }
}

/// Fill a cylinder-pressure `trace` given by `file` from that CSV: next to the rig file (or
/// any file of its `extends` chain, child first), else a bundled data file. A row is
/// `crank_angle_deg,pressure_pa`; a first row that is not numbers is a header; `#` starts a
/// comment. A bad row is an error at the CSV's line and column.
fn read_trace_file(rig: &mut Rig) -> Result<(), RigError> {
    let name = match &rig.file.gas.cylinder {
        CylinderPressure::Trace {
            file: Some(name), ..
        } => name.clone(),
        _ => return Ok(()),
    };
    let field = "gas.cylinder.file";
    let mut found: Option<(PathBuf, String)> = None;
    for src in &rig.sources {
        let Some(dir) = src.path.parent() else {
            continue;
        };
        if src.path.starts_with("<bundled>") {
            continue;
        }
        let path = dir.join(&name);
        match read_text(&path) {
            Ok(text) => {
                found = Some((path, text));
                break;
            }
            Err(e) if e.is_not_found() => {}
            Err(e) => return Err(rig.error(field, format!("{}: {e}", path.display()))),
        }
    }
    if found.is_none() {
        found = crate::bundled::data(&name)
            .map(|t| (PathBuf::from(format!("<bundled>/{name}")), t.to_string()));
    }
    let Some((path, text)) = found else {
        return Err(rig.error(
            field,
            format!("pressure trace `{name}` not found next to the rig file nor among the bundled data ({})", crate::bundled::data_names().join(", ")),
        ));
    };
    let (angles, pressures) = parse_trace(&text).map_err(|(line, col, msg)| {
        rig.error(field, format!("{}:{line}:{col}: {msg}", path.display()))
    })?;
    if let CylinderPressure::Trace {
        crank_angle_deg,
        pressure_pa,
        ..
    } = &mut rig.file.gas.cylinder
    {
        *crank_angle_deg = angles;
        *pressure_pa = pressures;
    }
    Ok(())
}

/// A bad row of a pressure trace: line, column (1-based) and what is wrong.
type TraceError = (usize, usize, String);

/// Parse a pressure trace CSV into angles and pressures, or `(line, column, message)`.
fn parse_trace(text: &str) -> Result<(Vec<f64>, Vec<f64>), TraceError> {
    let (mut angles, mut pressures) = (Vec::new(), Vec::new());
    let mut header_allowed = true;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("");
        if line.trim().is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != 2 {
            return Err((
                i + 1,
                1,
                format!(
                    "expected two columns `crank_angle_deg,pressure_pa`, found {}",
                    cells.len()
                ),
            ));
        }
        let first = cells[0].trim().parse::<f64>();
        if first.is_err() && header_allowed {
            header_allowed = false;
            continue;
        }
        header_allowed = false;
        let mut values = [0.0; 2];
        let mut col = 1;
        for (k, cell) in cells.iter().enumerate() {
            let what = ["crank angle (degrees)", "pressure (Pa)"][k];
            let lead = cell.len() - cell.trim_start().len();
            values[k] = cell.trim().parse::<f64>().map_err(|_| {
                (
                    i + 1,
                    col + lead,
                    format!("expected a number, the {what}, got `{}`", cell.trim()),
                )
            })?;
            col += cell.len() + 1;
        }
        angles.push(values[0]);
        pressures.push(values[1]);
    }
    Ok((angles, pressures))
}

/// Find the text of a rig named by `extends` in `from`: next to it on disk, else bundled.
/// `Ok(None)` if neither exists; a file that exists but cannot be read (a directory, a device,
/// too large) is an error, not a reason to look among the bundled rigs.
fn resolve_extends(from: &Path, name: &str) -> Result<Option<Source>, (PathBuf, ReadError)> {
    if let Some(dir) = from.parent() {
        let path = dir.join(name);
        match read_text(&path) {
            Ok(text) => return Ok(Some(Source { path, text })),
            Err(e) if e.is_not_found() => {}
            Err(e) => return Err((path, e)),
        }
    }
    Ok(crate::bundled::rig(name).map(|text| Source {
        path: PathBuf::from(format!("<bundled>/{name}")),
        text: text.to_string(),
    }))
}

/// Load a rig from `text` (named `path` in messages), resolve `extends`, apply `--set`
/// overrides, and validate.
pub fn load_rig_text(path: &Path, text: &str, sets: &[String]) -> Result<Rig, RigError> {
    let (sources, tables) = read_extends_chain(path, text)?;
    let single = tables.len() == 1;
    let mut table = merge_chain(tables);
    let overridden = apply_sets(&mut table, sets)?;
    let file = if single && sets.is_empty() {
        // The file exactly as written: toml's spans give precise locations.
        serde_path_to_error::deserialize::<_, RigFile>(toml::Deserializer::new(text)).map_err(
            |e| {
                let field = e.path().to_string();
                serde_error(path, text, e.inner(), &field)
            },
        )?
    } else {
        // Merged tables have no spans: the path serde was at names the field, which is then
        // found in the file that sets it (or in --set); an unknown key is found by name.
        serde_path_to_error::deserialize::<_, RigFile>(toml::Value::Table(table)).map_err(|e| {
            let field = e.path().to_string();
            let message = e.inner().message();
            if message.starts_with("unknown field") || field.is_empty() || field == "." {
                locate_key(&sources, message, &overridden)
            } else {
                field_error(&sources, &overridden, &field, message.to_string())
            }
        })?
    };
    let mut rig = Rig {
        file,
        sources,
        overridden,
        law_origins: BTreeMap::new(),
        unattached: Vec::new(),
    };
    read_trace_file(&mut rig)?;
    validate(&rig)?;
    Ok(rig)
}

/// The rig's text and every file it `extends` (child first, at most 8 levels), each parsed
/// into a table with its `extends` key removed.
fn read_extends_chain(
    path: &Path,
    text: &str,
) -> Result<(Vec<Source>, Vec<toml::Table>), RigError> {
    let mut sources = vec![Source {
        path: path.to_path_buf(),
        text: text.to_string(),
    }];
    let parse = |src: &Source| -> Result<toml::Table, RigError> {
        toml::from_str(&src.text).map_err(|e| serde_error(&src.path, &src.text, &e, ""))
    };
    let mut tables = vec![parse(&sources[0])?];
    while let Some(ext) = tables.last_mut().and_then(|t| t.remove("extends")) {
        let from = sources.last().map(|s| s.path.clone()).unwrap_or_default();
        let name = ext.as_str().ok_or_else(|| {
            field_error(
                &sources,
                &[],
                "extends",
                "must be the file name of the rig to extend".into(),
            )
        })?;
        if sources.len() > 8 {
            return Err(field_error(
                &sources,
                &[],
                "extends",
                "more than 8 levels of `extends`: is there a cycle?".into(),
            ));
        }
        let base = resolve_extends(&from, name)
            .map_err(|(path, e)| {
                field_error(
                    &sources,
                    &[],
                    "extends",
                    format!("the rig to extend, `{}`, {e}", path.display()),
                )
            })?
            .ok_or_else(|| {
                field_error(
                    &sources,
                    &[],
                    "extends",
                    format!(
                        "cannot find `{name}` next to `{}` or among the bundled rigs",
                        from.display()
                    ),
                )
            })?;
        tables.push(parse(&base)?);
        sources.push(base);
    }
    Ok((sources, tables))
}

/// The tables of an `extends` chain (child first) merged, the base first and each child over
/// it. A child that replaces the oil's viscosity without naming the oil drops the base's name,
/// grade and source.
fn merge_chain(mut tables: Vec<toml::Table>) -> toml::Table {
    let mut table = tables.pop().unwrap_or_default();
    while let Some(child) = tables.pop() {
        let oil = child.get("oil").and_then(toml::Value::as_table);
        let names_oil = oil.is_some_and(|o| OIL_DESCRIPTION.iter().any(|k| o.contains_key(*k)));
        if oil.is_some_and(|o| o.contains_key("viscosity")) && !names_oil {
            forget_oil_description(&mut table);
        }
        merge(&mut table, child);
    }
    table
}

/// Apply `--set KEY=VALUE` overrides in order and return the dotted paths they changed. Sets
/// that replace the viscosity without naming the oil drop its name, grade and source first.
fn apply_sets(table: &mut toml::Table, sets: &[String]) -> Result<Vec<String>, RigError> {
    let set_keys: Vec<&str> = sets
        .iter()
        .map(|s| s.split_once('=').map_or(s.as_str(), |(k, _)| k).trim())
        .collect();
    let changes_viscosity = set_keys
        .iter()
        .any(|k| *k == "oil" || *k == "oil.viscosity" || k.starts_with("oil.viscosity."));
    let names_oil = set_keys
        .iter()
        .any(|k| OIL_DESCRIPTION.iter().any(|d| *k == format!("oil.{d}")));
    if changes_viscosity && !names_oil {
        forget_oil_description(table);
    }
    sets.iter().map(|s| apply_set(table, s)).collect()
}

/// Load a rig from disk, or a bundled rig by name (`crf250r-motored` or `crf250r-motored.toml`)
/// when no such file exists. `sets` are `--set KEY=VALUE` overrides; the result is validated,
/// and an error names the file (or `--set`), line, column and field.
///
/// ```
/// use std::path::Path;
/// use tribo_config::rig::load_rig;
///
/// // The bundled CRF 250 R rig, with the rod made 40% lighter.
/// let rig = load_rig(Path::new("crf250r-motored"), &["bodies.rod.mass_scale=0.6".into()])?;
/// assert_eq!(rig.file.bodies.rod.mass_scale, 0.6);
/// assert_eq!(rig.overridden, ["bodies.rod.mass_scale"]);
///
/// // A value out of range is refused, naming where it came from and the field.
/// let err = load_rig(Path::new("crf250r-motored"), &["geometry.bore_m=-1".into()])
///     .expect_err("a negative bore");
/// assert_eq!(
///     err.to_string(),
///     "--set: geometry.bore_m: must be a positive number (m), got -1"
/// );
/// # Ok::<(), tribo_config::rig::RigError>(())
/// ```
pub fn load_rig(path: &Path, sets: &[String]) -> Result<Rig, RigError> {
    match read_text(path) {
        Ok(text) => load_rig_text(path, &text, sets),
        Err(e) if !e.is_not_found() => Err(file_error(path, "rig file", &e)),
        Err(e) => {
            let name = path.to_string_lossy();
            match crate::bundled::rig(&name) {
                Some(text) => {
                    let file = crate::bundled::file_name(&name);
                    let file = if file.ends_with(".toml") {
                        file
                    } else {
                        format!("{file}.toml")
                    };
                    load_rig_text(&PathBuf::from(format!("<bundled>/{file}")), text, sets)
                }
                None => Err(RigError {
                    file: path.to_path_buf(),
                    line: None,
                    column: None,
                    field: "(file)".into(),
                    message: format!(
                        "{e}, and no bundled rig has that name; bundled: {}",
                        crate::bundled::rig_names().join(", ")
                    ),
                }),
            }
        }
    }
}

/// An error about the file at `path` as a whole: the `what` (e.g. `rig file`) cannot be read.
pub fn file_error(path: &Path, what: &str, e: &ReadError) -> RigError {
    RigError {
        file: path.to_path_buf(),
        line: None,
        column: None,
        field: "(file)".into(),
        message: format!("the {what} {e}"),
    }
}

/// Validate a rig again after a program changed it (a study setting the cycle from data).
pub fn revalidate(rig: &Rig) -> Result<(), Box<RigError>> {
    validate(rig).map_err(Box::new)
}

pub use tribo_core::sim::readable;

/// The most cylinders an engine rig may have.
pub use tribo_core::engine::MAX_CYLINDERS;

/// The highest speed a test cycle may reach, rpm.
pub const MAX_SPEED_RPM: f64 = 30_000.0;
/// The longest test cycle, s.
pub const MAX_CYCLE_S: f64 = 3600.0;
/// The allowed range of `solver.step_deg`, degrees.
pub const STEP_DEG_RANGE: (f64, f64) = (0.01, 10.0);
/// The allowed range of `solver.max_step_deg`, degrees.
pub const MAX_STEP_DEG_RANGE: (f64, f64) = (0.1, 90.0);
/// The heaviest body (and crank unbalance mass) a rig may have, kg: an engine's crankshaft is a
/// few kg, a large single cylinder's tens; ten tonnes admits any test rig, while `1e308` would
/// overflow the inertia forces into infinities.
pub const MAX_MASS_KG: f64 = 1e4;
/// The largest moment of inertia (bodies, drive motor), kg m^2.
pub const MAX_INERTIA_KG_M2: f64 = 1e4;
/// The longest length (crank radius, bore, rod, unbalance radius, joint contact radius and
/// length), m.
pub const MAX_LENGTH_M: f64 = 10.0;
/// The largest mass or inertia scale factor (the lighter-rod study scales by about 0.6).
pub const MAX_SCALE: f64 = 1e3;
/// The densest oil accepted, kg/m^3 (engine oils are about 850).
pub const MAX_DENSITY_KG_M3: f64 = 2e4;
/// The most viscous oil accepted at any of the rig's temperatures, cSt (a cold 10W-50 is a
/// few thousand).
pub const MAX_VISCOSITY_CST: f64 = 1e6;
/// Largest gas pressure, Pa (1000 bar: far above any engine's peak).
const MAX_PRESSURE_PA: f64 = 1e8;

/// Why the sizes of a rig are bounded, in an error message.
const SIZE_WHY: &str = "far beyond any engine, and large enough to overflow the model";

/// Check a rig's values part by part; the first problem found is the error, located in the
/// file (or `--set`) that gives the value.
fn validate(rig: &Rig) -> Result<(), RigError> {
    let check = Check { rig };
    check.geometry()?;
    check.bodies()?;
    check.joints()?;
    check.load_shares()?;
    check.oil()?;
    let plateaus = check.cycle()?;
    check.oil_temperatures(plateaus)?;
    check.drive()?;
    check.measurement()?;
    check.solver()?;
    check.gas()?;
    check.engine()
}

/// The rig's validators, one per part of the file, run in the order of [`validate`] so the
/// first problem reported is the same whatever the split.
struct Check<'a> {
    rig: &'a Rig,
}

impl Check<'_> {
    /// `v` must be finite and above zero.
    fn positive(&self, field: &str, v: f64, unit: &str) -> Result<(), RigError> {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(self.rig.error(
                field,
                format!("must be a positive number ({unit}), got {v}"),
            ))
        }
    }

    /// `v` must be finite and not below zero.
    fn non_negative(&self, field: &str, v: f64, unit: &str) -> Result<(), RigError> {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(self
                .rig
                .error(field, format!("must be zero or positive ({unit}), got {v}")))
        }
    }

    /// `v` must be finite, above zero and at most `max` (a physical size; beyond it the model's
    /// forces overflow).
    fn size(&self, field: &str, v: f64, max: f64, unit: &str) -> Result<(), RigError> {
        self.positive(field, v, unit)?;
        self.at_most(field, v, max, unit)
    }

    /// `v` must be finite, not below zero and at most `max`.
    fn size_or_zero(&self, field: &str, v: f64, max: f64, unit: &str) -> Result<(), RigError> {
        self.non_negative(field, v, unit)?;
        self.at_most(field, v, max, unit)
    }

    /// `v` (finite) must be at most `max`.
    fn at_most(&self, field: &str, v: f64, max: f64, unit: &str) -> Result<(), RigError> {
        if v <= max {
            Ok(())
        } else {
            Err(self.rig.error(
                field,
                format!(
                    "must be at most {}{} ({SIZE_WHY}), got {}",
                    readable(max),
                    if unit == "-" {
                        String::new()
                    } else {
                        format!(" {unit}")
                    },
                    readable(v)
                ),
            ))
        }
    }

    /// `v` must be finite and within `[lo, hi]` (`why` says what the limits protect).
    fn within(
        &self,
        field: &str,
        v: f64,
        (lo, hi): (f64, f64),
        unit: &str,
        why: &str,
    ) -> Result<(), RigError> {
        if v.is_finite() && (lo..=hi).contains(&v) {
            Ok(())
        } else {
            Err(self.rig.error(
                field,
                format!(
                    "must be in [{lo}, {hi}] {unit} ({why}), got {}",
                    readable(v)
                ),
            ))
        }
    }

    /// Crank radius and bore.
    fn geometry(&self) -> Result<(), RigError> {
        let g = &self.rig.file.geometry;
        self.size(
            "geometry.crank_radius_m",
            g.crank_radius_m,
            MAX_LENGTH_M,
            "m",
        )?;
        self.size("geometry.bore_m", g.bore_m, MAX_LENGTH_M, "m")
    }

    /// Masses, inertias and scales of crank, rod and piston; a rod longer than the crank radius
    /// with its centre of mass between the pins.
    fn bodies(&self) -> Result<(), RigError> {
        let f = &self.rig.file;
        let c = &f.bodies.crank;
        let (m, j, l) = (MAX_MASS_KG, MAX_INERTIA_KG_M2, MAX_LENGTH_M);
        self.size("bodies.crank.inertia_kg_m2", c.inertia_kg_m2, j, "kg m^2")?;
        self.size("bodies.crank.mass_kg", c.mass_kg, m, "kg")?;
        self.size_or_zero(
            "bodies.crank.unbalance_mass_kg",
            c.unbalance_mass_kg,
            m,
            "kg",
        )?;
        self.size_or_zero(
            "bodies.crank.unbalance_radius_m",
            c.unbalance_radius_m,
            l,
            "m",
        )?;
        self.size("bodies.crank.mass_scale", c.mass_scale, MAX_SCALE, "-")?;
        self.size(
            "bodies.crank.inertia_scale",
            c.inertia_scale,
            MAX_SCALE,
            "-",
        )?;
        let r = &f.bodies.rod;
        self.size("bodies.rod.mass_kg", r.mass_kg, m, "kg")?;
        self.size("bodies.rod.inertia_kg_m2", r.inertia_kg_m2, j, "kg m^2")?;
        self.size("bodies.rod.length_m", r.length_m, l, "m")?;
        self.size("bodies.rod.mass_scale", r.mass_scale, MAX_SCALE, "-")?;
        self.size("bodies.rod.inertia_scale", r.inertia_scale, MAX_SCALE, "-")?;
        if r.length_m <= f.geometry.crank_radius_m {
            return Err(self.rig.error(
                "bodies.rod.length_m",
                format!(
                    "the rod ({} m) must be longer than the crank radius ({} m), or the mechanism locks",
                    r.length_m, f.geometry.crank_radius_m
                ),
            ));
        }
        if !(r.com_from_big_end_m.is_finite()
            && r.com_from_big_end_m >= 0.0
            && r.com_from_big_end_m <= r.length_m)
        {
            return Err(self.rig.error(
                "bodies.rod.com_from_big_end_m",
                format!(
                    "must lie between the pin centres, [0, {}] m, got {}",
                    r.length_m, r.com_from_big_end_m
                ),
            ));
        }
        let p = &f.bodies.piston;
        self.size("bodies.piston.mass_kg", p.mass_kg, m, "kg")?;
        self.size("bodies.piston.mass_scale", p.mass_scale, MAX_SCALE, "-")
    }

    /// Each joint's contact radius and length, and no empty law name.
    fn joints(&self) -> Result<(), RigError> {
        let engine = self.rig.file.engine.is_some();
        for (name, j) in self.rig.file.joints.named() {
            if name.starts_with("main_") {
                match (engine, j.is_absent()) {
                    (true, true) => continue,
                    (true, false) => {
                        return Err(self.rig.error(
                            &format!("joints.{name}"),
                            "an engine rig gives its main bearings as [[engine.mains]] (joints main_1 .. main_n); leave [joints.main_a] and [joints.main_b] out",
                        ))
                    }
                    (false, true) => {
                        return Err(self.rig.error(
                            &format!("joints.{name}"),
                            format!("missing table [joints.{name}]: the single-cylinder rig has two main bearings, main_a and main_b (an engine rig gives [[engine.mains]] instead)"),
                        ))
                    }
                    (false, false) => {}
                }
            }
            self.size(
                &format!("joints.{name}.radius_m"),
                j.radius_m,
                MAX_LENGTH_M,
                "m",
            )?;
            self.size(
                &format!("joints.{name}.length_m"),
                j.length_m,
                MAX_LENGTH_M,
                "m",
            )?;
            for (i, l) in j.laws.iter().enumerate() {
                if l.law.trim().is_empty() {
                    let field = format!("joints.{name}.laws[{i}].law");
                    return Err(self.rig.error(&field, "law name is empty"));
                }
            }
        }
        Ok(())
    }

    /// The main bearings' load shares: each in [0, 1], together 1.
    fn load_shares(&self) -> Result<(), RigError> {
        let j = &self.rig.file.joints;
        // An engine splits its main loads by the lever rule (docs/engines.md).
        if self.rig.file.engine.is_some() {
            return Ok(());
        }
        for (name, share) in [
            ("main_a", j.main_a.load_share),
            ("main_b", j.main_b.load_share),
        ] {
            if !(share.is_finite() && (0.0..=1.0).contains(&share)) {
                return Err(self.rig.error(
                    &format!("joints.{name}.load_share"),
                    format!("must be in [0, 1], got {share}"),
                ));
            }
        }
        let sum = j.main_a.load_share + j.main_b.load_share;
        if (sum - 1.0).abs() > 1e-9 {
            return Err(self.rig.error(
                "joints.main_b.load_share",
                format!("the two main-bearing load shares must add up to 1, they add up to {sum}"),
            ));
        }
        Ok(())
    }

    /// The gas pressures: ambient, the motored cylinder's ratio, exponent and intake pressure,
    /// a trace's table (two equal-length columns, angles rising within [0, 720), pressures
    /// positive), a sealed or vented crankcase's volume (above the displacement) and exponent,
    /// a vented one's breather (a diameter or an area, positive), discharge coefficient in
    /// (0, 1] and gas temperature; the 4-stroke phase 0 or 360 degrees (the rig's angle 0 is a
    /// top dead centre).
    fn gas(&self) -> Result<(), RigError> {
        let f = &self.rig.file;
        let g = &f.gas;
        self.size("gas.ambient_pa", g.ambient_pa, MAX_PRESSURE_PA, "Pa")?;
        if g.cycle_angle_at_zero_deg != 0.0 && g.cycle_angle_at_zero_deg != 360.0 {
            return Err(self.rig.error(
                "gas.cycle_angle_at_zero_deg",
                format!(
                    "must be 0 (crank angle 0 is the gas-exchange TDC) or 360 (the firing TDC), got {}",
                    readable(g.cycle_angle_at_zero_deg)
                ),
            ));
        }
        if f.geometry.engine_cycle == tribo_core::model::EngineCycle::TwoStroke && g.four_stroke() {
            return Err(self.rig.error(
                "geometry.engine_cycle",
                "a two-stroke engine cannot have a 4-stroke cylinder pressure (four-stroke valves or a 720-degree trace in [gas.cylinder])",
            ));
        }
        let displacement = std::f64::consts::PI
            * 0.25
            * f.geometry.bore_m.powi(2)
            * 2.0
            * f.geometry.crank_radius_m;
        match &g.cylinder {
            CylinderPressure::None => {}
            CylinderPressure::Motored {
                compression_ratio,
                polytropic_exponent,
                intake_pressure_pa,
                ..
            } => {
                self.within(
                    "gas.cylinder.compression_ratio",
                    *compression_ratio,
                    (1.01, 40.0),
                    "",
                    "a geometric compression ratio of a piston engine",
                )?;
                self.within(
                    "gas.cylinder.polytropic_exponent",
                    *polytropic_exponent,
                    (1.0, 1.67),
                    "",
                    "isothermal to monatomic adiabatic",
                )?;
                self.size(
                    "gas.cylinder.intake_pressure_pa",
                    *intake_pressure_pa,
                    MAX_PRESSURE_PA,
                    "Pa",
                )?;
            }
            CylinderPressure::Trace {
                crank_angle_deg,
                pressure_pa,
                ..
            } => {
                let field = if self.rig.file.gas.cylinder_file().is_some() {
                    "gas.cylinder.file"
                } else {
                    "gas.cylinder.crank_angle_deg"
                };
                if crank_angle_deg.len() < 2 || crank_angle_deg.len() != pressure_pa.len() {
                    return Err(self.rig.error(field, format!("a trace needs at least two points and as many pressures as angles, got {} angles and {} pressures", crank_angle_deg.len(), pressure_pa.len())));
                }
                for (i, w) in crank_angle_deg.windows(2).enumerate() {
                    if w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater) {
                        return Err(self.rig.error(
                            field,
                            format!(
                                "crank angles must rise: point {} ({}) is not above point {} ({})",
                                i + 2,
                                readable(w[1]),
                                i + 1,
                                readable(w[0])
                            ),
                        ));
                    }
                }
                let (lo, hi) = (
                    crank_angle_deg[0],
                    crank_angle_deg[crank_angle_deg.len() - 1],
                );
                if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && hi < 720.0) {
                    return Err(self.rig.error(field, format!("crank angles must lie in [0, 720) degrees of the 4-stroke cycle (0: gas-exchange TDC), got {} to {}", readable(lo), readable(hi))));
                }
                for (i, p) in pressure_pa.iter().enumerate() {
                    if !(p.is_finite() && *p > 0.0 && *p <= MAX_PRESSURE_PA) {
                        return Err(self.rig.error(field, format!("pressure at point {} must be an absolute pressure in (0, {}] Pa, got {}", i + 1, readable(MAX_PRESSURE_PA), readable(*p))));
                    }
                }
            }
        }
        match &g.crankcase {
            CrankcasePressure::Atmospheric => {}
            CrankcasePressure::Sealed {
                volume_at_tdc_m3,
                polytropic_exponent,
                pressure_at_tdc_pa,
            } => {
                self.crankcase_volume(*volume_at_tdc_m3, *polytropic_exponent, displacement)?;
                self.size(
                    "gas.crankcase.pressure_at_tdc_pa",
                    *pressure_at_tdc_pa,
                    MAX_PRESSURE_PA,
                    "Pa",
                )?;
            }
            CrankcasePressure::Vented {
                volume_at_tdc_m3,
                polytropic_exponent,
                breather_diameter_m,
                breather_area_m2,
                discharge_coefficient,
                temperature_c,
            } => {
                self.crankcase_volume(*volume_at_tdc_m3, *polytropic_exponent, displacement)?;
                match (breather_diameter_m, breather_area_m2) {
                    (Some(_), Some(_)) => {
                        return Err(self.rig.error(
                            "gas.crankcase.breather_area_m2",
                            "give the breather's diameter (`breather_diameter_m`) or its area (`breather_area_m2`), not both",
                        ))
                    }
                    (None, None) => {
                        return Err(self.rig.error(
                            "gas.crankcase",
                            "a vented crankcase needs its breather: `breather_diameter_m` (m) or `breather_area_m2` (m^2)",
                        ))
                    }
                    (Some(d), None) => {
                        self.size("gas.crankcase.breather_diameter_m", *d, MAX_LENGTH_M, "m")?
                    }
                    (None, Some(a)) => self.size(
                        "gas.crankcase.breather_area_m2",
                        *a,
                        MAX_LENGTH_M * MAX_LENGTH_M,
                        "m^2",
                    )?,
                }
                let cd = *discharge_coefficient;
                if !(cd.is_finite() && cd > 0.0 && cd <= 1.0) {
                    return Err(self.rig.error(
                        "gas.crankcase.discharge_coefficient",
                        format!(
                            "must be in (0, 1] (the breather's real flow over that of an ideal nozzle of its area; about 0.6 for a sharp-edged orifice), got {}",
                            readable(cd)
                        ),
                    ));
                }
                self.within(
                    "gas.crankcase.temperature_c",
                    *temperature_c,
                    (-50.0, 300.0),
                    "C",
                    "a crankcase gas temperature",
                )?;
            }
        }
        Ok(())
    }

    /// A closed crankcase's volume at TDC (5% above the displacement, at most 1 m^3) and its
    /// polytropic exponent.
    fn crankcase_volume(
        &self,
        volume: f64,
        exponent: f64,
        displacement: f64,
    ) -> Result<(), RigError> {
        self.size("gas.crankcase.volume_at_tdc_m3", volume, 1.0, "m^3")?;
        if volume <= 1.05 * displacement {
            return Err(self.rig.error(
                "gas.crankcase.volume_at_tdc_m3",
                format!(
                    "must exceed the displacement ({} m^3) by at least 5%, or the piston squeezes the crankcase to nothing, got {}",
                    readable(displacement),
                    readable(volume)
                ),
            ));
        }
        self.within(
            "gas.crankcase.polytropic_exponent",
            exponent,
            (1.0, 1.67),
            "",
            "isothermal to monatomic adiabatic",
        )
    }

    /// Oil density and the viscosity model's constants (temperatures: [`Self::oil_temperatures`],
    /// once the number of plateaus is known).
    fn oil(&self) -> Result<(), RigError> {
        let oil = &self.rig.file.oil;
        self.size(
            "oil.density_kg_m3",
            oil.density_kg_m3,
            MAX_DENSITY_KG_M3,
            "kg/m^3",
        )?;
        match oil.viscosity {
            ViscosityModel::Vogel {
                k_cst,
                theta1_c,
                theta2_c,
            } => {
                self.positive("oil.viscosity.k_cst", k_cst, "cSt")?;
                if !theta1_c.is_finite() || !theta2_c.is_finite() {
                    return Err(self
                        .rig
                        .error("oil.viscosity", "Vogel constants must be finite"));
                }
            }
            ViscosityModel::TwoPoint {
                kv40_cst,
                kv100_cst,
            } => {
                self.positive("oil.viscosity.kv40_cst", kv40_cst, "cSt")?;
                self.positive("oil.viscosity.kv100_cst", kv100_cst, "cSt")?;
                if kv100_cst >= kv40_cst {
                    return Err(self.rig.error("oil.viscosity.kv100_cst", format!("must be below kv40_cst ({kv40_cst} cSt): oil thins as it warms, got {kv100_cst}")));
                }
            }
        }
        Ok(())
    }

    /// The test cycle: not empty, non-negative target speeds, positive durations, at least one
    /// hold. Returns the number of holds (plateaus).
    fn cycle(&self) -> Result<usize, RigError> {
        let segments = self.rig.file.cycle.segments();
        if segments.is_empty() {
            return Err(self.rig.error("cycle.segments", "the test cycle is empty; give at least one ramp and one hold, or leave `segments` out for the thesis cycle"));
        }
        let window_s = self.rig.file.measurement.window_s;
        let mut holds = 0;
        let mut speed_rpm = 0.0;
        let mut total_s = 0.0;
        for (i, s) in segments.iter().enumerate() {
            let (d, field) = match s {
                Segment::Ramp { duration_s, to_rpm } => {
                    if !(to_rpm.is_finite() && (0.0..=MAX_SPEED_RPM).contains(to_rpm)) {
                        return Err(self.rig.error(
                            &format!("cycle.segments[{i}].to_rpm"),
                            format!(
                                "must be in [0, {MAX_SPEED_RPM}] rpm, got {}",
                                readable(*to_rpm)
                            ),
                        ));
                    }
                    speed_rpm = *to_rpm;
                    (*duration_s, "ramp")
                }
                Segment::Hold { duration_s } => {
                    holds += 1;
                    // The window is checked in `measurement`; a bad one is reported there.
                    let min_rpm = 60.0 / window_s;
                    if window_s.is_finite() && window_s > 0.0 && speed_rpm < min_rpm {
                        return Err(self.rig.error(
                            &format!("cycle.segments[{i}]"),
                            format!(
                                "a hold at {speed_rpm} rpm turns less than one whole revolution in the {window_s} s measurement window (measurement.window_s); a plateau needs at least 60 / window_s = {min_rpm} rpm"
                            ),
                        ));
                    }
                    (*duration_s, "hold")
                }
            };
            if !(d.is_finite() && d > 0.0) {
                return Err(self.rig.error(
                    &format!("cycle.segments[{i}].duration_s"),
                    format!("{field} time must be positive, got {d} s"),
                ));
            }
            total_s += d;
            if total_s > MAX_CYCLE_S {
                return Err(self.rig.error(
                    &format!("cycle.segments[{i}].duration_s"),
                    format!(
                        "the test cycle lasts {total_s} s up to this segment; it must last at most {MAX_CYCLE_S} s"
                    ),
                ));
            }
        }
        if holds == 0 {
            return Err(self.rig.error(
                "cycle.segments",
                "the test cycle has no hold, so nothing would be measured",
            ));
        }
        Ok(holds)
    }

    /// Oil temperatures: one, or one per plateau, each within the viscosity model's range and
    /// giving a physical viscosity.
    fn oil_temperatures(&self, plateaus: usize) -> Result<(), RigError> {
        let oil = &self.rig.file.oil;
        let temps: &[f64] = match &oil.temperature_c {
            Temperature::Constant(t) => std::slice::from_ref(t),
            Temperature::PerPlateau(v) => {
                if v.len() != plateaus {
                    return Err(self.rig.error(
                        "oil.temperature_c",
                        format!(
                            "gives {} temperatures but the cycle has {plateaus} plateaus",
                            v.len()
                        ),
                    ));
                }
                v
            }
        };
        for &t in temps {
            if !(t >= VALID_RANGE_C.0 && t <= VALID_RANGE_C.1) {
                return Err(self.rig.error(
                    "oil.temperature_c",
                    format!(
                        "{t} C is outside the viscosity model's range [{}, {}] C",
                        VALID_RANGE_C.0, VALID_RANGE_C.1
                    ),
                ));
            }
            let nu = oil.viscosity.kinematic_cst(t);
            if !(nu.is_finite() && nu > 0.0 && nu <= MAX_VISCOSITY_CST) {
                return Err(self.rig.error(
                    "oil.viscosity",
                    format!(
                        "gives a non-physical viscosity ({} cSt) at {t} C; an oil's is positive and at most {} cSt",
                        readable(nu),
                        readable(MAX_VISCOSITY_CST)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The PI drive's gains, torque limit, belt ratio and motor inertia (a prescribed drive has
    /// nothing to check).
    fn drive(&self) -> Result<(), RigError> {
        if let Drive::Pi {
            kp,
            ki,
            torque_limit_nm,
            belt_ratio,
            motor_inertia_kg_m2,
        } = self.rig.file.drive
        {
            self.size_or_zero("drive.kp", kp, 1e4, "N m s/rad")?;
            self.size_or_zero("drive.ki", ki, 1e6, "N m/rad")?;
            self.size("drive.torque_limit_nm", torque_limit_nm, 1e5, "N m")?;
            self.size("drive.belt_ratio", belt_ratio, 100.0, "-")?;
            self.size_or_zero(
                "drive.motor_inertia_kg_m2",
                motor_inertia_kg_m2,
                MAX_INERTIA_KG_M2,
                "kg m^2",
            )?;
        }
        Ok(())
    }

    /// The measurement window and low-pass frequency.
    fn measurement(&self) -> Result<(), RigError> {
        let m = &self.rig.file.measurement;
        self.positive("measurement.window_s", m.window_s, "s")?;
        self.positive("measurement.lowpass_hz", m.lowpass_hz, "Hz")
    }

    /// Step sizes, tolerances and the friction iteration's limit.
    /// A multi-cylinder engine (`docs/engines.md`): mains in axial order, throws between them
    /// and apart, at most two counterweights per throw, cylinders on existing throws with bank
    /// angles (or a V angle in [0, 180] and a bank each), offsets the rod can reach, exactly one
    /// rod per cylinder, a firing order that is a permutation of the cylinders and fits the
    /// crank, and laws only on the engine's joints.
    fn engine(&self) -> Result<(), RigError> {
        let f = &self.rig.file;
        let Some(e) = &f.engine else {
            return Ok(());
        };
        let l = MAX_LENGTH_M;
        let c = &f.bodies.crank;
        if c.unbalance_mass_kg != 0.0 {
            return Err(self.rig.error(
                "bodies.crank.unbalance_mass_kg",
                "an engine's unbalance is its counterweights, one per web: give them as `counterweights` of each [[engine.throws]] and leave the crank's unbalance at 0",
            ));
        }
        if !matches!(f.gas.crankcase, CrankcasePressure::Atmospheric) {
            return Err(self.rig.error(
                "gas.crankcase",
                "an engine's cylinders share one crankcase, which is not modelled yet: an engine rig takes an atmospheric crankcase only (kind = \"atmospheric\"); a sealed or vented crankcase is the single-cylinder rig's",
            ));
        }
        if e.cylinders.is_empty() || e.cylinders.len() > MAX_CYLINDERS {
            return Err(self.rig.error(
                "engine.cylinders",
                format!(
                    "an engine has 1 to {MAX_CYLINDERS} cylinders ([[engine.cylinders]]), got {}",
                    e.cylinders.len()
                ),
            ));
        }
        if e.mains.len() < 2 {
            return Err(self.rig.error(
                "engine.mains",
                format!(
                    "a crank runs in at least two main bearings ([[engine.mains]]), got {}",
                    e.mains.len()
                ),
            ));
        }
        for (i, m) in e.mains.iter().enumerate() {
            let at = |k: &str| format!("engine.mains[{i}].{k}");
            self.within(
                &at("axial_position_m"),
                m.axial_position_m,
                (-l, l),
                "m",
                SIZE_WHY,
            )?;
            self.size(&at("radius_m"), m.radius_m, l, "m")?;
            self.size(&at("length_m"), m.length_m, l, "m")?;
            if i > 0 && m.axial_position_m <= e.mains[i - 1].axial_position_m {
                return Err(self.rig.error(
                    &at("axial_position_m"),
                    format!(
                        "main bearings are listed in axial order: main_{} at {} m must lie beyond main_{i} at {} m",
                        i + 1,
                        m.axial_position_m,
                        e.mains[i - 1].axial_position_m
                    ),
                ));
            }
        }
        if e.throws.is_empty() {
            return Err(self.rig.error(
                "engine.throws",
                "the crank needs at least one throw ([[engine.throws]])",
            ));
        }
        let (first, last) = (
            e.mains[0].axial_position_m,
            e.mains[e.mains.len() - 1].axial_position_m,
        );
        for (j, t) in e.throws.iter().enumerate() {
            let at = |k: &str| format!("engine.throws[{j}].{k}");
            self.within(
                &at("angle_deg"),
                t.angle_deg,
                (-720.0, 720.0),
                "degrees",
                "a pin angle",
            )?;
            let z = t.axial_position_m;
            if !(z.is_finite() && z > first && z < last) {
                return Err(self.rig.error(
                    &at("axial_position_m"),
                    format!(
                        "a throw lies between two main bearings, strictly inside ({first}, {last}) m, got {}",
                        readable(z)
                    ),
                ));
            }
            if let Some(i) = e.throws[..j].iter().position(|o| o.axial_position_m == z) {
                return Err(self.rig.error(
                    &at("axial_position_m"),
                    format!(
                        "throw {} is at {z} m like throw {}: a throw listed twice? Rods sharing a pin (a V engine) name the same throw in [[engine.cylinders]]",
                        j + 1,
                        i + 1
                    ),
                ));
            }
            if t.counterweights.len() > 2 {
                return Err(self.rig.error(
                    &at("counterweights"),
                    format!(
                        "a throw has two webs, so at most two counterweights, got {}",
                        t.counterweights.len()
                    ),
                ));
            }
            for (w, cw) in t.counterweights.iter().enumerate() {
                let at = |k: &str| format!("engine.throws[{j}].counterweights[{w}].{k}");
                self.size_or_zero(&at("mass_kg"), cw.mass_kg, MAX_MASS_KG, "kg")?;
                self.size_or_zero(&at("radius_m"), cw.radius_m, l, "m")?;
                self.within(
                    &at("angle_deg"),
                    cw.angle_deg,
                    (-360.0, 360.0),
                    "degrees",
                    "an angle from the pin",
                )?;
            }
        }
        if let Some(v) = e.v_angle_deg {
            if !(v.is_finite() && (0.0..=180.0).contains(&v)) {
                return Err(self.rig.error(
                    "engine.v_angle_deg",
                    format!(
                        "the V angle is the angle between the two banks, in [0, 180] degrees (0: inline, 180: a boxer or 180-degree V), got {}",
                        readable(v)
                    ),
                ));
            }
        }
        let r = f.geometry.crank_radius_m;
        for (k, cyl) in e.cylinders.iter().enumerate() {
            let at = |f: &str| format!("engine.cylinders[{k}].{f}");
            if !(1..=e.throws.len()).contains(&cyl.throw) {
                return Err(self.rig.error(
                    &at("throw"),
                    format!(
                        "cylinder {} runs on throw {}, but the crank has throws 1 to {}",
                        k + 1,
                        cyl.throw,
                        e.throws.len()
                    ),
                ));
            }
            match (e.v_angle_deg, cyl.bank, cyl.bank_deg) {
                (Some(_), None, _) => {
                    return Err(self.rig.error(
                        &at("throw"),
                        format!("cylinder {}: a V engine (engine.v_angle_deg) names each cylinder's `bank`, \"left\" or \"right\"", k + 1),
                    ))
                }
                (Some(_), Some(_), Some(_)) => {
                    return Err(self.rig.error(
                        &at("bank_deg"),
                        "give either `bank` (with engine.v_angle_deg) or `bank_deg`, not both",
                    ))
                }
                (None, Some(_), _) => {
                    return Err(self.rig.error(
                        &at("bank"),
                        "`bank` (left or right) needs the engine's V angle, engine.v_angle_deg; or give the cylinder's `bank_deg`",
                    ))
                }
                (None, None, Some(b)) => self.within(
                    &at("bank_deg"),
                    b,
                    (-180.0, 180.0),
                    "degrees",
                    "the cylinder axis from the vertical; two banks are at most 180 degrees apart, a V angle in [0, 180]",
                )?,
                _ => {}
            }
            self.within(
                &at("pin_offset_m"),
                cyl.pin_offset_m,
                (-l, l),
                "m",
                SIZE_WHY,
            )?;
            self.within(
                &at("crank_offset_m"),
                cyl.crank_offset_m,
                (-l, l),
                "m",
                SIZE_WHY,
            )?;
        }
        let mut rod_of: Vec<Option<usize>> = vec![None; e.cylinders.len()];
        for (i, rod) in e.rods.iter().enumerate() {
            let at = |f: &str| format!("engine.rods[{i}].{f}");
            if !(1..=e.cylinders.len()).contains(&rod.cylinder) {
                return Err(self.rig.error(
                    &at("cylinder"),
                    format!(
                        "rod {} names cylinder {}, but the engine has cylinders 1 to {}",
                        i + 1,
                        rod.cylinder,
                        e.cylinders.len()
                    ),
                ));
            }
            if let Some(other) = rod_of[rod.cylinder - 1].replace(i) {
                return Err(self.rig.error(
                    &at("cylinder"),
                    format!(
                        "cylinder {} has two rods, engine.rods[{other}] and engine.rods[{i}]: one rod per cylinder (rods sharing a pin belong to different cylinders on one throw)",
                        rod.cylinder
                    ),
                ));
            }
            let base = &f.bodies.rod;
            if let Some(m) = rod.mass_kg {
                self.size(&at("mass_kg"), m, MAX_MASS_KG, "kg")?;
            }
            if let Some(j) = rod.inertia_kg_m2 {
                self.size(&at("inertia_kg_m2"), j, MAX_INERTIA_KG_M2, "kg m^2")?;
            }
            if let Some(len) = rod.length_m {
                self.size(&at("length_m"), len, l, "m")?;
            }
            let len = rod.length_m.unwrap_or(base.length_m);
            let com = rod.com_from_big_end_m.unwrap_or(base.com_from_big_end_m);
            if !(com.is_finite() && (0.0..=len).contains(&com)) {
                return Err(self.rig.error(
                    &at("com_from_big_end_m"),
                    format!("must lie between the pin centres, [0, {len}] m, got {com}"),
                ));
            }
            let cyl = &e.cylinders[rod.cylinder - 1];
            let reach = r + (cyl.pin_offset_m + cyl.crank_offset_m).abs();
            if len <= reach {
                return Err(self.rig.error(
                    &at("length_m"),
                    format!(
                        "the rod ({len} m) must be longer than the crank radius plus the cylinder's offsets ({reach} m), or the mechanism locks"
                    ),
                ));
            }
        }
        if let Some(k) = rod_of.iter().position(Option::is_none) {
            return Err(self.rig.error(
                &format!("engine.cylinders[{k}]"),
                format!(
                    "cylinder {} has no rod: add [[engine.rods]] with cylinder = {} (its mass, inertia and length default to [bodies.rod])",
                    k + 1,
                    k + 1
                ),
            ));
        }
        // The firing order: a permutation that fits the crank.
        let geo =
            tribo_core::engine::geometry(f).ok_or_else(|| self.rig.error("engine", "no engine"))?;
        let phase0 = f.gas.cycle_angle_at_zero_deg.to_radians();
        tribo_core::engine::cylinder_phases(
            &tribo_core::engine::top_dead_centres(&geo),
            &e.firing_order,
            phase0,
        )
        .map_err(|err| self.rig.error("engine.firing_order", err.to_string()))?;
        // The core's own checks (the same as above): a backstop, named at the engine table.
        tribo_core::engine::CrankTrain::new(geo)
            .map_err(|err| self.rig.error("engine", err.to_string()))?;
        let names = e.joint_names();
        if let Some(k) = e.laws.keys().find(|k| !names.contains(k)) {
            return Err(self.rig.error(
                &format!("engine.laws.{k}"),
                format!(
                    "the engine has no joint `{k}`; its joints are {} .. {}",
                    names[0],
                    names[names.len() - 1]
                ),
            ));
        }
        Ok(())
    }

    fn solver(&self) -> Result<(), RigError> {
        let s = &self.rig.file.solver;
        self.within(
            "solver.step_deg",
            s.step_deg,
            STEP_DEG_RANGE,
            "degrees",
            "smaller steps take days, larger ones miss a stroke's friction",
        )?;
        self.positive("solver.max_step_s", s.max_step_s, "s")?;
        self.positive("solver.friction_tol", s.friction_tol, "-")?;
        self.positive("solver.rel_tol", s.rel_tol, "-")?;
        self.within(
            "solver.max_step_deg",
            s.max_step_deg,
            MAX_STEP_DEG_RANGE,
            "degrees",
            "a step must resolve a stroke",
        )?;
        if s.rel_tol > 1e-2 {
            return Err(self.rig.error(
                "solver.rel_tol",
                format!(
                    "must be at most 1e-2 (a relative error per unit time), got {}",
                    s.rel_tol
                ),
            ));
        }
        if s.friction_max_iter == 0 {
            return Err(self
                .rig
                .error("solver.friction_max_iter", "must be at least 1"));
        }
        Ok(())
    }
}

/// One `--law JOINT=LAW[:PARAMS_TOML_FILE]` argument, parsed.
#[derive(Debug, Clone)]
pub struct LawArg {
    /// The joint.
    pub joint: String,
    /// The law and its parameters.
    pub law: LawRef,
    /// The argument and its parameter file, for locating errors about the law.
    pub origin: LawOrigin,
}

/// Parse one `--law JOINT=LAW[:PARAMS_TOML_FILE]` argument into the joint and the law; the
/// parameter file is read (capped, regular files only) and parsed here.
pub fn parse_law_arg(arg: &str) -> Result<LawArg, RigError> {
    let err = |message: String| RigError {
        file: PathBuf::from("--law"),
        line: None,
        column: None,
        field: arg.to_string(),
        message,
    };
    let (joint, spec) = arg
        .split_once('=')
        .ok_or_else(|| err("expected JOINT=LAW or JOINT=LAW:PARAMS.toml".into()))?;
    if !crate::lawset::is_joint_pattern(joint) {
        return Err(err(format!(
            "unknown joint `{joint}`; the rig's joints are {} (an engine's: main_1 .. main_n, big_end_k, small_end_k, piston_k; groups: main_*, big_end_*, small_end_*, piston_*)",
            JOINT_NAMES.join(", ")
        )));
    }
    let (law, params, source) = match spec.split_once(':') {
        Some((l, file)) => {
            let text = read_text(Path::new(file))
                .map_err(|e| err(format!("the parameter file `{file}` {e}")))?;
            let table: toml::Table = toml::from_str(&text).map_err(|e: toml::de::Error| {
                let at = e.span().map(|s| line_col(&text, s.start));
                let place = at.map_or(String::new(), |(l, c)| format!(":{l}:{c}"));
                err(format!("{file}{place}: {}", e.message()))
            })?;
            let source = Source {
                path: PathBuf::from(file),
                text,
            };
            (l, table, Some(Arc::new(source)))
        }
        None => (spec, toml::Table::new(), None),
    };
    Ok(LawArg {
        joint: joint.to_string(),
        law: LawRef {
            law: law.to_string(),
            params,
        },
        origin: LawOrigin::Arg {
            arg: arg.to_string(),
            params: source,
        },
    })
}

/// Apply `--law JOINT=LAW[:PARAMS_TOML_FILE]` arguments: the first for a joint replaces the
/// rig's laws there, later ones add.
pub fn attach_laws(rig: &mut Rig, args: &[String]) -> Result<(), RigError> {
    let mut replaced: Vec<String> = Vec::new();
    for arg in args {
        let LawArg { joint, law, origin } = parse_law_arg(arg)?;
        // A group or, on an engine, a single-cylinder name: every joint it names.
        let names = expand_joint(&joint, &rig.file);
        if names.is_empty() {
            return Err(RigError {
                file: PathBuf::from("--law"),
                line: None,
                column: None,
                field: arg.clone(),
                message: format!(
                    "the rig `{}` has no joint `{joint}`; its joints are {}",
                    rig.file.name,
                    match &rig.file.engine {
                        Some(e) => e.joint_names().join(", "),
                        None => JOINT_NAMES.join(", "),
                    }
                ),
            });
        }
        for name in names {
            let laws = match rig.file.engine.as_mut() {
                Some(e) => e.laws.entry(name.clone()).or_default(),
                None => match rig.file.joints.get_mut(&name) {
                    Some(j) => &mut j.laws,
                    None => continue,
                },
            };
            if !replaced.contains(&name) {
                laws.clear();
                rig.law_origins.retain(|(n, _), _| *n != name);
                replaced.push(name.clone());
            }
            rig.law_origins
                .insert((name.clone(), laws.len()), origin.clone());
            laws.push(law.clone());
            rig.overridden.push(format!("joints.{name}.laws"));
        }
    }
    Ok(())
}

/// Keys an oil file's `[oil]` table may hold: what describes the oil itself (temperatures
/// belong to the rig's cycle or to the sweep).
pub const OIL_FILE_KEYS: [&str; 5] = ["name", "grade", "source", "viscosity", "density_kg_m3"];

/// Read an oil file (`--oil FILE.toml`: an `[oil]` table with any of [`OIL_FILE_KEYS`]) and turn
/// it into `--set oil.KEY=VALUE` overrides, to be applied before the user's own `--set`s. The
/// file is checked here, so its mistakes are reported at its own line and column: unknown keys,
/// and a viscosity model that does not parse.
pub fn oil_file_sets(path: &Path) -> Result<Vec<String>, RigError> {
    let err = |text: &str, field: &str, message: String| RigError::at(path, text, field, message);
    let text = read_text(path).map_err(|e| file_error(path, "oil file", &e))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| serde_error(path, &text, &e, ""))?;
    if let Some(k) = table.keys().find(|k| *k != "oil") {
        return Err(err(
            &text,
            k,
            format!("unknown key `{k}`: an oil file holds one `[oil]` table"),
        ));
    }
    let oil = match table.get("oil") {
        Some(toml::Value::Table(t)) => t,
        _ => return Err(err(&text, "oil", "expected an `[oil]` table".into())),
    };
    let mut sets = Vec::new();
    for (k, v) in oil {
        if !OIL_FILE_KEYS.contains(&k.as_str()) {
            return Err(err(
                &text,
                &format!("oil.{k}"),
                format!(
                    "unknown field `{k}`, expected one of {}",
                    OIL_FILE_KEYS.join(", ")
                ),
            ));
        }
        if k == "viscosity" {
            v.clone()
                .try_into::<ViscosityModel>()
                .map_err(|e| err(&text, "oil.viscosity", e.message().to_string()))?;
        }
        sets.push(format!("oil.{k}={v}"));
    }
    Ok(sets)
}
