//! Contact mechanics the bundled film laws share (ring pack, piston skirt, plain journal) and any
//! law author may call: the film-parameter regime, two bracketing root finders (regula falsi;
//! Newton for a residual with its slope), and asperity contact by Greenwood and Tripp, the
//! nominal pressure the summits of two rough surfaces carry at a separation `h` of their mean
//! planes,
//!
//! ```text
//! p_a(h) = K E* F_5/2(h / sigma),    K = (16 sqrt(2) / 15) pi (eta beta sigma)^2 sqrt(sigma / beta)
//! F_n(x) = (2 pi)^(-1/2) integral_x^inf (s - x)^n exp(-s^2 / 2) ds
//! ```
//!
//! with Gaussian summit heights of composite standard deviation `sigma`, summit density `eta`,
//! summit radius `beta` and the composite modulus `1 / E* = (1 - nu_1^2) / E_1 + (1 - nu_2^2) / E_2`.
//! `F_5/2` is computed once by double-exponential quadrature and tabulated with its derivative
//! (`F_n' = -n F_(n-1)`) for cubic Hermite interpolation; it is not a curve fit.
//!
//! And the oil's viscosity-temperature line by Walther (ASTM D341), which the host's two-point
//! oil model and a law that heats its own film both draw.

use crate::contract::Regime;

/// The lubrication regime from the film parameter `lambda = h_min / sigma` (Hamrock's bands):
/// full film from 3, mixed from 1, boundary below.
pub fn film_regime(lambda: f64) -> Regime {
    if lambda >= 3.0 {
        Regime::Hydrodynamic
    } else if lambda >= 1.0 {
        Regime::Mixed
    } else {
        Regime::Boundary
    }
}

/// The root of `f`, increasing on `[lo, hi]`, by bracketing regula falsi (Illinois): an end
/// where `f` is already past zero is returned as is; the iteration stops when the bracket or
/// the iterate's move is below 1e-11 of `hi - lo`. (For a decreasing `f`, pass `-f`.)
pub fn root_increasing(f: impl Fn(f64) -> f64, lo: f64, hi: f64) -> f64 {
    let (mut a, mut b) = (lo, hi);
    let (mut fa, mut fb) = (f(a), f(b));
    if fa >= 0.0 {
        return a;
    }
    if fb <= 0.0 {
        return b;
    }
    let tol = 1e-11 * (hi - lo).abs();
    let mut side = 0i8;
    let mut last = f64::NAN;
    for _ in 0..200 {
        let x = (a * fb - b * fa) / (fb - fa);
        let x = if x.is_finite() && x > a && x < b {
            x
        } else {
            0.5 * (a + b)
        };
        let fx = f(x);
        if fx == 0.0 || (b - a) <= tol || (x - last).abs() <= tol {
            return x;
        }
        last = x;
        if fx < 0.0 {
            a = x;
            fa = fx;
            if side == -1 {
                fb *= 0.5;
            }
            side = -1;
        } else {
            b = x;
            fb = fx;
            if side == 1 {
                fa *= 0.5;
            }
            side = 1;
        }
    }
    0.5 * (a + b)
}

/// The root of `f`, increasing on `[lo, hi]` with `f(lo) <= 0 <= f(hi)` (the caller knows the
/// ends' signs; they are not evaluated), by Newton's method from `start` on the slope `f` returns
/// beside its value, `f(x) = (value, slope)`. Every evaluation narrows the bracket; a step that
/// would leave it, or a slope that is not positive, bisects instead, so the iteration converges
/// wherever Newton's would not. Stops when a step or the bracket is at most `tol` and returns the
/// point the last step reached, not evaluated (its error is of the order of the step squared
/// once Newton's steps converge). For a law whose residual and slope come cheaply together
/// (closed-form slopes); [`root_increasing`] needs no slope.
pub fn newton_increasing(
    mut f: impl FnMut(f64) -> (f64, f64),
    lo: f64,
    hi: f64,
    start: f64,
    tol: f64,
) -> f64 {
    let (mut lo, mut hi) = (lo, hi);
    let mut x = start;
    for _ in 0..200 {
        let (value, slope) = f(x);
        if value < 0.0 {
            lo = x;
        } else if value > 0.0 {
            hi = x;
        } else {
            return x;
        }
        let newton = x - value / slope;
        let next = if slope > 0.0 && newton >= lo && newton <= hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - x).abs() <= tol || hi - lo <= tol {
            return next;
        }
        x = next;
    }
    x
}

use std::sync::OnceLock;

/// Largest film parameter tabulated; beyond it `F_5/2` (below 1e-17) is taken as zero.
pub const LAMBDA_MAX: f64 = 8.0;

/// Table spacing in the film parameter.
const STEP: f64 = 0.01;

/// `F_n(x)` for `x >= 0` by exp-sinh quadrature: with `v = s - x = exp(pi/2 sinh t)` the
/// integrand `v^n exp(-(x + v)^2 / 2) dv` decays double-exponentially at both ends of `t`,
/// and the trapezoid rule in `t` converges to rounding.
pub fn gaussian_tail_moment(n: f64, x: f64) -> f64 {
    let h = 1.0 / 64.0;
    let half_pi = 0.5 * std::f64::consts::PI;
    let mut sum = 0.0;
    for i in -320..=320 {
        let t = i as f64 * h;
        let v = (half_pi * t.sinh()).exp();
        let dv = v * half_pi * t.cosh();
        let g = v.powf(n) * (-0.5 * (x + v) * (x + v)).exp() * dv;
        if g.is_finite() {
            sum += g;
        }
    }
    sum * h / (2.0 * std::f64::consts::PI).sqrt()
}

/// `F_5/2` and its derivative at the table's nodes.
fn table() -> &'static [(f64, f64)] {
    static TABLE: OnceLock<Vec<(f64, f64)>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let n = (LAMBDA_MAX / STEP).round() as usize;
        (0..=n)
            .map(|i| {
                let x = i as f64 * STEP;
                (
                    gaussian_tail_moment(2.5, x),
                    -2.5 * gaussian_tail_moment(1.5, x),
                )
            })
            .collect()
    })
}

/// `F_5/2(x)`, interpolated (cubic Hermite); `x < 0` is read as 0, `x >= LAMBDA_MAX` gives 0.
pub fn f52(x: f64) -> f64 {
    if x >= LAMBDA_MAX {
        return 0.0;
    }
    let t = table();
    let x = x.max(0.0);
    let i = ((x / STEP) as usize).min(t.len() - 2);
    let u = x / STEP - i as f64;
    let (y0, d0) = t[i];
    let (y1, d1) = t[i + 1];
    let (u2, u3) = (u * u, u * u * u);
    (2.0 * u3 - 3.0 * u2 + 1.0) * y0
        + (u3 - 2.0 * u2 + u) * STEP * d0
        + (-2.0 * u3 + 3.0 * u2) * y1
        + (u3 - u2) * STEP * d1
}

/// 16-point Gauss-Legendre nodes and weights on [-1, 1] (Abramowitz and Stegun, table 25.4).
const GAUSS_16: [(f64, f64); 16] = [
    (-0.989_400_934_991_649_9, 0.027_152_459_411_754_1),
    (-0.944_575_023_073_232_6, 0.062_253_523_938_647_9),
    (-0.865_631_202_387_831_7, 0.095_158_511_682_492_8),
    (-0.755_404_408_355_003, 0.124_628_971_255_533_9),
    (-0.617_876_244_402_643_7, 0.149_595_988_816_576_7),
    (-0.458_016_777_657_227_4, 0.169_156_519_395_002_5),
    (-0.281_603_550_779_258_9, 0.182_603_415_044_923_6),
    (-0.095_012_509_837_637_4, 0.189_450_610_455_068_5),
    (0.095_012_509_837_637_4, 0.189_450_610_455_068_5),
    (0.281_603_550_779_258_9, 0.182_603_415_044_923_6),
    (0.458_016_777_657_227_4, 0.169_156_519_395_002_5),
    (0.617_876_244_402_643_7, 0.149_595_988_816_576_7),
    (0.755_404_408_355_003, 0.124_628_971_255_533_9),
    (0.865_631_202_387_831_7, 0.095_158_511_682_492_8),
    (0.944_575_023_073_232_6, 0.062_253_523_938_647_9),
    (0.989_400_934_991_649_9, 0.027_152_459_411_754_1),
];

/// The rough surfaces' contact constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Roughness {
    /// Composite RMS roughness `sigma` of the two surfaces, m.
    pub sigma_m: f64,
    /// Roughness parameter `eta beta sigma`, -.
    pub eta_beta_sigma: f64,
    /// Asperity slope measure `sigma / beta`, -.
    pub sigma_over_beta: f64,
    /// Composite modulus `E*`, Pa.
    pub modulus_pa: f64,
}

impl Roughness {
    /// `K E*`: the asperity pressure at `F_5/2 = 1`, Pa.
    pub fn pressure_scale_pa(&self) -> f64 {
        16.0 * std::f64::consts::SQRT_2 / 15.0
            * std::f64::consts::PI
            * self.eta_beta_sigma
            * self.eta_beta_sigma
            * self.sigma_over_beta.sqrt()
            * self.modulus_pa
    }

    /// Load the asperities carry per unit length across a parabolic face (a ring's face, a
    /// barrel skirt's profile) of half width `half_width_m` and crown `crown_m` at minimum film
    /// `h_m`, N/m: `p_a` integrated over the face (16-point Gauss-Legendre on the part where the gap is below `LAMBDA_MAX sigma`).
    pub fn load_per_length(&self, half_width_m: f64, crown_m: f64, h_m: f64) -> f64 {
        let reach = (LAMBDA_MAX * self.sigma_m - h_m) / crown_m;
        if reach <= 0.0 {
            return 0.0;
        }
        let y_max = reach.sqrt().min(1.0);
        let f = |y: f64| f52((h_m + crown_m * y * y) / self.sigma_m);
        let sum: f64 = GAUSS_16
            .iter()
            .map(|&(x, w)| w * f(0.5 * y_max * (1.0 + x)))
            .sum();
        half_width_m * self.pressure_scale_pa() * sum * y_max
    }
}

/// The Walther (ASTM D341) line of an oil, `log10 log10(nu + 0.7) = A - B log10(T_K)` with `nu`
/// the kinematic viscosity in cSt: how oil charts interpolate viscosity between temperatures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaltherLine {
    /// `A`.
    pub a: f64,
    /// `B`, the slope (positive: the oil thins as it warms).
    pub b: f64,
}

/// `log10 log10(nu + 0.7)`, the Walther ordinate of a kinematic viscosity in cSt.
fn walther_ordinate(nu_cst: f64) -> f64 {
    (nu_cst + 0.7).log10().log10()
}

/// `log10` of the absolute temperature of `t_c` degrees Celsius.
fn log_kelvin(t_c: f64) -> f64 {
    (t_c + 273.15).log10()
}

impl WaltherLine {
    /// The line through the kinematic viscosities at 40 and 100 C (cSt), as oil data sheets
    /// give them.
    pub fn through_40_100(kv40_cst: f64, kv100_cst: f64) -> Self {
        let (x1, x2) = (log_kelvin(40.0), log_kelvin(100.0));
        let b = (walther_ordinate(kv40_cst) - walther_ordinate(kv100_cst)) / (x2 - x1);
        Self {
            a: walther_ordinate(kv40_cst) + b * x1,
            b,
        }
    }

    /// The line of slope `b` through `nu_cst` at `t_c`.
    pub fn through(nu_cst: f64, t_c: f64, b: f64) -> Self {
        Self {
            a: walther_ordinate(nu_cst) + b * log_kelvin(t_c),
            b,
        }
    }

    /// The kinematic viscosity at `t_c`, cSt.
    pub fn kinematic_cst(&self, t_c: f64) -> f64 {
        let z = self.a - self.b * log_kelvin(t_c);
        10f64.powf(10f64.powf(z)) - 0.7
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `F_n(0) = (2 pi)^(-1/2) 2^((n - 1)/2) Gamma((n + 1)/2)`: 0.5 for n = 0 (half the normal
    /// distribution), `(2 pi)^(-1/2)` for n = 1, `2^(3/4) Gamma(7/4) / sqrt(2 pi)` for n = 5/2.
    #[test]
    fn moments_at_zero_are_the_gamma_function_values() {
        let root = (2.0 * std::f64::consts::PI).sqrt();
        assert!((gaussian_tail_moment(0.0, 0.0) - 0.5).abs() < 1e-12);
        assert!((gaussian_tail_moment(1.0, 0.0) - 1.0 / root).abs() < 1e-12);
        // Gamma(7/4) = 0.919 062 526 848 883 (tables).
        let want = 2f64.powf(0.75) * 0.919_062_526_848_883 / root;
        assert!((gaussian_tail_moment(2.5, 0.0) - want).abs() < 1e-12);
        assert!((f52(0.0) - want).abs() < 1e-12);
    }

    /// The Gauss-Legendre rule integrates polynomials up to degree 31 exactly, and the face's
    /// asperity load agrees with a fine composite Simpson integral of the same integrand.
    #[test]
    fn the_face_integral_is_accurate() {
        for k in [0, 2, 10, 30] {
            let sum: f64 = GAUSS_16.iter().map(|&(x, w)| w * x.powi(k)).sum();
            assert!((sum - 2.0 / (k as f64 + 1.0)).abs() < 1e-14, "x^{k}: {sum}");
        }
        let r = Roughness {
            sigma_m: 0.35e-6,
            eta_beta_sigma: 0.04,
            sigma_over_beta: 1e-3,
            modulus_pa: 78e9,
        };
        for &(a, c, h) in &[
            (4e-4, 5e-6, 0.5e-6),
            (1.5e-4, 2e-6, 0.3e-6),
            (4e-4, 0.3e-6, 1e-6),
        ] {
            let n = 20000;
            let dy = 1.0 / n as f64;
            let f = |y: f64| f52((h + c * y * y) / r.sigma_m);
            let simpson: f64 = (0..=n)
                .map(|i| {
                    let w = if i == 0 || i == n {
                        1.0
                    } else if i % 2 == 1 {
                        4.0
                    } else {
                        2.0
                    };
                    w * f(i as f64 * dy)
                })
                .sum::<f64>()
                * dy
                / 3.0;
            let want = 2.0 * a * r.pressure_scale_pa() * simpson;
            let got = r.load_per_length(a, c, h);
            assert!(
                (got - want).abs() < 1e-6 * want,
                "{a} {c} {h}: {got} vs {want}"
            );
        }
    }

    /// `F_1(x) = phi(x) - x F_0(x)` (integration by parts) checks the quadrature away from
    /// zero, and the table interpolates between nodes to 1e-7 relative.
    #[test]
    fn quadrature_and_table_agree_with_identities() {
        for &x in &[0.5f64, 1.7, 3.0, 5.5] {
            let phi = (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
            let f1 = gaussian_tail_moment(1.0, x);
            let f0 = gaussian_tail_moment(0.0, x);
            assert!((f1 - (phi - x * f0)).abs() < 1e-13 * phi.max(1e-300) + 1e-16);
            let y = x + 0.00337;
            let exact = gaussian_tail_moment(2.5, y);
            assert!((f52(y) - exact).abs() < 1e-7 * exact, "{y}");
        }
    }

    /// Newton's root in its bracket: quadratic convergence to rounding on a smooth function, the
    /// bracket's bisection where Newton's steps would diverge (`atan`, from far out) or the slope
    /// is wrong, and an exact zero returned as is.
    #[test]
    fn newton_in_its_bracket() {
        let mut calls = 0;
        let r = newton_increasing(
            |x| {
                calls += 1;
                (x * x - 2.0, 2.0 * x)
            },
            0.0,
            2.0,
            1.0,
            1e-15,
        );
        assert!((r - 2f64.sqrt()).abs() <= 4e-16, "{r}");
        assert!(calls <= 7, "{calls} evaluations");
        // Newton on atan from 3 overshoots to about -9.5 and diverges; the bracket holds it.
        let r = newton_increasing(|x| (x.atan(), 1.0 / (1.0 + x * x)), -10.0, 20.0, 3.0, 1e-14);
        assert!(r.abs() < 1e-14, "{r}");
        // A slope of the wrong sign (here: always negative) leaves plain bisection.
        let r = newton_increasing(|x| (x - 0.3, -1.0), 0.0, 1.0, 0.9, 1e-12);
        assert!((r - 0.3).abs() < 2e-12, "{r}");
        assert_eq!(
            newton_increasing(|x| (x - 0.5, 1.0), 0.0, 1.0, 0.5, 1e-12),
            0.5
        );
    }

    /// The root finder finds a root to its tolerance, returns an end where `f` is already past
    /// zero, and the regime bands sit at film parameters 1 and 3.
    #[test]
    fn root_and_regime() {
        let r = root_increasing(|x| x.powi(3) - 2.0, 0.0, 4.0);
        assert!((r - 2f64.cbrt()).abs() < 1e-10, "{r}");
        assert_eq!(root_increasing(|x| x + 1.0, 0.0, 1.0), 0.0);
        assert_eq!(root_increasing(|x| x - 5.0, 0.0, 1.0), 1.0);
        assert_eq!(film_regime(3.0), Regime::Hydrodynamic);
        assert_eq!(film_regime(2.99), Regime::Mixed);
        assert_eq!(film_regime(1.0), Regime::Mixed);
        assert_eq!(film_regime(0.99), Regime::Boundary);
    }

    #[test]
    fn a_walther_line_passes_through_its_points_and_thins_with_temperature() {
        let line = WaltherLine::through_40_100(115.0, 17.5);
        assert!((line.kinematic_cst(40.0) - 115.0).abs() < 1e-9);
        assert!((line.kinematic_cst(100.0) - 17.5).abs() < 1e-9);
        assert!(line.kinematic_cst(80.0) < line.kinematic_cst(60.0));
        // The same line through one of its own points with its slope.
        let again = WaltherLine::through(line.kinematic_cst(70.0), 70.0, line.b);
        for t_c in [20.0, 90.0, 130.0] {
            let (x, y) = (line.kinematic_cst(t_c), again.kinematic_cst(t_c));
            assert!((x - y).abs() <= 1e-9 * x, "{t_c} C: {x} vs {y}");
        }
    }
}
