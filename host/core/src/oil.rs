//! Oil viscosity against temperature.

use tribo_plugin_api::serde::{Deserialize, Serialize};
use tribo_plugin_api::tribology::WaltherLine;

/// How kinematic viscosity depends on temperature.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(crate = "tribo_plugin_api::serde")]
#[serde(tag = "model", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ViscosityModel {
    /// Vogel: nu = k * exp(theta1 / (T + theta2)), nu in cSt, T in C.
    Vogel {
        /// k, cSt.
        k_cst: f64,
        /// theta1, C.
        theta1_c: f64,
        /// theta2, C.
        theta2_c: f64,
    },
    /// Walther / ASTM D341 through two kinematic viscosities at 40 and 100 C:
    /// log10(log10(nu + 0.7)) = A - B log10(T_K).
    TwoPoint {
        /// Kinematic viscosity at 40 C, cSt.
        kv40_cst: f64,
        /// Kinematic viscosity at 100 C, cSt.
        kv100_cst: f64,
    },
}

/// Temperatures at which the viscosity models are trusted, C. Outside this range they are
/// extrapolations (ASTM D341 charts and Vogel fits are made from 40 and 100 C data), so a rig
/// asking for them is rejected rather than silently extrapolated.
pub const VALID_RANGE_C: (f64, f64) = (-20.0, 160.0);

impl ViscosityModel {
    /// The model and its constants in one line, as a user would write them back (`vogel k_cst=...`),
    /// so a report says exactly which curve produced its viscosities.
    pub fn describe(&self) -> String {
        match *self {
            Self::Vogel {
                k_cst,
                theta1_c,
                theta2_c,
            } => format!("Vogel k_cst={k_cst} theta1_c={theta1_c} theta2_c={theta2_c}"),
            Self::TwoPoint {
                kv40_cst,
                kv100_cst,
            } => format!("Walther/ASTM D341 two-point kv40_cst={kv40_cst} kv100_cst={kv100_cst}"),
        }
    }

    /// Kinematic viscosity in cSt (mm^2/s) at `t_c` degrees Celsius.
    ///
    /// The two-point model passes through its two points and thins monotonically between them:
    ///
    /// ```
    /// use tribo_core::oil::ViscosityModel;
    ///
    /// let oil = ViscosityModel::TwoPoint { kv40_cst: 115.0, kv100_cst: 17.5 };
    /// assert!((oil.kinematic_cst(40.0) - 115.0).abs() < 1e-9);
    /// assert!((oil.kinematic_cst(100.0) - 17.5).abs() < 1e-9);
    /// assert!(oil.kinematic_cst(80.0) < oil.kinematic_cst(60.0));
    /// // Vogel: nu = k exp(theta1 / (T + theta2)); at 0 C that is k e^10 here.
    /// let vogel = ViscosityModel::Vogel { k_cst: 0.1, theta1_c: 1000.0, theta2_c: 100.0 };
    /// assert!((vogel.kinematic_cst(0.0) - 0.1 * 10f64.exp()).abs() < 1e-12);
    /// ```
    pub fn kinematic_cst(&self, t_c: f64) -> f64 {
        match *self {
            Self::Vogel {
                k_cst,
                theta1_c,
                theta2_c,
            } => k_cst * (theta1_c / (t_c + theta2_c)).exp(),
            Self::TwoPoint {
                kv40_cst,
                kv100_cst,
            } => WaltherLine::through_40_100(kv40_cst, kv100_cst).kinematic_cst(t_c),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_point_model_reproduces_its_points() {
        let m = ViscosityModel::TwoPoint {
            kv40_cst: 115.0,
            kv100_cst: 17.5,
        };
        assert!((m.kinematic_cst(40.0) - 115.0).abs() < 1e-9);
        assert!((m.kinematic_cst(100.0) - 17.5).abs() < 1e-9);
        let mid = m.kinematic_cst(80.0);
        assert!(mid > 17.5 && mid < 115.0);
    }

    #[test]
    fn vogel_evaluates_its_formula_and_thins_as_the_oil_warms() {
        // nu = k exp(theta1 / (T + theta2)), checked where the exponent is a round number: at
        // T = theta1 / n - theta2 the viscosity is k e^n exactly (constants: a Vogel fit of an
        // SAE 10W-50 used as an example, estimate; any positive constants would do).
        let (k, theta1, theta2) = (0.1153, 1105.2, 120.06);
        let m = ViscosityModel::Vogel {
            k_cst: k,
            theta1_c: theta1,
            theta2_c: theta2,
        };
        for n in [4.0_f64, 5.0, 5.5, 6.0, 8.0] {
            let t = theta1 / n - theta2;
            let want = k * n.exp();
            assert!(
                (m.kinematic_cst(t) - want).abs() <= 1e-12 * want,
                "at {t} C: {} vs {want}",
                m.kinematic_cst(t)
            );
        }
        // Falling with temperature over the range a rig may use.
        let mut last = f64::INFINITY;
        for t in (-20..=150).step_by(10) {
            let nu = m.kinematic_cst(f64::from(t));
            assert!(nu < last, "{t} C: {nu} not below {last}");
            last = nu;
        }
    }
}
