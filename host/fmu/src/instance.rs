//! One FMU instance: its variables' values, where it is in the FMI 2.0 Co-Simulation state
//! machine, and its worker process. Everything an instance has is its own; two instances in
//! one process share nothing (not even a worker).

use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::interface::{Causality, Interface, Kind, Role, Variability, DEFAULT_CALL_TIMEOUT_S};
use crate::log::{Logger, Status};
use crate::process::Worker;
use crate::protocol::{Reply, Report, Request};
use crate::stepping::Inputs;

/// Where an instance is in the FMI state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Phase {
    /// After fmi2Instantiate (or fmi2Reset).
    Instantiated,
    /// Between fmi2EnterInitializationMode and fmi2ExitInitializationMode.
    Initialization,
    /// Stepping.
    StepMode,
    /// After fmi2Terminate.
    Terminated,
    /// After an error: only fmi2Reset or fmi2FreeInstance help.
    Failed,
}

/// One variable's value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Value {
    /// fmi2Real.
    Real(f64),
    /// fmi2Boolean.
    Bool(bool),
    /// fmi2Integer (an enumeration's item, 1-based).
    Int(i32),
}

/// Why a call failed: logged and answered with fmi2Error.
pub type CallResult<T> = Result<T, String>;

/// A saved FMU state (fmi2GetFMUstate).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Saved {
    /// The FMU's GUID: a state of another FMU is refused.
    guid: String,
    values: Vec<Value>,
    time: f64,
    /// The worker's state.
    worker: Vec<u8>,
}

/// One FMU instance.
pub struct Instance {
    /// The importer's logger.
    pub log: Logger,
    resources: PathBuf,
    iface: Interface,
    values: Vec<Value>,
    phase: Phase,
    worker: Option<Worker>,
    /// Whether the worker's run has been built (at the first output or at leaving
    /// initialisation).
    started: bool,
    inputs_changed: bool,
    params_changed: bool,
    start_time: f64,
    time: f64,
    report: Report,
}

/// The start values of `iface`'s variables (outputs start at zero until computed).
fn start_values(iface: &Interface) -> Vec<Value> {
    iface
        .variables
        .iter()
        .map(|v| match &v.kind {
            Kind::Real { start, .. } => Value::Real(start.unwrap_or(0.0)),
            Kind::Boolean { start } => Value::Bool(*start),
            Kind::Enumeration { start, .. } => Value::Int(*start),
        })
        .collect()
}

impl Instance {
    /// A new instance reading `resources`, described by `iface`; [`Instance::spawn`] starts
    /// its worker.
    pub fn new(log: Logger, resources: PathBuf, iface: Interface) -> Self {
        let values = start_values(&iface);
        Self {
            log,
            resources,
            iface,
            values,
            phase: Phase::Instantiated,
            worker: None,
            started: false,
            inputs_changed: false,
            params_changed: false,
            start_time: 0.0,
            time: 0.0,
            report: Report::default(),
        }
    }

    /// Start the worker process and wait until it has read the resources.
    pub fn spawn(&mut self) -> CallResult<()> {
        let plugins = self.resources.join(crate::worker::PLUGIN_DIR);
        let laws = self
            .iface
            .laws
            .iter()
            .map(|l| {
                format!(
                    "law `{}` ({}) at joint `{}`",
                    l.law,
                    plugins.join(&l.library).display(),
                    l.joint
                )
            })
            .collect();
        let w = Worker::spawn(&self.resources, self.call_timeout(), laws)?;
        self.log.info(&format!(
            "worker process started for {}",
            self.resources.display()
        ));
        self.worker = Some(w);
        Ok(())
    }

    /// The value of the real variable with `role` (none declared: `None`).
    fn real_of(&self, role: &Role) -> Option<f64> {
        self.iface
            .variables
            .iter()
            .zip(&self.values)
            .find_map(|(v, x)| match x {
                Value::Real(s) if v.role == *role => Some(*s),
                _ => None,
            })
    }

    /// The `worker.call_timeout` parameter.
    fn call_timeout(&self) -> Duration {
        let s = self
            .real_of(&Role::CallTimeout)
            .filter(|s| s.is_finite() && *s > 0.0)
            .unwrap_or(DEFAULT_CALL_TIMEOUT_S);
        Duration::from_secs_f64(s.min(1e9))
    }

    /// Where the instance is.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The time of the last completed step (the start time before the first), s.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// A call's failure puts the instance in [`Phase::Failed`] and is returned as the error.
    fn fail<T>(&mut self, message: String) -> CallResult<T> {
        self.phase = Phase::Failed;
        Err(message)
    }

    fn require(&self, allowed: &[Phase], call: &str) -> CallResult<()> {
        if allowed.contains(&self.phase) {
            Ok(())
        } else {
            Err(format!(
                "{call} is not allowed now (the FMU is in phase {:?})",
                self.phase
            ))
        }
    }

    /// Send `request` to the worker; a worker failure ends the instance's usefulness.
    fn call(&mut self, request: &Request) -> CallResult<Reply> {
        let Some(w) = self.worker.as_mut() else {
            return self.fail("the FMU's worker process is not running (an earlier error stopped it; fmi2Reset starts a new one)".into());
        };
        match w.call(request) {
            Ok(Reply::Error(e)) => Err(e),
            Ok(reply) => Ok(reply),
            Err(e) => {
                self.worker = None;
                self.fail(e)
            }
        }
    }

    /// Send `request` and take the outputs it answers with.
    fn call_for_outputs(&mut self, request: &Request) -> CallResult<()> {
        match self.call(request)? {
            Reply::Outputs(r) => {
                self.report = *r;
                for w in &self.report.warnings {
                    self.log.log(Status::Warning, crate::log::WARNING, w);
                }
                Ok(())
            }
            other => self.fail(format!("the worker answered {other:?} instead of outputs")),
        }
    }

    /// fmi2SetupExperiment.
    pub fn setup_experiment(&mut self, start_time: f64) -> CallResult<()> {
        self.require(&[Phase::Instantiated], "fmi2SetupExperiment")?;
        if !start_time.is_finite() {
            return Err(format!("the start time must be finite, got {start_time}"));
        }
        self.start_time = start_time;
        self.time = start_time;
        Ok(())
    }

    /// fmi2EnterInitializationMode.
    pub fn enter_initialization(&mut self) -> CallResult<()> {
        self.require(&[Phase::Instantiated], "fmi2EnterInitializationMode")?;
        self.phase = Phase::Initialization;
        Ok(())
    }

    /// fmi2ExitInitializationMode: the run is built with the parameters and inputs set.
    pub fn exit_initialization(&mut self) -> CallResult<()> {
        self.require(&[Phase::Initialization], "fmi2ExitInitializationMode")?;
        self.refresh()?;
        self.phase = Phase::StepMode;
        Ok(())
    }

    /// Bring the worker's run up to the values set: build it at the first need, then hand it
    /// changed parameters and inputs.
    fn refresh(&mut self) -> CallResult<()> {
        if !self.started {
            let timeout = self.call_timeout();
            if let Some(w) = self.worker.as_mut() {
                w.set_limit(timeout);
            }
            let request = Request::Start {
                laws: self.law_tables()?,
                inputs: self.inputs(),
                start_time_s: self.start_time,
                crank_speed_start_rad_s: self.real_of(&Role::CrankSpeedStart).unwrap_or(0.0),
                timeout_s: timeout.as_secs_f64(),
            };
            self.call_for_outputs(&request)?;
            self.started = true;
            self.inputs_changed = false;
            self.params_changed = false;
        }
        if self.params_changed {
            let request = Request::Params(self.law_tables()?);
            self.call_for_outputs(&request)?;
            self.params_changed = false;
        }
        if self.inputs_changed {
            let request = Request::Inputs(self.inputs());
            self.call_for_outputs(&request)?;
            self.inputs_changed = false;
        }
        Ok(())
    }

    /// The inputs' current values.
    fn inputs(&self) -> Inputs {
        let mut inputs = Inputs::default();
        for (v, x) in self.iface.variables.iter().zip(&self.values) {
            if let Value::Real(x) = x {
                match v.role {
                    Role::CrankSpeedInput | Role::DriveTorqueInput => inputs.drive = *x,
                    Role::OilTemperatureInput => inputs.oil_temperature_c = *x,
                    _ => {}
                }
            }
        }
        inputs
    }

    /// Each law's parameters from the parameter variables, as TOML text.
    fn law_tables(&self) -> CallResult<Vec<String>> {
        let mut tables = vec![toml::Table::new(); self.iface.laws.len()];
        for (v, x) in self.iface.variables.iter().zip(&self.values) {
            let Role::LawParam {
                law,
                param,
                element,
            } = &v.role
            else {
                continue;
            };
            let table = tables.get_mut(*law).ok_or_else(|| {
                format!(
                    "variable {} names law {law}, which the FMU does not have",
                    v.name
                )
            })?;
            let value = match (x, &v.kind) {
                (Value::Real(r), _) => toml::Value::Float(*r),
                (Value::Bool(b), _) => toml::Value::Boolean(*b),
                (Value::Int(i), Kind::Enumeration { items, .. }) => {
                    let word = usize::try_from(*i - 1)
                        .ok()
                        .and_then(|k| items.get(k))
                        .ok_or_else(|| {
                            format!("{} = {i}: not one of its items 1..{}", v.name, items.len())
                        })?;
                    toml::Value::String(word.clone())
                }
                (Value::Int(i), _) => toml::Value::Integer(i64::from(*i)),
            };
            match element {
                None => {
                    table.insert(param.clone(), value);
                }
                Some(k) => {
                    let entry = table
                        .entry(param.clone())
                        .or_insert_with(|| toml::Value::Array(Vec::new()));
                    if let toml::Value::Array(a) = entry {
                        if a.len() <= *k {
                            a.resize(*k + 1, toml::Value::Float(0.0));
                        }
                        a[*k] = value;
                    }
                }
            }
        }
        Ok(tables.iter().map(toml::Table::to_string).collect())
    }

    /// The variable `vr`, checked to be of the type the call reads or writes.
    fn variable(&self, vr: u32, ty: &str) -> CallResult<&crate::interface::Variable> {
        let v = self
            .iface
            .variable(vr)
            .ok_or_else(|| format!("no variable has value reference {vr}"))?;
        let actual = match v.kind {
            Kind::Real { .. } => "Real",
            Kind::Boolean { .. } => "Boolean",
            Kind::Enumeration { .. } => "Integer",
        };
        if actual != ty {
            return Err(format!(
                "variable {} (value reference {vr}) is not of type {ty}",
                v.name
            ));
        }
        Ok(v)
    }

    /// The values of `vrs` (fmi2GetReal/Integer/Boolean): inputs and parameters as set,
    /// outputs as computed at the current instant.
    pub fn get(&mut self, vrs: &[u32], ty: &str) -> CallResult<Vec<Value>> {
        let mut out = Vec::with_capacity(vrs.len());
        for &vr in vrs {
            let v = self.variable(vr, ty)?;
            if v.causality == Causality::Output && v.variability != Variability::Constant {
                let role = v.role.clone();
                if matches!(self.phase, Phase::Instantiated) {
                    return Err(format!(
                        "output {} is computed from fmi2EnterInitializationMode on",
                        v.name
                    ));
                }
                if !matches!(self.phase, Phase::Terminated) {
                    self.refresh()?;
                }
                out.push(Value::Real(self.output(&role)));
            } else {
                out.push(self.values[vr as usize]);
            }
        }
        Ok(out)
    }

    /// The value of the output with `role` from the last report.
    fn output(&self, role: &Role) -> f64 {
        let r = &self.report;
        let joint = |j: usize| r.now.joints.get(j).copied().unwrap_or_default();
        match role {
            Role::CrankAngle => r.now.crank_angle_rad,
            Role::CrankSpeed => r.now.crank_speed_rad_s,
            Role::DriveTorque => r.now.drive_torque_nm,
            Role::DriveTorqueCycleMean => r.drive_torque_cycle_mean_nm,
            Role::FrictionTorque => r.now.friction_torque_nm(),
            Role::FrictionPower => r.now.friction_power_w(),
            Role::FrictionEnergy => r.now.friction_energy_j(),
            Role::FrictionTorqueCycleMean => r.friction_torque_cycle_mean_nm,
            Role::JointTorque { joint: j } => joint(*j).torque_nm,
            Role::JointPower { joint: j } => joint(*j).power_w,
            Role::JointEnergy { joint: j } => joint(*j).energy_j,
            _ => f64::NAN,
        }
    }

    /// Set `vrs` to `values` (fmi2SetReal/Integer/Boolean): inputs any time before
    /// termination, tunable parameters also while stepping, fixed ones only before.
    pub fn set(&mut self, vrs: &[u32], values: &[Value], ty: &str) -> CallResult<()> {
        for (&vr, &x) in vrs.iter().zip(values) {
            let v = self.variable(vr, ty)?;
            let stepping = matches!(self.phase, Phase::StepMode);
            match (v.causality, v.variability) {
                (Causality::Output, _) => {
                    return Err(format!("{} is an output and cannot be set", v.name))
                }
                (Causality::Parameter, Variability::Fixed) if stepping => {
                    return Err(format!(
                    "{} is a fixed parameter: it can only be set before fmi2ExitInitializationMode",
                    v.name
                ))
                }
                _ if matches!(self.phase, Phase::Terminated | Phase::Failed) => {
                    return Err(format!(
                        "{} cannot be set after termination or an error",
                        v.name
                    ))
                }
                _ => {}
            }
            if let (Value::Real(r), true) = (x, v.causality == Causality::Input) {
                if !r.is_finite() {
                    return Err(format!("input {} must be finite, got {r}", v.name));
                }
            }
            let is_input = v.causality == Causality::Input;
            let is_law = matches!(v.role, Role::LawParam { .. });
            if self.values[vr as usize] != x {
                self.values[vr as usize] = x;
                self.inputs_changed |= is_input;
                self.params_changed |= is_law;
            }
        }
        Ok(())
    }

    /// fmi2DoStep from `t` (the current time) over `h`.
    pub fn do_step(&mut self, t: f64, h: f64) -> CallResult<()> {
        self.require(&[Phase::StepMode], "fmi2DoStep")?;
        let tol = 1e-9 * t.abs().max(1.0);
        if (t - self.time).abs() > tol {
            return Err(format!(
                "fmi2DoStep from t = {t} s, but the FMU is at t = {} s: steps must follow each other",
                self.time
            ));
        }
        if !(h.is_finite() && h >= 0.0) {
            return Err(format!(
                "the communication step size must be a non-negative number, got {h}"
            ));
        }
        if self.params_changed {
            let request = Request::Params(self.law_tables()?);
            self.call_for_outputs(&request)?;
            self.params_changed = false;
        }
        let t_end = self.time + h;
        let request = Request::Step {
            t_end_s: t_end,
            inputs: self.inputs(),
        };
        self.call_for_outputs(&request)?;
        self.inputs_changed = false;
        self.time = t_end;
        Ok(())
    }

    /// fmi2Terminate: the worker ends.
    pub fn terminate(&mut self) -> CallResult<()> {
        self.require(&[Phase::StepMode, Phase::Initialization], "fmi2Terminate")?;
        if let Some(mut w) = self.worker.take() {
            w.stop();
        }
        self.phase = Phase::Terminated;
        Ok(())
    }

    /// fmi2Reset: back to just after instantiation, with a new worker.
    pub fn reset(&mut self) -> CallResult<()> {
        if let Some(mut w) = self.worker.take() {
            w.stop();
        }
        self.values = start_values(&self.iface);
        self.phase = Phase::Instantiated;
        self.started = false;
        self.inputs_changed = false;
        self.params_changed = false;
        self.start_time = 0.0;
        self.time = 0.0;
        self.report = Report::default();
        if let Err(e) = self.spawn() {
            return self.fail(e);
        }
        Ok(())
    }

    /// fmi2GetFMUstate.
    pub fn save(&mut self) -> CallResult<Saved> {
        self.require(&[Phase::StepMode, Phase::Initialization], "fmi2GetFMUstate")?;
        self.refresh()?;
        let worker = match self.call(&Request::Save)? {
            Reply::State(s) => s,
            other => return self.fail(format!("the worker answered {other:?} instead of a state")),
        };
        Ok(Saved {
            guid: self.iface.guid.clone(),
            values: self.values.clone(),
            time: self.time,
            worker,
        })
    }

    /// fmi2SetFMUstate.
    pub fn restore(&mut self, saved: &Saved) -> CallResult<()> {
        self.require(&[Phase::StepMode, Phase::Initialization], "fmi2SetFMUstate")?;
        if saved.guid != self.iface.guid || saved.values.len() != self.values.len() {
            return Err("the FMU state was saved by another FMU".into());
        }
        self.call_for_outputs(&Request::Restore(saved.worker.clone()))?;
        self.values.clone_from(&saved.values);
        self.time = saved.time;
        self.started = true;
        self.inputs_changed = false;
        self.params_changed = false;
        Ok(())
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        if let Some(mut w) = self.worker.take() {
            w.stop();
        }
    }
}

/// The first bytes of a serialised FMU state.
const STATE_MAGIC: &[u8; 8] = b"TRIBOFMU";

/// The version of the serialised FMU state's layout: `STATE_MAGIC`, this version (u32,
/// little-endian), then the MessagePack of [`Saved`] (whose worker part is the worker's own
/// versioned record, `dynamic::STATE_FORMAT_VERSION`).
pub const STATE_VERSION: u32 = 1;

/// A saved state as bytes (fmi2SerializeFMUstate) and back.
pub fn serialize(saved: &Saved) -> Vec<u8> {
    let mut bytes = STATE_MAGIC.to_vec();
    bytes.extend_from_slice(&STATE_VERSION.to_le_bytes());
    // A record of plain numbers, strings and bytes: writing it into a vector cannot fail.
    bytes.extend(rmp_serde::to_vec(saved).unwrap_or_default());
    bytes
}

/// A saved state from bytes [`serialize`] wrote; other bytes are refused, saying why.
pub fn deserialize(bytes: &[u8]) -> CallResult<Saved> {
    let body = bytes
        .strip_prefix(STATE_MAGIC.as_slice())
        .ok_or("these bytes are not a serialized state of a Tribo FMU")?;
    let (version, body) = body
        .split_first_chunk::<4>()
        .ok_or("the serialized state is cut short")?;
    let version = u32::from_le_bytes(*version);
    if version != STATE_VERSION {
        return Err(format!(
            "the serialized state is of version {version}, this FMU reads version {STATE_VERSION}"
        ));
    }
    rmp_serde::from_slice(body).map_err(|e| format!("not a serialized state of this FMU ({e})"))
}
