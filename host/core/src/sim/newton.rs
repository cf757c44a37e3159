//! Phase 2 of the friction/reaction iteration: a damped Newton iteration on the square roots
//! of the normal loads, with a bracketing fallback per joint, for laws whose load sensitivity
//! is unbounded at zero load (docs/solver.md). Entered only when phase 1 is seen to stall.
//!
//! The iteration itself (`settle`: convergence test, backtracking, bracketing fallback) is
//! written over a `SquareRoots` system; the rig's (`Iterate`, below) has as unknowns the
//! law-bearing joints' loads of any crank train, its Jacobian dense over them, one column per
//! joint from one round of that joint's laws and one solve of the crank model's reactions
//! (the kinematics stay as computed once per evaluation).

use nalgebra::{DMatrix, DVector, Vector2};
use tribo_plugin_api::loader::inflight;
use tribo_plugin_api::LawInput;

use super::bind::{LawMemory, Record};
use super::error::SimError;
use super::evaluate::{check_solve, Eval, Point, Work};
use super::Simulation;

/// Relative finite-difference step of phase 2's Jacobian, in `u = sqrt(W)` (about the square
/// root of the machine epsilon: half the digits for the derivative, ample for Newton).
pub(super) const NEWTON_FD_STEP: f64 = 1.5e-8;
/// Shortest step phase 2's backtracking tries, as a fraction of the Newton step, before it
/// gives up (seven halvings).
const NEWTON_MIN_STEP: f64 = 1.0 / 128.0;
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

/// One round's values per joint: the unknowns `u = sqrt(W)` the laws were evaluated at, the
/// normal loads `N` of the solve under their friction, the law totals per joint and the
/// solve's crank acceleration.
#[derive(Clone)]
struct Round {
    u: Vec<f64>,
    normals: Vec<f64>,
    totals: Vec<f64>,
    alpha: f64,
}

/// Phase 2's iterate. A round writes the run's scratch (law inputs, the crank model's
/// reactions) and the evaluation's rates: every path to convergence ends with a round at the
/// current `u` (the first, an accepted trial, or the one after bracketing), so what they hold
/// then is the converged round's, as after phase 1. Jacobian columns and bracketing solve
/// without recording.
struct Iterate<'s> {
    sim: &'s Simulation,
    w: &'s mut Work,
    rates: &'s mut [f64],
    regimes: &'s mut [u8],
    at: &'s Point,
    /// The largest normal load where phase 2 began: the bound on a law's force.
    reaction_n: f64,
    /// Per joint: the reaction's direction (components), normal load and moment at entry.
    comps: Vec<Vector2<f64>>,
    entry_normals: Vec<f64>,
    moments: Vec<f64>,
    /// The law-bearing joints, in joint order (the Jacobian's rows and columns).
    active: Vec<usize>,
    cur: Round,
    trial: Round,
    /// Scratch of a Jacobian column or a bracketing evaluation.
    totals: Vec<f64>,
    normals: Vec<f64>,
}

impl Iterate<'_> {
    /// A round at the trial's `u` (`trial`) or the current one's: every law-bearing joint's laws
    /// at its load `u^2` (rates recorded), the reactions and normal loads under their friction.
    fn round(&mut self, trial: bool) -> Result<(), SimError> {
        let r = if trial {
            &mut self.trial
        } else {
            &mut self.cur
        };
        let (sim, w) = (self.sim, &mut *self.w);
        let layout = sim.layout();
        let mut marks = inflight::round();
        for (ji, j) in sim.joints.iter().enumerate() {
            r.totals[ji] = 0.0;
            if !j.laws.is_empty() {
                let input = &mut w.inputs[ji];
                let load = r.u[ji] * r.u[ji];
                let moment = self.moments[ji];
                scaled_input(input, self.comps[ji], self.entry_normals[ji], moment, load);
                let record = Some(Record {
                    rates: &mut *self.rates,
                    regimes: &mut *self.regimes,
                });
                let mut laws = LawMemory {
                    states: &w.states,
                    reuse: &mut w.reuse,
                };
                r.totals[ji] = j.force(
                    input,
                    &mut laws,
                    self.reaction_n,
                    record,
                    layout,
                    &mut marks,
                )?;
            }
        }
        r.alpha = w.crank.solve(self.at.control, &sim.roles, &r.totals);
        let loads = w.crank.normals_against(&sim.roles, &mut r.normals, &w.prev);
        check_solve(
            sim,
            self.at.t,
            (r.alpha, w.crank.drive_torque()),
            &r.normals,
            loads.finite,
        )
    }

    /// The normal loads (into the scratch `normals`) with joint `j`'s laws at the load `load`
    /// and every other joint's friction that of the current round.
    fn column(&mut self, j: usize, load: f64) -> Result<(), SimError> {
        let (sim, w) = (self.sim, &mut *self.w);
        let input = &mut w.inputs[j];
        scaled_input(
            input,
            self.comps[j],
            self.entry_normals[j],
            self.moments[j],
            load,
        );
        self.totals.clone_from(&self.cur.totals);
        let layout = sim.layout();
        let mut marks = inflight::round();
        let mut laws = LawMemory {
            states: &w.states,
            reuse: &mut w.reuse,
        };
        self.totals[j] =
            sim.joints[j].force(input, &mut laws, self.reaction_n, None, layout, &mut marks)?;
        w.crank.solve(self.at.control, &sim.roles, &self.totals);
        w.crank
            .normals_against(&sim.roles, &mut self.normals, &w.prev);
        Ok(())
    }
}

impl SquareRoots for Iterate<'_> {
    type Vector = Vec<f64>;

    fn is_active(&self, j: usize) -> bool {
        !self.sim.joints[j].laws.is_empty()
    }

    fn u(&self, j: usize) -> f64 {
        self.cur.u[j]
    }

    fn residual(&self) -> Vec<f64> {
        let mut r = vec![0.0; self.cur.u.len()];
        for &i in &self.active {
            r[i] = self.cur.normals[i] - self.cur.u[i] * self.cur.u[i];
        }
        r
    }

    fn scale(&self) -> f64 {
        self.cur.normals.iter().fold(1.0_f64, |m, n| m.max(*n))
    }

    fn newton_step(
        &mut self,
        residual: &Vec<f64>,
        scale: f64,
    ) -> Result<Option<Vec<f64>>, SimError> {
        let n = self.active.len();
        let mut jac = DMatrix::<f64>::zeros(n, n);
        for c in 0..n {
            let j = self.active[c];
            let h = NEWTON_FD_STEP * self.cur.u[j].max(scale.sqrt());
            let uj = self.cur.u[j] + h;
            self.column(j, uj * uj)?;
            for (row, &i) in self.active.iter().enumerate() {
                let own = if i == j { 2.0 * self.cur.u[j] + h } else { 0.0 };
                jac[(row, c)] = (self.normals[i] - self.cur.normals[i]) / h - own;
            }
        }
        let rhs = DVector::from_iterator(n, self.active.iter().map(|&i| -residual[i]));
        Ok(jac.lu().solve(&rhs).map(|step| {
            let mut full = vec![0.0; residual.len()];
            for (row, &i) in self.active.iter().enumerate() {
                full[i] = step[row];
            }
            full
        }))
    }

    fn trial(&mut self, step: &Vec<f64>, length: f64) -> Result<f64, SimError> {
        for (t, (u, s)) in self.trial.u.iter_mut().zip(self.cur.u.iter().zip(step)) {
            *t = (u + length * s).abs();
        }
        self.round(true)?;
        let t = &self.trial;
        Ok(self
            .active
            .iter()
            .map(|&i| (t.normals[i] - t.u[i] * t.u[i]).powi(2))
            .sum::<f64>()
            .sqrt())
    }

    fn accept(&mut self) {
        std::mem::swap(&mut self.cur, &mut self.trial);
    }

    fn alone(&mut self, j: usize, x: f64) -> Result<f64, SimError> {
        self.column(j, x * x)?;
        Ok(self.normals[j] - x * x)
    }

    fn settle_joint(&mut self, j: usize, x: f64) -> Result<(), SimError> {
        self.cur.u[j] = x;
        self.round(false)
    }

    fn unsettled(&self, iterations: u32, residual: &Vec<f64>, scale: f64) -> SimError {
        let changes: Vec<f64> = residual.iter().map(|r| r.abs()).collect();
        self.sim
            .no_convergence(self.at.t, iterations, &changes, scale)
    }
}

impl Simulation {
    /// Phase 2 of the friction/reaction iteration at `at`, entered after phase 1's iteration
    /// `it` was seen to stall (`trend::plain_iteration_stalls`), from the reactions and normal loads
    /// of its last solve (the crank model's, and `e.normals`): a damped Newton iteration on the
    /// normal loads the laws see, `W`, solving `N(W) = W` where `N` is one round of laws and
    /// reactions.
    ///
    /// The unknowns are `u = sqrt(W)` per joint that carries laws. A law whose force grows like
    /// `sqrt(W)` (hydrodynamic friction) has an unbounded load sensitivity at `W = 0`, which makes
    /// the plain iteration (and Newton in `W`) oscillate; in `u` it is smooth, and laws smooth in
    /// `W` stay smooth. The Jacobian of `N(u^2) - u^2` comes from one-sided differences, one
    /// joint's laws and one solve of the reactions per column (the kinematics stay
    /// factorised); each step is halved until the residual's 2-norm decreases, so a step over
    /// the kink where a reaction changes sign cannot make it diverge (`settle`). The law
    /// inputs' reaction components keep the direction of the reactions at entry, scaled to the
    /// trial load.
    ///
    /// Converged when every law-bearing joint's `|N(W) - W|` is within `solver.friction_tol`
    /// times the largest normal load, within `solver.friction_max_iter` iterations in all;
    /// else a `NoConvergence` naming the joints and their laws. On return the scratch and `e`
    /// hold the final round, as after phase 1: the law inputs at the loads the laws saw, their
    /// rates, the reactions and normal loads of the solve under their friction. Returns the
    /// crank acceleration of that solve and the iteration count.
    pub(super) fn settle_by_newton(
        &self,
        at: &Point,
        w: &mut Work,
        e: &mut Eval,
        it: u32,
    ) -> Result<(f64, u32), SimError> {
        let n = self.joints.len();
        let (comps, moments): (Vec<_>, Vec<_>) =
            self.joints.iter().map(|j| w.crank.reaction(j.role)).unzip();
        let entry_normals = e.normals.to_vec();
        let start = Round {
            u: entry_normals.iter().map(|n| n.sqrt()).collect(),
            normals: vec![0.0; n],
            totals: vec![0.0; n],
            alpha: 0.0,
        };
        let active = (0..n)
            .filter(|&ji| !self.joints[ji].laws.is_empty())
            .collect();
        let mut x = Iterate {
            sim: self,
            reaction_n: entry_normals.iter().fold(0.0, |m: f64, n| m.max(*n)),
            at,
            comps,
            entry_normals,
            moments,
            active,
            trial: start.clone(),
            cur: start,
            totals: vec![0.0; n],
            normals: vec![0.0; n],
            w,
            rates: &mut e.rates,
            regimes: &mut e.regimes,
        };
        x.round(false)?;
        let iterations = settle(&mut x, it, self.max_iter, self.tol)?;
        let Iterate { cur, .. } = x;
        e.normals.copy_from_slice(&cur.normals);
        e.totals.copy_from_slice(&cur.totals);
        Ok((cur.alpha, iterations))
    }
}
