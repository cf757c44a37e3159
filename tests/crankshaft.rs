//! An engine's elastic crankshaft (`[engine.crankshaft]`): the modes `tribo modes` prints solve
//! the chain it prints, a throw's inertia lies between its own and its own plus its whole rod
//! and piston at the crank radius, the steady state converges on the rigid crank's as the
//! shaft stiffens (its error falling with the compliance), and the energy balance closes with
//! the shaft's and the damper's dissipation, steady and over the transient cycle.

mod common;

use common::*;

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// The bundled 4B11's sections (N m/rad) from the front, as inline4-4b11-elastic.toml has them.
const SECTIONS: [f64; 5] = [6.0e5, 3.3e5, 3.3e5, 3.3e5, 6.0e5];

/// The 4B11 with its crankshaft `scale` times as stiff as the bundled elastic one's (its
/// structural damping at the same share of critical), no damper, two plateaus.
fn stiffened(dir: &std::path::Path, scale: f64) -> String {
    let base = workspace().join("rigs/inline4-4b11.toml");
    let sections: Vec<String> = SECTIONS
        .iter()
        .map(|k| {
            format!(
                "{{ stiffness_nm_per_rad = {}, damping_nm_s_per_rad = {} }}",
                k * scale,
                2.0 * scale.sqrt()
            )
        })
        .collect();
    let text = format!(
        r#"extends = "{base}"
name = "stiffened"
[cycle]
segments = [
  {{ kind = "ramp", to_rpm = 2000.0, duration_s = 0.5 }}, {{ kind = "hold", duration_s = 1.0 }},
  {{ kind = "ramp", to_rpm = 7000.0, duration_s = 0.5 }}, {{ kind = "hold", duration_s = 1.0 }},
]
[engine.crankshaft]
flywheel_inertia_kg_m2 = 0.10
pulley_inertia_kg_m2 = 0.004
sections = [{}]
"#,
        sections.join(", "),
        base = base.display()
    );
    let path = dir.join(format!("stiffened-{scale}.toml"));
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

fn steady(rig: &str) -> serde_json::Value {
    json_in(
        &[
            "run",
            rig,
            "--lawset",
            "fedem-baseline",
            "--steady",
            "--json",
        ],
        &workspace(),
    )
}

fn torques(run: &serde_json::Value) -> Vec<f64> {
    run["plateaus"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| num(&p["motoring_torque_nm"]))
        .collect()
}

#[test]
fn the_elastic_crankshafts_modes_solve_its_printed_chain() {
    let report = json_in(
        &["modes", "rigs/inline4-4b11-elastic.toml", "--json"],
        &workspace(),
    );
    let names: Vec<&str> = report["inertias"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["name"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "flywheel",
            "throw 4",
            "throw 3",
            "throw 2",
            "throw 1",
            "front pulley",
            "damper ring"
        ]
    );
    closed_form::assert_modes_solve(&report);
    // The springs carry the rig file's damping (at crank speed: the shaft turns with the
    // crank, so nothing is reflected): 2 N m s/rad per section, 1.3 in the damper's layer.
    let damping: Vec<f64> = report["springs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| num(&s["damping_nm_s_per_rad"]))
        .collect();
    assert_eq!(damping, [2.0, 2.0, 2.0, 2.0, 2.0, 1.3]);
    // A throw's cycle-mean inertia: its own (a quarter of the 0.020 kg m^2 crank and two
    // 0.35 kg counterweights at 45 mm) plus its rod and piston, which move with less than
    // their whole mass (0.55 + 0.40 kg) at the crank radius (43 mm) on average.
    let own = 0.020 / 4.0 + 2.0 * 0.35 * 0.045 * 0.045;
    let most = own + (0.55 + 0.40) * 0.043 * 0.043;
    for node in &report["inertias"].as_array().unwrap()[1..5] {
        let j = num(&node["inertia_kg_m2"]);
        assert!(j > own && j < most, "{node}: {own} < J < {most}");
    }
}

#[test]
fn a_stiffening_crankshaft_converges_on_the_rigid_crank() {
    let dir = tempfile::tempdir().unwrap();
    let rigid = {
        let text = std::fs::read_to_string(stiffened(dir.path(), 1.0)).unwrap();
        let cut = text.find("[engine.crankshaft]").unwrap();
        let path = dir.path().join("rigid.toml");
        std::fs::write(&path, &text[..cut]).unwrap();
        torques(&steady(&path.to_string_lossy()))
    };
    // The shaft's twist, and with it the change of the crank train's motion and friction,
    // scale with its compliance: ten times as stiff, about a tenth of the difference.
    let mut errors = Vec::new();
    for scale in [1.0, 10.0, 100.0] {
        let elastic = torques(&steady(&stiffened(dir.path(), scale)));
        let e = elastic
            .iter()
            .zip(&rigid)
            .map(|(a, b)| ((a - b) / b).abs())
            .fold(0.0, f64::max);
        errors.push(e);
    }
    assert!(
        errors[0] > 1e-3,
        "a soft shaft moves the torque: {errors:?}"
    );
    for w in errors.windows(2) {
        let ratio = w[1] / w[0];
        assert!(ratio > 0.03 && ratio < 0.3, "{errors:?}");
    }
    assert!(errors[2] < 5e-4, "{errors:?}");
}

#[test]
fn the_crank_trains_motoring_torque_is_the_power_its_laws_dissipate() {
    let dir = tempfile::tempdir().unwrap();
    let run = steady(&stiffened(dir.path(), 1.0));
    for p in run["plateaus"].as_array().unwrap() {
        // Over a periodic cycle the throws, rods and pistons return to their state: the power
        // the shaft's sections put into them is what their joints' laws dissipate.
        let omega = num(&p["mean_speed_rpm"]) * std::f64::consts::TAU / 60.0;
        let laws: f64 = p["joints"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| num(&j["power_w"]))
            .sum();
        let torque = num(&p["motoring_torque_nm"]);
        assert!(
            (torque * omega - laws).abs() <= 1e-6 * laws,
            "{} rpm: {torque} N m x {omega} rad/s against {laws} W",
            num(&p["set_speed_rpm"])
        );
    }
}

#[test]
fn the_elastic_crankshaft_balances_its_energy_steady_and_over_the_cycle() {
    let cycle = |extra: &[&str]| {
        let mut args = vec![
            "run",
            "rigs/inline4-4b11-elastic.toml",
            "--lawset",
            "fedem-baseline",
            "--json",
        ];
        args.extend_from_slice(extra);
        json_in(&args, &workspace())
    };
    for run in [
        cycle(&["--steady"]),
        cycle(&[]),
        // PI gains scaled to the flywheel's 0.1 kg m^2 (the defaults suit the CRF's
        // 0.005 kg m^2 crank), its limit the rigid 4B11's in the regression cases.
        cycle(&[
            "--set",
            "drive={kind=\"pi\", kp=6.0, ki=240.0, torque_limit_nm=400.0}",
        ]),
    ] {
        let e = &run["energy"];
        // Motor work against the laws', the shaft's and the damper's dissipation and the
        // energy the shaft, the damper and the crank train hold: conserved to rounding.
        assert!(num(&e["relative_residual"]) < 1e-7, "{e}");
        assert!(num(&e["motor_work_j"]) > 0.0, "{e}");
    }
}
