//! The trait a Rust law author implements. Nothing here is unsafe or FFI-aware: the
//! [`export_law!`](crate::export_law) macro turns an implementation into a plugin library.

use serde::{de::DeserializeOwned, Serialize};

use crate::contract::{LawInput, LawOutput};
use crate::describe::{
    check_params, values_to_table, LawDescription, ParamError, ParamSpec, ParamValue,
};

/// A friction or damping law.
///
/// The host owns any state (MuJoCo-style): [`Law::evaluate`] is a pure function of the input and
/// the committed state, and [`Law::commit`] advances the state once the host accepts a step. A
/// rejected step is rolled back simply by not committing it.
pub trait Law: Sized + Send + Sync + 'static {
    /// Parameters as a serde type. `Default` gives the defaults `tribo laws` shows.
    type Params: Serialize + DeserializeOwned + Default;

    /// Unique law name used in rig and law-set files.
    const NAME: &'static str;
    /// Implementation version; use `env!("CARGO_PKG_VERSION")`.
    const VERSION: &'static str;
    /// One-line summary.
    const SUMMARY: &'static str;
    /// The bearing types the law is made for, a set of `SUITS_*` bits
    /// ([`SUITS_PLAIN`](crate::SUITS_PLAIN), [`SUITS_ROLLING`](crate::SUITS_ROLLING),
    /// [`SUITS_SLIDE`](crate::SUITS_SLIDE)); 0, the default, suits any joint. The host warns when
    /// a law is put on a joint whose declared bearing type it does not suit.
    const SUITS: u32 = 0;

    /// Every parameter with unit, meaning and allowed range, in the order of `Params`' fields.
    /// Defaults are taken from `Params::default()`, so they are written once.
    fn parameters() -> Vec<ParamSpec>;

    /// Build an instance from checked parameters; reject combinations that are individually in
    /// range but inconsistent (thresholds out of order, say) with a [`ParamError`].
    fn new(params: Self::Params) -> Result<Self, ParamError>;

    /// [`Law::new`] told which parameters the user gave (`given`, their names; the others hold
    /// their defaults). The default ignores `given`; a law overrides it to refuse a parameter
    /// given where another's value leaves it without effect (a parameter given is used or
    /// refused, never ignored).
    fn new_given(params: Self::Params, given: &[&str]) -> Result<Self, ParamError> {
        let _ = given;
        Self::new(params)
    }

    /// Number of `f64` state variables the host must keep for this instance (zero: stateless).
    fn state_size(&self) -> usize {
        0
    }

    /// Friction force or torque for `input`, given the committed `state` (of `state_size()`
    /// values, zero-initialised by the host).
    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput;

    /// Advance `state` over the accepted step described by `input` (its `dt_s` is the step).
    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        let _ = (input, state);
    }

    /// Evaluate `inputs.len()` inputs at once into `outputs` (as long). Input `k` is evaluated
    /// with the state starting at `states[k * state_stride]`, of `state_size()` values;
    /// `state_stride` 0 means every input shares the one state `states`. The host checks the
    /// lengths before calling. The default calls [`Law::evaluate`] for each input; override it
    /// only where a batch is cheaper (shared set-up, vectorised arithmetic), giving the same
    /// outputs to the bit.
    fn evaluate_many(
        &self,
        inputs: &[LawInput],
        states: &[f64],
        state_stride: usize,
        outputs: &mut [LawOutput],
    ) {
        let n = self.state_size();
        for (k, (input, out)) in inputs.iter().zip(outputs.iter_mut()).enumerate() {
            let start = k * state_stride;
            *out = self.evaluate(input, &states[start..start + n]);
        }
    }
}

/// The full description of `L`, with defaults read from `L::Params::default()`.
///
/// # Errors
/// If the defaults cannot be serialised or disagree with the declared parameter list, which is a
/// bug in the law; [`assert_law_is_consistent`] turns it into a failing unit test.
pub fn describe<L: Law>() -> Result<LawDescription, ParamError> {
    let defaults = toml::Table::try_from(L::Params::default()).map_err(|e| {
        ParamError::new("", format!("default parameters do not serialise: {e}")).for_law(L::NAME)
    })?;
    let mut parameters = L::parameters();
    for spec in &mut parameters {
        let value = defaults.get(&spec.name).ok_or_else(|| {
            ParamError::new(
                &spec.name,
                "declared in parameters() but not a field of Params",
            )
            .for_law(L::NAME)
        })?;
        spec.default = match (&spec.default, value) {
            (ParamValue::Number(_), v) => ParamValue::Number(
                v.as_float()
                    .or(v.as_integer().map(|i| i as f64))
                    .ok_or_else(|| {
                        ParamError::new(
                            &spec.name,
                            "declared as a number but Params holds another type",
                        )
                        .for_law(L::NAME)
                    })?,
            ),
            (ParamValue::NumberList(_), toml::Value::Array(a)) => ParamValue::NumberList(
                a.iter()
                    .filter_map(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
                    .collect(),
            ),
            (ParamValue::Bool(_), toml::Value::Boolean(b)) => ParamValue::Bool(*b),
            (ParamValue::Choice(_), toml::Value::String(s)) => ParamValue::Choice(s.clone()),
            _ => {
                return Err(
                    ParamError::new(&spec.name, "declared type does not match Params")
                        .for_law(L::NAME),
                )
            }
        };
    }
    for key in defaults.keys() {
        if !parameters.iter().any(|p| &p.name == key) {
            return Err(
                ParamError::new(key, "field of Params missing from parameters()").for_law(L::NAME),
            );
        }
    }
    Ok(LawDescription {
        name: L::NAME.into(),
        version: L::VERSION.into(),
        summary: L::SUMMARY.into(),
        parameters,
        suits: L::SUITS,
    })
}

/// Create an instance of `L` from user TOML: check names, types and ranges against the
/// description, deserialise into `L::Params` (missing keys at their defaults), then let the law
/// check consistency, told which keys the table gave ([`Law::new_given`]).
pub fn create_from_table<L: Law>(table: &toml::Table) -> Result<L, ParamError> {
    let desc = describe::<L>()?;
    let values = check_params(&desc, table)?;
    let params: L::Params = values_to_table(&values)
        .try_into()
        .map_err(|e: toml::de::Error| {
            ParamError::new("", e.message().to_string()).for_law(L::NAME)
        })?;
    let given: Vec<&str> = table.keys().map(String::as_str).collect();
    L::new_given(params, &given).map_err(|e| e.for_law(L::NAME))
}

/// For a law's unit tests: the declared parameters and `Params` agree, and the defaults are
/// accepted by the law's own checks.
///
/// # Panics
/// With the inconsistency, so the test fails with a readable message.
pub fn assert_law_is_consistent<L: Law>() {
    let desc = match describe::<L>() {
        Ok(d) => d,
        Err(e) => panic!("{e}"),
    };
    assert!(!desc.name.is_empty(), "law name is empty");
    assert!(
        !desc.summary.is_empty(),
        "law `{}` has no summary",
        desc.name
    );
    for p in &desc.parameters {
        assert!(
            !p.unit.is_empty(),
            "parameter `{}` has no unit (use \"-\")",
            p.name
        );
        assert!(
            !p.doc.is_empty(),
            "parameter `{}` is not documented",
            p.name
        );
    }
    if let Err(e) = create_from_table::<L>(&toml::Table::new()) {
        panic!("the default parameters are rejected: {e}");
    }
}
