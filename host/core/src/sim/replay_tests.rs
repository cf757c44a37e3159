//! The hold replay (`replay.rs`) against the same holds evaluated: what it must reproduce; and
//! the cycle repetition it relies on, where it never comes: a steady state and a crank-angle
//! trace that say so.

use std::f64::consts::TAU;

use tribo_plugin_api::loader::{LawLibrary, LawRegistry};
use tribo_plugin_api::{smooth_sign, Law, LawInput, LawOutput, ParamError, ParamSpec};

use super::replay::HoldReplay;
use super::results::RunResult;
use super::tests::with_sqrt_piston;
use super::Simulation;
use crate::cycle::Segment;
use crate::model::{QuadratureRule, RigFile, Temperature};

/// The short cycle of these tests: up to 3000 rpm, a hold of 0.6 s (the window 0.08 s: two
/// four-stroke cycles), up to 4500 rpm, a hold of 0.3 s.
fn short_cycle(model: &mut RigFile) {
    model.cycle.segments = Some(vec![
        Segment::Ramp {
            to_rpm: 3000.0,
            duration_s: 0.15,
        },
        Segment::Hold { duration_s: 0.6 },
        Segment::Ramp {
            to_rpm: 4500.0,
            duration_s: 0.1,
        },
        Segment::Hold { duration_s: 0.3 },
    ]);
    model.oil.temperature_c = Temperature::PerPlateau(vec![60.0, 90.0]);
}

/// The thesis rig on the short cycle with `model` and `registry`, Simpson's rule throughout,
/// run with hold replay `mode`.
fn run(model: &RigFile, registry: &LawRegistry, mode: HoldReplay) -> RunResult {
    let mut model = model.clone();
    model.solver.quadrature = QuadratureRule::Simpson;
    let mut sim = Simulation::new(&model, registry).expect("simulation builds");
    sim.hold_replay = mode;
    sim.run().expect("run")
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
}

/// Every plateau's motoring torque, per-law friction torque and mean load of `a` and `b`
/// within `tol` relative, over the same window.
fn assert_plateaus_within(a: &RunResult, b: &RunResult, tol: f64) {
    assert_windows_within(a, b, tol, 0.0);
}

/// As [`assert_plateaus_within`], the windows' bounds within `window_tol_s` (a PI drive's
/// window is found from the crank angle, which moves with the state).
fn assert_windows_within(a: &RunResult, b: &RunResult, tol: f64, window_tol_s: f64) {
    assert_eq!(a.plateaus.len(), b.plateaus.len());
    for (p, q) in a.plateaus.iter().zip(&b.plateaus) {
        let d = relative(p.motoring_torque_nm, q.motoring_torque_nm);
        assert!(d <= tol, "{} rpm: torque {d:e} apart", p.set_speed_rpm);
        for (x, y) in p.window_s.iter().zip(&q.window_s) {
            assert!(
                (x - y).abs() <= window_tol_s,
                "{} rpm: window {x} against {y}",
                p.set_speed_rpm
            );
        }
        for (j, k) in p.joints.iter().zip(&q.joints) {
            let d = relative(j.friction_torque_nm, k.friction_torque_nm);
            assert!(d <= tol, "{} rpm {}: {d:e} apart", p.set_speed_rpm, j.joint);
            let d = relative(j.mean_normal_load_n, k.mean_normal_load_n);
            assert!(
                d <= tol,
                "{} rpm {} load: {d:e} apart",
                p.set_speed_rpm,
                j.joint
            );
        }
    }
}

/// The steps a replay of the short cycle must replay, counted from the cycle alone: each
/// hold's time before its window in whole revolutions (the motored rig, without gas, repeats
/// every revolution: 360 one-degree steps), less the two revolutions evaluated, where at least
/// one is left.
fn expected_replayed() -> u64 {
    let mut replayed = 0;
    for (rpm, hold_s) in [(3000.0_f64, 0.6_f64), (4500.0, 0.3)] {
        let omega = rpm * TAU / 60.0;
        let period_s = TAU / omega;
        let window_cycles = (0.1 / period_s).floor();
        let before_s = hold_s - window_cycles * period_s;
        let cycles = (before_s / period_s + 1e-9).floor() as u64;
        if cycles >= 3 {
            replayed += (cycles - 2) * 360;
        }
    }
    replayed
}

/// A hold replayed is the hold evaluated in the same steps: the same plateaus to round-off
/// (the window is never replayed), the energy within the friction iteration's tolerance (the
/// replayed cycle is settled to it), the same step count, with the steps it should replay
/// counted independently; and the plateaus are those of the holds stepped as before, the
/// energy within the quadrature's own error of theirs.
#[test]
fn a_replayed_hold_is_the_hold_evaluated() {
    let (mut model, registry) =
        with_sqrt_piston(include_str!("../../../../rigs/crf250r-motored.toml"));
    short_cycle(&mut model);
    let replayed = run(&model, &registry, HoldReplay::On);
    let evaluated = run(&model, &registry, HoldReplay::Evaluate);
    let stepped = run(&model, &registry, HoldReplay::Off);
    let expected = expected_replayed();
    assert!(
        expected > 10_000,
        "the short cycle replays {expected} steps"
    );
    assert_eq!(replayed.replayed_steps, expected);
    assert_eq!((evaluated.replayed_steps, stepped.replayed_steps), (0, 0));
    assert_eq!(replayed.steps, evaluated.steps);
    assert_plateaus_within(&replayed, &evaluated, 1e-12);
    let (e, f) = (&replayed.energy, &evaluated.energy);
    assert!(relative(e.motor_work_j, f.motor_work_j) < 1e-8);
    assert!(relative(e.dissipated_j, f.dissipated_j) < 1e-8);
    assert!(replayed.energy.relative_residual.abs() < 1e-9);
    assert_plateaus_within(&replayed, &stepped, 1e-12);
    assert!(relative(e.motor_work_j, stepped.energy.motor_work_j) < 1e-6);
    assert!(relative(e.dissipated_j, stepped.energy.dissipated_j) < 1e-6);
}

/// Parameters of [`Drifting`].
#[derive(serde::Serialize, serde::Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct DriftParams {
    /// 0: the friction grows with the input's time (stateless); 1: with the time committed
    /// over, kept as state.
    committed: f64,
}

/// A law whose friction grows by 1 N per second, of the run's time (stateless) or of the time
/// it has been committed over (stateful), so no two cycles of a hold see the same law.
struct Drifting {
    stateful: bool,
}

impl Law for Drifting {
    type Params = DriftParams;
    const NAME: &'static str = "drifting-unit";
    const VERSION: &'static str = "0";
    const SUMMARY: &'static str = "friction growing with time (unit test)";

    fn parameters() -> Vec<ParamSpec> {
        vec![ParamSpec::number(
            "committed",
            "-",
            "0: time, 1: state",
            0.0,
            1.0,
        )]
    }

    fn new(p: DriftParams) -> Result<Self, ParamError> {
        Ok(Self {
            stateful: p.committed > 0.5,
        })
    }

    fn state_size(&self) -> usize {
        usize::from(self.stateful)
    }

    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        let grown = match self.stateful {
            true => state.first().copied().unwrap_or(0.0),
            false => input.time_s,
        };
        LawOutput::force(-smooth_sign(input.sliding_velocity_m_s, 1e-3).0 * (1.0 + grown))
    }

    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        if let Some(s) = state.first_mut() {
            *s += input.dt_s;
        }
    }
}

/// The thesis rig on the short cycle with the drifting law (`params`) on its piston alone, and
/// a registry holding the law.
fn with_drifting_piston(params: &str) -> (RigFile, LawRegistry) {
    let text = include_str!("../../../../rigs/crf250r-motored.toml");
    let mut model: RigFile = toml::from_str(text).expect("rig parses");
    short_cycle(&mut model);
    model.joints.piston.laws = vec![crate::model::LawRef {
        law: "drifting-unit".into(),
        params: toml::from_str(params).expect("params"),
    }];
    let mut registry = LawRegistry::new();
    registry
        .insert(LawLibrary::in_process::<Drifting>().expect("law describes itself"))
        .expect("one law");
    (model, registry)
}

/// A law whose output drifts with time makes the two evaluated cycles differ, and the hold is
/// then evaluated to its end: nothing replayed, the same numbers as every cycle evaluated.
#[test]
fn a_hold_whose_cycles_differ_is_not_replayed() {
    let (model, registry) = with_drifting_piston("committed = 0.0");
    let replayed = run(&model, &registry, HoldReplay::On);
    let evaluated = run(&model, &registry, HoldReplay::Evaluate);
    assert_eq!(replayed.replayed_steps, 0);
    assert_plateaus_within(&replayed, &evaluated, 0.0);
    assert_eq!(replayed.energy.motor_work_j, evaluated.energy.motor_work_j);
}

/// The default quadrature ("auto": Simpson in the windows and the replayed holds, Gauss-Lobatto
/// on the ramps) gives the plateaus of Simpson's rule throughout to round-off (a window owes
/// nothing to the steps before it), the energy within the quadratures' own error, in fewer
/// steps.
#[test]
fn the_auto_quadrature_keeps_simpsons_plateaus_in_fewer_steps() {
    let (mut model, registry) =
        with_sqrt_piston(include_str!("../../../../rigs/crf250r-motored.toml"));
    short_cycle(&mut model);
    model.solver.quadrature = QuadratureRule::Auto;
    let auto = Simulation::new(&model, &registry)
        .expect("simulation builds")
        .run()
        .expect("run");
    let simpson = run(&model, &registry, HoldReplay::On);
    assert_plateaus_within(&auto, &simpson, 1e-12);
    assert_eq!(auto.replayed_steps, simpson.replayed_steps);
    let (e, f) = (&auto.energy, &simpson.energy);
    assert!(relative(e.motor_work_j, f.motor_work_j) < 1e-6);
    assert!(relative(e.dissipated_j, f.dissipated_j) < 1e-6);
    assert!(auto.energy.relative_residual.abs() < 1e-9);
    assert!(
        auto.steps < simpson.steps,
        "{} steps against {}",
        auto.steps,
        simpson.steps
    );
}

/// The steady state of stateful laws whose cycles never repeat does not pass the last of its
/// settling cycles off as a steady state: every plateau's result carries a warning naming the
/// plateau and the bound.
#[test]
fn a_steady_state_whose_cycles_never_repeat_says_so() {
    let (model, registry) = with_drifting_piston("committed = 1.0");
    let mut sim = Simulation::new(&model, &registry).expect("simulation builds");
    let result = sim.run_steady().expect("steady state");
    for rpm in ["3000 rpm", "4500 rpm"] {
        assert!(
            result
                .warnings
                .iter()
                .any(|w| w.contains(rpm) && w.contains("did not repeat a cycle within 200 cycles")),
            "{rpm}: {:?}",
            result.warnings
        );
    }
}

/// A crank-angle trace of stateful laws whose cycles never repeat says so as the steady run
/// does (the same warning, naming the plateau and the bound), with the last cycle's change of
/// the mean drive torque. The drifting law's force is (1 + t) N at committed time t, so with
/// the piston's lever |dx/dtheta| (G) the mean torque of pass p (0-based, n samples h apart,
/// cycle time T = n h) is mean(G) (1 + T p) + h mean(k G_k); on a slider crank without pin
/// offset G is symmetric about the cycle's middle, which makes the second term mean(G) T / 2:
/// the relative change of the last of 200 passes is T / (1 + T (199 + 1/2)).
#[test]
fn a_crank_angle_trace_whose_cycles_never_repeat_says_so() {
    let (model, registry) = with_drifting_piston("committed = 1.0");
    let mut sim = Simulation::new(&model, &registry).expect("simulation builds");
    let traces = sim.crank_angle_traces(2.0).expect("traces");
    assert_eq!(traces.len(), 2);
    for t in &traces {
        let rpm = format!("{:.0} rpm", t.speed_rpm);
        let [warning] = t.warnings.as_slice() else {
            panic!("{rpm}: one warning expected, got {:?}", t.warnings);
        };
        assert!(
            warning.contains(&rpm) && warning.contains("did not repeat a cycle within 200 cycles"),
            "{warning}"
        );
        // Without gas loads a cycle is one revolution.
        assert_eq!(sim.revolutions_per_cycle(), 1);
        let cycle_s = TAU / (t.speed_rpm * TAU / 60.0);
        let expected = cycle_s / (1.0 + cycle_s * 199.5);
        let reported: f64 = warning
            .split("still moved by ")
            .nth(1)
            .and_then(|rest| rest.split_whitespace().next())
            .and_then(|x| x.parse().ok())
            .unwrap_or_else(|| panic!("no change in {warning}"));
        // Printed to two significant digits.
        assert!(
            (reported - expected).abs() <= 0.051 * 10f64.powf(expected.log10().floor()),
            "{rpm}: reported {reported}, closed form {expected}: {warning}"
        );
    }
}

/// The thesis rig under the PI drive (default gains, a torque limit it never reaches) on a
/// cycle whose first hold is long enough for the controller to settle: up to 3000 rpm in
/// 0.15 s, a hold of 1.5 s, up to 4500 rpm, a hold of 0.3 s (too short to settle).
fn pi_cycle(model: &mut RigFile) {
    short_cycle(model);
    if let Some(segments) = &mut model.cycle.segments {
        segments[1] = Segment::Hold { duration_s: 1.5 };
    }
    model.drive = crate::model::Drive::Pi {
        kp: 0.2,
        ki: 8.0,
        torque_limit_nm: 400.0,
        belt_ratio: 1.0,
        motor_inertia_kg_m2: 0.0,
    };
}

/// The rig `model` with `registry`, run with hold replay `mode` (the adaptive integrator).
fn run_pi(model: &RigFile, registry: &LawRegistry, mode: HoldReplay) -> RunResult {
    let mut sim = Simulation::new(model, registry).expect("simulation builds");
    sim.hold_replay = mode;
    sim.run().expect("run")
}

/// The thesis rig with the square-root-load piston law on [`pi_cycle`], and its registry.
fn sqrt_pi_rig() -> (RigFile, LawRegistry) {
    let (mut model, registry) =
        with_sqrt_piston(include_str!("../../../../rigs/crf250r-motored.toml"));
    pi_cycle(&mut model);
    (model, registry)
}

/// A PI run whose settled hold was replayed (`replayed`) against the same run with every
/// cycle evaluated: the replayed hold's plateau within the agreement (1e-7), the later
/// plateaus within the adaptive integrator's own tolerance (1e-5, windows 1e-6 s), the energy
/// terms within 1e-6, and the energy balance closed.
fn assert_replay_is_evaluation(replayed: &RunResult, evaluated: &RunResult) {
    let (p, q) = (&replayed.plateaus[0], &evaluated.plateaus[0]);
    let d = relative(p.motoring_torque_nm, q.motoring_torque_nm);
    assert!(d <= 1e-7, "the replayed hold's torque {d:e} apart");
    assert_windows_within(replayed, evaluated, 1e-5, 1e-6);
    let (e, f) = (&replayed.energy, &evaluated.energy);
    assert!(
        relative(e.motor_work_j, f.motor_work_j) < 1e-6,
        "{e:?} {f:?}"
    );
    assert!(
        relative(e.dissipated_j, f.dissipated_j) < 1e-6,
        "{e:?} {f:?}"
    );
    assert!(e.relative_residual.abs() < 1e-6, "{e:?}");
}

/// A PI hold replayed once its cycles agree is the hold evaluated in the same orbit cycles: the
/// replay starts within the agreement (the friction tolerance, 1e-7) of where the evaluated run
/// is, and the difference decays with the controller's settling, so the replayed hold's plateau
/// is within that agreement, the energy terms within 1e-6, the later plateaus within the
/// adaptive integrator's own tolerance; the energy balance still closes, and a settled hold
/// does replay.
#[test]
fn a_replayed_pi_hold_is_the_hold_evaluated() {
    let (model, registry) = sqrt_pi_rig();
    let replayed = run_pi(&model, &registry, HoldReplay::On);
    let evaluated = run_pi(&model, &registry, HoldReplay::Evaluate);
    let stepped = run_pi(&model, &registry, HoldReplay::Off);
    assert!(
        replayed.replayed_steps > 1000,
        "{} steps replayed",
        replayed.replayed_steps
    );
    assert_eq!((evaluated.replayed_steps, stepped.replayed_steps), (0, 0));
    // The replayed hold: its window starts from a state within a few times the agreement of
    // the evaluated run's, and the difference decays through the window; the plateaus after
    // it, started from states a little apart, part ways within the integrator's tolerance.
    assert_replay_is_evaluation(&replayed, &evaluated);
    // Cutting the hold into orbit cycles moves the steps, not the result beyond the adaptive
    // integrator's own tolerance.
    assert_windows_within(&replayed, &stepped, 1e-5, 1e-6);
}

/// Under the PI drive too, a law drifting with time keeps every cycle of a hold different: nothing
/// replayed, the numbers of every cycle evaluated.
#[test]
fn a_pi_hold_whose_cycles_differ_is_not_replayed() {
    let (mut model, registry) = with_drifting_piston("committed = 0.0");
    pi_cycle(&mut model);
    let replayed = run_pi(&model, &registry, HoldReplay::On);
    let evaluated = run_pi(&model, &registry, HoldReplay::Evaluate);
    assert_eq!(replayed.replayed_steps, 0);
    assert_plateaus_within(&replayed, &evaluated, 0.0);
    assert_eq!(replayed.energy.motor_work_j, evaluated.energy.motor_work_j);
}

/// A PI hold's settling extrapolated to its orbit (`settle.rs`) is the settling waited for: the
/// orbit is jumped to only once the cycles settle as a linear system does, the cycle after the
/// jump must agree with it, and what the rest of the settling would add is booked. So the replay
/// starts earlier than when waiting for two cycles to agree, the replayed hold's plateau stays
/// within the agreement (1e-7) of the hold evaluated, the energy terms within 1e-6, and the
/// energy balance closes (the motor's tail is what keeps it).
#[test]
fn a_pi_hold_settling_extrapolated_is_the_settling_waited_for() {
    let (model, registry) = sqrt_pi_rig();
    let jumped = run_pi(&model, &registry, HoldReplay::On);
    let waited = run_pi(&model, &registry, HoldReplay::Agreed);
    let evaluated = run_pi(&model, &registry, HoldReplay::Evaluate);
    assert!(
        2 * jumped.replayed_steps > 3 * waited.replayed_steps,
        "{} steps replayed with the settling extrapolated, {} without",
        jumped.replayed_steps,
        waited.replayed_steps
    );
    assert_replay_is_evaluation(&jumped, &evaluated);
}
