//! Phase 2 of an engine's friction/reaction iteration (`docs/solver.md`, `docs/engines.md`):
//! the single-cylinder rig's damped Newton iteration on `u = sqrt(W)` (`newton.rs`, whose
//! `settle` runs it) for any number of joints. Its unknowns are the law-bearing joints' loads
//! (every main bearing and every cylinder's big end, small end and piston that carries laws);
//! the Jacobian is dense over them, one column per joint from one round of that joint's laws
//! and one solve of the crank train's reactions (the kinematics stay as computed once per
//! evaluation).

use nalgebra::{DMatrix, DVector, Vector2};

use super::engine_run::{EngineSimulation, Work};
use super::error::SimError;
use super::evaluate::Point;
use super::newton::{scaled_input, settle, SquareRoots, NEWTON_FD_STEP};
use super::rates::RateLayout;
use crate::engine::{TrainLoads, TrainReactions};

/// One round's values per joint: the unknowns `u = sqrt(W)` the laws were evaluated at, the
/// normal loads `N` of the solve under their friction and the law totals per joint.
#[derive(Clone)]
struct Round {
    u: Vec<f64>,
    normals: Vec<f64>,
    totals: Vec<f64>,
}

/// Phase 2's iterate on an engine. A round writes the run's `Work` (law inputs, rates, friction
/// loads, reactions): every path to convergence ends with a round at the current `u` (the
/// first, an accepted trial, or the one after bracketing), so what `Work` holds then is the
/// converged round's, as after phase 1. Jacobian columns and bracketing solve into scratch.
struct EngineIterate<'s> {
    sim: &'s EngineSimulation,
    w: &'s mut Work,
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
    loads: TrainLoads,
    re: TrainReactions,
    normals: Vec<f64>,
}

impl EngineIterate<'_> {
    /// A round at the trial's `u` (`trial`) or the current one's: every law-bearing joint's laws
    /// at its load `u^2` (rates recorded), the friction loads, the reactions and normal loads.
    fn round(&mut self, trial: bool) -> Result<(), SimError> {
        let r = if trial {
            &mut self.trial
        } else {
            &mut self.cur
        };
        let w = &mut *self.w;
        let mut k = 0;
        for (ji, j) in self.sim.joints.iter().enumerate() {
            r.totals[ji] = 0.0;
            if !j.laws.is_empty() {
                let input = &mut w.inputs[ji];
                let load = r.u[ji] * r.u[ji];
                scaled_input(
                    input,
                    self.comps[ji],
                    self.entry_normals[ji],
                    self.moments[ji],
                    load,
                );
                let record = Some((&mut w.rates[..], k));
                r.totals[ji] = self.sim.joint_force(j, input, self.reaction_n, record)?;
            }
            k += j.laws.len();
        }
        self.sim.loads_from_totals(&r.totals, &mut w.loads);
        w.alpha = self.sim.solve(&w.kin, self.at.control, &w.loads, &mut w.re);
        self.sim.normals_into(&w.re, &mut r.normals);
        self.sim.check_normals(self.at.t, &r.normals)
    }

    /// The normal loads (into the scratch `normals`) with joint `j`'s laws at the load `load`
    /// and every other joint's friction that of the current round.
    fn column(&mut self, j: usize, load: f64) -> Result<(), SimError> {
        let input = &mut self.w.inputs[j];
        scaled_input(
            input,
            self.comps[j],
            self.entry_normals[j],
            self.moments[j],
            load,
        );
        self.totals.clone_from(&self.cur.totals);
        self.totals[j] = self
            .sim
            .joint_force(&self.sim.joints[j], input, self.reaction_n, None)?;
        self.sim.loads_from_totals(&self.totals, &mut self.loads);
        self.sim
            .solve(&self.w.kin, self.at.control, &self.loads, &mut self.re);
        self.sim.normals_into(&self.re, &mut self.normals);
        Ok(())
    }
}

impl SquareRoots for EngineIterate<'_> {
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

impl EngineSimulation {
    /// Phase 2 of the friction/reaction iteration at `at`, entered after phase 1's iteration
    /// `it` was seen to stall (`plain_iteration_stalls`), from the reactions and normal loads
    /// of its last solve (in `w`): `settle`'s damped Newton iteration on the square roots of
    /// the law-bearing joints' loads, the law inputs' reaction components along the directions
    /// of those entry reactions, scaled to the trial load. Converged by the same test as the
    /// single-cylinder rig's phase 2 (every law-bearing joint's `|N(W) - W|` within
    /// `solver.friction_tol` of the largest normal load), within `solver.friction_max_iter`
    /// iterations in all; else a `NoConvergence` naming the joints and their laws.
    ///
    /// On return `w` holds the final round, as after phase 1: the law inputs at the loads the
    /// laws saw, their rates, the friction loads, the reactions and normal loads of the solve
    /// under them, and the motor power.
    pub(super) fn settle_by_newton(
        &self,
        at: &Point,
        w: &mut Work,
        it: u32,
    ) -> Result<(), SimError> {
        let n = self.joints.len();
        let (comps, moments): (Vec<_>, Vec<_>) =
            (0..n).map(|ji| self.joint_reaction(ji, &w.re)).unzip();
        let entry_normals = w.normals.clone();
        let start = Round {
            u: entry_normals.iter().map(|n| n.sqrt()).collect(),
            normals: vec![0.0; n],
            totals: vec![0.0; n],
        };
        let active = (0..n)
            .filter(|&ji| !self.joints[ji].laws.is_empty())
            .collect();
        let loads = w.loads.clone();
        let re = w.re.clone();
        let mut x = EngineIterate {
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
            loads,
            re,
            normals: Vec::with_capacity(n),
            w,
        };
        x.round(false)?;
        let iterations = settle(&mut x, it, self.max_iter, self.tol)?;
        debug_assert!(x
            .active
            .iter()
            .all(|&i| x.w.inputs[i].normal_load_n == x.cur.u[i] * x.cur.u[i]));
        let EngineIterate { w, cur, .. } = x;
        w.normals = cur.normals;
        w.max_it = w.max_it.max(iterations);
        w.rates[RateLayout::MOTOR] = w.re.drive_torque_nm * at.omega;
        Ok(())
    }
}
