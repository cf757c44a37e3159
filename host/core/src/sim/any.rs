//! Any rig behind one type: the single-cylinder rig of the thesis ([`Simulation`]) or a
//! multi-cylinder engine ([`EngineSimulation`]), chosen by whether the model has an
//! `[engine]` table. Studies, the CLI and the Python package run rigs through it, so every
//! command works on every rig; each variant keeps its own solver (the thesis rig's numbers do
//! not move).

use tribo_plugin_api::loader::LawRegistry;

use super::{CrankAngleTrace, EngineSimulation, Fmep, RunResult, SimError, Simulation};
use crate::model::{RigFile, JOINT_NAMES};
use crate::observe::{Position, StepObserver};

/// A rig ready to run, whatever its crank train.
pub enum RigSimulation {
    /// The single-cylinder rig (five joints).
    Single(Box<Simulation>),
    /// A multi-cylinder engine (`docs/engines.md`).
    Engine(Box<EngineSimulation>),
}

/// The warning of a run with no law on any joint.
pub const NO_LAWS_WARNING: &str = "no law on any joint: every joint is frictionless, so the motoring torque is the mechanism's alone (zero on average at a constant speed); attach laws with a law set or --law (a frictionless reference rig is meant to give this)";

impl RigSimulation {
    /// Check `model`'s laws against `registry` (each law known, its parameters' names, types
    /// and ranges) without creating an instance.
    pub fn check_laws(model: &RigFile, registry: &LawRegistry) -> Result<(), SimError> {
        if model.engine.is_some() {
            EngineSimulation::check_laws(model, registry)
        } else {
            Simulation::check_laws(model, registry)
        }
    }

    /// Bind the model's laws (from `registry`) and prepare its crank train and cycle.
    pub fn new(model: &RigFile, registry: &LawRegistry) -> Result<Self, SimError> {
        Ok(if model.engine.is_some() {
            Self::Engine(Box::new(EngineSimulation::new(model, registry)?))
        } else {
            Self::Single(Box::new(Simulation::new(model, registry)?))
        })
    }

    /// Whether the rig is a multi-cylinder engine.
    pub fn is_engine(&self) -> bool {
        matches!(self, Self::Engine(_))
    }

    /// The joints' names, in the order of a time series' normal loads.
    pub fn joint_names(&self) -> Vec<String> {
        match self {
            Self::Single(_) => JOINT_NAMES.iter().map(|s| (*s).to_string()).collect(),
            Self::Engine(e) => e.joint_names(),
        }
    }

    /// Report progress (permille of the simulated cycle) to `p`.
    pub fn report_progress(&mut self, p: Position) {
        match self {
            Self::Single(s) => s.report_progress(p),
            Self::Engine(e) => e.report_progress(p),
        }
    }

    /// The run's FMEP definition.
    pub fn fmep(&self) -> Fmep {
        match self {
            Self::Single(s) => s.fmep(),
            Self::Engine(e) => e.fmep(),
        }
    }

    /// Laws bound on all joints together; zero when every joint is frictionless.
    pub fn law_count(&self) -> usize {
        match self {
            Self::Single(s) => s.layout().n,
            Self::Engine(e) => e.layout().n,
        }
    }

    /// A run's result with the warning a run without any law needs: its torque is the
    /// frictionless mechanism's, about zero, which a user rarely meant to compute.
    fn warn_if_lawless(&self, r: Result<RunResult, SimError>) -> Result<RunResult, SimError> {
        r.map(|mut r| {
            if self.law_count() == 0 {
                r.warnings.push(NO_LAWS_WARNING.to_string());
            }
            r
        })
    }

    /// Run the whole test cycle without per-step output.
    pub fn run(&mut self) -> Result<RunResult, SimError> {
        let r = match self {
            Self::Single(s) => s.run(),
            Self::Engine(e) => e.run(),
        };
        self.warn_if_lawless(r)
    }

    /// Run the whole test cycle, handing every accepted step to `observer`.
    pub fn run_with(&mut self, observer: &mut dyn StepObserver) -> Result<RunResult, SimError> {
        let r = match self {
            Self::Single(s) => s.run_with(observer),
            Self::Engine(e) => e.run_with(observer),
        };
        self.warn_if_lawless(r)
    }

    /// Each plateau's periodic steady state, computed directly.
    pub fn run_steady(&mut self) -> Result<RunResult, SimError> {
        let r = match self {
            Self::Single(s) => s.run_steady(),
            Self::Engine(e) => e.run_steady(),
        };
        self.warn_if_lawless(r)
    }

    /// Every plateau's cycle in steady state, sampled every `resolution_deg` degrees.
    pub fn crank_angle_traces(
        &mut self,
        resolution_deg: f64,
    ) -> Result<Vec<CrankAngleTrace>, SimError> {
        match self {
            Self::Single(s) => s.crank_angle_traces(resolution_deg),
            Self::Engine(e) => e.crank_angle_traces(resolution_deg),
        }
    }
}
