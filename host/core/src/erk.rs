//! Embedded explicit Runge-Kutta pairs and the step-size controller of the torque-driven run.
//!
//! A pair gives two solutions of different order from the same stages; their difference
//! estimates the local error, so the step can follow the dynamics instead of being fixed. The
//! pairs here are "first same as last": the last stage is evaluated at the accepted end state,
//! so it is the next step's first stage and each step costs one evaluation fewer than it has
//! stages. Coefficients are the published ones (cited per pair). Dormand-Prince 5(4) is the
//! one in use: on the thesis cycle Bogacki-Shampine 3(2) needed six times the evaluations for
//! the same tolerance (docs/performance.md).

/// The Butcher tableau of an embedded FSAL pair.
#[derive(Debug)]
pub struct Pair {
    /// Name for messages and docs.
    pub name: &'static str,
    /// Stage times as fractions of the step.
    pub c: &'static [f64],
    /// Stage coefficients: row `s` has `s` entries (explicit); the last row equals `b` (FSAL).
    pub a: &'static [&'static [f64]],
    /// Weights of the propagated (higher-order) solution.
    pub b: &'static [f64],
    /// Error weights: `b` minus the weights of the embedded lower-order solution.
    pub e: &'static [f64],
    /// Order of the propagated solution.
    pub order: u32,
    /// Order of the embedded solution (the local error estimate is `O(h^(low_order + 1))`).
    pub low_order: u32,
}

impl Pair {
    /// Number of stages (evaluations per step are one fewer, the first being reused).
    pub fn stages(&self) -> usize {
        self.c.len()
    }
}

/// Weights of Dormand-Prince 5(4)'s propagated solution (also its last stage row).
const DP54_B: [f64; 7] = [
    35.0 / 384.0,
    0.0,
    500.0 / 1113.0,
    125.0 / 192.0,
    -2187.0 / 6784.0,
    11.0 / 84.0,
    0.0,
];

/// Dormand & Prince, "A family of embedded Runge-Kutta formulae", J. Comp. Appl. Math. 6(1),
/// 1980: order 5 with an order-4 error estimate, 7 stages, FSAL (MATLAB's `ode45`).
pub const DORMAND_PRINCE_54: Pair = Pair {
    name: "Dormand-Prince 5(4)",
    c: &[0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0],
    a: &[
        &[],
        &[1.0 / 5.0],
        &[3.0 / 40.0, 9.0 / 40.0],
        &[44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0],
        &[
            19372.0 / 6561.0,
            -25360.0 / 2187.0,
            64448.0 / 6561.0,
            -212.0 / 729.0,
        ],
        &[
            9017.0 / 3168.0,
            -355.0 / 33.0,
            46732.0 / 5247.0,
            49.0 / 176.0,
            -5103.0 / 18656.0,
        ],
        // FSAL: the last stage is evaluated at the propagated solution.
        DP54_B.as_slice().split_at(6).0,
    ],
    b: &DP54_B,
    e: &[
        35.0 / 384.0 - 5179.0 / 57600.0,
        0.0,
        500.0 / 1113.0 - 7571.0 / 16695.0,
        125.0 / 192.0 - 393.0 / 640.0,
        -2187.0 / 6784.0 + 92097.0 / 339200.0,
        11.0 / 84.0 - 187.0 / 2100.0,
        -1.0 / 40.0,
    ],
    order: 5,
    low_order: 4,
};

/// Step-size control for an error measured per unit step: `err <= 1` accepts, and the next step
/// aims at `err = 0.9^k` (safety factor 0.9 on the step) within a factor 0.2..5 of this one.
/// `k` is the order of the controlled error in `h`, here `low_order` (the estimate is
/// `O(h^(low_order + 1))`, divided by the step).
///
/// Two forms. Integral (elementary) control: `h_new = 0.9 h err^(-1/k)`. Proportional-integral
/// control, in the form of Hairer & Wanner's DOPRI5 code (Hairer, Norsett & Wanner, Solving
/// Ordinary Differential Equations I, 2nd ed., section II.4, "Lund stabilization", after
/// K. Gustafsson, ACM TOMS 17(4), 1991): `h_new = 0.9 h err^(-1/k) (err_prev / 0.9^k)^beta`
/// after an accepted step, `err_prev` being the previous accepted step's error, `beta = 0.04`
/// (their default); after a rejection the integral form. The error target `0.9^k` is the
/// integral controller's, so the two differ only by the proportional term. (Gustafsson's own
/// exponents 0.7/k and 0.4/k with the safety factor 0.9 aim at much smaller errors and took
/// 22% more steps on the thesis cycle; docs/performance.md.)
#[derive(Debug, Clone, Copy)]
pub struct Controller {
    /// Exponent of this step's error: `1 / k`.
    exponent: f64,
    /// Exponent of the previous accepted step's error: 0 (integral) or `PI_BETA`.
    beta: f64,
    /// The error both forms aim at, `0.9^k`.
    target: f64,
    /// The previous accepted step's error (the target before the first step, which makes the
    /// first step integral; floored at 1e-4 so one very accurate step cannot hold back the next).
    err_prev: f64,
}

/// Exponent of the previous error in the PI form: DOPRI5's default. On the thesis cycle 0.02
/// to 0.04 took 1-2% fewer step attempts than integral control, 0.06 and more took more.
const PI_BETA: f64 = 0.04;

impl Controller {
    /// The integral controller for `pair`.
    pub fn new(pair: &Pair) -> Self {
        Self::of_order(pair.low_order)
    }

    /// The proportional-integral controller for `pair`.
    pub fn pi(pair: &Pair) -> Self {
        Self::pi_of_order(pair.low_order)
    }

    /// The integral controller for an error estimate of order `k` (`O(h^(k + 1))` per step),
    /// for step methods that are no Runge-Kutta pair (the prescribed crank's quadrature).
    pub fn of_order(k: u32) -> Self {
        let target = 0.9_f64.powi(k as i32);
        let k = k as f64;
        Self {
            exponent: 1.0 / k,
            beta: 0.0,
            target,
            err_prev: target,
        }
    }

    /// The proportional-integral controller for an error estimate of order `k`.
    pub fn pi_of_order(k: u32) -> Self {
        Self {
            beta: PI_BETA,
            ..Self::of_order(k)
        }
    }

    /// The next step after a step `h` with scaled error `err`. After a rejection the step never
    /// grows (`rejected`), so a step that failed is not immediately retried larger. An
    /// accepted step's error is remembered with [`Controller::accepted`].
    pub fn next(&self, h: f64, err: f64, rejected: bool) -> f64 {
        let fac = if err <= 0.0 {
            5.0
        } else if rejected || self.beta == 0.0 {
            0.9 * err.powf(-self.exponent)
        } else {
            0.9 * err.powf(-self.exponent) * (self.err_prev / self.target).powf(self.beta)
        };
        let max = if rejected { 1.0 } else { 5.0 };
        h * fac.clamp(0.2, max)
    }

    /// Remember the error of an accepted step (the PI form's memory).
    pub fn accepted(&mut self, err: f64) {
        self.err_prev = err.max(1e-4);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_tableau(p: &Pair) {
        let s = p.stages();
        assert_eq!(p.a.len(), s);
        assert_eq!(p.b.len(), s);
        assert_eq!(p.e.len(), s);
        for (i, row) in p.a.iter().enumerate() {
            assert_eq!(row.len(), i, "{}: row {i} must be explicit", p.name);
            let sum: f64 = row.iter().sum();
            assert!(
                (sum - p.c[i]).abs() < 1e-14,
                "{}: row {i} sums to c",
                p.name
            );
        }
        // FSAL: the last stage is the propagated solution.
        for (j, w) in p.a[s - 1].iter().enumerate() {
            assert!((w - p.b[j]).abs() < 1e-15, "{}: FSAL weight {j}", p.name);
        }
        assert!((p.c[s - 1] - 1.0).abs() < 1e-15);
        // Both solutions are consistent: weights sum to 1, error weights to 0.
        assert!((p.b.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        assert!(p.e.iter().sum::<f64>().abs() < 1e-14);
    }

    #[test]
    fn tableaus_are_explicit_consistent_and_fsal() {
        check_tableau(&DORMAND_PRINCE_54);
    }

    /// Fixed-step integration of y' = -y^2 exp(t), y(0) = 1 (exact: y = exp(-t)) to t = 1.5 with
    /// the pair's propagated solution; returns the final error and the mean error estimate.
    /// (Problems whose leading error term happens to cancel, like y' = -y cos t, show an
    /// erratic observed order and are no test of the coefficients.)
    fn integrate(p: &Pair, steps: usize) -> (f64, f64) {
        let f = |t: f64, y: f64| -y * y * t.exp();
        let t_end = 1.5_f64;
        let h = t_end / steps as f64;
        let (mut t, mut y) = (0.0_f64, 1.0_f64);
        let mut est = 0.0;
        for _ in 0..steps {
            let mut k = vec![0.0; p.stages()];
            for s in 0..p.stages() {
                let ys = y + h * p.a[s].iter().zip(&k).map(|(a, k)| a * k).sum::<f64>();
                k[s] = f(t + p.c[s] * h, ys);
            }
            est += (h * p.e.iter().zip(&k).map(|(e, k)| e * k).sum::<f64>()).abs();
            y += h * p.b.iter().zip(&k).map(|(b, k)| b * k).sum::<f64>();
            t += h;
        }
        ((y - (-t_end).exp()).abs(), est / steps as f64)
    }

    #[test]
    fn pairs_converge_at_their_order_and_estimate_the_lower_one() {
        {
            let p = &DORMAND_PRINCE_54;
            let (e1, d1) = integrate(p, 40);
            let (e2, d2) = integrate(p, 80);
            let observed = (e1 / e2).log2();
            assert!(
                (observed - p.order as f64).abs() < 0.3,
                "{}: global order {observed}",
                p.name
            );
            let local = (d1 / d2).log2();
            assert!(
                (local - (p.low_order + 1) as f64).abs() < 0.3,
                "{}: local estimate order {local}",
                p.name
            );
        }
    }

    #[test]
    fn controller_shrinks_on_large_errors_and_never_grows_after_a_rejection() {
        let c = Controller::new(&DORMAND_PRINCE_54);
        assert!(c.next(1.0, 2.0, false) < 1.0);
        assert_eq!(c.next(1.0, 1e-12, false), 5.0);
        assert_eq!(c.next(1.0, 1e-12, true), 1.0);
        assert_eq!(c.next(1.0, 1e12, true), 0.2);
        // At the target error the step stays close to what it was.
        let h = c.next(1.0, 0.9_f64.powf(4.0), false);
        assert!((h - 1.0).abs() < 1e-12, "{h}");
    }

    #[test]
    fn pi_controller_is_integral_on_target_and_follows_the_error_trend() {
        let pair = &DORMAND_PRINCE_54;
        let (integral, mut pi) = (Controller::new(pair), Controller::pi(pair));
        // Before any accepted step, and whenever the previous error was on target, the two agree.
        for err in [1e-3, 0.1, 0.5, 0.99] {
            let (a, b) = (integral.next(1.0, err, false), pi.next(1.0, err, false));
            assert!((a - b).abs() < 1e-12, "{err}: {a} vs {b}");
        }
        // A previous error above target with this one below it is a falling error: the
        // proportional term lets the step grow faster than the integral form; a rising error
        // (the previous one below target) slower.
        pi.accepted(0.95);
        assert!(pi.next(1.0, 0.3, false) > integral.next(1.0, 0.3, false));
        pi.accepted(1e-3);
        assert!(pi.next(1.0, 0.3, false) < integral.next(1.0, 0.3, false));
        // After a rejection both use the integral form and never grow.
        assert_eq!(pi.next(1.0, 2.0, true), integral.next(1.0, 2.0, true));
        assert!(pi.next(1.0, 1e-6, true) <= 1.0);
    }
}
