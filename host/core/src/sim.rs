//! The motored-rig simulation: the test cycle stepped through time, the friction/reaction
//! iteration at every evaluation, the drive, energy bookkeeping and plateau measurement.
//!
//! Pipeline of one evaluation (plain data in, plain data out):
//! `crank state -> Mechanism::solve (reactions) -> law inputs -> LawInstance::evaluate ->
//! joint loads -> Mechanism::solve ...` until the joint normal loads stop changing.
//!
//! Drives: `prescribed` evaluates the exact reference motion (no ODE for the mechanics; Simpson
//! quadrature of powers per step); `pi` integrates crank angle, speed and the controller's
//! integral with the error-controlled Dormand-Prince 5(4) pair (or fixed-step RK4 with stateful
//! laws or `solver.integrator = "rk4"`), powers integrated as part of the same state.

use std::f64::consts::TAU;
use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::Vector2;
use tribo_plugin_api::loader::{LawError, LawInstance, LawRegistry};
use tribo_plugin_api::serde::Serialize;
use tribo_plugin_api::{JointKind, LawInput, LawOutput, Regime};

use crate::cycle::{rad_s_to_rpm, Cycle};
use crate::erk::{Controller, Pair, DORMAND_PRINCE_54};
use crate::mechanics::{JointLoads, Mechanism, Reactions, RigGeometry};
use crate::model::{Drive, Integrator, RigFile, Temperature, JOINT_NAMES};

/// Standard gravity, m/s^2.
pub const GRAVITY_M_S2: f64 = 9.80665;

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A law cannot be bound (a law name that no plugin provides, bad law parameters): `field`
    /// is its dotted path in the model, `at` where the configuration layer found it
    /// (`file:line:column`), if it knows.
    #[error("{}{field}: {message}", at.as_deref().map(|a| format!("{a}: ")).unwrap_or_default())]
    Setup {
        /// Where the field was written, if known.
        at: Option<String>,
        /// Dotted path of the field, e.g. `joints.piston.laws[0].params`.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A law failed while running.
    #[error("joint `{joint}` at t = {time_s:.6} s (relative velocity {velocity}, normal load {load_n} N): {source}")]
    Law {
        /// Joint.
        joint: String,
        /// Simulation time, s.
        time_s: f64,
        /// Relative velocity at the failure.
        velocity: f64,
        /// Normal load at the failure, N.
        load_n: f64,
        /// The law's error.
        source: Box<LawError>,
    },
    /// A law returned a force that is not a finite number.
    #[error("joint `{}`, law `{}` ({}) returned a non-finite force ({}) at t = {:.6} s for inputs: velocity {}, normal load {} N", .0.joint, .0.law, .0.file, .0.force, .0.time_s, .0.velocity, .0.load_n)]
    NonFinite(Box<Fault>),
    /// A stateless law returned a force that pushes the motion (F*V > 0).
    #[error("joint `{}`, law `{}` ({}) adds energy at t = {:.6} s: force {} has the sign of the relative velocity {} (normal load {} N); a friction or damping law must oppose the motion", .0.joint, .0.law, .0.file, .0.time_s, .0.force, .0.velocity, .0.load_n)]
    AddsEnergy(Box<Fault>),
    /// The friction/reaction iteration did not converge: which joints' loads did not settle,
    /// with their laws, so the user knows which law to look at.
    #[error("{}", no_convergence_text(*.time_s, *.iterations, *.change_n, *.tol, .unsettled))]
    NoConvergence {
        /// Time.
        time_s: f64,
        /// Iterations made.
        iterations: u32,
        /// Largest last change of a normal load, N.
        change_n: f64,
        /// Tolerance, relative to the largest normal load.
        tol: f64,
        /// The law-bearing joints whose loads did not settle.
        unsettled: Vec<Unsettled>,
    },
    /// The adaptive integrator could not meet its tolerance with any usable step.
    #[error("the adaptive integrator could not meet solver.rel_tol = {rel_tol:.1e} at t = {time_s:.6} s (step down to {step_s:.3e} s): a law is probably discontinuous there; loosen solver.rel_tol or use solver.integrator = \"rk4\"")]
    StepTooSmall {
        /// Time.
        time_s: f64,
        /// The last step tried, s.
        step_s: f64,
        /// The tolerance in force.
        rel_tol: f64,
    },
    /// Writing the time series failed.
    #[error("writing the time series: {0}")]
    Io(#[from] std::io::Error),
}

/// Where, when and with which inputs a law returned an unusable force.
#[derive(Debug, Clone)]
pub struct Fault {
    /// Joint.
    pub joint: String,
    /// Law.
    pub law: String,
    /// Library file.
    pub file: String,
    /// Simulation time, s.
    pub time_s: f64,
    /// The force (or torque) returned.
    pub force: f64,
    /// Relative velocity given to the law.
    pub velocity: f64,
    /// Normal load given to the law, N.
    pub load_n: f64,
}

/// One law bound to one joint.
struct BoundLaw {
    name: String,
    instance: LawInstance,
    state: Vec<f64>,
    /// Calls made, and sampled time in them (every `TIMING_SAMPLE`-th call is timed).
    calls: AtomicU64,
    sampled_ns: AtomicU64,
}

/// One law call in this many is timed; the total is scaled up. Keeps timing off the hot path:
/// a clock read costs tens of ns on a virtual machine, and at 64 the reads took 3% of a PI run.
/// A steady comparison still times ~20 calls per law, a transient run thousands.
const TIMING_SAMPLE: u64 = 256;
/// How much looser than `solver.rel_tol` the error-controlled step holds the integrated normal
/// loads: they are reported as means (to four significant figures), not fed back into the
/// motion, and at 100 the mean loads still agree with fine fixed-step RK4 to about 1e-4.
const NORMALS_TOL_FACTOR: f64 = 100.0;

/// Where each accumulated quantity sits in an evaluation's rate vector, for `n` laws: the motor
/// power, then each law's dissipated power, its four regime indicators and its normal load.
#[derive(Debug, Clone, Copy)]
struct RateLayout {
    n: usize,
}

impl RateLayout {
    const MOTOR: usize = 0;
    fn len(self) -> usize {
        1 + 6 * self.n
    }
    /// Every law's dissipated power.
    fn powers(self) -> std::ops::Range<usize> {
        1..1 + self.n
    }
    /// Every law's regime indicators.
    fn regimes(self) -> std::ops::Range<usize> {
        1 + self.n..1 + 5 * self.n
    }
    /// Every law's normal load.
    fn normals(self) -> std::ops::Range<usize> {
        1 + 5 * self.n..1 + 6 * self.n
    }
    fn power(self, k: usize) -> usize {
        1 + k
    }
    fn regime(self, k: usize, regime: usize) -> usize {
        1 + self.n + 4 * k + regime
    }
    fn normal(self, k: usize) -> usize {
        1 + 5 * self.n + k
    }
    /// The error-controlled groups with their tolerance factors: the motor and law powers at
    /// `rel_tol`; the normal loads, only reported as means and never fed back, at
    /// `NORMALS_TOL_FACTOR` times it (a magnitude's valleys near zero need no steps the powers
    /// do not). Regime times are not controlled: their indicators jump by nature.
    fn controlled(self) -> [(std::ops::Range<usize>, f64); 2] {
        [
            (Self::MOTOR..self.powers().end, 1.0),
            (self.normals(), NORMALS_TOL_FACTOR),
        ]
    }
}

/// The crank angle within the revolution, [0, 2 pi). `rem_euclid` is exact but calls a software
/// `fmod` that loops over the exponent difference (1.5% of a PI run); one floor is within a few
/// ulp of the accumulated angle, far below its own integration error.
fn crank_angle(theta: f64) -> f64 {
    let r = theta - TAU * (theta / TAU).floor();
    if r >= TAU {
        r - TAU
    } else if r < 0.0 {
        r + TAU
    } else {
        r
    }
}

/// One law call with its wall time added to the law's sample (every `TIMING_SAMPLE`-th call).
fn timed_evaluate(law: &BoundLaw, input: &LawInput) -> Result<LawOutput, LawError> {
    let clock = std::time::Instant::now();
    let out = law.instance.evaluate(input, &law.state);
    let ns = (clock.elapsed().as_nanos() as u64).saturating_sub(clock_overhead_ns());
    let sum = law.sampled_ns.load(Ordering::Relaxed);
    law.sampled_ns.store(sum + ns, Ordering::Relaxed);
    out
}

/// A law that failed (panicked or returned an error code) at `input`.
#[cold]
fn law_failed(joint: &BoundJoint, t: f64, input: &LawInput, e: LawError) -> SimError {
    SimError::Law {
        joint: joint.name.into(),
        time_s: t,
        velocity: input.relative_velocity,
        load_n: input.normal_load_n,
        source: Box::new(e),
    }
}

/// A law that returned a non-finite force, or (stateless) one that adds energy.
#[cold]
fn unusable(joint: &BoundJoint, law: &BoundLaw, t: f64, input: &LawInput, force: f64) -> SimError {
    let fault = Box::new(Fault {
        joint: joint.name.into(),
        law: law.name.clone(),
        file: law.instance.path().display().to_string(),
        time_s: t,
        force,
        velocity: input.relative_velocity,
        load_n: input.normal_load_n,
    });
    if force.is_finite() {
        SimError::AddsEnergy(fault)
    } else {
        SimError::NonFinite(fault)
    }
}

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
fn plain_iteration_stalls(d: f64, d2: f64, tol_n: f64, remaining: u32) -> bool {
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

/// The friction loads from each joint's total law force or torque (main bearings summed).
fn loads_from(totals: &[f64; 5]) -> JointLoads {
    let mut loads = JointLoads::default();
    loads.main_torque_nm += totals[0];
    loads.main_torque_nm += totals[1];
    loads.big_end_torque_nm = totals[2];
    loads.small_end_torque_nm = totals[3];
    loads.slide_force_n = totals[4];
    loads
}

/// One evaluation's friction/reaction problem: what stays fixed while the loads settle (the
/// factorised kinematics, the drive's control, the joints' relative velocities) and the law
/// inputs, of which only the loads change. Borrowed, not moved: copying the kinematics and the
/// inputs cost 2% of a PI run's instructions.
struct Problem<'a> {
    kin: &'a crate::mechanics::Kinematics,
    control: Result<f64, f64>,
    rel: [f64; 5],
    inputs: &'a mut [LawInput; 5],
    t: f64,
}

impl Problem<'_> {
    /// Crank acceleration and reactions under the friction `loads`.
    fn solve(&self, loads: &JointLoads) -> (f64, Reactions) {
        let alpha = match self.control {
            Ok(alpha) => alpha,
            Err(torque) => self.kin.alpha_for_torque(torque, loads),
        };
        (alpha, self.kin.reactions(alpha, loads))
    }
}

/// The reactions where phase 2 began: their directions give the law inputs' components.
struct Base {
    comps: [Vector2<f64>; 5],
    normals: [f64; 5],
    moment: f64,
}

impl Base {
    /// Set joint `ji`'s law input to the normal load `w` (N), its components along the base
    /// reaction's direction.
    fn load_input(&self, input: &mut LawInput, ji: usize, w: f64) {
        let f = if self.normals[ji] > 0.0 {
            w / self.normals[ji]
        } else {
            0.0
        };
        input.normal_load_n = w;
        input.reaction_x_n = self.comps[ji].x * f;
        input.reaction_y_n = self.comps[ji].y * f;
        input.reaction_moment_nm = if ji == 4 { self.moment } else { 0.0 };
    }
}

/// A round of laws and reactions (phase 2), and the result of a settled iteration.
struct Settled {
    alpha: f64,
    re: Reactions,
    normals: [f64; 5],
    loads: JointLoads,
    /// Total law force or torque per joint.
    totals: [f64; 5],
    iterations: u32,
}

/// A joint whose normal load did not settle, with its laws (for the error message).
#[derive(Debug, Clone)]
pub struct Unsettled {
    /// Joint.
    pub joint: String,
    /// Laws bound to it.
    pub laws: Vec<String>,
    /// Last change (or residual) of its normal load, N.
    pub change_n: f64,
}

/// The message of [`SimError::NoConvergence`]: where, which joints and laws, what to do.
fn no_convergence_text(
    time_s: f64,
    iterations: u32,
    change_n: f64,
    tol: f64,
    unsettled: &[Unsettled],
) -> String {
    let head = format!(
        "the friction/reaction iteration did not converge at t = {time_s:.6} s after {iterations} iterations"
    );
    if unsettled.is_empty() {
        return format!(
            "{head}, too few to see the normal loads settle: raise solver.friction_max_iter"
        );
    }
    let one = |x: &Unsettled| {
        let laws: Vec<String> = x.laws.iter().map(|l| format!("`{l}`")).collect();
        let noun = if x.laws.len() == 1 { "law" } else { "laws" };
        format!("`{}` ({noun} {})", x.joint, laws.join(", "))
    };
    let items: Vec<String> = unsettled.iter().map(one).collect();
    let joints = match items.split_last() {
        Some((last, [])) => format!("joint {last}"),
        Some((last, rest)) => format!("joints {} and {last}", rest.join(", ")),
        None => String::new(),
    };
    let n_laws: usize = unsettled.iter().map(|x| x.laws.len()).sum();
    let (whose, its) = if n_laws == 1 {
        ("that law's", "its")
    } else {
        ("those laws'", "their")
    };
    format!(
        "{head}: the normal load of {joints} did not settle (last change {change_n:.3e} N, \
         tolerance {tol:.1e} of the largest load); check {whose} parameters at these loads ({its} load \
         sensitivity may be too strong or discontinuous there) or raise \
         solver.friction_max_iter"
    )
}

/// The cost of reading the clock twice, ns, measured once: subtracted from every timed call.
fn clock_overhead_ns() -> u64 {
    static OVERHEAD: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *OVERHEAD.get_or_init(|| {
        let n = 2000;
        let start = std::time::Instant::now();
        for _ in 0..n {
            let c = std::time::Instant::now();
            std::hint::black_box(c.elapsed());
        }
        (start.elapsed().as_nanos() / n) as u64
    })
}

/// A joint with its geometry and laws.
struct BoundJoint {
    name: &'static str,
    kind: JointKind,
    radius_m: f64,
    length_m: f64,
    laws: Vec<BoundLaw>,
}

/// Per-law result for one plateau.
#[derive(Debug, Clone, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct LawResult {
    /// Joint name.
    pub joint: String,
    /// Law name.
    pub law: String,
    /// Mean friction torque at the crank: dissipated power over mean crank speed, N m.
    pub friction_torque_nm: f64,
    /// Mean dissipated power, W.
    pub power_w: f64,
    /// Mean normal load of the joint over the window, N.
    pub mean_normal_load_n: f64,
    /// Time share of each lubrication regime.
    pub regime_share: RegimeShare,
}

/// Time shares of the lubrication regimes (they add up to 1).
#[derive(Debug, Clone, Copy, Serialize, Default)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct RegimeShare {
    /// The law reported no regime.
    pub none: f64,
    /// Boundary.
    pub boundary: f64,
    /// Mixed.
    pub mixed: f64,
    /// Hydrodynamic.
    pub hydrodynamic: f64,
}

/// One measured plateau.
#[derive(Debug, Clone, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct PlateauResult {
    /// Reference speed, rpm.
    pub set_speed_rpm: f64,
    /// Mean crank speed over the measurement window, rpm.
    pub mean_speed_rpm: f64,
    /// Mean motoring torque over whole crank revolutions, N m.
    pub motoring_torque_nm: f64,
    /// Oil temperature, C.
    pub oil_temp_c: f64,
    /// Dynamic viscosity at that temperature, Pa s.
    pub viscosity_pa_s: f64,
    /// Start and end of the window, s.
    pub window_s: [f64; 2],
    /// Whole revolutions averaged.
    pub revolutions: u32,
    /// Per joint and law.
    pub joints: Vec<LawResult>,
}

/// Energy bookkeeping over the whole run.
#[derive(Debug, Clone, Copy, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct EnergyBalance {
    /// Work of the drive torque on the crank, J.
    pub motor_work_j: f64,
    /// Change of kinetic plus potential energy, J.
    pub mechanical_energy_change_j: f64,
    /// Energy dissipated by all laws, J.
    pub dissipated_j: f64,
    /// motor work - energy change - dissipation, J.
    pub residual_j: f64,
    /// |residual| / motor work.
    pub relative_residual: f64,
}

/// Everything a run produces.
#[derive(Debug, Clone, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct RunResult {
    /// Rig name.
    pub rig: String,
    /// `prescribed` or `pi`.
    pub drive: String,
    /// One entry per hold of the cycle.
    pub plateaus: Vec<PlateauResult>,
    /// Energy residual over the run, J.
    pub energy_residual_j: f64,
    /// Full energy bookkeeping.
    pub energy: EnergyBalance,
    /// Steps taken.
    pub steps: u64,
    /// Largest number of friction/reaction iterations needed at one evaluation.
    pub max_friction_iterations: u32,
    /// Warnings (a drive at its torque limit, say).
    pub warnings: Vec<String>,
    /// Time spent in each law (estimated from sampled calls). Printed in the text report only:
    /// wall-clock time would make JSON and CSV results differ from run to run.
    #[serde(skip)]
    pub law_time: Vec<LawTime>,
}

/// Time a law took over a run.
#[derive(Debug, Clone, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct LawTime {
    /// Joint.
    pub joint: String,
    /// Law.
    pub law: String,
    /// Evaluations.
    pub calls: u64,
    /// Estimated seconds in the law (one call in 64 timed, the clock's own cost subtracted).
    pub seconds: f64,
}

/// Output of one evaluation.
#[derive(Debug, Clone)]
struct Eval {
    omega: f64,
    alpha: f64,
    /// Drive torque on the crank, N m.
    drive_torque: f64,
    /// Rates accumulated over time: motor power, then per law dissipated power, per law
    /// regime indicators (4), per law normal load.
    rates: Vec<f64>,
    /// Normal load per joint.
    normals: [f64; 5],
    /// Where the rates stop being smooth when these change sign: each joint's relative
    /// velocity (a friction force reverses), the piston's lateral reaction (its normal load,
    /// an absolute value, has a kink) and the PI drive's margin to its torque limit (the
    /// anti-windup switches its integrator).
    switches: [f64; SWITCHES],
    iterations: u32,
    /// Whether phase 2 (Newton) settled the loads; phase 1 otherwise. Read by the unit tests,
    /// which hold each phase to its own convergence test.
    #[cfg_attr(not(test), allow(dead_code))]
    newton: bool,
}

impl Eval {
    /// Whether the PI drive sat at its torque limit (its margin is the last switch).
    fn saturated(&self) -> bool {
        self.switches[SWITCHES - 1] < 0.0
    }
}

/// Number of switching functions in an evaluation.
const SWITCHES: usize = 7;

/// Crank angle (rad), speed (rad/s) and the PI controller's integral (rad).
type CrankState = (f64, f64, f64);

/// The steps stored near the end of one hold, for its whole-revolution window: time, crank
/// angle and speed of each, and in one flat buffer its accumulated quantities followed by their
/// rates. Sized before the run, so stepping through the window does not allocate.
struct Window {
    points: Vec<(f64, f64, f64)>,
    data: Vec<f64>,
    n: usize,
}

impl Window {
    fn with_capacity(points: usize, n: usize) -> Self {
        Self {
            points: Vec::with_capacity(points),
            data: Vec::with_capacity(points * 2 * n),
            n,
        }
    }

    fn push(&mut self, t: f64, theta: f64, omega: f64, acc: &[f64], rates: &[f64]) {
        self.points.push((t, theta, omega));
        self.data.extend_from_slice(acc);
        self.data.extend_from_slice(rates);
    }

    fn acc(&self, i: usize) -> &[f64] {
        &self.data[2 * self.n * i..2 * self.n * i + self.n]
    }

    fn rates(&self, i: usize) -> &[f64] {
        &self.data[2 * self.n * i + self.n..2 * self.n * (i + 1)]
    }
}

/// A ready-to-run simulation: mechanism, cycle, laws and drive.
pub struct Simulation {
    rig_name: String,
    mech: Mechanism,
    cycle: Cycle,
    joints: Vec<BoundJoint>,
    shares: [f64; 2],
    drive: Drive,
    temps: Vec<f64>,
    viscosities: Vec<f64>,
    window_s: f64,
    lowpass_hz: f64,
    step_rad: f64,
    max_step_s: f64,
    integrator: Integrator,
    rel_tol: f64,
    max_step_rad: f64,
    /// Which of an evaluation's `switches` matter: those of joints that carry a law.
    switch_mask: [bool; SWITCHES],
    /// Whether any bound law keeps state (then steps are fixed and committed).
    stateful: bool,
    tol: f64,
    max_iter: u32,
    n_laws: usize,
    progress: Option<crate::observe::Position>,
}

fn joint_kind(name: &str) -> JointKind {
    if name == "piston" {
        JointKind::Prismatic
    } else {
        JointKind::Revolute
    }
}

impl Simulation {
    /// Bind the model's laws (from `registry`) and prepare the mechanism and cycle.
    pub fn new(model: &RigFile, registry: &LawRegistry) -> Result<Self, SimError> {
        let f = model;
        let setup = |field: String, e: &dyn std::fmt::Display| SimError::Setup {
            at: None,
            field,
            message: e.to_string(),
        };
        let c = &f.bodies.crank;
        let (mu, ru) = (c.unbalance_mass_kg * c.mass_scale, c.unbalance_radius_m);
        let m_crank = c.mass_kg * c.mass_scale + mu;
        let offset = if m_crank > 0.0 {
            mu * ru / m_crank
        } else {
            0.0
        };
        let j_axis = c.inertia_kg_m2 * c.inertia_scale + mu * ru * ru;
        let drive_inertia = match f.drive {
            Drive::Pi {
                belt_ratio,
                motor_inertia_kg_m2,
                ..
            } => motor_inertia_kg_m2 * belt_ratio * belt_ratio,
            Drive::Prescribed => 0.0,
        };
        let r = &f.bodies.rod;
        let geo = RigGeometry {
            crank_radius_m: f.geometry.crank_radius_m,
            rod_length_m: r.length_m,
            rod_com_from_big_end_m: r.com_from_big_end_m,
            crank_inertia_kg_m2: j_axis - m_crank * offset * offset,
            crank_mass_kg: m_crank,
            crank_com_offset_m: offset,
            crank_com_angle_rad: c.unbalance_angle_deg.to_radians(),
            rod_mass_kg: r.mass_kg * r.mass_scale,
            rod_inertia_kg_m2: r.inertia_kg_m2 * r.inertia_scale,
            piston_mass_kg: f.bodies.piston.mass_kg * f.bodies.piston.mass_scale,
            gravity_m_s2: if f.geometry.gravity {
                GRAVITY_M_S2
            } else {
                0.0
            },
            drive_inertia_kg_m2: drive_inertia,
        };
        let mut joints = Vec::new();
        let mut n_laws = 0;
        for (name, j) in f.joints.named() {
            let mut laws = Vec::new();
            for (i, l) in j.laws.iter().enumerate() {
                let field = format!("joints.{name}.laws[{i}]");
                let lib = registry
                    .get(&l.law)
                    .map_err(|e| setup(format!("{field}.law"), &e))?;
                let instance = lib
                    .create(&l.params)
                    .map_err(|e| setup(format!("{field}.params"), &e))?;
                let state = vec![0.0; instance.state_size()];
                laws.push(BoundLaw {
                    name: l.law.clone(),
                    instance,
                    state,
                    calls: AtomicU64::new(0),
                    sampled_ns: AtomicU64::new(0),
                });
                n_laws += 1;
            }
            joints.push(BoundJoint {
                name,
                kind: joint_kind(name),
                radius_m: j.radius_m,
                length_m: j.length_m,
                laws,
            });
        }
        let mut switch_mask = [false; SWITCHES];
        for (ji, j) in joints.iter().enumerate() {
            switch_mask[ji] = !j.laws.is_empty();
        }
        switch_mask[5] = switch_mask[4];
        switch_mask[6] = matches!(f.drive, Drive::Pi { .. });
        let stateful = joints
            .iter()
            .any(|j| j.laws.iter().any(|l| !l.state.is_empty()));
        let cycle = Cycle::new(&f.cycle.segments());
        let temps: Vec<f64> = match &f.oil.temperature_c {
            Temperature::Constant(t) => vec![*t; cycle.plateaus().len()],
            Temperature::PerPlateau(v) => v.clone(),
        };
        let viscosities = temps
            .iter()
            .map(|t| f.oil.viscosity.kinematic_cst(*t) * 1e-6 * f.oil.density_kg_m3)
            .collect();
        Ok(Self {
            rig_name: f.name.clone(),
            mech: Mechanism::new(geo),
            cycle,
            joints,
            shares: [f.joints.main_a.load_share, f.joints.main_b.load_share],
            drive: f.drive.clone(),
            temps,
            viscosities,
            window_s: f.measurement.window_s,
            lowpass_hz: f.measurement.lowpass_hz,
            step_rad: f.solver.step_deg.to_radians(),
            max_step_s: f.solver.max_step_s,
            integrator: f.solver.integrator,
            rel_tol: f.solver.rel_tol,
            max_step_rad: f.solver.max_step_deg.to_radians(),
            switch_mask,
            stateful,
            tol: f.solver.friction_tol,
            max_iter: f.solver.friction_max_iter,
            n_laws,
            progress: None,
        })
    }

    /// Report progress (permille of the simulated cycle, or plateaus done in steady mode) to `p`.
    pub fn report_progress(&mut self, p: crate::observe::Position) {
        self.progress = Some(p);
    }

    /// The mechanism (for tests and studies).
    pub fn mechanism(&self) -> &Mechanism {
        &self.mech
    }

    /// Oil temperature and viscosity in force at time `t`: the plateau's value during a hold
    /// and the ramp leading to it; after the last plateau, the last value.
    fn oil_at(&self, t: f64) -> (f64, f64) {
        let i = self
            .cycle
            .plateaus()
            .iter()
            .position(|p| t <= p.t_end)
            .unwrap_or(self.temps.len().saturating_sub(1));
        (self.temps[i], self.viscosities[i])
    }

    fn layout(&self) -> RateLayout {
        RateLayout { n: self.n_laws }
    }

    /// Normal loads per joint from the reactions.
    fn normals(&self, re: &Reactions) -> [f64; 5] {
        let main = re.main_n.norm();
        [
            main * self.shares[0],
            main * self.shares[1],
            re.big_end_n.norm(),
            re.small_end_n.norm(),
            re.slide_lateral_n.abs(),
        ]
    }

    /// Evaluate the rig at one instant. `control` is `Ok(alpha)` for a prescribed crank or
    /// `Err(torque)` for a crank driven by a torque.
    #[allow(clippy::too_many_arguments)]
    fn evaluate(
        &self,
        t: f64,
        dt: f64,
        theta: f64,
        omega: f64,
        control: Result<f64, f64>,
        saturation_margin: f64,
        guess: &JointLoads,
        oil: (f64, f64),
        buffer: Vec<f64>,
    ) -> Result<(Eval, JointLoads), SimError> {
        let (temp, visc) = oil;
        let mut loads = *guess;
        let mut prev: Option<[f64; 5]> = None;
        let mut last_change: Option<f64> = None;
        let mut older_change: Option<f64> = None;
        // The caller's recycled buffer: no allocation per evaluation once warmed up.
        let mut rates = buffer;
        rates.clear();
        rates.resize(self.layout().len(), 0.0);
        // Positions, velocities and the factorised constraints do not depend on the loads:
        // computed once, the iteration below only recombines the multipliers.
        let kin = self.mech.kinematics(theta, omega);
        let qd = &kin.qd;
        let rel = [qd[2], qd[2], qd[5] - qd[2], qd[8] - qd[5], qd[7]];
        let crank_angle = crank_angle(theta);
        let mut inputs: [LawInput; 5] = std::array::from_fn(|ji| {
            let joint = &self.joints[ji];
            let mut input = LawInput::at_rest(joint.kind);
            input.contact_radius_m = joint.radius_m;
            input.contact_length_m = joint.length_m;
            input.oil_temp_c = temp;
            input.viscosity_pa_s = visc;
            input.engine_speed_rad_s = omega;
            input.crank_angle_rad = crank_angle;
            input.time_s = t;
            input.dt_s = dt;
            input.with_velocity(rel[ji])
        });
        let finish = |rates: Vec<f64>, alpha: f64, re: &Reactions, normals, iterations, newton| {
            let mut rates = rates;
            rates[RateLayout::MOTOR] = re.drive_torque_nm * omega;
            Eval {
                omega,
                alpha,
                drive_torque: re.drive_torque_nm,
                rates,
                normals,
                switches: [
                    rel[0],
                    rel[1],
                    rel[2],
                    rel[3],
                    rel[4],
                    re.slide_lateral_n,
                    saturation_margin,
                ],
                iterations,
                newton,
            }
        };
        let layout = self.layout();
        // Phase 1: the plain fixed-point iteration (solve, evaluate the laws at the resulting
        // normal loads, repeat). It settles every bundled law set in a few iterations.
        for it in 1..=self.max_iter {
            let alpha = match control {
                Ok(alpha) => alpha,
                Err(torque) => kin.alpha_for_torque(torque, &loads),
            };
            let re = kin.reactions(alpha, &loads);
            let normals = self.normals(&re);
            // Converged when the normal loads' distance to the fixed point is within tolerance:
            // the last change, or once the iteration is seen to contract by a factor rho, the
            // geometric remainder rho / (1 - rho) of it.
            let scale = normals.iter().fold(1.0_f64, |m, n| m.max(*n));
            let change = prev.map(|p| {
                p.iter()
                    .zip(&normals)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
            });
            let converged = change.is_some_and(|d| {
                let remainder = match last_change {
                    Some(d0) if d < 0.5 * d0 => d * (d / d0) / (1.0 - d / d0),
                    _ => d,
                };
                remainder <= self.tol * scale
            });
            let stalls = match (change, older_change) {
                (Some(d), Some(d2)) if !converged => {
                    plain_iteration_stalls(d, d2, self.tol * scale, self.max_iter - it)
                }
                _ => false,
            };
            older_change = last_change;
            last_change = change;
            if converged || self.n_laws == 0 {
                let e = finish(rates, alpha, &re, normals, it, false);
                return Ok((e, loads));
            }
            if stalls {
                let mut p = Problem {
                    kin: &kin,
                    control,
                    rel,
                    inputs: &mut inputs,
                    t,
                };
                let s = self.settle_by_newton(&mut p, it, &re, &normals, &mut rates)?;
                let e = finish(rates, s.alpha, &s.re, s.normals, s.iterations, true);
                return Ok((e, s.loads));
            }
            // Law inputs: only the loads change from one iteration to the next. (The law loop
            // is written out here rather than calling `joint_force`: this is the hot path, and
            // the call cost a tenth of a PI run's instructions.)
            let comps = self.components(&re);
            let mut new_loads = JointLoads::default();
            // Powers and mean loads are written for every law below; only the regime
            // indicators are set sparsely and need clearing.
            rates[layout.regimes()].fill(0.0);
            let mut k = 0;
            for (ji, joint) in self.joints.iter().enumerate() {
                let input = &mut inputs[ji];
                input.normal_load_n = normals[ji];
                input.reaction_x_n = comps[ji].x;
                input.reaction_y_n = comps[ji].y;
                input.reaction_moment_nm = if ji == 4 { re.slide_moment_nm } else { 0.0 };
                let input = &*input;
                let mut total = 0.0;
                for law in &joint.laws {
                    // One simulation is stepped by one thread: a plain load and store, not a
                    // locked read-modify-write (which cost ~15% of an evaluation).
                    let calls = law.calls.load(Ordering::Relaxed);
                    law.calls.store(calls + 1, Ordering::Relaxed);
                    let out = if calls % TIMING_SAMPLE == 0 {
                        timed_evaluate(law, input)
                    } else {
                        law.instance.evaluate(input, &law.state)
                    };
                    let out = match out {
                        Ok(out) => out,
                        Err(e) => return Err(law_failed(joint, t, input, e)),
                    };
                    // A stateless law must not add energy; a stateful one may return what it
                    // stored.
                    let power = out.force * rel[ji];
                    let adds = power > 0.0
                        && law.state.is_empty()
                        && power > 1e-9 * (1.0 + power.abs().sqrt());
                    if !out.force.is_finite() || adds {
                        return Err(unusable(joint, law, t, input, out.force));
                    }
                    total += out.force;
                    let regime = out.regime().unwrap_or(Regime::None) as usize;
                    rates[layout.power(k)] = -power;
                    rates[layout.regime(k, regime)] = 1.0;
                    rates[layout.normal(k)] = normals[ji];
                    k += 1;
                }
                match ji {
                    0 | 1 => new_loads.main_torque_nm += total,
                    2 => new_loads.big_end_torque_nm = total,
                    3 => new_loads.small_end_torque_nm = total,
                    _ => new_loads.slide_force_n = total,
                }
            }
            if it == self.max_iter {
                // The joints whose loads were still moving: the last change, or after a single
                // solve, the one the next solve would make.
                let before = prev.unwrap_or_else(|| {
                    let p = Problem {
                        kin: &kin,
                        control,
                        rel,
                        inputs: &mut inputs,
                        t,
                    };
                    self.normals(&p.solve(&new_loads).1)
                });
                let changes = std::array::from_fn(|ji| (before[ji] - normals[ji]).abs());
                let scale = before.iter().fold(scale, |m, n| m.max(*n));
                return Err(self.no_convergence(t, it, &changes, scale));
            }
            prev = Some(normals);
            loads = new_loads;
        }
        // Not reached (the last iteration returns), but an error is the honest answer.
        Err(self.no_convergence(t, self.max_iter, &[f64::NAN; 5], 1.0))
    }

    /// The reaction components each joint's laws see: main bearings (each its share), big end,
    /// small end (global x, y) and the slide (along and normal to its axis).
    fn components(&self, re: &Reactions) -> [Vector2<f64>; 5] {
        [
            re.main_n * self.shares[0],
            re.main_n * self.shares[1],
            re.big_end_n,
            re.small_end_n,
            Vector2::new(0.0, re.slide_lateral_n),
        ]
    }

    /// The friction force (slide) or torque (revolute) of all laws on joint `ji` for its input
    /// in `p`, checked (finite; a stateless law must not add energy). With `record`, each law's
    /// power, regime and load are written into the rate vector from law index `k` on.
    fn joint_force(
        &self,
        p: &Problem<'_>,
        ji: usize,
        record: Option<(&mut [f64], usize)>,
    ) -> Result<f64, SimError> {
        let joint = &self.joints[ji];
        let layout = self.layout();
        let input = &p.inputs[ji];
        let mut record = record;
        let mut total = 0.0;
        for (i, law) in joint.laws.iter().enumerate() {
            // One simulation is stepped by one thread: a plain load and store, not a locked
            // read-modify-write (which cost ~15% of an evaluation).
            let calls = law.calls.load(Ordering::Relaxed);
            law.calls.store(calls + 1, Ordering::Relaxed);
            let out = if calls % TIMING_SAMPLE == 0 {
                timed_evaluate(law, input)
            } else {
                law.instance.evaluate(input, &law.state)
            };
            let out = match out {
                Ok(out) => out,
                Err(e) => return Err(law_failed(joint, p.t, input, e)),
            };
            // A stateless law must not add energy; a stateful one may return what it stored.
            let power = out.force * p.rel[ji];
            let adds =
                power > 0.0 && law.state.is_empty() && power > 1e-9 * (1.0 + power.abs().sqrt());
            if !out.force.is_finite() || adds {
                return Err(unusable(joint, law, p.t, input, out.force));
            }
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
    fn settle_by_newton(
        &self,
        p: &mut Problem<'_>,
        mut it: u32,
        entry: &Reactions,
        entry_normals: &[f64; 5],
        rates: &mut [f64],
    ) -> Result<Settled, SimError> {
        let active: [bool; 5] = std::array::from_fn(|ji| !self.joints[ji].laws.is_empty());
        let base = Base {
            comps: self.components(entry),
            normals: *entry_normals,
            moment: entry.slide_moment_nm,
        };
        let mut u: [f64; 5] = std::array::from_fn(|ji| entry_normals[ji].sqrt());
        let mut cur = self.round(p, &base, &u, rates)?;
        loop {
            let residual: [f64; 5] = std::array::from_fn(|ji| {
                if active[ji] {
                    cur.normals[ji] - u[ji] * u[ji]
                } else {
                    0.0
                }
            });
            let scale = cur.normals.iter().fold(1.0_f64, |m, n| m.max(*n));
            if residual.iter().all(|r| r.abs() <= self.tol * scale) {
                return Ok(Settled {
                    iterations: it,
                    ..cur
                });
            }
            if it >= self.max_iter {
                let changes = residual.map(f64::abs);
                return Err(self.no_convergence(p.t, it, &changes, scale));
            }
            it += 1;
            // Jacobian of rho(u) = N(u^2) - u^2; joints without laws keep an identity row.
            let mut jac = nalgebra::Matrix5::<f64>::identity();
            for j in (0..5).filter(|&j| active[j]) {
                let h = NEWTON_FD_STEP * u[j].max(scale.sqrt());
                let uj = u[j] + h;
                base.load_input(&mut p.inputs[j], j, uj * uj);
                let mut totals = cur.totals;
                totals[j] = self.joint_force(p, j, None)?;
                let (_, re) = p.solve(&loads_from(&totals));
                let n = self.normals(&re);
                for i in (0..5).filter(|&i| active[i]) {
                    let own = if i == j { 2.0 * u[j] + h } else { 0.0 };
                    jac[(i, j)] = (n[i] - cur.normals[i]) / h - own;
                }
            }
            let rhs = nalgebra::Vector5::from_fn(|i, _| -residual[i]);
            let norm0 = residual.iter().map(|r| r * r).sum::<f64>().sqrt();
            let step = jac.lu().solve(&rhs);
            let mut length = if step.is_some() { 1.0 } else { 0.0 };
            let step = step.unwrap_or_else(nalgebra::Vector5::zeros);
            // Backtracking: the first step length whose residual is smaller.
            loop {
                if length < NEWTON_MIN_STEP {
                    // No descent along the Newton direction (a local minimum of the residual
                    // across a reaction's sign change, or a kink): settle the worst joint alone.
                    let worst = (0..5).filter(|&ji| active[ji]).fold(
                        None,
                        |w: Option<usize>, ji| match w {
                            Some(b) if residual[b].abs() >= residual[ji].abs() => Some(b),
                            _ => Some(ji),
                        },
                    );
                    let settled = match worst {
                        Some(j) => self.bracket_joint(p, &base, &cur, &u, j, scale)?,
                        None => None,
                    };
                    let Some(uj) = settled else {
                        let changes = residual.map(f64::abs);
                        return Err(self.no_convergence(p.t, it, &changes, scale));
                    };
                    if let Some(j) = worst {
                        u[j] = uj;
                    }
                    cur = self.round(p, &base, &u, rates)?;
                    break;
                }
                let trial_u: [f64; 5] = std::array::from_fn(|ji| (u[ji] + length * step[ji]).abs());
                let trial = self.round(p, &base, &trial_u, rates)?;
                let norm = (0..5)
                    .filter(|&ji| active[ji])
                    .map(|ji| (trial.normals[ji] - trial_u[ji] * trial_u[ji]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                if norm <= (1.0 - 1e-4 * length) * norm0 {
                    u = trial_u;
                    cur = trial;
                    break;
                }
                length *= 0.5;
            }
        }
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
            base.load_input(&mut p.inputs[j], j, x * x);
            let mut totals = cur.totals;
            totals[j] = self.joint_force(p, j, None)?;
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
        for (ji, joint) in self.joints.iter().enumerate() {
            if !joint.laws.is_empty() {
                base.load_input(&mut p.inputs[ji], ji, u[ji] * u[ji]);
                totals[ji] = self.joint_force(p, ji, Some((rates, k)))?;
            }
            k += joint.laws.len();
        }
        let loads = loads_from(&totals);
        let (alpha, re) = p.solve(&loads);
        Ok(Settled {
            alpha,
            normals: self.normals(&re),
            re,
            loads,
            totals,
            iterations: 0,
        })
    }

    /// The error for an iteration that did not settle: `changes` per joint (N), the joints
    /// with laws whose change exceeds the tolerance named with their laws.
    #[cold]
    fn no_convergence(&self, t: f64, iterations: u32, changes: &[f64; 5], scale: f64) -> SimError {
        let tol_n = self.tol * scale;
        // Empty when every change is within tolerance: the limit came before a second solve.
        let unsettled: Vec<Unsettled> = self
            .joints
            .iter()
            .zip(changes)
            .filter(|(j, _)| !j.laws.is_empty())
            .filter(|(_, c)| c.is_nan() || **c > tol_n)
            .map(|(j, c)| Unsettled {
                joint: j.name.into(),
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

    /// Commit every stateful law over the accepted step ending at `e`.
    fn commit(
        &mut self,
        t: f64,
        dt: f64,
        theta: f64,
        e: &Eval,
        oil: (f64, f64),
    ) -> Result<(), SimError> {
        if !self.stateful {
            return Ok(());
        }
        let (temp, visc) = oil;
        let qd = self.mech.kinematics(theta, e.omega).qd;
        let rel = [qd[2], qd[2], qd[5] - qd[2], qd[8] - qd[5], qd[7]];
        for (ji, joint) in self.joints.iter_mut().enumerate() {
            if joint.laws.iter().all(|l| l.state.is_empty()) {
                continue;
            }
            let mut input = LawInput::at_rest(joint.kind);
            input.normal_load_n = e.normals[ji];
            input.contact_radius_m = joint.radius_m;
            input.contact_length_m = joint.length_m;
            input.oil_temp_c = temp;
            input.viscosity_pa_s = visc;
            input.engine_speed_rad_s = e.omega;
            input.crank_angle_rad = crank_angle(theta);
            input.time_s = t;
            input.dt_s = dt;
            let input = input.with_velocity(rel[ji]);
            let e_normal = e.normals[ji];
            for law in &mut joint.laws {
                if !law.state.is_empty() {
                    law.instance
                        .commit(&input, &mut law.state)
                        .map_err(|e| SimError::Law {
                            joint: joint.name.into(),
                            time_s: t,
                            velocity: rel[ji],
                            load_n: e_normal,
                            source: Box::new(e),
                        })?;
                }
            }
        }
        Ok(())
    }

    fn energy(&self, theta: f64, omega: f64) -> f64 {
        let (st, _) = self.mech.solve(theta, omega, 0.0, &JointLoads::default());
        self.mech.kinetic_energy(&st.qd) + self.mech.potential_energy(&st.q)
    }

    /// Run the whole test cycle. With `timeseries`, one CSV line per step is streamed to it.
    pub fn run(&mut self, mut timeseries: Option<&mut dyn Write>) -> Result<RunResult, SimError> {
        let n = self.layout().len();
        let duration = self.cycle.duration();
        let plateaus = self.cycle.plateaus().to_vec();
        // Grid breakpoints: segment ends, and for a prescribed crank the exact window starts,
        // so every window begins and ends on a step.
        let mut breaks: Vec<f64> = self.cycle.breakpoints();
        let prescribed = matches!(self.drive, Drive::Prescribed);
        if prescribed {
            for p in &plateaus {
                let revs = self.window_revs(p.omega);
                breaks.push(p.t_end - revs as f64 * TAU / p.omega);
            }
        }
        breaks.retain(|b| *b > 0.0 && *b <= duration);
        breaks.sort_by(f64::total_cmp);
        breaks.dedup_by(|a, b| (*a - *b).abs() < 1e-12);

        if let Some(w) = timeseries.as_mut() {
            write!(
                w,
                "time_s,theta_rad,speed_rpm,motoring_torque_nm,motoring_torque_filtered_nm"
            )?;
            for name in JOINT_NAMES {
                write!(w, ",{name}_normal_load_n")?;
            }
            writeln!(w)?;
        }

        let (mut theta, mut omega, mut z) = (0.0, 0.0, 0.0);
        let mut acc = vec![0.0; n];
        let mut guess = JointLoads::default();
        let e0 = self.energy(0.0, 0.0);
        let (mut filtered, mut steps, mut max_it) = (0.0, 0_u64, 0_u32);
        // Window storage per plateau, sized for the steps its measurement margin will hold.
        let mut records: Vec<Window> = plateaus
            .iter()
            .map(|p| {
                let w = p.omega.max(1e-9);
                let h = self.time_step(self.step_rad, w);
                let margin = self.window_s + 2.0 * TAU / w;
                Window::with_capacity((margin / h).ceil() as usize + 16, n)
            })
            .collect();
        let mut saturated_time = vec![0.0; plateaus.len()];
        let mut t = 0.0;
        // Recycled rate buffers, and the RK4 end state carried into the next step.
        let mut pool: Vec<Vec<f64>> = Vec::new();
        let mut carried: Option<(Eval, JointLoads, f64)> = None;
        let (e_start, l_start) = self.step_eval(t, 0.0, theta, omega, z, &guess, Vec::new())?;
        let mut last_rates = e_start.rates.clone();
        // The adaptive integrator: stateless laws only (a stateful law's state is advanced with
        // the step's length, which must then not vary).
        let adaptive = !prescribed && self.integrator == Integrator::Adaptive && !self.stateful;
        let pair = &DORMAND_PRINCE_54;
        let control = Controller::new(pair);
        let mut fsal = (e_start, l_start);
        let (mut incr, mut est) = (vec![0.0; n], vec![0.0; n]);
        let mut stages: Vec<Eval> = Vec::with_capacity(pair.stages());
        let mut h_next = f64::INFINITY;
        let mut previous_end: Option<(f64, [f64; SWITCHES])> = None;
        for &b in &breaks {
            let (_, w_end, _) = self.cycle.reference(b);
            let w_max = w_end.max(self.cycle.reference(t).1).max(omega);
            let dt_target = self.time_step(self.step_rad, w_max);
            let m = ((b - t) / dt_target).ceil().max(1.0) as u64;
            let dt = (b - t) / m as f64;
            if prescribed {
                // The reference acceleration may jump at t: start this interval from its own
                // side of the jump so Simpson's rule never straddles it.
                let (th0, w0, a0) = self.cycle.reference_after(t);
                let (e0, l0) = self.evaluate(
                    t,
                    dt,
                    th0,
                    w0,
                    Ok(a0),
                    f64::INFINITY,
                    &guess,
                    self.oil_at(t),
                    pool.pop().unwrap_or_default(),
                )?;
                pool.push(std::mem::replace(&mut last_rates, e0.rates));
                guess = l0;
            }
            let mut i = 0_u64;
            while t < b {
                i += 1;
                let t1 = if i == m { b } else { t + dt };
                let h = t1 - t;
                let (t1, h, e_end, new_state) = if adaptive {
                    let (t1, e1, l1, state) = self.adaptive_step(
                        pair,
                        &control,
                        t,
                        b,
                        &mut h_next,
                        &mut previous_end,
                        (theta, omega, z),
                        &fsal,
                        (&mut incr, &mut est),
                        &mut stages,
                        &mut pool,
                        &mut max_it,
                    )?;
                    acc.iter_mut().zip(&incr).for_each(|(a, d)| *a += d);
                    guess = l1;
                    (t1, t1 - t, e1, state)
                } else if prescribed {
                    let (th_m, w_m, a_m) = self.cycle.reference(t + 0.5 * h);
                    let (em, lm) = self.evaluate(
                        t + 0.5 * h,
                        h,
                        th_m,
                        w_m,
                        Ok(a_m),
                        f64::INFINITY,
                        &guess,
                        self.oil_at(t + 0.5 * h),
                        pool.pop().unwrap_or_default(),
                    )?;
                    let (th1, w1, a1) = self.cycle.reference(t1);
                    let (e1, l1) = self.evaluate(
                        t1,
                        h,
                        th1,
                        w1,
                        Ok(a1),
                        f64::INFINITY,
                        &lm,
                        self.oil_at(t1),
                        pool.pop().unwrap_or_default(),
                    )?;
                    guess = l1;
                    max_it = max_it.max(em.iterations).max(e1.iterations);
                    // Simpson's rule on every accumulated rate.
                    for k in 0..n {
                        acc[k] += h / 6.0 * (last_rates[k] + 4.0 * em.rates[k] + e1.rates[k]);
                    }
                    pool.push(em.rates);
                    (t1, h, e1, (th1, w1, 0.0))
                } else {
                    // The previous step's end state is this step's first RK4 stage when the
                    // step size (which the laws see) is the same.
                    let first = carried
                        .take()
                        .filter(|(e, _, hh)| *hh == h && e.omega == omega)
                        .map(|(e, l, _)| (e, l));
                    let (e1, l1, state) = self.rk4_step(
                        t,
                        h,
                        theta,
                        omega,
                        z,
                        &mut guess,
                        &mut max_it,
                        &mut acc,
                        &mut pool,
                        first,
                    )?;
                    guess = l1;
                    (t1, h, e1, state)
                };
                theta = new_state.0;
                omega = new_state.1;
                z = new_state.2;
                self.commit(t1, h, theta, &e_end, self.oil_at(t1))?;
                last_rates.copy_from_slice(&e_end.rates);
                steps += 1;
                if steps % 4096 == 0 {
                    if let Some(p) = &self.progress {
                        p.set((1000.0 * t1 / duration) as u64);
                    }
                }
                // Low-pass filter of the motoring torque (first order, exact discretisation).
                let a = (-TAU * self.lowpass_hz * h).exp();
                filtered = a * filtered + (1.0 - a) * e_end.drive_torque;
                if let Some(w) = timeseries.as_mut() {
                    write!(
                        w,
                        "{t1:.7},{theta:.6},{:.4},{:.6},{filtered:.6}",
                        rad_s_to_rpm(omega),
                        e_end.drive_torque
                    )?;
                    for nl in e_end.normals {
                        write!(w, ",{nl:.4}")?;
                    }
                    writeln!(w)?;
                }
                for (pi, p) in plateaus.iter().enumerate() {
                    let margin = self.window_s + 2.0 * TAU / p.omega.max(1e-9) + 2.0 * h;
                    if t1 >= p.t_end - margin && t1 <= p.t_end + 1e-12 {
                        if e_end.saturated() {
                            saturated_time[pi] += h;
                        }
                        records[pi].push(t1, theta, omega, &acc, &last_rates);
                    }
                }
                if prescribed {
                    pool.push(e_end.rates);
                } else if adaptive {
                    pool.push(std::mem::replace(&mut fsal, (e_end, guess)).0.rates);
                } else {
                    carried = Some((e_end, guess, h));
                }
                t = t1;
            }
        }
        let e1 = self.energy(theta, omega);
        let motor_work = acc[0];
        let dissipated: f64 = acc[self.layout().powers()].iter().sum();
        let residual = motor_work - (e1 - e0) - dissipated;
        let energy = EnergyBalance {
            motor_work_j: motor_work,
            mechanical_energy_change_j: e1 - e0,
            dissipated_j: dissipated,
            residual_j: residual,
            relative_residual: if motor_work.abs() > 0.0 {
                residual.abs() / motor_work.abs()
            } else {
                residual.abs()
            },
        };
        let mut results = Vec::new();
        let mut warnings = Vec::new();
        for (pi, p) in plateaus.iter().enumerate() {
            results.push(self.measure(pi, p.omega, p.t_end, &records[pi]));
            if saturated_time[pi] > 0.5 * self.window_s {
                warnings.push(format!(
                    "at the {:.0} rpm plateau the drive sat at its torque limit for {:.3} s near the measurement window; the plateau torque is limited by the drive",
                    rad_s_to_rpm(p.omega),
                    saturated_time[pi]
                ));
            }
            let r = &results[pi];
            if (r.mean_speed_rpm - r.set_speed_rpm).abs() > 0.02 * r.set_speed_rpm {
                warnings.push(format!("the {:.0} rpm plateau reached only {:.1} rpm on average: the speed never settled", r.set_speed_rpm, r.mean_speed_rpm));
            }
        }
        Ok(RunResult {
            rig: self.rig_name.clone(),
            drive: match self.drive {
                Drive::Prescribed => "prescribed".into(),
                Drive::Pi { .. } => "pi".into(),
            },
            plateaus: results,
            energy_residual_j: residual,
            energy,
            steps,
            max_friction_iterations: max_it,
            warnings,
            law_time: self.law_time(),
        })
    }

    /// Calls and estimated time per law so far.
    fn law_time(&self) -> Vec<LawTime> {
        self.joints
            .iter()
            .flat_map(|j| {
                j.laws.iter().map(move |l| LawTime {
                    joint: j.name.into(),
                    law: l.name.clone(),
                    calls: l.calls.load(Ordering::Relaxed),
                    seconds: l.sampled_ns.load(Ordering::Relaxed) as f64
                        * TIMING_SAMPLE as f64
                        * 1e-9,
                })
            })
            .collect()
    }

    /// The time the crank needs to turn `angle_rad` at speed `omega`, capped by
    /// `solver.max_step_s` (which also covers a crank at rest).
    fn time_step(&self, angle_rad: f64, omega: f64) -> f64 {
        if omega > 0.0 {
            (angle_rad / omega).min(self.max_step_s)
        } else {
            self.max_step_s
        }
    }

    /// Whole revolutions in the measurement window at speed `omega` (at least one).
    fn window_revs(&self, omega: f64) -> u32 {
        ((self.window_s * omega / TAU).floor() as u32).max(1)
    }

    /// The drive torque, the controller integral's rate and the margin to the torque limit
    /// (negative while saturated) for a PI drive.
    fn pi_torque(&self, t: f64, omega: f64, z: f64) -> (f64, f64, f64) {
        match self.drive {
            Drive::Pi {
                kp,
                ki,
                torque_limit_nm,
                belt_ratio,
                ..
            } => {
                let e = self.cycle.reference(t).1 - omega;
                let raw = kp * e + ki * z;
                let motor = raw.clamp(-torque_limit_nm, torque_limit_nm);
                let margin = torque_limit_nm - raw.abs();
                // Conditional integration: stop integrating while saturated in the direction
                // the error pushes, so the integral cannot wind up.
                let dz = if margin < 0.0 && raw.signum() == e.signum() {
                    0.0
                } else {
                    e
                };
                (motor * belt_ratio, dz, margin)
            }
            Drive::Prescribed => (0.0, 0.0, f64::INFINITY),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn step_eval(
        &self,
        t: f64,
        dt: f64,
        theta: f64,
        omega: f64,
        z: f64,
        guess: &JointLoads,
        buffer: Vec<f64>,
    ) -> Result<(Eval, JointLoads), SimError> {
        match self.drive {
            Drive::Prescribed => {
                // The reference motion defines the state; the integrated one is not used.
                let (th, w, a) = self.cycle.reference(t);
                self.evaluate(
                    t,
                    dt,
                    th,
                    w,
                    Ok(a),
                    f64::INFINITY,
                    guess,
                    self.oil_at(t),
                    buffer,
                )
            }
            Drive::Pi { .. } => {
                let (torque, _, sat) = self.pi_torque(t, omega, z);
                self.evaluate(
                    t,
                    dt,
                    theta,
                    omega,
                    Err(torque),
                    sat,
                    guess,
                    self.oil_at(t),
                    buffer,
                )
            }
        }
    }

    /// One accepted error-controlled step from `t` towards the breakpoint `b`: steps are tried
    /// from `h_next` (capped by `solver.max_step_deg` and `max_step_s`, and ending exactly on
    /// `b` when close to it) and shrunk until the estimated error meets `solver.rel_tol`.
    /// `first` is the evaluation at the step's start. Returns the step's end time (exactly `b`
    /// when it lands there), the end evaluation with its loads and the end state; the
    /// accumulated quantities' increment is in `incr`, and `h_next` is updated for the
    /// following step.
    #[allow(clippy::too_many_arguments)]
    fn adaptive_step(
        &self,
        pair: &Pair,
        control: &Controller,
        t: f64,
        b: f64,
        h_next: &mut f64,
        previous_end: &mut Option<(f64, [f64; SWITCHES])>,
        y: CrankState,
        first: &(Eval, JointLoads),
        (incr, est): (&mut [f64], &mut [f64]),
        stages: &mut Vec<Eval>,
        pool: &mut Vec<Vec<f64>>,
        max_it: &mut u32,
    ) -> Result<(f64, Eval, JointLoads, CrankState), SimError> {
        let w = y.1.abs().max(self.cycle.reference(t).1.abs());
        let h_cap = self.time_step(self.max_step_rad, w);
        // Across a jump a step may err as much as a longest step of smooth running may.
        let h_floor = h_cap;
        // The first step: one `step_deg` of crank angle.
        let planned = if h_next.is_finite() {
            h_next.min(h_cap)
        } else {
            self.time_step(self.step_rad, w)
        };
        // A switch predicted (linearly from the last two step ends) to change sign within
        // the step: end the step on it, so the kink falls between steps.
        let mut h_switch = f64::INFINITY;
        if let Some((tp, gp)) = previous_end {
            for (i, (&a, &g)) in gp.iter().zip(&first.0.switches).enumerate() {
                if self.switch_mask[i] && a * g > 0.0 && (g - a) * g < 0.0 && t > *tp {
                    let dt = g * (t - *tp) / (a - g);
                    if dt > 0.05 * planned && dt < planned {
                        h_switch = h_switch.min(dt);
                    }
                }
            }
        }
        let mut h = planned.min(h_switch);
        let mut rejected = false;
        loop {
            let remaining = b - t;
            // End on the breakpoint, without leaving a sliver step before it.
            let h_try = if remaining <= 1.1 * h {
                remaining
            } else if remaining < 2.0 * h {
                0.5 * remaining
            } else {
                h
            };
            let (err, e1, l1, y1, crossing) =
                self.pair_step(pair, t, h_try, h_floor, y, first, (incr, est), stages, pool)?;
            *max_it = (*max_it).max(e1.iterations);
            if err <= 1.0 {
                // A step cut short to land on `b` or a switch does not shrink the next one.
                let next = control.next(h_try, err, rejected);
                let cut_short = h_switch.is_finite() || h_try < h;
                *h_next = if cut_short { next.max(planned) } else { next };
                *previous_end = Some((t, first.0.switches));
                let t1 = if h_try == remaining { b } else { t + h_try };
                return Ok((t1, e1, l1, y1));
            }
            pool.push(e1.rates);
            rejected = true;
            h = control.next(h_try, err, true);
            // A switch inside the failed step: retry up to it rather than by the error alone.
            if let Some(f) = crossing {
                if f > 0.02 && f < 0.95 {
                    h = f * h_try;
                }
            }
            if h <= 1e-12 * t.abs().max(1e-3) {
                return Err(SimError::StepTooSmall {
                    time_s: t,
                    step_s: h,
                    rel_tol: self.rel_tol,
                });
            }
        }
    }

    /// One attempted step of the embedded `pair` of length `h` from state `y` at `t`, `first`
    /// being the evaluation there. Returns the scaled error estimate (acceptable at <= 1), the
    /// end evaluation with its loads and the end state, and writes the step's increment of
    /// every accumulated quantity to `incr`.
    ///
    /// A step may err by `rel_tol` times the largest rate of the quantity over the step (at
    /// least 1 for the crank state; for powers and for normal loads the largest of the group,
    /// at least 1e-3 W or N; see [`RateLayout::controlled`]) times the step plus `h_floor`. Over smooth stretches that bounds
    /// the error per unit time, so the integrals over a hold are good to about `rel_tol`;
    /// across a jump of a rate (a law's near-discontinuity, the drive's anti-windup switch) the
    /// step shrinks until its error is that of an `h_floor` step instead of failing for ever.
    #[allow(clippy::too_many_arguments)]
    fn pair_step(
        &self,
        pair: &Pair,
        t: f64,
        h: f64,
        h_floor: f64,
        y: CrankState,
        first: &(Eval, JointLoads),
        (incr, est): (&mut [f64], &mut [f64]),
        stages: &mut Vec<Eval>,
        pool: &mut Vec<Vec<f64>>,
    ) -> Result<(f64, Eval, JointLoads, CrankState, Option<f64>), SimError> {
        const MAX_STAGES: usize = 8;
        let s = pair.stages();
        debug_assert!(s <= MAX_STAGES);
        let mut k = [[0.0_f64; 3]; MAX_STAGES];
        let (_, dz, _) = self.pi_torque(t, y.1, y.2);
        k[0] = [y.1, first.0.alpha, dz];
        // The friction iteration starts from the loads extrapolated (linearly in time) from the
        // two latest stages: one or two iterations fewer than starting from the latest.
        let mut loads = first.1;
        let mut older: Option<(f64, JointLoads)> = None;
        let mut t_last = t;
        stages.clear();
        let mut y1 = [y.0, y.1, y.2];
        for st in 1..s {
            let mut ys = [y.0, y.1, y.2];
            for (j, a) in pair.a[st].iter().enumerate() {
                for c in 0..3 {
                    ys[c] += h * a * k[j][c];
                }
            }
            let ts = t + pair.c[st] * h;
            let (torque, dz, sat) = self.pi_torque(ts, ys[1], ys[2]);
            let guess = match older {
                Some((t0, l0)) if t_last > t0 => {
                    loads.extrapolated(&l0, (ts - t_last) / (t_last - t0))
                }
                _ => loads,
            };
            let (e, l) = self.evaluate(
                ts,
                h,
                ys[0],
                ys[1],
                Err(torque),
                sat,
                &guess,
                self.oil_at(ts),
                pool.pop().unwrap_or_default(),
            )?;
            k[st] = [ys[1], e.alpha, dz];
            older = Some((t_last, loads));
            t_last = ts;
            loads = l;
            stages.push(e);
            y1 = ys;
        }
        let Some(end) = stages.pop() else {
            unreachable!("an embedded pair has at least two stages")
        };
        // Stage j's evaluation: the given first, the stored middle ones, the end.
        let evals: [&Eval; MAX_STAGES] = std::array::from_fn(|j| match j {
            0 => &first.0,
            j if j < s - 1 => &stages[j - 1],
            _ => &end,
        });
        let rates: [&[f64]; MAX_STAGES] = std::array::from_fn(|j| &evals[j].rates[..]);
        let mut err = 0.0_f64;
        // The crank state: angle, speed, controller integral.
        for c in 0..3 {
            let (est, peak) = k[..s]
                .iter()
                .zip(pair.e)
                .fold((0.0, 1.0_f64), |(sum, peak), (kj, e)| {
                    (sum + e * kj[c], peak.max(kj[c].abs()))
                });
            err = err.max((h * est).abs() / (self.rel_tol * (h + h_floor) * peak));
        }
        // The step's increments (propagated weights) and error estimates (error weights) of
        // every accumulated quantity, stage by stage so the loops run over contiguous rates.
        // Only the controlled groups need an error estimate.
        let controlled = self.layout().controlled();
        incr.fill(0.0);
        est.fill(0.0);
        for (j, r) in rates.iter().enumerate().take(s) {
            let (b, e) = (h * pair.b[j], h * pair.e[j]);
            if b != 0.0 {
                incr.iter_mut().zip(r.iter()).for_each(|(d, r)| *d += b * r);
            }
            if e != 0.0 {
                for (range, _) in &controlled {
                    est[range.clone()]
                        .iter_mut()
                        .zip(&r[range.clone()])
                        .for_each(|(d, r)| *d += e * r);
                }
            }
        }
        // Each group shares one scale, the largest rate of the group over the step: a small
        // quantity cannot be resolved below the evaluation's own noise, which the friction
        // iteration's tolerance sets relative to the largest of its group.
        for (range, factor) in controlled {
            let peak = rates[..s]
                .iter()
                .flat_map(|r| r[range.clone()].iter())
                .fold(1e-3_f64, |m, r| m.max(r.abs()));
            let worst = est[range].iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            err = err.max(worst / (factor * self.rel_tol * (h + h_floor) * peak));
        }
        // The first switch to change sign, located by linear interpolation between the stages
        // around it (as a fraction of the step).
        let mut crossing: Option<f64> = None;
        for i in (0..SWITCHES).filter(|i| self.switch_mask[*i]) {
            for j in 1..s {
                let (a, g) = (evals[j - 1].switches[i], evals[j].switches[i]);
                if a * g < 0.0 && pair.c[j] > pair.c[j - 1] {
                    let f = pair.c[j - 1] + (pair.c[j] - pair.c[j - 1]) * a / (a - g);
                    crossing = Some(crossing.map_or(f, |c: f64| c.min(f)));
                    break;
                }
            }
        }
        for e in stages.drain(..) {
            pool.push(e.rates);
        }
        Ok((err, end, loads, (y1[0], y1[1], y1[2]), crossing))
    }

    /// One classical RK4 step of crank angle, speed and controller integral, with every rate
    /// accumulated into `acc` by the same weights. `first` is the evaluation at the step's start
    /// if already known. Returns the evaluation at the step's end and its loads.
    #[allow(clippy::too_many_arguments)]
    fn rk4_step(
        &self,
        t: f64,
        h: f64,
        theta: f64,
        omega: f64,
        z: f64,
        guess: &mut JointLoads,
        max_it: &mut u32,
        acc: &mut [f64],
        pool: &mut Vec<Vec<f64>>,
        first: Option<(Eval, JointLoads)>,
    ) -> Result<(Eval, JointLoads, CrankState), SimError> {
        let stage = |tt: f64,
                     th: f64,
                     w: f64,
                     zz: f64,
                     g: &JointLoads,
                     buf: Vec<f64>|
         -> Result<(Eval, JointLoads, [f64; 3]), SimError> {
            let (torque, dz, sat) = self.pi_torque(tt, w, zz);
            let (e, l) = self.evaluate(tt, h, th, w, Err(torque), sat, g, self.oil_at(tt), buf)?;
            let k = [w, e.alpha, dz];
            Ok((e, l, k))
        };
        let (e1, l1, k1) = match first {
            Some((e, l)) => {
                let (_, dz, _) = self.pi_torque(t, omega, z);
                let k = [omega, e.alpha, dz];
                (e, l, k)
            }
            None => stage(t, theta, omega, z, guess, pool.pop().unwrap_or_default())?,
        };
        let (e2, l2, k2) = stage(
            t + 0.5 * h,
            theta + 0.5 * h * k1[0],
            omega + 0.5 * h * k1[1],
            z + 0.5 * h * k1[2],
            &l1,
            pool.pop().unwrap_or_default(),
        )?;
        let (e3, l3, k3) = stage(
            t + 0.5 * h,
            theta + 0.5 * h * k2[0],
            omega + 0.5 * h * k2[1],
            z + 0.5 * h * k2[2],
            &l2,
            pool.pop().unwrap_or_default(),
        )?;
        let (e4, l4, k4) = stage(
            t + h,
            theta + h * k3[0],
            omega + h * k3[1],
            z + h * k3[2],
            &l3,
            pool.pop().unwrap_or_default(),
        )?;
        let th1 = theta + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]);
        let w1 = omega + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]);
        let z1 = z + h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]);
        for (k, a) in acc.iter_mut().enumerate() {
            *a += h / 6.0 * (e1.rates[k] + 2.0 * e2.rates[k] + 2.0 * e3.rates[k] + e4.rates[k]);
        }
        *max_it = (*max_it)
            .max(e1.iterations)
            .max(e2.iterations)
            .max(e3.iterations)
            .max(e4.iterations);
        pool.extend([e1.rates, e2.rates, e3.rates, e4.rates]);
        // The state at the step end, for output, commit and the next step's first stage.
        let (end, lend) =
            self.step_eval(t + h, h, th1, w1, z1, &l4, pool.pop().unwrap_or_default())?;
        *guess = lend;
        *max_it = (*max_it).max(end.iterations);
        Ok((end, lend, (th1, w1, z1)))
    }

    /// Plateau values over the last whole revolutions of a hold.
    fn measure(&self, pi: usize, omega_ref: f64, t_end: f64, recs: &Window) -> PlateauResult {
        let revs = self.window_revs(omega_ref);
        let n = self.layout().len();
        let (t_e, theta_e, acc_e) = match recs.points.len() {
            0 => (t_end, 0.0, vec![0.0; n]),
            len => (
                recs.points[len - 1].0,
                recs.points[len - 1].1,
                recs.acc(len - 1).to_vec(),
            ),
        };
        let theta_s = theta_e - revs as f64 * TAU;
        // Find the interval holding theta_s and interpolate (cubic Hermite in time).
        let (mut t_s, mut acc_s) = (t_e, acc_e.clone());
        for i in 1..recs.points.len() {
            let ((ta, tha, wa), (tb, thb, wb)) = (recs.points[i - 1], recs.points[i]);
            if tha <= theta_s && theta_s <= thb {
                let h = tb - ta;
                let herm = |y0: f64, y1: f64, d0: f64, d1: f64, s: f64| {
                    let (s2, s3) = (s * s, s * s * s);
                    (2.0 * s3 - 3.0 * s2 + 1.0) * y0
                        + (s3 - 2.0 * s2 + s) * h * d0
                        + (-2.0 * s3 + 3.0 * s2) * y1
                        + (s3 - s2) * h * d1
                };
                // Solve herm(theta) = theta_s by bisection (theta is monotonic here).
                let (mut lo, mut hi) = (0.0, 1.0);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if herm(tha, thb, wa, wb, mid) < theta_s {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                let s = 0.5 * (lo + hi);
                t_s = ta + s * h;
                let (aa, ab, ra, rb) = (
                    recs.acc(i - 1),
                    recs.acc(i),
                    recs.rates(i - 1),
                    recs.rates(i),
                );
                acc_s = (0..n)
                    .map(|k| herm(aa[k], ab[k], ra[k], rb[k], s))
                    .collect();
                break;
            }
        }
        let dt = (t_e - t_s).max(1e-300);
        let dtheta = theta_e - theta_s;
        let delta: Vec<f64> = acc_e.iter().zip(&acc_s).map(|(e, s)| e - s).collect();
        self.plateau_result(pi, omega_ref, &delta, dt, dtheta, [t_s, t_e], revs)
    }

    /// Plateau values from the accumulated quantities `delta` over a window of `dt` seconds
    /// and `dtheta` radians.
    #[allow(clippy::too_many_arguments)]
    fn plateau_result(
        &self,
        pi: usize,
        omega_ref: f64,
        delta: &[f64],
        dt: f64,
        dtheta: f64,
        window_s: [f64; 2],
        revs: u32,
    ) -> PlateauResult {
        let d = |k: usize| delta[k];
        let layout = self.layout();
        let mut joints = Vec::new();
        let mut k = 0;
        for joint in &self.joints {
            for law in &joint.laws {
                let share = |r: usize| d(layout.regime(k, r)) / dt;
                joints.push(LawResult {
                    joint: joint.name.into(),
                    law: law.name.clone(),
                    friction_torque_nm: d(layout.power(k)) / dtheta,
                    power_w: d(layout.power(k)) / dt,
                    mean_normal_load_n: d(layout.normal(k)) / dt,
                    regime_share: RegimeShare {
                        none: share(0),
                        boundary: share(1),
                        mixed: share(2),
                        hydrodynamic: share(3),
                    },
                });
                k += 1;
            }
        }
        PlateauResult {
            set_speed_rpm: rad_s_to_rpm(omega_ref),
            mean_speed_rpm: rad_s_to_rpm(dtheta / dt),
            motoring_torque_nm: d(0) / dtheta,
            oil_temp_c: self.temps[pi],
            viscosity_pa_s: self.viscosities[pi],
            window_s,
            revolutions: revs,
            joints,
        }
    }

    /// Steady state at every plateau speed, computed directly: the crank turns at exactly the
    /// plateau speed and each quantity is integrated over one revolution (periodic trapezoid
    /// rule at the run's crank-angle step). Stateless laws need one revolution; with stateful laws revolutions are
    /// repeated until the revolution's mean torque repeats to 1e-9 (at most 200).
    pub fn run_steady(&mut self) -> Result<RunResult, SimError> {
        let plateaus = self.cycle.plateaus().to_vec();
        let n = self.layout().len();
        let stateful = self
            .joints
            .iter()
            .any(|j| j.laws.iter().any(|l| !l.state.is_empty()));
        let mut results = Vec::with_capacity(plateaus.len());
        let (mut motor, mut dissipated, mut max_it, mut steps) = (0.0, 0.0, 0_u32, 0_u64);
        let mut pool: Vec<Vec<f64>> = Vec::new();
        for (pi, p) in plateaus.iter().enumerate() {
            let w = p.omega;
            let oil = (self.temps[pi], self.viscosities[pi]);
            let m = ((TAU / self.step_rad).ceil() as usize).max(16);
            let h = TAU / w / m as f64;
            for j in &mut self.joints {
                for l in &mut j.laws {
                    l.state.iter_mut().for_each(|x| *x = 0.0);
                }
            }
            let mut guess = JointLoads::default();
            let mut last_torque = f64::NAN;
            let mut delta = vec![0.0; n];
            let max_revs = if stateful { 200 } else { 1 };
            let mut t = 0.0;
            for _ in 0..max_revs {
                delta.iter_mut().for_each(|x| *x = 0.0);
                // Over one whole revolution the integrand is periodic: the trapezoid rule on
                // equally spaced samples converges spectrally for smooth laws (and like Simpson's
                // for kinked ones) with one evaluation per step instead of two.
                for _ in 0..m {
                    let (e1, l1) = self.evaluate(
                        t + h,
                        h,
                        w * (t + h),
                        w,
                        Ok(0.0),
                        f64::INFINITY,
                        &guess,
                        oil,
                        pool.pop().unwrap_or_default(),
                    )?;
                    for (d, r) in delta.iter_mut().zip(&e1.rates) {
                        *d += h * r;
                    }
                    max_it = max_it.max(e1.iterations);
                    t += h;
                    self.commit(t, h, w * t, &e1, oil)?;
                    pool.push(e1.rates);
                    guess = l1;
                    steps += 1;
                }
                let torque = delta[0] / TAU;
                if !stateful || (torque - last_torque).abs() <= 1e-9 * torque.abs().max(1e-12) {
                    break;
                }
                last_torque = torque;
            }
            motor += delta[0];
            dissipated += delta[self.layout().powers()].iter().sum::<f64>();
            results.push(self.plateau_result(pi, w, &delta, TAU / w, TAU, [t - TAU / w, t], 1));
        }
        // Over a periodic revolution the mechanical energy returns to its start value, so the
        // balance is motor work = dissipation.
        let residual = motor - dissipated;
        let energy = EnergyBalance {
            motor_work_j: motor,
            mechanical_energy_change_j: 0.0,
            dissipated_j: dissipated,
            residual_j: residual,
            relative_residual: if motor.abs() > 0.0 {
                residual.abs() / motor.abs()
            } else {
                residual.abs()
            },
        };
        Ok(RunResult {
            rig: self.rig_name.clone(),
            drive: "steady".into(),
            plateaus: results,
            energy_residual_j: residual,
            energy,
            steps,
            max_friction_iterations: max_it,
            warnings: Vec::new(),
            law_time: self.law_time(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;
    use tribo_plugin_api::loader::LawLibrary;
    use tribo_plugin_api::{smooth_sign, Law, ParamError, ParamSpec};

    /// Parameters of [`SqrtLoad`].
    #[derive(Serialize, Deserialize)]
    #[serde(deny_unknown_fields, default)]
    struct SqrtParams {
        c_h: f64,
    }

    impl Default for SqrtParams {
        fn default() -> Self {
            Self { c_h: 5.0 }
        }
    }

    /// The piston law of `tests/fixtures/rust-sqrt-load-law` (mu_b 0.1, v_b 1 m/s, v_smooth
    /// 1 mm/s), linked in: its force grows as sqrt(W), so dF/dW is unbounded at W = 0.
    struct SqrtLoad {
        c_h: f64,
    }

    /// The law's force on the slide for input `i` at load `w`, written out independently.
    fn sqrt_force(c_h: f64, i: &LawInput, w: f64) -> f64 {
        let v = i.sliding_velocity_m_s;
        let l = TAU * i.contact_radius_m;
        let magnitude =
            c_h * (i.viscosity_pa_s * v.abs() * w / l).sqrt() * l + 0.1 * w * (-v.abs()).exp();
        -smooth_sign(v, 1e-3).0 * magnitude
    }

    impl Law for SqrtLoad {
        type Params = SqrtParams;
        const NAME: &'static str = "sqrt-unit";
        const VERSION: &'static str = "0";
        const SUMMARY: &'static str = "sqrt(load) hydrodynamic piston friction (unit test)";

        fn parameters() -> Vec<ParamSpec> {
            vec![ParamSpec::number(
                "c_h",
                "-",
                "hydrodynamic coefficient",
                0.0,
                1e3,
            )]
        }

        fn new(p: SqrtParams) -> Result<Self, ParamError> {
            Ok(Self { c_h: p.c_h })
        }

        fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
            LawOutput::force(sqrt_force(self.c_h, input, input.normal_load_n))
        }
    }

    fn sqrt_simulation() -> Simulation {
        // The bundled rig as plain data (the configuration layer's defaults are serde's).
        let text = include_str!("../../../rigs/crf250r-motored.toml");
        let mut model: RigFile = toml::from_str(text).expect("rig parses");
        let params: toml::Table = toml::from_str("c_h = 5.0").expect("params");
        model.joints.piston.laws = vec![crate::model::LawRef {
            law: "sqrt-unit".into(),
            params,
        }];
        let mut registry = LawRegistry::new();
        registry
            .insert(LawLibrary::in_process::<SqrtLoad>().expect("law describes itself"))
            .expect("one law");
        Simulation::new(&model, &registry).expect("simulation builds")
    }

    /// The plain fixed-point iteration alone, from the frictionless loads, written out with the
    /// law's formula: whether it settles within `tol * scale` in 500 iterations.
    fn plain_iteration_settles(
        sim: &Simulation,
        input: &LawInput,
        kin: &crate::mechanics::Kinematics,
        alpha: f64,
    ) -> bool {
        let mut loads = JointLoads::default();
        let mut w = kin.reactions(alpha, &loads).slide_lateral_n.abs();
        for _ in 0..500 {
            loads.slide_force_n = sqrt_force(5.0, input, w);
            let re = kin.reactions(alpha, &loads);
            let scale = sim.normals(&re).iter().fold(1.0_f64, |m, n| m.max(*n));
            let next = re.slide_lateral_n.abs();
            if (next - w).abs() <= sim.tol * scale {
                return true;
            }
            w = next;
        }
        false
    }

    #[test]
    fn evaluate_holds_the_fixed_point_where_the_plain_iteration_cannot() {
        let sim = sqrt_simulation();
        let mut plain_failures = 0;
        let mut checked = 0;
        let mut newton = 0;
        // Instants of the thesis cycle: the early ramp (15.9 rad/s, where the plain iteration
        // failed first), later in the ramp, and the 3000 and 9000 rpm holds.
        for t in [0.075747, 1.101931, 2.3, 11.9] {
            let (_, omega, alpha) = sim.cycle.reference(t);
            let oil = sim.oil_at(t);
            let eval = |theta: f64| {
                sim.evaluate(
                    t,
                    0.0,
                    theta,
                    omega,
                    Ok(alpha),
                    1.0,
                    &JointLoads::default(),
                    oil,
                    Vec::new(),
                )
                .expect("the iteration converges")
            };
            // Every sign change of the side thrust over a revolution, bisected down to the
            // rounding of the angle: the load the law sees there is as close to 0 as it gets.
            let n = 360;
            let mut angles: Vec<f64> = (0..n).map(|i| TAU * i as f64 / n as f64).collect();
            let lateral = |theta: f64| eval(theta).0.switches[5];
            for i in 0..n {
                let (mut a, mut b) = (TAU * i as f64 / n as f64, TAU * (i + 1) as f64 / n as f64);
                let fa = lateral(a);
                if fa * lateral(b) >= 0.0 {
                    continue;
                }
                for _ in 0..60 {
                    let m = 0.5 * (a + b);
                    if lateral(m) * fa > 0.0 {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                angles.extend([a, b]);
            }
            assert!(
                angles.len() >= n + 4,
                "two crossings a revolution at t = {t}"
            );
            for theta in angles {
                let (e, loads) = eval(theta);
                // The load the law saw (recorded with its power) and the law's force there.
                let w = e.rates[sim.layout().normal(0)];
                let kin = sim.mech.kinematics(theta, omega);
                let mut input = LawInput::at_rest(JointKind::Prismatic);
                input.contact_radius_m = sim.joints[4].radius_m;
                input.viscosity_pa_s = oil.1;
                let input = input.with_velocity(kin.qd[7]);
                let f = sqrt_force(5.0, &input, w);
                assert!((f - loads.slide_force_n).abs() <= 1e-12 * (1.0 + f.abs()));
                // Phi(W): the side thrust under that force, in the final solve.
                let phi = |w: f64| {
                    let applied = JointLoads {
                        slide_force_n: sqrt_force(5.0, &input, w),
                        ..JointLoads::default()
                    };
                    kin.reactions(alpha, &applied)
                };
                let re = phi(w);
                let normals = sim.normals(&re);
                let scale = normals.iter().fold(1.0_f64, |m, n| m.max(*n));
                // A fixed point W* = |Phi(W*)| within k * friction_tol * scale of x: Phi(w) - w
                // changes sign across that interval.
                let delta = sim.tol * scale;
                let rho = |w: f64| phi(w).slide_lateral_n.abs() - w;
                let near =
                    |x: f64, k: f64| rho((x - k * delta).max(0.0)) * rho(x + k * delta) <= 0.0;
                if e.newton {
                    // Phase 2's test: the load the law saw reproduces itself to tolerance, and
                    // a fixed point lies within tolerance of it.
                    newton += 1;
                    assert!(
                        (normals[4] - w).abs() <= delta && near(w, 1.0),
                        "t = {t}, theta = {theta}: the law saw {w} N, Phi(W) = {} N, tolerance \
                         {delta:e} N",
                        normals[4]
                    );
                }
                // (Phase 1's exit is its documented estimate, the last change and its ratio to
                // the one before, which cannot be re-checked from the result alone.)
                // The reported loads and the booked power are those of that final solve.
                assert_eq!(e.normals, normals);
                assert_eq!(e.rates[sim.layout().power(0)], -f * kin.qd[7]);
                if !plain_iteration_settles(&sim, &input, &kin, alpha) {
                    plain_failures += 1;
                }
                checked += 1;
            }
        }
        assert!(checked > 4 * 360);
        assert!(newton > 0, "phase 2 was exercised");
        // The instants near the crossings are the ones the plain iteration cannot settle.
        assert!(
            plain_failures > 0,
            "{checked} instants, all settled by the plain iteration"
        );
    }

    #[test]
    fn plain_iteration_is_abandoned_only_when_it_cannot_settle_within_reach() {
        // Contracting tenfold an iteration: kept.
        assert!(!plain_iteration_stalls(1e-5, 1e-3, 1e-7, 40));
        // Alternating, not shrinking over two iterations: abandoned.
        assert!(plain_iteration_stalls(1e-4, 1e-4, 1e-7, 40));
        assert!(plain_iteration_stalls(2e-4, 1e-4, 1e-7, 40));
        // 0.95 per iteration from 1e-3 to 1e-7: about 200 iterations, more than worth keeping.
        assert!(plain_iteration_stalls(1e-3 * 0.9025, 1e-3, 1e-7, 1000));
        // 0.5 per iteration: about 17 more, kept unless the limit is nearer.
        assert!(!plain_iteration_stalls(0.25e-3, 1e-3, 1e-7, 40));
        assert!(plain_iteration_stalls(0.25e-3, 1e-3, 1e-7, 5));
        // Nothing moved two iterations ago: the iteration had converged; never abandoned.
        assert!(!plain_iteration_stalls(0.0, 0.0, 1e-7, 40));
    }

    #[test]
    fn crank_angle_agrees_with_the_exact_remainder() {
        // Angles a long cycle reaches (11.5 s near 1000 rad/s), negative ones, and exact turns.
        let mut theta = -50.0;
        while theta < 1.2e4 {
            let (fast, exact) = (crank_angle(theta), theta.rem_euclid(TAU));
            assert!((0.0..TAU).contains(&fast), "{theta}: {fast}");
            // Equal up to the rounding of the turn count, or across the wrap at 2 pi.
            let d = (fast - exact).abs();
            assert!(d.min(TAU - d) < 1e-11, "{theta}: {fast} vs {exact}");
            theta += 0.37;
        }
        for turns in [-3.0, 0.0, 1.0, 1000.0] {
            assert!(crank_angle(turns * TAU) < 1e-9 || crank_angle(turns * TAU) > TAU - 1e-9);
        }
    }

    #[test]
    fn rate_layout_tiles_the_rate_vector() {
        let l = RateLayout { n: 3 };
        let mut seen = vec![0; l.len()];
        seen[RateLayout::MOTOR] += 1;
        for k in 0..3 {
            seen[l.power(k)] += 1;
            seen[l.normal(k)] += 1;
            (0..4).for_each(|r| seen[l.regime(k, r)] += 1);
            assert!(l.powers().contains(&l.power(k)));
            assert!(l.normals().contains(&l.normal(k)));
            assert!(l.regimes().contains(&l.regime(k, 3)));
        }
        assert!(seen.iter().all(|&c| c == 1), "{seen:?}");
    }
}
