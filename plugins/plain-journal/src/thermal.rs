//! The film's effective temperature from a heat balance (docs/laws/plain-journal.md,
//! "Thermal"): the bearing designer's effective-temperature method of Raimondi and Boyd as
//! Shigley teaches it. The friction power `P` is carried away by the oil flowing through the
//! film, which warms by `dT = P / (rho c_p Q)`; the film shears at the viscosity of its mean
//! temperature `T_eff = T_feed + dT / 2`. The viscosity at `T_eff` follows the oil's
//! Walther (ASTM D341) line through the viscosity the law is given at the feed temperature.
//!
//! Because `P` rises and `Q` does not with the viscosity (module docs of [`solve`]), the balance
//! `T = T_feed + P(mu(T)) / (2 rho c_p Q(mu(T)))` has exactly one root, bracketed by the feed
//! temperature and the rise the feed viscosity would give.

use tribo_plugin_api::tribology::{newton_increasing, WaltherLine};

/// Largest half-rise `T_eff - T_feed` the balance may reach, K: a film with no through-flow
/// (both members at rest or counter-rotating with no squeeze) would heat without bound in an
/// adiabatic balance; conduction into the journal and shell (not modelled) bounds it. Beyond
/// about 150 C above the sump a real engine oil has left its data's range anyway.
pub const MAX_HALF_RISE_K: f64 = 150.0;

/// The oil's thermal properties and its viscosity-temperature slope.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Oil {
    /// Walther slope `B` of `log10 log10(nu + 0.7) = A - B log10(T_K)` (nu in cSt), -.
    pub walther_b: f64,
    /// Density, kg/m^3 (turns the law's dynamic viscosity into the chart's kinematic one).
    pub density_kg_m3: f64,
    /// Specific heat, J/(kg K).
    pub specific_heat_j_kg_k: f64,
}

/// The Walther slope `B` through two kinematic viscosities at 40 and 100 C (cSt), as the
/// rig's `two-point` oil model draws its line.
pub fn walther_slope(kv40_cst: f64, kv100_cst: f64) -> f64 {
    WaltherLine::through_40_100(kv40_cst, kv100_cst).b
}

impl Oil {
    /// The dynamic viscosity at `t_c`, Pa s, on the Walther line of slope `walther_b` through
    /// `mu_feed_pa_s` at `t_feed_c` (exact at the feed temperature).
    pub fn viscosity_at(&self, mu_feed_pa_s: f64, t_feed_c: f64, t_c: f64) -> f64 {
        self.line_through(mu_feed_pa_s, t_feed_c).viscosity_at(t_c)
    }

    /// The Walther line through the feed oil's viscosity `mu_feed_pa_s` at `t_feed_c`, drawn
    /// once for a heat balance that reads it at many temperatures.
    pub fn line_through(&self, mu_feed_pa_s: f64, t_feed_c: f64) -> FeedLine {
        let nu_feed = mu_feed_pa_s / self.density_kg_m3 * 1e6;
        FeedLine {
            mu_feed_pa_s,
            t_feed_c,
            nu_feed_cst: nu_feed,
            line: (mu_feed_pa_s > 0.0)
                .then(|| WaltherLine::through(nu_feed, t_feed_c, self.walther_b)),
        }
    }

    /// `rho c_p`, J/(m^3 K).
    pub fn heat_capacity_j_m3_k(&self) -> f64 {
        self.density_kg_m3 * self.specific_heat_j_kg_k
    }
}

/// The oil's viscosity-temperature line through the feed oil ([`Oil::line_through`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedLine {
    mu_feed_pa_s: f64,
    t_feed_c: f64,
    nu_feed_cst: f64,
    /// `None` for a feed viscosity `<= 0` (no oil to heat: the viscosity stays as given).
    line: Option<WaltherLine>,
}

impl FeedLine {
    /// The dynamic viscosity at `t_c`, Pa s (exact at the feed temperature).
    pub fn viscosity_at(&self, t_c: f64) -> f64 {
        match self.line {
            Some(line) if t_c != self.t_feed_c => {
                self.mu_feed_pa_s * line.kinematic_cst(t_c) / self.nu_feed_cst
            }
            _ => self.mu_feed_pa_s,
        }
    }

    /// [`FeedLine::viscosity_at`] and its derivative in temperature, Pa s / K: differentiating
    /// the line, `d nu / dT = -B (nu + 0.7) ln(nu + 0.7) / T_K`.
    pub fn viscosity_and_slope(&self, t_c: f64) -> (f64, f64) {
        let Some(line) = self.line else {
            return (self.mu_feed_pa_s, 0.0);
        };
        let (mu, nu) = if t_c == self.t_feed_c {
            (self.mu_feed_pa_s, self.nu_feed_cst)
        } else {
            let nu = line.kinematic_cst(t_c);
            (self.mu_feed_pa_s * nu / self.nu_feed_cst, nu)
        };
        let dnu = -line.b * (nu + 0.7) * (nu + 0.7).ln() / (t_c + 273.15);
        (mu, self.mu_feed_pa_s * dnu / self.nu_feed_cst)
    }
}

/// The balance's answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilmTemperature {
    /// Effective (mean) film temperature `T_feed + dT / 2`, C.
    pub effective_c: f64,
    /// The oil's temperature rise through the film `dT = P / (rho c_p Q)`, K.
    pub rise_k: f64,
    /// Viscosity at the effective temperature, Pa s.
    pub viscosity_pa_s: f64,
}

/// Solve `T = T_feed + P(mu(T)) / (2 rho c_p Q(mu(T)))` for the film's effective temperature.
/// `power_and_flow(mu)` gives the friction power (W) and the heat-carrying flow (m^3/s) at
/// viscosity `mu`; the balance has one root when the power does not fall and the flow does not
/// rise with the viscosity (the law's film obeys both: the Couette power is proportional to `mu`,
/// the load's offset moment does not depend on it, and the squeeze flow falls as `1 / mu`).
pub fn solve(
    oil: &Oil,
    t_feed_c: f64,
    mu_feed_pa_s: f64,
    power_and_flow: impl Fn(f64) -> (f64, f64),
) -> FilmTemperature {
    let rho_cp = oil.heat_capacity_j_m3_k();
    let rise_at = |mu: f64| -> f64 {
        let (p, q) = power_and_flow(mu);
        half_rise(rho_cp, p, q)
    };
    let line = oil.line_through(mu_feed_pa_s, t_feed_c);
    let first = rise_at(mu_feed_pa_s);
    let (t_eff, mu) = if first <= 0.0 {
        (t_feed_c, line.viscosity_at(t_feed_c))
    } else {
        balance_root(&line, t_feed_c, first, rise_at)
    };
    FilmTemperature {
        effective_c: t_eff,
        rise_k: 2.0 * (t_eff - t_feed_c),
        viscosity_pa_s: mu,
    }
}

/// The root of the balance's residual `g(T) = T - T_feed - half_rise(mu(T))` on
/// `[T_feed, T_feed + first]` (`g = -first < 0` at the feed temperature, `>= 0` at the other
/// end), with the viscosity there. `g` rises with a slope of at least 1 (`mu` falls with `T`,
/// the half-rise does not fall with `mu`), so Newton's method ([`newton_increasing`]) converges
/// fast; each step costs one point of the Walther line (its slope in closed form, the
/// half-rise's in `mu` by a difference over 1e-7 of `mu`: the half-rise is cheap, the line is
/// not). Converged when a step is below 1e-11 of the bracket (as the shared root finder's
/// regula falsi this replaces, which needed about twice the points of the line).
fn balance_root(
    line: &FeedLine,
    t_feed_c: f64,
    first: f64,
    half_rise: impl Fn(f64) -> f64,
) -> (f64, f64) {
    let residual_and_slope = |t: f64| {
        let (mu, dmu_dt) = line.viscosity_and_slope(t);
        let hr = if t == t_feed_c { first } else { half_rise(mu) };
        let dmu = 1e-7 * mu;
        let dhr_dmu = (half_rise(mu + dmu) - hr) / dmu;
        (t - t_feed_c - hr, 1.0 - dhr_dmu * dmu_dt)
    };
    let t = newton_increasing(
        residual_and_slope,
        t_feed_c,
        t_feed_c + first,
        t_feed_c,
        1e-11 * first,
    );
    (t, line.viscosity_at(t))
}

/// The oil's temperature half-rise `T_eff - T_feed` at which power `power_w` (W) and
/// carrying flow `flow_m3_s` (m^3/s) balance, K: `P / (2 rho c_p Q)`, 0 without power, the
/// bound [`MAX_HALF_RISE_K`] without flow.
pub fn half_rise(rho_cp: f64, power_w: f64, flow_m3_s: f64) -> f64 {
    let p = power_w.max(0.0);
    if p == 0.0 {
        0.0
    } else if flow_m3_s > 0.0 {
        (p / (2.0 * rho_cp * flow_m3_s)).min(MAX_HALF_RISE_K)
    } else {
        MAX_HALF_RISE_K
    }
}

/// The film's heat held over the cycle (docs/laws/plain-journal.md, "Thermal": the cycle-mean
/// balance). The film and the surfaces next to it store heat: over a step `dt` at power `P` and
/// carrying flow `Q` the half-rise `x = T_eff - T_feed` obeys the lumped balance
/// `C dx/dt = P / 2 - rho c_p Q x` whose heat capacity `C = rho c_p Q_mean tau` gives the
/// film the time constant `tau` at its mean flow. Over a periodic cycle (`x` nearly constant)
/// its mean is `mean(P) = 2 rho c_p mean(Q) x`: the balance on the cycle means. The step is
/// the linear equation's exact solution with `P` and `Q` held (stable at any step): a
/// first-order lag towards `P / (2 rho c_p Q)` at the rate `Q / (Q_mean tau)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldFilm {
    /// The film's half-rise over the feed, `T_eff - T_feed`, K.
    pub half_rise_k: f64,
    /// The running mean of the carrying flow over the lag, m^3/s.
    pub mean_flow_m3_s: f64,
}

impl HeldFilm {
    /// The film after a step of `step_over_lag = dt / tau` at power `power_w` and carrying
    /// flow `flow_m3_s` (`rho_cp` the oil's `rho c_p`, J/(m^3 K)). The mean flow follows the
    /// same first-order lag; without flow the film keeps its temperature (no oil moves heat).
    pub fn step(self, rho_cp: f64, power_w: f64, flow_m3_s: f64, step_over_lag: f64) -> Self {
        let keep = (-step_over_lag).exp();
        let mean = flow_m3_s + (self.mean_flow_m3_s - flow_m3_s) * keep;
        if !(flow_m3_s > 0.0 && mean > 0.0) {
            return Self {
                half_rise_k: self.half_rise_k,
                mean_flow_m3_s: mean.max(0.0),
            };
        }
        let target = half_rise(rho_cp, power_w, flow_m3_s);
        let x = target + (self.half_rise_k - target) * (-step_over_lag * flow_m3_s / mean).exp();
        Self {
            half_rise_k: x.min(MAX_HALF_RISE_K),
            mean_flow_m3_s: mean,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The root of an increasing `g` in `[a, b]` by 200 halvings: to the last bit, and
    /// independent of the law's own Newton root.
    fn bisect(g: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
        for _ in 0..200 {
            let m = 0.5 * (a + b);
            if g(m) < 0.0 {
                a = m;
            } else {
                b = m;
            }
        }
        a
    }

    const OIL: Oil = Oil {
        walther_b: 3.5,
        density_kg_m3: 850.0,
        specific_heat_j_kg_k: 2000.0,
    };

    /// The anchored Walther line is the rig's two-point line: through 65 cSt at 40 C and 11
    /// cSt at 100 C, started from either point.
    #[test]
    fn the_walther_line_passes_through_the_oils_two_points() {
        let oil = Oil {
            walther_b: walther_slope(65.0, 11.0),
            ..OIL
        };
        let mu40 = 65e-6 * 850.0;
        let mu100 = oil.viscosity_at(mu40, 40.0, 100.0);
        assert!((mu100 / 850.0 * 1e6 - 11.0).abs() < 1e-9, "{mu100}");
        let back = oil.viscosity_at(mu100, 100.0, 40.0);
        assert!((back - mu40).abs() < 1e-12 * mu40);
    }

    /// With a given power and flow that do not depend on the viscosity the rise is exactly
    /// `P / (rho c_p Q)` and the effective temperature is the feed's plus half of it.
    #[test]
    fn the_rise_is_the_power_over_the_flows_heat_capacity() {
        let (p, q) = (150.0, 1.5e-6);
        let t = solve(&OIL, 90.0, 0.0117, |_| (p, q));
        let rise = p / (850.0 * 2000.0 * q);
        assert!((t.rise_k - rise).abs() < 1e-9 * rise, "{t:?} vs {rise}");
        assert!((t.effective_c - (90.0 + rise / 2.0)).abs() < 1e-9);
        assert!((t.viscosity_pa_s - OIL.viscosity_at(0.0117, 90.0, t.effective_c)).abs() < 1e-15);
    }

    /// A power proportional to the viscosity: the balance's root satisfies it, it lies between
    /// the feed temperature and the feed viscosity's rise, and it is unique (the residual rises
    /// strictly over a wide range of temperatures).
    #[test]
    fn the_fixed_point_converges_and_is_unique() {
        let q = 1.57e-6;
        let pf = |mu: f64| (1e4 * mu + 20.0, q);
        let t = solve(&OIL, 90.0, 0.0117, pf);
        let g = |t_c: f64| {
            let mu = OIL.viscosity_at(0.0117, 90.0, t_c);
            t_c - 90.0 - pf(mu).0 / (2.0 * OIL.heat_capacity_j_m3_k() * q)
        };
        assert!(g(t.effective_c).abs() < 1e-8, "{}", g(t.effective_c));
        let first = pf(0.0117).0 / (2.0 * OIL.heat_capacity_j_m3_k() * q);
        assert!(t.effective_c > 90.0 && t.effective_c < 90.0 + first);
        let mut last = g(40.0);
        for i in 1..=400 {
            let now = g(40.0 + 0.5 * i as f64);
            assert!(now > last, "not increasing at {} C", 40.0 + 0.5 * i as f64);
            last = now;
        }
        // Iterating the balance from the feed temperature lands on the same point.
        let mut t_it = 90.0;
        for _ in 0..200 {
            let mu = OIL.viscosity_at(0.0117, 90.0, t_it);
            t_it = 90.0 + pf(mu).0 / (2.0 * OIL.heat_capacity_j_m3_k() * q);
        }
        assert!(
            (t_it - t.effective_c).abs() < 1e-6,
            "{t_it} vs {}",
            t.effective_c
        );
    }

    /// The line's slope in closed form is the derivative of its viscosity (central
    /// differences), at the feed temperature and away from it.
    #[test]
    fn the_lines_slope_is_the_derivative_of_its_viscosity() {
        let line = OIL.line_through(0.0117, 90.0);
        for t_c in [40.0, 90.0, 91.5, 130.0, 220.0] {
            let (mu, slope) = line.viscosity_and_slope(t_c);
            assert_eq!(mu, line.viscosity_at(t_c));
            let e = 1e-3;
            let fd = (line.viscosity_at(t_c + e) - line.viscosity_at(t_c - e)) / (2.0 * e);
            assert!(
                slope < 0.0 && (slope - fd).abs() <= 1e-6 * fd.abs(),
                "{t_c} C: {slope} vs {fd}"
            );
        }
    }

    /// Newton's root is the balance's root found by plain bisection to the last bit (within
    /// 1e-9 K), for a power linear in the viscosity, a flow that switches from the rotating
    /// film's to the squeeze film's (a kink in the half-rise), a power with no viscous part, and
    /// a film hot enough to reach the bound; the viscosity returned is the line's at the root.
    #[test]
    fn the_root_is_the_bisected_root_of_the_balance() {
        let rho_cp = OIL.heat_capacity_j_m3_k();
        let cases: [&dyn Fn(f64) -> (f64, f64); 4] = [
            &|mu: f64| (1e4 * mu + 20.0, 1.57e-6),
            &|mu: f64| (9e3 * mu, (1.2e-6f64).max(1.2e-8 / mu)),
            &|_: f64| (60.0, 1.0e-6),
            &|mu: f64| (3e6 * mu, 1.0e-8),
        ];
        for (n, pf) in cases.iter().enumerate() {
            let t = solve(&OIL, 90.0, 0.0117, pf);
            let g = |t_c: f64| {
                let (p, q) = pf(OIL.viscosity_at(0.0117, 90.0, t_c));
                t_c - 90.0 - (p / (2.0 * rho_cp * q)).min(MAX_HALF_RISE_K)
            };
            let a = bisect(g, 90.0, 90.0 + MAX_HALF_RISE_K + 1.0);
            assert!(
                (t.effective_c - a).abs() < 1e-9,
                "case {n}: {} vs {a}",
                t.effective_c
            );
            assert_eq!(
                t.viscosity_pa_s,
                OIL.viscosity_at(0.0117, 90.0, t.effective_c)
            );
        }
    }

    /// A held film at constant power and flow answers a step in the feed temperature as a
    /// first-order lag: the film keeps its temperature at the step, then approaches the new
    /// feed plus the same rise as `1 - exp(-t / tau)`, exactly (the step is the linear
    /// equation's solution), whatever the step size.
    #[test]
    fn a_held_film_answers_a_feed_step_in_first_order() {
        let rho_cp = OIL.heat_capacity_j_m3_k();
        let (p, q) = (150.0, 1.5e-6);
        let x_star = p / (2.0 * rho_cp * q);
        let (t0, t1) = (90.0, 110.0);
        for (s, n) in [(0.01, 400), (0.05, 80)] {
            let mut t_film = t0 + x_star;
            let mut mean = q;
            for k in 1..=n {
                let held = HeldFilm {
                    half_rise_k: t_film - t1,
                    mean_flow_m3_s: mean,
                }
                .step(rho_cp, p, q, s);
                t_film = t1 + held.half_rise_k;
                mean = held.mean_flow_m3_s;
                let by_hand = t1 + x_star - (t1 - t0) * (-s * k as f64).exp();
                assert!(
                    (t_film - by_hand).abs() < 1e-11,
                    "step {s}, {k}: {t_film} vs {by_hand}"
                );
            }
        }
    }

    /// A film whose load alternates between two states each step, fast against the lag,
    /// settles where the cycle's mean power balances its mean flow, `T = T_feed + (P_a(mu) +
    /// P_b(mu)) / (2 rho c_p (Q_a + Q_b))` at the viscosity of `T` (found here by bisection),
    /// not at the mean of the two states' own balances, which lies 2.5 K hotter.
    #[test]
    fn an_alternating_film_settles_at_the_balance_of_the_means() {
        let rho_cp = OIL.heat_capacity_j_m3_k();
        let (t_feed, mu_feed) = (40.0, 0.05);
        let line = OIL.line_through(mu_feed, t_feed);
        let states = [
            |mu: f64| (2000.0 * mu + 5.0, 1.0e-6),
            |mu: f64| (2000.0 * mu + 5.0, 4.0e-6),
        ];
        let (mut t_film, mut mean) = (t_feed, 1.0e-6);
        let mut last = Vec::new();
        let n = 60_000;
        for k in 0..n {
            let (p, q) = states[k % 2](line.viscosity_at(t_film));
            let held = HeldFilm {
                half_rise_k: t_film - t_feed,
                mean_flow_m3_s: mean,
            }
            .step(rho_cp, p, q, 1e-3);
            t_film = t_feed + held.half_rise_k;
            mean = held.mean_flow_m3_s;
            if k >= n - 2000 {
                last.push(t_film);
            }
        }
        let settled = last.iter().sum::<f64>() / last.len() as f64;
        let g = |t: f64| {
            let mu = line.viscosity_at(t);
            let (pa, qa) = states[0](mu);
            let (pb, qb) = states[1](mu);
            t - t_feed - (pa + pb) / (2.0 * rho_cp * (qa + qb))
        };
        let a = bisect(g, t_feed, t_feed + 100.0);
        assert!((settled - a).abs() < 0.02, "{settled} vs {a}");
        let own = |i: usize| solve(&OIL, t_feed, mu_feed, states[i]).effective_c;
        let mean_of_own = 0.5 * (own(0) + own(1));
        assert!(mean_of_own - a > 2.0, "{mean_of_own} vs {a}");
    }

    /// Without flow a held film keeps its temperature; the mean flow follows the flow.
    #[test]
    fn a_held_film_without_flow_keeps_its_temperature() {
        let held = HeldFilm {
            half_rise_k: 12.0,
            mean_flow_m3_s: 1e-6,
        }
        .step(1.7e6, 50.0, 0.0, 0.5);
        assert_eq!(held.half_rise_k, 12.0);
        assert!((held.mean_flow_m3_s - 1e-6 * (-0.5f64).exp()).abs() < 1e-20);
    }

    /// No power, no rise; no flow, the bounded rise.
    #[test]
    fn no_power_no_rise_and_no_flow_is_bounded() {
        let t = solve(&OIL, 90.0, 0.0117, |_| (0.0, 1e-6));
        assert_eq!(t.effective_c, 90.0);
        assert_eq!(t.viscosity_pa_s, 0.0117);
        let t = solve(&OIL, 90.0, 0.0117, |_| (10.0, 0.0));
        assert!((t.effective_c - (90.0 + MAX_HALF_RISE_K)).abs() < 1e-6);
    }
}
