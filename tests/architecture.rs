//! The dependency invariants of ARCHITECTURE.md ("Invariant: ..."), checked from `cargo
//! metadata`: the crates form layers, each depending only on layers below it; the plugin
//! contract depends on no host crate; a law depends on the contract only; the solver and the
//! layers below the CLI carry no CLI, isolation or Python dependency. And inside each crate,
//! no import circle between its files (`imports`).

mod common;
#[path = "architecture/imports.rs"]
mod imports;

use std::collections::BTreeMap;
use std::process::{Command, Stdio};

use serde_json::Value;

/// Each workspace package's dependencies that are built into it (normal and build, not dev),
/// by package name, and the path of its manifest relative to the workspace.
struct Package {
    manifest: String,
    deps: Vec<String>,
    dev_deps: Vec<String>,
    /// The root files of its library and binaries (not tests, examples or benches).
    roots: Vec<std::path::PathBuf>,
}

fn packages() -> BTreeMap<String, Package> {
    let root = common::workspace();
    let out = Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(&root)
        .stderr(Stdio::inherit())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata failed (its message above)"
    );
    let meta: Value = serde_json::from_slice(&out.stdout).expect("cargo metadata's JSON");
    let mut map = BTreeMap::new();
    for p in meta["packages"].as_array().expect("packages") {
        let name = p["name"].as_str().expect("name").to_string();
        let manifest = p["manifest_path"].as_str().expect("manifest_path");
        let manifest = std::path::Path::new(manifest)
            .strip_prefix(&root)
            .map(|m| m.display().to_string())
            .unwrap_or_else(|_| manifest.to_string());
        let mut deps = Vec::new();
        let mut dev_deps = Vec::new();
        for d in p["dependencies"].as_array().expect("dependencies") {
            let dep = d["name"].as_str().expect("dependency name").to_string();
            if d["kind"].as_str() == Some("dev") {
                dev_deps.push(dep);
            } else {
                deps.push(dep);
            }
        }
        let roots = p["targets"]
            .as_array()
            .expect("targets")
            .iter()
            .filter(|t| {
                t["kind"].as_array().is_some_and(|k| {
                    k.iter().any(|k| {
                        matches!(
                            k.as_str(),
                            Some("lib" | "rlib" | "cdylib" | "staticlib" | "proc-macro" | "bin")
                        )
                    })
                })
            })
            .map(|t| std::path::PathBuf::from(t["src_path"].as_str().expect("src_path")))
            .collect();
        map.insert(
            name,
            Package {
                manifest,
                deps,
                dev_deps,
                roots,
            },
        );
    }
    map
}

/// The layer of a host-side crate (a crate depends only on lower layers); `None` for a law
/// or a test fixture.
fn layer(name: &str) -> Option<u32> {
    match name {
        "tribo-plugin-api" => Some(0),
        "tribo-core" | "tribo-isolate" => Some(1),
        "tribo-config" => Some(2),
        "tribo-studies" | "tribo-fmu" => Some(3),
        "tribo" | "tribo-python" => Some(4),
        _ => None,
    }
}

/// The crates that only the front ends (CLI, Python) may use.
const FRONT_END_ONLY: &[&str] = &["clap", "indicatif", "plotters", "anyhow", "pyo3"];

#[test]
fn every_workspace_crate_is_in_a_layer_or_is_a_law_or_a_fixture() {
    for (name, p) in packages() {
        let law = p.manifest.starts_with("plugins/") && name.starts_with("tribo-law-");
        let fixture = p.manifest.starts_with("tests/fixtures/");
        assert!(
            layer(&name).is_some() || law || fixture,
            "{name} ({}): a new crate: give it a layer here and in ARCHITECTURE.md",
            p.manifest
        );
    }
}

/// The layering's breaches in `all`: a crate depending on its own or a higher layer, or
/// linking a law or a fixture.
fn layer_breaches(all: &BTreeMap<String, Package>) -> Vec<String> {
    let mut out = Vec::new();
    for (name, p) in all {
        let Some(own) = layer(name) else { continue };
        for dep in p.deps.iter().filter(|d| all.contains_key(*d)) {
            match layer(dep) {
                Some(l) if l < own => {}
                Some(l) => out.push(format!("{name} (layer {own}) depends on {dep} (layer {l})")),
                None => out.push(format!(
                    "{name} depends on the law or fixture {dep}: laws are loaded, never linked"
                )),
            }
        }
    }
    out
}

#[test]
fn invariant_each_crate_depends_only_on_lower_layers() {
    let breaches = layer_breaches(&packages());
    assert!(breaches.is_empty(), "{breaches:#?}");
}

#[test]
fn the_layer_check_catches_a_dependency_upwards_and_a_linked_law() {
    let package = |manifest: &str, deps: &[&str]| Package {
        manifest: manifest.into(),
        deps: deps.iter().map(|d| d.to_string()).collect(),
        dev_deps: Vec::new(),
        roots: Vec::new(),
    };
    let mut all = BTreeMap::new();
    all.insert(
        "tribo-plugin-api".into(),
        package("plugin-api/Cargo.toml", &[]),
    );
    all.insert(
        "tribo-config".into(),
        package("host/config/Cargo.toml", &["tribo-core"]),
    );
    all.insert(
        "tribo-law-x".into(),
        package("plugins/x/Cargo.toml", &["tribo-plugin-api"]),
    );
    all.insert(
        "tribo-core".into(),
        package("host/core/Cargo.toml", &["tribo-plugin-api"]),
    );
    assert!(layer_breaches(&all).is_empty());
    all.insert(
        "tribo-core".into(),
        package("host/core/Cargo.toml", &["tribo-config"]),
    );
    assert_eq!(layer_breaches(&all).len(), 1, "{:?}", layer_breaches(&all));
    all.insert(
        "tribo-core".into(),
        package("host/core/Cargo.toml", &["tribo-law-x"]),
    );
    assert!(layer_breaches(&all)[0].contains("never linked"));
}

#[test]
fn invariant_the_plugin_contract_depends_on_no_host_crate() {
    let all = packages();
    let api = &all["tribo-plugin-api"];
    let host: Vec<&String> = api.deps.iter().filter(|d| all.contains_key(*d)).collect();
    assert!(host.is_empty(), "tribo-plugin-api depends on {host:?}");
}

#[test]
fn invariant_a_law_depends_on_the_plugin_contract_only() {
    let all = packages();
    for (name, p) in &all {
        let law = p.manifest.starts_with("plugins/");
        let fixture = p.manifest.starts_with("tests/fixtures/");
        if !law && !fixture {
            continue;
        }
        for dep in p.deps.iter().chain(&p.dev_deps) {
            assert!(
                !all.contains_key(dep) || dep == "tribo-plugin-api",
                "{name} ({}) depends on {dep}: a law sees the contract only",
                p.manifest
            );
        }
    }
}

#[test]
fn invariant_the_solver_depends_on_the_contract_and_numerics_only() {
    let all = packages();
    let core = &all["tribo-core"];
    let mut deps = core.deps.clone();
    deps.sort();
    assert_eq!(
        deps,
        ["nalgebra", "thiserror", "tribo-plugin-api"],
        "tribo-core's dependencies"
    );
}

#[test]
fn invariant_nothing_below_the_front_ends_uses_a_front_end_crate() {
    for (name, p) in packages() {
        if matches!(layer(&name), None | Some(4)) {
            continue;
        }
        for dep in &p.deps {
            assert!(
                !FRONT_END_ONLY.contains(&dep.as_str()),
                "{name} depends on {dep}, which only the CLI and the Python package may use"
            );
        }
    }
}

#[test]
fn invariant_abi_stable_is_named_by_the_plugin_contract_only() {
    for (name, p) in packages() {
        if name != "tribo-plugin-api" {
            assert!(
                !p.deps.iter().any(|d| d == "abi_stable"),
                "{name} depends on abi_stable directly"
            );
        }
    }
}

#[test]
fn invariant_the_host_links_no_law() {
    let all = packages();
    for (name, p) in &all {
        if layer(name).is_none() {
            continue;
        }
        for dep in &p.deps {
            assert!(
                !dep.starts_with("tribo-law-"),
                "{name} links the law {dep}: laws are found and loaded at run time"
            );
        }
    }
}

/// Import circles known and not yet removed, by crate: each circle's files, sorted (paths from
/// the workspace root). A circle listed here is printed but does not fail the test; any other
/// circle does, and so does a listed one that grew. tribo-core's goes with the simulation's
/// stages (`Simulation` as data and stages); the others run through a
/// parent module (`lib.rs`, `mod.rs`) that both defines items its children use and re-exports
/// theirs, and go once those items move into a leaf module of their own.
const KNOWN_CIRCLES: &[(&str, &[&str])] = &[
    (
        "tribo-core",
        &[
            "host/core/src/sim/adaptive.rs",
            "host/core/src/sim/crank_angle.rs",
            "host/core/src/sim/evaluate.rs",
            "host/core/src/sim/limit.rs",
            "host/core/src/sim/lobatto.rs",
            "host/core/src/sim/mod.rs",
            "host/core/src/sim/orbit.rs",
            "host/core/src/sim/plateau.rs",
            "host/core/src/sim/replay.rs",
            "host/core/src/sim/settings.rs",
            "host/core/src/sim/stepper.rs",
            "host/core/src/sim/stepping.rs",
            "host/core/src/sim/torsional.rs",
            "host/core/src/sim/transient.rs",
        ],
    ),
    (
        "tribo-config",
        &[
            "host/config/src/lawset.rs",
            "host/config/src/rig/error.rs",
            "host/config/src/rig/laws.rs",
            "host/config/src/rig/load.rs",
            "host/config/src/rig/mod.rs",
            "host/config/src/rig/oil_file.rs",
            "host/config/src/rig/trace.rs",
            "host/config/src/rig/validate/mod.rs",
        ],
    ),
    (
        "tribo-plugin-api",
        &[
            "plugin-api/src/loader/c_abi.rs",
            "plugin-api/src/loader/discover.rs",
            "plugin-api/src/loader/mod.rs",
            "plugin-api/src/loader/rust.rs",
        ],
    ),
];

/// Every crate's file-level import graph (`tests/architecture/imports.rs`), printed with
/// `--nocapture`: the files and imports per crate, and its circles with the names that tie them
/// (with `TRIBO_SHOW_IMPORTS=1`, every import).
#[test]
fn invariant_no_import_circle_between_the_files_of_a_crate() {
    let root = common::workspace();
    let show_all = std::env::var_os("TRIBO_SHOW_IMPORTS").is_some_and(|v| v == "1");
    let mut unknown = Vec::new();
    for (name, p) in packages() {
        for crate_root in &p.roots {
            let g = imports::graph(crate_root, &root).expect("the crate's sources read");
            let imports: usize = g.edges.values().map(|m| m.len()).sum();
            let found = imports::circles(&g);
            println!(
                "{name} ({}): {} files, {imports} file imports, {} circle(s)",
                crate_root
                    .strip_prefix(&root)
                    .unwrap_or(crate_root)
                    .display(),
                g.files.len(),
                found.len()
            );
            if show_all {
                for (a, to) in &g.edges {
                    for (b, names) in to {
                        let names: Vec<&str> = names.iter().map(String::as_str).collect();
                        println!("  {a} -> {b}: {}", names.join(", "));
                    }
                }
            }
            for c in found {
                let known = KNOWN_CIRCLES
                    .iter()
                    .any(|(k, files)| *k == name && files.iter().eq(c.iter()));
                let text = format!(
                    "{name}: circle of {}{}",
                    c.join(", "),
                    imports::describe(&g, &c)
                );
                println!("  {}{text}", if known { "known, " } else { "" });
                if !known {
                    unknown.push(text);
                }
            }
        }
    }
    assert!(
        unknown.is_empty(),
        "import circles between files (move what both sides share into a module below them):\n{}",
        unknown.join("\n")
    );
}

/// The circle finder on a small crate written for it: a root, a file module with a child in
/// its folder, a `mod.rs` module, imports by `crate::`, `super::`, a use tree, a child name, a
/// path in code; comments, strings and an inline test module's `use super::*` are no imports.
#[test]
fn the_import_graph_finds_a_circle_and_reads_no_comment_as_an_import() {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let src = dir.path().join("src");
    std::fs::create_dir_all(src.join("a")).expect("src/a");
    std::fs::create_dir_all(src.join("m")).expect("src/m");
    let write = |p: &str, text: &str| std::fs::write(src.join(p), text).expect("write");
    write(
        "lib.rs",
        "//! See [`crate::b`].\npub mod a;\npub mod b;\nmod m;\npub mod c;\nuse m::Thing;\n",
    );
    write(
        "a.rs",
        "pub mod inner;\nuse crate::{b::{X, Y as Z}, c};\nmod tests { use super::*; }\n",
    );
    write("a/inner.rs", "fn f() { super::super::m::go(); }\n");
    write(
        "b.rs",
        "// use crate::c::Q;\nconst S: &str = \"crate::c::Q\";\nconst R: &str = r#\"use crate::a;\"#;\nfn f<'a>(x: &'a u8) -> char { 'c' }\n",
    );
    write("c.rs", "use crate::m;\n");
    write("m/mod.rs", "pub fn go() { crate::a::f(); }\n");
    let g = imports::graph(&src.join("lib.rs"), dir.path()).expect("read");
    let edges: Vec<(String, String)> = g
        .edges
        .iter()
        .flat_map(|(a, to)| to.keys().map(move |b| (a.clone(), b.clone())))
        .collect();
    let e = |a: &str, b: &str| (format!("src/{a}"), format!("src/{b}"));
    assert_eq!(
        edges,
        [
            e("a.rs", "b.rs"),
            e("a.rs", "c.rs"),
            e("a/inner.rs", "m/mod.rs"),
            e("c.rs", "m/mod.rs"),
            e("lib.rs", "m/mod.rs"),
            e("m/mod.rs", "a.rs"),
        ]
    );
    // a -> c -> m -> a; b is imported from but imports nothing (its comment and strings).
    assert_eq!(
        imports::circles(&g),
        [vec!["src/a.rs", "src/c.rs", "src/m/mod.rs"]]
    );
    write("b.rs", "pub fn f() { crate::a::f(); }\n");
    let g = imports::graph(&src.join("lib.rs"), dir.path()).expect("read");
    assert_eq!(
        imports::circles(&g),
        [vec!["src/a.rs", "src/b.rs", "src/c.rs", "src/m/mod.rs"]]
    );
}
