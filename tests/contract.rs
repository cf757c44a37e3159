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
        let mut runs: Vec<serde_json::Value> = probes
            .iter()
            .map(|b| run_with_probe(rig, &b.path))
            .collect();
        // The warnings differ, and should: a v3 build declares what it suits (plain bearings
        // and slides), so it is warned about on the rig's rolling big end, and not on the
        // piston; a v1 or v2 library cannot declare it (suits any joint). Everything else is
        // the same.
        for (run, b) in runs.iter_mut().zip(&probes) {
            let warnings = run
                .as_object_mut()
                .and_then(|o| o.remove("warnings"))
                .unwrap_or_else(|| panic!("{}: no warnings field", b.what));
            let warnings: Vec<&str> = warnings
                .as_array()
                .expect("a list")
                .iter()
                .filter_map(|w| w.as_str())
                .collect();
            if b.version < 3 {
                assert!(warnings.is_empty(), "{}: {warnings:?}", b.what);
            } else {
                assert_eq!(warnings.len(), 1, "{}: {warnings:?}", b.what);
                assert_mentions(warnings[0], &["joint `big_end`", "`contract-probe`"]);
            }
        }
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
        // An entry's header names the library; a path too long for the 100-column report goes
        // on the indented line under it, so the entry is read as header plus path.
        let lines: Vec<&str> = stdout.lines().collect();
        let at = lines
            .iter()
            .position(|l| l.contains(p))
            .unwrap_or_else(|| panic!("{what}: {stdout}"));
        let line = if lines[at].starts_with(' ') && at > 0 {
            format!("{} {}", lines[at - 1], lines[at].trim())
        } else {
            lines[at].to_string()
        };
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

// ---------------------------------------------------------------------------------------------
// The host's side of version 3: what the rig and the engines put into the version-3 inputs,
// the diagnostics carried into the crank-angle results, the bearing types and the warning
// for a law on a bearing it does not suit.

/// Every law input the [`Recorder`] saw, with its joint's tag.
static RECORDED: std::sync::Mutex<Vec<(u32, LawInput)>> = std::sync::Mutex::new(Vec::new());

/// Parameters of [`Recorder`].
#[derive(serde::Serialize, serde::Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct RecorderParams {
    tag: f64,
}

/// A frictionless law, linked in, that records every input it is handed with its `tag` (the
/// joint it sits on): the reactions it sees are then those of the frictionless mechanism.
struct Recorder {
    tag: u32,
}

impl tribo::plugin_api::Law for Recorder {
    type Params = RecorderParams;
    const NAME: &'static str = "input-recorder";
    const VERSION: &'static str = "0";
    const SUMMARY: &'static str = "records its inputs, no friction (test)";

    fn parameters() -> Vec<tribo::plugin_api::ParamSpec> {
        vec![tribo::plugin_api::ParamSpec::number(
            "tag",
            "-",
            "joint tag",
            0.0,
            1e3,
        )]
    }

    fn new(p: RecorderParams) -> Result<Self, tribo::plugin_api::ParamError> {
        Ok(Self { tag: p.tag as u32 })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        RECORDED
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push((self.tag, *input));
        LawOutput::force(0.0)
    }
}

/// A law reference to the recorder with `tag`.
fn recorder(tag: u32) -> tribo::model::LawRef {
    tribo::model::LawRef {
        law: "input-recorder".into(),
        params: toml::from_str(&format!("tag = {tag}")).expect("params"),
    }
}

/// The centre of mass of a rod in the global frame at crank angle `theta`, from the geometry
/// alone: crank radius `r`, rod length `l`, centre of mass `a` from the big end, bore axis at
/// `bank` from the vertical, throw at `throw` ahead of the crank angle, small end `e` across
/// the bore axis.
fn rod_com(theta: f64, r: f64, l: f64, a: f64, bank: f64, throw: f64, e: f64) -> [f64; 2] {
    let phi = theta + throw - bank;
    let pin = [-r * phi.sin(), r * phi.cos()];
    let small = [e, pin[1] + (l * l - (e - pin[0]).powi(2)).sqrt()];
    let local = [
        pin[0] + (small[0] - pin[0]) * a / l,
        pin[1] + (small[1] - pin[1]) * a / l,
    ];
    let (s, c) = bank.sin_cos();
    [c * local[0] - s * local[1], s * local[0] + c * local[1]]
}

/// One cylinder's rod as [`rod_com`] needs it, with its mass (kg).
struct RodCheck {
    big_end_tag: u32,
    small_end_tag: u32,
    mass_kg: f64,
    com: Box<dyn Fn(f64) -> [f64; 2]>,
}

/// Check the recorded inputs: the version-3 fields against their definitions, the joint's
/// declared `(bearing type, inner body)` per tag (`expect`), and Newton's law on every rod at
/// every instant: the forces the crank pin and the piston pin put on the rod (the opposites of
/// the big end's and the small end's load on their inner members) plus its weight equal its
/// mass times the acceleration of its centre of mass, differentiated twice from the geometry
/// at the constant crank speed of the traces. Returns the number of instants checked.
fn check_recorded(
    what: &str,
    records: &[(u32, LawInput)],
    expect: &dyn Fn(u32) -> (u32, u32),
    rods: &[RodCheck],
    gravity_m_s2: f64,
) -> usize {
    use std::collections::HashMap;
    // An instant: its time within the plateau's cycle and the plateau's speed.
    let mut by_instant: HashMap<(u32, u64, u64), LawInput> = HashMap::new();
    for (tag, i) in records {
        assert_eq!(
            i.relative_velocity.to_bits(),
            (i.body_a_velocity - i.body_b_velocity).to_bits(),
            "{what}, tag {tag}: relative velocity is not A minus B"
        );
        assert_eq!(
            (i.bearing_type, i.inner_body),
            expect(*tag),
            "{what}, tag {tag}: bearing type and inner body"
        );
        let on_inner = if i.kind() == Some(JointKind::Revolute) {
            i.load_on_inner_x_n.hypot(i.load_on_inner_y_n)
        } else {
            i.load_on_inner_y_n.abs()
        };
        assert!(
            (on_inner - i.normal_load_n).abs() <= 1e-12 * i.normal_load_n.max(1.0),
            "{what}, tag {tag}: |load on inner| {on_inner} vs normal load {}",
            i.normal_load_n
        );
        let instant = (i.time_s.to_bits(), i.engine_speed_rad_s.to_bits());
        by_instant.insert((*tag, instant.0, instant.1), *i);
    }
    let mut checked = 0;
    for rod in rods {
        for ((tag, t, w), be) in &by_instant {
            if *tag != rod.big_end_tag {
                continue;
            }
            let se = by_instant
                .get(&(rod.small_end_tag, *t, *w))
                .unwrap_or_else(|| panic!("{what}: no small-end input at t = {t}"));
            // The big end's body B is the crank: its angle and speed are the crank's.
            let (theta, omega) = (be.body_b_angle, be.body_b_velocity);
            assert_eq!(omega, be.engine_speed_rad_s, "{what}: crank speed");
            let h = 1e-3;
            let (p, c, m) = ((rod.com)(theta + h), (rod.com)(theta), (rod.com)(theta - h));
            let scale = be.normal_load_n
                + se.normal_load_n
                + rod.mass_kg * (gravity_m_s2 + omega * omega * 0.05);
            for axis in 0..2 {
                let acc = omega * omega * (p[axis] - 2.0 * c[axis] + m[axis]) / (h * h);
                let weight = if axis == 1 {
                    -rod.mass_kg * gravity_m_s2
                } else {
                    0.0
                };
                let (l_be, l_se) = if axis == 0 {
                    (be.load_on_inner_x_n, se.load_on_inner_x_n)
                } else {
                    (be.load_on_inner_y_n, se.load_on_inner_y_n)
                };
                let residual = -l_be - l_se + weight - rod.mass_kg * acc;
                assert!(
                    residual.abs() <= 1e-6 * scale,
                    "{what}: Newton on the rod (tags {}, {}) at {theta} rad, {omega} rad/s, axis {axis}: residual {residual} N of {scale} N",
                    rod.big_end_tag,
                    rod.small_end_tag
                );
            }
            checked += 1;
        }
    }
    checked
}

/// The recorder's inputs over every plateau's cycle of `rig` (crank-angle traces at 5
/// degrees), with the recorder on the joints `tags` name.
fn recorded_run(rig: &tribo::model::RigFile) -> Vec<(u32, LawInput)> {
    let mut registry = tribo::plugin_api::loader::LawRegistry::new();
    registry
        .insert(LawLibrary::in_process::<Recorder>().expect("describes itself"))
        .expect("one law");
    RECORDED.lock().unwrap_or_else(|e| e.into_inner()).clear();
    let mut sim = tribo::sim::Simulation::new(rig, &registry).expect("binds");
    sim.crank_angle_traces(5.0).expect("traces");
    std::mem::take(&mut *RECORDED.lock().unwrap_or_else(|e| e.into_inner()))
}

#[test]
fn law_inputs_carry_both_bodies_and_the_load_on_the_inner_member() {
    // The thesis rig: tags 0-4 are main_a, main_b, big_end, small_end, piston.
    let mut rig = tribo::rig::load_rig(Path::new("crf250r-motored"), &[])
        .expect("bundled rig")
        .file;
    for (tag, name) in tribo::model::JOINT_NAMES.iter().enumerate() {
        rig.joints.get_mut(name).expect("joint").laws = vec![recorder(tag as u32)];
    }
    let records = recorded_run(&rig);
    let g = if rig.geometry.gravity {
        tribo::sim::GRAVITY_M_S2
    } else {
        0.0
    };
    let (r, rod) = (rig.geometry.crank_radius_m, rig.bodies.rod.clone());
    let rods = [RodCheck {
        big_end_tag: 2,
        small_end_tag: 3,
        mass_kg: rod.mass_kg * rod.mass_scale,
        com: Box::new(move |t| rod_com(t, r, rod.length_m, rod.com_from_big_end_m, 0.0, 0.0, 0.0)),
    }];
    // Rolling mains and big end, the crank pin (body B) inner in the big end; a plain small
    // end; the piston a slide.
    let expect = |tag: u32| match tag {
        0 | 1 => (2, 0),
        2 => (2, 1),
        3 => (1, 0),
        _ => (3, 0),
    };
    let n = check_recorded("crf250r-motored", &records, &expect, &rods, g);
    assert!(n > 500, "only {n} instants");

    // The inline-4: tags 100 + i for main i, 200/300/400 + k for cylinder k's big end, small
    // end and piston.
    let mut rig = tribo::rig::load_rig(Path::new("inline4-4b11"), &[])
        .expect("bundled rig")
        .file;
    let geo = tribo::engine::geometry(&rig).expect("an engine");
    let engine = rig.engine.as_mut().expect("an engine");
    for i in 0..engine.mains.len() {
        engine
            .laws
            .insert(format!("main_{}", i + 1), vec![recorder(100 + i as u32)]);
    }
    for k in 0..geo.cylinders.len() {
        for (kind, base) in [("big_end", 200), ("small_end", 300), ("piston", 400)] {
            engine
                .laws
                .insert(format!("{kind}_{}", k + 1), vec![recorder(base + k as u32)]);
        }
    }
    let records = recorded_run(&rig);
    let rods: Vec<RodCheck> = geo
        .cylinders
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let (r, c) = (geo.crank_radius_m, *c);
            let throw = geo.throws[c.throw].angle_rad;
            RodCheck {
                big_end_tag: 200 + k as u32,
                small_end_tag: 300 + k as u32,
                mass_kg: c.rod.mass_kg,
                com: Box::new(move |t| {
                    let e = c.pin_offset_m + c.crank_offset_m;
                    let rod = c.rod;
                    rod_com(
                        t,
                        r,
                        rod.length_m,
                        rod.com_from_big_end_m,
                        c.bank_rad,
                        throw,
                        e,
                    )
                }),
            }
        })
        .collect();
    // Plain shells on mains and big ends, a plain small end, slides.
    let expect = |tag: u32| match tag / 100 {
        1 => (1, 0),
        2 => (1, 1),
        3 => (1, 0),
        _ => (3, 0),
    };
    let n = check_recorded("inline4-4b11", &records, &expect, &rods, geo.gravity_m_s2);
    assert!(n > 2000, "only {n} instants");
}

/// The standard output of `tribo ARGS` run in the workspace, which must succeed.
fn stdout_of(args: &[&str]) -> String {
    let out = tribo_in(args, &workspace());
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{args:?}: {stderr}");
    stdout
}

/// The rows of a CSV file as maps from its header.
fn csv_rows(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("a header")
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

#[test]
fn crank_angle_csv_carries_the_diagnostics_a_law_reports() {
    let dir = tempfile::tempdir().expect("temp dir");
    let lib = built_library("tribo_fixture_probe_v3");
    let rig = workspace().join("rigs/crf250r-motored.toml");
    let out_dir = dir.path().join("angle");
    let stdout = stdout_of(&[
        "run",
        rig.to_str().expect("utf-8"),
        "--plugin",
        lib.to_str().expect("utf-8"),
        "--law",
        "big_end=contract-probe",
        "--law",
        "piston=coulomb",
        "--steady",
        "--crank-angle",
        out_dir.to_str().expect("utf-8"),
        "--resolution-deg",
        "10",
        "--quiet",
    ]);
    // The probe suits plain bearings and slides; the thesis rig's big end is a needle bearing.
    assert_mentions(
        &stdout,
        &[
            "warning: joint `big_end`: law `contract-probe`",
            "rolling-element",
        ],
    );
    let model = tribo::rig::load_rig(&rig, &[]).expect("bundled rig").file;
    let (r, l) = (model.geometry.crank_radius_m, model.bodies.rod.length_m);
    let rows = csv_rows(&out_dir.join("crank_angle.csv"));
    let big_end: Vec<_> = rows
        .iter()
        .filter(|row| row["joint"] == "big_end" && row["law"] == "contract-probe")
        .collect();
    assert!(big_end.len() >= 7 * 36, "{} rows", big_end.len());
    let num = |row: &std::collections::HashMap<String, String>, k: &str| -> f64 {
        row.get(k)
            .unwrap_or_else(|| panic!("no column {k}"))
            .parse()
            .unwrap_or_else(|e| panic!("{k}: {e}"))
    };
    for row in big_end {
        let theta = num(row, "crank_angle_deg").to_radians();
        let omega = num(row, "speed_rpm") * std::f64::consts::TAU / 60.0;
        // The big end's bodies: A the rod (angle psi, sin psi = -r sin(theta) / l, rate from
        // its derivative), B the crank.
        let sin_psi = -r * theta.sin() / l;
        let psi = sin_psi.asin();
        let psi_rate = -r * theta.cos() * omega / (l * psi.cos());
        let load = num(row, "normal_load_n");
        // The probe's formulas (tests/fixtures/contract-probe/law.rs): a rolling big end (type
        // 2), its crank pin (body B) inner.
        let want = [
            (
                "min_film_m",
                1e-6 * (1.0 + 0.5 * psi.sin()) * (1.0 + 1e-3 * (psi_rate + omega).abs()),
            ),
            ("eccentricity_x", 0.5 * theta.cos()),
            ("eccentricity_y", 0.4 * (psi - theta).sin()),
            ("peak_pressure_pa", 1e3 * load + 2e5),
            ("asperity_share", (2.0 + 4.0) / 8.0),
        ];
        for (k, w) in want {
            let got = num(row, k);
            assert!(
                (got - w).abs() <= 1e-12 * w.abs() + 1e-18,
                "{k} at {} deg, {} rpm: {got} vs {w}",
                row["crank_angle_deg"],
                row["speed_rpm"]
            );
        }
    }
    // A law that reports no diagnostics leaves its cells empty.
    let piston: Vec<_> = rows.iter().filter(|row| row["joint"] == "piston").collect();
    assert!(!piston.is_empty());
    assert!(piston.iter().all(|row| row["min_film_m"].is_empty()));
}

#[test]
fn a_law_on_a_bearing_it_does_not_suit_is_warned_about() {
    // Issue 25's case: the SKF rolling-bearing law on the 4B11's plain shells.
    let stdout = stdout_of(&[
        "run",
        "inline4-4b11",
        "--lawset",
        "physical-bearings",
        "--steady",
        "--quiet",
    ]);
    // Reports wrap at 100 columns: a warning continues on indented lines, so read each warning
    // whole before looking into it.
    let mut warnings: Vec<String> = Vec::new();
    for line in stdout.lines() {
        match warnings.last_mut() {
            Some(last) if line.starts_with("    ") => {
                last.push(' ');
                last.push_str(line.trim());
            }
            _ if line.starts_with("warning:") => warnings.push(line.to_string()),
            _ => warnings.push(String::new()),
        }
    }
    let warned = |joint: &str| {
        warnings.iter().any(|l| {
            l.starts_with(&format!("warning: joint `{joint}`: law `rolling-bearing`"))
                && l.contains("made for rolling bearings")
                && l.contains("a plain bearing")
        })
    };
    for joint in ["main_1", "main_5", "big_end_1", "big_end_4"] {
        assert!(warned(joint), "no warning for {joint}:\n{stdout}");
    }
    // The piston's fedem-friction is generic (suits any joint): no warning about it.
    assert!(!stdout.contains("`fedem-friction`"), "{stdout}");

    // The reverse: a plain-journal law on the thesis rig's roller mains; the JSON result
    // carries the warning too.
    let json = json_in(
        &[
            "run",
            "crf250r-motored",
            "--law",
            "main_a=petroff-journal",
            "--steady",
            "--json",
            "--quiet",
        ],
        &workspace(),
    );
    let warnings: Vec<&str> = json["warnings"]
        .as_array()
        .expect("warnings")
        .iter()
        .filter_map(|w| w.as_str())
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("joint `main_a`: law `petroff-journal`")
                && w.contains("plain bearings")
                && w.contains("a rolling-element bearing")),
        "{warnings:?}"
    );
    // The same rig with the thesis's generic laws (fedem-baseline): nothing to warn about.
    let stdout = stdout_of(&[
        "run",
        "crf250r-motored",
        "--lawset",
        "fedem-baseline",
        "--steady",
        "--quiet",
    ]);
    assert!(!stdout.contains("warning: joint"), "{stdout}");
}

#[test]
fn a_rig_declares_its_bearing_types_per_item_or_per_kind() {
    use tribo::plugin_api::BearingType::{Plain, Rolling, Slide, Unspecified};
    let engine_text =
        std::fs::read_to_string(workspace().join("rigs/inline4-4b11.toml")).expect("rig");
    // The first main and the second cylinder's big end say otherwise than their kind.
    let engine_text = engine_text
        .replacen(
            "[[engine.mains]]\n",
            "[[engine.mains]]\nbearing = \"rolling\"\n",
            1,
        )
        .replace(
            "cylinder = 2\n",
            "cylinder = 2\nbig_end_bearing = \"rolling\"\n",
        );
    let rig: tribo::model::RigFile = toml::from_str(&engine_text).expect("parses");
    for (joint, want) in [
        ("main_1", Rolling),
        ("main_2", Plain),
        ("main_5", Plain),
        ("big_end_1", Plain),
        ("big_end_2", Rolling),
        ("small_end_2", Plain),
        ("piston_3", Slide),
        ("main_6", Unspecified),
        ("big_end_5", Unspecified),
    ] {
        assert_eq!(rig.bearing_type(joint), want, "{joint}");
    }
    // Without a declaration a joint is unspecified (the thesis rig without its `bearing`
    // lines); a piston is a slide all the same.
    let thesis =
        std::fs::read_to_string(workspace().join("rigs/crf250r-motored.toml")).expect("rig");
    let bare: String = thesis
        .lines()
        .filter(|l| !l.starts_with("bearing = "))
        .map(|l| format!("{l}\n"))
        .collect();
    let bare: tribo::model::RigFile = toml::from_str(&bare).expect("parses");
    assert_eq!(bare.bearing_type("main_a"), Unspecified);
    assert_eq!(bare.bearing_type("big_end"), Unspecified);
    assert_eq!(bare.bearing_type("piston"), Slide);

    // A word that is not a bearing type, and a bearing on the piston, are refused at their
    // place in the file.
    let dir = tempfile::tempdir().expect("temp dir");
    for (what, rig_text, words) in [
        (
            "ball",
            thesis.replacen("bearing = \"rolling\"", "bearing = \"ball\"", 1),
            vec!["joints.main_a.bearing", "`ball`", "`plain` or `rolling`"],
        ),
        (
            "piston",
            thesis.replace(
                "[joints.piston]\n",
                "[joints.piston]\nbearing = \"plain\"\n",
            ),
            vec!["joints.piston.bearing", "slide"],
        ),
    ] {
        let path = dir.path().join(format!("{what}.toml"));
        std::fs::write(&path, &rig_text).expect("write");
        let out = tribo_in(
            &["run", path.to_str().expect("utf-8"), "--steady", "--quiet"],
            &workspace(),
        );
        let (_, stderr) = text(&out);
        assert!(!out.status.success(), "{what}: accepted");
        assert!(
            stderr.contains(&format!("{}:", path.display())),
            "{what}: {stderr}"
        );
        assert_mentions(&stderr, &words);
    }
}

/// Parameters of [`BadFilm`].
#[derive(serde::Serialize, serde::Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct BadFilmParams {}

/// A law whose reported film thickness turns negative a little after the start (test).
struct BadFilm;

impl tribo::plugin_api::Law for BadFilm {
    type Params = BadFilmParams;
    const NAME: &'static str = "bad-film";
    const VERSION: &'static str = "0";
    const SUMMARY: &'static str = "reports a negative film after 10 ms (test)";

    fn parameters() -> Vec<tribo::plugin_api::ParamSpec> {
        Vec::new()
    }

    fn new(_: BadFilmParams) -> Result<Self, tribo::plugin_api::ParamError> {
        Ok(Self)
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        let film = if input.time_s > 0.01 { -2e-6 } else { 1e-6 };
        LawOutput::force(0.0).with_min_film(film)
    }
}

#[test]
fn a_diagnostic_without_physical_sense_is_an_error_naming_law_joint_and_time() {
    let mut rig = tribo::rig::load_rig(Path::new("crf250r-motored"), &[])
        .expect("bundled rig")
        .file;
    rig.joints.get_mut("small_end").expect("joint").laws = vec![tribo::model::LawRef {
        law: "bad-film".into(),
        params: toml::Table::new(),
    }];
    let mut registry = tribo::plugin_api::loader::LawRegistry::new();
    registry
        .insert(LawLibrary::in_process::<BadFilm>().expect("describes itself"))
        .expect("one law");
    let mut sim = tribo::sim::Simulation::new(&rig, &registry).expect("binds");
    let e = sim.run().expect_err("a negative film");
    let msg = e.to_string();
    assert_mentions(
        &msg,
        &[
            "joint `small_end`",
            "law `bad-film`",
            "min_film_m",
            "at t = 0.01",
        ],
    );
}
