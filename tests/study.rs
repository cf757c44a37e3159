//! The CRF 250 R study: the main job, the FEDEM baseline against the thesis, calibration of the
//! regime-switching law, and the reduced-mass rod.

mod common;

use std::f64::consts::PI;
use std::path::Path;
use std::process::Command;

use common::*;

const TABLE_10_4: [f64; 7] = [1.01, 1.57, 1.58, 1.35, 1.27, 1.31, 1.50];
const TABLE_10_5: [f64; 7] = [1.01, 1.57, 1.58, 1.35, 1.27, 1.31, 1.50];

#[test]
fn main_job_prints_the_table_and_writes_labelled_svg_plots_from_any_directory() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    // The README's main job, from a directory that is not the checkout (bundled rig and data).
    let out = tribo_in(&["compare", "--out", "results"], dir.path());
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert_mentions(
        &stdout,
        &[
            "measured",
            "fedem-baseline",
            "stribeck-duty",
            "RMSE",
            "max |error|",
            "LOO RMSE",
            "ranked by leave-one-out cross-validated RMSE",
            "per-joint contributions",
        ],
    );
    let results = dir.path().join("results");
    for f in [
        "comparison.csv",
        "scores.csv",
        "validation.csv",
        "comparison.json",
        "torque_vs_speed.svg",
        "contributions_fedem-baseline.svg",
        "contributions_stribeck-duty.svg",
        "piston_regimes.svg",
    ] {
        assert!(results.join(f).is_file(), "{f} not written");
    }
    let svg = std::fs::read_to_string(results.join("torque_vs_speed.svg")).expect("svg");
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    for label in [
        "engine speed (rpm)",
        "motoring torque (N m)",
        "measured",
        "fedem-baseline (RMSE",
        "stribeck-duty (RMSE",
    ] {
        assert!(svg.contains(label), "plot lacks `{label}`");
    }
    let regimes = std::fs::read_to_string(results.join("piston_regimes.svg")).expect("svg");
    assert!(
        regimes.contains("stribeck-duty: mixed") && regimes.contains("time share"),
        "regime plot legend"
    );
    let contrib =
        std::fs::read_to_string(results.join("contributions_stribeck-duty.svg")).expect("svg");
    assert!(
        contrib.contains("piston (stribeck-duty)")
            && contrib.contains("friction torque at the crank (N m)")
    );
    // The JSON carries the same comparison: 7 speeds, measured values of table 10.4.
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(results.join("comparison.json")).expect("json"),
    )
    .expect("parses");
    let measured: Vec<f64> = json["data"]
        .as_array()
        .expect("data")
        .iter()
        .map(|d| d["torque_nm"].as_f64().unwrap_or(f64::NAN))
        .collect();
    assert_eq!(measured, TABLE_10_4);
}

#[test]
fn fedem_baseline_with_the_thesis_pi_drive_reproduces_table_10_5() {
    // docs/crf250r-study.md: the poly-line dampers read as torques at the plateau speed, and a
    // piston assembly of 0.225 kg (the rig's 0.27 kg is an estimate) close the gaps.
    let dir = tempfile::tempdir().expect("temp dir");
    let thesis_pi = "drive={kind=\"pi\", kp=0.05, ki=3.0, torque_limit_nm=5.0}";
    // The thesis's tuned PI drive and the lighter piston, compared against `extra` arguments.
    let compare = |extra: &[&str]| {
        let mut args = vec![
            "compare",
            "--lawset",
            "fedem-baseline",
            "--set",
            thesis_pi,
            "--set",
            "bodies.piston.mass_kg=0.225",
            "--json",
        ];
        args.extend_from_slice(extra);
        json_in(&args, dir.path())
    };
    let json = compare(&["--out", "o"]);
    let model: Vec<f64> = json["sets"][0]["run"]["plateaus"]
        .as_array()
        .expect("plateaus")
        .iter()
        .map(|p| p["motoring_torque_nm"].as_f64().unwrap_or(f64::NAN))
        .collect();
    for (i, (m, t)) in model.iter().zip(TABLE_10_5).enumerate() {
        let rpm = 3000 + 1000 * i;
        if rpm == 4000 {
            // FEDEM's drive reached only 409.308 rad/s here (table 10.5), 2.3% low, where its
            // poly-line gives 0.05 N m less damping; ours holds 4000 rpm. Checked below.
            assert!((m - t).abs() < 0.07, "{rpm} rpm: {m} vs {t}");
        } else {
            assert!((m - t).abs() <= 0.05, "{rpm} rpm: {m} vs table 10.5 {t}");
        }
    }
    // At the speeds FEDEM's drive actually reached (table 10.5), every plateau is within 0.05.
    let data = dir.path().join("fedem-speeds.csv");
    let speeds = [
        308.786, 409.308, 519.495, 630.735, 737.388, 841.448, 943.699,
    ];
    let mut csv = String::from("speed_rpm,torque_nm,oil_temp_c\n");
    for (w, t) in speeds.iter().zip(TABLE_10_5) {
        csv.push_str(&format!("{},{t},80\n", w * 30.0 / PI));
    }
    std::fs::write(&data, csv).expect("write");
    let json = compare(&["--data", data.to_str().expect("utf-8"), "--out", "o2"]);
    let errors: Vec<f64> = json["sets"][0]["errors_nm"]
        .as_array()
        .expect("errors")
        .iter()
        .map(|e| e.as_f64().unwrap_or(f64::NAN))
        .collect();
    assert!(errors.iter().all(|e| e.abs() <= 0.05), "{errors:?}");
}

#[test]
fn calibrated_regime_switching_law_stays_physical_and_compare_agrees() {
    // The calibration is bounded by published ranges (mu_b 0.05-0.15 for boundary-lubricated
    // steel/iron, c 1.8-4 from the slider's Reynolds solution, h_boundary from film parameter 1)
    // with k fixed at the slider's 1/2. With those bounds the law cannot reproduce table 10.4's
    // hump (docs/crf250r-study.md): the test asserts what the calibration must guarantee instead.
    let dir = tempfile::tempdir().expect("temp dir");
    let start = workspace().join("tests/fixtures/lawsets/stribeck-duty-start.toml");
    let fitted = dir.path().join("fitted.toml");
    let fit = json_in(
        &[
            "fit",
            "--lawset",
            start.to_str().expect("utf-8"),
            "--out",
            fitted.to_str().expect("utf-8"),
            "--json",
        ],
        dir.path(),
    );
    let names: Vec<&str> = fit["params"]
        .as_array()
        .expect("params")
        .iter()
        .map(|p| p.as_str().unwrap_or(""))
        .collect();
    assert!(
        names.len() <= 3,
        "{names:?}: at most 3 free parameters for 7 points"
    );
    let values = fit["values"].as_array().expect("values");
    for (name, v) in names.iter().zip(values) {
        let v = v.as_f64().expect("value");
        let (lo, hi) = match name.rsplit('.').next() {
            Some("mu_b") => (0.05, 0.15),
            Some("c") => (1.8, 4.0),
            Some("h_boundary") => (4.3e-8, 5.6e-5),
            other => panic!("unexpected free parameter {other:?}"),
        };
        assert!(
            v >= lo * (1.0 - 1e-9) && v <= hi * (1.0 + 1e-9),
            "{name} = {v} outside its published range [{lo}, {hi}]"
        );
    }
    let rmse = fit["rmse_nm"].as_f64().expect("rmse");
    assert!(rmse.is_finite() && rmse > 0.0);
    // The calibrated law set fed back to compare (full transient cycle) gives the same RMSE.
    let cmp = json_in(
        &[
            "compare",
            "--lawset",
            fitted.to_str().expect("utf-8"),
            "--out",
            "o",
            "--json",
        ],
        dir.path(),
    );
    let rmse_cmp = cmp["sets"][0]["rmse_nm"].as_f64().expect("rmse");
    assert!(
        (rmse_cmp - rmse).abs() < 5e-4,
        "compare {rmse_cmp} vs fit {rmse}"
    );
    // And the bundled law set is this calibration: the same error.
    let cmp = json_in(
        &[
            "compare",
            "--lawset",
            "stribeck-duty",
            "--out",
            "o3",
            "--json",
        ],
        dir.path(),
    );
    let bundled = cmp["sets"][0]["rmse_nm"].as_f64().expect("rmse");
    assert!(
        (bundled - rmse).abs() < 2e-3,
        "bundled {bundled} vs fit {rmse}"
    );
}

/// Steady compare of `lawset` with the seven speeds at one oil temperature: per speed, the
/// motoring torque, the piston's friction torque and the viscosity.
fn steady_at(lawset: &str, temp_c: f64, dir: &Path) -> Vec<(f64, f64, f64)> {
    let speeds: Vec<f64> = (3..=9).map(|k| 1000.0 * k as f64).collect();
    steady_plateaus(dir, lawset, &speeds, temp_c)
        .iter()
        .map(|p| {
            let piston = p["joints"]
                .as_array()
                .and_then(|j| j.iter().find(|x| x["joint"] == "piston"))
                .and_then(|x| x["friction_torque_nm"].as_f64())
                .unwrap_or(f64::NAN);
            (
                p["motoring_torque_nm"].as_f64().unwrap_or(f64::NAN),
                piston,
                p["viscosity_pa_s"].as_f64().unwrap_or(f64::NAN),
            )
        })
        .collect()
}

#[test]
fn mixed_film_law_set_transfers_across_oil_temperature_as_root_viscosity() {
    // Its piston contact is in full film over most of the stroke, where the slider theory gives
    // F = c_h sqrt(eta U W L): from 75 to 85 C the piston friction must fall as sqrt(eta85/eta75)
    // (asperity contact near the dead centres dissipates almost nothing, the bearings' moments
    // do not depend on viscosity), and the total torque must fall, at every speed.
    let dir = tempfile::tempdir().expect("temp dir");
    let (a, b) = (
        steady_at("mixed-film", 75.0, dir.path()),
        steady_at("mixed-film", 85.0, dir.path()),
    );
    assert_eq!(a.len(), 7);
    for ((m75, p75, e75), (m85, p85, e85)) in a.iter().zip(&b) {
        assert!(e85 < e75, "viscosity {e75} -> {e85}");
        let expected = (e85 / e75).sqrt();
        assert!(
            (p85 / p75 - expected).abs() < 0.01 * expected,
            "piston ratio {} vs sqrt(eta ratio) {expected}",
            p85 / p75
        );
        assert!(m85 < m75, "torque rose {m75} -> {m85}");
    }
}

#[test]
fn rod_mass_response_of_coulomb_laws_matches_an_independent_computation() {
    let dir = tempfile::tempdir().expect("temp dir");
    let lawset = dir.path().join("coulomb.toml");
    let mut text = String::from("name = \"coulomb-everywhere\"\n");
    for (joint, mu) in [
        ("main_a", 0.00245),
        ("main_b", 0.00245),
        ("big_end", 0.0025),
        ("small_end", 0.0025),
        ("piston", 0.08),
    ] {
        text.push_str(&format!(
            "[[laws]]\njoint = \"{joint}\"\nlaw = \"coulomb\"\nparams = {{ mu = {mu} }}\n"
        ));
    }
    std::fs::write(&lawset, text).expect("write");
    let (m, l) = (0.1748_f64, 0.105_f64);
    let inertia = format!("bodies.rod.inertia_kg_m2={}", 2.0 / 9.0 * m * l * l);
    let json = json_in(
        &[
            "mass-response",
            "--steady",
            "--lawset",
            lawset.to_str().expect("utf-8"),
            "--scale",
            "0.6",
            "--set",
            "geometry.gravity=false",
            "--set",
            "bodies.rod.com_from_big_end_m=0.035",
            "--set",
            &inertia,
            "--out",
            "o",
            "--json",
        ],
        dir.path(),
    );
    let changes = json[0]["changes"].as_array().expect("changes");
    assert_eq!(changes.len(), 7);
    for c in changes {
        let w = c["speed_rpm"].as_f64().expect("speed") * PI / 30.0;
        let (a, b) = (
            closed_form::friction(w, m),
            closed_form::friction(w, 0.6 * m),
        );
        for (j, joint) in c["joints"].as_array().expect("joints").iter().enumerate() {
            let want = b[j] - a[j];
            let got = joint["change_nm"].as_f64().expect("change");
            assert!(
                (got - want).abs() <= 0.01 * want.abs(),
                "{} rpm {}: {got} vs closed form {want}",
                c["speed_rpm"],
                joint["joint"]
            );
        }
    }
}

#[test]
fn mass_response_is_nonzero_for_load_dependent_laws_and_zero_for_the_damper() {
    let dir = tempfile::tempdir().expect("temp dir");
    let json = json_in(
        &[
            "mass-response",
            "--steady",
            "--lawset",
            "fedem-baseline",
            "--lawset",
            "stribeck-duty",
            "--out",
            "o",
            "--json",
        ],
        dir.path(),
    );
    for set in json.as_array().expect("sets") {
        for c in set["changes"].as_array().expect("changes") {
            for j in c["joints"].as_array().expect("joints") {
                let change = j["change_nm"].as_f64().expect("change");
                if j["law"] == "polyline-damper" {
                    assert_eq!(change, 0.0, "the speed-scheduled damper cannot see mass");
                } else {
                    assert!(
                        change != 0.0 && change < 0.0,
                        "{} {} at {}: {change}",
                        set["lawset"],
                        j["law"],
                        c["speed_rpm"]
                    );
                    assert!(j["normal_load_change_n"].as_f64().expect("load") < 0.0);
                }
            }
            // FEDEM's change (table 10.6 - 10.5) is shown alongside.
            if set["lawset"] == "fedem-baseline" && c["speed_rpm"] == 9000.0 {
                assert!((c["fedem_change_nm"].as_f64().expect("fedem") + 0.02).abs() < 1e-9);
            }
        }
    }
    // The sweep writes its plot.
    let _ = json_in(
        &[
            "mass-response",
            "--steady",
            "--scales",
            "0.5,0.8,1.1",
            "--lawset",
            "fedem-baseline",
            "--out",
            "sweep",
            "--json",
        ],
        dir.path(),
    );
    let svg = std::fs::read_to_string(dir.path().join("sweep/mass_sweep.svg")).expect("plot");
    assert!(svg.contains("rod mass scale (-)") && svg.contains("torque change (N m)"));
}

#[test]
fn steady_state_agrees_with_the_full_cycle_within_half_a_percent() {
    let dir = tempfile::tempdir().expect("temp dir");
    let sets = [
        "--lawset",
        "fedem-baseline",
        "--lawset",
        "stribeck-duty",
        "--lawset",
        "physical-bearings",
    ];
    let transient = json_in(
        &[&["compare", "--out", "t", "--json"][..], &sets].concat(),
        dir.path(),
    );
    let steady = json_in(
        &[&["compare", "--steady", "--out", "s", "--json"][..], &sets].concat(),
        dir.path(),
    );
    for (a, b) in transient["sets"]
        .as_array()
        .expect("sets")
        .iter()
        .zip(steady["sets"].as_array().expect("sets"))
    {
        for (p, q) in a["run"]["plateaus"]
            .as_array()
            .expect("p")
            .iter()
            .zip(b["run"]["plateaus"].as_array().expect("p"))
        {
            let (x, y) = (
                p["motoring_torque_nm"].as_f64().unwrap_or(0.0),
                q["motoring_torque_nm"].as_f64().unwrap_or(1.0),
            );
            assert!(
                (x - y).abs() <= 5e-3 * x.abs(),
                "{} at {}: transient {x} vs steady {y}",
                a["lawset"],
                p["set_speed_rpm"]
            );
        }
    }
}

#[test]
fn results_are_byte_identical_serial_or_parallel_and_run_to_run() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run = |out: &str, threads: Option<&str>| {
        let mut cmd = Command::new(tribo_exe());
        cmd.args(["compare", "--steady"])
            .args(ALL_LAWSETS)
            .args(["--out", out])
            .current_dir(dir.path())
            .env_remove("TRIBO_PLUGIN_PATH");
        if let Some(t) = threads {
            cmd.env("RAYON_NUM_THREADS", t);
        }
        let o = cmd.output().expect("runs");
        assert!(o.status.success(), "{}", text(&o).1);
    };
    ensure_plugins_built();
    run("serial", Some("1"));
    run("parallel", Some("4"));
    run("again", None);
    for f in ["comparison.json", "comparison.csv", "torque_vs_speed.svg"] {
        let a = std::fs::read(dir.path().join("serial").join(f)).expect("read");
        for other in ["parallel", "again"] {
            let b = std::fs::read(dir.path().join(other).join(f)).expect("read");
            assert!(a == b, "{f} differs between serial and {other}");
        }
    }
}

/// The `compare_bundled` example of `tribo-studies` runs the bundled comparison through the
/// libraries alone (no CLI crate) and reports what `tribo compare --steady` reports.
#[test]
fn library_example_runs_the_bundled_comparison_and_agrees_with_the_cli() {
    ensure_plugins_built();
    let exe = build_example("tribo-studies", "compare_bundled");
    let dir = tempfile::tempdir().expect("temp dir");
    let out = Command::new(&exe)
        .arg(profile_dir())
        .current_dir(dir.path())
        .env_remove("TRIBO_PLUGIN_PATH")
        .output()
        .expect("example runs");
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("mode steady"), "{stdout}");

    let out_dir = dir.path().join("cli");
    let cli = json_in(
        &[
            "compare",
            "--steady",
            "--json",
            "--quiet",
            "--out",
            &out_dir.to_string_lossy(),
        ],
        dir.path(),
    );
    let sets = cli["sets"].as_array().expect("sets");
    assert_eq!(sets.len(), 3);
    for s in sets {
        let name = s["lawset"].as_str().expect("name");
        let line = stdout
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("no line for {name} in:\n{stdout}"));
        let fields: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(fields[1], s["rank"].to_string(), "{name}: rank");
        let rmse = s["rmse_nm"].as_f64().expect("rmse");
        assert_eq!(fields[2], format!("{rmse:.4}"), "{name}: RMSE");
    }
    // One row per measured speed: speed, measured torque, one model torque per law set.
    let rows = stdout
        .lines()
        .filter(|l| l.split_whitespace().count() == 5)
        .filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()))
        .count();
    assert_eq!(rows, cli["data"].as_array().expect("data").len());
}
