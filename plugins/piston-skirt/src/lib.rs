//! `piston-skirt`: a hydrodynamic piston skirt carried by the side thrust
//! (docs/laws/piston-skirt.md).
//!
//! The skirt is two rigid barrel-shaped pads (thrust and anti-thrust side), each `L` high along
//! the bore and a wetted arc `B = arc R` wide, with a radial clearance `c`. The piston's lateral
//! offset `e` in the bore is the law's state: the films are `c - e` on the `+y` wall and `c + e`
//! on the `-y` wall. Each film carries
//!
//! ```text
//! W(h0, dh0/dt) = W_wedge(h0, |U|) + W_asp(h0) + W_sq(h0, dh0/dt)
//! W_wedge = 1.5 eta |U| L^2 J(k) / h0^2 * B        Reynolds, Swift-Stieber rupture, k = crown/h0
//! W_asp   = (L/2) integral p_a(h(s)) ds * B         Greenwood-Tripp on the barrel's gap
//! W_sq    = -K(h0) dh0/dt, K = 1.5 eta L^3 S(k) / h0^3 * B   only while the film closes
//! ```
//!
//! and the lateral balance of the (massless) piston, `W(c + e) - W(c - e) = Y` with `Y` the
//! side thrust (`load_on_inner_y_n`), gives `de/dt`; `commit` advances `e` by implicit Euler.
//! Friction: the shear of both films on the bore plus `mu_b` times the asperity load.

pub mod pad;

use serde::{Deserialize, Serialize};
use tribo_plugin_api::tribology::{film_regime, root_increasing, Roughness};
use tribo_plugin_api::{
    export_law, smooth_sign, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec, Regime,
    SUITS_SLIDE,
};

use pad::Pad;

/// Parameters of [`PistonSkirt`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Radial clearance between skirt and bore, m.
    pub clearance_m: f64,
    /// Skirt height along the bore (the pad's length in the sliding direction), m.
    pub skirt_height_m: f64,
    /// Wetted arc of each side of the skirt, rad.
    pub wetted_arc_rad: f64,
    /// Barrel drop of the profile from its crown to the skirt's edges, m.
    pub crown_m: f64,
    /// Composite RMS roughness of skirt and bore, m.
    pub sigma_m: f64,
    /// Boundary friction coefficient on the asperity load.
    pub mu_b: f64,
    /// Composite elastic modulus E' of skirt and bore, Pa.
    pub modulus_pa: f64,
    /// Greenwood-Tripp asperity density x radius x roughness.
    pub eta_beta_sigma: f64,
    /// Greenwood-Tripp roughness over asperity radius.
    pub sigma_over_beta: f64,
    /// Sliding-velocity scale of the boundary term's smoothed sign, m/s.
    pub v_smooth: f64,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            // estimate: cold radial clearance of forged motorcycle pistons, 0.03-0.07 mm
            // diametral on a 77 mm bore; the brief's published range 10-50 um radial.
            clearance_m: 25e-6,
            // estimate: short slipper skirt of a 250 cc motocross piston, 18-28 mm below the
            // pin boss (CRF 250 R piston drawings not published).
            skirt_height_m: 0.022,
            // estimate: slipper skirts span 60-100 degrees each side; 80 degrees.
            wetted_arc_rad: 80f64.to_radians(),
            // estimate: barrel profiles drop 5-30 um from the crown to the skirt edges.
            crown_m: 15e-6,
            // estimate: plateau-honed or Nikasil bore Rq 0.2-0.4 um with a coated, turned skirt
            // Rq 0.5-1.0 um; composite 0.3-1.5 um.
            sigma_m: 0.8e-6,
            // [S: Hutchings and Shipway, Tribology, 2nd ed. 2017] boundary-lubricated metals
            // 0.05-0.15.
            mu_b: 0.1,
            // estimate: aluminium-silicon skirt on an aluminium (Nikasil) or iron bore,
            // 1/E' = (1-nu1^2)/E1 + (1-nu2^2)/E2 gives 40-55 GPa.
            modulus_pa: 45e9,
            // [S: Hu, Cheng, Arai, Kobayashi, Aoyama, SAE 940595 (1994); Greenwood and Tripp
            // 1970] ring/liner values eta_s beta sigma 0.03-0.05, sigma/beta 1e-4 - 1e-2.
            eta_beta_sigma: 0.04,
            sigma_over_beta: 1e-3,
            v_smooth: 1e-3,
        }
    }
}

/// The skirt law (crate docs).
#[derive(Debug, Clone)]
pub struct PistonSkirt {
    p: Params,
    rough: Roughness,
}

/// State: the piston's lateral offset `e` (m, towards the cylinder frame's +y) and whether it
/// has been placed (1) or is still to be placed at the quasi-static offset (0).
const STATE: usize = 2;

/// The film never gets thinner than this fraction of `min(sigma, c)`; at the floor the rest of
/// the load is carried by contact (counted with the asperities).
const FLOOR: f64 = 0.01;

/// One wall's film at an offset: what the law needs for the balance and the friction.
#[derive(Debug, Clone, Copy)]
struct Side {
    h_m: f64,
    wedge_n: f64,
    asperity_n: f64,
    shear_n: f64,
    peak_pa: f64,
    damping: f64,
}

impl Side {
    fn carried_n(&self) -> f64 {
        self.wedge_n + self.asperity_n
    }
}

/// What the skirt looks like at one input (geometry, oil, speed, thrust).
#[derive(Debug, Clone, Copy)]
struct Contact {
    pad: Pad,
    eta: f64,
    speed: f64,
    thrust: f64,
}

impl PistonSkirt {
    fn floor(&self) -> f64 {
        FLOOR * self.p.sigma_m.min(self.p.clearance_m)
    }

    /// Largest offset: the film at the floor on the near wall.
    fn reach(&self) -> f64 {
        self.p.clearance_m - self.floor()
    }

    fn contact(&self, input: &LawInput) -> Option<Contact> {
        let eta = input.viscosity_pa_s;
        let r = input.contact_radius_m;
        if !(eta.is_finite() && eta > 0.0 && r.is_finite() && r > 0.0) {
            return None;
        }
        // On a slide the side thrust, signed; anywhere else (not what the law is made for) the
        // normal load pressing one pad.
        let thrust = match input.kind() {
            Some(JointKind::Prismatic) => input.load_on_inner_y_n,
            _ => input.normal_load_n,
        };
        let speed = input.sliding_velocity_m_s.abs();
        if !(thrust.is_finite() && speed.is_finite()) {
            return None;
        }
        Some(Contact {
            pad: Pad {
                height_m: self.p.skirt_height_m,
                crown_m: self.p.crown_m,
                width_m: self.p.wetted_arc_rad * r,
            },
            eta,
            speed,
            thrust,
        })
    }

    fn side(&self, c: &Contact, h: f64) -> Side {
        let (film, damping) = c.pad.sliding_and_damping(h, c.eta, c.speed);
        Side {
            h_m: h,
            wedge_n: film.load_n,
            asperity_n: self.asperity_n(c, h),
            shear_n: film.friction_n,
            peak_pa: film.peak_pa,
            damping,
        }
    }

    /// The static load (wedge and asperities) one wall's film `h` carries, N.
    fn carried(&self, c: &Contact, h: f64) -> f64 {
        c.pad.sliding_load_n(h, c.eta, c.speed) + self.asperity_n(c, h)
    }

    /// The load the asperities carry on one wall at film `h`, N: Greenwood-Tripp over the
    /// barrel's gap along the skirt's height, times the wetted width.
    fn asperity_n(&self, c: &Contact, h: f64) -> f64 {
        self.rough
            .load_per_length(0.5 * c.pad.height_m, c.pad.crown_m, h)
            * c.pad.width_m
    }

    /// Both walls at offset `e`: (the -y wall's film `c + e`, the +y wall's `c - e`).
    fn sides(&self, c: &Contact, e: f64) -> (Side, Side) {
        let cl = self.p.clearance_m;
        (self.side(c, cl + e), self.side(c, cl - e))
    }

    /// Excess of the films' static loads over the thrust at offset `e`: positive pushes the
    /// piston towards +y. Decreasing in `e`.
    fn excess(&self, c: &Contact, e: f64) -> f64 {
        let cl = self.p.clearance_m;
        self.carried(c, cl + e) - self.carried(c, cl - e) - c.thrust
    }

    /// The lateral speed `de/dt` at offset `e`: the excess carried by the closing film's
    /// squeeze (the opening film cavitates and carries none).
    fn rate(&self, c: &Contact, e: f64) -> (f64, Side, Side) {
        let (minus, plus) = self.sides(c, e);
        let r = minus.carried_n() - plus.carried_n() - c.thrust;
        let rate = if r > 0.0 {
            r / plus.damping
        } else if r < 0.0 {
            r / minus.damping
        } else {
            0.0
        };
        (rate, minus, plus)
    }

    /// The quasi-static offset: where the films carry the thrust without squeeze.
    fn quasi_static(&self, c: &Contact) -> f64 {
        let reach = self.reach();
        root_increasing(|e| -self.excess(c, e), -reach, reach)
    }

    fn offset(&self, c: &Contact, state: &[f64]) -> f64 {
        let placed = state.get(1).copied().unwrap_or(0.0) != 0.0;
        match state.first() {
            Some(&e) if placed && e.is_finite() => e.clamp(-self.reach(), self.reach()),
            _ => self.quasi_static(c),
        }
    }
}

impl Law for PistonSkirt {
    type Params = Params;
    const NAME: &'static str = "piston-skirt";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "Hydrodynamic piston skirt on the side thrust: barrel pads, Reynolds wedge (Swift-Stieber rupture) and squeeze, Greenwood-Tripp asperities, lateral offset as state";
    const SUITS: u32 = SUITS_SLIDE;

    fn parameters() -> Vec<ParamSpec> {
        vec![
            ParamSpec::number("clearance_m", "m", "radial clearance between skirt and bore (published 10-50 um)", 1e-6, 5e-4),
            ParamSpec::number("skirt_height_m", "m", "skirt height along the bore (the pad's length in the sliding direction)", 1e-3, 0.2),
            ParamSpec::number("wetted_arc_rad", "rad", "wetted arc of each side of the skirt (80 degrees = 1.396; at most half the bore)", 0.01, std::f64::consts::PI),
            ParamSpec::number("crown_m", "m", "barrel drop of the skirt profile from its crown to its edges (5-30 um; 0: a flat skirt, which carries no wedge load)", 0.0, 2e-4),
            ParamSpec::number("sigma_m", "m", "composite RMS roughness of skirt and bore (0.3-1.5 um)", 1e-8, 1e-5),
            ParamSpec::number("mu_b", "-", "boundary coefficient on the asperity load (0.05-0.15)", 0.0, 0.5),
            ParamSpec::number("modulus_pa", "Pa", "composite elastic modulus E' of skirt and bore (40-55 GPa for aluminium on aluminium or iron)", 1e8, 5e11),
            ParamSpec::number("eta_beta_sigma", "-", "Greenwood-Tripp asperity density x radius x roughness (0.03-0.05)", 1e-3, 1.0),
            ParamSpec::number("sigma_over_beta", "-", "Greenwood-Tripp roughness over asperity radius (1e-4 - 1e-2)", 1e-6, 0.1),
            ParamSpec::number("v_smooth", "m/s", "sliding-velocity scale of the boundary friction's smoothed sign", 1e-9, 1.0),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        let rough = Roughness {
            sigma_m: p.sigma_m,
            eta_beta_sigma: p.eta_beta_sigma,
            sigma_over_beta: p.sigma_over_beta,
            modulus_pa: p.modulus_pa,
        };
        Ok(Self { p, rough })
    }

    fn state_size(&self) -> usize {
        STATE
    }

    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        let Some(c) = self.contact(input) else {
            return LawOutput::force(0.0).with_regime(Regime::Hydrodynamic);
        };
        let e = self.offset(&c, state);
        let (rate, minus, plus) = self.rate(&c, e);
        let v = input.sliding_velocity_m_s;
        let shear = (minus.shear_n + plus.shear_n) * v.signum();
        let asperity = minus.asperity_n + plus.asperity_n;
        let (sign, _) = smooth_sign(v, self.p.v_smooth);
        let arm = match input.kind() {
            Some(JointKind::Revolute) => input.contact_radius_m,
            _ => 1.0,
        };
        let force = -(shear + self.p.mu_b * asperity * sign) * arm;
        // The loaded wall: the thinner film, with the squeeze it carries while closing.
        let (near, closing) = if minus.h_m <= plus.h_m {
            (minus, (-rate).max(0.0))
        } else {
            (plus, rate.max(0.0))
        };
        let squeeze_n = near.damping * closing;
        let total = near.carried_n() + squeeze_n;
        let share = if total > 0.0 {
            (near.asperity_n / total).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let peak = near.peak_pa + c.pad.squeeze_peak_pa(near.h_m, c.eta, closing);
        let lambda = near.h_m / self.p.sigma_m;
        let regime = film_regime(lambda);
        let mut out = LawOutput::force(force)
            .with_regime(regime)
            .with_min_film(near.h_m)
            .with_asperity_share(share)
            .with_peak_pressure(peak.max(0.0))
            .with_eccentricity(0.0, e / self.p.clearance_m);
        if c.thrust != 0.0 {
            out = out.with_coefficient(force.abs() / (c.thrust.abs() * arm));
        }
        out
    }

    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        if state.len() < STATE {
            return;
        }
        let Some(c) = self.contact(input) else {
            return;
        };
        let e0 = self.offset(&c, state);
        let dt = input.dt_s;
        let next = if dt > 0.0 && dt.is_finite() {
            // Implicit Euler, e1 = e0 + dt de/dt(e1). The excess falls as the piston moves
            // towards the quasi-static offset, so the root lies between e0 and the explicit
            // step's end e0 + dt de/dt(e0) (kept inside the clearance); should the squeeze's
            // damping make the rate rise there instead, the quasi-static offset bounds it.
            let reach = self.reach();
            let g = |x: f64| x - e0 - dt * self.rate(&c, x).0;
            let step = dt * self.rate(&c, e0).0;
            let (lo, hi) = if step > 0.0 {
                let end = (e0 + step).min(reach);
                (
                    e0,
                    if g(end) >= 0.0 {
                        end
                    } else {
                        self.quasi_static(&c)
                    },
                )
            } else if step < 0.0 {
                let end = (e0 + step).max(-reach);
                (
                    if g(end) <= 0.0 {
                        end
                    } else {
                        self.quasi_static(&c)
                    },
                    e0,
                )
            } else {
                (e0, e0)
            };
            if hi > lo {
                root_increasing(g, lo, hi)
            } else {
                e0
            }
        } else {
            e0
        };
        if next.is_finite() {
            state[0] = next;
            state[1] = 1.0;
        }
    }
}

export_law!(PistonSkirt);

#[cfg(test)]
mod tests;
