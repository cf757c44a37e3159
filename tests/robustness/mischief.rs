//! Laws up to mischief other than failing inside a call (`tests/fixtures/c/mischief.c`, one
//! library per case): a flood of standard error from a thread or from a daemon that left the
//! worker's session, a library cut short, an initialiser that calls `_exit(0)`, a reply forged
//! with the job's token and nonce read from memory. Each test asserts that the caller
//! survives, that the command exits non-zero naming the law or library where one failed, that
//! the innocent law set's results are written, and that the command is back within its limits
//! (+5 s).

use std::path::{Path, PathBuf};
use std::time::Duration;

use super::common::*;
use super::hostile::{args, build_case, other_sets_written, run_as_callee, Cmd, Ran};

/// Build case `case` of the mischief fixture into `dir` as the library of law
/// `mischief-NAME`.
fn build(dir: &Path, case: u32, name: &str) -> PathBuf {
    build_case(dir, "mischief.c", "mischief", case, name)
}

/// Build case `case` into `dir`, run `cmd` on it with `extra` options (a daemon or child it
/// leaves is ended afterwards), and list what is wrong: the failure must name the law, its
/// library and `words` within `limit`, and a compare must write the innocent set.
fn failing_case(
    dir: &Path,
    case: u32,
    name: &str,
    cmd: Cmd,
    extra: &[&str],
    words: &[&str],
    limit: Duration,
) -> (Ran, Vec<String>) {
    std::fs::create_dir_all(dir).expect("case dir");
    let lib = build(dir, case, name);
    let law = format!("mischief-{name}");
    let pid_file = dir.join("child.pid");
    let mut a = args(cmd, &lib, &law, dir, false);
    a.extend(extra.iter().map(|s| s.to_string()));
    let env = [(
        "TRIBO_TEST_PID_FILE",
        pid_file.to_string_lossy().into_owned(),
    )];
    let ran = run_as_callee(&a, dir, &env, Duration::from_secs(90));
    let outlived = still_running(&pid_file);
    end_daemon(&pid_file);
    let lib_name = lib
        .file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned();
    let law_named = format!("law `{law}`");
    let mut all = vec![law_named.as_str(), lib_name.as_str()];
    all.extend_from_slice(words);
    let mut p = failed_naming(&ran, &all, limit);
    if let Some(pid) = outlived {
        p.push(format!("process {pid} the law started outlived tribo"));
    }
    if matches!(cmd, Cmd::Compare) {
        p.extend(other_sets_written(dir, &ran.stdout));
    }
    (ran, p)
}

/// The process whose id a fixture wrote into `pid_file`, if it is still running (not ended
/// and not a zombie) 2 s after tribo returned: tribo kills a law's children, also one that
/// left the worker's session while the worker lived.
fn still_running(pid_file: &Path) -> Option<i32> {
    let pid = std::fs::read_to_string(pid_file)
        .ok()
        .and_then(|t| t.trim().parse::<i32>().ok())?;
    let running = || {
        std::fs::read_to_string(format!("/proc/{pid}/stat"))
            .ok()
            .and_then(|t| {
                t.rfind(')')
                    .map(|i| t[i + 1..].trim_start().starts_with('Z'))
            })
            .is_some_and(|zombie| !zombie)
    };
    let until = std::time::Instant::now() + Duration::from_secs(2);
    while running() {
        if std::time::Instant::now() > until {
            return Some(pid);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    None
}

/// End the process whose id a fixture wrote into `pid_file` (a daemon that left the worker's
/// session outlives it by design: the test cleans up after it).
fn end_daemon(pid_file: &Path) {
    if let Some(pid) = std::fs::read_to_string(pid_file)
        .ok()
        .and_then(|t| t.trim().parse::<i32>().ok())
    {
        // SAFETY: signalling the fixture's own daemon, whose id it wrote for this test.
        unsafe {
            libc::kill(pid, libc::SIGKILL);
        }
    }
}

/// What is wrong with a failed command: the caller gone, an exit other than 1, the words
/// missing, or past `limit`.
fn failed_naming(ran: &Ran, words: &[&str], limit: Duration) -> Vec<String> {
    let mut p = Vec::new();
    if !ran.caller_survived {
        p.push("the caller (sh) did not survive".to_string());
    }
    if ran.code != Some(1) {
        p.push(format!("exit code {:?}, expected 1", ran.code));
    }
    for w in words {
        if !ran.stderr.contains(w) {
            p.push(format!("message lacks `{w}`"));
        }
    }
    if ran.elapsed > limit {
        p.push(format!("took {:?}, over {limit:?}", ran.elapsed));
    }
    p
}

fn report(what: &str, p: &[String], ran: &Ran) {
    assert!(
        p.is_empty(),
        "{what}: {}\n--- stderr ({:?}, {} bytes):\n{}",
        p.join("; "),
        ran.elapsed,
        ran.stderr.len(),
        ran.stderr.chars().take(3000).collect::<String>()
    );
}

/// A law that floods standard error, from a thread (under `run`) or from a `setsid` daemon
/// (under `compare`, beside an innocent set), and then hangs in its call: the command ends at
/// the call limit (10 s) well within `--time-limit-s 20` + 5 s, names the law, forwards a
/// bounded amount of the flood (with a note of what was dropped), and the innocent set's
/// results are written.
#[test]
fn a_flood_of_standard_error_from_a_thread_or_a_setsid_daemon_is_bounded_by_the_limits() {
    ensure_plugins_built();
    let root = tempfile::tempdir().expect("temp dir");
    let cases = [
        (1, "flood-thread", Cmd::Run),
        (2, "flood-daemon", Cmd::Compare),
    ];
    std::thread::scope(|s| {
        for (case, name, cmd) in cases {
            let dir = root.path().join(name);
            s.spawn(move || {
                let (ran, mut p) = failing_case(
                    &dir,
                    case,
                    name,
                    cmd,
                    &["--time-limit-s", "20"],
                    &["did not return from one call", "more bytes were dropped"],
                    Duration::from_secs(25),
                );
                // What reaches the caller is bounded: 1 MiB of the flood and tribo's words.
                if ran.stderr.len() > 2 << 20 {
                    p.push(format!("{} bytes on standard error", ran.stderr.len()));
                }
                report(name, &p, &ran);
            });
        }
    });
}

/// `tribo laws --plugin DIR` with a plugin cut to 3000 bytes and one whose initialiser calls
/// `_exit(0)` beside a good law: exit 0, the good law listed, a warning naming each bad file
/// (the cut one as truncated); the JSON lists both as broken. `fmu export` asked for a law the
/// folder lacks (which opens every file in it) fails naming the law, without a crash.
#[test]
fn a_truncated_library_or_an_exiting_initialiser_is_a_warning_in_the_listing() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let plugins = d.join("plugins");
    std::fs::create_dir(&plugins).expect("plugin dir");
    compile_c(
        &[c_fixture("constructor_marker.c")],
        &plugins.join("libtribo_law_fixture_marker.so"),
        true,
    );
    let whole = std::fs::read(built_library("tribo_law_lugre")).expect("a built plugin");
    std::fs::write(plugins.join("libtribo_law_cut.so"), &whole[..3000]).expect("cut copy");
    build(&plugins, 3, "ctor-exit");
    let dir_arg = plugins.to_string_lossy().into_owned();
    let ran = run_as_callee(
        &["laws".into(), "--plugin".into(), dir_arg.clone()],
        d,
        &[],
        Duration::from_secs(60),
    );
    let mut p = Vec::new();
    if !ran.caller_survived || ran.code != Some(0) {
        p.push(format!(
            "exit {:?} (caller survived: {})",
            ran.code, ran.caller_survived
        ));
    }
    if !ran.stdout.contains("fixture-marker") || !ran.stdout.contains("coulomb") {
        p.push("the good laws are not listed".into());
    }
    let warned = |file: &str, word: &str| {
        ran.stderr
            .lines()
            .any(|l| l.starts_with("warning:") && l.contains(file) && l.contains(word))
    };
    if !warned("libtribo_law_cut.so", "truncated") {
        p.push("no warning naming the cut file as truncated".into());
    }
    if !warned("libtribo_law_mischief_ctor_exit.so", "status 0") {
        p.push("no warning naming the library whose initialiser exits".into());
    }
    if ran.elapsed > Duration::from_secs(20) {
        p.push(format!("took {:?}", ran.elapsed));
    }
    report("laws", &p, &ran);

    let json = run_as_callee(
        &[
            "laws".into(),
            "--json".into(),
            "--plugin".into(),
            dir_arg.clone(),
        ],
        d,
        &[],
        Duration::from_secs(60),
    );
    let v: serde_json::Value = serde_json::from_str(&json.stdout).expect("laws --json is JSON");
    let broken: Vec<String> = v["broken"]
        .as_array()
        .expect("broken")
        .iter()
        .map(|b| b["file"].as_str().unwrap_or("").to_string())
        .collect();
    assert!(
        broken.iter().any(|f| f.ends_with("libtribo_law_cut.so"))
            && broken
                .iter()
                .any(|f| f.ends_with("libtribo_law_mischief_ctor_exit.so")),
        "{broken:?}"
    );

    let fmu = fmu_export(d, &dir_arg, "no-such-law");
    let p = failed_naming(
        &fmu,
        &["libtribo_law_mischief_ctor_exit.so"],
        Duration::from_secs(20),
    );
    report("fmu export, unknown law", &p, &fmu);
    assert!(!d.join("x.fmu").exists(), "an FMU was written");
}

/// `tribo --plugin PLUGIN fmu export` of the frictionless rig with `law` on the piston, into
/// `x.fmu` in `dir`.
fn fmu_export(dir: &Path, plugin: &str, law: &str) -> Ran {
    let rig = workspace().join("rigs/reference-frictionless.toml");
    let a: Vec<String> = [
        "--plugin",
        plugin,
        "fmu",
        "export",
        &rig.to_string_lossy(),
        "--law",
        &format!("piston={law}"),
        "--out",
        "x.fmu",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    run_as_callee(&a, dir, &[], Duration::from_secs(60))
}

/// `fmu export` of a rig whose law's library calls `_exit(0)` when loaded: exit 1 naming the
/// library, no FMU written (it was exit 0 with no FMU and no word).
#[test]
fn fmu_export_with_an_initialiser_calling_exit_fails_naming_the_library() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lib = build(d, 3, "ctor-exit");
    let ran = fmu_export(d, &lib.to_string_lossy(), "mischief-ctor-exit");
    let p = failed_naming(
        &ran,
        &[
            "libtribo_law_mischief_ctor_exit.so",
            "while loading it",
            "status 0",
        ],
        Duration::from_secs(20),
    );
    report("fmu export", &p, &ran);
    assert!(!d.join("x.fmu").exists(), "an FMU was written");
}

/// A law that reads the job's token and the request's nonce from its process's memory, writes
/// a well-formed `Ok` reply with them and then calls `_exit(0)`: `check-law` and `run` fail
/// naming the law (the worker did not confirm the reply), never "all checks passed".
#[test]
fn a_reply_forged_with_the_token_and_nonce_by_a_law_that_died_is_not_accepted() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lib = build(d, 5, "forge-ok");
    let lib_name = lib
        .file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned();
    for cmd in [Cmd::CheckLaw, Cmd::Run] {
        let a = args(cmd, &lib, "mischief-forge-ok", d, false);
        let ran = run_as_callee(&a, d, &[], Duration::from_secs(60));
        let mut p = failed_naming(
            &ran,
            &["law `mischief-forge-ok`", &lib_name],
            Duration::from_secs(20),
        );
        if ran.stdout.contains("all checks passed") || ran.stderr.contains("all checks passed") {
            p.push("the forged reply passed the checks".into());
        }
        report(&format!("{cmd:?}"), &p, &ran);
    }
}

/// A law whose forked child (same process group) touches 2 GiB, or which writes 2 GiB into an
/// unmapped memory file, under `compare --memory-limit-mb 512` beside an innocent set: its set
/// fails at the memory limit naming the law, within the 10 s call limit (the law waits 5 s in
/// its call, so only the memory limit can stop it first), and the innocent set is written.
#[test]
fn the_memory_limit_counts_a_laws_children_and_memory_files() {
    ensure_plugins_built();
    let root = tempfile::tempdir().expect("temp dir");
    std::thread::scope(|s| {
        for (case, name) in [(9, "fork-hog"), (10, "memfd-hog")] {
            let dir = root.path().join(name);
            s.spawn(move || {
                let (ran, p) = failing_case(
                    &dir,
                    case,
                    name,
                    Cmd::Compare,
                    &["--memory-limit-mb", "512"],
                    &["over the limit of 512 MiB"],
                    Duration::from_secs(15),
                );
                report(name, &p, &ran);
            });
        }
    });
}

/// A law that zeroes the worker's shared in-flight page (so the page says nothing runs) and
/// never returns: stopped by `--call-limit-s 2` naming the law, not by the 30 s time limit.
#[test]
fn a_law_clearing_its_mark_on_the_shared_page_is_still_stopped_at_the_call_limit() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lib = build(d, 7, "clear-mark");
    let mut a = args(Cmd::Run, &lib, "mischief-clear-mark", d, false);
    a.extend([
        "--call-limit-s".into(),
        "2".into(),
        "--time-limit-s".into(),
        "30".into(),
    ]);
    let ran = run_as_callee(&a, d, &[], Duration::from_secs(60));
    let lib_name = lib.file_name().expect("name").to_string_lossy();
    let p = failed_naming(
        &ran,
        &[
            "law `mischief-clear-mark`",
            &lib_name,
            "did not return from one call in 2",
        ],
        Duration::from_secs(2 + 3 + 5),
    );
    report("clear-mark", &p, &ran);
}

/// In process, a run that fails (a parameter out of range, found after the library is loaded)
/// of a law whose library destructor calls `_exit(0)`: exit 1, not 0.
#[test]
fn a_destructor_calling_exit_in_process_does_not_turn_a_failure_into_success() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lib = build(d, 6, "dtor-exit");
    std::fs::write(d.join("bad.toml"), "c = 5.0\n").expect("params");
    let mut a = args(Cmd::Run, &lib, "mischief-dtor-exit:bad.toml", d, true);
    a.extend(["--time-limit-s".into(), "20".into()]);
    let ran = run_as_callee(&a, d, &[], Duration::from_secs(60));
    let p = failed_naming(
        &ran,
        &["law `mischief-dtor-exit`", "out of range"],
        Duration::from_secs(25),
    );
    report("dtor-exit", &p, &ran);
}

/// A rig named with 15 MiB of text (under the 16 MiB input cap): its report, which wraps the
/// name, is printed within the run's limits (wrapping was quadratic: 487 s).
#[test]
fn a_rig_with_a_15_mib_name_is_reported_within_its_limits() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let rig =
        std::fs::read_to_string(workspace().join("rigs/reference-frictionless.toml")).expect("rig");
    let name = "x".repeat(15 << 20);
    let rig = rig.replacen(
        "name = \"reference-frictionless\"",
        &format!("name = \"{name}\""),
        1,
    );
    assert!(rig.contains(&name), "the rig's name line moved");
    std::fs::write(d.join("big.toml"), rig).expect("rig file");
    let a: Vec<String> = [
        "run",
        "big.toml",
        "--set",
        "cycle.segments=[{kind=\"ramp\", to_rpm=3000, duration_s=0.3}, {kind=\"hold\", duration_s=0.3}]",
        "--quiet",
        "--time-limit-s",
        "20",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let ran = run_as_callee(&a, d, &[], Duration::from_secs(120));
    assert!(ran.caller_survived && ran.code == Some(0), "{}", ran.stderr);
    assert!(
        ran.elapsed < Duration::from_secs(25),
        "took {:?}",
        ran.elapsed
    );
    // Every character of the name is printed, cut into lines.
    let printed = ran.stdout.bytes().filter(|&b| b == b'x').count();
    assert!(printed >= name.len(), "{printed} of {} printed", name.len());
}

/// A law that plants a file in the `--out` folder of a compare while it runs, itself or from
/// a child process it starts, beside an innocent set: the planting law's set fails (exit 1)
/// naming the law, its library and the file; the planted file is removed; the innocent set's
/// results are written and the failed set listed.
#[test]
fn a_file_planted_in_the_result_folder_fails_the_planting_laws_set_and_the_others_are_written() {
    planted_case(8, "plant");
}

#[test]
fn a_file_a_laws_child_plants_in_the_result_folder_fails_that_laws_set_only() {
    planted_case(14, "plant-child");
}

fn planted_case(case: u32, name: &str) {
    let law = format!("mischief-{name}");
    let words = [
        "law set `hostile`",
        &format!("law `{law}`"),
        "`planted.txt` into the result folder",
    ];
    let (ran, d, mut p) = planting_run(case, name, false, &words);
    p.extend(other_sets_written(d.path(), &ran.stdout));
    report(name, &p, &ran);
}

/// Build case `case`, have it plant into an empty `--out` of a compare beside fedem-baseline
/// (`in_process`: with `--in-process`), and list what is wrong: exit 1 naming the law's library
/// and `words` within 30 s, the planted file still there.
fn planting_run(
    case: u32,
    name: &str,
    in_process: bool,
    words: &[&str],
) -> (Ran, tempfile::TempDir, Vec<String>) {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    let lib = build(d, case, name);
    let out = d.join("out");
    std::fs::create_dir(&out).expect("an empty --out");
    let a = args(
        Cmd::Compare,
        &lib,
        &format!("mischief-{name}"),
        d,
        in_process,
    );
    let env = [("TRIBO_TEST_PLANT_DIR", out.to_string_lossy().into_owned())];
    let ran = run_as_callee(&a, d, &env, Duration::from_secs(60));
    let lib_name = lib
        .file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned();
    let mut all = vec![lib_name.as_str()];
    all.extend_from_slice(words);
    let mut p = failed_naming(&ran, &all, Duration::from_secs(30));
    if out.join("planted.txt").exists() {
        p.push("the planted file is still there".into());
    }
    (ran, dir, p)
}

/// A law that double-forks a sleeper into a session of its own (its parent ends at once, so
/// the sleeper is nobody's descendant once orphaned): under `run`, where the law then behaves
/// (exit 0) and where it then `_exit`s its worker (exit 1, the law named), the sleeper is
/// killed with the worker's family, none of it survives tribo, and the run says how many
/// processes it killed.
#[test]
fn a_sleeper_a_law_double_forks_does_not_survive_the_run_and_is_reported() {
    ensure_plugins_built();
    let root = tempfile::tempdir().expect("temp dir");
    for (case, name, code) in [(12, "double-fork", 0), (13, "double-fork-exit", 1)] {
        let dir = root.path().join(name);
        std::fs::create_dir_all(&dir).expect("case dir");
        let lib = build(&dir, case, name);
        let pid_file = dir.join("child.pid");
        let mut a = args(Cmd::Run, &lib, &format!("mischief-{name}"), &dir, false);
        a.extend(["--time-limit-s".into(), "20".into()]);
        let env = [(
            "TRIBO_TEST_PID_FILE",
            pid_file.to_string_lossy().into_owned(),
        )];
        let ran = run_as_callee(&a, &dir, &env, Duration::from_secs(60));
        let outlived = still_running(&pid_file);
        end_daemon(&pid_file);
        let mut p = Vec::new();
        if !pid_file.exists() {
            p.push("the sleeper never started".to_string());
        }
        if !ran.caller_survived || ran.code != Some(code) {
            p.push(format!("exit code {:?}, expected {code}", ran.code));
        }
        if let Some(pid) = outlived {
            p.push(format!("the sleeper {pid} outlived tribo"));
        }
        let law = format!("law `mischief-{name}`");
        for w in [
            "1 process started by the laws of a worker",
            "was still running when the worker ended",
            law.as_str(),
        ] {
            if !ran.stderr.contains(w) {
                p.push(format!("message lacks `{w}`"));
            }
        }
        if ran.elapsed > Duration::from_secs(25) {
            p.push(format!("took {:?}", ran.elapsed));
        }
        report(name, &p, &ran);
    }
}

/// With `--in-process` every set runs in tribo's own process, so a file a law plants in
/// `--out` cannot be charged to one set: the command fails (exit 1) naming the file, the
/// option and the laws loaded, the file is removed, and every set's results are written.
#[test]
fn in_process_a_planted_file_fails_the_command_and_every_sets_results_are_written() {
    let words = [
        "`planted.txt` into the result folder",
        "with --in-process",
        "law `mischief-plant`",
    ];
    let (ran, dir, mut p) = planting_run(8, "plant", true, &words);
    let out = dir.path().join("out");
    let written = std::fs::read_to_string(out.join("comparison.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
    let sets: Vec<String> = written
        .as_ref()
        .and_then(|w| w["sets"].as_array())
        .map(|a| {
            a.iter()
                .filter_map(|s| s["lawset"].as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    if sets != ["fedem-baseline", "hostile"] {
        p.push(format!("sets written: {sets:?}, expected both"));
    }
    report("plant in process", &p, &ran);
}

/// A law that closes every descriptor from 3 up, or shuts down the worker's socket, and then
/// behaves: the worker cannot answer, and the run fails (exit 1) naming the law and its
/// library (the worker's laws, since no call was under way when it ended), never "no law".
#[test]
fn a_law_that_closes_the_channel_is_named_when_the_worker_cannot_answer() {
    ensure_plugins_built();
    let root = tempfile::tempdir().expect("temp dir");
    for (case, name) in [(15, "close-fds"), (16, "shutdown")] {
        let (ran, mut p) = failing_case(
            &root.path().join(name),
            case,
            name,
            Cmd::Run,
            &["--time-limit-s", "20"],
            &[],
            Duration::from_secs(25),
        );
        if ran.stderr.contains("while no law was running") {
            p.push("said no law was running".into());
        }
        report(name, &p, &ran);
    }
}
