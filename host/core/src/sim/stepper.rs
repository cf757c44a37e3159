//! Time stepping: one [`Stepper`] trait for a step method, with the prescribed crank's Simpson
//! quadrature and fixed-step RK4 here and the error-controlled Dormand-Prince pair in
//! `adaptive.rs`; the PI drive's torque; what the run loop hands a stepper ([`Integration`]).

use super::error::SimError;
use super::evaluate::{Eval, Point, Work};
use super::rates::RegimeTimes;
use super::types::Control;
use super::Simulation;
use crate::model::Drive;

/// Crank angle (rad), speed (rad/s) and the PI controller's integral (rad).
pub(super) type CrankState = (f64, f64, f64);

/// What the run loop and its stepper share: the time and crank state, the accumulated
/// quantities, the friction the next evaluation starts from and the run's counters.
#[derive(Debug, Clone)]
pub(super) struct Integration {
    /// Time at the start of the next step, s.
    pub(super) t: f64,
    /// Crank state there.
    pub(super) y: CrankState,
    /// Every accumulated quantity (see `RateLayout`), integrated from the start of the run.
    pub(super) acc: Vec<f64>,
    /// Each law's time in each regime (see `RegimeTimes`), integrated from the start of the
    /// run by the same rule.
    pub(super) regime_time: Vec<f64>,
    /// The rates at `t` (the last accepted evaluation), for the quadrature and the windows.
    pub(super) last_rates: Vec<f64>,
    /// The laws' regimes there.
    pub(super) last_regimes: Vec<u8>,
    /// The normal loads (per joint) and drive torque (N m) there.
    pub(super) last_normals: Vec<f64>,
    pub(super) last_torque: f64,
    /// Each joint's law total where the next friction iteration starts.
    pub(super) guess: Vec<f64>,
    /// Steps rejected by error control.
    pub(super) rejected: u64,
}

impl Integration {
    /// The start of a run: crank at rest at time 0, nothing accumulated, for `n` quantities
    /// and the regimes of `laws` laws.
    pub(super) fn new(n: usize, laws: RegimeTimes) -> Self {
        Self {
            t: 0.0,
            y: (0.0, 0.0, 0.0),
            acc: vec![0.0; n],
            regime_time: vec![0.0; laws.len()],
            last_rates: vec![0.0; n],
            last_regimes: vec![0; laws.n],
            last_normals: Vec::new(),
            last_torque: 0.0,
            guess: Vec::new(),
            rejected: 0,
        }
    }

    /// Keep what the accepted evaluation `e` at `t` gives the windows and the outputs.
    pub(super) fn record(&mut self, e: &Eval) {
        self.last_rates.copy_from_slice(&e.rates);
        self.last_regimes.copy_from_slice(&e.regimes);
        self.last_normals.clear();
        self.last_normals.extend_from_slice(&e.normals);
        self.last_torque = e.drive_torque;
    }

    /// Take `e`'s settled friction as the next evaluation's start.
    pub(super) fn settle_from(&mut self, e: &Eval) {
        self.guess.clear();
        self.guess.extend_from_slice(&e.totals);
    }
}

/// An accepted step.
pub(super) struct Step {
    /// End time, s.
    pub(super) t1: f64,
    /// Length, s.
    pub(super) h: f64,
    /// The evaluation at the end.
    pub(super) end: Eval,
    /// The crank state at the end.
    pub(super) y: CrankState,
}

/// A step method. The run loop walks the cycle's grid (segment ends and window starts) in
/// intervals; within one it asks the stepper for accepted steps, then hands each step's end
/// evaluation back once used (the next step's first stage, or a buffer to recycle).
pub(super) trait Stepper {
    /// An interval of the grid starts at `s.t`, to be covered by fixed steps of `dt`.
    fn begin_interval(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &mut Integration,
        dt: f64,
    ) -> Result<(), SimError> {
        let _ = (sim, w, s, dt);
        Ok(())
    }

    /// One accepted step from `s.t`: a fixed-step method ends at `t1`, an adaptive one where
    /// its error control says, at most at the interval's end `b`. The step's increments are
    /// added to `s.acc` and the friction at its end becomes `s.guess`.
    fn step(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &mut Integration,
        t1: f64,
        b: f64,
    ) -> Result<Step, SimError>;

    /// Take back the end evaluation of the step of length `h` once the run has used it.
    fn recycle(&mut self, end: Eval, h: f64, w: &mut Work);

    /// The inputs changed at `s.t` (the stepping API): forget every evaluation made with the
    /// old ones.
    fn restart(&mut self, sim: &Simulation, w: &mut Work, s: &Integration) -> Result<(), SimError> {
        let _ = (sim, w, s);
        Ok(())
    }
}

/// Prescribed crank: the reference motion is exact, so each step evaluates its midpoint and
/// end and integrates every rate with Simpson's rule.
#[derive(Clone)]
pub(super) struct Quadrature;

impl Stepper for Quadrature {
    fn begin_interval(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &mut Integration,
        dt: f64,
    ) -> Result<(), SimError> {
        // The reference acceleration may jump at t: start this interval from its own side of
        // the jump so Simpson's rule never straddles it.
        let e0 = prescribed_interval_start(sim, w, s, dt)?;
        w.recycle(e0);
        Ok(())
    }

    fn step(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &mut Integration,
        t1: f64,
        _b: f64,
    ) -> Result<Step, SimError> {
        let (t, h) = (s.t, t1 - s.t);
        let at = sim.prescribed_point(t + 0.5 * h, h, sim.reference(t + 0.5 * h));
        let mut em = w.eval();
        sim.evaluate(&at, &s.guess, w, &mut em)?;
        let (th1, w1, a1) = sim.reference(t1);
        let mut e1 = w.eval();
        sim.evaluate(
            &sim.prescribed_point(t1, h, (th1, w1, a1)),
            &em.totals,
            w,
            &mut e1,
        )?;
        s.settle_from(&e1);
        // Simpson's rule on every accumulated rate.
        for k in 0..s.acc.len() {
            s.acc[k] += h / 6.0 * (s.last_rates[k] + 4.0 * em.rates[k] + e1.rates[k]);
        }
        let stages: [&[u8]; 3] = [&s.last_regimes, &em.regimes, &e1.regimes];
        RegimeTimes::add_rule(&mut s.regime_time, stages, [1.0, 4.0, 1.0], h / 6.0);
        w.recycle(em);
        Ok(Step {
            t1,
            h,
            end: e1,
            y: (th1, w1, 0.0),
        })
    }

    fn recycle(&mut self, end: Eval, _h: f64, w: &mut Work) {
        w.recycle(end);
    }
}

/// The prescribed crank's evaluation at the start `s.t` of an interval of the grid, from the
/// side of the reference acceleration's jump the interval lies on, recorded and settled from:
/// what both prescribed quadratures begin an interval with.
pub(super) fn prescribed_interval_start(
    sim: &Simulation,
    w: &mut Work,
    s: &mut Integration,
    dt: f64,
) -> Result<Eval, SimError> {
    let at = sim.prescribed_point(s.t, dt, sim.reference_after(s.t));
    let mut e0 = w.eval();
    sim.evaluate(&at, &s.guess, w, &mut e0)?;
    s.record(&e0);
    s.settle_from(&e0);
    Ok(e0)
}

/// Classical RK4 with fixed steps of crank angle, crank speed and controller integral (a PI
/// drive with stateful laws, or `solver.integrator = "rk4"`).
#[derive(Default, Clone)]
pub(super) struct Rk4 {
    /// The previous step's end evaluation and its length: the next step's first stage when
    /// the step size (which the laws see) is the same and no law's state has moved since.
    carried: Option<(Eval, f64)>,
}

impl Stepper for Rk4 {
    fn step(
        &mut self,
        sim: &Simulation,
        w: &mut Work,
        s: &mut Integration,
        t1: f64,
        _b: f64,
    ) -> Result<Step, SimError> {
        let h = t1 - s.t;
        let omega = s.y.1;
        let reuse = !(sim.rules.fresh_first_stage && sim.stateful);
        let first = match self.carried.take() {
            Some((e, hh)) if reuse && hh == h && e.omega == omega => Some(e),
            Some((e, _)) => {
                w.recycle(e);
                None
            }
            None => None,
        };
        let (end, y) = sim.rk4_step(w, s, h, first)?;
        Ok(Step { t1, h, end, y })
    }

    fn recycle(&mut self, end: Eval, h: f64, w: &mut Work) {
        if let Some((old, _)) = self.carried.replace((end, h)) {
            w.recycle(old);
        }
    }

    fn restart(&mut self, _: &Simulation, w: &mut Work, _: &Integration) -> Result<(), SimError> {
        if let Some((old, _)) = self.carried.take() {
            w.recycle(old);
        }
        Ok(())
    }
}

impl Simulation {
    /// The time the crank needs to turn `angle_rad` at speed `omega`, capped by
    /// `solver.max_step_s` (which also covers a crank at rest).
    #[inline]
    pub(super) fn time_step(&self, angle_rad: f64, omega: f64) -> f64 {
        if omega > 0.0 {
            (angle_rad / omega).min(self.max_step_s)
        } else {
            self.max_step_s
        }
    }

    /// The evaluation point of a prescribed crank at `t` with reference `(theta, omega, alpha)`.
    #[inline]
    pub(super) fn prescribed_point(&self, t: f64, dt: f64, reference: CrankState) -> Point {
        let (theta, omega, alpha) = reference;
        Point {
            t,
            dt,
            theta,
            omega,
            control: Control::Acceleration(alpha),
            margin: f64::INFINITY,
            oil: self.oil_at(t),
        }
    }

    /// The evaluation point of the PI-driven crank at `t` in state `y`, and the controller
    /// integral's rate there.
    #[inline]
    pub(super) fn driven_point(&self, t: f64, dt: f64, y: CrankState, side: Side) -> (Point, f64) {
        let (torque, dz, margin) = self.pi_torque(t, y.1, y.2, side);
        let at = Point {
            t,
            dt,
            theta: y.0,
            omega: y.1,
            control: Control::Torque(torque),
            margin,
            oil: self.oil_at(t),
        };
        (at, dz)
    }

    /// The drive torque, the controller integral's rate and the margin to the torque limit
    /// (negative while saturated) for a PI drive, its law taken on `side` of the limit.
    #[inline]
    pub(super) fn pi_torque(&self, t: f64, omega: f64, z: f64, side: Side) -> (f64, f64, f64) {
        match self.held.torque_nm {
            // A drive torque set from outside replaces the controller (which holds still).
            Some(torque) => (torque, 0.0, f64::INFINITY),
            None => pi_drive(&self.drive, self.reference(t).1, omega, z, side),
        }
    }

    /// The evaluation at the end of a step (or the run's start) in state `y`: the reference
    /// motion for a prescribed crank (the integrated state is not used), the PI drive's
    /// torque otherwise.
    pub(super) fn step_eval(
        &self,
        t: f64,
        dt: f64,
        y: CrankState,
        guess: &[f64],
        w: &mut Work,
    ) -> Result<Eval, SimError> {
        let at = match self.drive {
            Drive::Prescribed {} => self.prescribed_point(t, dt, self.reference(t)),
            Drive::Pi { .. } => self.driven_point(t, dt, y, Side::Live).0,
        };
        let mut e = w.eval();
        self.evaluate(&at, guess, w, &mut e)?;
        Ok(e)
    }

    /// One classical RK4 step of length `h` from `s.t`, every rate accumulated into `s.acc`
    /// by the same weights. `first` is the evaluation at the step's start if already known.
    /// Returns the evaluation at the step's end and the end state.
    fn rk4_step(
        &self,
        w: &mut Work,
        s: &mut Integration,
        h: f64,
        first: Option<Eval>,
    ) -> Result<(Eval, CrankState), SimError> {
        let (t, (theta, omega, z)) = (s.t, s.y);
        let stage = |tt: f64, y: CrankState, g: &[f64], w: &mut Work| {
            let (at, dz) = self.driven_point(tt, h, y, Side::Live);
            let mut e = w.eval();
            self.evaluate(&at, g, w, &mut e)?;
            let k = [y.1, e.alpha, dz];
            Ok::<_, SimError>((e, k))
        };
        let (e1, k1) = match first {
            Some(e) => {
                let (_, dz, _) = self.pi_torque(t, omega, z, Side::Live);
                let k = [omega, e.alpha, dz];
                (e, k)
            }
            None => stage(t, s.y, &s.guess, w)?,
        };
        let at =
            |k: &[f64; 3], f: f64| (theta + f * h * k[0], omega + f * h * k[1], z + f * h * k[2]);
        let (e2, k2) = stage(t + 0.5 * h, at(&k1, 0.5), &e1.totals, w)?;
        let (e3, k3) = stage(t + 0.5 * h, at(&k2, 0.5), &e2.totals, w)?;
        let (e4, k4) = stage(t + h, at(&k3, 1.0), &e3.totals, w)?;
        let mix = |c: usize| h / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
        let (th1, w1, z1) = (theta + mix(0), omega + mix(1), z + mix(2));
        for (k, a) in s.acc.iter_mut().enumerate() {
            *a += h / 6.0 * (e1.rates[k] + 2.0 * e2.rates[k] + 2.0 * e3.rates[k] + e4.rates[k]);
        }
        let stages: [&[u8]; 4] = [&e1.regimes, &e2.regimes, &e3.regimes, &e4.regimes];
        RegimeTimes::add_rule(&mut s.regime_time, stages, [1.0, 2.0, 2.0, 1.0], h / 6.0);
        // The state at the step end, for output, commit and the next step's first stage.
        let end = self.step_eval(t + h, h, (th1, w1, z1), &e4.totals, w)?;
        s.settle_from(&end);
        for e in [e1, e2, e3, e4] {
            w.recycle(e);
        }
        Ok((end, (th1, w1, z1)))
    }
}

/// The PI drive `drive` at crank speed `omega` against the reference speed `reference`, with
/// controller integral `z`: the torque on the crank (through the belt), the integral's rate
/// and the margin to the torque limit (negative while saturated), its law taken on `side` of
/// the limit. A prescribed crank has no drive torque of its own (0, 0, infinite margin).
#[inline]
pub(super) fn pi_drive(
    drive: &Drive,
    reference: f64,
    omega: f64,
    z: f64,
    side: Side,
) -> (f64, f64, f64) {
    match *drive {
        Drive::Pi {
            kp,
            ki,
            torque_limit_nm,
            belt_ratio,
            ..
        } => {
            let e = reference - omega;
            let raw = kp * e + ki * z;
            let margin = torque_limit_nm - raw.abs();
            let beyond = match side {
                Side::Live => margin < 0.0,
                Side::Within => false,
                Side::Beyond => true,
            };
            if !beyond {
                return (raw * belt_ratio, e, margin);
            }
            // Conditional integration: stop integrating while saturated in the direction
            // the error pushes, so the integral cannot wind up.
            let dz = if raw.signum() == e.signum() { 0.0 } else { e };
            (torque_limit_nm.copysign(raw) * belt_ratio, dz, margin)
        }
        Drive::Prescribed {} => (0.0, 0.0, f64::INFINITY),
    }
}

/// Which side of the PI drive's torque limit its law is taken on. `Live`: the side the state
/// is on, as the drive itself. The adaptive integrator holds a step's stages on the side its
/// start is on (`Within`: the controller's torque and integration; `Beyond`: the limit, the
/// integral held while the error pushes further), so they see one smooth field, and ends a step
/// on a located crossing of the limit: the integral's rate jumps there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    Live,
    Within,
    Beyond,
}

impl Side {
    /// The other side of the limit (`Within` for `Live`, which is on no side of its own).
    pub(super) fn other(self) -> Side {
        match self {
            Side::Within => Side::Beyond,
            Side::Beyond | Side::Live => Side::Within,
        }
    }

    /// Whether margin `m` (N m) is past the limit, seen from this side (never for `Live`,
    /// which follows the state).
    pub(super) fn left_by(self, m: f64) -> bool {
        match self {
            Side::Within => m < 0.0,
            Side::Beyond => m > 0.0,
            Side::Live => false,
        }
    }
}
