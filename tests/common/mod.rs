//! Helpers shared by the integration tests: locating the built binary and plugins, building
//! fixtures, compiling C with the system compiler.
#![allow(dead_code)]

pub mod closed_form;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

/// The workspace root.
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("host/ has a parent")
        .to_path_buf()
}

/// `--lawset` arguments naming every bundled law set.
pub const ALL_LAWSETS: [&str; 6] = [
    "--lawset",
    "fedem-baseline",
    "--lawset",
    "stribeck-duty",
    "--lawset",
    "physical-bearings",
];

/// The `tribo` binary under test.
pub fn tribo_exe() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_tribo"))
}

/// The profile output directory (`target/debug` or `target/release`) holding the binary and
/// the plugin libraries.
pub fn profile_dir() -> PathBuf {
    tribo_exe()
        .parent()
        .expect("binary has a directory")
        .to_path_buf()
}

/// Build the plugin and fixture libraries into the profile directory (once per test process).
/// `cargo test` builds test targets, not every cdylib, so the tests make sure themselves.
pub fn ensure_plugins_built() {
    static BUILT: OnceLock<()> = OnceLock::new();
    BUILT.get_or_init(|| {
        let mut cmd = Command::new(env!("CARGO"));
        cmd.arg("build")
            .current_dir(workspace())
            .args(profile_args());
        // Every workspace member but the host: all law plugins and the fixtures.
        cmd.args(["--workspace", "--exclude", "tribo"]);
        let out = cmd.output().expect("cargo runs");
        assert!(
            out.status.success(),
            "building plugins failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    });
}

/// The `cargo build` arguments selecting the profile the tests were built with.
fn profile_args() -> Vec<String> {
    match profile_dir().file_name().and_then(|n| n.to_str()) {
        Some("debug") | None => Vec::new(),
        Some("release") => vec!["--release".into()],
        Some(other) => vec!["--profile".into(), other.into()],
    }
}

/// Build example `name` of workspace package `package` in the tests' profile and return the
/// path of its executable.
pub fn build_example(package: &str, name: &str) -> PathBuf {
    let out = Command::new(env!("CARGO"))
        .args(["build", "-p", package, "--example", name])
        .args(profile_args())
        .current_dir(workspace())
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "building example {name} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let exe = profile_dir()
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(exe.is_file(), "{} was not built", exe.display());
    exe
}

/// Path of a built library with crate lib-name `lib` in the profile directory.
pub fn built_library(lib: &str) -> PathBuf {
    ensure_plugins_built();
    let path = profile_dir().join(tribo::plugin_api::loader::plugin_file_name(lib));
    assert!(path.is_file(), "{} was not built", path.display());
    path
}

/// Run `tribo` with `args` in an environment without TRIBO_PLUGIN_PATH (unless `plugin_path`).
pub fn run_tribo(args: &[&str], plugin_path: Option<&Path>) -> Output {
    ensure_plugins_built();
    let mut cmd = Command::new(tribo_exe());
    cmd.args(args).env_remove("TRIBO_PLUGIN_PATH");
    if let Some(p) = plugin_path {
        cmd.env("TRIBO_PLUGIN_PATH", p);
    }
    cmd.output().expect("tribo runs")
}

/// Text of stdout and stderr.
pub fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The system C compiler (`$CC`, else `cc`).
pub fn c_compiler() -> String {
    std::env::var("CC").unwrap_or_else(|_| "cc".into())
}

/// Compile C `sources` into `output` with the contract header on the include path; `shared`
/// makes a shared library, otherwise an executable.
pub fn compile_c(sources: &[PathBuf], output: &Path, shared: bool) {
    compile_c_with(
        sources,
        output,
        shared,
        &workspace().join("plugin-api/include"),
    );
}

/// [`compile_c`] with the header from directory `include` (e.g. the frozen version-1 header).
pub fn compile_c_with(sources: &[PathBuf], output: &Path, shared: bool, include: &Path) {
    let mut cmd = Command::new(c_compiler());
    if shared {
        cmd.args(["-shared", "-fPIC"]);
    }
    cmd.args(["-O2", "-std=c99", "-Wall", "-Wextra"])
        .arg("-I")
        .arg(include)
        .args(sources)
        .arg("-o")
        .arg(output)
        .arg("-lm");
    let out = cmd.output().expect("the system C compiler runs");
    assert!(
        out.status.success(),
        "C compile failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A fixture C source.
pub fn c_fixture(name: &str) -> PathBuf {
    workspace().join("tests/fixtures/c").join(name)
}

/// `tribo ARGS` run in `cwd`, without TRIBO_PLUGIN_PATH.
pub fn tribo_in(args: &[&str], cwd: &Path) -> Output {
    ensure_plugins_built();
    Command::new(tribo_exe())
        .args(args)
        .current_dir(cwd)
        .env_remove("TRIBO_PLUGIN_PATH")
        .output()
        .expect("tribo runs")
}

/// `tribo ARGS` run in `cwd` (without TRIBO_PLUGIN_PATH), its standard output parsed as JSON;
/// panics with the standard error if the command fails.
pub fn json_in(args: &[&str], cwd: &Path) -> serde_json::Value {
    let out = tribo_in(args, cwd);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{args:?}: {stderr}");
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"))
}

/// Panics naming the first of `words` that `text` does not contain.
pub fn assert_mentions(text: &str, words: &[&str]) {
    for word in words {
        assert!(text.contains(word), "`{word}` missing:\n{text}");
    }
}

/// The plateaus (JSON) of `lawset` in a steady-state comparison at `speeds_rpm` with the oil at
/// `temp_c` (scores skipped: only the runs matter), run in `dir`.
pub fn steady_plateaus(
    dir: &Path,
    lawset: &str,
    speeds_rpm: &[f64],
    temp_c: f64,
) -> Vec<serde_json::Value> {
    let tag: String = lawset
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    let grid = dir.join(format!("grid-{tag}-{temp_c}.csv"));
    let mut text = String::from("speed_rpm,torque_nm,oil_temp_c\n");
    for s in speeds_rpm {
        text.push_str(&format!("{s},1.0,{temp_c}\n"));
    }
    std::fs::write(&grid, text).expect("write the speed grid");
    let out = format!("out-{tag}-{temp_c}");
    let j = json_in(
        &[
            "compare",
            "--steady",
            "--no-cv",
            "--lawset",
            lawset,
            "--data",
            grid.to_str().expect("utf-8"),
            "--out",
            &out,
            "--json",
        ],
        dir,
    );
    j["sets"][0]["run"]["plateaus"]
        .as_array()
        .expect("plateaus")
        .clone()
}
