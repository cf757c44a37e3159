//! The law author's workflow end to end: `tribo new-law` in a copy of the workspace, the
//! generated unit tests pass, the library builds, `tribo laws` lists it, and evaluating it
//! through the loaded library gives the value of its documented formula. The same for each
//! language (Rust, C, C++, Fortran): every template builds without a warning, passes its own
//! unit tests, loads, describes the same parameters and gives the same torques in `tribo run`
//! and `tribo compare`. Needs make, cc, c++ and gfortran (`.ci/setup-toolchains`).

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
    cargo_with(ws, target, args, &[])
}

fn cargo_with(ws: &Path, target: &Path, args: &[&str], env: &[(&str, &str)]) -> String {
    let out = Command::new(env!("CARGO"))
        .args(args)
        .current_dir(ws)
        .env("CARGO_TARGET_DIR", target)
        .envs(env.iter().copied())
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

    // The README's test command stays green with the new crate in the workspace: formatted
    // as generated, and clippy-clean with warnings denied.
    cargo(&ws, &target, &["fmt", "--all", "--check"]);
    cargo(
        &ws,
        &target,
        &[
            "clippy",
            "-p",
            "tribo-law-my-law",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ],
    );

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

/// `make ARGS` in `dir`: its standard output and error together; panics if it fails.
fn make(dir: &Path, args: &[&str]) -> String {
    let out = Command::new("make")
        .args(args)
        .current_dir(dir)
        .env_remove("TRIBO_INCLUDE")
        .output()
        .unwrap_or_else(|e| panic!("make cannot start ({e}); run .ci/setup-toolchains"));
    let (stdout, stderr) = text(&out);
    let all = format!("{stdout}{stderr}");
    assert!(
        out.status.success(),
        "make {args:?} in {} failed:\n{all}",
        dir.display()
    );
    all
}

/// `tribo new-law NAME --lang LANG [--dir DIR]` in `cwd`; panics unless it succeeds.
fn new_law(cwd: &Path, name: &str, lang: &str, dir: Option<&Path>) -> String {
    let mut cmd = Command::new(tribo_exe());
    cmd.args(["new-law", name, "--lang", lang]).current_dir(cwd);
    if let Some(d) = dir {
        cmd.arg("--dir").arg(d);
    }
    let out = cmd.output().expect("tribo runs");
    let (stdout, stderr) = text(&out);
    assert!(
        out.status.success(),
        "new-law {name} --lang {lang}: {stderr}"
    );
    stdout
}

/// The parameters every language's law is run with: none of them the default, and each of a
/// different size, so a law that read them in another order would give other numbers.
const PARAMS_TOML: &str = "mu_0 = 0.08\nslope = 0.015\nv_smooth = 2e-3\n";

/// Plateau motoring torques and the piston's friction torques of `tribo run --steady` with law
/// `name` from `library` on the piston.
fn steady_run(library: &Path, name: &str, params: &Path) -> (Vec<f64>, Vec<f64>) {
    let law = format!("piston={name}:{}", params.display());
    let out = Command::new(tribo_exe())
        .args([
            "run",
            "crf250r-motored",
            "--steady",
            "--json",
            "--law",
            &law,
            "--plugin",
        ])
        .arg(library)
        .env_remove("TRIBO_PLUGIN_PATH")
        .output()
        .expect("tribo runs");
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "tribo run with {name}: {stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).expect("json");
    let plateaus = json["plateaus"].as_array().expect("plateaus");
    let mut motoring = Vec::new();
    let mut piston = Vec::new();
    for p in plateaus {
        motoring.push(p["motoring_torque_nm"].as_f64().expect("motoring torque"));
        let joint = p["joints"]
            .as_array()
            .and_then(|j| j.iter().find(|j| j["joint"] == "piston"))
            .expect("the piston joint");
        assert_eq!(joint["law"], name, "{stdout}");
        piston.push(
            joint["friction_torque_nm"]
                .as_f64()
                .expect("friction torque"),
        );
    }
    (motoring, piston)
}

fn assert_close(what: &str, a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len(), "{what}: {a:?} vs {b:?}");
    for (x, y) in a.iter().zip(b) {
        assert!(
            (x - y).abs() <= 1e-12 * x.abs().max(y.abs()),
            "{what}: {x:e} vs {y:e} ({a:?} vs {b:?})"
        );
    }
}

#[test]
fn every_language_template_builds_loads_and_gives_the_same_torques() {
    ensure_plugins_built();
    let tmp = tempfile::tempdir().expect("temp dir");
    let ws = tmp.path().join("tribo");
    copy_tree(&workspace(), &ws);
    // Its own target directory: the other end-to-end test builds another copy of the
    // workspace at another path at the same time, and one directory shared by the two copies
    // made this test fail once in a parallel run.
    let target = workspace().join("target/e2e-new-law-languages");
    let laws_dir = tmp.path().join("laws");
    let params = tmp.path().join("params.toml");
    std::fs::write(&params, PARAMS_TOML).expect("write params");

    let mut built: Vec<(&str, String, std::path::PathBuf)> = Vec::new();

    // Rust: a workspace member, built as its README says; plugin-api is built here as every
    // law author builds it (without the host's loader feature), and must not warn, nor must its
    // documentation.
    let stdout = new_law(&ws, "same-rust", "rust", None);
    assert!(stdout.contains("created tribo-law-same-rust"), "{stdout}");
    let test_log = cargo(&ws, &target, &["test", "-p", "tribo-law-same-rust"]);
    assert!(test_log.contains("4 passed"), "{test_log}");
    let build_log = cargo(
        &ws,
        &target,
        &["build", "--release", "-p", "tribo-law-same-rust"],
    );
    assert!(!build_log.contains("warning"), "{build_log}");
    cargo_with(
        &ws,
        &target,
        &[
            "doc",
            "--no-deps",
            "-p",
            "tribo-plugin-api",
            "-p",
            "tribo-law-same-rust",
        ],
        &[("RUSTDOCFLAGS", "-D warnings")],
    );
    built.push((
        "rust",
        "same-rust".into(),
        target
            .join("release")
            .join(tribo::plugin_api::loader::plugin_file_name(
                "tribo_law_same_rust",
            )),
    ));

    // C, C++, Fortran: a folder each, generated from inside the checkout (so the Makefile points
    // at its plugin-api/include), tested and built by its Makefile.
    for lang in ["c", "cpp", "fortran"] {
        let name = format!("same-{lang}");
        let stdout = new_law(&ws, &name, lang, Some(&laws_dir));
        assert!(
            stdout.contains(&format!("created law `{name}` ({lang})")),
            "{stdout}"
        );
        let dir = laws_dir.join(&name);
        let makefile = std::fs::read_to_string(dir.join("Makefile")).expect("Makefile");
        let include = ws.join("plugin-api/include");
        assert!(
            makefile.contains(&format!("TRIBO_INCLUDE ?= {}\n", include.display())),
            "{makefile}"
        );
        assert!(std::fs::read_to_string(dir.join("README.md"))
            .expect("README")
            .contains("make test"));
        let test_log = make(&dir, &["test"]);
        assert!(
            test_log.contains(&format!("{name}: all tests passed")),
            "{test_log}"
        );
        let build_log = make(&dir, &[]);
        // Both builds compile with -Wall -Wextra (gfortran: -Wall -Wextra): `make test`
        // compiles what `make` then only links (Fortran's objects), so both logs are read.
        for log in [&test_log, &build_log] {
            assert!(!log.to_lowercase().contains("warning"), "{lang}: {log}");
        }
        let snake = name.replace('-', "_");
        let lib = dir.join(tribo::plugin_api::loader::plugin_file_name(&format!(
            "tribo_law_{snake}"
        )));
        assert!(lib.is_file(), "{} not built", lib.display());
        built.push((lang, name, lib));
    }

    // Every template's law passes the conformance checks, by library path as an author runs
    // them (`make check` runs the same command for C, C++ and Fortran).
    for (lang, _, lib) in &built {
        let out = std::process::Command::new(tribo_exe())
            .arg("check-law")
            .arg(lib)
            .env_remove("TRIBO_PLUGIN_PATH")
            .output()
            .expect("tribo check-law runs");
        let (stdout, stderr) = text(&out);
        assert!(
            out.status.success() && !stdout.contains("FAIL"),
            "{lang}: check-law failed:\n{stdout}{stderr}"
        );
    }

    // Loaded by tribo's loader: the right ABI, the same description, and the documented formula
    // at hand-picked points, identical in every language.
    let table: toml::Table = PARAMS_TOML.parse().expect("toml");
    let mut reference: Option<(tribo::plugin_api::LawDescription, Vec<f64>)> = None;
    for (lang, name, lib_path) in &built {
        let lib = LawLibrary::load(lib_path).expect("loads");
        assert_eq!(
            lib.abi(),
            if *lang == "rust" { Abi::Rust } else { Abi::C },
            "{lang}"
        );
        let mut description = lib.description().clone();
        assert_eq!(&description.name, name);
        description.name.clear();
        let inst = lib.create(&table).expect("creates");
        let mut forces = Vec::new();
        for (kind, v, n, r) in [
            (JointKind::Prismatic, 5.0, 200.0, 0.0),
            (JointKind::Prismatic, -0.7, 1500.0, 0.0),
            (JointKind::Revolute, 300.0, 2500.0, 0.02),
            (JointKind::Prismatic, 2e-4, 100.0, 0.0),
            (JointKind::Prismatic, 0.0, 100.0, 0.0),
        ] {
            let mut input = LawInput::at_rest(kind);
            input.normal_load_n = n;
            input.contact_radius_m = r;
            let out = inst
                .evaluate(&input.with_velocity(v), &[])
                .expect("evaluates");
            let want = template_formula(0.08, 0.015, 2e-3, kind, v, n, r);
            assert!(
                (out.force - want).abs() <= 1e-12 * (1.0 + want.abs()),
                "{lang} {kind:?} v={v}: {} vs {want}",
                out.force
            );
            let vs = input.with_velocity(v).sliding_velocity_m_s;
            assert_eq!(out.coefficient(), Some(0.08 + 0.015 * vs.abs()), "{lang}");
            forces.push(out.force);
        }
        match &reference {
            None => reference = Some((description, forces)),
            Some((d, f)) => {
                assert_eq!(&description, d, "{lang}: description differs from Rust's");
                assert_close(&format!("{lang} forces"), &forces, f);
            }
        }
    }

    // `tribo run` on the bundled rig, the law on the piston: the same plateau torques from
    // every language.
    let runs: Vec<(Vec<f64>, Vec<f64>)> = built
        .iter()
        .map(|(_, name, lib)| steady_run(lib, name, &params))
        .collect();
    assert!(runs[0].1.iter().all(|t| *t > 0.0), "{:?}", runs[0]);
    for ((lang, _, _), run) in built.iter().zip(&runs).skip(1) {
        assert_close(&format!("{lang} motoring torques"), &run.0, &runs[0].0);
        assert_close(&format!("{lang} piston torques"), &run.1, &runs[0].1);
    }

    // `tribo compare --law`: the law as one new set of its own, named after it (on the first
    // set's other joints), no bundled set carrying it; the same torques from every language.
    let mut added: Vec<Vec<f64>> = Vec::new();
    for (lang, name, lib) in &built {
        let out = Command::new(tribo_exe())
            .args(["compare", "--steady", "--no-cv", "--json", "--law"])
            .arg(format!("piston={name}:{}", params.display()))
            .arg("--plugin")
            .arg(lib)
            .arg("--out")
            .arg(tmp.path().join(format!("compare-{lang}")))
            .env_remove("TRIBO_PLUGIN_PATH")
            .output()
            .expect("tribo runs");
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "compare with {name}: {stderr}");
        let cmp: serde_json::Value = serde_json::from_str(&stdout).expect("json");
        let sets = cmp["sets"].as_array().expect("sets");
        let mut own = None;
        for set in sets {
            let plateaus = set["run"]["plateaus"].as_array().expect("plateaus");
            let carries = plateaus[0]["joints"]
                .as_array()
                .expect("joints")
                .iter()
                .any(|j| j["joint"] == "piston" && j["law"] == name.as_str());
            let is_new = set["lawset"] == name.as_str();
            assert_eq!(
                carries, is_new,
                "{lang}: {name} on the piston of {}",
                set["lawset"]
            );
            if is_new {
                assert!(own.is_none(), "{lang}: two sets named {name}");
                own = Some(
                    plateaus
                        .iter()
                        .map(|p| p["motoring_torque_nm"].as_f64().unwrap_or(f64::NAN))
                        .collect::<Vec<f64>>(),
                );
            }
        }
        added.push(own.unwrap_or_else(|| panic!("{lang}: no set named {name}")));
    }
    for ((lang, _, _), torques) in built.iter().zip(&added).skip(1) {
        assert_close(&format!("{lang} compare torques"), torques, &added[0]);
    }
}

#[test]
fn a_c_law_generated_outside_a_checkout_carries_its_header_and_builds() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let stdout = new_law(tmp.path(), "lone-law", "c", None);
    assert!(stdout.contains("created law `lone-law` (c)"), "{stdout}");
    let dir = tmp.path().join("lone-law");
    // No checkout above the temporary directory: the header travels with the law, and is the
    // header of this tribo.
    let copied = std::fs::read_to_string(dir.join("include/tribo_law.h")).expect("header");
    let original = std::fs::read_to_string(workspace().join("plugin-api/include/tribo_law.h"))
        .expect("header");
    assert_eq!(copied, original);
    let test_log = make(&dir, &["test"]);
    assert!(
        test_log.contains("lone-law: all tests passed"),
        "{test_log}"
    );
    make(&dir, &[]);
    let lib = LawLibrary::load(&dir.join(tribo::plugin_api::loader::plugin_file_name(
        "tribo_law_lone_law",
    )))
    .expect("loads");
    assert_eq!(lib.name(), "lone-law");

    // A Rust law needs the checkout's plugin-api, and says so.
    let out = Command::new(tribo_exe())
        .args(["new-law", "lone-rust"])
        .current_dir(tmp.path())
        .output()
        .expect("tribo runs");
    assert!(!out.status.success());
    assert!(
        text(&out).1.contains("no Tribo workspace"),
        "{}",
        text(&out).1
    );
}

#[test]
fn an_unknown_language_is_refused_with_the_choices() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let out = Command::new(tribo_exe())
        .args(["new-law", "py-law", "--lang", "python"])
        .current_dir(tmp.path())
        .output()
        .expect("tribo runs");
    assert_eq!(out.status.code(), Some(2), "clap's usage error");
    let stderr = text(&out).1;
    assert!(stderr.contains("rust, c, cpp or fortran"), "{stderr}");
    assert!(!tmp.path().join("py-law").exists());
}

/// `cargo fmt --check` accepts the generated Rust law whatever the length of its name (the
/// names end up in lines rustfmt would otherwise rewrap).
#[test]
fn generated_rust_law_is_formatted_for_short_and_long_names() {
    let tmp = tempfile::tempdir().expect("temp dir");
    let rustfmt = std::path::PathBuf::from(env!("CARGO")).with_file_name("rustfmt");
    for name in [
        "a",
        "probe-law",
        "abcdefghij-abcdefghij-abcdefghij-abcdefghij-abcd",
    ] {
        let out = Command::new(tribo_exe())
            .args(["new-law", name, "--dir"])
            .arg(tmp.path())
            .current_dir(workspace())
            .output()
            .expect("tribo runs");
        assert!(out.status.success(), "{}", text(&out).1);
        let lib = tmp.path().join(name).join("src/lib.rs");
        let check = Command::new(&rustfmt)
            .args(["--edition", "2021", "--check"])
            .arg(&lib)
            .output()
            .expect("rustfmt runs");
        assert!(
            check.status.success(),
            "{name}: rustfmt --check:\n{}",
            text(&check).0
        );
    }
}
