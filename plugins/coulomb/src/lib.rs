//! `coulomb`: constant-coefficient Coulomb friction on the joint's normal load, plus an optional
//! viscous term. The simplest load-dependent law, and the one that carries the plugin plumbing.
//!
//! Force (prismatic joint, N) or torque (revolute joint, N m):
//!
//! ```text
//! F = -[ mu * N * arm * sgn_eps(v_s) + c * v ]
//! ```
//!
//! with `N` the normal load from the joint reaction, `arm` the contact radius for a revolute
//! joint (1 for a prismatic one), `v_s` the sliding velocity at the contact, `v` the joint's
//! relative velocity, and `sgn_eps(x) = x / sqrt(x^2 + eps^2)` a sign function smoothed over the
//! velocity scale `eps` (`v_smooth`), so the law is continuous through zero velocity.

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{
    export_law, smooth_sign, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec,
};

/// Parameters of [`Coulomb`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Coulomb coefficient (-).
    pub mu: f64,
    /// Viscous coefficient: N s/m on a slide, N m s/rad on a revolute joint.
    pub c_viscous: f64,
    /// Sliding-velocity scale of the smoothed sign, m/s.
    pub v_smooth: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            mu: 0.1,
            c_viscous: 0.0,
            // estimate: 1 mm/s is far below any sliding speed of a running engine (the piston
            // passes it within microseconds of a dead centre), yet keeps the law smooth.
            v_smooth: 1e-3,
        }
    }
}

/// Coulomb friction with an optional viscous term.
#[derive(Debug, Clone)]
pub struct Coulomb {
    p: Params,
}

impl Law for Coulomb {
    type Params = Params;
    const NAME: &'static str = "coulomb";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str =
        "Constant-coefficient Coulomb friction on the joint reaction, plus optional viscous term";

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number("mu", "-", "Coulomb friction coefficient", 0.0, 10.0),
            ParamSpec::number(
                "c_viscous",
                "N s/m | N m s/rad",
                "viscous coefficient on the relative velocity (slide: N s/m, revolute: N m s/rad)",
                0.0,
                1e6,
            ),
            ParamSpec::number(
                "v_smooth",
                "m/s",
                "sliding-velocity scale over which the Coulomb sign is smoothed through zero",
                1e-9,
                1.0,
            ),
        ]
    }

    fn new(params: Params) -> Result<Self, ParamError> {
        Ok(Self { p: params })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        let arm = match input.kind() {
            Some(JointKind::Revolute) => input.contact_radius_m,
            _ => 1.0,
        };
        let (sign, dsign_dvs) = smooth_sign(input.sliding_velocity_m_s, self.p.v_smooth);
        let coulomb = self.p.mu * input.normal_load_n * arm;
        let force = -(coulomb * sign + self.p.c_viscous * input.relative_velocity);
        // d(v_s)/d(v) is the arm: the contact radius for a revolute joint, 1 for a slide.
        let dfdv = -(coulomb * dsign_dvs * arm + self.p.c_viscous);
        LawOutput::force(force)
            .with_coefficient(self.p.mu)
            .with_derivative(dfdv)
    }
}

export_law!(Coulomb);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Coulomb {
        let table: toml::Table = text.parse().expect("test TOML parses");
        create_from_table::<Coulomb>(&table).expect("test parameters are valid")
    }

    fn input(kind: JointKind, velocity: f64, load: f64, radius: f64) -> LawInput {
        let mut i = LawInput::at_rest(kind);
        i.normal_load_n = load;
        i.contact_radius_m = radius;
        i.with_velocity(velocity)
    }

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<Coulomb>();
        assert_law_conforms_with::<Coulomb>("mu = 0.08");
        assert_law_conforms_with::<Coulomb>("mu = 0.3\nc_viscous = 0.1");
        assert_law_conforms_with::<Coulomb>("mu = 0.2\nc_viscous = 0.05\nv_smooth = 0.01");
    }

    #[test]
    fn revolute_torque_is_mu_load_radius_when_sliding_fast() {
        let l = law("mu = 0.0025\nv_smooth = 1e-6");
        // 314 rad/s on a 17 mm pin: v_s = 5.3 m/s >> v_smooth, so the sign is 1 to 1e-12.
        let out = l.evaluate(&input(JointKind::Revolute, 314.0, 2000.0, 0.017), &[]);
        let expected = -0.0025 * 2000.0 * 0.017;
        assert!(
            (out.force - expected).abs() < 1e-12 * expected.abs(),
            "{}",
            out.force
        );
        assert_eq!(out.coefficient(), Some(0.0025));
    }

    #[test]
    fn viscous_term_adds_linearly() {
        let l = law("mu = 0.08\nc_viscous = 2.5\nv_smooth = 1e-6");
        let out = l.evaluate(&input(JointKind::Prismatic, -3.0, 150.0, 0.0384), &[]);
        // Moving at -3 m/s: friction +0.08*150, viscous -2.5*(-3) = +7.5.
        let expected = 0.08 * 150.0 + 7.5;
        assert!((out.force - expected).abs() < 1e-9, "{}", out.force);
    }

    #[test]
    fn negative_coefficient_is_rejected_by_name() {
        let table: toml::Table = "mu = -0.1".parse().expect("parses");
        let e = create_from_table::<Coulomb>(&table).unwrap_err();
        assert_eq!(e.parameter, "mu");
        assert!(e.message.contains("[0, 10]"), "{e}");
    }
}
