//! The studies users come for: a side-by-side comparison of law sets against measurements, the
//! response to a scaled body and to oil temperature. The data they run on and their errors are
//! in [`crate::inputs`] and [`crate::error`], re-exported here under the names front ends use.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use tribo_plugin_api::loader::LawRegistry;

pub use crate::error::{StudyError, SweepInputError};
pub use crate::inputs::{
    bundled_data_for, check_data, check_data_rig, check_lawsets, check_lawsets_described,
    check_unique_names, cycle_through, default_data, errors, parse_data, parse_meta, prepare,
    read_data, run_rig, set_with_laws, DataMeta, DataRow, DataRun, MAX_DATA_SPEED_RPM,
    MAX_DATA_TORQUE_NM, MIN_DATA_SPEED_RPM,
};
use crate::model::TorqueModel;
use crate::score::{self, Scores, TemperatureResponse, Validation};
pub use crate::score::{CalibrationStatus, SAME_TORQUE_NM};
use crate::uncertainty::Uncertainty;
use crate::verdict::{SetSummary, Verdict};
use tribo_config::lawset::{FreeParam, LawSet};
use tribo_config::rig::{readable, Rig, RigError};
use tribo_core::cycle::Segment;
use tribo_core::sim::RunResult;

/// One law set's results against the data.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SetResult {
    /// Law-set name.
    pub lawset: String,
    /// On a rig with a drivetrain, per data point: whether the transducer stayed within its
    /// rating there (its oscillation width and limit torque); a point outside it was measured
    /// outside the instrument's rating.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instrument_ok: Option<Vec<bool>>,
    /// Its file.
    pub file: String,
    /// The run.
    pub run: RunResult,
    /// Model minus measurement at each speed, N m.
    pub errors_nm: Vec<f64>,
    /// Root-mean-square error, N m (in sample: the set's parameters as they are).
    pub rmse_nm: f64,
    /// Largest absolute error, N m.
    pub max_abs_error_nm: f64,
    /// Place in the ranking by cross-validated RMSE (1 = best); sets tied with each other
    /// ([`SetResult::tie`]) share the place of the first of them.
    pub rank: usize,
    /// The sets this one cannot be told apart from on these data, and why (`None`: none).
    #[serde(default)]
    pub tie: Option<Tie>,
    /// Joints this set leaves without a law although another set of the comparison gives them
    /// one ([`mark_uncovered_joints`]): its torque lacks their friction, so its ranking is not
    /// like for like. Empty when it covers every joint the others do.
    #[serde(default)]
    pub uncovered_joints: Vec<String>,
    /// Out-of-sample scores: leave-one-out RMSE, free parameters, AICc, BIC.
    pub scores: Scores,
    /// The linearised uncertainty of the free parameters and the 95% band of the torque.
    pub uncertainty: Uncertainty,
    /// How the set's free parameters were treated: fitted to these data before scoring, kept
    /// at the file's values (`--no-fit`), or none to fit; with each parameter's estimate.
    pub calibration: SetCalibration,
    /// The law set with the fitted values, as TOML (fitted sets only; `compare` writes it as
    /// `fitted_<set>.toml` beside the results).
    pub fitted_lawset_toml: Option<String>,
    /// Lower edge of the 95% confidence band of the model torque at each speed, N m: the
    /// delta-method band of `ln T` mapped back, `T exp(-h/T)` with `h` the linearised
    /// half-width, so it stays above zero (see [`crate::uncertainty::log_band`]).
    pub band_lower_nm: Option<Vec<f64>>,
    /// Upper edge of the band, `T exp(h/T)`, N m.
    pub band_upper_nm: Option<Vec<f64>>,
    /// Whether the band is wider than the spread of the measured torques (then the data do not
    /// determine this set's prediction); `None` when there is no band.
    pub band_wider_than_data: Option<bool>,
    /// Why there is no band, in words (`None` when there is one).
    pub band_note: Option<String>,
    /// How the torque moves as the oil warms, at each data point.
    pub temperature_response: TemperatureResponse,
    /// Scores on data never used in fitting (`--validate`).
    pub validation: Vec<Validation>,
}

/// Sets a comparison cannot tell apart: their ranking errors differ by less than the data's
/// noise ([`rank_sets`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tie {
    /// The other sets of the tie, in ranking order.
    pub with: Vec<String>,
    /// Whether every set of the tie gives the same torque at every data point (within
    /// [`SAME_TORQUE_NM`]): then they are one model as far as these data go.
    pub same_torques: bool,
    /// The largest difference between the tied sets' ranking errors, N m.
    pub error_spread_nm: f64,
    /// The tolerance the tie used: the data's noise, N m.
    pub noise_nm: f64,
}

/// One free parameter of a set in a comparison.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ParamEstimate {
    /// `joint.law.param`.
    pub id: String,
    /// The law-set file's value (the fit's own start point).
    pub start: f64,
    /// The value scored: fitted, or the file's when not fitted.
    pub value: f64,
    /// The allowed range.
    pub bounds: [f64; 2],
    /// `lower` or `upper` when the value sits on that bound.
    pub at_bound: Option<String>,
    /// 1-sigma uncertainty, where the data determine it.
    pub std_dev: Option<f64>,
    /// Fitted inside its range with a 1-sigma uncertainty at most half its value
    /// ([`crate::uncertainty::POORLY_DETERMINED`]).
    pub determined: bool,
}

/// How a set's free parameters were treated in a comparison, and their values.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SetCalibration {
    /// Fitted, not fitted, or nothing to fit.
    pub status: CalibrationStatus,
    /// Each free parameter.
    pub params: Vec<ParamEstimate>,
    /// Why the optimiser stopped (fitted sets).
    pub termination: Option<String>,
}

impl SetCalibration {
    /// Parameters on a bound.
    pub fn on_bounds(&self) -> usize {
        self.params.iter().filter(|p| p.at_bound.is_some()).count()
    }
    /// Parameters the data do not determine (on a bound, or without a usable sigma).
    pub fn undetermined(&self) -> usize {
        self.params.iter().filter(|p| !p.determined).count()
    }
}

/// How a study runs the rig at each speed. Serialized (and displayed) as `steady` or
/// `transient`, the words the JSON has always used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RunMode {
    /// The periodic steady state at each plateau speed, computed directly.
    Steady,
    /// The whole test cycle, ramps included, measured over each plateau's window.
    Transient,
}

impl RunMode {
    /// [`RunMode::Steady`] if `steady`, else [`RunMode::Transient`] (the `--steady` flag).
    pub fn from_steady(steady: bool) -> Self {
        if steady {
            Self::Steady
        } else {
            Self::Transient
        }
    }

    /// The word used in JSON, tables and plot titles.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Steady => "steady",
            Self::Transient => "transient",
        }
    }
}

impl std::fmt::Display for RunMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A side-by-side comparison.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Comparison {
    /// Rig name.
    pub rig: String,
    /// Data file.
    pub data_file: String,
    /// The measurements.
    pub data: Vec<DataRow>,
    /// Steady state at each speed, or the full test cycle (`"steady"` or `"transient"` in JSON).
    pub mode: RunMode,
    /// What the ranking rests on, in words.
    pub ranked_by: String,
    /// The data's noise, one standard deviation, N m, as the data file declares it.
    pub noise_nm: Option<f64>,
    /// What the scores let a user conclude, in one sentence ([`crate::verdict`]).
    pub verdict: Verdict,
    /// Each law set, in the order given.
    pub sets: Vec<SetResult>,
    /// Law sets that gave no results (only when sets run in separate processes; in one
    /// process the first failure ends the study).
    #[serde(default)]
    pub failed: Vec<FailedSet>,
}

/// How `compare` scores the law sets.
#[derive(Debug, Clone)]
pub struct CompareOptions {
    /// Steady state at each speed instead of the full test cycle.
    pub steady: bool,
    /// Skip the leave-one-out refits (rank by in-sample RMSE, and say so).
    pub no_cv: bool,
    /// Score sets with free parameters at the file's values instead of fitting them first
    /// (each is then labelled "not fitted").
    pub no_fit: bool,
    /// Latin-hypercube start points of each set's calibration (besides its own values and the
    /// corners of its bounds).
    pub starts: usize,
    /// Data never used in fitting, scored separately.
    pub validate: Vec<DataRun>,
    /// Accept data whose `# rig:` names another rig (`--data-for-any-rig`).
    pub data_for_any_rig: bool,
    /// On a rig with a drivetrain, fit and score each set on the points its transducer
    /// measured within its rating only (`--trusted-points-only`); the others are still run
    /// and reported, marked by `instrument_ok`.
    pub trusted_points_only: bool,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            steady: false,
            no_cv: false,
            no_fit: false,
            starts: crate::fit::DEFAULT_STARTS,
            validate: Vec::new(),
            data_for_any_rig: false,
            trusted_points_only: false,
        }
    }
}

/// The points of `data` the transducer measured within its rating with law set `ls` at the
/// file's values (a steady pre-run at the data's points); all of them on a rig without a
/// drivetrain or unless `options.trusted_points_only`.
fn trusted_rows(
    rig: &Rig,
    ls: &LawSet,
    data: &DataRun,
    registry: &LawRegistry,
    options: &CompareOptions,
) -> Result<DataRun, StudyError> {
    if !options.trusted_points_only || rig.file.drivetrain.is_none() {
        return Ok(data.clone());
    }
    let r = prepare(rig, ls, Some(&data.rows))?;
    let run = run_rig(&r, registry, true).map_err(|e| StudyError::Run {
        lawset: ls.name().into(),
        error: Box::new(e),
    })?;
    let ok = instrument_ok(&run).unwrap_or_default();
    let rows: Vec<DataRow> = data
        .rows
        .iter()
        .zip(&ok)
        .filter(|(_, ok)| **ok)
        .map(|(row, _)| *row)
        .collect();
    if rows.len() < 2 {
        return Err(StudyError::Data {
            file: data.file.clone(),
            line: None,
            message: format!(
                "--trusted-points-only: law set `{}` leaves {} of {} points within the transducer's rating, too few to fit or score",
                ls.name(),
                rows.len(),
                data.rows.len()
            ),
        });
    }
    Ok(DataRun {
        rows,
        ..data.clone()
    })
}

/// One law set fitted to `data` (when it has free parameters and fitting is on), run against
/// it and scored: in-sample errors, out-of-sample scores, its band, its temperature response
/// and any validation data, all with the values it is ranked by.
fn score_set(
    rig: &Rig,
    ls: &LawSet,
    free: &[FreeParam],
    data: &DataRun,
    registry: &LawRegistry,
    options: &CompareOptions,
    spread: f64,
) -> Result<SetResult, StudyError> {
    let all = data;
    let trusted = trusted_rows(rig, ls, data, registry, options)?;
    let data = &trusted;
    let measured: Vec<f64> = all.rows.iter().map(|r| r.torque_nm).collect();
    let fitted = if free.is_empty() || options.no_fit {
        None
    } else {
        let fit_options = crate::fit::FitOptions {
            starts: options.starts,
            cross_validate: !options.no_cv,
            validate: Vec::new(),
            // The comparison has checked the data's rig already.
            data_for_any_rig: true,
        };
        Some(crate::fit::fit(
            rig,
            ls,
            free,
            std::slice::from_ref(data),
            registry,
            &fit_options,
        )?)
    };
    let used = fitted.as_ref().map_or(ls, |(_, l)| l);
    let r = prepare(rig, used, Some(&all.rows))?;
    let run = run_rig(&r, registry, options.steady).map_err(|e| StudyError::Run {
        lawset: ls.name().into(),
        error: Box::new(e),
    })?;
    let model: Vec<f64> = run
        .plateaus
        .iter()
        .map(|p| p.measured_torque_nm())
        .collect();
    let (errors_nm, mut rmse_nm, max_abs_error_nm) = errors(&model, &measured);
    let instrument_ok = instrument_ok(&run);
    // The points scored: the trusted ones under `--trusted-points-only`, else all.
    let subset = data.rows.len() < all.rows.len();
    let kept: Vec<f64> = if subset {
        errors_nm
            .iter()
            .zip(instrument_ok.iter().flatten())
            .filter(|(_, ok)| **ok)
            .map(|(e, _)| *e)
            .collect()
    } else {
        errors_nm.clone()
    };
    if subset {
        rmse_nm = (kept.iter().map(|x| x * x).sum::<f64>() / kept.len().max(1) as f64).sqrt();
    }
    let (mut scores, mut unc, calibration) = match &fitted {
        Some((f, _)) => (
            f.scores.clone(),
            f.uncertainty.clone(),
            fitted_calibration(f, free),
        ),
        None => {
            // Nothing fitted: scored as it is, like a set without free parameters.
            let tm = TorqueModel::new(rig, used, &[], vec![data.clone()], registry);
            let mut scores = score::scores_for_fit(&tm, &[], &kept, !options.no_cv);
            let status = if free.is_empty() {
                CalibrationStatus::NoFreeParameters
            } else {
                scores.notes.push(format!(
                    "not fitted (--no-fit): its {} free parameter{} keep the law-set file's values and it is scored as they are",
                    free.len(),
                    if free.len() == 1 { "" } else { "s" }
                ));
                CalibrationStatus::NotFitted
            };
            let calibration = SetCalibration {
                status,
                params: free
                    .iter()
                    .map(|f| ParamEstimate {
                        id: f.id.clone(),
                        start: f.value,
                        value: f.value,
                        bounds: f.bounds,
                        at_bound: crate::fit::bound_hit(f.value, f.bounds),
                        std_dev: None,
                        determined: false,
                    })
                    .collect(),
                termination: None,
            };
            (scores, Uncertainty::none(errors_nm.len()), calibration)
        }
    };
    // The in-sample figure is the compare run's own (steady or full cycle).
    scores.rmse_nm = rmse_nm;
    let prior = ls.prior_fit_on(&data.file);
    if let Some(prior) = prior {
        score::apply_prior_fit(&mut scores, &kept, prior);
        // Tuned elsewhere: no covariance of those numbers exists here.
        unc.band_half_width_nm = None;
    }
    if subset {
        // The fit's band covers the trusted points only, not every point the run reports.
        unc.band_half_width_nm = None;
    }
    let band = unc
        .band_half_width_nm
        .as_ref()
        .and_then(|h| crate::uncertainty::log_band(&model, h));
    let band_note = band
        .is_none()
        .then(|| band_missing(&calibration, prior, &unc, &model, data));
    let band_wider_than_data = band.as_ref().map(|(lo, hi)| {
        let widest = lo.iter().zip(hi).map(|(l, h)| h - l).fold(0.0, f64::max);
        widest > spread
    });
    let (band_lower_nm, band_upper_nm) = band.unzip();
    let validation = options
        .validate
        .iter()
        .map(|v| score::validate(rig, used, v, registry, options.steady))
        .collect::<Result<Vec<_>, _>>()?;
    let temperature_response = score::temperature_response(rig, used, data, registry)?;
    if temperature_response.max_rise_percent_per_10c > score::TEMPERATURE_RISE_FLAG_PERCENT {
        let (i, _) = temperature_response
            .percent_per_10c
            .iter()
            .enumerate()
            .fold(
                (0, f64::NEG_INFINITY),
                |a, (i, v)| if *v > a.1 { (i, *v) } else { a },
            );
        scores.notes.push(format!(
            "its torque rises {:.0}% per 10 C of oil warming at {:.0} rpm: full-film friction falls as oil thins and a mixed regime losing film rarely gives more than {:.0}%; check the law's regime transition before trusting this set away from the measured temperatures",
            temperature_response.max_rise_percent_per_10c,
            data.rows[i].speed_rpm,
            score::TEMPERATURE_RISE_FLAG_PERCENT
        ));
    }
    let fitted_lawset_toml = match &fitted {
        Some((f, l)) => Some(
            l.to_toml(&format!(
                "Fitted by `tribo compare` on rig {} against {}: RMSE {:.4} N m in sample, {} N m leave-one-out.\nParameters fitted: {}",
                rig.file.name,
                data.file.display(),
                f.rmse_nm,
                f.scores
                    .cv_rmse_nm
                    .map_or("(not computed)".to_string(), |v| format!("{v:.4}")),
                f.params.join(", ")
            ))
            .map_err(|e| StudyError::Data {
                file: ls.path.clone(),
                line: None,
                message: format!("the fitted law set cannot be written as TOML: {e}"),
            })?,
        ),
        None => None,
    };
    Ok(SetResult {
        lawset: ls.name().into(),
        file: ls.path.display().to_string(),
        run,
        errors_nm,
        rmse_nm,
        max_abs_error_nm,
        rank: 0,
        tie: None,
        uncovered_joints: Vec::new(),
        scores,
        uncertainty: unc,
        calibration,
        fitted_lawset_toml,
        band_lower_nm,
        band_upper_nm,
        band_wider_than_data,
        band_note,
        temperature_response,
        validation,
        instrument_ok,
    })
}

/// Per plateau of `run`, whether the transducer stayed within its rating (`None` on a rig
/// without a drivetrain, whose measurement is not modelled).
fn instrument_ok(run: &RunResult) -> Option<Vec<bool>> {
    run.plateaus
        .iter()
        .map(|p| p.instrument.as_ref().map(|i| i.within_rating()))
        .collect()
}

/// A fitted set's parameters as a comparison reports them (`free`: as the file gives them).
fn fitted_calibration(f: &crate::fit::FitResult, free: &[FreeParam]) -> SetCalibration {
    let params = (0..f.params.len())
        .map(|k| {
            let std_dev = f.std_dev.get(k).copied().flatten();
            let value = f.values[k];
            let at_bound = f.at_bound.get(k).cloned().flatten();
            ParamEstimate {
                id: f.params[k].clone(),
                start: free.get(k).map_or(f64::NAN, |p| p.value),
                value,
                bounds: f.bounds[k],
                determined: at_bound.is_none()
                    && std_dev.is_some_and(|sd| {
                        sd <= crate::uncertainty::POORLY_DETERMINED * value.abs()
                    }),
                at_bound,
                std_dev,
            }
        })
        .collect();
    SetCalibration {
        status: CalibrationStatus::Fitted,
        params,
        termination: Some(f.termination.clone()),
    }
}

/// Why a set has no 95% band, in words.
fn band_missing(
    calibration: &SetCalibration,
    prior: Option<&tribo_config::lawset::PriorFit>,
    unc: &Uncertainty,
    model: &[f64],
    data: &DataRun,
) -> String {
    let k = calibration.params.len();
    if let Some(p) = prior {
        return format!(
            "its {} numbers tuned to these data elsewhere have no covariance Tribo could estimate",
            p.parameters
        );
    }
    match calibration.status {
        CalibrationStatus::NoFreeParameters => {
            return "no free parameters: nothing is estimated from these data, so its error is what its residuals show".into()
        }
        CalibrationStatus::NotFitted => {
            return "not fitted (--no-fit): no covariance without a fit".into()
        }
        CalibrationStatus::Fitted => {}
    }
    let on = calibration.on_bounds();
    if on == k {
        return format!(
            "{} on {} bound{}: held there, nothing inside its range is left to vary",
            if k == 1 {
                "its free parameter is".to_string()
            } else {
                format!("all {k} free parameters are")
            },
            if k == 1 { "its" } else { "their" },
            if k == 1 { "" } else { "s" }
        );
    }
    if let Some((i, t)) = model.iter().enumerate().find(|(_, t)| **t <= 0.0) {
        return format!(
            "the model torque is {t:.3} N m at {:.0} rpm: a band of a positive torque (log scale) does not exist there",
            data.rows.get(i).map_or(f64::NAN, |d| d.speed_rpm)
        );
    }
    if unc.dof == 0 {
        return "no residual degrees of freedom (as many parameters as points)".into();
    }
    "the data do not determine its parameters (see the statements below)".into()
}

/// Run every law set on `rig` at the data's speeds and temperatures, in parallel, and score
/// each out of sample. The order of the results is the order of `lawsets`, whatever the
/// scheduling; `rank` orders them by cross-validated RMSE.
///
/// The laws come from plugins, so this example is compiled but not run here; the
/// `compare_bundled` example of this crate runs it (`cargo run --release -p tribo-studies
/// --example compare_bundled` after `cargo build --release`).
///
/// ```no_run
/// use std::path::{Path, PathBuf};
/// use tribo_config::{bundled, lawset::LawSet, rig::load_rig};
/// use tribo_plugin_api::loader::discover;
/// use tribo_studies::study::{compare, CompareOptions, DataRun};
///
/// let rig = load_rig(Path::new(bundled::DEFAULT_RIG), &[])?;
/// let sets = [LawSet::load("fedem-baseline")?, LawSet::load("stribeck-duty")?];
/// let data = DataRun::read(bundled::DEFAULT_DATA)?;
/// // Law plugins from a directory, TRIBO_PLUGIN_PATH and the executable's directory.
/// let registry = discover(&[PathBuf::from("target/release")])?;
/// let options = CompareOptions { steady: true, ..CompareOptions::default() };
/// let cmp = compare(&rig, &sets, &data, &registry, &options)?;
/// for set in &cmp.sets {
///     println!("{:<16} rank {} RMSE {:.4} N m", set.lawset, set.rank, set.rmse_nm);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn compare(
    rig: &Rig,
    lawsets: &[LawSet],
    data: &DataRun,
    registry: &LawRegistry,
    options: &CompareOptions,
) -> Result<Comparison, StudyError> {
    // A drivetrain's chain is integrated in the steady state only (`sim::torsional`).
    let effective = CompareOptions {
        steady: options.steady || rig.file.drivetrain.is_some(),
        ..options.clone()
    };
    let options = &effective;
    // Every input checked before anything runs.
    check_lawsets(rig, lawsets, registry)?;
    for d in std::iter::once(data).chain(&options.validate) {
        check_data_rig(rig, d, options.data_for_any_rig)?;
        check_data(rig, d)?;
    }
    let measured: Vec<f64> = data.rows.iter().map(|r| r.torque_nm).collect();
    let spread = measured.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - measured.iter().copied().fold(f64::INFINITY, f64::min);
    // Every set's free parameters are resolved before anything runs: a bad law-set entry is
    // reported at once, not after the other sets' runs.
    let frees = lawsets
        .iter()
        .map(|ls| {
            if ls.file.laws.iter().any(|e| !e.free.is_empty()) {
                ls.free_params(registry, None).map_err(Box::new)
            } else {
                Ok(Vec::new())
            }
        })
        .collect::<Result<Vec<_>, _>>()?;
    let sets = lawsets
        .par_iter()
        .zip(frees.par_iter())
        .map(|(ls, free)| score_set(rig, ls, free, data, registry, options, spread))
        .collect::<Result<Vec<_>, StudyError>>()?;
    let mut cmp = Comparison {
        rig: rig.file.name.clone(),
        data_file: data.file.display().to_string(),
        data: data.rows.clone(),
        mode: RunMode::from_steady(options.steady),
        ranked_by: ranked_by(options.no_cv).into(),
        noise_nm: data.meta.noise_nm,
        verdict: Default::default(),
        sets,
        failed: Vec::new(),
    };
    cmp.rank(options.no_cv);
    Ok(cmp)
}

impl Comparison {
    /// Rank the sets ([`rank_sets`]) and judge the result ([`judge`]); again
    /// after sets run in separate processes are merged.
    pub fn rank(&mut self, no_cv: bool) {
        let noise = self.noise_nm.unwrap_or_else(|| {
            let n = self.data.len().max(1) as f64;
            crate::verdict::ASSUMED_NOISE_SHARE
                * self.data.iter().map(|d| d.torque_nm.abs()).sum::<f64>()
                / n
        });
        rank_sets(&mut self.sets, no_cv, noise);
        mark_uncovered_joints(&mut self.sets);
        self.verdict = judge(self);
        if let Some(note) = self.instrument_note() {
            self.verdict.sentence.push_str(&note);
        }
    }

    /// The verdict's note on a rig with a drivetrain: the data points measured outside the
    /// transducer's rating by any set's run (`instrument_ok`), which no law can be judged on.
    fn instrument_note(&self) -> Option<String> {
        let outside: Vec<String> = self
            .data
            .iter()
            .enumerate()
            .filter(|(i, _)| {
                self.sets.iter().any(|s| {
                    s.instrument_ok
                        .as_ref()
                        .is_some_and(|ok| ok.get(*i) == Some(&false))
                })
            })
            .map(|(_, row)| format!("{:.0}", row.speed_rpm))
            .collect();
        if outside.is_empty() {
            return None;
        }
        Some(format!(
            "; the transducer worked outside its rating at {} of {} points ({} rpm: instrument_ok false), so those measurements are not trusted{}",
            outside.len(),
            self.data.len(),
            outside.join(", "),
            if self.sets.iter().all(|s| s.instrument_ok.is_none()) {
                ""
            } else {
                " (--trusted-points-only scores the rest)"
            }
        ))
    }
}

/// What the ranking of a comparison rests on, in words.
pub fn ranked_by(no_cv: bool) -> &'static str {
    if no_cv {
        "in-sample RMSE (cross-validation skipped with --no-cv): rewards sets with many free parameters"
    } else {
        "leave-one-out cross-validated RMSE: each point predicted by the set refitted without it (a set without free parameters: its in-sample RMSE; sets tuned to these data elsewhere have no out-of-sample figure and rank last)"
    }
}

/// Give each set its `rank`: cross-validated sets first, by their out-of-sample error; sets
/// without one (tuned elsewhere, or a fold failed) after them, by their in-sample error. With
/// `no_cv`, all by in-sample error. Used again when sets run in separate processes are merged.
///
/// Sets of one class whose errors lie within `noise_nm` (the data's one-sigma noise) of the
/// first set of their group are **tied**: these data cannot tell them apart, so they share a
/// place and each records the others ([`SetResult::tie`]). A difference smaller than the noise
/// of a single measurement is no evidence for one law over another.
pub fn rank_sets(sets: &mut [SetResult], no_cv: bool, noise_nm: f64) {
    let key = |s: &SetResult| {
        if no_cv {
            (0, s.rmse_nm)
        } else {
            match s.scores.cv_rmse_nm {
                Some(cv) => (0, cv),
                None => (1, s.rmse_nm),
            }
        }
    };
    let mut order: Vec<usize> = (0..sets.len()).collect();
    order.sort_by(|a, b| {
        let (ka, kb) = (key(&sets[*a]), key(&sets[*b]));
        ka.0.cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
    });
    for (place, &i) in order.iter().enumerate() {
        sets[i].rank = place + 1;
        sets[i].tie = None;
    }
    // Groups of tied sets, each led by its best set.
    let mut start = 0;
    while start < order.len() {
        let lead = key(&sets[order[start]]);
        let mut end = start + 1;
        while end < order.len() {
            let k = key(&sets[order[end]]);
            // A NaN error ties with nothing.
            let within = (k.1 - lead.1)
                .partial_cmp(&noise_nm)
                .is_some_and(|o| o.is_le());
            if k.0 != lead.0 || !within {
                break;
            }
            end += 1;
        }
        let group = &order[start..end];
        if group.len() > 1 {
            let same_torques = group.iter().all(|&i| {
                sets[i]
                    .errors_nm
                    .iter()
                    .zip(&sets[group[0]].errors_nm)
                    .all(|(a, b)| (a - b).abs() <= SAME_TORQUE_NM)
            });
            let spread = key(&sets[group[group.len() - 1]]).1 - lead.1;
            let place = sets[group[0]].rank;
            for &i in group {
                sets[i].rank = place;
                sets[i].tie = Some(Tie {
                    with: group
                        .iter()
                        .filter(|&&j| j != i)
                        .map(|&j| sets[j].lawset.clone())
                        .collect(),
                    same_torques,
                    error_spread_nm: spread,
                    noise_nm,
                });
            }
        }
        start = end;
    }
}

/// Set each set's [`SetResult::uncovered_joints`]: the joints some other set puts a law on
/// (in its first plateau's per-law results) and this one does not, in the order they first
/// appear.
pub fn mark_uncovered_joints(sets: &mut [SetResult]) {
    let covered = |s: &SetResult| -> Vec<String> {
        let mut joints: Vec<String> = Vec::new();
        for j in s.run.plateaus.first().map_or(&[][..], |p| &p.joints[..]) {
            if !joints.contains(&j.joint) {
                joints.push(j.joint.clone());
            }
        }
        joints
    };
    let each: Vec<Vec<String>> = sets.iter().map(covered).collect();
    let mut all: Vec<&String> = Vec::new();
    for j in each.iter().flatten() {
        if !all.contains(&j) {
            all.push(j);
        }
    }
    for (s, own) in sets.iter_mut().zip(&each) {
        s.uncovered_joints = all
            .iter()
            .filter(|j| !own.contains(j))
            .map(|j| (*j).clone())
            .collect();
    }
}

/// A law set that gave no results (its worker process crashed, hung, ran out of memory, or its
/// run failed), reported beside the sets that did.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FailedSet {
    /// Law-set name.
    pub lawset: String,
    /// Why, in words (names the law, its library and the signal or limit).
    pub message: String,
}

/// Which body a mass study scales.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScaledBody {
    /// The connecting rod (mass and inertia).
    Rod,
    /// The piston assembly (mass).
    Piston,
    /// The crankshaft (mass and inertia).
    Crank,
}

/// `rig` with `body`'s mass (and inertia) scale factors multiplied by `scale`.
pub fn scaled(rig: &Rig, body: ScaledBody, scale: f64) -> Result<Rig, Box<RigError>> {
    let mut r = rig.clone();
    let b = &mut r.file.bodies;
    match body {
        ScaledBody::Rod => {
            b.rod.mass_scale *= scale;
            b.rod.inertia_scale *= scale;
        }
        ScaledBody::Piston => b.piston.mass_scale *= scale,
        ScaledBody::Crank => {
            b.crank.mass_scale *= scale;
            b.crank.inertia_scale *= scale;
        }
    }
    r.overridden.push("bodies".into());
    tribo_config::rig::revalidate(&r)?;
    Ok(r)
}

/// One joint's and law's response to the scaling at one speed.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct JointChange {
    /// Joint.
    pub joint: String,
    /// Law.
    pub law: String,
    /// Friction torque, original rig, N m.
    pub original_nm: f64,
    /// Friction torque, scaled rig, N m.
    pub scaled_nm: f64,
    /// Change of the friction torque, N m.
    pub change_nm: f64,
    /// Change of the joint's mean normal load, N.
    pub normal_load_change_n: f64,
}

/// The response at one speed and scale.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SpeedChange {
    /// Speed, rpm.
    pub speed_rpm: f64,
    /// Scale factor.
    pub scale: f64,
    /// Motoring torque, original, N m.
    pub original_nm: f64,
    /// Motoring torque, scaled, N m.
    pub scaled_nm: f64,
    /// Change, N m.
    pub change_nm: f64,
    /// The FEDEM thesis's change for the same speed (table 10.6 minus 10.5, rod at 0.6), N m:
    /// present only in the rows of the thesis's own law set (see [`is_thesis_lawset`]) at
    /// scale 0.6 of the rod; absent (null) for every other law set.
    pub fedem_change_nm: Option<f64>,
    /// Per joint and law.
    pub joints: Vec<JointChange>,
}

/// One law set's mass response.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MassResponse {
    /// Law set.
    pub lawset: String,
    /// Body scaled.
    pub body: ScaledBody,
    /// Per scale and speed.
    pub changes: Vec<SpeedChange>,
}

/// Torque change per speed and joint when `body` is scaled by each of `scales`, for each law
/// set, against the unscaled rig. Runs in parallel; results in input order. `fedem` (speed,
/// change) is attached only to the thesis's own law set ([`is_thesis_lawset`]).
#[allow(clippy::too_many_arguments)]
pub fn mass_response(
    rig: &Rig,
    lawsets: &[LawSet],
    body: ScaledBody,
    scales: &[f64],
    registry: &LawRegistry,
    steady: bool,
    fedem: Option<&[(f64, f64)]>,
) -> Result<Vec<MassResponse>, StudyError> {
    // Every input checked before anything runs.
    check_lawsets(rig, lawsets, registry)?;
    check_scales(rig, body, scales)?;
    let jobs: Vec<(usize, Option<f64>)> = (0..lawsets.len())
        .flat_map(|i| std::iter::once((i, None)).chain(scales.iter().map(move |s| (i, Some(*s)))))
        .collect();
    let runs = jobs
        .par_iter()
        .map(|(i, s)| {
            let ls = &lawsets[*i];
            let base = prepare(rig, ls, None)?;
            let r = match s {
                Some(s) => scaled(&base, body, *s)?,
                None => base,
            };
            run_rig(&r, registry, steady).map_err(|e| StudyError::Run {
                lawset: ls.name().into(),
                error: Box::new(e),
            })
        })
        .collect::<Result<Vec<RunResult>, StudyError>>()?;
    let per_set = scales.len() + 1;
    let mut out = Vec::new();
    for (i, ls) in lawsets.iter().enumerate() {
        // FEDEM's change belongs to the thesis's model only, never to a user's law set.
        let fedem = fedem.filter(|_| is_thesis_lawset(ls));
        let original = &runs[i * per_set];
        let mut changes = Vec::new();
        for (k, s) in scales.iter().enumerate() {
            let run = &runs[i * per_set + 1 + k];
            for (p0, p1) in original.plateaus.iter().zip(&run.plateaus) {
                let joints = p0
                    .joints
                    .iter()
                    .zip(&p1.joints)
                    .map(|(a, b)| JointChange {
                        joint: a.joint.clone(),
                        law: a.law.clone(),
                        original_nm: a.friction_torque_nm,
                        scaled_nm: b.friction_torque_nm,
                        change_nm: b.friction_torque_nm - a.friction_torque_nm,
                        normal_load_change_n: b.mean_normal_load_n - a.mean_normal_load_n,
                    })
                    .collect();
                let fedem_change_nm = fedem.and_then(|f| {
                    f.iter()
                        .find(|(rpm, _)| (rpm - p0.set_speed_rpm).abs() < 0.5)
                        .map(|(_, d)| *d)
                });
                changes.push(SpeedChange {
                    speed_rpm: p0.set_speed_rpm,
                    scale: *s,
                    original_nm: p0.motoring_torque_nm,
                    scaled_nm: p1.motoring_torque_nm,
                    change_nm: p1.motoring_torque_nm - p0.motoring_torque_nm,
                    fedem_change_nm: if (*s - 0.6).abs() < 1e-9 {
                        fedem_change_nm
                    } else {
                        None
                    },
                    joints,
                });
            }
        }
        out.push(MassResponse {
            lawset: ls.name().into(),
            body,
            changes,
        });
    }
    Ok(out)
}

/// The name of the thesis's own law set, whose FEDEM results (tables 10.5, 10.6) may be shown
/// beside it.
pub const THESIS_LAWSET: &str = "fedem-baseline";

/// Whether `lawset` is the thesis's FEDEM model: the same laws, joints and parameters as the
/// bundled `fedem-baseline` (compared as parsed values, so comments, formatting, the file's
/// name and the set's name do not matter, while any changed coefficient or added law does).
/// Only then do the FEDEM thesis's numbers belong beside its results.
pub fn is_thesis_lawset(lawset: &LawSet) -> bool {
    tribo_config::bundled::lawset(THESIS_LAWSET)
        .and_then(|text| LawSet::from_text(Path::new(THESIS_LAWSET), text).ok())
        .is_some_and(|thesis| thesis.file.laws == lawset.file.laws)
}

/// FEDEM's torque change with the rod at 60% per speed: table 10.6 minus table 10.5.
pub fn fedem_rod_change() -> Vec<(f64, f64)> {
    // The FEDEM tables have `speed_rpm,sim_speed_rad_s,torque_nm` (no oil temperature), so they
    // are read by column name here rather than through `parse_data`.
    let read = |name: &str| -> Vec<(f64, f64)> {
        let Some(text) = tribo_config::bundled::data(name) else {
            return Vec::new();
        };
        let mut reader = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let Ok(headers) = reader.headers().cloned() else {
            return Vec::new();
        };
        let col = |n: &str| headers.iter().position(|h| h == n);
        let (Some(cs), Some(ct)) = (col("speed_rpm"), col("torque_nm")) else {
            return Vec::new();
        };
        reader
            .records()
            .filter_map(|r| {
                let r = r.ok()?;
                Some((r.get(cs)?.parse().ok()?, r.get(ct)?.parse().ok()?))
            })
            .collect()
    };
    let (a, b) = (read("fedem-tuned.csv"), read("fedem-light-rod.csv"));
    a.iter()
        .zip(&b)
        .map(|((rpm, t0), (_, t1))| (*rpm, t1 - t0))
        .collect()
}

/// What the oil of a sweep is: the rig's descriptive fields and its viscosity model, so the
/// JSON says which curve produced the viscosities.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct OilInfo {
    /// Name, if the rig gives one.
    pub name: Option<String>,
    /// SAE viscosity grade, if given.
    pub grade: Option<String>,
    /// Source of the viscosity data, if given.
    pub source: Option<String>,
    /// The viscosity model and its constants.
    pub viscosity: tribo_core::oil::ViscosityModel,
    /// Density, kg/m^3.
    pub density_kg_m3: f64,
    /// One-line description (name, grade, model constants, source), as printed.
    pub description: String,
}

impl OilInfo {
    /// The oil of `rig`.
    pub fn of(rig: &Rig) -> Self {
        let o = &rig.file.oil;
        Self {
            name: o.name.clone(),
            grade: o.grade.clone(),
            source: o.source.clone(),
            viscosity: o.viscosity.clone(),
            density_kg_m3: o.density_kg_m3,
            description: o.describe(),
        }
    }

    /// Dynamic viscosity at `t_c` C, Pa s (kinematic viscosity times density, as the solver
    /// computes it).
    pub fn dynamic_pa_s(&self, t_c: f64) -> f64 {
        self.viscosity.kinematic_cst(t_c) * 1e-6 * self.density_kg_m3
    }
}

/// Friction torque of one joint (all its laws summed) at one sweep point.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct JointTorque {
    /// Joint name.
    pub joint: String,
    /// Friction torque at the crank, N m.
    pub friction_torque_nm: f64,
}

/// One (speed, temperature) point of a law set's sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SweepPoint {
    /// Engine speed, rpm.
    pub speed_rpm: f64,
    /// Oil temperature, C.
    pub oil_temp_c: f64,
    /// Dynamic viscosity at that temperature, Pa s.
    pub viscosity_pa_s: f64,
    /// Mean motoring torque over the steady revolution, N m.
    pub torque_nm: f64,
    /// Per joint of the rig, in its report order (`RigFile::joint_names`: the single-cylinder
    /// rig's five, or an engine's mains and cylinder joints); joints without a law give zero.
    pub joints: Vec<JointTorque>,
    /// The Sandoval-Heywood correlation at this point (`tribo_core::correlation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub correlation: Option<tribo_core::correlation::Correlation>,
}

/// One law set's sweep: points ordered by temperature, then speed (the input order).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SweepSet {
    /// Law-set name.
    pub lawset: String,
    /// Its file.
    pub file: String,
    /// Every (temperature, speed) point.
    pub points: Vec<SweepPoint>,
    /// Warnings of the runs.
    pub warnings: Vec<String>,
}

impl SweepSet {
    /// The torque at speed index `i` and temperature index `k` of a sweep over `n_speeds`
    /// speeds.
    pub fn torque(&self, k: usize, i: usize, n_speeds: usize) -> f64 {
        self.points
            .get(k * n_speeds + i)
            .map_or(f64::NAN, |p| p.torque_nm)
    }
}

/// A temperature and speed sweep of several law sets (steady state at every point).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Sweep {
    /// Rig name.
    pub rig: String,
    /// The oil (name, grade, model, source).
    pub oil: OilInfo,
    /// Always [`RunMode::Steady`]: each point is the periodic steady state at that speed.
    pub mode: RunMode,
    /// Oil temperatures, C, in the order given.
    pub temps_c: Vec<f64>,
    /// Dynamic viscosity at each temperature, Pa s.
    pub viscosities_pa_s: Vec<f64>,
    /// Engine speeds, rpm, in the order given.
    pub speeds_rpm: Vec<f64>,
    /// Each law set.
    pub sets: Vec<SweepSet>,
    /// How FMEP is defined on this rig (basis, displacement), for the correlation's tables.
    #[serde(default)]
    pub fmep: tribo_core::sim::Fmep,
    /// Law sets that gave no results (only when sets run in separate processes).
    #[serde(default)]
    pub failed: Vec<FailedSet>,
}

/// Parse a comma-separated list of numbers given to `option` (`40,50,60`). Empty lists, empty
/// items and non-numbers are errors naming the option.
pub fn parse_list(option: &str, text: &str) -> Result<Vec<f64>, SweepInputError> {
    let err = |message: String| SweepInputError {
        option: option.into(),
        message,
    };
    if text.trim().is_empty() {
        return Err(err(
            "the list is empty; give comma-separated numbers, e.g. 40,60,80".into(),
        ));
    }
    text.split(',')
        .map(|item| {
            let item = item.trim();
            item.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| err(format!("`{item}` is not a number")))
        })
        .collect()
}

/// Check a sweep's temperatures (inside [`tribo_core::oil::VALID_RANGE_C`]) and speeds (positive),
/// both non-empty and without repeats, before any run starts.
pub fn check_sweep_inputs(temps_c: &[f64], speeds_rpm: &[f64]) -> Result<(), SweepInputError> {
    let err = |option: &str, message: String| SweepInputError {
        option: option.into(),
        message,
    };
    let (lo, hi) = tribo_core::oil::VALID_RANGE_C;
    if temps_c.is_empty() {
        return Err(err("--temps", "the list is empty".into()));
    }
    if speeds_rpm.is_empty() {
        return Err(err("--speeds", "the list is empty".into()));
    }
    if let Some(t) = temps_c.iter().find(|t| !(**t >= lo && **t <= hi)) {
        return Err(err(
            "--temps",
            format!(
                "{} C is outside the viscosity model's valid range [{lo}, {hi}] C",
                readable(*t)
            ),
        ));
    }
    if let Some(s) = speeds_rpm.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
        return Err(err(
            "--speeds",
            format!("every speed must be positive (rpm), got {}", readable(*s)),
        ));
    }
    for (option, list, unit) in [("--temps", temps_c, "C"), ("--speeds", speeds_rpm, "rpm")] {
        for (i, a) in list.iter().enumerate() {
            if list[..i].contains(a) {
                return Err(err(option, format!("{a} {unit} is given twice")));
            }
        }
    }
    Ok(())
}

/// The speeds of the plateaus of `rig`'s own test cycle, rpm, in the order held (each once).
pub fn plateau_speeds(rig: &Rig) -> Vec<f64> {
    let mut speed = 0.0;
    let mut out: Vec<f64> = Vec::new();
    for s in rig.file.cycle.segments() {
        match s {
            Segment::Ramp { to_rpm, .. } => speed = to_rpm,
            Segment::Hold { .. } => {
                if !out.contains(&speed) {
                    out.push(speed);
                }
            }
        }
    }
    out
}

/// Refuse `speeds_rpm` (given by `option`) above the rig's declared top speed
/// (`max_speed_rpm`), naming both.
pub fn check_speeds_for_rig(
    rig: &Rig,
    speeds_rpm: &[f64],
    option: &str,
) -> Result<(), SweepInputError> {
    match (
        rig.file.max_speed_rpm,
        speeds_rpm
            .iter()
            .find(|s| rig.file.max_speed_rpm.is_some_and(|top| **s > top)),
    ) {
        (Some(top), Some(s)) => Err(SweepInputError {
            option: option.into(),
            message: format!(
                "{} rpm is above the top speed of rig `{}` (max_speed_rpm = {} rpm)",
                readable(*s),
                rig.file.name,
                readable(top)
            ),
        }),
        _ => Ok(()),
    }
}

/// `rig` with `lawset` attached, driven through `speeds_rpm` (the thesis's ramp-and-hold
/// pattern) with the oil at `temp_c` on every plateau.
fn sweep_rig(
    rig: &Rig,
    lawset: &LawSet,
    speeds_rpm: &[f64],
    temp_c: f64,
) -> Result<Rig, Box<RigError>> {
    let rows: Vec<DataRow> = speeds_rpm
        .iter()
        .map(|s| DataRow {
            speed_rpm: *s,
            torque_nm: 0.0,
            oil_temp_c: temp_c,
        })
        .collect();
    prepare(rig, lawset, Some(&rows))
}

/// Check a sweep's temperatures and speeds, and that the rig can be driven through them (with
/// the first of `lawsets` attached): an error names `--speeds` or `--temps`, never a `--set`
/// nobody gave. No plugin is needed, so a caller can check before it starts any worker.
pub fn check_sweep(
    rig: &Rig,
    lawsets: &[LawSet],
    temps_c: &[f64],
    speeds_rpm: &[f64],
) -> Result<(), StudyError> {
    check_sweep_inputs(temps_c, speeds_rpm)?;
    if let Some(ls) = lawsets.first() {
        for t in temps_c {
            sweep_rig(rig, ls, speeds_rpm, *t).map_err(|mut e| {
                let speeds = e.field.starts_with("cycle");
                e.file = PathBuf::from(if speeds { "--speeds" } else { "--temps" });
                if let Some(i) = e.message.find(" (this run's cycle") {
                    e.message.truncate(i);
                }
                e.message.push_str(if speeds {
                    " (the sweep drives the rig through the speeds of --speeds)"
                } else {
                    " (the sweep holds the oil at each temperature of --temps)"
                });
                e
            })?;
        }
    }
    Ok(())
}

/// Check that the rig's `body` can be scaled by every factor of `scales` (a mass-response
/// study): an error names `--scale`. No plugin is needed.
pub fn check_scales(rig: &Rig, body: ScaledBody, scales: &[f64]) -> Result<(), StudyError> {
    for s in scales {
        scaled(rig, body, *s).map_err(|mut e| {
            e.file = PathBuf::from("--scale");
            e.message
                .push_str(&format!(" (the rig's value times the scale factor {s})"));
            e
        })?;
    }
    Ok(())
}

/// Run every law set at every temperature over `speeds_rpm`, in steady state, in parallel
/// (one job per law set and temperature; `progress`, if given, counts finished jobs). Results
/// are in input order whatever the scheduling, so the output is deterministic.
pub fn sweep(
    rig: &Rig,
    lawsets: &[LawSet],
    temps_c: &[f64],
    speeds_rpm: &[f64],
    registry: &LawRegistry,
    progress: Option<&tribo_core::observe::Position>,
) -> Result<Sweep, StudyError> {
    // Every input checked before anything runs.
    check_speeds_for_rig(rig, speeds_rpm, "--speeds")?;
    check_sweep(rig, lawsets, temps_c, speeds_rpm)?;
    check_lawsets(rig, lawsets, registry)?;
    let jobs: Vec<(usize, f64)> = (0..lawsets.len())
        .flat_map(|i| temps_c.iter().map(move |t| (i, *t)))
        .collect();
    let runs = jobs
        .par_iter()
        .map(|(i, t)| {
            let ls = &lawsets[*i];
            let r = sweep_rig(rig, ls, speeds_rpm, *t)?;
            let run = run_rig(&r, registry, true).map_err(|e| StudyError::Run {
                lawset: ls.name().into(),
                error: Box::new(e),
            });
            if let Some(p) = progress {
                p.inc();
            }
            run
        })
        .collect::<Result<Vec<RunResult>, StudyError>>()?;
    let oil = OilInfo::of(rig);
    let joint_names = rig.model().joint_names();
    let mut sets = Vec::with_capacity(lawsets.len());
    for (i, ls) in lawsets.iter().enumerate() {
        let mut points = Vec::with_capacity(temps_c.len() * speeds_rpm.len());
        // Each warning once, with the temperatures it was given at.
        let mut by_warning: Vec<(&String, Vec<f64>)> = Vec::new();
        for (k, t) in temps_c.iter().enumerate() {
            let run = &runs[i * temps_c.len() + k];
            for w in &run.warnings {
                match by_warning.iter_mut().find(|(x, _)| *x == w) {
                    Some((_, ts)) => ts.push(*t),
                    None => by_warning.push((w, vec![*t])),
                }
            }
            for p in &run.plateaus {
                let joints = joint_names
                    .iter()
                    .map(|name| JointTorque {
                        joint: name.clone(),
                        // Folded from +0: a joint without a law has no friction, 0, where
                        // an empty float `sum` gives -0 (written "-0" in the CSV).
                        friction_torque_nm: p
                            .joints
                            .iter()
                            .filter(|j| j.joint == *name)
                            .fold(0.0, |sum, j| sum + j.friction_torque_nm),
                    })
                    .collect();
                points.push(SweepPoint {
                    speed_rpm: p.set_speed_rpm,
                    oil_temp_c: p.oil_temp_c,
                    viscosity_pa_s: p.viscosity_pa_s,
                    torque_nm: p.motoring_torque_nm,
                    joints,
                    correlation: p.correlation.clone(),
                });
            }
        }
        let warnings = by_warning
            .into_iter()
            .map(|(w, ts)| {
                let list: Vec<String> = ts.iter().map(|t| t.to_string()).collect();
                if ts.len() == temps_c.len() && ts.len() > 1 {
                    format!("at every oil temperature ({} C): {w}", list.join(", "))
                } else {
                    format!("{} C: {w}", list.join(", "))
                }
            })
            .collect();
        sets.push(SweepSet {
            lawset: ls.name().into(),
            file: ls.path.display().to_string(),
            points,
            warnings,
        });
    }
    Ok(Sweep {
        rig: rig.file.name.clone(),
        viscosities_pa_s: temps_c.iter().map(|t| oil.dynamic_pa_s(*t)).collect(),
        oil,
        mode: RunMode::Steady,
        temps_c: temps_c.to_vec(),
        speeds_rpm: speeds_rpm.to_vec(),
        fmep: runs.first().map(|r| r.fmep).unwrap_or_default(),
        sets,
        failed: Vec::new(),
    })
}

/// What the verdict needs to know about one set of a comparison.
fn summary(s: &SetResult) -> SetSummary {
    SetSummary {
        name: s.lawset.clone(),
        out_of_sample_nm: s.scores.cv_rmse_nm,
        point_errors_nm: s.scores.cv_errors_nm.clone(),
        status: s.calibration.status,
        params: s.calibration.params.len(),
        on_bounds: s.calibration.on_bounds(),
        undetermined: s.calibration.undetermined(),
        prior_fitted: s.scores.prior_fitted_params,
        max_rise_percent_per_10c: s.temperature_response.max_rise_percent_per_10c,
        tied_with: s.tie.as_ref().map(|t| t.with.clone()).unwrap_or_default(),
        same_torques: s.tie.as_ref().is_some_and(|t| t.same_torques),
    }
}

/// The verdict of `c` ([`crate::verdict`] has the rules).
pub fn judge(c: &Comparison) -> Verdict {
    let sets: Vec<SetSummary> = c.sets.iter().map(summary).collect();
    let measured: Vec<f64> = c.data.iter().map(|d| d.torque_nm).collect();
    let speeds: Vec<f64> = c.data.iter().map(|d| d.speed_rpm).collect();
    crate::verdict::verdict(&sets, &measured, &speeds, c.noise_nm)
}

#[cfg(test)]
mod tests {
    use super::RunMode;

    #[test]
    fn run_mode_serializes_to_the_words_the_json_always_had() {
        for (mode, word) in [
            (RunMode::Steady, "steady"),
            (RunMode::Transient, "transient"),
        ] {
            let json = serde_json::to_string(&mode).expect("serializes");
            assert_eq!(json, format!("\"{word}\""));
            assert_eq!(mode.to_string(), word);
        }
        assert_eq!(RunMode::from_steady(true), RunMode::Steady);
        assert_eq!(RunMode::from_steady(false), RunMode::Transient);
    }
}
