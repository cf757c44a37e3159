//! `tribo fit`: least-squares calibration of a law set's free parameters to measured torque at
//! the measured speeds and oil temperatures (Levenberg-Marquardt on steady-state runs).
//!
//! Bounds are kept by a change of variable: each parameter is `lo + (hi - lo) * s(u)` with
//! `s(u) = (1 + tanh u) / 2` and `u` unbounded, in log space when the bounds span two decades or
//! more (thresholds, scales). The Jacobian is a forward difference in `u`, its columns run in
//! parallel.

use std::sync::Mutex;

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;
use serde::Serialize;
use tribo_plugin_api::loader::LawRegistry;

use crate::lawset::{FreeParam, LawSet};
use crate::rig::Rig;
use crate::study::{errors, prepare, run_rig, DataRow, StudyError};

/// The outcome of a calibration.
#[derive(Debug, Clone, Serialize)]
pub struct FitResult {
    /// Law set fitted.
    pub lawset: String,
    /// Parameter ids (`joint.law.param`).
    pub params: Vec<String>,
    /// Start values.
    pub start: Vec<f64>,
    /// Fitted values.
    pub values: Vec<f64>,
    /// Bounds.
    pub bounds: Vec<[f64; 2]>,
    /// Approximate 1-sigma uncertainty of each value (from the Jacobian), NaN if undetermined.
    pub std_dev: Vec<f64>,
    /// Speeds, rpm.
    pub speeds_rpm: Vec<f64>,
    /// Measured torque, N m.
    pub measured_nm: Vec<f64>,
    /// Model torque with the fitted values, N m.
    pub model_nm: Vec<f64>,
    /// Model minus measurement, N m.
    pub residuals_nm: Vec<f64>,
    /// Root-mean-square error, N m.
    pub rmse_nm: f64,
    /// Model evaluations made.
    pub evaluations: usize,
    /// Why the optimiser stopped.
    pub termination: String,
    /// Warnings about poorly determined parameters.
    pub warnings: Vec<String>,
}

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
    fn to_x(self, u: f64) -> f64 {
        let y = self.lo + (self.hi - self.lo) * 0.5 * (1.0 + u.tanh());
        if self.log {
            y.exp()
        } else {
            y
        }
    }
    fn to_u(self, x: f64) -> f64 {
        let y = if self.log {
            x.max(f64::MIN_POSITIVE).ln()
        } else {
            x
        };
        let s = ((y - self.lo) / (self.hi - self.lo)).clamp(1e-6, 1.0 - 1e-6);
        (2.0 * s - 1.0).atanh()
    }
}

struct Model<'a> {
    rig: &'a Rig,
    lawset: &'a LawSet,
    free: &'a [FreeParam],
    data: &'a [DataRow],
    registry: &'a LawRegistry,
    maps: Vec<Map>,
    evaluations: Mutex<usize>,
    error: Mutex<Option<String>>,
    /// The last parameters run and their torques: the optimiser asks for the Jacobian at the
    /// point whose residuals it has just computed.
    last: Mutex<Option<(Vec<f64>, Vec<f64>)>>,
}

impl Model<'_> {
    fn torques(&self, x: &[f64]) -> Option<Vec<f64>> {
        if let Ok(mut n) = self.evaluations.lock() {
            *n += 1;
        }
        let ls = self.lawset.with_values(self.free, x);
        let run = prepare(self.rig, &ls, Some(self.data))
            .map_err(|e| e.to_string())
            .and_then(|r| run_rig(&r, self.registry, true).map_err(|e| e.to_string()));
        match run {
            Ok(r) => Some(r.plateaus.iter().map(|p| p.motoring_torque_nm).collect()),
            Err(e) => {
                if let Ok(mut slot) = self.error.lock() {
                    slot.get_or_insert(e);
                }
                None
            }
        }
    }

    /// Torques, or a large penalty where the parameters do not run (thresholds crossed, say),
    /// so the optimiser rejects the step instead of stopping.
    fn torques_or_penalty(&self, x: &[f64]) -> Vec<f64> {
        self.torques(x)
            .unwrap_or_else(|| self.data.iter().map(|d| d.torque_nm + PENALTY_NM).collect())
    }

    /// As `torques_or_penalty`, remembering the result for the next call at the same point.
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

    fn x_of(&self, u: &DVector<f64>) -> Vec<f64> {
        u.iter().zip(&self.maps).map(|(u, m)| m.to_x(*u)).collect()
    }
}

/// Residual given to a parameter set that does not run, N m.
const PENALTY_NM: f64 = 1e3;

struct Problem<'a> {
    model: &'a Model<'a>,
    u: DVector<f64>,
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
        let t = self.model.torques_cached(&self.model.x_of(&self.u));
        Some(DVector::from_iterator(
            t.len(),
            t.iter().zip(self.model.data).map(|(m, d)| m - d.torque_nm),
        ))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        // Forward differences: one extra model run per parameter (the optimiser's own step
        // control tolerates their O(h) error; central differences doubled the fit's cost).
        let n = self.u.len();
        let m = self.model.data.len();
        let base = self.model.torques_cached(&self.model.x_of(&self.u));
        let cols: Vec<Vec<f64>> = (0..n)
            .into_par_iter()
            .map(|k| {
                let h = 1e-5 * (1.0 + self.u[k].abs());
                let mut up = self.u.clone();
                up[k] += h;
                let a = self.model.torques_or_penalty(&self.model.x_of(&up));
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

/// Calibrate `free` parameters of `lawset` on `rig` to `data`.
pub fn fit(
    rig: &Rig,
    lawset: &LawSet,
    free: &[FreeParam],
    data: &[DataRow],
    registry: &LawRegistry,
) -> Result<(FitResult, LawSet), StudyError> {
    let maps: Vec<Map> = free.iter().map(|f| Map::new(f.bounds)).collect();
    let model = Model {
        rig,
        lawset,
        free,
        data,
        registry,
        maps,
        evaluations: Mutex::new(0),
        error: Mutex::new(None),
        last: Mutex::new(None),
    };
    let u0 = DVector::from_iterator(
        free.len(),
        free.iter().zip(&model.maps).map(|(f, m)| m.to_u(f.value)),
    );
    // The start point must run; a failure there is the user's to fix, not the optimiser's.
    let start: Vec<f64> = free.iter().map(|f| f.value).collect();
    if model.torques(&start).is_none() {
        let msg = model
            .error
            .lock()
            .ok()
            .and_then(|e| e.clone())
            .unwrap_or_default();
        return Err(StudyError::Data {
            file: lawset.path.clone(),
            line: None,
            message: format!("the start values do not run: {msg}"),
        });
    }
    let problem = Problem {
        model: &model,
        u: u0,
    };
    let (done, report) = LevenbergMarquardt::new()
        .with_ftol(1e-7)
        .with_xtol(1e-7)
        .with_patience(30)
        .minimize(problem);
    let x = model.x_of(&done.u);
    let torques = model.torques(&x).ok_or_else(|| StudyError::Data {
        file: lawset.path.clone(),
        line: None,
        message: format!(
            "the fitted values do not run: {}",
            model
                .error
                .lock()
                .ok()
                .and_then(|e| e.clone())
                .unwrap_or_default()
        ),
    })?;
    let measured: Vec<f64> = data.iter().map(|d| d.torque_nm).collect();
    let (residuals_nm, rmse_nm, _) = errors(&torques, &measured);
    let (std_dev, warnings) = identifiability(&model, &x, &residuals_nm, free);
    let fitted = lawset.with_values(free, &x);
    let evaluations = model.evaluations.lock().map(|n| *n).unwrap_or(0);
    Ok((
        FitResult {
            lawset: lawset.name().into(),
            params: free.iter().map(|f| f.id.clone()).collect(),
            start,
            values: x,
            bounds: free.iter().map(|f| f.bounds).collect(),
            std_dev,
            speeds_rpm: data.iter().map(|d| d.speed_rpm).collect(),
            measured_nm: measured,
            model_nm: torques,
            residuals_nm,
            rmse_nm,
            evaluations,
            termination: format!("{:?}", report.termination),
            warnings,
        },
        fitted,
    ))
}

/// Uncertainties from the Jacobian in the physical parameters, and warnings for parameters the
/// data do not pin down (large relative uncertainty, near-perfect correlation, no sensitivity).
fn identifiability(
    model: &Model<'_>,
    x: &[f64],
    residuals: &[f64],
    free: &[FreeParam],
) -> (Vec<f64>, Vec<String>) {
    let (m, n) = (residuals.len(), x.len());
    let mut j = DMatrix::zeros(m, n);
    for k in 0..n {
        let h = 1e-6 * x[k].abs().max(1e-12);
        let (mut up, mut dn) = (x.to_vec(), x.to_vec());
        up[k] += h;
        dn[k] -= h;
        if let (Some(a), Some(b)) = (model.torques(&up), model.torques(&dn)) {
            for i in 0..m {
                j[(i, k)] = (a[i] - b[i]) / (2.0 * h);
            }
        }
    }
    let mut warnings = Vec::new();
    let dof = m.saturating_sub(n).max(1) as f64;
    let s2 = residuals.iter().map(|r| r * r).sum::<f64>() / dof;
    // Relative sensitivities (d torque / d ln x) expose parameters with no effect at all.
    for k in 0..n {
        let sens = (0..m)
            .map(|i| (j[(i, k)] * x[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        if sens < 1e-6 {
            warnings.push(format!("{}: the torque does not respond to it here (sensitivity {sens:.1e} N m per unit log change); its value is arbitrary", free[k].id));
        }
    }
    if m <= n {
        warnings.push(format!("{n} parameters for {m} data points: the fit can interpolate the data; expect the parameters to be poorly determined"));
    }
    let jtj = j.transpose() * &j;
    let std = match jtj.clone().try_inverse() {
        Some(inv) => {
            let sd: Vec<f64> = (0..n).map(|k| (s2 * inv[(k, k)]).max(0.0).sqrt()).collect();
            for k in 0..n {
                if sd[k] > 0.5 * x[k].abs() {
                    warnings.push(format!(
                        "{}: poorly determined, {} +- {:.2e} (1 sigma)",
                        free[k].id, x[k], sd[k]
                    ));
                }
                for l in k + 1..n {
                    let c = s2 * inv[(k, l)] / (sd[k] * sd[l]).max(1e-300);
                    if c.abs() > 0.99 {
                        warnings.push(format!("{} and {} are {:.3} correlated: the data fix a combination of them, not each", free[k].id, free[l].id, c));
                    }
                }
            }
            sd
        }
        None => {
            warnings.push(
                "the Jacobian is singular: some parameters cannot be told apart by these data"
                    .into(),
            );
            vec![f64::NAN; n]
        }
    };
    (std, warnings)
}
