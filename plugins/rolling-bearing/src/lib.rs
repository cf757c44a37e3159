//! `rolling-bearing`: the SKF constant-coefficient estimate of a rolling bearing's friction
//! moment, with an optional viscous drag term.
//!
//! ```text
//! M = -( 0.5 * mu * F * d * sgn_eps(v_s) + c_drag * omega )
//! ```
//!
//! `F` the radial load from the joint reaction (N), `d` the bore diameter `2 R` from the joint's
//! contact radius (m), `mu` the bearing's constant coefficient (SKF: cylindrical roller with cage
//! ~0.0011, needle roller with cage 0.0020-0.0030; physics notes section 5), `omega` the relative
//! angular velocity and `c_drag` a viscous drag coefficient (oil churning, N m s/rad).

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{
    export_law, smooth_sign, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec,
    SUITS_ROLLING,
};

/// Parameters of [`RollingBearing`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Constant friction coefficient (-).
    pub mu: f64,
    /// Viscous drag coefficient, N m s/rad.
    pub c_drag: f64,
    /// Sliding-velocity scale of the smoothed sign, m/s.
    pub v_smooth: f64,
}

impl Default for Params {
    fn default() -> Self {
        // [S: SKF catalogue] cylindrical roller bearing with cage.
        Self {
            mu: 0.0011,
            c_drag: 0.0,
            v_smooth: 1e-3,
        }
    }
}

/// Rolling bearing friction moment.
#[derive(Debug, Clone)]
pub struct RollingBearing {
    p: Params,
}

impl Law for RollingBearing {
    type Params = Params;
    const NAME: &'static str = "rolling-bearing";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str =
        "Rolling bearing moment M = 0.5*mu*F*d (SKF estimate) plus optional viscous drag";
    // What it models: a rolling-element bearing's catalogue friction moment.
    const SUITS: u32 = SUITS_ROLLING;

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "mu",
                "-",
                "constant bearing coefficient (SKF: cylindrical roller 0.0011, needle 0.002-0.003)",
                0.0,
                0.1,
            ),
            ParamSpec::number(
                "c_drag",
                "N m s/rad",
                "viscous drag (churning) coefficient on the relative angular velocity",
                0.0,
                10.0,
            ),
            ParamSpec::number(
                "v_smooth",
                "m/s",
                "sliding-velocity scale of the smoothed sign at zero speed",
                1e-9,
                1.0,
            ),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        Ok(Self { p })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        // d = 2R, so 0.5 * mu * F * d = mu * F * R; on a slide R is not an arm, use a force.
        let arm = if input.kind() == Some(JointKind::Revolute) {
            input.contact_radius_m
        } else {
            1.0
        };
        let (sign, dsign) = smooth_sign(input.sliding_velocity_m_s, self.p.v_smooth);
        let m0 = 0.5 * self.p.mu * input.normal_load_n * 2.0 * arm;
        LawOutput::force(-(m0 * sign + self.p.c_drag * input.relative_velocity))
            .with_coefficient(self.p.mu)
            .with_derivative(-(m0 * dsign * arm + self.p.c_drag))
    }
}

export_law!(RollingBearing);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Result<RollingBearing, ParamError> {
        create_from_table::<RollingBearing>(&text.parse().expect("toml"))
    }

    fn bearing(w: f64, f: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Revolute);
        i.contact_radius_m = 0.02;
        i.normal_load_n = f;
        i.with_velocity(w)
    }

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<RollingBearing>();
        assert_law_conforms_with::<RollingBearing>("mu = 0.002\nc_drag = 2e-5\nv_smooth = 0.01");
    }

    #[test]
    fn skf_moment_at_a_hand_point() {
        // 0.5 * 0.0011 * 3000 N * 0.040 m = 0.066 N m, plus 1e-5 * 500 rad/s drag.
        let out = law("mu = 0.0011\nc_drag = 1e-5\nv_smooth = 1e-9")
            .expect("valid")
            .evaluate(&bearing(500.0, 3000.0), &[]);
        assert!((out.force + 0.066 + 0.005).abs() < 1e-12, "{}", out.force);
    }

    #[test]
    fn rejects_negative_coefficient() {
        assert_eq!(law("mu = -0.001").unwrap_err().parameter, "mu");
    }
}
