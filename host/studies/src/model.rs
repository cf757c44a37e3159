//! The torque model a calibration and the scores evaluate: a law set with its free parameters
//! set, run in steady state at every point of the measured runs, and the [`Objective`] seam
//! the optimiser ([`crate::calibrate`]) works through.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use tribo_config::lawset::{FreeParam, LawSet};
use tribo_config::rig::Rig;
use tribo_plugin_api::loader::LawRegistry;

use crate::inputs::{prepare, run_rig, DataRun};

/// The model the fit and the scores evaluate: the law set with the free parameters set, run in
/// steady state at every point of every data run. Counts evaluations and failures.
pub struct TorqueModel<'a> {
    rig: &'a Rig,
    lawset: &'a LawSet,
    free: &'a [FreeParam],
    runs: Vec<DataRun>,
    registry: &'a LawRegistry,
    evaluations: AtomicUsize,
    failures: AtomicUsize,
    first_failure: Mutex<Option<String>>,
}

impl<'a> TorqueModel<'a> {
    /// The model of `lawset` on `rig` with `free` parameters, at the points of `runs`.
    pub fn new(
        rig: &'a Rig,
        lawset: &'a LawSet,
        free: &'a [FreeParam],
        runs: Vec<DataRun>,
        registry: &'a LawRegistry,
    ) -> Self {
        Self {
            rig,
            lawset,
            free,
            runs,
            registry,
            evaluations: AtomicUsize::new(0),
            failures: AtomicUsize::new(0),
            first_failure: Mutex::new(None),
        }
    }

    /// The rig, law set and registry the model runs on.
    pub fn parts(&self) -> (&'a Rig, &'a LawSet, &'a LawRegistry) {
        (self.rig, self.lawset, self.registry)
    }

    /// The data runs.
    pub fn runs(&self) -> &[DataRun] {
        &self.runs
    }

    /// The free parameters.
    pub fn free(&self) -> &[FreeParam] {
        self.free
    }

    /// Number of data points over all runs.
    pub fn points(&self) -> usize {
        self.runs.iter().map(|r| r.rows.len()).sum()
    }

    /// Measured torques in data order, N m.
    pub fn measured(&self) -> Vec<f64> {
        self.runs
            .iter()
            .flat_map(|r| r.rows.iter().map(|d| d.torque_nm))
            .collect()
    }

    /// Model torques at parameters `x`, N m, in data order; the failure's text if a run fails.
    pub fn torques(&self, x: &[f64]) -> Result<Vec<f64>, String> {
        self.evaluations.fetch_add(1, Ordering::Relaxed);
        let ls = self.lawset.with_values(self.free, x);
        let mut out = Vec::with_capacity(self.points());
        for run in &self.runs {
            let r = prepare(self.rig, &ls, Some(&run.rows))
                .map_err(|e| e.to_string())
                .and_then(|r| run_rig(&r, self.registry, true).map_err(|e| e.to_string()));
            match r {
                Ok(r) => out.extend(r.plateaus.iter().map(|p| p.measured_torque_nm())),
                Err(e) => {
                    self.failures.fetch_add(1, Ordering::Relaxed);
                    if let Ok(mut slot) = self.first_failure.lock() {
                        slot.get_or_insert_with(|| e.clone());
                    }
                    return Err(e);
                }
            }
        }
        Ok(out)
    }

    /// Evaluations so far.
    pub fn evaluations(&self) -> usize {
        self.evaluations.load(Ordering::Relaxed)
    }

    /// Failed evaluations so far and the first failure.
    pub fn failures(&self) -> (usize, Option<String>) {
        let first = self.first_failure.lock().ok().and_then(|s| s.clone());
        (self.failures.load(Ordering::Relaxed), first)
    }
}

/// What a calibration fits: a model's values at bounded parameters against measurements.
/// [`TorqueModel`] is the one the studies use; the multi-start search ([`crate::calibrate::search`]) works on any.
pub trait Objective: Sync {
    /// Each parameter's bounds, `[lower, upper]`.
    fn bounds(&self) -> Vec<[f64; 2]>;
    /// The measured values, in the order [`Objective::model`] returns its values.
    fn measured(&self) -> Vec<f64>;
    /// The model's values at parameters `x`, or why it could not be evaluated there.
    fn model(&self, x: &[f64]) -> Result<Vec<f64>, String>;
}

impl Objective for TorqueModel<'_> {
    fn bounds(&self) -> Vec<[f64; 2]> {
        self.free.iter().map(|f| f.bounds).collect()
    }
    fn measured(&self) -> Vec<f64> {
        TorqueModel::measured(self)
    }
    fn model(&self, x: &[f64]) -> Result<Vec<f64>, String> {
        self.torques(x)
    }
}
