//! Plugin discovery from the user's side: a broken library nobody asked for does not stop a
//! study, `tribo laws` lists what works and warns about the rest, only libraries that are asked
//! for are opened (their initialisers run), and plugin directories others can write are
//! warned about.

mod common;

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output};

use common::*;

/// `tribo ARGS` in `cwd` with `TRIBO_PLUGIN_PATH=plugin_path` and the extra environment `env`.
fn tribo(
    args: &[&str],
    cwd: &Path,
    plugin_path: impl AsRef<OsStr>,
    env: &[(&str, &Path)],
) -> Output {
    ensure_plugins_built();
    let mut cmd = Command::new(tribo_exe());
    cmd.args(args)
        .current_dir(cwd)
        .env("TRIBO_PLUGIN_PATH", plugin_path.as_ref())
        .env_remove("TRIBO_MARKER_FILE");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("tribo runs")
}

/// A plugin directory holding two unusable plugin files: a text file and a shared library
/// without the Tribo symbols. Returns the directory and the two files.
fn broken_plugin_dir() -> (tempfile::TempDir, String, String) {
    let dir = tempfile::tempdir().expect("temp dir");
    let text_file = dir.path().join("libtribo_law_broken.so");
    std::fs::write(&text_file, "this is a text file, not ELF\n").expect("write");
    let no_symbols = dir.path().join("libtribo_law_nosyms.so");
    compile_c(&[c_fixture("no_symbols.c")], &no_symbols, true);
    let s = |p: &Path| p.to_str().expect("utf-8").to_string();
    (dir, s(&text_file), s(&no_symbols))
}

#[test]
fn a_broken_library_nobody_asks_for_does_not_stop_a_compare() {
    let (plugins, text_file, no_symbols) = broken_plugin_dir();
    let work = tempfile::tempdir().expect("temp dir");
    let out = tribo(
        &["compare", "--steady", "--no-cv", "--out", "out", "--json"],
        work.path(),
        plugins.path(),
        &[],
    );
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).expect("JSON results");
    let sets = j["sets"].as_array().expect("sets");
    assert!(sets.len() >= 2, "{stdout}");
    for set in sets {
        let plateaus = set["run"]["plateaus"].as_array().expect("plateaus");
        assert!(!plateaus.is_empty());
        assert!(plateaus
            .iter()
            .all(|p| p["motoring_torque_nm"].as_f64().is_some_and(|t| t > 0.0)));
    }
    assert!(work.path().join("out/comparison.json").is_file());
    // Ignored without a word: the files were never opened.
    assert!(
        !stderr.contains(&text_file) && !stderr.contains(&no_symbols),
        "{stderr}"
    );
}

#[test]
fn tribo_laws_lists_the_good_laws_and_warns_about_each_broken_file() {
    let (plugins, text_file, no_symbols) = broken_plugin_dir();
    let out = tribo(&["laws"], plugins.path(), plugins.path(), &[]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    for law in ["coulomb", "c-coulomb", "stribeck-duty", "lugre"] {
        assert!(
            stdout.lines().any(|l| l.starts_with(&format!("{law} "))),
            "{law} not listed:\n{stdout}"
        );
    }
    // One warning per broken file, naming it and why.
    let warning_of = |file: &str| {
        stderr
            .lines()
            .find(|l| l.starts_with("warning:") && l.contains(file))
            .unwrap_or_else(|| panic!("no warning names {file}:\n{stderr}"))
            .to_string()
    };
    assert!(warning_of(&text_file).contains("not a loadable shared library"));
    assert!(warning_of(&no_symbols).contains("not a Tribo law"));
    assert!(!stdout.contains(&text_file), "warnings go to stderr");

    // JSON: the same laws, and each broken file with its error.
    let out = tribo(&["laws", "--json"], plugins.path(), plugins.path(), &[]);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    let j: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
    let names: Vec<&str> = j["laws"]
        .as_array()
        .expect("laws")
        .iter()
        .map(|l| l["name"].as_str().expect("name"))
        .collect();
    assert!(names.contains(&"coulomb") && names.contains(&"stribeck-duty"));
    let broken = j["broken"].as_array().expect("broken");
    let files: Vec<&str> = broken
        .iter()
        .map(|b| b["file"].as_str().expect("file"))
        .collect();
    assert_eq!(files, [text_file.as_str(), no_symbols.as_str()]);
    assert!(broken[0]["error"]
        .as_str()
        .is_some_and(|e| e.contains("not a loadable shared library")));
    assert_eq!(j["warnings"].as_array().expect("warnings").len(), 2);
}

#[test]
fn a_law_not_found_names_the_broken_candidates() {
    let (plugins, text_file, no_symbols) = broken_plugin_dir();
    let out = tribo(
        &[
            "run",
            "crf250r-motored",
            "--steady",
            "--law",
            "piston=broken",
        ],
        plugins.path(),
        plugins.path(),
        &[],
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_mentions(
        &stderr,
        &[
            "--law: piston=broken",
            "no law named `broken`",
            "coulomb",
            "2 plugin files could not be opened",
            &text_file,
            "not a loadable shared library",
            &no_symbols,
            "not a Tribo law",
        ],
    );
}

#[test]
fn an_explicit_plugin_file_that_fails_to_load_is_still_an_error() {
    let (plugins, text_file, _) = broken_plugin_dir();
    let empty = tempfile::tempdir().expect("temp dir");
    let out = tribo(
        &["run", "crf250r-motored", "--steady", "--plugin", &text_file],
        plugins.path(),
        empty.path(),
        &[],
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_mentions(&stderr, &[&text_file, "not a loadable shared library"]);
}

#[test]
fn a_library_is_opened_only_when_its_law_is_asked_for_or_listed() {
    let plugins = tempfile::tempdir().expect("temp dir");
    compile_c(
        &[c_fixture("constructor_marker.c")],
        &plugins.path().join("libtribo_law_fixture_marker.so"),
        true,
    );
    let work = tempfile::tempdir().expect("temp dir");
    let marker = work.path().join("opened.txt");
    let env = [("TRIBO_MARKER_FILE", marker.as_path())];
    let opened = || std::fs::read_to_string(&marker).unwrap_or_default();

    // A run whose rig does not use the law: the library's initialiser never runs.
    let out = tribo(
        &["run", "crf250r-motored", "--steady"],
        work.path(),
        plugins.path(),
        &env,
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out).1);
    assert!(!marker.exists(), "an unused plugin was opened");

    // A run that uses it opens it (once), and it works.
    let out = tribo(
        &[
            "run",
            "crf250r-motored",
            "--steady",
            "--law",
            "piston=fixture-marker",
        ],
        work.path(),
        plugins.path(),
        &env,
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out).1);
    assert_eq!(opened(), "opened\n");

    // `tribo laws` opens every library to list it.
    std::fs::remove_file(&marker).expect("reset the marker");
    let out = tribo(&["laws"], work.path(), plugins.path(), &env);
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stdout.contains("fixture-marker"), "{stdout}");
    assert_eq!(opened(), "opened\n");
}

#[test]
fn a_library_not_named_for_its_law_is_still_found() {
    let plugins = tempfile::tempdir().expect("temp dir");
    // The file name promises `other-name`; the library provides `fixture-marker`.
    compile_c(
        &[c_fixture("constructor_marker.c")],
        &plugins.path().join("libtribo_law_other_name.so"),
        true,
    );
    let work = tempfile::tempdir().expect("temp dir");
    let out = tribo(
        &[
            "run",
            "crf250r-motored",
            "--steady",
            "--law",
            "piston=fixture-marker",
            "--json",
        ],
        work.path(),
        plugins.path(),
        &[],
    );
    let (stdout, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(stdout.contains("fixture-marker"), "{stdout}");
}

#[test]
fn two_files_for_one_law_are_an_error_when_the_law_is_asked_for() {
    let original = built_library("tribo_law_coulomb");
    let name = original.file_name().expect("file name");
    let (a, b) = (
        tempfile::tempdir().expect("temp dir"),
        tempfile::tempdir().expect("temp dir"),
    );
    for dir in [&a, &b] {
        std::fs::copy(&original, dir.path().join(name)).expect("copy");
    }
    let path = std::env::join_paths([a.path(), b.path()]).expect("path list");
    let work = tempfile::tempdir().expect("temp dir");
    let out = tribo(
        &[
            "run",
            "crf250r-motored",
            "--steady",
            "--law",
            "piston=coulomb",
        ],
        work.path(),
        &path,
        &[],
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_mentions(
        &stderr,
        &[
            "two libraries provide the law `coulomb`",
            a.path().join(name).to_str().expect("utf-8"),
            b.path().join(name).to_str().expect("utf-8"),
        ],
    );
    // A run that does not use `coulomb` never opens either copy.
    let out = tribo(
        &[
            "run",
            "crf250r-motored",
            "--steady",
            "--law",
            "piston=c-coulomb",
        ],
        work.path(),
        &path,
        &[],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out).1);
}

#[cfg(unix)]
#[test]
fn a_plugin_directory_others_can_write_is_warned_about_with_its_name_and_mode() {
    use std::os::unix::fs::PermissionsExt;
    let chmod = |dir: &Path, mode: u32| {
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(mode)).expect("chmod")
    };
    let open = tempfile::tempdir().expect("temp dir");
    chmod(open.path(), 0o777);
    let closed = tempfile::tempdir().expect("temp dir");
    chmod(closed.path(), 0o755);
    let work = tempfile::tempdir().expect("temp dir");
    let open_name = open.path().to_str().expect("utf-8");
    let closed_name = closed.path().to_str().expect("utf-8");

    let out = tribo(
        &["run", "crf250r-motored", "--steady"],
        work.path(),
        open.path(),
        &[],
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning:") && l.contains(open_name))
        .collect();
    assert_eq!(warnings.len(), 1, "once per directory:\n{stderr}");
    assert_mentions(warnings[0], &["0777", "can be written by anyone", "as you"]);

    // The directory of an explicit --plugin file is checked too.
    let lib = open.path().join("libtribo_law_fixture_marker.so");
    compile_c(&[c_fixture("constructor_marker.c")], &lib, true);
    let out = tribo(
        &["laws", "--plugin", lib.to_str().expect("utf-8")],
        work.path(),
        closed.path(),
        &[],
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr
            .lines()
            .any(|l| l.starts_with("warning:") && l.contains(open_name) && l.contains("0777")),
        "{stderr}"
    );

    // A directory only its owner can write: no warning, nor for the executable's directory
    // when it is not writable by others either.
    let out = tribo(
        &["run", "crf250r-motored", "--steady"],
        work.path(),
        closed.path(),
        &[],
    );
    let (_, stderr) = text(&out);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(!stderr.contains(closed_name), "{stderr}");
    let exe_dir = profile_dir();
    let exe_mode = std::fs::metadata(&exe_dir)
        .expect("stat")
        .permissions()
        .mode();
    if exe_mode & 0o022 == 0 {
        assert!(!stderr.contains("can be written by"), "{stderr}");
    }
}

/// A plugin directory of 10,000 junk files gives a few warning lines, not one per file: the
/// first files by name and a count of the rest; `--json` still lists each under `broken`.
#[test]
fn ten_thousand_junk_plugin_files_give_a_short_summary() {
    let dir = tempfile::tempdir().expect("temp dir");
    let n = 10_000;
    for k in 0..n {
        std::fs::write(
            dir.path().join(format!("libtribo_law_junk{k}.so")),
            "junk\n",
        )
        .expect("write");
    }
    let out = tribo(&["laws"], dir.path(), dir.path(), &[]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(stdout.contains("coulomb"), "the good laws are listed");
    let lines: Vec<&str> = stderr.lines().collect();
    assert!(lines.len() <= 10, "{} lines of warnings", lines.len());
    assert!(stderr.len() < 2_000, "{} bytes of warnings", stderr.len());
    assert!(
        stderr.contains(&format!("{} more plugin files", n - 3))
            && stderr.contains(&format!("{n} in all")),
        "{stderr}"
    );
    let json = tribo(&["laws", "--json"], dir.path(), dir.path(), &[]);
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).expect("json");
    assert_eq!(v["broken"].as_array().map(Vec::len), Some(n));
}
