//! Law contract version 2 and the libraries built against version 1 (issue "Real engine
//! loading", point 4): a version-1 library still loads, and gives exactly the results of the
//! same law built against version 2, in Rust (abi_stable, the frozen version-1 module) and in
//! C (compiled here against the version-1 header as it was released, `tests/fixtures/c/v1`).
//!
//! The law is `contract-probe` (`tests/fixtures/contract-probe/law.rs` and
//! `tests/fixtures/c/contract_probe.c`): stateful, and reading the load, the sliding velocity,
//! the viscosity, the contact geometry, the crank angle and the step.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use tribo::plugin_api::loader::{LawInstance, LawLibrary};
use tribo::plugin_api::{JointKind, LawInput, LawOutput, CONTRACT_VERSION};

/// The four builds of the probe: (what, library, contract version it was built against).
fn probes(dir: &Path) -> Vec<(&'static str, PathBuf, u32)> {
    let c_v1 = dir.join("libprobe_c_v1.so");
    let c_v2 = dir.join("libprobe_c_v2.so");
    let source = [c_fixture("contract_probe.c")];
    compile_c_with(&source, &c_v1, true, &c_fixture("v1"));
    compile_c(&source, &c_v2, true);
    vec![
        ("Rust v1", built_library("tribo_fixture_probe_v1"), 1),
        ("Rust v2", built_library("tribo_fixture_probe_v2"), 2),
        ("C v1", c_v1, 1),
        ("C v2", c_v2, 2),
    ]
}

/// Inputs over both joint kinds, signs and sizes of velocity and load, crank angles, oils and
/// steps, with gas fields a version-1 law cannot see set to values it would notice.
fn inputs() -> Vec<LawInput> {
    let mut all = Vec::new();
    for kind in [JointKind::Revolute, JointKind::Prismatic] {
        for v in [-30.0, -0.7, -1e-4, 0.0, 2e-4, 0.9, 25.0] {
            for load in [0.0, 15.0, 4200.0] {
                for (k, theta) in [0.0, 1.3, 3.1, 5.9].into_iter().enumerate() {
                    let mut i = LawInput::at_rest(kind);
                    i.contact_radius_m = if kind == JointKind::Revolute {
                        0.017
                    } else {
                        0.0384
                    };
                    i.contact_length_m = 0.015 + 0.005 * k as f64;
                    i.normal_load_n = load;
                    i.reaction_x_n = 0.6 * load;
                    i.reaction_y_n = -0.8 * load;
                    i.oil_temp_c = 40.0 + 20.0 * k as f64;
                    i.viscosity_pa_s = 0.08 / (1.0 + k as f64);
                    i.engine_speed_rad_s = 314.0 + 10.0 * k as f64;
                    i.crank_angle_rad = theta;
                    i.time_s = 0.25 * k as f64;
                    i.dt_s = [0.0, 1e-5, 2e-4, 1e-3][k];
                    i.cylinder_pressure_pa = 3.2e6;
                    i.crankcase_pressure_pa = 1.4e5;
                    i.piston_from_tdc_m = 0.021;
                    i.cycle_angle_rad = theta + 4.0;
                    all.push(i.with_velocity(v));
                }
            }
        }
    }
    all
}

/// Every output of `law` along `inputs`, the state committed after each evaluation, and the
/// states themselves.
fn trajectory(law: &LawInstance, inputs: &[LawInput]) -> (Vec<LawOutput>, Vec<f64>) {
    let mut state = law.new_state().expect("state");
    let (mut outputs, mut states) = (Vec::new(), Vec::new());
    for i in inputs {
        outputs.push(law.evaluate(i, &state).expect("evaluates"));
        law.commit(i, &mut state).expect("commits");
        states.extend_from_slice(&state);
    }
    (outputs, states)
}

#[test]
fn v1_libraries_load_and_give_the_results_of_their_v2_builds() {
    let dir = tempfile::tempdir().expect("temp dir");
    let inputs = inputs();
    let mut results = Vec::new();
    for (what, path, version) in probes(dir.path()) {
        let lib = LawLibrary::load(&path).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(lib.contract_version(), version, "{what}");
        assert_eq!(lib.name(), "contract-probe");
        let law = lib.create(&toml::Table::new()).expect("defaults");
        assert_eq!(law.state_size(), 1, "{what}");
        results.push((what, trajectory(&law, &inputs)));
    }
    // Same language, v1 against v2: bit for bit, forces and states.
    for pair in [(0, 1), (2, 3)] {
        let (a, b) = (&results[pair.0], &results[pair.1]);
        assert_eq!(a.1, b.1, "{} and {} differ", a.0, b.0);
    }
    // Rust against C: the same formula through two compilers' libm, to rounding.
    let (rust, c) = (&results[1].1, &results[3].1);
    for (k, (r, c)) in rust.0.iter().zip(&c.0).enumerate() {
        let tol = 1e-12 * (1.0 + r.force.abs());
        assert!(
            (r.force - c.force).abs() <= tol,
            "input {k}: Rust {} vs C {}",
            r.force,
            c.force
        );
    }
    // The probe did something: some forces are large, and the state moved.
    assert!(rust.0.iter().any(|o| o.force.abs() > 10.0));
    assert!(rust.1.iter().any(|s| *s > 100.0));
}

/// `tribo run` of `rig` (steady) with the probe from `lib` on the big end and the piston.
fn run_with_probe(rig: &str, lib: &Path) -> serde_json::Value {
    let rig = workspace().join("rigs").join(rig);
    json_in(
        &[
            "run",
            rig.to_str().expect("utf-8"),
            "--plugin",
            lib.to_str().expect("utf-8"),
            "--law",
            "big_end=contract-probe",
            "--law",
            "piston=contract-probe",
            "--steady",
            "--json",
            "--quiet",
        ],
        &workspace(),
    )
}

#[test]
fn a_v1_library_runs_a_rig_exactly_like_its_v2_build() {
    let dir = tempfile::tempdir().expect("temp dir");
    let probes = probes(dir.path());
    // The thesis rig, and the head-on rig whose laws are handed non-atmospheric pressures.
    for rig in ["crf250r-motored.toml", "crf250r-compression.toml"] {
        let runs: Vec<serde_json::Value> = probes
            .iter()
            .map(|(_, path, _)| run_with_probe(rig, path))
            .collect();
        assert_eq!(runs[0], runs[1], "{rig}: Rust v1 and v2 runs differ");
        assert_eq!(runs[2], runs[3], "{rig}: C v1 and v2 runs differ");
        let torque = |r: &serde_json::Value| r["plateaus"][6]["motoring_torque_nm"].as_f64();
        let (rust, c) = (torque(&runs[1]), torque(&runs[3]));
        assert!(rust.is_some_and(|t| t > 0.0), "{rig}: {rust:?}");
        assert!(
            (rust.unwrap_or(0.0) - c.unwrap_or(0.0)).abs() < 1e-9,
            "{rig}: Rust {rust:?} vs C {c:?}"
        );
    }
}

#[test]
fn laws_list_the_contract_version_they_were_built_against() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (what, path, version) in probes(dir.path()) {
        let p = path.to_str().expect("utf-8");
        let listing = json_in(&["laws", "--plugin", p, "--json"], &workspace());
        let law = listing["laws"]
            .as_array()
            .and_then(|laws| laws.iter().find(|l| l["file"] == p))
            .unwrap_or_else(|| panic!("{what} listed: {listing}"));
        assert_eq!(law["contract_version"], version, "{what}");
        let listed = tribo_in(&["laws", "--plugin", p], &workspace());
        let (stdout, _) = text(&listed);
        let line = stdout
            .lines()
            .find(|l| l.contains(p))
            .unwrap_or_else(|| panic!("{what}: {stdout}"));
        assert_eq!(
            line.contains("contract v1"),
            version == 1,
            "{what}: an adapted library says so: {line}"
        );
    }
    assert_eq!(CONTRACT_VERSION, 2);
}

#[test]
fn versions_outside_the_supported_range_are_refused_with_the_range() {
    let dir = tempfile::tempdir().expect("temp dir");
    for version in [0, CONTRACT_VERSION + 1] {
        let src = dir.path().join(format!("v{version}.c"));
        std::fs::write(
            &src,
            format!("unsigned tribo_law_contract_version(void) {{ return {version}u; }}\n"),
        )
        .expect("write");
        let lib = dir.path().join(format!("libv{version}.so"));
        compile_c(&[src], &lib, true);
        let l = lib.to_str().expect("utf-8");
        let out = tribo_in(&["laws", "--plugin", l], &workspace());
        assert!(!out.status.success());
        let (_, stderr) = text(&out);
        assert_mentions(
            &stderr,
            &[
                l,
                &format!("contract version {version}"),
                "still loads versions 1 to 2",
            ],
        );
    }
}
