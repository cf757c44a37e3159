//! `lip-seal`: the drag of an elastomer radial lip seal on a rotating shaft (a crankshaft's
//! front and rear oil seals), as viscous shear in the thin oil film under the lip, with the
//! lip's own heat balance.
//!
//! ```text
//! u      = omega r                                        shaft surface speed, r = d / 2
//! P(mu)  = mu u^2 pi d b / h                              Couette shear power of the film
//! dT     = P(mu_lip) / (g pi d)                           lip above the sump: heat conducted away
//! mu_lip = mu_sump * nu(T_sump + dT) / nu(T_sump)         the oil's Walther line (ASTM D341)
//! T      = P(mu_lip) / omega                              torque opposing the rotation
//! ```
//!
//! `d` the shaft diameter at the lip, `b` the width of the lip's contact band, `h` the film
//! thickness under it, `g` the heat the lip and shaft carry away per metre of lip circumference
//! and kelvin of lip temperature above the sump, `mu_sump` the oil's viscosity at the sump
//! temperature (the law's input), `nu` the oil's kinematic viscosity on its Walther line
//! through `oil_kv40_cst` and `oil_kv100_cst`. The film is taken as the lip's roughness holds it
//! (micro-asperity lubrication: a film of the order of 1 um whose thickness hardly changes with
//! speed), so the shear is Couette; the heat balance makes the torque rise much less than
//! linearly with speed and fall much less than the sump viscosity with warmer oil: the hotter
//! the lip runs, the thinner its film's oil. A breakaway (static) torque at rest and the garter
//! spring's boundary friction are not modelled: the law is for a running engine.
//! Details, sources and the sweep: docs/laws/lip-seal.md.

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{export_law, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec};

/// Parameters of [`LipSeal`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Shaft diameter under the lip, m.
    pub shaft_diameter_m: f64,
    /// Width of the lip's contact band on the shaft, m.
    pub contact_width_m: f64,
    /// Oil film thickness under the lip, m.
    pub film_thickness_m: f64,
    /// Heat carried away from the lip per metre of circumference and kelvin above the sump,
    /// W/(m K); `0` switches the heat balance off (the film shears at the sump's viscosity).
    pub conductance_w_m_k: f64,
    /// The oil's kinematic viscosity at 40 C, cSt (its Walther line, for the lip's heating).
    pub oil_kv40_cst: f64,
    /// The oil's kinematic viscosity at 100 C, cSt.
    pub oil_kv100_cst: f64,
    /// Number of identical seals this entry stands for.
    pub seals: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            shaft_diameter_m: 0.085, // estimate: a rear crankshaft seal of a 2.0 L inline-4 (docs/laws/lip-seal.md)
            contact_width_m: 0.15e-3, // estimate: a new lip's band, 0.1-0.2 mm (docs/laws/lip-seal.md)
            film_thickness_m: 1.0e-6, // estimate: lip films of the order of 1 um, 0.25-2.5 um
            conductance_w_m_k: 7.0,   // estimate: a lip 20-40 K above the sump at 10-15 m/s
            oil_kv40_cst: 65.0,       // estimate: a typical 5W-30 (rigs/inline4-4b11.toml)
            oil_kv100_cst: 11.0,      // estimate: a typical 5W-30
            seals: 1.0,
        }
    }
}

/// The seal law (crate docs).
#[derive(Debug, Clone)]
pub struct LipSeal {
    p: Params,
    /// Walther slope of the oil, `B` in log10 log10(nu + 0.7) = A - B log10(T_K).
    walther_b: f64,
}

/// What the law gives at one speed and sump state: every intermediate, for reports and tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seal {
    /// Shear power of the films of all seals, W.
    pub power_w: f64,
    /// Lip temperature above the sump, K.
    pub lip_rise_k: f64,
    /// The film's dynamic viscosity at the lip, Pa s.
    pub lip_viscosity_pa_s: f64,
    /// Torque of all seals, N m (positive).
    pub torque_nm: f64,
}

/// Kelvin at 0 C.
const KELVIN: f64 = 273.15;

/// ASTM D341's `log10 log10(nu + 0.7)` of a kinematic viscosity in cSt.
fn loglog(nu_cst: f64) -> f64 {
    (nu_cst + 0.7).log10().log10()
}

/// The Walther slope `B` of an oil through its 40 C and 100 C viscosities.
fn walther_slope(kv40: f64, kv100: f64) -> f64 {
    (loglog(kv40) - loglog(kv100)) / ((100.0 + KELVIN).log10() - (40.0 + KELVIN).log10())
}

impl LipSeal {
    /// The oil's kinematic viscosity at `t_c` over that at `t0_c`, on its Walther line (the
    /// line's level cancels: only the slope matters, so the host's viscosity sets the level).
    fn viscosity_ratio(&self, t0_c: f64, t_c: f64) -> f64 {
        let nu = |t: f64| {
            let ll = loglog(self.p.oil_kv40_cst)
                - self.walther_b * ((t + KELVIN).log10() - (40.0 + KELVIN).log10());
            10f64.powf(10f64.powf(ll)) - 0.7
        };
        let (a, b) = (nu(t0_c), nu(t_c));
        if a > 0.0 && b > 0.0 {
            b / a
        } else {
            1.0
        }
    }

    /// The seal at shaft speed `omega` (rad/s, any sign) with oil of viscosity `mu_sump`
    /// (Pa s) at `sump_c` (C).
    pub fn seal(&self, omega: f64, mu_sump: f64, sump_c: f64) -> Seal {
        let p = &self.p;
        let r = 0.5 * p.shaft_diameter_m;
        let u = omega.abs() * r;
        let circumference = std::f64::consts::PI * p.shaft_diameter_m;
        // Film power per unit viscosity, W/(Pa s), of all seals.
        let shear = u * u * circumference * p.contact_width_m / p.film_thickness_m * p.seals;
        let power = |rise: f64| mu_sump * self.viscosity_ratio(sump_c, sump_c + rise) * shear;
        let conductance = p.conductance_w_m_k * circumference * p.seals;
        let rise = if conductance > 0.0 && shear > 0.0 && mu_sump > 0.0 {
            // rise - P(rise)/G is negative at 0 and positive at P(0)/G (P falls as the lip
            // warms): bisect to the root.
            let (mut lo, mut hi) = (0.0, power(0.0) / conductance);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if mid - power(mid) / conductance > 0.0 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            0.5 * (lo + hi)
        } else {
            0.0
        };
        let power_w = power(rise).max(0.0);
        Seal {
            power_w,
            lip_rise_k: rise,
            lip_viscosity_pa_s: mu_sump * self.viscosity_ratio(sump_c, sump_c + rise),
            torque_nm: if u > 0.0 { power_w / omega.abs() } else { 0.0 },
        }
    }
}

impl Law for LipSeal {
    type Params = Params;
    const NAME: &'static str = "lip-seal";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str =
        "Radial lip seal on a rotating shaft: Couette shear of the film under the lip, with the lip's heat balance";

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "shaft_diameter_m",
                "m",
                "shaft diameter under the lip",
                1e-3,
                1.0,
            ),
            ParamSpec::number(
                "contact_width_m",
                "m",
                "width of the lip's contact band",
                1e-5,
                2e-3,
            ),
            ParamSpec::number(
                "film_thickness_m",
                "m",
                "oil film thickness under the lip",
                1e-8,
                1e-4,
            ),
            ParamSpec::number(
                "conductance_w_m_k",
                "W/(m K)",
                "heat carried from the lip per metre of circumference and kelvin (0: isothermal)",
                0.0,
                1e4,
            ),
            ParamSpec::number(
                "oil_kv40_cst",
                "cSt",
                "oil kinematic viscosity at 40 C (Walther line for the lip's heating)",
                1.0,
                1e4,
            ),
            ParamSpec::number(
                "oil_kv100_cst",
                "cSt",
                "oil kinematic viscosity at 100 C",
                0.5,
                1e3,
            ),
            ParamSpec::number(
                "seals",
                "-",
                "number of identical seals this entry stands for",
                0.0,
                16.0,
            ),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        if p.oil_kv40_cst <= p.oil_kv100_cst {
            return Err(ParamError::new(
                "oil_kv40_cst",
                format!(
                    "an oil thins as it warms: expected oil_kv40_cst ({}) above oil_kv100_cst ({})",
                    p.oil_kv40_cst, p.oil_kv100_cst
                ),
            ));
        }
        let walther_b = walther_slope(p.oil_kv40_cst, p.oil_kv100_cst);
        Ok(Self { p, walther_b })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        if input.kind() != Some(JointKind::Revolute) {
            // A rotary seal acts on a turning shaft: on a slide it has no meaning.
            return LawOutput::force(0.0);
        }
        let w = input.relative_velocity;
        let s = self.seal(w, input.viscosity_pa_s.max(0.0), input.oil_temp_c);
        LawOutput::force(-s.torque_nm.copysign(w))
    }
}

export_law!(LipSeal);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> LipSeal {
        create_from_table::<LipSeal>(&text.parse().expect("toml")).expect("valid")
    }

    #[test]
    fn conforms() {
        assert_law_conforms::<LipSeal>();
        assert_law_conforms_with::<LipSeal>("shaft_diameter_m = 0.042\nconductance_w_m_k = 0.0");
    }

    /// Without the heat balance the film is Couette flow: the torque integrated by hand over
    /// the band, tau = mu u / h on the area pi d b at radius d/2, for an 85 mm shaft, a
    /// 0.15 mm band and a 1 um film at 3000 rpm and 10 mPa s:
    /// u = 314.159 * 0.0425 = 13.3518 m/s, tau = 0.01 * 13.3518 / 1e-6 = 133 518 Pa,
    /// area = pi * 0.085 * 1.5e-4 = 4.00553e-5 m^2, T = 133 518 * 4.00553e-5 * 0.0425
    /// = 0.227295 N m.
    #[test]
    fn isothermal_torque_is_couette_shear_over_the_band() {
        let l = law("conductance_w_m_k = 0.0");
        let w = 3000.0 * std::f64::consts::PI / 30.0;
        let s = l.seal(w, 0.01, 90.0);
        assert!((s.torque_nm - 0.227295).abs() < 1e-5, "{}", s.torque_nm);
        assert_eq!(s.lip_rise_k, 0.0);
        // Linear in viscosity and speed, and two seals twice one.
        let s2 = l.seal(2.0 * w, 0.02, 90.0);
        assert!((s2.torque_nm - 4.0 * s.torque_nm).abs() < 1e-9);
        let two = law("conductance_w_m_k = 0.0\nseals = 2.0").seal(w, 0.01, 90.0);
        assert!((two.torque_nm - 2.0 * s.torque_nm).abs() < 1e-12);
        // Opposes the rotation either way.
        let mut i = LawInput::at_rest(JointKind::Revolute);
        i.viscosity_pa_s = 0.01;
        i.oil_temp_c = 90.0;
        for sign in [1.0, -1.0] {
            let out = l.evaluate(&i.with_velocity(sign * w), &[]);
            assert!((out.force + sign * s.torque_nm).abs() < 1e-12);
        }
    }

    /// The heat balance closes: the lip's rise is the film's power over the conductance, the
    /// power is the Couette power at the viscosity of the lip's temperature on the oil's
    /// Walther line (computed here from ASTM D341 independently of the law's own function),
    /// and torque times speed is the power.
    #[test]
    fn the_lip_heat_balance_closes() {
        let l = law("");
        let (kv40, kv100) = (65.0_f64, 11.0_f64);
        let ll = |nu: f64| (nu + 0.7_f64).log10().log10();
        let b = (ll(kv40) - ll(kv100)) / (373.15_f64.log10() - 313.15_f64.log10());
        let nu_at = |t: f64| {
            10f64.powf(10f64.powf(ll(kv40) - b * ((t + 273.15_f64).log10() - 313.15_f64.log10())))
                - 0.7
        };
        // The line passes through both points.
        assert!((nu_at(100.0) - kv100).abs() < 1e-9 * kv100);
        for rpm in [1000.0, 3000.0, 6000.0] {
            let w = rpm * std::f64::consts::PI / 30.0;
            let mu = 0.0118;
            let s = l.seal(w, mu, 90.0);
            let lip_mu = mu * nu_at(90.0 + s.lip_rise_k) / nu_at(90.0);
            assert!(
                (s.lip_viscosity_pa_s - lip_mu).abs() < 1e-9 * lip_mu,
                "{rpm}"
            );
            let u = w * 0.0425;
            let couette = lip_mu * u * u * std::f64::consts::PI * 0.085 * 1.5e-4 / 1e-6;
            assert!((s.power_w - couette).abs() < 1e-6 * couette, "{rpm}");
            let g = 7.0 * std::f64::consts::PI * 0.085;
            assert!(
                (s.lip_rise_k - s.power_w / g).abs() < 1e-6 * s.lip_rise_k,
                "{rpm}"
            );
            assert!((s.torque_nm * w - s.power_w).abs() < 1e-9 * s.power_w);
        }
    }

    /// The trends and their reasons: faster runs hotter (rise grows with speed), so the
    /// torque grows much less than linearly; a warmer sump thins the film but the lip's own
    /// heating then falls, so the torque falls much less than the sump viscosity.
    #[test]
    fn heat_balance_softens_the_speed_and_temperature_trends() {
        let l = law("");
        let w = |rpm: f64| rpm * std::f64::consts::PI / 30.0;
        let (t1, t6) = (
            l.seal(w(1000.0), 0.0118, 90.0),
            l.seal(w(6000.0), 0.0118, 90.0),
        );
        assert!(t6.lip_rise_k > t1.lip_rise_k);
        assert!(t6.torque_nm > t1.torque_nm && t6.torque_nm < 6.0 * t1.torque_nm);
        // 40 C sump: 65 cSt; 110 C: about 8.5 cSt (the Walther line): d ln T / d ln mu < 1.
        let r = l.viscosity_ratio(40.0, 110.0);
        let (cold, hot) = (
            l.seal(w(3000.0), 0.055, 40.0),
            l.seal(w(3000.0), 0.055 * r, 110.0),
        );
        let sens = (cold.torque_nm / hot.torque_nm).ln() / (1.0 / r).ln();
        assert!(sens > 0.0 && sens < 1.0, "d ln T / d ln mu = {sens}");
    }

    /// Validation against a published seal-loss relation: ISO/TR 14179-2 (the thermal
    /// capacity of gear units) gives a radial lip seal's power loss as P = 7.69e-6 d^2 n W with
    /// the shaft diameter `d` in mm and the speed `n` in rpm (the seal method the FVA Workbench's
    /// loss documentation lists; public gear-loss codes transcribe the same constant), that is
    /// a torque of 7.69e-6 d^2 * 60 / (2 pi) = 7.343e-5 d^2 N m at every speed: 0.5306 N m on an
    /// 85 mm shaft, 0.1175 N m on a 40 mm one. The law with its bundled estimates (the 4B11's
    /// 85 mm rear and 40 mm front seals, its 5W-30 at 40-110 C: 55.3, 19.7, 11.7, 7.6 mPa s) is
    /// asked to be within a factor 1.5 of it, the spread of one seal type's measured friction
    /// between new and run-in lips.
    ///
    /// Not met: the law is 2-20 times below the relation (3-12 times at 90 C; closest on cold
    /// oil); the film (1 um) and the band (0.15 mm) are estimates, and the relation is a
    /// temperature-blind design value for industrial seals, so neither side settles the level
    /// (docs/laws/lip-seal.md, "Validation"). Run it with `cargo test --release -p
    /// tribo-law-lip-seal -- --ignored against_iso`.
    #[test]
    #[ignore = "not met: the law is 2-20x below ISO/TR 14179-2's seal loss, 3-12x at 90 C (docs/laws/lip-seal.md, Validation)"]
    fn the_seal_torque_against_iso_tr_14179_2() {
        let mut failures = Vec::new();
        for (d_mm, shaft) in [(85.0_f64, 0.085), (40.0, 0.040)] {
            let l = law(&format!("shaft_diameter_m = {shaft}"));
            let iso = 7.69e-6 * d_mm * d_mm * 60.0 / (2.0 * std::f64::consts::PI);
            for (t_c, mu) in [
                (40.0, 0.0553),
                (70.0, 0.0197),
                (90.0, 0.0117),
                (110.0, 0.0076),
            ] {
                for rpm in [1000.0, 3000.0, 6000.0] {
                    let w = rpm * std::f64::consts::PI / 30.0;
                    let ratio = l.seal(w, mu, t_c).torque_nm / iso;
                    if !(1.0 / 1.5..=1.5).contains(&ratio) {
                        failures.push(format!("{d_mm} mm, {t_c} C, {rpm} rpm: {ratio:.2}"));
                    }
                }
            }
        }
        assert!(failures.is_empty(), "law / ISO/TR 14179-2: {failures:#?}");
    }

    /// What the published relations agree on and the law reproduces in part, without any
    /// fitting: the seal torque hardly depends on speed (ISO/TR 14179-2's torque and the
    /// Patton-Nitschke-Heywood seal term are speed-independent), because the lip's film heats
    /// with the power it shears. From 1000 to 6000 rpm at 90 C an isothermal film's torque
    /// grows 6 times; the law's rear seal (85 mm, the one that heats most: power grows as d^3,
    /// the conductance as d) by less than 3, the front seal (40 mm) by less than 6 and more
    /// than the rear.
    #[test]
    fn the_seal_torque_flattens_in_speed_towards_the_published_relations() {
        let w = |rpm: f64| rpm * std::f64::consts::PI / 30.0;
        let growth = |shaft: f64| {
            let l = law(&format!("shaft_diameter_m = {shaft}"));
            l.seal(w(6000.0), 0.0117, 90.0).torque_nm / l.seal(w(1000.0), 0.0117, 90.0).torque_nm
        };
        let (rear, front) = (growth(0.085), growth(0.040));
        assert!(rear > 1.0 && rear < 3.0, "rear x{rear:.2}");
        assert!(front > rear && front < 6.0, "front x{front:.2}");
    }

    #[test]
    fn an_oil_that_thickens_as_it_warms_is_refused() {
        let e = create_from_table::<LipSeal>(
            &"oil_kv40_cst = 10.0\noil_kv100_cst = 11.0"
                .parse()
                .expect("toml"),
        )
        .unwrap_err();
        assert_eq!(e.parameter, "oil_kv40_cst");
    }
}
