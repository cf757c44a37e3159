//! What the FMU's library and its worker exchange about a run: the inputs held over a step,
//! the outputs at a communication point, and why a step was refused. The run itself is the
//! `dynamic` module's (this module names nothing of it: the run uses these types, not the
//! reverse).

use serde::{Deserialize, Serialize};
use tribo_core::sim::SimError;

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
}
