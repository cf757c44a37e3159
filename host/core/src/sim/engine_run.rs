//! A multi-cylinder engine's steady state (issue 18, `docs/engines.md`): each plateau speed
//! computed directly, the crank turning at exactly that speed, over one cycle (two
//! revolutions for a 4-stroke pressure), with the crank train of `crate::engine`, a law set's
//! laws on every main bearing and every cylinder's big end, small end and piston, and each
//! cylinder's gas pressure phase-shifted by the firing order.
//!
//! The friction/reaction iteration is the single-cylinder rig's (`evaluate`): the plain
//! fixed-point iteration (reactions, normal loads, laws, friction loads, until the normal
//! loads settle) and, where it is seen not to contract, phase 2's damped Newton iteration on
//! the square roots of the loads (`engine_newton.rs`). An iteration that does not settle ends
//! the run naming the joints.

use std::f64::consts::TAU;

use nalgebra::Vector2;
use tribo_plugin_api::loader::LawRegistry;
use tribo_plugin_api::{InnerBody, JointKind, LawInput, Regime};

use super::bind::{check_law, law_input, set_load, Bodies, BoundLaw, Contact, Instant};
use super::error::{SimError, Unsettled};
use super::evaluate::{crank_angle, Control, Point};
use super::newton::{Distance, Trend, Verdict};
use super::plateau::{plateau_values, Measured};
use super::rates::RateLayout;
use super::results::{
    DriveKind, EnergyBalance, Fmep, FmepBasis, GroupTotal, LawResult, LawTime, PlateauResult,
    RunResult,
};
use crate::cycle::Cycle;
use crate::engine::{
    cylinder_phases, geometry, top_dead_centres, CrankTrain, CylinderLoads, TrainKinematics,
    TrainLoads, TrainReactions,
};
use crate::gas::{cycle_angle, GasModel, LawGas};
use crate::model::{Drive, RigFile};

/// What a joint of an engine is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    /// Main bearing `i` (0-based).
    Main(usize),
    /// Cylinder `k`'s big end.
    BigEnd(usize),
    /// Cylinder `k`'s small end.
    SmallEnd(usize),
    /// Cylinder `k`'s piston slide.
    Piston(usize),
}

impl Role {
    /// The joint's group, naming it in a model error.
    fn group(self) -> &'static str {
        match self {
            Role::Main(_) => "main_*",
            Role::BigEnd(_) => "big_end_*",
            Role::SmallEnd(_) => "small_end_*",
            Role::Piston(_) => "piston_*",
        }
    }

    /// The cylinder whose gas state the joint's laws see (the mains: cylinder 1).
    fn cylinder(self) -> usize {
        match self {
            Role::Main(_) => 0,
            Role::BigEnd(k) | Role::SmallEnd(k) | Role::Piston(k) => k,
        }
    }

    fn kind(self) -> JointKind {
        match self {
            Role::Piston(_) => JointKind::Prismatic,
            _ => JointKind::Revolute,
        }
    }

    /// The inner member, as on the single-cylinder rig (`JointId::inner`): the crank pin
    /// (body B) in a big end, body A everywhere else.
    fn inner(self) -> InnerBody {
        match self {
            Role::BigEnd(_) => InnerBody::B,
            _ => InnerBody::A,
        }
    }
}

/// One joint of the engine with its contact geometry and laws.
pub(super) struct EngineJoint {
    pub(super) name: String,
    role: Role,
    /// What its laws are told about it besides the instant.
    contact: Contact,
    pub(super) laws: Vec<BoundLaw>,
}

/// A multi-cylinder engine ready for its steady state.
pub struct EngineSimulation {
    pub(super) rig_name: String,
    pub(super) train: CrankTrain,
    pub(super) joints: Vec<EngineJoint>,
    pub(super) cycle: Cycle,
    pub(super) temps: Vec<f64>,
    pub(super) viscosities: Vec<f64>,
    pub(super) step_rad: f64,
    pub(super) tol: f64,
    pub(super) max_iter: u32,
    /// Each cylinder's gas model with its own 4-stroke phase (none without `[gas]`).
    pub(super) gas: Vec<GasModel>,
    /// Each cylinder's 4-stroke phase from the firing order, rad.
    pub(super) phases: Vec<f64>,
    /// Each cylinder's piston position at its top dead centre, from the crank centre along
    /// its axis, m: `sqrt((l + r)^2 - e^2)` for the offset `e`.
    pub(super) tdc_position: Vec<f64>,
    pub(super) four_stroke: bool,
    displacement_m3: f64,
    pub(super) n_laws: usize,
    pub(super) stateful: bool,
    /// The drive of a transient run, its measurement window (s), the motoring torque's
    /// low-pass filter (Hz) and the largest step (s).
    pub(super) drive: Drive,
    pub(super) window_s: f64,
    pub(super) lowpass_hz: f64,
    pub(super) max_step_s: f64,
    /// Where a transient run reports its progress (permille of the cycle), if anyone reads it.
    pub(super) progress: Option<crate::observe::Position>,
}

impl EngineSimulation {
    /// Check an engine rig's laws against `registry` (each law known, its parameters' names,
    /// types and ranges) without creating an instance.
    pub fn check_laws(model: &RigFile, registry: &LawRegistry) -> Result<(), SimError> {
        for (name, _, laws) in joint_laws(model)? {
            for (i, l) in laws.iter().enumerate() {
                check_law(registry, l, &law_field(model, &name, i))?;
            }
        }
        Ok(())
    }

    /// Bind an engine rig's laws (from `registry`) and prepare its crank train, cycle and gas.
    pub fn new(model: &RigFile, registry: &LawRegistry) -> Result<Self, SimError> {
        let f = model;
        let setup = |message: String| SimError::Setup {
            at: None,
            field: "engine".into(),
            law: None,
            param: None,
            message,
        };
        let e = f
            .engine
            .as_ref()
            .ok_or_else(|| setup("not an engine rig: it has no [engine] table".into()))?;
        let geo = geometry(f).ok_or_else(|| setup("no engine".into()))?;
        let phases = cylinder_phases(
            &top_dead_centres(&geo),
            &e.firing_order,
            f.gas.cycle_angle_at_zero_deg.to_radians(),
        )
        .map_err(|err| setup(err.to_string()))?;
        let train = CrankTrain::new(geo).map_err(|err| setup(err.to_string()))?;
        let tdc_position = train
            .geometry()
            .cylinders
            .iter()
            .map(|c| {
                let reach = c.rod.length_m + train.geometry().crank_radius_m;
                let e = c.pin_offset_m + c.crank_offset_m;
                (reach * reach - e * e).sqrt()
            })
            .collect();
        let mut joints = Vec::new();
        let mut n_laws = 0;
        for (name, role, laws) in joint_laws(f)? {
            let (radius_m, length_m) = match role {
                Role::Main(i) => (e.mains[i].radius_m, e.mains[i].length_m),
                Role::BigEnd(_) => (f.joints.big_end.radius_m, f.joints.big_end.length_m),
                Role::SmallEnd(_) => (f.joints.small_end.radius_m, f.joints.small_end.length_m),
                Role::Piston(_) => (f.joints.piston.radius_m, f.joints.piston.length_m),
            };
            let laws = laws
                .iter()
                .enumerate()
                .map(|(i, l)| BoundLaw::bind(registry, l, &law_field(f, &name, i), &name))
                .collect::<Result<Vec<_>, _>>()?;
            n_laws += laws.len();
            joints.push(EngineJoint {
                contact: Contact {
                    kind: role.kind(),
                    radius_m,
                    length_m,
                    bearing: f.bearing_type(&name),
                    inner: role.inner(),
                },
                name,
                role,
                laws,
            });
        }
        // Each cylinder's gas: the rig's model with the cylinder's own 4-stroke phase,
        // evaluated at the cylinder's own crank angle.
        let gas: Vec<GasModel> = phases
            .iter()
            .filter_map(|phase| {
                let mut fk = f.clone();
                fk.gas.cycle_angle_at_zero_deg = phase.to_degrees();
                GasModel::from_rig(&fk)
            })
            .collect();
        let four_stroke = gas.iter().any(GasModel::four_stroke);
        let cycle = Cycle::new(&f.cycle.segments());
        let (temps, viscosities) = super::oil_schedule(f, &cycle);
        let stateful = joints
            .iter()
            .any(|j| j.laws.iter().any(BoundLaw::is_stateful));
        let n_cyl = e.cylinders.len() as f64;
        Ok(Self {
            rig_name: f.name.clone(),
            train,
            joints,
            cycle,
            temps,
            viscosities,
            step_rad: f.solver.step_deg.to_radians(),
            tol: f.solver.friction_tol,
            max_iter: f.solver.friction_max_iter,
            tdc_position,
            gas,
            phases,
            four_stroke,
            displacement_m3: n_cyl
                * std::f64::consts::PI
                * 0.25
                * f.geometry.bore_m
                * f.geometry.bore_m
                * 2.0
                * f.geometry.crank_radius_m,
            n_laws,
            stateful,
            drive: f.drive.clone(),
            window_s: f.measurement.window_s,
            lowpass_hz: f.measurement.lowpass_hz,
            max_step_s: f.solver.max_step_s,
            progress: None,
        })
    }

    /// The crank train.
    pub fn train(&self) -> &CrankTrain {
        &self.train
    }

    /// The engine's joint names in order (mains, then per cylinder big end, small end, piston).
    pub fn joint_names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// The run's FMEP definition: the displacement of all cylinders, 4-stroke when the gas
    /// pressure makes the cycle 4-stroke.
    pub fn fmep(&self) -> Fmep {
        Fmep {
            basis: if self.four_stroke {
                FmepBasis::FourStroke
            } else {
                FmepBasis::TwoStroke
            },
            displacement_m3: self.displacement_m3,
        }
    }

    fn cycle_angle(&self) -> f64 {
        if self.four_stroke {
            2.0 * TAU
        } else {
            TAU
        }
    }

    /// Where each accumulated quantity sits: the single-cylinder rig's layout over the
    /// engine's laws.
    pub(super) fn layout(&self) -> RateLayout {
        RateLayout { n: self.n_laws }
    }

    /// Steady state at every plateau speed (see the module): one cycle per plateau with
    /// stateless laws; with stateful laws cycles repeat until the mean torque repeats to 1e-9
    /// (at most 200). Every law's state starts from zero at every plateau.
    pub fn run_steady(&mut self) -> Result<RunResult, SimError> {
        let n_plateaus = self.cycle.plateaus().len();
        let mut results = Vec::with_capacity(n_plateaus);
        let (mut motor, mut dissipated, mut gas_work) = (0.0, 0.0, 0.0);
        let mut work = Work::new(self);
        let mut steps = 0_u64;
        for pi in 0..n_plateaus {
            let omega = self.cycle.plateaus()[pi].omega;
            self.reset_states();
            let (delta, t) = self.plateau(pi, omega, &mut work, &mut steps)?;
            motor += delta[RateLayout::MOTOR];
            gas_work += delta[self.layout().gas()];
            dissipated += delta[self.layout().powers()].iter().sum::<f64>();
            let cycle = self.cycle_angle();
            let window = Measured {
                delta,
                dt: cycle / omega,
                dtheta: cycle,
                window_s: [t - cycle / omega, t],
                revs: if self.four_stroke { 2 } else { 1 },
            };
            results.push(self.plateau_result(pi, omega, &window));
        }
        // The energy scale of the balance: the moving parts' energy at each plateau speed.
        let inertial: f64 = self
            .cycle
            .plateaus()
            .iter()
            .map(|p| {
                self.train
                    .mechanical_energy(std::f64::consts::FRAC_PI_2, p.omega)
                    .abs()
            })
            .sum();
        let energy = EnergyBalance::from_terms_with_gas(motor, 0.0, dissipated, gas_work)
            .relative_to(inertial);
        Ok(RunResult {
            rig: self.rig_name.clone(),
            drive: DriveKind::Steady,
            plateaus: results,
            fmep: self.fmep(),
            energy_residual_j: energy.residual_j,
            energy,
            steps,
            rejected_steps: 0,
            max_friction_iterations: work.max_it,
            warnings: Vec::new(),
            law_time: self.law_time(),
        })
    }

    /// Every law's state back to zero (each run, and each steady plateau, starts there).
    pub(super) fn reset_states(&mut self) {
        for l in self.joints.iter_mut().flat_map(|j| j.laws.iter_mut()) {
            l.state.iter_mut().for_each(|x| *x = 0.0);
        }
    }

    /// Calls and estimated time of every law so far.
    pub(super) fn law_time(&self) -> Vec<LawTime> {
        self.joints
            .iter()
            .flat_map(|j| j.laws.iter().map(|l| l.time(&j.name)))
            .collect()
    }

    /// One plateau: the accumulated quantities over its last cycle and the time at its end.
    fn plateau(
        &mut self,
        pi: usize,
        omega: f64,
        w: &mut Work,
        steps: &mut u64,
    ) -> Result<(Vec<f64>, f64), SimError> {
        let oil = (self.temps[pi], self.viscosities[pi]);
        let cycle = self.cycle_angle();
        let m = ((cycle / self.step_rad).ceil() as usize).max(16);
        let h = cycle / omega / m as f64;
        w.loads = TrainLoads {
            main_torque_nm: 0.0,
            cylinders: vec![CylinderLoads::default(); self.train.geometry().cylinders.len()],
        };
        let mut delta = vec![0.0; self.layout().len()];
        let mut last = f64::NAN;
        let mut t = 0.0;
        let max_cycles = if self.stateful { 200 } else { 1 };
        for _ in 0..max_cycles {
            delta.iter_mut().for_each(|x| *x = 0.0);
            // The periodic trapezoid rule on equally spaced samples (as the single-cylinder
            // steady state).
            for _ in 0..m {
                t += h;
                let at = Point::steady(t, h, omega * t, omega, oil);
                self.evaluate(&at, w)?;
                for (d, r) in delta.iter_mut().zip(&w.rates) {
                    *d += h * r;
                }
                if self.stateful {
                    self.commit(w)?;
                }
                *steps += 1;
            }
            let torque = delta[RateLayout::MOTOR] / cycle;
            if !self.stateful || (torque - last).abs() <= 1e-9 * torque.abs().max(1e-12) {
                break;
            }
            last = torque;
        }
        Ok((delta, t))
    }

    /// A joint's two bodies, body A first (`evaluate::joint_bodies` on the single-cylinder
    /// rig): a main bearing, crank and block; a big end, rod and crank; a small end, piston
    /// and rod (global angles, rad, and angular velocities, rad/s; a cylinder's piston is
    /// turned by its bank angle and does not rotate); a slide, the piston's position from the
    /// crank centre along the bore axis and its speed (m, m/s) and the cylinder. The relative
    /// velocity (`Bodies::relative`) is the crank speed, rod minus crank, piston minus rod,
    /// the piston speed.
    fn bodies(&self, role: Role, kin: &TrainKinematics) -> Bodies {
        let block = (0.0, 0.0);
        let crank = (kin.theta, kin.omega);
        let rod = |k: usize| {
            let c = &kin.cylinders[k];
            (self.bank_rad(k) + c.rod_angle_rad, c.rod_rate_rad_s)
        };
        match role {
            Role::Main(_) => Bodies { a: crank, b: block },
            Role::BigEnd(k) => Bodies {
                a: rod(k),
                b: crank,
            },
            Role::SmallEnd(k) => Bodies {
                a: (self.bank_rad(k), 0.0),
                b: rod(k),
            },
            Role::Piston(k) => Bodies {
                a: (
                    kin.cylinders[k].piston_position_m,
                    kin.cylinders[k].piston_speed_m_s,
                ),
                b: block,
            },
        }
    }

    /// Cylinder `k`'s bank angle (its bore axis from the vertical), rad.
    fn bank_rad(&self, k: usize) -> f64 {
        self.train.geometry().cylinders[k].bank_rad
    }

    /// The reaction joint `ji`'s laws see in `re`: its force and moment.
    pub(super) fn joint_reaction(&self, ji: usize, re: &TrainReactions) -> (Vector2<f64>, f64) {
        Self::reaction(self.joints[ji].role, re)
    }

    /// The reaction a joint's laws see: its force (components, global frame) and moment.
    fn reaction(role: Role, re: &TrainReactions) -> (Vector2<f64>, f64) {
        match role {
            Role::Main(i) => (re.mains_n[i], 0.0),
            Role::BigEnd(k) => (re.cylinders[k].big_end_n, 0.0),
            Role::SmallEnd(k) => (re.cylinders[k].small_end_n, 0.0),
            // As on the single-cylinder rig: the side thrust as the y component.
            Role::Piston(k) => (
                Vector2::new(0.0, re.cylinders[k].slide_lateral_n),
                re.cylinders[k].slide_moment_nm,
            ),
        }
    }

    /// One instant at crank angle `theta`: kinematics with the gas forces, then the
    /// friction/reaction iteration from `w.loads` (phase 1, and phase 2 when phase 1 stalls);
    /// the rates, law inputs, reactions, normal loads and settled loads of its final round are
    /// left in `w`. Whether phase 2 settled it.
    pub(super) fn evaluate(&self, at: &Point, w: &mut Work) -> Result<bool, SimError> {
        let theta = at.theta;
        let n_cyl = self.train.geometry().cylinders.len();
        w.gas_forces.clear();
        w.gas_forces.resize(n_cyl, 0.0);
        // Each cylinder's local angle: its gas model is evaluated there.
        let mut locals = [0.0; crate::engine::MAX_CYLINDERS];
        self.train.kinematics_into(theta, at.omega, &[], &mut w.kin);
        let mut travel = [0.0; crate::engine::MAX_CYLINDERS];
        for (k, c) in w.kin.cylinders.iter().enumerate() {
            locals[k] = c.local_angle_rad;
            travel[k] = self.tdc_position[k] - c.piston_position_m;
        }
        // What each cylinder's laws are handed (contract version 2): its gas state, or the
        // atmosphere, its piston travel and its own 4-stroke angle without a gas model.
        w.law_gas.clear();
        if self.gas.is_empty() {
            let geo = self.train.geometry();
            let ambient = tribo_plugin_api::contract::STANDARD_ATMOSPHERE_PA;
            for k in 0..geo.cylinders.len() {
                w.law_gas.push(LawGas {
                    cylinder_pa: ambient,
                    crankcase_pa: ambient,
                    piston_from_tdc_m: travel[k],
                    cycle_angle_rad: cycle_angle(locals[k] + self.phases[k]),
                });
            }
        } else {
            for (k, g) in self.gas.iter().enumerate() {
                // The volume follows the piston's true travel (with offsets, its dead centres
                // are not at local angles 0 and pi); the valve events stay at those angles.
                let state = g.at_travel(locals[k], at.omega, travel[k]);
                w.gas_forces[k] = state.force_n;
                w.law_gas.push((&state).into());
            }
            self.train
                .kinematics_into(theta, at.omega, &w.gas_forces, &mut w.kin);
        }
        w.rates.clear();
        w.rates.resize(self.layout().len(), 0.0);
        w.rates[self.layout().gas()] = -w
            .gas_forces
            .iter()
            .zip(&w.kin.cylinders)
            .map(|(f, c)| f * c.piston_speed_m_s)
            .sum::<f64>();
        // The law inputs but for the loads: built once, each round of laws sets only the loads.
        w.inputs.clear();
        if self.n_laws > 0 {
            for j in &self.joints {
                // A cylinder's joints see its own gas state; the mains, cylinder 1's.
                let instant = Instant {
                    t: at.t,
                    dt: at.dt,
                    crank_angle: crank_angle(theta),
                    omega: at.omega,
                    oil: at.oil,
                    gas: w.law_gas[j.role.cylinder()],
                };
                let bodies = self.bodies(j.role, &w.kin);
                w.inputs.push(law_input(&j.contact, &instant, &bodies));
            }
        }
        // Phase 1: the plain fixed-point iteration (solve, evaluate the laws at the resulting
        // normal loads, repeat), abandoned for phase 2 (`engine_newton.rs`) when it is seen
        // not to contract, by the single-cylinder rig's rule.
        let mut trend = Trend::default();
        for it in 1..=self.max_iter {
            w.alpha = self.solve(&w.kin, at.control, &w.loads, &mut w.re);
            self.normals_into(&w.re, &mut w.normals);
            self.check_normals(at.t, &w.normals)?;
            let scale = w.normals.iter().fold(1.0_f64, |m, n| m.max(*n));
            let change = (it > 1).then(|| {
                w.prev
                    .iter()
                    .zip(&w.normals)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
            });
            // The last change, not its geometric estimate: the engine's results stay those of
            // the single-phase iteration wherever phase 1 settles.
            let verdict = trend.judge(
                change,
                Distance::LastChange,
                self.tol * scale,
                self.max_iter - it,
            );
            if self.n_laws == 0 || matches!(verdict, Verdict::Converged) {
                w.max_it = w.max_it.max(it);
                w.rates[RateLayout::MOTOR] = w.re.drive_torque_nm * at.omega;
                return Ok(false);
            }
            if matches!(verdict, Verdict::Stalls) {
                self.settle_by_newton(at, w, it)?;
                return Ok(true);
            }
            if it == self.max_iter {
                let before = if it > 1 { &w.prev } else { &w.normals };
                let changes: Vec<f64> = before
                    .iter()
                    .zip(&w.normals)
                    .map(|(a, b)| (a - b).abs())
                    .collect();
                return Err(self.no_convergence(at.t, it, &changes, scale));
            }
            // A round of laws at these normal loads.
            let reaction_n = w.normals.iter().fold(0.0, |m: f64, n| m.max(*n));
            let mut loads = TrainLoads {
                main_torque_nm: 0.0,
                cylinders: std::mem::take(&mut w.loads.cylinders),
            };
            loads
                .cylinders
                .iter_mut()
                .for_each(|c| *c = CylinderLoads::default());
            let mut k = 0;
            for ((j, normal), input) in self.joints.iter().zip(&w.normals).zip(&mut w.inputs) {
                let (comp, moment) = Self::reaction(j.role, &w.re);
                set_load(input, comp, moment, *normal);
                let total = self.joint_force(j, input, reaction_n, Some((&mut w.rates, k)))?;
                add_load(&mut loads, j.role, total);
                k += j.laws.len();
            }
            w.loads = loads;
            std::mem::swap(&mut w.prev, &mut w.normals);
        }
        Err(self.no_convergence(at.t, self.max_iter, &[], 1.0))
    }

    /// The crank acceleration under the friction `loads` (the control's, or the one the
    /// drive torque causes) and the reactions `re` there; returns the acceleration.
    #[inline]
    pub(super) fn solve(
        &self,
        kin: &TrainKinematics,
        control: Control,
        loads: &TrainLoads,
        re: &mut TrainReactions,
    ) -> f64 {
        let alpha = match control {
            Control::Acceleration(alpha) => alpha,
            Control::Torque(torque) => self.train.alpha_for_torque(kin, torque, loads),
        };
        self.train.reactions_into(kin, alpha, loads, re);
        alpha
    }

    /// Each joint's normal load from the reactions `re`, into `out`.
    #[inline]
    pub(super) fn normals_into(&self, re: &TrainReactions, out: &mut Vec<f64>) {
        out.clear();
        out.extend(
            self.joints
                .iter()
                .map(|j| Self::reaction(j.role, re).0.norm()),
        );
    }

    /// A solve's normal loads must be finite (the laws are given them next): a non-finite one
    /// is the model's fault, named with its joint group.
    #[inline]
    pub(super) fn check_normals(&self, t: f64, normals: &[f64]) -> Result<(), SimError> {
        match self
            .joints
            .iter()
            .zip(normals)
            .find(|(_, n)| !n.is_finite())
        {
            Some((j, n)) => Err(SimError::Model {
                time_s: t,
                quantity: "normal load",
                joint: Some(j.role.group()),
                value: *n,
            }),
            None => Ok(()),
        }
    }

    /// The friction force (piston) or torque (bearings, pins) of all laws on joint `j` at
    /// `input`, checked (finite, bounded by `reaction_n`, a stateless law not adding energy).
    /// With `record`, each law's power, regime and load are written into the rates from law
    /// index `k` on.
    #[inline]
    pub(super) fn joint_force(
        &self,
        j: &EngineJoint,
        input: &LawInput,
        reaction_n: f64,
        mut record: Option<(&mut [f64], usize)>,
    ) -> Result<f64, SimError> {
        let layout = self.layout();
        let mut total = 0.0;
        for (i, law) in j.laws.iter().enumerate() {
            let out = law
                .call(input)
                .map_err(|e| super::bind::law_failed_named(&j.name, input, e))?;
            let power = super::bind::checked_power_named(
                &j.name,
                j.role.kind(),
                law,
                input,
                &out,
                reaction_n,
            )?;
            total += out.force;
            if let Some((rates, k)) = record.as_mut() {
                let regime = out.regime().unwrap_or(Regime::None) as usize;
                rates[layout.power(*k + i)] = -power;
                for r in 0..4 {
                    rates[layout.regime(*k + i, r)] = if r == regime { 1.0 } else { 0.0 };
                }
                rates[layout.normal(*k + i)] = input.normal_load_n;
            }
        }
        Ok(total)
    }

    /// The friction loads from each joint's law total `totals` (the mains' summed), into
    /// `loads`.
    pub(super) fn loads_from_totals(&self, totals: &[f64], loads: &mut TrainLoads) {
        loads.main_torque_nm = 0.0;
        loads
            .cylinders
            .iter_mut()
            .for_each(|c| *c = CylinderLoads::default());
        for (j, total) in self.joints.iter().zip(totals) {
            add_load(loads, j.role, *total);
        }
    }

    /// Commit every stateful law over the accepted step, at the inputs of the step's settled
    /// evaluation.
    pub(super) fn commit(&mut self, w: &Work) -> Result<(), SimError> {
        for (j, input) in self.joints.iter_mut().zip(&w.inputs) {
            for law in j.laws.iter_mut().filter(|l| l.is_stateful()) {
                law.commit(input)
                    .map_err(|e| super::bind::law_failed_named(&j.name, input, e))?;
            }
        }
        Ok(())
    }

    /// The error for an iteration that did not settle: the joints with laws whose normal load
    /// still moved by more than the tolerance (`changes` per joint, N).
    pub(super) fn no_convergence(
        &self,
        t: f64,
        iterations: u32,
        changes: &[f64],
        scale: f64,
    ) -> SimError {
        let unsettled = self
            .joints
            .iter()
            .zip(changes)
            // A NaN change (loads that ran off to infinity) is unsettled too.
            .filter(|(j, c)| !j.laws.is_empty() && (c.is_nan() || **c > self.tol * scale))
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

    /// Plateau `pi`'s result (mean speed `mean_omega`, rad/s) from the change of its
    /// accumulated quantities over the measured `window`, with the engine's groups.
    pub(super) fn plateau_result(
        &self,
        pi: usize,
        mean_omega: f64,
        window: &Measured,
    ) -> PlateauResult {
        let laws = self.joints.iter().flat_map(|j| {
            j.laws
                .iter()
                .map(move |l| (j.name.as_str(), l.name.as_str()))
        });
        let mut result = plateau_values(
            laws,
            self.layout(),
            &self.fmep(),
            window,
            self.cycle.plateaus()[pi].speed_rpm,
            mean_omega,
            (self.temps[pi], self.viscosities[pi]),
        );
        result.groups = group_totals(&result.joints, self.train.geometry().cylinders.len());
        result
    }
}

/// Add joint `role`'s law total to the friction loads (the mains' torques add up).
#[inline]
fn add_load(loads: &mut TrainLoads, role: Role, total: f64) {
    match role {
        Role::Main(_) => loads.main_torque_nm += total,
        Role::BigEnd(c) => loads.cylinders[c].big_end_torque_nm = total,
        Role::SmallEnd(c) => loads.cylinders[c].small_end_torque_nm = total,
        Role::Piston(c) => loads.cylinders[c].slide_force_n = total,
    }
}

/// Per-component (all mains, every cylinder's big ends, ...) and per-cylinder totals of the
/// friction torque and power.
fn group_totals(joints: &[LawResult], cylinders: usize) -> Vec<GroupTotal> {
    let total = |name: String, pick: &dyn Fn(&str) -> bool| {
        let (t, p) = joints
            .iter()
            .filter(|l| pick(&l.joint))
            .fold((0.0, 0.0), |(t, p), l| {
                (t + l.friction_torque_nm, p + l.power_w)
            });
        GroupTotal {
            group: name,
            friction_torque_nm: t,
            power_w: p,
        }
    };
    let mut out = Vec::new();
    for kind in crate::model::JOINT_KINDS {
        let prefix = format!("{kind}_");
        out.push(total(format!("{kind}_*"), &|j: &str| {
            j.starts_with(&prefix)
        }));
    }
    for k in 1..=cylinders {
        let suffix = format!("_{k}");
        out.push(total(format!("cylinder {k}"), &|j: &str| {
            !j.starts_with("main_") && j.ends_with(&suffix)
        }));
    }
    out
}

/// The engine's joints with their laws, in order: mains (`engine.laws`), then per cylinder
/// big end, small end, piston (`engine.laws`, else the `[joints.*]` table's laws).
fn joint_laws(f: &RigFile) -> Result<Vec<(String, Role, Vec<crate::model::LawRef>)>, SimError> {
    let Some(e) = &f.engine else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for i in 0..e.mains.len() {
        let name = format!("main_{}", i + 1);
        let laws = e.laws.get(&name).cloned().unwrap_or_default();
        out.push((name, Role::Main(i), laws));
    }
    for k in 0..e.cylinders.len() {
        for (kind, role, template) in [
            ("big_end", Role::BigEnd(k), &f.joints.big_end),
            ("small_end", Role::SmallEnd(k), &f.joints.small_end),
            ("piston", Role::Piston(k), &f.joints.piston),
        ] {
            let name = format!("{kind}_{}", k + 1);
            let laws = e
                .laws
                .get(&name)
                .cloned()
                .unwrap_or_else(|| template.laws.clone());
            out.push((name, role, laws));
        }
    }
    Ok(out)
}

/// The engine's joints by name with their laws, in order ([`joint_laws`] without the roles);
/// empty for a rig without an engine.
pub(super) fn laws_by_joint(f: &RigFile) -> Vec<(String, Vec<crate::model::LawRef>)> {
    joint_laws(f)
        .unwrap_or_default()
        .into_iter()
        .map(|(name, _, laws)| (name, laws))
        .collect()
}

/// The dotted field of law `i` on engine joint `name`: where a law set put it
/// (`joints.NAME.laws[i]`, located by the configuration layer through the law's origin), or
/// the `[joints.*]` table whose laws a cylinder joint took.
fn law_field(f: &RigFile, name: &str, i: usize) -> String {
    let from_engine = f.engine.as_ref().is_some_and(|e| e.laws.contains_key(name));
    if from_engine {
        format!("joints.{name}.laws[{i}]")
    } else {
        let kind = name.rsplit_once('_').map_or(name, |(k, _)| k);
        format!("joints.{kind}.laws[{i}]")
    }
}

/// The recycled state of the run: kinematics, reactions, loads, rates.
pub(super) struct Work {
    pub(super) kin: TrainKinematics,
    pub(super) re: TrainReactions,
    pub(super) loads: TrainLoads,
    /// The crank acceleration of the settled solve, rad/s^2.
    pub(super) alpha: f64,
    gas_forces: Vec<f64>,
    /// Each cylinder's gas state for its laws.
    pub(super) law_gas: Vec<LawGas>,
    pub(super) rates: Vec<f64>,
    /// Normal loads of this solve and the previous one, per joint.
    pub(super) normals: Vec<f64>,
    prev: Vec<f64>,
    /// The law inputs of the last round of laws, per joint (what a commit is given).
    pub(super) inputs: Vec<LawInput>,
    pub(super) max_it: u32,
}

impl Work {
    pub(super) fn new(sim: &EngineSimulation) -> Self {
        Self {
            kin: TrainKinematics::default(),
            re: TrainReactions::default(),
            loads: TrainLoads {
                main_torque_nm: 0.0,
                cylinders: vec![CylinderLoads::default(); sim.train.geometry().cylinders.len()],
            },
            alpha: 0.0,
            gas_forces: Vec::new(),
            law_gas: Vec::new(),
            rates: vec![0.0; sim.layout().len()],
            normals: Vec::with_capacity(sim.joints.len()),
            prev: Vec::with_capacity(sim.joints.len()),
            inputs: Vec::with_capacity(sim.joints.len()),
            max_it: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::{PI, TAU};
    use std::sync::Mutex;

    use serde::{Deserialize, Serialize};
    use tribo_plugin_api::loader::{LawLibrary, LawRegistry};
    use tribo_plugin_api::{Law, LawInput, LawOutput, ParamError, ParamSpec};

    use super::EngineSimulation;
    use crate::model::{LawRef, RigFile};

    /// (tag, input) of every evaluation of the `tag-unit` law.
    static SEEN: Mutex<Vec<(f64, LawInput)>> = Mutex::new(Vec::new());

    #[derive(Serialize, Deserialize, Default)]
    #[serde(deny_unknown_fields, default)]
    struct TagParams {
        tag: f64,
    }

    /// A light viscous damper that records its inputs under its `tag` (the cylinder).
    struct Tagged {
        tag: f64,
    }

    impl Law for Tagged {
        type Params = TagParams;
        const NAME: &'static str = "tag-unit";
        const VERSION: &'static str = "0";
        const SUMMARY: &'static str = "records its inputs under a tag (unit test)";

        fn parameters() -> Vec<ParamSpec> {
            vec![ParamSpec::number("tag", "-", "which cylinder", 0.0, 100.0)]
        }

        fn new(p: TagParams) -> Result<Self, ParamError> {
            Ok(Self { tag: p.tag })
        }

        fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
            if let Ok(mut seen) = SEEN.lock() {
                seen.push((self.tag, *input));
            }
            LawOutput::force(-1e-4 * input.sliding_velocity_m_s)
        }
    }

    /// The inline-4 test fixture with a motored 4-stroke head on every cylinder, the tagged law
    /// on each piston, one 3000 rpm plateau.
    fn fixture() -> RigFile {
        let text = include_str!("../../../../tests/fixtures/engines/inline4.toml");
        let mut model: RigFile = toml::from_str(text).expect("fixture parses");
        model.gas.cylinder = crate::model::CylinderPressure::Motored {
            compression_ratio: 10.0,
            polytropic_exponent: 1.3,
            intake_pressure_pa: 1e5,
            valves: crate::model::Valves::FourStroke,
        };
        model.cycle.segments = Some(vec![
            crate::cycle::Segment::Ramp {
                to_rpm: 3000.0,
                duration_s: 0.1,
            },
            crate::cycle::Segment::Hold { duration_s: 0.1 },
        ]);
        let engine = model.engine.as_mut().expect("an engine");
        for k in 1..=4 {
            let mut params = toml::Table::new();
            params.insert("tag".into(), toml::Value::Float(k as f64));
            engine.laws.insert(
                format!("piston_{k}"),
                vec![LawRef {
                    law: "tag-unit".into(),
                    params,
                }],
            );
        }
        model
    }

    #[test]
    fn each_cylinder_is_handed_its_own_four_stroke_phase_from_the_firing_order() {
        let model = fixture();
        let mut registry = LawRegistry::new();
        registry
            .insert(LawLibrary::in_process::<Tagged>().expect("law describes itself"))
            .expect("one law");
        SEEN.lock().expect("not poisoned").clear();
        let result = EngineSimulation::new(&model, &registry)
            .expect("engine simulation")
            .run_steady()
            .expect("steady run");
        assert_eq!(result.plateaus[0].revolutions, 2);
        let seen = std::mem::take(&mut *SEEN.lock().expect("not poisoned"));
        // Firing 1-3-4-2 on throws 0-180-180-0: at engine angle theta (accumulated), cylinder
        // k's 4-stroke angle is theta + its throw angle + its phase (0 for 1 and 2, 360 for 3
        // and 4), so they fire (4-stroke angle 360) at 360, 540, 720 and 900 degrees, in order.
        let offset = |k: usize| match k {
            1 => 0.0,
            2 => PI,
            3 => PI + TAU,
            _ => TAU,
        };
        let wrap = |a: f64| a.rem_euclid(2.0 * TAU);
        let mut checked = [0; 5];
        for (tag, input) in &seen {
            let k = *tag as usize;
            let theta = input.engine_speed_rad_s * input.time_s;
            let want = wrap(theta + offset(k));
            let got = input.cycle_angle_rad;
            let d = (got - want).abs().min(2.0 * TAU - (got - want).abs());
            assert!(d < 1e-6, "cylinder {k} at theta {theta}: {got} vs {want}");
            // Its own compression: the pressure handed is the polytropic law at its own piston
            // travel, highest near its own firing TDC.
            if d < 1e-6 && (got - TAU).abs() < 0.02 {
                assert!(
                    input.cylinder_pressure_pa > 1.5e6,
                    "{k}: {}",
                    input.cylinder_pressure_pa
                );
                checked[k] += 1;
            }
        }
        assert!(checked[1..].iter().all(|n| *n > 0), "{checked:?}");
        // The motored, reversible compression does no net work; the laws' damping only.
        let p = &result.plateaus[0];
        let friction: f64 = p.joints.iter().map(|l| l.friction_torque_nm).sum();
        assert!((p.motoring_torque_nm - friction).abs() < 1e-6 * (1.0 + friction.abs()));
    }
}
