//! Crank-angle-resolved results: per plateau, the rig at the plateau's speed sampled over one
//! cycle (a revolution, or 720 degrees for a 4-stroke cycle) at a fixed angular resolution:
//! each law's friction torque at the crank, power, normal load, sliding speed, regime and the
//! diagnostics it reports (contract version 3: minimum film, eccentricity, peak pressure,
//! asperity share), the big-end and main-bearing loads and the gas pressures.

use tribo_plugin_api::serde::{Deserialize, Serialize};
use tribo_plugin_api::{LawInput, LawOutput, Regime};

use super::bind::{checked_power, law_failed, set_load, BoundLaw};
use super::error::SimError;
use super::evaluate::{Eval, Point, Work};
use super::Simulation;

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
    /// W at crank speed `omega`, its `regime` code), normal load and sliding speed from its
    /// loaded `input`, and the diagnostics of `out`, the law at that input.
    fn new(power: f64, omega: f64, regime: u8, input: &LawInput, out: &LawOutput) -> Self {
        let (ex, ey) = out.eccentricity().unzip();
        Self {
            // At rest (a stepped run's start) nothing turns and nothing dissipates.
            friction_torque_nm: if omega != 0.0 { power / omega } else { 0.0 },
            power_w: power,
            normal_load_n: input.normal_load_n,
            sliding_speed_m_s: input.sliding_velocity_m_s,
            regime: regime_name(regime).to_string(),
            min_film_m: out.min_film(),
            eccentricity_x: ex,
            eccentricity_y: ey,
            peak_pressure_pa: out.peak_pressure(),
            asperity_share: out.asperity_share(),
        }
    }
}

/// Law `law` at its loaded `input` with its state `state` (on joint `joint` of kind `kind`,
/// the largest reaction `reaction_n`), for the diagnostics of a trace: the output of the same
/// evaluation the run makes, checked the same way (a diagnostic out of its physical range is
/// an error naming law, joint and time).
fn sample_output(
    joint: &str,
    kind: tribo_plugin_api::JointKind,
    law: &BoundLaw,
    input: &LawInput,
    state: &[f64],
    reaction_n: f64,
) -> Result<LawOutput, SimError> {
    let out = law
        .output(input, state)
        .map_err(|e| law_failed(joint, input, e))?;
    checked_power(joint, kind, law, input, &out, reaction_n)?;
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
    /// What the user must know about this trace: with stateful laws whose cycle did not
    /// repeat within the settling bound (200 cycles), the same warning the steady run gives (the
    /// samples are the last cycle's, not a settled one).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

fn regime_name(code: u8) -> &'static str {
    match code {
        k if k == Regime::Boundary as u8 => "boundary",
        k if k == Regime::Mixed as u8 => "mixed",
        k if k == Regime::Hydrodynamic as u8 => "hydrodynamic",
        _ => "none",
    }
}

/// The most samples one plateau's trace may hold: a 4-stroke cycle at 0.01 degree. A bound on
/// what a resolution can make a run allocate (at 1e-9 degree it asked for terabytes).
pub const MAX_SAMPLES_PER_CYCLE: usize = 72_000;

/// The most cycles a stateful steady run or trace runs while its mean drive torque has not
/// yet repeated (`cycle_repeats`); the last one is kept. A law whose state settles over many
/// revolutions (a bearing film holding its heat) needs tens of cycles; one warm-up cycle left
/// such a film still settling.
pub(super) const MAX_SETTLING_CYCLES: usize = 200;

/// Whether a cycle's mean drive torque `torque` repeats the previous cycle's `last` to 1e-9
/// relative, the steady run's test of a settled stateful cycle.
pub(super) fn cycle_repeats(torque: f64, last: f64) -> bool {
    (torque - last).abs() <= 1e-9 * torque.abs().max(1e-12)
}

/// The warning of a plateau at `speed_rpm` whose stateful laws did not repeat a cycle within
/// [`MAX_SETTLING_CYCLES`], the last cycle's mean motoring torque still moving by `change`
/// (relative): its values are that cycle's, not a steady state. One text for the steady run
/// and the crank-angle traces.
pub(super) fn unsettled_warning(speed_rpm: f64, change: f64) -> String {
    format!(
        "at the {speed_rpm:.0} rpm plateau the stateful laws did not repeat a cycle within {MAX_SETTLING_CYCLES} cycles (the mean motoring torque still moved by {change:.1e} of itself in the last): its values are the last cycle's, not a steady state"
    )
}

/// The crank-angle grid of a run's traces and what carries over from plateau to plateau: `n`
/// samples `h_angle` apart (rad), the evaluation work space and the friction guess.
struct TraceGrid {
    n: usize,
    h_angle: f64,
    w: Work,
    guess: Vec<f64>,
}

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
    /// `resolution_deg` degrees: each law's torque, power, load, sliding speed and regime, the
    /// loads and pressures; on an engine also each cylinder's and main bearing's loads. Laws
    /// start from zero state; with stateful laws cycles are repeated until the cycle's mean
    /// drive torque repeats to 1e-9 (as the steady run's cycles are; at most
    /// 200, the steady run's bound), and the last cycle is the one sampled.
    pub fn crank_angle_traces(
        &mut self,
        resolution_deg: f64,
    ) -> Result<Vec<CrankAngleTrace>, SimError> {
        let cycle = self.cycle_angle();
        let n = samples_per_cycle(cycle, resolution_deg)?;
        let laws = self.law_names();
        let mut grid = TraceGrid {
            n,
            h_angle: cycle / n as f64,
            w: self.work()?,
            guess: vec![0.0; self.joints.len()],
        };
        let mut traces = Vec::new();
        for pi in 0..self.cycle.plateaus().len() {
            let (samples, unsettled) = self.plateau_trace(pi, &mut grid)?;
            let speed_rpm = self.cycle.plateaus()[pi].speed_rpm;
            let mut warnings: Vec<String> = unsettled
                .map(|change| unsettled_warning(speed_rpm, change))
                .into_iter()
                .collect();
            if self.drivetrain.is_some() {
                warnings.push(format!("the {speed_rpm:.0} rpm traces are the rigid crank's at a constant speed: the rig's drivetrain and elastic crankshaft are not in them (`tribo run` integrates them)"));
            }
            traces.push(CrankAngleTrace {
                speed_rpm,
                laws: laws.clone(),
                samples,
                warnings,
            });
        }
        Ok(traces)
    }

    /// Plateau `pi`'s sampled cycle on `grid`, and, when its stateful laws did not repeat a
    /// cycle within [`MAX_SETTLING_CYCLES`], the last cycle's relative change of the mean
    /// drive torque.
    fn plateau_trace(
        &self,
        pi: usize,
        grid: &mut TraceGrid,
    ) -> Result<(Vec<AngleSample>, Option<f64>), SimError> {
        let TraceGrid {
            n,
            h_angle,
            ref mut w,
            ref mut guess,
        } = *grid;
        let omega = self.cycle.plateaus()[pi].omega;
        let oil = (self.temps[pi], self.viscosities[pi]);
        let h = h_angle / omega;
        let mut e = w.eval();
        w.states.reset();
        if self.rules.fresh_trace_guess {
            guess.fill(0.0);
        }
        let mut samples = sample_buffer(n)?;
        let (max_passes, mut last_torque) = if self.stateful {
            (MAX_SETTLING_CYCLES, f64::NAN)
        } else {
            (1, 0.0)
        };
        let mut unsettled = None;
        for pass in 0..max_passes {
            // Every pass after the first is sampled (the last one kept), so the cycle that
            // repeats its predecessor is the one returned.
            samples.clear();
            let mut torque_sum = 0.0;
            for k in 0..n {
                let theta = k as f64 * h_angle;
                let at = Point::steady((pass * n + k) as f64 * h, h, theta, omega, oil);
                self.evaluate(&at, guess, w, &mut e)?;
                guess.copy_from_slice(&e.totals);
                torque_sum += e.drive_torque;
                if pass > 0 || !self.stateful {
                    // Sampled before the commit: the laws' states are those the
                    // evaluation used.
                    samples.push(self.angle_sample(theta, omega, w, &e)?);
                }
                self.commit(w, &e)?;
            }
            let torque = torque_sum / n as f64;
            if !self.stateful || (pass > 0 && cycle_repeats(torque, last_torque)) {
                unsettled = None;
                break;
            }
            if pass > 0 {
                unsettled = Some((torque - last_torque) / torque.abs().max(1e-12));
            }
            last_torque = torque;
        }
        w.recycle(e);
        Ok((samples, unsettled))
    }

    /// Joint and law of every law, in the run-wide law order.
    pub fn law_names(&self) -> Vec<(String, String)> {
        self.joints
            .iter()
            .flat_map(|j| j.laws.iter().map(move |l| (j.name.clone(), l.name.clone())))
            .collect()
    }

    /// Every law's sample at crank speed `omega` from the last evaluation in `w` (its law
    /// inputs, the crank model's final solve and the laws' states), its settled normal loads
    /// `normals`, its rates and regimes `(rates, regimes)`: each law's rates and regime, and its
    /// diagnostics at the settled loads.
    pub(super) fn law_samples(
        &self,
        omega: f64,
        w: &Work,
        normals: &[f64],
        (rates, regimes): (&[f64], &[u8]),
    ) -> Result<Vec<LawSample>, SimError> {
        let layout = self.layout();
        let mut law_samples = Vec::with_capacity(self.n_laws);
        let reaction_n = normals.iter().fold(0.0, |m: f64, n| m.max(*n));
        for (ji, j) in self.joints.iter().enumerate() {
            // Without laws the inputs are not built (and nothing is sampled).
            let Some(mut input) = w.inputs.get(ji).copied() else {
                continue;
            };
            let (comp, moment) = w.crank.reaction(j.role);
            set_load(&mut input, comp, moment, normals[ji]);
            for (i, law) in j.laws.iter().enumerate() {
                let k = j.first_law + i;
                let state = w.states.of(k);
                let out = sample_output(&j.name, j.role.kind(), law, &input, state, reaction_n)?;
                let power = rates[layout.power(k)];
                law_samples.push(LawSample::new(power, omega, regimes[k], &input, &out));
            }
        }
        Ok(law_samples)
    }

    /// The sample at crank angle `theta` and speed `omega` from the settled evaluation `e`
    /// (its law inputs and the crank model's final solve in `w`).
    fn angle_sample(
        &self,
        theta: f64,
        omega: f64,
        w: &Work,
        e: &Eval,
    ) -> Result<AngleSample, SimError> {
        let law_samples = self.law_samples(omega, w, &e.normals, (&e.rates, &e.regimes))?;
        let loads = w.crank.loads_sample();
        let pressures = |k: usize| {
            w.law_gas
                .get(k)
                .map_or([crate::model::ATMOSPHERE_PA; 2], |g| {
                    [g.cylinder_pa, g.crankcase_pa]
                })
        };
        let cylinders: Vec<CylinderSample> = loads
            .cylinders
            .iter()
            .enumerate()
            .map(|(k, (big_end_n, side_thrust_n))| CylinderSample {
                big_end_n: *big_end_n,
                side_thrust_n: *side_thrust_n,
                pressures_pa: pressures(k),
            })
            .collect();
        Ok(AngleSample {
            crank_angle_deg: theta.to_degrees(),
            laws: law_samples,
            big_end_n: loads.big_end_n,
            main_n: loads.main_n,
            pressures_pa: pressures(0),
            drive_torque_nm: e.drive_torque,
            mains_n: loads.mains_n,
            cylinders,
        })
    }
}
