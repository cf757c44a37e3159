//! The doc runner: every fenced `sh` or `bash` block of README.md, python/README.md,
//! docs/writing-a-law.md, docs/fmu.md, docs/temperature.md, docs/reliability.md,
//! docs/crf250r-study.md, docs/engines.md, docs/solver.md, docs/performance.md and docs/laws/
//! is run as a script, from a fresh directory where `./target/release/tribo` and `tribo` are
//! this build's binary, and must succeed. A block that cannot run here says so in the doc, on
//! the line before its fence: `<!-- doc-runner: skip: WHY -->` (it needs a prior step, another
//! machine, or it is the test command itself); the runner refuses a marker without a reason.
//! Python blocks run under `python/build-and-test.sh`, which has the wheel installed; here they
//! must carry the marker naming that step. The README's lists of laws and law sets are checked
//! against `tribo laws` and the bundled law sets.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::*;

/// One fenced block of a document.
struct Block {
    /// The document, relative to the workspace.
    file: String,
    /// 1-based line of the opening fence.
    line: usize,
    /// The fence's info string (`sh`, `python`, `text`, ...).
    lang: String,
    /// The block's text.
    text: String,
    /// The reason of a `<!-- doc-runner: skip: WHY -->` marker before it.
    skip: Option<String>,
}

/// The documents the runner reads.
fn documents() -> Vec<PathBuf> {
    let ws = workspace();
    let mut docs = vec![
        ws.join("README.md"),
        ws.join("python/README.md"),
        ws.join("docs/writing-a-law.md"),
        ws.join("docs/fmu.md"),
        ws.join("docs/temperature.md"),
        ws.join("docs/reliability.md"),
        ws.join("docs/crf250r-study.md"),
        ws.join("docs/engines.md"),
        ws.join("docs/solver.md"),
        ws.join("docs/performance.md"),
    ];
    let mut found: Vec<PathBuf> = std::fs::read_dir(ws.join("docs/laws"))
        .expect("docs/laws")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    found.sort();
    docs.extend(found);
    docs
}

/// Every fenced block of `path`.
fn blocks(path: &Path) -> Vec<Block> {
    let text = std::fs::read_to_string(path).expect("read doc");
    let file = path
        .strip_prefix(workspace())
        .unwrap_or(path)
        .display()
        .to_string();
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let Some(info) = lines[i].trim_start().strip_prefix("```") else {
            i += 1;
            continue;
        };
        let start = i;
        let mut body = String::new();
        i += 1;
        while i < lines.len() && !lines[i].trim_start().starts_with("```") {
            body.push_str(lines[i]);
            body.push('\n');
            i += 1;
        }
        let skip = start
            .checked_sub(1)
            .and_then(|p| lines[p].trim().strip_prefix("<!-- doc-runner: skip:"))
            .map(|r| r.trim_end_matches("-->").trim().to_string());
        out.push(Block {
            file: file.clone(),
            line: start + 1,
            lang: info.trim().to_string(),
            text: body,
            skip,
        });
        i += 1;
    }
    out
}

/// A directory holding `tribo`, this build's binary, to put first on PATH.
fn bin_dir(tmp: &Path) -> PathBuf {
    let bin = tmp.join("bin");
    std::fs::create_dir_all(&bin).expect("mkdir");
    std::os::unix::fs::symlink(tribo_exe(), bin.join("tribo")).expect("symlink");
    bin
}

/// Run one shell block in a fresh directory whose `target` is this build's target directory;
/// `cargo build --release` alone is a step already done (the tests run on that build); any
/// other cargo command in a block fails it (such a block needs a skip marker).
fn run_shell(block: &Block, bin: &Path, tmp: &Path) -> Result<(), String> {
    let dir = tmp.join(format!(
        "{}-{}",
        block.file.replace(['/', '.'], "_"),
        block.line
    ));
    std::fs::create_dir_all(&dir).expect("mkdir");
    std::os::unix::fs::symlink(workspace().join("target"), dir.join("target")).expect("symlink");
    let prelude = "set -e\n\
        cargo() { if [ \"$*\" = \"build --release\" ]; then return 0; fi; \
        echo \"doc-runner: 'cargo $*' is not run here: mark the block\" >&2; return 97; }\n";
    let out = Command::new("timeout")
        .args(["300", "bash", "-c"])
        .arg(format!("{prelude}{}", block.text))
        .current_dir(&dir)
        .env(
            "PATH",
            format!(
                "{}:{}",
                bin.display(),
                std::env::var("PATH").unwrap_or_default()
            ),
        )
        .env_remove("TRIBO_PLUGIN_PATH")
        .env("HOME", &dir)
        .output()
        .map_err(|e| format!("bash: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        let (stdout, stderr) = text(&out);
        Err(format!(
            "{}:{}: exit {:?}\n--- block ---\n{}--- stdout (end) ---\n{}\n--- stderr (end) ---\n{}",
            block.file,
            block.line,
            out.status.code(),
            block.text,
            tail(&stdout),
            tail(&stderr)
        ))
    }
}

/// The last 30 lines of `s`.
fn tail(s: &str) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(30)..].join("\n")
}

#[test]
fn every_documented_command_and_script_runs_or_says_why_not() {
    ensure_plugins_built();
    let tmp = tempfile::tempdir().expect("temp dir");
    let bin = bin_dir(tmp.path());
    let mut failures = Vec::new();
    let mut ran = 0;
    for doc in documents() {
        for block in blocks(&doc) {
            let runnable = matches!(block.lang.as_str(), "sh" | "bash" | "python" | "py");
            if !runnable {
                continue;
            }
            if let Some(why) = &block.skip {
                if why.is_empty() {
                    failures.push(format!(
                        "{}:{}: a skip marker without a reason",
                        block.file, block.line
                    ));
                }
                continue;
            }
            if block.lang.starts_with("py") {
                failures.push(format!(
                    "{}:{}: a Python block needs the wheel: run it from python/build-and-test.sh and mark it `<!-- doc-runner: skip: ... -->`",
                    block.file, block.line
                ));
                continue;
            }
            ran += 1;
            if let Err(e) = run_shell(&block, &bin, tmp.path()) {
                failures.push(e);
            }
        }
    }
    assert!(ran >= 5, "only {ran} blocks ran");
    assert!(
        failures.is_empty(),
        "{} documented blocks failed:\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
}

/// The law names in the first column of the README's law table (`name` or `a`, `b`).
fn readme_table_names(readme: &str, header: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut inside = false;
    for line in readme.lines() {
        if line.starts_with(header) {
            inside = true;
            continue;
        }
        if inside {
            if !line.starts_with('|') {
                break;
            }
            let first = line.split('|').nth(1).unwrap_or("");
            names.extend(
                first
                    .split(',')
                    .map(|n| n.trim().trim_matches('`').to_string())
                    .filter(|n| !n.is_empty() && !n.starts_with("---")),
            );
        }
    }
    names
}

#[test]
fn readme_lists_every_law_and_every_bundled_law_set() {
    ensure_plugins_built();
    let readme = std::fs::read_to_string(workspace().join("README.md")).expect("readme");
    let out = run_tribo(&["laws", "--json"], None);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    let laws: serde_json::Value = serde_json::from_str(&stdout).expect("json");
    let found: Vec<String> = laws["laws"]
        .as_array()
        .expect("laws")
        .iter()
        .filter_map(|l| l["name"].as_str().map(str::to_string))
        .collect();
    // The law library: one directory per law under plugins/, each found by `tribo laws`.
    let mut library: Vec<String> = std::fs::read_dir(workspace().join("plugins"))
        .expect("plugins/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().to_string())
        .collect();
    library.sort();
    for law in &library {
        assert!(found.contains(law), "`tribo laws` does not list {law}");
        assert!(
            workspace()
                .join("docs/laws")
                .join(format!("{law}.md"))
                .is_file()
                || law.starts_with("c-"),
            "no docs/laws/{law}.md"
        );
    }
    let mut listed = readme_table_names(&readme, "| law | what | docs |");
    listed.sort();
    assert_eq!(
        listed, library,
        "README's law table against the law library"
    );
    // The bundled law sets, as the README lists them after `--lawset` takes a bundled name.
    let mut sets: Vec<String> = tribo::bundled::lawset_names()
        .iter()
        .map(|s| s.to_string())
        .collect();
    sets.sort();
    let line = readme
        .split("`--lawset` takes a bundled name (")
        .nth(1)
        .and_then(|r| r.split(')').next())
        .expect("the README lists the bundled law sets");
    let mut listed: Vec<String> = line
        .split(',')
        .map(|n| n.trim().trim_matches('`').to_string())
        .collect();
    listed.sort();
    assert_eq!(listed, sets, "README's bundled law sets");
    for set in &sets {
        assert!(
            workspace()
                .join("rigs/lawsets")
                .join(format!("{set}.toml"))
                .is_file(),
            "{set}"
        );
    }
}
