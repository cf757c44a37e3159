//! What a run produces: plateau results per law, the energy balance, and the run as a whole.

use std::fmt;

use tribo_plugin_api::serde::{Deserialize, Serialize};

/// How a run drove the crank: the `drive` of [`RunResult`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde", rename_all = "lowercase")]
pub enum DriveKind {
    /// The crank followed the cycle's reference motion exactly.
    Prescribed,
    /// A PI speed controller drove the crank with a torque.
    Pi,
    /// Each plateau computed directly as a periodic steady state.
    Steady,
}

impl DriveKind {
    /// The name used in JSON and reports.
    pub const fn as_str(self) -> &'static str {
        match self {
            DriveKind::Prescribed => "prescribed",
            DriveKind::Pi => "pi",
            DriveKind::Steady => "steady",
        }
    }
}

impl fmt::Display for DriveKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Per-law result for one plateau.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct LawResult {
    /// Joint name.
    pub joint: String,
    /// Law name.
    pub law: String,
    /// Mean friction torque at the crank: dissipated power over mean crank speed, N m.
    pub friction_torque_nm: f64,
    /// Mean dissipated power, W.
    pub power_w: f64,
    /// Mean normal load of the joint over the window, N.
    pub mean_normal_load_n: f64,
    /// Time share of each lubrication regime.
    pub regime_share: RegimeShare,
}

/// Time shares of the lubrication regimes (they add up to 1).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, Default)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct RegimeShare {
    /// The law reported no regime.
    pub none: f64,
    /// Boundary.
    pub boundary: f64,
    /// Mixed.
    pub mixed: f64,
    /// Hydrodynamic.
    pub hydrodynamic: f64,
}

/// One measured plateau.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct PlateauResult {
    /// Reference speed, rpm.
    pub set_speed_rpm: f64,
    /// Mean crank speed over the measurement window, rpm.
    pub mean_speed_rpm: f64,
    /// Mean motoring torque over whole crank revolutions (whole 4-stroke cycles when the gas
    /// pressure makes the cycle 4-stroke), N m.
    pub motoring_torque_nm: f64,
    /// Mean torque absorbed by the gas over the window (the gas work over the crank angle), N m.
    #[serde(default)]
    pub gas_torque_nm: f64,
    /// Oil temperature, C.
    pub oil_temp_c: f64,
    /// Dynamic viscosity at that temperature, Pa s.
    pub viscosity_pa_s: f64,
    /// Start and end of the window, s.
    pub window_s: [f64; 2],
    /// Whole revolutions averaged (an even number for a 4-stroke cycle).
    pub revolutions: u32,
    /// Per joint and law.
    pub joints: Vec<LawResult>,
}

/// Energy bookkeeping over the whole run.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct EnergyBalance {
    /// Work of the drive torque on the crank, J.
    pub motor_work_j: f64,
    /// Change of kinetic plus potential energy, J.
    pub mechanical_energy_change_j: f64,
    /// Energy dissipated by all laws, J.
    pub dissipated_j: f64,
    /// Work done on the gas in the cylinder and crankcase, J (zero without gas loads).
    #[serde(default)]
    pub gas_work_j: f64,
    /// motor work - energy change - dissipation - gas work, J.
    pub residual_j: f64,
    /// |residual| / motor work.
    pub relative_residual: f64,
}

/// Everything a run produces.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct RunResult {
    /// Rig name.
    pub rig: String,
    /// How the crank was driven (`prescribed`, `pi` or `steady` in JSON).
    pub drive: DriveKind,
    /// One entry per hold of the cycle.
    pub plateaus: Vec<PlateauResult>,
    /// Energy residual over the run, J.
    pub energy_residual_j: f64,
    /// Full energy bookkeeping.
    pub energy: EnergyBalance,
    /// Steps taken (accepted).
    pub steps: u64,
    /// Steps tried and rejected by the adaptive integrator's error control (0 for fixed
    /// steps). Not in the JSON, which stays what it was before the count existed.
    #[serde(skip)]
    pub rejected_steps: u64,
    /// Largest number of friction/reaction iterations needed at one evaluation.
    pub max_friction_iterations: u32,
    /// Warnings (a drive at its torque limit, say).
    pub warnings: Vec<String>,
    /// Time spent in each law (estimated from sampled calls). Printed in the text report only:
    /// wall-clock time would make JSON and CSV results differ from run to run.
    #[serde(skip)]
    pub law_time: Vec<LawTime>,
}

/// Time a law took over a run.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct LawTime {
    /// Joint.
    pub joint: String,
    /// Law.
    pub law: String,
    /// Evaluations.
    pub calls: u64,
    /// Estimated seconds in the law (one call in 256 timed, the clock's own cost subtracted).
    pub seconds: f64,
}
