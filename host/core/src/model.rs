//! The rig model as plain data: geometry, bodies, joints with their laws, oil, drive, cycle,
//! measurement and solver settings. This is what the solver consumes; reading it from files,
//! `extends`, `--set` overrides and validation live in the configuration layer (`tribo-config`).
//! The types derive serde (through the plugin contract's re-export) so a file or a program can
//! describe a rig the same way.

use tribo_plugin_api::serde::{Deserialize, Serialize};
use tribo_plugin_api::toml;
use tribo_plugin_api::BearingType;

use crate::cycle::{thesis_cycle, Segment};
use crate::oil::ViscosityModel;

/// A rig file as written. Every table rejects unknown keys.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct RigFile {
    /// Rig name, used in reports.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// The engine's top speed, rpm (its maximum operating speed or rev limit): test cycles,
    /// sweeps and measured data above it are refused. Absent: only the general limit applies.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_speed_rpm: Option<f64>,
    /// Crank radius, bore, gravity.
    pub geometry: Geometry,
    /// Crank, rod and piston.
    pub bodies: Bodies,
    /// The five joints and the laws on them.
    pub joints: Joints,
    /// Oil properties and temperatures.
    pub oil: Oil,
    /// How the crank is driven.
    pub drive: Drive,
    /// The test cycle (default: the thesis cycle).
    #[serde(default)]
    pub cycle: CycleSpec,
    /// How plateau values are measured.
    #[serde(default)]
    pub measurement: Measurement,
    /// Numerical settings.
    #[serde(default)]
    pub solver: SolverSettings,
    /// Gas pressures on the piston: cylinder above, crankcase below (default: none, the
    /// thesis's head-less rig with an atmospheric crankcase).
    #[serde(default)]
    pub gas: GasSpec,
    /// A multi-cylinder engine (`docs/engines.md`); absent: the single-cylinder rig.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub engine: Option<EngineSpec>,
    /// The torsional chain from the drive motor to the crank, with its torque transducer
    /// (`crate::drivetrain`); absent: the drive acts on a rigid crank.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drivetrain: Option<crate::drivetrain::DrivetrainSpec>,
    /// Another rig name whose measurements (`# rig:` in a data file) apply to this rig too: a
    /// rig modelling the same engine on the same bench in more detail (the thesis's test bed
    /// with its drivetrain measures what `crf250r-motored` idealises).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measured_as: Option<String>,
}

/// A multi-cylinder crank train: throws, main bearings, cylinders, rods and firing order
/// (`docs/engines.md`). The rig's `[bodies.crank]` is the crank's balanced part, `[bodies.rod]`
/// and `[bodies.piston]` every cylinder's unless a rod says otherwise, and `[joints.big_end]`,
/// `[joints.small_end]`, `[joints.piston]` every cylinder's joint geometry and laws.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct EngineSpec {
    /// Cylinder numbers (1-based) in firing order: a permutation of 1..n.
    pub firing_order: Vec<usize>,
    /// A V engine's included angle, degrees, in [0, 180]; its cylinders then name their
    /// `bank` (`left` at -V/2, `right` at +V/2) instead of a `bank_deg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v_angle_deg: Option<f64>,
    /// What every main bearing is, unless a main says otherwise (`bearing = "plain" |
    /// "rolling"`); unspecified when neither says.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub main_bearing: Option<Bearing>,
    /// Main bearings in axial order.
    pub mains: Vec<MainSpec>,
    /// Crank throws.
    pub throws: Vec<ThrowSpec>,
    /// Cylinders; cylinder k is the k-th entry.
    pub cylinders: Vec<CylinderSpec>,
    /// One rod per cylinder.
    pub rods: Vec<RodSpec>,
    /// An elastic crankshaft (its throws, flywheel, front pulley and damper as torsional
    /// nodes); absent: the crank is rigid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crankshaft: Option<crate::drivetrain::CrankshaftSpec>,
    /// Laws per engine joint (`main_2`, `piston_3`, ...): what a law set attaches. A cylinder
    /// joint not listed takes the laws of its `[joints.*]` table.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub laws: std::collections::BTreeMap<String, Vec<LawRef>>,
}

/// A main bearing of an engine.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct MainSpec {
    /// Position along the crank axis, m (strictly increasing from main to main).
    pub axial_position_m: f64,
    /// Journal radius, m.
    pub radius_m: f64,
    /// Bearing length, m.
    pub length_m: f64,
    /// What this main bearing is (overrides `[engine] main_bearing`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bearing: Option<Bearing>,
}

/// A crank throw (pin and its two webs).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct ThrowSpec {
    /// Pin angle added to the crank angle, degrees, in the direction of rotation.
    pub angle_deg: f64,
    /// Position along the crank axis, m: strictly between the first and last main.
    pub axial_position_m: f64,
    /// Counterweights, one per web (at most two).
    #[serde(default)]
    pub counterweights: Vec<CounterweightSpec>,
}

/// A web's counterweight as a point mass.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct CounterweightSpec {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Radius of its centre of mass, m.
    pub radius_m: f64,
    /// Angle from the throw's pin, degrees (180: opposite).
    #[serde(default = "deg180")]
    pub angle_deg: f64,
}

/// Which bank of a V engine a cylinder is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(rename_all = "lowercase")]
pub enum Bank {
    /// At -V/2 from the vertical.
    Left,
    /// At +V/2.
    Right,
}

/// A cylinder of an engine.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct CylinderSpec {
    /// The throw its rod runs on (1-based).
    pub throw: usize,
    /// Cylinder axis from the vertical, degrees, in the direction of rotation (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bank_deg: Option<f64>,
    /// The bank of a V engine (`engine.v_angle_deg`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bank: Option<Bank>,
    /// Piston-pin offset from the bore axis, m.
    #[serde(default)]
    pub pin_offset_m: f64,
    /// Bore axis offset from the crank centre, m.
    #[serde(default)]
    pub crank_offset_m: f64,
}

impl CylinderSpec {
    /// The bank angle, degrees, given the engine's V angle.
    pub fn bank_angle_deg(&self, v_angle_deg: Option<f64>) -> f64 {
        match (self.bank, v_angle_deg) {
            (Some(Bank::Left), Some(v)) => -0.5 * v,
            (Some(Bank::Right), Some(v)) => 0.5 * v,
            _ => self.bank_deg.unwrap_or(0.0),
        }
    }
}

/// A connecting rod of an engine: its cylinder, and anything that differs from `[bodies.rod]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct RodSpec {
    /// The cylinder (1-based).
    pub cylinder: usize,
    /// Mass, kg (default `[bodies.rod]`'s, scaled).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_kg: Option<f64>,
    /// In-plane moment of inertia, kg m^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertia_kg_m2: Option<f64>,
    /// Length between pin centres, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_m: Option<f64>,
    /// Centre of mass from the big-end centre, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub com_from_big_end_m: Option<f64>,
    /// What this rod's big end is (overrides `[joints.big_end] bearing`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub big_end_bearing: Option<Bearing>,
    /// What this rod's small end is (overrides `[joints.small_end] bearing`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub small_end_bearing: Option<Bearing>,
}

/// The joint groups of law sets: `main_*`, `big_end_*`, `small_end_*`, `piston_*`.
pub const JOINT_KINDS: [&str; 4] = ["main", "big_end", "small_end", "piston"];

impl EngineSpec {
    /// The engine's joint names in order: `main_1..main_n`, then per cylinder `big_end_k`,
    /// `small_end_k`, `piston_k`.
    pub fn joint_names(&self) -> Vec<String> {
        let mut names: Vec<String> = (1..=self.mains.len())
            .map(|i| format!("main_{i}"))
            .collect();
        for k in 1..=self.cylinders.len() {
            for kind in &JOINT_KINDS[1..] {
                names.push(format!("{kind}_{k}"));
            }
        }
        names
    }
}

impl RigFile {
    /// The rig's joint names in report order: [`JOINT_NAMES`] on the single-cylinder rig, an
    /// engine's [`EngineSpec::joint_names`].
    pub fn joint_names(&self) -> Vec<String> {
        match &self.engine {
            Some(e) => e.joint_names(),
            None => JOINT_NAMES.iter().map(|s| s.to_string()).collect(),
        }
    }

    /// The bearing type the rig declares for joint `name` (a name of
    /// [`RigFile::joint_names`]): every piston is a slide; a main, big end or small end is
    /// what its own entry says (an engine's `[[engine.mains]]` or `[[engine.rods]]` entry),
    /// else what its kind says (`[engine] main_bearing`, `[joints.big_end]`,
    /// `[joints.small_end]`), else unspecified. An unknown name is unspecified.
    pub fn bearing_type(&self, name: &str) -> BearingType {
        let declared =
            |b: Option<Bearing>| b.map_or(BearingType::Unspecified, Bearing::bearing_type);
        let numbered = |kind: &str| -> Option<usize> {
            name.strip_prefix(kind)?
                .strip_prefix('_')?
                .parse::<usize>()
                .ok()?
                .checked_sub(1)
        };
        if name.starts_with("piston") {
            return BearingType::Slide;
        }
        let Some(e) = &self.engine else {
            return self
                .joints
                .named()
                .into_iter()
                .find(|(n, _)| *n == name)
                .map_or(BearingType::Unspecified, |(_, j)| declared(j.bearing));
        };
        let rod = |k: usize| e.rods.iter().find(|r| r.cylinder == k + 1);
        let cylinder = |kind: &str| numbered(kind).filter(|k| *k < e.cylinders.len());
        if let Some(i) = numbered("main") {
            e.mains.get(i).map_or(BearingType::Unspecified, |m| {
                declared(m.bearing.or(e.main_bearing))
            })
        } else if let Some(k) = cylinder("big_end") {
            declared(
                rod(k)
                    .and_then(|r| r.big_end_bearing)
                    .or(self.joints.big_end.bearing),
            )
        } else if let Some(k) = cylinder("small_end") {
            declared(
                rod(k)
                    .and_then(|r| r.small_end_bearing)
                    .or(self.joints.small_end.bearing),
            )
        } else {
            BearingType::Unspecified
        }
    }
}

/// What a joint's bearing is, as a rig file says it (`bearing = "plain"` or `"rolling"`); the
/// piston is always a slide and says nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(rename_all = "lowercase")]
pub enum Bearing {
    /// A plain (hydrodynamic journal) bearing: shells or a bush on an oil film.
    Plain,
    /// A rolling-element bearing: balls, rollers or needles.
    Rolling,
}

impl Bearing {
    /// The contract's bearing type (what a law is handed in `LawInput::bearing_type`).
    pub fn bearing_type(self) -> BearingType {
        match self {
            Bearing::Plain => BearingType::Plain,
            Bearing::Rolling => BearingType::Rolling,
        }
    }
}

/// The joints a law-set entry's `joint` names on a rig: a joint, a group (`piston_*`), or on an
/// engine rig a single-cylinder name meaning every cylinder's (`big_end`). Empty if none.
/// `main_a`/`main_b` on an engine and numbered names beyond the rig's count match nothing.
pub fn expand_joint(pattern: &str, rig: &RigFile) -> Vec<String> {
    let kind_of = |name: &str| -> Option<(&'static str, Option<usize>)> {
        JOINT_KINDS.iter().find_map(|k| {
            let rest = name.strip_prefix(k)?;
            if rest.is_empty() {
                return Some((*k, None));
            }
            let n = rest.strip_prefix('_')?;
            if n == "*" {
                Some((*k, Some(0)))
            } else {
                n.parse::<usize>()
                    .ok()
                    .filter(|n| *n >= 1)
                    .map(|n| (*k, Some(n)))
            }
        })
    };
    match &rig.engine {
        None => {
            if JOINT_NAMES.contains(&pattern) {
                return vec![pattern.to_string()];
            }
            match kind_of(pattern) {
                Some(("main", Some(0))) => vec!["main_a".into(), "main_b".into()],
                Some(("main", Some(1))) => vec!["main_a".into()],
                Some(("main", Some(2))) => vec!["main_b".into()],
                Some((k, Some(0 | 1))) if k != "main" => vec![k.to_string()],
                _ => Vec::new(),
            }
        }
        Some(e) => {
            let names = e.joint_names();
            match kind_of(pattern) {
                Some((k, None)) if k != "main" => names
                    .into_iter()
                    .filter(|n| kind_of(n).is_some_and(|(nk, _)| nk == k))
                    .collect(),
                Some((k, Some(0))) => names
                    .into_iter()
                    .filter(|n| kind_of(n).is_some_and(|(nk, _)| nk == k))
                    .collect(),
                Some(_) if names.iter().any(|n| n == pattern) => vec![pattern.to_string()],
                _ => Vec::new(),
            }
        }
    }
}

/// Standard atmospheric pressure, Pa.
pub const ATMOSPHERE_PA: f64 = 101_325.0;

/// Standard gravity, m/s^2: the acceleration a rig's bodies feel when its `gravity` is on. Here
/// with the model rather than the solver so the crank-train models read it without importing
/// the solver that uses them.
pub const GRAVITY_M_S2: f64 = 9.80665;

fn atmosphere() -> f64 {
    ATMOSPHERE_PA
}

/// Gas pressures acting on the piston (`crate::gas` states the models).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct GasSpec {
    /// Pressure on the piston crown.
    #[serde(default)]
    pub cylinder: CylinderPressure,
    /// Pressure under the piston.
    #[serde(default)]
    pub crankcase: CrankcasePressure,
    /// Ambient pressure, Pa: on the crown of a head-less rig and the crankcase's reference.
    #[serde(default = "atmosphere")]
    pub ambient_pa: f64,
    /// Where the rig's crank angle 0 (a top dead centre) sits in the 4-stroke cycle, degrees:
    /// 0 = the gas-exchange TDC (start of intake), 360 = the firing (compression) TDC.
    #[serde(default)]
    pub cycle_angle_at_zero_deg: f64,
}

/// The pressure on the piston crown.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum CylinderPressure {
    /// No head: the crown sees the ambient pressure (the thesis rig).
    #[default]
    None,
    /// Head on, motored: polytropic compression and expansion of the trapped charge.
    Motored {
        /// Geometric compression ratio (cylinder volume at BDC over that at TDC), > 1.
        compression_ratio: f64,
        /// Polytropic exponent (1.4: adiabatic air, no heat loss).
        #[serde(default = "kappa")]
        polytropic_exponent: f64,
        /// Pressure of the charge at BDC (intake pressure), Pa.
        #[serde(default = "atmosphere")]
        intake_pressure_pa: f64,
        /// `closed` (the cylinder never opens: every revolution the same) or `four-stroke`
        /// (ideal valves at the dead centres: intake and exhaust strokes at the intake pressure).
        #[serde(default)]
        valves: Valves,
    },
    /// A pressure-vs-crank-angle trace over the 720-degree cycle, linearly interpolated.
    Trace {
        /// CSV file (`crank_angle_deg,pressure_pa`; 4-stroke angle from the gas-exchange TDC)
        /// read by the configuration layer into `crank_angle_deg`/`pressure_pa`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        file: Option<String>,
        /// Where the trace comes from (measurement, synthetic model and its numbers).
        #[serde(default)]
        source: Option<String>,
        /// Cycle angles, degrees, rising, within [0, 720).
        #[serde(default)]
        crank_angle_deg: Vec<f64>,
        /// Absolute cylinder pressure at each angle, Pa.
        #[serde(default)]
        pressure_pa: Vec<f64>,
    },
}

fn kappa() -> f64 {
    1.4
}

/// Valve events of the motored cylinder.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(rename_all = "kebab-case")]
pub enum Valves {
    /// Closed cylinder: compression and expansion every revolution (a 2-stroke-like cycle).
    #[default]
    Closed,
    /// Ideal 4-stroke valves at the dead centres.
    FourStroke,
}

/// The pressure under the piston.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum CrankcasePressure {
    /// Open to the ambient (default).
    #[default]
    Atmospheric,
    /// A sealed volume pumped by the piston underside, polytropic, no breather flow.
    Sealed {
        /// Crankcase volume with the piston at TDC, m^3 (must exceed the displacement).
        volume_at_tdc_m3: f64,
        /// Polytropic exponent (1.4: adiabatic, reversible).
        #[serde(default = "kappa")]
        polytropic_exponent: f64,
        /// Crankcase pressure with the piston at TDC, Pa (default: ambient).
        #[serde(default = "atmosphere")]
        pressure_at_tdc_pa: f64,
    },
    /// A crankcase volume pumped by the piston underside, polytropic, breathing to the ambient
    /// through an orifice (compressible nozzle flow); its pressure is the periodic steady
    /// solution at the crank speed (`crate::gas` states the model and its assumptions).
    Vented {
        /// Crankcase volume with the piston at TDC, m^3 (must exceed the displacement).
        volume_at_tdc_m3: f64,
        /// Polytropic exponent of the trapped gas (1.4: adiabatic; 1: isothermal).
        #[serde(default = "kappa")]
        polytropic_exponent: f64,
        /// Inner diameter of the breather orifice, m (give this or `breather_area_m2`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        breather_diameter_m: Option<f64>,
        /// Flow area of the breather orifice, m^2 (give this or `breather_diameter_m`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        breather_area_m2: Option<f64>,
        /// Discharge coefficient of the breather, in (0, 1]: the real mass flow over that of
        /// the ideal isentropic nozzle of the same area.
        discharge_coefficient: f64,
        /// Temperature of the crankcase gas at the ambient pressure, C (the polytrope passes
        /// through it; air breathed in arrives at it).
        #[serde(default = "room_c")]
        temperature_c: f64,
    },
}

/// Standard room temperature, C: the default crankcase gas temperature.
pub const ROOM_C: f64 = 20.0;

fn room_c() -> f64 {
    ROOM_C
}

impl CrankcasePressure {
    /// The breather's flow area, m^2, of a vented crankcase (from its diameter or its area;
    /// `None` for other kinds or when neither is given).
    pub fn breather_area_m2(&self) -> Option<f64> {
        match self {
            CrankcasePressure::Vented {
                breather_area_m2: Some(a),
                ..
            } => Some(*a),
            CrankcasePressure::Vented {
                breather_diameter_m: Some(d),
                ..
            } => Some(std::f64::consts::PI * 0.25 * d * d),
            _ => None,
        }
    }
}

impl Default for GasSpec {
    fn default() -> Self {
        Self {
            cylinder: CylinderPressure::None,
            crankcase: CrankcasePressure::Atmospheric,
            ambient_pa: ATMOSPHERE_PA,
            cycle_angle_at_zero_deg: 0.0,
        }
    }
}

impl GasSpec {
    /// Whether the rig has no gas load at all (the thesis rig): no head, open crankcase.
    pub fn is_none(&self) -> bool {
        matches!(self.cylinder, CylinderPressure::None)
            && matches!(self.crankcase, CrankcasePressure::Atmospheric)
    }

    /// The trace's CSV file name, if the cylinder pressure is a trace read from a file.
    pub fn cylinder_file(&self) -> Option<&str> {
        match &self.cylinder {
            CylinderPressure::Trace { file, .. } => file.as_deref(),
            _ => None,
        }
    }

    /// Whether the pressure repeats only every second revolution (a 4-stroke cycle).
    pub fn four_stroke(&self) -> bool {
        matches!(
            self.cylinder,
            CylinderPressure::Motored {
                valves: Valves::FourStroke,
                ..
            } | CylinderPressure::Trace { .. }
        )
    }
}

/// Geometry of the crank train.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    /// Crank radius (half the stroke), m.
    pub crank_radius_m: f64,
    /// Cylinder bore, m.
    pub bore_m: f64,
    /// Include gravity (9.81 m/s^2 along -y, the cylinder axis pointing up).
    #[serde(default = "yes")]
    pub gravity: bool,
    /// The engine's working cycle, which defines FMEP (work per cycle over the displacement):
    /// `four-stroke` (the default, and every bundled rig, head or no head) or `two-stroke`.
    #[serde(default)]
    pub engine_cycle: EngineCycle,
}

/// The working cycle of the engine a rig stands for. It sets the FMEP basis only: a head-less
/// motored four-stroke still repeats every revolution, but engine literature and every friction
/// correlation quote its FMEP per four-stroke cycle, 4 pi T / V_d.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde", rename_all = "kebab-case")]
pub enum EngineCycle {
    /// One cycle per two revolutions: FMEP = 4 pi T / V_d.
    #[default]
    FourStroke,
    /// One cycle per revolution: FMEP = 2 pi T / V_d.
    TwoStroke,
}

fn yes() -> bool {
    true
}
fn one() -> f64 {
    1.0
}
fn half() -> f64 {
    0.5
}
fn deg180() -> f64 {
    180.0
}

/// The three moving bodies.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Bodies {
    /// Crankshaft.
    pub crank: Crank,
    /// Connecting rod.
    pub rod: Rod,
    /// Piston assembly.
    pub piston: Piston,
}

/// Crankshaft.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Crank {
    /// Moment of inertia about the crank axis, without the unbalance mass, kg m^2.
    pub inertia_kg_m2: f64,
    /// Mass of the balanced part (centre of mass on the axis), kg; loads the mains under gravity.
    pub mass_kg: f64,
    /// Unbalance (counterweight) mass, kg.
    #[serde(default)]
    pub unbalance_mass_kg: f64,
    /// Radius of the unbalance mass, m.
    #[serde(default)]
    pub unbalance_radius_m: f64,
    /// Angle of the unbalance mass from the crank pin, degrees (180: opposite the pin).
    #[serde(default = "deg180")]
    pub unbalance_angle_deg: f64,
    /// Mass scale factor.
    #[serde(default = "one")]
    pub mass_scale: f64,
    /// Inertia scale factor.
    #[serde(default = "one")]
    pub inertia_scale: f64,
}

/// Connecting rod.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Rod {
    /// Mass, kg.
    pub mass_kg: f64,
    /// In-plane moment of inertia about the centre of mass, kg m^2.
    pub inertia_kg_m2: f64,
    /// Centre-to-centre length, m.
    pub length_m: f64,
    /// Centre-of-mass distance from the big-end centre, m.
    pub com_from_big_end_m: f64,
    /// Mass scale factor (FEDEM-style mass scaling, the lighter-rod study).
    #[serde(default = "one")]
    pub mass_scale: f64,
    /// Inertia scale factor.
    #[serde(default = "one")]
    pub inertia_scale: f64,
}

/// Piston assembly.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Piston {
    /// Mass of piston, rings, pin and clips, kg.
    pub mass_kg: f64,
    /// Mass scale factor.
    #[serde(default = "one")]
    pub mass_scale: f64,
}

/// The joints of the rig. There is no other joint: an unknown name is an error.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Joints {
    /// First main bearing (crank to block). Absent in an engine rig (its mains are
    /// `[[engine.mains]]`); a single-cylinder rig must give it (validation says so).
    #[serde(default = "Joint::absent", skip_serializing_if = "Joint::is_absent")]
    pub main_a: Joint,
    /// Second main bearing (see `main_a`).
    #[serde(default = "Joint::absent", skip_serializing_if = "Joint::is_absent")]
    pub main_b: Joint,
    /// Big end (crank pin to rod).
    pub big_end: Joint,
    /// Small end (rod to piston pin).
    pub small_end: Joint,
    /// Piston-cylinder slide.
    pub piston: Joint,
}

/// Names of the joints, in report order.
pub const JOINT_NAMES: [&str; 5] = ["main_a", "main_b", "big_end", "small_end", "piston"];

impl Joints {
    /// Joints with their names, in [`JOINT_NAMES`] order.
    pub fn named(&self) -> [(&'static str, &Joint); 5] {
        [
            ("main_a", &self.main_a),
            ("main_b", &self.main_b),
            ("big_end", &self.big_end),
            ("small_end", &self.small_end),
            ("piston", &self.piston),
        ]
    }

    /// Mutable access by name.
    pub fn get_mut(&mut self, name: &str) -> Option<&mut Joint> {
        match name {
            "main_a" => Some(&mut self.main_a),
            "main_b" => Some(&mut self.main_b),
            "big_end" => Some(&mut self.big_end),
            "small_end" => Some(&mut self.small_end),
            "piston" => Some(&mut self.piston),
            _ => None,
        }
    }
}

/// One joint: contact geometry and the laws acting on it.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Joint {
    /// Contact radius, m (journal/pin radius; half the bore for the piston).
    pub radius_m: f64,
    /// Contact length, m.
    pub length_m: f64,
    /// Share of the crank's main-bearing reaction this bearing carries (mains only).
    #[serde(default = "half")]
    pub load_share: f64,
    /// What the bearing is (`"plain"` or `"rolling"`; mains, big end and small end, never the
    /// piston); unspecified when absent. On an engine `[joints.big_end]` and
    /// `[joints.small_end]` say it for every cylinder.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bearing: Option<Bearing>,
    /// Friction and damping laws, summed.
    #[serde(default)]
    pub laws: Vec<LawRef>,
}

impl Joint {
    /// A main bearing the file does not give (an engine rig's `main_a`, `main_b`): no size.
    pub fn absent() -> Joint {
        Joint {
            radius_m: f64::NAN,
            length_m: f64::NAN,
            load_share: 0.5,
            bearing: None,
            laws: Vec::new(),
        }
    }

    /// Whether this is [`Joint::absent`] (not written in the file).
    pub fn is_absent(&self) -> bool {
        self.radius_m.is_nan()
            && self.length_m.is_nan()
            && self.laws.is_empty()
            && self.bearing.is_none()
    }
}

/// A law attached to a joint.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct LawRef {
    /// Law name as listed by `tribo laws`.
    pub law: String,
    /// Parameters (defaults for anything left out).
    #[serde(default)]
    pub params: toml::Table,
}

/// Oil.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Oil {
    /// What the oil is, e.g. "SAE 10W-50 motorcycle oil, typical" (shown in reports, so a
    /// result says which oil produced it). Descriptive only. A rig (or `--set`) that replaces
    /// `viscosity` without naming the oil drops the inherited name, grade and source.
    #[serde(default)]
    pub name: Option<String>,
    /// SAE viscosity grade, e.g. "10W-50". Descriptive only.
    #[serde(default)]
    pub grade: Option<String>,
    /// Where the viscosity data come from (datasheet, estimate and why). Descriptive only.
    #[serde(default)]
    pub source: Option<String>,
    /// Viscosity model.
    pub viscosity: ViscosityModel,
    /// Density, kg/m^3.
    pub density_kg_m3: f64,
    /// Oil temperature, C: one value, or one per plateau.
    pub temperature_c: Temperature,
}

impl Oil {
    /// The oil's name and grade for a report line, or a note that it has none.
    pub fn title(&self) -> String {
        match (&self.name, &self.grade) {
            (Some(n), Some(g)) => format!("{n}; grade SAE {g}"),
            (Some(n), None) => n.clone(),
            (None, Some(g)) => format!("SAE {g} oil"),
            (None, None) => "unnamed oil".into(),
        }
    }

    /// One line naming the oil, its viscosity model with constants, and the source.
    pub fn describe(&self) -> String {
        let mut s = format!("{}; {}", self.title(), self.viscosity.describe());
        if let Some(src) = &self.source {
            s.push_str("; source: ");
            s.push_str(src);
        }
        s
    }
}

/// One oil temperature for the whole run, or one per plateau.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(untagged)]
pub enum Temperature {
    /// Same temperature at every plateau.
    Constant(f64),
    /// One temperature per plateau, in order.
    PerPlateau(Vec<f64>),
}

/// Crank drive.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Drive {
    /// The crank follows the reference speed exactly; the motoring torque is the constraint torque.
    /// Written with braces (no fields) so that a PI setting given with it (`kp`,
    /// `torque_limit_nm`, ...) is refused as an unknown field, not silently dropped (serde ignores
    /// extra keys on a unit variant of an internally tagged enum).
    Prescribed {},
    /// A PI speed controller applies a limited torque through an optional belt.
    Pi {
        /// Proportional gain, N m per rad/s of crank-speed error.
        #[serde(default = "kp_default")]
        kp: f64,
        /// Integral gain, N m per rad of accumulated crank-angle error.
        #[serde(default = "ki_default")]
        ki: f64,
        /// Motor torque limit, N m (at the motor).
        #[serde(default = "limit_default")]
        torque_limit_nm: f64,
        /// Motor speed / crank speed.
        #[serde(default = "one")]
        belt_ratio: f64,
        /// Motor rotor inertia, kg m^2.
        #[serde(default)]
        motor_inertia_kg_m2: f64,
    },
}

impl Drive {
    /// The drive's rotor inertia as the crank feels it, kg m^2: the PI drive's motor inertia
    /// times the belt ratio squared; none for a prescribed crank.
    pub fn reflected_inertia_kg_m2(&self) -> f64 {
        match *self {
            Drive::Pi {
                belt_ratio,
                motor_inertia_kg_m2,
                ..
            } => motor_inertia_kg_m2 * belt_ratio * belt_ratio,
            Drive::Prescribed {} => 0.0,
        }
    }
}

// Default PI gains: the speed error decays at kp / (2 J) ~ 22 1/s on the CRF 250 R rig
// (J ~ 0.0046 kg m^2) with damping ratio ~ 0.8, so a 1 s hold settles to ~1e-9 of its initial
// error, while the proportional reaction to the once-per-revolution speed ripple stays under
// the torque limit up to 9000 rpm (a saturating P-term would bias the mean speed).
fn kp_default() -> f64 {
    0.2
}
fn ki_default() -> f64 {
    8.0
}
// [T table 9.2] electric motor torque limit.
fn limit_default() -> f64 {
    5.0
}

/// The test cycle.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct CycleSpec {
    /// Ramps and holds; absent means the thesis cycle.
    pub segments: Option<Vec<Segment>>,
}

impl CycleSpec {
    /// The segments to run.
    pub fn segments(&self) -> Vec<Segment> {
        self.segments.clone().unwrap_or_else(thesis_cycle)
    }
}

/// Plateau measurement.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct Measurement {
    /// Length of the averaging window at the end of each hold, s (thesis 10.4: 0.1 s); the
    /// whole crank revolutions that fit in it are used.
    #[serde(default = "window")]
    pub window_s: f64,
    /// Cut-off of the first-order low-pass filter on the motoring torque time series, Hz.
    #[serde(default = "lowpass")]
    pub lowpass_hz: f64,
}

fn window() -> f64 {
    0.1
}
fn lowpass() -> f64 {
    20.0
}

impl Default for Measurement {
    fn default() -> Self {
        Self {
            window_s: window(),
            lowpass_hz: lowpass(),
        }
    }
}

/// Numerical settings; the defaults hold for every speed (no per-speed step table). Written
/// out (an FMU's rig, a model handed to Python) with only the settings that differ from their
/// defaults: a setting written is one given, which a run that cannot use it refuses
/// (`docs/solver.md`, "Settings used or refused"), so a rig written back must not give them all.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(deny_unknown_fields)]
pub struct SolverSettings {
    /// Crank-angle step, degrees.
    #[serde(default = "step_deg", skip_serializing_if = "is_step_deg")]
    pub step_deg: f64,
    /// Largest time step, s (governs the start of the run when the crank is slow).
    #[serde(default = "max_step", skip_serializing_if = "is_max_step")]
    pub max_step_s: f64,
    /// Relative tolerance on joint normal loads in the friction/reaction iteration.
    #[serde(default = "friction_tol", skip_serializing_if = "is_friction_tol")]
    pub friction_tol: f64,
    /// Iteration limit of the friction/reaction iteration.
    #[serde(default = "friction_iter", skip_serializing_if = "is_friction_iter")]
    pub friction_max_iter: u32,
    /// Time integrator of a torque-driven (PI) crank; a prescribed crank is a quadrature
    /// (`quadrature`), so this given with it is refused (`sim::RUN_DEPENDENT_SETTINGS`).
    #[serde(default, skip_serializing_if = "is_default")]
    pub integrator: Integrator,
    /// Relative error allowed per unit time by the adaptive integrator.
    #[serde(default = "rel_tol", skip_serializing_if = "is_rel_tol")]
    pub rel_tol: f64,
    /// Largest crank-angle step of the adaptive integrator, degrees; absent: the default for
    /// the rig's crank train ([`SolverSettings::max_step_deg`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_step_deg: Option<f64>,
    /// Step-size controller of the adaptive integrator.
    #[serde(default, skip_serializing_if = "is_default")]
    pub step_control: StepControl,
    /// Quadrature of a prescribed crank with stateless laws.
    #[serde(default, skip_serializing_if = "is_default")]
    pub quadrature: QuadratureRule,
}

/// How a prescribed crank's rates are integrated (the motion is known, so only quadrature is
/// left). Law sets with a stateful law get `Simpson`: their state is advanced once per step
/// with the step's length, which must then not vary (`Lobatto` given with one is refused).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(rename_all = "kebab-case")]
pub enum QuadratureRule {
    /// Simpson's rule at `step_deg` where the result is measured (the plateaus' windows) and
    /// where it repeats (a hold's replayed cycles), Gauss-Lobatto as `Lobatto` elsewhere (the
    /// ramps): the plateaus of `Simpson` at the cost of fewer evaluations. With a stateful law
    /// or a cylinder pressure trace (a kink at every sample, where Lobatto's steps cost more
    /// than Simpson's), `Simpson` throughout.
    #[default]
    Auto,
    /// Simpson's rule at the fixed crank-angle step `step_deg`: two evaluations per step, the
    /// samples at fixed angles.
    Simpson,
    /// Error-controlled Gauss-Lobatto quadrature (5 nodes, degree 7, the embedded Simpson rule
    /// as error estimate) against `rel_tol`, up to `max_step_deg`, steps ending on the
    /// friction reversals and side-thrust sign changes.
    Lobatto,
}

/// How the adaptive integrator chooses its next step from the error estimates.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(rename_all = "kebab-case")]
pub enum StepControl {
    /// Integral (elementary) control: the next step from this step's error alone.
    Integral,
    /// Proportional-integral control (Gustafsson): this step's error and the previous
    /// accepted one's, which damps the step-size oscillation of the integral controller.
    #[default]
    Pi,
}

/// How a torque-driven crank is integrated.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(rename_all = "kebab-case")]
pub enum Integrator {
    /// Dormand-Prince 5(4) with error control: the step follows the dynamics within `rel_tol`,
    /// up to `max_step_deg`. Law sets with a stateful law use `rk4` instead: their state is
    /// advanced once per step with the step's length, so it must not vary (`adaptive` given
    /// with one is refused).
    #[default]
    Adaptive,
    /// Classical RK4 at the fixed crank-angle step `step_deg`.
    Rk4,
}

// 1 degree: halving it changes no plateau torque of the bundled study by more than 1e-5. 2 degrees
// would do for smooth laws, but a calibrated Stribeck law with close thresholds switches within a
// few degrees of stroke, and a fit then exploits the quadrature error (docs/solver.md).
fn step_deg() -> f64 {
    1.0
}
fn max_step() -> f64 {
    1e-3
}
// 1e-7: on the bundled study (prescribed drive, thesis cycle) the plateau torques differ from
// those at 1e-10 by at most 6e-7 relative (stribeck-duty; fedem-baseline 5e-8), far below the
// 1-degree integration error (~8e-6); 1e-8 costs ~12% more law calls for 2e-8.
fn friction_tol() -> f64 {
    1e-7
}
fn friction_iter() -> u32 {
    50
}
// 1e-6: on the thesis cycle with the fedem-baseline set the PI run's plateau torques are then
// within 8e-6 of fixed-step RK4 at 0.25 degrees (RK4 at the 1-degree default: 4e-6) with 1/25 of
// its steps; 1e-5 saves a third of the evaluations but leaves a bias of up to 2e-5.
fn rel_tol() -> f64 {
    1e-6
}
// 10 degrees: the torque has strong 2nd and 4th crank orders, so longer steps are rarely
// accepted at 1e-6 anyway (20 degrees changed neither the step count nor the time), and the
// streamed time series keeps at least 36 points per revolution.
const MAX_STEP_DEG_RIG: f64 = 10.0;
// 3 degrees on engines: at speed the longest step is what limits the Dormand-Prince pair's
// truncation error, which the PI drive pays for as motor work the train's energy does not show.
// Frictionless inline-4 fixture, thesis cycle, PI drive: energy residual 2.3e-7 of the motor work
// at 10 degrees, 1.4e-7 at 6, 6.9e-8 at 5, 2.3e-8 at 4, 5.5e-9 at 3 (V-twin: 5.9e-8, 1.8e-8,
// 3.5e-9, 7e-10, 1.7e-10); RK4 at 1 degree: 5.8e-11 with three times the evaluations
// (docs/engines.md).
const MAX_STEP_DEG_ENGINE: f64 = 3.0;

fn is_step_deg(v: &f64) -> bool {
    *v == step_deg()
}
fn is_max_step(v: &f64) -> bool {
    *v == max_step()
}
fn is_friction_tol(v: &f64) -> bool {
    *v == friction_tol()
}
fn is_friction_iter(v: &u32) -> bool {
    *v == friction_iter()
}
fn is_rel_tol(v: &f64) -> bool {
    *v == rel_tol()
}
fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}

impl SolverSettings {
    /// Largest crank-angle step of the adaptive integrator, degrees: the rig's
    /// `solver.max_step_deg`, or the default for its crank train (`engine`: a multi-cylinder
    /// `[engine]`).
    pub fn max_step_deg(&self, engine: bool) -> f64 {
        self.max_step_deg.unwrap_or(if engine {
            MAX_STEP_DEG_ENGINE
        } else {
            MAX_STEP_DEG_RIG
        })
    }
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            step_deg: step_deg(),
            max_step_s: max_step(),
            friction_tol: friction_tol(),
            friction_max_iter: friction_iter(),
            integrator: Integrator::default(),
            rel_tol: rel_tol(),
            max_step_deg: None,
            step_control: StepControl::default(),
            quadrature: QuadratureRule::default(),
        }
    }
}
