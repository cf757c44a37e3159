//! `fedem-friction`: FEDEM's friction element, thesis eq 6.11 without the viscous term (FEDEM
//! applies viscous friction as a separate damper; use `polyline-damper` for it).
//!
//! ```text
//! F = -[ F0 + mu * Fe * (1 + S * exp(-(V/V_slip)^2)) ] * sgn_eps(v_s)
//! ```
//!
//! `Fe` is the radial reaction times the contact radius for a revolute joint (so `F` is a torque,
//! N m, and `F0` a prestress torque) and the lateral reaction for a slide (`F` in N). `V` is the
//! joint's relative velocity (rad/s or m/s); `S = 0` or `V_slip = 0` switches the Stribeck term
//! off, as in the thesis's table 9.5.
//!
//! Zero velocity: FEDEM uses a stick/slip state machine with hysteresis (physics notes section
//! 3). On a speed-driven crank that gives singular systems (peer notes, lesson 4), so this law
//! uses a smooth sign `v_s / sqrt(v_s^2 + eps^2)` over the sliding-velocity scale `v_smooth`.
//! Bearings never reverse; the piston reverses twice a revolution and passes `eps` within
//! microseconds, so plateau torques do not depend on `eps` (checked in tests/laws.rs to 0.1%).

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{
    export_law, smooth_sign, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec,
};

/// Parameters of [`FedemFriction`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Coulomb coefficient (-).
    pub mu: f64,
    /// Prestress force (slide, N) or torque (revolute, N m).
    pub prestress: f64,
    /// Magnitude of the Stribeck effect S (-).
    pub stribeck_s: f64,
    /// Critical Stribeck speed V_slip (rad/s on a revolute joint, m/s on a slide).
    pub v_slip: f64,
    /// Sliding-velocity scale of the smoothed sign, m/s.
    pub v_smooth: f64,
}

impl Default for Params {
    fn default() -> Self {
        // Thesis table 9.5 uses S = 0, V_slip = 0 and no prestress everywhere.
        Self {
            mu: 0.0025,
            prestress: 0.0,
            stribeck_s: 0.0,
            v_slip: 0.0,
            v_smooth: 1e-3,
        }
    }
}

/// FEDEM's constant-coefficient friction element.
#[derive(Debug, Clone)]
pub struct FedemFriction {
    p: Params,
}

impl Law for FedemFriction {
    type Params = Params;
    const NAME: &'static str = "fedem-friction";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "FEDEM friction element (thesis eq 6.11 without viscous term): prestress + mu*Fe*(1 + S*exp(-(V/Vslip)^2))";

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number("mu", "-", "Coulomb coefficient on Fe (thesis table 9.5: 0.0025 big end, 0.00245 mains, 0.08 piston)", 0.0, 10.0),
            ParamSpec::number("prestress", "N | N m", "prestress force (slide) or torque (revolute), F0", 0.0, 1e5),
            ParamSpec::number("stribeck_s", "-", "magnitude of the Stribeck effect, S = (F_static - F_coulomb)/F_coulomb", 0.0, 100.0),
            ParamSpec::number("v_slip", "rad/s | m/s", "critical Stribeck speed V_slip; 0 switches the Stribeck term off", 0.0, 1e4),
            ParamSpec::number("v_smooth", "m/s", "sliding-velocity scale of the smoothed sign at zero velocity", 1e-9, 1.0),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        if p.stribeck_s > 0.0 && p.v_slip == 0.0 {
            return Err(ParamError::new(
                "v_slip",
                "must be positive when stribeck_s > 0 (the Stribeck term needs a speed scale)",
            ));
        }
        Ok(Self { p })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        let arm = match input.kind() {
            Some(JointKind::Revolute) => input.contact_radius_m,
            _ => 1.0,
        };
        let fe = input.normal_load_n * arm;
        let v = input.relative_velocity;
        let stribeck = if self.p.stribeck_s > 0.0 && self.p.v_slip > 0.0 {
            1.0 + self.p.stribeck_s * (-(v / self.p.v_slip).powi(2)).exp()
        } else {
            1.0
        };
        let (sign, _) = smooth_sign(input.sliding_velocity_m_s, self.p.v_smooth);
        let magnitude = self.p.prestress + self.p.mu * fe * stribeck;
        // Affine in the load (the prestress its intercept): the host need not call again when
        // only the load changes.
        LawOutput::force(-magnitude * sign)
            .with_coefficient(self.p.mu * stribeck)
            .affine_in_load(-self.p.mu * arm * stribeck * sign)
    }
}

export_law!(FedemFriction);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> FedemFriction {
        create_from_table::<FedemFriction>(&text.parse().expect("toml")).expect("valid")
    }

    fn input(kind: JointKind, v: f64, n: f64, r: f64) -> LawInput {
        let mut i = LawInput::at_rest(kind);
        i.normal_load_n = n;
        i.contact_radius_m = r;
        i.with_velocity(v)
    }

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<FedemFriction>();
        assert_law_conforms_with::<FedemFriction>("mu = 0.0025");
        assert_law_conforms_with::<FedemFriction>(
            "mu = 0.3\nprestress = 1.0\nstribeck_s = 2.0\nv_slip = 0.05",
        );
    }

    #[test]
    fn revolute_torque_is_mu_radial_load_radius() {
        // Big end, thesis table 9.5: mu 0.0025, R 0.017 m; 4000 N at 300 rad/s.
        let out = law("mu = 0.0025\nv_smooth = 1e-9")
            .evaluate(&input(JointKind::Revolute, 300.0, 4000.0, 0.017), &[]);
        assert!((out.force + 0.0025 * 4000.0 * 0.017).abs() < 1e-12);
    }

    #[test]
    fn prestress_and_stribeck_terms() {
        let l = law("mu = 0.08\nprestress = 5.0\nstribeck_s = 0.5\nv_slip = 0.2\nv_smooth = 1e-9");
        let v = 0.1;
        let out = l.evaluate(&input(JointKind::Prismatic, v, 300.0, 0.0384), &[]);
        let expected = -(5.0 + 0.08 * 300.0 * (1.0 + 0.5 * (-(v / 0.2_f64).powi(2)).exp()));
        assert!(
            (out.force - expected).abs() < 1e-9,
            "{} vs {expected}",
            out.force
        );
        // Far above V_slip the Stribeck term is gone.
        let fast = l.evaluate(&input(JointKind::Prismatic, -20.0, 300.0, 0.0384), &[]);
        assert!((fast.force - (5.0 + 0.08 * 300.0)).abs() < 1e-9);
    }

    #[test]
    fn rejects_bad_parameters_by_name() {
        let e =
            create_from_table::<FedemFriction>(&"mu = -0.1".parse().expect("toml")).unwrap_err();
        assert_eq!(e.parameter, "mu");
        assert!(e.message.contains("[0, 10]"));
        let e = create_from_table::<FedemFriction>(&"stribeck_s = 1.0".parse().expect("toml"))
            .unwrap_err();
        assert_eq!(e.parameter, "v_slip");
    }
}
