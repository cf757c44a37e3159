//! The simulation of any rig, whatever its crank train: the single-cylinder rig of the thesis
//! and multi-cylinder engines run through one solver, composed of named stages:
//!
//! - `joints` + `bind`: the rig's joints (names from the rig, a `Role` each) and their
//!   laws, law calls with sampled timing, output checks, commits of stateful laws;
//! - `crank`: the crank model behind one type (the single-cylinder rig's `Mechanism`, an
//!   engine's `CrankTrain`): kinematics once per evaluation, reactions under any friction;
//! - `evaluate` (with `newton` and `trend`): one instant, the friction/reaction iteration
//!   (`crank state -> reactions -> law inputs -> laws -> friction -> reactions ...` until the
//!   normal loads settle; `trend` judges phase 1's convergence and stalling, phase 2's Newton
//!   iteration takes over where the plain one stalls);
//! - `stepper` (with `adaptive` and `lobatto`): one trait for a step method: Simpson
//!   quadrature of the prescribed crank or its error-controlled Gauss-Lobatto quadrature
//!   (`solver.quadrature`), the error-controlled Dormand-Prince 5(4) pair of the PI drive with
//!   its step-size controller and switch handling, fixed-step RK4 (stateful laws or
//!   `solver.integrator = "rk4"`);
//! - `transient`: the run over the test cycle, a value advanced in time; `steady`: the steady
//!   state; `crank_angle`: one cycle per plateau resolved in crank angle;
//! - `plateau`: whole-revolution windows and plateau measurement; `energy`: the energy
//!   balance; `results`: what a run returns;
//! - `types`: the small value types the stages share (`Role`, `Bodies`, `Control`), in a leaf
//!   module so the stages that share them need not import one another.
//!
//! The core does no I/O: per-step output (a time series, progress) goes to a
//! [`StepObserver`].

mod adaptive;
mod bind;
mod crank;
mod crank_angle;
mod energy;
mod error;
mod evaluate;
mod joints;
mod limit;
mod lobatto;
mod newton;
mod orbit;
mod plateau;
mod rates;
mod replay;
#[cfg(test)]
mod replay_tests;
mod results;
mod settings;
mod settle;
mod steady;
mod stepper;
mod stepping;
#[cfg(test)]
mod tests;
mod torsional;
mod torsional_cycle;
mod transient;
mod trend;
mod types;

use std::f64::consts::PI;

use tribo_plugin_api::loader::LawRegistry;

use crate::cycle::Cycle;
use crate::engine::{cylinder_phases, geometry, top_dead_centres, CrankTrain};
use crate::gas::GasModel;
use crate::mechanics::{Mechanism, RigGeometry};
use crate::model::{Drive, Integrator, QuadratureRule, RigFile, StepControl, Temperature};
use crate::observe::{NoObserver, StepObserver};

pub use bind::suitability_notes;

/// The warning of a run with no law on any joint.
pub const NO_LAWS_WARNING: &str = "no law on any joint: every joint is frictionless, so the motoring torque is the mechanism's alone (zero on average at a constant speed); attach laws with a law set or --law (a frictionless reference rig is meant to give this)";
pub use crank_angle::{AngleSample, CrankAngleTrace, CylinderSample, LawSample};
pub use error::{readable, Fault, SimError, Unsettled, MAX_FORCE_PER_REACTION, REACTION_FLOOR_N};
pub use results::{
    ComponentFmep, DriveKind, EnergyBalance, Fmep, FmepBasis, GroupTotal, Instrument, LawResult,
    LawTime, PlateauFmep, PlateauResult, RegimeShare, RunResult,
};
pub use settings::RUN_DEPENDENT_SETTINGS;
pub use stepping::{Inputs, JointOutput, Outputs, Run, RunState, Snapshot, RUN_STATE_VERSION};

use bind::BoundJoint;
use crank::Crank;
use rates::{RateLayout, RegimeTimes};
use trend::Distance;
use types::Role;

/// Standard gravity, m/s^2 (defined with the rig model; kept here for callers of the solver).
pub use crate::model::GRAVITY_M_S2;

/// What a commit hands a stateful law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Commit {
    /// The last round's inputs loaded with the final solve's normal loads and reactions (the
    /// single-cylinder rig's rule before the solvers were one).
    Rebuilt,
    /// The last round's inputs as the laws were evaluated at them (the engines' rule).
    LastInputs,
}

/// The rules in which the single-cylinder rig's solver and the engines' differed before they
/// were one; each kept as it was, until settled in changes of their own.
#[derive(Debug, Clone, Copy)]
struct Rules {
    /// Phase 1's distance to the fixed point.
    distance: Distance,
    /// What a stateful law is committed at.
    commit: Commit,
    /// RK4 evaluates a step's first stage again when a stateful law's state moved at the
    /// commit before it (rather than reusing the previous step's end).
    fresh_first_stage: bool,
    /// Each plateau of the crank-angle traces starts its friction iteration from zero
    /// (rather than from the previous plateau's last point).
    fresh_trace_guess: bool,
}

impl Rules {
    /// The single-cylinder rig's.
    const RIG: Rules = Rules {
        distance: Distance::Geometric,
        commit: Commit::Rebuilt,
        fresh_first_stage: false,
        fresh_trace_guess: true,
    };
    /// The engines'.
    const ENGINE: Rules = Rules {
        distance: Distance::LastChange,
        commit: Commit::LastInputs,
        fresh_first_stage: true,
        fresh_trace_guess: false,
    };
}

/// A rig ready to run, whatever its crank train: crank model, cycle, laws bound to the joints,
/// drive, oil, gas and solver settings.
pub struct Simulation {
    rig_name: String,
    /// Whether the rig is a multi-cylinder engine (`[engine]`): its results name its groups
    /// and its crank-angle traces every cylinder and main.
    engine: bool,
    /// The crank model (its scratch is each run's own copy).
    crank: Crank,
    /// The joints in order, with their laws.
    joints: Vec<BoundJoint>,
    /// Each joint's role, in joint order (what the crank model solves with).
    roles: Vec<Role>,
    cycle: Cycle,
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
    /// The prescribed crank's quadrature (stateless laws).
    quadrature: QuadratureRule,
    /// Which of an evaluation's `switches` matter: the relative velocities of joints that
    /// carry a law, the side thrust of cylinders whose piston does, the PI drive's margin.
    switch_mask: Vec<bool>,
    /// The crank angles in one 4-stroke cycle (rad, [0, 4 pi), sorted) where a cylinder's
    /// pressure is not smooth (a trace's samples), on which the prescribed crank's
    /// error-controlled quadrature ends its steps.
    pressure_kinks: Vec<f64>,
    /// Whether any bound law keeps state (then steps are fixed and committed).
    stateful: bool,
    /// Whether a prescribed hold's repeating cycles are replayed (`sim/replay.rs`).
    hold_replay: replay::HoldReplay,
    tol: f64,
    max_iter: u32,
    n_laws: usize,
    progress: Option<crate::observe::Position>,
    /// Each cylinder's gas pressures (none without `[gas]`), with its own 4-stroke phase.
    gas: Vec<GasModel>,
    /// Swept volume of all cylinders, m^3.
    displacement_m3: f64,
    /// The engine's working cycle (the FMEP basis).
    engine_cycle: crate::model::EngineCycle,
    /// The correlation's view of the engine (`crate::correlation`).
    correlation: crate::correlation::EngineData,
    rules: Rules,
    /// Warnings about the laws on this rig (a law on a bearing type it does not suit), first
    /// among every result's warnings.
    notes: Vec<String>,
    /// Which of [`RUN_DEPENDENT_SETTINGS`] the user gave (`settings`): a run that cannot use
    /// one refuses it or says so.
    given: Vec<&'static str>,
    /// What a stepped run's inputs set instead of the rig's own (nothing in a plain run).
    held: stepping::Held,
    /// Each cylinder's ambient gas model on a rig without gas loads (else empty): what a
    /// cylinder pressure set from outside acts on.
    ambient_gas: Vec<GasModel>,
    /// The oil's viscosity model and density (kg/m^3), for an oil temperature set from outside.
    oil: (crate::oil::ViscosityModel, f64),
    /// The drivetrain from the motor to the crank (`[drivetrain]`), reflected to crank speed.
    drivetrain: Option<torsional::Torsion>,
}

/// The single-cylinder rig's mechanism: its bodies reduced to the rig's geometry (the crank's
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

/// The crank model of `f` and each cylinder's gas model (the rig's, and on a rig without gas
/// loads the ambient one a cylinder pressure set from outside acts on): an engine's crank
/// train with each cylinder's 4-stroke phase from the firing order, or the single-cylinder
/// mechanism.
fn crank_and_gas(f: &RigFile) -> Result<(Crank, [Vec<GasModel>; 2]), SimError> {
    let setup = |message: String| SimError::Setup {
        at: None,
        field: "engine".into(),
        law: None,
        param: None,
        message,
    };
    let (Some(e), Some(geo)) = (&f.engine, geometry(f)) else {
        let shares = [f.joints.main_a.load_share, f.joints.main_b.load_share];
        let crank = Crank::rig(Mechanism::new(rig_geometry(f)), shares);
        let gas: Vec<GasModel> = GasModel::from_rig(f).into_iter().collect();
        let ambient = if gas.is_empty() {
            vec![GasModel::ambient(f)]
        } else {
            Vec::new()
        };
        return Ok((crank, [gas, ambient]));
    };
    let phases = cylinder_phases(
        &top_dead_centres(&geo),
        &e.firing_order,
        f.gas.cycle_angle_at_zero_deg.to_radians(),
    )
    .map_err(|err| setup(err.to_string()))?;
    let train = CrankTrain::new(geo).map_err(|err| setup(err.to_string()))?;
    // Each cylinder's gas: the rig's model with the cylinder's own 4-stroke phase, evaluated
    // at the cylinder's own crank angle.
    let phased = |phase: &f64| {
        let mut fk = f.clone();
        fk.gas.cycle_angle_at_zero_deg = phase.to_degrees();
        fk
    };
    let gas: Vec<GasModel> = phases
        .iter()
        .filter_map(|phase| GasModel::from_rig(&phased(phase)))
        .collect();
    let ambient = if gas.is_empty() {
        phases
            .iter()
            .map(|p| GasModel::ambient(&phased(p)))
            .collect()
    } else {
        Vec::new()
    };
    let mut crank = Crank::train(train, phases);
    if e.crankshaft.is_some() {
        crank.make_elastic();
    }
    Ok((crank, [gas, ambient]))
}

/// The rig's drivetrain reflected to crank speed, its crank node the crank's cycle-mean
/// inertia (the reciprocating masses averaged over a revolution), the motor held by the drive.
fn torsion(f: &RigFile, crank: &Crank) -> Result<Option<torsional::Torsion>, SimError> {
    let setup = |prefix: &str, e: crate::drivetrain::DrivetrainError| SimError::Setup {
        at: None,
        field: format!("{prefix}.{}", e.field),
        law: None,
        param: None,
        message: e.message,
    };
    let shaft = f.engine.as_ref().and_then(|e| e.crankshaft.as_ref());
    let end = match shaft {
        Some(spec) => Some(
            spec.crank_end(&crank.throw_mean_inertias())
                .map_err(|e| setup("engine.crankshaft", e))?,
        ),
        None => None,
    };
    let chain = match (&f.drivetrain, end) {
        (None, None) => return Ok(None),
        (Some(spec), None) => spec
            .chain(crank.mean_inertia_kg_m2())
            .map_err(|e| setup("drivetrain", e))?,
        (Some(spec), Some(end)) => spec.chain_to(end).map_err(|e| setup("drivetrain", e))?,
        (None, Some(end)) => {
            crate::drivetrain::Chain::crankshaft(end, f.drive.reflected_inertia_kg_m2())
                .map_err(|e| setup("engine.crankshaft", e))?
        }
    };
    let (hold, limit_nm) = match f.drive {
        Drive::Prescribed {} => (crate::drivetrain::MotorHold::Prescribed, f64::INFINITY),
        Drive::Pi {
            kp,
            ki,
            torque_limit_nm,
            ..
        } => (crate::drivetrain::MotorHold::Pi { kp, ki }, torque_limit_nm),
    };
    Ok(Some(torsional::Torsion::new(
        chain,
        hold,
        limit_nm,
        shaft.is_some(),
    )))
}

/// The rig's drivetrain reflected to crank speed with the crank's cycle-mean inertia, and how
/// the drive holds its motor (`None` without a `[drivetrain]`): what `tribo modes` analyses.
pub fn drivetrain_chain(
    f: &RigFile,
) -> Result<Option<(crate::drivetrain::Chain, crate::drivetrain::MotorHold)>, SimError> {
    let (crank, _) = crank_and_gas(f)?;
    Ok(torsion(f, &crank)?.map(|t| (t.chain, t.hold)))
}

/// Which of an evaluation's switching functions matter (see `Simulation::switch_mask`).
/// A vented crankcase's breather reversal is watched by the prescribed crank's error-controlled
/// quadrature only: the PI drive reads the crankcase at the cycle's reference speed and was not
/// measured with it (its steps, and so its numbers, would move).
fn switch_mask(
    joints: &[BoundJoint],
    cylinders: usize,
    drive: &Drive,
    gas: &[GasModel],
) -> Vec<bool> {
    let mut mask: Vec<bool> = joints.iter().map(|j| !j.laws.is_empty()).collect();
    mask.extend((0..cylinders).map(|k| {
        joints
            .iter()
            .any(|j| j.role == Role::Piston(k) && !j.laws.is_empty())
    }));
    let vented = gas.first().is_some_and(GasModel::depends_on_speed);
    mask.push(vented && matches!(drive, Drive::Prescribed { .. }));
    mask.push(matches!(drive, Drive::Pi { .. }));
    mask
}

/// Every cylinder's pressure kinks ([`GasModel::pressure_kinks`], at the cylinder's own crank
/// angle) as crank angles of the crank, in one 4-stroke cycle, sorted.
fn pressure_kinks(crank: &Crank, gas: &[GasModel]) -> Vec<f64> {
    let offset = |k: usize| {
        crank
            .crank_train()
            .map_or(0.0, |t| t.geometry().cylinder_offset_rad(k))
    };
    let mut kinks: Vec<f64> = gas
        .iter()
        .enumerate()
        .flat_map(|(k, g)| {
            let d = offset(k);
            g.pressure_kinks()
                .into_iter()
                .map(move |a| crate::gas::cycle_angle(a - d))
        })
        .collect();
    kinks.sort_by(f64::total_cmp);
    kinks.dedup();
    kinks
}

impl Simulation {
    /// Check `model`'s laws against `registry` (each law known, its parameters' names, types
    /// and ranges) without creating an instance: no law code beyond its description runs.
    pub fn check_laws(model: &RigFile, registry: &LawRegistry) -> Result<(), SimError> {
        bind::check_laws(model, registry)
    }

    /// Bind the model's laws (from `registry`) and prepare the crank model, cycle and gas; the
    /// laws' suitability to the rig's bearings is judged here ([`suitability_notes`]). A
    /// setting the transient run cannot use with these laws and this drive is refused (of the
    /// settings given: here those that differ from their defaults, see
    /// [`Simulation::settings_given`]).
    pub fn new(model: &RigFile, registry: &LawRegistry) -> Result<Self, SimError> {
        let sim = Self::bind(model, registry)?;
        sim.refuse_unused_settings()?;
        Ok(sim)
    }

    /// [`Simulation::new`] without the check of the settings.
    fn bind(model: &RigFile, registry: &LawRegistry) -> Result<Self, SimError> {
        let f = model;
        let (crank, [gas, ambient_gas]) = crank_and_gas(f)?;
        let (joints, n_laws) = bind::bind_joints(f, registry)?;
        let cylinders = crank.cylinders();
        let cycle = Cycle::new(&f.cycle.segments());
        let (temps, viscosities) = oil_schedule(f, &cycle);
        let engine = f.engine.is_some();
        let drivetrain = torsion(f, &crank)?;
        Ok(Self {
            drivetrain,
            rig_name: f.name.clone(),
            engine,
            switch_mask: switch_mask(&joints, cylinders, &f.drive, &gas),
            pressure_kinks: pressure_kinks(&crank, &gas),
            stateful: joints.iter().any(BoundJoint::is_stateful),
            hold_replay: replay::HoldReplay::On,
            roles: joints.iter().map(|j| j.role).collect(),
            crank,
            joints,
            cycle,
            drive: f.drive.clone(),
            temps,
            viscosities,
            window_s: f.measurement.window_s,
            lowpass_hz: f.measurement.lowpass_hz,
            step_rad: f.solver.step_deg.to_radians(),
            max_step_s: f.solver.max_step_s,
            integrator: f.solver.integrator,
            rel_tol: f.solver.rel_tol,
            max_step_rad: f.solver.max_step_deg(engine).to_radians(),
            step_control: f.solver.step_control,
            quadrature: f.solver.quadrature,
            tol: f.solver.friction_tol,
            max_iter: f.solver.friction_max_iter,
            n_laws,
            progress: None,
            gas,
            displacement_m3: cylinders as f64
                * PI
                * 0.25
                * f.geometry.bore_m
                * f.geometry.bore_m
                * 2.0
                * f.geometry.crank_radius_m,
            engine_cycle: f.geometry.engine_cycle,
            correlation: crate::correlation::EngineData::from_rig(f),
            rules: if engine { Rules::ENGINE } else { Rules::RIG },
            notes: bind::suitability_notes(f, registry),
            given: settings::non_default_settings(f),
            held: stepping::Held::default(),
            ambient_gas,
            oil: (f.oil.viscosity.clone(), f.oil.density_kg_m3),
        })
    }

    /// The warnings about the laws on this rig, which every result carries first.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Laws bound on all joints together; zero when every joint is frictionless.
    pub fn law_count(&self) -> usize {
        self.n_laws
    }

    /// Every result's warnings: this rig's notes, then the run's own `warnings`, then the
    /// warning of a run without any law (its torque is the frictionless mechanism's, about
    /// zero, which a user rarely meant to compute).
    fn result_warnings(&self, warnings: Vec<String>) -> Vec<String> {
        let mut all = self.notes.clone();
        all.extend(warnings);
        if self.law_count() == 0 {
            all.push(NO_LAWS_WARNING.to_string());
        }
        all
    }

    /// Report progress (permille of the simulated cycle) to `p`.
    pub fn report_progress(&mut self, p: crate::observe::Position) {
        self.progress = Some(p);
    }

    /// Whether the rig is a multi-cylinder engine (`[engine]`).
    pub fn is_engine(&self) -> bool {
        self.engine
    }

    /// The joints' names in order, as in the results and a time series' normal loads (the
    /// single-cylinder rig's `main_a`, `main_b`, `big_end`, `small_end`, `piston`; an
    /// engine's `main_1 .. main_n`, then per cylinder `big_end_k`, `small_end_k`, `piston_k`).
    pub fn joint_names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// The single-cylinder rig's mechanism (`None` on an engine).
    pub fn mechanism(&self) -> Option<&Mechanism> {
        self.crank.mechanism()
    }

    /// An engine's crank train (`None` on the single-cylinder rig).
    pub fn train(&self) -> Option<&CrankTrain> {
        self.crank.crank_train()
    }

    /// The (first) cylinder's gas model, if the rig has gas loads.
    pub fn gas(&self) -> Option<&GasModel> {
        self.gas.first()
    }

    /// Crank revolutions per cycle: 2 when the gas pressure makes the cycle 4-stroke, else 1.
    pub fn revolutions_per_cycle(&self) -> u32 {
        if self.gas.iter().any(GasModel::four_stroke) {
            2
        } else {
            1
        }
    }

    /// The run's FMEP definition: the basis of the rig's engine cycle (`geometry.engine_cycle`),
    /// whatever the gas model.
    pub fn fmep(&self) -> Fmep {
        Fmep {
            basis: FmepBasis::from(self.engine_cycle),
            displacement_m3: self.displacement_m3,
        }
    }

    /// Oil temperature and viscosity in force at time `t`: the plateau's value during a hold
    /// and the ramp leading to it; after the last plateau, the last value; a temperature set
    /// from outside (the stepping API) while it is set.
    #[inline]
    fn oil_at(&self, t: f64) -> (f64, f64) {
        if let Some(oil) = self.held.oil {
            return oil;
        }
        let i = self
            .cycle
            .plateaus()
            .iter()
            .position(|p| t <= p.t_end)
            .unwrap_or(self.temps.len().saturating_sub(1));
        (self.temps[i], self.viscosities[i])
    }

    /// The crank's reference motion (angle, speed, acceleration) at `t`: the cycle's, or a
    /// speed set from outside held from where it was set.
    #[inline]
    fn reference(&self, t: f64) -> (f64, f64, f64) {
        match self.held.speed {
            Some(held) => held.at(t),
            None => self.cycle.reference(t),
        }
    }

    /// [`Simulation::reference`] on the side of `t` that starts there (the cycle's
    /// acceleration jumps at segment boundaries).
    #[inline]
    fn reference_after(&self, t: f64) -> (f64, f64, f64) {
        match self.held.speed {
            Some(held) => held.at(t),
            None => self.cycle.reference_after(t),
        }
    }

    /// The cylinders' gas models: the rig's, or the ambient ones while a cylinder pressure set
    /// from outside acts on a rig without gas loads.
    #[inline]
    fn gas_models(&self) -> &[GasModel] {
        if self.held.cylinder_pa.is_some() && self.gas.is_empty() {
            &self.ambient_gas
        } else {
            &self.gas
        }
    }

    #[inline]
    fn layout(&self) -> RateLayout {
        RateLayout { n: self.n_laws }
    }

    /// The laws' regime times, kept apart from the rates.
    #[inline]
    fn regime_times(&self) -> RegimeTimes {
        RegimeTimes { n: self.n_laws }
    }

    /// The name a model error gives joint `j`: the single-cylinder rig's joint name, an
    /// engine's joint group.
    fn model_name(&self, j: &BoundJoint) -> &'static str {
        match (self.engine, j.role) {
            (true, role) => role.group(),
            (false, Role::Main(0)) => "main_a",
            (false, Role::Main(_)) => "main_b",
            (false, Role::BigEnd(_)) => "big_end",
            (false, Role::SmallEnd(_)) => "small_end",
            (false, Role::Piston(_)) => "piston",
        }
    }

    /// Step every cycle of a prescribed hold (`false`) instead of replaying the cycles that
    /// repeat (`true`, the default): the same plateau torques, and every other result within
    /// the quadrature's own error, at several times the cost. For checking the replay.
    pub fn set_replay_holds(&mut self, replay: bool) {
        self.hold_replay = match replay {
            true => replay::HoldReplay::On,
            false => replay::HoldReplay::Off,
        };
    }

    /// Run the whole test cycle without per-step output.
    pub fn run(&mut self) -> Result<RunResult, SimError> {
        self.run_with(&mut NoObserver)
    }

    /// Run the whole test cycle, handing every accepted step to `observer` (the joints'
    /// normal loads in [`Simulation::joint_names`] order; a failing observer stops the run
    /// with its error). Every law's state starts from zero, so a simulation run twice gives
    /// the same result.
    pub fn run_with(&mut self, observer: &mut dyn StepObserver) -> Result<RunResult, SimError> {
        let names = self.joint_names();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        observer.start(&refs).map_err(SimError::Observer)?;
        if let Some(tor) = self.drivetrain.take() {
            let result = self.run_transient_drivetrain(&tor, observer);
            self.drivetrain = Some(tor);
            return result;
        }
        let mut run = self.start_transient()?;
        self.advance(&mut run, f64::INFINITY, u64::MAX, observer)?;
        self.finish_transient(&run)
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
