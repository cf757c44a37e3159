//! What a law says about itself, and the checking of user parameters against it.
//!
//! The description is the single source of truth for parameter names, units, defaults and
//! allowed ranges: `tribo laws` prints it, and [`check_params`] enforces it for both ABI paths
//! before a law instance is created.

use serde::Serialize;

/// A law's self-description: identity and parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LawDescription {
    /// Unique law name, as used in rig and law-set files (`coulomb`, `stribeck-duty`).
    pub name: String,
    /// Version of the law's implementation (semver of its crate).
    pub version: String,
    /// One-line summary of what the law models.
    pub summary: String,
    /// Parameters, in the order C plugins receive them.
    pub parameters: Vec<ParamSpec>,
    /// The bearing types the law is made for (`SUITS_*` bits; 0, any joint); listed as words
    /// (`["plain", "rolling", "slide"]`, empty for any).
    #[serde(serialize_with = "suits_words")]
    pub suits: u32,
}

/// `suits` as the list of bearing-type words it names.
fn suits_words<S: serde::Serializer>(suits: &u32, s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(crate::contract::suits_words(*suits))
}

/// The type and default of a parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", content = "default", rename_all = "snake_case")]
pub enum ParamValue {
    /// A real number.
    Number(f64),
    /// A list of real numbers (poly-line points, say); the range applies to each element.
    NumberList(Vec<f64>),
    /// A true/false switch.
    Bool(bool),
    /// One word out of [`ParamSpec::choices`].
    Choice(String),
}

impl ParamValue {
    /// The TOML-style type name, for error messages.
    pub fn type_name(&self) -> &'static str {
        match self {
            Self::Number(_) => "a number",
            Self::NumberList(_) => "a list of numbers",
            Self::Bool(_) => "true or false",
            Self::Choice(_) => "a string",
        }
    }

    /// The default rendered as TOML, for listings.
    pub fn to_toml_string(&self) -> String {
        match self {
            Self::Number(x) => format_number(*x),
            Self::NumberList(v) => {
                let items: Vec<String> = v.iter().map(|x| format_number(*x)).collect();
                format!("[{}]", items.join(", "))
            }
            Self::Bool(b) => b.to_string(),
            Self::Choice(s) => format!("\"{s}\""),
        }
    }
}

fn format_number(x: f64) -> String {
    if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e6) {
        format!("{x:e}")
    } else if x == x.trunc() {
        format!("{x:.1}")
    } else {
        format!("{x}")
    }
}

/// One parameter: name, unit, meaning, default and allowed range.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamSpec {
    /// Key in the parameter TOML table.
    pub name: String,
    /// Unit in plain text (`-` for dimensionless, `N s/m`, `rad/s`).
    pub unit: String,
    /// What the parameter means physically.
    pub doc: String,
    /// Type and default value.
    pub default: ParamValue,
    /// Smallest allowed value (numbers and number lists).
    pub min: f64,
    /// Largest allowed value (numbers and number lists).
    pub max: f64,
    /// Allowed words for a [`ParamValue::Choice`] parameter.
    pub choices: Vec<String>,
}

impl ParamSpec {
    /// A numeric parameter. The default is filled in later from the law's `Default` parameters.
    pub fn number(name: &str, unit: &str, doc: &str, min: f64, max: f64) -> Self {
        Self {
            name: name.into(),
            unit: unit.into(),
            doc: doc.into(),
            default: ParamValue::Number(0.0),
            min,
            max,
            choices: Vec::new(),
        }
    }

    /// A list-of-numbers parameter; `min` and `max` bound each element.
    pub fn number_list(name: &str, unit: &str, doc: &str, min: f64, max: f64) -> Self {
        Self {
            default: ParamValue::NumberList(Vec::new()),
            ..Self::number(name, unit, doc, min, max)
        }
    }

    /// A boolean switch.
    pub fn boolean(name: &str, doc: &str) -> Self {
        Self {
            default: ParamValue::Bool(false),
            ..Self::number(name, "-", doc, f64::NEG_INFINITY, f64::INFINITY)
        }
    }

    /// A word out of `choices`.
    pub fn choice(name: &str, doc: &str, choices: &[&str]) -> Self {
        Self {
            default: ParamValue::Choice(choices.first().copied().unwrap_or_default().into()),
            choices: choices.iter().map(|c| (*c).to_string()).collect(),
            ..Self::number(name, "-", doc, f64::NEG_INFINITY, f64::INFINITY)
        }
    }

    /// The allowed range as text, for messages and listings.
    pub fn range_text(&self) -> String {
        match &self.default {
            ParamValue::Bool(_) => "true or false".into(),
            ParamValue::Choice(_) => format!("one of {}", self.choices.join(", ")),
            _ => format!("[{}, {}]", format_bound(self.min), format_bound(self.max)),
        }
    }
}

fn format_bound(x: f64) -> String {
    if x == f64::INFINITY {
        "inf".into()
    } else if x == f64::NEG_INFINITY {
        "-inf".into()
    } else if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e6) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// A parameter the law cannot accept: names the law, the parameter and what is allowed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("law `{law}`, parameter `{parameter}`: {message}")]
pub struct ParamError {
    /// Law name.
    pub law: String,
    /// Offending parameter (empty when the problem is not tied to one).
    pub parameter: String,
    /// What is wrong and what is allowed.
    pub message: String,
}

impl ParamError {
    /// An error about `parameter`; the law name is filled in by whoever knows it.
    pub fn new(parameter: &str, message: impl Into<String>) -> Self {
        Self {
            law: String::new(),
            parameter: parameter.into(),
            message: message.into(),
        }
    }

    /// An error for a value outside `[min, max]`.
    pub fn out_of_range(parameter: &str, value: f64, min: f64, max: f64) -> Self {
        Self::new(
            parameter,
            format!(
                "value {value} is out of range; allowed [{}, {}]",
                format_bound(min),
                format_bound(max)
            ),
        )
    }

    /// Attach the law name.
    pub fn for_law(mut self, law: &str) -> Self {
        self.law = law.into();
        self
    }
}

/// Check a user's parameter table against a description: every key known, every value of the
/// declared type and inside its range. Returns the table completed with defaults, in
/// declaration order, so the law sees exactly the values that were checked.
pub fn check_params(
    desc: &LawDescription,
    table: &toml::Table,
) -> Result<Vec<(String, ParamValue)>, ParamError> {
    let law = desc.name.as_str();
    for key in table.keys() {
        if !desc.parameters.iter().any(|p| &p.name == key) {
            let known: Vec<&str> = desc.parameters.iter().map(|p| p.name.as_str()).collect();
            let expected = if known.is_empty() {
                "this law takes no parameters".to_string()
            } else {
                format!("expected one of: {}", known.join(", "))
            };
            return Err(
                ParamError::new(key, format!("unknown parameter; {expected}")).for_law(law),
            );
        }
    }
    let mut values = Vec::with_capacity(desc.parameters.len());
    for spec in &desc.parameters {
        let value = match table.get(&spec.name) {
            None => spec.default.clone(),
            Some(v) => convert(spec, v).map_err(|e| e.for_law(law))?,
        };
        check_range(spec, &value).map_err(|e| e.for_law(law))?;
        values.push((spec.name.clone(), value));
    }
    Ok(values)
}

fn as_number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(x) => Some(*x),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

fn convert(spec: &ParamSpec, v: &toml::Value) -> Result<ParamValue, ParamError> {
    let wrong = || {
        ParamError::new(
            &spec.name,
            format!(
                "expected {}, found {} `{}`",
                spec.default.type_name(),
                v.type_str(),
                v
            ),
        )
    };
    Ok(match &spec.default {
        ParamValue::Number(_) => ParamValue::Number(as_number(v).ok_or_else(wrong)?),
        ParamValue::NumberList(_) => {
            let arr = v.as_array().ok_or_else(wrong)?;
            let nums: Option<Vec<f64>> = arr.iter().map(as_number).collect();
            ParamValue::NumberList(nums.ok_or_else(wrong)?)
        }
        ParamValue::Bool(_) => ParamValue::Bool(v.as_bool().ok_or_else(wrong)?),
        ParamValue::Choice(_) => ParamValue::Choice(v.as_str().ok_or_else(wrong)?.to_string()),
    })
}

fn check_range(spec: &ParamSpec, value: &ParamValue) -> Result<(), ParamError> {
    let check = |x: f64| {
        if x.is_finite() && x >= spec.min && x <= spec.max {
            Ok(())
        } else {
            Err(ParamError::out_of_range(&spec.name, x, spec.min, spec.max))
        }
    };
    match value {
        ParamValue::Number(x) => check(*x),
        ParamValue::NumberList(v) => v.iter().try_for_each(|x| check(*x)),
        ParamValue::Bool(_) => Ok(()),
        ParamValue::Choice(c) => {
            if spec.choices.iter().any(|k| k == c) {
                Ok(())
            } else {
                Err(ParamError::new(
                    &spec.name,
                    format!("`{c}` is not allowed; {}", spec.range_text()),
                ))
            }
        }
    }
}

/// Turn checked values back into a TOML table (what a Rust law's serde type deserialises).
pub fn values_to_table(values: &[(String, ParamValue)]) -> toml::Table {
    values
        .iter()
        .map(|(k, v)| {
            let tv = match v {
                ParamValue::Number(x) => toml::Value::Float(*x),
                ParamValue::NumberList(xs) => {
                    toml::Value::Array(xs.iter().map(|x| toml::Value::Float(*x)).collect())
                }
                ParamValue::Bool(b) => toml::Value::Boolean(*b),
                ParamValue::Choice(s) => toml::Value::String(s.clone()),
            };
            (k.clone(), tv)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn desc() -> LawDescription {
        let mut mu = ParamSpec::number("mu", "-", "coefficient", 0.0, 1.0);
        mu.default = ParamValue::Number(0.1);
        let mut pts = ParamSpec::number_list("points", "rad/s", "speeds", 0.0, 2000.0);
        pts.default = ParamValue::NumberList(vec![1.0, 2.0]);
        LawDescription {
            name: "demo".into(),
            version: "0.1.0".into(),
            summary: "demo".into(),
            parameters: vec![mu, pts, ParamSpec::choice("mode", "m", &["smooth", "hard"])],
            suits: 0,
        }
    }

    fn table(text: &str) -> toml::Table {
        text.parse().expect("test TOML is valid")
    }

    #[test]
    fn defaults_fill_missing_values_in_order() {
        let v = check_params(&desc(), &table("")).expect("defaults are valid");
        assert_eq!(v[0], ("mu".into(), ParamValue::Number(0.1)));
        assert_eq!(v[2], ("mode".into(), ParamValue::Choice("smooth".into())));
    }

    #[test]
    fn integers_are_accepted_as_numbers() {
        let v = check_params(&desc(), &table("mu = 1")).expect("1 is in range");
        assert_eq!(v[0].1, ParamValue::Number(1.0));
    }

    #[test]
    fn unknown_key_is_named_with_the_alternatives() {
        let e = check_params(&desc(), &table("muu = 0.2")).unwrap_err();
        assert_eq!(e.parameter, "muu");
        assert_eq!(e.law, "demo");
        assert!(e.message.contains("mu, points, mode"), "{e}");
    }

    #[test]
    fn out_of_range_names_the_range() {
        let e = check_params(&desc(), &table("mu = -0.5")).unwrap_err();
        assert_eq!(e.parameter, "mu");
        assert!(e.to_string().contains("[0, 1]"), "{e}");
        let e = check_params(&desc(), &table("points = [1.0, 5000.0]")).unwrap_err();
        assert_eq!(e.parameter, "points");
    }

    #[test]
    fn wrong_type_and_bad_choice_are_rejected() {
        let e = check_params(&desc(), &table("mu = \"high\"")).unwrap_err();
        assert!(e.message.contains("expected a number"), "{e}");
        let e = check_params(&desc(), &table("mode = \"soft\"")).unwrap_err();
        assert!(e.message.contains("smooth, hard"), "{e}");
    }

    #[test]
    fn nan_is_never_in_range() {
        let e = check_params(&desc(), &table("mu = nan")).unwrap_err();
        assert_eq!(e.parameter, "mu");
    }
}
