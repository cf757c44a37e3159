//! Orbit replay: under the PI drive the crank speed is state, so the cycles of a hold repeat
//! only once the controller has settled onto the hold's periodic orbit. On that orbit the
//! integral action leaves no mean speed error, so its period is one engine cycle at the
//! reference speed. The stretch of a hold before its window's records is stepped in cycles of
//! that period, each cycle ending on a step. Cycles are evaluated until one agrees with the cycle
//! before it: every accumulated quantity's increment, and the crank state at its end (angle
//! turned, speed, controller integral), within `solver.friction_tol`. The later cycles of the
//! stretch then take that cycle's steps again, shifted in time and angle, without calling a
//! law. The window is always evaluated, from the state the replay leaves.
//!
//! What a replay leaves out is the rest of the settling: each cycle's change decays
//! geometrically, so the state where replay starts is within a few times the agreement of the
//! orbit, and the window, a tenth of a second later, is closer still.

use std::f64::consts::TAU;

use super::evaluate::{Eval, Work};
use super::replay::{agree, HoldReplay, RecordedSteps, StepIncrements, AGREEMENT_FLOOR};
use super::stepper::{CrankState, Integration, Step};
use super::Simulation;

/// A hold's stretch stepped in orbit cycles: their period and number, and the stretch's end.
#[derive(Debug, Clone, Copy)]
pub(super) struct OrbitCycles {
    /// One engine cycle at the hold's reference speed, s.
    pub(super) period: f64,
    /// Whole cycles in the stretch.
    pub(super) cycles: u64,
    /// The stretch's end, s: its start plus the cycles.
    pub(super) end: f64,
}

/// One cycle's record: its steps (their end times after the cycle's start and crank states with
/// the angle counted from the cycle's start; their increments and end evaluations), the sums
/// of the increments and the crank state at the cycle's end (angle from its start).
#[derive(Clone, Default)]
struct CycleRecord {
    at: Vec<(f64, CrankState)>,
    steps: RecordedSteps,
    sums: Vec<f64>,
    end: CrankState,
}

impl CycleRecord {
    fn clear(&mut self, per_step: usize) {
        self.at.clear();
        self.steps.clear();
        self.sums.clear();
        self.sums.resize(per_step, 0.0);
    }
}

/// The orbit replay of a PI hold's stretch under way.
#[derive(Clone)]
pub(super) struct Orbit {
    /// The stretch's cycles (0: idle), their period (s), the stretch's start (s), the cycles
    /// done and the stretch's end (s): the cycle under way ends a period after the cycles done,
    /// the last one on the stretch's end.
    cycles: u64,
    period: f64,
    from: f64,
    done: u64,
    end: f64,
    /// The cycle under way: its start time and crank state.
    start: (f64, CrankState),
    /// The cycle under way and the last one finished (the one replayed once they agree).
    current: CycleRecord,
    last: CycleRecord,
    /// Whether the last two cycles agreed: the rest of the stretch replays `last`.
    agreed: bool,
    /// The next step of `last` to replay.
    cursor: usize,
    increments: StepIncrements,
    /// Whether cycles may be replayed (not in [`HoldReplay::Evaluate`]).
    allowed: bool,
    agreement: f64,
}

impl Simulation {
    /// Whether the interval of the grid from `t` to `b` (s) holds a PI hold's stretch to step
    /// in orbit cycles, and which: a hold at constant reference speed, stateless laws, and at
    /// least three whole cycles before the window's records begin (with a cycle to spare).
    pub(super) fn orbit_cycles(&self, t: f64, b: f64) -> Option<OrbitCycles> {
        if self.stateful || self.hold_replay == HoldReplay::Off {
            return None;
        }
        let (_, omega, alpha) = self.reference_after(t);
        let (_, omega_b, _) = self.reference(b);
        if alpha != 0.0 || omega <= 0.0 || omega_b != omega {
            return None;
        }
        let spec = self.window_spec();
        let cycle = spec.cycle_angle();
        let hold = self
            .cycle
            .plateaus()
            .iter()
            .find(|p| p.t_start <= t && b <= p.t_end)?;
        // Where `Plateaus::record` starts recording for the window, at the longest step.
        let h_max = self.time_step(self.max_step_rad, omega);
        let records = hold.t_end - (spec.window_s + (cycle + TAU) / omega + 2.0 * h_max);
        let period = cycle / omega;
        let last = b.min(records - period);
        let cycles = ((last - t) / period).floor();
        // Two cycles to compare and one to replay (a NaN is none).
        if cycles.is_nan() || cycles < 3.0 {
            return None;
        }
        Some(OrbitCycles {
            period,
            cycles: cycles as u64,
            end: t + cycles * period,
        })
    }
}

impl Orbit {
    /// An idle orbit replay for a run accumulating `n_acc` quantities and `n_regime` regime
    /// times, in `mode`, with the run's friction/reaction tolerance.
    pub(super) fn new(
        (n_acc, n_regime): (usize, usize),
        mode: HoldReplay,
        friction_tol: f64,
    ) -> Self {
        Self {
            cycles: 0,
            period: 0.0,
            from: 0.0,
            done: 0,
            end: 0.0,
            start: (0.0, (0.0, 0.0, 0.0)),
            current: CycleRecord::default(),
            last: CycleRecord::default(),
            agreed: false,
            cursor: 0,
            increments: StepIncrements::new(n_acc, n_regime),
            allowed: mode == HoldReplay::On,
            agreement: friction_tol.max(AGREEMENT_FLOOR),
        }
    }

    /// Start stepping the stretch `plan` from `s`'s time and state. Returns its first cycle's
    /// end.
    pub(super) fn start(&mut self, plan: OrbitCycles, s: &Integration) -> f64 {
        let per_step = s.acc.len() + s.regime_time.len();
        self.cycles = plan.cycles;
        self.period = plan.period;
        self.from = s.t;
        self.done = 0;
        self.end = plan.end;
        self.start = (s.t, s.y);
        self.current.clear(per_step);
        self.agreed = false;
        self.cursor = 0;
        self.cycle_end()
    }

    /// Idle: the stretch is left (its cycles done, or the run planned again mid-cycle).
    pub(super) fn stop(&mut self) {
        self.cycles = 0;
    }

    /// Whether a stretch is under way.
    pub(super) fn active(&self) -> bool {
        self.done < self.cycles
    }

    /// The end of the cycle under way, s.
    fn cycle_end(&self) -> f64 {
        if self.done + 1 == self.cycles {
            self.end
        } else {
            self.from + (self.done + 1) as f64 * self.period
        }
    }

    /// The run reached time `s.t`: when that is the end of the cycle under way, the cycle is
    /// finished (compared with the one before, when evaluated) and the next one's end is
    /// returned; otherwise (the run was planned again mid-cycle) or at the stretch's end the
    /// replay goes idle (`None`).
    pub(super) fn next_cycle(&mut self, s: &Integration) -> Option<f64> {
        if !self.active() || s.t != self.cycle_end() {
            self.stop();
            return None;
        }
        if !self.agreed {
            let (_, y0) = self.start;
            self.current.end = (s.y.0 - y0.0, s.y.1, s.y.2);
            // `last` is this stretch's once a cycle of it is done.
            self.agreed = self.allowed && self.done > 0 && self.cycles_agree();
            std::mem::swap(&mut self.current, &mut self.last);
            self.current.clear(s.acc.len() + s.regime_time.len());
        }
        self.cursor = 0;
        self.start = (s.t, s.y);
        self.done += 1;
        self.active().then(|| self.cycle_end())
    }

    /// Whether the cycle just finished agrees with the one before: every increment and the
    /// end state (angle turned, speed, controller integral).
    fn cycles_agree(&self) -> bool {
        let (a, b) = (&self.last, &self.current);
        let tol = self.agreement;
        let close =
            |x: f64, y: f64, floor: f64| (x - y).abs() <= tol * x.abs().max(y.abs()).max(floor);
        agree(&a.sums, &b.sums, tol)
            && close(a.end.0, b.end.0, 0.0)
            && close(a.end.1, b.end.1, 0.0)
            && close(a.end.2, b.end.2, 1e-6 * b.end.0.abs())
    }

    /// Whether the step under way is recorded (its cycle is evaluated).
    pub(super) fn records(&self) -> bool {
        self.active() && !self.agreed
    }

    /// Before an evaluated step of the stretch: its increments to be kept apart.
    pub(super) fn begin_step(&mut self, s: &mut Integration) {
        self.increments.begin(s);
    }

    /// After an evaluated step that failed: the run's totals as they were, the replay idle.
    pub(super) fn abort_step(&mut self, s: &mut Integration) {
        self.increments.abort(s);
        self.stop();
    }

    /// After evaluated step `step` of the cycle under way: its increments added to the run's
    /// totals and kept with its end time, state and evaluation.
    pub(super) fn end_step(&mut self, s: &mut Integration, step: &Step, w: &mut Work) {
        let (t0, y0) = self.start;
        let c = &mut self.current;
        let (acc, times) = self.increments.end(s);
        for (sum, d) in c.sums.iter_mut().zip(acc.iter().chain(times)) {
            *sum += d;
        }
        c.at.push((step.t1 - t0, (step.y.0 - y0.0, step.y.1, step.y.2)));
        c.steps.push((acc, times), &step.end, w);
    }

    /// The next step of the cycle under way replayed, when the cycles agreed: its increments
    /// added to the run's totals, its friction the next evaluation's start. Returns its end
    /// time (`b`, the cycle's end, for its last step), crank state and the index of its end
    /// evaluation ([`Orbit::end_eval`]); `None`: step it.
    pub(super) fn replay(
        &mut self,
        s: &mut Integration,
        b: f64,
    ) -> Option<(f64, CrankState, usize)> {
        if !self.active() || !self.agreed {
            return None;
        }
        let k = self.cursor;
        let rec = &self.last;
        let (dt, y) = *rec.at.get(k)?;
        rec.steps.apply(k, s);
        self.cursor += 1;
        let (t0, y0) = self.start;
        let t1 = if self.cursor == rec.steps.len() {
            b
        } else {
            t0 + dt
        };
        Some((t1, (y0.0 + y.0, y.1, y.2), k))
    }

    /// The end evaluation of the replayed cycle's step `k`.
    pub(super) fn end_eval(&self, k: usize) -> &Eval {
        self.last.steps.end(k)
    }
}
