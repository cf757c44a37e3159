//! `tribo sweep` (torque over oil temperature and speed), the oil's name in the rig schema, and
//! the FEDEM thesis's column of `mass-response`. Every expected value is computed here,
//! independently of the host's code.

mod common;

use std::f64::consts::PI;

use common::*;

fn fixture(name: &str) -> String {
    workspace()
        .join("tests/fixtures/lawsets")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// Kinematic viscosity (cSt) of an oil given by its viscosities at 40 and 100 C, by the
/// Walther / ASTM D341 equation log log (nu + 0.7) = A - B log T, written out from the standard:
/// the straight line through the two points in (log T, log log Z) coordinates, evaluated at T.
fn astm_d341_cst(kv40: f64, kv100: f64, t_c: f64) -> f64 {
    let loglog = |nu: f64| ((nu + 0.7).log10()).log10();
    let (t1, t2, t) = (313.15_f64, 373.15_f64, t_c + 273.15);
    let slope = (loglog(kv100) - loglog(kv40)) / (t2.log10() - t1.log10());
    let y = loglog(kv40) + slope * (t.log10() - t1.log10());
    10f64.powf(10f64.powf(y)) - 0.7
}

/// The bundled rig's oil: typical 10W-50, KV40 115 cSt, KV100 17.5 cSt, 860 kg/m^3.
fn bundled_oil_pa_s(t_c: f64) -> f64 {
    astm_d341_cst(115.0, 17.5, t_c) * 1e-6 * 860.0
}

/// Points of one law set, as (speed rpm, temperature C) -> (torque N m, viscosity Pa s).
fn points(set: &serde_json::Value) -> Vec<(f64, f64, f64, f64)> {
    set["points"]
        .as_array()
        .expect("points")
        .iter()
        .map(|p| {
            (
                num(&p["speed_rpm"]),
                num(&p["oil_temp_c"]),
                num(&p["torque_nm"]),
                num(&p["viscosity_pa_s"]),
            )
        })
        .collect()
}

#[test]
fn viscous_law_torque_scales_with_the_astm_d341_viscosity() {
    let dir = tempfile::tempdir().expect("temp dir");
    let temps = [40.0, 55.0, 80.0, 110.0];
    let json = json_in(
        &[
            "sweep",
            "--lawset",
            &fixture("petroff-mains.toml"),
            "--temps",
            "40,55,80,110",
            "--speeds",
            "3000,6000,9000",
            "--out",
            "o",
            "--json",
        ],
        dir.path(),
    );
    // The oil is named, with its grade, model and source.
    let oil = &json["oil"];
    assert_eq!(oil["grade"], "10W-50");
    assert!(oil["name"].as_str().expect("name").contains("10W-50"));
    assert!(oil["source"]
        .as_str()
        .expect("source")
        .starts_with("estimate:"));
    assert_eq!(oil["viscosity"]["model"], "two-point");
    for (t, v) in temps
        .iter()
        .zip(json["viscosities_pa_s"].as_array().expect("v"))
    {
        let want = bundled_oil_pa_s(*t);
        assert!((num(v) - want).abs() <= 1e-9 * want, "{t} C: {v} vs {want}");
    }
    let pts = points(&json["sets"][0]);
    assert_eq!(pts.len(), 12);
    for &(rpm, t, torque, visc) in &pts {
        // Petroff on each main bearing: T = 2 pi eta omega R^3 L / c (R 20 mm, L 15 mm, c 20 um).
        // The crank turns at exactly omega in steady state, so the bearings' mean torque is
        // this at every crank angle; the inertia torque's mean over the periodic revolution is
        // zero (the trapezoid rule on a periodic integrand is accurate to rounding), so the
        // motoring torque is the two bearings' torque to ~1e-12 relative. 1e-9 leaves room for
        // rounding only.
        let eta = bundled_oil_pa_s(t);
        let omega = rpm * PI / 30.0;
        let want = 2.0 * 2.0 * PI * eta * omega * 0.020_f64.powi(3) * 0.015 / 2e-5;
        assert!(
            (torque - want).abs() <= 1e-9 * want,
            "{rpm} rpm {t} C: {torque} vs Petroff {want}"
        );
        assert!((visc - eta).abs() <= 1e-9 * eta);
        // Ratios between temperatures at the same speed equal the viscosity ratios.
        let at80 = pts
            .iter()
            .find(|p| p.0 == rpm && p.1 == 80.0)
            .expect("80 C point");
        let ratio = torque / at80.2;
        let want_ratio = astm_d341_cst(115.0, 17.5, t) / astm_d341_cst(115.0, 17.5, 80.0);
        assert!(
            (ratio - want_ratio).abs() <= 1e-9 * want_ratio,
            "{rpm} rpm {t} C: ratio {ratio} vs viscosity ratio {want_ratio}"
        );
    }
    // Colder oil, more torque: 40 C is about four times 80 C for this oil.
    let r = pts[0].2 / pts[6].2;
    assert!(r > 3.5 && r < 4.5, "{r}");
}

#[test]
fn a_user_oil_given_by_set_replaces_the_bundled_one_and_its_name() {
    let dir = tempfile::tempdir().expect("temp dir");
    // Vogel constants of physics notes 6 (the same typical 10W-50, fitted differently).
    let (k, th1, th2) = (0.1153_f64, 1105.2_f64, 120.06_f64);
    let vogel =
        format!("oil.viscosity={{model=\"vogel\", k_cst={k}, theta1_c={th1}, theta2_c={th2}}}");
    let json = json_in(
        &[
            "sweep",
            "--lawset",
            &fixture("petroff-mains.toml"),
            "--set",
            &vogel,
            "--temps",
            "60,90",
            "--speeds",
            "5000",
            "--out",
            "o",
            "--json",
        ],
        dir.path(),
    );
    // The bundled oil's name does not stick to a viscosity it does not describe.
    assert!(json["oil"]["name"].is_null() && json["oil"]["source"].is_null());
    assert_eq!(json["oil"]["viscosity"]["model"], "vogel");
    let pts = points(&json["sets"][0]);
    let nu = |t: f64| k * (th1 / (t + th2)).exp();
    let want = nu(60.0) / nu(90.0);
    let got = pts[0].2 / pts[1].2;
    assert!((got - want).abs() <= 1e-9 * want, "{got} vs Vogel {want}");
    // Naming it in the same breath keeps the name.
    let json = json_in(
        &[
            "sweep",
            "--lawset",
            &fixture("petroff-mains.toml"),
            "--set",
            &vogel,
            "--set",
            "oil.name=\"my oil\"",
            "--temps",
            "60",
            "--speeds",
            "5000",
            "--out",
            "o2",
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(json["oil"]["name"], "my oil");
}

/// The printed viscosity response `d ln T / d ln mu` between neighbouring temperatures: 1 for
/// Petroff bearings (torque proportional to viscosity), 0 for Coulomb friction (viscosity-blind),
/// one column per pair of temperatures and a row per speed.
#[test]
fn the_sweep_prints_the_viscosity_response_petroff_one_coulomb_zero() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (set, want) in [
        ("petroff-mains.toml", 1.0),
        ("fedem-coulomb-only.toml", 0.0),
    ] {
        let out = tribo_in(
            &[
                "sweep",
                "--lawset",
                &fixture(set),
                "--temps",
                "40,70,110",
                "--speeds",
                "3000,9000",
                "--out",
                "o",
            ],
            dir.path(),
        );
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{stderr}");
        let lines: Vec<&str> = stdout.lines().collect();
        let at = lines
            .iter()
            .position(|l| l.starts_with("viscosity response d ln T / d ln mu"))
            .unwrap_or_else(|| panic!("{set}: no response table in\n{stdout}"));
        let head: Vec<&str> = lines[at + 1].split_whitespace().collect();
        assert_eq!(head, ["rpm", "40-70", "70-110"], "{set}");
        for (row, rpm) in lines[at + 2..at + 4].iter().zip(["3000", "9000"]) {
            let cells: Vec<&str> = row.split_whitespace().collect();
            assert_eq!(cells[0], rpm, "{set}");
            for c in &cells[1..] {
                let r: f64 = c.parse().expect("number");
                assert!((r - want).abs() < 1e-3, "{set} {rpm}: {r}");
            }
        }
    }
}

#[test]
fn temperature_blind_law_set_gives_the_same_torque_at_every_temperature() {
    let dir = tempfile::tempdir().expect("temp dir");
    let json = json_in(
        &[
            "sweep",
            "--lawset",
            &fixture("fedem-coulomb-only.toml"),
            "--temps",
            "40,70,110",
            "--out",
            "o",
            "--json",
        ],
        dir.path(),
    );
    let pts = points(&json["sets"][0]);
    assert_eq!(pts.len(), 21);
    for &(rpm, t, torque, _) in &pts {
        let at40 = pts
            .iter()
            .find(|p| p.0 == rpm && p.1 == 40.0)
            .expect("40 C point");
        assert!(torque > 0.0);
        assert!(
            (torque - at40.2).abs() <= 1e-9 * at40.2,
            "{rpm} rpm: {torque} at {t} C vs {} at 40 C",
            at40.2
        );
    }
}

#[test]
fn csv_has_a_row_per_point_and_parses_back_to_the_json_and_the_plots_are_labelled() {
    let dir = tempfile::tempdir().expect("temp dir");
    // The defaults: bundled rig, default law sets, 40-110 C, 3000-9000 rpm.
    let out = tribo_in(&["sweep", "--out", "res"], dir.path());
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert_mentions(
        &stdout,
        &[
            "oil: typical SAE 10W-50",
            "Walther/ASTM D341",
            "viscosity (mPa s)",
            "law set fedem-baseline",
            "law set stribeck-duty",
            "110 C",
        ],
    );
    let res = dir.path().join("res");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(res.join("sweep.json")).expect("json"))
            .expect("parses");
    let (temps, speeds) = (
        json["temps_c"].as_array().expect("t").len(),
        json["speeds_rpm"].as_array().expect("s").len(),
    );
    assert_eq!((temps, speeds), (8, 7));
    let mut reader = csv::Reader::from_path(res.join("sweep.csv")).expect("csv");
    let headers = reader.headers().expect("headers").clone();
    let col = |n: &str| {
        headers
            .iter()
            .position(|h| h == n)
            .unwrap_or_else(|| panic!("no column {n}"))
    };
    let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.expect("row")).collect();
    let sets = json["sets"].as_array().expect("sets");
    assert_eq!(rows.len(), sets.len() * temps * speeds);
    let mut seen = std::collections::BTreeSet::new();
    let mut i = 0;
    for set in sets {
        for p in set["points"].as_array().expect("points") {
            let row = &rows[i];
            i += 1;
            let f = |n: &str| row[col(n)].parse::<f64>().expect("number");
            // Both files hold the shortest round-trip text of the same f64; serde_json's
            // default parser (no `float_roundtrip`) may land one ulp off it, Rust's `parse`
            // does not. So: equal to within two ulps.
            let same = |a: f64, b: f64| (a - b).abs() <= 4.5e-16 * a.abs().max(b.abs());
            assert_eq!(&row[col("lawset")], set["lawset"].as_str().expect("name"));
            for key in ["speed_rpm", "oil_temp_c", "viscosity_pa_s", "torque_nm"] {
                assert!(
                    same(f(key), num(&p[key])),
                    "{key}: {} vs {}",
                    f(key),
                    p[key]
                );
            }
            for j in p["joints"].as_array().expect("joints") {
                let name = format!("{}_friction_nm", j["joint"].as_str().expect("joint"));
                let want = num(&j["friction_torque_nm"]);
                assert!(same(f(&name), want), "{name}: {} vs {want}", f(&name));
                // A joint without a law (fedem-baseline's small end) has no friction: 0, not
                // the "-0" an empty sum of floats gives.
                assert_ne!(&row[col(&name)], "-0", "{name} at {:?}", row);
            }
            assert!(seen.insert((
                row[col("lawset")].to_string(),
                row[col("speed_rpm")].to_string(),
                row[col("oil_temp_c")].to_string()
            )));
        }
    }
    for set in ["fedem-baseline", "stribeck-duty"] {
        let svg = std::fs::read_to_string(res.join(format!("sweep_{set}.svg"))).expect("svg");
        for label in [
            "crank speed (rpm)",
            "motoring torque (N m)",
            "oil temperature",
            "40 C",
            "110 C",
        ] {
            assert!(svg.contains(label), "sweep_{set}.svg lacks `{label}`");
        }
    }
}

#[test]
fn bad_sweep_inputs_exit_1_naming_the_option() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cases: [(&[&str], &[&str]); 6] = [
        (&["--temps", "40,200"], &["--temps", "200", "valid range"]),
        (&["--temps", "-40"], &["--temps", "-40", "valid range"]),
        (&["--temps", ""], &["--temps", "empty"]),
        (
            &["--speeds", "-3000,4000"],
            &["--speeds", "-3000", "positive"],
        ),
        (
            &["--speeds", "3000,x"],
            &["--speeds", "`x` is not a number"],
        ),
        (&["--speeds", "3000,3000"], &["--speeds", "twice"]),
    ];
    for (extra, words) in cases {
        let mut args = vec!["sweep", "--out", "o"];
        args.extend_from_slice(extra);
        let out = tribo_in(&args, dir.path());
        let (_, stderr) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{extra:?}: {stderr}");
        for w in words {
            assert!(stderr.contains(w), "{extra:?}: `{w}` missing in {stderr}");
        }
        assert!(!dir.path().join("o").exists(), "{extra:?} wrote results");
    }
}

#[test]
fn unknown_oil_keys_are_rejected_with_their_place() {
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = std::fs::read_to_string(workspace().join("rigs/crf250r-motored.toml"))
        .expect("rig")
        .replace("grade = \"10W-50\"", "grade = \"10W-50\"\nbrand = \"x\"");
    let path = dir.path().join("rig.toml");
    std::fs::write(&path, &rig).expect("write");
    let line = rig
        .lines()
        .position(|l| l.starts_with("brand"))
        .expect("line")
        + 1;
    let out = tribo_in(
        &["sweep", path.to_str().expect("utf-8"), "--out", "o"],
        dir.path(),
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!("rig.toml:{line}:1")) && stderr.contains("unknown field `brand`"),
        "{stderr}"
    );
}

#[test]
fn fedem_thesis_change_is_shown_only_beside_the_thesis_law_set() {
    let dir = tempfile::tempdir().expect("temp dir");
    let args = [
        "mass-response",
        "--steady",
        "--lawset",
        "fedem-baseline",
        "--lawset",
        "stribeck-duty",
        "--out",
        "o",
    ];
    let out = tribo_in(&args, dir.path());
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let (fedem, user) = stdout
        .split_once("law set stribeck-duty")
        .expect("both sets");
    assert!(fedem.contains("FEDEM thesis (T 10.6-10.5)"), "{stdout}");
    assert!(
        !user.contains("FEDEM"),
        "a user's law set shows FEDEM:\n{user}"
    );
    let json = json_in(&[&args[..], &["--json"]].concat(), dir.path());
    let fedem_values = |set: &serde_json::Value| -> Vec<f64> {
        set["changes"]
            .as_array()
            .expect("changes")
            .iter()
            .filter_map(|c| c["fedem_change_nm"].as_f64())
            .collect()
    };
    // Table 10.6 minus table 10.5 (rigs/data), 3000-9000 rpm.
    let want = [0.00, 0.00, -0.01, -0.01, -0.02, -0.02, -0.02];
    let got = fedem_values(&json[0]);
    assert_eq!(got.len(), 7);
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() < 1e-9, "{got:?}");
    }
    assert!(fedem_values(&json[1]).is_empty());
    // A changed copy of the thesis's set is a user's set: no FEDEM column.
    let copy = std::fs::read_to_string(workspace().join("rigs/lawsets/fedem-baseline.toml"))
        .expect("law set")
        .replace("mu = 0.08", "mu = 0.06");
    let copy_path = dir.path().join("fedem-baseline.toml");
    std::fs::write(&copy_path, copy).expect("write");
    let json = json_in(
        &[
            "mass-response",
            "--steady",
            "--lawset",
            copy_path.to_str().expect("utf-8"),
            "--out",
            "o2",
            "--json",
        ],
        dir.path(),
    );
    assert!(fedem_values(&json[0]).is_empty());
}

#[test]
fn an_oil_file_names_and_replaces_the_oil_and_its_mistakes_are_located() {
    let dir = tempfile::tempdir().expect("temp dir");
    let oil = dir.path().join("oil.toml");
    std::fs::write(
        &oil,
        "[oil]\nname = \"SAE 5W-30 car oil, typical\"\ngrade = \"5W-30\"\nsource = \"estimate: test\"\nviscosity = { model = \"two-point\", kv40_cst = 65.0, kv100_cst = 11.0 }\n",
    )
    .expect("write");
    let json = json_in(
        &[
            "sweep",
            "--oil",
            oil.to_str().expect("utf-8"),
            "--lawset",
            &fixture("petroff-mains.toml"),
            "--temps",
            "50,100",
            "--speeds",
            "4000",
            "--out",
            "o",
            "--json",
        ],
        dir.path(),
    );
    assert_eq!(json["oil"]["name"], "SAE 5W-30 car oil, typical");
    assert_eq!(json["oil"]["grade"], "5W-30");
    for (t, v) in [50.0, 100.0]
        .iter()
        .zip(json["viscosities_pa_s"].as_array().expect("v"))
    {
        let want = astm_d341_cst(65.0, 11.0, *t) * 1e-6 * 860.0;
        assert!((num(v) - want).abs() <= 1e-9 * want, "{t} C: {v} vs {want}");
    }
    std::fs::write(&oil, "[oil]\nname = \"x\"\ncolour = \"red\"\n").expect("write");
    let out = tribo_in(
        &[
            "sweep",
            "--oil",
            oil.to_str().expect("utf-8"),
            "--out",
            "o2",
        ],
        dir.path(),
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("oil.toml:3:") && stderr.contains("unknown field `colour`"),
        "{stderr}"
    );
}
