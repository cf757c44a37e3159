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
    // The verdict, in words, above the ranking; and every line fits 100 columns.
    let verdict = stdout
        .lines()
        .position(|l| l.starts_with("Verdict: "))
        .unwrap_or_else(|| panic!("no `Verdict:` line in:\n{stdout}"));
    let ranking = stdout
        .lines()
        .position(|l| l.starts_with("scores, ranked by"))
        .expect("ranking");
    assert!(verdict < ranking, "the verdict comes before the ranking");
    for line in stdout.lines() {
        assert!(
            line.chars().count() <= 100,
            "{} columns: {line}",
            line.chars().count()
        );
    }
    // A page a person reads: at most 100 lines, and no number printed as a negative zero.
    let lines = stdout.lines().count();
    assert!(
        lines <= 100,
        "the main job printed {lines} lines:\n{stdout}"
    );
    for word in stdout.split(|c: char| c.is_whitespace() || c == '(' || c == ',') {
        let digits = word.trim_end_matches(['%', 'x', ')', ';', ',']);
        if let Some(rest) = digits.strip_prefix('-') {
            assert!(
                rest.is_empty() || !rest.chars().all(|c| c == '0' || c == '.'),
                "negative zero `{word}` in:\n{stdout}"
            );
        }
    }
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
    // Read back: no tick or label of any plot reads as a negative zero.
    for entry in std::fs::read_dir(&results).expect("results") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "svg") {
            let svg = std::fs::read_to_string(&path).expect("svg");
            for text in svg.split('>').filter_map(|t| t.split('<').next()) {
                let t = text.trim();
                assert!(
                    !(t.starts_with('-')
                        && t.len() > 1
                        && t[1..].chars().all(|c| c == '0' || c == '.')),
                    "{}: `{t}`",
                    path.display()
                );
            }
        }
    }
    let svg = std::fs::read_to_string(results.join("torque_vs_speed.svg")).expect("svg");
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    for label in [
        "crank speed (rpm)",
        "motoring torque (N m)",
        "measured",
        ">\nfedem-baseline\n<",
        ">\nstribeck-duty\n<",
        "RMSE ",
    ] {
        assert!(svg.contains(label), "plot lacks `{label}`");
    }
    let regimes = std::fs::read_to_string(results.join("piston_regimes.svg")).expect("svg");
    assert!(
        regimes.contains("stribeck-duty: mixed") && regimes.contains("share of the cycle"),
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
    // Two sets whose leave-one-out errors are within 1e-3 N m cannot be told apart by these
    // data: they share a place and the text says they are indistinguishable.
    let sets = json["sets"].as_array().expect("sets");
    for (i, a) in sets.iter().enumerate() {
        for b in &sets[i + 1..] {
            let (Some(ea), Some(eb)) = (
                a["scores"]["cv_rmse_nm"].as_f64(),
                b["scores"]["cv_rmse_nm"].as_f64(),
            ) else {
                continue;
            };
            if (ea - eb).abs() <= 1e-3 {
                let (na, nb) = (a["lawset"].as_str(), b["lawset"].as_str());
                assert_eq!(a["rank"], b["rank"], "{na:?} and {nb:?} tied");
                let tied_line = stdout.lines().find(|l| {
                    l.contains("indistinguishable")
                        && l.contains(na.unwrap_or("?"))
                        && l.contains(nb.unwrap_or("?"))
                });
                assert!(
                    tied_line.is_some(),
                    "{na:?}, {nb:?} not called indistinguishable:\n{stdout}"
                );
            }
        }
    }
}

/// A regression test of the calibration, not a validation: table 10.5 equals table 10.4, the
/// measurements the thesis tuned its FEDEM model to, and the piston mass here was chosen to
/// match them. It guards the rebuilt model against drifting from what it was tuned to; what was
/// not tuned is checked by `light_rod_change_of_the_fedem_baseline_against_table_10_6_minus_10_5`.
#[test]
fn regression_fedem_baseline_with_the_thesis_pi_drive_stays_on_table_10_5_it_was_tuned_to() {
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

/// Validation with what the calibration never saw: the thesis ran its tuned model again with a
/// rod at 60% mass (table 10.6). Its change, table 10.6 minus 10.5, is known to 0.01 N m (both
/// tables are rounded to 0.01). The rebuilt model must agree in what the physics fixes: a lighter
/// rod lowers every joint reaction, so the torque falls at every speed, and the inertia loads
/// grow with speed, so the fall does not shrink as the speed rises. The size does not agree: the
/// rebuilt Coulomb friction falls up to 0.18 N m where FEDEM's fell 0.02 (a finding explained in
/// docs/crf250r-study.md, "The reduced-mass rod"; the per-joint size is checked against closed
/// form by `rod_mass_response_of_coulomb_laws_matches_an_independent_computation`).
#[test]
fn light_rod_change_of_the_fedem_baseline_against_table_10_6_minus_10_5() {
    const TABLE_10_6: [f64; 7] = [1.01, 1.57, 1.57, 1.34, 1.25, 1.29, 1.48];
    let dir = tempfile::tempdir().expect("temp dir");
    let json = json_in(
        &[
            "mass-response",
            "--steady",
            "--lawset",
            "fedem-baseline",
            "--set",
            "bodies.piston.mass_kg=0.225",
            "--body",
            "rod",
            "--scale",
            "0.6",
            "--out",
            "mr",
            "--json",
        ],
        dir.path(),
    );
    let changes = json[0]["changes"].as_array().expect("changes");
    assert_eq!(
        changes.len(),
        TABLE_10_5.len(),
        "one change per plateau of table 10.5"
    );
    let mut previous = 0.0_f64;
    for (i, c) in changes.iter().enumerate() {
        let rpm = 3000.0 + 1000.0 * i as f64;
        assert_eq!(c["speed_rpm"].as_f64(), Some(rpm));
        let thesis = TABLE_10_6[i] - TABLE_10_5[i];
        let shown = c["fedem_change_nm"]
            .as_f64()
            .expect("the thesis's change is shown");
        assert!(
            (shown - thesis).abs() < 1e-9,
            "{rpm} rpm: shown {shown}, table {thesis}"
        );
        // The thesis's own change never rose (to its rounding): a lighter rod never cost torque.
        assert!(thesis <= 0.005, "{rpm} rpm: {thesis}");
        let change = c["change_nm"].as_f64().expect("change");
        assert!(
            change < 0.0,
            "{rpm} rpm: a lighter rod raised the torque by {change}"
        );
        assert!(
            change <= previous + 1e-9,
            "{rpm} rpm: the fall {change} is smaller than at the speed below ({previous})"
        );
        previous = change;
    }
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

/// The out-of-sample errors of a set in a comparison's JSON, point by point.
fn f64_list(v: &serde_json::Value) -> Vec<Option<f64>> {
    v.as_array()
        .expect("array")
        .iter()
        .map(serde_json::Value::as_f64)
        .collect()
}

#[test]
fn compare_fits_every_set_before_it_ranks_and_no_fit_is_labelled_everywhere() {
    // A fitted set minimises its in-sample error; leaving a point out can only make that point
    // worse: with both fits at their optimum, |LOO error| >= |in-sample error| at every point
    // (the full fit is no worse on all points than the fold's values, the fold no worse on the
    // others than the full fit's). A violation means a fit stopped short of its optimum.
    let dir = tempfile::tempdir().expect("temp dir");
    let start = workspace().join("tests/fixtures/lawsets/stribeck-duty-start.toml");
    let start = start.to_str().expect("utf-8");
    std::fs::write(
        dir.path().join("user.toml"),
        "name = \"user\"\n[[laws]]\njoint = \"main_*\"\nlaw = \"rolling-bearing\"\nparams = { mu = 0.0011 }\n\
         [[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\nparams = { mu = 0.3, c_viscous = 0.0 }\nfree = { mu = [0.01, 0.5], c_viscous = [0.0, 2.0] }\n",
    )
    .expect("write");
    let sets = [
        "--lawset",
        start,
        "--lawset",
        "mixed-film",
        "--lawset",
        "user.toml",
    ];
    let run = |extra: &[&str], out: &str| {
        let mut args = vec!["compare", "--steady", "--out", out, "--json"];
        args.extend_from_slice(&sets);
        args.extend_from_slice(extra);
        json_in(&args, dir.path())
    };
    let fitted = run(&[], "fitted");
    let as_is = run(&["--no-fit"], "as-is");
    for (s, u) in fitted["sets"]
        .as_array()
        .expect("sets")
        .iter()
        .zip(as_is["sets"].as_array().expect("sets"))
    {
        let name = s["lawset"].as_str().expect("name");
        assert_eq!(s["calibration"]["status"], "fitted", "{name}");
        let rmse = s["rmse_nm"].as_f64().expect("rmse");
        let loo = s["scores"]["cv_rmse_nm"].as_f64().expect("loo");
        assert!(rmse <= loo + 1e-9, "{name}: in sample {rmse} > LOO {loo}");
        let errors = f64_list(&s["errors_nm"]);
        for (i, (e, l)) in errors
            .iter()
            .zip(f64_list(&s["scores"]["cv_errors_nm"]))
            .enumerate()
        {
            let (e, l) = (e.expect("error"), l.expect("LOO error"));
            assert!(
                l.abs() >= e.abs() - 1e-6,
                "{name}, point {i}: LOO error {l} smaller than the fitted error {e}"
            );
        }
        // Fitting never does worse than the file's values.
        let file_rmse = u["rmse_nm"].as_f64().expect("rmse");
        assert!(rmse <= file_rmse + 1e-12, "{name}: {rmse} vs {file_rmse}");
    }
    // The start fixture and the user's set begin away from their optimum: compare moved them.
    for k in [0, 2] {
        let (a, b) = (
            fitted["sets"][k]["rmse_nm"].as_f64().expect("rmse"),
            as_is["sets"][k]["rmse_nm"].as_f64().expect("rmse"),
        );
        assert!(
            a < 0.9 * b,
            "{}: fitted {a} vs as is {b}",
            fitted["sets"][k]["lawset"]
        );
    }
    // The same calibration as `tribo fit`: the same values and error.
    let fit = json_in(
        &[
            "fit", "--lawset", start, "--no-cv", "--out", "f.toml", "--json",
        ],
        dir.path(),
    );
    let values = f64_list(&fit["values"]);
    let params = fitted["sets"][0]["calibration"]["params"]
        .as_array()
        .expect("params");
    assert_eq!(params.len(), values.len());
    for (p, v) in params.iter().zip(&values) {
        let (a, b) = (p["value"].as_f64().expect("value"), v.expect("value"));
        assert!(
            (a - b).abs() <= 1e-12 * b.abs(),
            "{}: {a} vs fit {b}",
            p["id"]
        );
    }
    // Not fitted: labelled so in every output, and scored as it is.
    let u = &as_is["sets"][0];
    assert_eq!(u["calibration"]["status"], "not fitted");
    assert_eq!(u["scores"]["cv_rmse_nm"], u["rmse_nm"]);
    assert!(u["fitted_lawset_toml"].is_null());
    let scores = std::fs::read_to_string(dir.path().join("as-is/scores.csv")).expect("csv");
    let mut r = csv::Reader::from_reader(scores.as_bytes());
    let col = r
        .headers()
        .expect("headers")
        .iter()
        .position(|h| h == "calibration")
        .expect("calibration column");
    let rows: Vec<csv::StringRecord> = r.records().map(|x| x.expect("row")).collect();
    assert_eq!(rows.len(), 3);
    assert!(rows.iter().all(|x| &x[col] == "not fitted"), "{scores}");
    let svg = std::fs::read_to_string(dir.path().join("as-is/torque_vs_speed.svg")).expect("svg");
    assert!(
        svg.contains("not fitted"),
        "the plot's legend says not fitted"
    );
    let out = tribo_in(
        &[
            &["compare", "--steady", "--no-fit", "--out", "as-is"][..],
            &sets,
        ]
        .concat(),
        dir.path(),
    );
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert_mentions(
        &stdout,
        &["stribeck-duty-start (not fitted)", "user (not fitted)"],
    );
    // A fitted set's values are written beside the results, and they give its error.
    let toml = dir.path().join("fitted/fitted_stribeck-duty-start.toml");
    assert!(toml.is_file());
    let again = json_in(
        &[
            "compare",
            "--steady",
            "--no-fit",
            "--lawset",
            toml.to_str().expect("utf-8"),
            "--out",
            "again",
            "--json",
        ],
        dir.path(),
    );
    let (a, b) = (
        again["sets"][0]["rmse_nm"].as_f64().expect("rmse"),
        fitted["sets"][0]["rmse_nm"].as_f64().expect("rmse"),
    );
    assert!((a - b).abs() <= 1e-9 * b, "{a} vs {b}");
}

#[test]
fn data_belong_to_their_rig_and_a_rig_without_measurements_asks_for_them() {
    let dir = tempfile::tempdir().expect("temp dir");
    let fails = |args: &[&str], words: &[&str]| {
        let out = tribo_in(args, dir.path());
        let (_, stderr) = text(&out);
        assert!(!out.status.success(), "{args:?} ran");
        assert_mentions(&stderr, words);
    };
    // The engine has no bundled measurements: nothing is compared silently.
    fails(
        &["compare", "inline4-4b11"],
        &["inline4-4b11", "no bundled measurements", "--data"],
    );
    fails(
        &["fit", "inline4-4b11", "--lawset", "stribeck-duty"],
        &["inline4-4b11", "no bundled measurements"],
    );
    // The CRF 250 R's measurements declare their rig.
    fails(
        &["compare", "inline4-4b11", "--data", "crf250r-measured.csv"],
        &["crf250r-motored", "inline4-4b11", "--data-for-any-rig"],
    );
    // Told they apply, the speeds above the engine's top speed are still refused.
    fails(
        &[
            "compare",
            "inline4-4b11",
            "--data",
            "crf250r-measured.csv",
            "--data-for-any-rig",
        ],
        &["8000 rpm", "top speed", "max_speed_rpm = 7000"],
    );
    fails(
        &[
            "sweep",
            "inline4-4b11",
            "--speeds",
            "3000,9000",
            "--temps",
            "80",
        ],
        &["--speeds", "9000 rpm", "max_speed_rpm = 7000"],
    );
    // A user's file naming another rig is refused, and accepted when told it applies.
    let data = dir.path().join("light.csv");
    std::fs::write(
        &data,
        "# rig: crf250r-light-rod\nspeed_rpm,torque_nm,oil_temp_c\n3000,0.9,80\n6000,1.2,80\n9000,1.4,80\n",
    )
    .expect("write");
    let data = data.to_str().expect("utf-8");
    let args = [
        "compare",
        "--steady",
        "--no-cv",
        "--lawset",
        "physical-bearings",
        "--data",
        data,
        "--json",
    ];
    fails(&args, &["crf250r-light-rod", "crf250r-motored"]);
    let ok = json_in(&[&args[..], &["--data-for-any-rig"]].concat(), dir.path());
    assert_eq!(ok["data"].as_array().expect("data").len(), 3);
    // A declared noise must be a positive number, reported at its line.
    let bad = dir.path().join("bad.csv");
    std::fs::write(
        &bad,
        "# a comment\n# noise_nm: -0.1\nspeed_rpm,torque_nm,oil_temp_c\n3000,1,80\n",
    )
    .expect("write");
    fails(
        &["compare", "--data", bad.to_str().expect("utf-8")],
        &["bad.csv:2", "noise_nm", "positive"],
    );
}

#[test]
fn a_run_without_laws_warns_and_require_laws_refuses_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run = json_in(
        &["run", "reference-frictionless", "--steady", "--json"],
        dir.path(),
    );
    let warnings = run["warnings"].to_string();
    assert!(warnings.contains("no law on any joint"), "{warnings}");
    // The energy line: the residual of a frictionless run is roundoff on the mechanism's
    // energy, not a ratio of two roundoff errors.
    let e = &run["energy"];
    assert!(e["motor_work_j"].as_f64().expect("work").abs() < 1e-6);
    let rel = e["relative_residual"].as_f64().expect("relative");
    assert!(rel < 1e-9, "relative residual {rel}");
    let out = tribo_in(&["run", "reference-frictionless", "--steady"], dir.path());
    let (stdout, _) = text(&out);
    assert!(stdout.contains("warning: no law on any joint"), "{stdout}");
    let out = tribo_in(
        &[
            "run",
            "reference-frictionless",
            "--steady",
            "--require-laws",
        ],
        dir.path(),
    );
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert_mentions(
        &stderr,
        &["--require-laws", "reference-frictionless", "no law"],
    );
    // With laws there is nothing to warn about.
    let run = json_in(
        &[
            "run",
            "reference-frictionless",
            "--steady",
            "--lawset",
            "physical-bearings",
            "--require-laws",
            "--json",
        ],
        dir.path(),
    );
    assert!(!run["warnings"].to_string().contains("no law on any joint"));
}

#[test]
fn bands_of_a_positive_torque_stay_above_zero_and_a_missing_band_says_why() {
    // Data the one-parameter Coulomb set cannot follow (a torque at 3000 rpm fifty times the
    // others): its coefficient is poorly determined, and the linear band's half-width exceeds
    // the torque itself, so `T - h` would be below zero.
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(
        dir.path().join("odd.csv"),
        "speed_rpm,torque_nm,oil_temp_c\n3000,1.5,80\n4000,0.02,80\n5000,0.02,80\n6000,0.02,80\n7000,0.02,80\n8000,0.02,80\n9000,0.02,80\n",
    )
    .expect("write");
    std::fs::write(
        dir.path().join("one.toml"),
        "name = \"one\"\n[[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\nparams = { mu = 0.05 }\nfree = { mu = [0.001, 0.5] }\n",
    )
    .expect("write");
    let args = [
        "compare",
        "--steady",
        "--no-cv",
        "--lawset",
        "one.toml",
        "--lawset",
        "mixed-film",
        "--lawset",
        "physical-bearings",
        "--data",
        "odd.csv",
        "--out",
        "o",
    ];
    let cmp = json_in(&[&args[..], &["--json"]].concat(), dir.path());
    let one = &cmp["sets"][0];
    let model: Vec<f64> = one["run"]["plateaus"]
        .as_array()
        .expect("plateaus")
        .iter()
        .map(|p| p["motoring_torque_nm"].as_f64().expect("torque"))
        .collect();
    let half = f64_list(&one["uncertainty"]["band_half_width_nm"]);
    let (lo, hi) = (
        f64_list(&one["band_lower_nm"]),
        f64_list(&one["band_upper_nm"]),
    );
    assert!(
        half.iter().zip(&model).any(|(h, t)| h.expect("h") > *t),
        "the linear band should reach below zero somewhere: {half:?} vs {model:?}"
    );
    for i in 0..model.len() {
        let (l, u, t) = (lo[i].expect("lower"), hi[i].expect("upper"), model[i]);
        assert!(l > 0.0 && l <= t && t <= u, "{l} {t} {u}");
        assert!(
            (l * u - t * t).abs() <= 1e-9 * t * t,
            "log band: {l} * {u} vs {t}^2"
        );
    }
    // Every set either has a band or says why not; never a "wider than data" without a band.
    for s in cmp["sets"].as_array().expect("sets") {
        let band = !s["band_lower_nm"].is_null();
        assert_eq!(band, s["band_note"].is_null(), "{}", s["lawset"]);
        assert_eq!(
            band,
            !s["band_wider_than_data"].is_null(),
            "{}",
            s["lawset"]
        );
    }
    let scores = std::fs::read_to_string(dir.path().join("o/scores.csv")).expect("csv");
    let mut r = csv::Reader::from_reader(scores.as_bytes());
    let h = r.headers().expect("headers").clone();
    let (w, n) = (
        h.iter()
            .position(|x| x == "band_wider_than_data")
            .expect("col"),
        h.iter().position(|x| x == "band_note").expect("col"),
    );
    for row in r.records() {
        let row = row.expect("row");
        assert_eq!(row[w].is_empty(), !row[n].is_empty(), "{scores}");
    }
    let out = tribo_in(&args, dir.path());
    let (stdout, _) = text(&out);
    assert_mentions(
        &stdout,
        &["no band for physical-bearings: no free parameters"],
    );
}

#[test]
fn reports_fit_100_columns_and_say_their_units_files_and_defaults() {
    let dir = tempfile::tempdir().expect("temp dir");
    let fits = |args: &[&str]| -> String {
        let out = tribo_in(args, dir.path());
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{args:?}: {stderr}");
        for line in stdout.lines() {
            assert!(line.chars().count() <= 100, "{args:?}: {line}");
        }
        stdout
    };
    fits(&["laws"]);
    fits(&[
        "run",
        "inline4-4b11",
        "--steady",
        "--lawset",
        "stribeck-duty",
    ]);
    fits(&[
        "fit",
        "--lawset",
        "stribeck-duty",
        "--no-cv",
        "--out",
        "f.toml",
    ]);
    fits(&[
        "sweep",
        "--lawset",
        "mixed-film",
        "--temps",
        "40,50,60,70,80,90,100,110",
    ]);
    let mass = fits(&[
        "mass-response",
        "--steady",
        "--lawset",
        "fedem-baseline",
        "--out",
        "mr",
    ]);
    assert_mentions(
        &mass,
        &[
            "rod mass and inertia scaled; motoring torque and its change, N m",
            "FEDEM thesis (T 10.6-10.5): the change the thesis's own FEDEM model gave",
            "wrote into mr: mass_response.json",
        ],
    );
    // Each study's --help names the law sets it runs without --lawset.
    for cmd in ["compare", "mass-response", "sweep"] {
        let help = fits(&[cmd, "--help"]).replace('\n', " ");
        for set in tribo::bundled::DEFAULT_LAWSETS {
            assert!(help.contains(set), "`{cmd} --help` does not name {set}");
        }
    }
    // The FMEP plot: crank speed along x, and each component its own colour.
    fits(&[
        "run",
        "crf250r-motored",
        "--steady",
        "--lawset",
        "fedem-baseline",
        "--fmep",
        "fmep",
    ]);
    // The correlation tables beside Tribo: an engine's run (long notes on the terms no law
    // models) and a comparison of more sets than fit side by side.
    fits(&[
        "run",
        "inline4-4b11",
        "--steady",
        "--lawset",
        "4b11-physical",
        "--fmep",
        "fmep4",
    ]);
    fits(&[
        "compare",
        "--lawset",
        "fedem-baseline",
        "--lawset",
        "stribeck-duty",
        "--lawset",
        "mixed-film",
        "--lawset",
        "physical-bearings",
    ]);
    let svg = std::fs::read_to_string(dir.path().join("fmep/fmep.svg")).expect("svg");
    assert!(svg.contains("crank speed (rpm)") && svg.contains("FMEP (kPa)"));
    let colours: std::collections::BTreeSet<&str> = svg
        .split("stroke=\"")
        .skip(1)
        .filter_map(|s| s.get(..7))
        .filter(|c| c.starts_with('#'))
        .collect();
    for joint in ["main_a", "main_b", "big_end", "piston"] {
        assert!(svg.contains(joint), "{joint} missing from the FMEP plot");
    }
    assert!(colours.len() >= 5, "{colours:?}");
}

/// Plateau motoring torques of every set of a comparison's JSON, by set name.
fn set_torques(cmp: &serde_json::Value) -> Vec<(String, Vec<f64>)> {
    cmp["sets"]
        .as_array()
        .expect("sets")
        .iter()
        .map(|s| {
            let torques = s["run"]["plateaus"]
                .as_array()
                .expect("plateaus")
                .iter()
                .map(|p| p["motoring_torque_nm"].as_f64().expect("torque"))
                .collect();
            (s["lawset"].as_str().expect("name").to_string(), torques)
        })
        .collect()
}

#[test]
fn compare_law_adds_one_set_on_its_base_and_leaves_the_bundled_sets_untouched() {
    let dir = tempfile::tempdir().expect("temp dir");
    let run = |extra: &[&str], out: &str| {
        let mut args = vec!["compare", "--steady", "--no-cv", "--out", out, "--json"];
        args.extend_from_slice(extra);
        set_torques(&json_in(&args, dir.path()))
    };
    let without = run(&[], "without");
    let with = run(&["--law", "piston=coulomb"], "with");
    assert_eq!(with.len(), without.len() + 1, "one more set");
    for ((name, before), (name_with, after)) in without.iter().zip(&with) {
        assert_eq!(name, name_with);
        for (b, a) in before.iter().zip(after) {
            assert!((a - b).abs() <= 1e-9, "{name}: {b} became {a} with --law");
        }
    }
    // The new set is the first set (fedem-baseline) with Coulomb on the piston instead of its
    // own piston law: the same set written out by hand gives the same torques.
    let baseline = std::fs::read_to_string(workspace().join("rigs/lawsets/fedem-baseline.toml"))
        .expect("read");
    let piston = baseline.rfind("[[laws]]").expect("a last law entry");
    assert!(
        baseline[piston..].contains("joint = \"piston\""),
        "the last entry is the piston's"
    );
    let by_hand = format!(
        "{}[[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\n",
        baseline[..piston]
            .replace("name = \"fedem-baseline\"", "name = \"by-hand\"")
            .lines()
            .filter(|l| !l.starts_with("prior_fit"))
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"
    );
    std::fs::write(dir.path().join("by-hand.toml"), by_hand).expect("write");
    let hand = run(&["--lawset", "by-hand.toml"], "hand");
    let (name, added) = with.last().expect("the new set");
    assert_eq!(name, "coulomb", "named after the law");
    for (h, a) in hand[0].1.iter().zip(added) {
        assert!((h - a).abs() <= 1e-9, "by hand {h}, --law {a}");
    }
    // And it is a different model from its base: the piston's law changed.
    assert!(added
        .iter()
        .zip(&without[0].1)
        .any(|(a, b)| (a - b).abs() > 1e-3));
    // --base and --name choose the base and the name.
    let named = run(
        &[
            "--law",
            "piston=coulomb",
            "--base",
            "stribeck-duty",
            "--name",
            "sd-coulomb",
        ],
        "named",
    );
    assert_eq!(named.last().expect("set").0, "sd-coulomb");
    assert_eq!(named.len(), without.len() + 1);
    // A name taken by another set is refused, saying how to rename.
    let clash = tribo_in(
        &[
            "compare",
            "--steady",
            "--no-cv",
            "--law",
            "piston=coulomb",
            "--name",
            "mixed-film",
        ],
        dir.path(),
    );
    assert!(!clash.status.success());
    assert!(text(&clash).1.contains("--name"), "{}", text(&clash).1);
}

#[test]
fn mass_response_sweep_prints_a_speed_by_scale_table_of_percent_change_and_a_csv() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = tribo_in(
        &[
            "mass-response",
            "--steady",
            "--scales",
            "0.6,0.8,1.0",
            "--lawset",
            "fedem-baseline",
            "--out",
            "m",
        ],
        dir.path(),
    );
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.lines().count() <= 20,
        "a table, not a listing:\n{stdout}"
    );
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("m/mass_response.json")).expect("json"),
    )
    .expect("parses");
    let changes = json[0]["changes"].as_array().expect("changes");
    // Each table row: rpm, the torque at scale 1, then the change in % per scale factor,
    // which must be 100 (scaled - original) / original of the JSON's torques.
    for rpm in [3000.0, 6000.0, 9000.0] {
        let row = stdout
            .lines()
            .find(|l| l.split_whitespace().next() == Some(&format!("{rpm:.0}")))
            .unwrap_or_else(|| panic!("no row for {rpm} rpm:\n{stdout}"));
        let cells: Vec<f64> = row
            .split_whitespace()
            .skip(2)
            .map(|c| c.parse().expect("a number"))
            .collect();
        for (cell, scale) in cells.iter().zip([0.6, 0.8, 1.0]) {
            let c = changes
                .iter()
                .find(|c| {
                    c["speed_rpm"].as_f64() == Some(rpm) && c["scale"].as_f64() == Some(scale)
                })
                .expect("change");
            let (o, s) = (
                c["original_nm"].as_f64().expect("o"),
                c["scaled_nm"].as_f64().expect("s"),
            );
            let percent = 100.0 * (s - o) / o;
            assert!(
                (cell - percent).abs() <= 0.006,
                "{rpm} rpm x{scale}: {cell} vs {percent}"
            );
        }
        // A lighter rod loads the joints less: the torque falls (the thesis's table 10.6).
        assert!(cells[0] < cells[1] && cells[1] < 1e-9, "{row}");
    }
    let csv = std::fs::read_to_string(dir.path().join("m/mass_response.csv")).expect("csv");
    assert!(csv
        .starts_with("lawset,body,scale,speed_rpm,original_nm,scaled_nm,change_nm,change_percent"));
    assert_eq!(
        csv.lines().count(),
        1 + 3 * changes.len() / 3,
        "a row per scale and speed"
    );
}

/// A set that leaves joints without a law the other sets cover is flagged in the ranking: the
/// text names the joints, and comparison.json lists them for that set only. The joints
/// expected are worked out here from the sets' own law lists in the JSON: every joint with a
/// law in fedem-baseline but not in the piston-only set.
#[test]
fn a_set_leaving_joints_without_a_law_is_flagged_in_the_ranking() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(
        dir.path().join("piston-only.toml"),
        "name = \"piston-only\"\ndescription = \"Coulomb on the piston, nothing on the bearings\"\n\n[[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\nparams = { mu = 0.05 }\n",
    )
    .expect("write law set");
    let args =
        "compare --steady --no-cv --lawset fedem-baseline --lawset piston-only.toml --out cmp";
    let out = tribo_in(&args.split(' ').collect::<Vec<_>>(), dir.path());
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("cmp/comparison.json")).expect("json"),
    )
    .expect("parse");
    let sets = json["sets"].as_array().expect("sets");
    let joints_of = |name: &str| -> Vec<String> {
        let set = sets
            .iter()
            .find(|s| s["lawset"] == name)
            .unwrap_or_else(|| panic!("{name} in {sets:?}"));
        let mut j: Vec<String> = set["run"]["plateaus"][0]["joints"]
            .as_array()
            .expect("joints")
            .iter()
            .map(|l| l["joint"].as_str().expect("joint").to_string())
            .collect();
        j.dedup();
        j
    };
    let covered = joints_of("piston-only");
    assert_eq!(covered, ["piston"]);
    let missing: Vec<String> = joints_of("fedem-baseline")
        .into_iter()
        .filter(|j| !covered.contains(j))
        .collect();
    assert!(missing.len() >= 3, "{missing:?}");
    for s in sets {
        let flagged: Vec<String> = s["uncovered_joints"]
            .as_array()
            .expect("uncovered_joints")
            .iter()
            .map(|v| v.as_str().expect("name").to_string())
            .collect();
        if s["lawset"] == "piston-only" {
            assert_eq!(flagged, missing);
        } else {
            assert!(flagged.is_empty(), "{s:?}");
        }
    }
    let line = stdout
        .lines()
        .find(|l| l.contains("piston-only: NO LAW on"))
        .unwrap_or_else(|| panic!("no flag in:\n{stdout}"));
    for j in &missing {
        assert!(line.contains(j.as_str()), "{j} not in {line}");
    }
    assert!(!stdout.contains("fedem-baseline: NO LAW"), "{stdout}");
}

/// On a frictionless rig every friction sum is empty: the run's and the sweep's text, CSV and
/// FMEP tables print 0, never `-0`, `-0.000` or `-0.00000`.
#[test]
fn a_frictionless_rig_prints_no_negative_zero() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let mut printed = String::new();
    for args in [
        "run reference-frictionless --steady --fmep f1",
        "sweep reference-frictionless --temps 40,110 --speeds 3000,6000 --out s1",
    ] {
        let out = tribo_in(&args.split(' ').collect::<Vec<_>>(), d);
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{args}: {stderr}");
        printed.push_str(&stdout);
    }
    for sub in ["f1", "s1"] {
        for e in std::fs::read_dir(d.join(sub)).expect("dir") {
            let path = e.expect("entry").path();
            if path.extension().is_some_and(|x| x == "csv") {
                printed.push_str(&std::fs::read_to_string(path).expect("csv"));
            }
        }
    }
    for token in printed.split([' ', ',', '\n', '(', ')']) {
        let negative_zero = token.strip_prefix('-').is_some_and(|r| {
            !r.is_empty() && r.chars().all(|c| c == '0' || c == '.') && r.contains('0')
        });
        assert!(!negative_zero, "`{token}` printed");
    }
}
