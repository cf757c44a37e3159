//! The prescribed crank's error-controlled quadrature: the motion is known exactly, so a step
//! only integrates the rates. Five-node Gauss-Lobatto (degree 7; the step's ends are nodes, so
//! the end evaluation is the next step's start: four evaluations per step), the Simpson rule on
//! the same nodes (ends and midpoint) as its error estimate, the step controlled per unit time
//! against `solver.rel_tol` as the PI drive's step is, and steps ending on the host-known
//! switches (friction reversals, side-thrust sign changes) so their kinks fall between steps.

use super::adaptive::{landing, plan_step, retry_after_rejection};
use super::error::SimError;
use super::evaluate::{Eval, Work};
use super::rates::RegimeTimes;
use super::stepper::{prescribed_interval_start, Integration, Step, Stepper};
use super::Simulation;
use crate::erk::Controller;

/// The interior nodes' distance from the midpoint, a fraction of the step: `sqrt(3/7) / 2`, the
/// roots of the derivative of the Legendre polynomial of degree 4 mapped onto [0, 1].
const HALF_GAP: f64 = 0.327_326_835_353_988_6;

/// The nodes as fractions of the step.
const NODES: [f64; 5] = [0.0, 0.5 - HALF_GAP, 0.5, 0.5 + HALF_GAP, 1.0];

/// The Gauss-Lobatto weights (fractions of the step), and the same times 180 as whole numbers
/// for the regime times (`RegimeTimes::add_rule` sums whole coefficients exactly).
const WEIGHTS: [f64; 5] = [
    9.0 / 180.0,
    49.0 / 180.0,
    64.0 / 180.0,
    49.0 / 180.0,
    9.0 / 180.0,
];
const WEIGHTS_180: [f64; 5] = [9.0, 49.0, 64.0, 49.0, 9.0];

/// Gauss-Lobatto minus Simpson (1/6, 0, 4/6, 0, 1/6): the estimate of Simpson's error, which
/// bounds the Lobatto rule's own by far over smooth stretches (`O(h^5)` against `O(h^9)`) and
/// is of its size across a kink, where both are `O(h^2)`.
const ERRORS: [f64; 5] = [
    -21.0 / 180.0,
    49.0 / 180.0,
    -56.0 / 180.0,
    49.0 / 180.0,
    -21.0 / 180.0,
];

/// Order of the error estimate (Simpson's local error is `O(h^5)`).
const ESTIMATE_ORDER: u32 = 4;

/// The Gauss-Lobatto stepper's state between steps.
#[derive(Clone)]
pub(super) struct Lobatto {
    control: Controller,
    /// The evaluation at the step's start: the previous step's end, or the interval's start.
    first: Eval,
    /// The attempt's evaluations at the later nodes (the last one at the step's end).
    nodes: Vec<Eval>,
    /// The step's increment and error estimate of every accumulated quantity.
    incr: Vec<f64>,
    est: Vec<f64>,
    /// The next step the controller proposes (infinite before the first).
    h_next: f64,
    /// Time and switching functions at the previous step's last interior node, to predict
    /// crossings from there to the step's end.
    previous: Option<(f64, Vec<f64>)>,
    /// The friction guess of the next node (extrapolated from the two latest nodes).
    guess: Vec<f64>,
}

impl Lobatto {
    /// A stepper whose controller is `pi` (proportional-integral) or integral, starting from
    /// the evaluation `first`, for `n` accumulated quantities.
    pub(super) fn new(pi: bool, first: Eval, n: usize) -> Self {
        Self {
            control: if pi {
                Controller::pi_of_order(ESTIMATE_ORDER)
            } else {
                Controller::of_order(ESTIMATE_ORDER)
            },
            first,
            nodes: Vec::with_capacity(NODES.len() - 1),
            incr: vec![0.0; n],
            est: vec![0.0; n],
            h_next: f64::INFINITY,
            previous: None,
            guess: Vec::new(),
        }
    }

    /// The step to try first from `t`: the controller's proposal within the longest allowed
    /// step, cut short to end on a switch predicted (linearly from the previous step's last
    /// interior node) to change sign within it. Returns the step, the planned (uncut) step and
    /// whether a switch cut it.
    fn plan(&self, sim: &Simulation, t: f64) -> (f64, f64, bool) {
        let w = sim.reference(t).1.abs();
        plan_step(
            sim,
            self.h_next,
            w,
            (t, self.previous.as_ref(), &self.first.switches),
        )
    }

    /// Evaluate the later nodes of the step from `t` to `t1` into `self.nodes`, each friction
    /// iteration starting from the two latest nodes' law totals extrapolated in time.
    fn evaluate_nodes(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        t: f64,
        t1: f64,
    ) -> Result<(), SimError> {
        let h = t1 - t;
        for (j, &x) in NODES.iter().enumerate().skip(1) {
            let tn = if j == NODES.len() - 1 { t1 } else { t + x * h };
            self.extrapolate(j, x);
            let at = sim.prescribed_point(tn, h, sim.reference(tn));
            let mut e = w.eval();
            let result = sim.evaluate(&at, &self.guess, w, &mut e);
            self.nodes.push(e);
            result?;
        }
        Ok(())
    }

    /// The friction guess of node `j` (at fraction `x`): linear in time through the two latest
    /// nodes, or the first node's totals for the second.
    fn extrapolate(&mut self, j: usize, x: f64) {
        let at = |k: usize| -> &Eval {
            if k == 0 {
                &self.first
            } else {
                &self.nodes[k - 1]
            }
        };
        self.guess.clear();
        if j >= 2 {
            let (last, older) = (at(j - 1), at(j - 2));
            let ratio = (x - NODES[j - 1]) / (NODES[j - 1] - NODES[j - 2]);
            let guess = last
                .totals
                .iter()
                .zip(&older.totals)
                .map(|(a, b)| a + ratio * (a - b));
            self.guess.extend(guess);
        } else {
            self.guess.extend_from_slice(&at(0).totals);
        }
    }

    /// One attempted step from `t` to `t1`: its scaled error (acceptable at <= 1), the step's
    /// increments in `self.incr`, and the first switch to change sign within it (a fraction of
    /// the step). `h_floor` is the longest step's length: across a kink a step may err as much
    /// as such a step of smooth running may.
    fn attempt(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        (t, t1): (f64, f64),
        h_floor: f64,
    ) -> Result<(f64, Option<f64>), SimError> {
        for e in self.nodes.drain(..) {
            w.recycle(e);
        }
        self.evaluate_nodes(sim, w, t, t1)?;
        let Self {
            first,
            nodes,
            incr,
            est,
            ..
        } = self;
        let evals: [&Eval; 5] = [first, &nodes[0], &nodes[1], &nodes[2], &nodes[3]];
        let err = sim.rate_error((&WEIGHTS, &ERRORS), &evals, t1 - t, h_floor, incr, est);
        Ok((err, first_crossing(sim, &evals)))
    }

    /// Take the accepted attempt from `t` to `t1` into `s`: the increments, the regime times,
    /// the friction to start from. Returns the end evaluation, which comes back as the next
    /// step's start once the run has used it (`recycle`).
    fn take(&mut self, s: &mut Integration, t: f64, t1: f64, w: &mut Work) -> Eval {
        let h = t1 - t;
        s.acc.iter_mut().zip(&self.incr).for_each(|(a, d)| *a += d);
        {
            let n = &self.nodes;
            let stages: [&[u8]; 5] = [
                &self.first.regimes,
                &n[0].regimes,
                &n[1].regimes,
                &n[2].regimes,
                &n[3].regimes,
            ];
            RegimeTimes::add_rule(&mut s.regime_time, stages, WEIGHTS_180, h / 180.0);
        }
        let t_node = t + NODES[3] * h;
        match &mut self.previous {
            Some((tp, gp)) => {
                *tp = t_node;
                gp.clear();
                gp.extend_from_slice(&self.nodes[2].switches);
            }
            None => self.previous = Some((t_node, self.nodes[2].switches.to_vec())),
        }
        let Some(end) = self.nodes.pop() else {
            unreachable!("an attempt evaluates every node")
        };
        s.settle_from(&end);
        for e in self.nodes.drain(..) {
            w.recycle(e);
        }
        end
    }
}

impl Stepper for Lobatto {
    /// The reference acceleration may jump at the interval's start: evaluate it from its own
    /// side so no step straddles the jump.
    fn begin_interval(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &mut Integration,
        dt: f64,
    ) -> Result<(), SimError> {
        let e0 = prescribed_interval_start(sim, w, s, dt)?;
        let old = std::mem::replace(&mut self.first, e0);
        w.recycle(old);
        self.previous = None;
        Ok(())
    }

    /// Steps are tried from the plan and shrunk until the estimated error meets
    /// `solver.rel_tol`; a step near the interval's end `b` ends exactly on it.
    fn step(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &mut Integration,
        _t1: f64,
        b: f64,
    ) -> Result<Step, SimError> {
        let t = s.t;
        let h_floor = sim.time_step(sim.max_step_rad, sim.reference(t).1.abs());
        let (mut h, planned, mut switch_cut) = self.plan(sim, t);
        let mut rejected = false;
        loop {
            // End on a cylinder pressure's kink; a retry is never lengthened to one (it would
            // try the failed step again).
            match sim.time_to_pressure_kink(t, h) {
                Some(dt) if !rejected || dt < h => {
                    switch_cut |= dt < h;
                    h = dt;
                }
                _ => {}
            }
            let remaining = b - t;
            // End on the breakpoint, without leaving a sliver step before it.
            let h_try = landing(h, remaining);
            let t1 = if h_try == remaining { b } else { t + h_try };
            let (err, crossing) = self.attempt(sim, w, (t, t1), h_floor)?;
            if err <= 1.0 {
                let next = self.control.next(h_try, err, rejected);
                self.control.accepted(err);
                let cut_short = switch_cut || h_try < h;
                self.h_next = if cut_short { next.max(planned) } else { next };
                let end = self.take(s, t, t1, w);
                let (theta, omega, _) = sim.reference(t1);
                return Ok(Step {
                    t1,
                    h: t1 - t,
                    end,
                    y: (theta, omega, 0.0),
                });
            }
            s.rejected += 1;
            rejected = true;
            h = retry_after_rejection(
                &self.control,
                (h_try, err, crossing),
                remaining,
                t,
                sim.rel_tol,
            )?;
        }
    }

    /// The step's end is the next one's start.
    fn recycle(&mut self, end: Eval, _h: f64, w: &mut Work) {
        let old = std::mem::replace(&mut self.first, end);
        w.recycle(old);
    }

    /// No crossing is predicted from the steps before the inputs changed (the run plans its
    /// interval again, whose start is evaluated anew).
    fn restart(&mut self, _: &Simulation, _: &mut Work, _: &Integration) -> Result<(), SimError> {
        self.previous = None;
        Ok(())
    }
}

impl Simulation {
    /// The step from `t` that ends on the next kink of a cylinder pressure (a trace's sample),
    /// when one lies within two planned steps `h` (as [`landing`] treats an interval's end: no
    /// sliver step before it); `None` when none does. A kink closer than a thousandth of the
    /// step is taken as on the step's start (the previous step ended on it).
    fn time_to_pressure_kink(&self, t: f64, h: f64) -> Option<f64> {
        let kinks = &self.pressure_kinks;
        if kinks.is_empty() {
            return None;
        }
        let (theta, omega, alpha) = self.reference_after(t);
        let cycle = crate::gas::CYCLE_4;
        let phi = crate::gas::cycle_angle(theta);
        let first = kinks.partition_point(|a| *a <= phi);
        for i in first..first + kinks.len() {
            let (k, wraps) = (i % kinks.len(), (i / kinks.len()) as f64);
            let gap = kinks[k] + wraps * cycle - phi;
            // The time the reference motion (constant acceleration) takes to turn by `gap`.
            let root = omega * omega + 2.0 * alpha * gap;
            if root < 0.0 || omega + root.sqrt() <= 0.0 {
                return None;
            }
            let dt = 2.0 * gap / (omega + root.sqrt());
            if dt <= 1e-3 * h {
                continue;
            }
            return (dt < 2.0 * h).then(|| landing(h, dt));
        }
        None
    }
}

/// The first switch to change sign within the step, located by linear interpolation between
/// the nodes around it (as a fraction of the step).
fn first_crossing(sim: &Simulation, evals: &[&Eval; 5]) -> Option<f64> {
    let mut crossing: Option<f64> = None;
    for i in (0..sim.switch_mask.len()).filter(|i| sim.switch_mask[*i]) {
        for j in 1..evals.len() {
            let (a, g) = (evals[j - 1].switches[i], evals[j].switches[i]);
            if a * g < 0.0 {
                let f = NODES[j - 1] + (NODES[j] - NODES[j - 1]) * a / (a - g);
                crossing = Some(crossing.map_or(f, |c: f64| c.min(f)));
                break;
            }
        }
    }
    crossing
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule integrates polynomials up to degree 7 exactly on [0, 1] and the error weights
    /// vanish on Simpson's exact cubics but not on x^4.
    #[test]
    fn lobatto_is_exact_to_degree_seven_and_estimates_simpson() {
        assert!((HALF_GAP - (3.0_f64 / 7.0).sqrt() / 2.0).abs() < 1e-16);
        for p in 0..=8 {
            let q: f64 = NODES.iter().zip(WEIGHTS).map(|(x, w)| w * x.powi(p)).sum();
            let exact = 1.0 / (p as f64 + 1.0);
            if p <= 7 {
                assert!((q - exact).abs() < 1e-15, "x^{p}: {q} vs {exact}");
            } else {
                assert!((q - exact).abs() > 1e-6, "x^{p} should not be exact");
            }
            let e: f64 = NODES.iter().zip(ERRORS).map(|(x, w)| w * x.powi(p)).sum();
            let simpson = [1.0 / 6.0, 0.0, 4.0 / 6.0, 0.0, 1.0 / 6.0];
            let s: f64 = NODES.iter().zip(simpson).map(|(x, w)| w * x.powi(p)).sum();
            assert!(
                (e - (q - s)).abs() < 1e-15,
                "error weights are Lobatto - Simpson"
            );
            if p <= 3 {
                assert!(e.abs() < 1e-15, "Simpson is exact for x^{p}");
            }
        }
        for (w, w180) in WEIGHTS.iter().zip(WEIGHTS_180) {
            assert_eq!(*w, w180 / 180.0);
        }
    }
}
