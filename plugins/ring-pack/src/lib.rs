//! `ring-pack`: the piston's ring pack as engineers model it (docs/laws/ring-pack.md). Each
//! ring (top, second, the two rails of the oil-control ring) is pressed on the liner by its
//! tension and, for the compression rings, by the gas behind it; its parabolic face rides on a
//! film from the Reynolds equation with sliding and squeeze (the minimum film of every ring is
//! the law's state), and where the film is thin the asperities carry load by Greenwood-Tripp.
//! Friction: viscous shear of the film plus a boundary coefficient on the asperity load.
//!
//! The modules are the mathematics, each tested on its own: [`profile`] the closed-form film of
//! a parabolic face, [`ring`] one ring's load balance and motion; the Greenwood-Tripp asperities
//! come from [`tribo_plugin_api::tribology`].

pub mod profile;
pub mod ring;

use serde::{Deserialize, Serialize};
use tribo_plugin_api::tribology::{film_regime, Roughness};
use tribo_plugin_api::{
    export_law, smooth_sign, JointKind, Law, LawInput, LawOutput, ParamError, ParamSpec,
    SUITS_SLIDE,
};

use profile::Face;
use ring::{Contact, Ring};

/// Parameters of [`RingPack`]. Sources and ranges: docs/laws/ring-pack.md.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Params {
    /// Top ring tangential (closing) force, N.
    pub top_tension_n: f64,
    /// Top ring face width in contact (axial), m.
    pub top_width_m: f64,
    /// Top ring crown height of the parabolic (barrel) face, m.
    pub top_crown_m: f64,
    /// Fraction of the cylinder-crankcase pressure drop behind the top ring, -.
    pub top_gas_fraction: f64,
    /// Second ring tangential force, N.
    pub second_tension_n: f64,
    /// Second ring face width, m.
    pub second_width_m: f64,
    /// Second ring crown height, m.
    pub second_crown_m: f64,
    /// Fraction of the pressure drop behind the second ring (the second land's pressure), -.
    pub second_gas_fraction: f64,
    /// Oil-control ring tangential force (expander and both rails), N.
    pub oil_tension_n: f64,
    /// Width of each oil-ring rail's face, m.
    pub oil_rail_width_m: f64,
    /// Crown height of each rail's face, m.
    pub oil_rail_crown_m: f64,
    /// Composite RMS roughness of ring faces and liner, m.
    pub roughness_m: f64,
    /// Greenwood-Tripp roughness parameter `eta beta sigma`, -.
    pub eta_beta_sigma: f64,
    /// Greenwood-Tripp asperity slope measure `sigma / beta`, -.
    pub sigma_over_beta: f64,
    /// Composite elastic modulus `E*` of ring and liner, Pa.
    pub modulus_pa: f64,
    /// Boundary friction coefficient on the asperity load, -.
    pub boundary_mu: f64,
    /// Velocity scale of the boundary friction's smoothed sign, m/s.
    pub v_smooth_m_s: f64,
    /// Oil supply at each face's inlet: `flooded` (every inlet full) or `starved` (each face
    /// rides the layer the face ahead of it left on the liner).
    pub inlet: String,
    /// Starved: the oil layer on the liner above the top ring, met by the top ring on the
    /// downstroke, m.
    pub top_supply_film_m: f64,
    /// Starved: where the top ring's downstroke layer comes from: `fixed` (`top_supply_film_m`
    /// everywhere) or `carried` (the layer the top ring itself left at that place of the
    /// liner on the last upstroke, `top_supply_film_m` where it has not been yet).
    pub top_supply: String,
}

impl Default for Params {
    fn default() -> Self {
        // Every value: docs/laws/ring-pack.md, "Parameters", with its source and range.
        Self {
            top_tension_n: 8.0,
            top_width_m: 0.8e-3,
            top_crown_m: 5e-6,
            top_gas_fraction: 1.0,
            second_tension_n: 7.0,
            second_width_m: 0.8e-3,
            second_crown_m: 10e-6,
            second_gas_fraction: 0.2,
            oil_tension_n: 20.0,
            oil_rail_width_m: 0.3e-3,
            oil_rail_crown_m: 2e-6,
            roughness_m: 0.35e-6,
            eta_beta_sigma: 0.04,
            sigma_over_beta: 1e-3,
            modulus_pa: 78e9,
            boundary_mu: 0.1,
            v_smooth_m_s: 0.01,
            inlet: "flooded".into(),
            top_supply_film_m: 1e-6,
            top_supply: "fixed".into(),
        }
    }
}

/// Number of faces: top, second, and one state for both identical oil-ring rails.
pub const RINGS: usize = 3;

/// State layout: the minimum film of each ring (m; the oil ring's upper rail), whether they
/// have been placed, then the oil ring's lower rail (the same as the upper when flooded).
const STATE: usize = RINGS + 2;

/// Index of the lower rail's film in the state.
const LOWER_RAIL: usize = RINGS + 1;

/// Carried top supply: the state after [`STATE`] holds the piston travel at the last commit
/// (m from top dead centre) and whether it is set (0 no, 1 yes, 2 yes and the commit was on
/// the upstroke), then per liner bin ([`LINER_BINS`] of [`LINER_BIN_M`] along the travel) the
/// oil the top ring laid there on its last upstroke (m^2 per metre of circumference), then
/// the length of the bin it covered (m): the layer met there is their quotient, so the oil
/// the top ring meets on the downstroke is the oil it laid, whatever the steps.
const TRAVEL: usize = STATE;

/// The first liner bin's oil in the state.
const BINS: usize = STATE + 2;

/// The first liner bin's covered length in the state.
const COVERED: usize = BINS + LINER_BINS;

/// Length of one liner bin along the bore, m.
pub const LINER_BIN_M: f64 = 1e-3;

/// Number of liner bins: 256 mm of piston travel (strokes up to that; travel beyond it shares
/// the last bin).
pub const LINER_BINS: usize = 256;

/// The faces in the order the liner meets them on the upstroke (piston towards the head: the
/// oil ring's lower rail leads, fed from the crankcase side): lower rail, upper rail, second,
/// top; indices into [`Faces`] (top 0, second 1, upper rail 2, lower rail 3).
const UPSTROKE: [usize; 4] = [3, 2, 1, 0];

/// The downstroke's order: the top ring leads, fed by the layer above it.
const DOWNSTROKE: [usize; 4] = [0, 1, 2, 3];

/// The four faces' values: top, second, the oil ring's upper and lower rails.
type Faces<T> = [T; 4];

/// The ring-pack law (crate docs).
#[derive(Debug, Clone)]
pub struct RingPack {
    rings: [Ring; RINGS],
    rough: Roughness,
    boundary_mu: f64,
    v_smooth: f64,
    /// Starved inlets (`inlet = "starved"`); flooded otherwise.
    starved: bool,
    top_supply_m: f64,
    /// Starved, the top ring's downstroke layer is the one it left on the last upstroke.
    carried: bool,
}

/// One evaluation of the pack: every ring's contact and the total force.
#[derive(Debug, Clone, Copy)]
pub struct PackState {
    /// Each ring's contact (the oil-ring entry is its upper rail).
    pub contacts: [Contact; RINGS],
    /// The oil ring's lower rail (the same as the upper when flooded).
    pub lower_rail: Contact,
    /// The oil layer each face ran into, m (top, second, upper rail, lower rail; `None`:
    /// flooded).
    pub supplies: Faces<Option<f64>>,
    /// Friction force on the piston along the bore axis, N (opposes the sliding velocity).
    pub force_n: f64,
    /// The hydrodynamic (viscous shear) part of the force, N.
    pub viscous_n: f64,
    /// The boundary (asperity) part of the force, N.
    pub boundary_n: f64,
    /// Radial load of the whole pack, N.
    pub radial_load_n: f64,
    /// Radial load the asperities carry, N.
    pub asperity_load_n: f64,
}

impl RingPack {
    /// The rings as declared (top, second, one oil-ring rail).
    pub fn rings(&self) -> &[Ring; RINGS] {
        &self.rings
    }

    /// The asperity contact constants.
    pub fn roughness(&self) -> &Roughness {
        &self.rough
    }

    fn loads(&self, input: &LawInput) -> [f64; RINGS] {
        let bore = 2.0 * input.contact_radius_m;
        let dp = input.cylinder_pressure_pa - input.crankcase_pressure_pa;
        let dp = if dp.is_finite() { dp } else { 0.0 };
        self.rings.map(|r| r.load_per_length(bore, dp))
    }

    /// The ring behind face `f` (the two rails share the oil ring).
    fn ring_of(&self, f: usize) -> &Ring {
        &self.rings[f.min(RINGS - 1)]
    }

    /// The committed film of face `f`, if placed.
    fn committed(state: &[f64], f: usize) -> Option<f64> {
        let placed = state.len() >= STATE && state[RINGS] != 0.0;
        placed.then(|| state[if f == 3 { LOWER_RAIL } else { f }])
    }

    /// Every face's contact at the committed films (the quasi-static film of the instant before
    /// the first commit), and the oil layer each ran into. Flooded: every inlet full, the two
    /// rails alike. Starved: in the order the liner meets the faces in this stroke, each face's
    /// supply is the layer the face ahead left (`h_out / 2`: the outlet flux `|u| h_out / 2`
    /// spread on the liner moving at `|u|`; the whole layer when the face rode above it); the
    /// leading face's is the crankcase side's (flooded) on the upstroke and `top_supply_film_m`
    /// on the downstroke.
    fn faces(
        &self,
        input: &LawInput,
        state: &[f64],
        loads: &[f64; RINGS],
    ) -> (Faces<Contact>, Faces<Option<f64>>) {
        let u = input.relative_velocity.abs();
        let mu = input.viscosity_pa_s.max(0.0);
        let mu_raw = input.viscosity_pa_s;
        let film = |f: usize, supply: Option<f64>| {
            let r = self.ring_of(f);
            let load = loads[f.min(RINGS - 1)];
            let h = Self::committed(state, f)
                .unwrap_or_else(|| r.steady(&self.rough, u, load, mu_raw, supply));
            r.contact(&self.rough, h, u, load, mu, supply)
        };
        if !self.starved {
            let c: [Contact; RINGS] = std::array::from_fn(|f| film(f, None));
            return ([c[0], c[1], c[2], c[2]], [None; 4]);
        }
        let (order, lead) = if input.relative_velocity >= 0.0 {
            (UPSTROKE, None)
        } else {
            (DOWNSTROKE, Some(self.top_supply_at(input, state)))
        };
        let mut contacts = [film(order[0], lead); 4];
        let mut supplies = [None; 4];
        let mut supply = lead;
        for &f in &order {
            let c = film(f, supply);
            contacts[f] = c;
            supplies[f] = supply;
            supply = Some(c.film.layer_left_m(u));
        }
        (contacts, supplies)
    }

    /// The liner bin of the piston travel `travel_m` (m from top dead centre).
    fn bin(travel_m: f64) -> usize {
        if travel_m.is_finite() && travel_m > 0.0 {
            ((travel_m / LINER_BIN_M) as usize).min(LINER_BINS - 1)
        } else {
            0
        }
    }

    /// The layer the top ring meets on the downstroke here: carried, the one it left at this
    /// bin on the last upstroke (where it has been); `top_supply_film_m` otherwise.
    fn top_supply_at(&self, input: &LawInput, state: &[f64]) -> f64 {
        if !self.carried || state.len() < COVERED + LINER_BINS {
            return self.top_supply_m;
        }
        let b = Self::bin(input.piston_from_tdc_m);
        let covered = state[COVERED + b];
        if covered > 0.0 {
            state[BINS + b] / covered
        } else {
            self.top_supply_m
        }
    }

    /// Carried: on the upstroke, the top ring lays `layer` on the stretch of liner it crossed
    /// since the last commit, each bin receiving the oil over the length it shares with the
    /// stretch; a bin the stroke reaches for the first time forgets the last upstroke's oil.
    /// The travel is remembered for the next commit.
    fn lay(&self, input: &LawInput, state: &mut [f64], layer: f64) {
        if !(self.starved && self.carried) || state.len() < COVERED + LINER_BINS {
            return;
        }
        let end = LINER_BINS as f64 * LINER_BIN_M;
        let now = if input.piston_from_tdc_m.is_finite() {
            input.piston_from_tdc_m.clamp(0.0, end)
        } else {
            0.0
        };
        let up = input.relative_velocity > 0.0 && layer.is_finite() && layer >= 0.0;
        if up && state[TRAVEL + 1] != 0.0 {
            let then = state[TRAVEL].clamp(0.0, end);
            let continuing = state[TRAVEL + 1] == 2.0;
            let (lo, hi) = (now.min(then), now.max(then));
            let top = Self::bin(hi);
            for b in Self::bin(lo)..=top {
                let start = b as f64 * LINER_BIN_M;
                let overlap = (hi.min(start + LINER_BIN_M) - lo.max(start)).max(0.0);
                if !(continuing && b == top) {
                    state[BINS + b] = 0.0;
                    state[COVERED + b] = 0.0;
                }
                state[BINS + b] += layer * overlap;
                state[COVERED + b] += overlap;
            }
        }
        state[TRAVEL] = now;
        state[TRAVEL + 1] = if up { 2.0 } else { 1.0 };
    }

    /// The pack at `input` with the committed `state`.
    pub fn pack(&self, input: &LawInput, state: &[f64]) -> PackState {
        let loads = self.loads(input);
        let v = input.relative_velocity;
        let circumference = 2.0 * std::f64::consts::PI * input.contact_radius_m;
        let (faces, supplies) = self.faces(input, state, &loads);
        let contacts = [faces[0], faces[1], faces[2]];
        let (mut shear, mut asp, mut radial) = (0.0, 0.0, 0.0);
        for (i, (r, c)) in self.rings.iter().zip(&contacts).enumerate() {
            // The oil ring's two rails (identical when flooded: 2 x, exactly).
            let (s, a) = if i == RINGS - 1 {
                (
                    c.film.shear_n_per_m + faces[3].film.shear_n_per_m,
                    c.asperity_n_per_m + faces[3].asperity_n_per_m,
                )
            } else {
                (c.film.shear_n_per_m, c.asperity_n_per_m)
            };
            shear += s;
            asp += a;
            radial += r.rails.max(1) as f64 * c.load_n_per_m;
        }
        let (sgn, _) = smooth_sign(v, self.v_smooth);
        let viscous = -v.signum() * shear * circumference;
        let boundary = -sgn * self.boundary_mu * asp * circumference;
        PackState {
            contacts,
            lower_rail: faces[3],
            supplies,
            force_n: viscous + boundary,
            viscous_n: viscous,
            boundary_n: boundary,
            radial_load_n: radial * circumference,
            asperity_load_n: asp * circumference,
        }
    }

    fn valid(input: &LawInput) -> bool {
        input.kind() == Some(JointKind::Prismatic)
            && input.contact_radius_m > 0.0
            && input.contact_radius_m.is_finite()
            && input.relative_velocity.is_finite()
            && input.viscosity_pa_s.is_finite()
    }
}

impl Law for RingPack {
    type Params = Params;
    const NAME: &'static str = "ring-pack";
    const VERSION: &'static str = env!("CARGO_PKG_VERSION");
    const SUMMARY: &'static str = "Piston ring pack: per ring tension and gas load, parabolic face on a Reynolds film (sliding + squeeze, Reynolds rupture), Greenwood-Tripp asperities, films as state";
    const SUITS: u32 = SUITS_SLIDE;

    fn parameters() -> Vec<ParamSpec> {
        let n = ParamSpec::number;
        vec![
            n(
                "top_tension_n",
                "N",
                "top ring tangential (closing) force; radial load 2 F_t / D per unit circumference",
                0.0,
                1000.0,
            ),
            n(
                "top_width_m",
                "m",
                "top ring face width in contact (axial)",
                1e-5,
                1e-2,
            ),
            n(
                "top_crown_m",
                "m",
                "top ring crown height of the parabolic (barrel) face",
                2e-7,
                1e-4,
            ),
            n(
                "top_gas_fraction",
                "-",
                "fraction of p_cylinder - p_crankcase acting behind the top ring",
                0.0,
                1.0,
            ),
            n(
                "second_tension_n",
                "N",
                "second ring tangential force",
                0.0,
                1000.0,
            ),
            n(
                "second_width_m",
                "m",
                "second ring face width in contact",
                1e-5,
                1e-2,
            ),
            n(
                "second_crown_m",
                "m",
                "second ring crown height",
                2e-7,
                1e-4,
            ),
            n(
                "second_gas_fraction",
                "-",
                "fraction of the pressure drop behind the second ring (second-land pressure)",
                0.0,
                1.0,
            ),
            n(
                "oil_tension_n",
                "N",
                "oil-control ring tangential force (expander, shared by its two rails)",
                0.0,
                1000.0,
            ),
            n(
                "oil_rail_width_m",
                "m",
                "face width of each oil-ring rail",
                1e-5,
                1e-2,
            ),
            n(
                "oil_rail_crown_m",
                "m",
                "crown height of each oil-ring rail's face",
                2e-7,
                1e-4,
            ),
            n(
                "roughness_m",
                "m",
                "composite RMS roughness sigma of ring faces and liner",
                1e-8,
                1e-5,
            ),
            n(
                "eta_beta_sigma",
                "-",
                "Greenwood-Tripp roughness parameter eta beta sigma",
                1e-3,
                1.0,
            ),
            n(
                "sigma_over_beta",
                "-",
                "Greenwood-Tripp asperity slope measure sigma / beta",
                1e-6,
                1.0,
            ),
            n(
                "modulus_pa",
                "Pa",
                "composite elastic modulus E* of ring and liner (1/E* = sum (1 - nu^2)/E)",
                1e9,
                1e12,
            ),
            n(
                "boundary_mu",
                "-",
                "boundary friction coefficient on the asperity load",
                0.0,
                1.0,
            ),
            n(
                "v_smooth_m_s",
                "m/s",
                "velocity scale of the boundary friction's smoothed sign",
                1e-6,
                1.0,
            ),
            ParamSpec::choice(
                "inlet",
                "oil at each face's inlet: flooded, or starved (each face rides the layer the face ahead left on the liner)",
                &["flooded", "starved"],
            ),
            n(
                "top_supply_film_m",
                "m",
                "starved: oil layer on the liner above the top ring, met on the downstroke",
                1e-9,
                1e-4,
            ),
            ParamSpec::choice(
                "top_supply",
                "starved: the top ring's downstroke layer, fixed (top_supply_film_m) or carried (the layer it left there on the last upstroke)",
                &["fixed", "carried"],
            ),
        ]
    }

    fn new(p: Params) -> Result<Self, ParamError> {
        let starved = match p.inlet.as_str() {
            "flooded" => false,
            "starved" => true,
            other => {
                return Err(ParamError::new(
                    "inlet",
                    format!("unknown inlet `{other}`: expected `flooded` or `starved`"),
                ))
            }
        };
        let carried = match p.top_supply.as_str() {
            "fixed" => false,
            "carried" => true,
            other => {
                return Err(ParamError::new(
                    "top_supply",
                    format!("unknown top_supply `{other}`: expected `fixed` or `carried`"),
                ))
            }
        };
        if carried && !starved {
            return Err(ParamError::new(
                "top_supply",
                "top_supply = \"carried\" needs inlet = \"starved\" (a flooded pack meets no layer on the liner)",
            ));
        }
        let ring = |crown_param: &'static str,
                    width: f64,
                    crown: f64,
                    tension: f64,
                    gas: f64,
                    rails: u32| {
            if crown > 0.5 * width {
                return Err(ParamError::new(
                    crown_param,
                    format!("a crown of {crown} m on a {width} m face is not a ring face (crown above half the width)"),
                ));
            }
            Ok(Ring {
                face: Face {
                    half_width_m: 0.5 * width,
                    crown_m: crown,
                },
                tension_n: tension,
                gas_fraction: gas,
                rails,
            })
        };
        Ok(Self {
            rings: [
                ring(
                    "top_crown_m",
                    p.top_width_m,
                    p.top_crown_m,
                    p.top_tension_n,
                    p.top_gas_fraction,
                    1,
                )?,
                ring(
                    "second_crown_m",
                    p.second_width_m,
                    p.second_crown_m,
                    p.second_tension_n,
                    p.second_gas_fraction,
                    1,
                )?,
                ring(
                    "oil_rail_crown_m",
                    p.oil_rail_width_m,
                    p.oil_rail_crown_m,
                    p.oil_tension_n,
                    0.0,
                    2,
                )?,
            ],
            rough: Roughness {
                sigma_m: p.roughness_m,
                eta_beta_sigma: p.eta_beta_sigma,
                sigma_over_beta: p.sigma_over_beta,
                modulus_pa: p.modulus_pa,
            },
            boundary_mu: p.boundary_mu,
            v_smooth: p.v_smooth_m_s,
            starved,
            top_supply_m: p.top_supply_film_m,
            carried,
        })
    }

    fn state_size(&self) -> usize {
        if self.starved && self.carried {
            COVERED + LINER_BINS
        } else {
            STATE
        }
    }

    fn evaluate(&self, input: &LawInput, state: &[f64]) -> LawOutput {
        if !Self::valid(input) {
            return LawOutput::force(0.0);
        }
        let p = self.pack(input, state);
        let h_min = p
            .contacts
            .iter()
            .map(|c| c.h_m)
            .fold(f64::INFINITY, f64::min);
        let peak = p
            .contacts
            .iter()
            .map(|c| c.film.peak_pa)
            .fold(0.0, f64::max);
        let lambda = h_min / self.rough.sigma_m;
        let regime = film_regime(lambda);
        let mut out = LawOutput::force(p.force_n)
            .with_regime(regime)
            .with_min_film(h_min)
            .with_peak_pressure(peak);
        if p.radial_load_n > 0.0 {
            out = out
                .with_coefficient(p.force_n.abs() / p.radial_load_n)
                .with_asperity_share((p.asperity_load_n / p.radial_load_n).clamp(0.0, 1.0));
        }
        out
    }

    fn commit(&self, input: &LawInput, state: &mut [f64]) {
        if state.len() < STATE || !Self::valid(input) {
            return;
        }
        let loads = self.loads(input);
        let (faces, supplies) = self.faces(input, state, &loads);
        let u = input.relative_velocity.abs();
        let mu = input.viscosity_pa_s;
        // Flooded, the rails are alike: the upper rail's film is the lower's.
        let count = if self.starved { 4 } else { RINGS };
        for f in 0..count {
            let h = faces[f].h_m;
            let h = match Self::committed(state, f) {
                Some(old) if !self.starved || old <= h => old,
                // Placed above a layer that has thinned since: the face is on the layer.
                Some(_) | None => h,
            };
            let (r, load) = (self.ring_of(f), loads[f.min(RINGS - 1)]);
            let next = if input.dt_s > 0.0 {
                r.advance(&self.rough, h, input.dt_s, u, load, mu, supplies[f])
            } else {
                h
            };
            if next.is_finite() {
                state[if f == 3 { LOWER_RAIL } else { f }] = next;
            }
        }
        if !self.starved {
            state[LOWER_RAIL] = state[RINGS - 1];
        }
        state[RINGS] = 1.0;
        self.lay(input, state, faces[0].film.layer_left_m(u));
    }
}

export_law!(RingPack);

#[cfg(test)]
mod tests {
    use super::*;
    use tribo_plugin_api::conformance::assert_law_conforms;

    #[test]
    fn conforms() {
        assert_law_conforms::<RingPack>();
    }

    #[test]
    fn conforms_starved() {
        tribo_plugin_api::conformance::assert_law_conforms_with::<RingPack>("inlet = \"starved\"");
    }

    #[test]
    fn conforms_carried() {
        tribo_plugin_api::conformance::assert_law_conforms_with::<RingPack>(
            "inlet = \"starved\"\ntop_supply = \"carried\"",
        );
    }

    #[test]
    fn an_unknown_top_supply_is_refused_naming_it() {
        let e = law("top_supply = \"borrowed\"").expect_err("refused");
        assert!(e.to_string().contains("top_supply"), "{e}");
    }

    #[test]
    fn an_unknown_inlet_is_refused_naming_it() {
        let e = law("inlet = \"drowned\"").expect_err("refused");
        assert!(e.to_string().contains("inlet"), "{e}");
    }

    /// Starved, each face is fed by the one ahead of it in the sliding direction: upstroke from
    /// the crankcase (flooded lower rail) up to the top ring, downstroke from the layer above
    /// the top ring down to the lower rail. Oil is conserved along the pack: a starved face
    /// (its film's inlet inside the face) passes on the layer it met, to the root's tolerance,
    /// in quasi-static sliding (no squeeze); a flooded one passes on less (the rest stays ahead
    /// of it), never more. Flooded, every inlet is full and both rails alike.
    #[test]
    fn a_starved_pack_feeds_each_ring_from_the_one_ahead() {
        let starved = law("inlet = \"starved\"\ntop_supply_film_m = 0.4e-6").expect("starved");
        for (v, order) in [(5.0, UPSTROKE), (-5.0, DOWNSTROKE)] {
            let p = starved.pack(&piston(v, 0.0), &[0.0; STATE]);
            let faces = [p.contacts[0], p.contacts[1], p.contacts[2], p.lower_rail];
            let lead = if v > 0.0 { None } else { Some(0.4e-6) };
            assert_eq!(p.supplies[order[0]], lead, "{v}");
            let mut starved_faces = 0;
            for w in order.windows(2) {
                let (ahead, next) = (w[0], w[1]);
                let left = faces[ahead].film.layer_left_m(5.0);
                assert_eq!(p.supplies[next], Some(left), "{v}: face {next}");
                if let Some(had) = p.supplies[ahead] {
                    let a = starved.rings()[ahead.min(2)].face.half_width_m;
                    assert!(
                        left <= had * (1.0 + 1e-9),
                        "{v}: face {ahead} left {left} of {had}"
                    );
                    if faces[ahead].film.inlet_m > -a * (1.0 - 1e-9) {
                        starved_faces += 1;
                        assert!(
                            (left - had).abs() <= 1e-8 * had,
                            "{v}: starved face {ahead} left {left} of {had}"
                        );
                    }
                }
            }
            assert!(starved_faces > 0, "{v}: no starved face checked");
        }
        let flooded = law("")
            .expect("defaults")
            .pack(&piston(5.0, 0.0), &[0.0; STATE]);
        assert_eq!(flooded.supplies, [None; 4]);
        assert_eq!(flooded.lower_rail, flooded.contacts[2]);
    }

    /// Carried top supply: on the downstroke the top ring meets, at each place of the liner,
    /// the layer it left there on the upstroke (the layer of a commit that crossed that bin);
    /// where it has not been, `top_supply_film_m`. Fixed, the state has no bins.
    #[test]
    fn a_carried_top_supply_is_the_layer_the_top_ring_left_there() {
        let text = "inlet = \"starved\"\ntop_supply = \"carried\"\ntop_supply_film_m = 0.7e-6";
        let l = law(text).expect("carried");
        assert_eq!(l.state_size(), COVERED + LINER_BINS);
        let fixed = law("inlet = \"starved\"").expect("fixed");
        assert_eq!(fixed.state_size(), STATE);
        let mut s = vec![0.0; l.state_size()];
        let at = |v: f64, travel: f64| {
            let mut i = piston(v, 0.0);
            i.piston_from_tdc_m = travel;
            i.dt_s = 0.3e-3 / v.abs();
            i
        };
        // Up the bore from 40 mm below TDC to 10 mm, 0.3 mm a step, the speed changing so that
        // the layer left changes from step to step.
        let mut laid = Vec::new();
        let mut travel = 0.040;
        while travel > 0.010 {
            let v = 2.0 + 100.0 * travel;
            let i = at(v, travel);
            laid.push((travel, l.pack(&i, &s).contacts[0].film.layer_left_m(v)));
            l.commit(&i, &mut s);
            travel -= 0.3e-3;
        }
        assert!(laid.windows(2).all(|w| w[0].1 != w[1].1), "{laid:?}");
        // Down again: the layer met is the mean of those laid over this bin (within a bin and
        // a step of here), and over the whole stretch the oil met is the oil laid.
        let near = |x: f64| {
            laid.iter()
                .filter(move |&&(y, _)| (y - x).abs() <= LINER_BIN_M + 0.3e-3)
                .map(|&(_, left)| left)
        };
        for &(x, _) in laid.iter().skip(1).take(laid.len() - 2) {
            let met = l.pack(&at(-3.0, x), &s).supplies[0].expect("starved");
            let lo = near(x).fold(f64::INFINITY, f64::min);
            let hi = near(x).fold(0.0, f64::max);
            assert!(
                met >= lo * (1.0 - 1e-12) && met <= hi * (1.0 + 1e-12),
                "at {x}: met {met}, laid {lo}-{hi}"
            );
        }
        // Each step laid its layer over the 0.3 mm it crossed before it (the first, nothing).
        let oil_laid: f64 = laid.iter().skip(1).map(|&(_, left)| left * 0.3e-3).sum();
        let (first, last) = (laid[0].0, laid[laid.len() - 1].0);
        let oil_met: f64 = (0..LINER_BINS)
            .map(|b| {
                let start = b as f64 * LINER_BIN_M;
                let share = (first.min(start + LINER_BIN_M) - last.max(start)).max(0.0);
                if share > 0.0 {
                    s[BINS + b] / s[COVERED + b] * share
                } else {
                    0.0
                }
            })
            .sum();
        assert!(
            (oil_met - oil_laid).abs() <= 1e-9 * oil_laid,
            "met {oil_met}, laid {oil_laid}"
        );
        // Never reached: the fixed layer.
        for x in [0.005, 0.06] {
            assert_eq!(l.pack(&at(-3.0, x), &s).supplies[0], Some(0.7e-6), "{x}");
        }
    }

    fn law(text: &str) -> Result<RingPack, ParamError> {
        tribo_plugin_api::create_from_table::<RingPack>(&text.parse().expect("toml"))
    }

    /// The CRF's piston sliding at `v` m/s on 80 C oil, the pressure drop `dp` across the pack.
    fn piston(v: f64, dp: f64) -> LawInput {
        let mut i = LawInput::at_rest(JointKind::Prismatic).with_velocity(v);
        i.contact_radius_m = 0.0384;
        i.contact_length_m = 0.03;
        i.viscosity_pa_s = 0.0249;
        i.cylinder_pressure_pa += dp;
        i
    }

    #[test]
    fn a_crown_above_half_the_face_is_refused_naming_it() {
        let e = law("oil_rail_width_m = 1e-5\noil_rail_crown_m = 1e-5").expect_err("refused");
        assert!(e.to_string().contains("oil_rail_crown_m"), "{e}");
    }

    /// The force opposes the sliding at every speed, vanishes at rest, and is odd in the
    /// velocity (a symmetric face).
    #[test]
    fn the_force_opposes_the_motion_and_is_odd() {
        let l = law("").expect("defaults");
        assert_eq!(l.evaluate(&piston(0.0, 0.0), &[0.0; STATE]).force, 0.0);
        for &v in &[1e-6, 1e-3, 0.1, 1.0, 5.0, 20.0] {
            let (p, n) = (
                l.evaluate(&piston(v, 0.0), &[0.0; STATE]).force,
                l.evaluate(&piston(-v, 0.0), &[0.0; STATE]).force,
            );
            assert!(p < 0.0 && (p + n).abs() <= 1e-12 * p.abs(), "{v}: {p} {n}");
        }
    }

    /// The radial load of each ring: 2 F_t / D, split between the oil ring's rails; a pressure
    /// drop towards the crankcase loads the top ring by all of it over its width, the second by
    /// its fraction, the oil ring not at all; a drop towards the cylinder loads nothing.
    #[test]
    fn tension_and_gas_load_the_rings_as_declared() {
        let l = law("").expect("defaults");
        let d = 0.0768;
        let [top, second, oil] = l.rings().map(|r| r.load_per_length(d, 1e6));
        assert!((top - (2.0 * 8.0 / d + 1e6 * 0.8e-3)).abs() < 1e-9);
        assert!((second - (2.0 * 7.0 / d + 0.2e6 * 0.8e-3)).abs() < 1e-9);
        assert!((oil - 20.0 / d).abs() < 1e-9);
        let reversed = l.rings().map(|r| r.load_per_length(d, -1e6));
        assert!((reversed[0] - 2.0 * 8.0 / d).abs() < 1e-9);
        // Gas behind the rings: more friction, a thinner top-ring film.
        let (calm, loaded) = (
            l.pack(&piston(5.0, 0.0), &[0.0; STATE]),
            l.pack(&piston(5.0, 2e6), &[0.0; STATE]),
        );
        assert!(loaded.force_n < calm.force_n);
        assert!(loaded.contacts[0].h_m < calm.contacts[0].h_m);
        assert_eq!(loaded.contacts[2].h_m, calm.contacts[2].h_m);
    }

    /// On a revolute joint the slide law gives no force and reports nothing.
    #[test]
    fn a_revolute_joint_gets_no_force() {
        let l = law("").expect("defaults");
        let mut i = LawInput::at_rest(JointKind::Revolute).with_velocity(300.0);
        i.contact_radius_m = 0.02;
        i.viscosity_pa_s = 0.02;
        let o = l.evaluate(&i, &[0.0; STATE]);
        assert_eq!((o.force, o.flags), (0.0, 0));
    }

    /// The films stay between the floor and the quasi-static film of the sliding speed: after a
    /// fast stroke stops, the squeeze film drains towards the asperities' floor, never below.
    #[test]
    fn a_stopped_ring_sinks_by_squeeze_to_the_asperity_floor() {
        let l = law("").expect("defaults");
        let mut s = [0.0; STATE];
        let mut i = piston(10.0, 0.0);
        i.dt_s = 1e-5;
        l.commit(&i, &mut s);
        let sliding = s[0];
        let mut stopped = piston(0.0, 0.0);
        stopped.dt_s = 1e-5;
        let mut last = sliding;
        for _ in 0..2000 {
            l.commit(&stopped, &mut s);
            assert!(s[0] <= last, "{} after {last}", s[0]);
            last = s[0];
        }
        let floor = l.rings()[0].floor(l.roughness(), 2.0 * 8.0 / 0.0768);
        assert!(
            s[0] < 0.5 * sliding && s[0] >= floor,
            "{} from {sliding}, floor {floor}",
            s[0]
        );
    }
}
