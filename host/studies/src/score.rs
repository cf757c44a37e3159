//! Out-of-sample scores: what a law set predicts at conditions it was not fitted to.
//!
//! - **Leave-one-out cross-validation**: for each data point, refit the free parameters
//!   without it (starting from the full fit) and predict it; the RMSE of those predictions is
//!   the figure comparisons rank by. A set without free parameters is not fitted, so its
//!   cross-validated error equals its in-sample error.
//! - **Information criteria** on the in-sample residual sum of squares `RSS` of `n` points with
//!   `k` free parameters, counting the noise variance as one more estimated parameter
//!   (`p = k + 1`, the least-squares convention of Burnham and Anderson, *Model Selection and
//!   Multimodel Inference*, 2002): `AIC = n ln(RSS/n) + 2p`, `AICc = AIC + 2p(p+1)/(n-p-1)`
//!   (undefined when `n <= p + 1`), `BIC = n ln(RSS/n) + p ln n`. Lower is better; only
//!   differences between sets on the same data mean anything.
//! - **Validation data** (`--validate`): points never used in fitting, scored as they are.
//!
//! Refits and predictions use steady-state runs, the fit's own model (steady state agrees with
//! the full cycle to about 1e-4 relative on the bundled rig; `tests/study.rs`).

use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tribo_plugin_api::loader::LawRegistry;

use crate::calibrate::calibrate;
use crate::error::StudyError;
use crate::inputs::{errors, prepare, run_rig, DataRow, DataRun};
use crate::model::TorqueModel;
use tribo_config::lawset::LawSet;
use tribo_config::rig::Rig;

/// Two sets whose torques differ by at most this at every data point give "the same torques",
/// N m: a fiftieth of the bundled data's declared noise, far below anything a torque
/// transducer resolves.
pub const SAME_TORQUE_NM: f64 = 1e-3;

/// How a set's free parameters entered a comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum CalibrationStatus {
    /// Calibrated on the comparison's data before it was scored (as `tribo fit` does).
    #[serde(rename = "fitted")]
    Fitted,
    /// Kept at the law-set file's values (`--no-fit`), and scored as they are.
    #[serde(rename = "not fitted")]
    NotFitted,
    /// The set has no free parameters.
    #[serde(rename = "no free parameters")]
    NoFreeParameters,
}

impl CalibrationStatus {
    /// The words used in tables, CSV and plot legends.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Fitted => "fitted",
            Self::NotFitted => "not fitted",
            Self::NoFreeParameters => "no free parameters",
        }
    }
}

/// Out-of-sample and information-criterion scores of one law set on one data set.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Scores {
    /// Data points.
    pub points: usize,
    /// Free parameters (fitted to the data).
    pub free_params: usize,
    /// Parameters tuned to these data outside Tribo (the law set's `prior_fit`); counted by
    /// the information criteria, and they leave no out-of-sample error to compute.
    pub prior_fitted_params: usize,
    /// In-sample root-mean-square error, N m.
    pub rmse_nm: f64,
    /// Leave-one-out cross-validated RMSE, N m (`None` if not computed or a fold failed).
    pub cv_rmse_nm: Option<f64>,
    /// Each point's leave-one-out prediction error (prediction minus measurement), N m.
    pub cv_errors_nm: Vec<Option<f64>>,
    /// Akaike information criterion.
    pub aic: Option<f64>,
    /// AIC with the small-sample correction; `None` when there are too few points for it.
    pub aicc: Option<f64>,
    /// Bayesian information criterion.
    pub bic: Option<f64>,
    /// What the scores cannot say, in words.
    pub notes: Vec<String>,
}

/// A law set scored on data never used in fitting.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Validation {
    /// The data file.
    pub file: String,
    /// Speeds, rpm.
    pub speeds_rpm: Vec<f64>,
    /// Oil temperatures, C.
    pub oil_temp_c: Vec<f64>,
    /// Measured torque, N m.
    pub measured_nm: Vec<f64>,
    /// Model torque, N m.
    pub model_nm: Vec<f64>,
    /// Model minus measurement, N m.
    pub errors_nm: Vec<f64>,
    /// Root-mean-square error, N m.
    pub rmse_nm: f64,
    /// Largest absolute error, N m.
    pub max_abs_error_nm: f64,
}

/// AIC, AICc and BIC for `n` points, residual sum of squares `rss` and `k` free parameters
/// (see the module documentation for the convention).
pub fn information_criteria(
    rss: f64,
    n: usize,
    k: usize,
) -> (Option<f64>, Option<f64>, Option<f64>) {
    if n == 0 || rss.is_nan() {
        return (None, None, None);
    }
    let nf = n as f64;
    let p = (k + 1) as f64;
    // A perfect fit has RSS = 0 and ln 0 = -inf: the criteria then say nothing useful.
    let ll = nf * (rss.max(1e-300) / nf).ln();
    let aic = ll + 2.0 * p;
    let aicc = (nf - p - 1.0 > 0.0).then(|| aic + 2.0 * p * (p + 1.0) / (nf - p - 1.0));
    let bic = ll + p * nf.ln();
    (Some(aic), aicc, Some(bic))
}

/// The points of `runs` without point `skip` (in data order), and that point as a run of its
/// own.
fn split(runs: &[DataRun], skip: usize) -> (Vec<DataRun>, DataRun) {
    let mut rest = Vec::new();
    let mut left = None;
    let mut i = 0;
    for r in runs {
        let mut rows = Vec::new();
        for d in &r.rows {
            if i == skip {
                left = Some(r.with_rows(vec![*d]));
            } else {
                rows.push(*d);
            }
            i += 1;
        }
        if !rows.is_empty() {
            rest.push(r.with_rows(rows));
        }
    }
    let left = left.unwrap_or_else(|| DataRun {
        file: Default::default(),
        rows: Vec::new(),
        meta: Default::default(),
    });
    (rest, left)
}

/// Leave-one-out prediction errors of `model`'s law set, refitting from `x` without each point.
fn leave_one_out(
    model: &TorqueModel<'_>,
    rig: &Rig,
    lawset: &LawSet,
    registry: &LawRegistry,
    x: &[f64],
) -> Vec<Result<f64, String>> {
    let n = model.points();
    (0..n)
        .into_par_iter()
        .map(|i| {
            let (rest, left) = split(model.runs(), i);
            let measured = left.rows.first().map(|d| d.torque_nm).unwrap_or(f64::NAN);
            let fold = TorqueModel::new(rig, lawset, model.free(), rest, registry);
            // The fit's own tolerances: a looser budget stops folds part-way along a flat
            // valley and moved the six-parameter stribeck-duty set's figure by 4%.
            let cal = calibrate(&fold, x);
            let at = TorqueModel::new(rig, lawset, model.free(), vec![left], registry);
            let t = at.torques(&cal.values)?;
            Ok(t.first().copied().unwrap_or(f64::NAN) - measured)
        })
        .collect()
}

/// Scores of parameters `x` of `model` (with in-sample `residuals`); leave-one-out refits when
/// `cross_validate`.
pub fn scores_for_fit(
    model: &TorqueModel<'_>,
    x: &[f64],
    residuals: &[f64],
    cross_validate: bool,
) -> Scores {
    let (rig, lawset, registry) = model.parts();
    let n = residuals.len();
    let k = x.len();
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    let rmse = (rss / n.max(1) as f64).sqrt();
    let (aic, aicc, bic) = information_criteria(rss, n, k);
    let mut notes = Vec::new();
    if aicc.is_none() {
        notes.push(format!(
            "AICc is undefined: {n} points leave no room for the small-sample correction with {k} free parameters plus the noise variance"
        ));
    }
    let (cv_rmse_nm, cv_errors_nm) = if k == 0 {
        (Some(rmse), residuals.iter().map(|r| Some(*r)).collect())
    } else if !cross_validate {
        notes.push("cross-validation not computed (--no-cv)".into());
        (None, vec![None; n])
    } else if n < 2 {
        notes.push("cross-validation needs at least two points".into());
        (None, vec![None; n])
    } else {
        let folds = leave_one_out(model, rig, lawset, registry, x);
        let errs: Vec<Option<f64>> = folds.iter().map(|r| r.as_ref().ok().copied()).collect();
        if let Some(e) = folds.iter().find_map(|r| r.as_ref().err()) {
            let failed = folds.iter().filter(|r| r.is_err()).count();
            notes.push(format!(
                "{failed} of {n} leave-one-out folds did not run, so no cross-validated error is given; the first: {e}"
            ));
            (None, errs)
        } else {
            let ss: f64 = errs.iter().flatten().map(|e| e * e).sum();
            (Some((ss / n as f64).sqrt()), errs)
        }
    };
    Scores {
        points: n,
        free_params: k,
        prior_fitted_params: 0,
        rmse_nm: rmse,
        cv_rmse_nm,
        cv_errors_nm,
        aic,
        aicc,
        bic,
        notes,
    }
}

/// Account for parameters tuned to the same data outside Tribo: the information criteria count
/// them, and no out-of-sample error can be computed because Tribo cannot refit them.
pub fn apply_prior_fit(
    scores: &mut Scores,
    residuals: &[f64],
    prior: &tribo_config::lawset::PriorFit,
) {
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    let k = scores.free_params + prior.parameters;
    let (aic, aicc, bic) = information_criteria(rss, residuals.len(), k);
    scores.prior_fitted_params = prior.parameters;
    scores.aic = aic;
    scores.aicc = aicc;
    scores.bic = bic;
    scores.cv_rmse_nm = None;
    scores.cv_errors_nm = vec![None; residuals.len()];
    scores.notes.retain(|n| !n.starts_with("AICc is undefined"));
    if aicc.is_none() {
        scores.notes.push(format!(
            "AICc is undefined: {} points cannot carry {k} tuned parameters plus the noise variance",
            residuals.len()
        ));
    }
    scores.notes.push(format!(
        "{} of its numbers were tuned to these same data outside Tribo ({}): its RMSE is in sample, and no out-of-sample error exists because Tribo cannot refit them; it ranks after the cross-validated sets",
        prior.parameters,
        if prior.source.is_empty() { "no source given" } else { prior.source.as_str() }
    ));
}

/// How a law set's torque moves when the oil warms: at each data point, the relative change of
/// the steady-state torque per +10 C, from runs 5 C below and above the point's temperature.
/// Lubrication physics gives a fall in full film (viscous shear scales with viscosity to a
/// power between 0.5 and 1) and at most a modest rise where a mixed regime loses film, so a
/// steep rise flags a law (or a calibration) to look at before trusting its verdict.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TemperatureResponse {
    /// Change of torque per +10 C at each data point, percent.
    pub percent_per_10c: Vec<f64>,
    /// The largest rise over the points, percent per 10 C.
    pub max_rise_percent_per_10c: f64,
}

/// Rise, percent per 10 C, above which `compare` flags a set's temperature response.
pub const TEMPERATURE_RISE_FLAG_PERCENT: f64 = 10.0;

/// The temperature response of `lawset` at the points of `data` (see [`TemperatureResponse`]).
pub fn temperature_response(
    rig: &Rig,
    lawset: &LawSet,
    data: &DataRun,
    registry: &LawRegistry,
) -> Result<TemperatureResponse, StudyError> {
    let (lo_c, hi_c) = tribo_core::oil::VALID_RANGE_C;
    let shifted = |dt: f64| {
        data.with_rows(
            data.rows
                .iter()
                .map(|d| DataRow {
                    oil_temp_c: (d.oil_temp_c + dt).clamp(lo_c, hi_c),
                    ..*d
                })
                .collect(),
        )
    };
    let (cold, warm) = (shifted(-5.0), shifted(5.0));
    let run = |d: &DataRun| validate(rig, lawset, d, registry, true).map(|v| v.model_nm);
    let (tc, tw) = (run(&cold)?, run(&warm)?);
    let percent_per_10c: Vec<f64> = tc
        .iter()
        .zip(&tw)
        .zip(cold.rows.iter().zip(&warm.rows))
        .map(|((c, w), (dc, dw))| {
            let span = (dw.oil_temp_c - dc.oil_temp_c).max(1e-9);
            let mid = 0.5 * (c + w);
            if mid.abs() < 1e-12 {
                0.0
            } else {
                100.0 * (w - c) / mid * 10.0 / span
            }
        })
        .collect();
    let max_rise = percent_per_10c
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    Ok(TemperatureResponse {
        percent_per_10c,
        max_rise_percent_per_10c: max_rise,
    })
}

/// Score `lawset` as it is on `data` (a run through the data's speeds at their oil
/// temperatures, steady state or the full cycle).
pub fn validate(
    rig: &Rig,
    lawset: &LawSet,
    data: &DataRun,
    registry: &LawRegistry,
    steady: bool,
) -> Result<Validation, StudyError> {
    let r = prepare(rig, lawset, Some(&data.rows))?;
    let run = run_rig(&r, registry, steady).map_err(|source| StudyError::Run {
        lawset: lawset.name().into(),
        error: Box::new(source),
    })?;
    let model: Vec<f64> = run
        .plateaus
        .iter()
        .map(|p| p.measured_torque_nm())
        .collect();
    let measured: Vec<f64> = data.rows.iter().map(|d| d.torque_nm).collect();
    let (errors_nm, rmse_nm, max_abs_error_nm) = errors(&model, &measured);
    Ok(Validation {
        file: display(&data.file),
        speeds_rpm: data.rows.iter().map(|d| d.speed_rpm).collect(),
        oil_temp_c: data.rows.iter().map(|d| d.oil_temp_c).collect(),
        measured_nm: measured,
        model_nm: model,
        errors_nm,
        rmse_nm,
        max_abs_error_nm,
    })
}

fn display(p: &Path) -> String {
    p.display().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn information_criteria_by_hand() {
        // n = 10, RSS = 0.5, k = 2 (p = 3): n ln(RSS/n) = 10 ln 0.05 = -29.957.
        let (aic, aicc, bic) = information_criteria(0.5, 10, 2);
        let ll = 10.0 * (0.05f64).ln();
        assert!((aic.expect("aic") - (ll + 6.0)).abs() < 1e-12);
        assert!((aicc.expect("aicc") - (ll + 6.0 + 24.0 / 6.0)).abs() < 1e-12);
        assert!((bic.expect("bic") - (ll + 3.0 * 10f64.ln())).abs() < 1e-12);
        // Six parameters on seven points: no small-sample correction possible.
        assert!(information_criteria(0.5, 7, 6).1.is_none());
    }

    #[test]
    fn split_leaves_out_exactly_one_point_across_runs() {
        let row = |s: f64| DataRow {
            speed_rpm: s,
            torque_nm: s / 1000.0,
            oil_temp_c: 80.0,
        };
        let runs = vec![
            DataRun {
                file: "a".into(),
                rows: vec![row(3000.0), row(4000.0)],
                meta: Default::default(),
            },
            DataRun {
                file: "b".into(),
                rows: vec![row(5000.0)],
                meta: Default::default(),
            },
        ];
        for skip in 0..3 {
            let (rest, left) = split(&runs, skip);
            let n: usize = rest.iter().map(|r| r.rows.len()).sum();
            assert_eq!(n, 2);
            assert_eq!(left.rows.len(), 1);
            assert!(rest
                .iter()
                .all(|r| r.rows.iter().all(|d| d.speed_rpm != left.rows[0].speed_rpm)));
        }
        // Leaving out the only point of run b drops that run.
        assert_eq!(split(&runs, 2).0.len(), 1);
    }
}
