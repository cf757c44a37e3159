//! The dependency invariants of ARCHITECTURE.md ("Invariant: ..."), checked from `cargo
//! metadata`: the crates form layers, each depending only on layers below it; the plugin
//! contract depends on no host crate; a law depends on the contract only; the solver and the
//! layers below the CLI carry no CLI, isolation or Python dependency.

mod common;

use std::collections::BTreeMap;
use std::process::{Command, Stdio};

use serde_json::Value;

/// Each workspace package's dependencies that are built into it (normal and build, not dev),
/// by package name, and the path of its manifest relative to the workspace.
struct Package {
    manifest: String,
    deps: Vec<String>,
    dev_deps: Vec<String>,
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
        map.insert(
            name,
            Package {
                manifest,
                deps,
                dev_deps,
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
