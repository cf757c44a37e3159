//! `petroff-journal`: viscous friction of a concentric, fully flooded journal bearing (Petroff).
//!
//! ```text
//! T = -2 pi eta omega R^3 L / c * f_e,    f_e = 1 / sqrt(1 - eps^2)
//! ```
//!
//! `eta` dynamic viscosity (Pa s), `omega` relative angular velocity (rad/s), `R` journal radius
//! and `L` bearing length (the joint's contact geometry, m), `c` radial clearance (m), and `f_e`
//! the optional eccentricity factor of the short/long-bearing shear integral (eps = 0: Petroff's
//! concentric result). Independent of load: a full film carries it. Revolute joints only; on a
//! slide the same shear law gives `F = -eta * A * v / c` with `A = 2 pi R L`.

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{
    export_law, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec, Regime, SUITS_PLAIN,
};

/// Parameters of [`Petroff`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Radial clearance, m.
    pub clearance_m: f64,
    /// Eccentricity ratio (-), 0 for a concentric journal.
    pub eccentricity: f64,
}

impl Default for Params {
    fn default() -> Self {
        // estimate: radial clearance ~ 1/1000 of the diameter for an automotive plain bearing.
        Self {
            clearance_m: 2e-5,
            eccentricity: 0.0,
        }
    }
}

/// Petroff journal bearing.
#[derive(Debug, Clone)]
pub struct Petroff {
    p: Params,
}

impl Petroff {
    /// Viscous coefficient: torque per rad/s (revolute) or force per m/s (slide).
    pub fn coefficient(&self, input: &LawInput) -> f64 {
        let (r, l, eta) = (
            input.contact_radius_m,
            input.contact_length_m,
            input.viscosity_pa_s,
        );
        let fe = 1.0 / (1.0 - self.p.eccentricity * self.p.eccentricity).sqrt();
        match input.kind() {
            Some(JointKind::Revolute) => {
                2.0 * std::f64::consts::PI * eta * r.powi(3) * l / self.p.clearance_m * fe
            }
            _ => eta * 2.0 * std::f64::consts::PI * r * l / self.p.clearance_m * fe,
        }
    }
}

impl Law for Petroff {
    type Params = Params;
    const NAME: &'static str = "petroff-journal";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "Hydrodynamic journal bearing (Petroff): T = 2*pi*eta*omega*R^3*L/c, optional eccentricity factor";
    // What it models: a hydrodynamic journal: shaft in a bush or shells on an oil film.
    const SUITS: u32 = SUITS_PLAIN;

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "clearance_m",
                "m",
                "radial clearance c between journal and bearing",
                1e-7,
                1e-2,
            ),
            ParamSpec::number(
                "eccentricity",
                "-",
                "eccentricity ratio eps; the shear torque grows as 1/sqrt(1 - eps^2)",
                0.0,
                0.99,
            ),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        Ok(Self { p })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        let k = self.coefficient(input);
        let force = -k * input.relative_velocity;
        let mut out = LawOutput::force(force)
            .with_derivative(-k)
            .with_regime(Regime::Hydrodynamic);
        let arm = if input.kind() == Some(JointKind::Revolute) {
            input.contact_radius_m
        } else {
            1.0
        };
        if input.normal_load_n > 0.0 && arm > 0.0 {
            out = out.with_coefficient(force.abs() / (input.normal_load_n * arm));
        }
        out
    }
}

export_law!(Petroff);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Result<Petroff, ParamError> {
        create_from_table::<Petroff>(&text.parse().expect("toml"))
    }

    fn journal(w: f64, eta: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Revolute);
        i.contact_radius_m = 0.02;
        i.contact_length_m = 0.015;
        i.viscosity_pa_s = eta;
        i.normal_load_n = 1000.0;
        i.with_velocity(w)
    }

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<Petroff>();
        assert_law_conforms_with::<Petroff>("clearance_m = 2e-5\neccentricity = 0.6");
    }

    #[test]
    fn petroff_torque_at_a_hand_point() {
        let l = law("clearance_m = 2e-5").expect("valid");
        // 2*pi*0.024*600*0.02^3*0.015/2e-5 = 0.5429 N m.
        let t = 2.0 * std::f64::consts::PI * 0.024 * 600.0 * 0.02_f64.powi(3) * 0.015 / 2e-5;
        let out = l.evaluate(&journal(600.0, 0.024), &[]);
        assert!((out.force + t).abs() < 1e-12, "{} vs {t}", out.force);
        assert!((t - 0.5429).abs() < 1e-3);
        let ecc = law("clearance_m = 2e-5\neccentricity = 0.6")
            .expect("valid")
            .evaluate(&journal(600.0, 0.024), &[]);
        assert!((ecc.force + t / 0.8).abs() < 1e-12);
    }

    #[test]
    fn rejects_zero_clearance() {
        let e = law("clearance_m = 0.0").unwrap_err();
        assert_eq!(e.parameter, "clearance_m");
        assert!(e.message.contains("out of range"));
    }
}
