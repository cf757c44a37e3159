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
        // The full transient cycle of three law sets takes seconds: long enough to kill midway.
        let mut cmd = Command::new(tribo_exe());
        cmd.args(["compare", "--quiet"])
            .args(ALL_LAWSETS)
            .arg("--out")
            .arg(&out)
            .env_remove("TRIBO_PLUGIN_PATH");
        with_default_sigint(&mut cmd);
        let mut child = cmd.spawn().expect("spawns");
        std::thread::sleep(Duration::from_millis(700));
        let status = Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(child.id().to_string())
            .status()
            .expect("kill runs");
        assert!(status.success());
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
