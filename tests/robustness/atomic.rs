//! Result files are written under a temporary name and renamed into place: a run that fails
//! midway, or a result that cannot be renamed into place, leaves the previous file as it was and
//! no temporary file behind.

use std::path::Path;
use std::process::Command;

use super::common::*;
use super::{args, misbehaving, SHORT};

/// Every name in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_run_failing_midway_leaves_the_previous_time_series_and_no_temporary_file() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("out");
    std::fs::create_dir(&out).expect("mkdir");
    let ts = out.join("ts.csv");
    std::fs::write(&ts, "previous time series\n").expect("write");
    // The law returns NaN at t = 0.2 s, after the time series has started streaming.
    let mut a = misbehaving(dir.path(), 0);
    a.extend(args(&["--timeseries", &ts.to_string_lossy()]));
    let run = Command::new(tribo_exe())
        .args(&a)
        .env_remove("TRIBO_PLUGIN_PATH")
        .output()
        .expect("tribo runs");
    let (_, stderr) = text(&run);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("non-finite force"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(&ts).expect("previous file"),
        "previous time series\n"
    );
    assert_eq!(names(&out), ["ts.csv"]);
}

#[test]
fn a_result_that_cannot_be_renamed_into_place_leaves_no_temporary_file() {
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("csv");
    // joints.csv is a non-empty directory: writing its data succeeds, the rename cannot.
    let blocker = out.join("joints.csv");
    std::fs::create_dir_all(&blocker).expect("mkdir");
    std::fs::write(blocker.join("kept.txt"), "kept").expect("write");
    let rig = workspace().join("rigs/reference-frictionless.toml");
    let run = Command::new(tribo_exe())
        .args(["run", &rig.to_string_lossy(), "--quiet", "--set", SHORT])
        .arg("--csv")
        .arg(&out)
        .env_remove("TRIBO_PLUGIN_PATH")
        .output()
        .expect("tribo runs");
    let (_, stderr) = text(&run);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("writing CSV into"), "{stderr}");
    assert_eq!(names(&out), ["joints.csv", "plateaus.csv"]);
    assert_eq!(
        std::fs::read_to_string(blocker.join("kept.txt")).expect("kept"),
        "kept"
    );
}
