//! The motored-rig simulation, composed of named stages:
//!
//! - `bind`: laws bound to joints ([`JointId`]), law calls with sampled timing, commits;
//! - `evaluate` (with `newton`): model evaluation at one instant, the friction/reaction
//!   iteration (`crank state -> reactions -> law inputs -> laws -> joint loads -> reactions
//!   ...` until the normal loads settle);
//! - `stepper` (with `adaptive`): one trait for a step method: Simpson quadrature of the
//!   prescribed crank, the error-controlled Dormand-Prince 5(4) pair of the PI drive with its
//!   step-size controller and switch handling, fixed-step RK4 (stateful laws or
//!   `solver.integrator = "rk4"`);
//! - `plateau`: whole-revolution windows and plateau measurement; `steady`: the steady state;
//!   `energy`: the energy balance; `results`: what a run returns.
//!
//! The core does no I/O: per-step output (a time series, progress) goes to a
//! [`StepObserver`].

mod adaptive;
mod any;
mod bind;
mod crank_angle;
mod energy;
mod engine_newton;
mod engine_run;
mod engine_transient;
mod error;
mod evaluate;
mod joint;
mod newton;
mod plateau;
mod rates;
mod results;
mod steady;
mod stepper;
#[cfg(test)]
mod tests;

use std::f64::consts::TAU;

use tribo_plugin_api::loader::LawRegistry;

use crate::cycle::Cycle;
use crate::erk::{Controller, DORMAND_PRINCE_54};
use crate::gas::GasModel;
use crate::mechanics::{JointLoads, Mechanism, RigGeometry};
use crate::model::{Drive, Integrator, RigFile, StepControl, Temperature, JOINT_NAMES};
use crate::observe::{NoObserver, StepObserver, StepSample};

pub use any::{suitability_notes, RigSimulation, NO_LAWS_WARNING};
pub use crank_angle::{AngleSample, CrankAngleTrace, CylinderSample, LawSample};
pub use engine_run::EngineSimulation;
pub use error::{readable, Fault, SimError, Unsettled, MAX_FORCE_PER_REACTION, REACTION_FLOOR_N};
pub use joint::JointId;
pub use results::{
    ComponentFmep, DriveKind, EnergyBalance, Fmep, FmepBasis, GroupTotal, LawResult, LawTime,
    PlateauFmep, PlateauResult, RegimeShare, RunResult,
};

use adaptive::Adaptive;
use bind::BoundJoint;
use evaluate::{SWITCHES, SWITCH_DRIVE, SWITCH_LATERAL};
use plateau::Plateaus;
use rates::RateLayout;
use stepper::{Quadrature, Rk4, Stepper, Work};

/// Standard gravity, m/s^2.
pub const GRAVITY_M_S2: f64 = 9.80665;

/// A ready-to-run simulation: mechanism, cycle, laws and drive.
pub struct Simulation {
    rig_name: String,
    mech: Mechanism,
    cycle: Cycle,
    /// The five joints in `JointId::ALL` order, with their laws.
    joints: Vec<BoundJoint>,
    shares: [f64; 2],
    drive: Drive,
    temps: Vec<f64>,
    viscosities: Vec<f64>,
    window_s: f64,
    lowpass_hz: f64,
    step_rad: f64,
    max_step_s: f64,
    integrator: Integrator,
    rel_tol: f64,
    max_step_rad: f64,
    /// The adaptive integrator's step-size controller.
    step_control: StepControl,
    /// Which of an evaluation's `switches` matter: those of joints that carry a law.
    switch_mask: [bool; SWITCHES],
    /// Whether any bound law keeps state (then steps are fixed and committed).
    stateful: bool,
    tol: f64,
    max_iter: u32,
    n_laws: usize,
    progress: Option<crate::observe::Position>,
    /// The gas pressures on the piston, if the rig has any.
    gas: Option<GasModel>,
    /// Displacement (swept volume), m^3.
    displacement_m3: f64,
}

/// The mechanism of the model: its bodies reduced to the rig's geometry (the crank's
/// unbalance folded into its mass, centre and inertia; the PI drive's motor inertia reflected
/// through the belt).
fn rig_geometry(f: &RigFile) -> RigGeometry {
    let c = &f.bodies.crank;
    let (mu, ru) = (c.unbalance_mass_kg * c.mass_scale, c.unbalance_radius_m);
    let m_crank = c.mass_kg * c.mass_scale + mu;
    let offset = if m_crank > 0.0 {
        mu * ru / m_crank
    } else {
        0.0
    };
    let j_axis = c.inertia_kg_m2 * c.inertia_scale + mu * ru * ru;
    let r = &f.bodies.rod;
    RigGeometry {
        crank_radius_m: f.geometry.crank_radius_m,
        rod_length_m: r.length_m,
        rod_com_from_big_end_m: r.com_from_big_end_m,
        crank_inertia_kg_m2: j_axis - m_crank * offset * offset,
        crank_mass_kg: m_crank,
        crank_com_offset_m: offset,
        crank_com_angle_rad: c.unbalance_angle_deg.to_radians(),
        rod_mass_kg: r.mass_kg * r.mass_scale,
        rod_inertia_kg_m2: r.inertia_kg_m2 * r.inertia_scale,
        piston_mass_kg: f.bodies.piston.mass_kg * f.bodies.piston.mass_scale,
        gravity_m_s2: if f.geometry.gravity {
            GRAVITY_M_S2
        } else {
            0.0
        },
        drive_inertia_kg_m2: f.drive.reflected_inertia_kg_m2(),
    }
}

/// A multi-cylinder engine rig is run by [`EngineSimulation`] (or [`RigSimulation`], which
/// picks either): the single-cylinder solver refuses it rather than give one cylinder's answer.
fn not_an_engine(f: &RigFile) -> Result<(), SimError> {
    match &f.engine {
        None => Ok(()),
        Some(e) => Err(SimError::Setup {
            at: None,
            field: "engine".into(),
            law: None,
            param: None,
            message: format!(
                "this rig is a {}-cylinder engine: the single-cylinder solver cannot run it; use EngineSimulation or RigSimulation (tribo_config::rig::any_simulation)",
                e.cylinders.len()
            ),
        }),
    }
}

/// Which step method a transient run uses.
enum Method {
    /// Prescribed crank: Simpson quadrature of the exact reference motion.
    Quadrature,
    /// PI drive, stateless laws: error-controlled Dormand-Prince 5(4).
    Adaptive,
    /// PI drive with stateful laws, or `solver.integrator = "rk4"`: fixed-step RK4.
    Rk4,
}

impl Simulation {
    /// Check `model`'s laws against `registry` (each law known, its parameters' names, types
    /// and ranges) without creating an instance: no law code beyond its description runs.
    pub fn check_laws(model: &RigFile, registry: &LawRegistry) -> Result<(), SimError> {
        not_an_engine(model)?;
        bind::check_laws(model, registry)
    }

    /// Bind the model's laws (from `registry`) and prepare the mechanism and cycle.
    pub fn new(model: &RigFile, registry: &LawRegistry) -> Result<Self, SimError> {
        let f = model;
        not_an_engine(f)?;
        let (joints, n_laws) = bind::bind_joints(f, registry)?;
        let mut switch_mask = [false; SWITCHES];
        for j in &joints {
            switch_mask[j.id.index()] = !j.laws.is_empty();
        }
        switch_mask[SWITCH_LATERAL] = switch_mask[JointId::Piston.index()];
        switch_mask[SWITCH_DRIVE] = matches!(f.drive, Drive::Pi { .. });
        let stateful = joints.iter().any(BoundJoint::is_stateful);
        let cycle = Cycle::new(&f.cycle.segments());
        let (temps, viscosities) = oil_schedule(f, &cycle);
        Ok(Self {
            rig_name: f.name.clone(),
            mech: Mechanism::new(rig_geometry(f)),
            cycle,
            joints,
            shares: [f.joints.main_a.load_share, f.joints.main_b.load_share],
            drive: f.drive.clone(),
            temps,
            viscosities,
            window_s: f.measurement.window_s,
            lowpass_hz: f.measurement.lowpass_hz,
            step_rad: f.solver.step_deg.to_radians(),
            max_step_s: f.solver.max_step_s,
            integrator: f.solver.integrator,
            rel_tol: f.solver.rel_tol,
            max_step_rad: f.solver.max_step_deg.to_radians(),
            step_control: f.solver.step_control,
            switch_mask,
            stateful,
            tol: f.solver.friction_tol,
            max_iter: f.solver.friction_max_iter,
            n_laws,
            progress: None,
            gas: GasModel::from_rig(f),
            displacement_m3: std::f64::consts::PI
                * 0.25
                * f.geometry.bore_m
                * f.geometry.bore_m
                * 2.0
                * f.geometry.crank_radius_m,
        })
    }

    /// Report progress (permille of the simulated cycle) to `p`.
    pub fn report_progress(&mut self, p: crate::observe::Position) {
        self.progress = Some(p);
    }

    /// The mechanism (for tests and studies).
    pub fn mechanism(&self) -> &Mechanism {
        &self.mech
    }

    /// The gas model, if the rig has gas loads.
    pub fn gas(&self) -> Option<&GasModel> {
        self.gas.as_ref()
    }

    /// Crank revolutions per cycle: 2 when the gas pressure makes the cycle 4-stroke, else 1.
    pub fn revolutions_per_cycle(&self) -> u32 {
        if self.gas.as_ref().is_some_and(GasModel::four_stroke) {
            2
        } else {
            1
        }
    }

    /// The run's FMEP definition: 4-stroke when the gas pressure makes the cycle 4-stroke,
    /// else per revolution.
    pub fn fmep(&self) -> Fmep {
        Fmep {
            basis: if self.revolutions_per_cycle() == 2 {
                FmepBasis::FourStroke
            } else {
                FmepBasis::TwoStroke
            },
            displacement_m3: self.displacement_m3,
        }
    }

    /// The load-independent kinematics at `theta`, `omega` with the gas force applied, and the
    /// gas state (if any), a vented crankcase read at the crank speed `gas_omega`.
    #[inline]
    pub(super) fn kinematics(
        &self,
        theta: f64,
        omega: f64,
        gas_omega: f64,
    ) -> (crate::mechanics::Kinematics, Option<crate::gas::GasState>) {
        match &self.gas {
            None => (self.mech.kinematics(theta, omega), None),
            Some(g) => {
                let s = g.at(theta, gas_omega);
                (
                    self.mech
                        .kinematics_with_piston_force(theta, omega, s.force_n),
                    Some(s),
                )
            }
        }
    }

    /// The crank speed a vented crankcase is read at for point `at`: the crank's own when it
    /// follows the cycle exactly (prescribed crank, steady state); the cycle's reference speed
    /// under the PI drive, whose speed ripples within a revolution far faster than the
    /// crankcase breathes (the tables are quasi-steady in the cycle's speed, and the mean
    /// speed follows the reference).
    #[inline]
    fn gas_speed(&self, at: &evaluate::Point) -> f64 {
        match at.control {
            evaluate::Control::Torque(_)
                if self.gas.as_ref().is_some_and(GasModel::depends_on_speed) =>
            {
                self.cycle.reference(at.t).1
            }
            _ => at.omega,
        }
    }

    /// The gas state the laws are handed at crank angle `theta` (accumulated): the gas
    /// model's `state` when the rig has one (the same evaluation's, so nothing is computed
    /// twice), else both pressures at the standard atmosphere, the piston travel read from the
    /// solve's positions `q` and the angle modulo one 4-stroke cycle. With a gas model but no
    /// `state`, the model is evaluated here (a vented crankcase at the crank speed `omega`).
    #[inline]
    pub(super) fn law_gas(
        &self,
        theta: f64,
        omega: f64,
        q: &crate::mechanics::Q,
        state: Option<&crate::gas::GasState>,
    ) -> crate::gas::LawGas {
        let travel = self.mech.piston_travel(q);
        match (state, &self.gas) {
            (Some(s), _) => s.into(),
            (None, Some(g)) => (&g.at_travel(theta, omega, travel)).into(),
            (None, None) => {
                let ambient = tribo_plugin_api::contract::STANDARD_ATMOSPHERE_PA;
                crate::gas::LawGas {
                    cylinder_pa: ambient,
                    crankcase_pa: ambient,
                    piston_from_tdc_m: travel,
                    cycle_angle_rad: crate::gas::cycle_angle(theta),
                }
            }
        }
    }

    /// Oil temperature and viscosity in force at time `t`: the plateau's value during a hold
    /// and the ramp leading to it; after the last plateau, the last value.
    #[inline]
    fn oil_at(&self, t: f64) -> (f64, f64) {
        oil_at(&self.cycle, &self.temps, &self.viscosities, t)
    }

    #[inline]
    fn layout(&self) -> RateLayout {
        RateLayout { n: self.n_laws }
    }

    /// Run the whole test cycle without per-step output.
    pub fn run(&mut self) -> Result<RunResult, SimError> {
        self.run_with(&mut NoObserver)
    }

    /// Run the whole test cycle, handing every accepted step to `observer` (a failing
    /// observer stops the run with its error). Every law's state starts from zero, so a
    /// simulation run twice gives the same result.
    pub fn run_with(&mut self, observer: &mut dyn StepObserver) -> Result<RunResult, SimError> {
        observer.start(&JOINT_NAMES).map_err(SimError::Observer)?;
        bind::reset_states(&mut self.joints);
        let method = match self.drive {
            Drive::Prescribed => Method::Quadrature,
            // A stateful law's state is advanced with the step's length, which must then not
            // vary: the adaptive integrator is for stateless laws only.
            Drive::Pi { .. } if self.integrator == Integrator::Adaptive && !self.stateful => {
                Method::Adaptive
            }
            Drive::Pi { .. } => Method::Rk4,
        };
        let e0 = self.mechanical_energy(0.0, 0.0);
        let mut w = Work::new(self.layout().len());
        let (e_start, l_start) = self.step_eval(0.0, 0.0, (0.0, 0.0, 0.0), &w.guess, Vec::new())?;
        w.last_rates = e_start.rates.clone();
        let (w, steps, plateaus) = match method {
            Method::Quadrature => self.transient(Quadrature, w, observer)?,
            Method::Rk4 => self.transient(Rk4::default(), w, observer)?,
            Method::Adaptive => {
                let n = self.layout().len();
                let control = match self.step_control {
                    StepControl::Integral => Controller::new(&DORMAND_PRINCE_54),
                    StepControl::Pi => Controller::pi(&DORMAND_PRINCE_54),
                };
                let stepper = Adaptive::new(&DORMAND_PRINCE_54, control, (e_start, l_start), n);
                self.transient(stepper, w, observer)?
            }
        };
        let change = self.mechanical_energy(w.y.0, w.y.1) - e0;
        let dissipated: f64 = w.acc[self.layout().powers()].iter().sum();
        let gas_work = w.acc[self.layout().gas()];
        let energy = EnergyBalance::from_terms_with_gas(
            w.acc[RateLayout::MOTOR],
            change,
            dissipated,
            gas_work,
        )
        .relative_to(e0.abs().max((e0 + change).abs()));
        let (results, warnings) = plateaus.results(|pi, m| self.plateau_result(pi, m))?;
        Ok(RunResult {
            rig: self.rig_name.clone(),
            drive: match self.drive {
                Drive::Prescribed => DriveKind::Prescribed,
                Drive::Pi { .. } => DriveKind::Pi,
            },
            plateaus: results,
            fmep: self.fmep(),
            energy_residual_j: energy.residual_j,
            energy,
            steps,
            rejected_steps: w.rejected,
            max_friction_iterations: w.max_it,
            warnings,
            law_time: bind::law_time(&self.joints),
        })
    }

    /// The run's grid: segment ends, and for a prescribed crank the exact window starts, so
    /// every window begins and ends on a step.
    fn grid(&self) -> Vec<f64> {
        grid(&self.cycle, &self.window_spec(), &self.drive)
    }

    /// The transient run with `stepper` over the grid: every accepted step is committed,
    /// observed, filtered and recorded for the plateau windows. Returns the final work state,
    /// the steps taken and the plateau records.
    fn transient<S: Stepper>(
        &mut self,
        mut stepper: S,
        mut w: Work,
        observer: &mut dyn StepObserver,
    ) -> Result<(Work, u64, Plateaus), SimError> {
        let duration = self.cycle.duration();
        let mut plateaus = Plateaus::new(
            self.cycle.plateaus(),
            self.window_spec(),
            self.layout().len(),
        );
        let (mut filtered, mut steps) = (0.0, 0_u64);
        for b in self.grid() {
            let (_, w_end, _) = self.cycle.reference(b);
            let w_max = w_end.max(self.cycle.reference(w.t).1).max(w.y.1);
            let dt_target = self.time_step(self.step_rad, w_max);
            let m = ((b - w.t) / dt_target).ceil().max(1.0) as u64;
            let dt = (b - w.t) / m as f64;
            stepper.begin_interval(self, &mut w, dt)?;
            let mut i = 0_u64;
            while w.t < b {
                i += 1;
                let t1 = if i == m { b } else { w.t + dt };
                let step = stepper.step(self, &mut w, t1, b)?;
                w.y = step.y;
                self.commit(step.t1, step.h, w.y.0, &step.end, self.oil_at(step.t1))?;
                w.last_rates.copy_from_slice(&step.end.rates);
                steps += 1;
                if steps % 4096 == 0 {
                    let permille = (1000.0 * step.t1 / duration) as u64;
                    if let Some(p) = &self.progress {
                        p.set(permille);
                    }
                    observer.progress(permille);
                }
                // Low-pass filter of the motoring torque (first order, exact discretisation).
                let a = (-TAU * self.lowpass_hz * step.h).exp();
                filtered = a * filtered + (1.0 - a) * step.end.drive_torque;
                observe(observer, &step, w.y, filtered)?;
                let crank = (w.y.0, w.y.1);
                let sat = step.end.saturated();
                plateaus.record(step.t1, step.h, crank, sat, &w.acc, &w.last_rates);
                stepper.recycle(step.end, step.h, &mut w);
                w.t = step.t1;
            }
        }
        Ok((w, steps, plateaus))
    }
}

/// Each plateau's oil temperature (C) and dynamic viscosity (Pa s) from the rig's `[oil]`.
fn oil_schedule(f: &RigFile, cycle: &Cycle) -> (Vec<f64>, Vec<f64>) {
    let temps: Vec<f64> = match &f.oil.temperature_c {
        Temperature::Constant(t) => vec![*t; cycle.plateaus().len()],
        Temperature::PerPlateau(v) => v.clone(),
    };
    let viscosities = temps
        .iter()
        .map(|t| f.oil.viscosity.kinematic_cst(*t) * 1e-6 * f.oil.density_kg_m3)
        .collect();
    (temps, viscosities)
}

/// Oil temperature and viscosity in force at time `t` of `cycle` (per plateau `temps`,
/// `viscosities`): the plateau's value during a hold and the ramp leading to it; after the
/// last plateau, the last value.
#[inline]
fn oil_at(cycle: &Cycle, temps: &[f64], viscosities: &[f64], t: f64) -> (f64, f64) {
    let i = cycle
        .plateaus()
        .iter()
        .position(|p| t <= p.t_end)
        .unwrap_or(temps.len().saturating_sub(1));
    (temps[i], viscosities[i])
}

/// A transient run's grid over `cycle`: segment ends, and for a prescribed crank the exact
/// window starts (`spec`), so every window begins and ends on a step.
fn grid(cycle: &Cycle, spec: &plateau::WindowSpec, drive: &Drive) -> Vec<f64> {
    let duration = cycle.duration();
    let mut breaks: Vec<f64> = cycle.breakpoints();
    if matches!(drive, Drive::Prescribed) {
        for p in cycle.plateaus() {
            let revs = spec.window_revs(p.omega);
            breaks.push(p.t_end - revs as f64 * TAU / p.omega);
        }
    }
    breaks.retain(|b| *b > 0.0 && *b <= duration);
    breaks.sort_by(f64::total_cmp);
    breaks.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    breaks
}

/// Hand the accepted `step` (crank state `y` at its end, filtered torque) to the observer.
fn observe(
    observer: &mut dyn StepObserver,
    step: &stepper::Step,
    y: stepper::CrankState,
    filtered: f64,
) -> Result<(), SimError> {
    let sample = StepSample {
        time_s: step.t1,
        crank_angle_rad: y.0,
        speed_rad_s: y.1,
        motoring_torque_nm: step.end.drive_torque,
        filtered_torque_nm: filtered,
        normal_loads_n: &step.end.normals,
    };
    observer.step(&sample).map_err(SimError::Observer)
}

impl Work {
    /// The start of a run: crank at rest at time 0, nothing accumulated, for `n` quantities.
    fn new(n: usize) -> Self {
        Self {
            t: 0.0,
            y: (0.0, 0.0, 0.0),
            acc: vec![0.0; n],
            last_rates: Vec::new(),
            guess: JointLoads::default(),
            pool: Vec::new(),
            max_it: 0,
            rejected: 0,
        }
    }
}
