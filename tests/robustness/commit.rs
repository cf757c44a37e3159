//! Result sets are committed whole (issue 15, point 3): a compare killed at any instant of its
//! write phase leaves the whole old set or the whole new set; concurrent runs into one `--out`
//! end with one whole set; links, devices, foreign directories and `../` names planted where
//! results go are refused or never followed, and nothing outside the result is touched.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};
use std::time::{Duration, Instant};

use super::common::*;

/// Set A: two law sets (its files include `contributions_fedem-baseline.svg`).
const SET_A: &[&str] = &["fedem-baseline", "stribeck-duty"];
/// Set B: one other law set, so its file list differs from A's.
const SET_B: &[&str] = &["mixed-film"];

/// `tribo compare --steady --no-cv` of `sets` into `out` (not started).
fn compare(sets: &[&str], out: &Path) -> Command {
    ensure_plugins_built();
    let mut cmd = Command::new(tribo_exe());
    cmd.args(["compare", "--steady", "--no-cv", "--quiet"]);
    for s in sets {
        cmd.args(["--lawset", s]);
    }
    cmd.arg("--out")
        .arg(out)
        .env_remove("TRIBO_PLUGIN_PATH")
        .env_remove("TRIBO_TEST_WRITE_PAUSE_MS")
        .stdout(std::process::Stdio::null());
    cmd
}

/// Run `cmd` to completion and require success.
fn succeed(cmd: &mut Command) {
    let out = cmd.output().expect("tribo runs");
    assert!(out.status.success(), "{cmd:?}: {}", text(&out).1);
}

/// Run `cmd` to completion and require exit code 1 (a clean failure, not a crash); returns
/// its standard error.
fn refused(cmd: &mut Command) -> String {
    let out: Output = cmd.output().expect("tribo runs");
    let stderr = text(&out).1;
    assert_eq!(out.status.code(), Some(1), "{cmd:?}: {stderr}");
    stderr
}

/// Every entry of `dir` (dot-files included) with its bytes; a non-regular entry is recorded
/// by its kind so it can never equal a file, and a missing `dir` as one entry saying so.
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let entries = match std::fs::read_dir(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return BTreeMap::from([("<no directory at all>".to_string(), Vec::new())]);
        }
        r => r,
    };
    entries
        .expect("result directory")
        .map(|e| {
            let e = e.expect("entry");
            let name = e.file_name().to_string_lossy().into_owned();
            let meta = std::fs::symlink_metadata(e.path()).expect("metadata");
            let bytes = if meta.is_file() {
                std::fs::read(e.path()).expect("read")
            } else {
                format!("<not a regular file: {:?}>", meta.file_type()).into_bytes()
            };
            (name, bytes)
        })
        .collect()
}

/// What distinguishes `got` from `want`, for messages.
fn difference(got: &BTreeMap<String, Vec<u8>>, want: &BTreeMap<String, Vec<u8>>) -> String {
    let mut d = Vec::new();
    for (name, bytes) in got {
        match want.get(name) {
            None => d.push(format!("+{name}")),
            Some(w) if w != bytes => d.push(format!("~{name}")),
            Some(_) => {}
        }
    }
    d.extend(
        want.keys()
            .filter(|n| !got.contains_key(*n))
            .map(|n| format!("-{n}")),
    );
    d.join(" ")
}

/// Entries of `parent` other than the result `name` and its lock file: leftovers.
fn leftovers(parent: &Path, name: &str) -> Vec<String> {
    let lock = format!(".{name}.lock");
    let mut v: Vec<String> = std::fs::read_dir(parent)
        .expect("parent")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n != name && *n != lock)
        .collect();
    v.sort();
    v
}

/// A reference set: `sets` compared into a fresh directory by an uninterrupted run.
fn reference(sets: &[&str], root: &Path, name: &str) -> BTreeMap<String, Vec<u8>> {
    let out = root.join(name);
    succeed(&mut compare(sets, &out));
    snapshot(&out)
}

/// A small xorshift generator: random kill instants without a dependency. The seed is printed
/// on failure, so a failing sequence can be understood.
struct Rng(u64);

impl Rng {
    fn from_clock() -> Self {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(1, |d| d.as_nanos() as u64);
        Self(nanos | 1)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Kill `child` with SIGKILL (what `Child::kill` sends on Unix) and reap it; whether it had
/// already finished successfully.
fn kill(mut child: Child) -> bool {
    let finished = matches!(child.try_wait(), Ok(Some(s)) if s.success());
    let _ = child.kill();
    let status = child.wait().expect("reaped");
    finished || status.success()
}

/// The pause of the write-phase test hook (`TRIBO_TEST_WRITE_PAUSE_MS`), milliseconds.
const PAUSE_MS: u64 = 100;

/// `compare` of `sets` into `out` with the write phase stretched by the test hook.
fn paused(sets: &[&str], out: &Path) -> Command {
    let mut cmd = compare(sets, out);
    cmd.env("TRIBO_TEST_WRITE_PAUSE_MS", PAUSE_MS.to_string());
    cmd
}

#[test]
fn a_kill_at_any_instant_of_the_write_phase_leaves_the_whole_old_or_the_whole_new_set() {
    const ROUNDS: usize = 20;
    let refs = tempfile::tempdir().expect("temp dir");
    let a = reference(SET_A, refs.path(), "a");
    let b = reference(SET_B, refs.path(), "b");
    assert!(a.contains_key("contributions_fedem-baseline.svg"));
    assert!(!b.contains_key("contributions_fedem-baseline.svg"));
    assert!(a.contains_key(".tribo-results") && b.contains_key(".tribo-results"));

    // The run to be killed, uninterrupted and timed over an existing set A: with the pauses
    // after each of its files, before the swap and after it, most of its time is the write
    // phase. Its result is B exactly.
    let timed = refs.path().join("timed");
    succeed(&mut compare(SET_A, &timed));
    let start = Instant::now();
    succeed(&mut paused(SET_B, &timed));
    let span = start.elapsed();
    assert_eq!(snapshot(&timed), b, "the pause hook changes nothing");
    // One pause per file but the marker, one before the swap and one after it.
    let write_phase = Duration::from_millis(PAUSE_MS * (b.len() as u64 + 1));
    assert!(span >= write_phase, "{span:?}");

    let work = tempfile::tempdir().expect("temp dir");
    let out = work.path().join("results");
    let mut rng = Rng::from_clock();
    let seed = rng.0;
    let (mut in_write, mut finished, mut old, mut new) = (0, 0, 0, 0);
    for round in 0..ROUNDS {
        // An uninterrupted run of A: the old set, and it removes the previous round's leftovers.
        succeed(&mut compare(SET_A, &out));
        assert_eq!(
            snapshot(&out),
            a,
            "round {round}: set A after an uninterrupted run"
        );
        assert!(
            leftovers(work.path(), "results").is_empty(),
            "round {round}: an uninterrupted run left {:?}",
            leftovers(work.path(), "results")
        );

        let child = paused(SET_B, &out).spawn().expect("spawns");
        // Stratified: round k kills at a random instant of the k-th twentieth of the run, so
        // the kills cover the whole run, its end included.
        let at = span.mul_f64((round as f64 + rng.unit()) / ROUNDS as f64);
        std::thread::sleep(at);
        let done = kill(child);

        let now = snapshot(&out);
        let left = leftovers(work.path(), "results");
        if now == a {
            old += 1;
            assert!(!done, "round {round}: a finished run left the old set");
        } else if now == b {
            new += 1;
        } else {
            panic!(
                "round {round} (seed {seed}, kill at {at:?}): neither set A ({}) nor set B ({}); leftovers {left:?}",
                difference(&now, &a),
                difference(&now, &b)
            );
        }
        if done {
            finished += 1;
        } else if !left.is_empty() || now == b {
            // Killed after its temporary directory appeared: inside the write phase.
            in_write += 1;
        }
    }
    succeed(&mut compare(SET_A, &out));
    assert_eq!(snapshot(&out), a);
    assert!(leftovers(work.path(), "results").is_empty());
    eprintln!(
        "{ROUNDS} kills (seed {seed}): {in_write} in the write phase, {finished} after the run finished; old set {old}, new set {new}"
    );
    assert!(
        in_write > 0,
        "no kill landed in the write phase (seed {seed}); the pause is too short"
    );
    assert!(old > 0, "no kill left the old set (seed {seed})");
}

#[test]
fn a_kill_right_after_the_swap_leaves_the_new_set_and_the_next_run_removes_the_old() {
    let refs = tempfile::tempdir().expect("temp dir");
    let a = reference(SET_A, refs.path(), "a");
    let b = reference(SET_B, refs.path(), "b");
    let work = tempfile::tempdir().expect("temp dir");
    let out = work.path().join("results");
    let marker_b = b.get(".tribo-results").expect("marker");
    // The instant the new set is in place, the old one is still under the temporary name (the
    // hook pauses there); kill then. Retried if the kill came too late (the run finished).
    let mut caught = false;
    for _ in 0..5 {
        succeed(&mut compare(SET_A, &out));
        let mut child = paused(SET_B, &out).spawn().expect("spawns");
        let deadline = Instant::now() + Duration::from_secs(30);
        while std::fs::read(out.join(".tribo-results")).ok().as_ref() != Some(marker_b) {
            assert!(Instant::now() < deadline, "the run never swapped");
            if let Ok(Some(s)) = child.try_wait() {
                panic!("the run ended before the swap: {s}");
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        if kill(child) {
            continue;
        }
        assert_eq!(
            snapshot(&out),
            b,
            "killed after the swap: the whole new set"
        );
        let left = leftovers(work.path(), "results");
        assert_eq!(
            left.len(),
            1,
            "the old set under its temporary name: {left:?}"
        );
        let old = work.path().join(&left[0]);
        assert!(
            left[0].starts_with(".results.") && left[0].ends_with(".tribo-tmp"),
            "{left:?}"
        );
        // The old set, whole or partly removed already: nothing but files of A, unchanged.
        for (name, bytes) in snapshot(&old) {
            assert!(
                a.get(&name) == Some(&bytes),
                "{name} in the leftover is not A's"
            );
        }
        caught = true;
        break;
    }
    assert!(caught, "every kill came after the run had finished");
    // The next run into the same directory removes the leftover.
    succeed(&mut compare(SET_A, &out));
    assert_eq!(snapshot(&out), a);
    assert!(leftovers(work.path(), "results").is_empty());
}

#[test]
fn sixteen_concurrent_runs_into_one_directory_end_with_one_whole_set() {
    let choices: [&[&str]; 4] = [
        &["fedem-baseline"],
        &["stribeck-duty"],
        &["mixed-film"],
        &["fedem-baseline", "physical-bearings"],
    ];
    let refs = tempfile::tempdir().expect("temp dir");
    let expected: Vec<BTreeMap<String, Vec<u8>>> = choices
        .iter()
        .enumerate()
        .map(|(i, c)| reference(c, refs.path(), &format!("r{i}")))
        .collect();
    for trial in 0..2 {
        let work = tempfile::tempdir().expect("temp dir");
        let out = work.path().join("shared");
        let children: Vec<Child> = (0..16)
            .map(|i| {
                compare(choices[i % choices.len()], &out)
                    .stderr(std::process::Stdio::piped())
                    .spawn()
                    .expect("spawns")
            })
            .collect();
        for child in children {
            let out = child.wait_with_output().expect("waits");
            assert!(
                out.status.success(),
                "trial {trial}: a run failed: {}",
                text(&out).1
            );
        }
        let now = snapshot(&out);
        assert!(
            expected.contains(&now),
            "trial {trial}: the directory is no single set: {}",
            expected
                .iter()
                .map(|e| difference(&now, e))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        assert!(leftovers(work.path(), "shared").is_empty());
    }
}

#[cfg(unix)]
#[test]
fn links_planted_at_result_names_are_never_followed() {
    use std::os::unix::fs::symlink;
    let root = tempfile::tempdir().expect("temp dir");
    let victim = root.path().join("victim.txt");
    std::fs::write(&victim, "precious").expect("write");
    let victim_dir = root.path().join("victim-dir");
    std::fs::create_dir(&victim_dir).expect("mkdir");
    std::fs::write(
        victim_dir.join(".tribo-results"),
        "command = \"x\"\nfiles = []\n",
    )
    .expect("write");
    std::fs::write(victim_dir.join("precious.txt"), "precious").expect("write");
    let refs = tempfile::tempdir().expect("temp dir");
    let b = reference(SET_B, refs.path(), "b");

    // A result file of an earlier set replaced by a link, and a link where a leftover
    // temporary directory of the result would be: the run replaces the set whole, through
    // neither link.
    let work = root.path().join("work");
    let out = work.join("results");
    succeed(&mut compare(SET_A, &out));
    std::fs::remove_file(out.join("comparison.json")).expect("rm");
    symlink(&victim, out.join("comparison.json")).expect("symlink");
    let planted = work.join(".results.Ab12Cd.tribo-tmp");
    symlink(&victim_dir, &planted).expect("symlink");
    succeed(&mut compare(SET_B, &out));
    assert_eq!(snapshot(&out), b);
    assert!(std::fs::symlink_metadata(&planted)
        .expect("the planted link is left alone")
        .file_type()
        .is_symlink());

    // The lock file planted as a link: refused, nothing written anywhere.
    let out2 = work.join("other");
    symlink(&victim, work.join(".other.lock")).expect("symlink");
    let msg = refused(&mut compare(SET_B, &out2));
    assert_mentions(&msg, &[".other.lock", "symbolic link"]);
    assert!(!out2.exists());

    // The result directory itself a link to a directory: refused, the directory untouched.
    let real = root.path().join("real");
    succeed(&mut compare(SET_A, &real));
    let before = snapshot(&real);
    let link = work.join("link");
    symlink(&real, &link).expect("symlink");
    let msg = refused(&mut compare(SET_B, &link));
    assert_mentions(
        &msg,
        &["--out", "link", "is a symbolic link", "does not follow"],
    );
    assert_eq!(snapshot(&real), before);
    assert!(std::fs::symlink_metadata(&link)
        .expect("link")
        .file_type()
        .is_symlink());

    // Single files: `fit --out` and `run --timeseries` to a link are refused.
    let file_link = work.join("fitted.toml");
    symlink(&victim, &file_link).expect("symlink");
    let msg = refused(
        Command::new(tribo_exe())
            .args([
                "fit",
                "--lawset",
                "stribeck-duty",
                "--no-cv",
                "--quiet",
                "--out",
            ])
            .arg(&file_link)
            .env_remove("TRIBO_PLUGIN_PATH"),
    );
    assert_mentions(&msg, &["fitted.toml", "is a symbolic link"]);
    let msg = refused(
        Command::new(tribo_exe())
            .args(["run", "reference-frictionless", "--quiet", "--timeseries"])
            .arg(&file_link)
            .env_remove("TRIBO_PLUGIN_PATH"),
    );
    assert_mentions(&msg, &["fitted.toml", "is a symbolic link"]);

    assert_eq!(
        std::fs::read_to_string(&victim).expect("victim"),
        "precious"
    );
    assert_eq!(
        std::fs::read_to_string(victim_dir.join("precious.txt")).expect("victim dir"),
        "precious"
    );
    let mut names: Vec<String> = std::fs::read_dir(&work)
        .expect("work")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            ".other.lock",
            ".results.Ab12Cd.tribo-tmp",
            ".results.lock",
            "fitted.toml",
            "link",
            "results"
        ],
        "nothing else was created beside the results"
    );
}

#[cfg(unix)]
#[test]
fn fit_out_dev_null_is_refused_and_dev_null_stays_a_device() {
    use std::os::unix::fs::FileTypeExt;
    ensure_plugins_built();
    let strays = || -> Vec<String> {
        std::fs::read_dir("/dev")
            .expect("/dev")
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".null"))
            .collect()
    };
    let before = strays();
    let msg = refused(
        Command::new(tribo_exe())
            .args(["fit", "--lawset", "stribeck-duty", "--no-cv", "--quiet"])
            .args(["--out", "/dev/null"])
            .env_remove("TRIBO_PLUGIN_PATH"),
    );
    assert_mentions(
        &msg,
        &["/dev/null is a character device", "not a regular file"],
    );
    let msg = refused(compare(SET_B, Path::new("/dev/null")).stderr(std::process::Stdio::piped()));
    assert_mentions(
        &msg,
        &["--out /dev/null is a character device", "not a directory"],
    );
    let meta = std::fs::symlink_metadata("/dev/null").expect("/dev/null");
    assert!(meta.file_type().is_char_device(), "/dev/null was replaced");
    assert_eq!(strays(), before, "temporary or lock files left in /dev");
}

#[test]
fn an_out_that_is_a_file_or_a_directory_of_other_files_is_refused_untouched() {
    let root = tempfile::tempdir().expect("temp dir");
    let home = root.path().join("home");
    std::fs::create_dir(&home).expect("mkdir");
    std::fs::write(home.join("thesis.tex"), "years of work").expect("write");
    let before = snapshot(&home);

    let msg = refused(&mut compare(SET_B, &home));
    assert_mentions(
        &msg,
        &[
            "--out",
            "holds files tribo did not write",
            "thesis.tex",
            "choose a new directory or empty it",
        ],
    );
    // `--out .` from inside it, and `run --csv` into it: refused too.
    let msg = refused(compare(SET_B, Path::new(".")).current_dir(&home));
    assert_mentions(&msg, &["--out .", "does not name"]);
    let msg = refused(
        Command::new(tribo_exe())
            .args([
                "run",
                "reference-frictionless",
                "--steady",
                "--quiet",
                "--csv",
            ])
            .arg(&home)
            .env_remove("TRIBO_PLUGIN_PATH"),
    );
    assert_mentions(
        &msg,
        &["--csv", "holds files tribo did not write", "thesis.tex"],
    );
    assert_eq!(snapshot(&home), before);

    let file = root.path().join("notes.txt");
    std::fs::write(&file, "notes").expect("write");
    let msg = refused(&mut compare(SET_B, &file));
    assert_mentions(&msg, &["notes.txt", "is a regular file, not a directory"]);
    assert_eq!(std::fs::read_to_string(&file).expect("read"), "notes");
    assert_eq!(leftovers(root.path(), "home"), ["notes.txt"]);
}

#[test]
fn a_law_set_name_with_dot_dot_writes_nothing_anywhere() {
    ensure_plugins_built();
    let root = tempfile::tempdir().expect("temp dir");
    let ls = root.path().join("ls.toml");
    std::fs::write(
        &ls,
        "name = \"x/../../../pwned\"\n[[laws]]\njoint = \"piston\"\nlaw = \"coulomb\"\n",
    )
    .expect("write");
    // Deep enough that `../../../` from inside the result still lands in the temp dir.
    let out = root.path().join("a/b/c/d/results");
    let msg = refused(
        Command::new(tribo_exe())
            .args(["compare", "--steady", "--no-cv", "--quiet", "--lawset"])
            .arg(&ls)
            .arg("--out")
            .arg(&out)
            .env_remove("TRIBO_PLUGIN_PATH"),
    );
    assert_mentions(&msg, &["x/../../../pwned", "contains `/`"]);
    let mut all: Vec<PathBuf> = Vec::new();
    let mut stack = vec![root.path().to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).expect("dir") {
            let p = e.expect("entry").path();
            if p.is_dir() {
                stack.push(p.clone());
            }
            all.push(p);
        }
    }
    assert_eq!(all, [ls], "only the law set exists");
}
