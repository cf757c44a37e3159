//! Conformance checks for a law library (feature `conformance`): what `tribo check-law` runs,
//! as a library function, so a Rust plugin's `cargo test` can run the same checks in one line
//! ([`assert_law_conforms`]).
//!
//! The checks work on a [`LawLibrary`], so Rust, C, C++ and Fortran laws are checked by the
//! same code. Each check gives a [`CheckResult`] (pass, fail or skip, with the first input that
//! failed), collected in a [`Report`]; nothing here panics on a misbehaving law, except the
//! `assert_*` helpers, which panic with the report on purpose.
//!
//! The sweep covers what the solver can hand a law on the bundled rig
//! (`rigs/crf250r-motored.toml`): relative velocity of both signs through zero
//! (1e-6 to 1000 rad/s on a revolute joint, 1e-6 to 30 m/s on a slide), normal loads 0 to 50 kN,
//! oil from 20 to 150 C (40, 80 and 110 C the working range, 20 and 150 C its cold and hot
//! edges: about 0.25 to 0.005 Pa s) with the rig oil's viscosity (ASTM D341 through 115 cSt at 40 C and
//! 17.5 cSt at 100 C, 860 kg/m^3), the main-bearing, small-end and piston contact geometries, two
//! engine speeds and both a zero (steady-state quadrature) and a transient time step.

use std::fmt::{self, Write as _};
use std::panic::{catch_unwind, AssertUnwindSafe};

use serde::Serialize;

use crate::contract::{JointKind, LawInput, LawOutput, CONTRACT_VERSION};
use crate::describe::{ParamSpec, ParamValue};
use crate::law::Law;
use crate::loader::{LawError, LawInstance, LawLibrary};

/// One conformance check. The names (`as_str`) are stable: scripts and tests match on them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Check {
    /// Contract version, name, version, summary and every parameter's unit, doc and range.
    Description,
    /// Every default lies in its declared range and the law creates from defaults alone.
    Defaults,
    /// The law creates with the parameters under test (the user's `--params`, else defaults).
    Create,
    /// Each numeric parameter at either bound, and each choice, is accepted (or refused by the
    /// law's own combination check, never a panic) and then evaluates to finite outputs.
    ParameterRange,
    /// Values outside a parameter's range (below, above, NaN, an unknown choice) are refused.
    OutOfRangeRefused,
    /// `evaluate` and `commit` return no error (panic, error code, undefined regime) on the sweep.
    NoErrors,
    /// Force and every flagged optional output are finite over the sweep.
    Finite,
    /// Every flagged diagnostic makes physical sense over the sweep: a film and a peak
    /// pressure `>= 0`, an eccentricity ratio of magnitude `< 1`, an asperity share in `[0, 1]`.
    Diagnostics,
    /// `force * relative_velocity <= 1e-9` over the sweep (stateless laws, and a stateful law
    /// from rest and in steady sliding), unless the law is declared active.
    Dissipative,
    /// A reported `dforce_dvelocity` agrees with central finite differences.
    Derivative,
    /// A reported `dforce_dload` agrees with central finite differences in the normal load; an
    /// output marked affine in the load is so at far loads and with the load turned.
    LoadDerivative,
    /// `evaluate` twice on one state gives bit-identical outputs and leaves the state unchanged.
    PureEvaluate,
    /// `commit` (stateful laws) is deterministic, keeps the state finite and bounded, changes
    /// it while sliding, and the force in steady sliding is finite.
    Commit,
    /// Instances on several threads at once give the same outputs as one instance alone.
    ThreadSafety,
    /// `evaluate_many` over batches of the sweep (one shared state, and a state per input at a
    /// stride) gives bit for bit what `evaluate` gives input by input.
    EvaluateMany,
}

impl Check {
    /// Every check, in the order they run and are reported.
    pub const ALL: [Check; 15] = [
        Check::Description,
        Check::Defaults,
        Check::Create,
        Check::ParameterRange,
        Check::OutOfRangeRefused,
        Check::NoErrors,
        Check::Finite,
        Check::Diagnostics,
        Check::Dissipative,
        Check::Derivative,
        Check::LoadDerivative,
        Check::PureEvaluate,
        Check::Commit,
        Check::ThreadSafety,
        Check::EvaluateMany,
    ];

    /// The check's stable name, as printed by `tribo check-law`.
    pub fn as_str(self) -> &'static str {
        match self {
            Check::Description => "description",
            Check::Defaults => "defaults",
            Check::Create => "create",
            Check::ParameterRange => "parameter-range",
            Check::OutOfRangeRefused => "out-of-range-refused",
            Check::NoErrors => "no-errors",
            Check::Finite => "finite",
            Check::Diagnostics => "diagnostics",
            Check::Dissipative => "dissipative",
            Check::Derivative => "derivative",
            Check::LoadDerivative => "load-derivative",
            Check::PureEvaluate => "pure-evaluate",
            Check::Commit => "commit",
            Check::ThreadSafety => "thread-safety",
            Check::EvaluateMany => "evaluate-many",
        }
    }
}

impl fmt::Display for Check {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How a check ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// The law met the check everywhere it was tried.
    Pass,
    /// The law failed the check; the detail names the input.
    Fail,
    /// The check did not apply (no derivative reported, a stateless law's commit) or could not
    /// run (no instance could be created); the detail says which.
    Skip,
}

impl Status {
    /// `pass`, `FAIL` or `skip`, as printed in the table.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Pass => "pass",
            Status::Fail => "FAIL",
            Status::Skip => "skip",
        }
    }
}

/// The outcome of one check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckResult {
    /// Which check.
    pub check: Check,
    /// Pass, fail or skip.
    pub status: Status,
    /// What was tried, or the first input that failed and how many more did.
    pub detail: String,
}

/// Every check's outcome for one law.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// Law name.
    pub law: String,
    /// Law version.
    pub version: String,
    /// Library file (or `<in-process NAME>`).
    pub path: String,
    /// ABI the law was loaded through.
    pub abi: String,
    /// The contract version the library was built against (an older one is adapted by the
    /// host, and the checks run through that adaptation).
    pub contract_version: u32,
    /// The results, in [`Check::ALL`] order.
    pub checks: Vec<CheckResult>,
}

impl Report {
    /// True when no check failed.
    pub fn passed(&self) -> bool {
        self.checks.iter().all(|c| c.status != Status::Fail)
    }

    /// The checks that failed, in order.
    pub fn failed(&self) -> Vec<Check> {
        self.checks
            .iter()
            .filter(|c| c.status == Status::Fail)
            .map(|c| c.check)
            .collect()
    }

    /// The result of `check`.
    pub fn get(&self, check: Check) -> Option<&CheckResult> {
        self.checks.iter().find(|c| c.check == check)
    }

    /// The report as a table: one line per check (name, result, detail) and a last line
    /// naming the failed checks, if any.
    pub fn to_table(&self) -> String {
        let mut s = String::new();
        // Writing to a String cannot fail.
        let _ = writeln!(
            s,
            "law `{}` {} ({}, {}), contract version {}{}",
            self.law,
            self.version,
            self.abi,
            self.path,
            self.contract_version,
            if self.contract_version == CONTRACT_VERSION {
                String::new()
            } else {
                format!(" (adapted to {CONTRACT_VERSION})")
            }
        );
        let _ = writeln!(s, "{:<22} {:<6} detail", "check", "result");
        for c in &self.checks {
            let _ = writeln!(
                s,
                "{:<22} {:<6} {}",
                c.check.as_str(),
                c.status.as_str(),
                c.detail
            );
        }
        let failed = self.failed();
        if failed.is_empty() {
            let _ = writeln!(s, "all checks passed");
        } else {
            let names: Vec<&str> = failed.iter().map(|c| c.as_str()).collect();
            let _ = writeln!(
                s,
                "{} check{} failed: {}",
                failed.len(),
                if failed.len() == 1 { "" } else { "s" },
                names.join(", ")
            );
        }
        s
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.to_table())
    }
}

/// What to check a law with.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Parameters for the sweep (missing keys take their defaults).
    pub params: toml::Table,
    /// The law is active on purpose (it may feed energy in, a motor model say) and this is
    /// why; the dissipation check is then skipped with this reason. The contract has no field
    /// for it, so whoever runs the check declares it.
    pub active: Option<String>,
}

/// Tolerance of the dissipation check: the largest power a law may feed in, W (or N m rad/s).
pub const DISSIPATION_TOL: f64 = 1e-9;
/// Relative tolerance of the derivative checks against central finite differences.
pub const DERIVATIVE_RTOL: f64 = 1e-5;
/// Inputs per batch of the `evaluate-many` check (odd, so no law can rely on a power of two).
pub const BATCH: usize = 97;
/// The largest magnitude a state variable may reach in the commit check before the state is
/// called unbounded.
pub const STATE_BOUND: f64 = 1e12;

/// Run every check on `lib` with the given parameters (missing keys take their defaults).
pub fn check_law(lib: &LawLibrary, params: &toml::Table) -> Report {
    check_with(
        lib,
        &Options {
            params: params.clone(),
            active: None,
        },
    )
}

/// Run every check on `lib` with `options`.
pub fn check_with(lib: &LawLibrary, options: &Options) -> Report {
    let mut results = Vec::new();
    let desc = lib.description();
    results.push(check_description(lib));
    results.push(check_defaults(lib));
    let instance = guarded(|| lib.create(&options.params));
    let instance = match instance {
        Ok(Ok(inst)) => {
            results.push(pass(
                Check::Create,
                if options.params.is_empty() {
                    "created with the defaults".to_string()
                } else {
                    format!(
                        "created with {} given parameter{}",
                        options.params.len(),
                        if options.params.len() == 1 { "" } else { "s" }
                    )
                },
            ));
            Some(inst)
        }
        Ok(Err(e)) => {
            results.push(fail(Check::Create, e.to_string()));
            None
        }
        Err(panic) => {
            results.push(fail(Check::Create, format!("create panicked: {panic}")));
            None
        }
    };
    results.push(check_parameter_range(lib, &options.params));
    results.push(check_out_of_range(lib, &options.params));
    match instance {
        Some(inst) => results.extend(check_instance(lib, &inst, options)),
        None => {
            for check in &Check::ALL[5..] {
                results.push(skip(
                    *check,
                    "no instance: the law could not be created (see `create`)",
                ));
            }
        }
    }
    Report {
        law: desc.name.clone(),
        version: desc.version.clone(),
        path: lib.path().display().to_string(),
        abi: lib.abi().to_string(),
        contract_version: lib.contract_version(),
        checks: results,
    }
}

/// Run every check on `lib` and panic with the report if one fails: the one line a law's
/// `cargo test` needs (see [`assert_law_conforms`] for a Rust law linked into the test).
///
/// # Panics
/// With the whole report when a check fails.
pub fn assert_conforms(lib: &LawLibrary, params: &toml::Table) {
    let report = check_law(lib, params);
    assert!(report.passed(), "law does not conform:\n{report}");
}

/// Check Rust law `L`, linked into the test, with its default parameters.
///
/// ```ignore
/// #[test]
/// fn conforms() {
///     tribo_plugin_api::conformance::assert_law_conforms::<MyLaw>();
/// }
/// ```
///
/// # Panics
/// With the report when a check fails, or when `L` cannot describe itself.
pub fn assert_law_conforms<L: Law>() {
    assert_law_conforms_with::<L>("");
}

/// Check Rust law `L`, linked into the test, with parameters given as TOML text.
///
/// # Panics
/// With the report when a check fails; when the text is not TOML or `L` cannot describe itself.
pub fn assert_law_conforms_with<L: Law>(params: &str) {
    let lib = match LawLibrary::in_process::<L>() {
        Ok(lib) => lib,
        Err(e) => panic!("law `{}` cannot describe itself: {e}", L::NAME),
    };
    let table: toml::Table = match params.parse() {
        Ok(t) => t,
        Err(e) => panic!("the test's parameters are not TOML: {e}"),
    };
    assert_conforms(&lib, &table);
}

fn pass(check: Check, detail: impl Into<String>) -> CheckResult {
    CheckResult {
        check,
        status: Status::Pass,
        detail: detail.into(),
    }
}

fn fail(check: Check, detail: impl Into<String>) -> CheckResult {
    CheckResult {
        check,
        status: Status::Fail,
        detail: detail.into(),
    }
}

fn skip(check: Check, detail: impl Into<String>) -> CheckResult {
    CheckResult {
        check,
        status: Status::Skip,
        detail: detail.into(),
    }
}

/// Run `f`, turning a panic (of a law linked in-process; plugin panics are caught on the
/// plugin side already) into its message.
fn guarded<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| {
        p.downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| p.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic without a message".into())
    })
}

/// Failures of one check over many inputs: the first is shown, the rest counted.
#[derive(Default)]
struct Findings {
    first: Option<String>,
    count: usize,
    tried: usize,
}

impl Findings {
    fn tried(&mut self) {
        self.tried += 1;
    }

    fn found(&mut self, what: impl FnOnce() -> String) {
        if self.first.is_none() {
            self.first = Some(what());
        }
        self.count += 1;
    }

    fn result(self, check: Check, passed: impl Into<String>) -> CheckResult {
        match self.first {
            None => pass(check, passed),
            Some(first) if self.count == 1 => fail(check, first),
            Some(first) => fail(
                check,
                format!(
                    "{first} (and {} more of {} tried)",
                    self.count - 1,
                    self.tried
                ),
            ),
        }
    }
}

fn check_description(lib: &LawLibrary) -> CheckResult {
    let d = lib.description();
    let mut problems = Vec::new();
    let valid_name = d
        .name
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_lowercase())
        && d.name
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-');
    if !valid_name {
        problems.push(format!(
            "name `{}` is not lower-case letters, digits and `-` starting with a letter",
            d.name
        ));
    }
    if d.version.trim().is_empty() {
        problems.push("version is empty".into());
    }
    if d.summary.trim().is_empty() {
        problems.push("summary is empty".into());
    } else if d.summary.contains('\n') {
        problems.push("summary is more than one line".into());
    }
    for (i, p) in d.parameters.iter().enumerate() {
        if p.name.trim().is_empty() {
            problems.push(format!("parameter {i} has no name"));
        }
        if d.parameters[..i].iter().any(|q| q.name == p.name) {
            problems.push(format!("parameter `{}` is declared twice", p.name));
        }
        if p.unit.trim().is_empty() {
            problems.push(format!("parameter `{}` has no unit (use \"-\")", p.name));
        }
        if p.doc.trim().is_empty() {
            problems.push(format!("parameter `{}` is not documented", p.name));
        }
        match &p.default {
            ParamValue::Number(_) | ParamValue::NumberList(_)
                if p.min.is_nan() || p.max.is_nan() || p.min > p.max =>
            {
                problems.push(format!(
                    "parameter `{}`: range {} is empty",
                    p.name,
                    p.range_text()
                ));
            }
            ParamValue::Choice(_) if p.choices.is_empty() => {
                problems.push(format!("parameter `{}` offers no choices", p.name));
            }
            _ => {}
        }
    }
    if problems.is_empty() {
        pass(
            Check::Description,
            format!(
                "contract version {}, {} parameter{}",
                lib.contract_version(),
                d.parameters.len(),
                if d.parameters.len() == 1 { "" } else { "s" }
            ),
        )
    } else {
        fail(Check::Description, problems.join("; "))
    }
}

/// Whether `value` lies in the range of `spec` (numbers and each element of a list).
fn in_range(spec: &ParamSpec, value: &ParamValue) -> bool {
    let ok = |x: f64| x.is_finite() && x >= spec.min && x <= spec.max;
    match value {
        ParamValue::Number(x) => ok(*x),
        ParamValue::NumberList(v) => v.iter().all(|x| ok(*x)),
        ParamValue::Bool(_) => true,
        ParamValue::Choice(c) => spec.choices.iter().any(|k| k == c),
    }
}

fn check_defaults(lib: &LawLibrary) -> CheckResult {
    let d = lib.description();
    let outside: Vec<String> = d
        .parameters
        .iter()
        .filter(|p| !in_range(p, &p.default))
        .map(|p| {
            format!(
                "default {} of `{}` is outside its range {}",
                p.default.to_toml_string(),
                p.name,
                p.range_text()
            )
        })
        .collect();
    if !outside.is_empty() {
        return fail(Check::Defaults, outside.join("; "));
    }
    match guarded(|| lib.create(&toml::Table::new())) {
        Ok(Ok(_)) => pass(
            Check::Defaults,
            "every default in range; created from defaults alone",
        ),
        Ok(Err(e)) => fail(Check::Defaults, format!("the defaults are refused: {e}")),
        Err(panic) => fail(
            Check::Defaults,
            format!("create panicked with the defaults: {panic}"),
        ),
    }
}

/// A few ordinary inputs (both joint kinds, both directions, a moderate load, warm oil), for
/// checking an instance made with unusual parameters.
fn probe_inputs() -> Vec<LawInput> {
    let mut v = Vec::new();
    for g in GEOMETRIES {
        for &vel in &[-1.0, 1.0] {
            v.push(sweep_input(g, vel, 1000.0, 80.0, 314.16, 2e-5));
        }
    }
    v
}

fn check_parameter_range(lib: &LawLibrary, base: &toml::Table) -> CheckResult {
    let d = lib.description();
    let mut findings = Findings::default();
    let mut refused = Vec::new();
    let mut tries: Vec<(String, toml::Value)> = Vec::new();
    for p in &d.parameters {
        match &p.default {
            ParamValue::Number(_) => {
                for bound in [p.min, p.max] {
                    if bound.is_finite() {
                        tries.push((p.name.clone(), toml::Value::Float(bound)));
                    }
                }
            }
            ParamValue::Choice(_) => {
                for c in &p.choices {
                    tries.push((p.name.clone(), toml::Value::String(c.clone())));
                }
            }
            ParamValue::Bool(_) => {
                for b in [false, true] {
                    tries.push((p.name.clone(), toml::Value::Boolean(b)));
                }
            }
            // A list's length may have to match another parameter; its elements' range is
            // covered by out-of-range-refused.
            ParamValue::NumberList(_) => {}
        }
    }
    for (name, value) in &tries {
        findings.tried();
        let mut table = base.clone();
        table.insert(name.clone(), value.clone());
        let what = format!("{name} = {value}");
        match guarded(|| lib.create(&table)) {
            Err(panic) => findings.found(|| format!("{what}: create panicked: {panic}")),
            Ok(Err(e)) if is_panic(&e) => findings.found(|| format!("{what}: {e}")),
            Ok(Err(_)) => refused.push(what),
            Ok(Ok(inst)) => {
                let state = match inst.new_state() {
                    Ok(s) => s,
                    Err(e) => {
                        findings.found(|| format!("{what}: {e}"));
                        continue;
                    }
                };
                for input in probe_inputs() {
                    match guarded(|| inst.evaluate(&input, &state)) {
                        Ok(Ok(out)) if all_finite(&out) => {}
                        Ok(Ok(out)) => {
                            findings.found(|| {
                                format!(
                                    "{what}: non-finite output {} at {}",
                                    describe_output(&out),
                                    describe_input(&input)
                                )
                            });
                            break;
                        }
                        Ok(Err(e)) => {
                            findings.found(|| format!("{what}: {e} at {}", describe_input(&input)));
                            break;
                        }
                        Err(panic) => {
                            findings.found(|| {
                                format!(
                                    "{what}: evaluate panicked: {panic} at {}",
                                    describe_input(&input)
                                )
                            });
                            break;
                        }
                    }
                }
            }
        }
    }
    let mut ok = format!(
        "{} bound and choice value{} tried",
        tries.len(),
        if tries.len() == 1 { "" } else { "s" }
    );
    if !refused.is_empty() {
        let _ = write!(
            ok,
            "; refused by the law's own combination check (allowed): {}",
            refused.join(", ")
        );
    }
    findings.result(Check::ParameterRange, ok)
}

/// A law error that is a panic (Rust plugins catch theirs and report them this way).
fn is_panic(e: &LawError) -> bool {
    matches!(e, LawError::LawFailed { message, .. } if message.starts_with("panicked"))
}

fn check_out_of_range(lib: &LawLibrary, base: &toml::Table) -> CheckResult {
    let d = lib.description();
    let mut tries: Vec<(String, toml::Value)> = Vec::new();
    for p in &d.parameters {
        let below = p.min - p.min.abs().max(1.0);
        let above = p.max + p.max.abs().max(1.0);
        match &p.default {
            ParamValue::Number(_) => {
                for x in [below, above] {
                    if x.is_finite() {
                        tries.push((p.name.clone(), toml::Value::Float(x)));
                    }
                }
                tries.push((p.name.clone(), toml::Value::Float(f64::NAN)));
            }
            ParamValue::NumberList(def) => {
                for x in [below, above, f64::NAN] {
                    if x.is_finite() || x.is_nan() {
                        let mut list: Vec<toml::Value> =
                            def.iter().map(|v| toml::Value::Float(*v)).collect();
                        match list.first_mut() {
                            Some(first) => *first = toml::Value::Float(x),
                            None => list.push(toml::Value::Float(x)),
                        }
                        tries.push((p.name.clone(), toml::Value::Array(list)));
                    }
                }
            }
            ParamValue::Choice(_) => tries.push((
                p.name.clone(),
                toml::Value::String("not-a-declared-choice".into()),
            )),
            ParamValue::Bool(_) => {}
        }
    }
    let mut findings = Findings::default();
    for (name, value) in &tries {
        findings.tried();
        let mut table = base.clone();
        table.insert(name.clone(), value.clone());
        match guarded(|| lib.create(&table)) {
            Ok(Err(e)) if !is_panic(&e) => {}
            Ok(Err(e)) => findings.found(|| format!("{name} = {value}: {e}")),
            Ok(Ok(_)) => findings.found(|| format!("{name} = {value} was accepted")),
            Err(panic) => findings.found(|| format!("{name} = {value}: create panicked: {panic}")),
        }
    }
    findings.result(
        Check::OutOfRangeRefused,
        format!(
            "{} out-of-range value{} refused",
            tries.len(),
            if tries.len() == 1 { "" } else { "s" }
        ),
    )
}

/// A contact of the bundled rig: joint kind, contact radius and length.
#[derive(Clone, Copy)]
struct Geometry {
    kind: JointKind,
    radius_m: f64,
    length_m: f64,
}

/// Main bearing, small end (revolute) and piston (prismatic) of `rigs/crf250r-motored.toml`.
const GEOMETRIES: [Geometry; 3] = [
    Geometry {
        kind: JointKind::Revolute,
        radius_m: 0.020,
        length_m: 0.015,
    },
    Geometry {
        kind: JointKind::Revolute,
        radius_m: 0.008,
        length_m: 0.015,
    },
    Geometry {
        kind: JointKind::Prismatic,
        radius_m: 0.0384,
        length_m: 0.030,
    },
];

/// Dynamic viscosity of the bundled rig's oil at `t_c`, Pa s: ASTM D341 (Walther) through
/// 115 cSt at 40 C and 17.5 cSt at 100 C, density 860 kg/m^3 (`rigs/crf250r-motored.toml`).
pub fn rig_oil_viscosity_pa_s(t_c: f64) -> f64 {
    crate::tribology::WaltherLine::through_40_100(115.0, 17.5).kinematic_cst(t_c) * 1e-6 * 860.0
}

fn sweep_input(g: Geometry, v: f64, load: f64, t_c: f64, engine: f64, dt: f64) -> LawInput {
    let mut i = LawInput::at_rest(g.kind);
    i.contact_radius_m = g.radius_m;
    i.contact_length_m = g.length_m;
    i.normal_load_n = load;
    // Body A (the crank, the piston) is the inner member of all three contacts; body B is at
    // rest, so body A moves at the relative velocity (`with_velocity`).
    match g.kind {
        JointKind::Revolute => {
            i.reaction_x_n = load;
            i.load_on_inner_x_n = load;
            i.body_a_angle = 1.0;
        }
        JointKind::Prismatic => {
            i.reaction_y_n = load;
            i.load_on_inner_y_n = load;
            i.body_a_angle = 0.02;
            i.bearing_type = crate::contract::BearingType::Slide as u32;
        }
    }
    i.oil_temp_c = t_c;
    i.viscosity_pa_s = rig_oil_viscosity_pa_s(t_c);
    i.engine_speed_rad_s = engine;
    i.crank_angle_rad = 1.0;
    i.time_s = 0.5;
    i.dt_s = dt;
    i.with_velocity(v)
}

/// Relative velocities of the sweep: both signs through zero, rad/s on a revolute joint (up to
/// about 9000 rpm), m/s on a slide (up to 30 m/s).
fn velocities(kind: JointKind) -> Vec<f64> {
    let mags: &[f64] = match kind {
        JointKind::Revolute => &[1e-6, 1e-3, 0.1, 3.0, 100.0, 1000.0],
        JointKind::Prismatic => &[1e-6, 1e-3, 0.1, 3.0, 30.0],
    };
    let mut v = vec![0.0];
    for &m in mags {
        v.push(m);
        v.push(-m);
    }
    v
}

/// The sweep: velocity x load x oil temperature x geometry x engine speed x time step.
fn sweep() -> Vec<LawInput> {
    let mut out = Vec::new();
    for g in GEOMETRIES {
        for v in velocities(g.kind) {
            for &load in &[0.0, 10.0, 1000.0, 50_000.0] {
                for &t in &[20.0, 40.0, 80.0, 110.0, 150.0] {
                    for &engine in &[314.16, 942.48] {
                        for &dt in &[0.0, 2e-5] {
                            out.push(sweep_input(g, v, load, t, engine, dt));
                        }
                    }
                }
            }
        }
    }
    out
}

fn kind_name(kind: Option<JointKind>) -> &'static str {
    match kind {
        Some(JointKind::Revolute) => "revolute",
        Some(JointKind::Prismatic) => "prismatic",
        None => "unknown joint kind",
    }
}

/// An input in words, for a failure's detail.
pub fn describe_input(i: &LawInput) -> String {
    let unit = if i.kind() == Some(JointKind::Revolute) {
        "rad/s"
    } else {
        "m/s"
    };
    format!(
        "{} v={:e} {unit} (sliding {:e} m/s), load {} N, oil {} C ({:.4} Pa s), r {} m, L {} m, engine {} rad/s, dt {} s",
        kind_name(i.kind()),
        i.relative_velocity,
        i.sliding_velocity_m_s,
        i.normal_load_n,
        i.oil_temp_c,
        i.viscosity_pa_s,
        i.contact_radius_m,
        i.contact_length_m,
        i.engine_speed_rad_s,
        i.dt_s
    )
}

fn describe_output(o: &LawOutput) -> String {
    let mut s = format!("F={:e}", o.force);
    if let Some(c) = o.coefficient() {
        let _ = write!(s, " mu={c:e}");
    }
    if let Some(h) = o.duty_parameter() {
        let _ = write!(s, " H={h:e}");
    }
    if let Some(d) = o.derivative() {
        let _ = write!(s, " dF/dv={d:e}");
    }
    if let Some(d) = o.load_derivative() {
        let _ = write!(s, " dF/dN={d:e}");
    }
    if let Some(h) = o.min_film() {
        let _ = write!(s, " h_min={h:e} m");
    }
    if let Some((x, y)) = o.eccentricity() {
        let _ = write!(s, " e=({x:e}, {y:e})");
    }
    if let Some(p) = o.peak_pressure() {
        let _ = write!(s, " p_max={p:e} Pa");
    }
    if let Some(a) = o.asperity_share() {
        let _ = write!(s, " asperity share={a:e}");
    }
    s
}

fn all_finite(o: &LawOutput) -> bool {
    let (ex, ey) = o.eccentricity().unwrap_or((0.0, 0.0));
    o.force.is_finite()
        && ex.is_finite()
        && ey.is_finite()
        && [
            o.coefficient(),
            o.duty_parameter(),
            o.derivative(),
            o.load_derivative(),
            o.min_film(),
            o.peak_pressure(),
            o.asperity_share(),
        ]
        .into_iter()
        .all(|x| x.is_none_or(f64::is_finite))
}

/// An output as the bits of every field, for bit-identical comparison (NaN included).
type OutputBits = [u64; 12];

/// The bits of every field of an output.
fn output_bits(o: &LawOutput) -> OutputBits {
    [
        o.force.to_bits(),
        o.coefficient.to_bits(),
        o.duty_parameter.to_bits(),
        o.dforce_dvelocity.to_bits(),
        u64::from(o.regime),
        u64::from(o.flags),
        o.dforce_dload.to_bits(),
        o.min_film_m.to_bits(),
        o.eccentricity_x.to_bits(),
        o.eccentricity_y.to_bits(),
        o.peak_pressure_pa.to_bits(),
        o.asperity_share.to_bits(),
    ]
}

/// The state's values as bits, read with volatile loads: a foreign `evaluate` that writes
/// through its `const double *` breaks the contract, and the compiler must not assume the
/// slice is unchanged when the check reads it back.
fn state_bits(state: &[f64]) -> Vec<u64> {
    (0..state.len())
        // SAFETY: in bounds of a live slice of f64.
        .map(|k| unsafe { std::ptr::read_volatile(state.as_ptr().add(k)) }.to_bits())
        .collect()
}

/// One guarded evaluation.
fn eval(inst: &LawInstance, input: &LawInput, state: &[f64]) -> Result<LawOutput, String> {
    match guarded(|| inst.evaluate(input, state)) {
        Ok(Ok(out)) => Ok(out),
        Ok(Err(e)) => Err(e.to_string()),
        Err(panic) => Err(format!("evaluate panicked: {panic}")),
    }
}

/// The checks that need an instance: the sweep, purity, derivative, commit, threads.
fn check_instance(lib: &LawLibrary, inst: &LawInstance, options: &Options) -> Vec<CheckResult> {
    let stateful = inst.state_size() > 0;
    let zero = match inst.new_state() {
        Ok(s) => s,
        Err(e) => {
            // The host could not allocate the declared state: an error, and nothing to run.
            return Check::ALL[5..]
                .iter()
                .map(|c| match c {
                    Check::NoErrors => fail(*c, e.to_string()),
                    _ => skip(*c, "no state (see `no-errors`)"),
                })
                .collect();
        }
    };
    let points = sweep();
    let mut errors = Findings::default();
    let mut finite = Findings::default();
    let mut diagnostics = Findings::default();
    let mut dissipative = Findings::default();
    let mut dfdv = DerivativeFindings::default();
    let mut dfdn = DerivativeFindings::default();
    let mut pure = Findings::default();
    let mut reference: Vec<Option<OutputBits>> = Vec::with_capacity(points.len());
    for input in &points {
        errors.tried();
        let state = zero.clone();
        let out = match eval(inst, input, &state) {
            Ok(out) => out,
            Err(e) => {
                errors.found(|| format!("{e} at {}", describe_input(input)));
                reference.push(None);
                continue;
            }
        };
        reference.push(Some(output_bits(&out)));
        // Purity: the state is untouched and a second call gives the same bits.
        pure.tried();
        if state_bits(&state) != state_bits(&zero) {
            pure.found(|| {
                format!(
                    "evaluate changed the state from {:?} to {:?} at {}",
                    zero,
                    state,
                    describe_input(input)
                )
            });
        } else if let Ok(again) = eval(inst, input, &state) {
            if output_bits(&again) != output_bits(&out) {
                pure.found(|| {
                    format!(
                        "two calls on the same state gave {} then {} at {}",
                        describe_output(&out),
                        describe_output(&again),
                        describe_input(input)
                    )
                });
            }
        }
        if out.flags & crate::contract::DIAGNOSTIC_FLAGS != 0 {
            diagnostics.tried();
            if let Some(bad) = out.bad_diagnostic() {
                diagnostics.found(|| format!("{bad} at {}", describe_input(input)));
            }
        }
        finite.tried();
        if !all_finite(&out) {
            finite.found(|| format!("{} at {}", describe_output(&out), describe_input(input)));
            continue;
        }
        dissipative.tried();
        let power = out.force * input.relative_velocity;
        if power > DISSIPATION_TOL {
            dissipative.found(|| {
                format!(
                    "F*v = {power:e} > 0 ({}){} at {}",
                    describe_output(&out),
                    if stateful { " from rest" } else { "" },
                    describe_input(input)
                )
            });
        }
        if let Some(d) = out.derivative() {
            let v = input.relative_velocity;
            let at = |x: f64| eval(inst, &input.with_velocity(x), &zero).map(|o| o.force);
            let verdict = fd_verdict(out.force, d, v, 1e-6 * v.abs().max(1e-3), at);
            dfdv.judge(verdict, "dF/dv", d, input, &mut errors);
        }
        if let Some(d) = out.load_derivative() {
            let n = input.normal_load_n;
            if n > 0.0 {
                let at = |x: f64| eval(inst, &at_load(input, x), &zero).map(|o| o.force);
                let verdict = fd_verdict(out.force, d, n, 1e-6 * n, at);
                dfdn.judge(verdict, "dF/dN", d, input, &mut errors);
            } else {
                dfdn.at_zero_load += 1;
            }
        }
        if out.flags & crate::contract::AFFINE_IN_LOAD != 0 {
            affine_claim(inst, input, &out, &zero, &mut dfdn, &mut errors);
        }
    }
    let mut results = Vec::new();
    let commit = if stateful {
        check_commit(inst, &zero, &mut errors, &mut dissipative, &mut pure)
    } else {
        check_stateless_commit(inst, &points, &mut errors)
    };
    let many = check_many(inst, &points, &reference, &zero);
    results.push(errors.result(
        Check::NoErrors,
        format!("{} inputs evaluated without error", points.len()),
    ));
    results.push(finite.result(
        Check::Finite,
        format!(
            "force and flagged outputs finite at {} inputs",
            points.len()
        ),
    ));
    results.push(if diagnostics.tried == 0 {
        skip(Check::Diagnostics, "the law reports no diagnostics")
    } else {
        let n = diagnostics.tried;
        diagnostics.result(
            Check::Diagnostics,
            format!("film >= 0, |e| < 1, peak pressure >= 0 and asperity share in [0, 1] where reported, at {n} inputs"),
        )
    });
    results.push(match &options.active {
        Some(reason) => skip(Check::Dissipative, format!("declared active: {reason}")),
        None => dissipative.result(
            Check::Dissipative,
            format!(
                "F*v <= {DISSIPATION_TOL:e} at {} inputs{}",
                points.len(),
                if stateful {
                    " from rest, and in steady sliding"
                } else {
                    ""
                }
            ),
        ),
    });
    results.push(dfdv.result(Check::Derivative, "dF/dv", "relative velocity"));
    results.push(dfdn.result(Check::LoadDerivative, "dF/dN", "normal load"));
    results.push(pure.result(
        Check::PureEvaluate,
        "state untouched and outputs bit-identical on a second call",
    ));
    results.push(commit);
    results.push(check_threads(lib, &options.params, &points, &reference));
    results.push(many);
    results
}

/// `input` with normal load `n`, its direction kept: the reaction and the load on the inner
/// member scaled with it (or, from zero, laid along the contact's usual direction).
fn at_load(input: &LawInput, n: f64) -> LawInput {
    let mut i = *input;
    if input.normal_load_n > 0.0 {
        let k = n / input.normal_load_n;
        i.reaction_x_n *= k;
        i.reaction_y_n *= k;
        i.load_on_inner_x_n *= k;
        i.load_on_inner_y_n *= k;
    }
    i.normal_load_n = n;
    i
}

/// An output marked affine in the load (`AFFINE_IN_LOAD`, which the host takes at its word to
/// skip calls) checked at other loads, far ones and the load turned: everything the same but
/// the force, which follows the flagged slope to rounding.
fn affine_claim(
    inst: &LawInstance,
    input: &LawInput,
    out: &LawOutput,
    zero: &[f64],
    dfdn: &mut DerivativeFindings,
    errors: &mut Findings,
) {
    dfdn.affine += 1;
    dfdn.findings.tried();
    let Some(slope) = out.load_slope() else {
        dfdn.findings.found(|| {
            format!(
                "the output is marked affine in the load without a finite slope (dF/dN) at {}",
                describe_input(input)
            )
        });
        return;
    };
    let n = input.normal_load_n;
    let mut others: Vec<LawInput> = [0.0, 0.5 * n, 3.0 * n + 100.0]
        .into_iter()
        .map(|x| at_load(input, x))
        .collect();
    // The same load turned a quarter turn, the moment reversed.
    let mut turned = *input;
    (turned.reaction_x_n, turned.reaction_y_n) = (-input.reaction_y_n, input.reaction_x_n);
    (turned.load_on_inner_x_n, turned.load_on_inner_y_n) =
        (-input.load_on_inner_y_n, input.load_on_inner_x_n);
    turned.reaction_moment_nm = -input.reaction_moment_nm;
    others.push(turned);
    let rest = |o: &LawOutput| {
        let mut r = *o;
        r.force = 0.0;
        output_bits(&r)
    };
    for other in others {
        let got = match eval(inst, &other, zero) {
            Ok(o) => o,
            Err(e) => {
                errors.found(|| format!("{e} at {}", describe_input(&other)));
                continue;
            }
        };
        let expected = out.force + slope * (other.normal_load_n - n);
        let scale = [out.force, got.force, slope * other.normal_load_n, slope * n]
            .iter()
            .fold(f64::MIN_POSITIVE, |m, x| m.max(x.abs()));
        // Not finite counts as off.
        let force_off = (got.force - expected)
            .abs()
            .partial_cmp(&(64.0 * f64::EPSILON * scale))
            .is_none_or(|o| o.is_gt());
        if force_off || rest(&got) != rest(out) {
            dfdn.findings.found(|| {
                format!(
                    "marked affine in the load (slope {slope:e}), but at {} it gives {} where {} and a force of {expected:e} were promised",
                    describe_input(&other),
                    describe_output(&got),
                    describe_output(out)
                )
            });
        }
    }
}

/// One derivative check's findings (dF/dv or dF/dN): judged points and their failures, and
/// the points not judged.
#[derive(Default)]
struct DerivativeFindings {
    findings: Findings,
    /// Inputs where the law reported the derivative.
    reported: usize,
    /// Reported where a kink or a feature narrower than the step lies within the step.
    unresolved: usize,
    /// Reported at zero load, where the load derivative is one-sided (not judged).
    at_zero_load: usize,
    /// Outputs marked affine in the load, whose promise was checked (`affine_claim`).
    affine: usize,
}

impl DerivativeFindings {
    /// Record the verdict on the law's derivative `d` (named `what`) at `input`; a neighbour
    /// that fails to evaluate is an error of the law.
    fn judge(
        &mut self,
        verdict: Result<DerivativeVerdict, String>,
        what: &str,
        d: f64,
        input: &LawInput,
        errors: &mut Findings,
    ) {
        self.reported += 1;
        match verdict {
            Ok(DerivativeVerdict::Agrees) => self.findings.tried(),
            Ok(DerivativeVerdict::Unresolved) => self.unresolved += 1,
            Ok(DerivativeVerdict::Disagrees(fd)) => {
                self.findings.tried();
                self.findings.found(|| {
                    format!(
                        "{what} = {d:e} but finite differences give {fd:e} at {}",
                        describe_input(input)
                    )
                });
            }
            Err(e) => errors.found(|| {
                format!(
                    "{e} (finite-difference neighbour of {})",
                    describe_input(input)
                )
            }),
        }
    }

    fn result(self, check: Check, what: &str, variable: &str) -> CheckResult {
        let reported = self.reported + self.at_zero_load + self.affine;
        if reported == 0 {
            return skip(check, format!("the law reports no {what}"));
        }
        let judged = self.reported - self.unresolved;
        let mut detail = format!(
            "{what} within {DERIVATIVE_RTOL:e} of central differences in the {variable} at {judged} inputs ({} at a kink or a feature narrower than the step, not judged",
            self.unresolved
        );
        if self.at_zero_load > 0 {
            let _ = write!(detail, "; {} at zero load, not judged", self.at_zero_load);
        }
        detail.push(')');
        if self.affine > 0 {
            let _ = write!(
                detail,
                "; marked affine in the load at {} inputs, and so at other loads",
                self.affine
            );
        }
        self.findings.result(check, detail)
    }
}

enum DerivativeVerdict {
    Agrees,
    /// A kink or a feature narrower than the step lies within the step: not judged.
    Unresolved,
    /// The finite-difference estimate the law's value disagrees with.
    Disagrees(f64),
}

/// Compare the law's derivative `d` at `x` (where the force is `f0`) with central differences
/// of step `h` and `h/2` of `force_at`. Points where the one-sided differences disagree (a
/// kink) or the two central ones do (a feature narrower than the step) are not judged.
fn fd_verdict(
    f0: f64,
    d: f64,
    x: f64,
    h: f64,
    force_at: impl Fn(f64) -> Result<f64, String>,
) -> Result<DerivativeVerdict, String> {
    let (fp, fm) = (force_at(x + h)?, force_at(x - h)?);
    let (fp2, fm2) = (force_at(x + 0.5 * h)?, force_at(x - 0.5 * h)?);
    if ![fp, fm, fp2, fm2].iter().all(|x| x.is_finite()) {
        return Ok(DerivativeVerdict::Unresolved);
    }
    let central = (fp - fm) / (2.0 * h);
    let central2 = (fp2 - fm2) / h;
    let (fwd, bwd) = ((fp - f0) / h, (f0 - fm) / h);
    // Rounding of the forces, amplified by the division by the step.
    let noise = 64.0 * f64::EPSILON * [fp, fm, f0].iter().fold(0.0f64, |m, x| m.max(x.abs())) / h;
    let scale = d.abs().max(central2.abs());
    if (fwd - bwd).abs() > 1e-2 * scale + 4.0 * noise
        || (central - central2).abs() > 1e-5 * scale + 4.0 * noise
    {
        return Ok(DerivativeVerdict::Unresolved);
    }
    if (central2 - d).abs() <= DERIVATIVE_RTOL * scale + 4.0 * noise {
        Ok(DerivativeVerdict::Agrees)
    } else {
        Ok(DerivativeVerdict::Disagrees(central2))
    }
}

/// `evaluate_many` against `evaluate`: the sweep in batches of [`BATCH`] sharing the zero
/// state (against `reference`, the one-by-one outputs), then, for a stateful law, a batch with
/// a different state per input (committed along a slide) at a stride one longer than the
/// state, the gaps filled with NaN so a law reading the wrong slice shows.
fn check_many(
    inst: &LawInstance,
    points: &[LawInput],
    reference: &[Option<OutputBits>],
    zero: &[f64],
) -> CheckResult {
    let mut findings = Findings::default();
    let mut outputs = vec![LawOutput::force(0.0); BATCH];
    for (b, batch) in points.chunks(BATCH).enumerate() {
        findings.tried();
        let outputs = &mut outputs[..batch.len()];
        let refs = &reference[b * BATCH..b * BATCH + batch.len()];
        if refs.iter().any(Option::is_none) {
            continue; // an input that fails alone: `no-errors` reports it
        }
        match guarded(|| inst.evaluate_many(batch, zero, 0, outputs)) {
            Ok(Ok(())) => {
                if let Some(k) =
                    (0..batch.len()).find(|&k| refs[k] != Some(output_bits(&outputs[k])))
                {
                    findings.found(|| {
                        format!(
                            "with one shared state, batch input {k} gave {} where evaluate gave F={:e}, at {}",
                            describe_output(&outputs[k]),
                            refs[k].map_or(f64::NAN, |r| f64::from_bits(r[0])),
                            describe_input(&batch[k])
                        )
                    });
                }
            }
            Ok(Err(e)) => findings.found(|| e.to_string()),
            Err(panic) => findings.found(|| format!("evaluate_many panicked: {panic}")),
        }
    }
    let size = zero.len();
    if size > 0 {
        findings.tried();
        let slide = sweep_input(GEOMETRIES[0], 3.0, 1000.0, 80.0, 314.16, COMMIT_DT);
        let batch: Vec<LawInput> = points
            .iter()
            .step_by(points.len() / BATCH)
            .take(BATCH)
            .copied()
            .collect();
        let stride = size + 1;
        let mut states = vec![f64::NAN; stride * batch.len()];
        let mut state = zero.to_vec();
        let mut expected = Vec::with_capacity(batch.len());
        for (k, input) in batch.iter().enumerate() {
            states[k * stride..k * stride + size].copy_from_slice(&state);
            expected.push(eval(inst, input, &state).map(|o| output_bits(&o)));
            if inst.commit(&slide, &mut state).is_err() {
                break; // `commit` and `no-errors` report it
            }
        }
        let outputs = &mut outputs[..batch.len()];
        match guarded(|| inst.evaluate_many(&batch, &states, stride, outputs)) {
            Ok(Ok(())) => {
                if let Some(k) = (0..batch.len())
                    .find(|&k| expected[k].as_ref().ok() != Some(&output_bits(&outputs[k])))
                {
                    findings.found(|| {
                        format!(
                            "with a state per input (stride {stride}), batch input {k} gave {} where evaluate on its state gave {}, at {}",
                            describe_output(&outputs[k]),
                            match &expected[k] {
                                Ok(bits) => format!("F={:e}", f64::from_bits(bits[0])),
                                Err(e) => e.clone(),
                            },
                            describe_input(&batch[k])
                        )
                    });
                }
            }
            Ok(Err(e)) => findings.found(|| e.to_string()),
            Err(panic) => findings.found(|| format!("evaluate_many panicked: {panic}")),
        }
    }
    let how = if inst.evaluates_batches() {
        "the law's own evaluate_many"
    } else {
        "the host's loop (the library has no evaluate_many)"
    };
    findings.result(
        Check::EvaluateMany,
        format!(
            "{} inputs in batches of {BATCH} through {how}{}: bit for bit as evaluate",
            points.len(),
            if size > 0 {
                ", and one batch with a state per input"
            } else {
                ""
            }
        ),
    )
}

/// A stateless law's commit: called with its empty state, it must not fail.
fn check_stateless_commit(
    inst: &LawInstance,
    points: &[LawInput],
    errors: &mut Findings,
) -> CheckResult {
    for input in points.iter().step_by(7) {
        errors.tried();
        let mut empty: [f64; 0] = [];
        match guarded(|| inst.commit(input, &mut empty)) {
            Ok(Ok(())) => {}
            Ok(Err(e)) => errors.found(|| format!("{e} at {}", describe_input(input))),
            Err(panic) => {
                errors.found(|| format!("commit panicked: {panic} at {}", describe_input(input)))
            }
        }
    }
    skip(Check::Commit, "stateless law (state size 0)")
}

/// Steps of the commit check: 0.1 s of sliding at a 20 us step (about 1 degree of crank at
/// 9000 rpm).
const COMMIT_STEPS: usize = 5000;
const COMMIT_DT: f64 = 2e-5;

/// A stateful law's commit: from rest, slide at constant velocity for [`COMMIT_STEPS`] steps.
/// The state must stay finite and within [`STATE_BOUND`], two copies committed alike must stay
/// bit-identical, some step must change the state, and the force in steady sliding must be
/// finite, dissipative and come from a pure evaluate.
fn check_commit(
    inst: &LawInstance,
    zero: &[f64],
    errors: &mut Findings,
    dissipative: &mut Findings,
    pure: &mut Findings,
) -> CheckResult {
    let mut findings = Findings::default();
    let mut changed = false;
    let mut cases = 0usize;
    'cases: for g in GEOMETRIES {
        let vels: &[f64] = match g.kind {
            JointKind::Revolute => &[-300.0, -0.1, 0.1, 300.0],
            JointKind::Prismatic => &[-10.0, -0.01, 0.01, 10.0],
        };
        for &v in vels {
            for &load in &[100.0, 5000.0] {
                cases += 1;
                findings.tried();
                let input = sweep_input(g, v, load, 80.0, 314.16, COMMIT_DT);
                let (mut a, mut b) = (zero.to_vec(), zero.to_vec());
                for step in 0..COMMIT_STEPS {
                    let before = a.clone();
                    for s in [&mut a, &mut b] {
                        match guarded(|| inst.commit(&input, s)) {
                            Ok(Ok(())) => {}
                            Ok(Err(e)) => {
                                errors.found(|| format!("{e} at {}", describe_input(&input)));
                                continue 'cases;
                            }
                            Err(panic) => {
                                errors.found(|| {
                                    format!(
                                        "commit panicked: {panic} at {}",
                                        describe_input(&input)
                                    )
                                });
                                continue 'cases;
                            }
                        }
                    }
                    changed |= state_bits(&a) != state_bits(&before);
                    if state_bits(&a) != state_bits(&b) {
                        findings.found(|| {
                            format!(
                                "two copies of the state committed alike differ after step {}: {a:?} vs {b:?} at {}",
                                step + 1,
                                describe_input(&input)
                            )
                        });
                        continue 'cases;
                    }
                    if let Some(x) = a.iter().find(|x| !x.is_finite() || x.abs() > STATE_BOUND) {
                        findings.found(|| {
                            format!(
                                "state value {x:e} after step {} (bound {STATE_BOUND:e}) at {}",
                                step + 1,
                                describe_input(&input)
                            )
                        });
                        continue 'cases;
                    }
                }
                let out = match eval(inst, &input, &a) {
                    Ok(out) => out,
                    Err(e) => {
                        errors.found(|| {
                            format!("{e} in steady sliding at {}", describe_input(&input))
                        });
                        continue;
                    }
                };
                pure.tried();
                let kept = a.clone();
                let again = eval(inst, &input, &a);
                if state_bits(&a) != state_bits(&kept)
                    || again.map(|o| output_bits(&o)).ok() != Some(output_bits(&out))
                {
                    pure.found(|| {
                        format!(
                            "evaluate on the steady-sliding state {kept:?} is not repeatable or changed it, at {}",
                            describe_input(&input)
                        )
                    });
                }
                if !all_finite(&out) {
                    findings.found(|| {
                        format!(
                            "{} in steady sliding at {}",
                            describe_output(&out),
                            describe_input(&input)
                        )
                    });
                    continue;
                }
                dissipative.tried();
                let power = out.force * input.relative_velocity;
                if power > DISSIPATION_TOL {
                    dissipative.found(|| {
                        format!(
                            "F*v = {power:e} > 0 ({}) in steady sliding at {}",
                            describe_output(&out),
                            describe_input(&input)
                        )
                    });
                }
            }
        }
    }
    if findings.first.is_none() && !changed {
        findings.found(|| {
            format!(
                "the law declares {} state value{} but commit never changed them while sliding",
                zero.len(),
                if zero.len() == 1 { "" } else { "s" }
            )
        });
    }
    findings.result(
        Check::Commit,
        format!(
            "{cases} slides of {COMMIT_STEPS} steps of {COMMIT_DT:e} s from rest: state finite, bounded, deterministic and changing"
        ),
    )
}

/// Four instances, each on its own thread, evaluate the sweep at once; every output must be
/// bit-identical to the first instance's alone.
fn check_threads(
    lib: &LawLibrary,
    params: &toml::Table,
    points: &[LawInput],
    reference: &[Option<OutputBits>],
) -> CheckResult {
    const THREADS: usize = 4;
    let outcomes: Vec<Result<Option<String>, String>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..THREADS)
            .map(|t| {
                scope.spawn(move || -> Result<Option<String>, String> {
                    let inst = match guarded(|| lib.create(params)) {
                        Ok(Ok(i)) => i,
                        Ok(Err(e)) => return Err(e.to_string()),
                        Err(p) => return Err(format!("create panicked: {p}")),
                    };
                    let state = inst.new_state().map_err(|e| e.to_string())?;
                    // Each thread walks the sweep from another starting point, so the
                    // instances are at different inputs at the same time.
                    let n = points.len();
                    for k in 0..n {
                        let i = (k + t * n / THREADS) % n;
                        let Some(expected) = reference[i] else {
                            continue;
                        };
                        let got = eval(&inst, &points[i], &state).map(|o| output_bits(&o));
                        if got.as_ref().ok() != Some(&expected) {
                            return Ok(Some(format!(
                                "thread {t}'s instance gave {} where one instance alone gave F={:e}, at {}",
                                match got {
                                    Ok(bits) => format!("F={:e}", f64::from_bits(bits[0])),
                                    Err(e) => e,
                                },
                                f64::from_bits(expected[0]),
                                describe_input(&points[i])
                            )));
                        }
                    }
                    Ok(None)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join()
                    .unwrap_or_else(|_| Err("a checking thread panicked".into()))
            })
            .collect()
    });
    let mut problems = Vec::new();
    for o in outcomes {
        match o {
            Ok(None) => {}
            Ok(Some(p)) | Err(p) => problems.push(p),
        }
    }
    match problems.first() {
        None => pass(
            Check::ThreadSafety,
            format!(
                "{THREADS} instances on {THREADS} threads matched one instance alone at {} inputs",
                points.len()
            ),
        ),
        Some(first) if problems.len() == 1 => fail(Check::ThreadSafety, first.clone()),
        Some(first) => fail(
            Check::ThreadSafety,
            format!("{first} (and {} more threads)", problems.len() - 1),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rig_oil_viscosity_reproduces_its_two_points() {
        // 115 cSt and 17.5 cSt at 860 kg/m^3.
        assert!((rig_oil_viscosity_pa_s(40.0) - 115e-6 * 860.0).abs() < 1e-9);
        assert!((rig_oil_viscosity_pa_s(100.0) - 17.5e-6 * 860.0).abs() < 1e-9);
        assert!(rig_oil_viscosity_pa_s(110.0) < rig_oil_viscosity_pa_s(80.0));
    }

    #[test]
    fn sweep_covers_both_signs_zero_both_kinds_and_the_load_range() {
        let s = sweep();
        for kind in [JointKind::Revolute, JointKind::Prismatic] {
            let of_kind: Vec<&LawInput> = s.iter().filter(|i| i.kind() == Some(kind)).collect();
            assert!(of_kind.iter().any(|i| i.relative_velocity == 0.0));
            assert!(of_kind.iter().any(|i| i.relative_velocity < 0.0));
            assert!(of_kind.iter().any(|i| i.relative_velocity > 0.0));
            let max_load = of_kind.iter().map(|i| i.normal_load_n).fold(0.0, f64::max);
            assert_eq!(max_load, 50_000.0);
        }
        assert!(s.iter().all(|i| i.viscosity_pa_s > 0.0));
    }
}
