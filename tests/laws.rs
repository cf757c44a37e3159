//! Every law of the library as a dynamic plugin: listed by `tribo laws`, and run through the CLI
//! on the reference rig with the law attached (positive dissipation, energy balance).

mod common;

use common::*;

// Gentle enough for the PI drive to follow within its 5 N m limit (J*alpha ~ 2.9 N m) and a
// hold long enough to settle (speed error decays at ~22 1/s), so the plateau is steady.
const SHORT_CYCLE: &str = "cycle.segments=[{kind=\"ramp\", to_rpm=3000, duration_s=0.5}, {kind=\"hold\", duration_s=0.8}]";

/// (law, joint, parameter TOML)
const CASES: [(&str, &str, &str); 9] = [
    ("coulomb", "piston", "mu = 0.08"),
    ("c-coulomb", "piston", "mu = 0.08"),
    ("fedem-friction", "big_end", "mu = 0.0025"),
    (
        "polyline-damper",
        "main_a",
        "c0 = 0.01\nspeeds_rad_s = [314.159, 418.879, 523.599]\nfactors = [0.091, 0.085, 0.073]",
    ),
    (
        "stribeck-duty",
        "piston",
        "mu_b = 0.1\nc = 1.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-4\npreload_n = 30.0",
    ),
    ("petroff-journal", "big_end", "clearance_m = 2e-5"),
    (
        "mixed-film",
        "piston",
        "mu_b = 0.1\nc_h = 1.884\nface_width_m = 1e-3\nsigma_m = 0.3e-6\npreload_n = 220.0",
    ),
    ("rolling-bearing", "main_b", "mu = 0.0011"),
    // The paper's sigma2 = 0.4 s/m per newton is mu ~ 4 at piston speeds; scaled for an engine.
    (
        "lugre",
        "piston",
        "mu_c = 0.05\nmu_s = 0.08\nsigma1 = 1.0\nsigma2 = 0.001",
    ),
];

#[test]
fn every_law_is_listed_as_a_dynamic_plugin() {
    let out = run_tribo(&["laws", "--json"], None);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).expect("json");
    for (law, _, _) in CASES {
        let entry = json["laws"]
            .as_array()
            .and_then(|l| l.iter().find(|x| x["name"] == law))
            .unwrap_or_else(|| panic!("{law} not listed"));
        assert!(entry["abi"] == "rust" || entry["abi"] == "c");
        assert!(std::path::Path::new(entry["file"].as_str().unwrap_or("")).is_file());
    }
}

fn run_with(law: &str, joint: &str, params: &str, extra: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().expect("temp dir");
    let pfile = dir.path().join("params.toml");
    std::fs::write(&pfile, params).expect("write params");
    let rig = workspace().join("rigs/reference-frictionless.toml");
    let attach = format!("{joint}={law}:{}", pfile.display());
    let mut args = vec![
        "run",
        rig.to_str().expect("utf-8"),
        "--law",
        &attach,
        "--set",
        SHORT_CYCLE,
        "--json",
    ];
    for e in extra {
        args.extend(["--set", e]);
    }
    let out = run_tribo(&args, None);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{law}: {stderr}");
    serde_json::from_str(&stdout).expect("json")
}

#[test]
fn every_law_runs_on_the_reference_rig_dissipating_with_energy_balance() {
    for (law, joint, params) in CASES {
        for drive in [None, Some("drive={kind=\"pi\"}")] {
            let json = run_with(law, joint, params, drive.as_slice());
            let p = &json["plateaus"][0];
            let j = &p["joints"][0];
            assert_eq!(j["law"], law);
            assert_eq!(j["joint"], joint);
            let power = j["power_w"].as_f64().expect("power");
            assert!(power > 0.0, "{law}: dissipated power {power}");
            let rel = json["energy"]["relative_residual"]
                .as_f64()
                .expect("residual");
            assert!(rel < 1e-6, "{law} ({:?}): energy residual {rel}", drive);
            // With one law on the rig, the plateau's motoring torque is that law's friction.
            let (m, f) = (
                p["motoring_torque_nm"].as_f64().unwrap_or(0.0),
                j["friction_torque_nm"].as_f64().unwrap_or(0.0),
            );
            assert!(
                (m - f).abs() <= 2e-3 * f.abs(),
                "{law}: motoring {m} vs friction {f}"
            );
        }
    }
}

#[test]
fn stribeck_duty_reports_regimes_on_the_rig() {
    let json = run_with(CASES[4].0, CASES[4].1, CASES[4].2, &[]);
    let share = &json["plateaus"][0]["joints"][0]["regime_share"];
    let total: f64 = ["none", "boundary", "mixed", "hydrodynamic"]
        .iter()
        .map(|k| share[*k].as_f64().unwrap_or(0.0))
        .sum();
    assert!((total - 1.0).abs() < 1e-6, "{share}");
    assert_eq!(
        share["none"].as_f64(),
        Some(0.0),
        "the law always reports a regime"
    );
}

#[test]
fn mixed_film_reports_film_parameter_regimes_on_the_rig() {
    let json = run_with(CASES[6].0, CASES[6].1, CASES[6].2, &[]);
    let share = &json["plateaus"][0]["joints"][0]["regime_share"];
    let get = |k: &str| share[k].as_f64().unwrap_or(0.0);
    let total: f64 = ["none", "boundary", "mixed", "hydrodynamic"]
        .iter()
        .map(|k| get(k))
        .sum();
    assert!((total - 1.0).abs() < 1e-6, "{share}");
    // A 1 mm face at 3000 rpm: a film of several um over 0.3 um roughness at mid-stroke, asperity
    // contact only near the dead centres (film parameter below 3 where the speed is small).
    assert!(
        get("hydrodynamic") > 0.5 && get("boundary") > 0.0,
        "{share}"
    );
}

#[test]
fn fedem_friction_plateau_torques_do_not_depend_on_the_sign_smoothing() {
    // The full thesis cycle with the table 9.5 coefficients, smoothing scale 1 mm/s vs 10 um/s.
    let rig = workspace().join("rigs/reference-frictionless.toml");
    let run = |eps: &str| -> serde_json::Value {
        let laws = [
            format!("joints.main_a.laws=[{{law=\"fedem-friction\", params={{mu=0.00245, v_smooth={eps}}}}}]"),
            format!("joints.main_b.laws=[{{law=\"fedem-friction\", params={{mu=0.00245, v_smooth={eps}}}}}]"),
            format!("joints.big_end.laws=[{{law=\"fedem-friction\", params={{mu=0.0025, v_smooth={eps}}}}}]"),
            format!("joints.piston.laws=[{{law=\"fedem-friction\", params={{mu=0.08, v_smooth={eps}}}}}]"),
        ];
        let mut args = vec!["run", rig.to_str().expect("utf-8"), "--json"];
        for l in &laws {
            args.extend(["--set", l.as_str()]);
        }
        let out = run_tribo(&args, None);
        assert!(out.status.success(), "{}", text(&out).1);
        serde_json::from_str(&text(&out).0).expect("json")
    };
    let (a, b) = (run("1e-3"), run("1e-5"));
    for (p, q) in a["plateaus"]
        .as_array()
        .expect("list")
        .iter()
        .zip(b["plateaus"].as_array().expect("list"))
    {
        let (x, y) = (
            p["motoring_torque_nm"].as_f64().unwrap_or(0.0),
            q["motoring_torque_nm"].as_f64().unwrap_or(1.0),
        );
        assert!(
            (x - y).abs() < 1e-3 * y.abs(),
            "{} rpm: {x} vs {y}",
            p["set_speed_rpm"]
        );
    }
}

#[test]
fn stateless_laws_dissipate_and_their_derivatives_match_finite_differences() {
    use tribo::plugin_api::loader::load_paths;
    use tribo::plugin_api::{JointKind, LawInput};
    ensure_plugins_built();
    let registry = load_paths(&[profile_dir()]).expect("plugins load");
    let mut checked = 0;
    for (law, _, params) in CASES {
        let lib = registry.get(law).expect("law present");
        let inst = lib.create(&params.parse().expect("toml")).expect("creates");
        if inst.state_size() > 0 {
            continue; // F*V <= 0 is a property of stateless laws only (LuGre stores energy)
        }
        checked += 1;
        for kind in [JointKind::Revolute, JointKind::Prismatic] {
            for &v in &[
                -900.0, -12.0, -0.4, -1e-3, -1e-6, 0.0, 1e-6, 1e-3, 0.4, 12.0, 900.0,
            ] {
                for &n in &[0.0, 25.0, 800.0, 15000.0] {
                    for &eta in &[0.004, 0.024, 0.3] {
                        let mut input = LawInput::at_rest(kind);
                        input.normal_load_n = n;
                        input.contact_radius_m = 0.02;
                        input.contact_length_m = 0.015;
                        input.viscosity_pa_s = eta;
                        input.engine_speed_rad_s = 450.0;
                        let at = |v: f64| {
                            inst.evaluate(&input.with_velocity(v), &[])
                                .expect("evaluates")
                        };
                        let out = at(v);
                        assert!(
                            out.force.is_finite() && out.force * v <= 0.0,
                            "{law} {kind:?} v={v} n={n} eta={eta}: F={}",
                            out.force
                        );
                        if let Some(d) = out.derivative() {
                            let h = 1e-7 * (1.0 + v.abs());
                            let fd = (at(v + h).force - at(v - h).force) / (2.0 * h);
                            assert!(
                                (fd - d).abs() <= 1e-4 * (1.0 + d.abs().max(fd.abs())),
                                "{law} {kind:?} v={v} n={n}: dF/dv {d} vs fd {fd}"
                            );
                        }
                    }
                }
            }
        }
    }
    assert_eq!(checked, 8, "every stateless law was swept");
}
