//! The rig's drivetrain: the modes `tribo modes` reports checked against the chain it prints
//! (independently: the determinant and the residual of `K - w^2 M`), the steady state's forced
//! response against the closed-form receptance of one inertia on one spring, the energy balance
//! with the chain's dampers (steady and transient), the transient cycle settling onto the
//! steady state, and the transducer's rating warnings.

mod common;

use std::f64::consts::TAU;

use common::*;

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

#[test]
fn modes_solve_the_printed_chain() {
    let report = json_in(&["modes", "crf250r-testbed", "--json"], &workspace());
    closed_form::assert_modes_solve(&report);
}

#[test]
fn modes_of_a_rig_without_drivetrain_is_a_clear_error() {
    let out = tribo_in(&["modes", "crf250r-motored"], &workspace());
    let (_, err) = text(&out);
    assert!(!out.status.success());
    assert_mentions(
        &err,
        &["[drivetrain]", "[engine.crankshaft]", "crf250r-testbed"],
    );
}

/// A rig whose crank is one inertia with an unbalance (gravity: a pure first-order torque
/// `m g r cos(theta)`), with negligible reciprocating masses (1e-12 kg: their second-order
/// inertia torque grows with the speed squared, and at 1e-7 kg it already moved the
/// peak-to-peak by 4e-4 at 9000 rpm) and no laws, on one transducer from a prescribed motor.
fn one_spring_rig(dir: &std::path::Path, k: f64, c: f64) -> std::path::PathBuf {
    let text = format!(
        r#"extends = "{base}"
name = "one-spring"
[bodies.crank]
inertia_kg_m2 = 0.004
mass_kg = 1.0
unbalance_mass_kg = 0.1
unbalance_radius_m = 0.02
[bodies.rod]
mass_kg = 1e-12
inertia_kg_m2 = 1e-18
length_m = 0.105
com_from_big_end_m = 0.035
[bodies.piston]
mass_kg = 1e-12
[joints.main_a]
radius_m = 0.02
length_m = 0.015
load_share = 0.5
[joints.main_b]
radius_m = 0.02
length_m = 0.015
load_share = 0.5
[joints.big_end]
radius_m = 0.017
length_m = 0.015
[joints.small_end]
radius_m = 0.008
length_m = 0.015
[joints.piston]
radius_m = 0.0384
length_m = 0.03
[drivetrain.motor]
inertia_kg_m2 = 0.01
[[drivetrain.elements]]
kind = "transducer"
name = "t"
stiffness_nm_per_rad = {k}
damping_nm_s_per_rad = {c}
rated_torque_nm = 5.0
limit_torque_nm = 7.5
oscillation_width_nm = 4.0
cutoff_hz = 1000.0
[drivetrain.daq]
sample_rate_hz = 1200.0
lowpass_hz = 200.0
range_nm = 10.0
record_s = 1.0
"#,
        base = workspace().join("rigs/crf250r-motored.toml").display()
    );
    let path = dir.join("one-spring.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn forced_response_matches_the_receptance_of_one_inertia_on_one_spring() {
    let dir = tempfile::tempdir().unwrap();
    let (k, c) = (290.0, 0.02);
    let rig = one_spring_rig(dir.path(), k, c);
    let run = json_in(
        &["run", rig.to_str().unwrap(), "--steady", "--json"],
        dir.path(),
    );
    // The crank's inertia about its axis with the unbalance, and the unbalance's gravity
    // torque amplitude.
    let (mu, ru) = (0.1, 0.02);
    let j = 0.004 + mu * ru * ru;
    let force = mu * 9.806_65 * ru;
    for p in run["plateaus"].as_array().unwrap() {
        let w = num(&p["set_speed_rpm"]) * TAU / 60.0;
        // Receptance of the crank on the spring, the spring's torque amplitude from it.
        let (re, im) = (k - w * w * j, w * c);
        let x = force / (re * re + im * im).sqrt();
        let torque = x * (k * k + (w * c).powi(2)).sqrt();
        let inst = &p["instrument"];
        let pp = num(&inst["peak_to_peak_nm"]);
        assert!(
            (pp - 2.0 * torque).abs() <= 1e-4 * 2.0 * torque,
            "{w} rad/s: peak-to-peak {pp} against {}",
            2.0 * torque
        );
        let fl = num(&inst["crank_speed_fluctuation"]);
        let expect = 2.0 * x * w / w;
        assert!(
            (fl - expect).abs() <= 1e-4 * expect,
            "speed fluctuation {fl} against {expect}"
        );
        // Frictionless: no mean torque on a periodic cycle (to the RK4 and settling tolerance).
        assert!(
            num(&inst["mean_torque_nm"]).abs() <= 1e-5 * torque,
            "{inst}"
        );
    }
}

/// The bundled test bed's steady run with the FEDEM set (stateless laws: quick).
fn testbed_run() -> serde_json::Value {
    json_in(
        &[
            "run",
            "crf250r-testbed",
            "--lawset",
            "fedem-baseline",
            "--steady",
            "--json",
        ],
        &workspace(),
    )
}

#[test]
fn the_energy_balance_books_the_chains_dampers() {
    let run = testbed_run();
    let e = &run["energy"];
    assert!(num(&e["relative_residual"]) < 1e-7, "{e}");
    // The chain's dampers take their share of the motor's work, beside the laws'.
    let chain: f64 = run["plateaus"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let cycle = 2.0 * std::f64::consts::PI;
            let w = num(&p["mean_speed_rpm"]) * TAU / 60.0;
            num(&p["instrument"]["chain_dissipation_w"]) * cycle / w
        })
        .sum();
    assert!(chain > 0.0);
    // Motor work less the laws' dissipation is the chain's, over periodic cycles.
    let gap = num(&e["motor_work_j"]) - (num(&e["dissipated_j"]) - chain);
    assert!(
        (gap - chain).abs() <= 1e-6 * num(&e["motor_work_j"]),
        "chain {chain} J, gap {gap} J"
    );
}

#[test]
fn a_transducer_outside_its_rating_is_warned_about_at_exactly_those_speeds() {
    let run = testbed_run();
    let warnings: Vec<String> = run["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap_or_default().to_string())
        .collect();
    let mut outside = 0;
    for p in run["plateaus"].as_array().unwrap() {
        let i = &p["instrument"];
        let over = num(&i["peak_to_peak_nm"]) > num(&i["oscillation_width_nm"])
            || num(&i["max_torque_nm"])
                .abs()
                .max(num(&i["min_torque_nm"]).abs())
                > num(&i["limit_torque_nm"]);
        let tag = format!("{:.0} rpm: the transducer", num(&p["set_speed_rpm"]));
        let warned = warnings.iter().any(|w| w.starts_with(&tag));
        assert_eq!(over, warned, "{tag}: outside {over}, warned {warned}");
        outside += usize::from(over);
    }
    assert!(
        outside > 0,
        "the bundled test bed leaves the rating somewhere: {warnings:?}"
    );
}

/// A test bed with long holds and well-damped couplings (damping well above the bundled
/// estimates: a solver check, not a rig), so each hold settles onto its periodic state.
const SETTLING_BED: &str = r#"
extends = "crf250r-motored.toml"
name = "settling-bed"
[oil]
temperature_c = 80.0   # one temperature for both holds
[drive]
kind = "prescribed"
[cycle]
segments = [
  { kind = "ramp", to_rpm = 3000.0, duration_s = 0.5 }, { kind = "hold", duration_s = 2.5 },
  { kind = "ramp", to_rpm = 7000.0, duration_s = 0.5 }, { kind = "hold", duration_s = 2.5 },
]
[drivetrain.motor]
inertia_kg_m2 = 0.0024
[[drivetrain.elements]]
kind = "belt"
name = "belt"
ratio = 2.0
stiffness_nm_per_rad = 280.0
damping_nm_s_per_rad = 0.1
[[drivetrain.elements]]
kind = "inertia"
name = "axle"
inertia_kg_m2 = 1.8e-4
[[drivetrain.elements]]
kind = "transducer"
name = "T22"
stiffness_nm_per_rad = 290.0
damping_nm_s_per_rad = 0.2
rated_torque_nm = 5.0
limit_torque_nm = 7.5
oscillation_width_nm = 4.0
cutoff_hz = 1000.0
[[drivetrain.elements]]
kind = "inertia"
name = "socket"
inertia_kg_m2 = 2.0e-5
[[drivetrain.elements]]
kind = "shaft"
name = "socket on bolt"
stiffness_nm_per_rad = 2000.0
damping_nm_s_per_rad = 0.5
[drivetrain.daq]
sample_rate_hz = 1200.0
lowpass_hz = 200.0
range_nm = 10.0
record_s = 5.0
"#;

/// The settling bed's run (`extra` arguments after the rig and the FEDEM set).
fn settling_run(dir: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    let rig = dir.join("settling-bed.toml");
    std::fs::write(&rig, SETTLING_BED).unwrap();
    let rig = rig.to_string_lossy().into_owned();
    let mut args = vec!["run", rig.as_str(), "--lawset", "fedem-baseline", "--json"];
    args.extend_from_slice(extra);
    json_in(&args, &workspace())
}

#[test]
fn the_transient_cycle_settles_onto_the_steady_state_of_each_hold() {
    let dir = tempfile::tempdir().unwrap();
    let transient = settling_run(dir.path(), &[]);
    let steady = settling_run(dir.path(), &["--steady"]);
    let (tp, sp) = (
        transient["plateaus"].as_array().unwrap(),
        steady["plateaus"].as_array().unwrap(),
    );
    assert_eq!(tp.len(), 2);
    for (t, s) in tp.iter().zip(sp) {
        let (ti, si) = (&t["instrument"], &s["instrument"]);
        // Integrated from rest through the ramps, against the periodic state found by
        // shooting from the chain's harmonic response: two routes to the same orbit.
        for key in [
            "mean_torque_nm",
            "peak_to_peak_nm",
            "max_torque_nm",
            "crank_speed_fluctuation",
        ] {
            let (a, b) = (num(&ti[key]), num(&si[key]));
            let scale = if key == "mean_torque_nm" {
                b.abs()
            } else {
                num(&si["peak_to_peak_nm"]).max(b.abs())
            };
            assert!(
                (a - b).abs() <= 5e-4 * scale,
                "{} rpm {key}: transient {a}, steady {b}",
                num(&t["set_speed_rpm"])
            );
        }
    }
}

#[test]
fn the_transient_cycle_with_a_drivetrain_balances_its_energy() {
    for extra in [&[][..], &["--set", "drive={kind=\"pi\"}"][..]] {
        let mut args = vec![
            "run",
            "crf250r-testbed",
            "--lawset",
            "fedem-baseline",
            "--json",
        ];
        args.extend_from_slice(extra);
        let run = json_in(&args, &workspace());
        let e = &run["energy"];
        // Motor work against the laws' and the chain's dissipation and the energy the chain
        // and the crank hold at the end: conserved to the integration's rounding.
        assert!(num(&e["relative_residual"]) < 1e-8, "{extra:?}: {e}");
        for p in run["plateaus"].as_array().unwrap() {
            let i = &p["instrument"];
            assert!(num(&i["chain_dissipation_w"]) > 0.0, "{i}");
            assert!(num(&i["peak_to_peak_nm"]) > 0.0, "{i}");
        }
    }
}
