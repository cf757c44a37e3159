//! Time stepping: one [`Stepper`] trait for a step method, with the prescribed crank's Simpson
//! quadrature and fixed-step RK4 here and the error-controlled Dormand-Prince pair in
//! `adaptive.rs`; the PI drive's torque; what the run loop hands a stepper ([`Work`]).

use super::error::SimError;
use super::evaluate::{Control, Eval, Point};
use super::Simulation;
use crate::mechanics::JointLoads;
use crate::model::Drive;

/// Crank angle (rad), speed (rad/s) and the PI controller's integral (rad).
pub(super) type CrankState = (f64, f64, f64);

/// What the run loop and its stepper share: the time and crank state, the accumulated
/// quantities, the friction loads that start the next evaluation, recycled rate buffers and
/// the run's counters.
pub(super) struct Work {
    /// Time at the start of the next step, s.
    pub(super) t: f64,
    /// Crank state there.
    pub(super) y: CrankState,
    /// Every accumulated quantity (see `RateLayout`), integrated from the start of the run.
    pub(super) acc: Vec<f64>,
    /// The rates at `t` (the last accepted evaluation), for the quadrature and the windows.
    pub(super) last_rates: Vec<f64>,
    /// Start of the next friction iteration.
    pub(super) guess: JointLoads,
    /// Rate buffers to reuse: no allocation per evaluation once warmed up.
    pub(super) pool: Vec<Vec<f64>>,
    /// Largest friction iteration count seen.
    pub(super) max_it: u32,
    /// Steps rejected by error control.
    pub(super) rejected: u64,
}

impl Work {
    /// A recycled rate buffer (or a new one while the pool warms up).
    pub(super) fn buffer(&mut self) -> Vec<f64> {
        self.pool.pop().unwrap_or_default()
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
    /// An interval of the grid starts at `w.t`, to be covered by fixed steps of `dt`.
    fn begin_interval(&mut self, sim: &Simulation, w: &mut Work, dt: f64) -> Result<(), SimError> {
        let _ = (sim, w, dt);
        Ok(())
    }

    /// One accepted step from `w.t`: a fixed-step method ends at `t1`, an adaptive one where its
    /// error control says, at most at the interval's end `b`. The step's increments are added to
    /// `w.acc` and the loads at its end become `w.guess`.
    fn step(&mut self, sim: &Simulation, w: &mut Work, t1: f64, b: f64) -> Result<Step, SimError>;

    /// Take back the end evaluation of the step of length `h` once the run has used it.
    fn recycle(&mut self, end: Eval, h: f64, w: &mut Work);
}

/// Prescribed crank: the reference motion is exact, so each step evaluates its midpoint and
/// end and integrates every rate with Simpson's rule.
pub(super) struct Quadrature;

impl Stepper for Quadrature {
    fn begin_interval(&mut self, sim: &Simulation, w: &mut Work, dt: f64) -> Result<(), SimError> {
        // The reference acceleration may jump at t: start this interval from its own side of
        // the jump so Simpson's rule never straddles it.
        let (theta, omega, alpha) = sim.cycle.reference_after(w.t);
        let at = sim.prescribed_point(w.t, dt, (theta, omega, alpha));
        let buffer = w.buffer();
        let (e0, l0) = sim.evaluate(&at, &w.guess, buffer)?;
        let old = std::mem::replace(&mut w.last_rates, e0.rates);
        w.pool.push(old);
        w.guess = l0;
        Ok(())
    }

    fn step(&mut self, sim: &Simulation, w: &mut Work, t1: f64, _b: f64) -> Result<Step, SimError> {
        let (t, h) = (w.t, t1 - w.t);
        let at = sim.prescribed_point(t + 0.5 * h, h, sim.cycle.reference(t + 0.5 * h));
        let buffer = w.buffer();
        let (em, lm) = sim.evaluate(&at, &w.guess, buffer)?;
        let (th1, w1, a1) = sim.cycle.reference(t1);
        let buffer = w.buffer();
        let (e1, l1) = sim.evaluate(&sim.prescribed_point(t1, h, (th1, w1, a1)), &lm, buffer)?;
        w.guess = l1;
        w.max_it = w.max_it.max(em.iterations).max(e1.iterations);
        // Simpson's rule on every accumulated rate.
        for k in 0..w.acc.len() {
            w.acc[k] += h / 6.0 * (w.last_rates[k] + 4.0 * em.rates[k] + e1.rates[k]);
        }
        w.pool.push(em.rates);
        Ok(Step {
            t1,
            h,
            end: e1,
            y: (th1, w1, 0.0),
        })
    }

    fn recycle(&mut self, end: Eval, _h: f64, w: &mut Work) {
        w.pool.push(end.rates);
    }
}

/// Classical RK4 with fixed steps of crank angle, crank speed and controller integral (a PI
/// drive with stateful laws, or `solver.integrator = "rk4"`).
#[derive(Default)]
pub(super) struct Rk4 {
    /// The previous step's end evaluation, its loads and the step length: the next step's
    /// first stage when the step size (which the laws see) is the same.
    carried: Option<(Eval, JointLoads, f64)>,
}

impl Stepper for Rk4 {
    fn step(&mut self, sim: &Simulation, w: &mut Work, t1: f64, _b: f64) -> Result<Step, SimError> {
        let h = t1 - w.t;
        let omega = w.y.1;
        let first = self
            .carried
            .take()
            .filter(|(e, _, hh)| *hh == h && e.omega == omega)
            .map(|(e, l, _)| (e, l));
        let (end, loads, y) = sim.rk4_step(w, h, first)?;
        w.guess = loads;
        Ok(Step { t1, h, end, y })
    }

    fn recycle(&mut self, end: Eval, h: f64, w: &mut Work) {
        self.carried = Some((end, w.guess, h));
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
    pub(super) fn driven_point(&self, t: f64, dt: f64, y: CrankState) -> (Point, f64) {
        let (torque, dz, margin) = self.pi_torque(t, y.1, y.2);
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
    /// (negative while saturated) for a PI drive.
    #[inline]
    pub(super) fn pi_torque(&self, t: f64, omega: f64, z: f64) -> (f64, f64, f64) {
        pi_drive(&self.drive, self.cycle.reference(t).1, omega, z)
    }

    /// The evaluation at the end of a step (or the run's start) in state `y`: the reference
    /// motion for a prescribed crank (the integrated state is not used), the PI drive's
    /// torque otherwise.
    pub(super) fn step_eval(
        &self,
        t: f64,
        dt: f64,
        y: CrankState,
        guess: &JointLoads,
        buffer: Vec<f64>,
    ) -> Result<(Eval, JointLoads), SimError> {
        let at = match self.drive {
            Drive::Prescribed => self.prescribed_point(t, dt, self.cycle.reference(t)),
            Drive::Pi { .. } => self.driven_point(t, dt, y).0,
        };
        self.evaluate(&at, guess, buffer)
    }

    /// One classical RK4 step of length `h` from `w.t`, every rate accumulated into `w.acc`
    /// by the same weights. `first` is the evaluation at the step's start if already known.
    /// Returns the evaluation at the step's end, its loads and the end state.
    fn rk4_step(
        &self,
        w: &mut Work,
        h: f64,
        first: Option<(Eval, JointLoads)>,
    ) -> Result<(Eval, JointLoads, CrankState), SimError> {
        let (t, (theta, omega, z)) = (w.t, w.y);
        let stage = |tt: f64, y: CrankState, g: &JointLoads, w: &mut Work| {
            let (at, dz) = self.driven_point(tt, h, y);
            let buffer = w.buffer();
            let (e, l) = self.evaluate(&at, g, buffer)?;
            let k = [y.1, e.alpha, dz];
            Ok::<_, SimError>((e, l, k))
        };
        let (e1, l1, k1) = match first {
            Some((e, l)) => {
                let (_, dz, _) = self.pi_torque(t, omega, z);
                let k = [omega, e.alpha, dz];
                (e, l, k)
            }
            None => {
                let g = w.guess;
                stage(t, w.y, &g, w)?
            }
        };
        let at =
            |k: &[f64; 3], f: f64| (theta + f * h * k[0], omega + f * h * k[1], z + f * h * k[2]);
        let (e2, l2, k2) = stage(t + 0.5 * h, at(&k1, 0.5), &l1, w)?;
        let (e3, l3, k3) = stage(t + 0.5 * h, at(&k2, 0.5), &l2, w)?;
        let (e4, l4, k4) = stage(t + h, at(&k3, 1.0), &l3, w)?;
        let mix = |c: usize| h / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
        let (th1, w1, z1) = (theta + mix(0), omega + mix(1), z + mix(2));
        for (k, a) in w.acc.iter_mut().enumerate() {
            *a += h / 6.0 * (e1.rates[k] + 2.0 * e2.rates[k] + 2.0 * e3.rates[k] + e4.rates[k]);
        }
        let its = [e1.iterations, e2.iterations, e3.iterations, e4.iterations];
        w.max_it = its.into_iter().fold(w.max_it, u32::max);
        w.pool.extend([e1.rates, e2.rates, e3.rates, e4.rates]);
        // The state at the step end, for output, commit and the next step's first stage.
        let buffer = w.buffer();
        let (end, lend) = self.step_eval(t + h, h, (th1, w1, z1), &l4, buffer)?;
        w.guess = lend;
        w.max_it = w.max_it.max(end.iterations);
        Ok((end, lend, (th1, w1, z1)))
    }
}

/// The PI drive `drive` at crank speed `omega` against the reference speed `reference`, with
/// controller integral `z`: the torque on the crank (through the belt), the integral's rate
/// and the margin to the torque limit (negative while saturated). A prescribed crank has no
/// drive torque of its own (0, 0, infinite margin).
#[inline]
pub(super) fn pi_drive(drive: &Drive, reference: f64, omega: f64, z: f64) -> (f64, f64, f64) {
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
            let motor = raw.clamp(-torque_limit_nm, torque_limit_nm);
            let margin = torque_limit_nm - raw.abs();
            // Conditional integration: stop integrating while saturated in the direction
            // the error pushes, so the integral cannot wind up.
            let dz = if margin < 0.0 && raw.signum() == e.signum() {
                0.0
            } else {
                e
            };
            (motor * belt_ratio, dz, margin)
        }
        Drive::Prescribed => (0.0, 0.0, f64::INFINITY),
    }
}
