//! Phase 1's view of its own progress (docs/solver.md): whether the plain fixed-point
//! iteration has converged, by the rig's `Distance` test, or is seen to stall, which hands the
//! evaluation to phase 2 (`newton.rs`). A leaf module: the evaluation reads it, and phase 2,
//! which uses the evaluation's scratch, needs nothing of it.

/// Phase 1 is kept while it is predicted to settle within this many more iterations (and the
/// limit): a Newton step costs one round of laws per law-bearing joint (up to five) plus at
/// least one more, so three of them cost about as much as twenty plain iterations.
const PLAIN_ITERATIONS_WORTH_KEEPING: u32 = 20;

/// Whether the plain fixed-point iteration will not settle in reasonable time, judged from its
/// last change `d` and the change two iterations before, `d2` (N): their ratio is the
/// contraction over two iterations, robust to the alternating sign of an iteration that
/// overshoots. Not contracting, or predicted (geometric series) to need more than
/// `PLAIN_ITERATIONS_WORTH_KEEPING` or `remaining` further iterations to bring the remainder
/// within `tol_n`, means it stalls.
pub(super) fn plain_iteration_stalls(d: f64, d2: f64, tol_n: f64, remaining: u32) -> bool {
    if d2 <= 0.0 || d <= 0.0 {
        return false;
    }
    let rho = (d / d2).sqrt();
    if rho >= 1.0 {
        return true;
    }
    // Still above tolerance after `limit` more iterations: d rho^limit rho / (1 - rho) > tol_n
    // (a product rather than a logarithm: this runs at every slow evaluation).
    let limit = PLAIN_ITERATIONS_WORTH_KEEPING.min(remaining);
    d * rho.powi(limit as i32) * rho > tol_n * (1.0 - rho)
}

/// Whether the geometric remainder `d (d/d0) / (1 - d/d0)` of the last change `d` after the
/// one before, `d0` (N, `d < d0 / 2`), is within `tol_n`. Decided by products where they are
/// clear by a margin a million times their rounding, by the quotient itself (the same
/// expression as ever, so the same verdict bit for bit) only near the boundary: the two
/// dependent divisions were the longest latency in the iteration's chain.
#[inline(always)]
fn geometric_within(d: f64, d0: f64, tol_n: f64) -> bool {
    // The remainder is d^2 / (d0 - d).
    let (lhs, rhs) = (d * d, tol_n * (d0 - d));
    if lhs < rhs * (1.0 - 1e-9) {
        true
    } else if lhs > rhs * (1.0 + 1e-9) {
        false
    } else {
        let r = d / d0;
        d * r / (1.0 - r) <= tol_n
    }
}

/// How phase 1 measures its distance to the fixed point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Distance {
    /// The last change of any normal load (the engines' test before the solvers were one).
    LastChange,
    /// The last change or, once the iteration is seen to contract by a factor rho < 0.5, the
    /// geometric remainder rho / (1 - rho) of it (the single-cylinder rig's test before the
    /// solvers were one).
    Geometric,
}

/// What phase 1 decides after a solve.
pub(super) enum Verdict {
    Converged,
    Stalls,
    Continue,
}

/// Phase 1's view of its own progress: the last two changes of the normal loads, from which
/// convergence and stalling are judged.
#[derive(Default)]
pub(super) struct Trend {
    last_change: Option<f64>,
    older_change: Option<f64>,
}

impl Trend {
    /// Take a solve's largest change of a normal load from the solve before (`None` at the
    /// first solve): converged when the `distance` to the fixed point is within `tol_n` (N);
    /// stalled when `plain_iteration_stalls` says so with `remaining` iterations left.
    pub(super) fn judge(
        &mut self,
        change: Option<f64>,
        distance: Distance,
        tol_n: f64,
        remaining: u32,
    ) -> Verdict {
        let converged = change.is_some_and(|d| match self.last_change {
            Some(d0) if distance == Distance::Geometric && d < 0.5 * d0 => {
                geometric_within(d, d0, tol_n)
            }
            _ => d <= tol_n,
        });
        let stalls = match (change, self.older_change) {
            (Some(d), Some(d2)) if !converged => plain_iteration_stalls(d, d2, tol_n, remaining),
            _ => false,
        };
        self.older_change = self.last_change;
        self.last_change = change;
        if converged {
            Verdict::Converged
        } else if stalls {
            Verdict::Stalls
        } else {
            Verdict::Continue
        }
    }
}

#[cfg(test)]
mod tests {
    use super::geometric_within;

    /// The products decide as the quotient does, on both sides of the boundary and on it:
    /// changes spread over twelve decades, contractions from 1e-6 to just under 0.5, and
    /// tolerances placed at the remainder itself and one ulp either side of it.
    #[test]
    fn the_product_test_gives_the_quotients_verdict() {
        let quotient = |d: f64, d0: f64, tol: f64| d * (d / d0) / (1.0 - d / d0) <= tol;
        let mut cases = 0;
        for e in -6..6 {
            for k in 1..200 {
                let d0 = 10f64.powi(e) * (1.0 + 0.013 * f64::from(k));
                for q in [1e-6, 1e-3, 0.01, 0.05, 0.2, 0.37, 0.499_999] {
                    let d = q * d0;
                    let remainder = d * (d / d0) / (1.0 - d / d0);
                    for tol in [
                        remainder,
                        remainder.next_up(),
                        remainder.next_down(),
                        remainder * 1.5,
                        remainder * 0.5,
                        1e-7,
                    ] {
                        assert_eq!(
                            geometric_within(d, d0, tol),
                            quotient(d, d0, tol),
                            "d {d:e} d0 {d0:e} tol {tol:e}"
                        );
                        cases += 1;
                    }
                }
            }
        }
        assert!(cases > 90_000);
        assert!(geometric_within(0.0, 1.0, 1e-7));
        assert!(!geometric_within(f64::NAN, 1.0, 1e-7));
    }
}
