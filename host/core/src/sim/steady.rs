//! The steady state: each plateau speed computed directly, the crank turning at exactly that
//! speed, every quantity integrated over whole revolutions with the periodic trapezoid rule.

use super::bind::reset_states;
use super::error::SimError;
use super::evaluate::Point;
use super::results::{DriveKind, EnergyBalance, RunResult};
use super::stepper::Work;
use super::Simulation;
use crate::mechanics::JointLoads;

impl Simulation {
    /// Steady state at every plateau speed, computed directly: the crank turns at exactly the
    /// plateau speed and each quantity is integrated over one cycle, a revolution or two for
    /// a 4-stroke cycle (periodic trapezoid rule at the run's crank-angle step). Stateless laws need one revolution; with stateful
    /// laws revolutions are repeated until the revolution's mean torque repeats to 1e-9 (at
    /// most 200). Every law's state starts from zero at every plateau.
    pub fn run_steady(&mut self) -> Result<RunResult, SimError> {
        let n_plateaus = self.cycle.plateaus().len();
        let mut results = Vec::with_capacity(n_plateaus);
        let (mut motor, mut dissipated, mut gas) = (0.0, 0.0, 0.0);
        let mut w = Work::new(self.layout().len());
        let mut steps = 0_u64;
        for pi in 0..n_plateaus {
            let omega = self.cycle.plateaus()[pi].omega;
            reset_states(&mut self.joints);
            let (delta, t) = self.steady_plateau(pi, omega, &mut w, &mut steps)?;
            motor += delta[0];
            dissipated += delta[self.layout().powers()].iter().sum::<f64>();
            gas += delta[self.layout().gas()];
            let cycle = self.cycle_angle();
            let window = [t - cycle / omega, t];
            let revs = self.revolutions_per_cycle();
            let measured = super::plateau::Measured {
                delta,
                dt: cycle / omega,
                dtheta: cycle,
                window_s: window,
                revs,
            };
            results.push(self.plateau_result(pi, &measured));
        }
        // Over a periodic revolution the mechanical energy returns to its start value, so the
        // balance is motor work = dissipation + gas work.
        let inertial: f64 = self
            .cycle
            .plateaus()
            .iter()
            .map(|p| {
                self.mechanical_energy(std::f64::consts::FRAC_PI_2, p.omega)
                    .abs()
            })
            .sum();
        let energy =
            EnergyBalance::from_terms_with_gas(motor, 0.0, dissipated, gas).relative_to(inertial);
        Ok(RunResult {
            rig: self.rig_name.clone(),
            drive: DriveKind::Steady,
            plateaus: results,
            fmep: self.fmep(),
            energy_residual_j: energy.residual_j,
            energy,
            steps,
            rejected_steps: 0,
            max_friction_iterations: w.max_it,
            warnings: Vec::new(),
            law_time: super::bind::law_time(&self.joints),
        })
    }

    /// Plateau `pi` at speed `omega`: the accumulated quantities over its last revolution, and
    /// the time at its end (from 0 at the plateau's start).
    fn steady_plateau(
        &mut self,
        pi: usize,
        omega: f64,
        w: &mut Work,
        steps: &mut u64,
    ) -> Result<(Vec<f64>, f64), SimError> {
        let oil = (self.temps[pi], self.viscosities[pi]);
        // One cycle: a revolution, or two for a 4-stroke cycle.
        let cycle = self.cycle_angle();
        let m = ((cycle / self.step_rad).ceil() as usize).max(16);
        let h = cycle / omega / m as f64;
        w.guess = JointLoads::default();
        let mut last_torque = f64::NAN;
        let mut delta = vec![0.0; self.layout().len()];
        let max_revs = if self.stateful { 200 } else { 1 };
        let mut t = 0.0;
        for _ in 0..max_revs {
            delta.iter_mut().for_each(|x| *x = 0.0);
            // Over one whole revolution the integrand is periodic: the trapezoid rule on
            // equally spaced samples converges spectrally for smooth laws (and like Simpson's
            // for kinked ones) with one evaluation per step instead of two.
            for _ in 0..m {
                let at = Point::steady(t + h, h, omega * (t + h), omega, oil);
                let buffer = w.buffer();
                let (e1, l1) = self.evaluate(&at, &w.guess, buffer)?;
                for (d, r) in delta.iter_mut().zip(&e1.rates) {
                    *d += h * r;
                }
                w.max_it = w.max_it.max(e1.iterations);
                t += h;
                self.commit(t, h, omega * t, &e1, oil)?;
                w.pool.push(e1.rates);
                w.guess = l1;
                *steps += 1;
            }
            let torque = delta[0] / cycle;
            if !self.stateful || (torque - last_torque).abs() <= 1e-9 * torque.abs().max(1e-12) {
                break;
            }
            last_torque = torque;
        }
        Ok((delta, t))
    }
}
