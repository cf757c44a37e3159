//! One ring (or one rail of the oil-control ring) on the liner: its radial load, the film that
//! carries the part of it the asperities do not, and the minimum film's motion in time.
//!
//! The ring has no radial inertia worth keeping (a few grams against loads of hundreds of
//! newtons per metre), so at every instant the film and the asperities carry the whole radial
//! load: `w = w_film(h, hdot) + w_asperity(h)`. Given the minimum film `h` (the law's state)
//! this fixes the squeeze velocity `hdot` ([`crate::profile::film_for_load`]); `commit` advances `h` by the
//! backward Euler rule `h_new = h_old + dt hdot(h_new)` (a monotone root: stable at any step,
//! however stiff the squeeze film gets near contact).

use crate::profile::{film_for_load_supplied, Face, Film};
use tribo_plugin_api::tribology::{root_increasing, Roughness, LAMBDA_MAX};

/// The thinnest film considered, in units of the composite roughness: below it the asperities
/// are in plastic contact and Greenwood-Tripp's elastic summits no longer describe them.
pub const LAMBDA_MIN: f64 = 0.1;

/// The thickest film considered, m (ring films are 0.1-20 um; a film this thick carries
/// nothing).
pub const H_MAX_M: f64 = 200e-6;

/// One ring: its face, its tension and how much of the pressure drop loads it from behind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ring {
    /// The face in contact with the liner (parabolic).
    pub face: Face,
    /// Tangential (closing) force of the ring, N: the elastic radial pressure is
    /// `2 F_t / (D b)` on a face of width `b`, so `2 F_t / D` per unit circumference.
    pub tension_n: f64,
    /// Fraction of `p_cylinder - p_crankcase` that acts behind the ring over its face width.
    pub gas_fraction: f64,
    /// How many faces share the tension (2 for the rails of a three-piece oil ring).
    pub rails: u32,
}

/// What one face does at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Minimum film, m.
    pub h_m: f64,
    /// Radial load per unit circumference, N/m.
    pub load_n_per_m: f64,
    /// The part of it the asperities carry, N/m.
    pub asperity_n_per_m: f64,
    /// The film carrying the rest.
    pub film: Film,
}

impl Ring {
    /// Radial load per unit circumference on one face, N/m: its share of the tension plus the
    /// gas behind it (a pressure drop towards the cylinder loads nothing).
    pub fn load_per_length(&self, bore_m: f64, pressure_drop_pa: f64) -> f64 {
        2.0 * self.tension_n / bore_m / self.rails.max(1) as f64
            + self.gas_fraction * pressure_drop_pa.max(0.0) * 2.0 * self.face.half_width_m
    }

    fn asperity(&self, rough: &Roughness, h_m: f64) -> f64 {
        rough.load_per_length(self.face.half_width_m, self.face.crown_m, h_m)
    }

    /// The film below which the asperities alone carry more than `load`: the least film the
    /// ring can sit at (never below `LAMBDA_MIN sigma`).
    pub fn floor(&self, rough: &Roughness, load: f64) -> f64 {
        let lo = LAMBDA_MIN * rough.sigma_m;
        let hi = LAMBDA_MAX * rough.sigma_m;
        if self.asperity(rough, lo) <= load {
            return lo;
        }
        root_increasing(|h| load - self.asperity(rough, h), lo, hi)
    }

    /// The thickest film the ring can ride on: [`H_MAX_M`], or, starved, twice the oil layer
    /// it runs into: the layer's flux `|u| s` fills a gap of `2 s` at the Couette flux, so a
    /// film can carry load up to that minimum gap (fed by the oil piled at its inlet) and
    /// above it the face touches no oil, and nothing holds it off the liner.
    pub fn ceiling(rough: &Roughness, supply_m: Option<f64>) -> f64 {
        supply_m.map_or(H_MAX_M, |s| {
            (2.0 * s).clamp(LAMBDA_MIN * rough.sigma_m, H_MAX_M)
        })
    }

    /// The face at minimum film `h_m` (raised to the floor of `load` if below it, lowered to the
    /// oil layer `supply_m` if above it), sliding at `u_abs` on oil of viscosity `mu` (Pa s,
    /// > 0); `supply_m` `None`: flooded.
    pub fn contact(
        &self,
        rough: &Roughness,
        h_m: f64,
        u_abs: f64,
        load: f64,
        mu: f64,
        supply_m: Option<f64>,
    ) -> Contact {
        let mut h = h_m.clamp(LAMBDA_MIN * rough.sigma_m, Self::ceiling(rough, supply_m));
        let mut asp = self.asperity(rough, h);
        if asp > load {
            h = self.floor(rough, load);
            asp = self.asperity(rough, h).min(load);
        }
        Contact {
            h_m: h,
            load_n_per_m: load,
            asperity_n_per_m: asp,
            film: film_for_load_supplied(&self.face, h, u_abs, load - asp, mu, None, supply_m),
        }
    }

    /// The minimum film at which the load is carried without squeeze (`hdot = 0`): the
    /// quasi-static film of this instant (the floor at rest, where no wedge acts).
    pub fn steady(
        &self,
        rough: &Roughness,
        u_abs: f64,
        load: f64,
        mu: f64,
        supply_m: Option<f64>,
    ) -> f64 {
        let guess = rough.sigma_m * 3.0;
        self.solve(rough, guess, u_abs, load, mu, supply_m, |_, hdot| -hdot)
    }

    /// The squeeze velocity at film `h`, m/s: what makes film and asperities carry `load`
    /// (the fully ruptured film's lift where the asperities alone carry more).
    pub fn squeeze(
        &self,
        rough: &Roughness,
        h: f64,
        u_abs: f64,
        load: f64,
        mu: f64,
        supply_m: Option<f64>,
    ) -> f64 {
        let asp = self.asperity(rough, h).min(load);
        film_for_load_supplied(&self.face, h, u_abs, load - asp, mu, None, supply_m).squeeze_m_s
    }

    /// The minimum film after a step of `dt_s` from `h_old`: linearly implicit (Rosenbrock)
    /// Euler steps `h + dt hdot / (1 - dt dhdot/dh)`, each moving the film by at most 10%
    /// (sub-steps where the film changes fast, near the dead centres). Like backward Euler it
    /// damps the squeeze film's relaxation (`dhdot/dh < 0`) at any step length instead of
    /// amplifying it; after 64 sub-steps the rest of the step is backward Euler solved to
    /// rounding. Never below the floor of the asperities, never above the oil layer when
    /// starved (`supply_m`, held over the step; `None`: flooded).
    #[allow(clippy::too_many_arguments)]
    pub fn advance(
        &self,
        rough: &Roughness,
        h_old: f64,
        dt_s: f64,
        u_abs: f64,
        load: f64,
        mu: f64,
        supply_m: Option<f64>,
    ) -> f64 {
        let lo_limit = LAMBDA_MIN * rough.sigma_m;
        if mu.is_nan() || mu <= 0.0 || mu.is_infinite() {
            return self.floor(rough, load);
        }
        let film = |h: f64, guess: Option<f64>| {
            let asp = self.asperity(rough, h).min(load);
            film_for_load_supplied(&self.face, h, u_abs, load - asp, mu, guess, supply_m)
        };
        let hi_limit = Self::ceiling(rough, supply_m);
        let mut h = h_old.clamp(lo_limit, hi_limit);
        let mut left = dt_s;
        for _ in 0..64 {
            let film0 = film(h, None);
            let f0 = film0.squeeze_m_s;
            // A backward difference at the ceiling (the film is not defined above the layer).
            let dh = if h + 1e-6 * h > hi_limit {
                -1e-6 * h
            } else {
                1e-6 * h
            };
            let slope = ((film(h + dh, Some(film0.rupture_m)).squeeze_m_s - f0) / dh).min(0.0);
            // The longest sub-step moving the film by 10%: |f0| t / (1 + t |slope|) <= h / 10.
            let room = f0.abs() - 0.1 * h * slope.abs();
            let t = if room > 0.0 {
                left.min(0.1 * h / room)
            } else {
                left
            };
            let step = t * f0 / (1.0 - t * slope);
            if !step.is_finite() {
                break;
            }
            h = (h + step).clamp(lo_limit, hi_limit);
            left -= t;
            if left <= 0.0 {
                return if self.asperity(rough, h) > load {
                    self.floor(rough, load)
                } else {
                    h
                };
            }
        }
        let h_start = h;
        self.solve(rough, h_start, u_abs, load, mu, supply_m, |x, hdot| {
            x - h_start - left * hdot
        })
    }

    /// The film `h` where `g(h, hdot(h))`, increasing in `h`, vanishes (in `ln h`, bracketed
    /// outwards from `guess`), raised to the floor where the asperities alone would carry more
    /// than the load. Below the floor `hdot` is the fully ruptured film's lift, so `g` stays
    /// increasing through it. Below the oil layer when starved.
    #[allow(clippy::too_many_arguments)]
    fn solve(
        &self,
        rough: &Roughness,
        guess: f64,
        u_abs: f64,
        load: f64,
        mu: f64,
        supply_m: Option<f64>,
        g: impl Fn(f64, f64) -> f64,
    ) -> f64 {
        let lo_limit = LAMBDA_MIN * rough.sigma_m;
        if mu.is_nan() || mu <= 0.0 || mu.is_infinite() {
            return self.floor(rough, load);
        }
        let f = |y: f64| {
            let h = y.exp();
            g(h, self.squeeze(rough, h, u_abs, load, mu, supply_m))
        };
        let hi_limit = Self::ceiling(rough, supply_m);
        let (y_min, y_max) = (lo_limit.ln(), hi_limit.ln());
        let y0 = guess.clamp(lo_limit, hi_limit).ln();
        // Bracket: step outwards from the guess by doubling widths in ln h.
        let f0 = f(y0);
        let (mut a, mut b) = (y0, y0);
        // For a time step `g` is a length: its size relative to the guess estimates the step
        // in ln h (twice it, so the first try usually brackets); otherwise start at 5%.
        let mut width = (2.0 * f0.abs() / y0.exp()).clamp(1e-9, 0.05);
        if f0 < 0.0 {
            while b < y_max {
                b = (y0 + width).min(y_max);
                if f(b) >= 0.0 {
                    break;
                }
                a = b;
                width *= 2.0;
            }
        } else {
            while a > y_min {
                a = (y0 - width).max(y_min);
                if f(a) <= 0.0 {
                    break;
                }
                b = a;
                width *= 2.0;
            }
        }
        let h = if a == b {
            a.exp()
        } else {
            root_increasing(f, a, b).exp()
        };
        if self.asperity(rough, h) > load {
            self.floor(rough, load)
        } else {
            h
        }
    }
}
