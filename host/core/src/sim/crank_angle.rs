//! Crank-angle-resolved results: per plateau, the rig at the plateau's speed sampled over one
//! cycle (a revolution, or 720 degrees for a 4-stroke cycle) at a fixed angular resolution:
//! each law's friction torque at the crank, power, normal load, sliding speed, regime and the
//! diagnostics it reports (contract version 3: minimum film, eccentricity, peak pressure,
//! asperity share), the big-end and main-bearing loads and the gas pressures.

use tribo_plugin_api::serde::{Deserialize, Serialize};
use tribo_plugin_api::{LawInput, LawOutput, Regime};

use super::bind::{reset_states, set_load, BoundLaw, Instant};
use super::engine_run::{EngineSimulation, Work as EngineWork};
use super::error::SimError;
use super::evaluate::{crank_angle, joint_bodies, Point};
use super::joint::JointId;
use super::Simulation;
use crate::mechanics::JointLoads;

/// One law at one crank angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct LawSample {
    /// Friction torque at the crank (dissipated power over crank speed), N m.
    pub friction_torque_nm: f64,
    /// Dissipated power, W.
    pub power_w: f64,
    /// The joint's normal load, N.
    pub normal_load_n: f64,
    /// Signed sliding speed at the contact, m/s.
    pub sliding_speed_m_s: f64,
    /// Lubrication regime the law reported.
    pub regime: String,
    /// Minimum oil-film thickness, m, if the law reports it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_film_m: Option<f64>,
    /// Eccentricity ratio, x component in the outer member's frame, if the law reports it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eccentricity_x: Option<f64>,
    /// Eccentricity ratio, y component, if the law reports it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eccentricity_y: Option<f64>,
    /// Peak film pressure, Pa, if the law reports it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_pressure_pa: Option<f64>,
    /// Share of the normal load carried by asperity contact, if the law reports it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub asperity_share: Option<f64>,
}

impl LawSample {
    /// The sample of one law: friction torque and power from the evaluation's rates (`power`
    /// W at crank speed `omega`, its regime `indicators`), normal load and sliding speed from
    /// its loaded `input`, and the diagnostics of `out`, the law at that input.
    fn new(power: f64, omega: f64, indicators: &[f64], input: &LawInput, out: &LawOutput) -> Self {
        let (ex, ey) = out.eccentricity().unzip();
        Self {
            friction_torque_nm: power / omega,
            power_w: power,
            normal_load_n: input.normal_load_n,
            sliding_speed_m_s: input.sliding_velocity_m_s,
            regime: regime_name(indicators).to_string(),
            min_film_m: out.min_film(),
            eccentricity_x: ex,
            eccentricity_y: ey,
            peak_pressure_pa: out.peak_pressure(),
            asperity_share: out.asperity_share(),
        }
    }
}

/// Law `law` at its loaded `input` (on joint `joint` of kind `kind`, the largest reaction
/// `reaction_n`), for the diagnostics of a trace: the output of the same evaluation the run
/// makes, checked the same way (a diagnostic out of its physical range is an error naming law,
/// joint and time).
fn sample_output(
    joint: &str,
    kind: tribo_plugin_api::JointKind,
    law: &BoundLaw,
    input: &LawInput,
    reaction_n: f64,
) -> Result<LawOutput, SimError> {
    let out = law
        .output(input)
        .map_err(|e| super::bind::law_failed_named(joint, input, e))?;
    super::bind::checked_power_named(joint, kind, law, input, &out, reaction_n)?;
    Ok(out)
}

/// The rig at one crank angle of a plateau's cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct AngleSample {
    /// Crank angle from the cycle's start (the rig's angle 0), degrees, [0, 360) or [0, 720).
    pub crank_angle_deg: f64,
    /// One entry per law, in the order of [`CrankAngleTrace::laws`].
    pub laws: Vec<LawSample>,
    /// Force from the crank on the rod at the big end (x, y), N.
    pub big_end_n: [f64; 2],
    /// Force from the ground on the crank at both main bearings together (x, y), N.
    pub main_n: [f64; 2],
    /// Cylinder and crankcase pressure, Pa (ambient for a rig without gas loads).
    pub pressures_pa: [f64; 2],
    /// Drive torque, N m.
    pub drive_torque_nm: f64,
    /// An engine's cylinders, in order (empty on the single-cylinder rig, whose one cylinder
    /// is the fields above; on an engine those are cylinder 1's big end and pressures and the
    /// mains' total).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cylinders: Vec<CylinderSample>,
    /// An engine's main bearings, in axial order: force from the ground on the crank (x, y),
    /// N (empty on the single-cylinder rig).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub mains_n: Vec<[f64; 2]>,
}

/// One cylinder of an engine at one crank angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct CylinderSample {
    /// Force from the crank on the rod at the big end (x, y, global frame), N.
    pub big_end_n: [f64; 2],
    /// Side thrust of the piston on the cylinder wall, across the bore, N.
    pub side_thrust_n: f64,
    /// Cylinder and crankcase pressure, Pa.
    pub pressures_pa: [f64; 2],
}

/// One plateau's cycle, resolved in crank angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct CrankAngleTrace {
    /// The plateau's speed, rpm.
    pub speed_rpm: f64,
    /// Joint and law of each law column.
    pub laws: Vec<(String, String)>,
    /// The samples, rising in crank angle.
    pub samples: Vec<AngleSample>,
}

fn regime_name(indicators: &[f64]) -> &'static str {
    let k = (0..4)
        .max_by(|a, b| indicators[*a].total_cmp(&indicators[*b]))
        .unwrap_or(0);
    match k {
        k if k == Regime::Boundary as usize => "boundary",
        k if k == Regime::Mixed as usize => "mixed",
        k if k == Regime::Hydrodynamic as usize => "hydrodynamic",
        _ => "none",
    }
}

/// The most samples one plateau's trace may hold: a 4-stroke cycle at 0.01 degree. A bound on
/// what a resolution can make a run allocate (at 1e-9 degree it asked for terabytes).
pub const MAX_SAMPLES_PER_CYCLE: usize = 72_000;

/// Samples over a cycle of `cycle_rad` at `resolution_deg`, at least 4 and at most
/// [`MAX_SAMPLES_PER_CYCLE`].
fn samples_per_cycle(cycle_rad: f64, resolution_deg: f64) -> Result<usize, SimError> {
    let n = cycle_rad / resolution_deg.to_radians();
    if n.is_finite() && n > 0.0 && n <= MAX_SAMPLES_PER_CYCLE as f64 + 0.5 {
        return Ok((n.round() as usize).max(4));
    }
    Err(SimError::Setup {
        at: None,
        field: "resolution_deg".into(),
        law: None,
        param: None,
        message: format!(
            "{resolution_deg} degrees makes {n:.3e} samples per cycle; at most {MAX_SAMPLES_PER_CYCLE} are allowed (0.01 degrees over a 4-stroke cycle)"
        ),
    })
}

/// A buffer for `n` samples, allocated fallibly (an error, never an abort).
fn sample_buffer<T>(n: usize) -> Result<Vec<T>, SimError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|e| SimError::Setup {
        at: None,
        field: "resolution_deg".into(),
        law: None,
        param: None,
        message: format!("cannot allocate {n} crank-angle samples: {e}"),
    })?;
    Ok(v)
}

impl Simulation {
    /// Every plateau's cycle at the plateau's speed (constant: the steady state), sampled every
    /// `resolution_deg` degrees. Laws start from zero state; a stateful law runs one cycle
    /// first so the sampled one is settled.
    pub fn crank_angle_traces(
        &mut self,
        resolution_deg: f64,
    ) -> Result<Vec<CrankAngleTrace>, SimError> {
        let cycle = self.cycle_angle();
        let n = samples_per_cycle(cycle, resolution_deg)?;
        let h_angle = cycle / n as f64;
        let laws: Vec<(String, String)> = self
            .joints
            .iter()
            .flat_map(|j| {
                j.laws
                    .iter()
                    .map(move |l| (j.id.name().to_string(), l.name.clone()))
            })
            .collect();
        let mut traces = Vec::new();
        for pi in 0..self.cycle.plateaus().len() {
            let omega = self.cycle.plateaus()[pi].omega;
            let oil = (self.temps[pi], self.viscosities[pi]);
            let h = h_angle / omega;
            reset_states(&mut self.joints);
            let mut guess = JointLoads::default();
            let mut samples = sample_buffer(n)?;
            let passes = if self.stateful { 2 } else { 1 };
            for pass in 0..passes {
                for k in 0..n {
                    let theta = k as f64 * h_angle;
                    let at = Point::steady((pass * n + k) as f64 * h, h, theta, omega, oil);
                    let (e, loads) = self.evaluate(&at, &guess, Vec::new())?;
                    guess = loads;
                    if pass + 1 == passes {
                        // Sampled before the commit: the laws' states are those the
                        // evaluation used.
                        samples.push(self.angle_sample(&at, &e)?);
                    }
                    self.commit(at.t, h, theta, &e, oil)?;
                }
            }
            traces.push(CrankAngleTrace {
                speed_rpm: self.cycle.plateaus()[pi].speed_rpm,
                laws: laws.clone(),
                samples,
            });
        }
        reset_states(&mut self.joints);
        Ok(traces)
    }

    /// The sample at point `at` from its evaluation `e`: each law's rates, and its diagnostics
    /// at the settled loads.
    fn angle_sample(&self, at: &Point, e: &super::evaluate::Eval) -> Result<AngleSample, SimError> {
        let (theta, omega) = (at.theta, at.omega);
        let layout = self.layout();
        let (kin, gas) = self.kinematics(theta, omega, omega);
        let bodies = joint_bodies(&kin);
        let instant = Instant {
            t: at.t,
            dt: at.dt,
            crank_angle: crank_angle(theta),
            omega,
            oil: at.oil,
            gas: self.law_gas(theta, omega, &kin.q, gas.as_ref()),
        };
        let mut law_samples = Vec::new();
        let mut idx = 0;
        let comps = self.components(&e.reactions);
        let reaction_n = e.normals.iter().fold(0.0, |m: f64, n| m.max(*n));
        for j in &self.joints {
            let mut input = j.input(&instant, &bodies[j.id]);
            let moment = if j.id == JointId::Piston {
                e.reactions.slide_moment_nm
            } else {
                0.0
            };
            set_load(&mut input, comps[j.id], moment, e.normals[j.id]);
            for law in &j.laws {
                let out = sample_output(j.id.name(), j.id.kind(), law, &input, reaction_n)?;
                let regimes: Vec<f64> = (0..4).map(|r| e.rates[layout.regime(idx, r)]).collect();
                let power = e.rates[layout.power(idx)];
                law_samples.push(LawSample::new(power, omega, &regimes, &input, &out));
                idx += 1;
            }
        }
        // Without gas loads both sides are at the standard atmosphere.
        let pressures_pa = match &e.gas {
            Some(g) => [g.cylinder_pa, g.crankcase_pa],
            None => [crate::model::ATMOSPHERE_PA; 2],
        };
        Ok(AngleSample {
            crank_angle_deg: theta.to_degrees(),
            laws: law_samples,
            big_end_n: [e.reactions.big_end_n.x, e.reactions.big_end_n.y],
            main_n: [e.reactions.main_n.x, e.reactions.main_n.y],
            pressures_pa,
            drive_torque_nm: e.drive_torque,
            cylinders: Vec::new(),
            mains_n: Vec::new(),
        })
    }
}

impl EngineSimulation {
    /// Every plateau's cycle at the plateau's speed (the steady state), sampled every
    /// `resolution_deg` degrees, as [`Simulation::crank_angle_traces`] with every joint of
    /// the engine and each cylinder's and main bearing's loads. Laws start from zero state; a
    /// stateful law runs one cycle first so the sampled one is settled.
    pub fn crank_angle_traces(
        &mut self,
        resolution_deg: f64,
    ) -> Result<Vec<CrankAngleTrace>, SimError> {
        let cycle = self.window_spec().cycle_angle();
        let n = samples_per_cycle(cycle, resolution_deg)?;
        let h_angle = cycle / n as f64;
        let laws: Vec<(String, String)> = self
            .joints
            .iter()
            .flat_map(|j| j.laws.iter().map(move |l| (j.name.clone(), l.name.clone())))
            .collect();
        let mut w = EngineWork::new(self);
        let mut traces = Vec::new();
        for pi in 0..self.cycle.plateaus().len() {
            let omega = self.cycle.plateaus()[pi].omega;
            let oil = (self.temps[pi], self.viscosities[pi]);
            let h = h_angle / omega;
            self.reset_states();
            let mut samples = sample_buffer(n)?;
            let passes = if self.stateful { 2 } else { 1 };
            for pass in 0..passes {
                for k in 0..n {
                    let theta = k as f64 * h_angle;
                    let at = Point::steady((pass * n + k) as f64 * h, h, theta, omega, oil);
                    self.evaluate(&at, &mut w)?;
                    if pass + 1 == passes {
                        // Sampled before the commit, as on the single-cylinder rig.
                        samples.push(self.angle_sample(&at, &w)?);
                    }
                    if self.stateful {
                        self.commit(&w)?;
                    }
                }
            }
            traces.push(CrankAngleTrace {
                speed_rpm: self.cycle.plateaus()[pi].speed_rpm,
                laws: laws.clone(),
                samples,
            });
        }
        self.reset_states();
        Ok(traces)
    }

    /// The sample at point `at` from the settled evaluation `w`: each law's rates, and its
    /// diagnostics at the settled loads.
    fn angle_sample(&self, at: &Point, w: &EngineWork) -> Result<AngleSample, SimError> {
        let (theta, omega) = (at.theta, at.omega);
        let layout = self.layout();
        let mut law_samples = Vec::new();
        let mut idx = 0;
        let reaction_n = w.normals.iter().fold(0.0, |m: f64, n| m.max(*n));
        for (ji, j) in self.joints.iter().enumerate() {
            // Without laws the inputs are not built (and nothing is sampled).
            let Some(mut input) = w.inputs.get(ji).copied() else {
                continue;
            };
            let (comp, moment) = self.joint_reaction(ji, &w.re);
            set_load(&mut input, comp, moment, w.normals[ji]);
            for law in &j.laws {
                let out = sample_output(&j.name, input_kind(&input), law, &input, reaction_n)?;
                let power = w.rates[layout.power(idx)];
                let regimes: Vec<f64> = (0..4).map(|r| w.rates[layout.regime(idx, r)]).collect();
                law_samples.push(LawSample::new(power, omega, &regimes, &input, &out));
                idx += 1;
            }
        }
        let cylinders: Vec<CylinderSample> =
            w.re.cylinders
                .iter()
                .zip(&w.law_gas)
                .map(|(c, g)| CylinderSample {
                    big_end_n: [c.big_end_n.x, c.big_end_n.y],
                    side_thrust_n: c.slide_lateral_n,
                    pressures_pa: [g.cylinder_pa, g.crankcase_pa],
                })
                .collect();
        let first = cylinders.first();
        Ok(AngleSample {
            crank_angle_deg: theta.to_degrees(),
            laws: law_samples,
            big_end_n: first.map_or([0.0; 2], |c| c.big_end_n),
            main_n: [w.re.main_total_n.x, w.re.main_total_n.y],
            pressures_pa: first.map_or([crate::model::ATMOSPHERE_PA; 2], |c| c.pressures_pa),
            drive_torque_nm: w.re.drive_torque_nm,
            mains_n: w.re.mains_n.iter().map(|m| [m.x, m.y]).collect(),
            cylinders,
        })
    }
}

/// The joint kind an input says (revolute unless prismatic).
fn input_kind(input: &LawInput) -> tribo_plugin_api::JointKind {
    input
        .kind()
        .unwrap_or(tribo_plugin_api::JointKind::Revolute)
}
