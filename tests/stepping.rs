//! The stepping API (`tribo::sim::Run`, issue 28): a run advanced by its caller equals
//! `tribo run`; inputs set between steps act as physics says; a saved state replays bit for
//! bit; two runs share nothing; bad inputs are refused naming the input.

mod common;

use std::path::Path;

use serde_json::Value;
use tribo::plugin_api::loader::{load_paths, LawRegistry};
use tribo::sim::{Inputs, Run};

fn registry() -> LawRegistry {
    common::ensure_plugins_built();
    load_paths(&[common::profile_dir()]).expect("plugins load")
}

/// The thesis rig with law set `lawset` (`None`: frictionless) and `sets`, as a stepped run.
fn run_of(lawset: Option<&str>, sets: &[&str], registry: &LawRegistry) -> Run {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let mut rig = tribo::rig::load_rig(Path::new("crf250r-motored"), &sets).expect("bundled rig");
    if let Some(set) = lawset {
        tribo::lawset::LawSet::load(set)
            .expect("bundled law set")
            .apply(&mut rig);
    }
    tribo::rig::simulation(&rig, registry)
        .expect("simulation")
        .start()
        .expect("run starts")
}

/// Every number of `a` within `rel` (relative) of `b`'s, recursively; `path` names the place.
fn assert_close(a: &Value, b: &Value, rel: f64, path: &str) {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (
                x.as_f64().unwrap_or(f64::NAN),
                y.as_f64().unwrap_or(f64::NAN),
            );
            let scale = x.abs().max(y.abs()).max(1e-300);
            assert!((x - y).abs() <= rel * scale, "{path}: {x} vs {y}");
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{path}: lengths");
            for (i, (p, q)) in x.iter().zip(y).enumerate() {
                assert_close(p, q, rel, &format!("{path}[{i}]"));
            }
        }
        (Value::Object(x), Value::Object(y)) => {
            for (k, v) in x {
                let w = y.get(k).unwrap_or_else(|| panic!("{path}.{k} missing"));
                assert_close(v, w, rel, &format!("{path}.{k}"));
            }
        }
        _ => assert_eq!(a, b, "{path}"),
    }
}

/// The thesis cycle with a dynamic law on every joint (the Stribeck law set), stepped one
/// accepted step at a time with the outputs read after each, gives `tribo run`'s plateaus,
/// energy balance and step count to 1e-12, for both drives.
#[test]
fn the_thesis_cycle_stepped_one_step_at_a_time_equals_tribo_run() {
    let registry = registry();
    for drive in [None, Some("drive={kind=\"pi\"}")] {
        let mut args = vec![
            "run",
            "crf250r-motored",
            "--lawset",
            "stribeck-duty",
            "--json",
        ];
        let sets: Vec<&str> = drive.into_iter().collect();
        for s in &sets {
            args.extend(["--set", s]);
        }
        let cli = common::json_in(&args, &common::workspace());
        let mut run = run_of(Some("stribeck-duty"), &sets, &registry);
        let (mut steps, mut t) = (0_u64, 0.0);
        while run.step().expect("step") {
            let out = run.outputs();
            assert!(out.time_s > t, "time goes forward");
            assert!(out.drive_torque_nm.is_finite());
            t = out.time_s;
            steps += 1;
        }
        let result = serde_json::to_value(run.result().expect("result")).expect("json");
        assert_eq!(result["steps"].as_u64(), Some(steps));
        for key in ["plateaus", "energy", "energy_residual_j", "steps", "fmep"] {
            assert_close(&result[key], &cli[key], 1e-12, &format!("{drive:?} {key}"));
        }
    }
}

/// `advance_to` lands on the time asked; a state saved mid-run (a stateful law, LuGre, on the
/// piston: its bristle state included) replays to the same numbers, bit for bit, however the
/// run went on in between.
#[test]
fn a_saved_state_replays_bit_for_bit() {
    let registry = registry();
    let lugre = "joints.piston.laws=[{law=\"lugre\", params={mu_c=0.08, mu_s=0.1, sigma2=0.0}}]";
    let mut run = run_of(None, &[lugre], &registry);
    run.advance_to(0.5).expect("advance");
    assert_eq!(run.time_s(), 0.5);
    let saved = run.save();
    run.advance_to(0.6).expect("advance");
    let first = (run.outputs(), run.laws().expect("laws"));
    // Elsewhere in between: hotter oil, a pressure on the crown, further in time.
    run.set_inputs(Inputs {
        oil_temperature_c: Some(110.0),
        cylinder_pressure_pa: Some(3e5),
        ..Inputs::default()
    })
    .expect("inputs");
    run.advance_to(0.65).expect("advance");
    run.restore(&saved).expect("restore");
    assert_eq!(run.time_s(), 0.5);
    assert_eq!(run.inputs(), Inputs::default());
    run.advance_to(0.6).expect("advance");
    assert_eq!((run.outputs(), run.laws().expect("laws")), first);
    // Another run's snapshot is refused.
    let mut other = run_of(None, &[lugre], &registry);
    let err = other.restore(&saved).expect_err("not its own");
    assert!(err.to_string().contains("restore"), "{err}");
}

/// Under the PI drive a settled hold's cycles are replayed (docs/solver.md). A run landed on a
/// time inside the replayed stretch (2.25 s: the 3000 rpm hold replays from before it, checked
/// below, and its stretch ends at 2.32 s, a whole number of revolutions before the window's
/// records) leaves the replay there and steps on; a state saved at that time and restored
/// after the run went on replays bit for bit; and the result is the uninterrupted run's within
/// the adaptive integrator's own tolerance (1e-5: the steps differ after the landing).
#[test]
fn a_pi_run_landed_inside_a_replayed_hold_steps_on() {
    let registry = registry();
    let pi = ["drive={kind=\"pi\"}"];
    let to_end = |run: &mut Run| while run.step().expect("step") {};
    // The uninterrupted run, its drive torque recorded per step in the 3000 rpm hold: a replayed
    // step repeats a step of a revolution (20 ms) before bit for bit, an evaluated one never.
    let mut whole = run_of(Some("fedem-baseline"), &pi, &registry);
    let mut hold: std::collections::HashMap<u64, f64> = std::collections::HashMap::new();
    let mut replayed_by = f64::INFINITY;
    while whole.step().expect("step") {
        let out = whole.outputs();
        if (1.5..2.5).contains(&out.time_s) {
            let bits = out.drive_torque_nm.to_bits();
            if let Some(t) = hold.get(&bits) {
                let revs = (out.time_s - t) / 0.02;
                if (revs - revs.round()).abs() < 1e-6 {
                    replayed_by = replayed_by.min(out.time_s);
                }
            }
            hold.insert(bits, out.time_s);
        }
    }
    assert!(
        replayed_by < 2.25,
        "the hold replays first at {replayed_by} s"
    );
    let whole = whole.result().expect("result");
    assert!(whole.replayed_steps > 0, "nothing replayed");
    let landed = |restore: bool| {
        let mut run = run_of(Some("fedem-baseline"), &pi, &registry);
        run.advance_to(2.25).expect("advance");
        assert_eq!(run.time_s(), 2.25);
        if restore {
            let saved = run.save();
            run.advance_to(2.4).expect("advance");
            run.restore(&saved).expect("restore");
        }
        to_end(&mut run);
        run.result().expect("result")
    };
    let (plain, restored) = (landed(false), landed(true));
    let json = |r: &tribo::sim::RunResult| serde_json::to_value(r).expect("json");
    for key in ["plateaus", "energy", "steps"] {
        assert_eq!(json(&restored)[key], json(&plain)[key], "{key}");
    }
    assert_close(
        &json(&plain)["plateaus"],
        &json(&whole)["plateaus"],
        1e-5,
        "plateaus",
    );
    assert!(plain.energy.relative_residual.abs() < 1e-6);
}

/// Two runs in one process share nothing: stepped in turns, one with other inputs, each gives
/// what it gives alone.
#[test]
fn two_runs_share_nothing() {
    let registry = registry();
    let lugre = "joints.piston.laws=[{law=\"lugre\", params={mu_c=0.08, mu_s=0.1, sigma2=0.0}}]";
    let mut a = run_of(Some("stribeck-duty"), &[lugre], &registry);
    let mut b = run_of(Some("stribeck-duty"), &[lugre], &registry);
    b.set_inputs(Inputs {
        oil_temperature_c: Some(40.0),
        ..Inputs::default()
    })
    .expect("inputs");
    for k in 1..=40 {
        let t = 0.01 * k as f64;
        a.advance_to(t).expect("a");
        b.advance_to(t).expect("b");
    }
    // Landing on every 10 ms moves the step grid: compare with a run landing alike, alone.
    let mut same_grid = run_of(Some("stribeck-duty"), &[lugre], &registry);
    for k in 1..=40 {
        same_grid.advance_to(0.01 * k as f64).expect("advance");
    }
    assert_eq!(a.outputs(), same_grid.outputs());
    assert_eq!(a.laws().expect("laws"), same_grid.laws().expect("laws"));
    assert_ne!(
        a.outputs(),
        b.outputs(),
        "the other oil changes the other run only"
    );
}

/// A cylinder pressure set from outside acts on the crown: on the frictionless rig at a held
/// speed, the drive torque changes by exactly the pressure's virtual work, -dp A dx/dtheta
/// (x the piston's travel from TDC, written out for the centred slider-crank).
#[test]
fn a_cylinder_pressure_does_its_virtual_work_on_the_crank() {
    let registry = registry();
    let rig = tribo::rig::load_rig(Path::new("reference-frictionless"), &[]).expect("rig");
    let f = rig.model();
    let (r, l) = (f.geometry.crank_radius_m, f.bodies.rod.length_m);
    let area = std::f64::consts::PI * 0.25 * f.geometry.bore_m.powi(2);
    let omega = 400.0;
    let dp = 2.0e5;
    let run_at = |p: Option<f64>| {
        let mut run = tribo::rig::simulation(&rig, &registry)
            .expect("simulation")
            .start()
            .expect("start");
        run.advance_to(0.2).expect("advance");
        run.set_inputs(Inputs {
            crank_speed_rad_s: Some(omega),
            cylinder_pressure_pa: p.map(|p| f.gas.ambient_pa + p),
            ..Inputs::default()
        })
        .expect("inputs");
        let mut out = Vec::new();
        for k in 1..=50 {
            run.advance_to(0.2 + 1e-3 * k as f64).expect("advance");
            let o = run.outputs();
            out.push((o.crank_angle_rad, o.drive_torque_nm));
        }
        out
    };
    let x = |theta: f64| {
        let s = r * theta.sin();
        r + l - (r * theta.cos() + (l * l - s * s).sqrt())
    };
    let (ambient, pressed) = (run_at(None), run_at(Some(dp)));
    let mut checked = 0;
    for ((theta, t0), (theta1, t1)) in ambient.iter().zip(&pressed) {
        assert_eq!(theta, theta1, "the same held motion");
        let h = 1e-6;
        let dx = (x(theta + h) - x(theta - h)) / (2.0 * h);
        let expected = -dp * area * dx;
        let got = t1 - t0;
        assert!(
            (got - expected).abs() <= 1e-6 * (1.0 + expected.abs()),
            "theta {theta}: {got} vs {expected}"
        );
        checked += usize::from(expected.abs() > 1.0);
    }
    assert!(
        checked > 20,
        "the pressure worked at {checked} instants only"
    );
}

/// The oil temperature set from outside reaches the laws: a Petroff journal on one main
/// bearing at a held speed dissipates 2 pi eta omega^2 R^3 L / c, eta the rig oil's viscosity
/// at the temperature set, less in hotter, thinner oil.
#[test]
fn the_oil_temperature_set_from_outside_sets_the_viscous_friction() {
    let registry = registry();
    let clearance = 2e-5;
    let petroff = format!(
        "joints.main_a.laws=[{{law=\"petroff-journal\", params={{clearance_m={clearance}, eccentricity=0.0}}}}]"
    );
    let omega = 500.0;
    let power_at = |c: f64| {
        let mut run = run_of(None, &[&petroff], &registry);
        run.advance_to(0.2).expect("advance");
        run.set_inputs(Inputs {
            crank_speed_rad_s: Some(omega),
            oil_temperature_c: Some(c),
            ..Inputs::default()
        })
        .expect("inputs");
        run.advance_to(0.25).expect("advance");
        let out = run.outputs();
        assert_eq!(out.crank_speed_rad_s, omega);
        out.joints[0].power_w
    };
    let rig = tribo::rig::load_rig(Path::new("crf250r-motored"), &[]).expect("rig");
    let f = rig.model();
    let (r, l) = (f.joints.main_a.radius_m, f.joints.main_a.length_m);
    let mut last = f64::INFINITY;
    for c in [40.0, 80.0, 110.0] {
        let eta = f.oil.viscosity.kinematic_cst(c) * 1e-6 * f.oil.density_kg_m3;
        let expected = std::f64::consts::TAU * eta * omega * omega * r.powi(3) * l / clearance;
        let got = power_at(c);
        assert!(
            (got - expected).abs() <= 1e-9 * expected,
            "{c} C: {got} vs {expected} W"
        );
        assert!(got < last, "hotter oil, less friction: {got} W at {c} C");
        last = got;
    }
}

/// Inputs that cannot be used are refused naming the input; the run is left as it was.
#[test]
fn bad_inputs_are_refused_naming_the_input() {
    let registry = registry();
    let mut run = run_of(None, &[], &registry);
    run.advance_to(0.1).expect("advance");
    let before = run.outputs();
    for (inputs, name) in [
        (
            Inputs {
                drive_torque_nm: Some(10.0),
                ..Inputs::default()
            },
            "drive_torque_nm",
        ),
        (
            Inputs {
                crank_speed_rad_s: Some(f64::NAN),
                ..Inputs::default()
            },
            "crank_speed_rad_s",
        ),
        (
            Inputs {
                oil_temperature_c: Some(500.0),
                ..Inputs::default()
            },
            "oil_temperature_c",
        ),
        (
            Inputs {
                cylinder_pressure_pa: Some(-1.0),
                ..Inputs::default()
            },
            "cylinder_pressure_pa",
        ),
    ] {
        let err = run.set_inputs(inputs).expect_err(name);
        assert!(err.to_string().contains(name), "{err}");
    }
    let err = run.advance_to(0.05).expect_err("backwards");
    assert!(err.to_string().contains("forward"), "{err}");
    assert_eq!(run.outputs(), before);
    assert_eq!(run.inputs(), Inputs::default());
    // Under the PI drive a torque replaces the controller, but not together with a speed.
    let mut pi = run_of(None, &["drive={kind=\"pi\"}"], &registry);
    let both = Inputs {
        crank_speed_rad_s: Some(300.0),
        drive_torque_nm: Some(5.0),
        ..Inputs::default()
    };
    let err = pi.set_inputs(both).expect_err("both");
    assert!(err.to_string().contains("not both"), "{err}");
}

/// Under the PI drive a torque set from outside drives the crank: more torque, more speed.
#[test]
fn a_drive_torque_set_from_outside_turns_the_crank() {
    let registry = registry();
    let speed_after = |torque: f64| {
        let mut run = run_of(Some("stribeck-duty"), &["drive={kind=\"pi\"}"], &registry);
        run.advance_to(0.5).expect("advance");
        let start = run.outputs().crank_speed_rad_s;
        run.set_inputs(Inputs {
            drive_torque_nm: Some(torque),
            ..Inputs::default()
        })
        .expect("inputs");
        run.advance_to(0.6).expect("advance");
        let out = run.outputs();
        let off = (out.drive_torque_nm - torque).abs();
        assert!(
            off <= 1e-9 * (1.0 + torque.abs()),
            "the torque is the input: {out:?}"
        );
        out.crank_speed_rad_s - start
    };
    let (none, some) = (speed_after(0.0), speed_after(20.0));
    assert!(none < 0.0, "friction alone slows the crank: {none} rad/s");
    assert!(some > none, "{some} vs {none} rad/s");
}

/// The PI drive crossing its torque limit: in the thesis cycle's fast ramps the 5 N m limit is
/// met and left many times a revolution, and the controller's integral stops and restarts there
/// (a jump in its rate). The adaptive integrator ends a step on each crossing
/// (`host/core/src/sim/limit.rs`) instead of crawling across the jump, and the run keeps its
/// tolerance: against the same run at a hundred times tighter `solver.rel_tol`, the plateau
/// torques and energy terms within 1e-5, the mechanical energy at the end within 1e-6 (the
/// final crank phase, which every crossing's timing error would shift).
#[test]
fn a_pi_drive_crossing_its_torque_limit_keeps_the_integrators_accuracy() {
    let registry = registry();
    let drive = "drive={kind=\"pi\",torque_limit_nm=5.0,belt_ratio=1.0}";
    let mut run = run_of(Some("fedem-baseline"), &[drive], &registry);
    let (mut crossings, mut was) = (0_u64, false);
    while run.step().expect("step") {
        let at_limit = (run.outputs().drive_torque_nm.abs() - 5.0).abs() < 1e-9;
        crossings += u64::from(at_limit != was);
        was = at_limit;
    }
    assert!(crossings > 100, "{crossings} crossings of the torque limit");
    let fast = run.result().expect("result");
    let mut tight = run_of(
        Some("fedem-baseline"),
        &[drive, "solver.rel_tol=1e-8"],
        &registry,
    );
    while tight.step().expect("step") {}
    let tight = tight.result().expect("result");
    let rel = |a: f64, b: f64| (a - b).abs() / a.abs().max(b.abs());
    for (p, q) in fast.plateaus.iter().zip(&tight.plateaus) {
        let d = rel(p.motoring_torque_nm, q.motoring_torque_nm);
        assert!(d < 1e-5, "{} rpm: {d:e}", p.set_speed_rpm);
    }
    let (e, f) = (&fast.energy, &tight.energy);
    assert!(rel(e.motor_work_j, f.motor_work_j) < 1e-5);
    assert!(rel(e.dissipated_j, f.dissipated_j) < 1e-5);
    let change = rel(e.mechanical_energy_change_j, f.mechanical_energy_change_j);
    assert!(change < 1e-6, "mechanical energy change {change:e} apart");
}

/// A run's state as plain numbers (`RunState`, what the FMU serialises): taken at 0.3 s of the
/// thesis cycle with a stateful law on the piston (LuGre: its bristle state carried), resumed by
/// another run of the same rig, it continues bit for bit as the run it was taken from after
/// `restart` (the stepper starting afresh there as the resumed one does), under a prescribed
/// crank (Simpson's rule) and under the PI drive (RK4). A state of a rig with other laws, or
/// of the other drive, is refused naming what differs, the run left as it was.
#[test]
fn a_run_state_resumed_by_another_run_continues_bit_for_bit() {
    let registry = registry();
    let lugre = "joints.piston.laws=[{law=\"lugre\", params={mu_c=0.08, mu_s=0.1, sigma2=0.0}}]";
    for drive in ["drive={kind=\"prescribed\"}", "drive={kind=\"pi\"}"] {
        let sets = [lugre, "solver.integrator=\"rk4\""];
        let sets: &[&str] = if drive.contains("pi") {
            &[lugre, drive, sets[1]]
        } else {
            &[lugre, drive]
        };
        let mut run = run_of(None, sets, &registry);
        run.advance_to(0.3).expect("advance");
        let state = run.state();
        assert_eq!(state.time_s(), 0.3);
        let inputs = Inputs {
            oil_temperature_c: Some(95.0),
            ..Inputs::default()
        };
        let go_on = |run: &mut Run| {
            run.set_inputs(inputs).expect("inputs");
            run.advance_to(0.35).expect("advance");
            (run.outputs(), run.laws().expect("laws"))
        };
        run.restart().expect("restart");
        let first = go_on(&mut run);
        let mut other = run_of(None, sets, &registry);
        other.resume(&state).expect("resume");
        assert_eq!(other.time_s(), 0.3);
        let second = go_on(&mut other);
        assert_eq!(first, second, "{drive}");
        // The state's law really moved: the piston dissipated energy.
        assert!(first.0.joints.iter().any(|j| j.energy_j > 0.0));
        // Another law set: other law states; the run keeps its own time.
        let mut plain = run_of(Some("fedem-baseline"), sets, &registry);
        let err = plain.resume(&state).expect_err("other laws");
        assert!(err.to_string().contains("resume"), "{err}");
        assert_eq!(plain.time_s(), 0.0);
    }
}

/// A run started turning (`Simulation::start_turning`, the FMU's torque input from a speed):
/// with no drive torque it slows, the drive does no work, and the crank's kinetic energy goes
/// into friction (and the gas, whose work over whole cycles nets out); it has no test-cycle
/// result to report. A prescribed crank cannot be started turning.
#[test]
fn a_run_started_turning_coasts_down_under_friction() {
    let registry = registry();
    let mut rig = tribo::rig::load_rig(
        Path::new("crf250r-motored"),
        &["drive={kind=\"pi\"}".to_string()],
    )
    .expect("bundled rig");
    tribo::lawset::LawSet::load("fedem-baseline")
        .expect("law set")
        .apply(&mut rig);
    let sim = || tribo::rig::simulation(&rig, &registry).expect("simulation");
    let omega0 = 3000.0 * std::f64::consts::PI / 30.0;
    let mut run = sim().start_turning(omega0).expect("starts turning");
    assert_eq!(run.outputs().crank_speed_rad_s, omega0);
    run.set_inputs(Inputs {
        drive_torque_nm: Some(0.0),
        ..Inputs::default()
    })
    .expect("inputs");
    run.advance_to(0.2).expect("advance");
    let out = run.outputs();
    assert!(out.crank_speed_rad_s < 0.95 * omega0, "{out:?}");
    assert!(out.drive_work_j.abs() < 1e-9, "{out:?}");
    let dissipated: f64 = out.joints.iter().map(|j| j.energy_j).sum();
    assert!(dissipated > 0.0);
    assert!(run.result().is_err());
    let prescribed = tribo::rig::load_rig(Path::new("crf250r-motored"), &[]).expect("rig");
    let err = tribo::rig::simulation(&prescribed, &registry)
        .expect("simulation")
        .start_turning(omega0)
        .err()
        .expect("refused");
    assert!(err.to_string().contains("PI drive"), "{err}");
}
