//! A compare killed midway (SIGINT, SIGKILL) leaves the previous results untouched and no
//! partial file under their names: a result set is rendered into a temporary directory and
//! swapped in whole (kills inside the write phase itself: `commit.rs`).

use std::process::Command;
use std::time::Duration;

use super::common::*;

#[test]
fn killing_a_compare_midway_leaves_previous_results_intact() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("results");
    let first = Command::new(tribo_exe())
        .args(["compare", "--steady", "--quiet", "--out"])
        .arg(&out)
        .env_remove("TRIBO_PLUGIN_PATH")
        .output()
        .expect("runs");
    assert!(first.status.success(), "{}", text(&first).1);
    let before = std::fs::read(out.join("comparison.json")).expect("first results");
    let names_before: Vec<String> = std::fs::read_dir(&out)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();

    for signal in ["INT", "KILL"] {
        // The full transient cycle of three law sets at a hundredth of the default crank-angle
        // step (Simpson throughout): over 30 s on the standard machine, so a signal 0.7 s in
        // lands midway on any machine. At the default step the run itself takes 0.65 s here,
        // and the signal came after it ended.
        let mut cmd = Command::new(tribo_exe());
        cmd.args(["compare", "--quiet"])
            .args(ALL_LAWSETS)
            .args(["--set", "solver.step_deg=0.01"])
            .args(["--set", "solver.quadrature=\"simpson\""])
            .arg("--out")
            .arg(&out)
            .env_remove("TRIBO_PLUGIN_PATH");
        with_default_sigint(&mut cmd);
        let mut child = cmd.spawn().expect("spawns");
        std::thread::sleep(Duration::from_millis(700));
        send(signal, child.id());
        let exit = child.wait().expect("waits");
        assert!(
            !exit.success(),
            "SIG{signal} arrived after the run finished; the test needs a longer run"
        );
        let after =
            std::fs::read(out.join("comparison.json")).expect("previous results still there");
        assert!(after == before, "SIG{signal}: comparison.json changed");
        for name in &names_before {
            let now = std::fs::read(out.join(name)).expect("file still there");
            assert!(!now.is_empty(), "SIG{signal}: {name} is empty");
        }
        // Nothing new under a result name: only temporary files (dot-prefixed) may remain.
        for e in std::fs::read_dir(&out).expect("dir") {
            let name = e.expect("entry").file_name().to_string_lossy().into_owned();
            assert!(
                names_before.contains(&name) || name.starts_with('.'),
                "SIG{signal}: unexpected {name}"
            );
        }
    }
}

/// Give the child SIGINT's default disposition. A test run started as a background job of a
/// shell without job control inherits SIGINT *ignored* (POSIX), and a child inherits that
/// through exec: `kill -INT` would then do nothing and the run finish, which is not what this
/// test is about. A user's Ctrl-C reaches tribo with the default disposition; so does the test.
fn with_default_sigint(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: between fork and exec only `signal`, which touches no memory of the parent's
    // threads (no allocation, no lock), is called.
    unsafe {
        cmd.pre_exec(|| {
            if libc::signal(libc::SIGINT, libc::SIG_DFL) == libc::SIG_ERR {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

/// The temporary directories (`.NAME.XXXXXX.tribo-tmp`) beside `out`.
fn temps_beside(out: &std::path::Path) -> Vec<String> {
    let name = out
        .file_name()
        .expect("name")
        .to_string_lossy()
        .into_owned();
    std::fs::read_dir(out.parent().expect("parent"))
        .expect("dir")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&format!(".{name}.")) && n.ends_with(".tribo-tmp"))
        .collect()
}

#[test]
fn sigint_or_sigterm_in_the_write_phase_removes_the_temporary_set_and_keeps_the_old() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("results");
    let first = Command::new(tribo_exe())
        .args(["compare", "--steady", "--no-cv", "--quiet", "--out"])
        .arg(&out)
        .env_remove("TRIBO_PLUGIN_PATH")
        .output()
        .expect("runs");
    assert!(first.status.success(), "{}", text(&first).1);
    let before = std::fs::read(out.join("comparison.json")).expect("first results");
    for signal in ["INT", "TERM"] {
        // Each file of the new set takes 400 ms to write (the test hook): the temporary set
        // is there for seconds.
        let mut cmd = Command::new(tribo_exe());
        cmd.args(["compare", "--steady", "--no-cv", "--quiet", "--out"])
            .arg(&out)
            .env("TRIBO_TEST_WRITE_PAUSE_MS", "400")
            .env_remove("TRIBO_PLUGIN_PATH");
        with_default_sigint(&mut cmd);
        let mut child = cmd.spawn().expect("spawns");
        let start = std::time::Instant::now();
        while temps_beside(&out).is_empty() {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "no temporary set appeared"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(Duration::from_millis(100));
        send(signal, child.id());
        let exit = child.wait().expect("waits");
        assert!(!exit.success(), "SIG{signal}: the run finished first");
        assert_eq!(
            temps_beside(&out),
            Vec::<String>::new(),
            "SIG{signal}: the temporary set was left behind"
        );
        let after = std::fs::read(out.join("comparison.json")).expect("old results there");
        assert!(after == before, "SIG{signal}: comparison.json changed");
    }
}

#[test]
fn sigterm_to_tribo_ends_its_workers_and_what_their_laws_started() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    // A law that forks a child then loops in one call: the worker and the child linger
    // unless tribo kills the worker's process group.
    let lib = d.join("libtribo_law_hostile_fork_linger.so");
    let out = Command::new(c_compiler())
        .args([
            "-shared",
            "-fPIC",
            "-O2",
            "-std=c99",
            "-DCASE=1",
            "-DAFTER=100",
        ])
        .arg("-I")
        .arg(workspace().join("plugin-api/include"))
        .arg(c_fixture("foreign_law.c"))
        .arg("-o")
        .arg(&lib)
        .output()
        .expect("cc runs");
    assert!(out.status.success(), "{}", text(&out).1);
    let pid_file = d.join("child.pid");
    let mut child = Command::new(tribo_exe())
        .arg("--plugin")
        .arg(&lib)
        .args(["run", "reference-frictionless", "--quiet", "--law"])
        .arg("piston=hostile-fork-linger")
        .args(["--call-limit-s", "0", "--time-limit-s", "0"])
        .env("TRIBO_TEST_PID_FILE", &pid_file)
        .env("TRIBO_TEST_STUCK_AFTER_FORK", "1")
        .env_remove("TRIBO_PLUGIN_PATH")
        .spawn()
        .expect("spawns");
    let start = std::time::Instant::now();
    while !pid_file.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the law never forked"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(200));
    let lingering: i32 = std::fs::read_to_string(&pid_file)
        .expect("pid")
        .trim()
        .parse()
        .expect("a pid");
    send("TERM", child.id());
    let exit = child.wait().expect("waits");
    assert!(!exit.success());
    let gone = |pid: i32| {
        std::fs::read_to_string(format!("/proc/{pid}/stat"))
            .map(|s| s.contains(") Z "))
            .unwrap_or(true)
    };
    let start = std::time::Instant::now();
    while !gone(lingering) && start.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(20));
    }
    if !gone(lingering) {
        send("KILL", lingering as u32);
        panic!("the law's child {lingering} outlived tribo's SIGTERM");
    }
}

/// Send signal `name` (`INT`, `TERM`, `KILL`) to process `pid`.
fn send(name: &str, pid: u32) {
    let status = Command::new("kill")
        .arg(format!("-{name}"))
        .arg(pid.to_string())
        .status()
        .expect("kill runs");
    assert!(status.success(), "kill -{name} {pid}");
}
