//! The one-sentence verdict of a comparison: what the scores let a user conclude, in words.
//! It reads a summary of each set ([`SetSummary`]), never the comparison itself, so the
//! comparison (`study::judge`) calls it and not the other way round.
//!
//! The sentence is chosen by these rules, in order (the rule's name is in the JSON):
//!
//! 1. `no-results`: no law set gave results.
//! 2. `not-judged`: no set has an out-of-sample error (every set was tuned to these data
//!    elsewhere, the leave-one-out refits were skipped with `--no-cv`, or their folds failed).
//!    The sentence says which.
//! 3. Otherwise the **best** set is the one with the lowest out-of-sample error `e` (its
//!    leave-one-out RMSE; for a set with nothing fitted to the data, its RMSE). The data's
//!    **noise** `s` is the one standard deviation the data file declares (`# noise_nm:`), or,
//!    when it declares none, 5% of the mean measured torque, which the sentence then calls
//!    assumed. The best set's parameters are *determined* when each was fitted inside its
//!    range with a 1-sigma uncertainty at most half its value; a set without free parameters,
//!    or not fitted (`--no-fit`), has none to determine.
//!    - `predicts`: `e <= s` and every parameter determined (or none fitted): the set predicts
//!      unseen points within the noise.
//!    - `predicts-undetermined`: `e <= s` but some parameter sits on a bound or is not
//!      determined: the curve can be trusted, its parameter values cannot.
//!    - `misses`: `e > s`: no set reproduces the data within their noise; the sentence gives
//!      `e` as a share of the mean measured torque, the point the best set misses most (as a
//!      share of the measured value there), and the state of its parameters.
//!
//! Sets tied with the best one in the ranking (their out-of-sample errors within the noise
//! `s` of the best's, `study::rank_sets`) are named with it as **indistinguishable**,
//! saying why: the same torque at every point, or errors apart by less than the noise.
//!
//! Whatever the rule under 3, a best set whose torque rises by more than
//! [`crate::score::TEMPERATURE_RISE_FLAG_PERCENT`] per 10 C of oil warming gets that said too,
//! and fitted sets left without an out-of-sample error (`--no-cv`) are named as not judged.

use serde::{Deserialize, Serialize};

use crate::score::{CalibrationStatus, SAME_TORQUE_NM, TEMPERATURE_RISE_FLAG_PERCENT};

/// Share of the mean measured torque taken as the data's noise when the data file declares
/// none, an assumption the verdict names. estimate: a round figure for the repeatability of a
/// motored friction torque at one oil temperature (the bundled CRF 250 R data declare their own,
/// 0.05 N m on about 1.4 N m, from the transducer's specification).
pub const ASSUMED_NOISE_SHARE: f64 = 0.05;

/// Which rule of the module documentation chose the sentence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum VerdictRule {
    /// No set gave results.
    NoResults,
    /// No set has an out-of-sample error.
    NotJudged,
    /// The best set predicts unseen points within the noise, every parameter determined.
    Predicts,
    /// Within the noise, but some parameter on a bound or undetermined.
    PredictsUndetermined,
    /// No set predicts the data within their noise.
    Misses,
}

/// The verdict of a comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    /// The rule that chose the sentence.
    pub rule: VerdictRule,
    /// The set it speaks of, if one.
    pub set: Option<String>,
    /// The noise the judgement used, N m (declared or assumed).
    pub noise_nm: Option<f64>,
    /// Whether that noise was assumed (the data file declares none).
    pub noise_assumed: bool,
    /// The sentence, printed after `Verdict: `.
    pub sentence: String,
}

impl Default for Verdict {
    fn default() -> Self {
        Self {
            rule: VerdictRule::NoResults,
            set: None,
            noise_nm: None,
            noise_assumed: false,
            sentence: "no law set gave results".into(),
        }
    }
}

/// A torque in N m in the verdict's words: two decimals, three below 0.1 N m.
fn nm(x: f64) -> String {
    if x.abs() < 0.1 {
        format!("{x:.3}")
    } else {
        format!("{x:.2}")
    }
}

/// What the verdict needs to know about one set.
#[derive(Debug, Clone)]
pub struct SetSummary {
    /// Law-set name.
    pub name: String,
    /// Out-of-sample error, N m, if it has one.
    pub out_of_sample_nm: Option<f64>,
    /// Each point's out-of-sample error (prediction minus measurement), N m.
    pub point_errors_nm: Vec<Option<f64>>,
    /// How its parameters were treated.
    pub status: CalibrationStatus,
    /// Free parameters.
    pub params: usize,
    /// Of them, on a bound.
    pub on_bounds: usize,
    /// Of them, not determined (on a bound included).
    pub undetermined: usize,
    /// Numbers tuned to these data elsewhere.
    pub prior_fitted: usize,
    /// Largest torque rise per 10 C of oil warming, percent.
    pub max_rise_percent_per_10c: f64,
    /// The sets it is tied with in the ranking (indistinguishable on these data).
    pub tied_with: Vec<String>,
    /// Whether those give the same torques at every point (else: errors within the noise).
    pub same_torques: bool,
}

/// The verdict for sets `sets` on data `measured` at `speeds_rpm` with declared noise
/// `noise_nm` (see the module documentation for the rules).
pub fn verdict(
    sets: &[SetSummary],
    measured: &[f64],
    speeds_rpm: &[f64],
    noise_nm: Option<f64>,
) -> Verdict {
    if sets.is_empty() {
        return Verdict::default();
    }
    let mean = measured.iter().map(|m| m.abs()).sum::<f64>() / measured.len().max(1) as f64;
    let (noise, assumed) = match noise_nm {
        Some(s) => (s, false),
        None => (ASSUMED_NOISE_SHARE * mean, true),
    };
    let unjudged: Vec<&str> = sets
        .iter()
        .filter(|s| s.out_of_sample_nm.is_none())
        .map(|s| s.name.as_str())
        .collect();
    let Some(best) = sets
        .iter()
        .filter(|s| s.out_of_sample_nm.is_some_and(f64::is_finite))
        .min_by(|a, b| {
            a.out_of_sample_nm
                .unwrap_or(f64::INFINITY)
                .total_cmp(&b.out_of_sample_nm.unwrap_or(f64::INFINITY))
        })
    else {
        let why = if sets.iter().all(|s| s.prior_fitted > 0) {
            "every set was tuned to these data elsewhere, so its error is in sample".to_string()
        } else {
            "no set has a leave-one-out error (skipped with --no-cv, or its refits failed), and the in-sample errors of fitted sets reward free parameters".to_string()
        };
        return Verdict {
            rule: VerdictRule::NotJudged,
            set: None,
            noise_nm: Some(noise),
            noise_assumed: assumed,
            sentence: format!("no set can be judged on unseen points: {why}"),
        };
    };
    let e = best.out_of_sample_nm.unwrap_or(f64::NAN);
    // Tied sets are one answer: the sentence names them together and says why.
    let tied: Vec<&SetSummary> = sets
        .iter()
        .filter(|s| best.tied_with.contains(&s.name))
        .collect();
    let best_names = if tied.is_empty() {
        best.name.clone()
    } else {
        let mut names: Vec<&str> = vec![best.name.as_str()];
        names.extend(tied.iter().map(|s| s.name.as_str()));
        let spread = tied
            .iter()
            .filter_map(|s| s.out_of_sample_nm)
            .map(|x| (x - e).abs())
            .fold(0.0, f64::max);
        format!(
            "{}, indistinguishable here: {}",
            join_and(&names),
            if best.same_torques {
                format!(
                    "the same torque within {} N m at every point",
                    SAME_TORQUE_NM
                )
            } else {
                format!(
                    "out-of-sample errors {} N m apart, within the noise",
                    nm(spread)
                )
            }
        )
    };
    let share = 100.0 * e / mean.max(1e-300);
    let noise_words = format!(
        "{} N m{}",
        nm(noise),
        if assumed {
            ", assumed: 5% of the mean torque, as the data declare none"
        } else {
            ""
        }
    );
    let k = best.params;
    let params_words = match best.status {
        CalibrationStatus::NoFreeParameters => "with no parameter fitted to these data".to_string(),
        CalibrationStatus::NotFitted => "at the law-set file's values (not fitted)".to_string(),
        CalibrationStatus::Fitted if best.undetermined == 0 => {
            "with every parameter determined".to_string()
        }
        CalibrationStatus::Fitted if best.on_bounds == k => {
            if k == 1 {
                "and its parameter sits on a bound of its allowed range".to_string()
            } else {
                "and its parameters sit on the bounds of their allowed ranges".to_string()
            }
        }
        CalibrationStatus::Fitted if best.on_bounds > 0 => format!(
            "and {} of its {k} parameters {}{}",
            best.on_bounds,
            if best.on_bounds == 1 {
                "sits on its bound"
            } else {
                "sit on their bounds"
            },
            if best.undetermined > best.on_bounds {
                format!(
                    ", {} more not determined by these data",
                    best.undetermined - best.on_bounds
                )
            } else {
                String::new()
            }
        ),
        CalibrationStatus::Fitted => format!(
            "but {} of its {k} parameters are not determined by these data",
            best.undetermined
        ),
    };
    let determined = best.status != CalibrationStatus::Fitted || best.undetermined == 0;
    let (rule, mut sentence) = if e <= noise && determined {
        (
            VerdictRule::Predicts,
            format!(
                "{best_names} predicts unseen points within {} N m ({share:.0}% of the mean torque, inside the noise of {noise_words}) {params_words}",
                nm(e)
            ),
        )
    } else if e <= noise {
        (
            VerdictRule::PredictsUndetermined,
            format!(
                "{best_names} predicts unseen points within the noise ({} N m against {noise_words}), {params_words}: trust its curve, not its parameter values",
                nm(e)
            ),
        )
    } else {
        let worst = best
            .point_errors_nm
            .iter()
            .zip(measured)
            .zip(speeds_rpm)
            .filter_map(|((err, m), rpm)| {
                err.map(|err| (100.0 * err.abs() / m.abs().max(1e-300), *rpm))
            })
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let miss = worst.map_or(String::new(), |(pct, rpm)| {
            format!(
                "{}misses {rpm:.0} rpm by {pct:.0}%",
                if tied.is_empty() {
                    ", which ".to_string()
                } else {
                    format!("; {} ", best.name)
                }
            )
        });
        (
            VerdictRule::Misses,
            format!(
                "no set reproduces the data within their noise ({noise_words}): the best out-of-sample error is {} N m ({share:.0}% of the mean torque; {best_names}{miss}), {params_words}",
                nm(e),
            ),
        )
    };
    if best.max_rise_percent_per_10c > TEMPERATURE_RISE_FLAG_PERCENT {
        sentence.push_str(&format!(
            "; its torque rises {:.0}% per 10 C of oil warming, against full-film physics",
            best.max_rise_percent_per_10c
        ));
    }
    let fitted_unjudged: Vec<&str> = unjudged
        .iter()
        .copied()
        .filter(|n| {
            sets.iter()
                .any(|s| s.name == *n && s.status == CalibrationStatus::Fitted)
        })
        .collect();
    if !fitted_unjudged.is_empty() {
        sentence.push_str(&format!(
            "; not judged, without an out-of-sample error: {}",
            fitted_unjudged.join(", ")
        ));
    }
    Verdict {
        rule,
        set: Some(best.name.clone()),
        noise_nm: Some(noise),
        noise_assumed: assumed,
        sentence,
    }
}

/// `a`, `a and b`, `a, b and c`.
fn join_and(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => one.to_string(),
        [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MEASURED: [f64; 4] = [1.0, 1.5, 1.5, 1.0];
    const SPEEDS: [f64; 4] = [3000.0, 5000.0, 7000.0, 9000.0];

    fn set(name: &str, loo: Option<f64>, status: CalibrationStatus, k: usize) -> SetSummary {
        SetSummary {
            name: name.into(),
            out_of_sample_nm: loo,
            point_errors_nm: vec![loo; 4],
            status,
            params: k,
            on_bounds: 0,
            undetermined: 0,
            prior_fitted: 0,
            max_rise_percent_per_10c: -5.0,
            tied_with: Vec::new(),
            same_torques: false,
        }
    }

    #[test]
    fn tied_sets_are_named_together_as_indistinguishable_and_why() {
        let mut a = set("alpha", Some(0.3), CalibrationStatus::Fitted, 1);
        let mut b = set("beta", Some(0.3 + 2e-6), CalibrationStatus::Fitted, 2);
        a.tied_with = vec!["beta".into()];
        b.tied_with = vec!["alpha".into()];
        a.same_torques = true;
        b.same_torques = true;
        let v = verdict(&[b.clone(), a.clone()], &MEASURED, &SPEEDS, Some(0.05));
        assert_eq!(v.rule, VerdictRule::Misses);
        assert!(
            v.sentence
                .contains("alpha and beta, indistinguishable here: the same torque"),
            "{}",
            v.sentence
        );
        // Different torques, errors apart by less than the noise: said so instead.
        a.same_torques = false;
        b.same_torques = false;
        let v = verdict(&[a, b], &MEASURED, &SPEEDS, Some(0.05));
        assert!(v.sentence.contains("within the noise"), "{}", v.sentence);
    }

    #[test]
    fn no_sets_no_results() {
        let v = verdict(&[], &MEASURED, &SPEEDS, None);
        assert_eq!(v.rule, VerdictRule::NoResults);
    }

    #[test]
    fn a_determined_set_within_the_declared_noise_predicts() {
        let mut a = set("alpha", Some(0.04), CalibrationStatus::Fitted, 2);
        a.point_errors_nm = vec![Some(0.03), Some(-0.05), Some(0.04), Some(0.02)];
        let b = set("beta", Some(0.3), CalibrationStatus::NoFreeParameters, 0);
        let v = verdict(&[b, a], &MEASURED, &SPEEDS, Some(0.05));
        assert_eq!(v.rule, VerdictRule::Predicts);
        assert_eq!(v.set.as_deref(), Some("alpha"));
        assert!(!v.noise_assumed);
        assert!(
            v.sentence.starts_with(
                "alpha predicts unseen points within 0.040 N m (3% of the mean torque"
            ) && v.sentence.ends_with("with every parameter determined"),
            "{}",
            v.sentence
        );
    }

    #[test]
    fn within_the_noise_with_a_parameter_on_its_bound_is_not_a_clean_prediction() {
        let mut a = set("alpha", Some(0.04), CalibrationStatus::Fitted, 2);
        a.on_bounds = 1;
        a.undetermined = 1;
        let v = verdict(&[a], &MEASURED, &SPEEDS, Some(0.05));
        assert_eq!(v.rule, VerdictRule::PredictsUndetermined);
        assert!(
            v.sentence
                .contains("1 of its 2 parameters sits on its bound")
                && v.sentence
                    .contains("trust its curve, not its parameter values"),
            "{}",
            v.sentence
        );
    }

    #[test]
    fn above_the_noise_misses_and_names_the_worst_point_and_the_bounds() {
        // Mean measured torque 1.25 N m; no declared noise: 5% of it (0.0625 N m) assumed.
        let mut a = set("alpha", Some(0.49), CalibrationStatus::Fitted, 3);
        a.point_errors_nm = vec![Some(-0.35), Some(-0.83), Some(0.2), Some(0.3)];
        a.on_bounds = 3;
        a.undetermined = 3;
        a.max_rise_percent_per_10c = 11.0;
        let b = set("beta", Some(0.75), CalibrationStatus::Fitted, 1);
        let mut tuned = set("tuned", None, CalibrationStatus::NoFreeParameters, 0);
        tuned.prior_fitted = 17;
        let v = verdict(&[tuned, b, a], &MEASURED, &SPEEDS, None);
        assert_eq!(v.rule, VerdictRule::Misses);
        assert!(v.noise_assumed);
        assert!((v.noise_nm.expect("noise") - 0.0625).abs() < 1e-12);
        let s = &v.sentence;
        assert!(
            s.starts_with("no set reproduces the data within their noise (0.062 N m, assumed"),
            "{s}"
        );
        assert!(s.contains("the best out-of-sample error is 0.49 N m (39% of the mean torque; alpha, which misses 5000 rpm by 55%)"), "{s}");
        assert!(
            s.contains("its parameters sit on the bounds of their allowed ranges"),
            "{s}"
        );
        assert!(s.contains("rises 11% per 10 C"), "{s}");
        // A set tuned elsewhere has no out-of-sample error but is not a fitted set left unjudged.
        assert!(!s.contains("not judged"), "{s}");
    }

    #[test]
    fn a_set_without_parameters_is_judged_by_its_error_alone() {
        let v = verdict(
            &[set(
                "plain",
                Some(0.02),
                CalibrationStatus::NoFreeParameters,
                0,
            )],
            &MEASURED,
            &SPEEDS,
            Some(0.05),
        );
        assert_eq!(v.rule, VerdictRule::Predicts);
        assert!(
            v.sentence
                .ends_with("with no parameter fitted to these data"),
            "{}",
            v.sentence
        );
        let v = verdict(
            &[set("file", Some(0.02), CalibrationStatus::NotFitted, 2)],
            &MEASURED,
            &SPEEDS,
            Some(0.05),
        );
        assert!(v.sentence.contains("(not fitted)"), "{}", v.sentence);
    }

    #[test]
    fn without_any_out_of_sample_error_nothing_is_judged() {
        let mut tuned = set("tuned", None, CalibrationStatus::NoFreeParameters, 0);
        tuned.prior_fitted = 17;
        let v = verdict(&[tuned.clone()], &MEASURED, &SPEEDS, None);
        assert_eq!(v.rule, VerdictRule::NotJudged);
        assert!(
            v.sentence.contains("tuned to these data elsewhere"),
            "{}",
            v.sentence
        );
        let fitted = set("fitted", None, CalibrationStatus::Fitted, 2);
        let v = verdict(&[tuned, fitted.clone()], &MEASURED, &SPEEDS, None);
        assert_eq!(v.rule, VerdictRule::NotJudged);
        assert!(v.sentence.contains("--no-cv"), "{}", v.sentence);
        // With a judged set beside it, the fitted set without a figure is named as unjudged.
        let plain = set("plain", Some(0.5), CalibrationStatus::NoFreeParameters, 0);
        let v = verdict(&[fitted, plain], &MEASURED, &SPEEDS, None);
        assert_eq!(v.rule, VerdictRule::Misses);
        assert!(
            v.sentence
                .ends_with("not judged, without an out-of-sample error: fitted"),
            "{}",
            v.sentence
        );
    }
}
