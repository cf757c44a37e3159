//! `tribo fmu export`: the archive's layout, what it carries and what it refuses. What the FMU
//! does once imported is tested with FMPy as the importer (`host/fmu/tests`, run by the
//! test command's Python half).

mod common;

use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

use common::*;

/// Every file of the archive at `path`: name, unix mode, bytes.
fn entries(path: &Path) -> BTreeMap<String, (u32, Vec<u8>)> {
    let file = std::fs::File::open(path).expect("the FMU exists");
    let mut zip = zip::ZipArchive::new(file).expect("the FMU is a zip archive");
    let mut out = BTreeMap::new();
    for i in 0..zip.len() {
        let mut f = zip.by_index(i).expect("entry");
        let mut bytes = Vec::new();
        f.read_to_end(&mut bytes).expect("read entry");
        out.insert(f.name().to_string(), (f.unix_mode().unwrap_or(0), bytes));
    }
    out
}

fn export(dir: &Path, out: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "fmu",
        "export",
        "crf250r-motored",
        "--lawset",
        "fedem-baseline",
    ];
    args.extend_from_slice(extra);
    args.extend(["--out", out]);
    tribo_in(&args, dir)
}

#[test]
fn an_export_carries_the_fmi_layout_and_the_rig_runs_as_the_cli_runs_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    for out in ["a.fmu", "b.fmu"] {
        let o = export(d, out, &[]);
        assert!(o.status.success(), "{}", text(&o).1);
    }
    let a = entries(&d.join("a.fmu"));
    // The same export twice is the same archive, byte for byte (fixed times, content GUID).
    assert_eq!(
        std::fs::read(d.join("a.fmu")).expect("a"),
        std::fs::read(d.join("b.fmu")).expect("b")
    );
    let names: Vec<&str> = a.keys().map(String::as_str).collect();
    assert_eq!(
        names,
        [
            "binaries/linux64/tribo_fmu.so",
            "modelDescription.xml",
            "resources/bin/tribo",
            "resources/interface.toml",
            "resources/model.toml",
            "resources/plugins/libtribo_law_fedem_friction.so",
            "resources/plugins/libtribo_law_polyline_damper.so",
        ]
    );
    // Executables keep their permission for extractors that honour it.
    for exe in [
        "binaries/linux64/tribo_fmu.so",
        "resources/bin/tribo",
        "resources/plugins/libtribo_law_fedem_friction.so",
    ] {
        assert_eq!(a[exe].0 & 0o777, 0o755, "{exe}");
    }
    // What is shipped is what was built.
    assert_eq!(
        a["resources/bin/tribo"].1,
        std::fs::read(tribo_exe()).expect("tribo")
    );
    assert_eq!(
        a["resources/plugins/libtribo_law_fedem_friction.so"].1,
        std::fs::read(built_library("tribo_law_fedem_friction")).expect("law library")
    );
    // One GUID in the description and the interface.
    let xml = String::from_utf8(a["modelDescription.xml"].1.clone()).expect("UTF-8");
    let iface: toml::Table =
        toml::from_str(std::str::from_utf8(&a["resources/interface.toml"].1).expect("UTF-8"))
            .expect("interface TOML");
    let guid = iface["guid"].as_str().expect("guid");
    assert!(xml.contains(&format!(r#"guid="{guid}""#)), "{guid}");
    // The description's variables are the interface's, in value-reference order.
    let vars = iface["variables"].as_array().expect("variables");
    for (vr, v) in vars.iter().enumerate() {
        let name = v["name"].as_str().expect("name");
        assert!(
            xml.contains(&format!(r#"name="{name}" valueReference="{vr}""#)),
            "{name} is not value reference {vr}"
        );
    }
    // The shipped rig is a rig file: run as the CLI runs the bundled one, the same numbers.
    std::fs::write(d.join("model.toml"), &a["resources/model.toml"].1).expect("write");
    let shipped = json_in(&["run", "model.toml", "--steady", "--json"], d);
    let bundled = json_in(
        &[
            "run",
            "crf250r-motored",
            "--lawset",
            "fedem-baseline",
            "--steady",
            "--json",
        ],
        d,
    );
    assert_eq!(shipped["plateaus"], bundled["plateaus"]);
    // Another parameter is another FMU.
    let o = export(d, "c.fmu", &["--set", "bodies.rod.mass_scale=0.8"]);
    assert!(o.status.success(), "{}", text(&o).1);
    let c = entries(&d.join("c.fmu"));
    assert_ne!(
        c["resources/interface.toml"].1,
        a["resources/interface.toml"].1
    );
}

#[test]
fn an_export_that_cannot_be_made_fails_with_a_message_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let d = dir.path();
    std::fs::create_dir(d.join("taken")).expect("dir");
    std::fs::write(d.join("bad.toml"), "name = \"bad\"\n\n[[laws]]\njoint = \"piston\"\nlaw = \"fedem-friction\"\nparams = { mu = 42.0 }\n").expect("write");
    let cases: [(&[&str], &[&str]); 3] = [
        (
            &[
                "fmu",
                "export",
                "crf250r-testbed",
                "--input",
                "drive-torque",
                "--out",
                "t.fmu",
            ],
            &["crf250r-testbed", "[drivetrain]", "tribo run"],
        ),
        (
            &[
                "fmu",
                "export",
                "crf250r-motored",
                "--lawset",
                "bad.toml",
                "--out",
                "t.fmu",
            ],
            &["bad.toml:", "mu", "42"],
        ),
        (
            &["fmu", "export", "crf250r-motored", "--out", "taken"],
            &["taken", "directory"],
        ),
    ];
    for (args, words) in cases {
        let o = tribo_in(args, d);
        let (_, stderr) = text(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {stderr}");
        assert_mentions(&stderr, words);
    }
    // Nothing was written: no FMU, no temporary file left beside it.
    let mut left: Vec<String> = std::fs::read_dir(d)
        .expect("read dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["bad.toml", "taken"]);
}

/// What `fmu export` prints of an engine with 384 parameters stays in lines of at most 100
/// characters: each law once with its joints, per-joint outputs once, parameters counted.
#[test]
fn an_engine_export_prints_short_lines() {
    let dir = tempfile::tempdir().expect("temp dir");
    let o = tribo_in(
        &[
            "fmu",
            "export",
            "inline4-4b11",
            "--lawset",
            "4b11-physical",
            "--out",
            "e.fmu",
        ],
        dir.path(),
    );
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    for line in stdout.lines() {
        assert!(
            line.chars().count() <= 100,
            "{} chars: {line}",
            line.chars().count()
        );
    }
    assert_eq!(stdout.matches("plain-journal on").count(), 1, "{stdout}");
    assert!(stdout.contains("parameters: "), "{stdout}");
}
