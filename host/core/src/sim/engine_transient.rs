//! An engine's transient run (issue 18): the whole test cycle, ramps included, with the crank
//! prescribed (Simpson's rule on the exact reference motion, as the single-cylinder rig) or
//! turned by the PI drive (classical RK4 at fixed steps of `solver.step_deg`), each plateau
//! measured over its last whole cycles by the single-cylinder rig's windows
//! (`plateau::Plateaus`), every accepted step handed to a [`StepObserver`].
//!
//! What the single-cylinder rig has and an engine does not (yet): the error-controlled
//! Dormand-Prince integrator with its switch handling (a PI-driven engine steps at fixed crank
//! angle, the single-cylinder rig's RK4 path) and the phase-2 Newton iteration.

use std::f64::consts::TAU;

use super::engine_run::{EngineSimulation, Work};
use super::error::SimError;
use super::evaluate::{Control, Point};
use super::plateau::{Plateaus, WindowSpec};
use super::results::{DriveKind, EnergyBalance, RunResult};
use super::stepper::{pi_drive, CrankState};
use crate::model::Drive;
use crate::observe::{NoObserver, Position, StepObserver, StepSample};

/// One evaluation kept while a step uses it: the rates, crank acceleration and drive torque
/// it settled on, the PI controller's integral rate and margin there, and the step the laws
/// were told.
struct Stage {
    rates: Vec<f64>,
    alpha: f64,
    torque: f64,
    dz: f64,
    margin: f64,
    dt: f64,
}

/// The run's buffers: the evaluation scratch, recycled rate vectors and the accumulated
/// quantities.
struct Run {
    w: Work,
    pool: Vec<Vec<f64>>,
    acc: Vec<f64>,
}

impl EngineSimulation {
    /// Report progress (permille of the simulated cycle) to `p`.
    pub fn report_progress(&mut self, p: Position) {
        self.progress = Some(p);
    }

    /// What the plateau windows need of this engine's run.
    pub(super) fn window_spec(&self) -> WindowSpec {
        WindowSpec {
            window_s: self.window_s,
            revs_per_cycle: if self.four_stroke { 2 } else { 1 },
            step_rad: self.step_rad,
            max_step_s: self.max_step_s,
        }
    }

    /// Run the whole test cycle without per-step output.
    pub fn run(&mut self) -> Result<RunResult, SimError> {
        self.run_with(&mut NoObserver)
    }

    /// Run the whole test cycle, handing every accepted step to `observer` (the joints'
    /// normal loads in [`EngineSimulation::joint_names`] order). Every law's state starts from
    /// zero, so a simulation run twice gives the same result.
    pub fn run_with(&mut self, observer: &mut dyn StepObserver) -> Result<RunResult, SimError> {
        let names = self.joint_names();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        observer.start(&refs).map_err(SimError::Observer)?;
        self.reset_states();
        let spec = self.window_spec();
        let n = self.layout().len();
        let prescribed = matches!(self.drive, Drive::Prescribed);
        let mut plateaus = Plateaus::new(self.cycle.plateaus(), spec, n);
        let mut run = Run {
            w: Work::new(self),
            pool: Vec::new(),
            acc: vec![0.0; n],
        };
        let e0 = self.train.mechanical_energy(0.0, 0.0);
        let (mut t, mut y): (f64, CrankState) = (0.0, (0.0, 0.0, 0.0));
        let mut start = self.stage(t, 0.0, y, self.reference_alpha(t), &mut run)?;
        let (mut filtered, mut steps) = (0.0, 0_u64);
        let duration = self.cycle.duration();
        for b in super::grid(&self.cycle, &spec, &self.drive) {
            let w_max = self
                .cycle
                .reference(b)
                .1
                .max(self.cycle.reference(t).1)
                .max(y.1);
            let m = ((b - t) / spec.time_step(spec.step_rad, w_max))
                .ceil()
                .max(1.0) as u64;
            let dt = (b - t) / m as f64;
            if prescribed {
                // The reference acceleration may jump at t: this interval starts from its own
                // side of the jump, so Simpson's rule never straddles it.
                let (theta, omega, alpha) = self.cycle.reference_after(t);
                let fresh = self.stage(t, dt, (theta, omega, 0.0), Some(alpha), &mut run)?;
                run.pool.push(std::mem::replace(&mut start, fresh).rates);
            }
            for i in 1..=m {
                let t1 = if i == m { b } else { t + dt };
                let h = t1 - t;
                // A stateful law's state moved at the last commit, and the laws are told the
                // step: the first stage is evaluated again unless it is still exact.
                if !prescribed && (self.stateful || start.dt != h) {
                    let fresh = self.stage(t, h, y, None, &mut run)?;
                    run.pool.push(std::mem::replace(&mut start, fresh).rates);
                }
                let (end, y1) = if prescribed {
                    self.simpson_step(t, t1, &start, &mut run)?
                } else {
                    self.rk4_step(t, h, y, &start, &mut run)?
                };
                // The scratch holds the end evaluation's law inputs: the commit point.
                if self.stateful {
                    self.commit(&run.w)?;
                }
                steps += 1;
                if steps % 4096 == 0 {
                    let permille = (1000.0 * t1 / duration) as u64;
                    if let Some(p) = &self.progress {
                        p.set(permille);
                    }
                    observer.progress(permille);
                }
                // Low-pass filter of the motoring torque (first order, exact discretisation).
                let a = (-TAU * self.lowpass_hz * h).exp();
                filtered = a * filtered + (1.0 - a) * end.torque;
                let sample = StepSample {
                    time_s: t1,
                    crank_angle_rad: y1.0,
                    speed_rad_s: y1.1,
                    motoring_torque_nm: end.torque,
                    filtered_torque_nm: filtered,
                    normal_loads_n: &run.w.normals,
                };
                observer.step(&sample).map_err(SimError::Observer)?;
                plateaus.record(t1, h, (y1.0, y1.1), end.margin < 0.0, &run.acc, &end.rates);
                run.pool.push(std::mem::replace(&mut start, end).rates);
                (t, y) = (t1, y1);
            }
        }
        let change = self.train.mechanical_energy(y.0, y.1) - e0;
        let layout = self.layout();
        let dissipated: f64 = run.acc[layout.powers()].iter().sum();
        let energy = EnergyBalance::from_terms_with_gas(
            run.acc[super::rates::RateLayout::MOTOR],
            change,
            dissipated,
            run.acc[layout.gas()],
        )
        .relative_to(e0.abs().max((e0 + change).abs()));
        let (results, warnings) =
            plateaus.results(|pi, m| self.plateau_result(pi, m.dtheta / m.dt, m))?;
        Ok(RunResult {
            rig: self.rig_name.clone(),
            drive: if prescribed {
                DriveKind::Prescribed
            } else {
                DriveKind::Pi
            },
            plateaus: results,
            fmep: self.fmep(),
            energy_residual_j: energy.residual_j,
            energy,
            steps,
            rejected_steps: 0,
            max_friction_iterations: run.w.max_it,
            warnings,
            law_time: self.law_time(),
        })
    }

    /// The reference crank acceleration at `t` when the crank is prescribed (none under the
    /// PI drive, whose torque sets it).
    fn reference_alpha(&self, t: f64) -> Option<f64> {
        match self.drive {
            Drive::Prescribed => Some(self.cycle.reference(t).2),
            Drive::Pi { .. } => None,
        }
    }

    /// The engine evaluated at `t` in crank state `y`, the laws told step `dt`: with the
    /// crank acceleration `alpha` when prescribed, else with the PI drive's torque.
    fn stage(
        &self,
        t: f64,
        dt: f64,
        y: CrankState,
        alpha: Option<f64>,
        run: &mut Run,
    ) -> Result<Stage, SimError> {
        let (control, dz, margin) = match alpha {
            Some(alpha) => (Control::Acceleration(alpha), 0.0, f64::INFINITY),
            None => {
                let (torque, dz, margin) =
                    pi_drive(&self.drive, self.cycle.reference(t).1, y.1, y.2);
                (Control::Torque(torque), dz, margin)
            }
        };
        let at = Point {
            t,
            dt,
            theta: y.0,
            omega: y.1,
            control,
            margin,
            oil: super::oil_at(&self.cycle, &self.temps, &self.viscosities, t),
        };
        run.w.rates = run.pool.pop().unwrap_or_default();
        self.evaluate(&at, &mut run.w)?;
        Ok(Stage {
            rates: std::mem::take(&mut run.w.rates),
            alpha: run.w.alpha,
            torque: run.w.re.drive_torque_nm,
            dz,
            margin,
            dt,
        })
    }

    /// One step of the prescribed crank from `t` to `t1`: the midpoint and the end of the
    /// exact reference motion, every rate integrated by Simpson's rule from `start`.
    fn simpson_step(
        &self,
        t: f64,
        t1: f64,
        start: &Stage,
        run: &mut Run,
    ) -> Result<(Stage, CrankState), SimError> {
        let h = t1 - t;
        let (theta_m, omega_m, alpha_m) = self.cycle.reference(t + 0.5 * h);
        let mid = self.stage(t + 0.5 * h, h, (theta_m, omega_m, 0.0), Some(alpha_m), run)?;
        let (theta1, omega1, alpha1) = self.cycle.reference(t1);
        let end = self.stage(t1, h, (theta1, omega1, 0.0), Some(alpha1), run)?;
        for (k, a) in run.acc.iter_mut().enumerate() {
            *a += h / 6.0 * (start.rates[k] + 4.0 * mid.rates[k] + end.rates[k]);
        }
        run.pool.push(mid.rates);
        Ok((end, (theta1, omega1, 0.0)))
    }

    /// One classical RK4 step of length `h` of the PI-driven crank (angle, speed, controller
    /// integral) from state `y` at `t`, `start` its first stage; every rate accumulated by the
    /// same weights. Returns the evaluation at the end state (the next step's first stage).
    fn rk4_step(
        &self,
        t: f64,
        h: f64,
        y: CrankState,
        start: &Stage,
        run: &mut Run,
    ) -> Result<(Stage, CrankState), SimError> {
        let slope = |s: &Stage, y: CrankState| [y.1, s.alpha, s.dz];
        let ahead =
            |k: [f64; 3], f: f64| (y.0 + f * h * k[0], y.1 + f * h * k[1], y.2 + f * h * k[2]);
        let k1 = slope(start, y);
        let y2 = ahead(k1, 0.5);
        let s2 = self.stage(t + 0.5 * h, h, y2, None, run)?;
        let k2 = slope(&s2, y2);
        let y3 = ahead(k2, 0.5);
        let s3 = self.stage(t + 0.5 * h, h, y3, None, run)?;
        let k3 = slope(&s3, y3);
        let y4 = ahead(k3, 1.0);
        let s4 = self.stage(t + h, h, y4, None, run)?;
        let k4 = slope(&s4, y4);
        let mix = |c: usize| h / 6.0 * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
        let y1 = (y.0 + mix(0), y.1 + mix(1), y.2 + mix(2));
        for (k, a) in run.acc.iter_mut().enumerate() {
            *a += h / 6.0 * (start.rates[k] + 2.0 * s2.rates[k] + 2.0 * s3.rates[k] + s4.rates[k]);
        }
        run.pool.extend([s2.rates, s3.rates, s4.rates]);
        // The end state, for output, commit and the next step's first stage.
        let end = self.stage(t + h, h, y1, None, run)?;
        Ok((end, y1))
    }
}
