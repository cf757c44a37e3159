//! Hostile laws (issue 29): one C law per case, each built from
//! `tests/fixtures/c/foreign_law.c` (`-DCASE=N`) and misbehaving after 3000 calls, run with the
//! default settings (no limit given) under `run`, `check-law` or `compare`. For each case the
//! test asserts that tribo and its caller survive (tribo runs under a shell in a process group
//! of its own; the shell must report tribo's exit), that the faulty run or law set fails with a
//! message naming the law (and never an innocent one), that the other law sets' results are
//! written, that nothing exits 0 without results, and that it all takes less than 60 s. The
//! cases run in parallel; the three stuck calls take the default per-call limit (10 s) each.
//!
//! Python's cases (a segfault, `exit`, `_exit` and a stuck call in a law called from Python)
//! are in `python/tests/test_isolation.py`, which builds the same fixture.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::common::*;

/// The command a case runs.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Cmd {
    /// `run` on a short cycle of the frictionless rig, the law on the piston, `--json`.
    Run,
    /// `check-law` on the library.
    CheckLaw,
    /// `compare --steady --no-cv` of fedem-baseline and a set with the law on the piston.
    Compare,
}

/// What a case must end with.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Outcome {
    /// Exit 1, the law named.
    Fails,
    /// Exit 0 with results.
    Succeeds,
}

struct Case {
    /// The fixture's case number and name (the law is `hostile-NAME`).
    case: u32,
    name: &'static str,
    cmd: Cmd,
    outcome: Outcome,
    /// Words the failure message must hold besides the law and its library.
    words: &'static [&'static str],
}

const CASES: &[Case] = &[
    Case {
        case: 1,
        name: "fork-linger",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        words: &["signal 6", "SIGABRT"],
    },
    Case {
        case: 2,
        name: "killpg",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        words: &["signal 15", "SIGTERM"],
    },
    Case {
        case: 3,
        name: "exit0",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        words: &["status 0", "without sending results"],
    },
    Case {
        case: 3,
        name: "exit0",
        cmd: Cmd::CheckLaw,
        outcome: Outcome::Fails,
        words: &["status 0", "without sending results"],
    },
    Case {
        case: 3,
        name: "exit0",
        cmd: Cmd::Compare,
        outcome: Outcome::Fails,
        words: &["status 0", "without sending results"],
    },
    Case {
        case: 4,
        name: "thread",
        cmd: Cmd::Run,
        outcome: Outcome::Succeeds,
        words: &[],
    },
    Case {
        case: 5,
        name: "stuck",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        words: &[
            "at joint `piston`",
            "did not return from one call in 10",
            "--call-limit-s",
            "the call's inputs: t = ",
            "normal load",
        ],
    },
    Case {
        case: 5,
        name: "stuck",
        cmd: Cmd::Compare,
        outcome: Outcome::Fails,
        words: &[
            "at joint `piston`",
            "did not return from one call in 10",
            "normal load",
        ],
    },
    Case {
        case: 5,
        name: "stuck",
        cmd: Cmd::CheckLaw,
        outcome: Outcome::Fails,
        words: &["did not return from one call in 10", "relative velocity"],
    },
    Case {
        case: 6,
        name: "forge-marker",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        // The law also wrote into the reply channel, which fails it before its segfault.
        words: &[],
    },
    Case {
        case: 7,
        name: "forge-reply",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        words: &["tribo did not write", "not trusted"],
    },
    Case {
        case: 8,
        name: "segfault",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        words: &["signal 11", "SIGSEGV"],
    },
    Case {
        case: 9,
        name: "stop",
        cmd: Cmd::Run,
        outcome: Outcome::Fails,
        words: &["stopped by signal 19", "SIGSTOP"],
    },
];

/// A short cycle: enough calls (thousands) for every fixture to reach its misbehaviour.
const SHORT: &str = "cycle.segments=[{kind=\"ramp\", to_rpm=3000, duration_s=0.3}, {kind=\"hold\", duration_s=0.3}]";

/// Build case `case` of the fixture into `dir` as the library of law `hostile-NAME`.
fn build(dir: &Path, case: u32, name: &str) -> PathBuf {
    build_case(dir, "foreign_law.c", "hostile", case, name)
}

/// Build case `case` of the C fixture `fixture` (`-DCASE=N`) into `dir` as the library of law
/// `PREFIX-NAME`, named as discovery expects.
pub(crate) fn build_case(
    dir: &Path,
    fixture: &str,
    prefix: &str,
    case: u32,
    name: &str,
) -> PathBuf {
    let lib = dir.join(format!(
        "libtribo_law_{prefix}_{}.so",
        name.replace('-', "_")
    ));
    let out = Command::new(c_compiler())
        .args(["-shared", "-fPIC", "-O2", "-std=c99", "-Wall", "-Wextra"])
        .arg(format!("-DCASE={case}"))
        .arg("-I")
        .arg(workspace().join("plugin-api/include"))
        .arg(c_fixture(fixture))
        .arg("-o")
        .arg(&lib)
        .arg("-lpthread")
        .output()
        .expect("the C compiler runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    lib
}

/// The arguments of `cmd` for law `law` in library `lib` (`in_process` adds `--in-process`).
pub(crate) fn args(cmd: Cmd, lib: &Path, law: &str, dir: &Path, in_process: bool) -> Vec<String> {
    let lib = lib.to_string_lossy().into_owned();
    let mut a: Vec<String> = match cmd {
        Cmd::Run => vec![
            "--plugin".into(),
            lib,
            "run".into(),
            workspace()
                .join("rigs/reference-frictionless.toml")
                .to_string_lossy()
                .into_owned(),
            "--law".into(),
            format!("piston={law}"),
            "--set".into(),
            SHORT.into(),
            "--json".into(),
        ],
        Cmd::CheckLaw => vec!["check-law".into(), lib],
        Cmd::Compare => {
            let set = dir.join("hostile.toml");
            std::fs::write(
                &set,
                format!("name = \"hostile\"\n[[laws]]\njoint = \"piston\"\nlaw = \"{law}\"\n"),
            )
            .expect("write the law set");
            vec![
                "--plugin".into(),
                lib,
                "compare".into(),
                "--steady".into(),
                "--no-cv".into(),
                "--lawset".into(),
                "fedem-baseline".into(),
                "--lawset".into(),
                set.to_string_lossy().into_owned(),
                "--out".into(),
                dir.join("out").to_string_lossy().into_owned(),
                "--json".into(),
            ]
        }
    };
    a.push("--quiet".into());
    if in_process {
        a.push("--in-process".into());
    }
    a
}

/// What one command did: tribo's exit code (None: killed by a signal), its output, whether its
/// caller (the shell) survived to report it, and how long it took.
pub(crate) struct Ran {
    pub(crate) code: Option<i32>,
    pub(crate) stdout: String,
    pub(crate) stderr: String,
    pub(crate) caller_survived: bool,
    pub(crate) elapsed: Duration,
}

/// Run tribo with `args` in `dir` under `sh` (the caller), the two in a new process group so a
/// law that signals its group could only ever hit them, never the test. The shell reports
/// tribo's exit status on a line of its own; a run past `limit` is killed.
pub(crate) fn run_as_callee(
    args: &[String],
    dir: &Path,
    env: &[(&str, String)],
    limit: Duration,
) -> Ran {
    let start = Instant::now();
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg("\"$@\"; echo \"caller-survived $?\" >&2")
        .arg("sh")
        .arg(tribo_exe())
        .args(args)
        .current_dir(dir)
        .env_remove("TRIBO_PLUGIN_PATH")
        .process_group(0);
    // Files, not pipes: the output is read once the command is done, and a command that writes
    // more than a pipe holds must not block on a reader that is not reading yet.
    let out_file = tempfile::tempfile().expect("stdout file");
    let err_file = tempfile::tempfile().expect("stderr file");
    cmd.stdout(Stdio::from(out_file.try_clone().expect("clone")))
        .stderr(Stdio::from(err_file.try_clone().expect("clone")));
    for (k, v) in env {
        cmd.env(k, v);
    }
    let mut child = cmd.spawn().expect("sh starts");
    let pid = child.id() as i32;
    loop {
        if child.try_wait().expect("wait").is_some() {
            break;
        }
        if start.elapsed() > limit {
            // SAFETY: killing the process group this test created.
            unsafe {
                libc::killpg(pid, libc::SIGKILL);
            }
            child.wait().expect("wait");
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let elapsed = start.elapsed();
    let read = |mut f: std::fs::File| {
        use std::io::{Read, Seek};
        let mut bytes = Vec::new();
        f.rewind().expect("rewind");
        f.read_to_end(&mut bytes).expect("read the output");
        String::from_utf8_lossy(&bytes).into_owned()
    };
    let (stdout, stderr) = (read(out_file), read(err_file));
    let report = stderr
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("caller-survived "))
        .map(str::to_string);
    let code = report.as_deref().and_then(|c| c.trim().parse::<i32>().ok());
    // sh reports 128+N for a child killed by signal N.
    let code = code.filter(|c| *c < 128);
    let stderr = stderr
        .lines()
        .filter(|l| !l.starts_with("caller-survived "))
        .collect::<Vec<_>>()
        .join("\n");
    Ran {
        code,
        stdout,
        stderr,
        caller_survived: report.is_some(),
        elapsed,
    }
}

/// Everything wrong with one case's run.
fn problems(c: &Case, lib: &Path, dir: &Path, ran: &Ran) -> Vec<String> {
    let mut p = Vec::new();
    let law = format!("hostile-{}", c.name);
    if !ran.caller_survived {
        p.push("the caller (sh) did not survive".into());
    }
    if ran.elapsed > Duration::from_secs(60) {
        p.push(format!("took {:?}, over 60 s", ran.elapsed));
    }
    match c.outcome {
        Outcome::Fails => {
            if ran.code != Some(1) {
                p.push(format!("exit code {:?}, expected 1", ran.code));
            }
            let errors: Vec<&str> = ran
                .stderr
                .lines()
                .filter(|l| l.starts_with("error:"))
                .collect();
            if errors.len() != 1 {
                p.push(format!("{} `error:` lines, expected one", errors.len()));
            }
            let message = ran.stderr.as_str();
            let lib_name = lib.file_name().map(|n| n.to_string_lossy().into_owned());
            for w in [Some(format!("law `{law}`")), lib_name]
                .into_iter()
                .flatten()
                .chain(c.words.iter().map(|w| w.to_string()))
            {
                if !message.contains(&w) {
                    p.push(format!("message lacks `{w}`"));
                }
            }
            if errors.iter().any(|e| e.contains("innocent")) {
                p.push("the message blames the innocent law a forged marker named".into());
            }
            match c.cmd {
                // Nothing that looks like results on standard output.
                Cmd::Run => {
                    if !ran.stdout.trim().is_empty() {
                        p.push(format!("results printed: {}", ran.stdout));
                    }
                }
                Cmd::CheckLaw => {}
                Cmd::Compare => p.extend(other_sets_written(dir, &ran.stdout)),
            }
        }
        Outcome::Succeeds => {
            if ran.code != Some(0) {
                p.push(format!("exit code {:?}, expected 0", ran.code));
            }
            if serde_json::from_str::<serde_json::Value>(&ran.stdout).is_err() {
                p.push("exit 0 without results on standard output".into());
            }
        }
    }
    p
}

/// A compare whose hostile set failed: fedem-baseline's results are written and printed, the
/// hostile set listed as failed.
pub(crate) fn other_sets_written(dir: &Path, stdout: &str) -> Vec<String> {
    let mut p = Vec::new();
    let written = std::fs::read_to_string(dir.join("out/comparison.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
    let Some(written) = written else {
        return vec!["comparison.json of the other set not written".into()];
    };
    let ran: Vec<&str> = written["sets"]
        .as_array()
        .map(|a| a.iter().filter_map(|s| s["lawset"].as_str()).collect())
        .unwrap_or_default();
    if ran != ["fedem-baseline"] {
        p.push(format!("sets written: {ran:?}, expected fedem-baseline"));
    }
    if written["failed"][0]["lawset"] != "hostile" {
        p.push(format!(
            "failed: {}, expected the hostile set",
            written["failed"]
        ));
    }
    match serde_json::from_str::<serde_json::Value>(stdout) {
        Ok(printed) if printed["sets"] == written["sets"] => {}
        _ => p.push("standard output is not the written comparison".into()),
    }
    p
}

#[test]
fn every_hostile_law_fails_only_its_own_run_or_set_naming_it_within_60_s() {
    ensure_plugins_built();
    let root = tempfile::tempdir().expect("temp dir");
    let failures: Vec<String> = std::thread::scope(|s| {
        let handles: Vec<_> = CASES
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let dir = root.path().join(format!("{i}-{}", c.name));
                s.spawn(move || {
                    std::fs::create_dir_all(&dir).expect("case dir");
                    let lib = build(&dir, c.case, c.name);
                    let law = format!("hostile-{}", c.name);
                    let pid_file = dir.join("child.pid");
                    let env = [(
                        "TRIBO_TEST_PID_FILE",
                        pid_file.to_string_lossy().into_owned(),
                    )];
                    let a = args(c.cmd, &lib, &law, &dir, false);
                    let ran = run_as_callee(&a, &dir, &env, Duration::from_secs(90));
                    let mut p = problems(c, &lib, &dir, &ran);
                    if c.case == 1 {
                        p.extend(lingering_child_gone(&pid_file));
                    }
                    if c.outcome == Outcome::Succeeds && p.is_empty() {
                        // The same run in process gives the same results, to the bit.
                        let a = args(c.cmd, &lib, &law, &dir, true);
                        let inp = run_as_callee(&a, &dir, &[], Duration::from_secs(90));
                        if inp.code != Some(0) || inp.stdout != ran.stdout {
                            p.push(format!(
                                "in process: exit {:?}, results differ: {}",
                                inp.code,
                                inp.stdout != ran.stdout
                            ));
                        }
                    }
                    (!p.is_empty()).then(|| {
                        format!(
                            "{} under {:?}: {}\n--- stderr ({:?}):\n{}",
                            c.name,
                            c.cmd,
                            p.join("; "),
                            ran.elapsed,
                            ran.stderr.chars().take(1500).collect::<String>()
                        )
                    })
                })
            })
            .collect();
        handles
            .into_iter()
            .filter_map(|h| h.join().expect("case thread"))
            .collect()
    });
    assert!(
        failures.is_empty(),
        "{} case(s) failed:\n{}",
        failures.len(),
        failures.join("\n\n")
    );
}

/// The child the fork-linger law left behind is gone: killed with its worker's process group.
fn lingering_child_gone(pid_file: &Path) -> Vec<String> {
    let Some(pid) = std::fs::read_to_string(pid_file)
        .ok()
        .and_then(|t| t.trim().parse::<i32>().ok())
    else {
        return vec!["the law's child never wrote its pid".into()];
    };
    let start = Instant::now();
    // Killed processes are reaped by init asynchronously: allow a moment.
    while start.elapsed() < Duration::from_secs(5) {
        let alive = std::fs::read_to_string(format!("/proc/{pid}/stat"))
            .map(|s| !s.contains(") Z "))
            .unwrap_or(false);
        if !alive {
            return Vec::new();
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: cleaning up the lingering process the failed assertion reports.
    unsafe {
        libc::kill(pid, libc::SIGKILL);
    }
    vec![format!("the law's child {pid} outlived the run")]
}

/// A case of tribo's own robustness: arguments (and a test hook or a shell limit), the exit
/// code, words the output must hold and words it must not.
struct HostCase {
    name: &'static str,
    shell: Option<&'static str>,
    env: &'static [(&'static str, &'static str)],
    args: &'static [&'static str],
    code: i32,
    words: &'static [&'static str],
    not: &'static [&'static str],
}

const HOST_CASES: &[HostCase] = &[
    HostCase {
        name: "a time limit of 1e300 s (it panicked, blamed on a law's exit())",
        shell: None,
        env: &[],
        args: &["run", "crf250r-motored", "--time-limit-s", "1e300"],
        code: 2,
        words: &["--time-limit-s", "got 1e300", "to 1e6"],
        not: &["exit()"],
    },
    HostCase {
        name: "a negative call limit",
        shell: None,
        env: &[],
        args: &["compare", "--call-limit-s=-1"],
        code: 2,
        words: &["--call-limit-s", "got -1"],
        not: &[],
    },
    HostCase {
        name: "a negative call limit written as a separate word",
        shell: None,
        env: &[],
        args: &["run", "crf250r-motored", "--call-limit-s", "-3"],
        code: 2,
        words: &["--call-limit-s", "got -3", "0 (no limit)"],
        not: &["unexpected argument"],
    },
    HostCase {
        name: "a negative mass scale",
        shell: None,
        env: &[],
        args: &["mass-response", "--scale", "-1", "--out", "o"],
        code: 1,
        words: &["--scale", "positive", "-1"],
        not: &["unexpected argument"],
    },
    HostCase {
        name: "an oil temperature of 1e300 C (printed with 300 digits)",
        shell: None,
        env: &[],
        args: &["sweep", "--temps", "1e300", "--out", "o"],
        code: 1,
        words: &["--temps", "1e300 C", "[-20, 160] C"],
        not: &["00000000000"],
    },
    HostCase {
        name: "a memory limit beyond 16 TiB",
        shell: None,
        env: &[],
        args: &["sweep", "--memory-limit-mb", "99999999999"],
        code: 2,
        words: &["--memory-limit-mb", "99999999999"],
        not: &[],
    },
    HostCase {
        name: "a crank-angle resolution of 1e-9 degrees (it aborted allocating 48 TB)",
        shell: None,
        env: &[],
        args: &[
            "run",
            "crf250r-motored",
            "--crank-angle",
            "ca",
            "--resolution-deg",
            "1e-9",
        ],
        code: 2,
        words: &["--resolution-deg", "0.01", "72000 samples"],
        not: &[],
    },
    HostCase {
        name: "sweep speeds of 1e6 rpm (reported per law set, blaming a --set)",
        shell: None,
        env: &[],
        args: &["sweep", "--speeds", "1000000", "--out", "o"],
        code: 1,
        // Refused once, by the rig's own declared limit (issue 27), before any set runs.
        words: &["--speeds", "max_speed_rpm = 14500 rpm", "1e6"],
        not: &["--set", "law set"],
    },
    HostCase {
        name: "a mass scale of 1e9 (reported per law set)",
        shell: None,
        env: &[],
        args: &["mass-response", "--steady", "--scales", "1e9", "--out", "o"],
        code: 1,
        words: &["--scale", "at most 1000"],
        not: &["law set"],
    },
    HostCase {
        name: "a panic in tribo is tribo's bug, not a law's exit()",
        shell: None,
        env: &[("TRIBO_TEST_PANIC", "main")],
        args: &["laws"],
        code: 101,
        words: &["internal error", "bug in tribo, not in a law"],
        not: &["exit()"],
    },
    HostCase {
        name: "a panic in a worker is tribo's bug too",
        shell: None,
        env: &[("TRIBO_TEST_PANIC", "worker")],
        args: &["run", "crf250r-motored", "--steady"],
        code: 1,
        words: &[
            "internal error in the worker process",
            "bug in tribo, not in a law",
        ],
        not: &["exit()", "signal"],
    },
    HostCase {
        name: "a time series past `ulimit -f` (SIGXFSZ killed tribo without a word)",
        shell: Some("ulimit -f 8; exec \"$@\""),
        env: &[],
        args: &["run", "crf250r-motored", "--timeseries", "ts.csv"],
        code: 1,
        words: &["ts.csv", "File too large"],
        not: &[],
    },
];

#[test]
fn host_failures_are_clear_errors_of_tribo_never_crashes_or_a_laws_fault() {
    ensure_plugins_built();
    let mut failures = Vec::new();
    for c in HOST_CASES {
        let dir = tempfile::tempdir().expect("temp dir");
        let mut cmd = match c.shell {
            Some(script) => {
                let mut s = Command::new("sh");
                s.arg("-c").arg(script).arg("sh").arg(tribo_exe());
                s
            }
            None => Command::new(tribo_exe()),
        };
        cmd.args(c.args)
            .arg("--quiet")
            .current_dir(dir.path())
            .env_remove("TRIBO_PLUGIN_PATH");
        for (k, v) in c.env {
            cmd.env(k, v);
        }
        let out = cmd.output().expect("tribo runs");
        let (stdout, stderr) = text(&out);
        let all = format!("{stdout}{stderr}");
        let mut p = Vec::new();
        if out.status.code() != Some(c.code) {
            p.push(format!("exit {:?}, expected {}", out.status.code(), c.code));
        }
        let errors = stderr.lines().filter(|l| l.starts_with("error:")).count();
        if errors != 1 {
            p.push(format!("{errors} `error:` lines, expected one"));
        }
        p.extend(
            c.words
                .iter()
                .filter(|w| !all.contains(*w))
                .map(|w| format!("lacks `{w}`")),
        );
        p.extend(
            c.not
                .iter()
                .filter(|w| all.contains(*w))
                .map(|w| format!("says `{w}`")),
        );
        if !p.is_empty() {
            failures.push(format!("{}: {}\n{all}", c.name, p.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}
