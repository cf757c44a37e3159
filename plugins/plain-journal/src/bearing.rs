//! The journal's motion and the film's torques: Booker's mobility method on the finite
//! bearing's tables (or Ocvirk's short bearing), the Couette shear over the full
//! circumference, and the torques on both members.
//!
//! Vectors are in the global (inertial) frame; `eps` is the eccentricity ratio vector `e / c`
//! of the inner member's centre from the outer member's, `force` the force the outer member
//! exerts on the inner one through the film (N), `omega_bar = (omega_inner + omega_outer) / 2`.

use std::f64::consts::PI;

use crate::short;
use crate::table;
use crate::tables;

/// How the film's pressure is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// Finite-length Reynolds solution with the Reynolds (Swift-Stieber) rupture condition,
    /// tabulated per `L / D` (`tables.rs`) and interpolated.
    Finite,
    /// Ocvirk's short bearing with the half-Sommerfeld condition, in closed form.
    Short,
}

/// A plain journal bearing's geometry and pressure model.
#[derive(Debug, Clone, Copy)]
pub struct Bearing {
    /// Journal radius, m.
    pub radius_m: f64,
    /// Bearing length, m.
    pub length_m: f64,
    /// Radial clearance, m.
    pub clearance_m: f64,
    /// Pressure model.
    pub model: Model,
}

/// The film's answer at one state: the eccentricity rate and the peak pressure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// `d eps / dt`, 1/s, global frame.
    pub eps_rate: [f64; 2],
    /// Pure-squeeze velocity `v = eps_dot - omega_bar z x eps`, 1/s.
    pub squeeze: [f64; 2],
    /// Peak film pressure, Pa.
    pub peak_pressure_pa: f64,
}

/// The viscosity-free part of the journal's motion at one eccentricity and load
/// ([`Bearing::squeeze_at`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Squeeze {
    /// The load's magnitude, N.
    load_n: f64,
    /// The tables' answer at the eccentricity and the load's direction.
    mobility: table::Mobility,
    /// Direction of the squeeze velocity, rad, global frame.
    direction: f64,
}

/// Largest eccentricity ratio the law lets the journal reach: the tables' edge. Beyond it the
/// film is thinner than 0.5% of the clearance, where asperity contact (not modelled here)
/// carries the load; the law reports the boundary regime there.
pub const EPS_CAP: f64 = 0.995;

impl Bearing {
    /// `L / D`.
    pub fn lambda(&self) -> f64 {
        self.length_m / (2.0 * self.radius_m)
    }

    /// Squeeze direction `gamma`, `|G|` and peak (nondimensional, module `reynolds` docs) for
    /// eccentricity ratio `eps` and load direction `beta` from the eccentricity.
    pub fn mobility(&self, eps: f64, beta: f64) -> table::Mobility {
        match self.model {
            Model::Finite => table::mobility(tables::tables(), self.lambda(), eps, beta),
            Model::Short => short_mobility(eps, beta, self.lambda()),
        }
    }

    /// `12 mu R^4 / c^2`: the force per unit squeeze velocity and unit `|G|`, N s.
    fn force_scale(&self, mu: f64) -> f64 {
        12.0 * mu * self.radius_m.powi(4) / (self.clearance_m * self.clearance_m)
    }

    /// The journal's eccentricity rate under `force` at `eps` (Booker's mobility method).
    pub fn motion(&self, eps: [f64; 2], force: [f64; 2], omega_bar: f64, mu: f64) -> Motion {
        let squeeze = self.squeeze_at(eps, force);
        self.motion_with(squeeze.as_ref(), eps, omega_bar, mu)
    }

    /// The part of [`Bearing::motion`] that does not depend on the viscosity (`None` when the
    /// film carries no load), for a caller that needs the motion at several viscosities.
    pub fn squeeze_at(&self, eps: [f64; 2], force: [f64; 2]) -> Option<Squeeze> {
        let w = force[0].hypot(force[1]);
        if w <= 0.0 {
            return None;
        }
        let e = eps[0].hypot(eps[1]).min(EPS_CAP);
        // The eccentricity's direction (any at the centre, where the film is axisymmetric).
        let theta_e = if e > 0.0 { eps[1].atan2(eps[0]) } else { 0.0 };
        // The load the journal carries points against the film force.
        let theta_w = (-force[1]).atan2(-force[0]);
        let m = self.mobility(e, theta_w - theta_e);
        Some(Squeeze {
            load_n: w,
            mobility: m,
            direction: theta_e + m.gamma,
        })
    }

    /// [`Bearing::motion`] from its viscosity-free part `squeeze` ([`Bearing::squeeze_at`] at
    /// the same `eps` and force).
    pub fn motion_with(
        &self,
        squeeze: Option<&Squeeze>,
        eps: [f64; 2],
        omega_bar: f64,
        mu: f64,
    ) -> Motion {
        let whirl = [-omega_bar * eps[1], omega_bar * eps[0]];
        // As before the split: no load or a viscosity `<= 0` leaves the whirl (a NaN
        // viscosity goes on and reports itself as NaN).
        let sq = match squeeze {
            Some(sq) if mu.is_nan() || mu > 0.0 => sq,
            _ => {
                return Motion {
                    eps_rate: whirl,
                    squeeze: [0.0, 0.0],
                    peak_pressure_pa: 0.0,
                }
            }
        };
        let speed = sq.load_n / (self.force_scale(mu) * sq.mobility.g);
        let v = [speed * sq.direction.cos(), speed * sq.direction.sin()];
        Motion {
            eps_rate: [v[0] + whirl[0], v[1] + whirl[1]],
            squeeze: v,
            peak_pressure_pa: 12.0 * mu * self.radius_m.powi(2) * speed
                / (self.clearance_m * self.clearance_m)
                * sq.mobility.peak,
        }
    }

    /// Couette coefficient over the full circumference, N m s: `2 pi mu R^3 L / (c sqrt(1 -
    /// eps^2))` (the convention of Raimondi and Boyd's friction variable: the shear of a full
    /// film, also where it has ruptured into streamers).
    pub fn couette(&self, eps: f64, mu: f64) -> f64 {
        let e = eps.min(EPS_CAP);
        2.0 * PI * mu * self.radius_m.powi(3) * self.length_m
            / (self.clearance_m * (1.0 - e * e).sqrt())
    }

    /// The quasi-static eccentricity under a steady `load` (N, magnitude) at mean speed
    /// `omega_bar`: `|eps|` with `load = 12 mu R^4 |omega_bar| eps |G(eps, -pi/2)| / c^2`, and
    /// the attitude angle between load and eccentricity (rad). Capped at [`EPS_CAP`].
    pub fn steady(&self, load: f64, omega_bar: f64, mu: f64) -> (f64, f64) {
        let scale = self.force_scale(mu) * omega_bar.abs();
        let capacity = |e: f64| -> (f64, f64) {
            let (g, att) = self.steady_g(e);
            (scale * e * g, att)
        };
        if load <= 0.0 || scale <= 0.0 {
            return (0.0, 0.5 * PI);
        }
        if capacity(EPS_CAP).0 <= load {
            return (EPS_CAP, capacity(EPS_CAP).1);
        }
        // Bisection in s = -ln(1 - eps), where the capacity rises smoothly.
        let (mut lo, mut hi) = (0.0, -(1.0 - EPS_CAP).ln());
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if capacity(1.0 - (-mid).exp()).0 < load {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo < 1e-15 {
                break;
            }
        }
        let e = 1.0 - (-(0.5 * (lo + hi))).exp();
        (e, capacity(e).1)
    }

    /// `|G|` and the attitude angle of the steadily loaded journal (squeeze at `-pi/2`).
    fn steady_g(&self, eps: f64) -> (f64, f64) {
        match self.model {
            Model::Finite => table::steady(tables::tables(), self.lambda(), eps),
            Model::Short => {
                let (g, _) = short::squeeze(eps, -0.5 * PI, self.lambda());
                (g[0].hypot(g[1]), (-g[1]).atan2(g[0]))
            }
        }
    }
}

/// Largest `|omega_bar / w|` the relative-rotation torque follows exactly ([`relative_torque`]).
pub const RATIO_MAX: f64 = 100.0;

/// The torque on the joint's relative rotation `w = omega_a - omega_b` whose power is the
/// film's rotational power `K w^2 + M omega_bar`:
/// `T = -(K w + M omega_bar w / (w^2 + (omega_bar / RATIO_MAX)^2))` (docs/laws/plain-journal.md).
pub fn relative_torque(
    b: &Bearing,
    eps: [f64; 2],
    force: [f64; 2],
    w: f64,
    omega_bar: f64,
    mu: f64,
) -> f64 {
    let e = eps[0].hypot(eps[1]);
    let scale = if e > EPS_CAP { EPS_CAP / e } else { 1.0 };
    let m = b.clearance_m * scale * (eps[0] * force[1] - eps[1] * force[0]);
    let k = b.couette(e, mu);
    let den = w * w + (omega_bar / RATIO_MAX).powi(2);
    let ratio = if den > 0.0 { omega_bar * w / den } else { 0.0 };
    -(k * w + m * ratio)
}

impl Bearing {
    /// Advance `eps` over `dt` under `force` at mean speed `omega_bar`: midpoint steps, as many
    /// as the squeeze film's relaxation rate needs (it grows about as `(1 - eps)^-2.5`), the
    /// eccentricity held at or inside [`EPS_CAP`].
    pub fn advance(
        &self,
        eps: [f64; 2],
        force: [f64; 2],
        omega_bar: f64,
        mu: f64,
        dt: f64,
    ) -> [f64; 2] {
        let rate = |e: [f64; 2]| self.motion(e, force, omega_bar, mu).eps_rate;
        let cap = |e: [f64; 2]| {
            let m = e[0].hypot(e[1]);
            if m > EPS_CAP {
                [e[0] * EPS_CAP / m, e[1] * EPS_CAP / m]
            } else {
                e
            }
        };
        let r0 = rate(eps);
        let e = eps[0].hypot(eps[1]);
        let speed = r0[0].hypot(r0[1]);
        let stiff = speed * 2.5 / (1.0 - e).max(1.0 - EPS_CAP) + omega_bar.abs();
        let n = ((stiff * dt / 0.25).ceil() as usize).clamp(1, 4000);
        let h = dt / n as f64;
        let mut x = eps;
        for i in 0..n {
            let k1 = if i == 0 { r0 } else { rate(x) };
            let mid = cap([x[0] + 0.5 * h * k1[0], x[1] + 0.5 * h * k1[1]]);
            let k2 = rate(mid);
            x = cap([x[0] + h * k2[0], x[1] + h * k2[1]]);
        }
        x
    }
}

/// The film's torques on both members and the rotational power it absorbs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Torques {
    /// Torque of the film on the inner member about its centre, N m.
    pub inner_nm: f64,
    /// Torque of the film on the outer member about its centre, N m.
    pub outer_nm: f64,
    /// The offset moment `(e x F)_z` of the load's line from the outer member's centre, N m.
    pub offset_moment_nm: f64,
}

/// Torques for eccentricity `eps` (global), film force on the inner member `force`, and the
/// members' speeds: `Q_inner = -K dw - M/2`, `Q_outer = K dw - M/2` with `dw = w_inner -
/// w_outer` and `M = (e x F)_z` (the Poiseuille part of the shear integrates to `M/2` on each).
pub fn torques(
    b: &Bearing,
    eps: [f64; 2],
    force: [f64; 2],
    omega_inner: f64,
    omega_outer: f64,
    mu: f64,
) -> Torques {
    let e = eps[0].hypot(eps[1]);
    let scale = if e > EPS_CAP { EPS_CAP / e } else { 1.0 };
    let k = b.couette(e, mu);
    let dw = omega_inner - omega_outer;
    let m = b.clearance_m * scale * (eps[0] * force[1] - eps[1] * force[0]);
    Torques {
        inner_nm: -k * dw - 0.5 * m,
        outer_nm: k * dw - 0.5 * m,
        offset_moment_nm: m,
    }
}

/// The short bearing's squeeze direction for load direction `beta`: the film force direction
/// rises monotonically with the squeeze direction over `[0, pi]`, so bisection finds it.
fn short_mobility(eps: f64, beta: f64, lambda: f64) -> table::Mobility {
    let b = beta.rem_euclid(2.0 * PI);
    let (b, sign) = if b > PI {
        (2.0 * PI - b, -1.0)
    } else {
        (b, 1.0)
    };
    let angle = |gamma: f64| {
        let (g, _) = short::squeeze(eps, gamma, lambda);
        let a = g[1].atan2(g[0]);
        if a < -1e-12 {
            a + 2.0 * PI
        } else {
            a
        }
    };
    let (mut lo, mut hi) = (0.0, PI);
    if b <= 0.0 {
        hi = 0.0;
    } else if b >= PI {
        lo = PI;
    } else {
        for _ in 0..80 {
            let mid = 0.5 * (lo + hi);
            if angle(mid) < b {
                lo = mid;
            } else {
                hi = mid;
            }
        }
    }
    let gamma = 0.5 * (lo + hi);
    let (g, peak) = short::squeeze(eps, gamma, lambda);
    table::Mobility {
        gamma: sign * gamma,
        g: g[0].hypot(g[1]),
        peak,
    }
}
