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
    /// The crankcase's pumping torque at the plateau's speed, N m: a vented crankcase's
    /// breather loss per revolution over 2 pi (the periodic cycle its tables hold), 0 for a
    /// sealed one; absent with an atmospheric crankcase. Part of the motoring torque, beside
    /// the friction.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crankcase_pumping_torque_nm: Option<f64>,
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
    /// Friction mean effective pressure, total and per component (basis: [`RunResult::fmep`]).
    #[serde(default)]
    pub fmep: PlateauFmep,
    /// An engine's totals per component (`main_*`, `big_end_*`, ...) and per cylinder; empty
    /// (and left out of the JSON) for the single-cylinder rig.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<GroupTotal>,
    /// The Sandoval-Heywood correlation for the rig's engine at this plateau's speed and oil
    /// (`tribo_core::correlation`), term by term beside the laws' FMEP.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlation: Option<crate::correlation::Correlation>,
    /// With a drivetrain: the transducer's torque as it was in its shaft and as the data
    /// acquisition recorded it, against its rating, and the crank's speed fluctuation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instrument: Option<Instrument>,
}

/// The measuring chain at one plateau: what the transducer carried over one periodic cycle,
/// what its acquisition recorded, and its rating (`crate::drivetrain`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct Instrument {
    /// The transducer's name.
    pub transducer: String,
    /// Mean shaft torque in the transducer over the cycle (the test cycle: over the plateau's
    /// measurement window), N m.
    pub mean_torque_nm: f64,
    /// Smallest shaft torque, N m.
    pub min_torque_nm: f64,
    /// Largest shaft torque, N m.
    pub max_torque_nm: f64,
    /// Largest minus smallest, N m.
    pub peak_to_peak_nm: f64,
    /// The mean of the acquired record (filtered, sampled, clipped to the input range), N m:
    /// what the rig's data report as the measured torque.
    pub acquired_mean_torque_nm: f64,
    /// Peak-to-peak of the acquired record, N m.
    pub acquired_peak_to_peak_nm: f64,
    /// Share of the record's samples clipped at the input range.
    pub clipped_share: f64,
    /// The crank's speed fluctuation over the cycle, (max - min) / mean.
    pub crank_speed_fluctuation: f64,
    /// Rated torque, N m.
    pub rated_torque_nm: f64,
    /// Limit torque, N m.
    pub limit_torque_nm: f64,
    /// Permitted oscillation width (peak to peak), N m.
    pub oscillation_width_nm: f64,
    /// Power dissipated in the chain's dampers, W.
    pub chain_dissipation_w: f64,
    /// Cycles integrated until the cycle repeated (steady state); 0 in the test cycle, which
    /// settles, or not, as the bench did.
    pub settling_cycles: u32,
}

impl PlateauResult {
    /// The torque a measurement of this plateau reports: the transducer's acquired mean with
    /// a drivetrain, the crank's mean motoring torque without one.
    pub fn measured_torque_nm(&self) -> f64 {
        self.instrument
            .as_ref()
            .map_or(self.motoring_torque_nm, |i| i.acquired_mean_torque_nm)
    }
}

impl Instrument {
    /// Whether the transducer stayed within its rating: its oscillation within the permitted
    /// width and its torque within the limit torque.
    pub fn within_rating(&self) -> bool {
        self.peak_to_peak_nm <= self.oscillation_width_nm
            && self.max_torque_nm.abs().max(self.min_torque_nm.abs()) <= self.limit_torque_nm
    }

    /// The warning of a plateau at `speed_rpm` whose measurement came from outside the
    /// transducer's rating, naming the figures; `None` within it.
    pub fn rating_warning(&self, speed_rpm: f64) -> Option<String> {
        if self.within_rating() {
            return None;
        }
        let peak = self.max_torque_nm.abs().max(self.min_torque_nm.abs());
        Some(format!(
            "{speed_rpm:.0} rpm: the transducer `{}` is outside its rating: it oscillates {:.2} N m peak to peak (permitted {:.2} N m) and reaches {:.2} N m (limit {:.2} N m, rated {:.2} N m); a measurement at this speed came from outside the instrument's rating",
            self.transducer,
            self.peak_to_peak_nm,
            self.oscillation_width_nm,
            peak,
            self.limit_torque_nm,
            self.rated_torque_nm
        ))
    }
}

/// The friction of a group of an engine's joints: a component over every cylinder
/// (`piston_*`) or one cylinder's joints (`cylinder 2`: big end, small end, piston).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct GroupTotal {
    /// `main_*`, `big_end_*`, `small_end_*`, `piston_*` or `cylinder K`.
    pub group: String,
    /// Mean friction torque at the crank, N m.
    pub friction_torque_nm: f64,
    /// Mean dissipated power, W.
    pub power_w: f64,
}

/// How FMEP is defined for a run: the work per cycle of the rig's engine (`geometry.engine_cycle`)
/// over the displacement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde", rename_all = "kebab-case")]
pub enum FmepBasis {
    /// One cycle per revolution, FMEP = 2 pi T / V_d: a two-stroke engine.
    TwoStroke,
    /// One cycle per two revolutions, FMEP = 4 pi T / V_d: a four-stroke engine, head-less or not.
    #[default]
    FourStroke,
}

impl From<crate::model::EngineCycle> for FmepBasis {
    fn from(c: crate::model::EngineCycle) -> Self {
        match c {
            crate::model::EngineCycle::FourStroke => FmepBasis::FourStroke,
            crate::model::EngineCycle::TwoStroke => FmepBasis::TwoStroke,
        }
    }
}

impl FmepBasis {
    /// The formula, for reports.
    pub fn formula(self) -> &'static str {
        match self {
            FmepBasis::TwoStroke => "FMEP = 2 pi T / V_d (two-stroke engine)",
            FmepBasis::FourStroke => "FMEP = 4 pi T / V_d (four-stroke engine)",
        }
    }
}

/// The run's FMEP definition: basis and swept volume.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct Fmep {
    /// 2-stroke (per revolution) or 4-stroke basis.
    pub basis: FmepBasis,
    /// Displacement (swept volume) V_d = pi / 4 bore^2 stroke, m^3.
    pub displacement_m3: f64,
}

impl Fmep {
    /// Mean effective pressure of a mean crank torque `torque_nm`, kPa.
    pub fn kpa(&self, torque_nm: f64) -> f64 {
        let cycle = match self.basis {
            FmepBasis::TwoStroke => std::f64::consts::TAU,
            FmepBasis::FourStroke => 2.0 * std::f64::consts::TAU,
        };
        if self.displacement_m3 > 0.0 {
            cycle * torque_nm / self.displacement_m3 * 1e-3
        } else {
            0.0
        }
    }
}

/// One plateau's FMEP breakdown, kPa (1 bar = 100 kPa).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct PlateauFmep {
    /// All laws together (from the dissipated power), kPa.
    pub total_kpa: f64,
    /// The motoring torque's mean effective pressure (friction plus any net gas work), kPa.
    pub motoring_kpa: f64,
    /// Per joint (component; the laws on it summed, the mains separately), in joint order.
    pub components: Vec<ComponentFmep>,
}

/// FMEP of one component (joint).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct ComponentFmep {
    /// Joint name.
    pub joint: String,
    /// Its friction mean effective pressure, kPa.
    pub kpa: f64,
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
    /// |residual| over the largest of motor work, energy change, dissipation, gas work and the
    /// mechanism's mechanical energy at the run's speeds (see `EnergyBalance::relative_to`);
    /// zero when all are zero.
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
    /// How the plateaus' FMEP is defined (basis, displacement).
    #[serde(default)]
    pub fmep: Fmep,
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
    /// Accepted steps of a prescribed hold's repeating cycles that were replayed instead of
    /// evaluated (counted in `steps` too; `sim/replay.rs`). Not in the JSON, as above.
    #[serde(skip)]
    pub replayed_steps: u64,
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
    /// Estimated seconds in the law: calls times the mean time of the sampled calls (one in 256
    /// timed, the last 512 kept, the slowest 5% dropped, the clock's own cost subtracted).
    pub seconds: f64,
}
