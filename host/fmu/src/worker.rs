//! The worker process behind each FMU instance: it reads the FMU's resources (the rig, the
//! interface, the law libraries), runs the rig and answers the FMU's requests
//! ([`crate::protocol`]). A law that crashes, hangs or exits takes only this process down; the
//! FMU reports it as an FMI error and the importer carries on.
//!
//! Runs as `tribo __fmu-worker RESOURCES` (the `tribo` executable shipped in the archive), so
//! the process guards of every `tribo` process (the fatal-signal handler naming the law, the
//! `exit()` hook, standard output kept for results) watch the laws here too.

use std::io::{Read, Write};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use tribo_core::model::RigFile;
use tribo_plugin_api::loader::{inflight, LawRegistry};

use crate::dynamic::Dynamic;
use crate::interface::{joint_laws, joint_laws_mut, Interface, DEFAULT_CALL_TIMEOUT_S};
use crate::protocol::{
    read_frame, write_frame, FrameError, Reply, Report, Request, PROTOCOL_VERSION,
};
use crate::stepping::{Inputs, Outputs, StepError};
use crate::FmuError;

/// The rig, with its laws, in the archive's `resources/`.
pub const MODEL_FILE: &str = "model.toml";
/// The interface (variables, laws, GUID) in `resources/`.
pub const INTERFACE_FILE: &str = "interface.toml";
/// The law libraries' directory in `resources/`.
pub const PLUGIN_DIR: &str = "plugins";
/// The worker executable in `resources/`.
pub const WORKER_EXE: &str = "bin/tribo";
/// The hidden subcommand of `tribo` that serves an FMU instance.
pub const WORKER_SUBCOMMAND: &str = "__fmu-worker";
/// Exit status of a worker that stopped itself at the per-request time limit.
pub const TIMEOUT_EXIT: i32 = 3;

/// Read the interface from `resources`.
pub fn read_interface(resources: &Path) -> Result<Interface, FmuError> {
    let path = resources.join(INTERFACE_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| FmuError::resource(&path, e))?;
    toml::from_str(&text).map_err(|e| FmuError::resource(&path, e))
}

/// Serve one FMU instance: report [`Reply::Ready`] (or why not) once the resources are read,
/// then answer requests from `input` on `output` until [`Request::Quit`] or the end of
/// `input` (the FMU's process is gone).
pub fn serve(
    resources: &Path,
    mut input: impl Read,
    mut output: impl Write,
) -> Result<(), FmuError> {
    let watchdog = Watchdog::start();
    let mut session = match Session::open(resources) {
        Ok(s) => {
            write_frame(&mut output, &Reply::Ready(PROTOCOL_VERSION)).map_err(FmuError::channel)?;
            s
        }
        Err(e) => {
            let _ = write_frame(&mut output, &Reply::Error(e.to_string()));
            return Err(e);
        }
    };
    loop {
        let request: Request = match read_frame(&mut input) {
            Ok(r) => r,
            Err(FrameError::Closed) => return Ok(()),
            Err(e) => return Err(FmuError::channel(e)),
        };
        if let Request::Start { timeout_s, .. } = &request {
            watchdog.set_limit(*timeout_s);
        }
        let quit = request == Request::Quit;
        watchdog.busy();
        let reply = if quit {
            Reply::Bye
        } else {
            session.handle(request)
        };
        watchdog.idle();
        write_frame(&mut output, &reply).map_err(FmuError::channel)?;
        if quit {
            return Ok(());
        }
    }
}

/// What a saved FMU state holds on the worker's side.
#[derive(Debug, Serialize, Deserialize)]
struct Saved {
    /// The law parameters in force.
    laws: Vec<String>,
    /// The inputs held.
    inputs: Inputs,
    /// The stepping run's own state.
    run: Vec<u8>,
    /// The cycle-mean record.
    means: CycleMeans,
    /// The FMU's time at the run's time 0, s.
    t0: f64,
}

/// One FMU instance's rig.
struct Session {
    iface: Interface,
    model: RigFile,
    registry: Arc<LawRegistry>,
    run: Option<Dynamic>,
    /// The law parameters in force (TOML text per law).
    laws: Vec<String>,
    /// The crank speed a torque-driven run starts at, rad/s.
    start_speed: f64,
    /// The FMU's time at the run's time 0 (the experiment's start time), s.
    t0: f64,
    /// The inputs held.
    inputs: Inputs,
    means: CycleMeans,
}

impl Session {
    /// Read the resources: the interface, the rig (validated as a rig file), the law
    /// libraries (each one the rig uses loaded now, so a missing or broken one is reported
    /// before the first step).
    fn open(resources: &Path) -> Result<Self, FmuError> {
        let iface = read_interface(resources)?;
        let model_path = resources.join(MODEL_FILE);
        let rig = tribo_config::rig::load_rig(&model_path, &[])
            .map_err(|e| FmuError::Invalid(e.to_string()))?;
        let model = rig.model().clone();
        // Each law library the interface names, opened now: a missing or broken one is
        // reported before the first step, by its file.
        let plugins = resources.join(PLUGIN_DIR);
        let mut files: Vec<std::path::PathBuf> = Vec::new();
        for slot in &iface.laws {
            let file = plugins.join(&slot.library);
            if !file.is_file() {
                return Err(FmuError::resource(
                    &file,
                    format!(
                        "missing: the library of law `{}` on joint `{}`",
                        slot.law, slot.joint
                    ),
                ));
            }
            if !files.contains(&file) {
                files.push(file);
            }
        }
        let registry = tribo_plugin_api::loader::load_paths(&files)
            .map_err(|e| FmuError::Invalid(e.to_string()))?;
        let joints: Vec<String> = joint_laws(&model)
            .into_iter()
            .filter(|(_, l)| !l.is_empty())
            .map(|(j, _)| j)
            .collect();
        if joints != iface.joints {
            return Err(FmuError::resource(
                &model_path,
                format!(
                    "its joints with laws ({}) are not the interface's ({})",
                    joints.join(", "),
                    iface.joints.join(", ")
                ),
            ));
        }
        Ok(Self {
            iface,
            model,
            registry: Arc::new(registry),
            run: None,
            laws: Vec::new(),
            start_speed: 0.0,
            t0: 0.0,
            inputs: Inputs::default(),
            means: CycleMeans::default(),
        })
    }

    /// Answer one request.
    fn handle(&mut self, request: Request) -> Reply {
        let result = match request {
            Request::Start {
                laws,
                inputs,
                start_time_s,
                crank_speed_start_rad_s,
                ..
            } => self
                .start(laws, &inputs, start_time_s, crank_speed_start_rad_s)
                .map(|()| None),
            Request::Inputs(inputs) => self.set_inputs(&inputs).map(|()| None),
            Request::Params(laws) => self.retune(laws).map(|()| None),
            Request::Step { t_end_s, inputs } => self.step(t_end_s, &inputs).map(|()| None),
            Request::Save => self.save().map(Some),
            Request::Restore(bytes) => self.restore(&bytes).map(|()| None),
            Request::Quit => return Reply::Bye,
        };
        match result {
            Ok(Some(state)) => Reply::State(state),
            Ok(None) => match self.report() {
                Ok(r) => Reply::Outputs(Box::new(r)),
                Err(e) => Reply::Error(e.to_string()),
            },
            Err(e) => Reply::Error(e.to_string()),
        }
    }

    fn run(&mut self) -> Result<&mut Dynamic, StepError> {
        self.run
            .as_mut()
            .ok_or_else(|| StepError::State("the run has not been started".into()))
    }

    /// The rig with law parameters `laws` (TOML text per law, the interface's order).
    fn model_with(&self, laws: &[String]) -> Result<RigFile, StepError> {
        if laws.len() != self.iface.laws.len() {
            return Err(StepError::Input(format!(
                "{} law parameter tables for {} laws",
                laws.len(),
                self.iface.laws.len()
            )));
        }
        let mut model = self.model.clone();
        for (slot, text) in self.iface.laws.iter().zip(laws) {
            let params: toml::Table = toml::from_str(text).map_err(|e| {
                StepError::Input(format!(
                    "parameters of law `{}` on joint `{}`: {e}",
                    slot.law, slot.joint
                ))
            })?;
            let law = joint_laws_mut(&mut model, &slot.joint)
                .and_then(|l| l.get_mut(slot.index))
                .ok_or_else(|| {
                    StepError::Input(format!(
                        "the rig has no law {} on joint `{}`",
                        slot.index + 1,
                        slot.joint
                    ))
                })?;
            law.params = params;
        }
        Ok(model)
    }

    /// A run of the rig with law parameters `laws` at its start with `inputs` (a
    /// torque-driven crank turning at `start_speed`, rad/s).
    fn new_run(
        &self,
        laws: &[String],
        inputs: &Inputs,
        start_speed: f64,
    ) -> Result<Dynamic, StepError> {
        let model = self.model_with(laws)?;
        Dynamic::start(
            &model,
            Arc::clone(&self.registry),
            self.iface.drive,
            start_speed,
            inputs,
        )
    }

    /// Build the run, the FMU's time `t0` (s) being the run's 0.
    fn start(
        &mut self,
        laws: Vec<String>,
        inputs: &Inputs,
        t0: f64,
        start_speed: f64,
    ) -> Result<(), StepError> {
        let run = self.new_run(&laws, inputs, start_speed)?;
        self.means = CycleMeans::default();
        self.means.record(&run.outputs());
        self.run = Some(run);
        self.laws = laws;
        self.inputs = *inputs;
        self.start_speed = start_speed;
        self.t0 = t0;
        Ok(())
    }

    fn set_inputs(&mut self, inputs: &Inputs) -> Result<(), StepError> {
        self.run()?.set_inputs(inputs)?;
        self.inputs = *inputs;
        Ok(())
    }

    /// New law parameters, the run's state kept.
    fn retune(&mut self, laws: Vec<String>) -> Result<(), StepError> {
        let state = self.run()?.save()?;
        let mut run = self.new_run(&laws, &self.inputs, self.start_speed)?;
        run.restore(&state)?;
        self.run = Some(run);
        self.laws = laws;
        Ok(())
    }

    fn step(&mut self, t_end: f64, inputs: &Inputs) -> Result<(), StepError> {
        self.set_inputs(inputs)?;
        let t0 = self.t0;
        let run = self.run()?;
        run.advance_to(t_end - t0)?;
        let out = run.outputs();
        self.means.record(&out);
        Ok(())
    }

    fn save(&mut self) -> Result<Vec<u8>, StepError> {
        let run = self.run()?.save()?;
        let saved = Saved {
            laws: self.laws.clone(),
            inputs: self.inputs,
            run,
            means: self.means.clone(),
            t0: self.t0,
        };
        rmp_serde::to_vec(&saved).map_err(|e| StepError::State(e.to_string()))
    }

    fn restore(&mut self, bytes: &[u8]) -> Result<(), StepError> {
        let saved: Saved =
            rmp_serde::from_slice(bytes).map_err(|e| StepError::State(e.to_string()))?;
        if saved.laws != self.laws || self.run.is_none() {
            self.run = Some(self.new_run(&saved.laws, &saved.inputs, self.start_speed)?);
            self.laws = saved.laws;
        }
        self.run()?.restore(&saved.run)?;
        self.inputs = saved.inputs;
        self.means = saved.means;
        self.t0 = saved.t0;
        Ok(())
    }

    fn report(&mut self) -> Result<Report, StepError> {
        let cycle = f64::from(self.iface.revolutions_per_cycle) * std::f64::consts::TAU;
        let run = self.run()?;
        let now = run.outputs();
        let warnings = run.take_warnings();
        let (friction, drive) = self.means.means(&now, cycle);
        Ok(Report {
            now,
            friction_torque_cycle_mean_nm: friction,
            drive_torque_cycle_mean_nm: drive,
            warnings,
        })
    }
}

/// The crank angle, friction energy and drive work at each communication point of the last
/// cycle, from which the means over the last whole cycle are read.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
struct CycleMeans {
    /// (crank angle rad, friction energy J, drive work J), rising in angle.
    points: Vec<(f64, f64, f64)>,
}

impl CycleMeans {
    /// Record the outputs of a communication point.
    fn record(&mut self, out: &Outputs) {
        let p = (
            out.crank_angle_rad,
            out.friction_energy_j(),
            out.drive_work_j,
        );
        match self.points.last() {
            Some(last) if last.0 >= p.0 => {
                // No crank motion since (a zero step, or inputs changed in place): the newer
                // values stand for this angle.
                if let Some(l) = self.points.last_mut() {
                    *l = p;
                }
            }
            _ => self.points.push(p),
        }
    }

    /// Friction and drive torque means over the cycle ending at `now` (energy over angle;
    /// linear in angle between communication points). Before a whole cycle has turned, the
    /// means since the start; before the crank has turned at all, the values at `now`.
    fn means(&mut self, now: &Outputs, cycle: f64) -> (f64, f64) {
        let theta = now.crank_angle_rad;
        let target = theta - cycle;
        // Keep one point at or before the target, drop older ones.
        let keep_from = self.points.iter().rposition(|p| p.0 <= target).unwrap_or(0);
        self.points.drain(..keep_from);
        let Some(&first) = self.points.first() else {
            return (now.friction_torque_nm(), now.drive_torque_nm);
        };
        let end = (theta, now.friction_energy_j(), now.drive_work_j);
        let start = if first.0 >= target {
            first
        } else {
            let next = self.points.get(1).copied().unwrap_or(end);
            let w = if next.0 > first.0 {
                (target - first.0) / (next.0 - first.0)
            } else {
                0.0
            };
            (
                target,
                first.1 + w * (next.1 - first.1),
                first.2 + w * (next.2 - first.2),
            )
        };
        let span = end.0 - start.0;
        if span <= 0.0 {
            return (now.friction_torque_nm(), now.drive_torque_nm);
        }
        ((end.1 - start.1) / span, (end.2 - start.2) / span)
    }
}

/// Stops the worker when one request takes longer than the limit, saying which law was
/// running: an FMU call never waits for ever on a law that hangs.
struct Watchdog {
    /// Milliseconds since `epoch` at which the current request runs out; 0 while idle.
    deadline_ms: Arc<AtomicU64>,
    limit_ms: Arc<AtomicU64>,
    epoch: Instant,
}

impl Watchdog {
    fn start() -> Self {
        let deadline_ms = Arc::new(AtomicU64::new(0));
        let limit_ms = Arc::new(AtomicU64::new((DEFAULT_CALL_TIMEOUT_S * 1e3) as u64));
        let epoch = Instant::now();
        let (d, l) = (Arc::clone(&deadline_ms), Arc::clone(&limit_ms));
        std::thread::spawn(move || loop {
            std::thread::sleep(Duration::from_millis(20));
            let deadline = d.load(Ordering::SeqCst);
            if deadline != 0 && epoch.elapsed().as_millis() as u64 > deadline {
                let running = inflight::running();
                let what = if running.is_empty() {
                    String::new()
                } else {
                    format!(" while running {}", running.join(", "))
                };
                let limit = l.load(Ordering::SeqCst) as f64 / 1e3;
                eprintln!(
                    "tribo FMU worker: a request took longer than worker.call_timeout = {limit} s{what}; the worker stopped"
                );
                // SAFETY: _exit ends the process at once; no destructor or exit hook runs
                // (the law may hold any lock).
                unsafe { libc::_exit(TIMEOUT_EXIT) }
            }
        });
        Self {
            deadline_ms,
            limit_ms,
            epoch,
        }
    }

    fn set_limit(&self, seconds: f64) {
        let ms = if seconds.is_finite() && seconds > 0.0 {
            (seconds * 1e3).min(u64::MAX as f64 / 2.0) as u64
        } else {
            (DEFAULT_CALL_TIMEOUT_S * 1e3) as u64
        };
        self.limit_ms.store(ms.max(1), Ordering::SeqCst);
    }

    fn busy(&self) {
        let now = self.epoch.elapsed().as_millis() as u64;
        let limit = self.limit_ms.load(Ordering::SeqCst);
        self.deadline_ms
            .store(now.saturating_add(limit).max(1), Ordering::SeqCst);
    }

    fn idle(&self) {
        self.deadline_ms.store(0, Ordering::SeqCst);
    }
}
