//! One case per failure users can cause: bad inputs, misbehaving plugins, solver trouble. Each
//! case runs the `tribo` binary and asserts the exit code and the key words of the message
//! (file, line, field, law, joint: whatever the user needs to fix it).

mod atomic;
mod commit;
#[path = "../common/mod.rs"]
mod common;
mod fuzz;
mod hostile;
mod interrupt;
mod limits;
mod mischief;

use std::path::Path;
use std::process::Command;

use common::*;

/// A failure case: how to set it up in a fresh directory, what `tribo` must exit with, and
/// which words its output must contain.
struct Case {
    name: &'static str,
    setup: fn(&Path) -> Vec<String>,
    code: i32,
    words: &'static [&'static str],
}

fn base_rig() -> String {
    std::fs::read_to_string(workspace().join("rigs/crf250r-motored.toml")).expect("rig")
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p.to_string_lossy().into_owned()
}

/// `tribo run` on the CRF 250 R rig written to `dir` with `from` replaced by `to`.
fn run_edited_rig(dir: &Path, from: &str, to: &str) -> Vec<String> {
    let p = write(dir, "rig.toml", &base_rig().replace(from, to));
    args(&["run", &p])
}

fn args(a: &[&str]) -> Vec<String> {
    a.iter().map(|s| s.to_string()).collect()
}

const SHORT: &str = "cycle.segments=[{kind=\"ramp\", to_rpm=3000, duration_s=0.3}, {kind=\"hold\", duration_s=0.3}]";

fn misbehaving(dir: &Path, mode: u32) -> Vec<String> {
    let lib = dir.join("libmisbehaving.so");
    compile_c(&[c_fixture("misbehaving_law.c")], &lib, true);
    let params = write(dir, "p.toml", &format!("mode = {mode}\nafter_s = 0.2\n"));
    let law = format!("piston=fixture-misbehaving:{params}");
    let rig = workspace().join("rigs/reference-frictionless.toml");
    let mut a = args(&[
        "--plugin",
        &lib.to_string_lossy(),
        "run",
        &rig.to_string_lossy(),
        "--law",
        &law,
        "--set",
        SHORT,
    ]);
    a.push("--quiet".into());
    a
}

fn cases() -> Vec<Case> {
    vec![
        // ---- inputs ----
        Case {
            name: "rig: unknown key, with file:line:column",
            setup: |d| run_edited_rig(d, "mass_kg = 0.1748", "mass_kg = 0.1748\nmas_scale = 0.6"),
            code: 1,
            // The bad key is the line after the rod's `mass_kg` (line 25 of the bundled rig).
            words: &["rig.toml:26:1", "unknown field `mas_scale`"],
        },
        Case {
            name: "rig: TOML syntax error",
            setup: |d| run_edited_rig(d, "bore_m = 0.0768", "bore_m = 0.0768 0.1"),
            code: 1,
            words: &["rig.toml:14:17", "bore_m", "expected newline"],
        },
        Case {
            name: "rig: negative mass",
            setup: |d| run_edited_rig(d, "mass_kg = 0.27", "mass_kg = -0.27"),
            code: 1,
            words: &["bodies.piston.mass_kg", "positive", "-0.27", "rig.toml:"],
        },
        Case {
            name: "rig: rod not longer than the crank",
            setup: |d| run_edited_rig(d, "length_m = 0.105", "length_m = 0.02"),
            code: 1,
            words: &["bodies.rod.length_m", "longer than the crank radius"],
        },
        Case {
            name: "rig: oil temperature outside the viscosity model's range",
            setup: |_| args(&["run", "crf250r-motored", "--set", "oil.temperature_c=400.0"]),
            code: 1,
            words: &[
                "oil.temperature_c",
                "400",
                "outside the viscosity model's range",
            ],
        },
        Case {
            name: "rig: empty test cycle",
            setup: |_| args(&["run", "crf250r-motored", "--set", "cycle.segments=[]"]),
            code: 1,
            words: &["cycle.segments", "empty"],
        },
        Case {
            name: "rig: non-positive hold",
            setup: |_| {
                args(&["run", "crf250r-motored", "--set", "cycle.segments=[{kind=\"ramp\", to_rpm=3000, duration_s=1.0}, {kind=\"hold\", duration_s=0.0}]"])
            },
            code: 1,
            words: &["cycle.segments[1].duration_s", "positive"],
        },
        Case {
            name: "law set: poly-line speeds not increasing",
            setup: |d| {
                let ls = write(d, "ls.toml", "name = \"x\"\n[[laws]]\njoint = \"main_a\"\nlaw = \"polyline-damper\"\nparams = { speeds_rad_s = [400.0, 300.0], factors = [1.0, 1.0] }\n");
                args(&["run", "crf250r-motored", "--lawset", &ls])
            },
            code: 1,
            // At the law-set file's line and column and entry, not at a rig path.
            words: &[
                "ls.toml:5:27",
                "laws[0] (joint main_a, law polyline-damper)",
                "parameter `speeds_rad_s`",
                "strictly increasing",
            ],
        },
        Case {
            name: "law set: a misspelled parameter, at its file:line:column and entry",
            setup: |d| {
                let ls = write(d, "ls.toml", "name = \"x\"\n[[laws]]\njoint = \"main_a\"\nlaw = \"coulomb\"\n[[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\n[laws.params]\nmu = 0.1\nmuu = 0.1\n");
                args(&["run", "crf250r-motored", "--lawset", &ls])
            },
            code: 1,
            words: &[
                "ls.toml:10:7",
                "laws[1] (joint piston, law coulomb): parameter `muu`: unknown parameter",
                "expected one of: mu,",
            ],
        },
        Case {
            name: "law set: a joint the rig lacks",
            setup: |d| {
                let ls = write(
                    d,
                    "ls.toml",
                    "name = \"x\"\n[[laws]]\njoint = \"wrist\"\nlaw = \"coulomb\"\n",
                );
                args(&["run", "crf250r-motored", "--lawset", &ls])
            },
            code: 1,
            words: &[
                "ls.toml:3:9",
                "laws[0].joint",
                "no joint `wrist`",
                "main_a, main_b, big_end, small_end, piston",
            ],
        },
        Case {
            name: "law: unknown law name",
            setup: |_| args(&["run", "crf250r-motored", "--law", "piston=no-such-law"]),
            code: 1,
            words: &["no law named `no-such-law`", "stribeck-duty"],
        },
        Case {
            name: "law: out-of-range parameter",
            setup: |d| {
                let p = write(d, "p.toml", "mu = 12.0\n");
                args(&[
                    "run",
                    "crf250r-motored",
                    "--law",
                    &format!("piston=coulomb:{p}"),
                ])
            },
            code: 1,
            // At the parameter file's line and column, with the `--law` argument.
            words: &[
                "p.toml:1:6",
                "--law piston=coulomb:",
                "law `coulomb`, parameter `mu`",
                "12",
                "[0, 10]",
            ],
        },
        Case {
            name: "law: unknown law given by --law",
            setup: |_| args(&["run", "crf250r-motored", "--law", "piston=nope"]),
            code: 1,
            words: &["--law: piston=nope: no law named `nope`"],
        },
        Case {
            name: "data: missing column",
            setup: |d| {
                let data = write(d, "d.csv", "speed_rpm,torque_nm\n3000,1.0\n");
                args(&[
                    "compare",
                    "--steady",
                    "--data",
                    &data,
                    "--out",
                    &d.join("o").to_string_lossy(),
                ])
            },
            code: 1,
            words: &["d.csv", "missing column `oil_temp_c`"],
        },
        Case {
            name: "data: non-numeric cell",
            setup: |d| {
                let data = write(
                    d,
                    "d.csv",
                    "speed_rpm,torque_nm,oil_temp_c\n3000,1.0,80\n4000,one point five,80\n",
                );
                args(&[
                    "compare",
                    "--steady",
                    "--data",
                    &data,
                    "--out",
                    &d.join("o").to_string_lossy(),
                ])
            },
            code: 1,
            words: &["d.csv:3", "torque_nm", "`one point five` is not a number"],
        },
        Case {
            name: "law set: a name that would leave the output directory",
            setup: |d| {
                let ls = write(
                    d,
                    "ls.toml",
                    "name = \"x/../../../pwned\"\n[[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\n",
                );
                args(&[
                    "compare",
                    "--steady",
                    "--lawset",
                    &ls,
                    "--out",
                    &d.join("o").to_string_lossy(),
                ])
            },
            code: 1,
            words: &[
                "ls.toml:1:8",
                "x/../../../pwned",
                "contains `/`",
                "ASCII letters, digits, `-`, `_` and `.`",
                "1 to 64",
            ],
        },
        Case {
            name: "law set: two sets with one name in one compare",
            setup: |d| {
                let text = "name = \"same\"\n[[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\n";
                let a = write(d, "a.toml", text);
                let b = write(d, "b.toml", text);
                args(&[
                    "compare",
                    "--steady",
                    "--lawset",
                    &a,
                    "--lawset",
                    &b,
                    "--out",
                    &d.join("o").to_string_lossy(),
                ])
            },
            code: 1,
            words: &[
                "two law sets are named `same`",
                "a.toml",
                "b.toml",
                "rename one",
            ],
        },
        Case {
            name: "law set: two sets with one name in one sweep",
            setup: |_| {
                args(&[
                    "sweep",
                    "--lawset",
                    "stribeck-duty",
                    "--lawset",
                    "stribeck-duty",
                    "--out",
                    "o",
                ])
            },
            code: 1,
            words: &[
                "two law sets are named `stribeck-duty`",
                "<bundled>/stribeck-duty.toml",
            ],
        },
        // ---- plugins ----
        Case {
            name: "plugin: not a shared library",
            setup: |d| {
                let p = write(d, "libtribo_law_fake.so", "not a library");
                args(&["--plugin", &p, "laws"])
            },
            code: 1,
            words: &["libtribo_law_fake.so", "not a loadable shared library"],
        },
        Case {
            name: "plugin: wrong architecture",
            setup: |d| {
                let mut bytes = std::fs::read(built_library("tribo_law_coulomb")).expect("read");
                bytes[18] = 0xB7; // e_machine = EM_AARCH64
                bytes[19] = 0x00;
                let p = d.join("libtribo_law_arm.so");
                std::fs::write(&p, bytes).expect("write");
                args(&["--plugin", &p.to_string_lossy(), "laws"])
            },
            code: 1,
            words: &[
                "libtribo_law_arm.so",
                "not a loadable shared library",
                "built for this platform",
            ],
        },
        Case {
            name: "plugin: missing symbols",
            setup: |d| {
                let lib = d.join("libincomplete.so");
                compile_c(&[c_fixture("missing_symbol.c")], &lib, true);
                args(&["--plugin", &lib.to_string_lossy(), "laws"])
            },
            code: 1,
            words: &["libincomplete.so", "tribo_law_create"],
        },
        Case {
            name: "plugin: other contract version",
            setup: |_| {
                args(&[
                    "--plugin",
                    &built_library("tribo_fixture_contract_mismatch").to_string_lossy(),
                    "laws",
                ])
            },
            code: 1,
            words: &[
                "tribo_fixture_contract_mismatch",
                // The fixture claims CONTRACT_VERSION + 1 (4 since contract version 3).
                "contract version 4",
                "rebuild the plugin",
            ],
        },
        Case {
            name: "plugin: panic in create",
            setup: |d| {
                let p = write(d, "p.toml", "panic_in_create = true\n");
                args(&[
                    "--plugin",
                    &built_library("tribo_fixture_panic_law").to_string_lossy(),
                    "run",
                    "crf250r-motored",
                    "--law",
                    &format!("piston=fixture-panic:{p}"),
                    "--quiet",
                ])
            },
            code: 1,
            words: &[
                "fixture-panic",
                "create",
                "panic in create",
                "p.toml: --law piston=fixture-panic:",
            ],
        },
        Case {
            name: "plugin: panic in evaluate, host survives and names law, joint and time",
            setup: |d| {
                let p = write(d, "p.toml", "panic_above = 5.0\n");
                args(&[
                    "--plugin",
                    &built_library("tribo_fixture_panic_law").to_string_lossy(),
                    "run",
                    "reference-frictionless",
                    "--law",
                    &format!("piston=fixture-panic:{p}"),
                    "--set",
                    SHORT,
                    "--quiet",
                ])
            },
            code: 1,
            words: &[
                "joint `piston`",
                "t = ",
                "relative velocity",
                "normal load",
                "fixture-panic",
                "evaluate",
                "fixture panic: velocity",
            ],
        },
        Case {
            name: "plugin: law returns NaN",
            setup: |d| misbehaving(d, 0),
            code: 1,
            words: &[
                "joint `piston`",
                "fixture-misbehaving",
                "libmisbehaving.so",
                "non-finite force (NaN)",
                "t = 0.2",
                "velocity",
                "normal load",
            ],
        },
        Case {
            name: "plugin: law returns infinity",
            setup: |d| misbehaving(d, 2),
            code: 1,
            words: &["fixture-misbehaving", "non-finite force (inf)"],
        },
        Case {
            name: "plugin: a C law returning a force of 1e300",
            setup: |d| {
                let lib = d.join("libhugeforce.so");
                compile_c(&[c_fixture("huge_force.c")], &lib, true);
                let rig = workspace().join("rigs/reference-frictionless.toml");
                args(&[
                    "--plugin",
                    &lib.to_string_lossy(),
                    "run",
                    &rig.to_string_lossy(),
                    "--law",
                    "piston=fixture-huge-force",
                    "--set",
                    SHORT,
                    "--quiet",
                ])
            },
            code: 1,
            words: &[
                "joint `piston`",
                "law `fixture-huge-force`",
                "libhugeforce.so",
                "returned a force of 1e300 N at t = ",
                "more than 1e6 times the largest joint reaction",
                "so at most",
            ],
        },
        Case {
            name: "plugin: stateless law adds energy",
            setup: |d| misbehaving(d, 1),
            code: 1,
            words: &[
                "joint `piston`",
                "fixture-misbehaving",
                "adds energy",
                "must oppose the motion",
            ],
        },
        Case {
            name: "plugin: a run reports the time spent in each law",
            setup: |_| {
                args(&[
                    "run",
                    "reference-frictionless",
                    "--lawset",
                    "fedem-baseline",
                    "--set",
                    SHORT,
                    "--quiet",
                ])
            },
            code: 0,
            words: &["time in laws", "piston", "fedem-friction", "calls"],
        },
        // ---- solver ----
        Case {
            name: "solver: friction/reaction iteration does not converge",
            setup: |_| {
                args(&[
                    "run",
                    "crf250r-motored",
                    "--lawset",
                    "fedem-baseline",
                    "--set",
                    "solver.friction_max_iter=1",
                    "--quiet",
                ])
            },
            code: 1,
            words: &[
                "did not converge",
                "after 1 iterations",
                "solver.friction_max_iter",
            ],
        },
        Case {
            name: "solver: drive at its torque limit (warning)",
            setup: |_| {
                args(&[
                    "run",
                    "reference-frictionless",
                    "--lawset",
                    "fedem-baseline",
                    "--set",
                    // Enough to turn the crank through the window (below about 2.8 N m the
                    // crank stalls: the next cases), not enough to hold 3000 rpm throughout.
                    "drive={kind=\"pi\", torque_limit_nm=3.4}",
                    "--set",
                    SHORT,
                    "--quiet",
                ])
            },
            code: 0,
            words: &["warning", "torque limit"],
        },
        Case {
            name: "solver: speed never reaches its plateau (warning)",
            setup: |_| {
                args(&[
                    "run",
                    "reference-frictionless",
                    "--lawset",
                    "fedem-baseline",
                    "--set",
                    "drive={kind=\"pi\", torque_limit_nm=2.9}",
                    "--set",
                    SHORT,
                    "--quiet",
                ])
            },
            code: 0,
            words: &["warning", "reached only", "never settled"],
        },
        Case {
            // At 0.5 N m the crank hardly turns: no whole-revolution window exists, and the run
            // used to print plateau values from an empty window (a mean of 3e302 rpm).
            name: "solver: drive too weak to turn the crank (error)",
            setup: |_| {
                args(&[
                    "run",
                    "reference-frictionless",
                    "--lawset",
                    "fedem-baseline",
                    "--set",
                    "drive={kind=\"pi\", torque_limit_nm=0.5}",
                    "--set",
                    SHORT,
                    "--quiet",
                ])
            },
            code: 1,
            words: &[
                "3000 rpm plateau has no measurement",
                "revolutions",
                "drive.torque_limit_nm",
            ],
        },
    ]
}

/// What is wrong with a failure's standard error `stderr` for the arguments `args`: not one
/// `error:` line; a part of the message (between `: `) said twice ("X: X"); `--set` blamed
/// when no `--set` was given.
fn message_problems(stderr: &str, args: &[String]) -> Vec<String> {
    let mut problems = Vec::new();
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    if errors.len() != 1 {
        problems.push(format!("{} `error:` lines, expected one", errors.len()));
    }
    for line in errors {
        let parts: Vec<&str> = line.split(": ").map(str::trim).collect();
        for (i, p) in parts.iter().enumerate() {
            if p.len() >= 12 && parts[i + 1..].contains(p) {
                problems.push(format!("`{p}` said twice"));
            }
        }
        if line.contains("--set") && !args.iter().any(|a| a == "--set") {
            problems.push("blames `--set`, which was not given".into());
        }
    }
    problems
}

#[test]
fn every_failure_ends_with_a_message_that_says_what_to_fix() {
    ensure_plugins_built();
    let mut failures = Vec::new();
    for case in cases() {
        let dir = tempfile::tempdir().expect("temp dir");
        let a = (case.setup)(dir.path());
        let out = Command::new(tribo_exe())
            .args(&a)
            .current_dir(dir.path())
            .env_remove("TRIBO_PLUGIN_PATH")
            .output()
            .expect("tribo runs");
        let (stdout, stderr) = text(&out);
        let all = format!("{stdout}{stderr}");
        let mut problems = Vec::new();
        if out.status.code() != Some(case.code) {
            problems.push(format!(
                "exit code {:?}, expected {}",
                out.status.code(),
                case.code
            ));
        }
        if out.status.code().is_none() {
            problems.push("killed by a signal (crash)".into());
        }
        for w in case.words {
            if !all.contains(w) {
                problems.push(format!("missing `{w}`"));
            }
        }
        if case.code == 1 {
            problems.extend(message_problems(&stderr, &a));
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {}\n--- stderr:\n{}",
                case.name,
                problems.join("; "),
                stderr.chars().take(600).collect::<String>()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} case(s) failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn a_full_standard_output_is_reported_once() {
    // The I/O error was printed twice ("...: No space left on device: No space left on
    // device"): once in the message and once as its cause.
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("/dev/full opens");
    let out = Command::new(tribo_exe())
        .arg("laws")
        .env_remove("TRIBO_PLUGIN_PATH")
        .stdout(full)
        .output()
        .expect("tribo runs");
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(
        stderr.matches("No space left on device").count(),
        1,
        "{stderr}"
    );
    assert!(message_problems(&stderr, &[]).is_empty(), "{stderr}");
}

#[test]
fn a_law_returning_1e300_fails_its_compare_naming_the_law_and_writes_nothing() {
    // Issue 15: such a law exited 0 with an RMSE of null.
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lib = d.join("libhugeforce.so");
    compile_c(&[c_fixture("huge_force.c")], &lib, true);
    let ls = write(
        d,
        "huge.toml",
        "name = \"huge\"\n[[laws]]\njoint = \"big_end\"\nlaw = \"fixture-huge-force\"\n",
    );
    let out = tribo_in(
        &[
            "--plugin",
            &lib.to_string_lossy(),
            "compare",
            "--steady",
            "--no-cv",
            "--lawset",
            "fedem-baseline",
            "--lawset",
            &ls,
            "--out",
            "o",
            "--quiet",
            // In one process the first failing set ends the study before anything is written;
            // isolated (the default) the other sets' results are written, which
            // tests/isolation.rs checks with the same kind of law.
            "--in-process",
        ],
        d,
    );
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stdout}{stderr}");
    assert_mentions(
        &stderr,
        &[
            "law set `huge`",
            "joint `big_end`",
            "law `fixture-huge-force`",
            "libhugeforce.so",
            "a torque of 1e300 N m",
            "more than 1e6 times the largest joint reaction",
        ],
    );
    assert!(message_problems(&stderr, &[]).is_empty(), "{stderr}");
    assert!(stdout.is_empty(), "{stdout}");
    let written: Vec<_> = std::fs::read_dir(d.join("o"))
        .map(|r| r.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(written.is_empty(), "results written: {written:?}");
}
