//! The transient run: the whole test cycle, ramps included, stepped over the cycle's grid
//! (segment ends, and for a prescribed crank the windows' starts) by one [`Stepper`], every
//! accepted step committed (stateful laws), observed, filtered and recorded for the plateau
//! windows. A run is a value ([`Transient`]) advanced in time, so it can stop and go on.

use std::f64::consts::TAU;

use super::adaptive::Adaptive;
use super::error::SimError;
use super::evaluate::{Eval, Work};
use super::lobatto::Lobatto;
use super::orbit::{Energy, Orbit};
use super::plateau::Plateaus;
use super::rates::RateLayout;
use super::replay::Replay;
use super::results::{EnergyBalance, RunResult};
use super::stepper::{CrankState, Integration, Quadrature, Rk4, Step, Stepper};
use super::{Commit, Simulation};
use crate::erk::{Controller, DORMAND_PRINCE_54};
use crate::model::{Drive, Integrator, QuadratureRule, StepControl};
use crate::observe::{StepObserver, StepSample};

/// The step method of a transient run.
#[derive(Clone)]
pub(super) enum Method {
    /// Prescribed crank: Simpson quadrature of the exact reference motion.
    Quadrature(Quadrature),
    /// Prescribed crank, stateless laws, `solver.quadrature = "lobatto"`: error-controlled
    /// Gauss-Lobatto quadrature.
    Lobatto(Box<Lobatto>),
    /// Prescribed crank, stateless laws, `solver.quadrature = "auto"` (the default): Simpson
    /// in the windows and a hold's whole cycles, Gauss-Lobatto elsewhere (`on_lobatto`, set
    /// per interval).
    Mixed {
        simpson: Quadrature,
        lobatto: Box<Lobatto>,
        on_lobatto: bool,
    },
    /// PI drive, stateless laws: error-controlled Dormand-Prince 5(4).
    Adaptive(Box<Adaptive>),
    /// PI drive with stateful laws, or `solver.integrator = "rk4"`: fixed-step RK4.
    Rk4(Rk4),
}

impl Method {
    fn stepper(&mut self) -> &mut dyn Stepper {
        match self {
            Method::Quadrature(q) => q,
            Method::Lobatto(l) => l.as_mut(),
            Method::Mixed {
                lobatto,
                on_lobatto: true,
                ..
            } => lobatto.as_mut(),
            Method::Mixed { simpson, .. } => simpson,
            Method::Adaptive(a) => a.as_mut(),
            Method::Rk4(r) => r,
        }
    }
}

/// The grid interval being stepped: its end `b`, its `m` equal steps of `dt` and how many
/// are done; for a hold stepped in whole cycles, its start `t0` (its steps end at `t0` plus
/// whole steps, so every cycle's steps are at the same crank angles).
#[derive(Debug, Clone, Copy)]
struct Interval {
    b: f64,
    m: u64,
    dt: f64,
    done: u64,
    cycles_from: Option<f64>,
}

/// A transient run in progress: the evaluation scratch (with every law's state), what the
/// stepper integrates, the stepper, the plateau records, the filtered torque and the counts.
#[derive(Clone)]
pub(super) struct Transient {
    pub(super) w: Work,
    pub(super) s: Integration,
    method: Method,
    grid: Vec<f64>,
    next: usize,
    interval: Option<Interval>,
    /// The replay of the hold interval under way (idle unless it is stepped in whole cycles).
    replay: Box<Replay>,
    /// The orbit replay of the PI hold stretch under way (idle unless one is stepped in
    /// orbit cycles).
    orbit: Box<Orbit>,
    /// Whether a stretch in orbit cycles ended (done, or left when the run was planned again
    /// inside it): the stepper starts again from the run's state before its next step.
    restart: bool,
    /// Steps replayed, not evaluated.
    replayed: u64,
    /// Steps taken and the filtered motoring torque.
    booked: Booked,
    /// The mechanism's energy at the start, J.
    e0: f64,
}

impl Simulation {
    /// Which step method a transient run uses.
    fn method(&self, first: Eval, w: &mut Work) -> Method {
        match self.drive {
            // A stateful law's state is advanced with the step's length, which must then not
            // vary: error-controlled steps are for stateless laws only.
            Drive::Prescribed {}
                if self.quadrature == QuadratureRule::Lobatto && !self.stateful =>
            {
                let pi = self.step_control == StepControl::Pi;
                Method::Lobatto(Box::new(Lobatto::new(pi, first, self.layout().len())))
            }
            // A pressure trace's kinks cost Lobatto more evaluations than Simpson's steps.
            Drive::Prescribed {}
                if self.quadrature == QuadratureRule::Auto
                    && !self.stateful
                    && self.pressure_kinks.is_empty() =>
            {
                let pi = self.step_control == StepControl::Pi;
                Method::Mixed {
                    simpson: Quadrature,
                    lobatto: Box::new(Lobatto::new(pi, first, self.layout().len())),
                    on_lobatto: false,
                }
            }
            Drive::Prescribed {} => {
                w.recycle(first);
                Method::Quadrature(Quadrature)
            }
            // A stateful law's state is advanced with the step's length, which must then not
            // vary: the adaptive integrator is for stateless laws only.
            Drive::Pi { .. } if self.integrator == Integrator::Adaptive && !self.stateful => {
                let control = match self.step_control {
                    StepControl::Integral => Controller::new(&DORMAND_PRINCE_54),
                    StepControl::Pi => Controller::pi(&DORMAND_PRINCE_54),
                };
                let n = self.layout().len();
                Method::Adaptive(Box::new(Adaptive::new(
                    &DORMAND_PRINCE_54,
                    control,
                    first,
                    n,
                    self.regime_times(),
                )))
            }
            Drive::Pi { .. } => {
                w.recycle(first);
                Method::Rk4(Rk4::default())
            }
        }
    }

    /// A transient run at its start: every law's state at zero, the crank at rest, the start
    /// evaluated.
    pub(super) fn start_transient(&self) -> Result<Transient, SimError> {
        if self.drivetrain.is_some() {
            return Err(SimError::Setup {
                at: None,
                field: "drivetrain".into(),
                law: None,
                param: None,
                message: "a rig with a [drivetrain] or an elastic crankshaft ([engine.crankshaft]) runs the whole test cycle (`run`) or the steady state (`--steady`); the stepping interface (the FMU, Python's stepping) does not integrate the chain's degrees of freedom".into(),
            });
        }
        let mut w = self.work()?;
        let n = self.layout().len();
        let mut s = Integration::new(n, self.regime_times());
        let first = self.step_eval(0.0, 0.0, (0.0, 0.0, 0.0), &[], &mut w)?;
        s.record(&first);
        s.settle_from(&first);
        Ok(Transient {
            method: self.method(first, &mut w),
            grid: self.grid(),
            next: 0,
            interval: None,
            replay: Box::new(Replay::new(
                (n, self.regime_times().len()),
                self.hold_replay,
                self.tol,
            )),
            orbit: Box::new(Orbit::new(
                (n, self.regime_times().len()),
                self.hold_replay,
                self.tol,
            )),
            restart: false,
            replayed: 0,
            booked: Booked {
                steps: 0,
                filtered: 0.0,
                plateaus: Plateaus::new(
                    self.cycle.plateaus(),
                    self.window_spec(),
                    (n, self.regime_times()),
                ),
            },
            e0: w.crank.mechanical_energy(0.0, 0.0),
            w,
            s,
        })
    }

    /// Advance the run `r` by accepted steps until it reaches `target` (s), the end of its
    /// grid (the cycle's end) or `max_steps` steps, handing each step to `observer`. Returns
    /// the number of steps taken.
    pub(super) fn advance(
        &self,
        r: &mut Transient,
        target: f64,
        max_steps: u64,
        observer: &mut dyn StepObserver,
    ) -> Result<u64, SimError> {
        let mut taken = 0;
        loop {
            if r.s.t >= target || taken >= max_steps {
                return Ok(taken);
            }
            let iv = match r.interval {
                Some(iv) if r.s.t < iv.b => iv,
                _ => {
                    let Some(iv) = self.next_interval(r) else {
                        return Ok(taken);
                    };
                    r.method
                        .stepper()
                        .begin_interval(self, &mut r.w, &mut r.s, iv.dt)?;
                    r.interval = Some(iv);
                    continue;
                }
            };
            let done = iv.done + 1;
            r.interval = Some(Interval { done, ..iv });
            let t1 = match iv.cycles_from {
                _ if done == iv.m => iv.b,
                Some(t0) => t0 + done as f64 * iv.dt,
                None => r.s.t + iv.dt,
            };
            match self.take_step(r, done, t1, iv.b)? {
                Taken::Evaluated(step) => self.accept(r, step, observer)?,
                Taken::Replayed(replayed) => self.accept_replayed(r, replayed, observer)?,
            }
            taken += 1;
        }
    }

    /// The next interval of the grid, from the run's time (`None` at the grid's end). An
    /// interval of a hold long enough is cut to whole engine cycles, stepped in whole steps
    /// per cycle, and its replay set up; the rest of it becomes an interval of its own. Under
    /// the PI drive a hold's stretch before its window's records is stepped in orbit cycles,
    /// each an interval ([`Orbit`]).
    fn next_interval(&self, r: &mut Transient) -> Option<Interval> {
        let orbit_was_active = r.orbit.active();
        let layout = self.layout();
        let crank = &r.w.crank;
        let energy = Energy {
            at: &|theta, omega| crank.mechanical_energy(theta, omega),
            taken: layout.powers(),
            gas: layout.gas(),
        };
        if let Some(end) = r.orbit.next_cycle(&mut r.s, &energy) {
            // A jump to the settled orbit: the stepper starts again from the state jumped to.
            r.restart |= r.orbit.take_jump();
            return Some(self.plan_interval(r, end));
        }
        // After a stretch in orbit cycles the stepper starts again from the run's state,
        // replayed or not, so what follows owes nothing to how the stretch was taken.
        r.restart |= orbit_was_active;
        let b = *r.grid.get(r.next)?;
        let window = self.starts_window(r.s.t, b);
        if window {
            // A window's first evaluation starts from the frictionless guess, so the window's
            // result owes nothing to how the hold was stepped.
            r.s.guess.fill(0.0);
        }
        // A window is stepped as it always was, never replayed.
        let simpson = matches!(r.method, Method::Quadrature(_) | Method::Mixed { .. }) && !window;
        r.replay.stop();
        let plan = self.hold_cycles(r.s.t, b, simpson);
        if let Method::Mixed { on_lobatto, .. } = &mut r.method {
            // Simpson where the result is measured or repeats, Lobatto elsewhere.
            *on_lobatto = !window && plan.is_none();
        }
        let Some(plan) = plan else {
            let orbit = match r.method {
                Method::Adaptive(_) => self.orbit_cycles(r.s.t, b),
                _ => None,
            };
            if let Some(orbit) = orbit.filter(|o| o.end < b) {
                r.grid.insert(r.next, orbit.end);
            }
            r.next += 1;
            let end = orbit.map_or(b, |o| r.orbit.start(o, &r.s));
            return Some(self.plan_interval(r, end));
        };
        if plan.end < b {
            r.grid.insert(r.next, plan.end);
        }
        r.next += 1;
        r.replay.start(plan);
        let m = plan.n * plan.cycles;
        Some(Interval {
            b: plan.end,
            m,
            dt: (plan.end - r.s.t) / m as f64,
            done: 0,
            cycles_from: Some(r.s.t),
        })
    }

    /// Step `done` of the interval under way, ending at `t1` (its end `b`): replayed where the
    /// hold's cycles repeat, evaluated otherwise (its increments recorded in the cycles that
    /// are compared and replayed).
    fn take_step(&self, r: &mut Transient, done: u64, t1: f64, b: f64) -> Result<Taken, SimError> {
        if let Some(k) = r.replay.replay(done, &mut r.s) {
            r.replayed += 1;
            let (theta, omega, _) = self.reference(t1);
            return Ok(Taken::Replayed((t1, (theta, omega, 0.0), k, false)));
        }
        if let Some((t1, y, k)) = r.orbit.replay(&mut r.s, b) {
            r.replayed += 1;
            return Ok(Taken::Replayed((t1, y, k, true)));
        }
        if std::mem::take(&mut r.restart) {
            r.method.stepper().restart(self, &mut r.w, &r.s)?;
        }
        let records = r.replay.active() && r.replay.records(done);
        let orbit = r.orbit.records();
        if records {
            r.replay.begin_step(&mut r.s);
        } else if orbit {
            r.orbit.begin_step(&mut r.s);
        }
        let step = r.method.stepper().step(self, &mut r.w, &mut r.s, t1, b);
        match (&step, records, orbit) {
            (Ok(step), true, _) => r.replay.end_step(done, &mut r.s, step, &mut r.w),
            (Err(_), true, _) => r.replay.abort_step(&mut r.s),
            (Ok(step), false, true) => r.orbit.end_step(&mut r.s, step, &mut r.w),
            (Err(_), false, true) => r.orbit.abort_step(&mut r.s),
            (_, false, false) => {}
        }
        step.map(Taken::Evaluated)
    }

    /// Make `t` (s, after the run's time) a point of the run's grid, so the run lands on it:
    /// the interval under way, if it reaches past `t`, is planned again from the run's time.
    /// Beyond the end of the cycle the grid goes on to `t`.
    pub(super) fn land_on(&self, r: &mut Transient, t: f64) {
        if t <= r.s.t {
            return;
        }
        let pos = r.grid.partition_point(|g| *g < t);
        let on_grid = r.grid.get(pos).is_some_and(|g| *g == t);
        if !on_grid {
            r.grid.insert(pos, t);
            if pos < r.next {
                // `t` falls inside the interval under way (which ends at the point now at
                // `pos + 1`): plan it again, to `t` first.
                r.next = pos;
                r.interval = None;
            }
        }
    }

    /// Plan the interval under way again from the run's time (its step, and for a prescribed
    /// crank its start evaluation): after the inputs changed, or a state was restored.
    pub(super) fn replan(&self, r: &mut Transient) -> Result<(), SimError> {
        r.orbit.stop();
        r.restart = false;
        if let Some(iv) = r.interval.take() {
            if r.s.t < iv.b {
                r.next -= 1;
            }
        }
        if let Method::Mixed { lobatto, .. } = &mut r.method {
            lobatto.restart(self, &mut r.w, &r.s)?;
        }
        r.method.stepper().restart(self, &mut r.w, &r.s)
    }

    /// Take up the run from its time after its state was set from outside (a resumed
    /// [`super::RunState`]): the next interval starts there, the stepper starts afresh.
    pub(super) fn seek(&self, r: &mut Transient) -> Result<(), SimError> {
        r.next = r.grid.partition_point(|g| *g <= r.s.t);
        r.interval = None;
        r.replay.stop();
        self.replan(r)
    }

    /// The interval of the grid from the run's time to `b`: whole steps of at most
    /// `solver.step_deg` at the fastest speed the interval reaches.
    fn plan_interval(&self, r: &Transient, b: f64) -> Interval {
        let (t, y) = (r.s.t, r.s.y);
        let (_, w_end, _) = self.reference(b);
        let w_max = w_end.max(self.reference(t).1).max(y.1);
        let dt_target = self.time_step(self.step_rad, w_max);
        let m = ((b - t) / dt_target).ceil().max(1.0) as u64;
        Interval {
            b,
            m,
            dt: (b - t) / m as f64,
            done: 0,
            cycles_from: None,
        }
    }

    /// Take the accepted `step`: commit the laws' states, book it ([`book`]), hand its end
    /// evaluation back to the stepper.
    fn accept(
        &self,
        r: &mut Transient,
        step: Step,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SimError> {
        self.commit(&mut r.w, &step.end)?;
        let at = (step.t1, step.h, step.y);
        book(self, &mut r.booked, &mut r.s, at, &step.end, observer)?;
        r.method.stepper().recycle(step.end, step.h, &mut r.w);
        Ok(())
    }

    /// Take the replayed step `(t1, y, k, orbit)`, ending at `t1` in crank state `y` (its
    /// increments already added): booked from the recorded end evaluation `k` (of the orbit
    /// replay's cycle if `orbit`, else of the prescribed hold's) in place, nothing to commit
    /// (stateless laws) or hand back.
    fn accept_replayed(
        &self,
        r: &mut Transient,
        (t1, y, k, orbit): Replayed,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SimError> {
        let at = (t1, t1 - r.s.t, y);
        let end = match orbit {
            true => r.orbit.end_eval(k),
            false => r.replay.end(k),
        };
        book(self, &mut r.booked, &mut r.s, at, end, observer)
    }

    /// The finished run's result: energy balance and every plateau's window.
    pub(super) fn finish_transient(&self, r: &Transient) -> Result<RunResult, SimError> {
        let layout = self.layout();
        let change = r.w.crank.mechanical_energy(r.s.y.0, r.s.y.1) - r.e0;
        let dissipated: f64 = r.s.acc[layout.powers()].iter().sum();
        let energy = EnergyBalance::from_terms_with_gas(
            r.s.acc[RateLayout::MOTOR],
            change,
            dissipated,
            r.s.acc[layout.gas()],
        )
        .relative_to(r.e0.abs().max((r.e0 + change).abs()));
        let (results, run_warnings) = r
            .booked
            .plateaus
            .results(|pi, m| self.plateau_result(pi, m))?;
        Ok(self.run_result(
            self.cycle_drive(),
            (results, energy),
            ([r.booked.steps, r.s.rejected, r.replayed], r.w.max_it),
            run_warnings,
        ))
    }

    /// Commit every stateful law over the accepted step whose end evaluation is `e`, at the
    /// law inputs of that evaluation's last round of laws (in `w`).
    pub(super) fn commit(&self, w: &mut Work, e: &Eval) -> Result<(), SimError> {
        if !self.stateful {
            return Ok(());
        }
        for (ji, j) in self.joints.iter().enumerate() {
            if !j.is_stateful() {
                continue;
            }
            let mut input = w.inputs[ji];
            if self.rules.commit == Commit::Rebuilt {
                let (comp, moment) = w.crank.reaction(j.role);
                super::bind::set_load(&mut input, comp, moment, e.normals[ji]);
            }
            j.commit(&input, &mut w.states)?;
        }
        Ok(())
    }

    /// Whether the interval of the grid from `t` to `b` (s) is a prescribed hold's whole
    /// measurement window.
    fn starts_window(&self, t: f64, b: f64) -> bool {
        let spec = self.window_spec();
        matches!(self.drive, Drive::Prescribed {})
            && self.cycle.plateaus().iter().any(|p| {
                b == p.t_end && (t - spec.window_start(p)).abs() <= 1e-12 * p.t_end.max(1.0)
            })
    }

    /// The run's grid over the cycle: segment ends, and for a prescribed crank the exact
    /// window starts, so every window begins and ends on a step.
    pub(super) fn grid(&self) -> Vec<f64> {
        let spec = self.window_spec();
        let duration = self.cycle.duration();
        let mut breaks: Vec<f64> = self.cycle.breakpoints();
        if matches!(self.drive, Drive::Prescribed {}) {
            breaks.extend(self.cycle.plateaus().iter().map(|p| spec.window_start(p)));
        }
        breaks.retain(|b| *b > 0.0 && *b <= duration);
        breaks.sort_by(f64::total_cmp);
        breaks.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        breaks
    }
}

/// An accepted step: evaluated by the stepper, or replayed ([`Replayed`]).
enum Taken {
    Evaluated(Step),
    Replayed(Replayed),
}

/// A replayed step: its end time (s) and crank state, and which recorded step it repeats
/// (its index, and whether of a PI hold's orbit cycle or of a prescribed hold's cycle).
type Replayed = (f64, CrankState, usize, bool);

/// What a run keeps of its accepted steps: their count, the motoring torque through the
/// first-order low-pass filter (N m) and the plateau windows' records.
#[derive(Clone)]
struct Booked {
    steps: u64,
    filtered: f64,
    plateaus: Plateaus,
}

/// Book the accepted step ending at `t1` after `h` (s) in crank state `y` with end evaluation
/// `end` into the run's records `booked` and integration `s`: progress, the filtered torque,
/// the observer, the windows.
fn book(
    sim: &Simulation,
    booked: &mut Booked,
    s: &mut Integration,
    (t1, h, y): (f64, f64, CrankState),
    end: &Eval,
    observer: &mut dyn StepObserver,
) -> Result<(), SimError> {
    s.y = y;
    s.record(end);
    booked.steps += 1;
    if booked.steps % 4096 == 0 {
        let permille = (1000.0 * t1 / sim.cycle.duration()) as u64;
        if let Some(p) = &sim.progress {
            p.set(permille);
        }
        observer.progress(permille);
    }
    // Without an observer that reads the samples the filter is not run: a run's observer is
    // the same for all its steps (a whole run's, or none for the stepping API).
    if observer.reads_samples() {
        // Low-pass filter of the motoring torque (first order, exact discretisation).
        let a = (-TAU * sim.lowpass_hz * h).exp();
        booked.filtered = a * booked.filtered + (1.0 - a) * end.drive_torque;
        let sample = StepSample {
            time_s: t1,
            crank_angle_rad: y.0,
            speed_rad_s: y.1,
            motoring_torque_nm: end.drive_torque,
            filtered_torque_nm: booked.filtered,
            normal_loads_n: &end.normals,
        };
        observer.step(&sample).map_err(SimError::Observer)?;
    }
    booked
        .plateaus
        .record(t1, h, (y.0, y.1), end.saturated(), s);
    s.t = t1;
    Ok(())
}
