//! The law author's workflow end to end: `tribo new-law` in a copy of the workspace, the
//! generated unit tests pass, the library builds, `tribo laws` lists it, and evaluating it
//! through the loaded library gives the value of its documented formula.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;
use tribo::plugin_api::loader::{Abi, LawLibrary};
use tribo::plugin_api::{JointKind, LawInput};

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("create dir");
    for entry in std::fs::read_dir(from).expect("read dir") {
        let entry = entry.expect("dir entry");
        let name = entry.file_name();
        if name == "target" || name == ".git" {
            continue;
        }
        let (src, dst) = (entry.path(), to.join(&name));
        if entry.file_type().expect("file type").is_dir() {
            copy_tree(&src, &dst);
        } else {
            std::fs::copy(&src, &dst).expect("copy file");
        }
    }
}

fn cargo(ws: &Path, target: &Path, args: &[&str]) -> String {
    let out = Command::new(env!("CARGO"))
        .args(args)
        .current_dir(ws)
        .env("CARGO_TARGET_DIR", target)
        .output()
        .expect("cargo runs");
    let all = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "cargo {args:?} failed:\n{all}");
    all
}

/// The formula the generated law documents: mu = mu_0 + slope*|v_s|, F = -mu*N*arm*sgn_eps(v_s).
fn template_formula(
    mu0: f64,
    slope: f64,
    eps: f64,
    kind: JointKind,
    v: f64,
    n: f64,
    r: f64,
) -> f64 {
    let arm = if kind == JointKind::Revolute { r } else { 1.0 };
    let vs = v * arm;
    -(mu0 + slope * vs.abs()) * n * arm * vs / (vs * vs + eps * eps).sqrt()
}

#[test]
fn new_law_builds_is_listed_and_evaluates_its_formula() {
    ensure_plugins_built();
    let tmp = tempfile::tempdir().expect("temp dir");
    let ws = tmp.path().join("tribo");
    copy_tree(&workspace(), &ws);
    // Nested builds get their own target directory so they never race the outer build.
    let target = workspace().join("target/e2e-new-law");

    let out = Command::new(tribo_exe())
        .args(["new-law", "my-law"])
        .current_dir(&ws)
        .output()
        .expect("tribo runs");
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("created tribo-law-my-law"), "{stdout}");
    let crate_dir = ws.join("plugins/my-law");
    for f in ["Cargo.toml", "src/lib.rs", "README.md"] {
        assert!(crate_dir.join(f).is_file(), "{f} not generated");
    }
    let readme = std::fs::read_to_string(crate_dir.join("README.md")).expect("readme");
    assert!(
        readme.contains("cargo build --release -p tribo-law-my-law"),
        "{readme}"
    );

    // Refuses to overwrite.
    let again = Command::new(tribo_exe())
        .args(["new-law", "my-law"])
        .current_dir(&ws)
        .output()
        .expect("runs");
    assert!(!again.status.success());
    assert!(text(&again).1.contains("already exists"));

    // The generated unit tests of the law's math pass as generated.
    let test_log = cargo(&ws, &target, &["test", "-p", "tribo-law-my-law"]);
    assert!(test_log.contains("4 passed"), "{test_log}");
    // The README's build command.
    cargo(
        &ws,
        &target,
        &["build", "--release", "-p", "tribo-law-my-law"],
    );
    let built = target
        .join("release")
        .join(tribo::plugin_api::loader::plugin_file_name(
            "tribo_law_my_law",
        ));
    assert!(built.is_file(), "{} missing", built.display());

    // Discovered from a plugin directory and listed.
    let plugin_dir = tmp.path().join("plugins");
    std::fs::create_dir_all(&plugin_dir).expect("mkdir");
    let installed = plugin_dir.join(built.file_name().expect("name"));
    std::fs::copy(&built, &installed).expect("copy");
    let out = run_tribo(&["laws", "--json"], Some(&plugin_dir));
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).expect("json");
    let law = json["laws"]
        .as_array()
        .and_then(|l| l.iter().find(|l| l["name"] == "my-law"))
        .unwrap_or_else(|| panic!("my-law not listed: {stdout}"));
    assert_eq!(law["abi"], "rust");
    assert_eq!(law["file"], installed.to_str().expect("utf-8"));

    // Evaluated through the loaded library: the documented formula.
    let lib = LawLibrary::load(&installed).expect("loads");
    assert_eq!(lib.abi(), Abi::Rust);
    let params: toml::Table = "mu_0 = 0.1\nslope = 0.02".parse().expect("toml");
    let inst = lib.create(&params).expect("creates");
    let eps = 1e-3; // the template's default v_smooth
    for (kind, v, n, r) in [
        (JointKind::Prismatic, 5.0, 200.0, 0.0),
        (JointKind::Prismatic, -0.7, 1500.0, 0.0),
        (JointKind::Revolute, 300.0, 2500.0, 0.02),
        (JointKind::Prismatic, 2e-4, 100.0, 0.0),
    ] {
        let mut input = LawInput::at_rest(kind);
        input.normal_load_n = n;
        input.contact_radius_m = r;
        let input = input.with_velocity(v);
        let got = inst.evaluate(&input, &[]).expect("evaluates").force;
        let want = template_formula(0.1, 0.02, eps, kind, v, n, r);
        assert!(
            (got - want).abs() <= 1e-12 * (1.0 + want.abs()),
            "{kind:?} v={v}: {got} vs {want}"
        );
    }
    // The README's comparison: the new law on the piston beside the two bundled law sets.
    let lawset = tmp.path().join("my-lawset.toml");
    std::fs::write(&lawset, "name = \"my-law\"\n\n[[laws]]\njoint = \"piston\"\nlaw = \"my-law\"\nparams = { mu_0 = 0.05, slope = 0.01 }\n").expect("write");
    let out = Command::new(tribo_exe())
        .args([
            "compare",
            "--lawset",
            "fedem-baseline",
            "--lawset",
            "stribeck-duty",
            "--lawset",
        ])
        .arg(&lawset)
        .args(["--steady", "--json", "--out"])
        .arg(tmp.path().join("cmp"))
        .env("TRIBO_PLUGIN_PATH", &plugin_dir)
        .output()
        .expect("tribo runs");
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let cmp: serde_json::Value = serde_json::from_str(&stdout).expect("json");
    let names: Vec<&str> = cmp["sets"]
        .as_array()
        .expect("sets")
        .iter()
        .filter_map(|s| s["lawset"].as_str())
        .collect();
    assert_eq!(names, ["fedem-baseline", "stribeck-duty", "my-law"]);
    let mine = &cmp["sets"][2]["run"]["plateaus"][0]["joints"][0];
    assert_eq!(
        (mine["joint"].as_str(), mine["law"].as_str()),
        (Some("piston"), Some("my-law"))
    );
    assert!(mine["friction_torque_nm"].as_f64().is_some_and(|t| t > 0.0));
    assert!(tmp.path().join("cmp/torque_vs_speed.svg").is_file());

    // At 5 m/s and 200 N the formula is -(0.1 + 0.02*5)*200 = -40 N to within the smoothing.
    let mut input = LawInput::at_rest(JointKind::Prismatic);
    input.normal_load_n = 200.0;
    let f = inst
        .evaluate(&input.with_velocity(5.0), &[])
        .expect("evaluates")
        .force;
    assert!((f + 40.0).abs() < 1e-6, "{f}");
}

#[test]
fn new_law_outside_the_workspace_is_a_standalone_crate_pointing_at_plugin_api() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let elsewhere = tmp.path().join("my-laws");
    let out = Command::new(tribo_exe())
        .args(["new-law", "shear-law", "--dir"])
        .arg(&elsewhere)
        .current_dir(workspace())
        .output()
        .expect("tribo runs");
    assert!(out.status.success(), "{}", text(&out).1);
    let manifest =
        std::fs::read_to_string(elsewhere.join("shear-law/Cargo.toml")).expect("manifest");
    assert!(manifest.contains("[workspace]"), "{manifest}");
    let api = manifest
        .lines()
        .find_map(|l| l.strip_prefix("tribo-plugin-api = { path = \""))
        .and_then(|l| l.strip_suffix("\" }"))
        .expect("plugin-api path dependency");
    assert!(
        elsewhere
            .join("shear-law")
            .join(api)
            .join("Cargo.toml")
            .is_file(),
        "{api}"
    );
}

#[test]
fn bad_law_names_are_refused() {
    for bad in ["My_Law", "-x", "a--b"] {
        let out = Command::new(tribo_exe())
            .args(["new-law", "--", bad])
            .current_dir(workspace())
            .output()
            .expect("runs");
        assert!(!out.status.success());
        assert!(text(&out).1.contains("not a valid law name"), "{bad}");
    }
}
