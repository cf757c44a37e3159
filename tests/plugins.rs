//! The plugin contract end to end: discovery, both ABIs, the C example compiled here with the
//! system compiler, and every load/create/evaluate failure with its message.

mod common;

use std::path::Path;

use common::*;
use tribo::plugin_api::loader::{load_paths, Abi, LawError, LawLibrary, MAX_STATE_SIZE};
use tribo::plugin_api::{JointKind, LawInput, CONTRACT_VERSION};

fn table(text: &str) -> toml::Table {
    text.parse().expect("test TOML parses")
}

fn input(kind: JointKind, velocity: f64, load: f64, radius: f64) -> LawInput {
    let mut i = LawInput::at_rest(kind);
    i.normal_load_n = load;
    i.contact_radius_m = radius;
    i.with_velocity(velocity)
}

/// The Coulomb + viscous formula both example laws implement, written out independently.
fn coulomb_formula(mu: f64, c: f64, eps: f64, kind: JointKind, v: f64, n: f64, r: f64) -> f64 {
    let arm = if kind == JointKind::Revolute { r } else { 1.0 };
    let vs = v * arm;
    -(mu * n * arm * vs / (vs * vs + eps * eps).sqrt() + c * v)
}

#[test]
fn laws_lists_rust_and_c_laws_with_their_files_as_json() {
    let out = run_tribo(&["laws", "--json"], None);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let json: serde_json::Value = serde_json::from_str(&stdout).expect("--json output parses");
    assert_eq!(json["contract_version"], CONTRACT_VERSION);
    let laws = json["laws"].as_array().expect("laws is a list");
    let find = |name: &str| {
        laws.iter()
            .find(|l| l["name"] == name)
            .unwrap_or_else(|| panic!("{name} not listed in {stdout}"))
    };
    for (name, abi) in [("coulomb", "rust"), ("c-coulomb", "c")] {
        let law = find(name);
        assert_eq!(law["abi"], abi);
        let file = law["file"].as_str().expect("file is text");
        assert!(Path::new(file).is_file(), "{file} does not exist");
        let mu = law["parameters"]
            .as_array()
            .and_then(|p| p.iter().find(|p| p["name"] == "mu"))
            .expect("mu is listed");
        assert_eq!(mu["unit"], "-");
        assert_eq!(mu["default"], 0.1);
        assert_eq!(mu["min"], 0.0);
    }
    // The table form names the same things.
    let out = run_tribo(&["laws"], None);
    let (stdout, _) = text(&out);
    assert!(
        stdout.contains("coulomb 0.1.0 [rust]") && stdout.contains("c-coulomb 0.1.0 [c]"),
        "{stdout}"
    );
}

#[test]
fn rust_and_c_paths_give_the_formula_and_the_same_handle() {
    let rust = LawLibrary::load(&built_library("tribo_law_coulomb")).expect("rust law loads");
    let dir = tempfile::tempdir().expect("temp dir");
    // The C example, compiled here with the system C compiler, not by the build script.
    let c_path = dir.path().join("libtribo_law_c_coulomb.so");
    compile_c(
        &[workspace().join("plugins/c-coulomb/c/c_coulomb.c")],
        &c_path,
        true,
    );
    let c = LawLibrary::load(&c_path).expect("C law loads");
    assert_eq!(rust.abi(), Abi::Rust);
    assert_eq!(c.abi(), Abi::C);
    assert_eq!(c.name(), "c-coulomb");
    assert_eq!(c.description().parameters.len(), 3);

    let params = table("mu = 0.08\nc_viscous = 0.4\nv_smooth = 0.002");
    let laws = [
        rust.create(&params).expect("rust create"),
        c.create(&params).expect("C create"),
    ];
    for law in &laws {
        assert_eq!(law.state_size(), 0);
        for kind in [JointKind::Revolute, JointKind::Prismatic] {
            for &v in &[-400.0, -2.0, -1e-3, 0.0, 5e-4, 3.0, 942.0] {
                for &n in &[0.0, 35.0, 12_000.0] {
                    let got = law
                        .evaluate(&input(kind, v, n, 0.017), &[])
                        .expect("evaluates");
                    let want = coulomb_formula(0.08, 0.4, 0.002, kind, v, n, 0.017);
                    assert!(
                        (got.force - want).abs() <= 1e-12 * (1.0 + want.abs()),
                        "{} {kind:?} v={v} n={n}: {} vs {want}",
                        law.name(),
                        got.force
                    );
                    assert_eq!(got.coefficient(), Some(0.08));
                }
            }
        }
    }
}

#[test]
fn c_header_layout_matches_the_rust_contract() {
    use std::mem::{offset_of, size_of};
    use tribo::plugin_api::LawOutput;
    let dir = tempfile::tempdir().expect("temp dir");
    let exe = dir.path().join("layout");
    compile_c(&[c_fixture("layout.c")], &exe, false);
    let out = std::process::Command::new(&exe)
        .output()
        .expect("layout program runs");
    let printed = String::from_utf8_lossy(&out.stdout).into_owned();
    let c: std::collections::HashMap<&str, usize> = printed
        .lines()
        .filter_map(|l| l.split_once(' '))
        .map(|(k, v)| (k, v.parse().expect("a number")))
        .collect();
    let rust = [
        ("input.size", size_of::<LawInput>()),
        ("output.size", size_of::<LawOutput>()),
        ("input.joint_kind", offset_of!(LawInput, joint_kind)),
        ("input.reserved", offset_of!(LawInput, reserved)),
        (
            "input.relative_velocity",
            offset_of!(LawInput, relative_velocity),
        ),
        (
            "input.sliding_velocity_m_s",
            offset_of!(LawInput, sliding_velocity_m_s),
        ),
        ("input.normal_load_n", offset_of!(LawInput, normal_load_n)),
        ("input.reaction_x_n", offset_of!(LawInput, reaction_x_n)),
        ("input.reaction_y_n", offset_of!(LawInput, reaction_y_n)),
        (
            "input.reaction_moment_nm",
            offset_of!(LawInput, reaction_moment_nm),
        ),
        (
            "input.contact_radius_m",
            offset_of!(LawInput, contact_radius_m),
        ),
        (
            "input.contact_length_m",
            offset_of!(LawInput, contact_length_m),
        ),
        ("input.oil_temp_c", offset_of!(LawInput, oil_temp_c)),
        ("input.viscosity_pa_s", offset_of!(LawInput, viscosity_pa_s)),
        (
            "input.engine_speed_rad_s",
            offset_of!(LawInput, engine_speed_rad_s),
        ),
        (
            "input.crank_angle_rad",
            offset_of!(LawInput, crank_angle_rad),
        ),
        ("input.time_s", offset_of!(LawInput, time_s)),
        ("input.dt_s", offset_of!(LawInput, dt_s)),
        ("output.force", offset_of!(LawOutput, force)),
        ("output.coefficient", offset_of!(LawOutput, coefficient)),
        (
            "output.duty_parameter",
            offset_of!(LawOutput, duty_parameter),
        ),
        (
            "output.dforce_dvelocity",
            offset_of!(LawOutput, dforce_dvelocity),
        ),
        ("output.regime", offset_of!(LawOutput, regime)),
        ("output.flags", offset_of!(LawOutput, flags)),
        ("contract", CONTRACT_VERSION as usize),
    ];
    for (key, value) in rust {
        assert_eq!(
            c.get(key),
            Some(&value),
            "{key}: C says {:?}, Rust {value}",
            c.get(key)
        );
    }
}

fn expect_failure(args: &[&str], needles: &[&str]) {
    let out = run_tribo(args, None);
    let (_, stderr) = text(&out);
    assert!(!out.status.success(), "expected failure for {args:?}");
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    for n in needles {
        assert!(stderr.contains(n), "`{n}` missing from: {stderr}");
    }
}

#[test]
fn a_file_that_is_not_a_shared_library_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let fake = dir.path().join("libtribo_law_fake.so");
    std::fs::write(&fake, "this is a text file, not ELF\n").expect("write");
    let f = fake.to_str().expect("utf-8 path");
    expect_failure(
        &["laws", "--plugin", f],
        &[f, "not a loadable shared library"],
    );
    // The same file found by directory scan was not asked for: `tribo laws` lists the other
    // laws and warns, naming the file and the same reason (tests/discovery.rs has the rest).
    let out = run_tribo(&["laws"], Some(dir.path()));
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stdout.contains("coulomb"), "{stdout}");
    assert!(
        stderr.lines().any(|l| l.starts_with("warning:")
            && l.contains(f)
            && l.contains("not a loadable shared library")),
        "{stderr}"
    );
}

#[test]
fn a_library_without_tribo_symbols_is_refused() {
    let dir = tempfile::tempdir().expect("temp dir");
    let lib = dir.path().join("libother.so");
    compile_c(&[c_fixture("no_symbols.c")], &lib, true);
    let l = lib.to_str().expect("utf-8 path");
    expect_failure(
        &["laws", "--plugin", l],
        &[l, "not a Tribo law", "tribo_law_contract_version"],
    );
}

#[test]
fn a_c_library_with_missing_functions_names_the_first_missing_one() {
    let dir = tempfile::tempdir().expect("temp dir");
    let lib = dir.path().join("libincomplete.so");
    compile_c(&[c_fixture("missing_symbol.c")], &lib, true);
    let l = lib.to_str().expect("utf-8 path");
    expect_failure(&["laws", "--plugin", l], &[l, "tribo_law_create"]);
}

#[test]
fn other_contract_versions_are_refused_for_both_abis() {
    let rust = built_library("tribo_fixture_contract_mismatch");
    let r = rust.to_str().expect("utf-8 path");
    let found = (CONTRACT_VERSION + 1).to_string();
    expect_failure(
        &["laws", "--plugin", r],
        &[
            r,
            &format!("contract version {found}"),
            &format!("speaks version {CONTRACT_VERSION}"),
        ],
    );

    let dir = tempfile::tempdir().expect("temp dir");
    let lib = dir.path().join("libold.so");
    // This fixture defines only the version symbol: if the loader touched anything else
    // first, the error would be a missing symbol instead.
    compile_c(&[c_fixture("wrong_version.c")], &lib, true);
    let l = lib.to_str().expect("utf-8 path");
    expect_failure(&["laws", "--plugin", l], &[l, "contract version 999"]);
}

#[test]
fn two_libraries_with_the_same_law_name_are_an_error_naming_both() {
    let original = built_library("tribo_law_coulomb");
    let a = tempfile::tempdir().expect("temp dir");
    let b = tempfile::tempdir().expect("temp dir");
    let name = original.file_name().expect("file name");
    std::fs::copy(&original, a.path().join(name)).expect("copy");
    std::fs::copy(&original, b.path().join(name)).expect("copy");
    let fa = a.path().join(name);
    let fb = b.path().join(name);
    expect_failure(
        &[
            "laws",
            "--plugin",
            a.path().to_str().expect("utf-8"),
            "--plugin",
            b.path().to_str().expect("utf-8"),
        ],
        &[
            "two libraries provide the law `coulomb`",
            fa.to_str().expect("utf-8"),
            fb.to_str().expect("utf-8"),
        ],
    );
}

#[test]
fn plugin_path_directories_are_scanned_and_non_plugins_ignored() {
    let dir = tempfile::tempdir().expect("temp dir");
    // A plugin under its plugin name, and a library that is not named like one.
    compile_c(
        &[workspace().join("plugins/c-coulomb/c/c_coulomb.c")],
        &dir.path().join("libtribo_law_c2.so"),
        true,
    );
    compile_c(
        &[c_fixture("no_symbols.c")],
        &dir.path().join("libsomething_else.so"),
        true,
    );
    std::fs::write(dir.path().join("notes.txt"), "not a library").expect("write");
    // The exe directory also provides c-coulomb: the duplicate must be reported, proving the
    // plugin-path directory was scanned and the non-plugin files were not loaded.
    let out = run_tribo(&["laws"], Some(dir.path()));
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stderr.contains("two libraries provide the law `c-coulomb`"),
        "{stderr}"
    );
    assert!(stderr.contains("libtribo_law_c2.so"), "{stderr}");
}

#[test]
fn unknown_and_out_of_range_parameters_are_rejected_by_name_for_both_abis() {
    let dir = tempfile::tempdir().expect("temp dir");
    let c_path = dir.path().join("libtribo_law_c_coulomb.so");
    compile_c(
        &[workspace().join("plugins/c-coulomb/c/c_coulomb.c")],
        &c_path,
        true,
    );
    for path in [built_library("tribo_law_coulomb"), c_path] {
        let lib = LawLibrary::load(&path).expect("loads");
        let e = lib.create(&table("mu = 0.1\nfriction = 3.0")).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("`friction`") && msg.contains("unknown parameter"),
            "{msg}"
        );
        assert!(
            msg.contains("expected one of: mu, c_viscous, v_smooth"),
            "{msg}"
        );
        let e = lib.create(&table("mu = -0.2")).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, LawError::Param { .. }), "{msg}");
        assert!(
            msg.contains("`mu`") && msg.contains("-0.2") && msg.contains("[0, 10]"),
            "{msg}"
        );
        assert!(
            msg.contains(lib.name()) && msg.contains(path.to_str().expect("utf-8")),
            "{msg}"
        );
        let e = lib.create(&table("v_smooth = \"fast\"")).unwrap_err();
        assert!(e.to_string().contains("expected a number"), "{e}");
    }
}

#[test]
fn a_panicking_law_is_reported_and_the_host_survives() {
    let path = built_library("tribo_fixture_panic_law");
    let lib = LawLibrary::load(&path).expect("loads");
    let law = lib.create(&table("panic_above = 1.0")).expect("creates");
    // Below the threshold it works; above it panics inside the plugin.
    let ok = law
        .evaluate(&input(JointKind::Prismatic, 0.5, 1.0, 0.0), &[])
        .expect("no panic");
    assert_eq!(ok.force, -0.5);
    let err = law
        .evaluate(&input(JointKind::Prismatic, 2.0, 1.0, 0.0), &[])
        .unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("fixture-panic"), "{msg}");
    assert!(msg.contains("fixture panic: velocity 2 above 1"), "{msg}");
    assert!(
        msg.contains("evaluate") && msg.contains(path.to_str().expect("utf-8")),
        "{msg}"
    );
    // Still alive, and the instance is still usable.
    assert!(law
        .evaluate(&input(JointKind::Prismatic, 0.1, 1.0, 0.0), &[])
        .is_ok());

    let err = lib.create(&table("panic_in_create = true")).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("fixture-panic") && msg.contains("create") && msg.contains("panic in create"),
        "{msg}"
    );
}

#[test]
fn load_paths_finds_the_laws_in_the_build_directory() {
    ensure_plugins_built();
    let reg = load_paths(&[profile_dir()]).expect("profile dir loads");
    assert!(reg.get("coulomb").is_ok());
    let e = reg.get("no-such-law").unwrap_err().to_string();
    assert!(
        e.contains("no law named `no-such-law`") && e.contains("coulomb"),
        "{e}"
    );
}

/// Compile the C example law into `dir` and load it.
fn c_coulomb_in(dir: &Path) -> LawLibrary {
    let c_path = dir.join("libtribo_law_c_coulomb.so");
    compile_c(
        &[workspace().join("plugins/c-coulomb/c/c_coulomb.c")],
        &c_path,
        true,
    );
    LawLibrary::load(&c_path).expect("C law loads")
}

#[test]
fn a_wrong_length_state_is_refused_before_the_law_is_called_for_both_abis() {
    let dir = tempfile::tempdir().expect("temp dir");
    let c = c_coulomb_in(dir.path());
    let rust = LawLibrary::load(&built_library("tribo_law_coulomb")).expect("rust law loads");
    let inp = input(JointKind::Revolute, 1.0, 100.0, 0.01);
    for lib in [&c, &rust] {
        let law = lib.create(&toml::Table::new()).expect("creates");
        assert_eq!(law.state_size(), 0);
        assert!(law.evaluate(&inp, &[]).is_ok());
        assert!(law.commit(&inp, &mut []).is_ok());
        let mut state = vec![7.0; 5];
        for e in [
            law.evaluate(&inp, &state).unwrap_err(),
            law.commit(&inp, &mut state).unwrap_err(),
        ] {
            let msg = e.to_string();
            assert!(
                matches!(
                    e,
                    LawError::StateLength {
                        expected: 0,
                        given: 5,
                        ..
                    }
                ),
                "{msg}"
            );
            assert!(
                msg.contains(lib.name())
                    && msg.contains("5 values")
                    && msg.contains("declares 0")
                    && msg.contains(lib.path().to_str().expect("utf-8")),
                "{msg}"
            );
        }
        assert_eq!(state, vec![7.0; 5], "{}: the law must not run", lib.name());
    }
}

#[test]
fn a_c_law_returning_an_undefined_regime_is_refused_naming_the_law_and_value() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("libtribo_law_bad_regime.so");
    compile_c(&[c_fixture("bad_regime.c")], &path, true);
    let lib = LawLibrary::load(&path).expect("loads");
    let law = lib.create(&toml::Table::new()).expect("creates");
    let e = law
        .evaluate(&input(JointKind::Prismatic, 1.0, 10.0, 0.0), &[])
        .unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(e, LawError::UndefinedRegime { value: 42, .. }),
        "{msg}"
    );
    assert!(
        msg.contains("fixture-bad-regime") && msg.contains("regime 42"),
        "{msg}"
    );
}

#[test]
fn a_c_law_declaring_a_huge_state_is_refused_not_allocated() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("libtribo_law_huge_state.so");
    compile_c(&[c_fixture("huge_state.c")], &path, true);
    let lib = LawLibrary::load(&path).expect("loads");
    let e = lib.create(&toml::Table::new()).unwrap_err();
    let msg = e.to_string();
    let size = 1usize << 40;
    assert!(
        matches!(e, LawError::StateTooLarge { size: s, .. } if s == size),
        "{msg}"
    );
    assert!(
        msg.contains("fixture-huge-state")
            && msg.contains(&size.to_string())
            && msg.contains(&MAX_STATE_SIZE.to_string()),
        "{msg}"
    );
}

/// `tribo laws` (or `laws --json`) with its standard output going to `stdout`.
fn laws_into(stdout: std::process::Stdio, json: bool) -> std::process::Child {
    ensure_plugins_built();
    let mut cmd = std::process::Command::new(tribo_exe());
    cmd.arg("laws");
    if json {
        cmd.arg("--json");
    }
    cmd.env_remove("TRIBO_PLUGIN_PATH")
        .stdout(stdout)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("tribo starts")
}

#[test]
fn a_closed_stdout_pipe_ends_quietly_with_status_1_not_a_panic() {
    for json in [false, true] {
        // Read end closed before tribo starts: its first write gets EPIPE, deterministically.
        let (reader, writer) = std::io::pipe().expect("pipe");
        drop(reader);
        let out = laws_into(writer.into(), json)
            .wait_with_output()
            .expect("tribo runs");
        let (_, stderr) = text(&out);
        assert_eq!(out.status.code(), Some(1), "json={json}: {stderr}");
        assert!(stderr.is_empty(), "a broken pipe is not reported: {stderr}");

        // The same with the child's own pipe, its read end dropped right after the spawn.
        let mut child = laws_into(std::process::Stdio::piped(), json);
        drop(child.stdout.take());
        let out = child.wait_with_output().expect("tribo runs");
        let (_, stderr) = text(&out);
        assert_ne!(out.status.code(), Some(101), "{stderr}");
        assert!(
            matches!(out.status.code(), Some(0 | 1)),
            "{:?}: {stderr}",
            out.status
        );
        assert!(!stderr.contains("panicked"), "{stderr}");
    }
}

#[cfg(target_os = "linux")]
#[test]
fn a_full_stdout_is_an_error_message_not_a_panic() {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full opens");
    let out = laws_into(full.into(), false)
        .wait_with_output()
        .expect("tribo runs");
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("cannot write the results to standard output")
            && !stderr.contains("panicked"),
        "{stderr}"
    );
}

#[test]
fn tribo_run_refuses_a_huge_state_and_an_undefined_regime_with_exit_1() {
    let dir = tempfile::tempdir().expect("temp dir");
    compile_c(
        &[c_fixture("huge_state.c")],
        &dir.path().join("libtribo_law_huge_state.so"),
        true,
    );
    compile_c(
        &[c_fixture("bad_regime.c")],
        &dir.path().join("libtribo_law_bad_regime.so"),
        true,
    );
    let huge = (1usize << 40).to_string();
    for (law, needles) in [
        (
            "fixture-huge-state",
            vec![
                "--law: piston=fixture-huge-state",
                "fixture-huge-state",
                huge.as_str(),
            ],
        ),
        (
            "fixture-bad-regime",
            vec!["piston", "fixture-bad-regime", "regime 42"],
        ),
    ] {
        let attach = format!("piston={law}");
        let out = run_tribo(
            &["run", "crf250r-motored", "--law", &attach],
            Some(dir.path()),
        );
        let (_, stderr) = text(&out);
        assert_eq!(out.status.code(), Some(1), "{law}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        for n in needles {
            assert!(stderr.contains(n), "`{n}` missing from: {stderr}");
        }
    }
}
