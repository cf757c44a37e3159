//! `tribo laws`: what plugins were found, as a table for people and JSON for programs, and the
//! warnings about the plugin search path every command prints.

use std::fmt::Display;
use std::io::Write as _;

use serde_json::{json, Value};
use tribo_plugin_api::loader::{LawLibrary, LawListing, LawRegistry};
use tribo_plugin_api::{ParamValue, CONTRACT_VERSION};

/// The warnings of a listing and its registry, one line each without the `warning: ` prefix:
/// plugin directories and files others can write, then plugin files that could not be opened.
pub fn warnings(registry: &LawRegistry, listing: &LawListing<'_>) -> Vec<String> {
    let mut out: Vec<String> = registry.warnings().iter().map(|w| w.to_string()).collect();
    out.extend(broken_warnings(listing));
    out
}

/// Broken plugin files named one by one; beyond this many, the first ones and a count.
pub const BROKEN_NAMED: usize = 3;

/// One warning per plugin file found on the search path that could not be opened (the error
/// names the file and the reason); past [`BROKEN_NAMED`] files, the first of them and one line
/// counting the rest (a directory of junk gives a few lines, not one per file; `tribo laws
/// --json` lists every one under `broken`).
pub fn broken_warnings(listing: &LawListing<'_>) -> Vec<String> {
    let n = listing.broken.len();
    let shown = if n > BROKEN_NAMED + 1 {
        BROKEN_NAMED
    } else {
        n
    };
    let mut out: Vec<String> = listing.broken[..shown]
        .iter()
        .map(|(_, e)| format!("skipped a plugin file that cannot be used: {e}"))
        .collect();
    if shown < n {
        out.push(format!(
            "skipped {} more plugin files that cannot be used ({n} in all; `tribo laws --json` lists each under `broken`)",
            n - shown
        ));
    }
    out
}

/// What a worker is asked for `tribo laws`: the listing as JSON or text, with the plugin
/// files to leave unopened (a file whose loading ended or hung an earlier worker) and why.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct LawsJob {
    /// JSON instead of the table.
    pub json: bool,
    /// Files not to open, with the reason.
    pub skip: Vec<(std::path::PathBuf, String)>,
}

/// The listing `tribo laws` prints, made where the plugins are opened (a worker process): every
/// library opened but those `job` skips, the warnings printed on standard error.
pub fn render(registry: &LawRegistry, job: &LawsJob) -> anyhow::Result<String> {
    for (path, reason) in &job.skip {
        registry.skip(path, reason.clone());
    }
    // Every library is opened here; one that cannot be is a warning, not a failure.
    let listing = registry.open_all()?;
    print_warnings(&broken_warnings(&listing));
    Ok(if job.json {
        format!(
            "{}\n",
            serde_json::to_string_pretty(&to_json(registry, &listing))?
        )
    } else {
        to_text(&listing)
    })
}

/// Print each of `lines` on standard error as `warning: LINE`. A standard error that cannot be
/// written is ignored: the warnings are advice, the results still go to standard output.
pub fn print_warnings<T: Display>(lines: &[T]) {
    let mut err = std::io::stderr().lock();
    for line in lines {
        let _ = writeln!(err, "warning: {line}");
    }
}

/// JSON listing: contract version, every law with its parameters, the plugin files that could
/// not be opened (`broken`: file and error) and every warning as printed (`warnings`).
pub fn to_json(registry: &LawRegistry, listing: &LawListing<'_>) -> Value {
    let laws: Vec<Value> = listing.laws.iter().map(|l| law_json(l)).collect();
    let broken: Vec<Value> = listing
        .broken
        .iter()
        .map(|(file, e)| json!({ "file": file.display().to_string(), "error": e.to_string() }))
        .collect();
    json!({
        "contract_version": CONTRACT_VERSION,
        "laws": laws,
        "broken": broken,
        "warnings": warnings(registry, listing),
    })
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
        "language": language(lib),
        "contract_version": lib.contract_version(),
        "file": lib.path().display().to_string(), "summary": d.summary,
        "suits": tribo_plugin_api::suits_words(lib.suits()), "parameters": params,
    })
}

/// The names the Fortran interface module's procedure `tribo_set_error` gets from the
/// compilers: gfortran, Intel Fortran (classic and ifx), LLVM Flang. Every Fortran law built
/// with the module (`tribo new-law --lang fortran` compiles it in) exports one of them.
const FORTRAN_MODULE_SYMBOLS: [&[u8]; 3] = [
    b"__tribo_law_MOD_tribo_set_error\0",
    b"tribo_law_mp_tribo_set_error_\0",
    b"_QMtribo_lawPtribo_set_error\0",
];

/// The language a law library was written in, as far as can be told: `rust` for the
/// abi_stable path, `fortran` for a C-ABI library that holds the Fortran interface module
/// (the Fortran module symbols), otherwise `c` (C, C++ or anything else behind the C header),
/// `in-process` for a law linked into this program.
pub fn language(lib: &LawLibrary) -> &'static str {
    use tribo_plugin_api::loader::Abi;
    match lib.abi() {
        Abi::Rust => "rust",
        Abi::InProcess => "in-process",
        Abi::C => {
            // SAFETY: the library is already loaded by the registry (its constructors ran
            // then); opening it again only takes another reference to the same mapping, and
            // the symbols are only looked up, never called or read.
            let fortran = unsafe { libloading::Library::new(lib.path()) }.is_ok_and(|l| {
                FORTRAN_MODULE_SYMBOLS
                    .iter()
                    .any(|name| unsafe { l.get::<*const ()>(name) }.is_ok())
            });
            if fortran {
                "fortran"
            } else {
                "c"
            }
        }
    }
}

/// Human-readable listing of the laws (the warnings go to standard error).
pub fn to_text(listing: &LawListing<'_>) -> String {
    let mut out = String::new();
    if listing.laws.is_empty() {
        out.push_str("no laws found (searched --plugin paths, TRIBO_PLUGIN_PATH and the tribo executable's directory)\n");
        return out;
    }
    for lib in &listing.laws {
        let d = lib.description();
        // A library built against an older contract is adapted by the host; say so.
        let adapted = if lib.contract_version() == CONTRACT_VERSION {
            String::new()
        } else {
            format!(", contract v{}", lib.contract_version())
        };
        out.push_str(&crate::report::wrap(
            &format!(
                "{} {} [{}{adapted}]  {}",
                d.name,
                d.version,
                language(lib),
                lib.path().display()
            ),
            crate::report::MAX_COLUMNS,
            "    ",
        ));
        out.push_str(&crate::report::wrap(
            &format!("    {}", d.summary),
            crate::report::MAX_COLUMNS,
            "    ",
        ));
        if lib.suits() != 0 {
            out.push_str(&crate::report::wrap(
                &format!("    made for {}", tribo_plugin_api::suits_text(lib.suits())),
                crate::report::MAX_COLUMNS,
                "    ",
            ));
        }
        // One line per parameter: name, default, unit and range; its meaning wrapped below.
        let width = d.parameters.iter().map(|p| p.name.len()).max().unwrap_or(0);
        for p in &d.parameters {
            let head = format!(
                "    {:width$} = {:<10} {:<18} {}",
                p.name,
                p.default.to_toml_string(),
                p.unit,
                p.range_text(),
            );
            out.push_str(&crate::report::wrap(
                head.trim_end(),
                crate::report::MAX_COLUMNS,
                "        ",
            ));
            out.push_str(&crate::report::wrap(
                &format!("        {}", p.doc),
                crate::report::MAX_COLUMNS,
                "        ",
            ));
        }
        out.push('\n');
    }
    out
}
