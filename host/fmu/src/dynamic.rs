//! The FMU's run: the rig's crank train integrated in time by the core's stepping API
//! ([`tribo_core::sim::Run`]) between communication points, the importer's inputs held over
//! each step. The crank accelerates under the drive torque against friction and the
//! mechanism's inertia (torque input), or follows the input speed (speed input); stateful laws
//! carry their history across every input change.
//!
//! Decisions, for a co-simulation importer:
//! - every communication point starts the stepper afresh ([`Run::restart`]): the inputs may
//!   jump there, and the run's state at a communication point is then its [`RunState`] alone,
//!   which is what a serialised FMU state holds, so a restored state continues bit for bit as
//!   the run it was taken from;
//! - fixed steps: RK4 for a torque-driven (PI) crank (`solver.integrator = "rk4"`), Simpson's
//!   rule for a prescribed one (`solver.quadrature = "simpson"`), each step at most
//!   `solver.step_deg` of crank angle at the current speed (and `solver.max_step_s`); no
//!   replay of repeating cycles (the inputs may change at any step);
//! - the run's schedule is the inputs': the rig's test cycle is not run (no plateau is
//!   recorded), the oil is at the input temperature.
//!
//! `tribo run --drive-torque` runs the same [`Dynamic`] from the command line.

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use tribo_core::cycle::Segment;
use tribo_core::model::{Drive, Integrator, QuadratureRule, RigFile, Temperature};
use tribo_core::sim::{Inputs as CoreInputs, Run, RunState, Simulation};
use tribo_plugin_api::loader::LawRegistry;

use crate::interface::{joint_laws, DriveMode};
use crate::stepping::{Inputs, JointOutput, Outputs, StepError};

/// The first bytes of a saved run: what [`Dynamic::restore`] checks before reading on.
const STATE_MAGIC: &[u8; 8] = b"TRIBORUN";

/// The version of the saved run's layout (after the magic bytes, little-endian u32): the
/// magic, this version, then the MessagePack of `Saved`.
pub const STATE_FORMAT_VERSION: u32 = 1;

/// The lowest speed of the run's own schedule, rad/s (about 100 rpm): its hold needs a
/// turning crank.
const SCHEDULE_MIN_SPEED: f64 = 10.0;

/// What a saved run holds.
#[derive(Debug, Serialize, Deserialize)]
struct Saved {
    /// How the crank is driven (a state of the other mode is refused).
    drive: DriveMode,
    /// The core run's state.
    run: RunState,
}

/// The rig `model` as the FMU runs it (see the module documentation), driven by `drive`, oil
/// at `oil_temperature_c` at the start. Its own schedule, which the inputs replace, is a short
/// ramp to `speed_rad_s` (at least `SCHEDULE_MIN_SPEED`) and a hold: under a torque input
/// its speed bounds the step from below (steps of at most `solver.step_deg` at the larger of
/// it and the crank's speed). A prescribed rig driven by a torque gets a PI drive
/// whose controller the torque input replaces (no motor inertia: the importer's drive is
/// outside the FMU).
pub fn stepping_model(
    model: &RigFile,
    drive: DriveMode,
    speed_rad_s: f64,
    oil_temperature_c: f64,
) -> RigFile {
    let mut m = model.clone();
    let rpm = speed_rad_s.max(SCHEDULE_MIN_SPEED) * 30.0 / std::f64::consts::PI;
    m.cycle.segments = Some(vec![
        Segment::Ramp {
            to_rpm: rpm,
            duration_s: 0.1,
        },
        Segment::Hold { duration_s: 1.0 },
    ]);
    m.oil.temperature_c = Temperature::Constant(oil_temperature_c);
    if drive == DriveMode::Torque && matches!(m.drive, Drive::Prescribed {}) {
        m.drive = Drive::Pi {
            kp: 0.0,
            ki: 0.0,
            torque_limit_nm: f64::MAX,
            belt_ratio: 1.0,
            motor_inertia_kg_m2: 0.0,
        };
    }
    match m.drive {
        Drive::Pi { .. } => {
            m.solver.integrator = Integrator::Rk4;
            m.solver.quadrature = QuadratureRule::default();
        }
        Drive::Prescribed {} => {
            m.solver.quadrature = QuadratureRule::Simpson;
            m.solver.integrator = Integrator::default();
        }
    }
    m
}

/// A rig run in time for the FMU (see the module documentation).
pub struct Dynamic {
    run: Run,
    drive: DriveMode,
    /// The joints with laws, in the interface's order.
    joints: Vec<String>,
    /// For each, its place in the run's joints.
    index: Vec<usize>,
    /// What the run warned of since the last [`Dynamic::take_warnings`].
    warnings: Vec<String>,
}

impl Dynamic {
    /// Start `model` (laws from `registry`) driven by `drive` with `inputs` at time 0: from
    /// rest under a speed input, turning at `start_speed_rad_s` under a torque input.
    pub fn start(
        model: &RigFile,
        registry: Arc<LawRegistry>,
        drive: DriveMode,
        start_speed_rad_s: f64,
        inputs: &Inputs,
    ) -> Result<Self, StepError> {
        check_oil(inputs.oil_temperature_c)?;
        let speed = match drive {
            DriveMode::Speed => inputs.drive,
            DriveMode::Torque => start_speed_rad_s,
        };
        if !(speed.is_finite() && speed >= 0.0) {
            return Err(StepError::Input(format!(
                "the crank speed at the start must be a speed >= 0 rad/s, got {speed}"
            )));
        }
        let m = stepping_model(model, drive, speed, inputs.oil_temperature_c);
        let mut sim = Simulation::new(&m, &registry)?;
        sim.set_replay_holds(false);
        let names = sim.joint_names();
        let run = match drive {
            DriveMode::Speed => sim.start()?,
            DriveMode::Torque => sim.start_turning(start_speed_rad_s)?,
        };
        let joints: Vec<String> = joint_laws(model)
            .into_iter()
            .filter(|(_, laws)| !laws.is_empty())
            .map(|(j, _)| j)
            .collect();
        let index = joints
            .iter()
            .map(|j| {
                names.iter().position(|n| n == j).ok_or_else(|| {
                    StepError::Input(format!("the solver has no joint `{j}` of the rig"))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut s = Self {
            run,
            drive,
            joints,
            index,
            // The rig's own notes (a law on a bearing it is not made for), as every result of
            // `tribo run` carries them first: once, at the start.
            warnings: tribo_core::sim::suitability_notes(model, &registry),
        };
        s.set_inputs(inputs)?;
        Ok(s)
    }

    /// The joints with laws, in output order.
    pub fn joints(&self) -> &[String] {
        &self.joints
    }

    /// Hold `inputs` from the run's time on.
    pub fn set_inputs(&mut self, inputs: &Inputs) -> Result<(), StepError> {
        check_oil(inputs.oil_temperature_c)?;
        let drive = inputs.drive;
        let (valid, what) = match self.drive {
            DriveMode::Speed => (
                drive.is_finite() && drive >= 0.0,
                "crank_speed must be a speed >= 0 rad/s",
            ),
            DriveMode::Torque => (
                drive.is_finite(),
                "drive_torque must be a finite torque in N.m",
            ),
        };
        if !valid {
            return Err(StepError::Input(format!("{what}, got {drive}")));
        }
        let mut core = CoreInputs {
            oil_temperature_c: Some(inputs.oil_temperature_c),
            ..CoreInputs::default()
        };
        match self.drive {
            DriveMode::Speed => core.crank_speed_rad_s = Some(drive),
            DriveMode::Torque => core.drive_torque_nm = Some(drive),
        }
        self.run.set_inputs(core)?;
        Ok(())
    }

    /// Integrate to time `t_s` (not before the run's time) with the inputs held, the stepper
    /// started afresh at the run's time (a communication point).
    pub fn advance_to(&mut self, t_s: f64) -> Result<(), StepError> {
        let now = self.run.time_s();
        if t_s.is_nan() || t_s < now {
            return Err(StepError::Input(format!(
                "cannot step back in time, from {now} s to {t_s} s"
            )));
        }
        if t_s == now {
            return Ok(());
        }
        self.run.restart()?;
        self.run.advance_to(t_s)?;
        Ok(())
    }

    /// The rig at the run's time.
    pub fn outputs(&self) -> Outputs {
        let out = self.run.outputs();
        let joints = self
            .index
            .iter()
            .map(|&k| {
                let j = &out.joints[k];
                JointOutput {
                    torque_nm: j.torque_at_crank_nm,
                    power_w: j.power_w,
                    energy_j: j.energy_j,
                }
            })
            .collect();
        Outputs {
            time_s: out.time_s,
            crank_angle_rad: out.crank_angle_rad,
            crank_speed_rad_s: out.crank_speed_rad_s,
            drive_torque_nm: out.drive_torque_nm,
            drive_work_j: out.drive_work_j,
            joints,
        }
    }

    /// The run's whole state as bytes: `STATE_MAGIC`, [`STATE_FORMAT_VERSION`] (u32,
    /// little-endian), then the MessagePack of the drive mode and the core run's
    /// [`RunState`] (every f64 bit for bit).
    pub fn save(&self) -> Result<Vec<u8>, StepError> {
        let saved = Saved {
            drive: self.drive,
            run: self.run.state(),
        };
        let body = rmp_serde::to_vec(&saved).map_err(|e| StepError::State(e.to_string()))?;
        let mut bytes = Vec::with_capacity(12 + body.len());
        bytes.extend_from_slice(STATE_MAGIC);
        bytes.extend_from_slice(&STATE_FORMAT_VERSION.to_le_bytes());
        bytes.extend_from_slice(&body);
        Ok(bytes)
    }

    /// Go back to a state [`Dynamic::save`] gave (of this rig and law set, in this drive
    /// mode). Bytes that are not one are refused, saying why; the run is then unchanged.
    pub fn restore(&mut self, bytes: &[u8]) -> Result<(), StepError> {
        let bad = |m: String| StepError::State(m);
        let body = bytes
            .strip_prefix(STATE_MAGIC.as_slice())
            .ok_or_else(|| bad("these bytes are not a saved Tribo run".into()))?;
        let (version, body) = body
            .split_first_chunk::<4>()
            .ok_or_else(|| bad("the saved run is cut short".into()))?;
        let version = u32::from_le_bytes(*version);
        if version != STATE_FORMAT_VERSION {
            return Err(bad(format!(
                "the saved run is of format version {version}, this FMU reads version {STATE_FORMAT_VERSION}"
            )));
        }
        let saved: Saved = rmp_serde::from_slice(body)
            .map_err(|e| bad(format!("the saved run cannot be read ({e})")))?;
        if saved.drive != self.drive {
            return Err(bad(format!(
                "it was saved by an FMU driven by {:?}, this one is driven by {:?}",
                saved.drive, self.drive
            )));
        }
        self.run.resume(&saved.run)?;
        Ok(())
    }

    /// What the run warned of since the last call, each warning once.
    pub fn take_warnings(&mut self) -> Vec<String> {
        std::mem::take(&mut self.warnings)
    }
}

/// The oil temperature input checked against the viscosity model's range.
fn check_oil(temp: f64) -> Result<(), StepError> {
    let (lo, hi) = tribo_core::oil::VALID_RANGE_C;
    if temp >= lo && temp <= hi {
        Ok(())
    } else {
        Err(StepError::Input(format!(
            "oil_temperature must be within [{lo}, {hi}] C (the viscosity model's valid range), got {temp}"
        )))
    }
}
