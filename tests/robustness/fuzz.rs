//! Property tests (proptest) of everything that parses user input: rig files, law-set files and
//! law parameters, data CSVs. Whatever the input, the result is a value or an error, never a
//! panic, and each case returns promptly; an error names the file, and what is accepted is
//! finite and in range. Case count: `TRIBO_FUZZ_CASES` (default 100 000) for the rig and the
//! generated law sets, a quarter of it for each data target and a tenth for the law-set
//! mutations (at least 256 each).

use std::path::Path;
use std::sync::OnceLock;

use proptest::prelude::*;
use tribo::lawset::LawSet;
use tribo::plugin_api::loader::{load_paths, LawRegistry};
use tribo::plugin_api::ParamValue;
use tribo::rig::{load_rig_text, Rig};
use tribo::study::{
    check_lawsets, parse_data, DataRow, MAX_DATA_SPEED_RPM, MAX_DATA_TORQUE_NM, MIN_DATA_SPEED_RPM,
};

use super::common::*;

fn cases() -> u32 {
    std::env::var("TRIBO_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(100_000)
}

fn config() -> ProptestConfig {
    config_with(cases())
}

fn config_with(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
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
            "mixed_film",
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
        match load_rig_text(Path::new("fuzz.toml"), &text, &[]) {
            // What is accepted is a rig a run can use: positive, finite sizes and masses.
            Ok(rig) => {
                let (g, b) = (&rig.file.geometry, &rig.file.bodies);
                for (what, v) in [
                    ("geometry.crank_radius_m", g.crank_radius_m),
                    ("geometry.bore_m", g.bore_m),
                    ("bodies.crank.inertia_kg_m2", b.crank.inertia_kg_m2),
                    ("bodies.piston.mass_kg", b.piston.mass_kg),
                ] {
                    prop_assert!(v.is_finite() && v > 0.0, "accepted {what} = {v}:\n{text}");
                }
                if let Some(top) = rig.file.max_speed_rpm {
                    prop_assert!(top.is_finite() && top > 0.0, "accepted max_speed_rpm = {top}");
                }
            }
            // An error names the file and the field or the line.
            Err(e) => {
                let shown = e.to_string();
                prop_assert!(!e.file.as_os_str().is_empty(), "{shown}");
                prop_assert!(!e.field.is_empty() || e.line.is_some(), "{shown}");
                prop_assert!(shown.starts_with(&e.file.display().to_string()), "{shown}");
            }
        }
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
            // Creating every law instance checks the parameters against each law's declaration;
            // what it accepts, the law set's own check accepts too (every value in its range).
            if tribo::rig::simulation(&rig, registry()).is_ok() {
                prop_assert!(set.check_params(registry()).is_ok(), "{text}");
            }
            // A refused parameter is named: the law-set file and the entry's field.
            if let Err(e) = set.check_params(registry()) {
                let shown = e.to_string();
                prop_assert!(shown.starts_with("fuzz-lawset.toml"), "{shown}");
                prop_assert!(e.field.starts_with("laws"), "{shown}");
            }
            match set.free_params(registry(), None) {
                // A free parameter starts inside its bounds.
                Ok(free) => {
                    for p in free {
                        prop_assert!(
                            p.bounds[0] <= p.value && p.value <= p.bounds[1],
                            "{}: {} outside {:?}",
                            p.id,
                            p.value,
                            p.bounds
                        );
                    }
                }
                Err(e) => {
                    let shown = e.to_string();
                    prop_assert!(shown.starts_with("fuzz-lawset.toml"), "{shown}");
                    prop_assert!(e.field.starts_with("laws"), "{shown}");
                }
            }
        }
    }
}

// ---- data CSV ----

/// The bundled measurements, the valid CSV the data mutations start from.
fn data_text() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    TEXT.get_or_init(|| {
        std::fs::read_to_string(workspace().join("rigs/data/crf250r-measured.csv")).expect("data")
    })
}

/// A cell a spreadsheet might hold, sensible or not.
fn cell() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|x| format!("{x:?}")),
        (-2e4..2e4f64).prop_map(|x| format!("{x}")),
        Just("NaN".to_string()),
        Just("inf".to_string()),
        Just("-inf".to_string()),
        Just("1e308".to_string()),
        Just("-1e308".to_string()),
        Just("1e400".to_string()),
        Just("1e-320".to_string()),
        Just("-0".to_string()),
        Just(String::new()),
        Just("3,000".to_string()),
        Just("\"3000\"".to_string()),
        Just("0x10".to_string()),
        "[ -~]{0,10}",
    ]
}

/// One edit of a CSV text: a cell, a line, a header, a column, the line endings, a byte order
/// mark.
fn data_edit() -> impl Strategy<Value = (u8, usize, usize, String, String)> {
    (0..12u8, 0..64usize, 0..4usize, cell(), "[ -~]{0,30}")
}

fn apply_data_edit(
    text: &str,
    (op, line, col, cell, junk): &(u8, usize, usize, String, String),
) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        lines.push(String::new());
    }
    let i = line % lines.len();
    let header = lines.iter().position(|l| !l.starts_with('#')).unwrap_or(0);
    let set_cell = |l: &str, col: usize, v: &str| -> String {
        let mut cells: Vec<String> = l.split(',').map(str::to_string).collect();
        let c = col % cells.len();
        cells[c] = v.to_string();
        cells.join(",")
    };
    match op {
        0 => lines[i] = set_cell(&lines[i], *col, cell),
        1 => {
            lines.remove(i);
        }
        2 => lines.insert(i, lines[i].clone()),
        3 => lines.insert(i, junk.clone()),
        4 => lines[header] = set_cell(&lines[header], *col, junk),
        5 => {
            // Drop a column everywhere below the comments.
            for l in lines.iter_mut().skip(header) {
                let mut cells: Vec<&str> = l.split(',').collect();
                if cells.len() > 1 {
                    cells.remove(*col % cells.len());
                }
                *l = cells.join(",");
            }
        }
        6 => {
            // Add a column (to the header only, or to every line).
            for (k, l) in lines.iter_mut().enumerate().skip(header) {
                if k == header || col % 2 == 0 {
                    l.push(',');
                    l.push_str(if k == header { "extra" } else { cell });
                }
            }
        }
        7 => {
            // Swap two columns everywhere: columns are found by name.
            for l in lines.iter_mut().skip(header) {
                let mut cells: Vec<&str> = l.split(',').collect();
                let n = cells.len();
                cells.swap(*col % n, (*col + 1) % n);
                *l = cells.join(",");
            }
        }
        8 => return format!("\u{feff}{}", lines.join("\n")),
        9 => return lines.join("\r\n"),
        10 => lines.insert(i, String::new()),
        _ => lines[i] = junk.clone(),
    }
    lines.join("\n")
}

/// The data mutations: one to four edits of the bundled measurements.
fn data_mutation() -> impl Strategy<Value = String> {
    proptest::collection::vec(data_edit(), 1..5).prop_map(|edits| {
        edits
            .iter()
            .fold(data_text().to_string(), |t, e| apply_data_edit(&t, e))
    })
}

/// What `parse_data` must give for any text: rows that are finite, in range, and sorted by
/// distinct speeds; or an error naming the file.
fn check_data_result(text: &str) -> Result<(), TestCaseError> {
    match parse_data(Path::new("fuzz-data.csv"), text) {
        Ok(rows) => {
            prop_assert!(!rows.is_empty());
            let (t_lo, t_hi) = tribo::oil::VALID_RANGE_C;
            for DataRow {
                speed_rpm,
                torque_nm,
                oil_temp_c,
            } in &rows
            {
                prop_assert!((MIN_DATA_SPEED_RPM..=MAX_DATA_SPEED_RPM).contains(speed_rpm));
                prop_assert!(torque_nm.is_finite() && torque_nm.abs() <= MAX_DATA_TORQUE_NM);
                prop_assert!((t_lo..=t_hi).contains(oil_temp_c));
            }
            prop_assert!(rows.windows(2).all(|w| w[0].speed_rpm < w[1].speed_rpm));
        }
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(msg.starts_with("fuzz-data.csv"), "{}", msg);
        }
    }
    Ok(())
}

proptest! {
    // The data parser is cheap; a quarter of the cases keeps the whole fuzzing near 20 s.
    #![proptest_config(config_with((cases() / 4).max(256)))]

    #[test]
    fn data_parser_on_mutated_csv_gives_checked_rows_or_an_error_naming_the_file(
        text in data_mutation()
    ) {
        check_data_result(&text)?;
    }

    #[test]
    fn data_parser_on_random_bytes_gives_checked_rows_or_an_error_naming_the_file(
        bytes in proptest::collection::vec(any::<u8>(), 0..256)
    ) {
        check_data_result(&String::from_utf8_lossy(&bytes))?;
    }
}

// ---- law-set files ----

/// The bundled law sets, the valid files the law-set mutations start from.
fn lawset_texts() -> &'static [String] {
    static TEXTS: OnceLock<Vec<String>> = OnceLock::new();
    TEXTS.get_or_init(|| {
        [
            "fedem-baseline",
            "stribeck-duty",
            "mixed-film",
            "physical-bearings",
        ]
        .iter()
        .map(|n| {
            std::fs::read_to_string(workspace().join(format!("rigs/lawsets/{n}.toml")))
                .expect("law set")
        })
        .collect()
    })
}

fn the_rig() -> &'static Rig {
    static RIG: OnceLock<Rig> = OnceLock::new();
    RIG.get_or_init(|| load_rig_text(Path::new("rig.toml"), rig_text(), &[]).expect("valid rig"))
}

/// Byte ranges of the numbers written in `line` (not parts of names).
fn numbers(line: &str) -> Vec<std::ops::Range<usize>> {
    let b = line.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = (b[i].is_ascii_digit() || b[i] == b'-')
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'));
        if starts {
            let j = i + line[i..]
                .find(|c: char| !(c.is_ascii_alphanumeric() || "+-._".contains(c)))
                .unwrap_or(line.len() - i);
            out.push(i..j);
            i = j;
        } else {
            i += 1;
        }
    }
    out
}

/// One edit of a law-set text: a whole value, a number inside an inline table (a parameter or
/// a bound), a name, a line deleted, inserted or garbled.
fn lawset_edit() -> impl Strategy<Value = (u8, usize, usize, String, String)> {
    let word = prop_oneof![
        Just("joint"),
        Just("law"),
        Just("params"),
        Just("free"),
        Just("name"),
        Just("mu"),
        Just("mu_b"),
        Just("load"),
        Just("prior_fit"),
        Just("main_a"),
        Just("piston"),
        Just("wrist"),
        Just("coulomb"),
        Just("stribeck-duty"),
        Just("nope"),
    ];
    (
        0..7u8,
        0..128usize,
        0..16usize,
        value(),
        (word, "[ -~]{0,16}"),
    )
        .prop_map(|(op, line, k, v, (w, junk))| {
            (op, line, k, v, if op == 6 { w.to_string() } else { junk })
        })
}

fn apply_lawset_edit(
    text: &str,
    (op, line, k, v, junk): &(u8, usize, usize, String, String),
) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    // Edits go to the lines that say something (the files are half comments).
    let content: Vec<usize> = (0..lines.len())
        .filter(|&k| !lines[k].trim().is_empty() && !lines[k].starts_with('#'))
        .collect();
    let Some(&i) = content.get(line % content.len().max(1)) else {
        return junk.clone();
    };
    match op {
        0 => {
            if let Some((key, _)) = lines[i].split_once('=') {
                lines[i] = format!("{key}= {v}");
            }
        }
        1 => {
            // A number inside the line (a parameter in an inline table, a bound).
            let spans = numbers(&lines[i]);
            if !spans.is_empty() {
                let r = spans[k % spans.len()].clone();
                lines[i].replace_range(r, v);
            }
        }
        2 => {
            lines.remove(i);
        }
        3 => lines.insert(i, format!("{junk} = {v}")),
        4 => lines[i] = junk.clone(),
        5 => {
            // A key inside an inline table renamed.
            let keys: Vec<usize> = lines[i].match_indices(", ").map(|(p, _)| p + 2).collect();
            if let Some(&p) = keys.get(k % keys.len().max(1)) {
                let end = lines[i][p..].find(' ').map_or(lines[i].len(), |e| p + e);
                lines[i].replace_range(p..end, junk);
            }
        }
        _ => {
            // A quoted name (joint, law, set name) replaced by another, real or not.
            if let Some(a) = lines[i].find('"') {
                if let Some(b) = lines[i][a + 1..].find('"') {
                    lines[i].replace_range(a + 1..a + 1 + b, junk);
                }
            }
        }
    }
    lines.join("\n")
}

/// The law-set mutations: one to three edits of a bundled law set.
fn lawset_mutation() -> impl Strategy<Value = String> {
    (0..4usize, proptest::collection::vec(lawset_edit(), 1..4)).prop_map(|(n, edits)| {
        let base = lawset_texts()[n].clone();
        edits.iter().fold(base, |t, e| apply_lawset_edit(&t, e))
    })
}

proptest! {
    // Each case binds every law of the set on the rig (as `check_lawsets` does before a
    // study): a tenth of the cases.
    #![proptest_config(config_with((cases() / 10).max(256)))]

    #[test]
    fn mutated_lawsets_give_a_checked_set_or_an_error_naming_the_file(text in lawset_mutation()) {
        let file = "fuzz-lawset.toml";
        let set = match LawSet::from_text(Path::new(file), &text) {
            Ok(set) => set,
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(msg.starts_with(file), "{}", msg);
                return Ok(());
            }
        };
        // Every law bound on the rig, as a study checks before it runs.
        if let Err(e) = check_lawsets(the_rig(), std::slice::from_ref(&set), registry()) {
            let msg = e.to_string();
            prop_assert!(msg.contains(file), "{}", msg);
            return Ok(());
        }
        // Accepted: every law exists, every parameter it was given is declared, and every
        // number is finite and within the declared range.
        for e in &set.file.laws {
            let lib = registry().get(&e.law).map_err(|e| TestCaseError::fail(e.to_string()))?;
            for (k, v) in &e.params {
                let spec = lib.description().parameters.iter().find(|p| &p.name == k);
                prop_assert!(spec.is_some(), "{} accepted for {}", k, e.law);
                let spec = spec.expect("checked");
                let nums: Vec<f64> = match (&spec.default, v) {
                    (ParamValue::Number(_), v) => v.as_float().or(v.as_integer().map(|i| i as f64)).into_iter().collect(),
                    (ParamValue::NumberList(_), toml::Value::Array(a)) => a.iter().filter_map(|x| x.as_float().or(x.as_integer().map(|i| i as f64))).collect(),
                    _ => Vec::new(),
                };
                for x in nums {
                    prop_assert!(x.is_finite() && x >= spec.min && x <= spec.max, "{} = {} accepted for {}", k, x, e.law);
                }
            }
            for (p, [lo, hi]) in &e.free {
                prop_assert!(lo.is_finite() && hi.is_finite() && lo < hi, "free {} = [{}, {}]", p, lo, hi);
            }
        }
        // Free parameters: found, or an error naming the file; their start values in bounds.
        match set.free_params(registry(), None) {
            Ok(free) => {
                for f in free {
                    prop_assert!(f.value.is_finite() && f.value >= f.bounds[0] && f.value <= f.bounds[1]);
                }
            }
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(msg.contains(file), "{}", msg);
            }
        }
    }
}
