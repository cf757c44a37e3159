//! The error-controlled PI-drive stepper: the embedded Dormand-Prince 5(4) pair, its
//! step-size controller, and the handling of switches (steps end on predicted sign changes of
//! joint velocities, side thrust and drive margin; a failed step is retried up to a crossing;
//! a step's stages are held on one side of the drive's torque limit and a step ends on each
//! crossing of it, `super::limit`).

use super::error::SimError;
use super::evaluate::{Eval, Work};
use super::limit::{Landing, LimitCrossing};
use super::rates::RegimeTimes;
use super::stepper::{CrankState, Integration, Side, Step, Stepper};
use super::Simulation;
use crate::erk::{Controller, Pair};

/// Most stages a pair may have (fixed-size stage arrays on the stack).
const MAX_STAGES: usize = 8;

/// The adaptive stepper's state between steps.
#[derive(Clone)]
pub(super) struct Adaptive {
    pair: &'static Pair,
    control: Controller,
    /// The evaluation at the current step's start (the previous step's last stage): "first
    /// same as last".
    fsal: Eval,
    /// The step's increment and error estimate of every accumulated quantity.
    incr: Vec<f64>,
    est: Vec<f64>,
    /// The step's increment of every law's regime times.
    regime_incr: Vec<f64>,
    /// The middle stages' evaluations (recycled).
    stages: Vec<Eval>,
    /// The next step the controller proposes (infinite before the first).
    h_next: f64,
    /// Time and switching functions at the previous step's start, to predict crossings.
    previous_end: Option<(f64, Vec<f64>)>,
    /// The friction guess of the next stage (extrapolated from the two latest stages).
    guess: Vec<f64>,
    /// The side of the PI drive's torque limit the next step is held on when the last one
    /// ended on a crossing of it ([`super::limit`]).
    side: Option<Side>,
}

/// One attempted step.
struct Attempt {
    /// Scaled error estimate (acceptable at <= 1).
    err: f64,
    end: Eval,
    y: CrankState,
    /// The first switch to change sign within the step, as a fraction of it.
    crossing: Option<f64>,
    /// The first middle stage past the torque limit on the side the step was held on: its
    /// time from the step's start and its margin.
    stage_past: Option<(f64, f64)>,
}

impl Adaptive {
    /// A stepper for `pair` with `control`, starting from the evaluation `first` at the run's
    /// start, for `n` accumulated quantities and the regimes of `laws`.
    pub(super) fn new(
        pair: &'static Pair,
        control: Controller,
        first: Eval,
        n: usize,
        laws: RegimeTimes,
    ) -> Self {
        Self {
            pair,
            control,
            fsal: first,
            incr: vec![0.0; n],
            est: vec![0.0; n],
            regime_incr: vec![0.0; laws.len()],
            stages: Vec::with_capacity(pair.stages()),
            h_next: f64::INFINITY,
            previous_end: None,
            guess: Vec::new(),
            side: None,
        }
    }

    /// The step to try first from `t` (state `y`): the controller's proposal within the
    /// longest allowed step, cut short to end on a switch predicted (linearly from the last two
    /// step ends) to change sign within it, so the kink falls between steps. Returns the step,
    /// the planned (uncut) step and whether a switch cut it.
    fn plan(&self, sim: &Simulation, t: f64, y: CrankState) -> (f64, f64, bool) {
        let w = y.1.abs().max(sim.reference(t).1.abs());
        let before = self.previous_end.as_ref();
        plan_step(sim, self.h_next, w, (t, before, &self.fsal.switches))
    }
}

impl Stepper for Adaptive {
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
        let (t, y) = (s.t, s.y);
        // Across a jump a step may err as much as a longest step of smooth running may.
        let h_floor = sim.time_step(sim.max_step_rad, y.1.abs().max(sim.reference(t).1.abs()));
        let (mut h, planned, switch_cut) = self.plan(sim, t, y);
        let mut limit = LimitCrossing::start(self.side.take(), margin(&self.fsal));
        let mut rejected = false;
        loop {
            let remaining = b - t;
            // End on the breakpoint, without leaving a sliver step before it (unless landing
            // on the torque limit, which must be met where it is).
            let h_try = match limit.landing() {
                true => h.min(remaining),
                false => landing(h, remaining),
            };
            let a = self.attempt(sim, w, s, (t, h_try, h_floor), limit.side())?;
            if a.err <= 1.0 {
                let tol_t = sim.rel_tol * (h_try + h_floor);
                match limit.check((h_try, margin(&a.end)), a.stage_past, tol_t) {
                    Landing::Take { on_crossing } => {
                        // A step cut short to land on `b` or a switch does not shrink the next.
                        let next = self.control.next(h_try, a.err, rejected);
                        // A step landed on the torque limit has the crossing's length, not the
                        // controller's: its error tells the controller nothing of the field.
                        if !limit.landing() {
                            self.control.accepted(a.err);
                        }
                        let cut_short = switch_cut || h_try < h || on_crossing;
                        self.h_next = if cut_short { next.max(planned) } else { next };
                        self.side = on_crossing.then(|| limit.side().other());
                        let t1 = if h_try == remaining { b } else { t + h_try };
                        return Ok(self.take(s, t, t1, a));
                    }
                    Landing::Retry(next) => h = next,
                    Landing::Again => h = h_try,
                }
                w.recycle(a.end);
                continue;
            }
            w.recycle(a.end);
            s.rejected += 1;
            rejected = true;
            let failed = (h_try, a.err, a.crossing);
            h = retry_after_rejection(&self.control, failed, remaining, t, sim.rel_tol)?;
        }
    }

    fn recycle(&mut self, end: Eval, _h: f64, w: &mut Work) {
        let old = std::mem::replace(&mut self.fsal, end);
        w.recycle(old);
    }

    /// The first stage evaluated again with the new inputs; no switch is predicted from the
    /// steps before.
    fn restart(&mut self, sim: &Simulation, w: &mut Work, s: &Integration) -> Result<(), SimError> {
        let e = sim.step_eval(s.t, 0.0, s.y, &s.guess, w)?;
        self.recycle(e, 0.0, w);
        self.previous_end = None;
        self.side = None;
        Ok(())
    }
}

/// The PI drive's margin to its torque limit at an evaluation (the last switch).
fn margin(e: &Eval) -> f64 {
    e.switches.last().copied().unwrap_or(f64::INFINITY)
}

impl Adaptive {
    /// The accepted attempt `a` from `t` to `t1`: its increments added to the run's totals,
    /// the switches at its start kept to predict the next crossing from.
    fn take(&mut self, s: &mut Integration, t: f64, t1: f64, a: Attempt) -> Step {
        match &mut self.previous_end {
            Some((tp, gp)) => {
                *tp = t;
                gp.clear();
                gp.extend_from_slice(&self.fsal.switches);
            }
            None => self.previous_end = Some((t, self.fsal.switches.to_vec())),
        }
        s.acc.iter_mut().zip(&self.incr).for_each(|(a, d)| *a += d);
        s.regime_time
            .iter_mut()
            .zip(&self.regime_incr)
            .for_each(|(a, d)| *a += d);
        s.settle_from(&a.end);
        Step {
            t1,
            h: t1 - t,
            end: a.end,
            y: a.y,
        }
    }

    /// One attempted step of length `h` from `w`'s state at `t`, the start evaluation being
    /// `self.fsal`. The step's increment of every accumulated quantity goes to `self.incr`.
    ///
    /// A step may err by `rel_tol` times the largest rate of the quantity over the step (at
    /// least 1 for the crank state; for powers and for normal loads the largest of the group,
    /// at least 1e-3 W or N; see `RateLayout::controlled`) times the step plus `h_floor`. Over
    /// smooth stretches that bounds the error per unit time, so the integrals over a hold are
    /// good to about `rel_tol`; across a jump of a rate (a law's near-discontinuity, the
    /// drive's anti-windup switch) the step shrinks until its error is that of an `h_floor`
    /// step instead of failing for ever.
    fn attempt(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        state: &Integration,
        (t, h, h_floor): (f64, f64, f64),
        side: Side,
    ) -> Result<Attempt, SimError> {
        let s = self.pair.stages();
        debug_assert!(s <= MAX_STAGES);
        let (k, end, y) = self.stages(sim, w, state, (t, h), side)?;
        let Self {
            pair,
            fsal,
            stages,
            incr,
            est,
            regime_incr,
            ..
        } = self;
        // Stage j's evaluation: the given first, the stored middle ones, the end.
        let evals: [&Eval; MAX_STAGES] = std::array::from_fn(|j| match j {
            0 => &*fsal,
            j if j < s - 1 => &stages[j - 1],
            _ => &end,
        });
        let crank = crank_error(pair, &k[..s], h, sim.rel_tol * (h + h_floor));
        let rates = sim.rate_error((pair.b, pair.e), &evals[..s], h, h_floor, incr, est);
        // The regimes by the same propagated weights, stage by stage as the rates.
        regime_incr.fill(0.0);
        for (e, b) in evals[..s].iter().zip(pair.b) {
            let b = h * b;
            if b != 0.0 {
                RegimeTimes::add(regime_incr, &e.regimes, b);
            }
        }
        let crossing = first_crossing(sim, pair, &evals[..s]);
        // A middle stage past the torque limit (the margin out and back within the step). A
        // stage at the step's end time is no such sign: it is a lower-order value of the end's
        // own margin, and where the two disagree in sign at a crossing it sent the landing
        // search back and forth on one instant.
        let stage_past = (1..s - 1)
            .filter(|&j| pair.c[j] < 1.0)
            .find(|&j| side.left_by(margin(evals[j])))
            .map(|j| (pair.c[j] * h, margin(evals[j])));
        for e in stages.drain(..) {
            w.recycle(e);
        }
        Ok(Attempt {
            err: crank.max(rates),
            end,
            y,
            crossing,
            stage_past,
        })
    }

    /// The stages of a step of length `h` from `t` (state `s.y`): the crank state's rates `k`
    /// per stage (the first from `self.fsal`), the middle stages' evaluations into
    /// `self.stages`, and the end evaluation and end state.
    fn stages(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &Integration,
        (t, h): (f64, f64),
        side: Side,
    ) -> Result<([[f64; 3]; MAX_STAGES], Eval, CrankState), SimError> {
        let (pair, y) = (self.pair, s.y);
        let mut k = [[0.0_f64; 3]; MAX_STAGES];
        let (_, dz, _) = sim.pi_torque(t, y.1, y.2, side);
        k[0] = [y.1, self.fsal.alpha, dz];
        self.stages.clear();
        let mut y1 = [y.0, y.1, y.2];
        for st in 1..pair.stages() {
            let mut ys = [y.0, y.1, y.2];
            for (j, a) in pair.a[st].iter().enumerate() {
                for c in 0..3 {
                    ys[c] += h * a * k[j][c];
                }
            }
            let ts = t + pair.c[st] * h;
            let (at, dz) = sim.driven_point(ts, h, (ys[0], ys[1], ys[2]), side);
            self.extrapolate(t, h, st);
            let mut e = w.eval();
            sim.evaluate(&at, &self.guess, w, &mut e)?;
            k[st] = [ys[1], e.alpha, dz];
            self.stages.push(e);
            y1 = ys;
        }
        let Some(end) = self.stages.pop() else {
            unreachable!("an embedded pair has at least two stages")
        };
        Ok((k, end, (y1[0], y1[1], y1[2])))
    }

    /// The friction iteration of stage `st` of a step of length `h` from `t` starts from the
    /// law totals extrapolated (linearly in time) from the two latest stages: one or two
    /// iterations fewer than starting from the latest.
    fn extrapolate(&mut self, t: f64, h: f64, st: usize) {
        let c = self.pair.c;
        let last = if st == 1 {
            &self.fsal.totals
        } else {
            &self.stages[st - 2].totals
        };
        self.guess.clear();
        if st >= 2 {
            let (ts, t_last, t0) = (t + c[st] * h, t + c[st - 1] * h, t + c[st - 2] * h);
            if t_last > t0 {
                let older = if st == 2 {
                    &self.fsal.totals
                } else {
                    &self.stages[st - 3].totals
                };
                let ratio = (ts - t_last) / (t_last - t0);
                self.guess
                    .extend(last.iter().zip(older).map(|(a, b)| a + ratio * (a - b)));
                return;
            }
        }
        self.guess.extend_from_slice(last);
    }
}

/// The crank state's scaled error (angle, speed, controller integral), each relative to the
/// largest of its stage rates (at least 1) and to `tol_h`, the tolerance times the step plus
/// the floor step.
fn crank_error(pair: &Pair, k: &[[f64; 3]], h: f64, tol_h: f64) -> f64 {
    let mut err = 0.0_f64;
    for c in 0..3 {
        let (est, peak) = k
            .iter()
            .zip(pair.e)
            .fold((0.0, 1.0_f64), |(sum, peak), (kj, e)| {
                (sum + e * kj[c], peak.max(kj[c].abs()))
            });
        err = err.max((h * est).abs() / (tol_h * peak));
    }
    err
}

/// The first switch to change sign, located by linear interpolation between the stages
/// around it (as a fraction of the step).
fn first_crossing(sim: &Simulation, pair: &Pair, evals: &[&Eval]) -> Option<f64> {
    let mut crossing: Option<f64> = None;
    for i in (0..sim.switch_mask.len()).filter(|i| sim.switch_mask[*i]) {
        for j in 1..evals.len() {
            let (a, g) = (evals[j - 1].switches[i], evals[j].switches[i]);
            if a * g < 0.0 && pair.c[j] > pair.c[j - 1] {
                let f = pair.c[j - 1] + (pair.c[j] - pair.c[j - 1]) * a / (a - g);
                crossing = Some(crossing.map_or(f, |c: f64| c.min(f)));
                break;
            }
        }
    }
    crossing
}

impl Simulation {
    /// The step's increments (propagated weights `b`, into `incr`) and error estimates (error
    /// weights `e`, into `est`) of every accumulated quantity, and the largest scaled error of
    /// the controlled groups. Stage by stage so the loops run over contiguous rates; only the
    /// controlled groups need an error estimate. The weights are fractions of the step: a
    /// Runge-Kutta pair's, or the prescribed crank's quadrature rules (`lobatto.rs`).
    pub(super) fn rate_error(
        &self,
        (weights, errors): (&[f64], &[f64]),
        evals: &[&Eval],
        h: f64,
        h_floor: f64,
        incr: &mut [f64],
        est: &mut [f64],
    ) -> f64 {
        let controlled = self.layout().controlled();
        incr.fill(0.0);
        est.fill(0.0);
        // Each group shares one scale, the largest rate of the group over the step: a small
        // quantity cannot be resolved below the evaluation's own noise, which the friction
        // iteration's tolerance sets relative to the largest of its group. Taken in the same
        // pass as the sums, stage by stage.
        let mut peaks = [1e-3_f64; 2];
        for (j, ev) in evals.iter().enumerate() {
            let r = &ev.rates[..];
            let (b, e) = (h * weights[j], h * errors[j]);
            if b != 0.0 {
                incr.iter_mut().zip(r.iter()).for_each(|(d, r)| *d += b * r);
            }
            for ((range, _), peak) in controlled.iter().zip(&mut peaks) {
                let group = &r[range.clone()];
                if e != 0.0 {
                    est[range.clone()]
                        .iter_mut()
                        .zip(group)
                        .for_each(|(d, r)| *d += e * r);
                }
                *peak = group.iter().fold(*peak, |m, r| m.max(r.abs()));
            }
        }
        let mut err = 0.0_f64;
        for ((range, factor), peak) in controlled.into_iter().zip(peaks) {
            let worst = est[range].iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            err = err.max(worst / (factor * self.rel_tol * (h + h_floor) * peak));
        }
        err
    }
}

/// The step to try with `h` planned and `remaining` left to the interval's end: the end itself
/// when it is within 10% of `h`, half the way when it is within two steps (no sliver step before
/// a breakpoint), else `h`. Shared by the error-controlled steppers.
pub(super) fn landing(h: f64, remaining: f64) -> f64 {
    if remaining <= 1.1 * h {
        remaining
    } else if remaining < 2.0 * h {
        0.5 * remaining
    } else {
        h
    }
}

/// The length to retry after a rejected step `failed = (h_try, err, crossing)` at `t`: the
/// controller's, cut to a switch predicted inside the step, and kept short of a breakpoint the
/// failed step landed on (otherwise a retry within 10% of it is snapped back by [`landing`] to
/// the very step that failed, for ever: the PI drive at 3.8 N m, a crossing at 91-95% of a step
/// ending 0.41 ms before a hold's end). A length the time's precision cannot resolve is an error.
pub(super) fn retry_after_rejection(
    control: &Controller,
    failed: (f64, f64, Option<f64>),
    remaining: f64,
    t: f64,
    rel_tol: f64,
) -> Result<f64, SimError> {
    let (h_try, err, crossing) = failed;
    let mut h = control.next(h_try, err, true);
    if let Some(f) = crossing {
        if f > 0.02 && f < 0.95 {
            h = f * h_try;
        }
    }
    if h_try == remaining {
        h = h.min(0.9 * remaining / 1.1);
    }
    if h <= 1e-12 * t.abs().max(1e-3) {
        return Err(SimError::StepTooSmall {
            time_s: t,
            step_s: h,
            rel_tol,
        });
    }
    Ok(h)
}

/// A time and the switching functions there: the earlier sample a switch is predicted from.
pub(super) type SwitchSample = (f64, Vec<f64>);

/// The step an error-controlled stepper tries first at crank speed `w`: the controller's
/// proposal `h_next` within the longest allowed step (one `step_deg` of crank angle for the
/// first step), cut short to end on the first switch predicted from `at = (t, before, now)`
/// (see [`first_switch`]). Returns the step, the planned (uncut) step and whether a switch cut it.
pub(super) fn plan_step(
    sim: &Simulation,
    h_next: f64,
    w: f64,
    at: (f64, Option<&SwitchSample>, &[f64]),
) -> (f64, f64, bool) {
    let planned = if h_next.is_finite() {
        h_next.min(sim.time_step(sim.max_step_rad, w))
    } else {
        sim.time_step(sim.step_rad, w)
    };
    let (t, before, now) = at;
    let h_switch = first_switch(sim, before, now, t, planned);
    (planned.min(h_switch), planned, h_switch.is_finite())
}

/// How far from `t` the first host-known switch is predicted to change sign, linearly from its
/// value `before` (time and switching functions of an earlier sample) to its value `now` at
/// `t`; only a crossing between 5% and 100% of the `planned` step counts (infinity: none).
/// Shared by the error-controlled steppers, so a kink falls between steps.
fn first_switch(
    sim: &Simulation,
    before: Option<&SwitchSample>,
    now: &[f64],
    t: f64,
    planned: f64,
) -> f64 {
    let mut h_switch = f64::INFINITY;
    if let Some((tp, gp)) = before {
        for (i, (&a, &g)) in gp.iter().zip(now).enumerate() {
            if sim.switch_mask[i] && a * g > 0.0 && (g - a) * g < 0.0 && t > *tp {
                let dt = g * (t - *tp) / (a - g);
                if dt > 0.05 * planned && dt < planned {
                    h_switch = h_switch.min(dt);
                }
            }
        }
    }
    h_switch
}
