//! Hold replay: under a prescribed crank at constant speed with stateless laws, every engine
//! cycle of a hold sees the same crank angles, speed, oil and gas, so its steps repeat. The
//! interval before a hold's measurement window is stepped in whole cycles of whole steps; the
//! first two cycles are evaluated, and when their increments agree the later cycles take the
//! second's steps again (each step's increments added, its end evaluation handed on, time and
//! crank angle advanced) without calling a law. The window itself is always evaluated.
//!
//! The check of the two cycles is what makes this safe: a law whose output depends on time,
//! or anything else that does not repeat, shows as two cycles that differ, and the hold is
//! then stepped as any interval.

use super::evaluate::{Eval, Work};
use super::stepper::{Integration, Step};
use super::Simulation;

/// Least relative agreement of the two evaluated cycles' increments (each accumulated quantity
/// and regime time) for the rest of a hold to be replayed: the friction/reaction iteration's
/// tolerance (`solver.friction_tol`), within which every evaluation is settled and two cycles
/// are the same cycle as far as the solver can tell (a hold's first cycle still carries the
/// ramp's last friction as its iteration start: about 2e-9 on the bundled rig), but never
/// tighter than this, far above round-off (the second cycle's crank angles are the first's plus
/// a cycle, their sines differing in the last bits).
pub(super) const AGREEMENT_FLOOR: f64 = 1e-10;

/// Evaluated cycles before any is replayed: one to compare with and the one replayed.
const EVALUATED_CYCLES: u64 = 2;

/// The replay of the interval of a hold under way: its steps per cycle, what the evaluated
/// cycles accumulated and the second cycle's steps. One per run, its buffers reused hold after
/// hold.
#[derive(Clone)]
pub(super) struct Replay {
    /// Steps per engine cycle (0: idle).
    n: u64,
    /// Each quantity's increment over the first cycle, then over the second: the accumulated
    /// quantities followed by the regime times.
    cycles: [Vec<f64>; 2],
    /// The second cycle's steps.
    steps: RecordedSteps,
    /// Where the step under way accumulates.
    increments_now: StepIncrements,
    /// Whether the two cycles agreed (`None` until the second is done).
    agreed: Option<bool>,
    /// Whether the cycles may be replayed (not in [`HoldReplay::Evaluate`]).
    allowed: bool,
    /// The relative agreement the two cycles must show.
    agreement: f64,
}

/// Whether a run replays the repeating cycles of its prescribed holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum HoldReplay {
    /// Replay them (the default).
    On,
    /// Step every hold as any interval.
    Off,
    /// Step the holds in whole cycles, as the replay does, but evaluate every cycle: what a
    /// replay must reproduce (the tests' reference).
    #[cfg_attr(not(test), allow(dead_code))]
    Evaluate,
    /// Replay as `On`, but a PI hold only once two evaluated cycles agree, its settling not
    /// extrapolated ([`super::settle`]): what the extrapolation must reproduce.
    #[cfg_attr(not(test), allow(dead_code))]
    Agreed,
}

/// An interval of a hold stepped in whole cycles: its steps per cycle and its cycles.
#[derive(Debug, Clone, Copy)]
pub(super) struct HoldCycles {
    /// Steps per engine cycle.
    pub(super) n: u64,
    /// Whole cycles in the interval.
    pub(super) cycles: u64,
    /// The interval's end, s: a whole number of cycles after its start.
    pub(super) end: f64,
}

impl Simulation {
    /// Whether the interval of the grid from `t` to `b` (s) can be replayed, and how: a
    /// prescribed crank at constant speed, stateless laws, and at least one cycle beyond the
    /// two evaluated. `simpson`: the run steps with the prescribed Simpson quadrature (the
    /// only step method whose steps are replayed).
    pub(super) fn hold_cycles(&self, t: f64, b: f64, simpson: bool) -> Option<HoldCycles> {
        if !simpson || self.stateful || self.hold_replay == HoldReplay::Off {
            return None;
        }
        let (_, omega, alpha) = self.reference_after(t);
        let (_, omega_b, _) = self.reference(b);
        if alpha != 0.0 || omega <= 0.0 || omega_b != omega {
            return None;
        }
        let period = self.window_spec().cycle_angle() / omega;
        let dt_target = self.time_step(self.step_rad, omega);
        // Steps no longer than the run's step (a ratio one rounding above a whole number is
        // that number).
        let n = (period / dt_target * (1.0 - 1e-12)).ceil().max(1.0) as u64;
        let whole = (b - t) / period;
        let cycles = (whole + 1e-9).floor();
        if cycles < (EVALUATED_CYCLES + 1) as f64 {
            return None;
        }
        // A remainder of a rounding error is no interval of its own.
        let end = if whole - cycles < 1e-9 {
            b
        } else {
            t + cycles * period
        };
        Some(HoldCycles {
            n,
            cycles: cycles as u64,
            end,
        })
    }
}

impl Replay {
    /// An idle replay for a run accumulating `n_acc` quantities and `n_regime` regime times,
    /// in `mode`, with the run's friction/reaction tolerance.
    pub(super) fn new(
        (n_acc, n_regime): (usize, usize),
        mode: HoldReplay,
        friction_tol: f64,
    ) -> Self {
        let per_step = n_acc + n_regime;
        Self {
            n: 0,
            cycles: [vec![0.0; per_step], vec![0.0; per_step]],
            steps: RecordedSteps::default(),
            increments_now: StepIncrements::new(n_acc, n_regime),
            agreed: None,
            allowed: matches!(mode, HoldReplay::On | HoldReplay::Agreed),
            agreement: friction_tol.max(AGREEMENT_FLOOR),
        }
    }

    /// Start the replay of an interval planned as `plan`, keeping the buffers (a run's holds
    /// have about the same steps per cycle, so only the first allocates).
    pub(super) fn start(&mut self, plan: HoldCycles) {
        self.n = plan.n;
        for sums in &mut self.cycles {
            sums.fill(0.0);
        }
        self.steps.clear();
        self.agreed = None;
    }

    /// Idle: the interval under way is not replayed.
    pub(super) fn stop(&mut self) {
        self.n = 0;
    }

    /// Whether an interval is under way in whole cycles.
    pub(super) fn active(&self) -> bool {
        self.n > 0
    }

    /// The cycle step `done` (1-based within the interval) falls in.
    fn cycle_of(&self, done: u64) -> u64 {
        (done - 1) / self.n
    }

    /// Whether step `done` is one of the evaluated cycles' (its increments recorded).
    pub(super) fn records(&self, done: u64) -> bool {
        self.cycle_of(done) < EVALUATED_CYCLES
    }

    /// Before an evaluated step: its increments to be kept apart.
    pub(super) fn begin_step(&mut self, s: &mut Integration) {
        self.increments_now.begin(s);
    }

    /// After an evaluated step that failed: the run's totals back as they were (a failed step
    /// adds nothing), the replay idle.
    pub(super) fn abort_step(&mut self, s: &mut Integration) {
        self.increments_now.abort(s);
        self.stop();
    }

    /// After evaluated step `done` (ending with `step`): its increments added to the run's
    /// totals (the same additions the step would have made to them), kept for its cycle and,
    /// in the second cycle, kept for the replay; at the second cycle's end the two cycles
    /// compared.
    pub(super) fn end_step(&mut self, done: u64, s: &mut Integration, step: &Step, w: &mut Work) {
        let cycle = self.cycle_of(done) as usize;
        let (acc, times) = self.increments_now.end(s);
        let sums = &mut self.cycles[cycle];
        for (sum, d) in sums.iter_mut().zip(acc.iter().chain(times)) {
            *sum += d;
        }
        if cycle == 1 {
            self.steps.push((acc, times), &step.end, w);
            if done == EVALUATED_CYCLES * self.n {
                self.agreed = Some(self.allowed && self.cycles_agree());
            }
        }
    }

    /// Whether the two evaluated cycles accumulated the same, quantity by quantity.
    fn cycles_agree(&self) -> bool {
        let [a, b] = &self.cycles;
        agree(a, b, self.agreement)
    }

    /// Step `done` replayed from the second cycle when the two cycles agreed: its increments
    /// added to the run's totals, its friction the next evaluation's start. Returns which of
    /// the cycle's steps it is (its end evaluation: [`Replay::end`]); `None`: step it.
    pub(super) fn replay(&mut self, done: u64, s: &mut Integration) -> Option<usize> {
        if !self.active() || self.records(done) || self.agreed != Some(true) {
            return None;
        }
        let k = ((done - 1) % self.n) as usize;
        self.steps.apply(k, s);
        Some(k)
    }

    /// The end evaluation of the second cycle's step `k`.
    pub(super) fn end(&self, k: usize) -> &Eval {
        self.steps.end(k)
    }
}

/// The steps of a cycle kept for replay: each step's increments (the accumulated quantities,
/// then the regime times) and its end evaluation, in buffers kept from cycle to cycle (only
/// the first cycle recorded allocates).
#[derive(Clone, Default)]
pub(super) struct RecordedSteps {
    increments: Vec<f64>,
    /// The end evaluations (the first `len` of these buffers).
    ends: Vec<Eval>,
    len: usize,
}

impl RecordedSteps {
    /// Empty, the buffers kept.
    pub(super) fn clear(&mut self) {
        self.increments.clear();
        self.len = 0;
    }

    /// Steps recorded.
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// Record a step with increments `(acc, times)` and end evaluation `end`.
    pub(super) fn push(&mut self, (acc, times): (&[f64], &[f64]), end: &Eval, w: &mut Work) {
        self.increments.extend(acc.iter().chain(times));
        if self.len == self.ends.len() {
            self.ends.push(w.eval());
        }
        self.ends[self.len].copy_from(end);
        self.len += 1;
    }

    /// Replay step `k` on the run `s`: its increments added to the run's totals, its friction
    /// the next evaluation's start.
    pub(super) fn apply(&self, k: usize, s: &mut Integration) {
        let n_acc = s.acc.len();
        let per_step = n_acc + s.regime_time.len();
        let (acc, times) = self.increments[k * per_step..(k + 1) * per_step].split_at(n_acc);
        add_increments(s, acc, times);
        s.settle_from(&self.ends[k]);
    }

    /// The end evaluation of step `k`.
    pub(super) fn end(&self, k: usize) -> &Eval {
        &self.ends[k]
    }
}

/// Whether two cycles' increments `a` and `b` agree quantity by quantity within `agreement`
/// relative (of the larger, and at least of a millionth of the largest of all: a quantity
/// near zero is not held to its own round-off).
pub(super) fn agree(a: &[f64], b: &[f64], agreement: f64) -> bool {
    let scale = a.iter().chain(b).fold(0.0_f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .all(|(x, y)| (x - y).abs() <= agreement * x.abs().max(y.abs()).max(1e-6 * scale))
}

/// One step's increments kept apart from the run's totals: the totals set aside while the
/// stepper accumulates into zeroed buffers, then the increments added to them (the same
/// additions the step would have made) and handed out.
#[derive(Clone)]
pub(super) struct StepIncrements {
    kept: (Vec<f64>, Vec<f64>),
}

impl StepIncrements {
    /// Buffers for `n_acc` accumulated quantities and `n_regime` regime times.
    pub(super) fn new(n_acc: usize, n_regime: usize) -> Self {
        Self {
            kept: (vec![0.0; n_acc], vec![0.0; n_regime]),
        }
    }

    /// Before the step: the run's totals set aside, the step accumulates from zero.
    pub(super) fn begin(&mut self, s: &mut Integration) {
        std::mem::swap(&mut s.acc, &mut self.kept.0);
        std::mem::swap(&mut s.regime_time, &mut self.kept.1);
        s.acc.fill(0.0);
        s.regime_time.fill(0.0);
    }

    /// After a failed step: the run's totals back as they were.
    pub(super) fn abort(&mut self, s: &mut Integration) {
        std::mem::swap(&mut s.acc, &mut self.kept.0);
        std::mem::swap(&mut s.regime_time, &mut self.kept.1);
    }

    /// After the step: its increments added to the run's totals, and returned (accumulated
    /// quantities, regime times).
    pub(super) fn end(&mut self, s: &mut Integration) -> (&[f64], &[f64]) {
        self.abort(s);
        add_increments(s, &self.kept.0, &self.kept.1);
        (&self.kept.0, &self.kept.1)
    }
}

/// Add one step's increments of the accumulated quantities `acc` and regime times `times` to
/// the run's totals in `s`, as the step itself adds them.
pub(super) fn add_increments(s: &mut Integration, acc: &[f64], times: &[f64]) {
    for (total, d) in s.acc.iter_mut().zip(acc) {
        *total += d;
    }
    for (total, d) in s.regime_time.iter_mut().zip(times) {
        *total += d;
    }
}
