//! Jobs of the Python module in a worker process (`tribo_isolate`), unless the caller asks for
//! `in_process=True`. The worker is this Python interpreter started again (`-I`, so no user
//! site or environment changes it) with only this native module loaded (not the `tribo`
//! package, so pandas is never imported there), serving one job: a law that segfaults, calls
//! `exit()` or `_exit()`, hangs inside a call, stops or kills its process group fails the call
//! with a `tribo.SimulationError` naming the law; the interpreter and the user's script go on.
//! While waiting, Ctrl-C still works (the wait checks Python's signals and kills the worker),
//! and what the law writes on standard error reaches `sys.stderr`.
//!
//! A worker serves one Python thread's calls one after another (a long-lived worker: starting
//! an interpreter costs tens of milliseconds, a steady run a few): its plugins stay loaded, as
//! they do in process. It is replaced when it failed (a crash, a limit), when the limits asked
//! for change, or when the working directory or `TRIBO_PLUGIN_PATH` it was started with did; it
//! ends with its thread, or with this process.

use std::cell::RefCell;
use std::ffi::OsString;
use std::path::PathBuf;
use std::process::Command;

use pyo3::prelude::*;
use serde::{Deserialize, Serialize};
use tribo_isolate::{Event, Limits, WorkerFailure};

use crate::failure::{Failure, Kind};

/// A job for the worker: the function and its job JSON.
#[derive(Serialize, Deserialize)]
pub(crate) enum Job {
    /// `run`.
    Run(String),
    /// `compare`.
    Compare(String),
    /// `mass_response`.
    MassResponse(String),
    /// `fit`.
    Fit(String),
    /// `sweep`.
    Sweep(String),
    /// `laws`.
    Laws(crate::jobs::LawsJob),
}

/// A worker's answer: the function's result, or its failure (exception class and message).
#[derive(Serialize, Deserialize)]
pub(crate) enum Output {
    /// `run`.
    Run(Box<crate::jobs::RunReply>),
    /// `compare`.
    Compare(Box<tribo_studies::study::Comparison>),
    /// `mass_response`.
    MassResponse(Vec<tribo_studies::study::MassResponse>),
    /// `fit`.
    Fit((Box<tribo_studies::fit::FitResult>, String)),
    /// `sweep`.
    Sweep(Box<tribo_studies::study::Sweep>),
    /// `laws`: the listing as JSON text.
    Laws(String),
    /// The job failed as it would in process.
    Failed(Failure),
}

/// How a call runs its laws: the keyword arguments `in_process`, `time_limit_s`,
/// `memory_limit_mb`, `call_limit_s` of the Python functions (as JSON).
#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct Isolation {
    in_process: bool,
    time_limit_s: f64,
    memory_limit_mb: u64,
    call_limit_s: f64,
}

impl Default for Isolation {
    fn default() -> Self {
        let l = Limits::default();
        Self {
            in_process: false,
            time_limit_s: l.time_s,
            memory_limit_mb: l.memory_mb,
            call_limit_s: l.call_s,
        }
    }
}

/// What a cached worker was started with: a call with other values needs a new one.
#[derive(PartialEq)]
struct Started {
    limits: Limits,
    cwd: Option<PathBuf>,
    plugin_path: Option<OsString>,
}

impl Started {
    fn now(limits: Limits) -> Self {
        Self {
            limits,
            cwd: std::env::current_dir().ok(),
            plugin_path: std::env::var_os(tribo_plugin_api::loader::PLUGIN_PATH_ENV),
        }
    }
}

thread_local! {
    /// This thread's worker, kept between calls.
    static WORKER: RefCell<Option<(Started, tribo_isolate::Worker)>> = const { RefCell::new(None) };
}

/// The Python code a worker interpreter runs: load this module from its file (argument 1)
/// without importing the `tribo` package, and serve.
const BOOT: &str = "import sys, importlib.util as u\nfrom importlib.machinery import ExtensionFileLoader as L\nl = L('tribo._native', sys.argv[1])\ns = u.spec_from_file_location('tribo._native', sys.argv[1], loader=l)\nm = u.module_from_spec(s)\nl.exec_module(m)\nm._worker_main()\n";

/// What starts a worker: this interpreter (`sys.executable`) and this module's file.
struct Program {
    exe: PathBuf,
    module: PathBuf,
}

impl Program {
    /// This interpreter and module, or why a worker cannot be started.
    fn find(py: Python<'_>) -> Result<Self, Failure> {
        let fail = |what: &str| {
            Failure::new(
                Kind::Simulation,
                format!("cannot start a worker process for the laws: {what}; pass in_process=True to run them in this process"),
            )
        };
        let exe: PathBuf = py
            .import("sys")
            .and_then(|m| m.getattr("executable"))
            .and_then(|e| e.extract())
            .map_err(|_| fail("sys.executable is not available"))?;
        if exe.as_os_str().is_empty() {
            return Err(fail("sys.executable is empty (an embedded interpreter)"));
        }
        let module: PathBuf = py
            .import("tribo._native")
            .and_then(|m| m.getattr("__file__"))
            .and_then(|f| f.extract())
            .map_err(|_| fail("the file of tribo._native is not known"))?;
        Ok(Self { exe, module })
    }

    /// The command that starts a worker: the interpreter running [`BOOT`] on the module.
    fn command(&self) -> Command {
        let mut cmd = Command::new(&self.exe);
        cmd.args(["-I", "-c", BOOT]).arg(&self.module);
        cmd
    }
}

/// What a call does with a worker's events while it waits: standard error and notes to
/// `sys.stderr`; on each tick Python's signals are checked, and Ctrl-C (kept in `interrupted`)
/// stops the wait.
fn python_events(
    interrupted: &mut Option<PyErr>,
) -> impl FnMut(Event<'_>) -> Result<(), WorkerFailure> + '_ {
    move |e| {
        match e {
            Event::Stderr(line) => to_stderr(line),
            Event::Slow(note) => to_stderr(&format!("note: {note}")),
            Event::Tick => {
                if let Err(e) = Python::attach(|py| py.check_signals()) {
                    *interrupted = Some(e);
                    return Err(WorkerFailure::Interrupted);
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// Write `text` to Python's `sys.stderr` (where a notebook shows it).
fn to_stderr(text: &str) {
    Python::attach(|py| {
        let _ = py
            .import("sys")
            .and_then(|m| m.getattr("stderr"))
            .and_then(|e| e.call_method1("write", (format!("{text}\n"),)));
    });
}

/// Run a job: in this process with `in_process`, else in a worker (`wrap` makes its job,
/// `pick` takes its answer). `what` names the job in a worker's failure ("the run").
pub(crate) fn dispatch<T: Send>(
    py: Python<'_>,
    job: &str,
    isolation: Option<&str>,
    what: &str,
    wrap: fn(String) -> Job,
    pick: fn(Output) -> Option<T>,
) -> PyResult<T> {
    let iso: Isolation = match isolation {
        Some(text) => serde_json::from_str(text).map_err(|e| {
            crate::failure::raise(py, Failure::new(Kind::Input, format!("isolation: {e}")))
        })?,
        None => Isolation::default(),
    };
    let limits = Limits {
        time_s: iso.time_limit_s,
        memory_mb: iso.memory_limit_mb,
        call_s: iso.call_limit_s,
    }
    .checked(["time_limit_s", "memory_limit_mb", "call_limit_s"])
    .map_err(|e| crate::failure::raise(py, Failure::new(Kind::Input, e.to_string())))?;
    if iso.in_process {
        let job = wrap(job.to_string());
        return crate::failure::detached(py, move || match pick(local(job)) {
            Some(t) => Ok(t),
            None => Err(Failure::new(
                Kind::Simulation,
                "the job gave another job's answer",
            )),
        });
    }
    let command = Program::find(py)
        .map_err(|f| crate::failure::raise(py, f))?
        .command();
    let job = wrap(job.to_string());
    let mut interrupted: Option<PyErr> = None;
    let answer = py.detach(|| {
        let started = Started::now(limits);
        let cached = WORKER.with(|w| w.borrow_mut().take());
        let mut worker = match cached {
            Some((s, w)) if s == started && w.alive() => w,
            other => {
                if let Some((_, w)) = other {
                    w.finish();
                }
                tribo_isolate::Worker::start(command, limits)?
            }
        };
        let r = worker.call::<_, Output>(&job, &mut python_events(&mut interrupted));
        // Kept for the next call unless it failed (then it is gone already).
        if matches!(r, Ok(_) | Err(WorkerFailure::Study(_))) {
            WORKER.with(|w| *w.borrow_mut() = Some((started, worker)));
        } else {
            worker.finish();
        }
        r
    });
    if let Some(e) = interrupted {
        return Err(e);
    }
    match answer {
        Ok(Output::Failed(f)) => Err(crate::failure::raise(py, f)),
        Ok(o) => pick(o).ok_or_else(|| {
            crate::failure::raise(
                py,
                Failure::new(Kind::Simulation, "a worker answered another job's question"),
            )
        }),
        Err(WorkerFailure::Study(message)) => Err(crate::failure::raise(
            py,
            Failure::new(Kind::Simulation, message),
        )),
        Err(e) => Err(crate::failure::raise(
            py,
            Failure::new(Kind::Simulation, format!("{what} failed: {e}")),
        )),
    }
}

/// `laws()`: the listing, made in fresh worker processes (the libraries opened
/// there, never in this one); a file whose loading ended, crashed or hung a worker is left out
/// and listed as broken with the reason, as `tribo laws` does.
pub(crate) fn laws(py: Python<'_>, plugin_paths: &[PathBuf]) -> PyResult<serde_json::Value> {
    let program = Program::find(py).map_err(|f| crate::failure::raise(py, f))?;
    let mut interrupted: Option<PyErr> = None;
    let listed = py.detach(|| {
        tribo_isolate::listing::skipping_unloadable(|skip| {
            let job = Job::Laws(crate::jobs::LawsJob {
                plugin_paths: plugin_paths
                    .iter()
                    .filter(|p| !skip.iter().any(|(s, _)| s == *p))
                    .cloned()
                    .collect(),
                skip: skip.to_vec(),
            });
            let mut worker = tribo_isolate::Worker::start(program.command(), Limits::default())?;
            let r = worker.call::<_, Output>(&job, &mut python_events(&mut interrupted));
            worker.finish();
            match r? {
                Output::Laws(text) => Ok(Ok(text)),
                Output::Failed(f) => Ok(Err(f)),
                _ => Err(WorkerFailure::Internal(
                    "a worker answered another job's question".into(),
                )),
            }
        })
    });
    if let Some(e) = interrupted {
        return Err(e);
    }
    let (text, skipped) = match listed {
        Ok((Ok(text), skipped)) => (text, skipped),
        Ok((Err(f), _)) => return Err(crate::failure::raise(py, f)),
        Err(WorkerFailure::Study(message)) => {
            return Err(crate::failure::raise(
                py,
                Failure::new(Kind::Simulation, message),
            ))
        }
        Err(e) => {
            return Err(crate::failure::raise(
                py,
                Failure::new(Kind::Simulation, format!("listing the laws failed: {e}")),
            ))
        }
    };
    // A skipped file given in `plugin_paths` is not in the worker's listing: add it here.
    let mut value: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
        crate::failure::raise(
            py,
            Failure::new(Kind::Simulation, format!("reading the listing: {e}")),
        )
    })?;
    if let Some(broken) = value["broken"].as_array_mut() {
        for (path, why) in skipped.iter().filter(|(p, _)| plugin_paths.contains(p)) {
            broken.push(serde_json::json!({
                "file": path.display().to_string(),
                "error": format!("`{}` was not opened: {why}", path.display()),
            }));
        }
    }
    Ok(value)
}

/// Run `job` here, its failure as an answer.
fn local(job: Job) -> Output {
    let r = match job {
        Job::Run(j) => crate::jobs::run_local(&j).map(|r| Output::Run(Box::new(r))),
        Job::Compare(j) => crate::jobs::compare_local(&j).map(Output::Compare),
        Job::MassResponse(j) => crate::jobs::mass_response_local(&j).map(Output::MassResponse),
        Job::Fit(j) => crate::jobs::fit_local(&j).map(Output::Fit),
        Job::Sweep(j) => crate::jobs::sweep_local(&j).map(Output::Sweep),
        Job::Laws(j) => crate::jobs::laws_local(&j).map(Output::Laws),
    };
    r.unwrap_or_else(Output::Failed)
}

/// `_worker_main()`: be a worker (this interpreter was started by [`Program::command`]); never
/// returns.
#[pyfunction]
pub(crate) fn _worker_main() {
    tribo_isolate::guard::install();
    tribo_isolate::serve(|job: Job, _session: &tribo_isolate::Session| Ok(local(job)))
}
