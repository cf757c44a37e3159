//! The stepping API: a transient run as a value a caller advances in time (co-simulation, an
//! FMU), setting inputs between steps, reading outputs, saving and restoring the whole state.
//!
//! A [`Run`] owns its [`Simulation`]: two runs made from two simulations share nothing (each
//! has its own law instances, states and scratch), so they may be stepped on two threads.
//! Without inputs set, a run stepped to the end of the cycle is the plain run: the same steps,
//! the same numbers ([`Simulation::run`]).
//!
//! ```
//! use tribo_core::model::RigFile;
//! use tribo_core::plugin_api::loader::LawRegistry;
//! use tribo_core::sim::{Inputs, Simulation};
//!
//! // The thesis rig without its laws (an empty registry will do), prescribed crank.
//! let text = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../../rigs/crf250r-motored.toml"));
//! let mut model: RigFile = toml::from_str(text)?;
//! for joint in [&mut model.joints.main_a, &mut model.joints.main_b, &mut model.joints.big_end,
//!               &mut model.joints.small_end, &mut model.joints.piston] {
//!     joint.laws.clear();
//! }
//! let mut run = Simulation::new(&model, &LawRegistry::new())?.start()?;
//!
//! // Follow the cycle for 0.1 s, then hold the crank at 300 rad/s with oil at 90 C.
//! run.advance_to(0.1)?;
//! assert_eq!(run.time_s(), 0.1);
//! run.set_inputs(Inputs {
//!     crank_speed_rad_s: Some(300.0),
//!     oil_temperature_c: Some(90.0),
//!     ..Inputs::default()
//! })?;
//! let saved = run.save();
//! run.advance_to(0.2)?;
//! let out = run.outputs();
//! assert_eq!(out.crank_speed_rad_s, 300.0);
//! assert_eq!(out.joints.len(), 5);
//! // No friction anywhere: no joint dissipates.
//! assert!(out.joints.iter().all(|j| j.power_w == 0.0));
//!
//! // Back to 0.1 s and the same way again: the same crank angle to the last bit.
//! run.restore(&saved)?;
//! run.advance_to(0.2)?;
//! assert_eq!(run.outputs().crank_angle_rad, out.crank_angle_rad);
//!
//! // A drive torque needs the PI drive: the prescribed crank refuses it, naming it.
//! let err = run.set_inputs(Inputs { drive_torque_nm: Some(5.0), ..Inputs::default() });
//! assert!(err.unwrap_err().to_string().contains("drive_torque_nm"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::sync::atomic::{AtomicU64, Ordering};

use super::crank_angle::LawSample;
use super::error::SimError;
use super::rates::RateLayout;
use super::results::RunResult;
use super::stepper::Integration;
use super::transient::Transient;
use super::Simulation;
use crate::model::Drive;
use crate::observe::NoObserver;
use tribo_plugin_api::serde::{Deserialize, Serialize};

/// What a stepped run's caller sets between steps; `None` leaves the rig's own.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct Inputs {
    /// Crank speed, rad/s (>= 0): a prescribed crank turns at it from where it is; the PI
    /// drive holds it as its set speed. `None`: the cycle's.
    pub crank_speed_rad_s: Option<f64>,
    /// Drive torque on the crank, N m, in place of the PI controller's (PI drive only; not
    /// with a crank speed). `None`: the controller's.
    pub drive_torque_nm: Option<f64>,
    /// Oil temperature, C (its viscosity from the rig's oil). `None`: the rig's schedule.
    pub oil_temperature_c: Option<f64>,
    /// Cylinder pressure on every piston crown, Pa absolute (the crankcase side stays the
    /// rig's). `None`: the rig's gas model (the ambient pressure on a rig without `[gas]`).
    pub cylinder_pressure_pa: Option<f64>,
}

/// The inputs as the solver holds them (see `Simulation::held`).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Held {
    pub(super) speed: Option<HeldSpeed>,
    pub(super) torque_nm: Option<f64>,
    /// Oil temperature (C) and dynamic viscosity (Pa s).
    pub(super) oil: Option<(f64, f64)>,
    pub(super) cylinder_pa: Option<f64>,
}

/// A crank speed set at time `t0` with the crank at angle `theta0`: the reference motion from
/// there on.
#[derive(Debug, Clone, Copy)]
pub(super) struct HeldSpeed {
    t0: f64,
    theta0: f64,
    omega: f64,
}

impl HeldSpeed {
    /// Angle, speed and acceleration of the held motion at `t`.
    #[inline]
    pub(super) fn at(&self, t: f64) -> (f64, f64, f64) {
        (self.theta0 + self.omega * (t - self.t0), self.omega, 0.0)
    }
}

/// One joint after the last accepted step.
#[derive(Debug, Clone, PartialEq)]
pub struct JointOutput {
    /// The joint's name (the rig's: `piston`, `main_1`, `big_end_3`, ...).
    pub name: String,
    /// The force (slide, N) or torque (bearing or pin, N m) of the joint's laws together.
    pub law_total: f64,
    /// Power its laws dissipate, W (positive when dissipating).
    pub power_w: f64,
    /// That power as a torque at the crank (power over crank speed; 0 at rest), N m.
    pub torque_at_crank_nm: f64,
    /// Its normal load, N.
    pub normal_load_n: f64,
    /// Energy its laws dissipated since the start, J.
    pub energy_j: f64,
}

/// A stepped run's state after its last accepted step.
#[derive(Debug, Clone, PartialEq)]
pub struct Outputs {
    /// Time, s.
    pub time_s: f64,
    /// Crank angle (accumulated from the start), rad.
    pub crank_angle_rad: f64,
    /// Crank speed, rad/s.
    pub crank_speed_rad_s: f64,
    /// Drive torque on the crank (the motoring torque), N m.
    pub drive_torque_nm: f64,
    /// Work the drive did on the crank since the start, J.
    pub drive_work_j: f64,
    /// Power all laws dissipate, W.
    pub friction_power_w: f64,
    /// That power as a torque at the crank (0 at rest), N m.
    pub friction_torque_nm: f64,
    /// Every joint, in the rig's joint order ([`Simulation::joint_names`]).
    pub joints: Vec<JointOutput>,
}

/// A run's whole state at one instant (crank, integrator, accumulated quantities, every law's
/// state, inputs): what [`Run::restore`] goes back to.
#[derive(Clone)]
pub struct Snapshot {
    owner: u64,
    run: Box<Transient>,
    held: Held,
    inputs: Inputs,
    from_rest: bool,
}

/// The version of [`RunState`]'s fields: a state saved under another version is refused by
/// [`Run::resume`], not misread.
pub const RUN_STATE_VERSION: u32 = 1;

/// A run's state as plain numbers, to be written out (an FMU's serialised state) and resumed
/// by a run of the same simulation ([`Run::resume`]): time, crank, controller integral,
/// accumulated quantities, the friction the next evaluation starts from, every law's state
/// (the host owns it: a law's state is its declared vector of numbers) and the inputs.
///
/// What it leaves out is what a run rebuilds: the stepper's carried evaluations and the
/// plateau records. A fixed-step run (RK4, Simpson's rule) continues from it exactly as the
/// run it was taken from continues after [`Run::restart`]; an error-controlled one (adaptive,
/// Lobatto) to its tolerance, its step size found afresh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(crate = "tribo_plugin_api::serde")]
pub struct RunState {
    /// [`RUN_STATE_VERSION`] when saved.
    version: u32,
    time_s: f64,
    /// Crank angle (rad), speed (rad/s) and the PI controller's integral (rad).
    crank: [f64; 3],
    accumulated: Vec<f64>,
    regime_time: Vec<f64>,
    last_rates: Vec<f64>,
    last_regimes: Vec<u8>,
    last_normals: Vec<f64>,
    last_torque: f64,
    guess: Vec<f64>,
    rejected: u64,
    /// The normal loads of the last friction solve (where the next one starts).
    previous_normals: Vec<f64>,
    law_states: Vec<Vec<f64>>,
    inputs: Inputs,
    /// Where a held crank speed was set: time (s) and crank angle (rad).
    speed_anchor: Option<(f64, f64)>,
}

impl RunState {
    /// The run's time, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The crank speed, rad/s.
    pub fn crank_speed_rad_s(&self) -> f64 {
        self.crank[1]
    }
}

/// A transient run advanced by its caller (see the module documentation).
pub struct Run {
    sim: Simulation,
    run: Box<Transient>,
    inputs: Inputs,
    /// Which run a snapshot belongs to.
    id: u64,
    /// Whether the run went on from the rig's start at rest (not started turning, not
    /// resumed): only then is [`Run::result`] the cycle's result.
    from_rest: bool,
}

/// The source of run ids.
static RUN_IDS: AtomicU64 = AtomicU64::new(0);

impl Simulation {
    /// A stepped run of this simulation at its start (time 0, crank at rest, every law's state
    /// at zero), the rig's own inputs in force.
    pub fn start(mut self) -> Result<Run, SimError> {
        self.held = Held::default();
        let run = Box::new(self.start_transient()?);
        Ok(Run {
            sim: self,
            run,
            inputs: Inputs::default(),
            id: RUN_IDS.fetch_add(1, Ordering::Relaxed),
            from_rest: true,
        })
    }

    /// A stepped run of this simulation at time 0 with the crank already turning at
    /// `crank_speed_rad_s` (angle 0, controller integral 0, every law's state at zero): a
    /// run driven by a torque from a speed (a coast-down). PI drive only (a prescribed crank
    /// follows its speed input from rest).
    pub fn start_turning(self, crank_speed_rad_s: f64) -> Result<Run, SimError> {
        let bad = |message: String| SimError::Input {
            input: "crank_speed_rad_s",
            message,
        };
        if matches!(self.drive, Drive::Prescribed {}) {
            return Err(bad("a prescribed crank follows its speed input from rest: starting it turning needs the PI drive (drive = {kind = \"pi\"})".into()));
        }
        if !(crank_speed_rad_s.is_finite() && (0.0..=MAX_SPEED_RAD_S).contains(&crank_speed_rad_s))
        {
            return Err(bad(format!(
                "{crank_speed_rad_s} rad/s is outside [0, {MAX_SPEED_RAD_S}] rad/s"
            )));
        }
        let mut run = self.start()?;
        let r = &mut run.run;
        r.s.y = (0.0, crank_speed_rad_s, 0.0);
        let e = run.sim.step_eval(0.0, 0.0, r.s.y, &[], &mut r.w)?;
        r.s.record(&e);
        r.s.settle_from(&e);
        r.w.recycle(e);
        run.sim.seek(r)?;
        run.from_rest = false;
        Ok(run)
    }
}

/// The highest crank speed an input or a start may ask, rad/s: beyond any engine's (about
/// 40 000 rpm).
const MAX_SPEED_RAD_S: f64 = 4000.0;

impl Run {
    /// The simulation being run (names, FMEP definition, settings).
    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    /// The run's time, s.
    pub fn time_s(&self) -> f64 {
        self.run.s.t
    }

    /// The inputs in force.
    pub fn inputs(&self) -> Inputs {
        self.inputs
    }

    /// Set the inputs from the run's time on. Refused, naming the input: a value that is not
    /// finite or out of its range, a drive torque on a prescribed crank or with a crank speed.
    /// Setting the inputs in force changes nothing.
    pub fn set_inputs(&mut self, inputs: Inputs) -> Result<(), SimError> {
        if inputs == self.inputs {
            return Ok(());
        }
        let held = self.held(&inputs)?;
        self.sim.held = held;
        self.inputs = inputs;
        self.sim.replan(&mut self.run)
    }

    /// The solver's form of `inputs`, checked.
    fn held(&self, inputs: &Inputs) -> Result<Held, SimError> {
        let bad = |input: &'static str, message: String| SimError::Input { input, message };
        let check = |input: &'static str, v: Option<f64>, lo: f64, hi: f64, unit: &str| match v {
            Some(x) if !(x.is_finite() && (lo..=hi).contains(&x)) => Err(bad(
                input,
                format!("{x} {unit} is outside [{lo}, {hi}] {unit}"),
            )),
            _ => Ok(()),
        };
        // Beyond any engine's speed (about 40 000 rpm), torque and cylinder pressure (a
        // fired engine peaks near 20 MPa); the oil temperatures the rig files accept.
        check(
            "crank_speed_rad_s",
            inputs.crank_speed_rad_s,
            0.0,
            MAX_SPEED_RAD_S,
            "rad/s",
        )?;
        check("drive_torque_nm", inputs.drive_torque_nm, -1e5, 1e5, "N m")?;
        let (lo, hi) = crate::oil::VALID_RANGE_C;
        check("oil_temperature_c", inputs.oil_temperature_c, lo, hi, "C")?;
        check(
            "cylinder_pressure_pa",
            inputs.cylinder_pressure_pa,
            0.0,
            1e8,
            "Pa",
        )?;
        if inputs.drive_torque_nm.is_some() {
            if matches!(self.sim.drive, Drive::Prescribed {}) {
                return Err(bad("drive_torque_nm", "a prescribed crank follows its speed: a drive torque needs the PI drive (drive = {kind = \"pi\"}); set crank_speed_rad_s instead".into()));
            }
            if inputs.crank_speed_rad_s.is_some() {
                return Err(bad("drive_torque_nm", "the crank is driven by a speed or by a torque, not both: leave crank_speed_rad_s unset".into()));
            }
        }
        let (t, y) = (self.run.s.t, self.run.s.y);
        // The speed held as it was where it is set again unchanged (a new anchor otherwise).
        let speed = match (inputs.crank_speed_rad_s, self.sim.held.speed) {
            (Some(omega), Some(h)) if h.omega == omega => Some(h),
            (Some(omega), _) => Some(HeldSpeed {
                t0: t,
                theta0: y.0,
                omega,
            }),
            (None, _) => None,
        };
        let (viscosity, density) = &self.sim.oil;
        Ok(Held {
            speed,
            torque_nm: inputs.drive_torque_nm,
            oil: inputs
                .oil_temperature_c
                .map(|c| (c, viscosity.kinematic_cst(c) * 1e-6 * density)),
            cylinder_pa: inputs.cylinder_pressure_pa,
        })
    }

    /// One accepted step (of the run's own size; error-controlled under the PI drive).
    /// Returns whether one was taken: not at the end of the cycle (go on with
    /// [`Run::advance_to`]).
    pub fn step(&mut self) -> Result<bool, SimError> {
        let taken = self
            .sim
            .advance(&mut self.run, f64::INFINITY, 1, &mut NoObserver)?;
        Ok(taken == 1)
    }

    /// Advance to time `t_s` exactly (s; beyond the end of the cycle too: the last segment
    /// goes on). A time the run has passed is refused (restore a saved state to go back).
    pub fn advance_to(&mut self, t_s: f64) -> Result<(), SimError> {
        let now = self.run.s.t;
        if !t_s.is_finite() || t_s < now {
            return Err(SimError::Input {
                input: "advance_to",
                message: format!("the run is at {now} s and goes forward only: {t_s} s cannot be reached (restore a saved state to go back)"),
            });
        }
        self.sim.land_on(&mut self.run, t_s);
        self.sim
            .advance(&mut self.run, t_s, u64::MAX, &mut NoObserver)?;
        Ok(())
    }

    /// The state after the last accepted step: time, crank, drive torque, and per joint its
    /// laws' force or torque, power and normal load.
    pub fn outputs(&self) -> Outputs {
        let (sim, s) = (&self.sim, &self.run.s);
        let layout = sim.layout();
        let omega = s.y.1;
        let at_crank = |p: f64| if omega != 0.0 { p / omega } else { 0.0 };
        let joints: Vec<JointOutput> = sim
            .joints
            .iter()
            .enumerate()
            .map(|(ji, j)| {
                let power: f64 = (0..j.laws.len())
                    .map(|i| s.last_rates[layout.power(j.first_law + i)])
                    .sum();
                let energy: f64 = (0..j.laws.len())
                    .map(|i| s.acc[layout.power(j.first_law + i)])
                    .sum();
                JointOutput {
                    name: j.name.clone(),
                    law_total: s.guess.get(ji).copied().unwrap_or(0.0),
                    power_w: power,
                    torque_at_crank_nm: at_crank(power),
                    normal_load_n: s.last_normals.get(ji).copied().unwrap_or(0.0),
                    energy_j: energy,
                }
            })
            .collect();
        let power: f64 = joints.iter().map(|j| j.power_w).sum();
        Outputs {
            time_s: s.t,
            crank_angle_rad: s.y.0,
            crank_speed_rad_s: omega,
            drive_torque_nm: s.last_torque,
            drive_work_j: s.acc[RateLayout::MOTOR],
            friction_power_w: power,
            friction_torque_nm: at_crank(power),
            joints,
        }
    }

    /// Every law after the last accepted step (in the order of
    /// [`Simulation::law_names`]): its torque at the crank, power, load, sliding speed and
    /// regime, and the diagnostics it reports (contract version 3: film, eccentricity,
    /// pressure, asperity share), evaluated at the step's settled loads with the states
    /// committed there.
    pub fn laws(&self) -> Result<Vec<LawSample>, SimError> {
        let s = &self.run.s;
        self.sim.law_samples(
            s.y.1,
            &self.run.w,
            &s.last_normals,
            (&s.last_rates, &s.last_regimes),
        )
    }

    /// The whole state now, to [`Run::restore`] later.
    pub fn save(&self) -> Snapshot {
        Snapshot {
            owner: self.id,
            run: self.run.clone(),
            held: self.sim.held,
            inputs: self.inputs,
            from_rest: self.from_rest,
        }
    }

    /// Go back to the state `saved` (of this run): time, crank, integrator, accumulated
    /// quantities, every law's state and the inputs. A snapshot of another run is refused.
    pub fn restore(&mut self, saved: &Snapshot) -> Result<(), SimError> {
        if saved.owner != self.id {
            return Err(SimError::Input {
                input: "restore",
                message:
                    "the snapshot was saved by another run: a run restores its own states only"
                        .into(),
            });
        }
        self.run.clone_from(&saved.run);
        self.sim.held = saved.held;
        self.inputs = saved.inputs;
        self.from_rest = saved.from_rest;
        Ok(())
    }

    /// The run's result so far (plateaus, energy balance, counts) as [`Simulation::run`] gives
    /// it at the end of the cycle; a plateau not yet passed has no measurement (an error).
    /// Refused for a run that started turning or was resumed: it has no cycle from rest.
    pub fn result(&self) -> Result<RunResult, SimError> {
        if !self.from_rest {
            return Err(SimError::Input {
                input: "result",
                message: "a run started turning or resumed from a saved state has no test cycle from rest to report: read its outputs".into(),
            });
        }
        self.sim.finish_transient(&self.run)
    }

    /// Forget what the stepper carries from its last steps (its last evaluation, reused as
    /// the next step's first stage), as a resumed run starts: from here the run continues
    /// exactly as a run resumed from [`Run::state`] taken now (for a fixed-step method).
    pub fn restart(&mut self) -> Result<(), SimError> {
        self.sim.seek(&mut self.run)
    }

    /// The run's state as plain numbers (see [`RunState`]).
    pub fn state(&self) -> RunState {
        let (s, w) = (&self.run.s, &self.run.w);
        RunState {
            version: RUN_STATE_VERSION,
            time_s: s.t,
            crank: [s.y.0, s.y.1, s.y.2],
            accumulated: s.acc.clone(),
            regime_time: s.regime_time.clone(),
            last_rates: s.last_rates.clone(),
            last_regimes: s.last_regimes.clone(),
            last_normals: s.last_normals.clone(),
            last_torque: s.last_torque,
            guess: s.guess.clone(),
            rejected: s.rejected,
            previous_normals: w.prev.to_vec(),
            law_states: w.states.to_vecs(),
            inputs: self.inputs,
            speed_anchor: self.sim.held.speed.map(|h| (h.t0, h.theta0)),
        }
    }

    /// Take up `state` (of a run of the same simulation: the same rig, laws and settings),
    /// the stepper starting afresh. Refused, saying what differs, if its version, a size or
    /// an input does not fit this run; the run is then left as it was.
    pub fn resume(&mut self, state: &RunState) -> Result<(), SimError> {
        let bad = |message: String| SimError::Input {
            input: "resume",
            message,
        };
        if state.version != RUN_STATE_VERSION {
            return Err(bad(format!(
                "the state is of version {}, this run reads version {RUN_STATE_VERSION}",
                state.version
            )));
        }
        let (s, w) = (&self.run.s, &self.run.w);
        let sizes = [
            (
                "accumulated quantities",
                state.accumulated.len(),
                s.acc.len(),
            ),
            ("regime times", state.regime_time.len(), s.regime_time.len()),
            ("rates", state.last_rates.len(), s.last_rates.len()),
            ("regimes", state.last_regimes.len(), s.last_regimes.len()),
            (
                "normal loads",
                state.last_normals.len(),
                self.sim.joints.len(),
            ),
            ("law totals", state.guess.len(), self.sim.joints.len()),
            ("solver loads", state.previous_normals.len(), w.prev.len()),
        ];
        if let Some((what, got, want)) = sizes.iter().find(|(_, got, want)| got != want) {
            return Err(bad(format!(
                "it has {got} {what}, this run {want}: it was saved by a run of another rig or law set"
            )));
        }
        let numbers = [state.time_s, state.crank[0], state.crank[1], state.crank[2]];
        if !numbers.iter().all(|x| x.is_finite()) || state.time_s < 0.0 {
            return Err(bad(
                "its time or crank state is not a finite number (a time >= 0)".into(),
            ));
        }
        // The inputs checked as `set_inputs` checks them, the speed anchored where saved.
        let mut held = self.held(&state.inputs)?;
        match (&mut held.speed, state.speed_anchor) {
            (Some(h), Some((t0, theta0))) if t0.is_finite() && theta0.is_finite() => {
                h.t0 = t0;
                h.theta0 = theta0;
            }
            (None, None) => {}
            _ => return Err(bad("its crank speed input and its anchor disagree".into())),
        }
        let mut states = self.run.w.states.clone();
        states.set_from(&state.law_states).map_err(bad)?;
        let r = &mut self.run;
        r.w.states = states;
        r.w.prev.copy_from_slice(&state.previous_normals);
        r.s = Integration {
            t: state.time_s,
            y: (state.crank[0], state.crank[1], state.crank[2]),
            acc: state.accumulated.clone(),
            regime_time: state.regime_time.clone(),
            last_rates: state.last_rates.clone(),
            last_regimes: state.last_regimes.clone(),
            last_normals: state.last_normals.clone(),
            last_torque: state.last_torque,
            guess: state.guess.clone(),
            rejected: state.rejected,
        };
        self.sim.held = held;
        self.inputs = state.inputs;
        self.from_rest = false;
        self.sim.seek(&mut self.run)
    }
}
