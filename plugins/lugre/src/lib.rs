//! `lugre`: the LuGre dynamic friction model (Canudas de Wit, Olsson, Astrom, Lischinsky, IEEE
//! TAC 40(3), 1995), scaled by the joint's normal load. The bristle deflection `z` is the law's
//! one state variable, held by the host.
//!
//! ```text
//! g(v)  = mu_c + (mu_s - mu_c) * exp(-(v/v_s)^2)
//! dz/dt = v - sigma0 * |v| * z / g(v)
//! F     = -N * arm * (sigma0 * z + sigma1 * dz/dt + sigma2 * v)
//! ```
//!
//! `v` is the sliding velocity at the contact (m/s), `N` the normal load (N), `arm` the contact
//! radius on a revolute joint (torque) or 1 on a slide. The sigmas and `g` are per newton of
//! normal load: with `N = 1 N` the default parameters are exactly the paper's standard set
//! (sigma0 1e5 N/m, sigma1 316 N s/m, sigma2 0.4 N s/m, Fc 1 N, Fs 1.5 N, vs 0.001 m/s).
//!
//! `commit` advances `z` over the step with the exact solution of the bristle equation at the
//! step's velocity (stable however stiff `sigma0 |v| / g` is). `evaluate` uses the state that
//! same update predicts for the end of the step, with `dz/dt` as its difference quotient, so the
//! force is consistent with what will be committed (a pure function of committed state and
//! input); with `dt_s = 0` (steady-state quadrature) it uses the committed `z` and the ODE.

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{export_law, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec};

/// Parameters of [`LuGre`], per newton of normal load.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Bristle stiffness per unit load, 1/m.
    pub sigma0: f64,
    /// Bristle damping per unit load, s/m.
    pub sigma1: f64,
    /// Viscous coefficient per unit load, s/m.
    pub sigma2: f64,
    /// Coulomb coefficient (-).
    pub mu_c: f64,
    /// Static coefficient (-).
    pub mu_s: f64,
    /// Stribeck velocity, m/s.
    pub v_s: f64,
}

impl Default for Params {
    fn default() -> Self {
        // [S: Canudas de Wit et al. 1995] standard parameter set, per newton of normal load.
        Self {
            sigma0: 1e5,
            sigma1: 316.0,
            sigma2: 0.4,
            mu_c: 1.0,
            mu_s: 1.5,
            v_s: 1e-3,
        }
    }
}

/// LuGre friction.
#[derive(Debug, Clone)]
pub struct LuGre {
    p: Params,
}

impl LuGre {
    /// Steady-state friction per unit load, g(v).
    pub fn g(&self, v: f64) -> f64 {
        self.p.mu_c + (self.p.mu_s - self.p.mu_c) * (-(v / self.p.v_s).powi(2)).exp()
    }

    fn zdot(&self, v: f64, z: f64) -> f64 {
        v - self.p.sigma0 * v.abs() * z / self.g(v)
    }

    /// Exact solution of the bristle equation over `dt` at constant `v`.
    fn advance(&self, z: f64, v: f64, dt: f64) -> f64 {
        if v == 0.0 || dt <= 0.0 {
            return z;
        }
        let a = self.p.sigma0 * v.abs() / self.g(v);
        let z_ss = v / a;
        z_ss + (z - z_ss) * (-a * dt).exp()
    }
}

impl Law for LuGre {
    type Params = Params;
    const NAME: &'static str = "lugre";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str =
        "LuGre dynamic friction (bristle state in host-owned law state), scaled by the normal load";

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "sigma0",
                "1/m",
                "bristle stiffness per newton of normal load",
                1.0,
                1e12,
            ),
            ParamSpec::number(
                "sigma1",
                "s/m",
                "bristle damping per newton of normal load",
                0.0,
                1e9,
            ),
            ParamSpec::number(
                "sigma2",
                "s/m",
                "viscous friction per newton of normal load",
                0.0,
                1e6,
            ),
            ParamSpec::number("mu_c", "-", "Coulomb level of g(v)", 1e-9, 10.0),
            ParamSpec::number(
                "mu_s",
                "-",
                "static (breakaway) level of g(v), >= mu_c",
                1e-9,
                10.0,
            ),
            ParamSpec::number("v_s", "m/s", "Stribeck velocity of g(v)", 1e-9, 100.0),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        if p.mu_s < p.mu_c {
            return Err(ParamError::new(
                "mu_s",
                format!("must be at least mu_c ({}), got {}", p.mu_c, p.mu_s),
            ));
        }
        Ok(Self { p })
    }

    fn state_size(&self) -> usize {
        1
    }

    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        let arm = if input.kind() == Some(JointKind::Revolute) {
            input.contact_radius_m
        } else {
            1.0
        };
        let v = input.sliding_velocity_m_s;
        let z0 = state.first().copied().unwrap_or(0.0);
        let (z, zdot) = if input.dt_s > 0.0 {
            let z1 = self.advance(z0, v, input.dt_s);
            (z1, (z1 - z0) / input.dt_s)
        } else {
            (z0, self.zdot(v, z0))
        };
        let per_load = self.p.sigma0 * z + self.p.sigma1 * zdot + self.p.sigma2 * v;
        let n = input.normal_load_n;
        let mut out = LawOutput::force(-n * arm * per_load);
        if v != 0.0 {
            out = out.with_coefficient(per_load.abs());
        }
        out
    }

    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        let v = input.sliding_velocity_m_s;
        if let Some(z) = state.first_mut() {
            *z = self.advance(*z, v, input.dt_s);
        }
    }
}

export_law!(LuGre);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Result<LuGre, ParamError> {
        create_from_table::<LuGre>(&text.parse().expect("toml"))
    }

    fn slide(v: f64, n: f64, dt: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Prismatic);
        i.normal_load_n = n;
        i.dt_s = dt;
        i.with_velocity(v)
    }

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<LuGre>();
        assert_law_conforms_with::<LuGre>("mu_c = 0.05\nmu_s = 0.08\nsigma1 = 1.0\nsigma2 = 0.001");
    }

    #[test]
    fn steady_state_force_is_g_plus_viscous() {
        let l = law("").expect("defaults");
        for &v in &[-0.1, -0.002, 0.0005, 0.001, 0.01, 1.0] {
            let mut z = [0.0];
            for _ in 0..2000 {
                l.commit(&slide(v, 1.0, 1e-3), &mut z);
            }
            let f = l.evaluate(&slide(v, 1.0, 1e-3), &z).force;
            // Hand formula: g(v) = 1 + 0.5*exp(-(v/0.001)^2), F = -(g + 0.4 v) sgn(v).
            let g = 1.0 + 0.5 * (-(v / 0.001_f64).powi(2)).exp();
            let expected = -(g * v.signum() + 0.4 * v);
            assert!((f - expected).abs() < 1e-9, "v={v}: {f} vs {expected}");
            // Scaled by the normal load.
            let f300 = l.evaluate(&slide(v, 300.0, 1e-3), &z).force;
            assert!((f300 - 300.0 * expected).abs() < 1e-6);
        }
    }

    /// A 1 kg block on a unit-load LuGre contact, pushed by a constant force.
    fn push(l: &LuGre, applied: f64, seconds: f64) -> (f64, f64) {
        let dt = 1e-5;
        let (mut x, mut v, mut z) = (0.0, 0.0, [0.0]);
        for _ in 0..(seconds / dt) as usize {
            let f = l.evaluate(&slide(v, 1.0, dt), &z).force;
            v += (applied + f) * dt;
            x += v * dt;
            l.commit(&slide(v, 1.0, dt), &mut z);
        }
        (x, v)
    }

    #[test]
    fn pre_sliding_displacement_below_the_coulomb_force() {
        let l = law("").expect("defaults");
        // 0.5 N < Fc = 1 N: the block sticks; the bristles deflect by about F/sigma0 = 5 um.
        let (x, v) = push(&l, 0.5, 0.5);
        assert!(x > 0.0 && x < 2e-5, "stick displacement {x} m");
        assert!(
            (x - 0.5 / 1e5).abs() < 0.5 * 0.5 / 1e5,
            "close to F/sigma0: {x}"
        );
        assert!(v.abs() < 1e-4, "at rest: {v}");
        // 2 N > Fs = 1.5 N: it breaks away and slides.
        let (x, v) = push(&l, 2.0, 0.5);
        assert!(x > 0.05 && v > 0.1, "gross sliding: x={x} v={v}");
    }

    #[test]
    fn rejects_static_below_coulomb() {
        let e = law("mu_c = 1.0\nmu_s = 0.5").unwrap_err();
        assert_eq!(e.parameter, "mu_s");
        assert_eq!(law("sigma0 = 0.0").unwrap_err().parameter, "sigma0");
    }
}
