//! The vented crankcase: the volume under the piston, pumped by the piston underside, breathing
//! to the ambient through an orifice (the breather).
//!
//! **Model.** The crankcase volume is `V(theta) = V_tdc - A x(theta)` (x: piston travel from
//! TDC, exact slider-crank; on an engine the shared crankcase of every cylinder,
//! `V(theta) = V_tdc - A (sum_k x_k(theta) - sum_k x_k(theta_ref))`, [`Underside`]). Its gas follows a polytrope through the ambient state,
//! `p / rho^n = p_a / rho_a^n` with `rho_a = p_a / (R T_ref)`, so its temperature is
//! `T(p) = T_ref (p / p_a)^((n-1)/n)` (n = 1: isothermal at `T_ref`). With the mass
//! `m = rho V` and the mass flow `mdot` out through the breather,
//!
//! ```text
//! dp/p = n drho/rho = n (dm/m - dV/V)
//! dp/dt = (n p / V) (-dV/dt) - (n p / (rho V)) mdot
//!       = (n p / V) (-dV/dt - Q),   Q = mdot / rho(p): the volume flow out at crankcase state,
//! ```
//!
//! and at a constant crank speed `omega` (`dt = dtheta / omega`), in `y = ln p`:
//!
//! ```text
//! dy/dtheta = (n / V(theta)) (-dV/dtheta - Q(p) / omega).
//! ```
//!
//! With no flow this is `p V^n = const`, the sealed crankcase.
//!
//! **Breather flow.** One-dimensional isentropic flow of air (gamma = 1.4, R = 287.05 J/(kg K))
//! through a restriction of area `A_b` with discharge coefficient `Cd`, from the upstream
//! stagnation state `(p_0, T_0)` to the downstream pressure `p_T`, choked below the critical
//! ratio (Heywood, *Internal Combustion Engine Fundamentals*, McGraw-Hill 1988, Appendix C,
//! "Equations for fluid flow through a restriction"):
//!
//! ```text
//! mdot = Cd A_b p_0 / sqrt(R T_0) psi(p_T / p_0)
//! psi(r) = r^(1/gamma) sqrt(2 gamma / (gamma - 1) (1 - r^((gamma-1)/gamma)))   r > r*
//! psi(r) = sqrt(gamma) (2 / (gamma + 1))^((gamma+1) / (2 (gamma-1)))             r <= r*
//! r* = (2 / (gamma + 1))^(gamma / (gamma-1)) = 0.528
//! ```
//!
//! Out of the crankcase (`p > p_a`) the upstream state is the crankcase's `(p, T(p))`; into it
//! the ambient's `(p_a, T_ref)`. Why compressible: on the CRF 250 R the piston underside
//! displaces up to `A v_max ~ 4.6e-3 m^2 * 25 m/s ~ 0.1 m^3/s` at 9000 rpm; through a 9 mm
//! breather (`Cd A_b ~ 4e-5 m^2`) that would be a velocity far above sonic, so the pressure
//! ratio across the breather is not small and the incompressible orifice law
//! `mdot = Cd A sqrt(2 rho dp)` (which the formula above reduces to for `dp << p`) would
//! overstate the flow; the nozzle law chokes instead. For small ratios both agree, which the
//! tests use (the open-breather limit).
//!
//! **Periodic steady solution.** At a constant speed the pressure settles to a cycle repeating
//! every revolution. It is found directly: the revolution map `y(0) -> y(2 pi)` is monotone
//! and contracting, and its fixed point is solved by the secant method on
//! `G(y0) = y(2 pi) - y0` (bracketed once the sign changes; a few revolutions, where plain
//! repetition would need hundreds when the breather is small). Each revolution is integrated
//! in crank angle at `NODES_PER_REV` equal steps by the 2-stage, L-stable, stiffly accurate
//! SDIRK method of order 2 (Alexander 1977; Hairer and Wanner, *Solving Ordinary Differential
//! Equations II*, section IV.6): implicit because a large breather makes the equation stiff
//! (its limit is the open crankcase), L-stable so the stiff part is damped, not mirrored.
//! Each stage is one scalar equation in `y`, increasing with slope at least 1 (the outflow
//! rises with the pressure), bracketed between the ambient and the flow-free value and solved
//! by the Illinois method. The work the piston does on the gas over the revolution,
//! `W = -closed integral p dV` (positive: the breather's pumping loss; zero without flow), is
//! accumulated with the same stages.

use std::f64::consts::TAU;
use std::sync::{Arc, Mutex};

/// Specific gas constant of dry air, J/(kg K).
pub const R_AIR: f64 = 287.05;
/// Ratio of specific heats of air, for the isentropic flow through the breather.
pub const GAMMA_AIR: f64 = 1.4;
/// Table nodes (and integration steps) per revolution: 0.5 degree.
pub const NODES_PER_REV: usize = 720;
/// The periodic solution is accepted when one revolution returns to its start within this
/// (in `ln p`, i.e. relative pressure).
pub const PERIODIC_TOL: f64 = 1e-12;
/// Most revolutions integrated in the search for the periodic solution.
const MAX_REVOLUTIONS: u32 = 60;
/// The SDIRK parameter gamma = 1 - 1/sqrt(2) (L-stable, order 2).
const SDIRK_GAMMA: f64 = 1.0 - std::f64::consts::FRAC_1_SQRT_2;

/// One piston pumping the crankcase: a slider-crank whose local crank angle is the crank angle
/// plus `phase_rad` (an engine's cylinder: its throw angle minus its bank angle).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slider {
    /// Local crank angle minus the crank angle, rad.
    pub phase_rad: f64,
    /// Crank radius, m.
    pub crank_radius_m: f64,
    /// Rod length, m.
    pub rod_length_m: f64,
    /// Pin plus crank offset across the bore axis, m (0 for a centred slider-crank).
    pub offset_m: f64,
}

impl Slider {
    /// Piston travel from its TDC and its derivative in crank angle at crank angle `theta`
    /// (exact slider-crank with offset; the centred one's formulas, bit for bit, at zero
    /// offset and phase).
    pub fn travel(&self, theta: f64) -> (f64, f64) {
        let (r, l, e) = (self.crank_radius_m, self.rod_length_m, self.offset_m);
        let (s, c) = (theta + self.phase_rad).sin_cos();
        let top = ((r + l) * (r + l) - e * e).sqrt();
        let root = (l * l - r * r * s * s - e * (e + 2.0 * r * s)).sqrt();
        (
            top - r * c - root,
            r * s + (r * r * s * c + e * r * c) / root,
        )
    }
}

/// The pistons whose undersides pump one crankcase: the single-cylinder rig's one, or every
/// cylinder of an engine (one shared crankcase, `docs/engines.md`).
#[derive(Debug, Clone, PartialEq)]
pub struct Underside {
    /// Piston area (every cylinder's), m^2.
    pub piston_area_m2: f64,
    /// The pistons.
    pub pistons: Vec<Slider>,
    /// The summed travel at the reference state the crankcase's volume and pressure at TDC are
    /// given for (cylinder 1 at its local angle 0), m: 0 on the single-cylinder rig.
    pub travel_at_reference_m: f64,
}

impl Underside {
    /// The summed piston travel from TDC minus its reference value, and its derivative in
    /// crank angle, at crank angle `theta`: the crankcase volume is `V_tdc - A` times it.
    pub fn travel(&self, theta: f64) -> (f64, f64) {
        let (x, dx) = self.pistons.iter().fold((0.0, 0.0), |(x, dx), p| {
            let (xk, dxk) = p.travel(theta);
            (x + xk, dx + dxk)
        });
        (x - self.travel_at_reference_m, dx)
    }
}

/// A vented crankcase: its geometry, gas and breather, everything the pressure equation needs.
#[derive(Debug, Clone, PartialEq)]
pub struct Breather {
    /// Crankcase volume at the reference state (the piston, an engine's cylinder 1, at TDC),
    /// m^3.
    pub volume_at_tdc_m3: f64,
    /// The pistons pumping it.
    pub underside: Underside,
    /// Polytropic exponent of the crankcase gas.
    pub polytropic_exponent: f64,
    /// Discharge coefficient times the breather's area, m^2.
    pub discharge_area_m2: f64,
    /// Ambient pressure, Pa.
    pub ambient_pa: f64,
    /// Gas temperature at the ambient pressure, K.
    pub temperature_k: f64,
}

/// The geometry at one stage point of a step: what the pressure equation needs of `V(theta)`.
#[derive(Debug, Clone, Copy)]
struct StagePoint {
    /// `n / V`, 1/m^3.
    n_over_v: f64,
    /// `-dV/dtheta`, m^3/rad (positive while the piston descends and compresses).
    minus_dv: f64,
}

/// The periodic steady crankcase cycle at one crank speed.
#[derive(Debug, Clone, PartialEq)]
pub struct VentedCycle {
    /// Crank speed, rad/s.
    pub omega_rad_s: f64,
    /// Crankcase pressure at the crank angles `2 pi k / NODES_PER_REV`, Pa, k = 0..N-1
    /// (angle 0: piston at TDC).
    pub pressure_pa: Vec<f64>,
    /// Work done on the crankcase gas over one revolution, `-closed integral p dV`, J: the
    /// breather's pumping loss (positive).
    pub pumping_work_j: f64,
    /// Time constant of the approach to the periodic cycle, s: `-T_rev / ln(lambda)` with
    /// `lambda` the revolution map's slope at the fixed point (infinite without flow).
    pub time_constant_s: f64,
    /// Revolutions integrated to find the cycle.
    pub revolutions: u32,
    /// `|ln p(2 pi) - ln p(0)|` of the last revolution (at most `PERIODIC_TOL` when found).
    pub periodicity_residual: f64,
}

impl Breather {
    fn stage_point(&self, theta: f64) -> StagePoint {
        let (x, dx) = self.underside.travel(theta);
        let a = self.underside.piston_area_m2;
        let v = self.volume_at_tdc_m3 - a * x;
        StagePoint {
            n_over_v: self.polytropic_exponent / v,
            minus_dv: a * dx,
        }
    }

    /// Volume flow out of the crankcase through the breather, at the crankcase's state, m^3/s
    /// (negative: air breathed in), at crankcase pressure `p`.
    pub fn outflow_m3_s(&self, p: f64) -> f64 {
        self.flow(p).0
    }

    /// The outflow `Q(p)` and its derivative `dQ/d(ln p)` (infinite at the ambient pressure,
    /// where the orifice law has a square-root foot).
    fn flow(&self, p: f64) -> (f64, f64) {
        let pa = self.ambient_pa;
        let rt_ref = R_AIR * self.temperature_k;
        let n = self.polytropic_exponent;
        let k = (n - 1.0) / n;
        // T(p) / T_ref on the polytrope through the ambient state.
        let t_ratio = (p / pa).powf(k);
        let (q, dln_q) = if p >= pa {
            // Q = mdot / rho = Cd A psi(p_a / p) sqrt(R T(p)); d ln(p_a / p) / d ln p = -1.
            let (psi, e) = nozzle_with_slope(pa / p);
            let q = self.discharge_area_m2 * psi * (rt_ref * t_ratio).sqrt();
            (q, 0.5 * k - e)
        } else {
            // mdot = Cd A p_a psi(p / p_a) / sqrt(R T_ref) inwards; rho(p) = p / (R T(p)).
            let (psi, e) = nozzle_with_slope(p / pa);
            let q = -self.discharge_area_m2 * psi * rt_ref.sqrt() * (pa / p) * t_ratio;
            (q, k - 1.0 + e)
        };
        // Q rises with p everywhere; at p = p_a (Q = 0) its slope is infinite.
        let dq = q * dln_q;
        (q, if dq.is_nan() { f64::INFINITY } else { dq })
    }

    /// The periodic steady cycle at crank speed `omega` (> 0), starting the search from the
    /// pressure `p_start` at TDC (the ambient, or a neighbouring speed's solution).
    pub fn periodic(&self, omega: f64, p_start: f64) -> VentedCycle {
        let h = TAU / NODES_PER_REV as f64;
        let points: Vec<[StagePoint; 2]> = (0..NODES_PER_REV)
            .map(|k| {
                let t0 = k as f64 * h;
                [
                    self.stage_point(t0 + SDIRK_GAMMA * h),
                    self.stage_point(t0 + h),
                ]
            })
            .collect();
        let mut ys = vec![0.0; NODES_PER_REV];
        // The fixed point of y0 -> y(2 pi): G(y0) = y(2 pi) - y0 decreases (the map's slope is
        // in (0, 1]). Secant steps; bisection once a bracket is known and a step leaves it; a
        // plain revolution (y0 <- y(2 pi), which never crosses the root since G' > -1) while
        // there is no slope yet.
        let mut y = p_start.max(1e-3 * self.ambient_pa).ln();
        let (end, mut work) = self.revolution(omega, &points, y, &mut ys);
        let mut g = end - y;
        let mut revolutions = 1;
        let mut slope = f64::NAN;
        // Bracket: G >= 0 at `below`, G <= 0 at `above`.
        let (mut below, mut above) = (f64::NEG_INFINITY, f64::INFINITY);
        while g.abs() > PERIODIC_TOL && revolutions < MAX_REVOLUTIONS {
            if g > 0.0 {
                below = below.max(y);
            } else {
                above = above.min(y);
            }
            let mut next = if slope < 0.0 && slope.is_finite() {
                y - g / slope
            } else {
                y + g
            };
            if !(below < next && next < above) {
                next = if below.is_finite() && above.is_finite() {
                    0.5 * (below + above)
                } else {
                    y + g
                };
            }
            if next == y {
                // No representable step left: as periodic as the arithmetic allows.
                break;
            }
            let (end, w) = self.revolution(omega, &points, next, &mut ys);
            revolutions += 1;
            let g_next = end - next;
            slope = (g_next - g) / (next - y);
            y = next;
            g = g_next;
            work = w;
        }
        if !slope.is_finite() {
            // Periodic from the first revolution: measure the map's slope with one more,
            // slightly off the cycle (the table keeps the cycle's values).
            let dy = 1e-6;
            let mut scratch = vec![0.0; NODES_PER_REV];
            let (end, _) = self.revolution(omega, &points, y + dy, &mut scratch);
            slope = ((end - y - dy) - g) / dy;
        }
        VentedCycle {
            omega_rad_s: omega,
            pressure_pa: ys.iter().map(|y| y.exp()).collect(),
            pumping_work_j: work,
            time_constant_s: time_constant(slope, omega),
            revolutions,
            periodicity_residual: g.abs(),
        }
    }

    /// One revolution from `ln p = y0` at TDC at speed `omega`: `ys` receives `ln p` at the
    /// nodes (node k at angle k h, k = 0..N-1). Returns `ln p` after the revolution and the
    /// work done on the gas, `integral p (-dV)`, J.
    fn revolution(
        &self,
        omega: f64,
        points: &[[StagePoint; 2]],
        y0: f64,
        ys: &mut [f64],
    ) -> (f64, f64) {
        let h = TAU / NODES_PER_REV as f64;
        let gh = SDIRK_GAMMA * h;
        let ln_pa = self.ambient_pa.ln();
        let mut y = y0;
        let mut work = 0.0;
        // The last step's slope, to guess the next stages (0 at the start: a guess only).
        let mut k2 = 0.0;
        for (k, stage) in points.iter().enumerate() {
            ys[k] = y;
            // Stage 1: Y1 = y + gamma h f(theta_1, Y1).
            let (y1, p1) = self.stage(omega, &stage[0], y, gh, ln_pa, y + gh * k2);
            let k1 = (y1 - y) / gh;
            // Stage 2 (stiffly accurate, the step's result): Y2 = y + (1 - gamma) h k1 +
            // gamma h f(theta + h, Y2).
            let base = y + (1.0 - SDIRK_GAMMA) * h * k1;
            let (y2, p2) = self.stage(omega, &stage[1], base, gh, ln_pa, y + h * k1);
            k2 = (y2 - base) / gh;
            work += h
                * ((1.0 - SDIRK_GAMMA) * p1 * stage[0].minus_dv
                    + SDIRK_GAMMA * p2 * stage[1].minus_dv);
            y = y2;
        }
        (y, work)
    }

    /// Solve the stage equation `Y = base + gh (n/V) (-dV - Q(e^Y) / omega)` for `Y`, from
    /// `guess`; returns `Y` and `e^Y`. The residual `r(Y) = Y - y_free + gh (n/V) Q(e^Y) /
    /// omega` rises with slope at least 1 and is bracketed by the ambient (`Q = 0`) and the
    /// flow-free value `y_free`: Newton's method inside the bracket, bisecting when a step
    /// leaves it, until `|r| <= 1e-13` (which, since `r' >= 1`, bounds the error in `Y`).
    fn stage(
        &self,
        omega: f64,
        at: &StagePoint,
        base: f64,
        gh: f64,
        ln_pa: f64,
        guess: f64,
    ) -> (f64, f64) {
        let y_free = base + gh * at.n_over_v * at.minus_dv;
        let c = gh * at.n_over_v / omega;
        let (mut lo, mut hi) = if y_free >= ln_pa {
            (ln_pa, y_free)
        } else {
            (y_free, ln_pa)
        };
        let mut y = if guess.is_finite() {
            guess.clamp(lo, hi)
        } else {
            y_free
        };
        let mut p = y.exp();
        for _ in 0..200 {
            let (q, dq) = self.flow(p);
            let r = y - y_free + c * q;
            if r.abs() <= 1e-13 {
                break;
            }
            if r > 0.0 {
                hi = y;
            } else {
                lo = y;
            }
            let mut next = y - r / (1.0 + c * dq);
            if !(lo < next && next < hi) {
                next = 0.5 * (lo + hi);
            }
            if next == y {
                break;
            }
            y = next;
            p = y.exp();
        }
        (y, p)
    }
}

/// How many tables [`table`] keeps (about 12 KB each).
const CACHE_TABLES: usize = 256;

/// Tables computed in this process, shared by every simulation of the same crankcase at the
/// same speed (a fit or a comparison builds many simulations of one rig; an engine's cylinders
/// share one crankcase). A table is a pure function of its crankcase and speed (compared
/// value for value, the speed bit for bit), so sharing it changes no result.
static CACHE: Mutex<Vec<(Breather, u64, Arc<Table>)>> = Mutex::new(Vec::new());

/// The periodic cycle of `breather` at crank speed `omega` (> 0) as a table: computed once
/// per process and kept (the oldest dropped beyond [`CACHE_TABLES`]).
pub(crate) fn table(breather: &Breather, omega: f64) -> Arc<Table> {
    let b = breather;
    let w = omega.to_bits();
    // A poisoned lock (a panic elsewhere while holding it) only costs the cache.
    if let Ok(cache) = CACHE.lock() {
        if let Some((_, _, t)) = cache.iter().find(|(k, kw, _)| *kw == w && k == b) {
            return Arc::clone(t);
        }
    }
    let t = Arc::new(Table::new(b.periodic(omega, b.ambient_pa).pressure_pa));
    if let Ok(mut cache) = CACHE.lock() {
        if cache.len() >= CACHE_TABLES {
            cache.remove(0);
        }
        cache.push((b.clone(), w, Arc::clone(&t)));
    }
    t
}

/// The mass flux function `psi` of isentropic flow of air through a restriction at the ratio
/// `r` of downstream to upstream pressure, in (0, 1]: `mdot = Cd A p_0 / sqrt(R T_0) psi(r)`
/// (choked, constant, below the critical ratio).
pub fn nozzle(r: f64) -> f64 {
    nozzle_with_slope(r).0
}

/// [`nozzle`] and its logarithmic slope `d ln psi / d ln r` (0 when choked, minus infinity
/// at `r = 1`).
fn nozzle_with_slope(r: f64) -> (f64, f64) {
    // gamma = 1.4: 1/gamma = 5/7, (gamma-1)/gamma = 2/7, 2 gamma/(gamma-1) = 7.
    const CRITICAL: f64 = 0.528_281_787_717_174_2; // (2/2.4)^3.5
    const CHOKED: f64 = 0.684_731_456_377_270_5; // sqrt(1.4) (2/2.4)^3
    if r <= CRITICAL {
        (CHOKED, 0.0)
    } else {
        // psi = s^5 sqrt(7 (1 - s^2)) with s = r^(1/7);
        // d ln psi / d ln r = 5/7 - s^2 / (7 (1 - s^2)).
        let s = r.powf(1.0 / 7.0);
        let s2 = s * s;
        let s5 = s2 * s2 * s;
        let rest = (1.0 - s2).max(0.0);
        (s5 * (7.0 * rest).sqrt(), (5.0 - s2 / rest) / 7.0)
    }
}

/// A tabulated periodic cycle: pressure at equal angle steps over a revolution and its slope,
/// evaluated by cubic Hermite interpolation.
#[derive(Debug, Clone)]
pub(crate) struct Table {
    pressure_pa: Vec<f64>,
    /// dp/dtheta times the step (Hermite's scaled slopes).
    slope_h: Vec<f64>,
}

impl Table {
    /// The table of `cycle`'s pressures, slopes by periodic fourth-order central differences
    /// (smooth whatever the stiffness of the equation that produced the values).
    pub(crate) fn new(pressure_pa: Vec<f64>) -> Self {
        let n = pressure_pa.len();
        let at = |k: isize| pressure_pa[k.rem_euclid(n as isize) as usize];
        let slope_h = (0..n as isize)
            .map(|k| (at(k - 2) - 8.0 * at(k - 1) + 8.0 * at(k + 1) - at(k + 2)) / 12.0)
            .collect();
        Self {
            pressure_pa,
            slope_h,
        }
    }

    /// The pressure at crank angle `theta` (any real; periodic in 2 pi).
    pub(crate) fn at(&self, theta: f64) -> f64 {
        let n = self.pressure_pa.len();
        let u = theta.rem_euclid(TAU) / TAU * n as f64;
        let k = (u.floor() as usize).min(n - 1);
        let t = (u - k as f64).clamp(0.0, 1.0);
        let k1 = if k + 1 == n { 0 } else { k + 1 };
        let (p0, p1) = (self.pressure_pa[k], self.pressure_pa[k1]);
        let (m0, m1) = (self.slope_h[k], self.slope_h[k1]);
        let t2 = t * t;
        let t3 = t2 * t;
        (2.0 * t3 - 3.0 * t2 + 1.0) * p0
            + (t3 - 2.0 * t2 + t) * m0
            + (-2.0 * t3 + 3.0 * t2) * p1
            + (t3 - t2) * m1
    }
}

/// The time constant, s, of a deviation from the periodic cycle at crank speed `omega`, from the
/// slope `slope` of `G(y0) = y(2 pi) - y0` at the fixed point: the revolution map's slope
/// `lambda = 1 + G'` shrinks a deviation by `lambda` per revolution.
fn time_constant(slope: f64, omega: f64) -> f64 {
    let lambda = 1.0 + slope;
    if lambda <= 0.0 {
        // Gone within a revolution.
        0.0
    } else if lambda >= 1.0 {
        f64::INFINITY
    } else {
        -(TAU / omega) / lambda.ln()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nozzle_function_is_continuous_at_the_critical_ratio_and_zero_without_a_difference() {
        let g = GAMMA_AIR;
        let critical = (2.0 / (g + 1.0)).powf(g / (g - 1.0));
        let choked = g.sqrt() * (2.0 / (g + 1.0)).powf((g + 1.0) / (2.0 * (g - 1.0)));
        assert!((nozzle(0.1) - choked).abs() < 1e-15);
        assert!((nozzle(critical + 1e-12) - choked).abs() < 1e-9);
        assert_eq!(nozzle(1.0), 0.0);
        // Small differences: the incompressible orifice, psi ~ sqrt(2 (1 - r)).
        let r: f64 = 1.0 - 1e-6;
        assert!((nozzle(r) / (2.0 * (1.0 - r)).sqrt() - 1.0).abs() < 1e-5);
    }

    #[test]
    fn the_table_interpolates_a_smooth_periodic_function_to_fourth_order() {
        let f = |t: f64| 1e5 + 3e4 * t.sin() + 1e4 * (2.0 * t).cos();
        let table = Table::new(
            (0..NODES_PER_REV)
                .map(|k| f(TAU * k as f64 / NODES_PER_REV as f64))
                .collect(),
        );
        for i in 0..1000 {
            let t = -3.0 + 0.0137 * i as f64;
            assert!((table.at(t) - f(t)).abs() < 1e-4, "{t}");
        }
    }
}
