//! `mixed-film`: a mixed-lubrication law for the piston ring pack and skirt (usable on a
//! journal): slider-bearing film thickness, Greenwood-Tripp asperity share, boundary friction
//! on the asperities and hydrodynamic shear on the film.
//!
//! ```text
//! W      = N + preload + W_gas                  total normal load, N
//! W_gas  = max(p_cyl - p_cc, 0) * 2 pi R * h_g  gas load behind the rings (slides; h_g = 0: off)
//! w      = W / L_c                              load per unit contact length, N/m
//! h_min  = K_h * b * sqrt(eta * |U| / w)        minimum film of the optimum fixed-incline slider
//! Lambda = h_min / sigma                        film parameter
//! phi    = F_5/2(Lambda) / F_5/2(0)             asperity (boundary) share, Greenwood-Tripp
//! F_h    = c_h * sqrt(eta * |U| * W * L_c)      full-film (hydrodynamic) friction
//! F      = -sgn_eps(U) * [ phi * mu_b * W + (1 - phi) * F_h ] * arm
//! ```
//!
//! `L_c` is the contact length across the sliding direction: the bore circumference `2 pi R` on
//! a slide (R = the joint's contact radius, half the bore), the bearing width on a revolute
//! joint. `arm` is the contact radius on a revolute joint (the output is a torque) and 1 on a
//! slide. `F_n(x) = (2 pi)^(-1/2) * integral_x^inf (s - x)^n exp(-s^2/2) ds` is the Gaussian
//! asperity integral, computed by quadrature once (a table shared by every instance) and
//! interpolated; it is not the `(4 - Lambda)^6.804` fit.
//!
//! # The slider constants
//!
//! For an infinitely wide plane slider of width `b` (along the motion) with outlet film `h0` and
//! inlet film `n h0`, the Reynolds equation `dp/dx = 6 eta U (h - h*) / h^3` with `p = 0` at
//! both ends gives the load and the friction on the moving surface per unit width
//!
//! ```text
//! w  = 6 eta U b^2 / h0^2 * [ln n - 2 (n - 1)/(n + 1)] / (n - 1)^2
//! F' = eta U b / h0 * [4 ln n - 6 (n - 1)/(n + 1)] / (n - 1)
//! ```
//!
//! The load is largest at `n = 2.1887`, where `w = 0.16024 eta U b^2 / h0^2`, so
//! `h0 = K_h b sqrt(eta U / w)` with `K_h = sqrt(0.16024) = 0.40030`, and `F' = 0.75420 eta U b
//! / h0 = c_h sqrt(eta U w)` with `c_h = 0.75420 / 0.40030 = 1.8841`: the width cancels from the
//! friction. Over the plausible inclinations `n = 2..5` c_h stays within 1.81-1.94 (its minimum
//! 1.81 near n = 3). The unit test `slider_constants_from_an_independent_reynolds_integration`
//! integrates the Reynolds equation numerically and recovers both constants.
//!
//! The hydrodynamic friction therefore scales as `eta^(1/2)` (Sandoval and Heywood, SAE
//! 2003-01-0725, scale ring and skirt hydrodynamic terms by `(mu/mu_ref)^0.5`), the boundary
//! term does not depend on viscosity, and the film parameter grows as `sqrt(eta U / w)`.

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{
    export_law, smooth_sign, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec, Regime,
    SUITS_SLIDE,
};

/// Minimum-film constant of the optimum fixed-incline slider: `h_min = K_H b sqrt(eta U / w)`.
pub const K_H: f64 = 0.400_303_8;

/// Friction constant of the optimum fixed-incline slider: `F' = C_H sqrt(eta U w)`.
pub const C_H: f64 = 1.884_073;

/// Largest film parameter in the Greenwood-Tripp table; beyond it the asperity share is zero
/// (it is below 1e-20 there).
pub const LAMBDA_MAX: f64 = 8.0;

/// Table spacing in the film parameter.
const TABLE_STEP: f64 = 0.005;

/// `F_n(x)` by quadrature: with `s = x + u^2` the integrand of `(2 pi)^(-1/2) * integral_x^inf
/// (s - x)^n exp(-s^2/2) ds` becomes `2 u^(2n+1) exp(-(x + u^2)^2 / 2)`, smooth at `u = 0`;
/// composite Simpson on `[0, u_max]` where the integrand has decayed below `exp(-50)` of its
/// scale.
pub fn gaussian_integral(n: f64, x: f64) -> f64 {
    // (x + u^2)^2 / 2 >= 50 for u^2 >= 10 - min(x, 0): beyond it the tail is negligible.
    let u_max = (10.0 - x.min(0.0)).sqrt() + 0.5;
    let intervals = 2000usize;
    let h = u_max / intervals as f64;
    let f = |u: f64| {
        let s = x + u * u;
        2.0 * u.powf(2.0 * n + 1.0) * (-0.5 * s * s).exp()
    };
    let mut sum = f(0.0) + f(u_max);
    for i in 1..intervals {
        let weight = if i % 2 == 1 { 4.0 } else { 2.0 };
        sum += weight * f(i as f64 * h);
    }
    sum * h / 3.0 / (2.0 * std::f64::consts::PI).sqrt()
}

/// `ln(F_5/2(Lambda) / F_5/2(0))` at `Lambda = i * TABLE_STEP`, computed once.
fn log_share_table() -> &'static [f64] {
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let f0 = gaussian_integral(2.5, 0.0);
        let count = (LAMBDA_MAX / TABLE_STEP).round() as usize + 1;
        (0..count)
            .map(|i| (gaussian_integral(2.5, i as f64 * TABLE_STEP) / f0).ln())
            .collect()
    })
}

/// Asperity share `phi(Lambda) = F_5/2(Lambda) / F_5/2(0)`: 1 at `Lambda <= 0`, falling
/// monotonically, 0 beyond [`LAMBDA_MAX`]. Linear interpolation of its logarithm in the table
/// (relative error below 1e-5 with the table's spacing).
pub fn asperity_share(lambda: f64) -> f64 {
    if lambda.is_nan() {
        return 1.0;
    }
    if lambda <= 0.0 {
        return 1.0;
    }
    if lambda >= LAMBDA_MAX {
        return 0.0;
    }
    let table = log_share_table();
    let t = lambda / TABLE_STEP;
    let i = (t.floor() as usize).min(table.len() - 2);
    let frac = t - i as f64;
    (table[i] + frac * (table[i + 1] - table[i])).exp()
}

/// Parameters of [`MixedFilm`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Boundary (asperity) friction coefficient (-).
    pub mu_b: f64,
    /// Hydrodynamic friction constant c_h in `F_h = c_h sqrt(eta U W L_c)` (-).
    pub c_h: f64,
    /// Face width of the contact along the sliding direction, m (ring face width).
    pub face_width_m: f64,
    /// Composite RMS roughness of the two surfaces, m.
    pub sigma_m: f64,
    /// Load added to the joint reaction, N (ring tension as radial load).
    pub preload_n: f64,
    /// Sliding-velocity scale of the smoothed sign, m/s.
    pub v_smooth: f64,
    /// Effective ring height loaded from behind by the gas, m (0: no gas loading).
    pub ring_gas_height_m: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            // [S: Hutchings and Shipway, Tribology, 2nd ed. 2017, boundary lubrication: 0.05-0.15]
            mu_b: 0.1,
            // [derived] the optimum fixed-incline slider (module doc)
            c_h: C_H,
            // estimate: a 1 mm ring face (motorcycle rings 0.7-1.2 mm)
            face_width_m: 1.0e-3,
            // estimate: honed liner plateau and lapped ring face, composite Rq ~0.3 um
            sigma_m: 0.3e-6,
            preload_n: 0.0,
            v_smooth: 1e-3,
            // Off by default: the head-less thesis rig has no gas load, and the bundled law
            // sets keep their calibrated meaning.
            ring_gas_height_m: 0.0,
        }
    }
}

/// The mixed-film law.
#[derive(Debug, Clone)]
pub struct MixedFilm {
    p: Params,
}

/// Everything the law computes at one input, for tests and reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Total normal load W = N + preload + gas load, N.
    pub load_n: f64,
    /// Load per unit contact length w, N/m.
    pub unit_load_n_m: f64,
    /// Minimum film thickness, m.
    pub film_m: f64,
    /// Film parameter Lambda = h_min / sigma (-).
    pub lambda: f64,
    /// Asperity share phi (-).
    pub share: f64,
    /// Full-film friction F_h, N.
    pub hydrodynamic_n: f64,
    /// Friction magnitude at the contact, N.
    pub friction_n: f64,
}

impl MixedFilm {
    /// Radial gas load on the ring pack of a slide, N (contract version 2): the pressure drop
    /// across the rings, cylinder over crankcase, acting on the back of the ring over its
    /// effective height all round the bore, `max(p_cyl - p_cc, 0) * 2 pi R * h_gas`. A reversed
    /// drop unloads nothing (the ring then seats on the groove's upper flank, estimate). Zero on
    /// a revolute joint and when `ring_gas_height_m` is 0.
    pub fn gas_load(&self, input: &LawInput) -> f64 {
        if self.p.ring_gas_height_m == 0.0 || input.kind() != Some(JointKind::Prismatic) {
            return 0.0;
        }
        let drop = (input.cylinder_pressure_pa - input.crankcase_pressure_pa).max(0.0);
        drop * 2.0 * std::f64::consts::PI * input.contact_radius_m * self.p.ring_gas_height_m
    }

    /// The contact's film, shares and friction magnitude (at the contact, before the arm).
    pub fn contact(&self, input: &LawInput) -> Contact {
        let p = &self.p;
        let length = match input.kind() {
            Some(JointKind::Revolute) => input.contact_length_m,
            _ => 2.0 * std::f64::consts::PI * input.contact_radius_m,
        }
        .max(1e-12);
        let load = (input.normal_load_n.abs() + p.preload_n + self.gas_load(input)).max(0.0);
        let w = load / length;
        let eta_u = (input.viscosity_pa_s * input.sliding_velocity_m_s.abs()).max(0.0);
        let film = if w > 0.0 {
            K_H * p.face_width_m * (eta_u / w).sqrt()
        } else {
            f64::INFINITY
        };
        let lambda = film / p.sigma_m;
        let share = asperity_share(lambda);
        let hydrodynamic = p.c_h * (eta_u * load * length).sqrt();
        Contact {
            load_n: load,
            unit_load_n_m: w,
            film_m: film,
            lambda,
            share,
            hydrodynamic_n: hydrodynamic,
            friction_n: share * p.mu_b * load + (1.0 - share) * hydrodynamic,
        }
    }
}

/// Hamrock's regimes by film parameter: boundary below 1, mixed 1-3, full film above 3.
pub fn regime(lambda: f64) -> Regime {
    if lambda < 1.0 {
        Regime::Boundary
    } else if lambda < 3.0 {
        Regime::Mixed
    } else {
        Regime::Hydrodynamic
    }
}

impl Law for MixedFilm {
    type Params = Params;
    const NAME: &'static str = "mixed-film";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "Mixed lubrication: slider film h ~ b sqrt(eta U/w), Greenwood-Tripp asperity share, mu_b W + c_h sqrt(eta U W L)";
    // What it models: a slider film on a ring or skirt (load per unit circumference).
    const SUITS: u32 = SUITS_SLIDE;

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number("mu_b", "-", "boundary (asperity) coefficient; 0.05-0.15 for boundary-lubricated steel/cast iron (Hutchings and Shipway)", 0.0, 0.5),
            ParamSpec::number("c_h", "-", "full-film constant in F_h = c_h sqrt(eta U W L_c): 1.88 for one optimum slider, 1.81-1.94 over inclinations 2-5, up to ~4 for three rings sharing the load", 0.1, 20.0),
            ParamSpec::number("face_width_m", "m", "contact width along the motion (ring face width, ~0.7-1.2 mm on motorcycle rings)", 1e-6, 0.1),
            ParamSpec::number("sigma_m", "m", "composite RMS roughness of the two surfaces (honed liner with ring: ~0.1-0.6 um)", 1e-9, 1e-4),
            ParamSpec::number("preload_n", "N", "load added to the joint reaction: ring tension as radial load, 2 pi x tangential tension per ring", 0.0, 1e5),
            ParamSpec::number("v_smooth", "m/s", "sliding-velocity scale of the smoothed sign at reversal", 1e-9, 1.0),
            ParamSpec::number("ring_gas_height_m", "m", "effective ring height the gas presses from behind (slides): W += max(p_cyl - p_crankcase, 0) 2 pi R h; estimate ~0.5-1 x the top ring's height (0.7-1.2 mm on motorcycle rings); 0 turns gas loading off", 0.0, 0.01),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        // Every value is range-checked by the host against `parameters()`; nothing to combine.
        // The asperity table is built here (once per process), not inside the first evaluation.
        log_share_table();
        Ok(Self { p })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        let c = self.contact(input);
        let arm = match input.kind() {
            Some(JointKind::Revolute) => input.contact_radius_m,
            _ => 1.0,
        };
        let (sign, _) = smooth_sign(input.sliding_velocity_m_s, self.p.v_smooth);
        let coefficient = if c.load_n > 0.0 {
            c.friction_n / c.load_n
        } else {
            0.0
        };
        let duty = if c.unit_load_n_m > 0.0 {
            input.viscosity_pa_s * input.sliding_velocity_m_s.abs() / c.unit_load_n_m
        } else {
            0.0
        };
        LawOutput::force(-sign * c.friction_n * arm)
            .with_coefficient(coefficient)
            .with_duty_parameter(duty)
            .with_regime(regime(c.lambda))
    }
}

export_law!(MixedFilm);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Result<MixedFilm, ParamError> {
        create_from_table::<MixedFilm>(&text.parse().expect("toml"))
    }

    fn slide(v: f64, n: f64, eta: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Prismatic);
        i.normal_load_n = n;
        i.contact_radius_m = 0.0384;
        i.viscosity_pa_s = eta;
        i.with_velocity(v)
    }

    /// Gamma function by the Lanczos approximation (g = 7, 9 terms), independent of the law.
    fn gamma(x: f64) -> f64 {
        const C: [f64; 9] = [
            0.999_999_999_999_809_9,
            676.520_368_121_885_1,
            -1_259.139_216_722_402_8,
            771.323_428_777_653_1,
            -176.615_029_162_140_6,
            12.507_343_278_686_905,
            -0.138_571_095_265_720_12,
            9.984_369_578_019_572e-6,
            1.505_632_735_149_311_6e-7,
        ];
        let x = x - 1.0;
        let t = x + 7.5;
        let mut a = C[0];
        for (i, c) in C.iter().enumerate().skip(1) {
            a += c / (x + i as f64);
        }
        (2.0 * std::f64::consts::PI).sqrt() * t.powf(x + 0.5) * (-t).exp() * a
    }

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<MixedFilm>();
        assert_law_conforms_with::<MixedFilm>("preload_n = 20.0");
        assert_law_conforms_with::<MixedFilm>(
            "mu_b = 0.1\nc_h = 1.884\nface_width_m = 1e-3\nsigma_m = 0.3e-6\npreload_n = 220.0",
        );
    }

    #[test]
    fn gaussian_integral_at_zero_matches_its_closed_form() {
        // F_n(0) = 2^((n-1)/2) Gamma((n+1)/2) / sqrt(2 pi).
        for n in [0.0, 1.0, 1.5, 2.0, 2.5, 3.0] {
            let exact = 2f64.powf((n - 1.0) / 2.0) * gamma((n + 1.0) / 2.0)
                / (2.0 * std::f64::consts::PI).sqrt();
            let q = gaussian_integral(n, 0.0);
            assert!(
                (q - exact).abs() < 1e-10 * exact,
                "F_{n}(0) = {q} vs {exact}"
            );
        }
        // n = 0 is the Gaussian tail: F_0(x) = erfc(x / sqrt 2) / 2; at x = 1, 0.158655254.
        assert!((gaussian_integral(0.0, 1.0) - 0.158_655_253_931_457).abs() < 1e-9);
        // F_5/2(0) = 2^(3/4) Gamma(7/4) / sqrt(2 pi) = 0.616634...
        assert!((gaussian_integral(2.5, 0.0) - 0.616_634_218_996_844).abs() < 1e-9);
    }

    #[test]
    fn asperity_share_is_one_at_contact_monotone_and_matches_direct_quadrature() {
        assert_eq!(asperity_share(0.0), 1.0);
        assert_eq!(asperity_share(-1.0), 1.0);
        assert_eq!(asperity_share(LAMBDA_MAX + 1.0), 0.0);
        let f0 = gaussian_integral(2.5, 0.0);
        let mut prev = 1.0;
        for i in 1..=1600 {
            let l = i as f64 * 0.00497; // off the table's nodes
            let s = asperity_share(l);
            assert!(s < prev, "not decreasing at {l}: {s} >= {prev}");
            prev = s;
            if i % 37 == 0 {
                let direct = gaussian_integral(2.5, l) / f0;
                assert!(
                    (s - direct).abs() <= 2e-5 * direct,
                    "Lambda {l}: {s} vs {direct}"
                );
            }
        }
        // Hamrock's regime edges: mostly asperity contact at 1, nearly none at 3.
        assert!(asperity_share(1.0) > 0.05 && asperity_share(3.0) < 1e-3);
    }

    /// Load and friction of a plane slider with inlet/outlet ratio `n`, width 1, outlet film 1,
    /// eta U = 1: pressure by integrating dp/dx = 6 (h - h*)/h^3 with h* from p(1) = 0 (shooting
    /// on a fine grid), load by the trapezoid rule, friction on the moving surface
    /// eta U/h + (h/2) dp/dx.
    fn slider(n: f64) -> (f64, f64) {
        let m = 20_000;
        let dx = 1.0 / m as f64;
        let h = |i: usize| n - (n - 1.0) * i as f64 * dx;
        let end_pressure = |hs: f64| {
            let mut p = 0.0;
            for i in 0..m {
                let g = |h: f64| 6.0 * (h - hs) / h.powi(3);
                p += 0.5 * (g(h(i)) + g(h(i + 1))) * dx;
            }
            p
        };
        // p(1) falls as h* rises: bisection between the two film extremes.
        let (mut lo, mut hi) = (1.0, n);
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if end_pressure(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let hs = 0.5 * (lo + hi);
        let g = |h: f64| 6.0 * (h - hs) / h.powi(3);
        let (mut p, mut load, mut friction) = (0.0, 0.0, 0.0);
        for i in 0..m {
            let p_next = p + 0.5 * (g(h(i)) + g(h(i + 1))) * dx;
            load += 0.5 * (p + p_next) * dx;
            let shear = |h: f64| 1.0 / h + 0.5 * h * g(h);
            friction += 0.5 * (shear(h(i)) + shear(h(i + 1))) * dx;
            p = p_next;
        }
        (load, friction)
    }

    #[test]
    fn slider_constants_from_an_independent_reynolds_integration() {
        // Maximise the load over the inclination ratio by golden-section search.
        let (mut a, mut b) = (1.5, 3.5);
        let g = (5f64.sqrt() - 1.0) / 2.0;
        for _ in 0..40 {
            let (c, d) = (b - g * (b - a), a + g * (b - a));
            if slider(c).0 > slider(d).0 {
                b = d;
            } else {
                a = c;
            }
        }
        let n = 0.5 * (a + b);
        let (w, f) = slider(n);
        // w = W' h0^2 / (eta U b^2) = K_h^2;  F' = f eta U b / h0 = (f / K_h) sqrt(eta U W').
        let k_h = w.sqrt();
        let c_h = f / k_h;
        assert!((n - 2.1887).abs() < 0.01, "optimum ratio {n}");
        assert!((k_h - K_H).abs() < 1e-4 * K_H, "K_h {k_h} vs {K_H}");
        assert!((c_h - C_H).abs() < 1e-4 * C_H, "c_h {c_h} vs {C_H}");
        // And the friction constant over inclinations 2..5 stays within the documented range.
        for n in [2.0, 3.0, 4.0, 5.0] {
            let (w, f) = slider(n);
            let c = f / w.sqrt();
            assert!((1.80..=1.95).contains(&c), "n {n}: c_h {c}");
        }
    }

    #[test]
    fn force_at_a_hand_point() {
        let l = law("mu_b = 0.1\nc_h = 2.0\nface_width_m = 1e-3\nsigma_m = 1e-6\npreload_n = 100.0\nv_smooth = 1e-9").expect("valid");
        // N 150 N + 100 N preload = 250 N on a 76.8 mm bore: L_c = 2 pi 0.0384 = 0.241274 m,
        // w = 1036.16 N/m; eta U = 0.024 * 2 = 0.048 N/m; h = 0.40030 * 1e-3 * sqrt(4.6325e-5)
        // = 2.7245e-6 m, Lambda = 2.7245.
        let input = slide(2.0, 150.0, 0.024);
        let lc = 2.0 * std::f64::consts::PI * 0.0384;
        let w = 250.0 / lc;
        let film = 0.400_303_8 * 1e-3 * (0.048 / w).sqrt();
        assert!((film - 2.7245e-6).abs() < 1e-9, "{film}");
        let phi = gaussian_integral(2.5, film / 1e-6) / gaussian_integral(2.5, 0.0);
        let fh = 2.0 * (0.048 * 250.0 * lc).sqrt();
        let expected = phi * 0.1 * 250.0 + (1.0 - phi) * fh;
        let c = l.contact(&input);
        assert!((c.lambda - film / 1e-6).abs() < 1e-9);
        assert!((c.share - phi).abs() < 2e-5 * phi);
        let out = l.evaluate(&input, &[]);
        assert!(
            (out.force + expected).abs() < 1e-4 * expected,
            "{} vs {expected}",
            out.force
        );
        assert_eq!(out.regime(), Some(Regime::Mixed));
        assert!((out.coefficient().expect("reported") - expected / 250.0).abs() < 1e-5);
        assert!((out.duty_parameter().expect("reported") - 0.048 / w).abs() < 1e-15);
    }

    /// Contract version 2: the pressure drop across the rings loads the ring from behind. The
    /// law at (N, p_cyl, p_cc) must equal the law at N + (p_cyl - p_cc) 2 pi R h with no gas
    /// (the load is all the film sees), and a reversed drop, a journal or h = 0 add nothing.
    #[test]
    fn gas_pressure_behind_the_ring_adds_its_load() {
        let with_gas = law("ring_gas_height_m = 1e-3").expect("valid");
        let without = law("").expect("valid");
        let mut input = slide(1.5, 120.0, 0.01);
        input.cylinder_pressure_pa = 2.1e6;
        input.crankcase_pressure_pa = 1.0e5;
        // 2.0 MPa on a 1 mm band round a 76.8 mm bore: 2e6 * 2 pi 0.0384 * 1e-3 = 482.55 N.
        let gas_n = 2.0e6 * 2.0 * std::f64::consts::PI * 0.0384 * 1e-3;
        assert!((gas_n - 482.549).abs() < 1e-3, "{gas_n}");
        let loaded = with_gas.contact(&input);
        assert!((loaded.load_n - (120.0 + gas_n)).abs() < 1e-9);
        let reference = without.evaluate(&slide(1.5, 120.0 + gas_n, 0.01), &[]);
        let out = with_gas.evaluate(&input, &[]);
        assert!((out.force - reference.force).abs() <= 1e-12 * reference.force.abs());
        assert!(out.force.abs() > 2.0 * without.evaluate(&input, &[]).force.abs());
        // Reversed drop: nothing added.
        let mut reversed = input;
        reversed.cylinder_pressure_pa = 0.5e5;
        assert_eq!(with_gas.contact(&reversed).load_n, 120.0);
        // A journal sees no ring gas load.
        let mut journal = input;
        journal.joint_kind = JointKind::Revolute as u32;
        journal.contact_length_m = 0.015;
        assert_eq!(with_gas.contact(&journal).load_n, 120.0);
        // Default: off, whatever the pressures.
        assert_eq!(without.contact(&input).load_n, 120.0);
    }

    #[test]
    fn full_film_scales_as_root_viscosity_and_boundary_not_at_all() {
        // Smooth surfaces and a thick film: phi = 0, F = c_h sqrt(eta U W L).
        let film = law("sigma_m = 1e-9\nface_width_m = 0.01\npreload_n = 50.0").expect("valid");
        let a = film.evaluate(&slide(5.0, 100.0, 0.01), &[]).force;
        let b = film.evaluate(&slide(5.0, 100.0, 0.04), &[]).force;
        assert_eq!(film.contact(&slide(5.0, 100.0, 0.01)).share, 0.0);
        assert!((b / a - 2.0).abs() < 1e-12, "ratio {}", b / a);
        // Rough surfaces and a thin film (Lambda < 1e-6, 1 - phi < 1e-5): F = mu_b W whatever eta.
        let rough = law("sigma_m = 1e-4\nface_width_m = 1e-6\nmu_b = 0.12\nv_smooth = 1e-9")
            .expect("valid");
        for eta in [0.005, 0.02, 0.08] {
            let c = rough.contact(&slide(1e-4, 100.0, eta));
            assert!(c.share > 1.0 - 1e-5, "{}", c.share);
            assert!(
                (c.friction_n - 12.0).abs() < 1e-5 * 12.0,
                "{}",
                c.friction_n
            );
        }
    }

    #[test]
    fn film_parameter_rises_with_viscosity_and_speed_and_falls_with_load() {
        let l = law("preload_n = 0.0").expect("valid");
        let lam = |v: f64, n: f64, eta: f64| l.contact(&slide(v, n, eta)).lambda;
        let base = lam(3.0, 200.0, 0.02);
        assert!((lam(3.0, 200.0, 0.08) / base - 2.0).abs() < 1e-12);
        assert!((lam(12.0, 200.0, 0.02) / base - 2.0).abs() < 1e-12);
        assert!((lam(3.0, 800.0, 0.02) / base - 0.5).abs() < 1e-12);
    }

    #[test]
    fn dissipative_over_a_sweep() {
        let l = law("preload_n = 20.0").expect("valid");
        for &v in &[-20.0, -0.3, -1e-6, 0.0, 1e-6, 0.3, 20.0] {
            for &n in &[0.0, 50.0, 5000.0] {
                for &eta in &[0.0, 0.005, 0.02, 0.2] {
                    let f = l.evaluate(&slide(v, n, eta), &[]).force;
                    assert!(f * v <= 0.0 && f.is_finite(), "v={v} n={n} eta={eta} f={f}");
                }
            }
        }
        // A journal: the output is a torque opposing the rotation.
        let mut j = LawInput::at_rest(JointKind::Revolute);
        j.normal_load_n = 500.0;
        j.contact_radius_m = 0.02;
        j.contact_length_m = 0.015;
        j.viscosity_pa_s = 0.02;
        for omega in [-300.0, 300.0] {
            let t = l.evaluate(&j.with_velocity(omega), &[]).force;
            assert!(t * omega < 0.0, "{t}");
        }
    }

    #[test]
    fn rejects_out_of_range_values() {
        assert_eq!(law("mu_b = -0.1").unwrap_err().parameter, "mu_b");
        assert_eq!(law("sigma_m = 0.0").unwrap_err().parameter, "sigma_m");
        assert_eq!(
            law("face_width_m = 1.0").unwrap_err().parameter,
            "face_width_m"
        );
        assert_eq!(law("c_h = 0.0").unwrap_err().parameter, "c_h");
        assert_eq!(law("preload_n = -1.0").unwrap_err().parameter, "preload_n");
        assert!(law("unknown = 1.0").is_err());
    }
}
