//! The steady state: each plateau speed computed directly, the crank turning at exactly that
//! speed, every quantity integrated over one cycle (a revolution, two for a 4-stroke
//! pressure) with the periodic trapezoid rule.

use super::error::SimError;
use super::evaluate::{Point, Work};
use super::plateau::Measured;
use super::rates::{RateLayout, RegimeTimes};
use super::results::{DriveKind, EnergyBalance, RunResult};
use super::types::Control;
use super::Simulation;

/// Cycles of the plateau's length (a revolution, two for a 4-stroke pressure) over which the
/// steady state spins the crank up from rest where its stateful laws need it.
const SPIN_UP_CYCLES: f64 = 4.0;

impl Simulation {
    /// Steady state at every plateau speed, computed directly: the crank turns at exactly the
    /// plateau speed and each quantity is integrated over one cycle, a revolution or two for
    /// a 4-stroke cycle (periodic trapezoid rule at the run's crank-angle step). Stateless
    /// laws need one cycle; with stateful laws cycles are repeated until the cycle's mean
    /// torque repeats to 1e-9 (at most 200). Every law's state starts from zero at every
    /// plateau; where stateful laws find no consistent load in that start (LuGre's bristles
    /// at zero deflection under the full sliding speed), the crank is first spun up from rest
    /// (`Simulation::spin_up`) and the cycles measured from there.
    pub fn run_steady(&mut self) -> Result<RunResult, SimError> {
        if let Some(tor) = self.drivetrain.take() {
            let result = self.run_steady_drivetrain(&tor);
            self.drivetrain = Some(tor);
            return result;
        }
        let n_plateaus = self.cycle.plateaus().len();
        let mut results = Vec::with_capacity(n_plateaus);
        let (mut motor, mut dissipated, mut gas) = (0.0, 0.0, 0.0);
        let mut w = self.work()?;
        let mut steps = 0_u64;
        let mut unsettled = Vec::new();
        let layout = self.layout();
        for pi in 0..n_plateaus {
            let omega = self.cycle.plateaus()[pi].omega;
            w.states.reset();
            let before = steps;
            let SteadyCycle {
                delta,
                regime_time,
                t,
                unsettled: change,
            } = match self.steady_plateau(pi, omega, (0.0, 0.0), &mut w, &mut steps) {
                Err(_) if self.stateful => {
                    steps = before;
                    w.states.reset();
                    let start = self.spin_up(pi, omega, &mut w, &mut steps)?;
                    self.steady_plateau(pi, omega, start, &mut w, &mut steps)?
                }
                other => other?,
            };
            if let Some(change) = change {
                unsettled.push(super::crank_angle::unsettled_warning(
                    self.cycle.plateaus()[pi].speed_rpm,
                    change,
                ));
            }
            motor += delta[RateLayout::MOTOR];
            dissipated += delta[layout.powers()].iter().sum::<f64>();
            gas += delta[layout.gas()];
            let cycle = self.cycle_angle();
            let measured = Measured {
                delta,
                regime_time,
                dt: cycle / omega,
                dtheta: cycle,
                window_s: [t - cycle / omega, t],
                revs: self.revolutions_per_cycle(),
            };
            results.push(self.plateau_result(pi, &measured));
        }
        // Over a periodic cycle the mechanical energy returns to its start value, so the
        // balance is motor work = dissipation + gas work.
        let inertial: f64 = self
            .cycle
            .plateaus()
            .iter()
            .map(|p| {
                self.crank
                    .mechanical_energy(std::f64::consts::FRAC_PI_2, p.omega)
                    .abs()
            })
            .sum();
        let energy =
            EnergyBalance::from_terms_with_gas(motor, 0.0, dissipated, gas).relative_to(inertial);
        Ok(self.steady_result(results, energy, (steps, w.max_it), unsettled))
    }

    /// A steady run's result from its plateaus, energy balance, step count and largest
    /// friction iteration count, and the run's own warnings.
    pub(super) fn steady_result(
        &self,
        plateaus: Vec<super::results::PlateauResult>,
        energy: EnergyBalance,
        (steps, max_it): (u64, u32),
        warnings: Vec<String>,
    ) -> RunResult {
        let warnings = [self.steady_settings_warnings(), warnings].concat();
        self.run_result(
            DriveKind::Steady,
            (plateaus, energy),
            ([steps, 0, 0], max_it),
            warnings,
        )
    }

    /// A run's result from its plateaus and energy balance, its step counts (taken, rejected,
    /// replayed) and most friction iterations, and its warnings (the rig's notes added).
    pub(super) fn run_result(
        &self,
        drive: DriveKind,
        (plateaus, energy): (Vec<super::results::PlateauResult>, EnergyBalance),
        ([steps, rejected, replayed], max_it): ([u64; 3], u32),
        warnings: Vec<String>,
    ) -> RunResult {
        RunResult {
            rig: self.rig_name.clone(),
            drive,
            plateaus,
            fmep: self.fmep(),
            energy_residual_j: energy.residual_j,
            energy,
            steps,
            rejected_steps: rejected,
            replayed_steps: replayed,
            max_friction_iterations: max_it,
            warnings: self.result_warnings(warnings),
            law_time: super::bind::law_time(&self.joints),
        }
    }

    /// The result's drive: the rig's, for a run over the test cycle.
    pub(super) fn cycle_drive(&self) -> DriveKind {
        match self.drive {
            crate::model::Drive::Prescribed {} => DriveKind::Prescribed,
            crate::model::Drive::Pi { .. } => DriveKind::Pi,
        }
    }

    /// Plateau `pi` at speed `omega` from time `start.0` and crank angle `start.1`: its last
    /// cycle ([`SteadyCycle`]).
    fn steady_plateau(
        &self,
        pi: usize,
        omega: f64,
        start: (f64, f64),
        w: &mut Work,
        steps: &mut u64,
    ) -> Result<SteadyCycle, SimError> {
        let (t0, theta0) = start;
        let oil = (self.temps[pi], self.viscosities[pi]);
        let cycle = self.cycle_angle();
        let m = ((cycle / self.step_rad).ceil() as usize).max(16);
        let h = cycle / omega / m as f64;
        let mut guess = vec![0.0; self.joints.len()];
        let mut last_torque = f64::NAN;
        let mut delta = vec![0.0; self.layout().len()];
        let mut regime_time = vec![0.0; self.regime_times().len()];
        let max_cycles = if self.stateful {
            super::crank_angle::MAX_SETTLING_CYCLES
        } else {
            1
        };
        let mut t = t0;
        let mut e = w.eval();
        let mut unsettled = None;
        for _ in 0..max_cycles {
            delta.iter_mut().for_each(|x| *x = 0.0);
            regime_time.fill(0.0);
            // Over one whole cycle the integrand is periodic: the trapezoid rule on equally
            // spaced samples converges spectrally for smooth laws (and like Simpson's for
            // kinked ones) with one evaluation per step instead of two.
            for _ in 0..m {
                let at = Point::steady(t + h, h, theta0 + omega * (t + h - t0), omega, oil);
                self.evaluate(&at, &guess, w, &mut e)?;
                for (d, r) in delta.iter_mut().zip(&e.rates) {
                    *d += h * r;
                }
                RegimeTimes::add(&mut regime_time, &e.regimes, h);
                t += h;
                self.commit(w, &e)?;
                guess.copy_from_slice(&e.totals);
                *steps += 1;
            }
            let torque = delta[RateLayout::MOTOR] / cycle;
            if !self.stateful || super::crank_angle::cycle_repeats(torque, last_torque) {
                unsettled = None;
                break;
            }
            unsettled = Some((torque - last_torque) / torque.abs().max(1e-12));
            last_torque = torque;
        }
        w.recycle(e);
        Ok(SteadyCycle {
            delta,
            regime_time,
            t,
            unsettled,
        })
    }

    /// Spin the crank up from rest to plateau `pi`'s speed `omega` at a constant acceleration
    /// over [`SPIN_UP_CYCLES`] cycles, every step committed, as a transient run brings the
    /// stateful laws to speed. Returns the time and crank angle at its end.
    fn spin_up(
        &self,
        pi: usize,
        omega: f64,
        w: &mut Work,
        steps: &mut u64,
    ) -> Result<(f64, f64), SimError> {
        let oil = (self.temps[pi], self.viscosities[pi]);
        let angle = SPIN_UP_CYCLES * self.cycle_angle();
        let alpha = omega * omega / (2.0 * angle);
        let duration = omega / alpha;
        // At most the run's crank-angle step at the end, where the crank is fastest.
        let m = ((2.0 * angle / self.step_rad).ceil() as usize).max(16);
        let h = duration / m as f64;
        let mut guess = vec![0.0; self.joints.len()];
        let mut e = w.eval();
        for k in 1..=m {
            let t = h * k as f64;
            let at = Point {
                t,
                dt: h,
                theta: 0.5 * alpha * t * t,
                omega: alpha * t,
                control: Control::Acceleration(alpha),
                margin: f64::INFINITY,
                oil,
            };
            self.evaluate(&at, &guess, w, &mut e)?;
            self.commit(w, &e)?;
            guess.copy_from_slice(&e.totals);
            *steps += 1;
        }
        w.recycle(e);
        Ok((duration, angle))
    }
}

/// A plateau's last steady cycle: the accumulated quantities and the laws' regime times over
/// it, the time at its end (s, from the plateau's start), and, when stateful laws never
/// repeated a cycle, the last cycle's relative change of the mean motoring torque.
struct SteadyCycle {
    delta: Vec<f64>,
    regime_time: Vec<f64>,
    t: f64,
    unsettled: Option<f64>,
}
