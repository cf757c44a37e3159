//! Phase 2 of the friction/reaction iteration: a damped Newton iteration on the square roots
//! of the normal loads, with a bracketing fallback per joint, for laws whose load sensitivity
//! is unbounded at zero load (docs/solver.md). Entered only when phase 1 is seen to stall.

use nalgebra::{Matrix5, Vector2, Vector5};
use tribo_plugin_api::LawInput;

use super::error::SimError;
use super::evaluate::{check_solve, loads_from, Problem, Settled};
use super::joint::JointId;
use super::Simulation;
use crate::mechanics::Reactions;

/// Relative finite-difference step of phase 2's Jacobian, in `u = sqrt(W)` (about the square
/// root of the machine epsilon: half the digits for the derivative, ample for Newton).
const NEWTON_FD_STEP: f64 = 1.5e-8;
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
        let f = if self.normals[id] > 0.0 {
            w / self.normals[id]
        } else {
            0.0
        };
        input.normal_load_n = w;
        input.reaction_x_n = self.comps[id].x * f;
        input.reaction_y_n = self.comps[id].y * f;
        input.reaction_moment_nm = if id == JointId::Piston {
            self.moment
        } else {
            0.0
        };
    }
}

/// Phase 2's iterate: the unknowns `u = sqrt(W)`, which joints carry laws, and the round at `u`.
struct Iterate<'b> {
    base: &'b Base,
    active: [bool; 5],
    u: [f64; 5],
    cur: Settled,
}

impl Iterate<'_> {
    /// The residual `N(u^2) - u^2` per joint with laws (0 elsewhere).
    fn residual(&self) -> [f64; 5] {
        std::array::from_fn(|ji| {
            if self.active[ji] {
                self.cur.normals[ji] - self.u[ji] * self.u[ji]
            } else {
                0.0
            }
        })
    }

    /// The joints with laws.
    fn active(&self) -> impl Iterator<Item = usize> + '_ {
        (0..5).filter(|&ji| self.active[ji])
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
    /// the kink where a reaction changes sign cannot make it diverge. The law inputs' reaction
    /// components keep the direction of the reactions at entry, scaled to the trial load.
    ///
    /// Converged by the same test as phase 1: every law-bearing joint's `|N(W) - W|` within
    /// `solver.friction_tol` times the largest normal load. The result is that last round: its
    /// loads are exactly those of the final solve and of the powers recorded in `rates`.
    pub(super) fn settle_by_newton(
        &self,
        p: &mut Problem<'_>,
        mut it: u32,
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
        let active = std::array::from_fn(|ji| !self.joints[ji].laws.is_empty());
        let mut x = Iterate {
            base: &base,
            active,
            u,
            cur,
        };
        loop {
            let residual = x.residual();
            let scale = x.cur.normals.iter().fold(1.0_f64, |m, n| m.max(*n));
            if residual.iter().all(|r| r.abs() <= self.tol * scale) {
                return Ok(Settled {
                    iterations: it,
                    ..x.cur
                });
            }
            if it >= self.max_iter {
                let changes = residual.map(f64::abs);
                return Err(self.no_convergence(p.t, it, &changes, scale));
            }
            it += 1;
            let step = self
                .jacobian(p, &x, scale)?
                .lu()
                .solve(&Vector5::from_fn(|i, _| -residual[i]));
            if !self.descend(p, &mut x, step, &residual, rates)? {
                self.settle_worst(p, &mut x, &residual, scale, it, rates)?;
            }
        }
    }

    /// Jacobian of `rho(u) = N(u^2) - u^2` by one-sided differences; joints without laws keep
    /// an identity row.
    fn jacobian(
        &self,
        p: &mut Problem<'_>,
        x: &Iterate<'_>,
        scale: f64,
    ) -> Result<Matrix5<f64>, SimError> {
        let mut jac = Matrix5::<f64>::identity();
        for j in x.active() {
            let h = NEWTON_FD_STEP * x.u[j].max(scale.sqrt());
            let uj = x.u[j] + h;
            let id = JointId::ALL[j];
            x.base.load_input(&mut p.inputs[id], id, uj * uj);
            let mut totals = x.cur.totals;
            totals[j] = self.joint_force(p, id, None)?;
            let (_, re) = p.solve(&loads_from(&totals));
            let n = self.normals(&re);
            for i in x.active() {
                let own = if i == j { 2.0 * x.u[j] + h } else { 0.0 };
                jac[(i, j)] = (n[i] - x.cur.normals[i]) / h - own;
            }
        }
        Ok(jac)
    }

    /// Backtracking along the Newton `step` (`None` if the Jacobian is singular): the first
    /// length, halving down to `NEWTON_MIN_STEP`, whose residual's 2-norm is smaller. Whether
    /// one was found (the iterate moved there).
    fn descend(
        &self,
        p: &mut Problem<'_>,
        x: &mut Iterate<'_>,
        step: Option<Vector5<f64>>,
        residual: &[f64; 5],
        rates: &mut [f64],
    ) -> Result<bool, SimError> {
        let Some(step) = step else {
            return Ok(false);
        };
        let norm0 = residual.iter().map(|r| r * r).sum::<f64>().sqrt();
        let mut length = 1.0;
        while length >= NEWTON_MIN_STEP {
            let trial_u: [f64; 5] = std::array::from_fn(|ji| (x.u[ji] + length * step[ji]).abs());
            let trial = self.round(p, x.base, &trial_u, rates)?;
            let norm = x
                .active()
                .map(|ji| (trial.normals[ji] - trial_u[ji] * trial_u[ji]).powi(2))
                .sum::<f64>()
                .sqrt();
            if norm <= (1.0 - 1e-4 * length) * norm0 {
                x.u = trial_u;
                x.cur = trial;
                return Ok(true);
            }
            length *= 0.5;
        }
        Ok(false)
    }

    /// No descent along the Newton direction (a local minimum of the residual across a
    /// reaction's sign change, or a kink): settle the worst joint alone by bracketing, or fail
    /// naming the joints that did not settle.
    fn settle_worst(
        &self,
        p: &mut Problem<'_>,
        x: &mut Iterate<'_>,
        residual: &[f64; 5],
        scale: f64,
        it: u32,
        rates: &mut [f64],
    ) -> Result<(), SimError> {
        let worst = x.active().fold(None, |w: Option<usize>, ji| match w {
            Some(b) if residual[b].abs() >= residual[ji].abs() => Some(b),
            _ => Some(ji),
        });
        let settled = match worst {
            Some(j) => self.bracket_joint(p, x.base, &x.cur, &x.u, j, scale)?,
            None => None,
        };
        let (Some(j), Some(uj)) = (worst, settled) else {
            let changes = residual.map(f64::abs);
            return Err(self.no_convergence(p.t, it, &changes, scale));
        };
        x.u[j] = uj;
        x.cur = self.round(p, x.base, &x.u, rates)?;
        Ok(())
    }

    /// Settle joint `j` alone, the other joints' loads held at `u^2`: a root of
    /// `rho_j(x) = N_j - x^2` in `x = sqrt(W_j)` by regula falsi (Illinois) on a bracket.
    /// `rho_j(0) >= 0` always (a normal load is a magnitude) and `rho_j` falls below zero once
    /// `x^2` outgrows the load the friction can cause, so a bracket `[0, x]` exists: unlike
    /// Newton, this cannot stall at a local minimum of the residual. `None` if no bracket is
    /// found (the caller reports the joint as unsettled); a law's failure is passed on.
    fn bracket_joint(
        &self,
        p: &mut Problem<'_>,
        base: &Base,
        cur: &Settled,
        u: &[f64; 5],
        j: usize,
        scale: f64,
    ) -> Result<Option<f64>, SimError> {
        let mut rho = |x: f64| -> Result<f64, SimError> {
            base.load_input(&mut p.inputs[j], JointId::ALL[j], x * x);
            let mut totals = cur.totals;
            totals[j] = self.joint_force(p, JointId::ALL[j], None)?;
            let (_, re) = p.solve(&loads_from(&totals));
            Ok(self.normals(&re)[j] - x * x)
        };
        let tol_n = 0.25 * self.tol * scale;
        let (mut lo, mut r_lo) = (0.0, rho(0.0)?);
        if r_lo <= tol_n {
            return Ok(Some(0.0));
        }
        let (mut hi, mut r_hi) = (u[j], rho(u[j])?);
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
