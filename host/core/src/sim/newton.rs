//! Phase 2 of the friction/reaction iteration: a damped Newton iteration on the square roots
//! of the normal loads, with a bracketing fallback per joint, for laws whose load sensitivity
//! is unbounded at zero load (docs/solver.md). Entered only when phase 1 is seen to stall.
//!
//! The iteration itself (`settle`: convergence test, backtracking, bracketing fallback) and
//! phase 1's judgement of its own progress (`Trend`) are shared by the single-cylinder rig
//! (`Simulation`, below) and the multi-cylinder engine (`engine_newton.rs`); each supplies its
//! rounds of laws and reactions through `SquareRoots`.

use nalgebra::{Matrix5, Vector2, Vector5};
use tribo_plugin_api::LawInput;

use super::error::SimError;
use super::evaluate::{check_solve, loads_from, Problem, Settled};
use super::joint::JointId;
use super::Simulation;
use crate::mechanics::Reactions;

/// Relative finite-difference step of phase 2's Jacobian, in `u = sqrt(W)` (about the square
/// root of the machine epsilon: half the digits for the derivative, ample for Newton).
pub(super) const NEWTON_FD_STEP: f64 = 1.5e-8;
/// Shortest step phase 2's backtracking tries, as a fraction of the Newton step, before it
/// gives up (seven halvings).
const NEWTON_MIN_STEP: f64 = 1.0 / 128.0;
/// Phase 1 is kept while it is predicted to settle within this many more iterations (and the
/// limit): a Newton step costs one round of laws per law-bearing joint (up to five) plus at
/// least one more, so three of them cost about as much as twenty plain iterations.
const PLAIN_ITERATIONS_WORTH_KEEPING: u32 = 20;

/// Whether the plain fixed-point iteration will not settle in reasonable time, judged from its
/// last change `d` and the change two iterations before, `d2` (N): their ratio is the
/// contraction over two iterations, robust to the alternating sign of an iteration that
/// overshoots. Not contracting, or predicted (geometric series) to need more than
/// `PLAIN_ITERATIONS_WORTH_KEEPING` or `remaining` further iterations to bring the remainder
/// within `tol_n`, means it stalls.
pub(super) fn plain_iteration_stalls(d: f64, d2: f64, tol_n: f64, remaining: u32) -> bool {
    if d2 <= 0.0 || d <= 0.0 {
        return false;
    }
    let rho = (d / d2).sqrt();
    if rho >= 1.0 {
        return true;
    }
    // Still above tolerance after `limit` more iterations: d rho^limit rho / (1 - rho) > tol_n
    // (a product rather than a logarithm: this runs at every slow evaluation).
    let limit = PLAIN_ITERATIONS_WORTH_KEEPING.min(remaining);
    d * rho.powi(limit as i32) * rho > tol_n * (1.0 - rho)
}

/// How phase 1 measures its distance to the fixed point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Distance {
    /// The last change of any normal load (the engine's test).
    LastChange,
    /// The last change or, once the iteration is seen to contract by a factor rho < 0.5, the
    /// geometric remainder rho / (1 - rho) of it (the single-cylinder rig's test).
    Geometric,
}

/// What phase 1 decides after a solve.
pub(super) enum Verdict {
    Converged,
    Stalls,
    Continue,
}

/// Phase 1's view of its own progress: the last two changes of the normal loads, from which
/// convergence and stalling are judged.
#[derive(Default)]
pub(super) struct Trend {
    last_change: Option<f64>,
    older_change: Option<f64>,
}

impl Trend {
    /// Take a solve's largest change of a normal load from the solve before (`None` at the
    /// first solve): converged when the `distance` to the fixed point is within `tol_n` (N);
    /// stalled when `plain_iteration_stalls` says so with `remaining` iterations left.
    pub(super) fn judge(
        &mut self,
        change: Option<f64>,
        distance: Distance,
        tol_n: f64,
        remaining: u32,
    ) -> Verdict {
        let converged = change.is_some_and(|d| {
            let remainder = match self.last_change {
                Some(d0) if distance == Distance::Geometric && d < 0.5 * d0 => {
                    d * (d / d0) / (1.0 - d / d0)
                }
                _ => d,
            };
            remainder <= tol_n
        });
        let stalls = match (change, self.older_change) {
            (Some(d), Some(d2)) if !converged => plain_iteration_stalls(d, d2, tol_n, remaining),
            _ => false,
        };
        self.older_change = self.last_change;
        self.last_change = change;
        if converged {
            Verdict::Converged
        } else if stalls {
            Verdict::Stalls
        } else {
            Verdict::Continue
        }
    }
}

/// Set a law input's normal load to `w` (N), its reaction components (and so its load on the
/// inner member) along `comp`, the reaction where phase 2 began (normal load `normal`), scaled
/// to `w`, and its moment.
#[inline]
pub(super) fn scaled_input(
    input: &mut LawInput,
    comp: Vector2<f64>,
    normal: f64,
    moment: f64,
    w: f64,
) {
    let f = if normal > 0.0 { w / normal } else { 0.0 };
    super::bind::set_load(input, Vector2::new(comp.x * f, comp.y * f), moment, w);
}

/// A friction/reaction problem in phase 2's unknowns `u = sqrt(W)`, one per joint, of which
/// the law-bearing ones are iterated: the rig's rounds of laws and reactions, on which `settle`
/// runs the Newton iteration. It holds the current round (at the current `u`) and at most one
/// pending trial.
pub(super) trait SquareRoots {
    /// A value per joint.
    type Vector: AsRef<[f64]>;
    /// Whether joint `j` carries laws (the others keep their reactions' loads).
    fn is_active(&self, j: usize) -> bool;
    /// The current unknown of joint `j`, sqrt(N).
    fn u(&self, j: usize) -> f64;
    /// The current round's residual `N(u^2) - u^2` per joint (0 on joints without laws).
    fn residual(&self) -> Self::Vector;
    /// The current round's largest normal load, at least 1 N: the scale of the tolerance.
    fn scale(&self) -> f64;
    /// The Newton step from the current `u` solving `J step = -residual` with the Jacobian by
    /// finite differences (`scale` sets the smallest step); `None` if it is singular.
    fn newton_step(
        &mut self,
        residual: &Self::Vector,
        scale: f64,
    ) -> Result<Option<Self::Vector>, SimError>;
    /// A round at `|u + length * step|`, kept as the pending trial: its residual's 2-norm
    /// over the law-bearing joints.
    fn trial(&mut self, step: &Self::Vector, length: f64) -> Result<f64, SimError>;
    /// The pending trial becomes the current round.
    fn accept(&mut self);
    /// `rho_j(x) = N_j - x^2` with joint `j`'s laws at the load `x^2` and the other joints'
    /// friction that of the current round.
    fn alone(&mut self, j: usize, x: f64) -> Result<f64, SimError>;
    /// Move joint `j` to `u_j = x` and make a round there the current one.
    fn settle_joint(&mut self, j: usize, x: f64) -> Result<(), SimError>;
    /// The error naming the law-bearing joints whose `|residual|` exceeds the tolerance.
    fn unsettled(&self, iterations: u32, residual: &Self::Vector, scale: f64) -> SimError;
}

/// Phase 2 on `x` from iteration `it` (phase 1's count): damped Newton steps until every
/// law-bearing joint's `|N(W) - W|` is within `tol` times the largest normal load, at most
/// `max_iter` iterations in all. Each Newton step is halved until the residual's 2-norm
/// falls; where none does, the worst joint is settled alone by bracketing. Returns the
/// iteration count; the converged round is `x`'s current one, and the last round computed.
pub(super) fn settle<S: SquareRoots>(
    x: &mut S,
    mut it: u32,
    max_iter: u32,
    tol: f64,
) -> Result<u32, SimError> {
    loop {
        let residual = x.residual();
        let scale = x.scale();
        if residual.as_ref().iter().all(|r| r.abs() <= tol * scale) {
            return Ok(it);
        }
        if it >= max_iter {
            return Err(x.unsettled(it, &residual, scale));
        }
        it += 1;
        let step = x.newton_step(&residual, scale)?;
        if !descend(x, step, &residual)? {
            settle_worst(x, &residual, tol, scale, it)?;
        }
    }
}

/// Backtracking along the Newton `step` (`None` if the Jacobian is singular): the first
/// length, halving down to `NEWTON_MIN_STEP`, whose residual's 2-norm is smaller. Whether
/// one was found (the iterate moved there).
fn descend<S: SquareRoots>(
    x: &mut S,
    step: Option<S::Vector>,
    residual: &S::Vector,
) -> Result<bool, SimError> {
    let Some(step) = step else {
        return Ok(false);
    };
    let norm0 = residual.as_ref().iter().map(|r| r * r).sum::<f64>().sqrt();
    let mut length = 1.0;
    while length >= NEWTON_MIN_STEP {
        let norm = x.trial(&step, length)?;
        if norm <= (1.0 - 1e-4 * length) * norm0 {
            x.accept();
            return Ok(true);
        }
        length *= 0.5;
    }
    Ok(false)
}

/// No descent along the Newton direction (a local minimum of the residual across a
/// reaction's sign change, or a kink): settle the worst joint alone by bracketing, or fail
/// naming the joints that did not settle.
fn settle_worst<S: SquareRoots>(
    x: &mut S,
    residual: &S::Vector,
    tol: f64,
    scale: f64,
    it: u32,
) -> Result<(), SimError> {
    let r = residual.as_ref();
    let worst =
        (0..r.len())
            .filter(|&ji| x.is_active(ji))
            .fold(None, |w: Option<usize>, ji| match w {
                Some(b) if r[b].abs() >= r[ji].abs() => Some(b),
                _ => Some(ji),
            });
    let settled = match worst {
        Some(j) => {
            let start = x.u(j);
            bracket(|v| x.alone(j, v), start, tol, scale)?
        }
        None => None,
    };
    let (Some(j), Some(uj)) = (worst, settled) else {
        return Err(x.unsettled(it, residual, scale));
    };
    x.settle_joint(j, uj)
}

/// A root of one joint's `rho(x) = N - x^2` in `x = sqrt(W)` (from `start`, its current
/// value) by regula falsi (Illinois) on a bracket, to a quarter of `tol` times `scale`.
/// `rho(0) >= 0` always (a normal load is a magnitude) and `rho` falls below zero once `x^2`
/// outgrows the load the friction can cause, so a bracket `[0, x]` exists: unlike Newton,
/// this cannot stall at a local minimum of the residual. `None` if no bracket is found (the
/// caller reports the joint as unsettled); a law's failure is passed on.
fn bracket(
    mut rho: impl FnMut(f64) -> Result<f64, SimError>,
    start: f64,
    tol: f64,
    scale: f64,
) -> Result<Option<f64>, SimError> {
    let tol_n = 0.25 * tol * scale;
    let (mut lo, mut r_lo) = (0.0, rho(0.0)?);
    if r_lo <= tol_n {
        return Ok(Some(0.0));
    }
    let (mut hi, mut r_hi) = (start, rho(start)?);
    let mut grow = 0;
    while r_hi > 0.0 {
        // Beyond every root: the load the friction can cause grows slower than x^2.
        grow += 1;
        if grow > 60 || !r_hi.is_finite() {
            return Ok(None);
        }
        lo = hi;
        r_lo = r_hi;
        hi = 2.0 * hi + 1e-3 * scale.sqrt();
        r_hi = rho(hi)?;
    }
    // Illinois: regula falsi that halves the weight of an end kept twice in a row.
    let mut kept = 0_i32;
    for _ in 0..200 {
        let x = if r_lo - r_hi > 0.0 {
            (lo * -r_hi + hi * r_lo) / (r_lo - r_hi)
        } else {
            0.5 * (lo + hi)
        };
        let r = rho(x)?;
        if r.abs() <= tol_n || hi - lo <= 4.0 * f64::EPSILON * hi {
            return Ok(Some(x));
        }
        if r > 0.0 {
            lo = x;
            r_lo = r;
            if kept > 0 {
                r_hi *= 0.5;
            }
            kept = 1;
        } else {
            hi = x;
            r_hi = r;
            if kept < 0 {
                r_lo *= 0.5;
            }
            kept = -1;
        }
    }
    Ok(None)
}

/// The reactions where phase 2 began: their directions give the law inputs' components.
struct Base {
    comps: [Vector2<f64>; 5],
    normals: [f64; 5],
    moment: f64,
}

impl Base {
    /// Set joint `id`'s law input to the normal load `w` (N), its components along the base
    /// reaction's direction.
    fn load_input(&self, input: &mut LawInput, id: JointId, w: f64) {
        let moment = if id == JointId::Piston {
            self.moment
        } else {
            0.0
        };
        scaled_input(input, self.comps[id], self.normals[id], moment, w);
    }
}

/// Phase 2's iterate on the single-cylinder rig: the unknowns `u = sqrt(W)`, which joints
/// carry laws, the round at `u` and the pending trial, with the problem and the rates the
/// rounds write.
struct Iterate<'s, 'a> {
    sim: &'s Simulation,
    p: &'s mut Problem<'a>,
    rates: &'s mut [f64],
    base: Base,
    active: [bool; 5],
    u: [f64; 5],
    cur: Settled,
    trial: Option<([f64; 5], Settled)>,
}

impl SquareRoots for Iterate<'_, '_> {
    type Vector = [f64; 5];

    fn is_active(&self, j: usize) -> bool {
        self.active[j]
    }

    fn u(&self, j: usize) -> f64 {
        self.u[j]
    }

    fn residual(&self) -> [f64; 5] {
        std::array::from_fn(|ji| {
            if self.active[ji] {
                self.cur.normals[ji] - self.u[ji] * self.u[ji]
            } else {
                0.0
            }
        })
    }

    fn scale(&self) -> f64 {
        self.cur.normals.iter().fold(1.0_f64, |m, n| m.max(*n))
    }

    fn newton_step(
        &mut self,
        residual: &[f64; 5],
        scale: f64,
    ) -> Result<Option<[f64; 5]>, SimError> {
        let step = self
            .jacobian(scale)?
            .lu()
            .solve(&Vector5::from_fn(|i, _| -residual[i]));
        Ok(step.map(|s| std::array::from_fn(|i| s[i])))
    }

    fn trial(&mut self, step: &[f64; 5], length: f64) -> Result<f64, SimError> {
        let trial_u: [f64; 5] = std::array::from_fn(|ji| (self.u[ji] + length * step[ji]).abs());
        let trial = self
            .sim
            .round(self.p, &self.base, &trial_u, &mut *self.rates)?;
        let norm = (0..5)
            .filter(|&ji| self.active[ji])
            .map(|ji| (trial.normals[ji] - trial_u[ji] * trial_u[ji]).powi(2))
            .sum::<f64>()
            .sqrt();
        self.trial = Some((trial_u, trial));
        Ok(norm)
    }

    fn accept(&mut self) {
        if let Some((u, cur)) = self.trial.take() {
            self.u = u;
            self.cur = cur;
        }
    }

    fn alone(&mut self, j: usize, x: f64) -> Result<f64, SimError> {
        let id = JointId::ALL[j];
        self.base.load_input(&mut self.p.inputs[id], id, x * x);
        let mut totals = self.cur.totals;
        totals[j] = self.sim.joint_force(self.p, id, None)?;
        let (_, re) = self.p.solve(&loads_from(&totals));
        Ok(self.sim.normals(&re)[j] - x * x)
    }

    fn settle_joint(&mut self, j: usize, x: f64) -> Result<(), SimError> {
        self.u[j] = x;
        self.cur = self
            .sim
            .round(self.p, &self.base, &self.u, &mut *self.rates)?;
        Ok(())
    }

    fn unsettled(&self, iterations: u32, residual: &[f64; 5], scale: f64) -> SimError {
        let changes = residual.map(f64::abs);
        self.sim
            .no_convergence(self.p.t, iterations, &changes, scale)
    }
}

impl Iterate<'_, '_> {
    /// Jacobian of `rho(u) = N(u^2) - u^2` by one-sided differences; joints without laws keep
    /// an identity row.
    fn jacobian(&mut self, scale: f64) -> Result<Matrix5<f64>, SimError> {
        let mut jac = Matrix5::<f64>::identity();
        for j in (0..5).filter(|&j| self.active[j]) {
            let h = NEWTON_FD_STEP * self.u[j].max(scale.sqrt());
            let uj = self.u[j] + h;
            let id = JointId::ALL[j];
            self.base.load_input(&mut self.p.inputs[id], id, uj * uj);
            let mut totals = self.cur.totals;
            totals[j] = self.sim.joint_force(self.p, id, None)?;
            let (_, re) = self.p.solve(&loads_from(&totals));
            let n = self.sim.normals(&re);
            for i in (0..5).filter(|&i| self.active[i]) {
                let own = if i == j { 2.0 * self.u[j] + h } else { 0.0 };
                jac[(i, j)] = (n[i] - self.cur.normals[i]) / h - own;
            }
        }
        Ok(jac)
    }
}

impl Simulation {
    /// Phase 2 of the friction/reaction iteration, entered when the plain iteration does not
    /// contract (see `plain_iteration_stalls`): a damped Newton iteration on the normal loads
    /// the laws see, `W`, solving `N(W) = W` where `N` is one round of laws and reactions.
    ///
    /// The unknowns are `u = sqrt(W)` per joint that carries laws. A law whose force grows like
    /// `sqrt(W)` (hydrodynamic friction) has an unbounded load sensitivity at `W = 0`, which makes
    /// the plain iteration (and Newton in `W`) oscillate; in `u` it is smooth, and laws smooth in
    /// `W` stay smooth. The Jacobian of `N(u^2) - u^2` comes from one-sided differences, one
    /// joint's laws and one re-combination of the multipliers per column (the kinematics stay
    /// factorised); each step is halved until the residual's 2-norm decreases, so a step over
    /// the kink where a reaction changes sign cannot make it diverge (`settle`). The law
    /// inputs' reaction components keep the direction of the reactions at entry, scaled to the
    /// trial load.
    ///
    /// Converged by the same test as phase 1: every law-bearing joint's `|N(W) - W|` within
    /// `solver.friction_tol` times the largest normal load. The result is that last round: its
    /// loads are exactly those of the final solve and of the powers recorded in `rates`.
    pub(super) fn settle_by_newton(
        &self,
        p: &mut Problem<'_>,
        it: u32,
        entry: &Reactions,
        entry_normals: &[f64; 5],
        rates: &mut [f64],
    ) -> Result<Settled, SimError> {
        let base = Base {
            comps: self.components(entry),
            normals: *entry_normals,
            moment: entry.slide_moment_nm,
        };
        p.reaction_n = entry_normals.iter().fold(0.0, |m, n| m.max(*n));
        let u: [f64; 5] = std::array::from_fn(|ji| entry_normals[ji].sqrt());
        let cur = self.round(p, &base, &u, rates)?;
        let mut x = Iterate {
            sim: self,
            p,
            rates,
            base,
            active: std::array::from_fn(|ji| !self.joints[ji].laws.is_empty()),
            u,
            cur,
            trial: None,
        };
        let iterations = settle(&mut x, it, self.max_iter, self.tol)?;
        Ok(Settled {
            iterations,
            ..x.cur
        })
    }

    /// One round of phase 2: every law evaluated at the loads `u^2` (powers, regimes and loads
    /// recorded in `rates`), then the reactions under the resulting friction loads.
    fn round(
        &self,
        p: &mut Problem<'_>,
        base: &Base,
        u: &[f64; 5],
        rates: &mut [f64],
    ) -> Result<Settled, SimError> {
        rates[self.layout().regimes()].fill(0.0);
        let mut totals = [0.0; 5];
        let mut k = 0;
        for joint in &self.joints {
            let id = joint.id;
            if !joint.laws.is_empty() {
                base.load_input(&mut p.inputs[id], id, u[id] * u[id]);
                totals[id] = self.joint_force(p, id, Some((rates, k)))?;
            }
            k += joint.laws.len();
        }
        let loads = loads_from(&totals);
        let (alpha, re) = p.solve(&loads);
        let normals = self.normals(&re);
        check_solve(p.t, alpha, &re, &normals)?;
        Ok(Settled {
            alpha,
            normals,
            re,
            loads,
            totals,
            iterations: 0,
        })
    }
}
