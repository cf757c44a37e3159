//! Laws bound to joints: each joint's name, role, geometry and laws, the law call with its
//! sampled timing, the checks on what a law returns, and the commit of stateful laws after an
//! accepted step. A law's state is the run's (`LawStates`), not the binding's: a simulation
//! holds no state between runs, and a run's state can be saved and restored whole.

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use nalgebra::Vector2;
use tribo_plugin_api::loader::inflight::Round;
use tribo_plugin_api::loader::{LawError, LawInstance, LawRegistry};
use tribo_plugin_api::{
    suits, suits_text, BearingType, InnerBody, JointKind, LawInput, LawOutput, DIAGNOSTIC_FLAGS,
    HAS_COEFFICIENT, HAS_DERIVATIVE, HAS_LOAD_DERIVATIVE,
};

use super::error::{readable, Fault, SimError, MAX_FORCE_PER_REACTION, REACTION_FLOOR_N};
use super::joints::joint_specs;
use super::results::LawTime;
use super::types::{Bodies, Role};
use crate::model::RigFile;

/// One law call in this many is timed; the total is scaled up. Keeps timing off the hot path:
/// a clock read costs tens of ns on a virtual machine, and at 64 the reads took 3% of a PI run.
/// A steady comparison still times ~20 calls per law, a transient run thousands.
const TIMING_SAMPLE: u64 = 256;

/// Timed calls kept per law (the most recent ones, cyclically): the estimate is their mean
/// with the slowest 5% dropped, so a thread preempted during one timed call (milliseconds, on a
/// shared machine) is not scaled up by the sample rate into seconds "in the law".
const TIMING_KEPT: usize = 512;

/// One law bound to one joint.
pub(super) struct BoundLaw {
    pub(super) name: String,
    instance: LawInstance,
    /// The length of the law's state (0: stateless).
    state_len: usize,
    /// Calls made, timed calls made, and the durations of the last [`TIMING_KEPT`] timed
    /// calls in ns (every `TIMING_SAMPLE`-th call is timed).
    calls: AtomicU64,
    timed: AtomicU64,
    sampled_ns: Box<[AtomicU32]>,
}

impl BoundLaw {
    /// Evaluate the law at `input` with its committed state into `out`, marked as running
    /// through the round `round`, counting the call and timing one in `TIMING_SAMPLE`. One
    /// simulation is stepped by one thread: a plain load and store, not a locked
    /// read-modify-write (which cost ~15% of an evaluation).
    #[inline(always)]
    pub(super) fn call(
        &self,
        input: &LawInput,
        state: &LawState,
        out: &mut LawOutput,
        round: &mut Round,
    ) -> Result<(), LawError> {
        let calls = self.calls.load(Ordering::Relaxed);
        self.calls.store(calls + 1, Ordering::Relaxed);
        // Not the first call: a law's one-off set-up there (a table built lazily) scaled by
        // the sample rate once reported a 0.1 s run as 30 s in the law.
        if calls % TIMING_SAMPLE == TIMING_SAMPLE / 2 {
            self.timed_call(input, state, out, round)
        } else {
            // SAFETY: a `LawState` is made by this law's instance, of its state size, and never
            // changes length (`LawStates`).
            unsafe { self.instance.evaluate_in_round(input, &state.0, out, round) }
        }
    }

    /// The law at `input` with the state `state`, neither counted nor timed: for reports made
    /// after a run (the crank-angle traces' diagnostics).
    pub(super) fn output(&self, input: &LawInput, state: &[f64]) -> Result<LawOutput, LawError> {
        self.instance.evaluate(input, state)
    }

    /// One law call with its wall time added to the law's sample.
    #[inline(never)]
    fn timed_call(
        &self,
        input: &LawInput,
        state: &LawState,
        out: &mut LawOutput,
        round: &mut Round,
    ) -> Result<(), LawError> {
        let clock = std::time::Instant::now();
        // SAFETY: as in `call`.
        let result = unsafe { self.instance.evaluate_in_round(input, &state.0, out, round) };
        let ns = (clock.elapsed().as_nanos() as u64).saturating_sub(clock_overhead_ns());
        let k = self.timed.load(Ordering::Relaxed);
        self.timed.store(k + 1, Ordering::Relaxed);
        let slot = &self.sampled_ns[k as usize % TIMING_KEPT];
        slot.store(u32::try_from(ns).unwrap_or(u32::MAX), Ordering::Relaxed);
        result
    }

    /// Estimated ns per call: the mean of the kept timed calls without the slowest 5%.
    fn ns_per_call(&self) -> f64 {
        let kept = (self.timed.load(Ordering::Relaxed) as usize).min(TIMING_KEPT);
        let mut ns: Vec<u32> = self.sampled_ns[..kept]
            .iter()
            .map(|a| a.load(Ordering::Relaxed))
            .collect();
        ns.sort_unstable();
        ns.truncate(kept - kept / 20);
        if ns.is_empty() {
            return 0.0;
        }
        ns.iter().map(|&x| f64::from(x)).sum::<f64>() / ns.len() as f64
    }

    /// Whether the law keeps state (then it is committed after each accepted step).
    pub(super) fn is_stateful(&self) -> bool {
        self.state_len > 0
    }

    /// Bind law `l` (the model's field `field`, `joints.J.laws[i]`) on joint `joint` from
    /// `registry`: its library, an instance with checked parameters (named with the joint in
    /// crash and hang reports), and its zero state.
    pub(super) fn bind(
        registry: &LawRegistry,
        l: &crate::model::LawRef,
        field: &str,
        joint: &str,
    ) -> Result<BoundLaw, SimError> {
        let lib = registry
            .get(&l.law)
            .map_err(|e| setup_error(format!("{field}.law"), e))?;
        let mut instance = lib
            .create(&l.params)
            .map_err(|e| setup_error(format!("{field}.params"), e))?;
        instance.set_joint(joint);
        let state = instance
            .new_state()
            .map_err(|e| setup_error(format!("{field}.law"), e))?;
        Ok(BoundLaw {
            name: l.law.clone(),
            instance,
            state_len: state.len(),
            calls: AtomicU64::new(0),
            timed: AtomicU64::new(0),
            sampled_ns: (0..TIMING_KEPT).map(|_| AtomicU32::new(0)).collect(),
        })
    }

    /// A fresh state of the law (zeros, as at binding), allocated fallibly by the loader: the
    /// only way a [`LawState`] is made, so its length is the instance's state size.
    fn new_state(&self) -> Result<LawState, LawError> {
        let state = self.instance.new_state()?;
        debug_assert_eq!(state.len(), self.instance.state_size());
        Ok(LawState(state.into_boxed_slice()))
    }

    /// Calls and estimated time so far, as on joint `joint`.
    pub(super) fn time(&self, joint: &str) -> LawTime {
        LawTime {
            joint: joint.into(),
            law: self.name.clone(),
            calls: self.calls.load(Ordering::Relaxed),
            seconds: self.ns_per_call() * self.calls.load(Ordering::Relaxed) as f64 * 1e-9,
        }
    }
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

/// A joint with its name, role on the crank, contact geometry and laws.
pub(super) struct BoundJoint {
    pub(super) name: String,
    pub(super) role: Role,
    /// What every law input of the joint says about it besides the instant.
    pub(super) contact: Contact,
    pub(super) laws: Vec<BoundLaw>,
    /// The run-wide index of the joint's first law (laws are numbered joint by joint).
    pub(super) first_law: usize,
}

/// What a law is told about its joint beyond the instant: the kind, the contact radius and
/// length (m), the bearing type the rig declares and which body is the inner member.
#[derive(Debug, Clone, Copy)]
pub(super) struct Contact {
    pub(super) kind: JointKind,
    pub(super) radius_m: f64,
    pub(super) length_m: f64,
    pub(super) bearing: BearingType,
    pub(super) inner: InnerBody,
}

/// What every law input of one instant shares: time, step, crank and oil.
#[derive(Debug, Clone, Copy)]
pub(super) struct Instant {
    pub(super) t: f64,
    pub(super) dt: f64,
    /// Crank angle within the revolution, rad.
    pub(super) crank_angle: f64,
    pub(super) omega: f64,
    /// Oil temperature (C) and dynamic viscosity (Pa s).
    pub(super) oil: (f64, f64),
    /// Pressures, piston travel and 4-stroke angle (contract version 2).
    pub(super) gas: crate::gas::LawGas,
}

impl BoundJoint {
    /// Whether any of the joint's laws keeps state.
    pub(super) fn is_stateful(&self) -> bool {
        self.laws.iter().any(BoundLaw::is_stateful)
    }

    /// Commit every stateful law of the joint over an accepted step ending at `input`, each
    /// advancing its own entry of the run's `states`.
    pub(super) fn commit(&self, input: &LawInput, states: &mut LawStates) -> Result<(), SimError> {
        for (i, law) in self.laws.iter().enumerate() {
            if law.is_stateful() {
                law.instance
                    .commit(input, &mut states.0[self.first_law + i].0)
                    .map_err(|e| law_failed(&self.name, input, e))?;
            }
        }
        Ok(())
    }

    /// The friction force (slide) or torque (revolute) of all the joint's laws at `input`, each
    /// with its state from `laws` and marked running through `round`, checked (finite, of a
    /// physical size against `reaction_n`, a stateless law not adding energy). With `record`,
    /// each law's power and load are written into the rates and its regime into the codes. A
    /// law whose output this evaluation said is affine in the load is not called again.
    #[inline(always)]
    pub(super) fn force(
        &self,
        input: &LawInput,
        laws: &mut LawMemory<'_>,
        reaction_n: f64,
        mut record: Option<Record<'_>>,
        layout: super::rates::RateLayout,
        round: &mut Round,
    ) -> Result<f64, SimError> {
        let mut total = 0.0;
        for (i, law) in self.laws.iter().enumerate() {
            let k = self.first_law + i;
            let moved = laws.reuse.at(k, input.normal_load_n);
            let out = match &moved {
                Some(out) => out,
                None => {
                    // Written by the law straight into its slot: no copy of an output the
                    // processor has not finished storing.
                    let slot = laws.reuse.slot(k);
                    if let Err(e) = law.call(input, &laws.states.0[k], slot, round) {
                        return Err(law_failed(&self.name, input, e));
                    }
                    laws.reuse.keep(k, input.normal_load_n)
                }
            };
            let power = checked_power(&self.name, self.role.kind(), law, input, out, reaction_n)?;
            total += out.force;
            if let Some(r) = record.as_mut() {
                let regime = out.regime().unwrap_or(tribo_plugin_api::Regime::None);
                r.rates[layout.power(k)] = -power;
                r.regimes[k] = regime as u8;
                r.rates[layout.normal(k)] = input.normal_load_n;
            }
        }
        Ok(total)
    }
}

/// What the laws of one evaluation are called with besides their input: their committed
/// states, and the outputs kept for the evaluation's later rounds.
pub(super) struct LawMemory<'a> {
    pub(super) states: &'a LawStates,
    pub(super) reuse: &'a mut Reuse,
}

/// The outputs of one evaluation that their laws marked affine in the load
/// (`LawOutput::load_slope`), with the load each was made at, by run-wide law index: the
/// evaluation's later rounds change only the loads, so the output at a new load is computed
/// from these instead of calling the law again. Every law call writes its output into its slot
/// here; only an affine one is kept. Forgotten at the start of every evaluation.
#[derive(Debug, Clone)]
pub(super) struct Reuse {
    outputs: Vec<LawOutput>,
    /// The load each kept output was made at, N; `None` for one not kept.
    kept_n: Vec<Option<f64>>,
    any: bool,
}

impl Reuse {
    /// Room for `n_laws` laws, none kept.
    pub(super) fn new(n_laws: usize) -> Self {
        Self {
            outputs: vec![LawOutput::force(0.0); n_laws],
            kept_n: vec![None; n_laws],
            any: false,
        }
    }

    /// Forget every kept output: a new evaluation (another instant, or another state).
    #[inline(always)]
    pub(super) fn forget(&mut self) {
        if self.any {
            self.kept_n.fill(None);
            self.any = false;
        }
    }

    /// Law `k`'s output at the normal load `load_n` from its kept one, if it has one: the
    /// force moved along its slope (unchanged, bit for bit, for a slope of 0).
    #[inline(always)]
    fn at(&self, k: usize, load_n: f64) -> Option<LawOutput> {
        if !self.any {
            return None;
        }
        let kept_n = self.kept_n[k]?;
        let mut out = self.outputs[k];
        if out.dforce_dload != 0.0 {
            out.force += out.dforce_dload * (load_n - kept_n);
        }
        Some(out)
    }

    /// Where law `k`'s call writes its output.
    #[inline(always)]
    fn slot(&mut self, k: usize) -> &mut LawOutput {
        &mut self.outputs[k]
    }

    /// Law `k`'s output just written into its slot, made at the normal load `load_n`: kept if
    /// the law marked it affine in the load.
    #[inline(always)]
    fn keep(&mut self, k: usize, load_n: f64) -> &LawOutput {
        if self.outputs[k].load_slope().is_some() {
            self.kept_n[k] = Some(load_n);
            self.any = true;
        }
        &self.outputs[k]
    }
}

/// Where a round of laws records what each law did: its power and normal load in an
/// evaluation's rates, its regime (a `Regime` as code) in the evaluation's regime codes.
pub(super) struct Record<'a> {
    pub(super) rates: &'a mut [f64],
    pub(super) regimes: &'a mut [u8],
}

/// One law's state: made only by its own instance ([`BoundLaw::new_state`]) and never resized,
/// so its length is the law's declared state size, checked once there and not on every call.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct LawState(Box<[f64]>);

/// Every law's state over a run, by the run-wide law index (empty for a stateless law).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct LawStates(Vec<LawState>);

impl LawStates {
    /// Every law's fresh state (zeros), as at binding.
    pub(super) fn new(joints: &[BoundJoint]) -> Result<Self, SimError> {
        let mut states = Vec::new();
        for j in joints {
            for (i, law) in j.laws.iter().enumerate() {
                let state = law
                    .new_state()
                    .map_err(|e| setup_error(format!("{}.law", law_field_of(j, i)), e))?;
                states.push(state);
            }
        }
        Ok(Self(states))
    }

    /// Every state back to zeros.
    pub(super) fn reset(&mut self) {
        self.0.iter_mut().for_each(|s| s.0.fill(0.0));
    }

    /// Law `k`'s state (run-wide index).
    pub(super) fn of(&self, k: usize) -> &[f64] {
        &self.0[k].0
    }

    /// Every law's state as plain numbers, by run-wide index (what a saved run carries).
    pub(super) fn to_vecs(&self) -> Vec<Vec<f64>> {
        self.0.iter().map(|s| s.0.to_vec()).collect()
    }

    /// Every law's state from `values` ([`LawStates::to_vecs`] of a run of the same laws).
    /// Refused, saying which, if the count of laws or a law's state size differs.
    pub(super) fn set_from(&mut self, values: &[Vec<f64>]) -> Result<(), String> {
        if values.len() != self.0.len() {
            return Err(format!(
                "{} law states for {} laws",
                values.len(),
                self.0.len()
            ));
        }
        for (k, (s, v)) in self.0.iter().zip(values).enumerate() {
            if s.0.len() != v.len() {
                return Err(format!(
                    "law {k} has a state of {} numbers, the saved one {}",
                    s.0.len(),
                    v.len()
                ));
            }
        }
        for (s, v) in self.0.iter_mut().zip(values) {
            s.0.copy_from_slice(v);
        }
        Ok(())
    }
}

/// The dotted field naming law `i` of joint `j` in an error.
fn law_field_of(j: &BoundJoint, i: usize) -> String {
    format!("joints.{}.laws[{i}]", j.name)
}

/// The law input of a joint with `contact` at rest: its contact fields (kind, radius, length,
/// bearing type, inner member) set, which stay the same for a whole run.
pub(super) fn contact_input(contact: &Contact) -> LawInput {
    let mut input = LawInput::at_rest(contact.kind);
    input.contact_radius_m = contact.radius_m;
    input.contact_length_m = contact.length_m;
    input.bearing_type = contact.bearing as u32;
    input.inner_body = contact.inner as u32;
    input
}

/// Make `input` (a joint's [`contact_input`]) the joint's unloaded input at instant `at` with
/// its bodies at `bodies`, in place: every field but the contact's set, the loads to zero. The
/// solver keeps one input per joint for a run and refreshes it each evaluation.
#[inline(always)]
pub(super) fn refresh_input(input: &mut LawInput, at: &Instant, bodies: &Bodies) {
    input.normal_load_n = 0.0;
    input.reaction_x_n = 0.0;
    input.reaction_y_n = 0.0;
    input.reaction_moment_nm = 0.0;
    input.load_on_inner_x_n = 0.0;
    input.load_on_inner_y_n = 0.0;
    input.oil_temp_c = at.oil.0;
    input.viscosity_pa_s = at.oil.1;
    input.engine_speed_rad_s = at.omega;
    input.crank_angle_rad = at.crank_angle;
    input.time_s = at.t;
    input.dt_s = at.dt;
    input.cylinder_pressure_pa = at.gas.cylinder_pa;
    input.crankcase_pressure_pa = at.gas.crankcase_pa;
    input.piston_from_tdc_m = at.gas.piston_from_tdc_m;
    input.cycle_angle_rad = at.gas.cycle_angle_rad;
    let relative = bodies.relative();
    input.relative_velocity = relative;
    input.sliding_velocity_m_s = match input.kind() {
        Some(JointKind::Revolute) => relative * input.contact_radius_m,
        _ => relative,
    };
    (input.body_a_angle, input.body_a_velocity) = bodies.a;
    (input.body_b_angle, input.body_b_velocity) = bodies.b;
}

/// Load a law input: normal load `w` (N), reaction components `comp` (the force body B exerts
/// on body A: global x, y on a revolute joint, along and normal to the axis on a slide) and
/// moment `moment`; the load on the inner member is that force, or its opposite where body B
/// is the inner member (the big end's crank pin).
#[inline(always)]
pub(super) fn set_load(input: &mut LawInput, comp: Vector2<f64>, moment: f64, w: f64) {
    input.normal_load_n = w;
    input.reaction_x_n = comp.x;
    input.reaction_y_n = comp.y;
    input.reaction_moment_nm = moment;
    let on_inner = if input.inner_body == InnerBody::B as u32 {
        -comp
    } else {
        comp
    };
    input.load_on_inner_x_n = on_inner.x;
    input.load_on_inner_y_n = on_inner.y;
}

/// Check a law's output on joint `joint` of kind `kind` at `input` (finite; of a physical size
/// against `reaction_n`, the largest joint reaction of the solve the law is evaluated at;
/// optional outputs it marks present finite, its diagnostics of physical sense; a stateless law
/// must not add energy, a stateful one may return what it stored) and return its power into the
/// joint.
#[inline(always)]
pub(super) fn checked_power(
    joint: &str,
    kind: JointKind,
    law: &BoundLaw,
    input: &LawInput,
    out: &LawOutput,
    reaction_n: f64,
) -> Result<f64, SimError> {
    if !out.force.is_finite() {
        return Err(unusable(joint, law, input, out.force));
    }
    // Below the bound at the floor load, and every optional output the law flags of sense:
    // a few comparisons inline. Only a doubtful output goes to the full (cold) check.
    if out.force.abs() > MAX_FORCE_PER_REACTION * REACTION_FLOOR_N || !flagged_fields_sound(out) {
        implausible(joint, kind, law, input, out, reaction_n)?;
    }
    let power = out.force * input.relative_velocity;
    let adds = power > 0.0 && !law.is_stateful() && power > 1e-9 * (1.0 + power.abs().sqrt());
    if adds {
        return Err(unusable(joint, law, input, out.force));
    }
    Ok(power)
}

/// Whether every optional output `out` flags is sound: the coefficient, dF/dv and dF/dN
/// finite, the diagnostics of physical sense (`LawOutput::bad_diagnostic`). Unflagged fields
/// are not read; a law that flags nothing costs one test.
#[inline(always)]
fn flagged_fields_sound(out: &LawOutput) -> bool {
    let flags = out.flags;
    if flags & (HAS_COEFFICIENT | HAS_DERIVATIVE | HAS_LOAD_DERIVATIVE | DIAGNOSTIC_FLAGS) == 0 {
        return true;
    }
    let finite_if = |bit: u32, x: f64| flags & bit == 0 || x.is_finite();
    finite_if(HAS_COEFFICIENT, out.coefficient)
        && finite_if(HAS_DERIVATIVE, out.dforce_dvelocity)
        && finite_if(HAS_LOAD_DERIVATIVE, out.dforce_dload)
        && (flags & DIAGNOSTIC_FLAGS == 0 || out.bad_diagnostic().is_none())
}

/// The error for an output no law may give, if `out` is one: a finite force or torque of more
/// than [`MAX_FORCE_PER_REACTION`] times the largest joint reaction (`reaction_n`, the law's
/// own normal load, at least [`REACTION_FLOOR_N`]), a non-finite coefficient, dF/dv or dF/dN
/// marked present, or a diagnostic marked present that makes no physical sense
/// (`LawOutput::bad_diagnostic`: a negative film or pressure, `|e| >= 1`, a share outside
/// `[0, 1]`).
#[cold]
fn implausible(
    joint: &str,
    kind: JointKind,
    law: &BoundLaw,
    input: &LawInput,
    out: &LawOutput,
    reaction_n: f64,
) -> Result<(), SimError> {
    let (noun, unit) = match kind {
        JointKind::Prismatic => ("force", "N"),
        JointKind::Revolute => ("torque", "N m"),
    };
    let scale = reaction_n.max(input.normal_load_n).max(REACTION_FLOOR_N);
    let bound = MAX_FORCE_PER_REACTION * scale;
    let (what, why) = if out.force.abs() > bound {
        (
            format!("a {noun} of {} {unit}", readable(out.force)),
            format!(
                "that is more than {MAX_FORCE_PER_REACTION:e} times the largest joint reaction at that instant ({scale:.1} N, so at most {bound:.3e} {unit}): no friction or damping law gives such a {noun}, so the law is wrong at these inputs"
            ),
        )
    } else if let Some(c) = out.coefficient().filter(|c| !c.is_finite()) {
        (
            format!("a non-finite friction coefficient ({c})"),
            "it marked the coefficient present (HAS_COEFFICIENT), so it must be a number; a law without one leaves the flag clear".to_string(),
        )
    } else if let Some(d) = out.derivative().filter(|d| !d.is_finite()) {
        (
            format!("a non-finite dF/dv ({d})"),
            "it marked the derivative present (HAS_DERIVATIVE), so it must be a number; a law without one leaves the flag clear".to_string(),
        )
    } else if let Some(d) = out.load_derivative().filter(|d| !d.is_finite()) {
        (
            format!("a non-finite dF/dN ({d})"),
            "it marked the load derivative present (HAS_LOAD_DERIVATIVE), so it must be a number; a law without one leaves the flag clear".to_string(),
        )
    } else if let Some(bad) = out.bad_diagnostic() {
        (
            format!("the diagnostic {} = {}", bad.field, readable(bad.value)),
            format!(
                "a diagnostic the law marks present must make physical sense: {} expected",
                bad.expected
            ),
        )
    } else {
        return Ok(());
    };
    Err(SimError::Implausible {
        fault: fault(joint, law, input, out.force),
        what,
        why,
    })
}

/// Check the model's laws against `registry` without creating any instance: each law exists and
/// its parameters have the names, types and ranges its description declares. Only the laws'
/// descriptions are read, so no law code runs: a study checks every law set this way before it
/// starts, and a law that misbehaves when created or run fails only its own set later.
pub(super) fn check_laws(model: &RigFile, registry: &LawRegistry) -> Result<(), SimError> {
    for spec in joint_specs(model) {
        for (i, l) in spec.laws.iter().enumerate() {
            check_law(registry, l, &spec.law_field(i))?;
        }
    }
    Ok(())
}

/// Check one law (the model's field `field`) against `registry` without creating it: the law
/// exists and its parameters have the declared names, types and ranges.
fn check_law(
    registry: &LawRegistry,
    l: &crate::model::LawRef,
    field: &str,
) -> Result<(), SimError> {
    let lib = registry
        .get(&l.law)
        .map_err(|e| setup_error(format!("{field}.law"), e))?;
    tribo_plugin_api::describe::check_params(lib.description(), &l.params).map_err(|source| {
        setup_error(
            format!("{field}.params"),
            LawError::Param {
                error: source,
                path: lib.path().to_path_buf(),
            },
        )
    })?;
    Ok(())
}

/// A binding problem as a setup error; a parameter's problem keeps the law and parameter apart
/// from the message, so the configuration layer can point at the parameter in the file that
/// gives it.
fn setup_error(field: String, e: LawError) -> SimError {
    match e {
        LawError::Param {
            error: source,
            path,
        } => SimError::Setup {
            at: None,
            field,
            law: Some(source.law),
            param: (!source.parameter.is_empty()).then_some(source.parameter),
            message: format!("{} (library `{}`)", source.message, path.display()),
        },
        other => SimError::Setup {
            at: None,
            field,
            law: None,
            param: None,
            message: other.to_string(),
        },
    }
}

/// Bind the model's laws from `registry` to its joints, in joint order (laws numbered joint by
/// joint); the number of laws bound in all is returned with them.
pub(super) fn bind_joints(
    model: &RigFile,
    registry: &LawRegistry,
) -> Result<(Vec<BoundJoint>, usize), SimError> {
    let mut joints = Vec::new();
    let mut n_laws = 0;
    for spec in joint_specs(model) {
        let laws = spec
            .laws
            .iter()
            .enumerate()
            .map(|(i, l)| BoundLaw::bind(registry, l, &spec.law_field(i), &spec.name))
            .collect::<Result<Vec<_>, _>>()?;
        let first_law = n_laws;
        n_laws += laws.len();
        joints.push(BoundJoint {
            contact: Contact {
                kind: spec.role.kind(),
                radius_m: spec.contact.0,
                length_m: spec.contact.1,
                bearing: model.bearing_type(&spec.name),
                inner: spec.role.inner(),
            },
            name: spec.name,
            role: spec.role,
            laws,
            first_law,
        });
    }
    Ok((joints, n_laws))
}

/// One warning per law on a joint whose declared bearing type the law does not suit (its
/// `SUITS_*` bits; a law declaring none, or a joint the rig declares nothing for, is never
/// warned about), naming the joint, the law, what the law is made for and what the joint is.
/// A law the registry cannot provide is left to the binding's error.
pub fn suitability_notes(model: &RigFile, registry: &LawRegistry) -> Vec<String> {
    let mut notes = Vec::new();
    for spec in joint_specs(model) {
        let bearing = model.bearing_type(&spec.name);
        for law in &spec.laws {
            let Ok(lib) = registry.get(&law.law) else {
                continue;
            };
            if !suits(lib.suits(), bearing) {
                notes.push(format!(
                    "joint `{}`: law `{}` is made for {}, but the rig declares {} there",
                    spec.name,
                    law.law,
                    suits_text(lib.suits()),
                    bearing_words(bearing)
                ));
            }
        }
    }
    notes
}

/// A declared bearing type in a sentence.
fn bearing_words(bearing: BearingType) -> &'static str {
    match bearing {
        BearingType::Unspecified => "no bearing type",
        BearingType::Plain => "a plain bearing",
        BearingType::Rolling => "a rolling-element bearing",
        BearingType::Slide => "a slide",
    }
}

/// Calls and estimated time per law so far.
pub(super) fn law_time(joints: &[BoundJoint]) -> Vec<LawTime> {
    joints
        .iter()
        .flat_map(|j| j.laws.iter().map(move |l| l.time(&j.name)))
        .collect()
}

/// A law that failed (panicked or returned an error code) at `input` on joint `joint`.
#[cold]
pub(super) fn law_failed(joint: &str, input: &LawInput, e: LawError) -> SimError {
    SimError::Law {
        joint: joint.into(),
        time_s: input.time_s,
        velocity: input.relative_velocity,
        load_n: input.normal_load_n,
        error: Box::new(e),
    }
}

/// Where, when and with which inputs `law` on `joint` returned `force`.
fn fault(joint: &str, law: &BoundLaw, input: &LawInput, force: f64) -> Box<Fault> {
    Box::new(Fault {
        joint: joint.into(),
        law: law.name.clone(),
        file: law.instance.path().display().to_string(),
        time_s: input.time_s,
        force,
        velocity: input.relative_velocity,
        load_n: input.normal_load_n,
    })
}

/// A law that returned a non-finite force, or (stateless) one that adds energy.
#[cold]
fn unusable(joint: &str, law: &BoundLaw, input: &LawInput, force: f64) -> SimError {
    let fault = fault(joint, law, input, force);
    if force.is_finite() {
        SimError::AddsEnergy(fault)
    } else {
        SimError::NonFinite(fault)
    }
}
