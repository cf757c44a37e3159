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
//! The settling need not be waited for: once the last cycles settle as a linear system does,
//! their recurrence gives the orbit they settle to and what the rest of the settling would add
//! to each total ([`super::settle`]). The run jumps there, books that tail, and the cycle after
//! the jump must agree with the orbit extrapolated, as two evaluated cycles must, before any
//! cycle is replayed.
//!
//! What a replay leaves out is the rest of the settling: each cycle's change decays
//! geometrically, so the state where replay starts is within a few times the agreement of the
//! orbit, and the window, a tenth of a second later, is closer still.

use std::f64::consts::TAU;

use super::evaluate::{Eval, Work};
use super::rates::RateLayout;
use super::replay::{agree, HoldReplay, RecordedSteps, StepIncrements, AGREEMENT_FLOOR};
use super::settle::{Recurrence, CYCLES};
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
    /// The settling's extrapolation ([`Settling`]).
    settling: Settling,
}

/// The settling's extrapolation: the last cycles since the stretch's start or its last jump,
/// each a row of `width` quantities `[angle turned, speed, integral, sums...]` (`kept` of
/// `CYCLES` rows, the oldest first), the limit and tail computed from them, the jumps made in
/// this stretch, and whether the run's state jumped at the end of the last cycle (the stepper
/// must start again).
#[derive(Clone, Default)]
struct Settling {
    /// Whether jumps are made ([`HoldReplay::On`]).
    extrapolates: bool,
    rows: Vec<f64>,
    kept: usize,
    width: usize,
    limit: Vec<f64>,
    tail: Vec<f64>,
    jumps: u32,
    jumped: bool,
}

/// What the energy balance needs of a jump: the mechanism's mechanical energy (J) at a crank
/// angle and speed, and the accumulated quantities that take energy from the crank (the laws'
/// dissipation and the gas).
pub(super) struct Energy<'a> {
    pub(super) at: &'a dyn Fn(f64, f64) -> f64,
    pub(super) taken: std::ops::Range<usize>,
    pub(super) gas: usize,
}

/// Jumps to an extrapolated orbit in one stretch at most: each is checked by the cycle after
/// it, and one that fails is followed by cycles nearer the orbit than before it.
const MAX_JUMPS: u32 = 3;

/// The crank-state quantities of a cycle's row (angle turned, speed, integral), which the
/// recurrence is fitted to; the sums after them follow it.
const STATE: usize = 3;

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
            allowed: matches!(mode, HoldReplay::On | HoldReplay::Agreed),
            agreement: friction_tol.max(AGREEMENT_FLOOR),
            settling: Settling {
                extrapolates: mode == HoldReplay::On,
                ..Settling::default()
            },
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
        self.settling.start(STATE + per_step);
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
    pub(super) fn next_cycle(&mut self, s: &mut Integration, energy: &Energy) -> Option<f64> {
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
            if self.settling.extrapolates && !self.agreed && self.done + 2 < self.cycles {
                self.extrapolate(s, energy);
            }
        }
        self.cursor = 0;
        self.start = (s.t, s.y);
        self.done += 1;
        self.active().then(|| self.cycle_end())
    }

    /// Whether the cycle just finished agrees with the one before (or, after a jump, with
    /// the orbit jumped to): every increment and the end state (angle turned, speed,
    /// controller integral).
    fn cycles_agree(&self) -> bool {
        let (a, b) = (&self.last, &self.current);
        agree(&a.sums, &b.sums, self.agreement) && self.ends_agree(a.end, b.end)
    }

    /// Whether two cycles' end states agree: angle turned, speed, controller integral (held
    /// to a millionth of the angle turned at least, as it passes through zero).
    fn ends_agree(&self, a: CrankState, b: CrankState) -> bool {
        let tol = self.agreement;
        let close =
            |x: f64, y: f64, floor: f64| (x - y).abs() <= tol * x.abs().max(y.abs()).max(floor);
        close(a.0, b.0, 0.0) && close(a.1, b.1, 0.0) && close(a.2, b.2, 1e-6 * b.0.abs())
    }

    /// After evaluated cycle `last`, which did not agree with the one before: once the last
    /// [`CYCLES`] settle as a linear system does, jump to the orbit they settle to
    /// ([`super::settle`]). The run's crank state becomes the orbit's at this time (the
    /// angle ahead by what the rest of the settling would still turn), every total gains
    /// what the rest of the settling would still add, and `last` becomes the orbit's cycle,
    /// which the next cycle, started from it, must agree with to be replayed.
    ///
    /// The motor's share is what keeps the run's energy balance through the jump: the
    /// mechanical energy jumped by, plus what the laws and the gas would still take. The
    /// recurrence follows the settling to first order; the motor's power, a product of the
    /// controller's torque and the speed, both settling, has a second-order part it does not,
    /// and the balance is the exact statement of what the motor supplies.
    fn extrapolate(&mut self, s: &mut Integration, energy: &Energy) {
        let last = &self.last;
        let row = [last.end.0, last.end.1, last.end.2];
        let reported =
            |k: usize| k == RateLayout::MOTOR || energy.taken.contains(&k) || k == energy.gas;
        // What the replay of the stretch's remaining cycles may miss each sum by.
        let budget = self.agreement * (self.cycles - self.done) as f64;
        let Some(rec) = self.settling.push((&row, &last.sums), budget, reported) else {
            return;
        };
        let limit = &self.settling.limit;
        let orbit = (limit[0], limit[1], limit[2]);
        if self.jumps_nowhere(orbit, &limit[STATE..]) {
            return;
        }
        // The window measures the trajectory, settled or not: jump only when the settling left
        // by the stretch's end is within the agreement, as a replay of agreed cycles assumes.
        let left = self
            .settling
            .left_after(&rec, (self.cycles - self.done) as usize);
        let at_end = (orbit.0 + left[0], orbit.1 + left[1], orbit.2 + left[2]);
        if !self.ends_agree(orbit, at_end) {
            return;
        }
        let st = &mut self.settling;
        let (limit, tail) = (&st.limit, &st.tail);
        let y = (s.y.0 + tail[0], orbit.1, orbit.2);
        let n_acc = s.acc.len();
        let taken = energy.taken.clone().chain([energy.gas]);
        let taken: f64 = taken.map(|i| tail[STATE + i]).sum();
        let motor = (energy.at)(y.0, y.1) - (energy.at)(s.y.0, s.y.1) + taken;
        s.y = y;
        for (total, d) in s.acc.iter_mut().zip(&tail[STATE..STATE + n_acc]) {
            *total += d;
        }
        s.acc[RateLayout::MOTOR] += motor - tail[STATE + RateLayout::MOTOR];
        for (total, d) in s.regime_time.iter_mut().zip(&tail[STATE + n_acc..]) {
            *total += d;
        }
        self.last.end = orbit;
        self.last.sums.copy_from_slice(&limit[STATE..]);
        st.jumped();
    }

    /// Whether the orbit extrapolated to is the last cycle already, within the agreement: the
    /// cycles will agree without a jump.
    fn jumps_nowhere(&self, orbit: CrankState, sums: &[f64]) -> bool {
        agree(&self.last.sums, sums, self.agreement) && self.ends_agree(self.last.end, orbit)
    }

    /// Whether the run's state jumped at the end of the last cycle (once: the caller starts
    /// the stepper again from it).
    pub(super) fn take_jump(&mut self) -> bool {
        std::mem::take(&mut self.settling.jumped)
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

impl Settling {
    /// A stretch starts: no cycles kept, no jumps, rows of `width` quantities.
    fn start(&mut self, width: usize) {
        self.width = width;
        self.rows.resize(CYCLES * width, 0.0);
        self.limit.resize(width, 0.0);
        self.tail.resize(width, 0.0);
        self.kept = 0;
        self.jumps = 0;
        self.jumped = false;
    }

    /// Keep a finished cycle's row (its end state `state` and its `sums`). With [`CYCLES`]
    /// kept and a jump left, fit their recurrence; when one fits, the limit of every quantity
    /// and (for the increments: angle turned, sums) the tail still to come after this cycle
    /// are left in `limit` and `tail`, and the recurrence returned when they are good for a
    /// jump: the tails of the `reported` sums known within `budget` (relative, of a cycle's
    /// sum).
    fn push(
        &mut self,
        (state, sums): (&[f64; STATE], &[f64]),
        budget: f64,
        reported: impl Fn(usize) -> bool,
    ) -> Option<Recurrence> {
        let w = self.width;
        if self.kept == CYCLES {
            self.rows.copy_within(w.., 0);
            self.kept -= 1;
        }
        let row = &mut self.rows[self.kept * w..(self.kept + 1) * w];
        row[..STATE].copy_from_slice(state);
        row[STATE..].copy_from_slice(sums);
        self.kept += 1;
        if self.kept < CYCLES || self.jumps >= MAX_JUMPS {
            return None;
        }
        let x = |j: usize, c: usize| self.rows[j * w + c];
        let d = |j: usize, c: usize| x(j + 1, c) - x(j, c);
        let rec = Recurrence::fit(d, STATE)?;
        let m = rec.order();
        for c in 0..w {
            // The limit from the last m changes; what the cycles after the last would add
            // beyond the limit, from the last m values' deviations.
            let from = CYCLES - 1 - m;
            let limit = x(from, c) + rec.sum(|l| d(from + l, c));
            let settled = rec.sum(|l| x(CYCLES - m + l, c) - limit);
            let seen: f64 = (CYCLES - m..CYCLES).map(|j| x(j, c) - limit).sum();
            self.limit[c] = limit;
            self.tail[c] = settled - seen;
        }
        // A reported total's tail is only as good as the recurrence follows its sum: a sum
        // whose change is mostly of second order (a dissipation whose first-order part cancels
        // over the loop's oscillation) is not followed. The jump waits until each such tail is
        // known within what the replay of the stretch's remaining cycles may miss it by (the
        // agreement per cycle, as in `agree`). The other totals are read only as differences
        // over a window, which is evaluated: their tails reach no result.
        let sums = STATE..w;
        let scale = self.limit[sums.clone()]
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        let known = |c: usize| {
            let allowed = budget * self.limit[c].abs().max(1e-6 * scale);
            self.tail[c].abs() <= allowed || rec.misses(d, c) * self.tail[c].abs() <= allowed
        };
        sums.filter(|c| reported(c - STATE))
            .all(known)
            .then_some(rec)
    }

    /// The settling left `k` cycles after the last one kept, by the recurrence: each state
    /// quantity's deviation from its limit (angle turned, speed, integral).
    fn left_after(&self, rec: &Recurrence, k: usize) -> [f64; STATE] {
        let w = self.width;
        std::array::from_fn(|c| {
            let last = [
                self.rows[(CYCLES - 2) * w + c] - self.limit[c],
                self.rows[(CYCLES - 1) * w + c] - self.limit[c],
            ];
            rec.ahead(&last, k)
        })
    }

    /// The run jumped to the limit: the cycles kept belong to the trajectory left.
    fn jumped(&mut self) {
        self.kept = 0;
        self.jumps += 1;
        self.jumped = true;
    }
}
