//! The barrel-shaped skirt pad's film in closed form: the infinitely wide pad of height `L`
//! (along the motion) whose film is `h(s) = h0 (1 + k s^2)`, `s = 2x/L` in `[-1, 1]`,
//! `k = crown / h0`, in steady sliding (Reynolds with the Swift-Stieber rupture condition) and
//! in pure squeeze (full film between the edges).
//!
//! Every integral is of the form `I_n = integral ds / (1 + k s^2)^n` (n = 1, 2, 3) or
//! `integral s ds / (1 + k s^2)^n`, which have closed forms (arctangent and the reduction
//! `I_{n+1} = s / (2n (1 + k s^2)^n) + (2n - 1)/(2n) I_n`); the rupture point is the one root of
//! a scalar equation. `docs/laws/piston-skirt.md` has the derivation.

use std::sync::OnceLock;

use tribo_plugin_api::tribology::newton_increasing;

/// The three antiderivatives `I_1, I_2, I_3` of `1 / (1 + k s^2)^n` at `s` (zero at `s = 0`).
fn antiderivatives(k: f64, s: f64) -> [f64; 3] {
    let q = 1.0 + k * s * s;
    let i1 = if k > 0.0 {
        let r = k.sqrt();
        (r * s).atan() / r
    } else {
        s
    };
    let i2 = s / (2.0 * q) + 0.5 * i1;
    let i3 = s / (4.0 * q * q) + 0.75 * i2;
    [i1, i2, i3]
}

/// `[I_1, I_2, I_3]` over `[a, b]`.
#[cfg(test)]
fn integrals(k: f64, a: f64, b: f64) -> [f64; 3] {
    let (lo, hi) = (antiderivatives(k, a), antiderivatives(k, b));
    [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]]
}

/// The steady sliding film of a pad, per unit `eta |U|`, as dimensionless factors of `k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlidingShape {
    /// Where the film ruptures, `s_c` in `(0, 1)` (the divergent half; `p = dp/dx = 0` there).
    pub rupture_s: f64,
    /// `J` in the load per unit width `w = 1.5 eta U L^2 J / h0^2`.
    pub load: f64,
    /// `Phi` in the friction on the sliding surface per unit width `f = eta U L Phi / (2 h0)`.
    pub friction: f64,
    /// `P` in the peak pressure `p_max = 3 eta U L P / h0^2` (at `s = -s_c`).
    pub peak: f64,
}

/// `G(s_c) = I_2(-1, s_c) - (1 + k s_c^2) I_3(-1, s_c)`: zero where the film ruptures (the
/// pressure back to zero with zero gradient), decreasing in `s_c` with slope `-2 k s_c I_3`.
#[cfg(test)]
fn rupture_residual(k: f64, s: f64) -> (f64, f64) {
    rupture_residual_from(k, s, &antiderivatives(k, -1.0))
}

/// [`rupture_residual`] with the inlet edge's antiderivatives `inlet` (at `s = -1`) given: they
/// do not change while the rupture point is searched.
fn rupture_residual_from(k: f64, s: f64, inlet: &[f64; 3]) -> (f64, f64) {
    let hi = antiderivatives(k, s);
    let i = [hi[0] - inlet[0], hi[1] - inlet[1], hi[2] - inlet[2]];
    let m = 1.0 + k * s * s;
    (i[1] - m * i[2], -2.0 * k * s * i[2])
}

/// The rupture point: Newton's method kept inside a shrinking bracket of `(0, 1)` (G > 0 at 0,
/// G < 0 at 1 for every k > 0, and G is decreasing there).
pub fn rupture_point(k: f64) -> f64 {
    rupture_point_from(k, &antiderivatives(k, -1.0))
}

/// [`rupture_point`] with the inlet edge's antiderivatives given, started from the table.
fn rupture_point_from(k: f64, inlet: &[f64; 3]) -> f64 {
    rupture_newton(k, inlet, rupture_start(k))
}

/// Nodes of the rupture point's start table, uniform in `t = 1 / sqrt(1 + k)` over `[0, 1]`.
const START_NODES: usize = 64;

/// `s_c sqrt(1 + k)` and its derivative in `t = 1 / sqrt(1 + k)` at the start table's nodes.
/// It lies between 0.475 (`k` to infinity) and 0.5 (`k` to 0) and is smooth in `t`, so its cubic
/// Hermite interpolation starts Newton's iteration within about 1e-7 of the root (three steps to
/// rounding instead of six or more from the middle of the bracket). Computed once, by the
/// iteration itself from the middle of the bracket.
fn start_table() -> &'static [(f64, f64)] {
    static TABLE: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let scaled = |t: f64| {
            let k = 1.0 / (t * t) - 1.0;
            if k <= 0.0 {
                0.5
            } else {
                rupture_newton(k, &antiderivatives(k, -1.0), 0.5) / t
            }
        };
        (0..=START_NODES)
            .map(|i| {
                let t = (i as f64 / START_NODES as f64).max(1e-9);
                let (a, b) = ((t - 1e-6).max(1e-9), (t + 1e-6).min(1.0));
                (scaled(t), (scaled(b) - scaled(a)) / (b - a))
            })
            .collect()
    })
}

/// Where Newton's iteration for the rupture point starts: the start table's value at `k`.
fn rupture_start(k: f64) -> f64 {
    let table = start_table();
    let t = 1.0 / (1.0 + k).sqrt();
    let step = 1.0 / START_NODES as f64;
    let x = t * START_NODES as f64;
    if !(x >= 0.0 && x <= START_NODES as f64) {
        return 0.5;
    }
    let i = (x as usize).min(START_NODES - 1);
    let u = x - i as f64;
    let ((y0, d0), (y1, d1)) = (table[i], table[i + 1]);
    let (u2, u3) = (u * u, u * u * u);
    let scaled = (2.0 * u3 - 3.0 * u2 + 1.0) * y0
        + (u3 - 2.0 * u2 + u) * step * d0
        + (-2.0 * u3 + 3.0 * u2) * y1
        + (u3 - u2) * step * d1;
    let s = scaled * t;
    if s > 0.0 && s < 1.0 {
        s
    } else {
        0.5
    }
}

/// The rupture point by Newton's method from `start` ([`newton_increasing`] on `-G`), kept
/// inside a shrinking bracket of `(0, 1)`, to rounding: a step below 1e-15 of the root's size,
/// which is at least `0.475 / sqrt(1 + k)` (the start table's bounds).
fn rupture_newton(k: f64, inlet: &[f64; 3], start: f64) -> f64 {
    newton_increasing(
        |s| {
            let (g, dg) = rupture_residual_from(k, s, inlet);
            (-g, -dg)
        },
        0.0,
        1.0,
        start,
        1e-15 * 0.475 / (1.0 + k).sqrt(),
    )
}

/// The sliding film's factors at `k = crown / h0 > 0`. The film is full from the inlet edge
/// (`s = -1`, ambient pressure: a flooded inlet) to the rupture point; beyond it the oil runs in
/// streamers filling the fraction `h_c / h` of the gap, which carry the flow `U h_c / 2` and
/// shear only where they touch (`eta U h_c / h^2`).
pub fn sliding(k: f64) -> SlidingShape {
    sliding_from(k, &antiderivatives(k, -1.0))
}

/// [`sliding`] with the inlet edge's antiderivatives given. The antiderivatives are odd in `s`,
/// so those at the outlet edge and at `-s_c` are the negated ones at the inlet edge and `s_c`.
fn sliding_from(k: f64, inlet: &[f64; 3]) -> SlidingShape {
    let (sc, load) = rupture_and_load_from(k, inlet);
    let m = 1.0 + k * sc * sc;
    let at_c = antiderivatives(k, sc);
    let full = [at_c[0] - inlet[0], at_c[1] - inlet[1], at_c[2] - inlet[2]];
    let tail_1 = -inlet[1] - at_c[1];
    let friction = 4.0 * full[0] - 3.0 * m * full[1] + m * tail_1;
    // The pressure peaks where h = h_c in the convergent half, at s = -s_c.
    let to_peak = [-at_c[1] - inlet[1], -at_c[2] - inlet[2]];
    let peak = to_peak[0] - m * to_peak[1];
    SlidingShape {
        rupture_s: sc,
        load,
        friction,
        peak,
    }
}

/// The rupture point and the load factor `J` alone (what the lateral balance needs).
pub fn rupture_and_load(k: f64) -> (f64, f64) {
    rupture_and_load_from(k, &antiderivatives(k, -1.0))
}

/// [`rupture_and_load`] with the inlet edge's antiderivatives given.
fn rupture_and_load_from(k: f64, inlet: &[f64; 3]) -> (f64, f64) {
    let sc = rupture_point_from(k, inlet);
    let m = 1.0 + k * sc * sc;
    // J = -integral_{-1}^{s_c} s [1/q^2 - m/q^3] ds, with integral s/q^n = -1/(2k(n-1) q^(n-1)),
    // written without the 1/k so that it keeps its digits for small k.
    let q1 = 1.0 + k;
    let one_minus = 1.0 - sc * sc;
    let d2 = -one_minus / (2.0 * m * q1); // [integral s/q^2] from -1 to s_c
    let d3 = -one_minus * (2.0 + k * (1.0 + sc * sc)) / (4.0 * m * m * q1 * q1); // [s/q^3]
    (sc, -(d2 - m * d3))
}

/// `S(k) = integral_{-1}^{1} s^2 / (1 + k s^2)^3 ds`, the squeeze film's load factor
/// (`2/3` for a flat pad).
pub fn squeeze_factor(k: f64) -> f64 {
    squeeze_factor_from(k, &antiderivatives(k, -1.0))
}

/// [`squeeze_factor`] with the antiderivatives at `s = -1` given (those at `s = 1` are their
/// negatives).
fn squeeze_factor_from(k: f64, inlet: &[f64; 3]) -> f64 {
    if k < 0.1 {
        // Series of s^2 / (1 + k s^2)^3 = sum_j (-1)^j (j+1)(j+2)/2 k^j s^(2j+2), integrated
        // term by term (the closed form below loses digits to cancellation as k -> 0).
        let mut sum = 0.0;
        let mut power = 1.0;
        for j in 0..60 {
            let term = power * ((j + 1) * (j + 2)) as f64 / 2.0 * 2.0 / (2 * j + 3) as f64;
            sum += if j % 2 == 0 { term } else { -term };
            power *= k;
        }
        return sum;
    }
    let i = [-inlet[1] - inlet[1], -inlet[2] - inlet[2]];
    (i[0] - i[1]) / k
}

/// `integral_0^1 s / (1 + k s^2)^3 ds = (2 + k) / (4 (1 + k)^2)`: the squeeze pressure at the
/// crown per unit of its scale.
pub fn squeeze_peak_factor(k: f64) -> f64 {
    (2.0 + k) / (4.0 * (1.0 + k) * (1.0 + k))
}

/// One side's film in physical units: a pad of height `height_m` and crown drop `crown_m` at
/// minimum film `h0_m`, `width_m` wide (across the motion).
#[derive(Debug, Clone, Copy)]
pub struct Pad {
    /// Pad height along the motion (the skirt's height), m.
    pub height_m: f64,
    /// Barrel drop from the crown to the pad's edges, m.
    pub crown_m: f64,
    /// Wetted width across the motion (arc length), m.
    pub width_m: f64,
}

/// The sliding film of one side at one instant, N and Pa.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlidingFilm {
    /// Load the film carries, N (pushing the pad away from the wall).
    pub load_n: f64,
    /// Friction on the sliding surface, N, for the given speed (opposing it).
    pub friction_n: f64,
    /// Peak film pressure, Pa.
    pub peak_pa: f64,
}

impl Pad {
    /// The steady sliding film at minimum film `h0_m`, viscosity `eta` and sliding speed
    /// `speed_m_s >= 0` (symmetric pad: the direction does not matter).
    pub fn sliding(&self, h0_m: f64, eta: f64, speed_m_s: f64) -> SlidingFilm {
        let k = self.crown_m / h0_m;
        if k <= 0.0 {
            return self.flat_sliding(h0_m, eta, speed_m_s);
        }
        self.sliding_of(sliding(k), h0_m, eta, speed_m_s)
    }

    /// [`Pad::sliding`] and [`Pad::squeeze_damping`] at the same film, the integrals from the
    /// inlet edge computed once for both.
    pub fn sliding_and_damping(&self, h0_m: f64, eta: f64, speed_m_s: f64) -> (SlidingFilm, f64) {
        let k = self.crown_m / h0_m;
        if k <= 0.0 {
            return (
                self.flat_sliding(h0_m, eta, speed_m_s),
                self.squeeze_damping(h0_m, eta),
            );
        }
        let inlet = antiderivatives(k, -1.0);
        (
            self.sliding_of(sliding_from(k, &inlet), h0_m, eta, speed_m_s),
            self.damping_of(squeeze_factor_from(k, &inlet), h0_m, eta),
        )
    }

    /// A flat pad: Couette shear, no wedge.
    fn flat_sliding(&self, h0_m: f64, eta: f64, speed_m_s: f64) -> SlidingFilm {
        SlidingFilm {
            load_n: 0.0,
            friction_n: eta * speed_m_s * self.height_m / h0_m * self.width_m,
            peak_pa: 0.0,
        }
    }

    /// The sliding film of shape `s` in physical units.
    fn sliding_of(&self, s: SlidingShape, h0_m: f64, eta: f64, speed_m_s: f64) -> SlidingFilm {
        let l = self.height_m;
        let scale = eta * speed_m_s;
        SlidingFilm {
            load_n: self.wedge_n(s.load, h0_m, scale),
            friction_n: scale * l * s.friction / (2.0 * h0_m) * self.width_m,
            peak_pa: 3.0 * scale * l * s.peak / (h0_m * h0_m),
        }
    }

    /// The load of the steady sliding film alone, N (as [`Pad::sliding`]'s `load_n`).
    pub fn sliding_load_n(&self, h0_m: f64, eta: f64, speed_m_s: f64) -> f64 {
        let k = self.crown_m / h0_m;
        if k <= 0.0 || speed_m_s == 0.0 {
            return 0.0;
        }
        self.wedge_n(rupture_and_load(k).1, h0_m, eta * speed_m_s)
    }

    /// `w = 1.5 eta U L^2 J / h0^2` over the width, N.
    fn wedge_n(&self, j: f64, h0_m: f64, eta_u: f64) -> f64 {
        1.5 * eta_u * self.height_m * self.height_m * j / (h0_m * h0_m) * self.width_m
    }

    /// The squeeze film's damping `K`, N s/m: an approaching film (`dh0/dt < 0`) carries
    /// `-K dh0/dt`. Full film, ambient pressure at both edges.
    pub fn squeeze_damping(&self, h0_m: f64, eta: f64) -> f64 {
        self.damping_of(squeeze_factor(self.crown_m / h0_m), h0_m, eta)
    }

    /// `K` from the squeeze factor `S(k)`.
    fn damping_of(&self, factor: f64, h0_m: f64, eta: f64) -> f64 {
        1.5 * eta * self.height_m.powi(3) * factor / h0_m.powi(3) * self.width_m
    }

    /// Peak squeeze pressure (at the crown), Pa, for an approach speed `-dh0/dt = rate_m_s >= 0`.
    pub fn squeeze_peak_pa(&self, h0_m: f64, eta: f64, rate_m_s: f64) -> f64 {
        let k = self.crown_m / h0_m;
        let half = 0.5 * self.height_m;
        12.0 * eta * rate_m_s * half * half / h0_m.powi(3) * squeeze_peak_factor(k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reduction formula's antiderivatives differentiate back to their integrands.
    #[test]
    fn antiderivatives_differentiate_to_their_integrands() {
        for k in [1e-3, 0.5, 3.0, 40.0] {
            for s in [-0.9, -0.2, 0.3, 0.8] {
                let d = 1e-6;
                let (a, b) = (antiderivatives(k, s + d), antiderivatives(k, s - d));
                let q: f64 = 1.0 + k * s * s;
                for n in 0..3 {
                    let fd = (a[n] - b[n]) / (2.0 * d);
                    let exact = q.powi(-(n as i32 + 1));
                    assert!(
                        (fd - exact).abs() < 1e-8,
                        "k {k} s {s} n {n}: {fd} vs {exact}"
                    );
                }
            }
        }
    }

    /// The rupture point is the root, and in (0, 1).
    #[test]
    fn rupture_point_is_the_root_in_the_divergent_half() {
        for k in [1e-4, 0.01, 0.3, 1.0, 7.0, 100.0, 1e4] {
            let s = rupture_point(k);
            assert!(s > 0.0 && s < 1.0, "k {k}: {s}");
            let (g, _) = rupture_residual(k, s);
            let scale = integrals(k, -1.0, s)[1];
            assert!(g.abs() <= 1e-13 * scale, "k {k}: G = {g}");
        }
    }

    /// The start table puts Newton's iteration within 1e-6 of the rupture point from a nearly
    /// flat to a sharply barrelled pad, and the root from it satisfies the rupture condition to
    /// rounding, as the root from the middle of the bracket does (the two within 1e-9: for a
    /// nearly flat pad `G` is a difference of nearly equal integrals, which leaves the root's
    /// last digits to rounding, about 1e-16 / k).
    #[test]
    fn the_start_table_starts_next_to_the_root() {
        for i in 0..=400 {
            let k = 10f64.powf(-6.0 + 15.0 * i as f64 / 400.0);
            let inlet = antiderivatives(k, -1.0);
            let plain = rupture_newton(k, &inlet, 0.5);
            let start = rupture_start(k);
            assert!(
                (start - plain).abs() <= 1e-6 * plain,
                "k {k}: {start} vs {plain}"
            );
            let root = rupture_point(k);
            let (g, _) = rupture_residual(k, root);
            let scale = integrals(k, -1.0, root)[1];
            assert!(g.abs() <= 1e-13 * scale, "k {k}: G = {g}");
            assert!(
                (root - plain).abs() <= 1e-9 * plain,
                "k {k}: {root} vs {plain}"
            );
        }
    }

    /// The flat-pad limit of the squeeze factor and its series agree with the closed form.
    #[test]
    fn squeeze_factor_series_meets_the_closed_form() {
        assert_eq!(squeeze_factor(0.0), 2.0 / 3.0);
        let (a, b) = (squeeze_factor(0.1 - 1e-12), squeeze_factor(0.1 + 1e-12));
        assert!((a - b).abs() < 1e-11 * a, "{a} vs {b}");
    }
}
