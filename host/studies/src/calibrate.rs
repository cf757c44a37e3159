//! The optimiser under a calibration: bounds kept by a change of variable, Levenberg-Marquardt
//! on any [`Objective`], start points (the law set's own values, the box's corners, a Latin
//! hypercube) and the multi-start search; a parameter pushed against its bound named.

use std::sync::Mutex;

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use rayon::prelude::*;

use crate::inputs::errors;
use crate::model::{Objective, TorqueModel};

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
pub(crate) fn pushed_past_bound(
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
