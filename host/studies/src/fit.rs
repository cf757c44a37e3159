//! `tribo fit`: least-squares calibration of a law set's free parameters to measured torque at
//! the measured speeds and oil temperatures (Levenberg-Marquardt on steady-state runs), over one
//! or several measured runs at once.
//!
//! Bounds are kept by a change of variable: each parameter is `lo + (hi - lo) * s(u)` with
//! `s(u) = (1 + tanh u) / 2` and `u` unbounded, in log space when the bounds span two decades or
//! more (thresholds, scales). The Jacobian is a forward difference in `u`, its columns run in
//! parallel. Nothing is hidden from the user: trial points that do not run are counted and the
//! first failure is reported, parameters that end on a bound are named, the optimiser's reason
//! for stopping is given in words, and the uncertainty report ([`crate::uncertainty`]) says when
//! the data cannot determine the parameters.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tribo_plugin_api::loader::LawRegistry;

use crate::score::{self, Scores, Validation};
use crate::study::{errors, prepare, run_rig, DataRun, StudyError};
use crate::uncertainty::{uncertainty_within_bounds, Uncertainty};
use tribo_config::lawset::{FreeParam, LawSet};
use tribo_config::rig::Rig;

/// How to calibrate.
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// Number of start points: the law set's own values, then quasi-random points spread over
    /// the bounds (a Halton sequence, so runs are reproducible). The best result is kept.
    pub starts: usize,
    /// Whether to score the calibration out of sample (leave-one-out refits).
    pub cross_validate: bool,
    /// Data never used in fitting, scored with the fitted values.
    pub validate: Vec<DataRun>,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            starts: 1,
            cross_validate: true,
            validate: Vec::new(),
        }
    }
}

/// One measured run's points against the calibrated model.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunFit {
    /// The data file.
    pub file: String,
    /// Speeds, rpm.
    pub speeds_rpm: Vec<f64>,
    /// Oil temperature of each point, C.
    pub oil_temp_c: Vec<f64>,
    /// Measured torque, N m.
    pub measured_nm: Vec<f64>,
    /// Model torque with the fitted values, N m.
    pub model_nm: Vec<f64>,
    /// Model minus measurement, N m.
    pub residuals_nm: Vec<f64>,
    /// This run's root-mean-square residual, N m.
    pub rmse_nm: f64,
    /// Half-width of the 95% confidence band of the model torque at each point, N m (`None`
    /// where the parameters are not determined).
    pub band_half_width_nm: Option<Vec<f64>>,
}

/// The outcome of one start point.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StartOutcome {
    /// Start values.
    pub start: Vec<f64>,
    /// Values reached.
    pub values: Vec<f64>,
    /// RMSE reached, N m (`None` if the start point did not run).
    pub rmse_nm: Option<f64>,
    /// Why the optimiser stopped, in words.
    pub termination: String,
}

/// The outcome of a calibration.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FitResult {
    /// Law set fitted.
    pub lawset: String,
    /// Parameter ids (`joint.law.param`).
    pub params: Vec<String>,
    /// Start values (of the start point the best result came from).
    pub start: Vec<f64>,
    /// Fitted values.
    pub values: Vec<f64>,
    /// Bounds.
    pub bounds: Vec<[f64; 2]>,
    /// `lower` or `upper` where a fitted value ended on its bound (within 0.1% of the range).
    pub at_bound: Vec<Option<String>>,
    /// Approximate 1-sigma uncertainty of each value (from the Jacobian); `None` where the data
    /// do not determine it.
    pub std_dev: Vec<Option<f64>>,
    /// The uncertainty analysis: covariance-based intervals, correlations, conditioning.
    pub uncertainty: Uncertainty,
    /// All points in data order (runs concatenated): speeds, rpm.
    pub speeds_rpm: Vec<f64>,
    /// Measured torque, N m.
    pub measured_nm: Vec<f64>,
    /// Model torque with the fitted values, N m.
    pub model_nm: Vec<f64>,
    /// Model minus measurement, N m.
    pub residuals_nm: Vec<f64>,
    /// Root-mean-square error over all points, N m.
    pub rmse_nm: f64,
    /// Per measured run.
    pub runs: Vec<RunFit>,
    /// Out-of-sample scores: leave-one-out RMSE, AICc, BIC.
    pub scores: Scores,
    /// Scores on data never used in fitting (`--validate`).
    pub validation: Vec<Validation>,
    /// Model evaluations made (each a steady-state run of every data run).
    pub evaluations: usize,
    /// Trial points at which the model did not run (the optimiser was steered away from them).
    pub failed_evaluations: usize,
    /// The first such failure, verbatim.
    pub first_failure: Option<String>,
    /// Why the optimiser stopped, in words.
    pub termination: String,
    /// Whether the optimiser reported convergence (ftol, xtol, gtol or zero residuals).
    pub converged: bool,
    /// Every start point's outcome (one unless `--starts` asked for more).
    pub starts: Vec<StartOutcome>,
    /// Warnings: poorly determined parameters, bounds reached, failures, spread of starts.
    pub warnings: Vec<String>,
}

/// Maps an unbounded optimiser variable to a bounded parameter.
#[derive(Clone, Copy)]
struct Map {
    lo: f64,
    hi: f64,
    log: bool,
}

impl Map {
    fn new(b: [f64; 2]) -> Self {
        let log = b[0] > 0.0 && b[1] / b[0] >= 100.0;
        if log {
            Self {
                lo: b[0].ln(),
                hi: b[1].ln(),
                log,
            }
        } else {
            Self {
                lo: b[0],
                hi: b[1],
                log,
            }
        }
    }
    /// The parameter for a unit-interval coordinate `s` (0 at the lower bound).
    fn at_unit(self, s: f64) -> f64 {
        let y = self.lo + (self.hi - self.lo) * s;
        if self.log {
            y.exp()
        } else {
            y
        }
    }
    fn unit(self, x: f64) -> f64 {
        let y = if self.log {
            x.max(f64::MIN_POSITIVE).ln()
        } else {
            x
        };
        (y - self.lo) / (self.hi - self.lo)
    }
    fn to_x(self, u: f64) -> f64 {
        self.at_unit(0.5 * (1.0 + u.tanh()))
    }
    fn to_u(self, x: f64) -> f64 {
        let s = self.unit(x).clamp(1e-6, 1.0 - 1e-6);
        (2.0 * s - 1.0).atanh()
    }
}

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
                Ok(r) => out.extend(r.plateaus.iter().map(|p| p.motoring_torque_nm)),
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

/// Residual given to a parameter set that does not run, N m: steers the optimiser away. Every
/// use is counted and reported.
const PENALTY_NM: f64 = 1e3;

/// The optimiser's view of a [`TorqueModel`]: unbounded variables, residuals, a Jacobian.
struct Problem<'m, 'a> {
    model: &'m TorqueModel<'a>,
    maps: &'m [Map],
    measured: &'m [f64],
    u: DVector<f64>,
    /// The last point run and its torques: the optimiser asks for the Jacobian at the point
    /// whose residuals it has just computed.
    last: Mutex<Option<(Vec<f64>, Vec<f64>)>>,
}

impl Problem<'_, '_> {
    fn x_of(&self, u: &DVector<f64>) -> Vec<f64> {
        u.iter().zip(self.maps).map(|(u, m)| m.to_x(*u)).collect()
    }

    fn torques_or_penalty(&self, x: &[f64]) -> Vec<f64> {
        self.model
            .torques(x)
            .unwrap_or_else(|_| self.measured.iter().map(|d| d + PENALTY_NM).collect())
    }

    fn torques_cached(&self, x: &[f64]) -> Vec<f64> {
        if let Ok(last) = self.last.lock() {
            if let Some((lx, lt)) = last.as_ref() {
                if lx.as_slice() == x {
                    return lt.clone();
                }
            }
        }
        let t = self.torques_or_penalty(x);
        if let Ok(mut last) = self.last.lock() {
            *last = Some((x.to_vec(), t.clone()));
        }
        t
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, u: &DVector<f64>) {
        self.u.copy_from(u);
    }

    fn params(&self) -> DVector<f64> {
        self.u.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let t = self.torques_cached(&self.x_of(&self.u));
        Some(DVector::from_iterator(
            t.len(),
            t.iter().zip(self.measured).map(|(m, d)| m - d),
        ))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        // Forward differences: one extra model run per parameter (the optimiser's own step
        // control tolerates their O(h) error; central differences doubled the fit's cost).
        let n = self.u.len();
        let m = self.measured.len();
        let base = self.torques_cached(&self.x_of(&self.u));
        let cols: Vec<Vec<f64>> = (0..n)
            .into_par_iter()
            .map(|k| {
                let h = 1e-5 * (1.0 + self.u[k].abs());
                let mut up = self.u.clone();
                up[k] += h;
                let a = self.torques_or_penalty(&self.x_of(&up));
                a.iter().zip(&base).map(|(a, b)| (a - b) / h).collect()
            })
            .collect();
        let mut j = DMatrix::zeros(m, n);
        for (k, c) in cols.into_iter().enumerate() {
            for (i, v) in c.into_iter().enumerate() {
                j[(i, k)] = v;
            }
        }
        Some(j)
    }
}

/// The optimiser's stopping reason in words a user can act on.
fn termination_words(t: &TerminationReason) -> String {
    match t {
        TerminationReason::Converged { ftol, xtol } => match (ftol, xtol) {
            (true, true) => "converged: neither the residuals nor the parameters change any more".into(),
            (true, false) => "converged: the sum of squared residuals no longer decreases".into(),
            _ => "converged: the parameters no longer change".into(),
        },
        TerminationReason::ResidualsZero => "converged: the model reproduces the data exactly".into(),
        TerminationReason::Orthogonal => "converged: the residuals are orthogonal to every parameter direction (a stationary point)".into(),
        TerminationReason::LostPatience => "stopped: the evaluation budget ran out before convergence; the values are the best found, not a minimum".into(),
        TerminationReason::NoImprovementPossible(what) => format!("stopped: no further improvement possible at machine precision ({what})"),
        TerminationReason::Numerical(what) => format!("failed: a non-finite number appeared ({what})"),
        TerminationReason::User(what) => format!("failed: the model could not be evaluated ({what})"),
        TerminationReason::NoParameters => "nothing to fit: no free parameters".into(),
        TerminationReason::NoResiduals => "nothing to fit: no data points".into(),
        TerminationReason::WrongDimensions(what) => format!("failed: inconsistent dimensions ({what})"),
    }
}

/// One optimiser run from `start`.
pub struct Calibration {
    /// Values reached.
    pub values: Vec<f64>,
    /// Why it stopped, in words.
    pub termination: String,
    /// Whether it reported convergence.
    pub converged: bool,
}

/// Run Levenberg-Marquardt on `model` from `start` (physical values within the bounds).
pub fn calibrate(model: &TorqueModel<'_>, start: &[f64]) -> Calibration {
    let maps: Vec<Map> = model.free.iter().map(|f| Map::new(f.bounds)).collect();
    let measured = model.measured();
    let u0 = DVector::from_iterator(
        start.len(),
        start.iter().zip(&maps).map(|(x, m)| m.to_u(*x)),
    );
    let problem = Problem {
        model,
        maps: &maps,
        measured: &measured,
        u: u0,
        last: Mutex::new(None),
    };
    let (done, report) = LevenbergMarquardt::new()
        .with_ftol(1e-7)
        .with_xtol(1e-7)
        .with_patience(30)
        .minimize(problem);
    Calibration {
        values: done.x_of(&done.u),
        termination: termination_words(&report.termination),
        converged: report.termination.was_successful(),
    }
}

/// The `i`-th point of a Halton sequence in `dims` dimensions (bases 2, 3, 5, ...): spread-out,
/// reproducible start points without a random generator.
fn halton(i: usize, dims: usize) -> Vec<f64> {
    const PRIMES: [usize; 12] = [2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37];
    (0..dims)
        .map(|d| {
            let b = PRIMES[d % PRIMES.len()];
            let (mut f, mut r, mut k) = (1.0, 0.0, i);
            while k > 0 {
                f /= b as f64;
                r += f * (k % b) as f64;
                k /= b;
            }
            r
        })
        .collect()
}

/// The start points: the law set's values, then Halton points over the bounds (kept 5% away
/// from them, where the change of variable is flat).
fn start_points(free: &[FreeParam], n: usize) -> Vec<Vec<f64>> {
    let maps: Vec<Map> = free.iter().map(|f| Map::new(f.bounds)).collect();
    let mut out = vec![free.iter().map(|f| f.value).collect::<Vec<f64>>()];
    for i in 1..n {
        let h = halton(i, free.len());
        out.push(
            h.iter()
                .zip(&maps)
                .map(|(s, m)| m.at_unit(0.05 + 0.9 * s))
                .collect(),
        );
    }
    out
}

/// Which bound, if any, `x` ended on (within 0.1% of the range, in the optimiser's scale).
pub fn bound_hit(x: f64, bounds: [f64; 2]) -> Option<String> {
    let s = Map::new(bounds).unit(x);
    if s <= 1e-3 {
        Some("lower".into())
    } else if s >= 1.0 - 1e-3 {
        Some("upper".into())
    } else {
        None
    }
}

/// Calibrate `free` parameters of `lawset` on `rig` to the points of `runs` (one parameter set
/// for all of them, each point at its own oil temperature). Returns the report and the law set
/// with the fitted values written in.
///
/// The laws come from plugins, so this example is compiled but not run here.
///
/// ```no_run
/// use std::path::{Path, PathBuf};
/// use tribo_config::{bundled, lawset::LawSet, rig::load_rig};
/// use tribo_plugin_api::loader::discover;
/// use tribo_studies::fit::{fit, FitOptions};
/// use tribo_studies::study::DataRun;
///
/// let rig = load_rig(Path::new(bundled::DEFAULT_RIG), &[])?;
/// let set = LawSet::load("stribeck-duty")?;
/// let runs = [DataRun::read(bundled::DEFAULT_DATA)?];
/// let registry = discover(&[PathBuf::from("target/release")])?;
/// // The parameters the law set marks `free`, with their bounds and start values.
/// let free = set.free_params(&registry, None)?;
/// let options = FitOptions { cross_validate: false, ..FitOptions::default() };
/// let (report, fitted) = fit(&rig, &set, &free, &runs, &registry, &options)?;
/// for (name, value) in report.params.iter().zip(&report.values) {
///     println!("{name} = {value}");
/// }
/// println!("RMSE {:.4} N m", report.rmse_nm);
/// std::fs::write("fitted.toml", fitted.to_toml("calibrated")?)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn fit(
    rig: &Rig,
    lawset: &LawSet,
    free: &[FreeParam],
    runs: &[DataRun],
    registry: &LawRegistry,
    options: &FitOptions,
) -> Result<(FitResult, LawSet), StudyError> {
    // Every input checked before anything runs.
    crate::study::check_lawsets(rig, std::slice::from_ref(lawset), registry)?;
    for d in runs.iter().chain(&options.validate) {
        crate::study::check_data(rig, d)?;
    }
    let model = TorqueModel::new(rig, lawset, free, runs.to_vec(), registry);
    let data_error = |message: String| StudyError::Data {
        file: lawset.path.clone(),
        line: None,
        message,
    };
    // The law set's own start point must run; a failure there is the user's to fix.
    let start: Vec<f64> = free.iter().map(|f| f.value).collect();
    if let Err(e) = model.torques(&start) {
        return Err(data_error(format!("the start values do not run: {e}")));
    }
    let measured = model.measured();
    let outcomes = run_starts(&model, free, options.starts.max(1), &measured);
    let best = outcomes
        .iter()
        .enumerate()
        .filter_map(|(i, o)| o.2.map(|r| (i, r)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
        .ok_or_else(|| {
            data_error(format!(
                "no start point reached values that run: {}",
                model.failures().1.unwrap_or_default()
            ))
        })?;
    let (best_start, cal, _) = &outcomes[best];
    let x = cal.values.clone();
    let torques = model
        .torques(&x)
        .map_err(|e| data_error(format!("the fitted values do not run: {e}")))?;
    let (residuals_nm, rmse_nm, _) = errors(&torques, &measured);
    let on_bound: Vec<bool> = x
        .iter()
        .zip(free)
        .map(|(v, f)| bound_hit(*v, f.bounds).is_some())
        .collect();
    let unc = uncertainty_within_bounds(&model, &x, &residuals_nm, &on_bound);
    let scores = score::scores_for_fit(&model, &x, &residuals_nm, options.cross_validate);
    let fitted = lawset.with_values(free, &x);
    let validation = options
        .validate
        .iter()
        .map(|v| score::validate(rig, &fitted, v, registry, true))
        .collect::<Result<Vec<_>, _>>()?;

    let at_bound: Vec<Option<String>> = x
        .iter()
        .zip(free)
        .map(|(v, f)| bound_hit(*v, f.bounds))
        .collect();
    let start_outcomes: Vec<StartOutcome> = outcomes
        .iter()
        .map(|(s, c, r)| StartOutcome {
            start: s.clone(),
            values: c.values.clone(),
            rmse_nm: *r,
            termination: c.termination.clone(),
        })
        .collect();
    let (failed, first_failure) = model.failures();
    let warnings = fit_warnings(FitFindings {
        free,
        uncertainty: &unc,
        at_bound: &at_bound,
        failed,
        evaluations: model.evaluations(),
        first_failure: first_failure.as_deref(),
        calibration: cal,
        starts: &start_outcomes,
        rmse_nm,
        scores: &scores,
    });
    let run_fits = run_fits(runs, &measured, &torques, &residuals_nm, &unc);
    Ok((
        FitResult {
            lawset: lawset.name().into(),
            params: free.iter().map(|f| f.id.clone()).collect(),
            start: best_start.clone(),
            values: x,
            bounds: free.iter().map(|f| f.bounds).collect(),
            at_bound,
            std_dev: unc.std_dev.clone(),
            uncertainty: unc,
            speeds_rpm: runs
                .iter()
                .flat_map(|r| r.rows.iter().map(|d| d.speed_rpm))
                .collect(),
            measured_nm: measured,
            model_nm: torques,
            residuals_nm,
            rmse_nm,
            runs: run_fits,
            scores,
            validation,
            evaluations: model.evaluations(),
            failed_evaluations: failed,
            first_failure,
            termination: cal.termination.clone(),
            converged: cal.converged,
            starts: start_outcomes,
            warnings,
        },
        fitted,
    ))
}

/// Every start point calibrated (in parallel): start, outcome, RMSE reached (if it runs).
fn run_starts(
    model: &TorqueModel<'_>,
    free: &[FreeParam],
    n: usize,
    measured: &[f64],
) -> Vec<(Vec<f64>, Calibration, Option<f64>)> {
    start_points(free, n)
        .into_par_iter()
        .map(|s| {
            let c = calibrate(model, &s);
            let rmse = model
                .torques(&c.values)
                .ok()
                .map(|t| errors(&t, measured).1);
            (s, c, rmse)
        })
        .collect()
}

/// What a calibration found that the user must be told.
struct FitFindings<'f> {
    free: &'f [FreeParam],
    uncertainty: &'f Uncertainty,
    at_bound: &'f [Option<String>],
    failed: usize,
    evaluations: usize,
    first_failure: Option<&'f str>,
    calibration: &'f Calibration,
    starts: &'f [StartOutcome],
    rmse_nm: f64,
    scores: &'f Scores,
}

/// The warnings of a calibration: undetermined parameters, bounds reached, trial points that
/// did not run, no convergence, the spread of the start points, what the scores cannot say.
fn fit_warnings(f: FitFindings<'_>) -> Vec<String> {
    let mut warnings = f.uncertainty.statements.clone();
    for (p, b) in f.free.iter().zip(f.at_bound) {
        if let Some(side) = b {
            warnings.push(format!(
                "{}: ended on its {side} bound ({:?}); the data push it beyond the range you allowed, so the value is the bound, not an estimate",
                p.id, p.bounds
            ));
        }
    }
    if f.failed > 0 {
        warnings.push(format!(
            "{} of {} trial points did not run and were steered away from; the first: {}",
            f.failed,
            f.evaluations,
            f.first_failure.unwrap_or("(no message)")
        ));
    }
    if !f.calibration.converged {
        warnings.push(format!(
            "the optimiser did not converge: {}",
            f.calibration.termination
        ));
    }
    if f.starts.len() > 1 {
        warnings.extend(start_spread(f.free, f.starts, f.rmse_nm));
    }
    warnings.extend(f.scores.notes.iter().cloned());
    warnings
}

/// Each data run's points, residuals and band, cut from the concatenated vectors.
fn run_fits(
    runs: &[DataRun],
    measured: &[f64],
    torques: &[f64],
    residuals: &[f64],
    unc: &Uncertainty,
) -> Vec<RunFit> {
    let mut offset = 0;
    runs.iter()
        .map(|r| {
            let n = r.rows.len();
            let range = offset..offset + n;
            offset += n;
            let res = residuals[range.clone()].to_vec();
            let rmse = (res.iter().map(|e| e * e).sum::<f64>() / n.max(1) as f64).sqrt();
            RunFit {
                file: r.file.display().to_string(),
                speeds_rpm: r.rows.iter().map(|d| d.speed_rpm).collect(),
                oil_temp_c: r.rows.iter().map(|d| d.oil_temp_c).collect(),
                measured_nm: measured[range.clone()].to_vec(),
                model_nm: torques[range.clone()].to_vec(),
                residuals_nm: res,
                rmse_nm: rmse,
                band_half_width_nm: unc
                    .band_half_width_nm
                    .as_ref()
                    .map(|b| b[range.clone()].to_vec()),
            }
        })
        .collect()
}

/// How far apart the start points ended: distinct minima with near-equal error mean the data
/// do not single out one parameter set.
fn start_spread(free: &[FreeParam], starts: &[StartOutcome], best_rmse: f64) -> Vec<String> {
    let near: Vec<&StartOutcome> = starts
        .iter()
        .filter(|s| s.rmse_nm.is_some_and(|r| r <= 1.05 * best_rmse + 1e-12))
        .collect();
    let mut out = vec![format!(
        "{} of {} start points reached within 5% of the best RMSE ({:.4} N m)",
        near.len(),
        starts.len(),
        best_rmse
    )];
    for (k, f) in free.iter().enumerate() {
        let (lo, hi) = near
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
                (a.min(s.values[k]), b.max(s.values[k]))
            });
        let scale = lo.abs().max(hi.abs()).max(1e-300);
        if (hi - lo) / scale > 0.05 {
            out.push(format!(
                "{}: start points with near-best error end anywhere from {lo:.4e} to {hi:.4e}: not determined by these data",
                f.id
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halton_points_fill_the_unit_cube_without_repeats() {
        let pts: Vec<Vec<f64>> = (1..50).map(|i| halton(i, 3)).collect();
        for p in &pts {
            assert!(p.iter().all(|v| (0.0..1.0).contains(v)));
        }
        for (i, a) in pts.iter().enumerate() {
            for b in &pts[i + 1..] {
                assert_ne!(a, b);
            }
        }
        // Base 2 in the first dimension: 1/2, 1/4, 3/4, ...
        assert_eq!(halton(1, 1)[0], 0.5);
        assert_eq!(halton(2, 1)[0], 0.25);
        assert_eq!(halton(3, 1)[0], 0.75);
    }

    #[test]
    fn bound_map_round_trips_and_detects_bounds() {
        for b in [[0.0, 1.0], [1e-6, 1e-1], [-3.0, 5.0]] {
            let m = Map::new(b);
            for s in [0.1, 0.5, 0.9] {
                let x = m.at_unit(s);
                assert!((m.to_x(m.to_u(x)) - x).abs() <= 1e-9 * x.abs().max(1e-12));
            }
            assert_eq!(bound_hit(b[0], b).as_deref(), Some("lower"));
            assert_eq!(bound_hit(b[1], b).as_deref(), Some("upper"));
            assert_eq!(bound_hit(m.at_unit(0.5), b), None);
        }
    }
}
