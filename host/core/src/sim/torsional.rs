//! The steady state with the rig's drivetrain (`crate::drivetrain`): at each plateau the
//! chain's nodes and the crank are integrated together (classical RK4 at the run's crank-angle
//! step), the motor held by the drive, from the chain's linear harmonic response to the rigid
//! crank's torque until the cycle repeats; the last cycle is measured as the rigid steady state
//! is, and the transducer's shaft torque as its data acquisition records it ([`Instrument`]).

use nalgebra::Complex;
use std::f64::consts::TAU;

use super::error::SimError;
use super::evaluate::{Eval, Point, Work};
use super::plateau::Measured;
use super::rates::RegimeTimes;
use super::results::{Instrument, PlateauResult};
use super::types::Control;
use super::Simulation;
use crate::drivetrain::{Chain, MotorHold};

/// Most cycles integrated at a plateau before it is reported unsettled.
const MAX_CYCLES: usize = 2000;
/// A cycle repeats when its transducer mean and peak-to-peak change by less than this share
/// of its peak-to-peak plus mean from the cycle before.
const REPEAT_TOL: f64 = 1e-7;

/// The drivetrain as a run holds it: the reflected chain, how the motor is held, and the
/// motor's torque limit (N m at the motor; infinite for a prescribed motor).
#[derive(Debug, Clone)]
pub(super) struct Torsion {
    pub(super) chain: Chain,
    pub(super) hold: MotorHold,
    pub(super) limit_nm: f64,
    /// Per node: the crank throw it is on an elastic crankshaft (empty for a rigid crank,
    /// the chain's last node).
    pub(super) throw_at: Vec<Option<usize>>,
}

/// The motor's reference at crank speed: angle (rad) and speed (rad/s).
pub(super) type Motor = (f64, f64);

/// One evaluation's instant: time and step length (s), the motor's reference, the oil (C,
/// Pa s).
pub(super) type Stage = (f64, f64, Motor, (f64, f64));

/// The chain's state at an instant: node angles and speeds at crank speed (motor first).
pub(super) struct Nodes {
    phi: Vec<f64>,
    w: Vec<f64>,
    /// Each spring's torque at crank speed.
    torques: Vec<f64>,
    /// An elastic crankshaft's throws: each one's twist from the crank node (angle, speed)
    /// and the net torque of the sections on it.
    twist: Vec<(f64, f64)>,
    load: Vec<f64>,
}

impl Torsion {
    /// The drivetrain `chain` held by `hold` (the motor's torque `limit_nm`), its crank rigid
    /// or, if `elastic`, the engine's throws at the chain's throw nodes.
    pub(super) fn new(chain: Chain, hold: MotorHold, limit_nm: f64, elastic: bool) -> Self {
        let mut throw_at = Vec::new();
        if elastic {
            throw_at = vec![None; chain.inertias.len()];
            for (j, node) in chain.throws.iter().enumerate() {
                throw_at[*node] = Some(j);
            }
        }
        Torsion {
            chain,
            hold,
            limit_nm,
            throw_at,
        }
    }

    /// Whether the crankshaft is elastic (its throws nodes of their own).
    fn elastic(&self) -> bool {
        !self.throw_at.is_empty()
    }

    /// The crank's node: the rigid crank, or an elastic crankshaft's first throw (the
    /// reference its twist is measured from).
    fn crank_node(&self) -> usize {
        self.chain.throws.first().copied().unwrap_or(self.n() - 1)
    }

    /// Index of the crank's angle in the integrated state.
    pub(super) fn crank_angle(&self) -> usize {
        self.crank_node() - self.first()
    }

    /// Index of the crank's speed in the integrated state.
    pub(super) fn crank_speed(&self) -> usize {
        self.n() - 2 * self.first() + self.crank_node()
    }

    /// Index of the first integrated node (the motor's angle is imposed when prescribed).
    fn first(&self) -> usize {
        match self.hold {
            MotorHold::Prescribed => 1,
            MotorHold::Pi { .. } => 0,
        }
    }

    fn n(&self) -> usize {
        self.chain.inertias.len()
    }

    /// Length of the integrated state: free angles, free speeds, motor work, chain dissipation.
    pub(super) fn len(&self) -> usize {
        2 * (self.n() - self.first()) + 2
    }

    /// Every node's angle and speed with the motor's reference at `motor` (angle, speed).
    pub(super) fn nodes(&self, motor: Motor, y: &[f64]) -> Nodes {
        let n = self.n();
        let throws = if self.elastic() {
            self.chain.throws.len()
        } else {
            0
        };
        let mut s = Nodes {
            phi: vec![0.0; n],
            w: vec![0.0; n],
            torques: vec![0.0; n - 1],
            twist: vec![(0.0, 0.0); throws],
            load: vec![0.0; throws],
        };
        self.fill(motor, y, &mut s);
        s
    }

    /// [`Torsion::nodes`] into `s`, with each spring's torque there: no allocation per
    /// evaluation.
    fn fill(&self, (theta, omega): Motor, y: &[f64], s: &mut Nodes) {
        let (n, f) = (self.n(), self.first());
        let m = n - f;
        s.phi[..f].fill(theta);
        s.w[..f].fill(omega);
        s.phi[f..].copy_from_slice(&y[..m]);
        s.w[f..].copy_from_slice(&y[m..2 * m]);
        for i in 0..n - 1 {
            s.torques[i] = self.chain.spring_torque(i, &s.phi, &s.w);
        }
        let r = self.crank_node();
        for (j, node) in self.chain.throws.iter().enumerate().take(s.twist.len()) {
            s.twist[j] = (s.phi[*node] - s.phi[r], s.w[*node] - s.w[r]);
            let behind = if *node + 1 < n { s.torques[*node] } else { 0.0 };
            s.load[j] = s.torques[*node - 1] - behind;
        }
    }

    /// The motor's torque at crank speed: the first spring's reaction for a prescribed motor,
    /// the PI controller's (limited at the motor) otherwise.
    /// The second value says whether the controller sat at its limit.
    fn motor_torque(&self, (theta, omega): Motor, s: &Nodes, spring0: f64) -> (f64, bool) {
        match self.hold {
            MotorHold::Prescribed => (spring0, false),
            MotorHold::Pi { kp, ki } => {
                let r = self.chain.ratios[0];
                let raw = r * (kp * (omega - s.w[0]) + ki * (theta - s.phi[0]));
                let held = raw.clamp(-self.limit_nm, self.limit_nm);
                (held * r, held != raw)
            }
        }
    }
}

impl Simulation {
    /// The state derivative at `t` (the crank's acceleration from one evaluation into `e`);
    /// whether the motor's controller sat at its limit there.
    #[allow(clippy::too_many_arguments)]
    fn torsion_rate(
        &self,
        tor: &Torsion,
        (t, h, reference, oil): Stage,
        y: &[f64],
        guess: &[f64],
        (w, s): (&mut Work, &mut Nodes),
        e: &mut Eval,
        dy: &mut [f64],
    ) -> Result<bool, SimError> {
        tor.fill(reference, y, s);
        let (n, f) = (tor.n(), tor.first());
        let torques = &s.torques;
        let (motor, saturated) = tor.motor_torque(reference, s, torques[0]);
        let r = tor.crank_node();
        let control = if tor.elastic() {
            w.crank.set_throws(Some((&s.twist, &s.load)));
            Control::Throws
        } else {
            Control::Torque(torques[n - 2])
        };
        let at = Point {
            t,
            dt: h,
            theta: s.phi[r],
            omega: s.w[r],
            control,
            margin: f64::INFINITY,
            oil,
        };
        self.evaluate(&at, guess, w, e)?;
        let m = n - f;
        let alphas = w.crank.throw_alphas();
        for k in 0..m {
            let node = k + f;
            dy[k] = s.w[node];
            let drive = if node == 0 { motor } else { torques[node - 1] };
            let behind = if node + 1 < n { torques[node] } else { 0.0 };
            // A throw or the rigid crank (the last node) moves as the crank train solved it.
            dy[m + k] = match (tor.throw_at.get(node), node == n - 1) {
                (Some(Some(j)), _) => alphas[*j],
                (None, true) => e.alpha,
                _ => (drive - behind) / tor.chain.inertias[node],
            };
        }
        dy[2 * m] = motor * s.w[0];
        dy[2 * m + 1] = (0..n - 1)
            .map(|i| tor.chain.springs[i].c * (s.w[i] - s.w[i + 1]).powi(2))
            .sum();
        Ok(saturated)
    }

    /// The state at the plateau's start: the chain's linear harmonic response to the rigid
    /// crank's torque (rigid samples `rigid`, uniform over one cycle of `omega`).
    fn torsion_start(&self, tor: &Torsion, omega: f64, rigid: &[f64]) -> Vec<f64> {
        let m = rigid.len();
        let period = self.cycle_angle() / omega;
        let base = TAU / period;
        let mut p = vec![0.0; tor.n()];
        let mut v = vec![0.0; tor.n()];
        let mean: f64 = rigid.iter().sum::<f64>() / m as f64;
        if let Some(x) = tor.chain.harmonic(tor.hold, Complex::new(-mean, 0.0), 0.0) {
            p.iter_mut().zip(&x).for_each(|(a, b)| *a += b.re);
        }
        for k in 1..m.div_ceil(2) {
            let ck = dft(rigid, k);
            let wk = base * k as f64;
            if let Some(x) = tor.chain.harmonic(tor.hold, -ck, wk) {
                for i in 0..tor.n() {
                    p[i] += 2.0 * x[i].re;
                    v[i] += 2.0 * (Complex::new(0.0, wk) * x[i]).re;
                }
            }
        }
        let f = tor.first();
        let mut y = vec![0.0; tor.len()];
        let mf = tor.n() - f;
        for k in 0..mf {
            y[k] = p[k + f];
            y[mf + k] = omega + v[k + f];
        }
        y
    }

    /// One cycle of the rigid crank at `omega`: the drive torque at `m` uniform instants.
    fn rigid_samples(
        &self,
        omega: f64,
        oil: (f64, f64),
        m: usize,
        w: &mut Work,
    ) -> Result<Vec<f64>, SimError> {
        let h = self.cycle_angle() / omega / m as f64;
        w.crank.set_throws(None);
        let mut guess = vec![0.0; self.joints.len()];
        let mut e = w.eval();
        let mut out = Vec::with_capacity(m);
        for j in 0..m {
            let t = h * j as f64;
            self.evaluate(
                &Point::steady(t, h, omega * t, omega, oil),
                &guess,
                w,
                &mut e,
            )?;
            self.commit(w, &e)?;
            guess.copy_from_slice(&e.totals);
            out.push(e.drive_torque);
        }
        w.recycle(e);
        Ok(out)
    }
}

/// Coefficient `k` of the discrete Fourier transform of uniform samples over one period
/// (`x(t) = c0 + sum 2 Re(c_k e^{i k W t})`).
fn dft(x: &[f64], k: usize) -> Complex<f64> {
    let m = x.len() as f64;
    let step = Complex::from_polar(1.0, -TAU * k as f64 / m);
    let mut rot = Complex::new(1.0, 0.0);
    let mut sum = Complex::new(0.0, 0.0);
    for v in x {
        sum += rot * *v;
        rot *= step;
    }
    sum / m
}

/// What one RK4 step leaves: the new state, and the rates and regimes integrated over it.
pub(super) struct Stages {
    evals: [Eval; 4],
    k: [Vec<f64>; 4],
    /// The stage state.
    ys: Vec<f64>,
    /// The chain at the last stage evaluated.
    nodes: Nodes,
}

impl Stages {
    /// Scratch for RK4 steps of the state `y` (its chain with the motor at `motor`).
    pub(super) fn new(tor: &Torsion, w: &mut Work, motor: Motor, y: &[f64]) -> Self {
        let mut st = Stages {
            evals: [w.eval(), w.eval(), w.eval(), w.eval()],
            k: std::array::from_fn(|_| vec![0.0; y.len()]),
            ys: vec![0.0; y.len()],
            nodes: tor.nodes(motor, y),
        };
        // The first evaluation's friction iteration starts from no friction.
        st.evals[3].totals.fill(0.0);
        st
    }

    /// The evaluation at the start of the step under way.
    pub(super) fn first(&self) -> &Eval {
        &self.evals[0]
    }

    /// The evaluations, to hand back to the work's pool.
    pub(super) fn into_evals(self) -> [Eval; 4] {
        self.evals
    }
}

/// One cycle's record: the transducer torque (N m, in the transducer) and the crank speed at
/// each step's start, the rates and regimes integrated over the cycle, the state at its end.
struct CycleRecord {
    torque: Vec<f64>,
    speed: Vec<f64>,
    delta: Vec<f64>,
    regime_time: Vec<f64>,
    chain_energy: [f64; 2],
}

impl Simulation {
    /// One classical RK4 step of `h` from `(t, y)` (`st.k[0]` already holds the rate at the
    /// start, `st.evals[0]` its evaluation); the rates accumulated into `rec`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn torsion_step(
        &self,
        tor: &Torsion,
        (t, h, oil): (f64, f64, (f64, f64)),
        reference: &dyn Fn(f64) -> Motor,
        y: &mut [f64],
        st: &mut Stages,
        w: &mut Work,
        (delta, regime_time): (&mut [f64], &mut [f64]),
    ) -> Result<(), SimError> {
        for (stage, c) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
            for (i, v) in st.ys.iter_mut().enumerate() {
                *v = y[i] + c * h * st.k[stage - 1][i];
            }
            let (done, rest) = st.evals.split_at_mut(stage);
            self.torsion_rate(
                tor,
                (t + c * h, h, reference(t + c * h), oil),
                &st.ys,
                &done[stage - 1].totals,
                (w, &mut st.nodes),
                &mut rest[0],
                &mut st.k[stage],
            )?;
        }
        for (i, v) in y.iter_mut().enumerate() {
            *v += h / 6.0 * (st.k[0][i] + 2.0 * st.k[1][i] + 2.0 * st.k[2][i] + st.k[3][i]);
        }
        for (k, a) in delta.iter_mut().enumerate() {
            let r = |s: usize| st.evals[s].rates[k];
            *a += h / 6.0 * (r(0) + 2.0 * r(1) + 2.0 * r(2) + r(3));
        }
        let regimes: [&[u8]; 4] = [
            &st.evals[0].regimes,
            &st.evals[1].regimes,
            &st.evals[2].regimes,
            &st.evals[3].regimes,
        ];
        RegimeTimes::add_rule(regime_time, regimes, [1.0, 2.0, 2.0, 1.0], h / 6.0);
        Ok(())
    }

    /// The rate at the start of a step into `st.k[0]`/`st.evals[0]`, the laws committed
    /// there; the transducer's torque (N m, in the transducer), the crank's speed there and
    /// whether the motor's controller sat at its limit.
    pub(super) fn torsion_begin(
        &self,
        tor: &Torsion,
        at: Stage,
        y: &[f64],
        st: &mut Stages,
        w: &mut Work,
    ) -> Result<(f64, f64, bool), SimError> {
        let (first, last) = st.evals.split_at_mut(3);
        let saturated = self.torsion_rate(
            tor,
            at,
            y,
            &last[0].totals,
            (w, &mut st.nodes),
            &mut first[0],
            &mut st.k[0],
        )?;
        self.commit(w, &st.evals[0])?;
        // The scratch now holds the chain at the step's start.
        let s = &st.nodes;
        let torque = tor
            .chain
            .transducer_torque(s.torques[tor.chain.measured_spring()]);
        Ok((torque, s.w[tor.crank_node()], saturated))
    }

    /// The chain's energy at `(t, y)`: its free nodes' kinetic energy (the crank's mechanical
    /// energy from the crank model) plus the springs' strain energy, J. A prescribed motor's
    /// rotor belongs to the drive: the motor's work is what its shaft passes to the chain.
    pub(super) fn torsion_energy(&self, tor: &Torsion, motor: Motor, y: &[f64]) -> f64 {
        let s = tor.nodes(motor, y);
        let (n, r) = (tor.n(), tor.crank_node());
        let crank = |i: usize| match tor.throw_at.get(i) {
            Some(j) => j.is_some(),
            None => i == n - 1,
        };
        let kinetic: f64 = (tor.first()..n)
            .filter(|i| !crank(*i))
            .map(|i| 0.5 * tor.chain.inertias[i] * s.w[i] * s.w[i])
            .sum();
        kinetic
            + tor.chain.strain_energy(&s.phi)
            + self.crank.twisted_energy(s.phi[r], s.w[r], &s.twist)
    }

    /// Integrate cycle after cycle at plateau `pi` until the transducer's cycle repeats; the
    /// last cycle's record, the number of cycles and, if it never repeated, its last change.
    fn torsion_cycles(
        &self,
        tor: &Torsion,
        pi: usize,
        w: &mut Work,
        steps: &mut u64,
    ) -> Result<(CycleRecord, usize, Option<f64>, [f64; 2]), SimError> {
        let omega = self.cycle.plateaus()[pi].omega;
        let oil = (self.temps[pi], self.viscosities[pi]);
        let period = self.cycle_angle() / omega;
        // The crank-angle step, and no longer than the chain's stiffest mode lets RK4 go.
        let m = ((self.cycle_angle() / self.step_rad).ceil() as usize)
            .max((period / self.torsion_step_cap(tor)).ceil() as usize)
            .max(16);
        let h = period / m as f64;
        let rigid = self.rigid_samples(omega, oil, m, w)?;
        let mut y = self.torsion_start(tor, omega, &rigid);
        let mut st = Stages::new(tor, w, (0.0, omega), &y);
        let shoot = Shooting::new(tor, self.cycle_angle() / omega);
        let (mut last, mut t) = ((f64::NAN, f64::NAN), 0.0);
        for cycle in 1..=MAX_CYCLES {
            let y0 = y.clone();
            let mut rec = self.empty_record(m);
            rec.chain_energy[0] = self.torsion_energy(tor, (omega * t, omega), &y);
            let works = [y[y.len() - 2], y[y.len() - 1]];
            let reference = |t: f64| (omega * t, omega);
            for _ in 0..m {
                let at = (t, h, reference(t), oil);
                let (torque, speed, _) = self.torsion_begin(tor, at, &y, &mut st, w)?;
                rec.torque.push(torque);
                rec.speed.push(speed);
                let sums = (rec.delta.as_mut_slice(), rec.regime_time.as_mut_slice());
                self.torsion_step(tor, (t, h, oil), &reference, &mut y, &mut st, w, sums)?;
                t += h;
                *steps += 1;
            }
            rec.chain_energy[1] = self.torsion_energy(tor, (omega * t, omega), &y);
            let work = [y[y.len() - 2] - works[0], y[y.len() - 1] - works[1]];
            let (mean, pp) = stats(&rec.torque);
            let change =
                ((mean - last.0).abs().max((pp - last.1).abs())) / (pp + mean.abs()).max(1e-12);
            last = (mean, pp);
            if change > REPEAT_TOL && cycle < MAX_CYCLES {
                shoot.correct(&y0, &mut y, omega * self.cycle_angle() / omega);
            }
            if change <= REPEAT_TOL || cycle == MAX_CYCLES {
                for e in st.evals {
                    w.recycle(e);
                }
                let unsettled = (change > REPEAT_TOL).then_some(change);
                return Ok((rec, cycle, unsettled, work));
            }
        }
        unreachable!("the loop returns at its last cycle")
    }

    fn empty_record(&self, m: usize) -> CycleRecord {
        CycleRecord {
            torque: Vec::with_capacity(m),
            speed: Vec::with_capacity(m),
            delta: vec![0.0; self.layout().len()],
            regime_time: vec![0.0; self.regime_times().len()],
            chain_energy: [0.0; 2],
        }
    }

    /// Plateau `pi` with the drivetrain: its result (with the instrument's figures), the
    /// motor's work and the chain's dissipation over the measured cycle (J), and a warning
    /// where the cycle never repeated or the transducer left its rating.
    pub(super) fn torsion_plateau(
        &self,
        tor: &Torsion,
        pi: usize,
        w: &mut Work,
        steps: &mut u64,
    ) -> Result<(PlateauResult, [f64; 3], Vec<String>), SimError> {
        let (rec, cycles, unsettled, work) = self.torsion_cycles(tor, pi, w, steps)?;
        let p = &self.cycle.plateaus()[pi];
        let period = self.cycle_angle() / p.omega;
        let measured = Measured {
            delta: rec.delta.clone(),
            regime_time: rec.regime_time.clone(),
            dt: period,
            dtheta: self.cycle_angle(),
            window_s: [0.0, period],
            revs: self.revolutions_per_cycle(),
        };
        let mut result = self.plateau_result(pi, &measured);
        let instrument = instrument(tor, &rec, period, cycles, work[1] / period);
        let mut warnings = Vec::new();
        let what = if instrument.is_some() {
            "the transducer's"
        } else {
            "the drive shaft's torque"
        };
        if let Some(change) = unsettled {
            warnings.push(format!(
                "at the {:.0} rpm plateau the drivetrain did not repeat a cycle within {MAX_CYCLES} cycles ({what} mean and peak-to-peak still moved by {change:.1e} of their size in the last): its values are the last cycle's, not a steady state",
                p.speed_rpm
            ));
        }
        if let Some(text) = instrument
            .as_ref()
            .and_then(|i| i.rating_warning(p.speed_rpm))
        {
            warnings.push(text);
        }
        result.instrument = instrument;
        let change = rec.chain_energy[1] - rec.chain_energy[0];
        Ok((result, [work[0], work[1], change], warnings))
    }
}

/// The periodic state's correction from one cycle: the linear chain's `(I - Phi)^-1`, the
/// cycle's gap applied to its start (`y* = y0 + (I - Phi)^-1 (y(T) - y0 - rotation)`), which
/// lands on the periodic state in one cycle for a linear chain and converges fast for a mildly
/// nonlinear crank.
struct Shooting {
    inverse: Option<nalgebra::DMatrix<f64>>,
    m: usize,
}

impl Shooting {
    fn new(tor: &Torsion, period: f64) -> Self {
        let phi = tor.chain.monodromy(tor.hold, period);
        let n = phi.nrows();
        let gap = nalgebra::DMatrix::identity(n, n) - phi;
        Shooting {
            inverse: gap.try_inverse(),
            m: n / 2,
        }
    }

    /// Move the state `y` (at the cycle's end, started from `y0`) to the corrected start of
    /// the next cycle, carried over by the rotation `turn` (rad) the cycle made.
    fn correct(&self, y0: &[f64], y: &mut [f64], turn: f64) {
        let Some(inv) = &self.inverse else { return };
        let n = 2 * self.m;
        let gap = nalgebra::DVector::from_fn(n, |i, _| {
            y[i] - y0[i] - if i < self.m { turn } else { 0.0 }
        });
        let step = inv * gap;
        for i in 0..n {
            y[i] = y0[i] + step[i] + if i < self.m { turn } else { 0.0 };
        }
    }
}

/// Mean, least and largest of samples.
#[derive(Debug, Clone, Copy)]
pub(super) struct Span {
    pub(super) mean: f64,
    pub(super) lo: f64,
    pub(super) hi: f64,
}

impl Span {
    pub(super) fn of(x: impl Iterator<Item = f64>) -> Self {
        let (mut sum, mut count) = (0.0, 0usize);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in x {
            sum += v;
            count += 1;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        Span {
            mean: sum / count.max(1) as f64,
            lo,
            hi,
        }
    }

    pub(super) fn width(&self) -> f64 {
        self.hi - self.lo
    }
}

/// Mean and peak-to-peak of samples.
fn stats(x: &[f64]) -> (f64, f64) {
    let span = Span::of(x.iter().copied());
    (span.mean, span.width())
}

/// What the acquisition records of `x`, clipped to its input `range` (N m): the record's mean,
/// its peak-to-peak and the share of samples clipped.
pub(super) fn record(x: impl Iterator<Item = f64>, range: f64) -> (f64, f64, f64) {
    let (mut count, mut clipped) = (0usize, 0usize);
    let span = Span::of(x.map(|v| {
        count += 1;
        clipped += usize::from(v.abs() > range);
        v.clamp(-range, range)
    }));
    (
        span.mean,
        span.width(),
        clipped as f64 / count.max(1) as f64,
    )
}

/// The instrument's figures: the shaft torque's and the crank speed's spans, the acquired
/// record ([`record`]), the chain's dissipation (W) and the cycles it took to settle.
pub(super) fn instrument_of(
    r: &crate::drivetrain::Rating,
    (shaft, speed): (Span, Span),
    acquired: (f64, f64, f64),
    chain_w: f64,
    cycles: u32,
) -> Instrument {
    Instrument {
        transducer: r.name.clone(),
        mean_torque_nm: shaft.mean,
        min_torque_nm: shaft.lo,
        max_torque_nm: shaft.hi,
        peak_to_peak_nm: shaft.width(),
        acquired_mean_torque_nm: acquired.0,
        acquired_peak_to_peak_nm: acquired.1,
        clipped_share: acquired.2,
        crank_speed_fluctuation: speed.width() / speed.mean,
        rated_torque_nm: r.rated_nm,
        limit_torque_nm: r.limit_nm,
        oscillation_width_nm: r.width_nm,
        chain_dissipation_w: chain_w,
        settling_cycles: cycles,
    }
}

/// The instrument's figures from one periodic cycle of samples.
fn instrument(
    tor: &Torsion,
    rec: &CycleRecord,
    period: f64,
    cycles: usize,
    chain_w: f64,
) -> Option<Instrument> {
    let (rating, daq) = tor.chain.instrument.as_ref()?;
    let spans = (
        Span::of(rec.torque.iter().copied()),
        Span::of(rec.speed.iter().copied()),
    );
    let acquired = acquire(&rec.torque, period, rating, daq);
    Some(instrument_of(
        rating,
        spans,
        acquired,
        chain_w,
        cycles as u32,
    ))
}

/// The transducer's periodic signal as the acquisition records it: through the transducer's
/// and the amplifier's first-order low-passes, sampled at the acquisition's rate over its
/// record, clipped to its range. Returns the record's mean, its peak-to-peak and the share of
/// samples clipped.
fn acquire(
    torque: &[f64],
    period: f64,
    rating: &crate::drivetrain::Rating,
    daq: &crate::drivetrain::DaqSpec,
) -> (f64, f64, f64) {
    let m = torque.len();
    let base = TAU / period;
    let (fc, fl) = (rating.cutoff_hz, daq.lowpass_hz);
    let coeffs: Vec<Complex<f64>> = (0..m.div_ceil(2))
        .map(|k| {
            let f = base * k as f64 / TAU;
            let h = Complex::new(1.0, f / fc) * Complex::new(1.0, f / fl);
            dft(torque, k) / h
        })
        .collect();
    let count = (daq.record_s * daq.sample_rate_hz).round().max(1.0) as usize;
    let samples = (0..count).map(|s| {
        let t = s as f64 / daq.sample_rate_hz;
        let step = Complex::from_polar(1.0, base * t);
        let mut rot = step;
        let mut x = coeffs[0].re;
        for c in &coeffs[1..] {
            x += 2.0 * (c * rot).re;
            rot *= step;
        }
        x
    });
    record(samples, daq.range_nm)
}

impl Simulation {
    /// The steady state of every plateau with the drivetrain (see the module). The energy
    /// balance is the chain's over each measured cycle: motor work = the laws' dissipation +
    /// the chain's + the gas work + the change of the chain's and crank's energy.
    pub(super) fn run_steady_drivetrain(
        &mut self,
        tor: &Torsion,
    ) -> Result<super::results::RunResult, SimError> {
        let mut w = self.work()?;
        let (mut steps, mut results, mut warnings) = (0_u64, Vec::new(), Vec::new());
        let (mut motor, mut dissipated, mut gas, mut change) = (0.0, 0.0, 0.0, 0.0);
        for pi in 0..self.cycle.plateaus().len() {
            w.states.reset();
            let (result, work, notes) = self.torsion_plateau(tor, pi, &mut w, &mut steps)?;
            let cycle = self.cycle_angle();
            motor += work[0];
            dissipated += work[1]
                + result.joints.iter().map(|j| j.power_w).sum::<f64>() * cycle
                    / (result.mean_speed_rpm * TAU / 60.0);
            gas += result.gas_torque_nm * cycle;
            change += work[2];
            results.push(result);
            warnings.extend(notes);
        }
        let energy =
            super::results::EnergyBalance::from_terms_with_gas(motor, change, dissipated, gas)
                .relative_to(0.0);
        Ok(self.steady_result(results, energy, (steps, w.max_it), warnings))
    }
}
