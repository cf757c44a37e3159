//! Property tests (proptest) of everything that parses user input: rig files, law-set files and
//! law parameters. Whatever the input, the result is a value or an error, never a panic, and
//! each case returns promptly. Case count: `TRIBO_FUZZ_CASES` (default 100 000 per target).

use std::path::Path;
use std::sync::OnceLock;

use proptest::prelude::*;
use tribo::lawset::LawSet;
use tribo::plugin_api::loader::{load_paths, LawRegistry};
use tribo::rig::load_rig_text;

use super::common::*;

fn cases() -> u32 {
    std::env::var("TRIBO_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100_000)
}

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn rig_text() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| {
        std::fs::read_to_string(workspace().join("rigs/crf250r-motored.toml")).expect("rig")
    })
}

fn registry() -> &'static LawRegistry {
    static REG: OnceLock<LawRegistry> = OnceLock::new();
    REG.get_or_init(|| {
        ensure_plugins_built();
        let libs: Vec<_> = [
            "coulomb",
            "fedem_friction",
            "polyline_damper",
            "stribeck_duty",
            "petroff_journal",
            "rolling_bearing",
            "lugre",
        ]
        .iter()
        .map(|n| built_library(&format!("tribo_law_{n}")))
        .collect();
        load_paths(&libs).expect("laws load")
    })
}

/// A TOML value a user might type, sensible or not.
fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|x| format!("{x:?}")),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("0".to_string()),
        Just("-1".to_string()),
        Just("1e308".to_string()),
        Just("true".to_string()),
        Just("\"two-point\"".to_string()),
        Just("[]".to_string()),
        Just("[1.0, -2.0, 3.0]".to_string()),
        Just(
            "{ model = \"vogel\", k_cst = 0.1, theta1_c = 1100.0, theta2_c = -100.0 }".to_string()
        ),
        Just("[{kind=\"hold\", duration_s=1.0}]".to_string()),
        "[ -~]{0,12}".prop_map(|s| format!("\"{s}\"")),
        "[ -~]{0,12}",
    ]
}

/// One edit of the valid rig: change a value, delete a line, insert a line, or garble a line.
fn rig_edit() -> impl Strategy<Value = String> {
    let n = rig_text().lines().count();
    (0..n, 0..4u8, value(), "[a-z_.]{1,16}", "[ -~]{0,24}").prop_map(|(line, op, v, key, junk)| {
        let mut lines: Vec<String> = rig_text().lines().map(str::to_string).collect();
        match op {
            0 => {
                if let Some((k, _)) = lines[line].split_once('=') {
                    lines[line] = format!("{k}= {v}");
                }
            }
            1 => {
                lines.remove(line);
            }
            2 => lines.insert(line, format!("{key} = {v}")),
            _ => lines[line] = junk,
        }
        lines.join("\n")
    })
}

fn lawset_text() -> impl Strategy<Value = String> {
    let joint = prop_oneof![
        Just("main_a"),
        Just("big_end"),
        Just("piston"),
        Just("wrist"),
        Just("")
    ];
    let law = prop_oneof![
        Just("coulomb"),
        Just("stribeck-duty"),
        Just("polyline-damper"),
        Just("lugre"),
        Just("nope")
    ];
    let param = prop_oneof![
        Just("mu"),
        Just("mu_b"),
        Just("h_boundary"),
        Just("h_hydrodynamic"),
        Just("speeds_rad_s"),
        Just("factors"),
        Just("sigma0"),
        Just("load"),
        Just("xyz")
    ];
    let entry = (
        joint,
        law,
        proptest::collection::vec((param, value()), 0..4),
        proptest::option::of(value()),
    );
    proptest::collection::vec(entry, 0..4).prop_map(|entries| {
        let mut t = String::from("name = \"fuzz\"\n");
        for (j, l, params, free) in entries {
            let p: Vec<String> = params.iter().map(|(k, v)| format!("{k} = {v}")).collect();
            t.push_str(&format!(
                "[[laws]]\njoint = \"{j}\"\nlaw = \"{l}\"\nparams = {{ {} }}\n",
                p.join(", ")
            ));
            if let Some(f) = free {
                t.push_str(&format!("free = {{ mu = {f} }}\n"));
            }
        }
        t
    })
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn rig_parser_returns_a_rig_or_an_error(text in rig_edit()) {
        let _ = load_rig_text(Path::new("fuzz.toml"), &text, &[]);
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn lawset_parser_and_law_parameters_return_a_value_or_an_error(text in lawset_text()) {
        if let Ok(set) = LawSet::from_text(Path::new("fuzz-lawset.toml"), &text) {
            let rig = load_rig_text(Path::new("rig.toml"), rig_text(), &[]).expect("valid rig");
            let mut rig = rig;
            set.apply(&mut rig);
            // Creating every law instance checks the parameters against each law's declaration.
            let _ = tribo::rig::simulation(&rig, registry());
            let _ = set.free_params(registry(), None);
        }
    }
}
