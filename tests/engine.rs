//! Multi-cylinder engines (issue 18, docs/engines.md): the `[engine]` description read and
//! validated with errors naming file, line, column and field; law sets attaching to joint
//! groups on engines and on the single-cylinder rig; engines through the transient run, the
//! time series, the crank-angle results and every study.

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
    // A sealed crankcase is one volume under every piston (issue 28; tests/gas.rs checks its
    // pressure): the inline-4 loads with one, and refuses one the pistons squeeze to nothing.
    let sealed = |volume: &str| {
        base.replace(
            "[drive]",
            &format!("[gas.crankcase]\nkind = \"sealed\"\nvolume_at_tdc_m3 = {volume}\n\n[drive]"),
        )
    };
    load_rig_text(&fixture("inline4"), &sealed("0.004"), &[]).expect("one shared crankcase");
    let e = error_of("inline4", &sealed("0.0003"));
    assert_eq!(e.field, "gas.crankcase.volume_at_tdc_m3", "{e}");
    assert!(e.message.contains("displacement"), "{e}");
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
        "[joints.main_b]\nradius_m = 0.020           # [T table 9.5]\nlength_m = 0.015           # estimate: roller bearing width\nload_share = 0.5           # [T 9.2]\nbearing = \"rolling\"        # [T 5.6]\n",
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

/// The `tribo` command in `dir` with `args`: its output (exit 0 required).
fn tribo_ok(dir: &Path, args: &[&str]) -> std::process::Output {
    let out = Command::new(common::tribo_exe())
        .current_dir(dir)
        .args(args)
        .output()
        .expect("tribo runs");
    assert!(
        out.status.success(),
        "tribo {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn a_one_cylinder_engine_runs_the_cycle_like_the_thesis_rig() {
    // The transient run of the engine path (crank train, its own stepping, the shared plateau
    // windows) against the single-cylinder solver on the same mechanism: the prescribed crank
    // (Simpson's rule on both) and the PI drive (fixed-step RK4 on both: the single-cylinder
    // rig's `solver.integrator = "rk4"`). Same steps, same plateaus, to 1e-9.
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = dir.path().join("one.toml");
    std::fs::write(&rig, thesis_as_engine()).expect("write");
    let rig = rig.to_str().expect("utf-8");
    let tight = ["--set", "solver.friction_tol=1e-12"];
    let pi = ["--set", "drive.kind=pi", "--set", "solver.integrator=rk4"];
    // Simpson throughout, as the comparison was written for (the default "auto" takes
    // error-controlled steps on the ramps, up to each crank train's own max_step_deg).
    let simpson = ["--set", "solver.quadrature=\"simpson\""];
    for (set, drive) in [
        ("fedem-baseline", &simpson[..]),
        ("stribeck-duty", &simpson[..]),
        ("stribeck-duty", &pi[..]),
    ] {
        let run = |r: &str| {
            let mut a = vec!["run", r, "--lawset", set];
            a.extend(tight);
            a.extend(drive);
            run_json(dir.path(), &a)
        };
        let (thesis, engine) = (run("crf250r-motored"), run(rig));
        assert_eq!(engine["steps"], thesis["steps"], "{set} {drive:?}");
        assert_eq!(engine["drive"], thesis["drive"]);
        for (g, t) in torques(&engine).iter().zip(&torques(&thesis)) {
            assert!(
                (g - t).abs() <= 1e-9 * t.abs(),
                "{set} {drive:?}: {g} vs {t}"
            );
        }
        for (pe, pt) in engine["plateaus"]
            .as_array()
            .expect("plateaus")
            .iter()
            .zip(thesis["plateaus"].as_array().expect("plateaus"))
        {
            let (me, mt) = (
                pe["mean_speed_rpm"].as_f64().expect("speed"),
                pt["mean_speed_rpm"].as_f64().expect("speed"),
            );
            assert!((me - mt).abs() <= 1e-9 * mt, "{set}: {me} vs {mt} rpm");
        }
        let residual = engine["energy"]["relative_residual"]
            .as_f64()
            .expect("residual");
        assert!(
            residual < 1e-8,
            "{set} {drive:?}: energy residual {residual}"
        );
    }
}

#[test]
fn an_engine_runs_the_whole_cycle_and_keeps_its_energy_balance() {
    // Inline-4 and V-twin, prescribed crank and PI drive. Without laws: the motor's work is the
    // change of the train's kinetic and potential energy (written out independently of the
    // crank equation, `CrankTrain::mechanical_energy`), to 1e-8; every plateau's mean torque
    // over whole revolutions is zero to 1e-9 of the peak. With a law set: the motor's work is
    // the energy change plus the laws' dissipation, and the prescribed plateaus, measured after
    // a second of hold, are the steady state's to 1e-4.
    let dir = tempfile::tempdir().expect("temp dir");
    for name in ["inline4", "vtwin"] {
        let rig = fixture(name);
        let rig = rig.to_str().expect("utf-8");
        for drive in [
            &[][..],
            &[
                "--set",
                "drive.kind=pi",
                "--set",
                "drive.torque_limit_nm=500",
            ][..],
        ] {
            let mut a = vec!["run", rig];
            a.extend(drive);
            let r = run_json(dir.path(), &a);
            let residual = r["energy"]["relative_residual"].as_f64().expect("residual");
            assert!(residual < 1e-8, "{name} {drive:?}: {residual}");
            let motor = r["energy"]["motor_work_j"].as_f64().expect("work");
            assert!(
                motor > 1.0,
                "{name}: the run spins the train up ({motor} J)"
            );
            if drive.is_empty() {
                for p in r["plateaus"].as_array().expect("plateaus") {
                    let t = p["motoring_torque_nm"].as_f64().expect("torque");
                    assert!(t.abs() < 1e-6, "{name}: frictionless mean torque {t}");
                }
            } else {
                for p in r["plateaus"].as_array().expect("plateaus") {
                    let (set, mean) = (
                        p["set_speed_rpm"].as_f64().expect("set"),
                        p["mean_speed_rpm"].as_f64().expect("mean"),
                    );
                    assert!(
                        (mean - set).abs() < 0.01 * set,
                        "{name}: {mean} rpm at {set}"
                    );
                }
            }
        }
        if name == "inline4" {
            // A motored 4-stroke head on every cylinder, phased by the firing order: the gas
            // work over the run is reversible, the plateaus are whole 4-stroke cycles.
            let head =
                "gas.cylinder={kind=\"motored\", compression_ratio=10.0, valves=\"four-stroke\"}";
            let r = run_json(dir.path(), &["run", rig, "--set", head]);
            let residual = r["energy"]["relative_residual"].as_f64().expect("residual");
            assert!(residual < 1e-8, "{name} with compression: {residual}");
            for p in r["plateaus"].as_array().expect("plateaus") {
                let t = p["motoring_torque_nm"].as_f64().expect("torque");
                assert!(t.abs() < 1e-6, "{name} with compression: mean torque {t}");
                let revs = p["revolutions"].as_u64().expect("revolutions");
                assert!(revs % 2 == 0, "whole 4-stroke cycles: {revs}");
            }
        }
        let tight = ["--set", "solver.friction_tol=1e-12"];
        let mut a = vec!["run", rig, "--lawset", "stribeck-duty"];
        a.extend(tight);
        let transient = run_json(dir.path(), &a);
        let e = &transient["energy"];
        let (motor, change, lost) = (
            e["motor_work_j"].as_f64().expect("work"),
            e["mechanical_energy_change_j"].as_f64().expect("change"),
            e["dissipated_j"].as_f64().expect("dissipated"),
        );
        assert!(
            lost > 0.1 * motor,
            "{name}: the laws dissipate ({lost} of {motor} J)"
        );
        assert!((motor - change - lost).abs() < 1e-8 * motor, "{name}: {e}");
        a.push("--steady");
        let steady = run_json(dir.path(), &a);
        for (t, s) in torques(&transient).iter().zip(&torques(&steady)) {
            assert!(
                (t - s).abs() < 1e-4 * s.abs(),
                "{name}: transient {t} vs steady {s}"
            );
        }
    }
}

#[test]
fn an_engines_time_series_and_crank_angle_results_cover_every_joint_and_cylinder() {
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = fixture("inline4");
    let rig = rig.to_str().expect("utf-8");
    // The time series: a column per joint of the engine, a line per step.
    let out = tribo_ok(
        dir.path(),
        &[
            "run",
            rig,
            "--lawset",
            "stribeck-duty",
            "--timeseries",
            "ts.csv",
            "--csv",
            "cs",
            "--json",
        ],
    );
    let result: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let series = std::fs::read_to_string(dir.path().join("ts.csv")).expect("time series");
    let header: Vec<&str> = series.lines().next().expect("header").split(',').collect();
    for j in ["main_1", "main_5", "big_end_1", "small_end_4", "piston_4"] {
        assert!(
            header.contains(&format!("{j}_normal_load_n").as_str()),
            "{header:?}"
        );
    }
    assert_eq!(header.len(), 5 + 5 + 3 * 4);
    let lines = series.lines().count() as u64 - 1;
    assert_eq!(Some(lines), result["steps"].as_u64());
    // The CSV's per-component and per-cylinder totals recombine the per-law rows: the four
    // components, and the mains plus the four cylinders, each add up to all the laws.
    let rows = |f: &str| -> Vec<Vec<String>> {
        let mut r = csv::Reader::from_path(dir.path().join("cs").join(f)).expect(f);
        r.records()
            .map(|x| x.expect("row").iter().map(str::to_string).collect())
            .collect()
    };
    let (laws, groups) = (rows("joints.csv"), rows("groups.csv"));
    let speed = &laws[0][0];
    let all: f64 = laws
        .iter()
        .filter(|r| &r[0] == speed)
        .map(|r| r[3].parse::<f64>().expect("torque"))
        .sum();
    let group = |g: &str| {
        groups
            .iter()
            .find(|r| &r[0] == speed && r[1] == g)
            .map(|r| r[2].parse::<f64>().expect("torque"))
            .unwrap_or_else(|| panic!("group {g} in groups.csv"))
    };
    let components: f64 = ["main_*", "big_end_*", "small_end_*", "piston_*"]
        .iter()
        .map(|g| group(g))
        .sum();
    let cylinders: f64 = (1..=4).map(|k| group(&format!("cylinder {k}"))).sum();
    assert!(all > 0.0);
    assert!(
        (components - all).abs() < 1e-9 * all,
        "{components} vs {all}"
    );
    assert!(
        (cylinders + group("main_*") - all).abs() < 1e-9 * all,
        "{cylinders} vs {all}"
    );

    // Crank-angle results in steady state at 1 degree. The flat-plane crank has throws at 0,
    // 180, 180 and 0 degrees and every cylinder upright: cylinder 2's (and 3's) big-end load
    // and side thrust at theta are cylinder 1's at theta + 180 degrees, cylinder 4's are
    // cylinder 1's at theta. The cycle mean of the drive torque is the steady plateau torque
    // (the same angles, the same periodic rule).
    let tight = [
        "--set",
        "solver.friction_tol=1e-12",
        "--set",
        "solver.step_deg=1",
    ];
    let mut a = vec![
        "run",
        rig,
        "--lawset",
        "stribeck-duty",
        "--steady",
        "--resolution-deg",
        "1",
    ];
    a.extend(tight);
    a.extend(["--crank-angle", "ca"]);
    let steady = run_json(dir.path(), &a);
    let read = |f: &str| -> Vec<Vec<String>> {
        let mut r = csv::Reader::from_path(dir.path().join("ca").join(f)).expect(f);
        r.records()
            .map(|x| x.expect("row").iter().map(str::to_string).collect())
            .collect()
    };
    let num = |s: &str| s.parse::<f64>().expect("number");
    let cylinders = read("crank_angle_cylinders.csv");
    let first_speed = &cylinders[0][0];
    let at = |cyl: usize, deg: usize| -> [f64; 3] {
        let row = cylinders
            .iter()
            .filter(|r| &r[0] == first_speed && r[2] == cyl.to_string())
            .nth(deg % 360)
            .expect("sample");
        assert_eq!(num(&row[1]).round() as usize, deg % 360);
        [num(&row[3]), num(&row[4]), num(&row[5])]
    };
    let mut peak = 0.0_f64;
    for deg in 0..360 {
        let one = at(1, deg);
        peak = peak.max(one[1].abs());
        for (cyl, shift) in [(2, 180), (3, 180), (4, 0)] {
            let other = at(cyl, deg + 360 - shift);
            for c in 0..3 {
                assert!(
                    (other[c] - one[c]).abs() <= 1e-6 * (1.0 + one[c].abs().max(peak)),
                    "cylinder {cyl} at {}: {other:?} vs cylinder 1 at {deg}: {one:?}",
                    (deg + 360 - shift) % 360
                );
            }
        }
    }
    let mains = read("crank_angle_mains.csv");
    assert_eq!(
        mains.len(),
        cylinders.len() / 4 * 5,
        "one row per main and angle"
    );
    let loads = read("crank_angle_loads.csv");
    let torque: Vec<f64> = loads
        .iter()
        .filter(|r| &r[0] == first_speed)
        .map(|r| num(&r[8]))
        .collect();
    assert_eq!(torque.len(), 360);
    let mean = torque.iter().sum::<f64>() / 360.0;
    let plateau = torques(&steady)[0];
    assert!(
        (mean - plateau).abs() < 1e-8 * plateau.abs(),
        "{mean} vs {plateau}"
    );
}

#[test]
fn the_studies_run_on_an_engine() {
    // Data made by the model itself at a known Coulomb coefficient on every piston (steady
    // state at the rig's plateau speeds): `fit` started elsewhere recovers it, `compare` gives
    // the true set zero error and ranks it first, `sweep` and `mass-response` run with the
    // engine's joints, and the mass response's torques are the steady runs' of the rig and of
    // the rig with the lighter rods.
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = fixture("inline4");
    let rig = rig.to_str().expect("utf-8");
    let set = |name: &str, mu: f64| {
        format!(
            "name = \"{name}\"\n[[laws]]\njoint = \"main_*\"\nlaw = \"rolling-bearing\"\nparams = {{ mu = 0.0011 }}\n[[laws]]\njoint = \"piston_*\"\nlaw = \"coulomb\"\nparams = {{ mu = {mu} }}\nfree = {{ mu = [0.01, 0.3] }}\n"
        )
    };
    std::fs::write(dir.path().join("truth.toml"), set("truth", 0.08)).expect("write");
    std::fs::write(dir.path().join("start.toml"), set("start", 0.03)).expect("write");
    let truth = run_json(
        dir.path(),
        &["run", rig, "--steady", "--lawset", "truth.toml"],
    );
    let mut data =
        String::from("# made by the model at mu = 0.08\nspeed_rpm,torque_nm,oil_temp_c\n");
    for p in truth["plateaus"].as_array().expect("plateaus") {
        data.push_str(&format!(
            "{},{},{}\n",
            p["set_speed_rpm"].as_f64().expect("speed").round(),
            p["motoring_torque_nm"].as_f64().expect("torque"),
            p["oil_temp_c"].as_f64().expect("oil"),
        ));
    }
    std::fs::write(dir.path().join("data.csv"), data).expect("write");

    let out = tribo_ok(
        dir.path(),
        &[
            "fit",
            rig,
            "--lawset",
            "start.toml",
            "--data",
            "data.csv",
            "--json",
            "--out",
            "fitted.toml",
        ],
    );
    let fit: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let mu = fit["values"][0].as_f64().expect("fitted mu");
    assert!((mu - 0.08).abs() < 1e-5, "fitted mu {mu}: {fit}");

    let out = tribo_ok(
        dir.path(),
        &[
            "compare",
            rig,
            "--steady",
            "--lawset",
            "start.toml",
            "--lawset",
            "truth.toml",
            "--data",
            "data.csv",
            "--no-cv",
            "--json",
        ],
    );
    let cmp: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let sets = cmp["sets"].as_array().expect("sets");
    let truth_set = sets.iter().find(|s| s["lawset"] == "truth").expect("truth");
    let rmse = truth_set["rmse_nm"].as_f64().expect("rmse");
    assert!(rmse < 1e-9, "the true set reproduces the data: {rmse}");
    assert_eq!(truth_set["rank"], 1);
    let joints: Vec<&str> = truth_set["run"]["plateaus"][0]["joints"]
        .as_array()
        .expect("joints")
        .iter()
        .map(|j| j["joint"].as_str().expect("joint"))
        .collect();
    assert!(
        joints.contains(&"piston_4") && joints.contains(&"main_5"),
        "{joints:?}"
    );

    let out = tribo_ok(
        dir.path(),
        &["sweep", rig, "--lawset", "truth.toml", "--json"],
    );
    let sweep: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    // Every point lists the engine's joints; at the rig's oil temperature the sweep's torque is
    // the steady run's.
    let points = sweep["sets"][0]["points"].as_array().expect("points");
    let names: Vec<&str> = points[0]["joints"]
        .as_array()
        .expect("joints")
        .iter()
        .map(|j| j["joint"].as_str().expect("joint"))
        .collect();
    assert_eq!(names.len(), 5 + 3 * 4, "{names:?}");
    assert!(
        names.contains(&"main_5") && names.contains(&"piston_4"),
        "{names:?}"
    );
    let oil = truth["plateaus"][0]["oil_temp_c"].as_f64().expect("oil");
    for p in points
        .iter()
        .filter(|p| p["oil_temp_c"].as_f64() == Some(oil))
    {
        let speed = p["speed_rpm"].as_f64().expect("speed");
        let run = truth["plateaus"]
            .as_array()
            .expect("plateaus")
            .iter()
            .find(|q| (q["set_speed_rpm"].as_f64().expect("speed") - speed).abs() < 1e-6)
            .map(|q| q["motoring_torque_nm"].as_f64().expect("torque"));
        if let Some(t) = run {
            let s = p["torque_nm"].as_f64().expect("torque");
            assert!(
                (s - t).abs() < 1e-9 * t.abs(),
                "sweep {s} vs run {t} at {speed} rpm"
            );
        }
    }
    let piston: f64 = points[0]["joints"]
        .as_array()
        .expect("joints")
        .iter()
        .filter(|j| {
            j["joint"]
                .as_str()
                .is_some_and(|n| n.starts_with("piston_"))
        })
        .map(|j| j["friction_torque_nm"].as_f64().expect("torque"))
        .sum();
    assert!(
        piston > 0.0,
        "the pistons' Coulomb friction is in the sweep's joints"
    );

    let out = tribo_ok(
        dir.path(),
        &[
            "mass-response",
            rig,
            "--steady",
            "--lawset",
            "truth.toml",
            "--json",
        ],
    );
    let mr: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    // The comparison's plots on an engine: every joint in the contributions, the pistons'
    // regimes (a law that reports them, averaged over the four pistons) in the regime plot.
    tribo_ok(
        dir.path(),
        &[
            "compare",
            rig,
            "--steady",
            "--lawset",
            "stribeck-duty",
            "--data",
            "data.csv",
            "--no-cv",
            "--out",
            "plots",
        ],
    );
    let svg = |f: &str| std::fs::read_to_string(dir.path().join("plots").join(f)).expect(f);
    let contrib = svg("contributions_stribeck-duty.svg");
    for j in ["main_1", "main_5", "big_end_4", "piston_1", "piston_4"] {
        assert!(contrib.contains(j), "contributions plot lacks {j}");
    }
    let regimes = svg("piston_regimes.svg");
    assert!(
        regimes.contains("stribeck-duty: mixed"),
        "regime plot legend"
    );
    assert!(
        !regimes.contains("no law set reports"),
        "the pistons' regimes are plotted"
    );
    let light = run_json(
        dir.path(),
        &[
            "run",
            rig,
            "--steady",
            "--lawset",
            "truth.toml",
            "--set",
            "bodies.rod.mass_scale=0.6",
            "--set",
            "bodies.rod.inertia_scale=0.6",
        ],
    );
    let changes = mr[0]["changes"].as_array().expect("changes");
    for ((c, t), l) in changes.iter().zip(torques(&truth)).zip(torques(&light)) {
        let (o, s) = (
            c["original_nm"].as_f64().expect("original"),
            c["scaled_nm"].as_f64().expect("scaled"),
        );
        assert!((o - t).abs() < 1e-9 * t.abs(), "original {o} vs run {t}");
        assert!((s - l).abs() < 1e-9 * l.abs(), "scaled {s} vs run {l}");
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
        assert_eq!(v["fmep"]["basis"], "four-stroke"); // issue 25: a four-stroke engine, head-less
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

// ---- phase 2 of the friction/reaction iteration on engines (docs/solver.md) ----

/// The sqrt-load fixture law set written with joint groups (every piston, main and big end)
/// and the fixture library holding its piston law.
fn sqrt_load_files() -> (String, String) {
    let set = common::workspace().join("tests/fixtures/lawsets/sqrt-load-every-piston.toml");
    let lib = common::built_library("tribo_fixture_sqrt_load_law");
    (
        set.to_string_lossy().into_owned(),
        lib.to_string_lossy().into_owned(),
    )
}

/// `tribo run RIG --lawset SET EXTRA` with `--plugin LIB` (fixtures are not found by name).
fn plugged_run<'a>(lib: &'a str, rig: &'a str, set: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec!["--plugin", lib, "run", rig, "--lawset", set];
    a.extend_from_slice(extra);
    a
}

/// `tribo --quiet ARGS` in `dir`, expected to fail with exit code 1: its stderr.
fn tribo_fails(dir: &Path, args: &[&str]) -> String {
    let out = Command::new(common::tribo_exe())
        .current_dir(dir)
        .arg("--quiet")
        .args(args)
        .output()
        .expect("tribo runs");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "tribo {args:?}: {stderr}");
    stderr
}

/// The friction torque of the law on `joint` in plateau `p`.
fn joint_torque(p: &serde_json::Value, joint: &str) -> f64 {
    p["joints"]
        .as_array()
        .expect("joints")
        .iter()
        .find(|j| j["joint"] == joint)
        .and_then(|j| j["friction_torque_nm"].as_f64())
        .unwrap_or_else(|| panic!("no law on {joint}"))
}

#[test]
fn a_one_cylinder_engine_settles_a_sqrt_load_piston_law_like_the_thesis_rig() {
    // The sqrt(load) piston law stalls the plain iteration where the side thrust crosses zero
    // (at t = 0.0757 s of the cycle the engine's plain iteration failed after 50 iterations
    // before phase 2 existed). Both solvers now settle it by phase 2, each to friction_tol
    // (tightened to 1e-12): the engine's plateau torques, its piston's share and its mean
    // speeds equal the single-cylinder solver's to 1e-9 (what the law sets settled by phase 1
    // are held to above; observed 5e-12), steady, prescribed and PI (RK4 on both).
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = dir.path().join("one.toml");
    std::fs::write(&rig, thesis_as_engine()).expect("write");
    let rig = rig.to_str().expect("utf-8");
    let (set, lib) = sqrt_load_files();
    let pi = ["--set", "drive.kind=pi", "--set", "solver.integrator=rk4"];
    // Prescribed: Simpson throughout, as the comparison was written for (see above).
    let simpson = ["--set", "solver.quadrature=\"simpson\""];
    for drive in [&["--steady"][..], &simpson[..], &pi[..]] {
        let run = |r: &str| {
            let mut extra = vec!["--set", "solver.friction_tol=1e-12"];
            extra.extend(drive);
            run_json(dir.path(), &plugged_run(&lib, r, &set, &extra))
        };
        let (thesis, engine) = (run("crf250r-motored"), run(rig));
        assert_eq!(engine["steps"], thesis["steps"], "{drive:?}");
        let pairs = engine["plateaus"]
            .as_array()
            .expect("plateaus")
            .iter()
            .zip(thesis["plateaus"].as_array().expect("plateaus"));
        for (pe, pt) in pairs {
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs();
            let (te, tt) = (
                pe["motoring_torque_nm"].as_f64().expect("torque"),
                pt["motoring_torque_nm"].as_f64().expect("torque"),
            );
            assert!(tt > 0.1 && close(te, tt), "{drive:?}: {te} vs {tt}");
            let (fe, ft) = (joint_torque(pe, "piston_1"), joint_torque(pt, "piston"));
            assert!(close(fe, ft), "{drive:?}: piston {fe} vs {ft}");
            let (me, mt) = (
                pe["mean_speed_rpm"].as_f64().expect("speed"),
                pt["mean_speed_rpm"].as_f64().expect("speed"),
            );
            assert!(close(me, mt), "{drive:?}: {me} vs {mt} rpm");
        }
        let residual = engine["energy"]["relative_residual"]
            .as_f64()
            .expect("residual");
        assert!(
            residual.abs() < 1e-8,
            "{drive:?}: energy residual {residual}"
        );
    }
}

#[test]
fn an_engine_whose_laws_admit_no_consistent_load_fails_in_phase_2_naming_the_joint() {
    // Coulomb with mu = 10 on the piston: where friction adds to the side thrust the load it
    // causes grows faster than the load itself, so no consistent load exists. Phase 2 finds
    // neither a descent step nor a bracket and says so before the iteration limit, at the same
    // instant and iteration as the single-cylinder solver, naming the piston and its law only
    // (the plain iteration alone ran to the limit at another instant, naming no joint).
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = dir.path().join("one.toml");
    std::fs::write(&rig, thesis_as_engine()).expect("write");
    let set = dir.path().join("mu10.toml");
    std::fs::write(
        &set,
        "name = \"mu10\"\n[[laws]]\njoint = \"piston_*\"\nlaw = \"coulomb\"\nparams = { mu = 10.0 }\n",
    )
    .expect("write");
    let set = set.to_str().expect("utf-8");
    let engine = tribo_fails(
        dir.path(),
        &["run", rig.to_str().expect("utf-8"), "--lawset", set],
    );
    let thesis = tribo_fails(dir.path(), &["run", "crf250r-motored", "--lawset", set]);
    // "... did not converge at t = T s after N iterations: the normal load of joint ..."
    let head = |s: &str| {
        s.split(": the normal load")
            .next()
            .unwrap_or("")
            .to_string()
    };
    assert!(
        engine.contains("after ") && head(&engine) == head(&thesis),
        "engine: {engine}\nthesis: {thesis}"
    );
    let iterations: u32 = head(&engine)
        .rsplit("after ")
        .next()
        .and_then(|s| s.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("an iteration count");
    assert!(
        iterations < 50,
        "phase 2 gave up before the limit: {engine}"
    );
    assert!(
        engine.contains("joint `piston_1` (law `coulomb`) did not settle")
            && engine.contains("solver.friction_max_iter"),
        "{engine}"
    );
    assert!(
        !engine.contains("main_") && !engine.contains("big_end"),
        "{engine}"
    );

    // The sqrt-load set with an iteration limit too low to settle: the joints named.
    let (sqrt, lib) = sqrt_load_files();
    let rig = rig.to_str().expect("utf-8");
    let a = plugged_run(&lib, rig, &sqrt, &["--set", "solver.friction_max_iter=2"]);
    let low = tribo_fails(dir.path(), &a);
    assert!(
        low.contains("after 2 iterations") && low.contains("`piston_1` (law `sqrt-load-test`)"),
        "{low}"
    );
}

#[test]
fn the_inline4_with_a_sqrt_load_law_on_every_piston_runs_steady_and_transient() {
    // Flat-plane crank, upright cylinders: cylinders 1 and 4 (throw 0 degrees) and 2 and 3
    // (180) are the same slider-crank at the same instant, and the two throws are the same
    // slider-crank half a revolution apart, so over whole revolutions every piston dissipates
    // alike. Steady (friction_tol 1e-12; 360 points a revolution, so the throws see the same
    // angles): all four to 1e-9 (observed 2e-14). Prescribed transient: 1 = 4 and 2 = 3 to
    // 1e-9; across the throws to 2e-5, the plateau window's ends falling between steps at
    // different angles of the two throws (observed 5e-6 with this law's kink at zero side
    // thrust, 3e-7 with the bundled laws). The energy balance closes in both.
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = fixture("inline4");
    let rig = rig.to_str().expect("utf-8");
    let (set, lib) = sqrt_load_files();
    let run = |extra: &[&str]| run_json(dir.path(), &plugged_run(&lib, rig, &set, extra));
    let steady = run(&["--steady", "--set", "solver.friction_tol=1e-12"]);
    let transient = run(&[]);
    for (r, across) in [(&steady, 1e-9), (&transient, 2e-5)] {
        let residual = r["energy"]["relative_residual"].as_f64().expect("residual");
        assert!(residual.abs() < 1e-6, "{}: {residual}", r["drive"]);
        for p in r["plateaus"].as_array().expect("plateaus") {
            let per: Vec<f64> = (1..=4)
                .map(|k| joint_torque(p, &format!("piston_{k}")))
                .collect();
            assert!(per[0] > 0.1, "{}: the law dissipates: {per:?}", r["drive"]);
            let same = |a: f64, b: f64, tol: f64| (a - b).abs() <= tol * a.abs();
            assert!(
                same(per[0], per[3], 1e-9) && same(per[1], per[2], 1e-9),
                "{per:?}"
            );
            assert!(same(per[0], per[1], across), "{}: {per:?}", r["drive"]);
            // Every law's friction adds up to the motoring torque (no net gas work).
            let laws: f64 = p["joints"]
                .as_array()
                .expect("joints")
                .iter()
                .map(|j| j["friction_torque_nm"].as_f64().expect("torque"))
                .sum();
            let motoring = p["motoring_torque_nm"].as_f64().expect("torque");
            assert!(
                (motoring - laws).abs() < 1e-6 * laws,
                "{motoring} vs {laws}"
            );
        }
    }
    // The transient's holds reach the steady state (the solver test's bound for this law).
    for (t, s) in torques(&transient).iter().zip(&torques(&steady)) {
        assert!((t - s).abs() <= 5e-3 * s, "transient {t} vs steady {s}");
    }
}

#[test]
fn an_engines_pi_drive_runs_the_adaptive_integrator_with_the_rigs_settings() {
    // Issue 28: an engine's PI drive runs what `[solver]` says, as the single-cylinder rig does:
    // by default Dormand-Prince 5(4) (fewer steps than RK4 at `step_deg`, whose count is the
    // cycle's length in degrees), RK4 on request; `rel_tol`, `max_step_deg` and `step_control`
    // each change the steps (used, never ignored). The adaptive plateaus agree with RK4 at
    // 1 degree within the adaptive run's tolerance against fine RK4 on the single-cylinder rig
    // (5e-5, tests/solver.rs).
    let dir = tempfile::tempdir().expect("temp dir");
    let rig = fixture("inline4");
    let rig = rig.to_str().expect("utf-8");
    // The stribeck-duty set this was measured with (H from a nominal load; the bundled set
    // became consistent in issue 26 and switches regime at other instants).
    let set = common::workspace().join("tests/fixtures/lawsets/stribeck-duty-nominal.toml");
    let set = set.to_str().expect("utf-8").to_string();
    let pi = ["--set", "drive.kind=pi", "--lawset", set.as_str()];
    let limit = ["--set", "drive.torque_limit_nm=500"];
    let run = |extra: &[&str]| {
        let mut a = vec!["run", rig];
        a.extend(pi);
        a.extend(limit);
        a.extend(extra);
        run_json(dir.path(), &a)
    };
    let steps = |r: &serde_json::Value| r["steps"].as_u64().expect("steps");
    let adaptive = run(&[]);
    let rk4 = run(&["--set", "solver.integrator=rk4"]);
    assert!(
        3 * steps(&adaptive) < steps(&rk4),
        "adaptive {} vs rk4 {} steps",
        steps(&adaptive),
        steps(&rk4)
    );
    for (a, r) in torques(&adaptive).iter().zip(&torques(&rk4)) {
        assert!((a - r).abs() < 5e-5 * r.abs(), "adaptive {a} vs rk4 {r}");
    }
    let residual = adaptive["energy"]["relative_residual"]
        .as_f64()
        .expect("residual");
    assert!(residual < 1e-8, "energy residual {residual}");
    let integral = run(&["--set", "solver.step_control=integral"]);
    assert_ne!(steps(&integral), steps(&adaptive), "step_control is used");
    // Frictionless (cheaper; there the longest step decides at speed, so the controller's
    // form does not show in the count): the tolerance and the longest step move the steps.
    let frictionless = |extra: &[&str]| {
        let mut a = vec!["run", rig, "--set", "drive.kind=pi"];
        a.extend(limit);
        a.extend(extra);
        steps(&run_json(dir.path(), &a))
    };
    let default = frictionless(&[]);
    for setting in ["solver.rel_tol=1e-5", "solver.max_step_deg=10"] {
        assert_ne!(
            frictionless(&["--set", setting]),
            default,
            "{setting} is used"
        );
    }
}

// ---- The 4B11 against the correlation's groups (issue 48) ----

/// The correlation's groups on the 4B11 at `rpm` with oil of viscosity `mu`, written out from
/// the published terms (PNH, SAE 890836, with Sandoval and Heywood's `(mu/mu0)^0.5`): the rig's
/// 86 x 86 mm bore and stroke, four cylinders, five 50 x 20 mm mains and four 48 x 20 mm rod
/// bearings, head-less. Returns (crankshaft, reciprocating) in kPa; their sum is the rubbing
/// total.
fn correlation_groups_4b11(rpm: f64, mu: f64) -> (f64, f64) {
    let root = (mu / tribo::correlation::reference_viscosity_pa_s()).sqrt();
    let (b, s, nc) = (86.0_f64, 86.0_f64, 4.0_f64);
    let den = b * b * s * nc;
    let seals = 1.22e5 * 50.0 / den;
    let mains = 5.0 * 3.03e-4 * root * rpm * 50f64.powi(3) * 20.0 / den;
    let turbulent = 1.35e-10 * 50f64.powi(2) * rpm * rpm * 5.0 / nc;
    let sp = 2.0 * s * 1e-3 * rpm / 60.0;
    let skirt = 2.94e2 * root * sp / b;
    let rings = 4.06e4 * (1.0 + 1000.0 / rpm) / (b * b);
    let rods = 4.0 * 3.03e-4 * root * rpm * 48f64.powi(3) * 20.0 / den;
    (seals + mains + turbulent, skirt + rings + rods)
}

/// One row of fmep.csv: (rpm, component, kPa).
type FmepRow = (f64, String, f64);

/// `tribo run inline4-4b11 --lawset SET --steady --fmep DIR --json`: (rpm, viscosity) per
/// plateau from the JSON and the rows of DIR/fmep.csv.
fn run_4b11_fmep(set: &str) -> (Vec<(f64, f64)>, Vec<FmepRow>) {
    let dir = tempfile::tempdir().expect("temp dir");
    let fmep = dir.path().join("fmep");
    let args = [
        "run",
        "inline4-4b11",
        "--lawset",
        set,
        "--steady",
        "--json",
        "--fmep",
        fmep.to_str().expect("utf-8"),
    ];
    let out = tribo_ok(dir.path(), &args);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("run JSON");
    let plateaus = v["plateaus"]
        .as_array()
        .expect("plateaus")
        .iter()
        .map(|p| {
            (
                p["set_speed_rpm"].as_f64().expect("rpm"),
                p["viscosity_pa_s"].as_f64().expect("viscosity"),
            )
        })
        .collect();
    (plateaus, fmep_rows(&fmep))
}

/// (rpm, component, kPa) of `dir`/fmep.csv.
fn fmep_rows(dir: &Path) -> Vec<FmepRow> {
    let mut r = csv::Reader::from_path(dir.join("fmep.csv")).expect("fmep.csv");
    r.records()
        .map(|row| {
            let row = row.expect("row");
            (
                row[0].parse().expect("rpm"),
                row[1].to_string(),
                row[2].parse().expect("kPa"),
            )
        })
        .collect()
}

/// Tribo's groups at `rpm` from fmep.csv rows: (crankshaft: every main, reciprocating: every
/// big end, small end and piston, rubbing total).
fn tribo_groups(rows: &[FmepRow], rpm: f64) -> (f64, f64, f64) {
    let sum = |pick: &dyn Fn(&str) -> bool| -> f64 {
        rows.iter()
            .filter(|(r, c, _)| *r == rpm && pick(c))
            .map(|x| x.2)
            .sum()
    };
    let crank = sum(&|c| c.starts_with("main_"));
    let recip = sum(&|c| {
        c.starts_with("big_end_") || c.starts_with("small_end_") || c.starts_with("piston_")
    });
    let total = sum(&|c| c == "total");
    (crank, recip, total)
}

/// The 4B11 against the correlation's guard band: the unfitted `4b11-physical` (the manual's
/// middle clearances, seals and windage on the crank) at 90 C, 1000-6000 rpm, read from
/// `fmep.csv`: the rubbing total within +-30% of the correlation's head-less rubbing total, the
/// crankshaft group (every main) and the reciprocating group (big ends, small ends, pistons)
/// each within a factor 1.5 of the correlation's groups, written out here from the published
/// terms.
///
/// Not met at 6000 rpm only: the crankshaft group is 0.652 of the correlation's (17.40 against
/// 26.67 kPa), 0.38 kPa short of the band. Why (docs/engines.md, "The correlation's groups"):
/// the correlation's crank group grows 6.2 times from 1000 to 6000 rpm, Tribo's 3.1 times,
/// because 15.19 kPa of it at 6000 rpm (57%) is the empirical `N^2` "turbulent dissipation"
/// term, and the physical windage and oil-pumping law gives 0.50 kPa there. With the ratio at
/// 1000 rpm at 1.286, the band leaves a window of 0.38-0.93 kPa of constant crank friction to
/// add; the seal law's level is uncertain by more than that (its validation against ISO/TR
/// 14179-2 is 3-12 times below at 90 C), so the verdict at 6000 rpm is set by an estimate, and
/// no sourced mechanism supplies the `N^2` growth. Each of these closes the 0.060 N m alone,
/// and none has a source that fixes it (docs/engines.md, "What the 6000 rpm verdict rests
/// on"): the seals at the Patton-Nitschke-Heywood seal term's level (0.692) or ISO's (0.755);
/// 5-10% of the main films' heat conducted through the metal instead of carried by the oil
/// (the law's balance is adiabatic: +2.3-4.7% on the films); a crankcase mist of 4 kg/m^3
/// for the windage. Run it with `cargo test --release --test engine -- --ignored
/// the_4b11_stands`.
#[test]
#[ignore = "not met at 6000 rpm: crankshaft group 0.652 of the correlation's (0.38 kPa short), whose N^2 turbulent-dissipation term (15.2 kPa) no sourced mechanism supplies; the seal level, the mains' adiabatic heat balance or the mist density each close the gap, none sourced (docs/engines.md)"]
fn the_4b11_stands_in_the_correlation_s_guard_band_at_90_c() {
    let (plateaus, rows) = run_4b11_fmep("4b11-physical");
    let mut failures = Vec::new();
    for &(rpm, mu) in plateaus.iter().filter(|p| p.0 <= 6000.0) {
        let (c_crank, c_recip) = correlation_groups_4b11(rpm, mu);
        let (crank, recip, total) = tribo_groups(&rows, rpm);
        assert!(
            (total - crank - recip).abs() <= 1e-9 * total,
            "{rpm}: the groups make the total"
        );
        for (what, ratio, lo, hi) in [
            ("total", total / (c_crank + c_recip), 0.7, 1.3),
            ("crankshaft", crank / c_crank, 1.0 / 1.5, 1.5),
            ("reciprocating", recip / c_recip, 1.0 / 1.5, 1.5),
        ] {
            if !(lo..=hi).contains(&ratio) {
                failures.push(format!(
                    "{rpm} rpm {what}: {ratio:.3} outside {lo:.3}-{hi:.3}"
                ));
            }
        }
    }
    assert_eq!(plateaus.iter().filter(|p| p.0 <= 6000.0).count(), 6);
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The guard band `run --fmep` writes beside every plateau (fmep_correlation.json) is the
/// groups' ratios computed here from fmep.csv and the published terms, each judged against
/// its band: the printed verdict is the physics', whichever way it goes.
#[test]
fn the_guard_band_printed_beside_the_4b11_is_its_groups_against_the_correlation() {
    let dir = tempfile::tempdir().expect("temp dir");
    let fmep = dir.path().join("fmep");
    let cycle = "cycle.segments=[{kind=\"ramp\", to_rpm=1000.0, duration_s=0.2}, \
        {kind=\"hold\", duration_s=0.2}, {kind=\"ramp\", to_rpm=6000.0, duration_s=0.2}, \
        {kind=\"hold\", duration_s=0.2}]";
    let out = tribo_ok(
        dir.path(),
        &[
            "run",
            "inline4-4b11",
            "--lawset",
            "4b11-physical",
            "--steady",
            "--set",
            cycle,
            "--json",
            "--fmep",
            fmep.to_str().expect("utf-8"),
        ],
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("run JSON");
    let rows = fmep_rows(&fmep);
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(fmep.join("fmep_correlation.json")).expect("json"),
    )
    .expect("correlation JSON");
    let mut checked = 0;
    for p in v["plateaus"].as_array().expect("plateaus") {
        let rpm = p["set_speed_rpm"].as_f64().expect("rpm");
        let mu = p["viscosity_pa_s"].as_f64().expect("mu");
        let (c_crank, c_recip) = correlation_groups_4b11(rpm, mu);
        let (crank, recip, total) = tribo_groups(&rows, rpm);
        let plateau = json["plateaus"]
            .as_array()
            .expect("plateaus")
            .iter()
            .find(|x| x["set_speed_rpm"].as_f64() == Some(rpm))
            .expect("plateau");
        let band = plateau["guard_band"].as_array().expect("guard band");
        for (group, ratio, lo, hi) in [
            ("total", total / (c_crank + c_recip), 0.7, 1.3),
            ("crankshaft", crank / c_crank, 1.0 / 1.5, 1.5),
            ("reciprocating", recip / c_recip, 1.0 / 1.5, 1.5),
        ] {
            let g = band
                .iter()
                .find(|g| g["group"] == group)
                .unwrap_or_else(|| panic!("{rpm}: no {group} in {band:?}"));
            let printed = g["ratio"].as_f64().expect("ratio");
            assert!(
                (printed - ratio).abs() <= 1e-9 * ratio,
                "{rpm} {group}: printed {printed} vs {ratio}"
            );
            assert_eq!(g["inside"].as_bool(), Some((lo..=hi).contains(&ratio)));
            checked += 1;
        }
    }
    assert_eq!(checked, 6);
}

/// The clearance band: the same set at the manual's minimum, middle and maximum oil clearance
/// runs in one `sweep`, and at 1000 rpm, where the films are thick and cool, the tighter
/// bearings shear harder (Petroff: the film's torque falls with the clearance), mains and big
/// ends alike; everything but the two plain-journal entries is the same in the three sets.
#[test]
fn the_clearance_band_runs_the_manual_s_three_clearances_in_one_sweep() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = tribo_ok(
        dir.path(),
        &[
            "sweep",
            "inline4-4b11",
            "--lawset",
            "4b11-physical-tight",
            "--lawset",
            "4b11-physical",
            "--lawset",
            "4b11-physical-loose",
            "--temps",
            "90",
            "--speeds",
            "1000",
            "--out",
            "band",
            "--quiet",
        ],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    for set in [
        "4b11-physical-tight",
        "4b11-physical",
        "4b11-physical-loose",
    ] {
        assert!(stdout.contains(&format!("law set {set}:")), "{stdout}");
    }
    // Clearances as the three files give them: 6, 10.5 and 15 um on the mains, 9, 15.75 and
    // 22.5 um on the big ends: the manual's 0.012-0.030 and 0.018-0.045 mm diametral.
    let read = |name: &str| -> toml::Value {
        let p = common::workspace().join(format!("rigs/lawsets/{name}.toml"));
        toml::from_str(&std::fs::read_to_string(&p).expect("set")).expect("toml")
    };
    let clearance = |set: &toml::Value, joint: &str| -> f64 {
        set["laws"]
            .as_array()
            .expect("laws")
            .iter()
            .find(|l| {
                l["joint"].as_str() == Some(joint) && l["law"].as_str() == Some("plain-journal")
            })
            .and_then(|l| l["params"]["clearance_m"].as_float())
            .expect("clearance")
    };
    let sets: Vec<toml::Value> = [
        "4b11-physical-tight",
        "4b11-physical",
        "4b11-physical-loose",
    ]
    .iter()
    .map(|n| read(n))
    .collect();
    for (k, (main, rod)) in [
        (0.012e-3, 0.018e-3),
        (0.021e-3, 0.0315e-3),
        (0.030e-3, 0.045e-3),
    ]
    .iter()
    .enumerate()
    {
        assert!((clearance(&sets[k], "main_*") - main / 2.0).abs() < 1e-12);
        assert!((clearance(&sets[k], "big_end") - rod / 2.0).abs() < 1e-12);
    }
    // Apart from the clearances the sets are the same.
    let strip = |set: &toml::Value| -> Vec<toml::Value> {
        let mut laws = set["laws"].as_array().expect("laws").clone();
        for l in &mut laws {
            if let Some(p) = l.get_mut("params").and_then(|p| p.as_table_mut()) {
                p.remove("clearance_m");
            }
        }
        laws
    };
    assert_eq!(strip(&sets[0]), strip(&sets[1]));
    assert_eq!(strip(&sets[2]), strip(&sets[1]));
    // The sweep's own numbers: per set, each joint's torque at 1000 rpm.
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("band/sweep.json")).expect("sweep.json"),
    )
    .expect("json");
    let torque = |set: &str, prefix: &str| -> f64 {
        let s = json["sets"]
            .as_array()
            .expect("sets")
            .iter()
            .find(|s| s["lawset"] == set)
            .expect("set");
        s["points"][0]["joints"]
            .as_array()
            .expect("joints")
            .iter()
            .filter(|j| j["joint"].as_str().unwrap_or("").starts_with(prefix))
            .map(|j| j["friction_torque_nm"].as_f64().expect("torque"))
            .sum()
    };
    for prefix in ["main_", "big_end_"] {
        let t: Vec<f64> = [
            "4b11-physical-tight",
            "4b11-physical",
            "4b11-physical-loose",
        ]
        .iter()
        .map(|s| torque(s, prefix))
        .collect();
        assert!(t[0] > t[1] && t[1] > t[2], "{prefix}: {t:?}");
    }
}
