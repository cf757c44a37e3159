//! Model evaluation at one instant: kinematics once, then the friction/reaction iteration
//! (phase 1, the plain fixed-point iteration; phase 2, in `newton.rs`, when it stalls) until
//! the joints' normal loads settle. Plain data in, plain data out.

use std::f64::consts::TAU;

use nalgebra::Vector2;
use tribo_plugin_api::{LawInput, Regime};

use super::bind::{law_failed, set_load, Bodies, Instant};
use super::error::{SimError, Unsettled};
use super::joint::JointId;
use super::newton::{Distance, Trend, Verdict};
use super::rates::RateLayout;
use super::Simulation;
use crate::gas::GasState;
use crate::mechanics::{JointLoads, Kinematics, Reactions};

/// How the crank is driven at an evaluation: its acceleration is known (prescribed crank,
/// steady state), or a torque is applied and the acceleration follows from the dynamics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Control {
    /// Crank acceleration, rad/s^2.
    Acceleration(f64),
    /// Drive torque on the crank, N m.
    Torque(f64),
}

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

/// Number of switching functions in an evaluation.
pub(super) const SWITCHES: usize = 7;
/// The switching function of the piston's lateral reaction (after the five joints').
pub(super) const SWITCH_LATERAL: usize = 5;
/// The switching function of the PI drive's torque margin.
pub(super) const SWITCH_DRIVE: usize = 6;

/// Output of one evaluation.
#[derive(Debug, Clone)]
pub(super) struct Eval {
    pub(super) omega: f64,
    pub(super) alpha: f64,
    /// Drive torque on the crank, N m.
    pub(super) drive_torque: f64,
    /// Rates accumulated over time: motor power, then per law dissipated power, per law
    /// regime indicators (4), per law normal load (see `RateLayout`).
    pub(super) rates: Vec<f64>,
    /// Normal load per joint.
    pub(super) normals: [f64; 5],
    /// Where the rates stop being smooth when these change sign: each joint's relative
    /// velocity (a friction force reverses), the piston's lateral reaction (its normal load,
    /// an absolute value, has a kink) and the PI drive's margin to its torque limit (the
    /// anti-windup switches its integrator).
    pub(super) switches: [f64; SWITCHES],
    pub(super) iterations: u32,
    /// Whether phase 2 (Newton) settled the loads; phase 1 otherwise. Read by the unit tests,
    /// which hold each phase to its own convergence test.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) newton: bool,
    /// The gas pressures, piston position and 4-stroke angle at this instant (rigs with gas
    /// loads): what a law will be handed by contract v2.
    pub(super) gas: Option<GasState>,
    /// The settled joint reactions.
    pub(super) reactions: Reactions,
}

impl Eval {
    /// Whether the PI drive sat at its torque limit.
    pub(super) fn saturated(&self) -> bool {
        self.switches[SWITCH_DRIVE] < 0.0
    }
}

/// The crank angle within the revolution, [0, 2 pi). `rem_euclid` is exact but calls a software
/// `fmod` that loops over the exponent difference (1.5% of a PI run); one floor is within a few
/// ulp of the accumulated angle, far below its own integration error.
pub(super) fn crank_angle(theta: f64) -> f64 {
    let r = theta - TAU * (theta / TAU).floor();
    if r >= TAU {
        r - TAU
    } else if r < 0.0 {
        r + TAU
    } else {
        r
    }
}

/// Each joint's two bodies from the mechanism's coordinates `q` and velocities `qd` (crank,
/// rod and piston: x, y, angle each), body A first: the main bearings, crank and block (at
/// rest); the big end, rod and crank; the small end, piston and rod (angles, rad/s); the
/// slide, the piston's position and speed along the cylinder axis and the cylinder (m, m/s).
pub(super) fn joint_bodies(kin: &Kinematics) -> [Bodies; 5] {
    let (q, qd) = (&kin.q, &kin.qd);
    let block = (0.0, 0.0);
    let crank = (q[2], qd[2]);
    let rod = (q[5], qd[5]);
    let piston = (q[8], qd[8]);
    [
        Bodies { a: crank, b: block },
        Bodies { a: crank, b: block },
        Bodies { a: rod, b: crank },
        Bodies { a: piston, b: rod },
        Bodies {
            a: (q[7], qd[7]),
            b: block,
        },
    ]
}

/// Each joint's relative velocity ([`Bodies::relative`]): the main bearings turn with the
/// crank, the big end at rod minus crank, the small end at piston minus rod (rad/s), the slide
/// at the piston's axial speed (m/s).
pub(super) fn relative_velocities(bodies: &[Bodies; 5]) -> [f64; 5] {
    bodies.map(|b| b.relative())
}

/// The friction loads from each joint's total law force or torque (main bearings summed).
pub(super) fn loads_from(totals: &[f64; 5]) -> JointLoads {
    let mut loads = JointLoads::default();
    for id in JointId::ALL {
        add_load(&mut loads, id, totals[id]);
    }
    loads
}

/// Add joint `id`'s total law force or torque to the friction loads.
#[inline(always)]
fn add_load(loads: &mut JointLoads, id: JointId, total: f64) {
    match id {
        JointId::MainA | JointId::MainB => loads.main_torque_nm += total,
        JointId::BigEnd => loads.big_end_torque_nm = total,
        JointId::SmallEnd => loads.small_end_torque_nm = total,
        JointId::Piston => loads.slide_force_n = total,
    }
}

/// One evaluation's friction/reaction problem: what stays fixed while the loads settle (the
/// factorised kinematics, the drive's control, the joints' relative velocities) and the law
/// inputs, of which only the loads change. Borrowed, not moved: copying the kinematics and the
/// inputs cost 2% of a PI run's instructions.
pub(super) struct Problem<'a> {
    pub(super) kin: &'a Kinematics,
    pub(super) control: Control,
    pub(super) inputs: &'a mut [LawInput; 5],
    pub(super) t: f64,
    /// The largest joint normal load of the solve the laws are evaluated at, N: the scale of
    /// the bound on a law's force (`MAX_FORCE_PER_REACTION`).
    pub(super) reaction_n: f64,
}

impl Problem<'_> {
    /// Crank acceleration and reactions under the friction `loads`.
    pub(super) fn solve(&self, loads: &JointLoads) -> (f64, Reactions) {
        let alpha = match self.control {
            Control::Acceleration(alpha) => alpha,
            Control::Torque(torque) => self.kin.alpha_for_torque(torque, loads),
        };
        (alpha, self.kin.reactions(alpha, loads))
    }
}

/// A round of laws and reactions, and the result of a settled iteration.
pub(super) struct Settled {
    pub(super) alpha: f64,
    pub(super) re: Reactions,
    pub(super) normals: [f64; 5],
    pub(super) loads: JointLoads,
    /// Total law force or torque per joint.
    pub(super) totals: [f64; 5],
    pub(super) iterations: u32,
}

/// Phase 1's view of its own progress: the normal loads of the last solve and the trend of
/// its changes, from which convergence (the geometric remainder) and stalling are judged.
#[derive(Default)]
struct Progress {
    prev: Option<[f64; 5]>,
    trend: Trend,
}

impl Progress {
    /// Take the solve's `normals` at iteration `it`: converged when their distance to the
    /// fixed point is within `tol` of `scale` (the last change or, once the iteration is seen
    /// to contract by a factor rho, the geometric remainder rho / (1 - rho) of it); stalled
    /// when `plain_iteration_stalls` says so.
    fn judge(&mut self, normals: &[f64; 5], tol: f64, scale: f64, remaining: u32) -> Verdict {
        let change = self.prev.map(|p| {
            p.iter()
                .zip(normals)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        });
        self.trend
            .judge(change, Distance::Geometric, tol * scale, remaining)
    }
}

impl Simulation {
    /// Normal loads per joint from the reactions.
    #[inline]
    pub(super) fn normals(&self, re: &Reactions) -> [f64; 5] {
        let main = re.main_n.norm();
        [
            main * self.shares[0],
            main * self.shares[1],
            re.big_end_n.norm(),
            re.small_end_n.norm(),
            re.slide_lateral_n.abs(),
        ]
    }

    /// The reaction components each joint's laws see: main bearings (each its share), big end,
    /// small end (global x, y) and the slide (along and normal to its axis).
    #[inline]
    pub(super) fn components(&self, re: &Reactions) -> [Vector2<f64>; 5] {
        [
            re.main_n * self.shares[0],
            re.main_n * self.shares[1],
            re.big_end_n,
            re.small_end_n,
            Vector2::new(0.0, re.slide_lateral_n),
        ]
    }

    /// Evaluate the rig at point `at`: the friction/reaction iteration from the loads `guess`,
    /// the rates written into the recycled `buffer`. Returns the evaluation and the friction
    /// loads it settled on (the next evaluation's guess).
    pub(super) fn evaluate(
        &self,
        at: &Point,
        guess: &JointLoads,
        buffer: Vec<f64>,
    ) -> Result<(Eval, JointLoads), SimError> {
        let mut loads = *guess;
        let mut progress = Progress::default();
        // The caller's recycled buffer: no allocation per evaluation once warmed up.
        let mut rates = buffer;
        rates.clear();
        rates.resize(self.layout().len(), 0.0);
        // Positions, velocities and the factorised constraints do not depend on the loads:
        // computed once, the iteration below only recombines the multipliers.
        let (kin, gas) = self.kinematics(at.theta, at.omega, self.gas_speed(at));
        let bodies = joint_bodies(&kin);
        let rel = relative_velocities(&bodies);
        // The power into the gas: the gas force's power on the piston, negated.
        if let Some(g) = &gas {
            rates[self.layout().gas()] = -g.force_n * kin.qd[7];
        }
        let instant = Instant {
            t: at.t,
            dt: at.dt,
            crank_angle: crank_angle(at.theta),
            omega: at.omega,
            oil: at.oil,
            gas: self.law_gas(at.theta, at.omega, &kin.q, gas.as_ref()),
        };
        check_inputs(at, &rel)?;
        let mut inputs: [LawInput; 5] =
            std::array::from_fn(|ji| self.joints[ji].input(&instant, &bodies[ji]));
        let mut p = Problem {
            kin: &kin,
            control: at.control,
            inputs: &mut inputs,
            t: at.t,
            reaction_n: 0.0,
        };
        // Phase 1: the plain fixed-point iteration (solve, evaluate the laws at the resulting
        // normal loads, repeat). It settles every bundled law set in a few iterations.
        for it in 1..=self.max_iter {
            let (alpha, re) = p.solve(&loads);
            let normals = self.normals(&re);
            check_solve(at.t, alpha, &re, &normals)?;
            let scale = normals.iter().fold(1.0_f64, |m, n| m.max(*n));
            let verdict = progress.judge(&normals, self.tol, scale, self.max_iter - it);
            if matches!(verdict, Verdict::Converged) || self.n_laws == 0 {
                let s = Settled {
                    alpha,
                    re,
                    normals,
                    loads,
                    totals: [0.0; 5],
                    iterations: it,
                };
                return Ok((finish(at, &rel, rates, &s, false, gas), loads));
            }
            if matches!(verdict, Verdict::Stalls) {
                let s = self.settle_by_newton(&mut p, it, &re, &normals, &mut rates)?;
                return Ok((finish(at, &rel, rates, &s, true, gas), s.loads));
            }
            let new_loads = self.plain_round(&mut p, &re, &normals, &mut rates)?;
            if it == self.max_iter {
                return Err(self.plain_failure(&p, &progress, &new_loads, &normals, scale, it));
            }
            progress.prev = Some(normals);
            loads = new_loads;
        }
        // Not reached (the last iteration returns), but an error is the honest answer.
        Err(self.no_convergence(at.t, self.max_iter, &[f64::NAN; 5], 1.0))
    }

    /// One round of phase 1: every law evaluated at the reactions `re` (normal loads
    /// `normals`), powers, regimes and loads recorded in `rates`. Returns the friction loads.
    #[inline(always)]
    fn plain_round(
        &self,
        p: &mut Problem<'_>,
        re: &Reactions,
        normals: &[f64; 5],
        rates: &mut [f64],
    ) -> Result<JointLoads, SimError> {
        // Law inputs: only the loads change from one iteration to the next.
        let comps = self.components(re);
        p.reaction_n = normals.iter().fold(0.0, |m, n| m.max(*n));
        let mut new_loads = JointLoads::default();
        // Powers and mean loads are written for every law below; only the regime indicators
        // are set sparsely and need clearing.
        rates[self.layout().regimes()].fill(0.0);
        let mut k = 0;
        for joint in &self.joints {
            let id = joint.id;
            let moment = if id == JointId::Piston {
                re.slide_moment_nm
            } else {
                0.0
            };
            set_load(&mut p.inputs[id], comps[id], moment, normals[id]);
            let total = self.joint_force(p, id, Some((rates, k)))?;
            add_load(&mut new_loads, id, total);
            k += joint.laws.len();
        }
        Ok(new_loads)
    }

    /// The error when phase 1 reached `solver.friction_max_iter`: the joints whose loads were
    /// still moving, by the last change or, after a single solve, the one the next solve makes.
    #[cold]
    fn plain_failure(
        &self,
        p: &Problem<'_>,
        progress: &Progress,
        new_loads: &JointLoads,
        normals: &[f64; 5],
        scale: f64,
        it: u32,
    ) -> SimError {
        let before = progress
            .prev
            .unwrap_or_else(|| self.normals(&p.solve(new_loads).1));
        let changes = std::array::from_fn(|ji| (before[ji] - normals[ji]).abs());
        let scale = before.iter().fold(scale, |m, n| m.max(*n));
        self.no_convergence(p.t, it, &changes, scale)
    }

    /// The friction force (slide) or torque (revolute) of all laws on joint `id` for its input
    /// in `p`, checked (finite; a stateless law must not add energy). With `record`, each law's
    /// power, regime and load are written into the rate vector from law index `k` on.
    #[inline(always)]
    pub(super) fn joint_force(
        &self,
        p: &Problem<'_>,
        id: JointId,
        record: Option<(&mut [f64], usize)>,
    ) -> Result<f64, SimError> {
        let joint = &self.joints[id.index()];
        let layout = self.layout();
        let input = &p.inputs[id];
        let mut record = record;
        let mut total = 0.0;
        for (i, law) in joint.laws.iter().enumerate() {
            let out = match law.call(input) {
                Ok(out) => out,
                Err(e) => return Err(law_failed(id, input, e)),
            };
            let power = joint.checked_power(law, input, &out, p.reaction_n)?;
            total += out.force;
            if let Some((rates, k)) = record.as_mut() {
                let regime = out.regime().unwrap_or(Regime::None) as usize;
                rates[layout.power(*k + i)] = -power;
                rates[layout.regime(*k + i, regime)] = 1.0;
                rates[layout.normal(*k + i)] = input.normal_load_n;
            }
        }
        Ok(total)
    }

    /// The error for an iteration that did not settle: `changes` per joint (N), the joints
    /// with laws whose change exceeds the tolerance named with their laws.
    #[cold]
    pub(super) fn no_convergence(
        &self,
        t: f64,
        iterations: u32,
        changes: &[f64; 5],
        scale: f64,
    ) -> SimError {
        let tol_n = self.tol * scale;
        // Empty when every change is within tolerance: the limit came before a second solve.
        let unsettled: Vec<Unsettled> = self
            .joints
            .iter()
            .zip(changes)
            .filter(|(j, _)| !j.laws.is_empty())
            .filter(|(_, c)| c.is_nan() || **c > tol_n)
            .map(|(j, c)| Unsettled {
                joint: j.id.name().into(),
                laws: j.laws.iter().map(|l| l.name.clone()).collect(),
                change_n: *c,
            })
            .collect();
        SimError::NoConvergence {
            time_s: t,
            iterations,
            change_n: changes.iter().fold(0.0, |m, c| m.max(*c)),
            tol: self.tol,
            unsettled,
        }
    }
}

/// The host's own inputs to the laws at `at` (crank speed, oil viscosity, each joint's
/// relative velocity `rel`) must be finite: a non-finite one is the model's fault, reported as
/// such before any law could be blamed for it.
#[inline(always)]
fn check_inputs(at: &Point, rel: &[f64; 5]) -> Result<(), SimError> {
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
        let id = JointId::ALL
            .into_iter()
            .find(|id| !rel[*id].is_finite())
            .unwrap_or(JointId::MainA);
        model("relative velocity", Some(id.name()), rel[id])
    })
}

/// A solve's crank acceleration, drive torque and normal loads must be finite (the laws are
/// given the loads next): a non-finite one is the model's fault, named with its joint.
#[inline(always)]
pub(super) fn check_solve(
    t: f64,
    alpha: f64,
    re: &Reactions,
    normals: &[f64; 5],
) -> Result<(), SimError> {
    let all = alpha.is_finite()
        & re.drive_torque_nm.is_finite()
        & normals.iter().fold(true, |ok, n| ok & n.is_finite());
    if all {
        return Ok(());
    }
    let model = |quantity, joint, value| SimError::Model {
        time_s: t,
        quantity,
        joint,
        value,
    };
    Err(
        match JointId::ALL
            .into_iter()
            .find(|id| !normals[*id].is_finite())
        {
            Some(id) => model("normal load", Some(id.name()), normals[id]),
            None if !alpha.is_finite() => model("crank acceleration", None, alpha),
            None => model("drive torque", None, re.drive_torque_nm),
        },
    )
}

/// The evaluation at `at` from the final solve `s`: its reactions, normal loads and
/// iterations, the motor power, and the switching functions (`rel`: the joints' relative
/// velocities).
fn finish(
    at: &Point,
    rel: &[f64; 5],
    mut rates: Vec<f64>,
    s: &Settled,
    newton: bool,
    gas: Option<GasState>,
) -> Eval {
    rates[RateLayout::MOTOR] = s.re.drive_torque_nm * at.omega;
    let mut switches = [0.0; SWITCHES];
    switches[..5].copy_from_slice(rel);
    switches[SWITCH_LATERAL] = s.re.slide_lateral_n;
    switches[SWITCH_DRIVE] = at.margin;
    Eval {
        omega: at.omega,
        alpha: s.alpha,
        drive_torque: s.re.drive_torque_nm,
        rates,
        normals: s.normals,
        switches,
        iterations: s.iterations,
        newton,
        gas,
        reactions: s.re,
    }
}
