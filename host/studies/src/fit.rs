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
    /// Latin-hypercube start points spread over the bounds, in addition to the law set's own
    /// values and the corners of the bounds ([`start_points`]); the best result is polished and
    /// kept.
    pub starts: usize,
    /// Whether to score the calibration out of sample (leave-one-out refits).
    pub cross_validate: bool,
    /// Data never used in fitting, scored with the fitted values.
    pub validate: Vec<DataRun>,
    /// Accept data whose `# rig:` names another rig (`--data-for-any-rig`).
    pub data_for_any_rig: bool,
}

/// Latin-hypercube start points when none are asked for (`tribo fit`, `tribo compare`).
pub const DEFAULT_STARTS: usize = 4;

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            starts: DEFAULT_STARTS,
            cross_validate: true,
            validate: Vec::new(),
            data_for_any_rig: false,
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
    /// Half-width of the linearised 95% confidence band of the model torque at each point, N m
    /// (`None` where the parameters are not determined).
    pub band_half_width_nm: Option<Vec<f64>>,
    /// The band as printed: on a log scale so it stays above zero
    /// ([`crate::uncertainty::log_band`]), lower edges, N m.
    #[serde(default)]
    pub band_lower_nm: Option<Vec<f64>>,
    /// Upper edges of that band, N m.
    #[serde(default)]
    pub band_upper_nm: Option<Vec<f64>>,
}

/// The outcome of one start point.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StartOutcome {
    /// Where the start point came from: `own values`, `corner`, `latin hypercube`, or
    /// `polish` (a second run from the best result).
    #[serde(default)]
    pub kind: String,
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
/// [`TorqueModel`] is the one the studies use; the multi-start search ([`search`]) works on any.
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

/// Residual given to a parameter set that does not run, N m: steers the optimiser away. Every
/// use is counted and reported.
const PENALTY_NM: f64 = 1e3;

/// The optimiser's view of an [`Objective`]: unbounded variables, residuals, a Jacobian.
struct Problem<'m> {
    model: &'m dyn Objective,
    maps: &'m [Map],
    measured: &'m [f64],
    u: DVector<f64>,
    /// The last point run and its torques: the optimiser asks for the Jacobian at the point
    /// whose residuals it has just computed.
    last: Mutex<Option<(Vec<f64>, Vec<f64>)>>,
}

impl Problem<'_> {
    fn x_of(&self, u: &DVector<f64>) -> Vec<f64> {
        u.iter().zip(self.maps).map(|(u, m)| m.to_x(*u)).collect()
    }

    fn torques_or_penalty(&self, x: &[f64]) -> Vec<f64> {
        self.model
            .model(x)
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

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
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
#[derive(Debug, Clone)]
pub struct Calibration {
    /// Values reached.
    pub values: Vec<f64>,
    /// Why it stopped, in words.
    pub termination: String,
    /// Whether it reported convergence.
    pub converged: bool,
}

/// Run Levenberg-Marquardt on `model` from `start` (physical values within the bounds).
pub fn calibrate(model: &dyn Objective, start: &[f64]) -> Calibration {
    let maps: Vec<Map> = model.bounds().into_iter().map(Map::new).collect();
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

/// Where a corner start sits, in unit coordinates of each range: just inside the bound, since
/// the change of variable is flat on the bound itself (a start there could not move), while
/// a minimum on the bound is still reached from here.
const CORNER_INSET: f64 = 0.02;

/// Corners used at most: all `2^k` up to four parameters, then this many of them.
const MAX_CORNERS: usize = 16;

/// A Latin hypercube of `n` points in `dims` dimensions in the unit cube: each dimension cut
/// into `n` equal strata, one point in the middle of each, the strata paired across dimensions
/// by a seeded shuffle (reproducible: the same points on every run).
pub fn latin_hypercube(n: usize, dims: usize) -> Vec<Vec<f64>> {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let mut rng = rand_xorshift::XorShiftRng::seed_from_u64(0x7472_6962_6f00 + dims as u64);
    let columns: Vec<Vec<usize>> = (0..dims)
        .map(|_| {
            let mut strata: Vec<usize> = (0..n).collect();
            strata.shuffle(&mut rng);
            strata
        })
        .collect();
    (0..n)
        .map(|i| {
            columns
                .iter()
                .map(|c| (c[i] as f64 + 0.5) / n as f64)
                .collect()
        })
        .collect()
}

/// The corners of the unit cube in `dims` dimensions (inset by [`CORNER_INSET`]): all of them
/// up to [`MAX_CORNERS`], else the two opposite extremes and corners picked by the bits of
/// spread-out integers.
fn corners(dims: usize) -> Vec<Vec<f64>> {
    let at = |bits: u64| -> Vec<f64> {
        (0..dims)
            .map(|d| {
                if bits >> (d % 64) & 1 == 1 {
                    1.0 - CORNER_INSET
                } else {
                    CORNER_INSET
                }
            })
            .collect()
    };
    if dims == 0 {
        return Vec::new();
    }
    if dims <= 4 {
        return (0..1u64 << dims).map(at).collect();
    }
    let mut picked = vec![0u64, u64::MAX];
    let mut k = 1u64;
    while picked.len() < MAX_CORNERS {
        // Golden-ratio multiples walk through the bit patterns without repeating early ones.
        let bits = k.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        k += 1;
        let mask = if dims >= 64 {
            u64::MAX
        } else {
            (1u64 << dims) - 1
        };
        if !picked.iter().any(|p| p & mask == bits & mask) {
            picked.push(bits);
        }
    }
    picked.into_iter().map(at).collect()
}

/// The start points of a calibration, each with where it came from: the law set's own values,
/// the corners of the bounds box, then `lhs` Latin-hypercube points over it. Spread over the
/// whole box so that a minimum on a bound is found even when the own values sit in the basin
/// of a minimum inside.
pub fn start_points(own: &[f64], bounds: &[[f64; 2]], lhs: usize) -> Vec<(&'static str, Vec<f64>)> {
    if bounds.is_empty() {
        return vec![("own values", own.to_vec())];
    }
    let maps: Vec<Map> = bounds.iter().copied().map(Map::new).collect();
    let physical =
        |unit: &[f64]| -> Vec<f64> { unit.iter().zip(&maps).map(|(s, m)| m.at_unit(*s)).collect() };
    let mut out = vec![("own values", own.to_vec())];
    out.extend(
        corners(bounds.len())
            .iter()
            .map(|c| ("corner", physical(c))),
    );
    out.extend(
        latin_hypercube(lhs, bounds.len())
            .iter()
            .map(|p| ("latin hypercube", physical(p))),
    );
    out
}

/// Root-mean-square of `model` minus `measured`.
fn rmse_of(model: &[f64], measured: &[f64]) -> f64 {
    errors(model, measured).1
}

/// The outcome of a multi-start search: every start's calibration and the polished best.
pub struct Search {
    /// Every start: where it came from, its values, the calibration, its RMSE (if it runs).
    pub outcomes: Vec<(&'static str, Vec<f64>, Calibration, Option<f64>)>,
    /// Index of the outcome the best result came from (before polishing).
    pub best: usize,
    /// The best result after a second optimiser run from it (kept only if no worse).
    pub result: Calibration,
    /// Its RMSE.
    pub rmse: f64,
}

/// Calibrate `model` from every start point of [`start_points`] (in parallel), take the best,
/// and polish it with a fresh optimiser run from there (the damping the first run ended with
/// can stop it short of a minimum on a bound). `None` if no start reached values that run.
pub fn search(model: &dyn Objective, own: &[f64], lhs: usize) -> Option<Search> {
    let measured = model.measured();
    let bounds = model.bounds();
    let mut outcomes: Vec<(&'static str, Vec<f64>, Calibration, Option<f64>)> =
        start_points(own, &bounds, lhs)
            .into_par_iter()
            .map(|(kind, s)| {
                let c = calibrate(model, &s);
                let rmse = model.model(&c.values).ok().map(|t| rmse_of(&t, &measured));
                (kind, s, c, rmse)
            })
            .collect();
    let best = outcomes
        .iter()
        .enumerate()
        .filter_map(|(i, o)| o.3.map(|r| (i, r)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)?;
    let (mut result, mut rmse) = (outcomes[best].2.clone(), outcomes[best].3?);
    let polished = calibrate(model, &result.values);
    let polished_rmse = model
        .model(&polished.values)
        .ok()
        .map(|t| rmse_of(&t, &measured));
    outcomes.push((
        "polish",
        result.values.clone(),
        polished.clone(),
        polished_rmse,
    ));
    if let Some(r) = polished_rmse.filter(|r| *r <= rmse) {
        (result, rmse) = (polished, r);
    }
    Some(Search {
        outcomes,
        best,
        result,
        rmse,
    })
}

/// How far the residuals must lean on a parameter at its bound, as the cosine between the
/// residual vector and the torque's sensitivity to it, before the bound counts as pushed: at
/// an optimum inside the range that cosine is zero (the gradient vanishes).
const PUSH_COSINE: f64 = 1e-3;

/// Whether the data push parameter `k` of `x` past its `side` bound: the sum of squares would
/// still fall beyond it. Its gradient there is `2 r . J_k`; the bound is pushed when that
/// points outwards and the cosine between the residuals `r` and the sensitivity `J_k` (a
/// difference into the range) exceeds [`PUSH_COSINE`]. A bound reached along a direction the
/// error does not change in (a valley the data cannot resolve) is not pushed.
fn pushed_past_bound(
    model: &TorqueModel<'_>,
    x: &[f64],
    residuals: &[f64],
    k: usize,
    side: &str,
) -> bool {
    let [lo, hi] = model.free()[k].bounds;
    let inward = if side == "lower" { 1.0 } else { -1.0 };
    let h = 1e-6 * (hi - lo).abs().max(1e-300);
    let mut xi = x.to_vec();
    xi[k] = (x[k] + inward * h).clamp(lo, hi);
    let (Ok(inside), Ok(at)) = (model.torques(&xi), model.torques(x)) else {
        // The range's inside does not run: the bound is what holds the fit.
        return true;
    };
    let step = xi[k] - x[k];
    if step == 0.0 {
        return true;
    }
    let jk: Vec<f64> = inside
        .iter()
        .zip(&at)
        .map(|(a, b)| (a - b) / step)
        .collect();
    let dot: f64 = residuals.iter().zip(&jk).map(|(r, j)| r * j).sum();
    let norms = residuals.iter().map(|r| r * r).sum::<f64>().sqrt()
        * jk.iter().map(|j| j * j).sum::<f64>().sqrt();
    if norms <= 0.0 {
        return false;
    }
    // dS/dx = 2 r . J_k: positive at a lower bound (S rises into the range), negative at an
    // upper one, when the data push outwards.
    inward * dot / norms > PUSH_COSINE
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
        crate::study::check_data_rig(rig, d, options.data_for_any_rig)?;
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
    let found = search(&model, &start, options.starts).ok_or_else(|| {
        data_error(format!(
            "no start point reached values that run: {}",
            model.failures().1.unwrap_or_default()
        ))
    })?;
    let best_start = &found.outcomes[found.best].1;
    let cal = &found.result;
    let x = cal.values.clone();
    let torques = model
        .torques(&x)
        .map_err(|e| data_error(format!("the fitted values do not run: {e}")))?;
    let (residuals_nm, rmse_nm, _) = errors(&torques, &measured);
    let at_bound: Vec<Option<String>> = x
        .iter()
        .zip(free)
        .map(|(v, f)| bound_hit(*v, f.bounds))
        .collect();
    // Held by its bound only where the data push it there; one that reached a bound along a
    // direction the error does not change in is analysed as inside its range.
    let held: Vec<bool> = at_bound
        .iter()
        .enumerate()
        .map(|(k, side)| {
            side.as_deref()
                .is_some_and(|side| pushed_past_bound(&model, &x, &residuals_nm, k, side))
        })
        .collect();
    let unc = uncertainty_within_bounds(&model, &x, &residuals_nm, &held);
    let scores = score::scores_for_fit(&model, &x, &residuals_nm, options.cross_validate);
    let fitted = lawset.with_values(free, &x);
    let validation = options
        .validate
        .iter()
        .map(|v| score::validate(rig, &fitted, v, registry, true))
        .collect::<Result<Vec<_>, _>>()?;

    let start_outcomes: Vec<StartOutcome> = found
        .outcomes
        .iter()
        .map(|(kind, s, c, r)| StartOutcome {
            kind: kind.to_string(),
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
        held: &held,
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

/// What a calibration found that the user must be told.
struct FitFindings<'f> {
    free: &'f [FreeParam],
    uncertainty: &'f Uncertainty,
    at_bound: &'f [Option<String>],
    held: &'f [bool],
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
    for ((p, b), held) in f.free.iter().zip(f.at_bound).zip(f.held) {
        match (b, held) {
            (Some(side), true) => warnings.push(format!(
                "{}: ended on its {side} bound ({:?}); the data push it beyond the range you allowed, so the value is the bound, not an estimate",
                p.id, p.bounds
            )),
            (Some(side), false) => warnings.push(format!(
                "{}: ended on its {side} bound ({:?}), but the error does not change as it moves back into its range: the bound is where a direction the data do not determine ended, not a limit the data push against",
                p.id, p.bounds
            )),
            _ => {}
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
            let half = unc
                .band_half_width_nm
                .as_ref()
                .map(|b| b[range.clone()].to_vec());
            let band = half
                .as_ref()
                .and_then(|h| crate::uncertainty::log_band(&torques[range.clone()], h));
            let (band_lower_nm, band_upper_nm) = band.unzip();
            RunFit {
                file: r.file.display().to_string(),
                speeds_rpm: r.rows.iter().map(|d| d.speed_rpm).collect(),
                oil_temp_c: r.rows.iter().map(|d| d.oil_temp_c).collect(),
                measured_nm: measured[range.clone()].to_vec(),
                model_nm: torques[range.clone()].to_vec(),
                residuals_nm: res,
                rmse_nm: rmse,
                band_half_width_nm: half,
                band_lower_nm,
                band_upper_nm,
            }
        })
        .collect()
}

/// How far apart the start points ended: distinct minima with near-equal error mean the data
/// do not single out one parameter set.
fn start_spread(free: &[FreeParam], starts: &[StartOutcome], best_rmse: f64) -> Vec<String> {
    let starts: Vec<&StartOutcome> = starts.iter().filter(|s| s.kind != "polish").collect();
    let near: Vec<&StartOutcome> = starts
        .iter()
        .copied()
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
    fn latin_hypercube_puts_one_point_in_every_stratum_of_every_dimension() {
        for (n, dims) in [(1, 1), (5, 3), (8, 2), (13, 6)] {
            let pts = latin_hypercube(n, dims);
            assert_eq!(pts.len(), n);
            for d in 0..dims {
                let mut strata: Vec<usize> = pts
                    .iter()
                    .map(|p| (p[d] * n as f64).floor() as usize)
                    .collect();
                strata.sort_unstable();
                assert_eq!(strata, (0..n).collect::<Vec<_>>(), "n {n}, dimension {d}");
            }
        }
        // Reproducible: the same design on every call.
        assert_eq!(latin_hypercube(6, 3), latin_hypercube(6, 3));
    }

    #[test]
    fn corners_are_all_vertices_up_to_four_dimensions_and_distinct_beyond() {
        for dims in 1..=4 {
            let c = corners(dims);
            assert_eq!(c.len(), 1 << dims);
            for (i, a) in c.iter().enumerate() {
                assert!(a
                    .iter()
                    .all(|v| *v == CORNER_INSET || *v == 1.0 - CORNER_INSET));
                assert!(c[i + 1..].iter().all(|b| b != a));
            }
        }
        let c = corners(6);
        assert_eq!(c.len(), MAX_CORNERS);
        assert!(c.contains(&vec![CORNER_INSET; 6]) && c.contains(&vec![1.0 - CORNER_INSET; 6]));
        for (i, a) in c.iter().enumerate() {
            assert!(c[i + 1..].iter().all(|b| b != a));
        }
    }

    /// Residuals with a minimum inside the range and a lower one on its upper bound, in the
    /// first parameter; the second has a plain minimum inside. Known optimum: x0 = 1 (the
    /// bound), x1 = 0.4.
    struct BoundOptimum;

    impl BoundOptimum {
        /// Sum of squares along x0: `(x - 0.3)^2 + 4 (1 - s(x))^2` with a steep logistic step
        /// `s` at 0.9. Near 0.3 the step is flat (`s` ~ 1e-5), so 0.3 is a minimum (4.0);
        /// past the step the second term vanishes and at x = 1 the sum is 0.55, still falling
        /// (its slope there is -0.6), so the bound holds the optimum.
        fn residuals(x: f64) -> [f64; 2] {
            let s = 1.0 / (1.0 + (-(x - 0.9) / 0.05).exp());
            [x - 0.3, 2.0 * (1.0 - s)]
        }
    }

    impl Objective for BoundOptimum {
        fn bounds(&self) -> Vec<[f64; 2]> {
            vec![[0.0, 1.0], [0.0, 1.0]]
        }
        fn measured(&self) -> Vec<f64> {
            vec![0.0; 3]
        }
        fn model(&self, x: &[f64]) -> Result<Vec<f64>, String> {
            let [a, b] = Self::residuals(x[0]);
            Ok(vec![a, b, x[1] - 0.4])
        }
    }

    #[test]
    fn multi_start_finds_a_global_optimum_on_a_bound_past_a_local_one_inside() {
        let own = [0.28, 0.9];
        // From the own values alone the optimiser settles in the inner minimum: the case the
        // spread start points exist for.
        let local = calibrate(&BoundOptimum, &own);
        assert!((local.values[0] - 0.3).abs() < 1e-3, "{:?}", local.values);
        let found = search(&BoundOptimum, &own, 4).expect("runs");
        let x = &found.result.values;
        assert_eq!(
            bound_hit(x[0], [0.0, 1.0]).as_deref(),
            Some("upper"),
            "{x:?}"
        );
        assert!((x[1] - 0.4).abs() < 1e-4, "{x:?}");
        let [a, b] = BoundOptimum::residuals(1.0);
        let best = ((a * a + b * b) / 3.0).sqrt();
        assert!(
            (found.rmse - best).abs() < 1e-3 * best,
            "{} vs {best}",
            found.rmse
        );
        // Every kind of start is there: own values, 4 corners, 4 Latin-hypercube points, and
        // the polish of the best.
        let kinds: Vec<&str> = found.outcomes.iter().map(|o| o.0).collect();
        assert_eq!(kinds.iter().filter(|k| **k == "corner").count(), 4);
        assert_eq!(kinds.iter().filter(|k| **k == "latin hypercube").count(), 4);
        assert_eq!(kinds.first(), Some(&"own values"));
        assert_eq!(kinds.last(), Some(&"polish"));
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
