//! The FMU's variables: what `modelDescription.xml` declares and what the FMU's library serves,
//! built once at export from the rig and its laws and shipped in the archive
//! (`resources/interface.toml`), so the description and the running FMU cannot disagree.
//!
//! A variable's value reference is its index in [`Interface::variables`].

use serde::{Deserialize, Serialize};
use tribo_core::model::{LawRef, RigFile, JOINT_NAMES};
use tribo_plugin_api::loader::LawRegistry;
use tribo_plugin_api::{ParamSpec, ParamValue};

use crate::FmuError;

/// How the importer drives the crank: which of crank speed and drive torque is the input (the
/// other is an output).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DriveMode {
    /// The crank turns at the input speed; the torque that takes is an output.
    Speed,
    /// The input torque drives the crank; its speed is an output.
    Torque,
}

/// What a variable stands for, so the FMU's library knows what to do with it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "role", rename_all = "snake_case")]
pub enum Role {
    /// Input: crank speed, rad/s (speed mode).
    CrankSpeedInput,
    /// Input: drive torque on the crank, N m (torque mode).
    DriveTorqueInput,
    /// Input: oil temperature, C.
    OilTemperatureInput,
    /// Output: accumulated crank angle, rad.
    CrankAngle,
    /// Output: crank speed, rad/s (torque mode).
    CrankSpeed,
    /// Output: the drive torque the prescribed speed takes, N m (speed mode).
    DriveTorque,
    /// Output: the drive torque's mean over the last whole cycle, N m (speed mode).
    DriveTorqueCycleMean,
    /// Output: every law's friction torque at the crank, summed, N m.
    FrictionTorque,
    /// Output: every law's dissipated power, summed, W.
    FrictionPower,
    /// Output: energy dissipated by every law since the start, J.
    FrictionEnergy,
    /// Output: the friction torque's mean over the last whole cycle, N m.
    FrictionTorqueCycleMean,
    /// Output: one joint's friction torque at the crank (all its laws), N m.
    JointTorque {
        /// Index into [`Interface::joints`].
        joint: usize,
    },
    /// Output: one joint's dissipated power, W.
    JointPower {
        /// Index into [`Interface::joints`].
        joint: usize,
    },
    /// Output: energy one joint dissipated since the start, J.
    JointEnergy {
        /// Index into [`Interface::joints`].
        joint: usize,
    },
    /// Parameter: the crank speed a torque-driven crank starts turning at, rad/s.
    CrankSpeedStart,
    /// Parameter: a law parameter (one element of a list parameter).
    LawParam {
        /// Index into [`Interface::laws`].
        law: usize,
        /// The parameter's name in the law's description.
        param: String,
        /// For a list parameter, the element (0-based).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        element: Option<usize>,
    },
    /// Parameter: how long the FMU waits for one answer of its worker process, s.
    CallTimeout,
}

/// FMI causality.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Causality {
    /// Set by the importer before or between steps.
    Input,
    /// Computed by the FMU.
    Output,
    /// Set by the importer; tunable ones also between steps.
    Parameter,
}

/// FMI variability.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Variability {
    /// Changes any time.
    Continuous,
    /// A parameter that may change between steps.
    Tunable,
    /// A parameter fixed after initialisation.
    Fixed,
    /// Never changes: its value is its start value.
    Constant,
}

/// A variable's FMI type, with what the type needs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Kind {
    /// fmi2Real.
    Real {
        /// Start value (inputs and parameters).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        start: Option<f64>,
        /// Unit name (declared in the description's unit definitions).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        unit: Option<String>,
        /// Smallest allowed value.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        min: Option<f64>,
        /// Largest allowed value.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        max: Option<f64>,
    },
    /// fmi2Boolean.
    Boolean {
        /// Start value.
        start: bool,
    },
    /// An enumeration (served through fmi2Integer): one word out of `items`, 1-based.
    Enumeration {
        /// Start value (1-based item).
        start: i32,
        /// The type's name in the description's type definitions.
        type_name: String,
        /// The words, in order.
        items: Vec<String>,
    },
}

/// One FMI scalar variable.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Variable {
    /// Structured FMI name (`piston.friction_torque`, `big_end.fedem_friction.mu`).
    pub name: String,
    /// What it is, for the importer's user.
    pub description: String,
    /// Input, output or parameter.
    pub causality: Causality,
    /// How often it may change.
    pub variability: Variability,
    /// Type, start value, unit.
    #[serde(flatten)]
    pub kind: Kind,
    /// What the FMU does with it.
    pub role: Role,
}

/// One law on one joint, as the FMU's parameters address it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LawSlot {
    /// Joint name (`piston`, `main_2`).
    pub joint: String,
    /// Position among the joint's laws.
    pub index: usize,
    /// Law name.
    pub law: String,
    /// The law's library, a file name in the archive's `resources/plugins/`.
    pub library: String,
}

/// Everything the FMU's library needs to know about its variables, and what the description
/// states.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Interface {
    /// The FMU's GUID (also in `modelDescription.xml`; checked at instantiation).
    pub guid: String,
    /// Model name (the rig's).
    pub model_name: String,
    /// One line on what the FMU is.
    pub description: String,
    /// The Tribo version that exported it.
    pub tribo_version: String,
    /// Which of crank speed and drive torque is the input.
    pub drive: DriveMode,
    /// Crank revolutions per cycle: 2 when the gas pressure makes the cycle 4-stroke.
    pub revolutions_per_cycle: u32,
    /// The joints that carry laws, in output order.
    pub joints: Vec<String>,
    /// Every law, joint by joint.
    pub laws: Vec<LawSlot>,
    /// The variables; a value reference is an index.
    pub variables: Vec<Variable>,
}

/// The modelIdentifier: the FMU library's file name in `binaries/linux64/` without `.so`.
pub const MODEL_IDENTIFIER: &str = "tribo_fmu";

/// Default time the FMU waits for one answer of its worker process, s.
pub const DEFAULT_CALL_TIMEOUT_S: f64 = 60.0;

/// The joints of `model` with the laws on each, in report order: the single-cylinder rig's
/// five, or an engine's mains then per cylinder big end, small end and piston (an engine
/// joint without its own list takes its `[joints.*]` table's laws).
pub fn joint_laws(model: &RigFile) -> Vec<(String, Vec<LawRef>)> {
    match &model.engine {
        None => JOINT_NAMES
            .iter()
            .zip(model.joints.named())
            .map(|(name, (_, j))| ((*name).to_string(), j.laws.clone()))
            .collect(),
        Some(e) => model
            .joint_names()
            .into_iter()
            .map(|name| {
                let template = match name.rsplit_once('_').map(|(k, _)| k) {
                    Some("big_end") => model.joints.big_end.laws.clone(),
                    Some("small_end") => model.joints.small_end.laws.clone(),
                    Some("piston") => model.joints.piston.laws.clone(),
                    _ => Vec::new(),
                };
                let laws = e.laws.get(&name).cloned().unwrap_or(template);
                (name, laws)
            })
            .collect(),
    }
}

/// The law list of joint `joint` of `model` to edit: an engine's cylinder joint gets its own
/// list (a copy of its `[joints.*]` table's) so the edit stays on that joint.
pub fn joint_laws_mut<'a>(model: &'a mut RigFile, joint: &str) -> Option<&'a mut Vec<LawRef>> {
    let template = joint_laws(model)
        .into_iter()
        .find(|(name, _)| name == joint)?
        .1;
    match &mut model.engine {
        None => model.joints.get_mut(joint).map(|j| &mut j.laws),
        Some(e) => Some(e.laws.entry(joint.to_string()).or_insert(template)),
    }
}

/// `text` as an FMI identifier: letters, digits and `_`, not starting with a digit.
fn identifier(text: &str) -> String {
    let mut s: String = text
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert(0, '_');
    }
    s
}

/// A law's unit text (`N s/m | N m s/rad`) for a joint: the alternative that fits it (turning
/// joints the one in rad or N m, the piston slide the other), in Modelica's syntax
/// (`N.m.s/rad`); `None` for a dimensionless `-`.
pub fn law_unit(unit: &str, slide: bool) -> Option<String> {
    let turning = |a: &str| a.contains("rad") || a.contains("N m");
    let alternatives: Vec<&str> = unit.split('|').map(str::trim).collect();
    let pick = alternatives
        .iter()
        .find(|a| turning(a) != slide)
        .or(alternatives.first())
        .copied()
        .unwrap_or("");
    let modelica = pick.split_whitespace().collect::<Vec<_>>().join(".");
    (!modelica.is_empty() && modelica != "-").then_some(modelica)
}

/// A Real variable's type.
fn real(start: Option<f64>, unit: &str) -> Kind {
    Kind::Real {
        start,
        unit: Some(unit.to_string()),
        min: None,
        max: None,
    }
}

/// An output variable.
fn output(name: String, description: String, unit: &str, role: Role) -> Variable {
    Variable {
        name,
        description,
        causality: Causality::Output,
        variability: Variability::Continuous,
        kind: real(None, unit),
        role,
    }
}

/// What the interface is built from at export.
pub struct Source<'a> {
    /// The rig with its laws.
    pub model: &'a RigFile,
    /// Where its laws' descriptions come from.
    pub registry: &'a LawRegistry,
    /// Which input drives the crank.
    pub drive: DriveMode,
    /// The Tribo version exporting.
    pub tribo_version: &'a str,
}

impl Interface {
    /// The interface of `src.model`: inputs, outputs per law-bearing joint and in total, every
    /// law parameter as a tunable parameter starting at the rig's value (or the law's default).
    /// The GUID is left empty; the archive fills it in from the content.
    pub fn build(src: &Source) -> Result<Self, FmuError> {
        let model = src.model;
        let (speed0, temp0) = first_plateau(model);
        let mut vars = drive_variables(src.drive, speed0);
        vars.push(Variable {
            name: "oil_temperature".into(),
            description: "oil temperature (sets the viscosity the laws see)".into(),
            causality: Causality::Input,
            variability: Variability::Continuous,
            kind: Kind::Real {
                start: Some(temp0),
                unit: Some("degC".into()),
                min: Some(tribo_core::oil::VALID_RANGE_C.0),
                max: Some(tribo_core::oil::VALID_RANGE_C.1),
            },
            role: Role::OilTemperatureInput,
        });
        vars.extend(total_outputs());
        let mut joints = Vec::new();
        let mut laws = Vec::new();
        let mut params = Vec::new();
        for (joint, refs) in joint_laws(model) {
            if refs.is_empty() {
                continue;
            }
            let j = joints.len();
            joints.push(joint.clone());
            vars.extend(joint_outputs(&joint, j));
            let mut bases: Vec<String> = Vec::new();
            for (index, r) in refs.iter().enumerate() {
                let lib = src.registry.get(&r.law).map_err(|e| FmuError::Law {
                    joint: joint.clone(),
                    law: r.law.clone(),
                    message: e.to_string(),
                })?;
                // The same law twice on a joint: `coulomb`, then `coulomb_2`.
                let base = identifier(&r.law);
                let same = bases.iter().filter(|b| **b == base).count();
                let ident = match same {
                    0 => base.clone(),
                    n => format!("{base}_{}", n + 1),
                };
                bases.push(base);
                let values = tribo_plugin_api::describe::check_params(lib.description(), &r.params)
                    .map_err(|e| FmuError::Law {
                        joint: joint.clone(),
                        law: r.law.clone(),
                        message: e.to_string(),
                    })?;
                let slot = laws.len();
                laws.push(LawSlot {
                    joint: joint.clone(),
                    index,
                    law: r.law.clone(),
                    library: file_name(lib.path()),
                });
                let prefix = format!("{joint}.{ident}");
                let slide = joint.starts_with("piston");
                for spec in &lib.description().parameters {
                    let value = values
                        .iter()
                        .find(|(n, _)| *n == spec.name)
                        .map_or(&spec.default, |(_, v)| v);
                    params.extend(law_params(&prefix, slot, spec, value, &r.law, slide));
                }
            }
        }
        vars.extend(params);
        vars.push(Variable {
            name: "worker.call_timeout".into(),
            description: "longest wait for one answer of the FMU's worker process (a step, a state save); a law that takes longer is stopped and the call fails".into(),
            causality: Causality::Parameter,
            variability: Variability::Fixed,
            kind: Kind::Real {
                start: Some(DEFAULT_CALL_TIMEOUT_S),
                unit: Some("s".into()),
                min: Some(0.0),
                max: None,
            },
            role: Role::CallTimeout,
        });
        let revolutions_per_cycle = if model.gas.four_stroke() { 2 } else { 1 };
        Ok(Self {
            guid: String::new(),
            model_name: model.name.clone(),
            description: format!(
                "Tribo engine friction: rig `{}` with its laws, crank driven by {}",
                model.name,
                match src.drive {
                    DriveMode::Speed => "speed",
                    DriveMode::Torque => "torque",
                }
            ),
            tribo_version: src.tribo_version.to_string(),
            drive: src.drive,
            revolutions_per_cycle,
            joints,
            laws,
            variables: vars,
        })
    }

    /// The variable with value reference `vr`.
    pub fn variable(&self, vr: u32) -> Option<&Variable> {
        self.variables.get(vr as usize)
    }
}

/// The rig's first plateau: its speed (rad/s) and oil temperature (C), the inputs' start values.
fn first_plateau(model: &RigFile) -> (f64, f64) {
    let cycle = tribo_core::cycle::Cycle::new(&model.cycle.segments());
    let speed = cycle.plateaus().first().map_or(0.0, |p| p.omega);
    let temp = match &model.oil.temperature_c {
        tribo_core::model::Temperature::Constant(t) => *t,
        tribo_core::model::Temperature::PerPlateau(v) => v.first().copied().unwrap_or(20.0),
    };
    (speed, temp)
}

/// The drive's input and output pair.
fn drive_variables(drive: DriveMode, speed0: f64) -> Vec<Variable> {
    let speed = |causality, start, role| Variable {
        name: "crank_speed".into(),
        description: "crank speed".into(),
        causality,
        variability: Variability::Continuous,
        kind: real(start, "rad/s"),
        role,
    };
    let torque = |causality, start, role| Variable {
        name: "drive_torque".into(),
        description: "torque the drive applies to the crank (the motoring torque)".into(),
        causality,
        variability: Variability::Continuous,
        kind: real(start, "N.m"),
        role,
    };
    let mean = output(
        "drive_torque_cycle_mean".into(),
        "drive torque averaged over the last whole cycle (a revolution; two for a 4-stroke cycle): the motoring torque"
            .into(),
        "N.m",
        Role::DriveTorqueCycleMean,
    );
    match drive {
        DriveMode::Speed => vec![
            speed(Causality::Input, Some(speed0), Role::CrankSpeedInput),
            torque(Causality::Output, None, Role::DriveTorque),
            mean,
        ],
        DriveMode::Torque => vec![
            torque(Causality::Input, Some(0.0), Role::DriveTorqueInput),
            speed(Causality::Output, None, Role::CrankSpeed),
            mean,
            Variable {
                name: "crank_speed_start".into(),
                description:
                    "crank speed at the start (the crank turns from there under the drive torque)"
                        .into(),
                causality: Causality::Parameter,
                variability: Variability::Fixed,
                kind: Kind::Real {
                    start: Some(speed0),
                    unit: Some("rad/s".into()),
                    min: Some(0.0),
                    max: None,
                },
                role: Role::CrankSpeedStart,
            },
        ],
    }
}

/// The rig's total outputs.
fn total_outputs() -> Vec<Variable> {
    vec![
        output(
            "crank_angle".into(),
            "crank angle from top dead centre, accumulated (not wrapped)".into(),
            "rad",
            Role::CrankAngle,
        ),
        output(
            "friction_torque".into(),
            "friction torque at the crank, every law summed (dissipated power over crank speed)"
                .into(),
            "N.m",
            Role::FrictionTorque,
        ),
        output(
            "friction_power".into(),
            "power dissipated by every law".into(),
            "W",
            Role::FrictionPower,
        ),
        output(
            "friction_energy".into(),
            "energy dissipated by every law since the start".into(),
            "J",
            Role::FrictionEnergy,
        ),
        output(
            "friction_torque_cycle_mean".into(),
            "friction torque averaged over the last whole cycle (a revolution; two for a 4-stroke cycle)".into(),
            "N.m",
            Role::FrictionTorqueCycleMean,
        ),
    ]
}

/// One joint's outputs.
fn joint_outputs(joint: &str, j: usize) -> Vec<Variable> {
    vec![
        output(
            format!("{joint}.friction_torque"),
            format!("friction torque at the crank of joint {joint} (all its laws)"),
            "N.m",
            Role::JointTorque { joint: j },
        ),
        output(
            format!("{joint}.friction_power"),
            format!("power dissipated at joint {joint}"),
            "W",
            Role::JointPower { joint: j },
        ),
        output(
            format!("{joint}.friction_energy"),
            format!("energy dissipated at joint {joint} since the start"),
            "J",
            Role::JointEnergy { joint: j },
        ),
    ]
}

/// The FMI parameters of one law parameter (a list parameter gives one per element).
fn law_params(
    prefix: &str,
    law: usize,
    spec: &ParamSpec,
    value: &ParamValue,
    law_name: &str,
    slide: bool,
) -> Vec<Variable> {
    let finite = |x: f64| x.is_finite().then_some(x);
    let var = |name: String, kind: Kind, element: Option<usize>| Variable {
        name,
        description: format!("law {law_name}: {}", spec.doc),
        causality: Causality::Parameter,
        variability: Variability::Tunable,
        kind,
        role: Role::LawParam {
            law,
            param: spec.name.clone(),
            element,
        },
    };
    let number = |x: f64| Kind::Real {
        start: Some(x),
        unit: law_unit(&spec.unit, slide),
        min: finite(spec.min),
        max: finite(spec.max),
    };
    let name = format!("{prefix}.{}", identifier(&spec.name));
    match value {
        ParamValue::Number(x) => vec![var(name, number(*x), None)],
        ParamValue::NumberList(xs) => xs
            .iter()
            .enumerate()
            .map(|(i, x)| var(format!("{name}[{}]", i + 1), number(*x), Some(i)))
            .collect(),
        ParamValue::Bool(b) => vec![var(name, Kind::Boolean { start: *b }, None)],
        ParamValue::Choice(word) => {
            let start = spec.choices.iter().position(|c| c == word).unwrap_or(0) as i32 + 1;
            vec![var(
                name,
                Kind::Enumeration {
                    start,
                    type_name: format!("{}.{}", identifier(law_name), identifier(&spec.name)),
                    items: spec.choices.clone(),
                },
                None,
            )]
        }
    }
}

/// The file name of `path`, as text.
fn file_name(path: &std::path::Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_law_unit_takes_the_alternative_of_the_joint_kind_in_modelica_syntax() {
        assert_eq!(
            law_unit("N s/m | N m s/rad", true).as_deref(),
            Some("N.s/m")
        );
        assert_eq!(
            law_unit("N s/m | N m s/rad", false).as_deref(),
            Some("N.m.s/rad")
        );
        assert_eq!(
            law_unit("N m s/rad | N s/m", true).as_deref(),
            Some("N.s/m")
        );
        assert_eq!(law_unit("N | N m", false).as_deref(), Some("N.m"));
        assert_eq!(law_unit("N | N m", true).as_deref(), Some("N"));
        assert_eq!(law_unit("rad/s | m/s", true).as_deref(), Some("m/s"));
        assert_eq!(law_unit("m", false).as_deref(), Some("m"));
        assert_eq!(law_unit("-", false), None);
    }

    #[test]
    fn identifiers_are_fmi_names() {
        assert_eq!(identifier("fedem-friction"), "fedem_friction");
        assert_eq!(identifier("2x"), "_2x");
        assert_eq!(identifier(""), "_");
    }
}
