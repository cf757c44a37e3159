//! `crank-churning`: the drag of crank webs and counterweights dipping into the oil sump, from
//! Changenet and Velex's churning correlation for a partially immersed rotating disc or gear
//! (C. Changenet, P. Velex, "A model for the prediction of churning losses in geared
//! transmissions: preliminary results", ASME J. Mech. Design 129(1), 2007, pp. 128-133).
//!
//! ```text
//! T    = 1/2 rho omega^2 S_m R^3 C_m                  per disc, times the number of discs
//! S_m  = 2 R^2 (a - sin a cos a) + 2 a R b,  a = acos(1 - h/R)   wetted faces and rim
//! Fr   = omega^2 R / g,  Re_c = omega R b / nu,  nu = mu / rho
//! C_m  = 1.366 (h/D)^0.45 (V0/D^3)^0.1 Fr^-0.6 Re_c^-0.21          Re_c <= 6000
//! C_m  = 3.644 (h/D)^0.1 (V0/D^3)^-0.35 Fr^-0.88 (b/D)^0.85        Re_c >= 9000
//! ```
//!
//! `R` the disc's (web's) outer radius, `D = 2R`, `b` its width (web thickness), `h` the
//! immersion depth of its lowest point, `V0` the oil volume in the sump, `rho` the oil's
//! density, `mu` its dynamic viscosity (the law's input), `omega` the crank's speed relative
//! to the block. Between `Re_c` 6000 and 9000, where the paper's two regimes meet, `C_m` is
//! interpolated linearly in `ln Re_c` between the two formulas (this law's choice; the paper
//! gives no formula there). The correlation was fitted on spur gears; a crank web is a disc
//! without teeth, so applying it to webs is an extrapolation, and a counterweight that is not
//! a full disc dips only over part of the revolution (`discs` may be fractional to say so).
//! Attach it to one main bearing of a rig whose crank runs in a wet sump.

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{export_law, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec};

/// Gravity, m/s^2.
const G: f64 = 9.81;

/// Parameters of [`CrankChurning`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Outer radius of a web or counterweight, m.
    pub disc_radius_m: f64,
    /// Web thickness along the crank axis, m.
    pub disc_width_m: f64,
    /// Number of webs dipping (may be fractional: a counterweight sweeping part of a circle).
    pub discs: f64,
    /// Immersion depth of the web's lowest point below the oil surface, m.
    pub immersion_m: f64,
    /// Oil volume in the sump, m^3.
    pub oil_volume_m3: f64,
    /// Oil density, kg/m^3.
    pub density_kg_m3: f64,
}

impl Default for Params {
    fn default() -> Self {
        // The CRF 250 R crank (thesis 8.1: it "rotates in the oil bath in the sump", 0.7 l).
        Self {
            disc_radius_m: 0.060, // estimate: two-web crank with ~60 mm webs (physics notes 9)
            disc_width_m: 0.015,  // estimate: web thickness of a 250 cc single, 12-18 mm
            discs: 2.0,           // two webs
            immersion_m: 0.010,   // estimate: oil level at the dip-stick maximum, unpublished
            oil_volume_m3: 0.7e-3, // [T 8.1] about 0.7 l in the crank sump
            density_kg_m3: 860.0, // estimate: typical 10W-50 (physics notes 6)
        }
    }
}

/// The churning law (crate docs).
#[derive(Debug, Clone)]
pub struct CrankChurning {
    p: Params,
}

/// What the correlation gives at one speed: every intermediate, for reports and tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Churning {
    /// Wetted surface of one disc, m^2.
    pub wetted_m2: f64,
    /// Froude number.
    pub froude: f64,
    /// Reynolds number `omega R b / nu`.
    pub reynolds: f64,
    /// Dimensionless drag torque.
    pub c_m: f64,
    /// Drag torque of all discs, N m (positive).
    pub torque_nm: f64,
}

impl CrankChurning {
    /// The correlation at crank speed `omega` (rad/s, any sign) with oil of dynamic viscosity
    /// `mu` (Pa s).
    pub fn churning(&self, omega: f64, mu: f64) -> Churning {
        let p = &self.p;
        let (r, b, h) = (
            p.disc_radius_m,
            p.disc_width_m,
            p.immersion_m.min(2.0 * p.disc_radius_m),
        );
        let d = 2.0 * r;
        let a = (1.0 - h / r).clamp(-1.0, 1.0).acos();
        let wetted = 2.0 * r * r * (a - a.sin() * a.cos()) + 2.0 * a * r * b;
        let w = omega.abs();
        let froude = w * w * r / G;
        let nu = mu / p.density_kg_m3;
        let reynolds = if nu > 0.0 {
            w * r * b / nu
        } else {
            f64::INFINITY
        };
        let low = |re: f64| {
            1.366
                * (h / d).powf(0.45)
                * (p.oil_volume_m3 / d.powi(3)).powf(0.1)
                * froude.powf(-0.6)
                * re.powf(-0.21)
        };
        let high = 3.644
            * (h / d).powf(0.1)
            * (p.oil_volume_m3 / d.powi(3)).powf(-0.35)
            * froude.powf(-0.88)
            * (b / d).powf(0.85);
        let c_m = if reynolds <= 6000.0 {
            low(reynolds)
        } else if reynolds >= 9000.0 {
            high
        } else {
            let t = (reynolds / 6000.0).ln() / (9000.0f64 / 6000.0).ln();
            low(6000.0) + t * (high - low(6000.0))
        };
        let torque = if w > 0.0 && h > 0.0 {
            0.5 * p.density_kg_m3 * w * w * wetted * r.powi(3) * c_m * p.discs
        } else {
            0.0
        };
        Churning {
            wetted_m2: wetted,
            froude,
            reynolds,
            c_m,
            torque_nm: torque,
        }
    }
}

impl Law for CrankChurning {
    type Params = Params;
    const NAME: &'static str = "crank-churning";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str =
        "Crank webs churning the sump oil (Changenet-Velex 2007 correlation for partially immersed discs)";

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "disc_radius_m",
                "m",
                "outer radius of a crank web or counterweight",
                1e-3,
                1.0,
            ),
            ParamSpec::number(
                "disc_width_m",
                "m",
                "web thickness along the crank axis",
                1e-4,
                0.5,
            ),
            ParamSpec::number(
                "discs",
                "-",
                "number of webs dipping into the oil (fractional: part of a circle)",
                0.0,
                32.0,
            ),
            ParamSpec::number(
                "immersion_m",
                "m",
                "immersion depth of the web's lowest point (0: no churning)",
                0.0,
                1.0,
            ),
            ParamSpec::number("oil_volume_m3", "m^3", "oil volume in the sump", 1e-6, 1.0),
            ParamSpec::number("density_kg_m3", "kg/m^3", "oil density", 500.0, 1200.0),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        if p.immersion_m > 2.0 * p.disc_radius_m {
            return Err(ParamError::new(
                "immersion_m",
                format!(
                    "an immersion of {} m drowns a web of radius {} m (at most its diameter)",
                    p.immersion_m, p.disc_radius_m
                ),
            ));
        }
        Ok(Self { p })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        if input.kind() != Some(JointKind::Revolute) {
            // Churning acts on a rotating crank: on a slide it has no meaning.
            return LawOutput::force(0.0);
        }
        let w = input.relative_velocity;
        let c = self.churning(w, input.viscosity_pa_s.max(0.0));
        LawOutput::force(-c.torque_nm.copysign(w))
    }
}

export_law!(CrankChurning);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> CrankChurning {
        create_from_table::<CrankChurning>(&text.parse().expect("toml")).expect("valid")
    }

    #[test]
    fn conforms() {
        assert_law_conforms::<CrankChurning>();
        assert_law_conforms_with::<CrankChurning>("immersion_m = 0.05\ndiscs = 4.0");
    }

    /// The correlation evaluated independently (a separate script, the steps written out
    /// below) for two 60 mm webs, 15 mm thick, dipping 10 mm into 0.7 l of oil of 860 kg/m^3:
    /// the wetted half angle a = acos(1 - 10/60) = 0.585686 rad, S_m = 1.954545e-3 m^2; at
    /// 1000 rpm with 24.9 mPa s, Fr = 67.0717, Re_c = 3255.14 (low regime), C_m = 5.984269e-3,
    /// T = 2.382683e-2 N m; at 3000 rpm Re_c = 9765.43 (high regime), C_m = 2.378491e-3,
    /// T = 8.523133e-2 N m; at 2000 rpm Re_c = 6510.29 (between the regimes), C_m =
    /// 2.807141e-3, T = 4.470740e-2 N m; at 3000 rpm with 98.9 mPa s Re_c = 2458.64 (low),
    /// T = 6.086353e-2 N m.
    #[test]
    fn torque_equals_the_correlation_evaluated_by_hand() {
        let l = law("");
        for (rpm, mu, re, c_m, torque) in [
            (1000.0, 0.0249, 3255.144, 5.984269e-3, 2.382683e-2),
            (2000.0, 0.0249, 6510.288, 2.807141e-3, 4.470740e-2),
            (3000.0, 0.0249, 9765.433, 2.378491e-3, 8.523133e-2),
            (9000.0, 0.0249, 29296.298, 3.440077e-4, 1.109452e-1),
            (3000.0, 0.0989, 2458.638, 1.698476e-3, 6.086353e-2),
        ] {
            let w = rpm * std::f64::consts::PI / 30.0;
            let c = l.churning(w, mu);
            assert!((c.wetted_m2 - 1.954545e-3).abs() < 1e-9);
            assert!(
                (c.reynolds - re).abs() < 1e-3 * re * 1e-3,
                "{rpm}: Re {}",
                c.reynolds
            );
            assert!((c.c_m - c_m).abs() < 1e-6 * c_m, "{rpm}: C_m {}", c.c_m);
            assert!(
                (c.torque_nm - torque).abs() < 1e-6 * torque,
                "{rpm}: {}",
                c.torque_nm
            );
            let mut i = LawInput::at_rest(JointKind::Revolute);
            i.viscosity_pa_s = mu;
            let out = l.evaluate(&i.with_velocity(-w), &[]);
            assert!(
                (out.force - torque).abs() < 1e-6 * torque,
                "opposes the rotation"
            );
        }
    }

    /// No immersion, no churning; deeper immersion and more discs churn more.
    #[test]
    fn immersion_and_discs_scale_the_drag() {
        let w = 600.0;
        assert_eq!(law("immersion_m = 0.0").churning(w, 0.02).torque_nm, 0.0);
        let shallow = law("immersion_m = 0.005").churning(w, 0.02).torque_nm;
        let deep = law("immersion_m = 0.02").churning(w, 0.02).torque_nm;
        assert!(deep > shallow && shallow > 0.0);
        let two = law("discs = 2.0").churning(w, 0.02).torque_nm;
        let four = law("discs = 4.0").churning(w, 0.02).torque_nm;
        assert!((four - 2.0 * two).abs() < 1e-12 * four);
    }

    #[test]
    fn a_drowned_disc_is_refused() {
        let e = create_from_table::<CrankChurning>(
            &"disc_radius_m = 0.05\nimmersion_m = 0.2"
                .parse()
                .expect("toml"),
        )
        .unwrap_err();
        assert_eq!(e.parameter, "immersion_m");
    }
}
