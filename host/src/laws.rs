//! `tribo laws`: what plugins were found, as a table for people and JSON for programs.

use std::fmt::Write as _;

use serde_json::{json, Value};
use tribo_plugin_api::loader::{LawLibrary, LawRegistry};
use tribo_plugin_api::{ParamValue, CONTRACT_VERSION};

/// JSON listing: contract version and every law with its parameters.
pub fn to_json(registry: &LawRegistry) -> Value {
    let laws: Vec<Value> = registry.libraries().iter().map(law_json).collect();
    json!({ "contract_version": CONTRACT_VERSION, "laws": laws })
}

fn law_json(lib: &LawLibrary) -> Value {
    let d = lib.description();
    let params: Vec<Value> = d
        .parameters
        .iter()
        .map(|p| {
            let (kind, default) = match &p.default {
                ParamValue::Number(x) => ("number", json!(x)),
                ParamValue::NumberList(v) => ("number_list", json!(v)),
                ParamValue::Bool(b) => ("bool", json!(b)),
                ParamValue::Choice(c) => ("choice", json!(c)),
            };
            let bound = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
            json!({
                "name": p.name, "unit": p.unit, "doc": p.doc, "kind": kind,
                "default": default, "min": bound(p.min), "max": bound(p.max),
                "choices": p.choices,
            })
        })
        .collect();
    json!({
        "name": d.name, "version": d.version, "abi": lib.abi().to_string(),
        "file": lib.path().display().to_string(), "summary": d.summary, "parameters": params,
    })
}

/// Human-readable listing.
pub fn to_text(registry: &LawRegistry) -> String {
    let mut out = String::new();
    if registry.libraries().is_empty() {
        out.push_str("no laws found (searched --plugin paths, TRIBO_PLUGIN_PATH and the tribo executable's directory)\n");
        return out;
    }
    for lib in registry.libraries() {
        let d = lib.description();
        let _ = writeln!(
            out,
            "{} {} [{}]  {}",
            d.name,
            d.version,
            lib.abi(),
            lib.path().display()
        );
        let _ = writeln!(out, "    {}", d.summary);
        let width = d.parameters.iter().map(|p| p.name.len()).max().unwrap_or(0);
        for p in &d.parameters {
            let _ = writeln!(
                out,
                "    {:width$} = {:<10} {:<18} {:<18} {}",
                p.name,
                p.default.to_toml_string(),
                p.unit,
                p.range_text(),
                p.doc,
            );
        }
        out.push('\n');
    }
    out
}
