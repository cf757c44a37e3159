//! Law contract version 3 and the libraries built against versions 1 and 2: an older library
//! still loads and gives exactly the results of the same law built against version 3, in Rust
//! (abi_stable, the frozen version-1 and version-2 modules) and in C (compiled here against
//! the version-1 and version-2 headers as they were released, `tests/fixtures/c/v1`, `v2`); a
//! version-3 law sees the version-3 inputs, reports the version-3 outputs, declares what it
//! suits and evaluates batches.
//!
//! The law is `contract-probe` (`tests/fixtures/contract-probe/law.rs` and
//! `tests/fixtures/c/contract_probe.c`): stateful, its force reading the load, the sliding
//! velocity, the viscosity, the contact geometry, the crank angle and the step; its
//! version-3 outputs echo the version-3 inputs by formulas written out again below.

mod common;

use std::path::{Path, PathBuf};

use common::*;
use tribo::plugin_api::contract::v2::FLAGS as V2_FLAGS;
use tribo::plugin_api::loader::{LawInstance, LawLibrary};
use tribo::plugin_api::{
    smooth_sign, BearingType, JointKind, LawInput, LawOutput, CONTRACT_VERSION, DIAGNOSTIC_FLAGS,
    HAS_COEFFICIENT, HAS_LOAD_DERIVATIVE, SUITS_PLAIN, SUITS_SLIDE,
};

/// One build of the probe.
struct Build {
    what: &'static str,
    path: PathBuf,
    /// The contract version it was built against.
    version: u32,
    rust: bool,
}

/// The six builds of the probe: Rust and C, against versions 1, 2 and 3.
fn probes(dir: &Path) -> Vec<Build> {
    let source = [c_fixture("contract_probe.c")];
    let mut builds = Vec::new();
    for (version, rust_lib, what_rust, what_c) in [
        (1, "tribo_fixture_probe_v1", "Rust v1", "C v1"),
        (2, "tribo_fixture_probe_v2", "Rust v2", "C v2"),
        (3, "tribo_fixture_probe_v3", "Rust v3", "C v3"),
    ] {
        let c = dir.join(format!("libprobe_c_v{version}.so"));
        if version == CONTRACT_VERSION {
            compile_c(&source, &c, true);
        } else {
            compile_c_with(&source, &c, true, &c_fixture(&format!("v{version}")));
        }
        builds.push(Build {
            what: what_rust,
            path: built_library(rust_lib),
            version,
            rust: true,
        });
        builds.push(Build {
            what: what_c,
            path: c,
            version,
            rust: false,
        });
    }
    builds
}

/// The probe's law from `b`, checked to say its version.
fn probe_law(b: &Build) -> (LawLibrary, LawInstance) {
    let lib = LawLibrary::load(&b.path).unwrap_or_else(|e| panic!("{}: {e}", b.what));
    assert_eq!(lib.contract_version(), b.version, "{}", b.what);
    assert_eq!(lib.name(), "contract-probe");
    let law = lib.create(&toml::Table::new()).expect("defaults");
    assert_eq!(law.state_size(), 1, "{}", b.what);
    (lib, law)
}

/// Inputs over both joint kinds, signs and sizes of velocity and load, crank angles, oils and
/// steps, with fields an older law cannot see (the gas state, the version-3 fields) set to
/// values it would notice.
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
                    i.inner_body = (k % 2) as u32;
                    i.bearing_type = k as u32;
                    i.load_on_inner_x_n = -0.6 * load;
                    i.load_on_inner_y_n = 0.8 * load;
                    let b = (0.3 * theta, 120.0 - 50.0 * k as f64);
                    all.push(i.with_bodies((theta, b.1 + v), b));
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

/// The version-3 outputs the probe's formulas give for `i` with state `s`: dF/dN, min film,
/// eccentricity (x, y), peak pressure, asperity share (law.rs, written out again here).
fn expected_v3(i: &LawInput) -> [f64; 6] {
    let (sign, _) = smooth_sign(i.sliding_velocity_m_s, 1e-3);
    let arm = if i.kind() == Some(JointKind::Revolute) {
        i.contact_radius_m
    } else {
        1.0
    };
    let (a, b) = (i.body_a_angle, i.body_b_angle);
    let bearing = f64::from(i.bearing_type);
    [
        -sign * 0.05 * 0.5 * (1.0 + 0.05 * i.crank_angle_rad.cos()) * arm,
        1e-6 * (1.0 + 0.5 * a.sin()) * (1.0 + 1e-3 * (i.body_a_velocity + i.body_b_velocity).abs()),
        0.5 * b.cos(),
        0.4 * (a - b).sin(),
        1e3 * i.load_on_inner_x_n.hypot(i.load_on_inner_y_n) + 1e5 * bearing,
        (bearing + 4.0 * f64::from(i.inner_body)) / 8.0,
    ]
}

/// The version-3 fields of an output, in [`expected_v3`]'s order.
fn v3_fields(o: &LawOutput) -> [f64; 6] {
    [
        o.dforce_dload,
        o.min_film_m,
        o.eccentricity_x,
        o.eccentricity_y,
        o.peak_pressure_pa,
        o.asperity_share,
    ]
}

/// An output without its version-3 part, as bits: what every version must agree on.
fn v2_bits(o: &LawOutput) -> [u64; 6] {
    [
        o.force.to_bits(),
        o.coefficient.to_bits(),
        o.duty_parameter.to_bits(),
        o.dforce_dvelocity.to_bits(),
        u64::from(o.regime),
        u64::from(o.flags & V2_FLAGS),
    ]
}

#[test]
fn older_libraries_load_and_give_the_results_of_their_v3_builds() {
    let dir = tempfile::tempdir().expect("temp dir");
    let inputs = inputs();
    let builds = probes(dir.path());
    let results: Vec<(Vec<LawOutput>, Vec<f64>)> = builds
        .iter()
        .map(|b| trajectory(&probe_law(b).1, &inputs))
        .collect();
    for (b, (outputs, states)) in builds.iter().zip(&results) {
        // Same language, each older version against version 3: bit for bit, forces, the
        // other version-2 outputs and states.
        let v3 = builds
            .iter()
            .position(|c| c.rust == b.rust && c.version == CONTRACT_VERSION)
            .expect("a v3 build");
        let (v3_out, v3_states) = &results[v3];
        assert_eq!(
            states, v3_states,
            "{} and its v3 build differ in state",
            b.what
        );
        for (k, (o, r)) in outputs.iter().zip(v3_out).enumerate() {
            assert_eq!(v2_bits(o), v2_bits(r), "{}, input {k}", b.what);
            if b.version < 3 {
                // Only the flags its version knew (the C build set others), and no
                // version-3 output.
                assert_eq!(o.flags, HAS_COEFFICIENT, "{}, input {k}", b.what);
                assert_eq!(v3_fields(o), [0.0; 6], "{}, input {k}", b.what);
            } else {
                assert_eq!(
                    o.flags,
                    HAS_COEFFICIENT | HAS_LOAD_DERIVATIVE | DIAGNOSTIC_FLAGS
                );
            }
        }
    }
    // Rust against C: the same formula through two compilers' libm, to rounding.
    let (rust, c) = (&results[4], &results[5]);
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

#[test]
fn a_v3_law_sees_the_v3_inputs_and_reports_the_v3_outputs() {
    let dir = tempfile::tempdir().expect("temp dir");
    let inputs = inputs();
    // Every bearing type and both inner bodies are among the inputs.
    for t in 0..4 {
        assert!(inputs
            .iter()
            .any(|i| i.bearing() == BearingType::from_u32(t)));
    }
    assert!(inputs.iter().any(|i| i.inner_body == 1));
    for b in probes(dir.path()).iter().filter(|b| b.version == 3) {
        let (lib, law) = probe_law(b);
        assert_eq!(lib.suits(), SUITS_PLAIN | SUITS_SLIDE, "{}", b.what);
        let state = law.new_state().expect("state");
        for (k, i) in inputs.iter().enumerate() {
            let out = law.evaluate(i, &state).expect("evaluates");
            assert_eq!(out.bad_diagnostic(), None, "{}, input {k}", b.what);
            for (got, want) in v3_fields(&out).into_iter().zip(expected_v3(i)) {
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1e-300),
                    "{}, input {k}: {got} vs {want}",
                    b.what
                );
            }
        }
        // The load derivative is the force's: a finite difference in the load agrees.
        let i = inputs
            .iter()
            .find(|i| i.normal_load_n > 1000.0 && i.relative_velocity > 1.0);
        let i = i.expect("a loaded, sliding input");
        let f = |n: f64| {
            let mut j = *i;
            j.normal_load_n = n;
            law.evaluate(&j, &state).expect("evaluates").force
        };
        let d = law.evaluate(i, &state).expect("evaluates").dforce_dload;
        let fd = (f(i.normal_load_n + 1.0) - f(i.normal_load_n - 1.0)) / 2.0;
        assert!(
            (fd - d).abs() <= 1e-9 * d.abs(),
            "{}: dF/dN {d} vs {fd}",
            b.what
        );
    }
}

#[test]
fn evaluate_many_gives_evaluate_in_every_version_and_names_a_failing_input() {
    let dir = tempfile::tempdir().expect("temp dir");
    let inputs = inputs();
    for b in probes(dir.path()) {
        let (_, law) = probe_law(&b);
        // The library's own batch call from version 3 on, the host's loop before.
        assert_eq!(law.evaluates_batches(), b.version == 3, "{}", b.what);
        let states: Vec<f64> = (0..inputs.len()).map(|k| 3.0 * k as f64).collect();
        let mut outputs = vec![LawOutput::force(0.0); inputs.len()];
        law.evaluate_many(&inputs, &states, 1, &mut outputs)
            .unwrap_or_else(|e| panic!("{}: {e}", b.what));
        for (k, (i, o)) in inputs.iter().zip(&outputs).enumerate() {
            let alone = law.evaluate(i, &states[k..k + 1]).expect("evaluates");
            assert_eq!(o, &alone, "{}, input {k}", b.what);
        }
        // One shared state.
        law.evaluate_many(&inputs, &[50.0], 0, &mut outputs)
            .unwrap_or_else(|e| panic!("{}: {e}", b.what));
        let alone = law.evaluate(&inputs[17], &[50.0]).expect("evaluates");
        assert_eq!(outputs[17], alone, "{}", b.what);
        // A failing input is found and named, with the error it gives alone.
        let mut bad = inputs[..12].to_vec();
        bad[7].normal_load_n = -1.0;
        let e = law
            .evaluate_many(&bad, &states[..12], 1, &mut outputs[..12])
            .unwrap_err();
        assert_eq!(e.index, Some(7), "{}: {e}", b.what);
        let msg = e.to_string();
        let why = if b.rust {
            "negative normal load"
        } else {
            "error code 3"
        };
        assert_mentions(&msg, &["batch input 7", "contract-probe", why]);
    }
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
fn older_libraries_run_a_rig_exactly_like_their_v3_builds() {
    let dir = tempfile::tempdir().expect("temp dir");
    let probes = probes(dir.path());
    // The thesis rig, and the head-on rig whose laws are handed non-atmospheric pressures.
    for rig in ["crf250r-motored.toml", "crf250r-compression.toml"] {
        let runs: Vec<serde_json::Value> = probes
            .iter()
            .map(|b| run_with_probe(rig, &b.path))
            .collect();
        // Rust v1, C v1, Rust v2, C v2, Rust v3, C v3.
        for k in 0..4 {
            assert_eq!(
                runs[k],
                runs[k + 2],
                "{rig}: {} and {} runs differ",
                probes[k].what,
                probes[k + 2].what
            );
        }
        let torque = |r: &serde_json::Value| r["plateaus"][6]["motoring_torque_nm"].as_f64();
        let (rust, c) = (torque(&runs[4]), torque(&runs[5]));
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
    for Build {
        what,
        path,
        version,
        ..
    } in probes(dir.path())
    {
        let p = path.to_str().expect("utf-8");
        let listing = json_in(&["laws", "--plugin", p, "--json"], &workspace());
        let law = listing["laws"]
            .as_array()
            .and_then(|laws| laws.iter().find(|l| l["file"] == p))
            .unwrap_or_else(|| panic!("{what} listed: {listing}"));
        assert_eq!(law["contract_version"], version, "{what}");
        // What it suits: declared from version 3 on; an older library cannot say (any).
        let suits = if version == 3 {
            serde_json::json!(["plain", "slide"])
        } else {
            serde_json::json!([])
        };
        assert_eq!(law["suits"], suits, "{what}: {law}");
        let listed = tribo_in(&["laws", "--plugin", p], &workspace());
        let (stdout, _) = text(&listed);
        let line = stdout
            .lines()
            .find(|l| l.contains(p))
            .unwrap_or_else(|| panic!("{what}: {stdout}"));
        assert_eq!(
            line.contains(&format!("contract v{version}")),
            version < 3,
            "{what}: an adapted library says so: {line}"
        );
    }
    assert_eq!(CONTRACT_VERSION, 3);
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
                "still loads versions 1 to 3",
            ],
        );
    }
}
