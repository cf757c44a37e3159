//! `tribo._native`: the Rust half of the `tribo` Python package.
//!
//! Each function takes a job as JSON (the rig, law sets and options as the CLI's arguments
//! would give them), runs it through the same library calls as `tribo ... --in-process`, with
//! the GIL released, in a worker process (module `isolated`: this interpreter started again
//! with only this module loaded, so a law that crashes, exits or hangs cannot take the user's
//! script down) unless asked to run in process, and hands the result back as the Python objects (dicts, lists, floats)
//! that `json.loads` would make of the CLI's `--json` text (so the numbers are the same bits),
//! built directly from the result (module `topy`) rather than written as text and parsed
//! again. The Python package (`python/tribo/`) turns those into pandas DataFrames and numpy
//! arrays. Errors are raised as the exception classes of `tribo.errors`, carrying the CLI's
//! message.

mod isolated;
mod topy;

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use serde::Deserialize;

use tribo_config::bundled;
use tribo_config::lawset::LawSet;
use tribo_config::rig::{self, Rig, RigError};
use tribo_core::observe::{ObserverError, StepObserver, StepSample};
use tribo_core::sim::SimError;
use tribo_plugin_api::loader::{discover, LawError, LawRegistry};
use tribo_studies::fit::{FitOptions, FitResult};
use tribo_studies::study::{self, DataRun, StudyError, SweepInputError};

/// Where the plugins of the checkout this module was built from are: `target/release` beside
/// the workspace, the directory of the `tribo` binary. The CLI searches its own directory; this
/// module is loaded by Python, whose directory holds no laws, so it searches the checkout's
/// instead (only if it exists where the module runs).
const CHECKOUT_PLUGINS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../target/release");

/// What went wrong, as the Python exception class of `tribo.errors` that reports it.
#[derive(Debug, Clone, Copy, serde::Serialize, Deserialize)]
enum Kind {
    /// A rig, law set, data file, parameter or option the user gave is wrong.
    Input,
    /// A law library cannot be loaded.
    Plugin,
    /// A run failed (a law's fault, the solver did not converge, ...).
    Simulation,
}

impl Kind {
    /// The class name in `tribo.errors`.
    fn class(self) -> &'static str {
        match self {
            Kind::Input => "InputError",
            Kind::Plugin => "PluginError",
            Kind::Simulation => "SimulationError",
        }
    }
}

/// An error on its way to Python: the exception class and the CLI's message.
#[derive(Debug, serde::Serialize, Deserialize)]
struct Failure {
    /// Which exception.
    kind: Kind,
    /// The message as the CLI prints it after `error: `.
    message: String,
}

impl Failure {
    fn new(kind: Kind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }
}

/// `e` and its causes joined by `: `, as the CLI prints an error chain (`{:#}` of anyhow).
fn chain(e: &dyn std::error::Error) -> String {
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
fn pythonic(mut e: RigError) -> RigError {
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
fn raise(py: Python<'_>, f: Failure) -> PyErr {
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

/// A rig as the Python side describes it: a bundled name or file (`source`), or a text or
/// table given in Python (`text` / `table`, named `name` in messages); `sets` are `--set`
/// overrides and `oil` an `--oil` file.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RigSpec {
    source: Option<String>,
    text: Option<String>,
    table: Option<serde_json::Value>,
    name: Option<String>,
    sets: Vec<String>,
    oil: Option<PathBuf>,
}

/// A law set as the Python side describes it (as [`RigSpec`]), plus `--law` arguments added.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct LawSetSpec {
    source: Option<String>,
    text: Option<String>,
    table: Option<serde_json::Value>,
    name: Option<String>,
    laws: Vec<String>,
}

/// A TOML document from a table given in Python (as JSON).
fn table_text(table: &serde_json::Value, what: &str) -> Result<String, Failure> {
    toml::to_string(table).map_err(|e| {
        Failure::new(
            Kind::Input,
            format!("the {what} given as a dict cannot be written as TOML: {e} (None values and mixed lists have no TOML form)"),
        )
    })
}

impl RigSpec {
    /// Load, extend, override and validate, as `tribo run RIG --oil ... --set ...` does.
    fn load(&self) -> Result<Rig, Failure> {
        let mut sets = match &self.oil {
            Some(path) => rig::oil_file_sets(path)?,
            None => Vec::new(),
        };
        sets.extend(self.sets.iter().cloned());
        let name = self.name.as_deref().unwrap_or("<python>.toml");
        if let Some(text) = &self.text {
            return Ok(rig::load_rig_text(Path::new(name), text, &sets)?);
        }
        if let Some(table) = &self.table {
            let text = table_text(table, "rig")?;
            return Ok(rig::load_rig_text(Path::new(name), &text, &sets)?);
        }
        let source = self.source.as_deref().unwrap_or(bundled::DEFAULT_RIG);
        Ok(rig::load_rig(Path::new(source), &sets)?)
    }
}

impl LawSetSpec {
    /// Load the law set and add its `--law` arguments.
    fn load(&self) -> Result<LawSet, Failure> {
        let name = self.name.as_deref().unwrap_or("<python>.toml");
        let mut ls = if let Some(text) = &self.text {
            LawSet::from_text(Path::new(name), text)?
        } else if let Some(table) = &self.table {
            LawSet::from_text(Path::new(name), &table_text(table, "law set")?)?
        } else {
            let source = self.source.as_deref().ok_or_else(|| {
                Failure::new(
                    Kind::Input,
                    "a law set needs a name, a file, a text or a dict",
                )
            })?;
            LawSet::load(source)?
        };
        ls.add_law_args(&self.laws)?;
        Ok(ls)
    }
}

/// Law sets given, or the CLI's defaults.
fn lawsets(specs: &[LawSetSpec]) -> Result<Vec<LawSet>, Failure> {
    if specs.is_empty() {
        return bundled::DEFAULT_LAWSETS
            .iter()
            .map(|n| Ok(LawSet::load(n)?))
            .collect();
    }
    specs.iter().map(LawSetSpec::load).collect()
}

/// Data runs by name or file.
fn data_runs(names: &[String]) -> Result<Vec<DataRun>, Failure> {
    names.iter().map(|n| Ok(DataRun::read(n)?)).collect()
}

/// Registries already found, by search path and `TRIBO_PLUGIN_PATH`: each law library is
/// opened once per process, as in one `tribo` command.
type Registries = Vec<((Vec<PathBuf>, Option<std::ffi::OsString>), Arc<LawRegistry>)>;
static REGISTRIES: Mutex<Registries> = Mutex::new(Vec::new());

/// The search path: `plugin_paths` (as `--plugin`), then the checkout's `target/release` if
/// it exists; `discover` adds `TRIBO_PLUGIN_PATH` and the executable's directory.
fn search_path(plugin_paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut paths = plugin_paths.to_vec();
    let checkout = PathBuf::from(CHECKOUT_PLUGINS);
    if checkout.is_dir() {
        paths.push(std::fs::canonicalize(&checkout).unwrap_or(checkout));
    }
    paths
}

/// The law registry for `plugin_paths`, found once and kept.
fn registry(plugin_paths: &[PathBuf]) -> Result<Arc<LawRegistry>, Failure> {
    let key = (
        plugin_paths.to_vec(),
        std::env::var_os(tribo_plugin_api::loader::PLUGIN_PATH_ENV),
    );
    let mut cache = REGISTRIES.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, r)) = cache.iter().find(|(k, _)| *k == key) {
        return Ok(Arc::clone(r));
    }
    let r = Arc::new(discover(&search_path(plugin_paths))?);
    cache.push((key, Arc::clone(&r)));
    Ok(r)
}

/// Run `work` without the GIL and turn its failure into the Python exception.
fn detached<T: Send>(
    py: Python<'_>,
    work: impl FnOnce() -> Result<T, Failure> + Send,
) -> PyResult<T> {
    py.detach(work).map_err(|f| raise(py, f))
}

/// A result as the Python objects `json.loads` would make of the CLI's `--json` for it.
fn to_python<'py, T: serde::Serialize + ?Sized>(
    py: Python<'py>,
    value: &T,
) -> PyResult<Bound<'py, PyAny>> {
    topy::to_py(py, value).map_err(|e| match e {
        topy::ToPyError::Python(e) => e,
        shape @ topy::ToPyError::Shape(_) => raise(
            py,
            Failure::new(
                Kind::Simulation,
                format!("handing the results to Python: {shape}"),
            ),
        ),
    })
}

/// Run a job as [`isolated::dispatch`] does, then hand its result to Python as [`to_python`]
/// does.
fn isolated_value<'py, T: serde::Serialize + Send>(
    py: Python<'py>,
    job: &str,
    isolation: Option<&str>,
    what: &str,
    wrap: fn(String) -> isolated::Job,
    pick: fn(isolated::Output) -> Option<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let value = isolated::dispatch(py, job, isolation, what, wrap, pick)?;
    to_python(py, &value)
}

/// Run `work` without the GIL, then hand its result to Python as [`to_python`] does.
fn detached_value<'py, T: serde::Serialize + Send>(
    py: Python<'py>,
    work: impl FnOnce() -> Result<T, Failure> + Send,
) -> PyResult<Bound<'py, PyAny>> {
    let value = detached(py, work)?;
    to_python(py, &value)
}

/// The time series of a transient run: its column names ([`SERIES_COLUMNS`], then each
/// joint's normal load, named when the run starts) and the values row after row.
#[derive(Default, serde::Serialize, Deserialize)]
struct Series {
    columns: Vec<String>,
    values: Vec<f64>,
}

/// The columns of a time series before the joints' normal loads, in the order [`Series`]
/// stores them. The names and units are those of the CLI's `--timeseries` CSV.
const SERIES_COLUMNS: [&str; 5] = [
    "time_s",
    "theta_rad",
    "speed_rpm",
    "motoring_torque_nm",
    "motoring_torque_filtered_nm",
];

impl StepObserver for Series {
    fn start(&mut self, joints: &[&str]) -> Result<(), ObserverError> {
        self.columns = SERIES_COLUMNS.iter().map(|c| c.to_string()).collect();
        self.columns
            .extend(joints.iter().map(|j| format!("{j}_normal_load_n")));
        Ok(())
    }

    fn step(&mut self, s: &StepSample<'_>) -> Result<(), ObserverError> {
        self.values.extend_from_slice(&[
            s.time_s,
            s.crank_angle_rad,
            tribo_core::cycle::rad_s_to_rpm(s.speed_rad_s),
            s.motoring_torque_nm,
            s.filtered_torque_nm,
        ]);
        self.values.extend_from_slice(s.normal_loads_n);
        Ok(())
    }
}

/// `load_rig(spec_json)`: the rig loaded and validated; returns `{"path", "model"}`: the file
/// it came from and its model (as the JSON of the model, in Python objects).
#[pyfunction]
fn load_rig<'py>(py: Python<'py>, spec: &str) -> PyResult<Bound<'py, PyAny>> {
    detached_value(py, || {
        let spec: RigSpec = serde_json::from_str(spec)?;
        let rig = spec.load()?;
        let model = serde_json::to_value(rig.model()).map_err(|e| {
            Failure::new(
                Kind::Simulation,
                format!("serialising the rig's model: {e}"),
            )
        })?;
        Ok(serde_json::json!({
            "path": rig.path().display().to_string(),
            "model": model,
        }))
    })
}

/// `load_lawset(spec_json)`: the law set loaded; returns `{"path", "file"}`: its file and its
/// content.
/// `modes(spec)`: the drivetrain's modal report, as `tribo modes --json` (`inertias`,
/// `springs`, `modes`, all at crank speed). Raises `tribo.InputError` for a rig without one.
#[pyfunction]
fn modes<'py>(py: Python<'py>, spec: &str) -> PyResult<Bound<'py, PyAny>> {
    let report = detached(py, || {
        let spec: RigSpec = serde_json::from_str(spec)?;
        let rig = spec.load()?;
        let model = rig.model();
        let (chain, hold) = tribo_core::sim::drivetrain_chain(model)?.ok_or_else(|| {
            Failure::new(
                Kind::Input,
                format!(
                    "rig `{}` has no [drivetrain]: modes() analyses the chain from the motor to the crank (e.g. the bundled crf250r-testbed)",
                    model.name
                ),
            )
        })?;
        let plateaus: Vec<f64> = tribo_core::cycle::Cycle::new(&model.cycle.segments())
            .plateaus()
            .iter()
            .map(|p| p.speed_rpm)
            .collect();
        Ok(chain.report(&model.name, hold, &plateaus))
    })?;
    to_python(py, &report)
}

#[pyfunction]
fn load_lawset<'py>(py: Python<'py>, spec: &str) -> PyResult<Bound<'py, PyAny>> {
    detached_value(py, || {
        let spec: LawSetSpec = serde_json::from_str(spec)?;
        let ls = spec.load()?;
        let file = serde_json::to_value(&ls.file)
            .map_err(|e| Failure::new(Kind::Simulation, format!("serialising the law set: {e}")))?;
        Ok(serde_json::json!({
            "path": ls.path.display().to_string(),
            "file": file,
        }))
    })
}

/// `free_params(lawset_json, plugin_paths, ids)`: the free parameters of a law set (those it
/// marks, or `ids`), with bounds and start values: a list of dicts.
#[pyfunction]
#[pyo3(signature = (lawset, plugin_paths, ids=None))]
fn free_params<'py>(
    py: Python<'py>,
    lawset: &str,
    plugin_paths: Vec<PathBuf>,
    ids: Option<Vec<String>>,
) -> PyResult<Bound<'py, PyAny>> {
    detached_value(py, || {
        let spec: LawSetSpec = serde_json::from_str(lawset)?;
        let ls = spec.load()?;
        let registry = registry(&plugin_paths)?;
        let free = ls.free_params(&registry, ids.as_deref())?;
        let rows: Vec<_> = free
            .iter()
            .map(|p| {
                serde_json::json!({
                    "id": p.id, "entry": p.entry, "param": p.param,
                    "lower": p.bounds[0], "upper": p.bounds[1], "value": p.value,
                })
            })
            .collect::<Vec<_>>();
        Ok(rows)
    })
}

/// `check_lawset(lawset_json, plugin_paths)`: every entry's parameters checked against its
/// law's declaration (names, types, ranges) without running anything, so that
/// `LawSet.set_params` refuses a bad value when it is called rather than when a run starts.
#[pyfunction]
fn check_lawset(py: Python<'_>, lawset: &str, plugin_paths: Vec<PathBuf>) -> PyResult<()> {
    detached(py, || {
        let spec: LawSetSpec = serde_json::from_str(lawset)?;
        let ls = spec.load()?;
        let registry = registry(&plugin_paths)?;
        Ok(ls.check_params(&registry)?)
    })
}

/// `laws(plugin_paths)`: every law found (name, version, file), and the files that could not
/// be opened with the reason: `{"laws": [...], "broken": [...]}`. The libraries are opened in
/// worker processes, as `tribo laws` opens them: one whose initialiser ends, crashes or hangs
/// its process is listed as broken, naming why, and the interpreter goes on.
#[pyfunction]
fn laws<'py>(py: Python<'py>, plugin_paths: Vec<PathBuf>) -> PyResult<Bound<'py, PyAny>> {
    let value = isolated::laws(py, &plugin_paths)?;
    to_python(py, &value)
}

/// The files a listing leaves unopened and the search path besides them: what a worker asks
/// for when it lists the laws ([`laws_local`]).
#[derive(serde::Serialize, Deserialize)]
pub(crate) struct LawsJob {
    /// The `plugin_paths` given, but the files left out.
    pub(crate) plugin_paths: Vec<PathBuf>,
    /// Files not to open (their loading took a worker down), with the reason.
    pub(crate) skip: Vec<(PathBuf, String)>,
}

/// The listing of [`laws`] as JSON text, made where the libraries are opened (a worker).
fn laws_local(job: &LawsJob) -> Result<String, Failure> {
    let registry = registry(&job.plugin_paths)?;
    for (path, reason) in &job.skip {
        registry.skip(path, reason.clone());
    }
    let listing = registry.open_all()?;
    let laws: Vec<_> = listing
        .laws
        .iter()
        .map(|l| {
            serde_json::json!({
                "name": l.name(),
                "file": l.path().display().to_string(),
            })
        })
        .collect();
    let broken: Vec<_> = listing
        .broken
        .iter()
        .map(|(p, e)| serde_json::json!({"file": p.display().to_string(), "error": chain(*e)}))
        .collect();
    Ok(serde_json::json!({"laws": laws, "broken": broken}).to_string())
}

/// `search_path(plugin_paths)`: the paths searched before `TRIBO_PLUGIN_PATH`.
#[pyfunction]
fn plugin_search_path(plugin_paths: Vec<PathBuf>) -> Vec<PathBuf> {
    search_path(&plugin_paths)
}

/// A `tribo run` job.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunJob {
    rig: RigSpec,
    lawset: Option<LawSetSpec>,
    #[serde(default)]
    laws: Vec<String>,
    #[serde(default)]
    steady: bool,
    #[serde(default)]
    timeseries: bool,
    #[serde(default)]
    plugin_paths: Vec<PathBuf>,
}

/// A run's result and, with a time series, its column names and samples.
type RunOutput<'py> = (
    Bound<'py, PyAny>,
    Option<(Vec<String>, Bound<'py, PyBytes>)>,
);

/// `run(job_json, isolation_json)`: one rig through its cycle (or steady state), as `tribo run
/// --json`. Returns the result (as Python objects), and with `timeseries` the column names and
/// the samples as native-endian f64 bytes (row after row).
#[pyfunction]
#[pyo3(signature = (job, isolation=None))]
fn run<'py>(py: Python<'py>, job: &str, isolation: Option<&str>) -> PyResult<RunOutput<'py>> {
    let (result, series) = *isolated::dispatch(
        py,
        job,
        isolation,
        "the run",
        isolated::Job::Run,
        |o| match o {
            isolated::Output::Run(r) => Some(r),
            _ => None,
        },
    )?;
    let result = to_python(py, &result)?;
    let series = series.map(|s| {
        let bytes: Vec<u8> = s.values.iter().flat_map(|v| v.to_ne_bytes()).collect();
        (s.columns, PyBytes::new(py, &bytes))
    });
    Ok((result, series))
}

/// A run's result and its time series, if asked for.
type RunReply = (tribo_core::sim::RunResult, Option<Series>);

/// `run` in this process.
fn run_local(job: &str) -> Result<RunReply, Failure> {
    let job: RunJob = serde_json::from_str(job)?;
    if job.steady && job.timeseries {
        return Err(Failure::new(
            Kind::Input,
            "timeseries=True needs a transient run: a steady run computes each plateau directly and has no time history",
        ));
    }
    let mut rig = job.rig.load()?;
    if let Some(ls) = &job.lawset {
        ls.load()?.apply(&mut rig);
    }
    rig::attach_laws(&mut rig, &job.laws)?;
    let registry = registry(&job.plugin_paths)?;
    let mut sim = rig::simulation(&rig, &registry)?;
    let (result, series) = if job.steady {
        (sim.run_steady()?, None)
    } else if job.timeseries {
        let mut s = Series::default();
        (sim.run_with(&mut s)?, Some(s))
    } else {
        (sim.run()?, None)
    };
    Ok((result, series))
}

/// A `tribo compare` job.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CompareJob {
    rig: RigSpec,
    #[serde(default)]
    lawsets: Vec<LawSetSpec>,
    data: Option<String>,
    #[serde(default)]
    validate: Vec<String>,
    #[serde(default)]
    steady: bool,
    #[serde(default)]
    no_cv: bool,
    #[serde(default)]
    no_fit: bool,
    #[serde(default = "default_starts")]
    starts: usize,
    #[serde(default)]
    data_for_any_rig: bool,
    /// On a rig with a drivetrain, fit and score on the points measured within the
    /// transducer's rating only.
    #[serde(default)]
    trusted_points_only: bool,
    #[serde(default)]
    plugin_paths: Vec<PathBuf>,
}

/// Latin-hypercube start points of a calibration when the job gives none.
fn default_starts() -> usize {
    tribo_studies::fit::DEFAULT_STARTS
}

/// `compare(job_json, isolation_json)`: law sets against measured data, as `tribo compare
/// --json`.
#[pyfunction]
#[pyo3(signature = (job, isolation=None))]
fn compare<'py>(
    py: Python<'py>,
    job: &str,
    isolation: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    isolated_value(
        py,
        job,
        isolation,
        "the comparison",
        isolated::Job::Compare,
        |o| match o {
            isolated::Output::Compare(c) => Some(c),
            _ => None,
        },
    )
}

/// `compare` in this process.
fn compare_local(job: &str) -> Result<Box<study::Comparison>, Failure> {
    let job: CompareJob = serde_json::from_str(job)?;
    let rig = job.rig.load()?;
    let sets = lawsets(&job.lawsets)?;
    study::check_unique_names(&sets)?;
    let data = match job.data.as_deref() {
        Some(d) => DataRun::read(d)?,
        None => DataRun::read(study::default_data(&rig)?)?,
    };
    let options = study::CompareOptions {
        steady: job.steady,
        no_cv: job.no_cv,
        no_fit: job.no_fit,
        starts: job.starts,
        validate: data_runs(&job.validate)?,
        data_for_any_rig: job.data_for_any_rig,
        trusted_points_only: job.trusted_points_only,
    };
    let registry = registry(&job.plugin_paths)?;
    Ok(Box::new(study::compare(
        &rig, &sets, &data, &registry, &options,
    )?))
}

/// A `tribo mass-response` job.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MassJob {
    rig: RigSpec,
    #[serde(default)]
    lawsets: Vec<LawSetSpec>,
    body: String,
    scales: Vec<f64>,
    #[serde(default)]
    steady: bool,
    #[serde(default)]
    plugin_paths: Vec<PathBuf>,
}

/// `mass_response(job_json, isolation_json)`: torque change for a scaled body, as `tribo
/// mass-response --json`.
#[pyfunction]
#[pyo3(signature = (job, isolation=None))]
fn mass_response<'py>(
    py: Python<'py>,
    job: &str,
    isolation: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    isolated_value(
        py,
        job,
        isolation,
        "the mass response",
        isolated::Job::MassResponse,
        |o| match o {
            isolated::Output::MassResponse(m) => Some(m),
            _ => None,
        },
    )
}

/// `mass_response` in this process.
fn mass_response_local(job: &str) -> Result<Vec<study::MassResponse>, Failure> {
    let job: MassJob = serde_json::from_str(job)?;
    let body = match job.body.as_str() {
        "rod" => study::ScaledBody::Rod,
        "piston" => study::ScaledBody::Piston,
        "crank" => study::ScaledBody::Crank,
        other => {
            return Err(Failure::new(
                Kind::Input,
                format!(
                    "body: `{other}` is not a body that can be scaled; use rod, piston or crank"
                ),
            ))
        }
    };
    if let Some(bad) = job.scales.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        return Err(Failure::new(
            Kind::Input,
            format!("--scale/--scales: every scale factor must be positive, got {bad}"),
        ));
    }
    let rig = job.rig.load()?;
    let sets = lawsets(&job.lawsets)?;
    study::check_unique_names(&sets)?;
    let registry = registry(&job.plugin_paths)?;
    let fedem = study::fedem_rod_change();
    let fedem = (body == study::ScaledBody::Rod).then_some(fedem.as_slice());
    Ok(study::mass_response(
        &rig,
        &sets,
        body,
        &job.scales,
        &registry,
        job.steady,
        fedem,
    )?)
}

/// A `tribo fit` job.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FitJob {
    rig: RigSpec,
    lawset: LawSetSpec,
    params: Option<Vec<String>>,
    #[serde(default)]
    data: Vec<String>,
    #[serde(default)]
    validate: Vec<String>,
    starts: usize,
    #[serde(default)]
    no_cv: bool,
    #[serde(default)]
    data_for_any_rig: bool,
    #[serde(default)]
    plugin_paths: Vec<PathBuf>,
}

/// `fit(job_json, isolation_json)`: calibrate a law set's free parameters, as `tribo fit
/// --json`; returns the report (as Python objects) and the calibrated law set as the TOML
/// `tribo fit` writes.
#[pyfunction]
#[pyo3(signature = (job, isolation=None))]
fn fit<'py>(
    py: Python<'py>,
    job: &str,
    isolation: Option<&str>,
) -> PyResult<(Bound<'py, PyAny>, String)> {
    let (result, text) = isolated::dispatch(
        py,
        job,
        isolation,
        "the fit",
        isolated::Job::Fit,
        |o| match o {
            isolated::Output::Fit(f) => Some(f),
            _ => None,
        },
    )?;
    Ok((to_python(py, &result)?, text))
}

/// `fit` in this process: the report and the calibrated law set.
fn fit_local(job: &str) -> Result<(Box<FitResult>, String), Failure> {
    let job: FitJob = serde_json::from_str(job)?;
    if job.starts > 64 {
        return Err(Failure::new(
            Kind::Input,
            format!("starts: {} is not in 0..=64", job.starts),
        ));
    }
    let rig = job.rig.load()?;
    let ls = job.lawset.load()?;
    let names = if job.data.is_empty() {
        vec![study::default_data(&rig)?.to_string()]
    } else {
        job.data.clone()
    };
    let runs = data_runs(&names)?;
    let options = FitOptions {
        starts: job.starts,
        cross_validate: !job.no_cv,
        validate: data_runs(&job.validate)?,
        data_for_any_rig: job.data_for_any_rig,
    };
    let registry = registry(&job.plugin_paths)?;
    let free = ls.free_params(&registry, job.params.as_deref())?;
    let (result, fitted) = tribo_studies::fit::fit(&rig, &ls, &free, &runs, &registry, &options)?;
    let text = fitted
        .to_toml(&fit_header(&rig, &result, runs.len()))
        .map_err(|e| {
            Failure::new(
                Kind::Simulation,
                format!("serialising the calibrated law set: {e}"),
            )
        })?;
    Ok((Box::new(result), text))
}

/// The header `tribo fit` writes above a calibrated law set.
fn fit_header(rig: &Rig, result: &FitResult, runs: usize) -> String {
    format!(
        "Calibrated by `tribo fit` on rig {} against {} points in {} run(s): RMSE {:.4} N m in sample, {} N m leave-one-out.\nParameters fitted: {}",
        rig.file.name,
        result.measured_nm.len(),
        runs,
        result.rmse_nm,
        result
            .scores
            .cv_rmse_nm
            .map_or("(not computed)".to_string(), |v| format!("{v:.4}")),
        result.params.join(", ")
    )
}

/// A `tribo sweep` job.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepJob {
    rig: RigSpec,
    #[serde(default)]
    lawsets: Vec<LawSetSpec>,
    temps_c: Vec<f64>,
    speeds_rpm: Vec<f64>,
    #[serde(default)]
    plugin_paths: Vec<PathBuf>,
}

/// `sweep(job_json, isolation_json)`: torque over oil temperature and speed, as `tribo sweep
/// --json`.
#[pyfunction]
#[pyo3(signature = (job, isolation=None))]
fn sweep<'py>(py: Python<'py>, job: &str, isolation: Option<&str>) -> PyResult<Bound<'py, PyAny>> {
    isolated_value(
        py,
        job,
        isolation,
        "the sweep",
        isolated::Job::Sweep,
        |o| match o {
            isolated::Output::Sweep(w) => Some(w),
            _ => None,
        },
    )
}

/// `sweep` in this process.
fn sweep_local(job: &str) -> Result<Box<study::Sweep>, Failure> {
    let job: SweepJob = serde_json::from_str(job)?;
    study::check_sweep_inputs(&job.temps_c, &job.speeds_rpm)?;
    let rig = job.rig.load()?;
    let sets = lawsets(&job.lawsets)?;
    study::check_unique_names(&sets)?;
    let registry = registry(&job.plugin_paths)?;
    Ok(Box::new(study::sweep(
        &rig,
        &sets,
        &job.temps_c,
        &job.speeds_rpm,
        &registry,
        None,
    )?))
}

/// The bundled rigs, law sets and data files, by kind.
#[pyfunction]
fn bundled_names() -> (Vec<&'static str>, Vec<&'static str>, Vec<&'static str>) {
    (
        bundled::rig_names(),
        bundled::lawset_names(),
        bundled::data_names(),
    )
}

/// The native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load_rig, m)?)?;
    m.add_function(wrap_pyfunction!(load_lawset, m)?)?;
    m.add_function(wrap_pyfunction!(modes, m)?)?;
    m.add_function(wrap_pyfunction!(free_params, m)?)?;
    m.add_function(wrap_pyfunction!(check_lawset, m)?)?;
    m.add_function(wrap_pyfunction!(laws, m)?)?;
    m.add_function(wrap_pyfunction!(plugin_search_path, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(mass_response, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(bundled_names, m)?)?;
    m.add_function(wrap_pyfunction!(isolated::_worker_main, m)?)?;
    m.add("CHECKOUT_PLUGINS", CHECKOUT_PLUGINS)?;
    Ok(())
}
