//! What the data say about a calibrated parameter set: standard deviations and correlations
//! from the linearised covariance `s^2 (J^T J)^-1`, the conditioning of the problem, and the 95%
//! confidence band of the model torque at each data point (the delta method).
//!
//! Why the covariance and not a bootstrap: a residual bootstrap needs hundreds of refits (each
//! a full calibration), and with as few residual degrees of freedom as engine friction data
//! have (7 points, 2 to 6 parameters) the resampled residuals carry almost no information. The
//! linearisation is stated, and where it cannot be trusted (a near-singular `J^T J`, no degrees
//! of freedom) the report says so instead of printing numbers.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use statrs::distribution::{ContinuousCDF, StudentsT};

use crate::model::TorqueModel;

/// The linearised uncertainty of a parameter set on its data.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Uncertainty {
    /// Residual degrees of freedom: points minus free parameters.
    pub dof: usize,
    /// Residual standard deviation `sqrt(RSS / dof)`, N m (`None` without degrees of freedom).
    pub residual_sd_nm: Option<f64>,
    /// Student's t quantile for a two-sided 95% interval at `dof`.
    pub t95: Option<f64>,
    /// 1-sigma standard deviation of each parameter; `None` where undetermined.
    pub std_dev: Vec<Option<f64>>,
    /// 95% interval of each parameter (value +- t95 sigma); `None` where undetermined.
    pub interval95: Vec<Option<[f64; 2]>>,
    /// Correlation matrix of the parameters, when it exists.
    pub correlation: Option<Vec<Vec<f64>>>,
    /// Ratio of the largest to the smallest singular value of the Jacobian in relative
    /// parameter changes: how close the data come to not telling the parameters apart.
    pub condition_number: Option<f64>,
    /// Half-width of the 95% confidence band of the model torque at each point, N m.
    pub band_half_width_nm: Option<Vec<f64>>,
    /// Plain statements of what is not determined and why.
    pub statements: Vec<String>,
}

impl Uncertainty {
    /// No free parameters: nothing is estimated, so no band from fitting exists (the set's
    /// structural error is what its residuals show).
    pub fn none(points: usize) -> Self {
        Self {
            dof: points,
            residual_sd_nm: None,
            t95: None,
            std_dev: Vec::new(),
            interval95: Vec::new(),
            correlation: None,
            condition_number: None,
            band_half_width_nm: None,
            statements: Vec::new(),
        }
    }
}

/// A parameter whose 1-sigma uncertainty exceeds this fraction of its value is reported as
/// poorly determined (its 95% interval then reaches past zero or the other side of it).
pub const POORLY_DETERMINED: f64 = 0.5;

/// The 95% band of a positive model torque `t` from the linearised half-widths `half` (the
/// delta method on `T`), taken on a log scale: the delta method on `ln T` gives the half-width
/// `h / T`, mapped back as `[T exp(-h/T), T exp(h/T)]`. It equals `T -+ h` to first order, never
/// reaches zero or below (a friction torque cannot), and is symmetric in ratio
/// (`lower * upper = T^2`). `None` when a torque is not positive (no log scale exists there).
pub fn log_band(t: &[f64], half: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    if t.len() != half.len()
        || t.iter()
            .any(|v| v.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater))
    {
        return None;
    }
    let ratio: Vec<f64> = t.iter().zip(half).map(|(t, h)| (h / t).exp()).collect();
    Some((
        t.iter().zip(&ratio).map(|(t, r)| t / r).collect(),
        t.iter().zip(&ratio).map(|(t, r)| t * r).collect(),
    ))
}

/// Condition number of the scaled Jacobian above which `J^T J` is treated as singular
/// (relative parameter changes). The central differences resolve a singular value only down to
/// a noise floor: two main bearings carrying one load on one radius (an exactly confounded pair)
/// measured 8.9e7 once the kinematics' last bits changed, and more than 1e8 before; 1e7 stays a
/// factor of about nine under that floor.
const SINGULAR_CONDITION: f64 = 1e7;

/// A parameter's finite-difference step: relative to its value, or to its range near zero.
fn step(x: f64, bounds: [f64; 2]) -> f64 {
    1e-6 * x
        .abs()
        .max(1e-3 * (bounds[1] - bounds[0]).abs())
        .max(1e-300)
}

/// The Jacobian of the model torques with respect to the physical parameters at `x`: central
/// differences, one-sided at a bound. A column whose runs fail is `None`.
fn jacobian(model: &TorqueModel<'_>, x: &[f64], base: &[f64]) -> Vec<Option<Vec<f64>>> {
    let free = model.free();
    (0..x.len())
        .map(|k| {
            let [lo, hi] = free[k].bounds;
            let h = step(x[k], free[k].bounds);
            let at = |v: f64| {
                let mut p = x.to_vec();
                p[k] = v;
                model.torques(&p).ok()
            };
            let col = if x[k] + h <= hi && x[k] - h >= lo {
                let (a, b) = (at(x[k] + h)?, at(x[k] - h)?);
                a.iter().zip(&b).map(|(a, b)| (a - b) / (2.0 * h)).collect()
            } else if x[k] + h <= hi {
                let a = at(x[k] + h)?;
                a.iter().zip(base).map(|(a, b)| (a - b) / h).collect()
            } else {
                let b = at(x[k] - h)?;
                base.iter().zip(&b).map(|(a, b)| (a - b) / h).collect()
            };
            Some(col)
        })
        .collect()
}

/// The uncertainty of parameters `x` of `model` where some may sit on their bounds. A bound
/// that holds is an active constraint: the linearisation is only valid for the parameters
/// inside their ranges, so those on a bound are held at it (no sigma, no interval) and the
/// others' uncertainty and the band are computed with them fixed.
pub fn uncertainty_within_bounds(
    model: &TorqueModel<'_>,
    x: &[f64],
    residuals: &[f64],
    on_bound: &[bool],
) -> Uncertainty {
    if !on_bound.iter().any(|b| *b) {
        return uncertainty(model, x, residuals);
    }
    let (rig, lawset, registry) = model.parts();
    let free = model.free();
    let pinned = lawset.with_values(free, x);
    let inner: Vec<tribo_config::lawset::FreeParam> = free
        .iter()
        .zip(on_bound)
        .filter(|(_, b)| !**b)
        .map(|(f, _)| f.clone())
        .collect();
    let xi: Vec<f64> = x
        .iter()
        .zip(on_bound)
        .filter(|(_, b)| !**b)
        .map(|(v, _)| *v)
        .collect();
    let sub = TorqueModel::new(rig, &pinned, &inner, model.runs().to_vec(), registry);
    let mut u = if inner.is_empty() {
        // Nothing inside its range is left to vary: no band can be estimated (a zero band
        // would claim a certainty the data never gave).
        let mut u = Uncertainty::none(residuals.len());
        u.band_half_width_nm = None;
        u.std_dev = vec![None; 0];
        u
    } else {
        uncertainty(&sub, &xi, residuals)
    };
    // Back to the full parameter list: the pinned ones have no sigma.
    let mut it_sd = u.std_dev.clone().into_iter();
    let mut it_iv = u.interval95.clone().into_iter();
    u.std_dev = on_bound
        .iter()
        .map(|b| if *b { None } else { it_sd.next().flatten() })
        .collect();
    u.interval95 = on_bound
        .iter()
        .map(|b| if *b { None } else { it_iv.next().flatten() })
        .collect();
    u.correlation = None;
    let held: Vec<&str> = free
        .iter()
        .zip(on_bound)
        .filter(|(_, b)| **b)
        .map(|(f, _)| f.id.as_str())
        .collect();
    u.statements.push(format!(
        "{} {} on {} bound: held there as an active constraint (the data push past the allowed range), so sigmas and the band cover only the parameters inside their ranges",
        held.join(", "),
        if held.len() == 1 { "is" } else { "are" },
        if held.len() == 1 { "its" } else { "their" }
    ));
    u
}

/// The Jacobian in physical units, the relative scale of each parameter (its value, or its
/// range near zero), and the ids of parameters whose neighbourhood does not run.
struct Sensitivity {
    j: DMatrix<f64>,
    scale: Vec<f64>,
    failed: Vec<String>,
}

impl Sensitivity {
    fn at(model: &TorqueModel<'_>, x: &[f64], base: &[f64]) -> Self {
        let free = model.free();
        let (m, n) = (base.len(), x.len());
        let scale = x
            .iter()
            .zip(free)
            .map(|(v, f)| {
                let range = (f.bounds[1] - f.bounds[0]).abs();
                if v.abs() > 1e-3 * range {
                    v.abs()
                } else {
                    range
                }
            })
            .collect();
        let mut j = DMatrix::zeros(m, n);
        let mut failed = Vec::new();
        for (k, c) in jacobian(model, x, base).iter().enumerate() {
            match c {
                Some(c) => j.column_mut(k).copy_from_slice(c),
                None => failed.push(free[k].id.clone()),
            }
        }
        Self { j, scale, failed }
    }

    /// The Jacobian in relative parameter changes (d torque / d ln x).
    fn scaled(&self) -> DMatrix<f64> {
        let (m, n) = self.j.shape();
        DMatrix::from_fn(m, n, |i, k| self.j[(i, k)] * self.scale[k])
    }

    /// Statements for parameters the torque does not respond to.
    fn insensitive(&self, ids: &[&str]) -> Vec<String> {
        let js = self.scaled();
        (0..js.ncols())
            .filter_map(|k| {
                let sens = js.column(k).norm();
                (sens < 1e-6).then(|| format!(
                    "{}: the torque does not respond to it here (sensitivity {sens:.1e} N m per relative change); its value is arbitrary",
                    ids[k]
                ))
            })
            .collect()
    }
}

/// Condition number of the scaled Jacobian, and the parameter combination along its weakest
/// direction (what the data cannot see), as `+0.71 d ln a -0.70 d ln b`.
fn conditioning(js: &DMatrix<f64>, ids: &[&str]) -> (f64, String) {
    let (m, n) = js.shape();
    let svd = js.clone().svd(false, true);
    let sv = &svd.singular_values;
    let smax = sv.iter().copied().fold(0.0_f64, f64::max);
    let smin = if m >= n {
        sv.iter().copied().fold(f64::INFINITY, f64::min)
    } else {
        0.0
    };
    let cond = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    let weakest = svd.v_t.as_ref().and_then(|vt| {
        let k = (0..sv.len()).min_by(|a, b| sv[*a].total_cmp(&sv[*b]))?;
        Some(vt.row(k).iter().copied().collect::<Vec<f64>>())
    });
    let combo = weakest
        .map(|w| {
            let mut terms: Vec<(f64, &str)> = w.iter().copied().zip(ids.iter().copied()).collect();
            terms.sort_by(|a, b| b.0.abs().total_cmp(&a.0.abs()));
            terms
                .iter()
                .filter(|(c, _)| c.abs() > 0.1)
                .map(|(c, id)| format!("{c:+.2} d ln {id}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_default();
    (cond, combo)
}

/// Standard deviations, 95% intervals, correlations and their statements from the covariance.
fn from_covariance(out: &mut Uncertainty, cov: &DMatrix<f64>, x: &[f64], ids: &[&str]) {
    let n = x.len();
    let t = out.t95.unwrap_or(f64::NAN);
    let sd: Vec<f64> = (0..n).map(|k| cov[(k, k)].max(0.0).sqrt()).collect();
    for k in 0..n {
        out.std_dev[k] = Some(sd[k]);
        out.interval95[k] = Some([x[k] - t * sd[k], x[k] + t * sd[k]]);
        if sd[k] > POORLY_DETERMINED * x[k].abs() {
            out.statements.push(format!(
                "{}: poorly determined, {:.4e} +- {:.2e} (1 sigma)",
                ids[k], x[k], sd[k]
            ));
        }
    }
    let corr: Vec<Vec<f64>> = (0..n)
        .map(|a| {
            (0..n)
                .map(|b| cov[(a, b)] / (sd[a] * sd[b]).max(1e-300))
                .collect()
        })
        .collect();
    for a in 0..n {
        for b in a + 1..n {
            if corr[a][b].abs() > 0.99 {
                out.statements.push(format!(
                    "{} and {} are {:.3} correlated: the data fix a combination of them, not each",
                    ids[a], ids[b], corr[a][b]
                ));
            }
        }
    }
    out.correlation = Some(corr);
}

/// The uncertainty of parameters `x` of `model`, whose residuals there are `residuals`.
pub fn uncertainty(model: &TorqueModel<'_>, x: &[f64], residuals: &[f64]) -> Uncertainty {
    let (m, n) = (residuals.len(), x.len());
    if n == 0 {
        return Uncertainty::none(m);
    }
    let ids: Vec<&str> = model.free().iter().map(|f| f.id.as_str()).collect();
    let dof = m.saturating_sub(n);
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    let mut out = Uncertainty {
        dof,
        residual_sd_nm: (dof > 0).then(|| (rss / dof as f64).sqrt()),
        t95: (dof > 0)
            .then(|| StudentsT::new(0.0, 1.0, dof as f64).ok())
            .flatten()
            .map(|t| t.inverse_cdf(0.975)),
        std_dev: vec![None; n],
        interval95: vec![None; n],
        correlation: None,
        condition_number: None,
        band_half_width_nm: None,
        statements: Vec::new(),
    };
    if m <= n {
        out.statements.push(format!(
            "{n} free parameters for {m} data points: no residual degrees of freedom, so the fit can pass through every point and the data say nothing about the parameters' uncertainty; fix some parameters or add data"
        ));
    }
    let Ok(base) = model.torques(x) else {
        out.statements
            .push("the model does not run at the fitted values".into());
        return out;
    };
    let sens = Sensitivity::at(model, x, &base);
    if !sens.failed.is_empty() {
        out.statements.push(format!(
            "the model does not run next to the fitted values of {}: their sensitivities are unknown",
            sens.failed.join(", ")
        ));
    }
    out.statements.extend(sens.insensitive(&ids));
    let js = sens.scaled();
    let (cond, combo) = conditioning(&js, &ids);
    out.condition_number = cond.is_finite().then_some(cond);
    if !sens.failed.is_empty() || dof == 0 {
        return out;
    }
    if cond > SINGULAR_CONDITION {
        out.statements.push(format!(
            "J^T J is singular or nearly so (condition number {}): the data cannot tell the parameters apart along {combo}; no uncertainties or bands are given; fix one of these parameters or add data that separate them",
            if cond.is_finite() { format!("{cond:.1e}") } else { "infinite".into() }
        ));
        return out;
    }
    let Some(inv) = (js.transpose() * &js).try_inverse() else {
        out.statements
            .push("J^T J could not be inverted: no uncertainties are given".into());
        return out;
    };
    // Covariance in physical units: S (s^2 (Js^T Js)^-1) S.
    let s2 = rss / dof as f64;
    let scale = &sens.scale;
    let cov = DMatrix::from_fn(n, n, |a, b| s2 * inv[(a, b)] * scale[a] * scale[b]);
    from_covariance(&mut out, &cov, x, &ids);
    // Delta method: var(T_i) = g_i^T C g_i with g_i the Jacobian row in physical units.
    let t = out.t95.unwrap_or(f64::NAN);
    let j = &sens.j;
    let band = (0..m)
        .map(|i| {
            let mut v = 0.0;
            for a in 0..n {
                for b in 0..n {
                    v += j[(i, a)] * cov[(a, b)] * j[(i, b)];
                }
            }
            t * v.max(0.0).sqrt()
        })
        .collect();
    out.band_half_width_nm = Some(band);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_band_stays_positive_and_matches_the_linear_band_when_narrow() {
        let t = [1.0, 0.2, 3.0];
        // Narrow: within 0.5% of T -+ h (second-order terms h^2 / 2T).
        let narrow = [0.01, 0.002, 0.03];
        let (lo, hi) = log_band(&t, &narrow).expect("band");
        for i in 0..3 {
            assert!((lo[i] - (t[i] - narrow[i])).abs() < 1e-4 * t[i]);
            assert!((hi[i] - (t[i] + narrow[i])).abs() < 1e-4 * t[i]);
        }
        // Wide: a linear half-width larger than the torque, where T - h < 0; the log band
        // stays above zero and is symmetric in ratio.
        let wide = [1.5, 0.5, 4.0];
        let (lo, hi) = log_band(&t, &wide).expect("band");
        for i in 0..3 {
            assert!(t[i] - wide[i] < 0.0 && lo[i] > 0.0, "{}", lo[i]);
            assert!((lo[i] * hi[i] - t[i] * t[i]).abs() < 1e-12 * t[i] * t[i]);
            assert!(lo[i] < t[i] && t[i] < hi[i]);
        }
        // A torque that is not positive has no log band.
        assert!(log_band(&[1.0, 0.0], &[0.1, 0.1]).is_none());
        assert!(log_band(&[1.0, -0.5], &[0.1, 0.1]).is_none());
    }

    #[test]
    fn t_quantiles_match_tables() {
        // Two-sided 95% quantiles of Student's t (any statistics table).
        for (dof, q) in [(1.0, 12.706), (2.0, 4.303), (5.0, 2.571), (30.0, 2.042)] {
            let t = StudentsT::new(0.0, 1.0, dof)
                .expect("valid")
                .inverse_cdf(0.975);
            assert!((t - q).abs() < 1e-3, "dof {dof}: {t}");
        }
    }
}
