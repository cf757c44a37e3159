//! The test cycle with the rig's drivetrain: the chain's nodes and the crank integrated
//! together from rest through the whole cycle, ramps included (classical RK4 in whole steps
//! per interval of the cycle's grid, the motor following the cycle's reference or held by the
//! PI controller). Each plateau is measured over its hold's last whole cycles as the rigid run
//! measures it ([`Plateaus`]); the transducer's shaft torque is filtered through the
//! transducer's and the acquisition's low-passes as it goes and sampled at the acquisition's
//! rate inside the same window ([`Signal`]): the bench's own record, transients included.

use std::f64::consts::TAU;

use super::error::SimError;
use super::plateau::{Plateaus, WindowSpec};
use super::results::{EnergyBalance, Instrument, PlateauResult, RunResult};
use super::stepper::Integration;
use super::torsional::{instrument_of, record, Motor, Span, Stages, Torsion};
use super::Simulation;
use crate::observe::{StepObserver, StepSample};

/// The largest RK4 step as a share of its stability limit on the imaginary axis
/// (`|h w| <= 2.83`) at the chain's stiffest mode: the chain's modes are lightly damped, so
/// its eigenvalues sit near that axis.
const STABILITY_SHARE: f64 = 0.7;

/// The transducer's signal near the end of each hold: time, the shaft torque (N m, in the
/// transducer), the torque through both low-passes, the crank's speed and the energy the
/// chain's dampers have dissipated (J), at every step's start within the hold's measurement
/// margin.
struct Signal {
    /// Per plateau: the span it records, s, and its samples.
    holds: Vec<([f64; 2], Vec<[f64; 5]>)>,
    /// The two first-order low-passes' cut-offs, Hz: the transducer's, the acquisition's.
    cutoffs: [f64; 2],
    /// Their outputs now, N m.
    filtered: [f64; 2],
}

impl Signal {
    fn new(sim: &Simulation, spec: &WindowSpec, tor: &Torsion) -> Self {
        let holds = sim
            .cycle
            .plateaus()
            .iter()
            .map(|p| {
                let w = p.omega.max(1e-9);
                let margin = spec.window_s + (spec.cycle_angle() + TAU) / w;
                // Sized before the run, as the windows' records are: no allocation while stepping.
                let steps = (margin / spec.time_step(spec.step_rad, w)).ceil() as usize + 16;
                ([p.t_end - margin, p.t_end], Vec::with_capacity(steps))
            })
            .collect();
        Signal {
            holds,
            // Without a transducer the signal is the drive shaft's torque as it is.
            cutoffs: tor
                .chain
                .instrument
                .as_ref()
                .map_or([f64::INFINITY; 2], |(r, d)| [r.cutoff_hz, d.lowpass_hz]),
            filtered: [0.0; 2],
        }
    }

    /// The sample at `t` of the shaft torque `torque` held over the step of `h` before it
    /// (first-order low-passes, exact for a signal held over the step), and the crank speed.
    fn push(&mut self, t: f64, h: f64, [torque, speed, dissipated]: [f64; 3]) {
        let mut input = torque;
        for (f, fc) in self.filtered.iter_mut().zip(self.cutoffs) {
            let a = (-TAU * fc * h).exp();
            *f = a * *f + (1.0 - a) * input;
            input = *f;
        }
        for (span, samples) in &mut self.holds {
            if t >= span[0] && t <= span[1] + 1e-12 {
                samples.push([t, torque, self.filtered[1], speed, dissipated]);
            }
        }
    }

    /// The instrument's figures over the window `[t0, t1]` (s) of plateau `pi`.
    fn instrument(&self, pi: usize, [t0, t1]: [f64; 2], tor: &Torsion) -> Option<Instrument> {
        let (rating, daq) = tor.chain.instrument.as_ref()?;
        let inside = || {
            self.holds[pi]
                .1
                .iter()
                .filter(move |s| s[0] >= t0 - 1e-12 && s[0] < t1 - 1e-12)
        };
        let spans = (
            Span::of(inside().map(|s| s[1])),
            Span::of(inside().map(|s| s[3])),
        );
        let count = (((t1 - t0) * daq.sample_rate_hz).floor() as usize).max(1);
        let acquired = record(
            (0..count).map(|k| self.at(pi, t0 + k as f64 / daq.sample_rate_hz, 2)),
            daq.range_nm,
        );
        let dissipated = self.at(pi, t1, 4) - self.at(pi, t0, 4);
        let chain_w = dissipated / (t1 - t0).max(1e-300);
        Some(instrument_of(rating, spans, acquired, chain_w, 0))
    }

    /// Field `k` of plateau `pi`'s samples at `t`, linear between steps.
    fn at(&self, pi: usize, t: f64, k: usize) -> f64 {
        let samples = &self.holds[pi].1;
        let j = samples.partition_point(|s| s[0] <= t).max(1) - 1;
        match (samples.get(j), samples.get(j + 1)) {
            (Some(a), Some(b)) if b[0] > a[0] => {
                let s = ((t - a[0]) / (b[0] - a[0])).clamp(0.0, 1.0);
                a[k] + s * (b[k] - a[k])
            }
            (Some(a), _) => a[k],
            _ => 0.0,
        }
    }
}

impl Simulation {
    /// The largest step the chain allows an explicit RK4 step, s: the stability limit at its
    /// stiffest mode, with the crank at the least inertia it has over the cycle (the
    /// reciprocating mass at a dead centre), so the limit holds at every crank angle.
    pub(super) fn torsion_step_cap(&self, tor: &Torsion) -> f64 {
        let inertia_at = |theta: f64| {
            2.0 * (self.crank.mechanical_energy(theta, 1.0)
                - self.crank.mechanical_energy(theta, 0.0))
        };
        let least = (0..144)
            .map(|k| inertia_at(self.cycle_angle() * k as f64 / 144.0))
            .fold(f64::INFINITY, f64::min);
        let mut chain = tor.chain.clone();
        let bare = self.crank.throw_inertias();
        if bare.is_empty() {
            if let Some(crank) = chain.inertias.last_mut() {
                if least.is_finite() && least > 0.0 {
                    *crank = crank.min(least);
                }
            }
        } else {
            // An elastic crankshaft's throws: at least their own inertia at any angle.
            for (node, j) in chain.throws.iter().zip(bare) {
                chain.inertias[*node] = chain.inertias[*node].min(*j);
            }
        }
        let stiffest = chain
            .modes(tor.hold)
            .iter()
            .map(|m| m.frequency_hz)
            .fold(0.0, f64::max);
        if stiffest > 0.0 {
            STABILITY_SHARE * 2.83 / (TAU * stiffest)
        } else {
            f64::INFINITY
        }
    }

    /// The whole test cycle with the drivetrain (see the module). The energy balance is the
    /// whole chain's: motor work = the laws' dissipation + the chain's + the gas work + the
    /// change of the chain's and the crank's energy from rest.
    pub(super) fn run_transient_drivetrain(
        &self,
        tor: &Torsion,
        observer: &mut dyn StepObserver,
    ) -> Result<RunResult, SimError> {
        let mut w = self.work()?;
        let n = self.layout().len();
        let spec = self.window_spec();
        let reference = |t: f64| -> Motor {
            let (theta, omega, _) = self.reference(t);
            (theta, omega)
        };
        let y = vec![0.0; tor.len()];
        let mut run = CycleRun {
            s: Integration::new(n, self.regime_times()),
            plateaus: Plateaus::new(self.cycle.plateaus(), spec, (n, self.regime_times())),
            signal: Signal::new(self, &spec, tor),
            st: Stages::new(tor, &mut w, reference(0.0), &y),
            e0: self.torsion_energy(tor, reference(0.0), &y),
            y,
            steps: 0,
            filtered: 0.0,
        };
        let cap = self.torsion_step_cap(tor);
        let (mut t, mut last) = (0.0, None);
        for b in self.grid() {
            if b <= t {
                continue;
            }
            let omega_max = reference(t)
                .1
                .max(reference(b).1)
                .max(run.y[tor.crank_speed()]);
            let dt = self.time_step(self.step_rad, omega_max).min(cap);
            let m = ((b - t) / dt).ceil().max(1.0) as u64;
            let h = (b - t) / m as f64;
            for k in 0..m {
                let at = (t, h, reference(t), self.oil_at(t));
                self.torsion_mark(&mut run, tor, at, last, &mut w, observer)?;
                let sums = (run.s.acc.as_mut_slice(), run.s.regime_time.as_mut_slice());
                let (y, st) = (&mut run.y, &mut run.st);
                self.torsion_step(tor, (t, h, at.3), &reference, y, st, &mut w, sums)?;
                last = Some(h);
                t = if k + 1 == m { b } else { t + h };
                run.steps += 1;
            }
        }
        // The cycle's end: evaluated so the last step is booked.
        let at = (t, 0.0, reference(t), self.oil_at(t));
        self.torsion_mark(&mut run, tor, at, last, &mut w, observer)?;
        run.s.t = t;
        self.torsion_cycle_result(run, tor, w)
    }

    /// The finished run's result: every plateau with its instrument, the energy balance.
    fn torsion_cycle_result(
        &self,
        run: CycleRun,
        tor: &Torsion,
        mut w: super::evaluate::Work,
    ) -> Result<RunResult, SimError> {
        let t = run.s.t;
        let (theta, omega, _) = self.reference(t);
        let (plateaus, warnings) = self.torsion_cycle_plateaus(&run, tor)?;
        let change = self.torsion_energy(tor, (theta, omega), &run.y) - run.e0;
        let CycleRun {
            s,
            y,
            st,
            e0,
            steps,
            ..
        } = run;
        for e in st.into_evals() {
            w.recycle(e);
        }
        let layout = self.layout();
        let dissipated: f64 = s.acc[layout.powers()].iter().sum::<f64>() + y[y.len() - 1];
        let energy = EnergyBalance::from_terms_with_gas(
            y[y.len() - 2],
            change,
            dissipated,
            s.acc[layout.gas()],
        )
        .relative_to(e0.abs().max((e0 + change).abs()));
        Ok(self.run_result(
            self.cycle_drive(),
            (plateaus, energy),
            ([steps, 0, 0], w.max_it),
            warnings,
        ))
    }

    /// The evaluation at the start of a step (`at`), committing the laws there; the step of
    /// `last` (s) that ended there booked; the transducer's signal sampled.
    fn torsion_mark(
        &self,
        run: &mut CycleRun,
        tor: &Torsion,
        at: super::torsional::Stage,
        last: Option<f64>,
        w: &mut super::evaluate::Work,
        observer: &mut dyn StepObserver,
    ) -> Result<(), SimError> {
        let (torque, speed, saturated) = self.torsion_begin(tor, at, &run.y, &mut run.st, w)?;
        if let Some(h) = last {
            self.book_torsion_step(run, tor, (at.0, h, speed, saturated), observer)?;
        }
        let dissipated = run.y[run.y.len() - 1];
        run.signal
            .push(at.0, last.unwrap_or(0.0), [torque, speed, dissipated]);
        Ok(())
    }

    /// Book the step of `h` that ended at `t` (crank `speed` there, the motor's controller at
    /// its limit if `saturated`), now that its end's evaluation (`run.st.first()`) is known:
    /// the windows' records, the filtered torque, the observer, the progress.
    fn book_torsion_step(
        &self,
        run: &mut CycleRun,
        tor: &Torsion,
        (t, h, speed, saturated): (f64, f64, f64, bool),
        observer: &mut dyn StepObserver,
    ) -> Result<(), SimError> {
        let end = run.st.first();
        run.s.record(end);
        let theta = run.y[tor.crank_angle()];
        run.plateaus.record(t, h, (theta, speed), saturated, &run.s);
        let a = (-TAU * self.lowpass_hz * h).exp();
        run.filtered = a * run.filtered + (1.0 - a) * end.drive_torque;
        if observer.reads_samples() {
            let sample = StepSample {
                time_s: t,
                crank_angle_rad: theta,
                speed_rad_s: speed,
                motoring_torque_nm: end.drive_torque,
                filtered_torque_nm: run.filtered,
                normal_loads_n: &end.normals,
            };
            observer.step(&sample).map_err(SimError::Observer)?;
        }
        if run.steps % 4096 == 0 {
            let permille = (1000.0 * t / self.cycle.duration()) as u64;
            if let Some(p) = &self.progress {
                p.set(permille);
            }
            observer.progress(permille);
        }
        Ok(())
    }

    /// Every plateau's result with its instrument's figures over its measurement window, and
    /// the warnings: the windows' own, and where the transducer left its rating.
    fn torsion_cycle_plateaus(
        &self,
        run: &CycleRun,
        tor: &Torsion,
    ) -> Result<(Vec<PlateauResult>, Vec<String>), SimError> {
        let windows = std::cell::RefCell::new(vec![[0.0; 2]; self.cycle.plateaus().len()]);
        let (results, mut warnings) = run.plateaus.results(|pi, m| {
            windows.borrow_mut()[pi] = m.window_s;
            self.plateau_result(pi, m)
        })?;
        let windows = windows.into_inner();
        let mut results = results;
        for (pi, r) in results.iter_mut().enumerate() {
            let instrument = run.signal.instrument(pi, windows[pi], tor);
            warnings.extend(
                instrument
                    .as_ref()
                    .and_then(|i| i.rating_warning(r.set_speed_rpm)),
            );
            r.instrument = instrument;
        }
        Ok((results, warnings))
    }
}

/// A transient run with the drivetrain under way: the accumulated quantities, the windows'
/// records, the transducer's signal, the chain's and crank's state and its RK4 scratch, the
/// energy at the start (J), the steps taken and the filtered motoring torque (N m).
struct CycleRun {
    s: Integration,
    plateaus: Plateaus,
    signal: Signal,
    st: Stages,
    e0: f64,
    y: Vec<f64>,
    steps: u64,
    filtered: f64,
}
