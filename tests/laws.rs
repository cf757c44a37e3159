//! Every law of the library as a dynamic plugin: listed by `tribo laws`, run through the CLI
//! on the reference rig with the law attached (positive dissipation, energy balance), passed by
//! `tribo check-law`, and plotted by `tribo plot-law`. Faulty laws written for these tests fail
//! `check-law`, each naming the check it breaks.

mod common;

use common::*;
use serde::{Deserialize, Serialize};
use tribo::plugin_api::conformance::{self, Check, Options, Report, Status};
use tribo::plugin_api::loader::{plugin_file_name, LawLibrary};
use tribo::plugin_api::{JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec};

// Gentle enough for the PI drive to follow within its 5 N m limit (J*alpha ~ 2.9 N m) and a
// hold long enough to settle (speed error decays at ~22 1/s), so the plateau is steady.
const SHORT_CYCLE: &str = "cycle.segments=[{kind=\"ramp\", to_rpm=3000, duration_s=0.5}, {kind=\"hold\", duration_s=0.8}]";

/// (law, joint, parameter TOML)
const CASES: [(&str, &str, &str); 14] = [
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
    ("crank-churning", "main_a", "immersion_m = 0.01"),
    (
        "piston-skirt",
        "piston",
        "clearance_m = 25e-6\nskirt_height_m = 0.022\ncrown_m = 15e-6\nsigma_m = 0.8e-6",
    ),
    // The paper's sigma2 = 0.4 s/m per newton is mu ~ 4 at piston speeds; scaled for an engine.
    (
        "lugre",
        "piston",
        "mu_c = 0.05\nmu_s = 0.08\nsigma1 = 1.0\nsigma2 = 0.001",
    ),
    // The defaults are the CRF 250 R's pack (docs/laws/ring-pack.md); the boundary coefficient
    // written out so the file is not empty.
    ("ring-pack", "piston", "boundary_mu = 0.1"),
    // The 4B11's rear crankshaft seal (rigs/lawsets/4b11-physical.toml) on a main bearing.
    ("lip-seal", "main_a", "shaft_diameter_m = 0.085"),
    ("crank-windage", "main_a", "discs = 2.0"),
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

/// The ring pack on the thesis rig (`tribo run crf250r-motored --law piston=ring-pack
/// --crank-angle`): its friction force against crank angle has the shape floating-liner
/// measurements show. In each stroke the force peaks near the fastest piston (full film, where
/// the viscous shear follows the sliding speed), and the asperities carry load at the dead
/// centres (mixed film, where the wedge vanishes and only the squeeze film is left) but not at
/// mid-stroke.
#[test]
fn ring_pack_friction_against_crank_angle_has_the_floating_liner_shape() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out_dir = dir.path().join("ca");
    let out = run_tribo(
        &[
            "run",
            "crf250r-motored",
            "--steady",
            "--law",
            "piston=ring-pack",
            "--crank-angle",
            out_dir.to_str().expect("utf-8"),
        ],
        None,
    );
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    let csv = std::fs::read_to_string(out_dir.join("crank_angle.csv")).expect("crank_angle.csv");
    let mut lines = csv.lines();
    let head: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |n: &str| {
        head.iter()
            .position(|h| *h == n)
            .unwrap_or_else(|| panic!("{n}: {head:?}"))
    };
    let (c_rpm, c_deg, c_law, c_power, c_speed, c_share) = (
        col("speed_rpm"),
        col("crank_angle_deg"),
        col("law"),
        col("power_w"),
        col("sliding_speed_m_s"),
        col("asperity_share"),
    );
    // (rpm, deg, |force| N, |sliding speed|, asperity share)
    let rows: Vec<(f64, f64, f64, f64, f64)> = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[c_law] == "ring-pack")
        .map(|f| {
            let n = |i: usize| f[i].parse::<f64>().unwrap_or_else(|e| panic!("{f:?}: {e}"));
            let v = n(c_speed).abs();
            let force = if v > 0.0 { n(c_power).abs() / v } else { 0.0 };
            (n(c_rpm), n(c_deg), force, v, n(c_share))
        })
        .collect();
    let near = |deg: f64, centre: f64, band: f64| {
        let d = (deg - centre).rem_euclid(360.0);
        d <= band || d >= 360.0 - band
    };
    let mean = |xs: Vec<f64>| xs.iter().sum::<f64>() / xs.len().max(1) as f64;
    for rpm in [3000.0, 6000.0, 9000.0] {
        let rev: Vec<_> = rows.iter().filter(|r| r.0 == rpm).collect();
        assert!(rev.len() >= 360, "{rpm} rpm: {} samples", rev.len());
        let dead = mean(
            rev.iter()
                .filter(|r| near(r.1, 0.0, 5.0) || near(r.1, 180.0, 5.0))
                .map(|r| r.4)
                .collect(),
        );
        let mid = mean(
            rev.iter()
                .filter(|r| near(r.1, 80.0, 10.0) || near(r.1, 280.0, 10.0))
                .map(|r| r.4)
                .collect(),
        );
        assert!(
            dead > 0.0 && dead > 100.0 * mid,
            "{rpm} rpm: asperity share {dead} at the dead centres, {mid} mid-stroke"
        );
        for (from, to) in [(0.0, 180.0), (180.0, 360.0)] {
            let stroke: Vec<_> = rev.iter().filter(|r| r.1 >= from && r.1 < to).collect();
            let f = stroke
                .iter()
                .max_by(|a, b| a.2.total_cmp(&b.2))
                .expect("samples");
            let v = stroke
                .iter()
                .max_by(|a, b| a.3.total_cmp(&b.3))
                .expect("samples");
            assert!(
                (f.1 - v.1).abs() <= 30.0,
                "{rpm} rpm: force peaks at {} deg, piston fastest at {} deg",
                f.1,
                v.1
            );
        }
    }
}

/// Issue 25 point 2: the plain journal bearings' diagnostics in `--crank-angle` on the 4B11
/// with `4b11-physical`, checked by their physics: the eccentricity ratio inside the wall,
/// the minimum film the law's `c (1 - |e|)` with the law set's clearance, a peak film pressure
/// no lower than the load can be carried with (the film force `W` is at most the peak pressure
/// times the projected area twice, `2 D L`: `|F| <= p_max * integral of |cos| R L`), and the
/// journals running more eccentric at 6000 rpm than at 3000 (the big end's inertia load grows
/// with speed squared, its film's carrying capacity with speed: the Sommerfeld number falls).
/// The eccentricity loci are drawn per plateau, only where a law reports them.
#[test]
fn plain_journal_diagnostics_in_the_crank_angle_results_obey_the_film_physics() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out_dir = dir.path().join("ca");
    let cycle = "cycle.segments=[{kind=\"ramp\", to_rpm=3000.0, duration_s=0.2}, \
        {kind=\"hold\", duration_s=0.2}, {kind=\"ramp\", to_rpm=6000.0, duration_s=0.2}, \
        {kind=\"hold\", duration_s=0.2}]";
    let out = run_tribo(
        &[
            "run",
            "inline4-4b11",
            "--lawset",
            "4b11-physical",
            "--set",
            cycle,
            "--crank-angle",
            out_dir.to_str().expect("utf-8"),
        ],
        None,
    );
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    // Clearances from the law set, journal sizes from the rig: the test's own reading.
    let read = |p: &str| -> toml::Value {
        toml::from_str(&std::fs::read_to_string(workspace().join(p)).expect(p)).expect(p)
    };
    let lawset = read("rigs/lawsets/4b11-physical.toml");
    let clearance = |joint: &str| -> f64 {
        lawset["laws"]
            .as_array()
            .expect("laws")
            .iter()
            .find(|l| l["joint"].as_str() == Some(joint))
            .and_then(|l| l["params"]["clearance_m"].as_float())
            .unwrap_or_else(|| panic!("{joint}'s clearance"))
    };
    let rig = read("rigs/inline4-4b11.toml");
    let size = |t: &toml::Value| {
        (
            2.0 * t["radius_m"].as_float().expect("r"),
            t["length_m"].as_float().expect("l"),
        )
    };
    let mains: Vec<(f64, f64)> = rig["engine"]["mains"]
        .as_array()
        .expect("mains")
        .iter()
        .map(size)
        .collect();
    let big_end = size(&rig["joints"]["big_end"]);
    let rows = crank_angle_rows(&out_dir.join("crank_angle.csv"));
    let journal: Vec<_> = rows
        .iter()
        .filter(|r| r["law"] == "plain-journal")
        .collect();
    assert!(journal.len() >= 2 * 9 * 360, "{} rows", journal.len());
    let num = |r: &std::collections::HashMap<String, String>, k: &str| -> f64 {
        r[k].parse()
            .unwrap_or_else(|e| panic!("{k} = {:?}: {e}", r[k]))
    };
    let mut mean_e = std::collections::BTreeMap::<(String, u32), (f64, usize)>::new();
    for r in &journal {
        let joint = r["joint"].as_str();
        let ((d, l), c) = match joint.strip_prefix("main_") {
            Some(k) => (
                mains[k.parse::<usize>().expect("main number") - 1],
                clearance("main_*"),
            ),
            None => (big_end, clearance("big_end")),
        };
        let e = num(r, "eccentricity_x").hypot(num(r, "eccentricity_y"));
        let film = num(r, "min_film_m");
        let peak = num(r, "peak_pressure_pa");
        let load = num(r, "normal_load_n");
        let at = format!(
            "{joint} at {} deg, {} rpm",
            r["crank_angle_deg"], r["speed_rpm"]
        );
        assert!((0.0..1.0).contains(&e), "{at}: |e| = {e}");
        assert!(
            (film - c * (1.0 - e)).abs() <= 1e-9 * c,
            "{at}: film {film} vs c(1-e) {}",
            c * (1.0 - e)
        );
        // 3%: the tabulated peak against the solver's own (within 0.7%, docs/laws/plain-journal.md).
        assert!(
            peak > 0.0 && peak >= 0.97 * load / (2.0 * d * l),
            "{at}: peak {peak} Pa, load {load} N"
        );
        let key = (joint.to_string(), num(r, "speed_rpm") as u32);
        let m = mean_e.entry(key).or_default();
        *m = (m.0 + e, m.1 + 1);
    }
    for k in 1..=4 {
        let joint = format!("big_end_{k}");
        let e = |rpm: u32| {
            let (sum, n) = mean_e[&(joint.clone(), rpm)];
            sum / n as f64
        };
        assert!(
            e(6000) > e(3000),
            "{joint}: mean e/c {} at 6000 rpm, {} at 3000",
            e(6000),
            e(3000)
        );
    }
    for rpm in [3000, 6000] {
        let svg = std::fs::read_to_string(out_dir.join(format!("eccentricity_{rpm}.svg")))
            .expect("the eccentricity loci");
        for label in [
            "main_1",
            "main_5",
            "big_end_4",
            "e/c",
            "bearing wall",
            "counter-clockwise",
        ] {
            assert!(svg.contains(label), "{rpm} rpm: no `{label}` in the plot");
        }
        // The skirts' lateral offsets are drawn against crank angle on their own axes, not
        // as journals' loci.
        assert!(
            !svg.contains("piston_"),
            "{rpm} rpm: a piston among the journals"
        );
        let svg = std::fs::read_to_string(out_dir.join(format!("piston_offset_{rpm}.svg")))
            .expect("the pistons' offsets");
        for label in [
            "piston_1 (piston-skirt)",
            "piston_4 (piston-skirt)",
            "crank angle (degrees)",
            "lateral offset e/c (-), across the bore",
        ] {
            assert!(
                svg.contains(label),
                "{rpm} rpm: no `{label}` in the offset plot"
            );
        }
    }
    // Rolling-bearing and tuned laws report no eccentricity: no loci plot.
    let plain = dir.path().join("rolling");
    let out = run_tribo(
        &[
            "run",
            "inline4-4b11",
            "--lawset",
            "physical-bearings",
            "--set",
            cycle,
            "--crank-angle",
            plain.to_str().expect("utf-8"),
            "--quiet",
        ],
        None,
    );
    assert!(out.status.success(), "{}", text(&out).1);
    assert!(plain.join("bearing_loads_3000.svg").is_file());
    assert!(!plain.join("eccentricity_3000.svg").exists());
    assert!(!plain.join("piston_offset_3000.svg").exists());
}

/// The rows of a `crank_angle.csv`, by column name.
fn crank_angle_rows(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).expect("crank_angle.csv");
    let head = r.headers().expect("header").clone();
    r.records()
        .map(|row| {
            let row = row.expect("row");
            head.iter()
                .map(String::from)
                .zip(row.iter().map(String::from))
                .collect()
        })
        .collect()
}

/// Joint of the bundled rig each law is plotted on (its natural place in the engine).
fn plot_joint(law: &str) -> &'static str {
    match law {
        "petroff-journal" | "rolling-bearing" | "polyline-damper" | "crank-churning"
        | "lip-seal" | "crank-windage" => "main_a",
        "fedem-friction" => "big_end",
        _ => "piston",
    }
}

fn write_params(dir: &std::path::Path, law: &str, params: &str) -> std::path::PathBuf {
    let f = dir.join(format!("{law}.toml"));
    std::fs::write(&f, params).expect("write params");
    f
}

#[test]
fn check_law_passes_every_bundled_law_with_defaults_and_rig_parameters() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (law, _, params) in CASES {
        let pfile = write_params(dir.path(), law, params);
        let with_params = [
            "check-law",
            law,
            "--json",
            "--params",
            pfile.to_str().expect("utf-8"),
        ];
        for args in [&with_params[..3], &with_params[..]] {
            let out = run_tribo(args, None);
            let (stdout, stderr) = text(&out);
            assert!(out.status.success(), "{law} {args:?}: {stdout}\n{stderr}");
            let json: serde_json::Value = serde_json::from_str(&stdout).expect("json");
            assert_eq!(json["law"], law);
            let checks = json["checks"].as_array().expect("checks");
            assert_eq!(
                checks.len(),
                Check::ALL.len(),
                "{law}: every check reported"
            );
            for c in checks {
                let name = c["check"].as_str().unwrap_or("");
                let status = c["status"].as_str().unwrap_or("");
                // Only checks that do not apply may be skipped: dF/dv, dF/dN or diagnostics of a
                // law that reports none, commit of a stateless law. Everything else must have
                // run and passed.
                let expected = match name {
                    "derivative" => matches!(
                        law,
                        "coulomb"
                            | "c-coulomb"
                            | "petroff-journal"
                            | "polyline-damper"
                            | "rolling-bearing"
                    ),
                    "commit" => matches!(law, "lugre" | "ring-pack" | "piston-skirt"),
                    // Contract version 3's outputs: the ring pack and the skirt report film
                    // diagnostics; the laws that mark their outputs affine in the load report
                    // its slope, dF/dN.
                    "diagnostics" => matches!(law, "ring-pack" | "piston-skirt"),
                    "load-derivative" => matches!(law, "fedem-friction" | "polyline-damper"),
                    _ => true,
                };
                let want = if expected { "pass" } else { "skip" };
                assert_eq!(status, want, "{law} {args:?}: {name}: {}", c["detail"]);
            }
        }
    }
    // The table form says so, and a library can be named by its path as well as by its name.
    ensure_plugins_built();
    let lib = built_library("tribo_law_c_coulomb");
    let out = run_tribo(&["check-law", lib.to_str().expect("utf-8")], None);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("law `c-coulomb`") && stdout.contains("all checks passed"),
        "{stdout}"
    );
    // Every line of the table within 100 columns: plain-journal's long details are wrapped
    // under their own column, its rows still starting with the check's name.
    let out = run_tribo(&["check-law", "plain-journal"], None);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.lines().all(|l| l.chars().count() <= 100), "{stdout}");
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("derivative             pass   dF/dv")),
        "{stdout}"
    );
}

#[test]
fn check_law_refuses_bad_arguments_with_clear_errors() {
    let dir = tempfile::tempdir().expect("temp dir");
    let missing = dir.path().join("nope.toml");
    let out = run_tribo(
        &[
            "check-law",
            "coulomb",
            "--params",
            missing.to_str().expect("utf-8"),
        ],
        None,
    );
    assert!(!out.status.success());
    assert_mentions(&text(&out).1, &["nope.toml", "parameter file"]);
    let bad = write_params(dir.path(), "bad", "mu = 0.1\nmu = = 2\n");
    let out = run_tribo(
        &[
            "check-law",
            "coulomb",
            "--params",
            bad.to_str().expect("utf-8"),
        ],
        None,
    );
    assert!(!out.status.success());
    assert_mentions(&text(&out).1, &["bad.toml", "line 2"]);
    // A parameter out of range is the `create` check's failure, naming the parameter.
    let high = write_params(dir.path(), "high", "mu = 50.0\n");
    let out = run_tribo(
        &[
            "check-law",
            "coulomb",
            "--params",
            high.to_str().expect("utf-8"),
        ],
        None,
    );
    assert_eq!(out.status.code(), Some(1));
    let (stdout, stderr) = text(&out);
    assert!(
        stdout.contains("create") && stdout.contains("`mu`"),
        "{stdout}"
    );
    assert_mentions(&stderr, &["coulomb", "create"]);
    let out = run_tribo(&["check-law", "no-such-law"], None);
    assert!(!out.status.success());
    assert_mentions(&text(&out).1, &["no-such-law"]);
}

// ---- Faulty laws: each breaks one rule and must fail exactly the check for it. ----

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct MuParams {
    mu: f64,
}

impl Default for MuParams {
    fn default() -> Self {
        Self { mu: 0.1 }
    }
}

fn mu_spec() -> Vec<ParamSpec> {
    vec![ParamSpec::number(
        "mu",
        "-",
        "friction coefficient",
        0.0,
        1.0,
    )]
}

/// A stateless fixture law with the one parameter `mu` (its doc, type, name, summary and
/// output in terms of `mu` and the input): the laws the checks below must catch, each wrong in
/// one way.
macro_rules! mu_fixture {
    (
        $(#[$doc:meta])* $ty:ident, $name:literal, $summary:literal,
        |$mu:ident, $input:ident| $body:block
    ) => {
        $(#[$doc])*
        struct $ty(f64);
        impl Law for $ty {
            type Params = MuParams;
            const NAME: &'static str = $name;
            const VERSION: &'static str = "0.1.0";
            const SUMMARY: &'static str = $summary;
            fn parameters() -> Vec<ParamSpec> {
                mu_spec()
            }
            fn new(p: MuParams) -> Result<Self, ParamError> {
                Ok(Self(p.mu))
            }
            fn evaluate(&self, $input: &LawInput, _: &[f64]) -> LawOutput {
                let $mu = self.0;
                $body
            }
        }
    };
}

fn arm(input: &LawInput) -> f64 {
    if input.kind() == Some(JointKind::Revolute) {
        input.contact_radius_m
    } else {
        1.0
    }
}

mu_fixture! {
    /// Pushes along the motion: feeds energy in.
    Pushing, "fixture-pushing", "friction with the wrong sign",
    |mu, input| {
        let (s, _) = tribo::plugin_api::smooth_sign(input.sliding_velocity_m_s, 1e-3);
        LawOutput::force(mu * input.normal_load_n * arm(input) * s)
    }
}

mu_fixture! {
    /// A viscous damper whose reported dF/dv is twice the true one.
    WrongDerivative, "fixture-wrong-derivative", "viscous damper with a wrong dF/dv",
    |mu, input| {
        let c = mu * (1.0 + input.normal_load_n);
        LawOutput::force(-c * input.relative_velocity).with_derivative(-2.0 * c)
    }
}

mu_fixture! {
    /// Coulomb friction with a hard sign written as v/|v|: NaN at zero velocity.
    NanAtRest, "fixture-nan-at-rest", "Coulomb friction as v/|v|",
    |mu, input| {
        let v = input.sliding_velocity_m_s;
        LawOutput::force(-mu * input.normal_load_n * arm(input) * v / v.abs())
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct HighMu {
    mu: f64,
}

impl Default for HighMu {
    fn default() -> Self {
        // The fault: outside the declared [0, 1].
        Self { mu: 2.0 }
    }
}

/// A default outside its own declared range.
struct BadDefault(f64);
impl Law for BadDefault {
    type Params = HighMu;
    const NAME: &'static str = "fixture-bad-default";
    const VERSION: &'static str = "0.1.0";
    const SUMMARY: &'static str = "a default outside its range";
    fn parameters() -> Vec<ParamSpec> {
        mu_spec()
    }
    fn new(p: HighMu) -> Result<Self, ParamError> {
        Ok(Self(p.mu))
    }
    fn evaluate(&self, input: &LawInput, _: &[f64]) -> LawOutput {
        LawOutput::force(-self.0 * input.relative_velocity)
    }
}

mu_fixture! {
    /// Panics above 20 kN.
    PanicsUnderLoad, "fixture-panics-under-load", "panics above 20 kN",
    |mu, input| {
        assert!(input.normal_load_n <= 20e3, "load table ends at 20 kN");
        LawOutput::force(-mu * input.relative_velocity)
    }
}

/// A state that grows tenfold at every commit (an unstable integrator).
struct Diverging(f64);
impl Law for Diverging {
    type Params = MuParams;
    const NAME: &'static str = "fixture-diverging";
    const VERSION: &'static str = "0.1.0";
    const SUMMARY: &'static str = "a state that blows up";
    fn parameters() -> Vec<ParamSpec> {
        mu_spec()
    }
    fn new(p: MuParams) -> Result<Self, ParamError> {
        Ok(Self(p.mu))
    }
    fn state_size(&self) -> usize {
        1
    }
    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        let z = state.first().copied().unwrap_or(0.0).abs();
        LawOutput::force(-(self.0 + z) * input.relative_velocity)
    }
    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        if let Some(z) = state.first_mut() {
            *z = 10.0 * *z + input.dt_s;
        }
    }
}

mu_fixture! {
    /// Coulomb friction reporting a film that goes negative above 2 kN (an unclamped film
    /// formula): physically impossible.
    NegativeFilm, "fixture-negative-film", "a film thickness below zero",
    |mu, input| {
        let (s, _) = tribo::plugin_api::smooth_sign(input.sliding_velocity_m_s, 1e-3);
        LawOutput::force(-mu * input.normal_load_n * arm(input) * s)
            .with_min_film(2e-6 - 1e-9 * input.normal_load_n)
    }
}

mu_fixture! {
    /// Coulomb friction whose reported dF/dN is twice the true one.
    WrongLoadDerivative, "fixture-wrong-load-derivative", "Coulomb friction with a wrong dF/dN",
    |mu, input| {
        let (s, _) = tribo::plugin_api::smooth_sign(input.sliding_velocity_m_s, 1e-3);
        let per_newton = -mu * arm(input) * s;
        LawOutput::force(per_newton * input.normal_load_n).with_load_derivative(2.0 * per_newton)
    }
}

mu_fixture! {
    /// Friction whose coefficient grows with the load (`mu (1 + N / 10 kN)`), its true local dF/dN
    /// reported, but its output marked affine in the load: a promise the host would act on.
    FalselyAffine, "fixture-falsely-affine", "load-dependent friction marked affine in the load",
    |mu, input| {
        let (s, _) = tribo::plugin_api::smooth_sign(input.sliding_velocity_m_s, 1e-3);
        let n = input.normal_load_n;
        let per_newton = -mu * arm(input) * s;
        LawOutput::force(per_newton * n * (1.0 + n / 1e4))
            .affine_in_load(per_newton * (1.0 + 2.0 * n / 1e4))
    }
}

/// A stateful viscous law (its coefficient grows with the distance slid) whose batch call
/// reads the first input's state for every input: the stride ignored.
struct BatchIgnoresStride(f64);
impl Law for BatchIgnoresStride {
    type Params = MuParams;
    const NAME: &'static str = "fixture-batch-ignores-stride";
    const VERSION: &'static str = "0.1.0";
    const SUMMARY: &'static str = "an evaluate_many that ignores the state stride";
    fn parameters() -> Vec<ParamSpec> {
        mu_spec()
    }
    fn new(p: MuParams) -> Result<Self, ParamError> {
        Ok(Self(p.mu))
    }
    fn state_size(&self) -> usize {
        1
    }
    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        LawOutput::force(-(self.0 + state[0]) * input.relative_velocity)
    }
    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        state[0] += input.dt_s * input.relative_velocity.abs();
    }
    fn evaluate_many(
        &self,
        inputs: &[LawInput],
        states: &[f64],
        _state_stride: usize,
        outputs: &mut [LawOutput],
    ) {
        for (input, out) in inputs.iter().zip(outputs.iter_mut()) {
            *out = self.evaluate(input, &states[..1]);
        }
    }
}

fn report_of<L: Law>() -> Report {
    let lib = LawLibrary::in_process::<L>().expect("describes itself");
    conformance::check_law(&lib, &toml::Table::new())
}

fn detail(r: &Report, c: Check) -> String {
    r.get(c).map(|x| x.detail.clone()).unwrap_or_default()
}

#[test]
fn a_non_dissipative_law_fails_dissipative_unless_declared_active() {
    let r = report_of::<Pushing>();
    assert_eq!(r.failed(), vec![Check::Dissipative], "{r}");
    assert!(detail(&r, Check::Dissipative).contains("F*v"), "{r}");
    // Declared active, with its reason, it passes and the reason is shown.
    let lib = LawLibrary::in_process::<Pushing>().expect("describes itself");
    let r = conformance::check_with(
        &lib,
        &Options {
            params: toml::Table::new(),
            active: Some("a test motor".into()),
        },
    );
    assert!(r.passed(), "{r}");
    let d = r.get(Check::Dissipative).expect("reported");
    assert_eq!(d.status, Status::Skip);
    assert!(d.detail.contains("a test motor"), "{r}");
}

#[test]
fn a_wrong_derivative_fails_derivative() {
    let r = report_of::<WrongDerivative>();
    assert_eq!(r.failed(), vec![Check::Derivative], "{r}");
    assert!(
        detail(&r, Check::Derivative).contains("finite differences"),
        "{r}"
    );
}

#[test]
fn nan_at_zero_velocity_fails_finite_naming_the_input() {
    let r = report_of::<NanAtRest>();
    assert_eq!(r.failed(), vec![Check::Finite], "{r}");
    let d = detail(&r, Check::Finite);
    assert!(d.contains("F=NaN") && d.contains("v=0e0"), "{d}");
}

#[test]
fn an_out_of_range_default_fails_defaults_naming_the_parameter() {
    let r = report_of::<BadDefault>();
    assert_eq!(r.failed(), vec![Check::Defaults, Check::Create], "{r}");
    let d = detail(&r, Check::Defaults);
    assert!(
        d.contains("`mu`") && d.contains("2.0") && d.contains("[0, 1]"),
        "{d}"
    );
    // Nothing can be evaluated without an instance: those checks say so instead of passing.
    assert_eq!(r.get(Check::Finite).map(|c| c.status), Some(Status::Skip));
}

#[test]
fn a_panic_is_a_named_error_not_a_crash() {
    let r = report_of::<PanicsUnderLoad>();
    assert_eq!(r.failed(), vec![Check::NoErrors], "{r}");
    let d = detail(&r, Check::NoErrors);
    assert!(
        d.contains("panicked") && d.contains("load table ends at 20 kN"),
        "{d}"
    );
    assert!(d.contains("load 50000 N"), "{d}");
}

#[test]
fn a_negative_film_fails_diagnostics_naming_the_value() {
    let r = report_of::<NegativeFilm>();
    assert_eq!(r.failed(), vec![Check::Diagnostics], "{r}");
    let d = detail(&r, Check::Diagnostics);
    assert!(d.contains("min_film_m = -") && d.contains(">= 0 m"), "{d}");
    assert!(d.contains("load 50000 N"), "{d}");
}

#[test]
fn a_wrong_load_derivative_fails_load_derivative() {
    let r = report_of::<WrongLoadDerivative>();
    assert_eq!(r.failed(), vec![Check::LoadDerivative], "{r}");
    let d = detail(&r, Check::LoadDerivative);
    assert!(
        d.contains("dF/dN") && d.contains("finite differences"),
        "{d}"
    );
    // A right one passes, and the zero-load points are counted as not judged.
    let r = report_of::<NegativeFilm>();
    assert_eq!(
        r.get(Check::LoadDerivative).map(|c| c.status),
        Some(Status::Skip),
        "{r}"
    );
}

#[test]
fn a_law_falsely_marked_affine_in_the_load_fails_load_derivative() {
    let r = report_of::<FalselyAffine>();
    assert_eq!(r.failed(), vec![Check::LoadDerivative], "{r}");
    let d = detail(&r, Check::LoadDerivative);
    assert!(d.contains("marked affine in the load"), "{d}");
    // The bundled laws that mark it pass: Coulomb on the reactions, the poly-line damper
    // (its slope 0).
    ensure_plugins_built();
    let registry = tribo::plugin_api::loader::load_paths(&[profile_dir()]).expect("plugins load");
    for name in ["fedem-friction", "polyline-damper"] {
        let lib = registry.get(name).expect("bundled");
        let r = conformance::check_law(lib, &toml::Table::new());
        assert!(r.passed(), "{name}: {r}");
        let d = detail(&r, Check::LoadDerivative);
        assert!(!d.contains("no dF/dN"), "{name} marks its slope: {d}");
    }
}

#[test]
fn a_batch_that_ignores_the_stride_fails_evaluate_many() {
    let r = report_of::<BatchIgnoresStride>();
    assert_eq!(r.failed(), vec![Check::EvaluateMany], "{r}");
    let d = detail(&r, Check::EvaluateMany);
    assert!(
        d.contains("a state per input") && d.contains("batch input"),
        "{d}"
    );
}

#[test]
fn a_diverging_state_fails_commit() {
    let r = report_of::<Diverging>();
    assert_eq!(r.failed(), vec![Check::Commit], "{r}");
    assert!(detail(&r, Check::Commit).contains("state value"), "{r}");
}

#[test]
fn a_state_mutating_evaluate_fails_pure_evaluate_through_the_c_abi_and_the_cli() {
    let dir = tempfile::tempdir().expect("temp dir");
    let lib_path = dir
        .path()
        .join(plugin_file_name("tribo_law_fixture_mutating"));
    compile_c(&[c_fixture("mutating_evaluate.c")], &lib_path, true);
    let lib = LawLibrary::load(&lib_path).expect("loads");
    let r = conformance::check_law(&lib, &toml::Table::new());
    assert_eq!(r.failed(), vec![Check::PureEvaluate], "{r}");
    assert!(
        detail(&r, Check::PureEvaluate).contains("changed the state"),
        "{r}"
    );
    // Through the command: exit 1, the table marks the check, the error names it.
    let out = run_tribo(&["check-law", lib_path.to_str().expect("utf-8")], None);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stdout}\n{stderr}");
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("pure-evaluate") && l.contains("FAIL")),
        "{stdout}"
    );
    assert!(stdout.contains("1 check failed: pure-evaluate"), "{stdout}");
    assert_mentions(&stderr, &["fixture-mutating-evaluate", "pure-evaluate"]);
}

#[test]
fn plot_law_writes_an_svg_for_every_bundled_law() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (law, _, params) in CASES {
        let pfile = write_params(dir.path(), law, params);
        let svg = dir.path().join(format!("{law}.svg"));
        let out = run_tribo(
            &[
                "plot-law",
                law,
                "--params",
                pfile.to_str().expect("utf-8"),
                "--joint",
                plot_joint(law),
                "--out",
                svg.to_str().expect("utf-8"),
            ],
            None,
        );
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{law}: {stderr}");
        assert!(stdout.contains(svg.to_str().expect("utf-8")), "{stdout}");
        let text = std::fs::read_to_string(&svg).expect("svg written");
        assert!(
            text.trim_start().starts_with("<svg") && text.trim_end().ends_with("</svg>"),
            "{law}"
        );
        assert!(text.contains(law), "{law}: the title names the law");
        // Three loads x two temperatures, in both panels.
        assert!(
            text.matches("<polyline").count() >= 12,
            "{law}: six curves per panel"
        );
        for label in ["200 N, 40 C", "5000 N, 100 C"] {
            assert!(text.contains(label), "{law}: legend entry {label}");
        }
    }
    // A joint the rig does not have is refused by name.
    let out = run_tribo(&["plot-law", "coulomb", "--joint", "crosshead"], None);
    assert!(!out.status.success());
    assert_mentions(&text(&out).1, &["crosshead", "piston"]);
}

#[test]
fn plot_law_curves_are_the_law_at_the_plotted_loads_and_oil() {
    ensure_plugins_built();
    let registry = tribo::plugin_api::loader::load_paths(&[profile_dir()]).expect("plugins load");
    // Coulomb on the piston: |F| = mu N far above the smoothing speed, opposing the motion.
    let lib = registry.get("coulomb").expect("coulomb");
    let c = tribo::check::sample_law(lib, &"mu = 0.08".parse().expect("toml"), "piston")
        .expect("sampled");
    assert_eq!(c.curves.len(), 6);
    for k in &c.curves {
        for &(v, f) in &k.points {
            assert!(f * v <= 0.0, "opposes motion: v {v} F {f}");
            if v.abs() > 1.0 {
                assert!(
                    (f.abs() - 0.08 * k.load_n).abs() < 1e-6 * k.load_n,
                    "v {v}: {f}"
                );
            }
        }
    }
    // Petroff on a main bearing: torque proportional to viscosity, so the 40 C curve is the
    // hotter one times the rig oil's viscosity ratio, at every speed and load.
    let lib = registry.get("petroff-journal").expect("petroff");
    let c = tribo::check::sample_law(lib, &"clearance_m = 2e-5".parse().expect("toml"), "main_a")
        .expect("sampled");
    let (cold, hot) = (&c.curves[0], &c.curves[3]);
    assert_eq!((cold.oil_temp_c, hot.oil_temp_c), (40.0, 100.0));
    let ratio = cold.viscosity_pa_s / hot.viscosity_pa_s;
    assert!(
        (ratio - 115.0 / 17.5).abs() < 1e-9,
        "rig oil 115 / 17.5 cSt: {ratio}"
    );
    for (a, b) in cold.points.iter().zip(&hot.points) {
        assert!(
            (a.1 - ratio * b.1).abs() <= 1e-9 * a.1.abs().max(1e-12),
            "{a:?} {b:?}"
        );
    }
}

#[test]
fn a_law_that_crashes_check_law_is_named_with_the_signal() {
    let dir = tempfile::tempdir().expect("temp dir");
    let lib_path = dir.path().join(plugin_file_name("tribo_law_fixture_crash"));
    compile_c(&[c_fixture("crash_in_evaluate.c")], &lib_path, true);
    let out = run_tribo(&["check-law", lib_path.to_str().expect("utf-8")], None);
    let (_, stderr) = text(&out);
    assert!(!out.status.success(), "{stderr}");
    assert_mentions(&stderr, &["SIGSEGV", "fixture-crash-in-evaluate"]);
}

/// Across the plugin boundary the law knows which parameters were given: the plain journal,
/// loaded as a plugin, refuses a heat-balance lag given to an isothermal film (it would be
/// ignored), and accepts the same lag left at its default or given to a held film.
#[test]
fn a_plugin_is_told_which_parameters_were_given() {
    let lib = LawLibrary::load(&built_library("tribo_law_plain_journal")).expect("loads");
    let table = |text: &str| -> toml::Table { text.parse().expect("toml") };
    let e = match lib.create(&table("thermal_lag_rev = 2.0")) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("a lag given to an isothermal film was accepted"),
    };
    assert_mentions(
        &e,
        &[
            "thermal_lag_rev = 2",
            "isothermal",
            "remove thermal_lag_rev",
        ],
    );
    lib.create(&table("")).expect("the defaults");
    lib.create(&table(
        "thermal = \"effective\"\noil_kv40_cst = 65.0\noil_kv100_cst = 11.0\nthermal_lag_rev = 2.0",
    ))
    .expect("a held film's lag");
}
