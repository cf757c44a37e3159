//! Regression harness (issue 28), named as such: the solver against results captured with the
//! code before its refactoring into one solver for every crank train. Not a physics test (the
//! other suites check the physics against closed forms and the thesis): it proves that a
//! restructuring moved no number.
//!
//! `tests/fixtures/regression/cases.json` holds, for every bundled rig with its own laws, with
//! each bundled law set and with a stateful law (LuGre on the pistons), the results of a
//! steady run, a transient run with the prescribed crank and one with the PI drive (engines
//! with the fixed-step RK4 they had), and the crank-angle traces (30 degrees), all on a short
//! cycle of two plateaus (3000 and 6000 rpm, oil at 60 and 90 C) so the whole harness runs in
//! seconds; the frictionless engines run transient with their own laws only (with a law set
//! they are the other engine rigs). Recorded: every plateau's
//! motoring, gas and per-law friction torques, powers, mean loads, regime shares, component
//! groups, speeds and windows; the energy balance; step counts; per crank angle every law's
//! torque, power, load and sliding speed, the big-end, main and per-cylinder reactions, the
//! pressures and the drive torque. A case that failed when captured records its error and must
//! still fail. The file names the commit whose code produced it (`source`).
//!
//! The comparison is 1e-9 relative, a value below one unit (1 N m, 1 N, 1 W, 1 Pa, 1 J)
//! compared to 1e-9 of that unit; the energy terms are compared on the scale of the motor
//! work (the residual is a difference of large terms). FMEP is not compared as a number: its
//! basis is a definition another issue changes; each plateau's FMEP must follow from its
//! torques by the run's own `Fmep`.
//!
//! Capturing (only with the code the fixture is meant to record: a change to a bundled rig's
//! or law set's data is captured again with the solver of its own commit, and the commit
//! message says so): `TRIBO_REGRESSION_CAPTURE=<commit> cargo test --release --test
//! regression`. A rig or law set bundled after the capture is reported, not compared.
//! `TRIBO_REGRESSION_RECAPTURE=<commit>:<case>[;<case>...]` captures the named cases only, into
//! the existing file (each recaptured case noted with its commit under `recaptured`): for a
//! change announced as moving exactly those cases (a case that failed and now runs).

mod common;

use std::path::Path;

use serde_json::{json, Value};
use tribo::plugin_api::loader::{load_paths, LawRegistry};

/// The short cycle every case runs: two plateaus, long enough for the 0.1 s window.
const CYCLE: &str = "cycle.segments=[{kind=\"ramp\", to_rpm=3000.0, duration_s=0.15}, {kind=\"hold\", duration_s=0.2}, {kind=\"ramp\", to_rpm=6000.0, duration_s=0.15}, {kind=\"hold\", duration_s=0.15}]";
/// The oil of every case: one temperature per plateau.
const OIL: &str = "oil.temperature_c=[60.0, 90.0]";
/// The PI drive of the transient PI cases: a torque limit every bundled rig stays below on the
/// short cycle's ramps.
const PI: &str = "drive={kind=\"pi\", torque_limit_nm=400.0}";
/// LuGre at a Coulomb level of 0.08 without viscous term (the solver tests' stateful law).
const LUGRE: &str = "lugre:{mu_c=0.08, mu_s=0.1, sigma2=0.0}";
/// Crank-angle resolution of the traces, degrees.
const RESOLUTION_DEG: f64 = 30.0;

fn fixture_path() -> std::path::PathBuf {
    common::workspace().join("tests/fixtures/regression/cases.json")
}

/// What a case runs.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Steady,
    Prescribed,
    Pi,
    CrankAngle,
}

impl Mode {
    fn name(self) -> &'static str {
        match self {
            Mode::Steady => "steady",
            Mode::Prescribed => "prescribed",
            Mode::Pi => "pi",
            Mode::CrankAngle => "crank-angle",
        }
    }
}

/// One case: a bundled rig, a law set (`own`: the rig's own laws; `lugre`: LuGre on every
/// piston), a mode.
struct Case {
    rig: String,
    laws: String,
    mode: Mode,
}

impl Case {
    fn name(&self) -> String {
        format!("{} / {} / {}", self.rig, self.laws, self.mode.name())
    }
}

/// Every case: each bundled rig with its own laws, each bundled law set and LuGre, steady and
/// in crank angle; transient (both drives) likewise, but the frictionless engines (the
/// engines with a law set are the other engine rigs' runs again) with their own laws only.
fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    let mut sets: Vec<String> = vec!["own".into()];
    sets.extend(tribo::bundled::lawset_names().iter().map(|s| s.to_string()));
    sets.push("lugre".into());
    for rig in tribo::bundled::rig_names() {
        let reference = rig.contains("frictionless") && !rig.starts_with("reference");
        for laws in &sets {
            for mode in [Mode::Steady, Mode::Prescribed, Mode::Pi, Mode::CrankAngle] {
                let transient = matches!(mode, Mode::Prescribed | Mode::Pi);
                if transient && reference && laws != "own" {
                    continue;
                }
                out.push(Case {
                    rig: rig.to_string(),
                    laws: laws.clone(),
                    mode,
                });
            }
        }
    }
    out
}

fn registry() -> LawRegistry {
    common::ensure_plugins_built();
    load_paths(&[common::profile_dir()]).expect("plugins load")
}

/// The case's rig, law set applied, with the short cycle and the drive of its mode.
fn rig_of(case: &Case) -> tribo::rig::Rig {
    let mut sets = vec![CYCLE.to_string(), OIL.to_string()];
    let engine = tribo::rig::load_rig(Path::new(&case.rig), &[])
        .expect("bundled rig")
        .file
        .engine
        .is_some();
    if case.mode == Mode::Pi {
        sets.push(PI.into());
        if engine {
            // The integrator engines ran before they had the adaptive one.
            sets.push("solver.integrator=\"rk4\"".into());
        }
    }
    let mut rig = tribo::rig::load_rig(Path::new(&case.rig), &sets).expect("bundled rig");
    match case.laws.as_str() {
        "own" => {}
        "lugre" => {
            let joint = if engine { "piston_*" } else { "piston" };
            let dir = tempfile::tempdir().expect("temp dir");
            let (law, params) = LUGRE.split_once(':').expect("law:params");
            let file = dir.path().join("lugre.toml");
            let table = params
                .trim_matches(|c| c == '{' || c == '}')
                .replace(", ", "\n");
            std::fs::write(&file, table).expect("write params");
            let arg = format!("{joint}={law}:{}", file.display());
            tribo::rig::attach_laws(&mut rig, &[arg]).expect("lugre attaches");
        }
        set => tribo::lawset::LawSet::load(set)
            .expect("bundled law set")
            .apply(&mut rig),
    }
    rig
}

/// The case's results as JSON, or its error as `{"error": message}`.
fn run_case(case: &Case, registry: &LawRegistry) -> Value {
    let rig = rig_of(case);
    let mut sim = match tribo::rig::simulation(&rig, registry) {
        Ok(s) => s,
        Err(e) => return json!({ "error": e.to_string() }),
    };
    // The warnings about laws on bearings they do not suit (added after the capture) are a
    // message about the set-up, not a result of the solver: left out, exactly those.
    let notes = sim.notes().to_vec();
    let solved = |mut r: tribo::sim::RunResult| {
        r.warnings.retain(|w| !notes.contains(w));
        run_json(&r)
    };
    let result = match case.mode {
        Mode::Steady => sim.run_steady().map(solved),
        Mode::Prescribed | Mode::Pi => sim.run().map(solved),
        Mode::CrankAngle => sim
            .crank_angle_traces(RESOLUTION_DEG)
            .map(|t| serde_json::to_value(t).expect("traces serialise")),
    };
    result.unwrap_or_else(|e| json!({ "error": e.to_string() }))
}

/// A run's result without what is not a result of the solver (law timing, the iteration count
/// diagnostic, the correlation beside it). FMEP is checked for consistency with the torques
/// instead (`fmep_follows`).
fn run_json(r: &tribo::sim::RunResult) -> Value {
    fmep_follows(r);
    let mut v = serde_json::to_value(r).expect("result serialises");
    if let Some(o) = v.as_object_mut() {
        o.remove("law_time");
        o.remove("fmep");
        // A diagnostic of the iteration, whose definition the refactoring unifies (the
        // largest count over every evaluation; the single-cylinder solver counted step ends).
        o.remove("max_friction_iterations");
    }
    // Two definitions issue 27 changed, checked for consistency instead (`energy_follows`):
    // the relative residual's scale, and the warning of a run without any law.
    energy_follows(r);
    if let Some(e) = v["energy"].as_object_mut() {
        e.remove("relative_residual");
    }
    if let Some(w) = v["warnings"].as_array_mut() {
        w.retain(|x| x.as_str() != Some(tribo::sim::NO_LAWS_WARNING));
    }
    for p in v["plateaus"].as_array_mut().into_iter().flatten() {
        if let Some(o) = p.as_object_mut() {
            o.remove("fmep");
            // The Sandoval-Heywood correlation beside the laws (issue 25): computed from the
            // rig's geometry and oil, not by the solver.
            o.remove("correlation");
            // The crankcase model's pumping torque at the plateau speed (issue 28, added
            // after the capture): the gas model's periodic cycle reported beside the run, not
            // a result of its integration (the measured gas torque is compared).
            o.remove("crankcase_pumping_torque_nm");
        }
    }
    v
}

/// The energy balance's relative residual is the residual over a scale at least as large as
/// each of its terms (so never above |residual| / |term|), and a run warns that it has no law
/// exactly when no plateau has a law.
fn energy_follows(r: &tribo::sim::RunResult) {
    let e = &r.energy;
    let largest = [
        e.motor_work_j,
        e.mechanical_energy_change_j,
        e.dissipated_j,
        e.gas_work_j,
    ]
    .iter()
    .fold(0.0_f64, |a, x| a.max(x.abs()));
    assert!(e.relative_residual >= 0.0, "{}", r.rig);
    if largest > 0.0 {
        assert!(
            e.relative_residual <= e.residual_j.abs() / largest * (1.0 + 1e-12),
            "{}: {} vs {}",
            r.rig,
            e.relative_residual,
            e.residual_j.abs() / largest
        );
    }
    let lawless = r.plateaus.iter().all(|p| p.joints.is_empty());
    let warned = r.warnings.iter().any(|w| w == tribo::sim::NO_LAWS_WARNING);
    assert_eq!(lawless, warned, "{}", r.rig);
}

/// Each plateau's FMEP follows from its torques by the run's own definition.
fn fmep_follows(r: &tribo::sim::RunResult) {
    for p in &r.plateaus {
        let total: f64 = p.joints.iter().map(|l| l.friction_torque_nm).sum();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(1.0);
        assert!(close(p.fmep.total_kpa, r.fmep.kpa(total)), "{}", r.rig);
        assert!(close(p.fmep.motoring_kpa, r.fmep.kpa(p.motoring_torque_nm)));
        for c in &p.fmep.components {
            let t: f64 = p
                .joints
                .iter()
                .filter(|l| l.joint == c.joint)
                .map(|l| l.friction_torque_nm)
                .sum();
            assert!(close(c.kpa, r.fmep.kpa(t)), "{}: {}", r.rig, c.joint);
        }
    }
}

/// Compare `got` with the captured `want` at `path`; differences are pushed to `diffs`.
/// `energy_scale` is the motor work of the run, the scale of its energy terms.
fn compare(path: &str, got: &Value, want: &Value, energy_scale: f64, diffs: &mut Vec<String>) {
    match (got, want) {
        (Value::Object(g), Value::Object(w)) => {
            let scale = match w.get("motor_work_j").and_then(Value::as_f64) {
                Some(m) => m.abs().max(1.0),
                None => energy_scale,
            };
            for (k, wv) in w {
                match g.get(k) {
                    Some(gv) => compare(&format!("{path}.{k}"), gv, wv, scale, diffs),
                    None => diffs.push(format!("{path}.{k}: missing")),
                }
            }
            for k in g.keys().filter(|k| !w.contains_key(*k)) {
                diffs.push(format!("{path}.{k}: not in the capture"));
            }
        }
        (Value::Array(g), Value::Array(w)) => {
            if g.len() != w.len() {
                diffs.push(format!("{path}: {} entries, captured {}", g.len(), w.len()));
                return;
            }
            for (i, (gv, wv)) in g.iter().zip(w).enumerate() {
                compare(&format!("{path}[{i}]"), gv, wv, energy_scale, diffs);
            }
        }
        (Value::Number(g), Value::Number(w)) if w.is_u64() || w.is_i64() => {
            if g != w {
                diffs.push(format!("{path}: {g}, captured {w}"));
            }
        }
        (g, w) if g.is_number() && w.is_number() => {
            let (g, w) = (
                g.as_f64().unwrap_or(f64::NAN),
                w.as_f64().unwrap_or(f64::NAN),
            );
            let key = path.rsplit('.').next().unwrap_or("");
            let floor = if key.ends_with("_j") || key == "relative_residual" {
                energy_scale
            } else {
                1.0
            };
            let tol = if key == "relative_residual" {
                1e-9
            } else {
                1e-9 * w.abs().max(floor)
            };
            // A NaN on either side is a difference too.
            let within = (g - w).abs() <= tol;
            if !within {
                diffs.push(format!("{path}: {g:e}, captured {w:e} (tolerance {tol:e})"));
            }
        }
        (g, w) => {
            if g != w {
                diffs.push(format!("{path}: {g}, captured {w}"));
            }
        }
    }
}

/// Capture again the cases `spec` names (`<commit>:<case>;<case>...`) into the existing
/// fixture, noting each under `recaptured` with the commit; every other case is kept as it was.
fn recapture(spec: &str, cases: &[Case], registry: &LawRegistry) {
    let (commit, names) = spec.split_once(':').expect("<commit>:<case>[;<case>...]");
    let path = fixture_path();
    let text = std::fs::read_to_string(&path).expect("the captured cases");
    let mut doc: Value = serde_json::from_str(&text).expect("JSON");
    for name in names.split(';') {
        let case = cases
            .iter()
            .find(|c| c.name() == name)
            .unwrap_or_else(|| panic!("no case named {name}"));
        doc["cases"][name] = run_case(case, registry);
        doc["recaptured"][name] = json!(commit);
    }
    let text = serde_json::to_string(&doc).expect("serialise");
    std::fs::write(&path, text + "\n").expect("write the capture");
}

#[test]
fn regression_harness_every_bundled_rig_and_law_set_gives_the_captured_numbers() {
    let registry = registry();
    let cases = cases();
    if let Ok(source) = std::env::var("TRIBO_REGRESSION_CAPTURE") {
        let mut captured = serde_json::Map::new();
        for case in &cases {
            let clock = std::time::Instant::now();
            captured.insert(case.name(), run_case(case, &registry));
            eprintln!("{:.3} s {}", clock.elapsed().as_secs_f64(), case.name());
        }
        let doc = json!({
            "source": source,
            "cycle": CYCLE,
            "oil": OIL,
            "pi_drive": PI,
            "lugre": LUGRE,
            "resolution_deg": RESOLUTION_DEG,
            "cases": captured,
        });
        let path = fixture_path();
        std::fs::create_dir_all(path.parent().expect("a directory")).expect("mkdir");
        let text = serde_json::to_string(&doc).expect("serialise");
        std::fs::write(&path, text + "\n").expect("write the capture");
        return;
    }
    if let Ok(spec) = std::env::var("TRIBO_REGRESSION_RECAPTURE") {
        recapture(&spec, &cases, &registry);
        return;
    }
    let text = std::fs::read_to_string(fixture_path()).expect("the captured cases");
    let doc: Value = serde_json::from_str(&text).expect("JSON");
    let captured = doc["cases"].as_object().expect("cases");
    // A rig or law set bundled after the capture is not covered (capture again to cover it);
    // a captured case that no longer exists is a failure.
    let missing: Vec<String> = captured
        .keys()
        .filter(|k| !cases.iter().any(|c| c.name() == **k))
        .cloned()
        .collect();
    assert!(
        missing.is_empty(),
        "captured cases no longer run: {missing:?}"
    );
    let mut failures = Vec::new();
    for case in &cases {
        let name = case.name();
        let Some(want) = captured.get(&name) else {
            eprintln!("{name}: not in the capture (bundled since), not compared");
            continue;
        };
        // The relative residual's scale changed on purpose (issue 27; `energy_follows` checks
        // it instead): left out of both sides, every other number compared as before.
        let mut want = want.clone();
        if let Some(e) = want.get_mut("energy").and_then(|e| e.as_object_mut()) {
            e.remove("relative_residual");
        }
        let want = &want;
        let got = run_case(case, &registry);
        let mut diffs = Vec::new();
        match (want.get("error"), got.get("error")) {
            (Some(_), Some(_)) => {}
            (Some(w), None) => diffs.push(format!("runs now; captured the error {w}")),
            (None, Some(g)) => diffs.push(format!("fails now: {g}")),
            (None, None) => compare("", &got, want, 1.0, &mut diffs),
        }
        if !diffs.is_empty() {
            let shown: Vec<&String> = diffs.iter().take(5).collect();
            failures.push(format!("{name} ({} differences): {shown:#?}", diffs.len()));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases differ from the capture at {}:\n{}",
        failures.len(),
        cases.len(),
        doc["source"],
        failures.join("\n")
    );
}
