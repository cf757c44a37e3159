//! `stribeck-duty`: a Coulomb coefficient driven by the duty (Hersey) parameter, switching
//! between boundary, mixed and hydrodynamic lubrication.
//!
//! ```text
//! H    = eta * |U| / w                      duty parameter (dimensionless)
//! mu_h = c * H^k                            hydrodynamic branch
//! s    = clamp(ln(H/H_b) / ln(H_h/H_b), 0, 1)
//! phi  = 1 - (3 s^2 - 2 s^3)                boundary weight (smooth mode)
//! mu   = phi * mu_b + (1 - phi) * mu_h      coefficient
//! F    = -mu * N_eff * arm * sgn_eps(U)
//! ```
//!
//! `eta` is the oil's dynamic viscosity (Pa s), `U` the sliding velocity at the contact (m/s),
//! `N_eff = N + preload` the normal load from the joint reaction plus a preload (ring tension, N),
//! and `w` a load per unit contact length: `N_eff / L` for a journal (L = bearing width: load per
//! projected area times the diameter) and `N_eff / (2 pi R)` for a slide (R = half the bore: load
//! per unit circumference of ring and skirt). `arm` is the contact radius on a revolute joint
//! (torque) and 1 on a slide (force).
//!
//! Regimes: boundary for `H < H_b`, mixed for `H_b <= H < H_h`, hydrodynamic for `H >= H_h`. The
//! smooth blend is C1 in H (the smoothstep has zero slope at both thresholds), so the coefficient
//! and its derivative are continuous; `switch = "hard"` jumps from mu_b to mu_h at sqrt(H_b H_h)
//! for comparison. With `mu_h(H_h) < mu_b` the minimum of the coefficient lies inside the mixed
//! regime: the Stribeck shape.
//!
//! Which load defines H (physics notes section 2): by default (`load = "instantaneous"`) the
//! load the force uses, `N_eff`, floored at `load_floor_n` so that H stays finite where the
//! reaction vanishes (an unloaded slide at the dead centres without preload: `0/0`); the floor
//! only caps H, the force still uses `N_eff`. In a motored engine the inertia loads grow with
//! speed squared, so this H *falls* with speed. `load = "nominal"` defines H from
//! `nominal_load_n` (plus preload) instead, a fixed load, so H grows with speed as the thesis
//! read its curve (chapter 11); it is inconsistent with the force on purpose (kept to compare
//! with that reading, used by no bundled law set).

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{
    export_law, smooth_sign, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec, Regime,
    SUITS_PLAIN, SUITS_SLIDE,
};

/// Parameters of [`StribeckDuty`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Boundary coefficient (-).
    pub mu_b: f64,
    /// Hydrodynamic coefficient scale c in mu_h = c H^k (-).
    pub c: f64,
    /// Hydrodynamic exponent k (1: Petroff journal, 0.5: ring/skirt slider).
    pub k: f64,
    /// Duty parameter where the boundary regime ends (-).
    pub h_boundary: f64,
    /// Duty parameter where the hydrodynamic regime begins (-).
    pub h_hydrodynamic: f64,
    /// Preload added to the reaction, N (ring tension).
    pub preload_n: f64,
    /// `instantaneous` or `nominal`: the load that defines H.
    pub load: String,
    /// Nominal load for `load = "nominal"`, N.
    pub nominal_load_n: f64,
    /// Smallest load defining H (`load = "instantaneous"`), N.
    pub load_floor_n: f64,
    /// `smooth` (C1 blend) or `hard` (jump at the geometric mean of the thresholds).
    pub switch: String,
    /// Sliding-velocity scale of the smoothed sign, m/s.
    pub v_smooth: f64,
}

impl Default for Params {
    fn default() -> Self {
        // estimate: textbook Stribeck values for a lubricated ring/skirt contact (Hamrock;
        // physics notes section 4): mu_b ~ 0.1, k = 1/2; thresholds spanning two decades.
        Self {
            mu_b: 0.1,
            c: 1.0,
            k: 0.5,
            h_boundary: 1e-5,
            h_hydrodynamic: 1e-3,
            preload_n: 0.0,
            load: "instantaneous".into(),
            nominal_load_n: 100.0,
            // estimate: far below any working load of a ring or skirt (tens to thousands of
            // N), so it acts only where the reaction vanishes.
            load_floor_n: 1.0,
            switch: "smooth".into(),
            v_smooth: 1e-3,
        }
    }
}

/// The regime-switching duty-parameter law.
#[derive(Debug, Clone)]
pub struct StribeckDuty {
    p: Params,
    nominal: bool,
    hard: bool,
}

impl StribeckDuty {
    /// Coefficient and regime at duty parameter `h`.
    pub fn coefficient(&self, h: f64) -> (f64, Regime) {
        let p = &self.p;
        let mu_h = p.c * h.max(0.0).powf(p.k);
        let regime = if h < p.h_boundary {
            Regime::Boundary
        } else if h < p.h_hydrodynamic {
            Regime::Mixed
        } else {
            Regime::Hydrodynamic
        };
        let phi = if self.hard {
            if h < (p.h_boundary * p.h_hydrodynamic).sqrt() {
                1.0
            } else {
                0.0
            }
        } else {
            let s = ((h.max(1e-300) / p.h_boundary).ln() / (p.h_hydrodynamic / p.h_boundary).ln())
                .clamp(0.0, 1.0);
            1.0 - s * s * (3.0 - 2.0 * s)
        };
        (phi * p.mu_b + (1.0 - phi) * mu_h, regime)
    }

    /// Duty parameter for an input.
    pub fn duty(&self, input: &LawInput) -> f64 {
        let load = if self.nominal {
            self.p.nominal_load_n + self.p.preload_n
        } else {
            (input.normal_load_n + self.p.preload_n).max(self.p.load_floor_n)
        };
        let length = match input.kind() {
            Some(JointKind::Revolute) => input.contact_length_m,
            _ => 2.0 * std::f64::consts::PI * input.contact_radius_m,
        };
        let w = load.max(1e-12) / length.max(1e-12);
        input.viscosity_pa_s * input.sliding_velocity_m_s.abs() / w
    }
}

impl Law for StribeckDuty {
    type Params = Params;
    const NAME: &'static str = "stribeck-duty";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "Coulomb coefficient from the duty parameter H = eta*U/w: boundary, mixed, hydrodynamic (c*H^k)";
    // What it models: a lubricated sliding contact, journal or ring and skirt; the Hersey number of a sliding film does not describe rolling elements.
    const SUITS: u32 = SUITS_PLAIN | SUITS_SLIDE;

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number("mu_b", "-", "boundary coefficient (asperity contact); typically 0.05-0.15 for lubricated steel/iron", 0.0, 2.0),
            ParamSpec::number("c", "-", "hydrodynamic scale in mu_h = c*H^k", 0.0, 1e6),
            ParamSpec::number("k", "-", "hydrodynamic exponent: 1 Petroff journal, 0.5 ring/skirt slider", 0.0, 2.0),
            ParamSpec::number("h_boundary", "-", "duty parameter where boundary lubrication ends", 1e-15, 1e3),
            ParamSpec::number("h_hydrodynamic", "-", "duty parameter where full-film lubrication begins (> h_boundary)", 1e-15, 1e3),
            ParamSpec::number("preload_n", "N", "load added to the joint reaction (piston ring tension)", 0.0, 1e5),
            ParamSpec::choice("load", "load defining H: the load the force uses (reaction plus preload, floored at load_floor_n), or nominal_load_n plus preload (the thesis's reading, inconsistent with the force)", &["instantaneous", "nominal"]),
            ParamSpec::number("nominal_load_n", "N", "fixed load defining H when load = \"nominal\"", 1e-6, 1e6),
            ParamSpec::number("load_floor_n", "N", "smallest load defining H when load = \"instantaneous\" (H stays finite where the reaction vanishes; the force uses the actual load)", 1e-6, 1e4),
            ParamSpec::choice("switch", "smooth (C1 blend between the thresholds) or hard (jump at their geometric mean)", &["smooth", "hard"]),
            ParamSpec::number("v_smooth", "m/s", "sliding-velocity scale of the smoothed sign at reversal", 1e-9, 1.0),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        if p.h_hydrodynamic <= p.h_boundary {
            return Err(ParamError::new(
                "h_hydrodynamic",
                format!(
                    "thresholds out of order: must be above h_boundary ({}), got {}",
                    p.h_boundary, p.h_hydrodynamic
                ),
            ));
        }
        Ok(Self {
            nominal: p.load == "nominal",
            hard: p.switch == "hard",
            p,
        })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        let h = self.duty(input);
        let (mu, regime) = self.coefficient(h);
        let arm = match input.kind() {
            Some(JointKind::Revolute) => input.contact_radius_m,
            _ => 1.0,
        };
        let n_eff = input.normal_load_n + self.p.preload_n;
        let (sign, _) = smooth_sign(input.sliding_velocity_m_s, self.p.v_smooth);
        LawOutput::force(-mu * n_eff * arm * sign)
            .with_coefficient(mu)
            .with_duty_parameter(h)
            .with_regime(regime)
    }
}

export_law!(StribeckDuty);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Result<StribeckDuty, ParamError> {
        create_from_table::<StribeckDuty>(&text.parse().expect("toml"))
    }

    fn slide(v: f64, n: f64, eta: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Prismatic);
        i.normal_load_n = n;
        i.contact_radius_m = 0.0384;
        i.viscosity_pa_s = eta;
        i.with_velocity(v)
    }

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<StribeckDuty>();
        assert_law_conforms_with::<StribeckDuty>("preload_n = 20.0");
        assert_law_conforms_with::<StribeckDuty>("mu_b = 0.1\nc = 1.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-4\npreload_n = 30.0");
        assert_law_conforms_with::<StribeckDuty>("switch = \"hard\"\nload = \"nominal\"");
    }

    #[test]
    fn duty_parameter_and_force_at_a_hand_point() {
        let l = law("mu_b = 0.1\nc = 2.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-5\npreload_n = 50.0\nv_smooth = 1e-9").expect("valid");
        // eta 0.024 Pa s, U 10 m/s, N 150 N + 50 N preload on a 76.8 mm bore:
        // w = 200 / (pi * 0.0768) = 828.9 N/m, H = 0.024 * 10 / 828.9 = 2.895e-4 (hydrodynamic).
        let input = slide(10.0, 150.0, 0.024);
        let w = 200.0 / (2.0 * std::f64::consts::PI * 0.0384);
        let h = 0.024 * 10.0 / w;
        let out = l.evaluate(&input, &[]);
        assert!((out.duty_parameter().expect("reported") - h).abs() < 1e-15);
        let mu = 2.0 * h.sqrt();
        assert!((out.coefficient().expect("reported") - mu).abs() < 1e-12);
        assert!((out.force + mu * 200.0).abs() < 1e-9);
        assert_eq!(out.regime(), Some(Regime::Hydrodynamic));
    }

    #[test]
    fn stribeck_shape_over_six_decades() {
        let l = law("mu_b = 0.12\nc = 3.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-4")
            .expect("valid");
        let mut prev_regime = Regime::Boundary;
        let (mut min_mu, mut min_h) = (f64::INFINITY, 0.0);
        for i in 0..=600 {
            let h = 10f64.powf(-8.0 + 6.0 * i as f64 / 600.0);
            let (mu, regime) = l.coefficient(h);
            let expected = if h < 1e-6 {
                Regime::Boundary
            } else if h < 1e-4 {
                Regime::Mixed
            } else {
                Regime::Hydrodynamic
            };
            assert_eq!(regime, expected, "H = {h}");
            assert!(regime as u32 >= prev_regime as u32, "regimes in order");
            prev_regime = regime;
            if mu < min_mu {
                min_mu = mu;
                min_h = h;
            }
        }
        assert!(
            min_h > 1e-6 && min_h < 1e-4,
            "minimum at H = {min_h} must be in the mixed regime"
        );
        // Below the coefficient at both thresholds: mu_b = 0.12 and mu_h(1e-4) = 3 * 1e-2.
        assert!(min_mu < 3.0 * 1e-4_f64.sqrt(), "{min_mu}");
    }

    #[test]
    fn smooth_mode_is_continuous_with_continuous_slope_at_the_thresholds() {
        let l = law("mu_b = 0.12\nc = 3.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-4")
            .expect("valid");
        for t in [1e-6, 1e-4] {
            let e = 1e-12 * t; // natural change over 2e is ~1e-13 relative, far below 1e-9
            let (a, _) = l.coefficient(t - e);
            let (b, _) = l.coefficient(t + e);
            assert!(
                (a - b).abs() <= 1e-9 * a.abs().max(b.abs()),
                "jump at {t}: {a} vs {b}"
            );
            // One-sided slopes must agree. The natural slope scale near a threshold is mu_b / t
            // (a kink would differ by ~mu_b / (t ln(H_h/H_b)) ~ 2.6e4 here); the one-sided
            // difference's own error is ~ d * mu'' ~ 1e-2 of that scale for d = 1e-6 t.
            let d = 1e-6 * t;
            let left = (l.coefficient(t).0 - l.coefficient(t - d).0) / d;
            let right = (l.coefficient(t + d).0 - l.coefficient(t).0) / d;
            assert!(
                (left - right).abs() <= 1e-3 * 0.12 / t,
                "slope at {t}: {left} vs {right}"
            );
        }
        // The hard switch jumps, by contrast.
        let hard = law("mu_b = 0.12\nc = 3.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-4\nswitch = \"hard\"").expect("valid");
        let m = 1e-5;
        assert!(
            (hard.coefficient(m * (1.0 - 1e-9)).0 - hard.coefficient(m * (1.0 + 1e-9)).0).abs()
                > 0.05
        );
    }

    /// The duty parameter is computed from the load the force uses: H = eta |U| 2 pi R /
    /// max(N + preload, floor), evaluated here independently over loads from zero (a dead
    /// centre without thrust) to 5 kN, and the force is the coefficient of that H times the
    /// same load.
    #[test]
    fn duty_parameter_uses_the_load_the_force_uses_with_a_floor() {
        let l = law("mu_b = 0.12\nc = 2.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-5\nload_floor_n = 5.0\nv_smooth = 1e-9")
            .expect("valid");
        let with_preload = law("mu_b = 0.12\nc = 2.0\nk = 0.5\nh_boundary = 1e-6\nh_hydrodynamic = 1e-5\npreload_n = 220.0\nload_floor_n = 5.0\nv_smooth = 1e-9")
            .expect("valid");
        let circumference = 2.0 * std::f64::consts::PI * 0.0384;
        for (law, preload) in [(&l, 0.0), (&with_preload, 220.0)] {
            for n in [0.0, 1.0, 4.999, 5.0, 30.0, 800.0, 5000.0] {
                for (u, eta) in [(0.01, 0.1), (3.0, 0.024), (15.0, 0.012)] {
                    let out = law.evaluate(&slide(u, n, eta), &[]);
                    let load = f64::max(n + preload, 5.0);
                    let h = eta * u * circumference / load;
                    let got = out.duty_parameter().expect("reported");
                    assert!(
                        (got - h).abs() <= 1e-14 * h,
                        "N {n} + {preload}: H {got} vs {h}"
                    );
                    let (mu, _) = law.coefficient(h);
                    let force = -mu * (n + preload);
                    assert!(
                        (out.force - force).abs() <= 1e-12 * force.abs().max(1e-300),
                        "N {n}: {} vs {force}",
                        out.force
                    );
                    assert!(got.is_finite() && out.force.is_finite());
                }
            }
        }
    }

    #[test]
    fn nominal_load_makes_h_independent_of_the_reaction() {
        let l = law("load = \"nominal\"\nnominal_load_n = 100.0").expect("valid");
        let a = l.evaluate(&slide(5.0, 10.0, 0.02), &[]).duty_parameter();
        let b = l.evaluate(&slide(5.0, 5000.0, 0.02), &[]).duty_parameter();
        assert_eq!(a, b);
        let inst = law("").expect("valid");
        assert!(
            inst.evaluate(&slide(5.0, 10.0, 0.02), &[]).duty_parameter()
                > inst
                    .evaluate(&slide(5.0, 5000.0, 0.02), &[])
                    .duty_parameter()
        );
    }

    #[test]
    fn rejects_thresholds_out_of_order_and_bad_values() {
        let e = law("h_boundary = 1e-3\nh_hydrodynamic = 1e-5").unwrap_err();
        assert_eq!(e.parameter, "h_hydrodynamic");
        assert!(e.message.contains("out of order"));
        assert_eq!(law("mu_b = -0.1").unwrap_err().parameter, "mu_b");
        assert_eq!(law("load = \"average\"").unwrap_err().parameter, "load");
    }
}
