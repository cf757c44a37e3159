//! `plain-journal`: a hydrodynamic plain journal bearing under dynamic load
//! (docs/laws/plain-journal.md). The journal's eccentricity ratio vector is the law's state,
//! moved by Booker's mobility method on the finite-length Reynolds tables (or Ocvirk's short
//! bearing) under the load the outer member puts on the inner one (contract version 3); the
//! modules below are its mathematics, each tested on its own.

pub mod bearing;
pub mod reynolds;
pub mod short;
pub mod table;
pub mod tables;

use serde::{Deserialize, Serialize};
use tribo_plugin_api::tribology::film_regime;
use tribo_plugin_api::{
    export_law, InnerBody, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec, Regime,
    SUITS_PLAIN,
};

use bearing::{relative_torque, Bearing, Model, EPS_CAP};

/// Parameters of [`PlainJournal`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Radial clearance, m.
    pub clearance_m: f64,
    /// Pressure model: `finite` (tabulated Reynolds solution) or `short` (Ocvirk).
    pub model: String,
    /// Composite roughness Rq of journal and shell, m (for the reported regime only).
    pub roughness_m: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            // estimate: automotive crank bearings, diametral 0.02-0.05 mm on 45-55 mm
            // journals (about 0.001 x D); 20 um radial.
            clearance_m: 20e-6,
            model: "finite".into(),
            // estimate: ground journal Rq ~0.15 um, shell overlay ~0.35 um.
            roughness_m: 0.4e-6,
        }
    }
}

/// The plain journal bearing law (crate docs).
#[derive(Debug, Clone)]
pub struct PlainJournal {
    clearance_m: f64,
    model: Model,
    roughness_m: f64,
}

/// State layout: the eccentricity ratio vector (global frame) and whether it has been placed.
const STATE: usize = 3;

/// One evaluation's film: what [`PlainJournal::evaluate`] reports and [`Law::commit`] moves.
struct Film {
    bearing: Bearing,
    /// Eccentricity ratio vector, global frame.
    eps: [f64; 2],
    /// Force of the outer member on the inner one through the film, N, global frame.
    force: [f64; 2],
    /// Mean of the members' speeds, rad/s.
    omega_bar: f64,
    /// Angle of the outer member, rad (its frame for the reported eccentricity).
    outer_angle: f64,
    mu: f64,
}

impl PlainJournal {
    /// The film at `input` with the committed `state` (the quasi-static position of this load
    /// before the first commit).
    fn film(&self, input: &LawInput, state: &[f64]) -> Film {
        let bearing = Bearing {
            radius_m: input.contact_radius_m,
            length_m: input.contact_length_m,
            clearance_m: self.clearance_m,
            model: self.model,
        };
        let force = load_on_inner(input);
        // Which member is the journal: body A unless the host says body B.
        let (w_in, w_out, outer_angle) = match input.inner() {
            Some(InnerBody::B) => (
                input.body_b_velocity,
                input.body_a_velocity,
                input.body_a_angle,
            ),
            _ => (
                input.body_a_velocity,
                input.body_b_velocity,
                input.body_b_angle,
            ),
        };
        let omega_bar = 0.5 * (w_in + w_out);
        let mu = input.viscosity_pa_s;
        let placed = state.get(2).copied().unwrap_or(0.0) != 0.0;
        let eps = if placed {
            [state[0], state[1]]
        } else {
            quasi_static(&bearing, force, omega_bar, mu)
        };
        Film {
            bearing,
            eps,
            force,
            omega_bar,
            outer_angle,
            mu,
        }
    }

    fn valid_geometry(input: &LawInput) -> bool {
        input.contact_radius_m > 0.0
            && input.contact_length_m > 0.0
            && input.viscosity_pa_s.is_finite()
            && input.viscosity_pa_s >= 0.0
    }
}

/// The force the outer member exerts on the inner one (contract v3's `load_on_inner`). A host
/// that does not fill it (zero while the joint carries a load) leaves the joint's reaction,
/// which has the same line: the film's torque and the eccentricity's size are the same, its
/// direction possibly turned by half a turn.
fn load_on_inner(input: &LawInput) -> [f64; 2] {
    let f = [input.load_on_inner_x_n, input.load_on_inner_y_n];
    if f[0] == 0.0 && f[1] == 0.0 && input.normal_load_n > 0.0 {
        let r = [input.reaction_x_n, input.reaction_y_n];
        let m = r[0].hypot(r[1]);
        if m > 0.0 {
            return r;
        }
        return [0.0, input.normal_load_n];
    }
    f
}

/// The journal's steady position under `force` at mean speed `omega_bar`: the steady
/// eccentricity at the attitude angle from the load line, turned in the direction of rotation.
fn quasi_static(b: &Bearing, force: [f64; 2], omega_bar: f64, mu: f64) -> [f64; 2] {
    let w = force[0].hypot(force[1]);
    if w <= 0.0 || omega_bar == 0.0 || mu <= 0.0 {
        return [0.0, 0.0];
    }
    let (e, attitude) = b.steady(w, omega_bar, mu);
    // The load the journal carries points against the film's force on it.
    let theta = (-force[1]).atan2(-force[0]) + attitude * omega_bar.signum();
    [e * theta.cos(), e * theta.sin()]
}

impl Law for PlainJournal {
    type Params = Params;
    const NAME: &'static str = "plain-journal";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "Hydrodynamic plain journal bearing under dynamic load: finite-length Reynolds (Swift-Stieber rupture) tables, Booker mobility, eccentricity as state";
    const SUITS: u32 = SUITS_PLAIN;

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number(
                "clearance_m",
                "m",
                "radial clearance c between journal and shell",
                1e-7,
                1e-3,
            ),
            ParamSpec::choice(
                "model",
                "finite: tabulated finite-length Reynolds solution (Swift-Stieber rupture); short: Ocvirk's short bearing (half-Sommerfeld, closed form)",
                &["finite", "short"],
            ),
            ParamSpec::number(
                "roughness_m",
                "m",
                "composite roughness Rq of journal and shell; sets the reported regime from h_min / Rq",
                1e-9,
                1e-4,
            ),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        let model = match p.model.as_str() {
            "finite" => Model::Finite,
            "short" => Model::Short,
            other => {
                return Err(ParamError::new(
                    "model",
                    format!("expected `finite` or `short`, got `{other}`"),
                ))
            }
        };
        Ok(Self {
            clearance_m: p.clearance_m,
            model,
            roughness_m: p.roughness_m,
        })
    }

    fn state_size(&self) -> usize {
        STATE
    }

    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        if !Self::valid_geometry(input) {
            return LawOutput::force(0.0);
        }
        let r = input.contact_radius_m;
        let l = input.contact_length_m;
        let mu = input.viscosity_pa_s;
        if input.kind() != Some(JointKind::Revolute) {
            // A sleeve on a slide: the concentric film's shear.
            let k = mu * 2.0 * std::f64::consts::PI * r * l / self.clearance_m;
            return LawOutput::force(-k * input.relative_velocity)
                .with_derivative(-k)
                .with_regime(Regime::Hydrodynamic)
                .with_min_film(self.clearance_m);
        }
        let f = self.film(input, state);
        let torque = relative_torque(
            &f.bearing,
            f.eps,
            f.force,
            input.relative_velocity,
            f.omega_bar,
            f.mu,
        );
        let e = f.eps[0].hypot(f.eps[1]).min(EPS_CAP);
        let h_min = self.clearance_m * (1.0 - e);
        let peak = f
            .bearing
            .motion(f.eps, f.force, f.omega_bar, f.mu)
            .peak_pressure_pa;
        // The eccentricity in the outer member's frame.
        let (s, c) = (-f.outer_angle).sin_cos();
        let scale = if f.eps[0].hypot(f.eps[1]) > EPS_CAP {
            EPS_CAP / f.eps[0].hypot(f.eps[1])
        } else {
            1.0
        };
        let (ex, ey) = (f.eps[0] * scale, f.eps[1] * scale);
        let lambda = h_min / self.roughness_m;
        let regime = film_regime(lambda);
        let mut out = LawOutput::force(torque)
            .with_regime(regime)
            .with_min_film(h_min)
            .with_eccentricity(c * ex - s * ey, s * ex + c * ey)
            .with_peak_pressure(peak.max(0.0));
        if input.normal_load_n > 0.0 {
            out = out.with_coefficient(torque.abs() / (input.normal_load_n * r));
        }
        out
    }

    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        if state.len() < STATE
            || input.kind() != Some(JointKind::Revolute)
            || !Self::valid_geometry(input)
        {
            return;
        }
        let f = self.film(input, state);
        let next = if input.dt_s > 0.0 {
            f.bearing
                .advance(f.eps, f.force, f.omega_bar, f.mu, input.dt_s)
        } else {
            f.eps
        };
        if next[0].is_finite() && next[1].is_finite() {
            state[0] = next[0];
            state[1] = next[1];
            state[2] = 1.0;
        }
    }
}

export_law!(PlainJournal);

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;
    use tribo_plugin_api::conformance::assert_law_conforms;
    use tribo_plugin_api::create_from_table;

    fn law(text: &str) -> Result<PlainJournal, ParamError> {
        create_from_table::<PlainJournal>(&text.parse().expect("toml"))
    }

    /// A main bearing: the crank (body A, inner) turning at `omega` in the block, loaded
    /// downwards by `w` N (the film pushes the journal up).
    fn main_bearing(omega: f64, w: f64, dt: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Revolute).with_velocity(omega);
        i.contact_radius_m = 0.025;
        i.contact_length_m = 0.020;
        i.viscosity_pa_s = 0.0117;
        i.normal_load_n = w;
        i.reaction_y_n = w;
        i.load_on_inner_y_n = w;
        i.dt_s = dt;
        i
    }

    #[test]
    fn conforms() {
        assert_law_conforms::<PlainJournal>();
    }

    #[test]
    fn rejects_an_unknown_model() {
        let e = law("model = \"long\"").expect_err("unknown model");
        assert!(e.to_string().contains("model"), "{e}");
    }

    /// At zero load the journal is centred and the torque is Petroff's.
    #[test]
    fn petroff_at_zero_load() {
        let l = law("clearance_m = 2e-5").expect("law");
        let i = main_bearing(300.0, 0.0, 0.0);
        let out = l.evaluate(&i, &[0.0; STATE]);
        let petroff = 2.0 * PI * 0.0117 * 0.025f64.powi(3) * 0.020 * 300.0 / 2e-5;
        assert!(
            (out.force + petroff).abs() <= 1e-12 * petroff,
            "{}",
            out.force
        );
        assert_eq!(out.min_film(), Some(2e-5));
    }

    /// Under a steady load the first commit places the journal at its steady position and
    /// further commits keep it there (Booker's mobility of the steady state is zero); the
    /// torque is the steady journal's `K omega + e W sin(phi) / 2`, above Petroff's.
    #[test]
    fn a_steady_load_keeps_the_journal_at_its_steady_position() {
        let l = law("clearance_m = 2e-5").expect("law");
        let i = main_bearing(300.0, 5000.0, 1e-4);
        let mut s = [0.0; STATE];
        l.commit(&i, &mut s);
        let first = [s[0], s[1]];
        for _ in 0..200 {
            l.commit(&i, &mut s);
        }
        let moved = (s[0] - first[0]).hypot(s[1] - first[1]);
        assert!(moved < 0.02 * first[0].hypot(first[1]), "moved {moved}");
        let out = l.evaluate(&i, &s);
        let petroff = 2.0 * PI * 0.0117 * 0.025f64.powi(3) * 0.020 * 300.0 / 2e-5;
        assert!(out.force < -petroff, "{} vs Petroff {petroff}", out.force);
        let (ex, ey) = out.eccentricity().expect("eccentricity");
        // Loaded downwards, the journal sits below the centre, turned towards the rotation.
        assert!(ey < 0.0 && ex > 0.0, "({ex}, {ey})");
        let h = out.min_film().expect("film");
        assert!((h - 2e-5 * (1.0 - ex.hypot(ey))).abs() < 1e-15);
        assert!(out.peak_pressure().expect("peak") > 5000.0 / (0.05 * 0.020));
    }

    /// The reported eccentricity is in the outer member's frame: the same state seen from a
    /// bearing turned by a quarter turn is turned back by a quarter turn.
    #[test]
    fn the_eccentricity_is_reported_in_the_outer_members_frame() {
        let l = law("clearance_m = 2e-5").expect("law");
        let mut i = main_bearing(300.0, 5000.0, 0.0);
        let s = [0.3, -0.4, 1.0];
        let (x0, y0) = l.evaluate(&i, &s).eccentricity().expect("ecc");
        i.body_b_angle = 0.5 * PI;
        let (x1, y1) = l.evaluate(&i, &s).eccentricity().expect("ecc");
        assert!((x0 - 0.3).abs() < 1e-15 && (y0 + 0.4).abs() < 1e-15);
        assert!(
            (x1 - y0).abs() < 1e-12 && (y1 + x0).abs() < 1e-12,
            "({x1}, {y1})"
        );
    }

    /// Hotter, thinner oil: the journal runs more eccentric, the film thinner, the torque
    /// lower (the sweep of docs/laws/plain-journal.md in one line).
    #[test]
    fn thinner_oil_means_a_thinner_film_and_less_torque() {
        let l = law("clearance_m = 2e-5").expect("law");
        let mut cold = main_bearing(300.0, 5000.0, 0.0);
        cold.viscosity_pa_s = 0.055;
        let hot = main_bearing(300.0, 5000.0, 0.0);
        let (oc, oh) = (l.evaluate(&cold, &[0.0; 3]), l.evaluate(&hot, &[0.0; 3]));
        assert!(oh.min_film() < oc.min_film());
        assert!(oh.force.abs() < oc.force.abs());
    }
}
