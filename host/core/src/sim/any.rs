//! Any rig behind one type: the single-cylinder rig of the thesis ([`Simulation`]) or a
//! multi-cylinder engine ([`EngineSimulation`]), chosen by whether the model has an
//! `[engine]` table. Studies, the CLI and the Python package run rigs through it, so every
//! command works on every rig; each variant keeps its own solver (the thesis rig's numbers do
//! not move).

use tribo_plugin_api::loader::LawRegistry;
use tribo_plugin_api::{suits, suits_text, BearingType};

use super::{CrankAngleTrace, EngineSimulation, Fmep, RunResult, SimError, Simulation};
use crate::model::{LawRef, RigFile, JOINT_NAMES};
use crate::observe::{Position, StepObserver};

/// A rig ready to run, whatever its crank train, with the warnings its laws raise on it.
pub struct RigSimulation {
    kind: Kind,
    /// Warnings about the laws on this rig (a law on a bearing type it does not suit), added
    /// to every result.
    notes: Vec<String>,
}

/// The crank train's own simulation.
enum Kind {
    /// The single-cylinder rig (five joints).
    Single(Box<Simulation>),
    /// A multi-cylinder engine (`docs/engines.md`).
    Engine(Box<EngineSimulation>),
}

/// The warning of a run with no law on any joint.
pub const NO_LAWS_WARNING: &str = "no law on any joint: every joint is frictionless, so the motoring torque is the mechanism's alone (zero on average at a constant speed); attach laws with a law set or --law (a frictionless reference rig is meant to give this)";

/// One warning per law on a joint whose declared bearing type the law does not suit (its
/// `SUITS_*` bits; a law declaring none, or a joint the rig declares nothing for, is never
/// warned about), naming the joint, the law, what the law is made for and what the joint is.
/// A law the registry cannot provide is left to the binding's error.
pub fn suitability_notes(model: &RigFile, registry: &LawRegistry) -> Vec<String> {
    let joints: Vec<(String, Vec<LawRef>)> = if model.engine.is_some() {
        super::engine_run::laws_by_joint(model)
    } else {
        model
            .joints
            .named()
            .iter()
            .map(|(name, j)| ((*name).to_string(), j.laws.clone()))
            .collect()
    };
    let mut notes = Vec::new();
    for (joint, laws) in joints {
        let bearing = model.bearing_type(&joint);
        for law in laws {
            let Ok(lib) = registry.get(&law.law) else {
                continue;
            };
            if !suits(lib.suits(), bearing) {
                notes.push(format!(
                    "joint `{joint}`: law `{}` is made for {}, but the rig declares {} there",
                    law.law,
                    suits_text(lib.suits()),
                    bearing_words(bearing)
                ));
            }
        }
    }
    notes
}

/// A declared bearing type in a sentence.
fn bearing_words(bearing: BearingType) -> &'static str {
    match bearing {
        BearingType::Unspecified => "no bearing type",
        BearingType::Plain => "a plain bearing",
        BearingType::Rolling => "a rolling-element bearing",
        BearingType::Slide => "a slide",
    }
}

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

    /// Bind the model's laws (from `registry`) and prepare its crank train and cycle; the
    /// laws' suitability to the rig's bearings is judged here ([`suitability_notes`]).
    pub fn new(model: &RigFile, registry: &LawRegistry) -> Result<Self, SimError> {
        let kind = if model.engine.is_some() {
            Kind::Engine(Box::new(EngineSimulation::new(model, registry)?))
        } else {
            Kind::Single(Box::new(Simulation::new(model, registry)?))
        };
        Ok(Self {
            kind,
            notes: suitability_notes(model, registry),
        })
    }

    /// Whether the rig is a multi-cylinder engine.
    pub fn is_engine(&self) -> bool {
        matches!(self.kind, Kind::Engine(_))
    }

    /// The warnings about the laws on this rig, which every result carries first.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The joints' names, in the order of a time series' normal loads.
    pub fn joint_names(&self) -> Vec<String> {
        match &self.kind {
            Kind::Single(_) => JOINT_NAMES.iter().map(|s| (*s).to_string()).collect(),
            Kind::Engine(e) => e.joint_names(),
        }
    }

    /// `result` with this rig's notes before its own warnings, and the warning of a run
    /// without any law after them.
    fn noted(&self, result: Result<RunResult, SimError>) -> Result<RunResult, SimError> {
        result.map(|mut r| {
            r.warnings.splice(0..0, self.notes.iter().cloned());
            // A run without any law: its torque is the frictionless mechanism's, about zero,
            // which a user rarely meant to compute.
            if self.law_count() == 0 {
                r.warnings.push(NO_LAWS_WARNING.to_string());
            }
            r
        })
    }

    /// Report progress (permille of the simulated cycle) to `p`.
    pub fn report_progress(&mut self, p: Position) {
        match &mut self.kind {
            Kind::Single(s) => s.report_progress(p),
            Kind::Engine(e) => e.report_progress(p),
        }
    }

    /// The run's FMEP definition.
    pub fn fmep(&self) -> Fmep {
        match &self.kind {
            Kind::Single(s) => s.fmep(),
            Kind::Engine(e) => e.fmep(),
        }
    }

    /// Laws bound on all joints together; zero when every joint is frictionless.
    pub fn law_count(&self) -> usize {
        match &self.kind {
            Kind::Single(s) => s.layout().n,
            Kind::Engine(e) => e.layout().n,
        }
    }

    /// Run the whole test cycle without per-step output.
    pub fn run(&mut self) -> Result<RunResult, SimError> {
        let r = match &mut self.kind {
            Kind::Single(s) => s.run(),
            Kind::Engine(e) => e.run(),
        };
        self.noted(r)
    }

    /// Run the whole test cycle, handing every accepted step to `observer`.
    pub fn run_with(&mut self, observer: &mut dyn StepObserver) -> Result<RunResult, SimError> {
        let r = match &mut self.kind {
            Kind::Single(s) => s.run_with(observer),
            Kind::Engine(e) => e.run_with(observer),
        };
        self.noted(r)
    }

    /// Each plateau's periodic steady state, computed directly.
    pub fn run_steady(&mut self) -> Result<RunResult, SimError> {
        let r = match &mut self.kind {
            Kind::Single(s) => s.run_steady(),
            Kind::Engine(e) => e.run_steady(),
        };
        self.noted(r)
    }

    /// Every plateau's cycle in steady state, sampled every `resolution_deg` degrees.
    pub fn crank_angle_traces(
        &mut self,
        resolution_deg: f64,
    ) -> Result<Vec<CrankAngleTrace>, SimError> {
        match &mut self.kind {
            Kind::Single(s) => s.crank_angle_traces(resolution_deg),
            Kind::Engine(e) => e.crank_angle_traces(resolution_deg),
        }
    }
}
