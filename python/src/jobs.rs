//! The jobs of the Python functions as data (JSON from the Python side: rig and law-set specs,
//! options) and their bodies, run in this process: what a worker process or an
//! `in_process=True` call does with a job.

use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use tribo_config::bundled;
use tribo_config::lawset::LawSet;
use tribo_config::rig::{self, Rig};
use tribo_core::observe::{ObserverError, StepObserver, StepSample};
use tribo_plugin_api::loader::{discover, LawRegistry};
use tribo_studies::fit::{FitOptions, FitResult};
use tribo_studies::study::{self, DataRun};

use crate::failure::{chain, Failure, Kind};

/// Where the plugins of the checkout this module was built from are: `target/release` beside
/// the workspace, the directory of the `tribo` binary. The CLI searches its own directory; this
/// module is loaded by Python, whose directory holds no laws, so it searches the checkout's
/// instead (only if it exists where the module runs).
pub(crate) const CHECKOUT_PLUGINS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../target/release");

/// A rig as the Python side describes it: a bundled name or file (`source`), or a text or
/// table given in Python (`text` / `table`, named `name` in messages); `sets` are `--set`
/// overrides and `oil` an `--oil` file.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub(crate) struct RigSpec {
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
pub(crate) struct LawSetSpec {
    source: Option<String>,
    text: Option<String>,
    table: Option<serde_json::Value>,
    name: Option<String>,
    laws: Vec<String>,
}

/// A TOML document from a table given in Python (as JSON).
pub(crate) fn table_text(table: &serde_json::Value, what: &str) -> Result<String, Failure> {
    toml::to_string(table).map_err(|e| {
        Failure::new(
            Kind::Input,
            format!("the {what} given as a dict cannot be written as TOML: {e} (None values and mixed lists have no TOML form)"),
        )
    })
}

impl RigSpec {
    /// Load, extend, override and validate, as `tribo run RIG --oil ... --set ...` does.
    pub(crate) fn load(&self) -> Result<Rig, Failure> {
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
    pub(crate) fn load(&self) -> Result<LawSet, Failure> {
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
pub(crate) fn lawsets(specs: &[LawSetSpec]) -> Result<Vec<LawSet>, Failure> {
    if specs.is_empty() {
        return bundled::DEFAULT_LAWSETS
            .iter()
            .map(|n| Ok(LawSet::load(n)?))
            .collect();
    }
    specs.iter().map(LawSetSpec::load).collect()
}

/// Data runs by name or file.
pub(crate) fn data_runs(names: &[String]) -> Result<Vec<DataRun>, Failure> {
    names.iter().map(|n| Ok(DataRun::read(n)?)).collect()
}

/// Registries already found, by search path and `TRIBO_PLUGIN_PATH`: each law library is
/// opened once per process, as in one `tribo` command.
pub(crate) type Registries = Vec<((Vec<PathBuf>, Option<std::ffi::OsString>), Arc<LawRegistry>)>;

pub(crate) static REGISTRIES: Mutex<Registries> = Mutex::new(Vec::new());

/// The search path: `plugin_paths` (as `--plugin`), then the checkout's `target/release` if
/// it exists; `discover` adds `TRIBO_PLUGIN_PATH` and the executable's directory.
pub(crate) fn search_path(plugin_paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut paths = plugin_paths.to_vec();
    let checkout = PathBuf::from(CHECKOUT_PLUGINS);
    if checkout.is_dir() {
        paths.push(std::fs::canonicalize(&checkout).unwrap_or(checkout));
    }
    paths
}

/// The law registry for `plugin_paths`, found once and kept.
pub(crate) fn registry(plugin_paths: &[PathBuf]) -> Result<Arc<LawRegistry>, Failure> {
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

/// The time series of a transient run: its column names ([`SERIES_COLUMNS`], then each
/// joint's normal load, named when the run starts) and the values row after row.
#[derive(Default, serde::Serialize, Deserialize)]
pub(crate) struct Series {
    pub(crate) columns: Vec<String>,
    pub(crate) values: Vec<f64>,
}

/// The columns of a time series before the joints' normal loads, in the order [`Series`]
/// stores them. The names and units are those of the CLI's `--timeseries` CSV.
pub(crate) const SERIES_COLUMNS: [&str; 5] = [
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
pub(crate) fn laws_local(job: &LawsJob) -> Result<String, Failure> {
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

/// A `tribo run` job.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RunJob {
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

/// A run's result and its time series, if asked for.
pub(crate) type RunReply = (tribo_core::sim::RunResult, Option<Series>);

/// `run` in this process.
pub(crate) fn run_local(job: &str) -> Result<RunReply, Failure> {
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
pub(crate) struct CompareJob {
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
pub(crate) fn default_starts() -> usize {
    tribo_studies::fit::DEFAULT_STARTS
}

/// `compare` in this process.
pub(crate) fn compare_local(job: &str) -> Result<Box<study::Comparison>, Failure> {
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
pub(crate) struct MassJob {
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

/// `mass_response` in this process.
pub(crate) fn mass_response_local(job: &str) -> Result<Vec<study::MassResponse>, Failure> {
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
pub(crate) struct FitJob {
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

/// `fit` in this process: the report and the calibrated law set.
pub(crate) fn fit_local(job: &str) -> Result<(Box<FitResult>, String), Failure> {
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
        .to_toml(&tribo_studies::fit::calibrated_header(
            &rig,
            &result,
            runs.len(),
        ))
        .map_err(|e| {
            Failure::new(
                Kind::Simulation,
                format!("serialising the calibrated law set: {e}"),
            )
        })?;
    Ok((Box::new(result), text))
}

/// A `tribo sweep` job.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SweepJob {
    rig: RigSpec,
    #[serde(default)]
    lawsets: Vec<LawSetSpec>,
    temps_c: Vec<f64>,
    speeds_rpm: Vec<f64>,
    #[serde(default)]
    plugin_paths: Vec<PathBuf>,
}

/// `sweep` in this process.
pub(crate) fn sweep_local(job: &str) -> Result<Box<study::Sweep>, Failure> {
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
