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

mod failure;
mod isolated;
mod jobs;
mod topy;

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyBytes;
use tribo_config::bundled;

use crate::failure::{detached, raise, Failure, Kind};
use crate::jobs::*;

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

/// `search_path(plugin_paths)`: the paths searched before `TRIBO_PLUGIN_PATH`.
#[pyfunction]
fn plugin_search_path(plugin_paths: Vec<PathBuf>) -> Vec<PathBuf> {
    search_path(&plugin_paths)
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
