//! Multi-cylinder engines (issue 18, docs/engines.md): the `[engine]` description read and
//! validated with errors naming file, line, column and field; law sets attaching to joint
//! groups on engines and on the single-cylinder rig; an engine rig refused by the simulation
//! with a clear message rather than solved as one cylinder.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use tribo::engine::{cylinder_phases, geometry, top_dead_centres, CrankTrain};
use tribo::lawset::LawSet;
use tribo::rig::{load_rig, load_rig_text, Rig, RigError};

fn fixture(name: &str) -> PathBuf {
    common::workspace()
        .join("tests/fixtures/engines")
        .join(format!("{name}.toml"))
}

fn text(name: &str) -> String {
    std::fs::read_to_string(fixture(name)).expect("fixture")
}

/// Load `text` as if it were the fixture `name`, expecting an error.
fn error_of(name: &str, text: &str) -> RigError {
    load_rig_text(&fixture(name), text, &[]).expect_err("a rig error")
}

/// The 1-based line of the first occurrence of `needle` in `text` after `after`.
fn line_of(text: &str, after: &str, needle: &str) -> usize {
    let start = text.find(after).expect("anchor");
    let at = start + text[start..].find(needle).expect("needle");
    text[..at].matches('\n').count() + 1
}

fn laws_on(rig: &Rig, joint: &str) -> Vec<String> {
    let names: Vec<String> = match &rig.file.engine {
        Some(e) => e.laws.get(joint).cloned().unwrap_or_default(),
        None => rig
            .file
            .joints
            .named()
            .into_iter()
            .find(|(n, _)| *n == joint)
            .map(|(_, j)| j.laws.clone())
            .unwrap_or_default(),
    }
    .into_iter()
    .map(|l| l.law)
    .collect();
    names
}

#[test]
fn the_inline4_and_v_twin_fixtures_describe_their_crank_trains() {
    let rig = load_rig(&fixture("inline4"), &[]).expect("valid inline-4");
    let e = rig.file.engine.as_ref().expect("an engine");
    assert_eq!(
        e.joint_names()[..6],
        [
            "main_1",
            "main_2",
            "main_3",
            "main_4",
            "main_5",
            "big_end_1"
        ]
    );
    let geo = geometry(&rig.file).expect("engine geometry");
    assert_eq!(geo.cylinders.len(), 4);
    let train = CrankTrain::new(geo.clone()).expect("crank train");
    // Every throw midway between two mains: half its load on each.
    for split in train.main_split() {
        assert!((split[0].1 - 0.5).abs() < 1e-12 && (split[1].1 - 0.5).abs() < 1e-12);
    }
    // Firing 1-3-4-2 every 180 degrees: cylinders 3 and 4 start on their firing TDC half.
    let phases = cylinder_phases(&top_dead_centres(&geo), &e.firing_order, 0.0).expect("fits");
    let deg: Vec<f64> = phases.iter().map(|p| p.to_degrees().round()).collect();
    assert_eq!(deg, [0.0, 0.0, 360.0, 360.0]);

    let rig = load_rig(&fixture("vtwin"), &[]).expect("valid V-twin");
    let geo = geometry(&rig.file).expect("engine geometry");
    let banks: Vec<f64> = geo
        .cylinders
        .iter()
        .map(|c| c.bank_rad.to_degrees())
        .collect();
    assert_eq!(banks, [-45.0, 45.0]);
    assert_eq!(geo.cylinders[0].throw, geo.cylinders[1].throw);
    assert!(CrankTrain::new(geo).is_ok());
}

/// A bad engine description: what it is, the edited fixture text, the field the error must
/// name, words of the message, and the text (after an anchor) its line must point at.
type Case = (
    &'static str,
    String,
    &'static str,
    &'static [&'static str],
    (&'static str, &'static str),
);

/// Each bad engine description is refused at its field.
#[test]
fn bad_engine_descriptions_are_refused_naming_the_field() {
    let base = text("inline4");
    let cases: [Case; 8] = [
        (
            "firing order not a permutation",
            base.replace("firing_order = [1, 3, 4, 2]", "firing_order = [1, 3, 3, 2]"),
            "engine.firing_order",
            &["not a permutation of 1..4"],
            ("[engine]", "firing_order"),
        ),
        (
            "firing order that does not fit the crank",
            base.replace("firing_order = [1, 3, 4, 2]", "firing_order = [1, 2, 3, 4]"),
            "engine.firing_order",
            &["does not fit the crank", "720-degree"],
            ("[engine]", "firing_order"),
        ),
        (
            "a throw listed twice",
            base.replacen("axial_position_m = 0.135", "axial_position_m = 0.045", 1),
            "engine.throws[1].axial_position_m",
            &["throw 2 is at 0.045 m like throw 1", "listed twice"],
            ("angle_deg = 180.0", "axial_position_m"),
        ),
        (
            "a cylinder without a rod",
            base.replace("[[engine.rods]]\ncylinder = 3\n", ""),
            "engine.cylinders[2]",
            &["cylinder 3 has no rod", "[[engine.rods]] with cylinder = 3"],
            // The third [[engine.cylinders]] header.
            ("throw = 2\n", "[[engine.cylinders]]"),
        ),
        (
            "two rods on one cylinder",
            base.replace("cylinder = 4", "cylinder = 2"),
            "engine.rods[3].cylinder",
            &["cylinder 2 has two rods"],
            // The fourth rod, after the third's `cylinder = 3`.
            ("[[engine.rods]]\ncylinder = 3", "cylinder = 2"),
        ),
        (
            "a V angle outside 0-180",
            base.replace(
                "firing_order = [1, 3, 4, 2]",
                "firing_order = [1, 3, 4, 2]\nv_angle_deg = 200.0",
            ),
            "engine.v_angle_deg",
            &["[0, 180] degrees", "200"],
            ("[engine]", "v_angle_deg"),
        ),
        (
            "a cylinder on a throw that does not exist",
            base.replacen("throw = 4", "throw = 7", 1),
            "engine.cylinders[3].throw",
            &["throw 7", "throws 1 to 4"],
            ("throw = 3", "throw = 7"),
        ),
        (
            "a main bearing of the single-cylinder rig on an engine",
            base.replace(
                "[joints.big_end]",
                "[joints.main_a]\nradius_m = 0.02\nlength_m = 0.01\n[joints.big_end]",
            ),
            "joints.main_a",
            &["[[engine.mains]]"],
            ("", "[joints.main_a]"),
        ),
    ];
    for (what, edited, field, words, (anchor, needle)) in cases {
        assert_ne!(edited, base, "{what}: the edit applies");
        let e = error_of("inline4", &edited);
        assert_eq!(e.field, field, "{what}: {e}");
        for w in words {
            assert!(e.message.contains(w), "{what}: `{w}` in {e}");
        }
        assert_eq!(e.file, fixture("inline4"), "{what}");
        let want = line_of(&edited, anchor, needle);
        assert_eq!(e.line, Some(want), "{what}: {e}");
        assert!(e.column.is_some(), "{what}: {e}");
        // The rendered message carries file:line:column and the field.
        let shown = e.to_string();
        assert!(
            shown.contains(&format!("inline4.toml:{want}:")) && shown.contains(field),
            "{what}: {shown}"
        );
    }
    // A sealed crankcase: the cylinders would each pump their own, not one shared volume.
    let e = error_of(
        "inline4",
        &base.replace(
            "[drive]",
            "[gas.crankcase]\nkind = \"sealed\"\nvolume_at_tdc_m3 = 0.004\n\n[drive]",
        ),
    );
    assert_eq!(e.field, "gas.crankcase", "{e}");
    assert!(e.message.contains("share one crankcase"), "{e}");
    // A cylinder banked beyond 180 degrees (without a V angle).
    let e = error_of(
        "inline4",
        &base.replacen("throw = 2\n", "throw = 2\nbank_deg = 270.0\n", 1),
    );
    assert_eq!(e.field, "engine.cylinders[1].bank_deg", "{e}");
    assert!(e.message.contains("[-180, 180]"), "{e}");
}

#[test]
fn a_single_cylinder_rig_still_needs_both_main_bearings() {
    let thesis = tribo::bundled::rig("crf250r-motored").expect("bundled");
    let cut = thesis.replace(
        "[joints.main_b]\nradius_m = 0.020           # [T table 9.5]\nlength_m = 0.015           # estimate: roller bearing width\nload_share = 0.5           # [T 9.2]\n",
        "",
    );
    assert_ne!(cut, thesis);
    let e = load_rig_text(Path::new("crf250r-motored.toml"), &cut, &[]).expect_err("no main_b");
    assert_eq!(e.field, "joints.main_b", "{e}");
    assert!(e.message.contains("missing table [joints.main_b]"), "{e}");
}

#[test]
fn every_bundled_law_set_applies_to_every_bundled_rig_and_to_the_engines() {
    let mut rigs: Vec<Rig> = tribo::bundled::rig_names()
        .into_iter()
        .map(|n| load_rig(Path::new(n), &[]).expect("bundled rig"))
        .collect();
    rigs.push(load_rig(&fixture("inline4"), &[]).expect("inline-4"));
    rigs.push(load_rig(&fixture("vtwin"), &[]).expect("V-twin"));
    for set_name in tribo::bundled::lawset_names() {
        let set = LawSet::load(set_name).expect("bundled set");
        for rig in &rigs {
            let mut r = rig.clone();
            set.apply(&mut r);
            assert!(
                r.unattached.is_empty(),
                "{set_name} on {}: {:?}",
                r.file.name,
                r.unattached
            );
            // Each main bearing gets the set's main laws, each cylinder its big-end and
            // piston laws: the same on every joint of a group.
            let names: Vec<String> = match &r.file.engine {
                Some(e) => e.joint_names(),
                None => tribo::rig::JOINT_NAMES.map(String::from).to_vec(),
            };
            for kind in ["main", "big_end", "small_end", "piston"] {
                let of_kind: Vec<Vec<String>> = names
                    .iter()
                    .filter(|n| n.starts_with(kind))
                    .map(|n| laws_on(&r, n))
                    .collect();
                assert!(!of_kind.is_empty(), "{kind} on {}", r.file.name);
                assert!(
                    of_kind.iter().all(|l| *l == of_kind[0]),
                    "{set_name} on {}: {kind} {of_kind:?}",
                    r.file.name
                );
            }
            assert!(!laws_on(
                &r,
                names
                    .iter()
                    .find(|n| n.starts_with("piston"))
                    .expect("piston")
            )
            .is_empty());
        }
    }
}

#[test]
fn groups_on_the_thesis_rig_bind_what_the_per_joint_entries_bound() {
    // The bundled sets now say `main_*`; on the thesis rig that is main_a and main_b, each
    // with the laws in entry order, exactly as the two per-main entries of each law did.
    let mut rig = load_rig(Path::new("crf250r-motored"), &[]).expect("rig");
    LawSet::load("fedem-baseline").expect("set").apply(&mut rig);
    for main in ["main_a", "main_b"] {
        assert_eq!(laws_on(&rig, main), ["fedem-friction", "polyline-damper"]);
    }
    assert_eq!(
        laws_on(&rig, "big_end"),
        ["fedem-friction", "polyline-damper"]
    );
    assert!(laws_on(&rig, "small_end").is_empty());
    assert_eq!(laws_on(&rig, "piston"), ["fedem-friction"]);
    // Numbered names reach cylinder 1 and the two mains.
    let set = LawSet::from_text(
        Path::new("ls.toml"),
        "name = \"n\"\n[[laws]]\njoint = \"main_2\"\nlaw = \"coulomb\"\n[[laws]]\njoint = \"piston_1\"\nlaw = \"coulomb\"\n",
    )
    .expect("set");
    set.apply(&mut rig);
    assert!(rig.unattached.is_empty());
    assert_eq!(laws_on(&rig, "main_b"), ["coulomb"]);
    assert!(laws_on(&rig, "main_a").is_empty());
    assert_eq!(laws_on(&rig, "piston"), ["coulomb"]);
}

#[test]
fn an_entry_naming_no_joint_of_the_rig_is_refused_at_the_entry() {
    let registry = tribo::plugin_api::loader::LawRegistry::new();
    let set = LawSet::from_text(
        Path::new("ls.toml"),
        "name = \"x\"\n[[laws]]\njoint = \"piston_*\"\nlaw = \"coulomb\"\n[[laws]]\njoint = \"piston_5\"\nlaw = \"coulomb\"\n",
    )
    .expect("a valid set: piston_5 exists on a 5-cylinder engine");
    let mut rig = load_rig(&fixture("inline4"), &[]).expect("inline-4");
    set.apply(&mut rig);
    let e = tribo::rig::check_laws(&rig, &registry).expect_err("no piston_5");
    let msg = e.to_string();
    assert!(msg.contains("ls.toml:6:9"), "{msg}");
    assert!(
        msg.contains("laws[1].joint") && msg.contains("no joint `piston_5`"),
        "{msg}"
    );
    assert!(msg.contains("main_1, main_2"), "{msg}");
    // main_a on an engine: the engine's mains are named.
    let set = LawSet::from_text(
        Path::new("ls.toml"),
        "name = \"x\"\n[[laws]]\njoint = \"main_a\"\nlaw = \"coulomb\"\n",
    )
    .expect("set");
    set.apply(&mut rig);
    let msg = tribo::rig::check_laws(&rig, &registry)
        .expect_err("main_a")
        .to_string();
    assert!(msg.contains("main_1 .. main_n; main_* attaches"), "{msg}");
    // A name no rig has is refused when the set is read, listing the groups.
    let e = LawSet::from_text(
        Path::new("ls.toml"),
        "name = \"x\"\n[[laws]]\njoint = \"piston_0\"\nlaw = \"coulomb\"\n",
    )
    .expect_err("piston_0");
    assert!(e.message.contains("piston_*"), "{e}");
}

#[test]
fn an_engine_runs_in_steady_state_only_and_studies_say_so() {
    // The transient run and the studies are the single-cylinder solver's: on an engine they
    // stop with a message naming what works, never a single cylinder's numbers.
    let rig = fixture("inline4");
    let rig = rig.to_str().expect("utf-8");
    for (args, words) in [
        (vec!["run", rig], ["4-cylinder engine", "--steady"]),
        (
            vec!["run", rig, "--steady", "--crank-angle", "ca"],
            ["4-cylinder engine", "--crank-angle"],
        ),
        (
            vec!["compare", rig],
            ["4-cylinder engine", "steady state only"],
        ),
    ] {
        let dir = tempfile::tempdir().expect("temp dir");
        let out = Command::new(common::tribo_exe())
            .current_dir(dir.path())
            .args(&args)
            .output()
            .expect("tribo runs");
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        for w in words {
            assert!(err.contains(w), "{args:?}: `{w}` in {err}");
        }
        assert!(out.stdout.is_empty(), "{args:?}: no numbers");
    }
}

/// The thesis rig written as a one-cylinder engine: one throw midway between the two mains
/// (so each main carries half, as `load_share = 0.5`), the same bodies, joints and oil.
fn thesis_as_engine() -> String {
    let thesis = tribo::bundled::rig("crf250r-motored").expect("bundled");
    let start = thesis.find("[joints.main_a]").expect("main_a");
    let end = thesis.find("[joints.big_end]").expect("big_end");
    let mut text = format!("{}{}", &thesis[..start], &thesis[end..]);
    text.push_str(
        "\n[engine]\nfiring_order = [1]\n\
         [[engine.mains]]\naxial_position_m = 0.0\nradius_m = 0.020\nlength_m = 0.015\n\
         [[engine.mains]]\naxial_position_m = 0.1\nradius_m = 0.020\nlength_m = 0.015\n\
         [[engine.throws]]\nangle_deg = 0.0\naxial_position_m = 0.05\n\
         [[engine.cylinders]]\nthrow = 1\n[[engine.rods]]\ncylinder = 1\n",
    );
    text
}

/// `tribo run ARGS --json` in `dir`: the parsed result (exit 0 required).
fn run_json(dir: &Path, args: &[&str]) -> serde_json::Value {
    let out = Command::new(common::tribo_exe())
        .current_dir(dir)
        .args(args)
        .arg("--json")
        .output()
        .expect("tribo runs");
    assert!(
        out.status.success(),
        "tribo {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

fn torques(v: &serde_json::Value) -> Vec<f64> {
    v["plateaus"]
        .as_array()
        .expect("plateaus")
        .iter()
        .map(|p| p["motoring_torque_nm"].as_f64().expect("torque"))
        .collect()
}

#[test]
fn a_one_cylinder_engine_runs_like_the_thesis_rig() {
    // The engine path (crank train, its own friction iteration, per-joint laws) against the
    // single-cylinder solver on the same mechanism, law set and steady state. The friction
    // iteration is tightened so both settle far below the comparison's tolerance.
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = dir.path().join("one.toml");
    std::fs::write(&rig, thesis_as_engine()).expect("write");
    let tight = ["--set", "solver.friction_tol=1e-12"];
    for set in ["fedem-baseline", "physical-bearings", "stribeck-duty"] {
        let mut a = vec!["run", "crf250r-motored", "--steady", "--lawset", set];
        a.extend(tight);
        let thesis = torques(&run_json(dir.path(), &a));
        let mut b = vec![
            "run",
            rig.to_str().expect("utf-8"),
            "--steady",
            "--lawset",
            set,
        ];
        b.extend(tight);
        let engine = run_json(dir.path(), &b);
        let got = torques(&engine);
        assert_eq!(got.len(), thesis.len());
        for (g, t) in got.iter().zip(&thesis) {
            assert!((g - t).abs() <= 1e-9 * t.abs(), "{set}: {g} vs {t}");
        }
        // Per-joint names of the engine, and its per-component totals add up.
        let p = &engine["plateaus"][6];
        let joints: Vec<&str> = p["joints"]
            .as_array()
            .expect("joints")
            .iter()
            .map(|j| j["joint"].as_str().expect("name"))
            .collect();
        assert!(
            joints.contains(&"main_1") && joints.contains(&"piston_1"),
            "{joints:?}"
        );
        let groups = p["groups"].as_array().expect("groups");
        let by = |g: &str| {
            groups
                .iter()
                .find(|x| x["group"] == g)
                .and_then(|x| x["friction_torque_nm"].as_f64())
                .expect("group")
        };
        let all: f64 = ["main_*", "big_end_*", "small_end_*", "piston_*"]
            .iter()
            .map(|g| by(g))
            .sum();
        let laws: f64 = p["joints"]
            .as_array()
            .expect("joints")
            .iter()
            .map(|j| j["friction_torque_nm"].as_f64().expect("torque"))
            .sum();
        assert!((all - laws).abs() <= 1e-12 * laws.abs().max(1.0));
        assert!((by("cylinder 1") + by("main_*") - laws).abs() <= 1e-12 * laws.abs().max(1.0));
    }
}

#[test]
fn frictionless_engines_need_no_mean_torque_with_or_without_compression() {
    // No laws: the mean drive torque of every plateau is zero (inertia and gravity are
    // conservative); with a motored 4-stroke head on every cylinder, phased by the firing
    // order, the reversible compression adds no net work either, and the cycle is 720 degrees
    // with the displacement of all cylinders in the FMEP.
    let dir = tempfile::tempdir().expect("temp dir");
    for name in ["inline4", "vtwin"] {
        let rig = fixture(name);
        let rig = rig.to_str().expect("utf-8");
        let plain = run_json(dir.path(), &["run", rig, "--steady"]);
        for t in torques(&plain) {
            assert!(t.abs() < 1e-9, "{name}: {t}");
        }
        // Closed cylinders (compression every revolution) on both; the volume follows the
        // true piston travel, so even the V-twin's offset cylinder does no net work.
        let closed = "gas.cylinder={kind=\"motored\", compression_ratio=10.0}";
        let shut = run_json(dir.path(), &["run", rig, "--steady", "--set", closed]);
        for t in torques(&shut) {
            assert!(t.abs() < 1e-6, "{name} with closed cylinders: {t}");
        }
        let head =
            "gas.cylinder={kind=\"motored\", compression_ratio=10.0, valves=\"four-stroke\"}";
        let fired = run_json(dir.path(), &["run", rig, "--steady", "--set", head]);
        if name == "inline4" {
            // Ideal valves at the dead centres: exact without offsets (on an offset cylinder
            // the valves switch at local angles 0 and pi, a little off its dead centres).
            for t in torques(&fired) {
                assert!(t.abs() < 1e-6, "{name} with compression: {t}");
            }
        }
        assert_eq!(fired["fmep"]["basis"], "four-stroke");
        assert_eq!(fired["plateaus"][0]["revolutions"], 2);
        let loaded = load_rig(&fixture(name), &[]).expect("rig");
        let n = loaded.file.engine.as_ref().expect("engine").cylinders.len() as f64;
        let g = &loaded.file.geometry;
        let vd = n * std::f64::consts::PI / 4.0 * g.bore_m * g.bore_m * 2.0 * g.crank_radius_m;
        let got = fired["fmep"]["displacement_m3"].as_f64().expect("V_d");
        assert!((got - vd).abs() < 1e-15, "{got} vs {vd}");
    }
}

#[test]
fn a_law_set_runs_on_every_cylinder_of_the_inline4() {
    // Coulomb on every piston: the engine's piston friction is the sum over cylinders, and
    // cylinders 1 and 4 (one throw angle) dissipate what 2 and 3 do (the other), since the
    // flat-plane crank puts them half a revolution apart on the same slider-crank.
    let dir = tempfile::tempdir().expect("temp dir");
    let set = dir.path().join("pistons.toml");
    std::fs::write(
        &set,
        "name = \"pistons\"\n[[laws]]\njoint = \"piston_*\"\nlaw = \"coulomb\"\nparams = { mu = 0.05 }\n",
    )
    .expect("write");
    let rig = fixture("inline4");
    let v = run_json(
        dir.path(),
        &[
            "run",
            rig.to_str().expect("utf-8"),
            "--steady",
            "--lawset",
            set.to_str().expect("utf-8"),
            "--set",
            "geometry.gravity=false",
        ],
    );
    for p in v["plateaus"].as_array().expect("plateaus") {
        let per: Vec<f64> = (1..=4)
            .map(|k| {
                p["joints"]
                    .as_array()
                    .expect("joints")
                    .iter()
                    .find(|j| j["joint"] == format!("piston_{k}").as_str())
                    .and_then(|j| j["friction_torque_nm"].as_f64())
                    .expect("piston")
            })
            .collect();
        assert!(per.iter().all(|t| *t > 0.0), "{per:?}");
        for k in 1..4 {
            assert!((per[k] - per[0]).abs() < 1e-6 * per[0], "{per:?}");
        }
        let motoring = p["motoring_torque_nm"].as_f64().expect("torque");
        let sum: f64 = per.iter().sum();
        assert!((motoring - sum).abs() < 1e-6 * sum, "{motoring} vs {sum}");
    }
}

#[test]
fn the_bundled_engines_and_their_frictionless_references_run() {
    // The bundled inline-4 and V-twin: their frictionless references need no mean torque at any
    // plateau; with a law set every joint group carries friction, the motoring torque is the
    // mains' plus every cylinder's friction, and the inline-4's cylinders dissipate alike (one
    // slider-crank each, half a revolution apart).
    let dir = tempfile::tempdir().expect("temp dir");
    for (rig, cylinders) in [("inline4-4b11", 4), ("vtwin-90", 2)] {
        let reference = run_json(
            dir.path(),
            &["run", &format!("{rig}-frictionless"), "--steady"],
        );
        for t in torques(&reference) {
            assert!(t.abs() < 1e-9, "{rig}: {t}");
        }
        let v = run_json(
            dir.path(),
            &["run", rig, "--steady", "--lawset", "fedem-baseline"],
        );
        assert_eq!(v["fmep"]["basis"], "two-stroke");
        for p in v["plateaus"].as_array().expect("plateaus") {
            let groups = p["groups"].as_array().expect("groups");
            let by = |g: &str| {
                groups
                    .iter()
                    .find(|x| x["group"] == g)
                    .and_then(|x| x["friction_torque_nm"].as_f64())
                    .unwrap_or_else(|| panic!("{g} in {groups:?}"))
            };
            for g in ["main_*", "big_end_*", "piston_*"] {
                assert!(by(g) > 0.0, "{rig} {g}");
            }
            let per: Vec<f64> = (1..=cylinders)
                .map(|k| by(&format!("cylinder {k}")))
                .collect();
            let motoring = p["motoring_torque_nm"].as_f64().expect("torque");
            let total = by("main_*") + per.iter().sum::<f64>();
            assert!(
                (motoring - total).abs() < 1e-6 * total,
                "{rig}: {motoring} vs {total}"
            );
            if cylinders == 4 {
                for k in 1..4 {
                    assert!((per[k] - per[0]).abs() < 1e-6 * per[0], "{per:?}");
                }
            }
        }
    }
}
