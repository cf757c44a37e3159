//! Shear thinning of a polymer-thickened (multigrade) oil (docs/laws/plain-journal.md, "Shear
//! thinning"): Cross's flow equation (M. M. Cross, J. Colloid Sci. 20 (1965) 417),
//!
//! ```text
//! eta(gamma_dot) = eta_inf + (eta_0 - eta_inf) / (1 + (gamma_dot / gamma_c)^m)
//! ```
//!
//! between the low-shear (first Newtonian) viscosity `eta_0` that kinematic viscometers
//! measure and the second Newtonian plateau `eta_inf` near the base oil's, where the viscosity
//! modifier's coils are aligned with the flow. The law states the plateau through the oil's
//! HTHS-like ratio `eta(10^6 1/s) / eta_0` (SAE J300 grades an oil's high-shear viscosity at
//! 150 C and 10^6 1/s), so `eta_inf / eta_0 = (r - F) / (1 - F)` with `F` Cross's fraction at
//! 10^6 1/s. The ratios are taken to hold at every temperature (no time-temperature shift of
//! `gamma_c`), so the thinning is a factor `eta / eta_0` of the shear rate alone.

/// The shear rate at which an oil's high-temperature high-shear viscosity is graded (SAE J300,
/// ASTM D4683), 1/s.
pub const HTHS_RATE_1_S: f64 = 1e6;

/// Cross's model as a factor on the low-shear viscosity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cross {
    /// `eta_inf / eta_0`, the second Newtonian plateau over the low-shear viscosity, in [0, 1].
    pub plateau_ratio: f64,
    /// `gamma_c`, the shear rate halfway between the plateaus, 1/s.
    pub critical_rate_1_s: f64,
    /// `m`, the thinning's exponent.
    pub exponent: f64,
}

/// Why a set of Cross parameters is refused: the HTHS-like ratio asks for more thinning at
/// 10^6 1/s than the curve can give (a plateau below zero).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TooMuchThinning {
    /// The least ratio the curve allows at 10^6 1/s (its plateau at zero).
    pub least_ratio: f64,
}

impl Cross {
    /// The model whose viscosity at 10^6 1/s is `hths_ratio` of the low-shear viscosity.
    pub fn from_hths_ratio(
        hths_ratio: f64,
        critical_rate_1_s: f64,
        exponent: f64,
    ) -> Result<Self, TooMuchThinning> {
        let f = cross_fraction(HTHS_RATE_1_S, critical_rate_1_s, exponent);
        if hths_ratio < f {
            return Err(TooMuchThinning { least_ratio: f });
        }
        Ok(Self {
            plateau_ratio: ((hths_ratio - f) / (1.0 - f)).min(1.0),
            critical_rate_1_s,
            exponent,
        })
    }

    /// `eta / eta_0` at shear rate `rate_1_s` (its magnitude): 1 at rest, falling to the
    /// plateau ratio.
    pub fn factor(&self, rate_1_s: f64) -> f64 {
        let f = cross_fraction(rate_1_s.abs(), self.critical_rate_1_s, self.exponent);
        self.plateau_ratio + (1.0 - self.plateau_ratio) * f
    }
}

impl Cross {
    /// `d(eta gamma_dot) / d gamma_dot / eta_0` at `rate_1_s`: the shear stress's slope in the
    /// shear rate over the low-shear viscosity, `factor + gamma_dot d factor / d gamma_dot`
    /// (what a film's force per unit sliding speed changes by).
    pub fn stress_slope(&self, rate_1_s: f64) -> f64 {
        let x = (rate_1_s.abs() / self.critical_rate_1_s).powf(self.exponent);
        let f = 1.0 / (1.0 + x);
        self.plateau_ratio + (1.0 - self.plateau_ratio) * f * (1.0 - self.exponent * x * f)
    }
}

/// `1 / (1 + (rate / critical)^m)`: the share of the polymer's thickening left at `rate`.
fn cross_fraction(rate_1_s: f64, critical_rate_1_s: f64, exponent: f64) -> f64 {
    1.0 / (1.0 + (rate_1_s / critical_rate_1_s).powf(exponent))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The factor is Cross's equation written out by hand, the plateau follows from the HTHS
    /// ratio, and at 10^6 1/s the factor is that ratio.
    #[test]
    fn the_factor_is_cross_equation() {
        let c = Cross::from_hths_ratio(0.85, 1e6, 2.0 / 3.0).expect("cross");
        // At gamma_c Cross's fraction is one half: 0.85 = p + (1 - p) / 2.
        assert!(
            (c.plateau_ratio - 0.70).abs() < 1e-15,
            "{}",
            c.plateau_ratio
        );
        assert!((c.factor(1e6) - 0.85).abs() < 1e-15);
        for rate in [0.0, 1e3, 1.3e5, 4e5, 9.2e5, 3e6, 1e9] {
            let by_hand = 0.70 + 0.30 / (1.0 + (rate / 1e6f64).powf(2.0 / 3.0));
            assert!(
                (c.factor(rate) - by_hand).abs() < 1e-15,
                "{rate}: {} vs {by_hand}",
                c.factor(rate)
            );
            assert_eq!(c.factor(-rate), c.factor(rate));
        }
        assert_eq!(c.factor(0.0), 1.0);
        assert!((c.factor(1e12) - 0.70).abs() < 1e-4);
        // Another critical rate: the plateau moves so that 10^6 1/s still gives the ratio.
        let c = Cross::from_hths_ratio(0.9, 3e5, 1.0).expect("cross");
        assert!((c.factor(1e6) - 0.9).abs() < 1e-15);
    }

    /// The stress slope is the derivative of `factor(rate) rate` (central differences), and
    /// stays positive (the stress rises with the rate: the Cross curve with `m <= 1` does not
    /// turn back).
    #[test]
    fn the_stress_slope_is_the_derivative_of_the_stress() {
        for m in [0.5, 2.0 / 3.0, 1.0] {
            let c = Cross::from_hths_ratio(0.85, 1e6, m).expect("cross");
            for rate in [1e2, 1e4, 3e5, 1e6, 4e6, 1e8] {
                let e = 1e-5 * rate;
                let stress = |g: f64| c.factor(g) * g;
                let fd = (stress(rate + e) - stress(rate - e)) / (2.0 * e);
                let slope = c.stress_slope(rate);
                assert!(
                    slope > 0.0 && (slope - fd).abs() < 1e-7,
                    "{m} {rate}: {slope} vs {fd}"
                );
            }
        }
    }

    /// A ratio of one is no thinning at any rate; a ratio below the curve's least is refused.
    #[test]
    fn a_ratio_of_one_is_newtonian_and_too_low_a_ratio_is_refused() {
        let c = Cross::from_hths_ratio(1.0, 1e6, 2.0 / 3.0).expect("cross");
        for rate in [0.0, 1e5, 1e6, 1e8] {
            assert_eq!(c.factor(rate), 1.0);
        }
        let e = Cross::from_hths_ratio(0.4, 1e6, 1.0).expect_err("below the plateau at zero");
        assert_eq!(e.least_ratio, 0.5);
    }
}
