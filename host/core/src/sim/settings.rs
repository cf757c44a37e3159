//! Settings used or refused: which of the rig's `[solver]` and `[drive]` settings a run does
//! not use, so that a setting the user gave is never silently ignored (`docs/solver.md`,
//! "Settings used or refused"). A transient run refuses a setting given for it that it cannot
//! use with these laws and this drive (an error naming the setting, its value, why and what to
//! do instead); the steady state, which uses none of the transient's step methods or the
//! drive, runs and says in its warnings which given settings it left aside. A default that does
//! not apply is neither.

use super::error::{readable, SimError};
use super::Simulation;
use crate::model::{Drive, Integrator, QuadratureRule, RigFile, SolverSettings, StepControl};

/// The settings whose use depends on the run: the transient's step methods and the drive.
/// (`solver.step_deg`, `friction_tol` and `friction_max_iter` are used by every run.)
pub const RUN_DEPENDENT_SETTINGS: [&str; 7] = [
    "drive.kind",
    "solver.integrator",
    "solver.quadrature",
    "solver.rel_tol",
    "solver.max_step_deg",
    "solver.step_control",
    "solver.max_step_s",
];

/// One setting a run does not use: the dotted field, its value as written in a rig file, and
/// why (with what to do instead).
#[derive(Debug, Clone, PartialEq)]
struct Unused {
    field: &'static str,
    value: String,
    why: String,
}

/// The run-dependent settings of `f` whose value differs from the default: given by the user
/// for certain (the drive is always given: a rig file must name it). What the core alone can
/// tell; the rig loader, which sees the files, also knows a default written out
/// ([`Simulation::settings_given`]).
pub(super) fn non_default_settings(f: &RigFile) -> Vec<&'static str> {
    let s = &f.solver;
    let d = SolverSettings::default();
    let differs = [
        true,
        s.integrator != d.integrator,
        s.quadrature != d.quadrature,
        s.rel_tol != d.rel_tol,
        s.max_step_deg.is_some(),
        s.step_control != d.step_control,
        s.max_step_s != d.max_step_s,
    ];
    RUN_DEPENDENT_SETTINGS
        .iter()
        .zip(differs)
        .filter(|(_, differs)| *differs)
        .map(|(field, _)| *field)
        .collect()
}

/// A setting's value as a rig file writes it.
fn quoted(s: &str) -> String {
    format!("\"{s}\"")
}

impl Simulation {
    /// Tell the simulation which settings the user gave (`given(field)` for each of
    /// [`RUN_DEPENDENT_SETTINGS`]: written in the rig file or one it extends, or set by
    /// `--set`), rather than the core's guess (the values that differ from their defaults), and
    /// check them again. Refused as in [`Simulation::new`]: a setting given for the transient
    /// run that it cannot use with these laws and this drive.
    pub fn settings_given(&mut self, given: impl Fn(&str) -> bool) -> Result<(), SimError> {
        self.given = RUN_DEPENDENT_SETTINGS
            .iter()
            .copied()
            .filter(|f| given(f))
            .collect();
        self.refuse_unused_settings()
    }

    /// The first setting given for the transient run that it cannot use, as a setup error at
    /// the setting (the rig loader locates it in its file).
    pub(super) fn refuse_unused_settings(&self) -> Result<(), SimError> {
        match self
            .unused_by_transient()
            .into_iter()
            .find(|u| self.given.contains(&u.field))
        {
            None => Ok(()),
            Some(u) => Err(SimError::Setup {
                at: None,
                field: u.field.to_string(),
                law: None,
                param: None,
                message: format!("{} cannot be used by this run: {}", u.value, u.why),
            }),
        }
    }

    /// The warnings of a steady run: each given setting it does not use.
    pub(super) fn steady_settings_warnings(&self) -> Vec<String> {
        self.unused_by_steady()
            .into_iter()
            .filter(|u| self.given.contains(&u.field))
            .map(|u| format!("{} = {} is not used: {}", u.field, u.value, u.why))
            .collect()
    }

    /// The first stateful law, as "law `L` on joint `J`".
    fn stateful_law(&self) -> String {
        self.joints
            .iter()
            .find_map(|j| {
                j.laws
                    .iter()
                    .find(|l| l.is_stateful())
                    .map(|l| format!("law `{}` on joint `{}`", l.name, j.name))
            })
            .unwrap_or_else(|| "a law".into())
    }

    /// The values of the step-method settings, as a rig file writes them.
    fn values(&self) -> [String; 6] {
        let integrator = match self.integrator {
            Integrator::Adaptive => "adaptive",
            Integrator::Rk4 => "rk4",
        };
        let quadrature = match self.quadrature {
            QuadratureRule::Auto => "auto",
            QuadratureRule::Simpson => "simpson",
            QuadratureRule::Lobatto => "lobatto",
        };
        let control = match self.step_control {
            StepControl::Integral => "integral",
            StepControl::Pi => "pi",
        };
        [
            quoted(integrator),
            quoted(quadrature),
            readable(self.rel_tol),
            // Back to the degrees written, without the conversion's last bits.
            readable((self.max_step_rad.to_degrees() * 1e9).round() / 1e9),
            quoted(control),
            readable(self.max_step_s),
        ]
    }

    /// The settings the transient run does not use, with these laws and this drive (the
    /// choice of step method mirrors the transient's).
    fn unused_by_transient(&self) -> Vec<Unused> {
        let [integrator, quadrature, rel_tol, max_step, control, _] = self.values();
        let mut out = Vec::new();
        let mut unused = |field, value: &String, why: String| {
            out.push(Unused {
                field,
                value: value.clone(),
                why,
            })
        };
        let fixed_steps = match self.drive {
            Drive::Prescribed {} => {
                unused("solver.integrator", &integrator, "the crank is prescribed (drive.kind = \"prescribed\"): its motion is known, so only its rates are integrated, by solver.quadrature; remove solver.integrator, or use drive.kind = \"pi\" to integrate the crank's motion".into());
                if self.quadrature == QuadratureRule::Lobatto && self.stateful {
                    unused("solver.quadrature", &quadrature, format!("{} keeps state, which is advanced once per step with the step's length, so its steps must not vary; the run would integrate with Simpson's rule at solver.step_deg. Remove solver.quadrature (or set it to \"simpson\"), or use stateless laws", self.stateful_law()));
                }
                // "auto" is Simpson throughout with a stateful law or a pressure trace.
                let simpson_only = self.quadrature == QuadratureRule::Simpson
                    || self.stateful
                    || (self.quadrature == QuadratureRule::Auto && !self.pressure_kinks.is_empty());
                simpson_only
                    .then_some("the prescribed crank is integrated by Simpson's rule at the fixed step solver.step_deg, without error control (solver.quadrature = \"simpson\"; \"auto\" with a stateful law or a cylinder pressure trace); remove it, or use solver.quadrature = \"lobatto\" (stateless laws) for error-controlled steps")
            }
            Drive::Pi { .. } => {
                unused("solver.quadrature", &quadrature, "the quadrature is the prescribed crank's; with drive.kind = \"pi\" the crank's motion is integrated by solver.integrator. Remove solver.quadrature, or use drive.kind = \"prescribed\"".into());
                if self.integrator == Integrator::Adaptive && self.stateful {
                    unused("solver.integrator", &integrator, format!("{} keeps state, which is advanced once per step with the step's length, so its steps must not vary; the run would integrate with fixed-step RK4 at solver.step_deg. Set solver.integrator = \"rk4\" (what runs), or use stateless laws", self.stateful_law()));
                }
                (self.integrator == Integrator::Rk4 || self.stateful)
                    .then_some("the PI drive's crank is integrated by RK4 at the fixed step solver.step_deg, without error control; remove it, or use solver.integrator = \"adaptive\" (stateless laws) for error-controlled steps")
            }
        };
        if let Some(why) = fixed_steps {
            unused("solver.rel_tol", &rel_tol, why.into());
            unused("solver.max_step_deg", &max_step, why.into());
            unused("solver.step_control", &control, why.into());
        }
        out
    }

    /// The settings the steady state does not use: it turns the crank at exactly each plateau
    /// speed and integrates one cycle at the fixed step `solver.step_deg`.
    fn unused_by_steady(&self) -> Vec<Unused> {
        let [integrator, quadrature, rel_tol, max_step, control, max_step_s] = self.values();
        let why = "the steady state integrates each plateau's cycle at the fixed crank-angle step solver.step_deg (it applies to the transient run)";
        let mut out = Vec::new();
        if matches!(self.drive, Drive::Pi { .. }) {
            out.push(Unused {
                field: "drive.kind",
                value: quoted("pi"),
                why: "the steady state turns the crank at exactly each plateau speed, so the PI drive and its gains, torque limit, belt and motor apply to the transient run only".into(),
            });
        }
        for (field, value) in [
            ("solver.integrator", integrator),
            ("solver.quadrature", quadrature),
            ("solver.rel_tol", rel_tol),
            ("solver.max_step_deg", max_step),
            ("solver.step_control", control),
            ("solver.max_step_s", max_step_s),
        ] {
            out.push(Unused {
                field,
                value,
                why: why.into(),
            });
        }
        out
    }
}
