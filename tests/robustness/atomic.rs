//! Result files are written under a temporary name and renamed into place, result directories
//! are swapped in whole: a run that fails midway, or a result that cannot be put in place,
//! leaves the previous results as they were and no temporary file behind.

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
fn a_csv_directory_holding_other_files_is_refused_untouched_and_no_temporary_file_remains() {
    // Before result sets were committed whole, `plateaus.csv` was renamed into place and then
    // `joints.csv` (here a non-empty directory) failed: half a new set beside an old one. Now
    // a directory holding files tribo did not write is refused before anything is written.
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("csv");
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
    assert!(
        stderr.contains("holds files tribo did not write (joints.csv)"),
        "{stderr}"
    );
    assert_eq!(names(&out), ["joints.csv"]);
    assert_eq!(
        names(dir.path()),
        ["csv"],
        "no temporary or lock file beside it"
    );
    assert_eq!(
        std::fs::read_to_string(blocker.join("kept.txt")).expect("kept"),
        "kept"
    );
}

#[test]
fn run_csv_replaces_both_tables_together() {
    // A second `run --csv` into the same directory replaces the pair whole: both tables of
    // every run are of that run's plateau speed.
    ensure_plugins_built();
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("csv");
    for speed in [3000.0, 4000.0] {
        let cycle = format!(
            "cycle.segments=[{{kind=\"ramp\", to_rpm={speed}, duration_s=0.3}}, {{kind=\"hold\", duration_s=0.3}}]"
        );
        let run = Command::new(tribo_exe())
            .args([
                "run",
                "reference-frictionless",
                "--quiet",
                "--lawset",
                "fedem-baseline",
            ])
            .args(["--set", &cycle, "--csv"])
            .arg(&out)
            .env_remove("TRIBO_PLUGIN_PATH")
            .output()
            .expect("tribo runs");
        assert!(run.status.success(), "{}", text(&run).1);
        for table in ["plateaus.csv", "joints.csv"] {
            let t = std::fs::read_to_string(out.join(table)).expect("table");
            let speeds: Vec<f64> = t
                .lines()
                .skip(1)
                .map(|l| {
                    l.split(',')
                        .next()
                        .and_then(|v| v.parse().ok())
                        .expect("speed")
                })
                .collect();
            assert!(!speeds.is_empty(), "{table}: {t}");
            assert!(
                speeds.iter().all(|s| (s - speed).abs() < 1e-6),
                "{table} after the {speed} rpm run: {speeds:?}"
            );
        }
    }
    assert_eq!(
        names(&out),
        [".tribo-results", "joints.csv", "plateaus.csv"]
    );
    assert_eq!(names(dir.path()), [".csv.lock", "csv"]);
}
