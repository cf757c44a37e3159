//! Model evaluation at one instant: kinematics once, then the friction/reaction iteration
//! (phase 1, the plain fixed-point iteration; phase 2, in `newton.rs`, when it stalls) until
//! the joints' normal loads settle. The same for every crank train: the crank model
//! ([`Crank`]) answers for kinematics and reactions, the joints' laws for the friction.

use std::f64::consts::TAU;

use tribo_plugin_api::loader::inflight;
use tribo_plugin_api::LawInput;

use super::bind::{
    contact_input, refresh_input, set_load, Instant, LawMemory, LawStates, Record, Reuse,
};
use super::crank::Crank;
use super::error::{SimError, Unsettled};
use super::rates::RateLayout;
use super::trend::{Trend, Verdict};
use super::types::{Bodies, Control};
use super::Simulation;
use crate::gas::{GasModel, LawGas};

/// A NaN with a payload no arithmetic makes: what debug builds fill an evaluation's rates with
/// before it writes them, so that one left unwritten is caught.
const UNWRITTEN: u64 = 0x7ff8_dead_beef_0001;

/// Where and how to evaluate the rig.
#[derive(Debug, Clone, Copy)]
pub(super) struct Point {
    /// Time, s.
    pub(super) t: f64,
    /// The step the laws are told, s.
    pub(super) dt: f64,
    /// Crank angle (accumulated), rad.
    pub(super) theta: f64,
    /// Crank speed, rad/s.
    pub(super) omega: f64,
    pub(super) control: Control,
    /// The PI drive's margin to its torque limit (negative while saturated; infinite else).
    pub(super) margin: f64,
    /// Oil temperature (C) and dynamic viscosity (Pa s).
    pub(super) oil: (f64, f64),
}

impl Point {
    /// A crank at constant speed `omega` at accumulated angle `theta`, time `t`, the laws told
    /// step `dt`, with oil `oil`: the steady state's and the crank-angle traces' points.
    pub(super) fn steady(t: f64, dt: f64, theta: f64, omega: f64, oil: (f64, f64)) -> Self {
        Self {
            t,
            dt,
            theta,
            omega,
            control: Control::Acceleration(0.0),
            margin: f64::INFINITY,
            oil,
        }
    }
}

/// Output of one evaluation. Its buffers are boxed slices of the run's fixed sizes (made once by
/// [`Work::eval`]), so an evaluation is small enough (112 bytes) to be moved through the
/// steppers, the pool and a step without a `memcpy` call.
#[derive(Debug, Clone)]
pub(super) struct Eval {
    pub(super) omega: f64,
    pub(super) alpha: f64,
    /// Drive torque on the crank, N m.
    pub(super) drive_torque: f64,
    /// Rates accumulated over time: motor power, then per law dissipated power, per law
    /// normal load (see `RateLayout`).
    pub(super) rates: Box<[f64]>,
    /// Each law's lubrication regime (a `Regime` as code; see `RegimeTimes`).
    pub(super) regimes: Box<[u8]>,
    /// Normal load per joint, N.
    pub(super) normals: Box<[f64]>,
    /// Where the rates stop being smooth when these change sign: each joint's relative
    /// velocity (a friction force reverses), each cylinder's side thrust (its normal load, an
    /// absolute value, has a kink), a vented crankcase's pressure above the ambient (the
    /// breather's flow reverses: the orifice law's square-root foot) and last the PI drive's
    /// margin to its torque limit (the anti-windup switches its integrator).
    pub(super) switches: Box<[f64]>,
    /// Each joint's law force or torque in the final solve: the friction the next evaluation
    /// starts from.
    pub(super) totals: Box<[f64]>,
    pub(super) iterations: u32,
    /// Whether phase 2 (Newton) settled the loads; phase 1 otherwise. Read by the unit tests,
    /// which hold each phase to its own convergence test.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) newton: bool,
}

/// The lengths of an evaluation's buffers in one run: rates, laws (regimes), joints (normal
/// loads, totals) and switches.
#[derive(Debug, Clone, Copy)]
pub(super) struct EvalSizes {
    rates: usize,
    laws: usize,
    joints: usize,
    switches: usize,
}

impl Eval {
    /// Make this evaluation (a buffer of the same run) a copy of `other`, in place.
    pub(super) fn copy_from(&mut self, other: &Eval) {
        self.omega = other.omega;
        self.alpha = other.alpha;
        self.drive_torque = other.drive_torque;
        self.rates.copy_from_slice(&other.rates);
        self.regimes.copy_from_slice(&other.regimes);
        self.normals.copy_from_slice(&other.normals);
        self.switches.copy_from_slice(&other.switches);
        self.totals.copy_from_slice(&other.totals);
        self.iterations = other.iterations;
        self.newton = other.newton;
    }

    /// Whether the PI drive sat at its torque limit.
    pub(super) fn saturated(&self) -> bool {
        self.switches.last().is_some_and(|m| *m < 0.0)
    }
}

/// A run's evaluation scratch: the crank model with its configuration and last solve, each
/// cylinder's gas state for its laws, the law inputs of the last round of laws (what a commit
/// is given), every law's state, the normal loads of the solve before, and recycled
/// evaluations. No allocation per evaluation once warmed up.
#[derive(Clone)]
pub(super) struct Work {
    pub(super) crank: Crank,
    pub(super) law_gas: Vec<LawGas>,
    pub(super) inputs: Vec<LawInput>,
    /// Each joint's two bodies and relative velocity in the configuration evaluated.
    pub(super) bodies: Vec<Bodies>,
    pub(super) rel: Vec<f64>,
    pub(super) prev: Box<[f64]>,
    pub(super) states: LawStates,
    /// The current evaluation's outputs that their laws marked affine in the load.
    pub(super) reuse: Reuse,
    /// Largest friction iteration count seen.
    pub(super) max_it: u32,
    sizes: EvalSizes,
    pool: Vec<Eval>,
}

impl Work {
    /// A recycled evaluation (or a new one while the pool warms up).
    pub(super) fn eval(&mut self) -> Eval {
        let n = self.sizes;
        self.pool.pop().unwrap_or_else(|| Eval {
            omega: 0.0,
            alpha: 0.0,
            drive_torque: 0.0,
            rates: vec![0.0; n.rates].into_boxed_slice(),
            regimes: vec![0; n.laws].into_boxed_slice(),
            normals: vec![0.0; n.joints].into_boxed_slice(),
            switches: vec![0.0; n.switches].into_boxed_slice(),
            totals: vec![0.0; n.joints].into_boxed_slice(),
            iterations: 0,
            newton: false,
        })
    }

    /// Give an evaluation back for reuse.
    pub(super) fn recycle(&mut self, e: Eval) {
        self.pool.push(e);
    }
}

/// The crank angle within the revolution, [0, 2 pi). `rem_euclid` is exact but calls a software
/// `fmod` that loops over the exponent difference (1.5% of a PI run); one floor is within a few
/// ulp of the accumulated angle, far below its own integration error.
pub(super) fn crank_angle(theta: f64) -> f64 {
    let r = theta - TAU * floor(theta / TAU);
    if r >= TAU {
        r - TAU
    } else if r < 0.0 {
        r + TAU
    } else {
        r
    }
}

/// `x.floor()`, the same number, without the call to the C library's `floor` that the
/// baseline x86-64 target makes (no SSE4.1 rounding instruction): through an integer below
/// 2^52, where every float is exact, and the sign copied so that -0 stays -0.
#[inline(always)]
fn floor(x: f64) -> f64 {
    if x.abs() < 4.0e15 {
        let t = x as i64 as f64;
        (if t > x { t - 1.0 } else { t }).copysign(x)
    } else {
        x.floor()
    }
}

impl Simulation {
    /// A fresh scratch for a run of this simulation, every law's state at zero.
    pub(super) fn work(&self) -> Result<Work, SimError> {
        let n = self.joints.len();
        Ok(Work {
            crank: self.crank.clone(),
            law_gas: Vec::with_capacity(self.crank.cylinders()),
            // One input per joint, refreshed each evaluation (none without laws).
            inputs: if self.n_laws > 0 {
                self.joints
                    .iter()
                    .map(|j| contact_input(&j.contact))
                    .collect()
            } else {
                Vec::new()
            },
            bodies: vec![Bodies::default(); n],
            rel: vec![0.0; n],
            prev: vec![0.0; n].into_boxed_slice(),
            states: LawStates::new(&self.joints)?,
            reuse: Reuse::new(self.n_laws),
            max_it: 0,
            sizes: EvalSizes {
                rates: self.layout().len(),
                laws: self.n_laws,
                joints: n,
                switches: n + self.crank.cylinders() + 2,
            },
            pool: Vec::new(),
        })
    }

    /// Evaluate the rig at point `at`: the friction/reaction iteration from the law totals
    /// `guess` (per joint), the result written into the recycled `e` (its `totals` the
    /// friction the next evaluation starts from); the law inputs of its last round of laws
    /// stay in `w`.
    pub(super) fn evaluate(
        &self,
        at: &Point,
        guess: &[f64],
        w: &mut Work,
        e: &mut Eval,
    ) -> Result<(), SimError> {
        self.prepare(at, guess, w, e)?;
        // Phase 1: the plain fixed-point iteration (solve, evaluate the laws at the resulting
        // normal loads, repeat), abandoned for phase 2 (`newton.rs`) when it is seen not to
        // contract. It settles every bundled law set in a few iterations.
        let mut trend = Trend::default();
        for it in 1..=self.max_iter {
            let alpha = w.crank.solve(at.control, &self.roles, &e.totals);
            // The largest load (the laws' output check's scale) and the largest change from the
            // solve before (`w.prev`; meaningless at the first solve).
            let loads = w
                .crank
                .normals_against(&self.roles, &mut e.normals, &w.prev);
            let torque = w.crank.drive_torque();
            check_solve(self, at.t, (alpha, torque), &e.normals, loads.finite)?;
            // The convergence scale, at least 1 N (the loads are finite and not negative).
            let reaction_n = loads.largest_n;
            let scale = reaction_n.max(1.0);
            let change = (it > 1).then_some(loads.change_n);
            let verdict = trend.judge(
                change,
                self.rules.distance,
                self.tol * scale,
                self.max_iter - it,
            );
            if matches!(verdict, Verdict::Converged) || self.n_laws == 0 {
                self.finish(at, w, e, alpha, it, false);
                return Ok(());
            }
            if matches!(verdict, Verdict::Stalls) {
                let (alpha, it) = self.settle_by_newton(at, w, e, it)?;
                self.finish(at, w, e, alpha, it, true);
                return Ok(());
            }
            self.plain_round(w, e, reaction_n)?;
            if it == self.max_iter {
                return Err(self.plain_failure(at, w, e, it));
            }
            // The loads just made become the solve before; the next solve writes over the
            // older ones.
            std::mem::swap(&mut w.prev, &mut e.normals);
        }
        // Not reached (the last iteration returns), but an error is the honest answer.
        Err(self.no_convergence(at.t, self.max_iter, &[], 1.0))
    }

    /// Everything of an evaluation at `at` that does not depend on the loads: the gas power
    /// set, the friction started from `guess`, the configuration and
    /// the relative velocities (checked finite), and the law inputs but for the loads.
    #[inline(always)]
    fn prepare(
        &self,
        at: &Point,
        guess: &[f64],
        w: &mut Work,
        e: &mut Eval,
    ) -> Result<(), SimError> {
        let layout = self.layout();
        // The buffers have the run's sizes (`Work::eval`). Every rate is written by the
        // evaluation itself: the gas power here, each law's power and load by the last round
        // of laws (phase 1's or phase 2's; every round records), the motor power by `finish`;
        // so the rates are not cleared. Debug builds poison them to prove it (`finish`).
        #[cfg(debug_assertions)]
        e.rates.fill(f64::from_bits(UNWRITTEN));
        e.normals.fill(0.0);
        w.reuse.forget();
        let given = guess.len().min(e.totals.len());
        e.totals[..given].copy_from_slice(&guess[..given]);
        e.totals[given..].fill(0.0);
        // Positions, velocities and the factorised constraints do not depend on the loads:
        // computed once, the iteration below only recombines the multipliers.
        let gas = self.gas_models();
        let gas_power = w.crank.kinematics(
            at.theta,
            at.omega,
            gas,
            (self.gas_speed(at), self.held.cylinder_pa),
            &mut w.law_gas,
        );
        e.rates[layout.gas()] = if gas.is_empty() { 0.0 } else { gas_power };
        for ((b, r), j) in w.bodies.iter_mut().zip(&mut w.rel).zip(&self.joints) {
            *b = w.crank.bodies(j.role);
            *r = b.relative();
        }
        check_inputs(self, at, &w.rel)?;
        // The law inputs but for the loads: refreshed once, each round of laws sets only the
        // loads.
        let angle = crank_angle(at.theta);
        for ((input, j), bodies) in w.inputs.iter_mut().zip(&self.joints).zip(&w.bodies) {
            let instant = Instant {
                t: at.t,
                dt: at.dt,
                crank_angle: angle,
                omega: at.omega,
                oil: at.oil,
                // A cylinder's joints see its own gas state; the mains, cylinder 1's.
                gas: w.law_gas[j.role.cylinder()],
            };
            refresh_input(input, &instant, bodies);
        }
        Ok(())
    }

    /// One round of phase 1: every law evaluated at the last solve's reactions (its normal
    /// loads in `e.normals`), powers and loads recorded in `e.rates`, regimes in `e.regimes`,
    /// each joint's law total into `e.totals`; `reaction_n` is the largest of those loads.
    #[inline(always)]
    fn plain_round(&self, w: &mut Work, e: &mut Eval, reaction_n: f64) -> Result<(), SimError> {
        let layout = self.layout();
        // The thread's crash-report slot, looked up once for the round's law calls.
        let mut marks = inflight::round();
        for (ji, j) in self.joints.iter().enumerate() {
            if j.laws.is_empty() {
                e.totals[ji] = 0.0;
                continue;
            }
            let (comp, moment) = w.crank.reaction(j.role);
            let input = &mut w.inputs[ji];
            set_load(input, comp, moment, e.normals[ji]);
            let record = Some(Record {
                rates: &mut e.rates,
                regimes: &mut e.regimes,
            });
            let mut laws = LawMemory {
                states: &w.states,
                reuse: &mut w.reuse,
            };
            e.totals[ji] = j.force(input, &mut laws, reaction_n, record, layout, &mut marks)?;
        }
        Ok(())
    }

    /// The settled evaluation at `at` from the final solve (crank acceleration `alpha`, after
    /// `it` iterations; `newton` if phase 2 settled it): motor power, drive torque and the
    /// switching functions.
    fn finish(&self, at: &Point, w: &mut Work, e: &mut Eval, alpha: f64, it: u32, newton: bool) {
        let torque = w.crank.drive_torque();
        e.rates[RateLayout::MOTOR] = torque * at.omega;
        debug_assert!(
            e.rates.iter().all(|r| r.to_bits() != UNWRITTEN),
            "an evaluation left a rate unwritten"
        );
        e.omega = at.omega;
        e.alpha = alpha;
        e.drive_torque = torque;
        e.iterations = it;
        e.newton = newton;
        // Relative velocities, each cylinder's side thrust, the crankcase pressure above the
        // ambient, the margin (`Work::eval`'s sizes).
        let (rel, rest) = e.switches.split_at_mut(w.rel.len());
        rel.copy_from_slice(&w.rel);
        if let Some((margin, rest)) = rest.split_last_mut() {
            if let Some((crankcase, thrusts)) = rest.split_last_mut() {
                for (k, s) in thrusts.iter_mut().enumerate() {
                    *s = w.crank.lateral(k);
                }
                *crankcase = match (self.gas_models().first(), w.law_gas.first()) {
                    (Some(g), Some(s)) => s.crankcase_pa - g.ambient_pa(),
                    _ => 0.0,
                };
            }
            *margin = at.margin;
        }
        w.max_it = w.max_it.max(it);
    }

    /// The error when phase 1 reached `solver.friction_max_iter`: the joints whose loads were
    /// still moving, by the last change or, after a single solve, the one the next solve makes.
    #[cold]
    fn plain_failure(&self, at: &Point, w: &mut Work, e: &Eval, it: u32) -> SimError {
        let mut next = vec![0.0; self.joints.len()];
        w.crank.solve(at.control, &self.roles, &e.totals);
        w.crank.normals_against(&self.roles, &mut next, &w.prev);
        let (before, after): (&[f64], &[f64]) = if it > 1 {
            (&w.prev, &e.normals)
        } else {
            (&e.normals, &next)
        };
        let changes: Vec<f64> = before
            .iter()
            .zip(after)
            .map(|(a, b)| (a - b).abs())
            .collect();
        let scale = before
            .iter()
            .chain(after.iter())
            .fold(1.0_f64, |m, n| m.max(*n));
        self.no_convergence(at.t, it, &changes, scale)
    }

    /// The error for an iteration that did not settle: `changes` per joint (N), the joints
    /// with laws whose change exceeds the tolerance named with their laws.
    #[cold]
    pub(super) fn no_convergence(
        &self,
        t: f64,
        iterations: u32,
        changes: &[f64],
        scale: f64,
    ) -> SimError {
        let tol_n = self.tol * scale;
        // Empty when every change is within tolerance: the limit came before a second solve.
        let unsettled: Vec<Unsettled> = self
            .joints
            .iter()
            .zip(changes)
            .filter(|(j, _)| !j.laws.is_empty())
            // A NaN change (loads that ran off to infinity) is unsettled too.
            .filter(|(_, c)| c.is_nan() || **c > tol_n)
            .map(|(j, c)| Unsettled {
                joint: j.name.clone(),
                laws: j.laws.iter().map(|l| l.name.clone()).collect(),
                change_n: *c,
            })
            .collect();
        SimError::NoConvergence {
            time_s: t,
            iterations,
            change_n: changes.iter().fold(0.0, |m: f64, c| m.max(*c)),
            tol: self.tol,
            unsettled,
        }
    }

    /// The crank speed a vented crankcase is read at for point `at`: the crank's own when it
    /// follows the cycle exactly (prescribed crank, steady state); the cycle's reference speed
    /// under the PI drive, whose speed ripples within a revolution far faster than the
    /// crankcase breathes (the tables are quasi-steady in the cycle's speed, and the mean
    /// speed follows the reference).
    #[inline]
    fn gas_speed(&self, at: &Point) -> f64 {
        match at.control {
            Control::Torque(_)
                if self.held.torque_nm.is_none()
                    && self.gas.iter().any(GasModel::depends_on_speed) =>
            {
                self.reference(at.t).1
            }
            _ => at.omega,
        }
    }
}

/// The host's own inputs to the laws at `at` (crank speed, oil viscosity, each joint's
/// relative velocity `rel`) must be finite: a non-finite one is the model's fault, reported as
/// such before any law could be blamed for it.
#[inline(always)]
fn check_inputs(sim: &Simulation, at: &Point, rel: &[f64]) -> Result<(), SimError> {
    let all = at.omega.is_finite()
        & at.oil.1.is_finite()
        & at.theta.is_finite()
        & rel.iter().fold(true, |ok, v| ok & v.is_finite());
    if all {
        return Ok(());
    }
    let model = |quantity, joint, value| SimError::Model {
        time_s: at.t,
        quantity,
        joint,
        value,
    };
    Err(if !at.omega.is_finite() {
        model("crank speed", None, at.omega)
    } else if !at.theta.is_finite() {
        model("crank angle", None, at.theta)
    } else if !at.oil.1.is_finite() {
        model("oil viscosity", None, at.oil.1)
    } else {
        let (j, v) = sim
            .joints
            .iter()
            .zip(rel)
            .find(|(_, v)| !v.is_finite())
            .map_or((None, f64::NAN), |(j, v)| (Some(sim.model_name(j)), *v));
        model("relative velocity", j, v)
    })
}

/// A solve's crank acceleration and drive torque (`solved`) and normal loads (all finite if
/// `loads_finite`) must be finite (the laws are given the loads next): a non-finite one is the
/// model's fault, named with its joint.
#[inline(always)]
pub(super) fn check_solve(
    sim: &Simulation,
    t: f64,
    solved: (f64, f64),
    normals: &[f64],
    loads_finite: bool,
) -> Result<(), SimError> {
    let (alpha, drive_torque) = solved;
    if alpha.is_finite() & drive_torque.is_finite() & loads_finite {
        return Ok(());
    }
    solve_error(sim, t, solved, normals)
}

/// The error of a solve [`check_solve`] found a non-finite value in.
#[cold]
fn solve_error(
    sim: &Simulation,
    t: f64,
    (alpha, drive_torque): (f64, f64),
    normals: &[f64],
) -> Result<(), SimError> {
    let model = |quantity, joint, value| SimError::Model {
        time_s: t,
        quantity,
        joint,
        value,
    };
    Err(
        match sim.joints.iter().zip(normals).find(|(_, n)| !n.is_finite()) {
            Some((j, n)) => model("normal load", Some(sim.model_name(j)), *n),
            None if !alpha.is_finite() => model("crank acceleration", None, alpha),
            None => model("drive torque", None, drive_torque),
        },
    )
}

#[cfg(test)]
mod floor_tests {
    /// The inline floor is the library's, bit for bit: signed zeros, halves, integers, the
    /// neighbours of integers, the edge of the fast path, and not-a-number.
    #[test]
    fn the_inline_floor_is_the_library_floor() {
        let mut xs = vec![
            0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 3.999_999, -3.999_999, 4.0e15, -4.0e15,
        ];
        xs.extend([
            1e300,
            -1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
        ]);
        for k in -2000..2000 {
            let x = f64::from(k) * 0.37 + 1e-9;
            xs.extend([
                x,
                x.next_up(),
                x.next_down(),
                f64::from(k),
                f64::from(k).next_down(),
            ]);
        }
        for x in xs {
            assert_eq!(
                super::floor(x).to_bits(),
                x.floor().to_bits(),
                "floor({x:e})"
            );
        }
        assert!(super::floor(f64::NAN).is_nan());
    }
}
