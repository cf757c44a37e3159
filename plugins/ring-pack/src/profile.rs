//! The film of one parabolic ring face on a flat liner: the one-dimensional Reynolds equation
//! with steady sliding and squeeze, solved in closed form.
//!
//! In the ring's frame the liner slides at speed `u` (the leading edge is the inlet; the face is
//! symmetric, so only `|u|` matters) and the face's profile is
//! `h(x) = h + crown (x / a)^2` on `-a <= x <= a` (`a` half the face width, `h` the minimum film).
//! The Reynolds equation `d/dx(h^3 dp/dx) = 6 mu u dh/dx + 12 mu dh/dt` integrates once to
//! `h^3 dp/dx = 6 mu u h + 12 mu hdot x + C`. With `s = x sqrt(crown / h) / a`
//! (`h(x) = h (1 + s^2)`, `x = L s`, `L = a sqrt(h / crown)`, `S = sqrt(crown / h)` the edge)
//! every integral of the pressure, the load and the shear is a polynomial over a power of
//! `1 + s^2`, integrated in closed form (arctangents and rational terms: [`Prims`]).
//!
//! Boundary conditions: the inlet is flooded at the ambient pressure (`p = 0`, gauge); where the
//! film diverges it ruptures by the Reynolds (Swift-Stieber) condition, `p = dp/dx = 0` at the
//! rupture point `s_c`, and carries the oil on in streamers filling `h(s_c) / h(s)` of the gap
//! (flow continuity at the rupture); a film squeezed fast enough stays whole to the outlet
//! (`p = 0` there, `dp/dx <= 0`). Given the load the film must carry, the squeeze velocity
//! `hdot` follows (the film's mobility): below the load the full film can reach, the rupture
//! point is the root of a monotone function of `s_c`; above it the full film's load is linear in
//! `hdot`.

use tribo_plugin_api::tribology::{newton_increasing, root_increasing};

/// The ring face: half its axial width and the height of its parabolic crown at the edges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Face {
    /// Half the axial width of the face in contact, m.
    pub half_width_m: f64,
    /// Crown height: the profile's drop from its apex to the face's edges, m.
    pub crown_m: f64,
}

/// The film that carries a given load at a given minimum film and sliding speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Film {
    /// Rate of change of the minimum film, m/s (negative: the ring approaches the liner).
    pub squeeze_m_s: f64,
    /// Viscous friction force per unit circumference on the liner, N/m, opposing the liner's
    /// motion relative to the ring (its magnitude: always `>= 0` for a film that carries load).
    pub shear_n_per_m: f64,
    /// Peak film pressure, Pa (gauge).
    pub peak_pa: f64,
    /// Where the film ruptures, m from the apex towards the outlet; the half width when the film
    /// is whole to the outlet; the inlet when it carries nothing.
    pub rupture_m: f64,
    /// Where the full film begins, m from the apex (minus the half width when flooded; nearer
    /// the apex when starved: where the gap closes to the oil available on the liner).
    pub inlet_m: f64,
    /// The film at the outlet boundary, m: at the rupture point, or at the trailing edge when
    /// the film is whole to it. The flux leaving there is `|u| outlet_film_m / 2` or more
    /// (exactly that at a rupture), which is what the oil left behind on the liner is built on.
    pub outlet_film_m: f64,
    /// The oil flux into the film at its inlet, m^2/s per metre of circumference (in the ring's
    /// frame): `|u| h_in / 2 - h_in^3 p' / (12 mu)` there.
    pub inflow_m2_s: f64,
    /// The oil flux leaving at the outlet, m^2/s per metre of circumference: the inflow plus
    /// what the squeeze pushes out between inlet and outlet (`dq/dx = -dh/dt`). It leaves a
    /// layer `outflow / |u|` on the liner.
    pub outflow_m2_s: f64,
}

impl Film {
    /// The layer this face leaves on the liner behind it, m: its outflow spread on the liner
    /// moving at `u_abs`, at most half the outlet film (the Couette share of a film whose
    /// outlet is whole: the part of the outflow a squeeze pushes out there is not laid down,
    /// which near the dead centres, where `|u|` vanishes, would make a layer of any
    /// thickness); at rest, half the outlet film.
    pub fn layer_left_m(&self, u_abs: f64) -> f64 {
        let half = 0.5 * self.outlet_film_m;
        if u_abs > 0.0 {
            (self.outflow_m2_s / u_abs).min(half)
        } else {
            half
        }
    }
}

/// The flux of a whole film at `s` (its inlet or outlet): `|u| h / 2 - h^3 p' / (12 mu)` with
/// `dp/ds = (alpha s^2 + beta s + gamma) / (1 + s^2)^3`, which is
/// `|u| h_m / 2 - h_m^3 (beta s + gamma) / (12 mu L)` (the `alpha` terms cancel the Couette
/// flux's `s^2` part).
fn whole_film_flux(u_abs: f64, h_m: f64, mu: f64, l: f64, beta: f64, gamma: f64, s: f64) -> f64 {
    0.5 * u_abs * h_m - h_m.powi(3) * (beta * s + gamma) / (12.0 * mu * l)
}

/// Antiderivatives at `s` of `s^k / (1 + s^2)^3` (`m[k]`, k = 0..3), of `s^k / (1 + s^2)^2`
/// (`n[k]`, k = 0..2) and of `1 / (1 + s^2)` (`j1`).
#[derive(Debug, Clone, Copy)]
pub struct Prims {
    /// `integral s^k / (1 + s^2)^3`, k = 0..3.
    pub m: [f64; 4],
    /// `integral s^k / (1 + s^2)^2`, k = 0..2.
    pub n: [f64; 3],
    /// `atan(s)`.
    pub j1: f64,
}

impl Prims {
    /// The antiderivatives at `s`.
    pub fn at(s: f64) -> Self {
        let q = 1.0 + s * s;
        let at = s.atan();
        let j2 = 0.5 * s / q + 0.5 * at;
        let j3 = 0.25 * s / (q * q) + 0.375 * s / q + 0.375 * at;
        Self {
            m: [
                j3,
                -0.25 / (q * q),
                0.125 * s / q - 0.25 * s / (q * q) + 0.125 * at,
                -0.5 / q + 0.25 / (q * q),
            ],
            n: [j2, -0.5 / q, 0.5 * at - 0.5 * s / q],
            j1: at,
        }
    }

    /// `self - lower`, term by term: the definite integrals from `lower`'s point to `self`'s.
    pub fn minus(&self, lower: &Prims) -> Prims {
        let mut d = *self;
        for k in 0..4 {
            d.m[k] -= lower.m[k];
        }
        for k in 0..3 {
            d.n[k] -= lower.n[k];
        }
        d.j1 -= lower.j1;
        d
    }

    /// `integral 1 / (1 + s^2)^2` (the same as `n[0]`).
    pub fn j2(&self) -> f64 {
        self.n[0]
    }
}

/// The rupture branch at rupture point `sc`: the squeeze number `Q = 2 hdot L / (h |u|)` that
/// puts `p = 0` at `sc` (with `dp/dx = 0` there), and the load in units of `L * 6 mu |u| L / h^2`.
#[cfg(test)]
fn rupture_branch(sc: f64, lower: &Prims) -> (f64, f64) {
    let b = Branch::at(sc, lower);
    (b.q, b.load)
}

/// The rupture branch at one rupture point `sc`, with the slope of its load.
#[derive(Debug, Clone, Copy)]
struct Branch {
    /// The rupture point, in `s`.
    sc: f64,
    /// The antiderivatives at `sc`.
    at: Prims,
    /// Their integrals from the inlet edge to `sc`.
    d: Prims,
    /// The squeeze number `Q = 2 hdot L / (h |u|)` that puts `p = 0` at `sc`.
    q: f64,
    /// The load, in units of `L * 6 mu |u| L / h^2`.
    load: f64,
    /// `d load / d sc`, same units.
    slope: f64,
}

impl Branch {
    /// The branch at `sc`; `lower`, the inlet edge's antiderivatives, computed once per film.
    fn at(sc: f64, lower: &Prims) -> Self {
        let at = Prims::at(sc);
        let d = at.minus(lower);
        // p(sc) = 0: integral (t - sc)(t + sc + Q) / (1 + t^2)^3 from -S to sc vanishes.
        let a = d.m[2] - sc * sc * d.m[0];
        let b = d.m[1] - sc * d.m[0];
        let q = if b != 0.0 { -a / b } else { 0.0 };
        let k = sc + q;
        // Load: -integral (t - sc)^2 (t + k) / (1 + t^2)^3 (by parts, p = 0 at both ends).
        let load = -(d.m[3]
            + (k - 2.0 * sc) * d.m[2]
            + (sc * sc - 2.0 * sc * k) * d.m[1]
            + sc * sc * k * d.m[0]);
        // Its slope by Leibniz's rule: the integrand vanishes at the upper limit, and the
        // derivative of (t - sc)^2 (t + k) in sc is -2 (t - sc)(t + k), whose integral is
        // p(sc) = 0, plus (t - sc)^2 dk/dsc. The condition p(sc) = 0, written
        // `m2 - sc m1 + k (m1 - sc m0) = 0`, differentiates the same way (its upper-limit terms
        // cancel too): `-(m1 + k m0) + b dk/dsc = 0`.
        let dk = if b != 0.0 {
            (d.m[1] + k * d.m[0]) / b
        } else {
            0.0
        };
        let slope = -dk * (d.m[2] - 2.0 * sc * d.m[1] + sc * sc * d.m[0]);
        Self {
            sc,
            at,
            d,
            q,
            load,
            slope,
        }
    }
}

/// The rupture branch in `(s_in, big_s)` (`s_in` the inlet, `lower`'s point) that carries
/// `target` (in the branch's load units): Newton's method on the closed-form slope
/// ([`newton_increasing`]), inside a bracket every step narrows (bisection where a step would
/// leave it). The branch's load rises from 0 at the inlet to the full film's at the outlet
/// edge, which is above `target`, so the bracket needs no evaluation.
/// Starts from `guess` (a nearby film's rupture point, in `s`) when there is one. Converged when
/// a step moves the point by less than 1e-14 of the face's half width (in `s`).
fn rupture_for_load(
    target: f64,
    lower: &Prims,
    s_in: f64,
    big_s: f64,
    guess: Option<f64>,
) -> Branch {
    // The apex when it lies inside the stretch (always, flooded), else the stretch's middle.
    let middle = if s_in < 0.0 {
        0.0
    } else {
        0.5 * (s_in + big_s)
    };
    let start = guess.filter(|g| *g > s_in && *g < big_s).unwrap_or(middle);
    let sc = newton_increasing(
        |x| {
            let b = Branch::at(x, lower);
            (b.load - target, b.slope)
        },
        s_in,
        big_s,
        start,
        1e-14 * big_s,
    );
    Branch::at(sc, lower)
}

/// The film of `face` at minimum film `h_m` (> 0), sliding speed `u_abs` (>= 0, m/s) and
/// viscosity `mu` (> 0, Pa s) that carries `load_n_per_m` (N per metre of circumference):
/// the squeeze velocity that makes it carry that load, its shear and its peak pressure.
/// A load `<= 0` gives the fully ruptured film (nothing carried: the ring lifts as fast as the
/// inlet can follow, `hdot = crown |u| / a`).
pub fn film_for_load(face: &Face, h_m: f64, u_abs: f64, load_n_per_m: f64, mu: f64) -> Film {
    film_for_load_near(face, h_m, u_abs, load_n_per_m, mu, None)
}

/// [`film_for_load`] with a guess of the rupture point (m from the apex, a nearby film's
/// `rupture_m`): the search starts there, which saves most of it when the film has barely
/// changed (a finite-difference neighbour). The same root either way.
pub fn film_for_load_near(
    face: &Face,
    h_m: f64,
    u_abs: f64,
    load_n_per_m: f64,
    mu: f64,
    rupture_guess_m: Option<f64>,
) -> Film {
    film_for_load_supplied(face, h_m, u_abs, load_n_per_m, mu, rupture_guess_m, None)
}

/// The meniscus, in `s`, of a face at minimum film `h_m` meeting a layer of oil `supply_m`
/// thick on the liner: where the gap closes to the layer, `h (1 + s^2) = supply` on the
/// converging side; the apex when the layer is no thicker than the minimum film. `None`:
/// flooded (no supply given, or a layer at least as thick as the gap at the leading edge).
/// The film of a starved face begins there or further out ([`film_for_load_supplied`]).
pub fn starved_inlet_s(face: &Face, h_m: f64, supply_m: Option<f64>) -> Option<f64> {
    let supply = supply_m?;
    if supply >= h_m + face.crown_m {
        return None;
    }
    Some(-((supply / h_m - 1.0).max(0.0)).sqrt())
}

/// [`film_for_load_near`] with the oil available at the inlet: `supply_m`, the thickness of the
/// layer on the liner the face runs into (`None`: flooded). The layer brings `|u| supply` of
/// oil per metre of circumference, and a face passes on what it takes in, so:
///
/// - the film begins where it takes in the layer's whole flux (its inflow, Couette less
///   Poiseuille at the inlet, equals `|u| supply`), between the meniscus where the gap closes
///   to the layer ([`starved_inlet_s`], the apex if it never does; a filled gap there takes at
///   most half of it) and the leading edge: the oil a face cannot take in piles up ahead of it
///   and moves its inlet out until it can (quasi-steady: the pile's own volume is not
///   tracked); so the film's outflow is the layer's flux, and a ruptured film's outlet gap is
///   twice the layer;
/// - a face whose minimum film is above twice the layer can take none of it in (a gap that
///   wide is not filled by the layer's flux): when the asperities carry the load the face is
///   dry (no viscous shear) and the layer goes on whole; the ring's film never rises there
///   ([`crate::ring::Ring::ceiling`]);
/// - a face whose flooded film takes in no more than the layer brings is flooded (the rest
///   stays ahead of it), as is one meeting a layer at least as thick as the gap at its leading
///   edge: the same film, to the bit, as without a supply.
///
/// At rest (`u_abs = 0`) no oil is carried in and the film begins at the meniscus.
pub fn film_for_load_supplied(
    face: &Face,
    h_m: f64,
    u_abs: f64,
    load_n_per_m: f64,
    mu: f64,
    rupture_guess_m: Option<f64>,
    supply_m: Option<f64>,
) -> Film {
    let Some(meniscus) = starved_inlet_s(face, h_m, supply_m) else {
        return flooded(face, h_m, u_abs, load_n_per_m, mu, rupture_guess_m);
    };
    let supply = supply_m.unwrap_or(f64::INFINITY);
    let from =
        |s_in: f64| film_from_inlet(face, h_m, u_abs, load_n_per_m, mu, rupture_guess_m, s_in);
    if 2.0 * supply < h_m && load_n_per_m <= 0.0 {
        return dry(u_abs, supply);
    }
    if u_abs <= 0.0 || 2.0 * supply < h_m {
        return from(meniscus);
    }
    let big_s = (face.crown_m / h_m).sqrt();
    let intake = u_abs * supply;
    if load_n_per_m <= 0.0 {
        // Nothing carried: streamers from where the gap is twice the layer (their Couette flux
        // `|u| h / 2` the layer's).
        let s2 = (2.0 * supply / h_m - 1.0).max(0.0).sqrt();
        return if s2 >= big_s {
            flooded(face, h_m, u_abs, load_n_per_m, mu, rupture_guess_m)
        } else {
            from(-s2)
        };
    }
    let full = flooded(face, h_m, u_abs, load_n_per_m, mu, rupture_guess_m);
    if full.inflow_m2_s <= intake {
        return full;
    }
    // Moving the inlet in takes in less: from more than the layer at the leading edge to at
    // most half of it at the meniscus.
    let s_in = root_increasing(|s| intake - from(s).inflow_m2_s, -big_s, meniscus);
    from(s_in)
}

/// A face the layer passes under without bridging the gap: no film, no shear, the layer
/// carried on whole.
fn dry(u_abs: f64, supply: f64) -> Film {
    Film {
        squeeze_m_s: 0.0,
        shear_n_per_m: 0.0,
        peak_pa: 0.0,
        rupture_m: 0.0,
        inlet_m: 0.0,
        outlet_film_m: 2.0 * supply,
        inflow_m2_s: u_abs * supply,
        outflow_m2_s: u_abs * supply,
    }
}

/// The flooded film (inlet at the leading edge): [`film_for_load_near`].
fn flooded(
    face: &Face,
    h_m: f64,
    u_abs: f64,
    load_n_per_m: f64,
    mu: f64,
    rupture_guess_m: Option<f64>,
) -> Film {
    let a = face.half_width_m;
    let big_s = (face.crown_m / h_m).sqrt();
    let l = a / big_s;
    let top = Prims::at(big_s);
    let low = Prims::at(-big_s);
    let full = top.minus(&low);
    // Units: the shear `mu |u| L / h`, the pressure gradient's sliding part `6 mu |u| L / h^2`.
    let shear_unit = mu * u_abs * l / h_m;
    let alpha = 6.0 * mu * u_abs * l / (h_m * h_m);
    let edge_film = h_m * (1.0 + big_s * big_s);
    if load_n_per_m <= 0.0 {
        return Film {
            squeeze_m_s: face.crown_m * u_abs / a,
            shear_n_per_m: shear_unit * (1.0 + big_s * big_s) * full.j2(),
            peak_pa: 0.0,
            rupture_m: -a,
            inlet_m: -a,
            outlet_film_m: edge_film,
            inflow_m2_s: 0.5 * u_abs * edge_film,
            outflow_m2_s: 0.5 * u_abs * edge_film,
        };
    }
    // The whole film: dp/ds = (alpha (s^2 + c) + beta s) / (1 + s^2)^3, p(+-S) = 0.
    let c = -full.m[2] / full.m[0];
    let w_edge = l * alpha * (big_s * big_s + c) * full.m[2] / big_s;
    if load_n_per_m >= w_edge {
        let beta = -load_n_per_m / (l * full.m[2]);
        let squeeze = beta * h_m.powi(3) / (12.0 * mu * l * l);
        // Peak at the smaller root of alpha s^2 + beta s + alpha c (stable form; beta < 0).
        let disc = (beta * beta - 4.0 * alpha * alpha * c).max(0.0);
        let s1 = 2.0 * alpha * c / (disc.sqrt() - beta);
        let d = Prims::at(s1).minus(&low);
        let peak = alpha * (d.m[2] + c * d.m[0]) + beta * d.m[1];
        let flux = |s: f64| whole_film_flux(u_abs, h_m, mu, l, beta, alpha * c, s);
        return Film {
            squeeze_m_s: squeeze,
            shear_n_per_m: shear_unit * (full.j1 + 3.0 * (full.n[2] + c * full.n[0])),
            peak_pa: peak.max(0.0),
            rupture_m: a,
            inlet_m: -a,
            outlet_film_m: edge_film,
            inflow_m2_s: flux(-big_s),
            outflow_m2_s: flux(big_s),
        };
    }
    // Ruptured film: the rupture point whose load is the one asked for (the load rises
    // monotonically from 0 at the inlet edge to `w_edge` at the outlet edge).
    let target = load_n_per_m / (l * alpha);
    let branch = rupture_for_load(target, &low, -big_s, big_s, rupture_guess_m.map(|x| x / l));
    ruptured(branch, &top, -big_s, h_m, u_abs, l, shear_unit, alpha)
}

/// The film of a ruptured `branch` whose inlet is `s_in` (`top` the trailing edge's
/// antiderivatives): its squeeze, shear (Couette, Poiseuille and the streamers beyond the
/// rupture), peak and fluxes (`|u| h_c / 2` at the rupture, `dq/dx = -dh/dt` back to the inlet).
#[allow(clippy::too_many_arguments)]
fn ruptured(
    branch: Branch,
    top: &Prims,
    s_in: f64,
    h_m: f64,
    u_abs: f64,
    l: f64,
    shear_unit: f64,
    alpha: f64,
) -> Film {
    let (sc, q, at_c, d) = (branch.sc, branch.q, branch.at, branch.d);
    let k = sc + q;
    let poiseuille = d.n[2] + (k - sc) * d.n[1] - sc * k * d.n[0];
    let streamers = (1.0 + sc * sc) * (top.j2() - at_c.j2());
    let sp = (-k).clamp(s_in, sc);
    let dp = Prims::at(sp).minus(&Prims::at(s_in));
    let peak = alpha * (dp.m[2] + (k - sc) * dp.m[1] - sc * k * dp.m[0]);
    let squeeze = q * h_m * u_abs / (2.0 * l);
    let outlet_film = h_m * (1.0 + sc * sc);
    let outflow = 0.5 * u_abs * outlet_film;
    // The shear booked is never negative: the push of an asymmetric (starved) squeeze film is
    // the squeeze's work, which is not booked (as in `film_from_inlet`'s whole film).
    Film {
        squeeze_m_s: squeeze,
        shear_n_per_m: (shear_unit * (d.j1 + 3.0 * poiseuille + streamers)).max(0.0),
        peak_pa: peak.max(0.0),
        rupture_m: sc * l,
        inlet_m: s_in * l,
        outlet_film_m: outlet_film,
        inflow_m2_s: outflow + squeeze * (sc - s_in) * l,
        outflow_m2_s: outflow,
    }
}

/// The film of a face whose full film begins at `s_in` (in `s`, `-S <= s_in <= 0`) with
/// `p = 0` there: `flooded`'s three branches (nothing carried, whole to the trailing edge,
/// ruptured) on the wetted stretch `[s_in, S]` instead of `[-S, S]`. The whole film's pressure
/// gradient is `(alpha s^2 + beta s + gamma) / (1 + s^2)^3` in `s`, with `p = 0` at both ends
/// of a stretch that is no longer symmetric (so the odd moments `m[1]`, `m[3]` and `n[1]` no
/// longer vanish); `gamma` replaces the flooded code's `alpha c` so that a film at rest
/// (`alpha = 0`) needs no division by the sliding speed. Public for the closed-form checks of
/// a film from a given inlet.
pub fn film_from_inlet(
    face: &Face,
    h_m: f64,
    u_abs: f64,
    load_n_per_m: f64,
    mu: f64,
    rupture_guess_m: Option<f64>,
    s_in: f64,
) -> Film {
    let a = face.half_width_m;
    let big_s = (face.crown_m / h_m).sqrt();
    let l = a / big_s;
    let top = Prims::at(big_s);
    let low = Prims::at(s_in);
    let full = top.minus(&low);
    let shear_unit = mu * u_abs * l / h_m;
    let alpha = 6.0 * mu * u_abs * l / (h_m * h_m);
    let inlet_film = h_m * (1.0 + s_in * s_in);
    if load_n_per_m <= 0.0 {
        // Nothing carried: the film ruptures at its inlet and the streamers carry the oil on.
        return Film {
            squeeze_m_s: face.crown_m * u_abs / a,
            shear_n_per_m: shear_unit * (1.0 + s_in * s_in) * (top.j2() - low.j2()),
            peak_pa: 0.0,
            rupture_m: s_in * l,
            inlet_m: s_in * l,
            outlet_film_m: inlet_film,
            inflow_m2_s: 0.5 * u_abs * inlet_film,
            outflow_m2_s: 0.5 * u_abs * inlet_film,
        };
    }
    let w_edge = l * alpha * Branch::at(big_s, &low).load;
    if load_n_per_m >= w_edge {
        // p(s_in) = p(S) = 0: alpha m2 + beta m1 + gamma m0 = 0; the load by parts:
        // W / L = -(alpha m3 + beta m2 + gamma m1).
        let m = full.m;
        let beta =
            -(load_n_per_m / l + alpha * (m[3] - m[2] * m[1] / m[0])) / (m[2] - m[1] * m[1] / m[0]);
        let gamma = -(alpha * m[2] + beta * m[1]) / m[0];
        let squeeze = beta * h_m.powi(3) / (12.0 * mu * l * l);
        // Peak where the gradient first falls to zero (stable form of the smaller root).
        let disc = (beta * beta - 4.0 * alpha * gamma).max(0.0);
        let s1 = (2.0 * gamma / (disc.sqrt() - beta)).clamp(s_in, big_s);
        let d = Prims::at(s1).minus(&low);
        let peak = alpha * d.m[2] + beta * d.m[1] + gamma * d.m[0];
        // Shear: the Couette part, and the Poiseuille part (h/2) dp/dx, whose factor
        // 3 / alpha times shear_unit is h / 2.
        // The Poiseuille part of an asymmetric (starved) squeeze film can push the liner along
        // (`beta n1 < 0`); at low speed it may outweigh the Couette part. That work comes from
        // the squeeze (`w hdot`), which the law does not book (no radial degree of freedom), so
        // neither is the push: the shear booked is never negative (docs/laws/ring-pack.md).
        let shear = (shear_unit * (full.j1 + 3.0 * full.n[2])
            + 0.5 * h_m * (gamma * full.n[0] + beta * full.n[1]))
            .max(0.0);
        let flux = |s: f64| whole_film_flux(u_abs, h_m, mu, l, beta, gamma, s);
        return Film {
            squeeze_m_s: squeeze,
            shear_n_per_m: shear,
            peak_pa: peak.max(0.0),
            rupture_m: a,
            inlet_m: s_in * l,
            outlet_film_m: h_m * (1.0 + big_s * big_s),
            inflow_m2_s: flux(s_in),
            outflow_m2_s: flux(big_s),
        };
    }
    let target = load_n_per_m / (l * alpha);
    let guess = rupture_guess_m.map(|x| x / l);
    let branch = rupture_for_load(target, &low, s_in, big_s, guess);
    ruptured(branch, &top, s_in, h_m, u_abs, l, shear_unit, alpha)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The antiderivatives differentiate back to their integrands (central differences).
    #[test]
    fn antiderivatives_differentiate_to_their_integrands() {
        for &s in &[-3.0, -0.7, 0.0, 0.4, 2.5] {
            let e = 1e-5;
            let (p, m) = (Prims::at(s + e), Prims::at(s - e));
            let q: f64 = 1.0 + s * s;
            for k in 0..4 {
                let d = (p.m[k] - m.m[k]) / (2.0 * e);
                let want = s.powi(k as i32) / q.powi(3);
                assert!((d - want).abs() < 1e-8, "m[{k}] at {s}: {d} vs {want}");
            }
            for k in 0..3 {
                let d = (p.n[k] - m.n[k]) / (2.0 * e);
                let want = s.powi(k as i32) / q.powi(2);
                assert!((d - want).abs() < 1e-8, "n[{k}] at {s}: {d} vs {want}");
            }
        }
    }

    /// The branch's closed-form slope is the derivative of its load (five-point central
    /// differences; near the inlet edge, where the load is a difference of nearly equal
    /// antiderivatives, within 1e-9 of the branch's mean slope), and the Newton search lands
    /// where the branch carries the target load, from any start.
    #[test]
    fn the_rupture_branch_slope_is_its_loads_derivative() {
        for &big_s in &[0.3, 1.0, 4.0, 20.0] {
            let low = Prims::at(-big_s);
            let w = |sc: f64| rupture_branch(sc, &low).1;
            let mean_slope = w(big_s) / (2.0 * big_s);
            for i in 1..20 {
                let sc = -big_s + 2.0 * big_s * i as f64 / 20.0;
                let e = 1e-3 * big_s;
                let fd = (8.0 * (w(sc + e) - w(sc - e)) - (w(sc + 2.0 * e) - w(sc - 2.0 * e)))
                    / (12.0 * e);
                let b = Branch::at(sc, &low);
                assert!(b.slope > 0.0, "S {big_s}, sc {sc}: slope {}", b.slope);
                assert!(
                    (b.slope - fd).abs() <= 1e-6 * fd.abs() + 1e-9 * mean_slope,
                    "S {big_s}, sc {sc}: {} vs {fd}",
                    b.slope
                );
            }
            let (_, w_max) = rupture_branch(big_s, &low);
            for frac in [1e-6, 0.01, 0.3, 0.9, 0.999_999] {
                let target = frac * w_max;
                for guess in [None, Some(-0.99 * big_s), Some(0.0), Some(0.99 * big_s)] {
                    let b = rupture_for_load(target, &low, -big_s, big_s, guess);
                    assert!(
                        (b.load - target).abs() <= 1e-12 * w_max,
                        "S {big_s}, target {target}, guess {guess:?}: {}",
                        b.load
                    );
                }
            }
        }
    }

    /// The rupture branch's load rises monotonically from zero at the inlet to the full film's
    /// at the outlet edge (what the root search relies on), flooded (inlet at the leading edge)
    /// and starved (inlet inside the face, up to the apex).
    #[test]
    fn the_rupture_branch_load_is_monotone() {
        for &(big_s, inlet) in &[
            (0.3, 1.0),
            (1.0, 1.0),
            (4.0, 1.0),
            (20.0, 1.0),
            (1.0, 0.5),
            (4.0, 0.2),
            (20.0, 0.01),
            (4.0, 0.0),
        ] {
            let s_in = -inlet * big_s;
            let low = Prims::at(s_in);
            // Rounding: near the inlet edge the load is a difference of antiderivatives of
            // order one that nearly cancel (1e-16 absolute).
            let (_, w_max) = rupture_branch(big_s, &low);
            let mut last = -1.0;
            for i in 1..400 {
                let sc = s_in + (big_s - s_in) * i as f64 / 400.0;
                let (_, w) = rupture_branch(sc, &low);
                assert!(
                    w > last - 1e-12 * w_max,
                    "S {big_s}, sc {sc}: {w} after {last}"
                );
                last = w;
            }
        }
    }
}
