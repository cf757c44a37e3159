//! What the FMU needs from Tribo's solver to step a rig between communication points: the
//! [`Stepping`] seam. [`start`] builds one for a rig; today that is the quasi-steady adapter
//! ([`crate::quasi_steady`]) over the solver's steady crank-angle evaluation, to be replaced by
//! the core's stepping API when it exists (`docs/fmu.md`, "Status").

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use tribo_core::model::RigFile;
use tribo_core::sim::SimError;
use tribo_plugin_api::loader::LawRegistry;

use crate::interface::DriveMode;

/// The inputs held over the next step.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Inputs {
    /// Crank speed, rad/s (speed mode) or drive torque, N m (torque mode).
    pub drive: f64,
    /// Oil temperature, C.
    pub oil_temperature_c: f64,
}

/// One joint's friction at the current instant, and since the start.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct JointOutput {
    /// Friction torque at the crank (dissipated power over crank speed), N m.
    pub torque_nm: f64,
    /// Dissipated power, W.
    pub power_w: f64,
    /// Energy dissipated since the start, J.
    pub energy_j: f64,
}

/// The rig at the current instant.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Outputs {
    /// Time, s.
    pub time_s: f64,
    /// Accumulated crank angle, rad.
    pub crank_angle_rad: f64,
    /// Crank speed, rad/s.
    pub crank_speed_rad_s: f64,
    /// Torque the drive applies to the crank, N m.
    pub drive_torque_nm: f64,
    /// Work the drive has done since the start, J.
    pub drive_work_j: f64,
    /// Per joint with laws, in the interface's order.
    pub joints: Vec<JointOutput>,
    /// The drivetrain's transducer over the periodic cycle at the current inputs (a rig with a
    /// `[drivetrain]`; none without).
    #[serde(default)]
    pub instrument: Option<tribo_core::sim::Instrument>,
}

impl Outputs {
    /// Every joint's friction torque, summed, N m.
    pub fn friction_torque_nm(&self) -> f64 {
        self.joints.iter().map(|j| j.torque_nm).sum()
    }

    /// Every joint's dissipated power, summed, W.
    pub fn friction_power_w(&self) -> f64 {
        self.joints.iter().map(|j| j.power_w).sum()
    }

    /// Energy every joint dissipated since the start, J.
    pub fn friction_energy_j(&self) -> f64 {
        self.joints.iter().map(|j| j.energy_j).sum()
    }
}

/// Why a step, an input or a state was refused.
#[derive(Debug, thiserror::Error)]
pub enum StepError {
    /// The solver failed (a law error, a non-converging instant, a bad rig value).
    #[error(transparent)]
    Sim(#[from] SimError),
    /// An input the solver cannot run with.
    #[error("{0}")]
    Input(String),
    /// A saved state that does not belong to this run.
    #[error("the FMU state cannot be restored: {0}")]
    State(String),
    /// Something this version of the solver cannot do yet.
    #[error("{0}")]
    Unsupported(String),
}

/// A rig being stepped: inputs set between steps, `advance_to` a later time, outputs read,
/// the whole state saved and restored (law states included). Two values share nothing.
pub trait Stepping {
    /// The joints with laws, in output order.
    fn joints(&self) -> &[String];

    /// Hold `inputs` from now on; the outputs at the current instant follow them.
    fn set_inputs(&mut self, inputs: &Inputs) -> Result<(), StepError>;

    /// Integrate to time `t_s` (not before the current time) with the inputs held.
    fn advance_to(&mut self, t_s: f64) -> Result<(), StepError>;

    /// The rig at the current instant.
    fn outputs(&self) -> Outputs;

    /// The whole state, as bytes only [`Stepping::restore`] of the same rig reads.
    fn save(&self) -> Vec<u8>;

    /// Go back to a state [`Stepping::save`] gave.
    fn restore(&mut self, state: &[u8]) -> Result<(), StepError>;

    /// What the run warned of since the last call, each warning once: what `tribo run` prints
    /// with its results and the importer must know too (a law on a bearing it is not made
    /// for; a steady cycle whose stateful laws did not settle).
    fn take_warnings(&mut self) -> Vec<String> {
        Vec::new()
    }
}

/// A stepping run of `model` (laws from `registry`) driven as `drive` from `start_time_s` with
/// `inputs`.
pub fn start(
    model: &RigFile,
    registry: Arc<LawRegistry>,
    drive: DriveMode,
    start_time_s: f64,
    inputs: &Inputs,
) -> Result<Box<dyn Stepping>, StepError> {
    match drive {
        DriveMode::Speed => Ok(Box::new(crate::quasi_steady::QuasiSteady::new(
            model.clone(),
            registry,
            start_time_s,
            inputs,
        )?)),
        DriveMode::Torque => Err(StepError::Unsupported(TORQUE_MODE_MISSING.into())),
    }
}

/// Why the drive-torque input is not offered yet.
pub const TORQUE_MODE_MISSING: &str = "a drive-torque input needs the crank's dynamics stepped by Tribo's solver, which this version does not offer yet (docs/fmu.md, \"Status\"); export with --drive speed";
