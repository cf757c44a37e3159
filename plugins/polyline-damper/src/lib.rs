//! `polyline-damper`: a viscous damper whose coefficient is scheduled on engine speed by a
//! poly-line, the form of the thesis's table 9.6 (FEDEM's viscous damper with a scaling function).
//!
//! ```text
//! F = -c0 * f(omega_engine) * V
//! ```
//!
//! `V` is the joint's relative velocity (rad/s on a revolute joint, giving a torque in N m;
//! m/s on a slide, giving a force in N), `f` is linear between the points `(speeds, factors)`
//! and held constant beyond the first and last point. Being a function of speed only, it does
//! not respond to any change of load or mass: that is what makes it a workaround.
//!
//! With `per_engine_speed = true` the coefficient is `c0 * f(omega) / omega_engine` (c0 then in
//! N m or N): the poly-line gives the damping torque at the plateau speed directly. That is the
//! reading of the thesis's table 9.6 that reproduces its table 10.5 (docs/crf250r-study.md).
//! At standstill the engine speed is bounded below by [`STANDSTILL_RAD_S`]: there the torque
//! ramps linearly through zero instead of jumping as a sign.

use serde::{Deserialize, Serialize};
use tribo_plugin_api::{export_law, Law, LawInput, LawOutput, ParamError, ParamSpec};

/// Parameters of [`PolylineDamper`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Base coefficient c0: N m s/rad (revolute) or N s/m (slide).
    pub c0: f64,
    /// Engine speeds of the poly-line points, rad/s, strictly increasing.
    pub speeds_rad_s: Vec<f64>,
    /// Scale factor at each point (-).
    pub factors: Vec<f64>,
    /// Divide the coefficient by the engine speed (the poly-line then gives a torque or force).
    pub per_engine_speed: bool,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            c0: 1.0,
            speeds_rad_s: vec![0.0],
            factors: vec![0.0],
            per_engine_speed: false,
        }
    }
}

/// The engine speed below which a per-engine-speed coefficient stops growing, rad/s (0.5 rpm):
/// the torque is then linear in the speed through standstill. estimate: a numerical bound, not
/// a thesis number (the table starts at 3000 rpm). It is the scale over which the FEDEM set's
/// Coulomb law smooths its sign (`v_smooth` = 1 mm/s of sliding on the 20 mm crank journal), so
/// the set has one standstill scale; the former 1e-3 rad/s made a start from rest 50 times
/// stiffer than the friction's own (on the thesis PI run, 1 800 steps of 11 microseconds in the
/// first 0.02 s, while the crank had not yet turned). It acts only within 0.5 rpm of standstill.
pub const STANDSTILL_RAD_S: f64 = 0.05;

/// Speed-scheduled viscous damper.
#[derive(Debug, Clone)]
pub struct PolylineDamper {
    p: Params,
}

impl PolylineDamper {
    /// The poly-line factor at engine speed `w` (rad/s).
    pub fn factor(&self, w: f64) -> f64 {
        let (s, f) = (&self.p.speeds_rad_s, &self.p.factors);
        let n = s.len();
        if w <= s[0] {
            return f[0];
        }
        if w >= s[n - 1] {
            return f[n - 1];
        }
        // A branch-free count over the (few) breakpoints: the engine speed dithers around a
        // breakpoint on every plateau, where a binary search mispredicts.
        let i = s.iter().filter(|x| **x <= w).count();
        let t = (w - s[i - 1]) / (s[i] - s[i - 1]);
        f[i - 1] + t * (f[i] - f[i - 1])
    }
}

impl Law for PolylineDamper {
    type Params = Params;
    const NAME: &'static str = "polyline-damper";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str =
        "Viscous damper c0*f(engine speed)*V with f a poly-line (thesis table 9.6)";

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "c0",
                "N m s/rad | N s/m",
                "base viscous coefficient (revolute: N m s/rad, slide: N s/m)",
                0.0,
                1e6,
            ),
            ParamSpec::number_list(
                "speeds_rad_s",
                "rad/s",
                "engine speeds of the poly-line points, strictly increasing",
                0.0,
                1e5,
            ),
            ParamSpec::number_list(
                "factors",
                "-",
                "scale factor at each point; held constant beyond the ends",
                0.0,
                1e6,
            ),
            ParamSpec::boolean(
                "per_engine_speed",
                "coefficient c0*f/omega_engine: the poly-line gives the damping torque (N m) or force (N) at the engine speed",
            ),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        if p.speeds_rad_s.is_empty() {
            return Err(ParamError::new(
                "speeds_rad_s",
                "the poly-line is empty; give at least one point",
            ));
        }
        if p.factors.len() != p.speeds_rad_s.len() {
            return Err(ParamError::new(
                "factors",
                format!(
                    "has {} values but speeds_rad_s has {}; give one factor per speed",
                    p.factors.len(),
                    p.speeds_rad_s.len()
                ),
            ));
        }
        if let Some(i) = p.speeds_rad_s.windows(2).position(|w| w[1] <= w[0]) {
            return Err(ParamError::new(
                "speeds_rad_s",
                format!(
                    "must be strictly increasing; point {} ({}) is not above point {} ({})",
                    i + 1,
                    p.speeds_rad_s[i + 1],
                    i,
                    p.speeds_rad_s[i]
                ),
            ));
        }
        Ok(Self { p })
    }

    fn evaluate(&self, input: &LawInput, _state: &[f64]) -> LawOutput {
        let w = input.engine_speed_rad_s;
        let mut c = self.p.c0 * self.factor(w);
        if self.p.per_engine_speed {
            // Bounded at standstill, where the relative velocity vanishes with the engine speed.
            c /= w.abs().max(STANDSTILL_RAD_S);
        }
        LawOutput::force(-c * input.relative_velocity)
            .with_derivative(-c)
            .affine_in_load(0.0)
    }
}

export_law!(PolylineDamper);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
    use tribo_plugin_api::{create_from_table, JointKind};

    fn law(text: &str) -> Result<PolylineDamper, ParamError> {
        create_from_table::<PolylineDamper>(&text.parse().expect("toml"))
    }

    fn input(engine: f64, v: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Revolute);
        i.engine_speed_rad_s = engine;
        i.with_velocity(v)
    }

    // Thesis table 9.6, crankshaft column.
    const CRANK: &str = "c0 = 1.0\nspeeds_rad_s = [314.159, 418.879, 523.599, 628.319, 733.038, 837.758, 942.478]\nfactors = [0.091, 0.085, 0.073, 0.060, 0.040, 0.020, 0.0]";

    /// The checks of `tribo check-law` (description, defaults and ranges, finite, dissipative,
    /// dF/dv, pure evaluate, commit, threads) with the defaults and the parameter sets below.
    #[test]
    fn conforms() {
        assert_law_conforms::<PolylineDamper>();
        assert_law_conforms_with::<PolylineDamper>(CRANK);
        assert_law_conforms_with::<PolylineDamper>(&format!("{CRANK}\nper_engine_speed = true"));
    }

    #[test]
    fn interpolates_and_holds_the_ends() {
        let l = law(CRANK).expect("valid");
        assert!((l.factor(314.159) - 0.091).abs() < 1e-12);
        // Halfway between 3000 and 4000 rpm: (0.091 + 0.085) / 2.
        assert!((l.factor(0.5 * (314.159 + 418.879)) - 0.088).abs() < 1e-12);
        assert_eq!(l.factor(100.0), 0.091);
        assert_eq!(l.factor(2000.0), 0.0);
        // Torque at 3000 rpm on the crank: -0.091 * 314.159.
        let out = l.evaluate(&input(314.159, 314.159), &[]);
        assert!((out.force + 0.091 * 314.159).abs() < 1e-9);
        assert_eq!(out.derivative(), Some(-0.091));
    }

    /// Through standstill a per-engine-speed damper on a main bearing (relative velocity the
    /// engine speed) gives a torque linear in the speed, continuous with the poly-line's torque
    /// at the bound, and of the opposite sign to the motion on both sides.
    #[test]
    fn per_engine_speed_torque_ramps_through_standstill() {
        let l = law(&format!("{CRANK}\nper_engine_speed = true")).expect("valid");
        let torque = |w: f64| l.evaluate(&input(w, w), &[]).force;
        // At the bound, the poly-line's torque below its first point (0.091 N m).
        assert!((torque(STANDSTILL_RAD_S) + 0.091).abs() < 1e-12);
        assert!((torque(-STANDSTILL_RAD_S) - 0.091).abs() < 1e-12);
        // Half the bound, half the torque; zero at rest.
        assert!((torque(0.5 * STANDSTILL_RAD_S) + 0.0455).abs() < 1e-12);
        assert_eq!(torque(0.0), 0.0);
        // Beyond it, the poly-line's torque whatever the speed.
        assert!((torque(3.0 * STANDSTILL_RAD_S) + 0.091).abs() < 1e-12);
    }

    #[test]
    fn per_engine_speed_gives_the_poly_line_as_a_torque() {
        let l = law(&format!("{CRANK}\nper_engine_speed = true")).expect("valid");
        // On a main bearing the relative velocity is the engine speed: torque = -c0 * f.
        let out = l.evaluate(&input(418.879, 418.879), &[]);
        assert!((out.force + 0.085).abs() < 1e-12, "{}", out.force);
    }

    #[test]
    fn continuous_in_engine_speed() {
        // Dissipation is in `conforms`; the poly-line must also have no jump at its knots.
        let l = law(CRANK).expect("valid");
        for k in 0..2000 {
            let w = k as f64;
            let (a, b) = (l.factor(w), l.factor(w + 1e-9));
            assert!((a - b).abs() < 1e-9);
        }
    }

    #[test]
    fn rejects_bad_poly_lines_by_name() {
        let e = law("speeds_rad_s = []\nfactors = []").unwrap_err();
        assert_eq!(e.parameter, "speeds_rad_s");
        assert!(e.message.contains("empty"));
        let e = law("speeds_rad_s = [1.0, 3.0, 2.0]\nfactors = [1.0, 1.0, 1.0]").unwrap_err();
        assert_eq!(e.parameter, "speeds_rad_s");
        assert!(e.message.contains("increasing"));
        let e = law("speeds_rad_s = [1.0, 2.0]\nfactors = [1.0]").unwrap_err();
        assert_eq!(e.parameter, "factors");
        let e = law("c0 = -1.0").unwrap_err();
        assert_eq!(e.parameter, "c0");
    }
}
