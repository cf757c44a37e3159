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

use serde::{Deserialize, Serialize};
use tribo_config::lawset::{FreeParam, LawSet};
use tribo_config::rig::Rig;
use tribo_plugin_api::loader::LawRegistry;

use crate::calibrate::pushed_past_bound;
pub use crate::calibrate::{
    bound_hit, calibrate, latin_hypercube, search, start_points, Calibration, Search,
};
use crate::error::StudyError;
use crate::inputs::{errors, DataRun};
pub use crate::model::{Objective, TorqueModel};
use crate::score::{self, Scores, Validation};
use crate::uncertainty::{uncertainty_within_bounds, Uncertainty};

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
    crate::inputs::check_lawsets(rig, std::slice::from_ref(lawset), registry)?;
    for d in runs.iter().chain(&options.validate) {
        crate::inputs::check_data_rig(rig, d, options.data_for_any_rig)?;
        crate::inputs::check_data(rig, d)?;
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

/// The comment `tribo fit` (and Python's `fit`) writes above a calibrated law set: the rig, the
/// points and runs it was fitted to, its in-sample and leave-one-out RMSE, the parameters.
pub fn calibrated_header(rig: &Rig, result: &FitResult, runs: usize) -> String {
    format!(
        "Calibrated by `tribo fit` on rig {} against {} points in {} run(s): RMSE {:.4} N m in sample, {} N m leave-one-out.\nParameters fitted: {}",
        rig.file.name,
        result.measured_nm.len(),
        runs,
        result.rmse_nm,
        result
            .scores
            .cv_rmse_nm
            .map_or("(not computed)".to_string(), |v| format!("{v:.4}")),
        result.params.join(", ")
    )
}
