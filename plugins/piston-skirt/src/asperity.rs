//! Asperity contact of the skirt on the bore: the Greenwood-Tripp pressure
//! `p_a(h) = K E' F_5/2(h / sigma)`, `K = (16 sqrt 2 / 15) pi (eta_s beta sigma)^2 sqrt(sigma/beta)`,
//! integrated over the barrel pad's varying gap.

use std::sync::OnceLock;

/// Largest film parameter tabulated; beyond it `F_5/2` is below 1e-15 and taken as zero.
pub const LAMBDA_MAX: f64 = 8.0;

/// Table step in the film parameter.
const STEP: f64 = 1.0 / 256.0;

/// `F_5/2(x) = (2 pi)^(-1/2) integral_x^inf (t - x)^(5/2) exp(-t^2/2) dt` by direct quadrature:
/// with `t = x + u^2` the integrand `2 u^6 exp(-(x + u^2)^2 / 2)` is smooth; Gauss-Legendre on
/// 32 panels of `u` in `[0, 4]` (beyond, the integrand is below exp(-128)).
pub fn f52(x: f64) -> f64 {
    // 5-point Gauss-Legendre nodes and weights on [-1, 1].
    const NODES: [f64; 5] = [
        0.0,
        0.538_469_310_105_683_1,
        -0.538_469_310_105_683_1,
        0.906_179_845_938_664,
        -0.906_179_845_938_664,
    ];
    const WEIGHTS: [f64; 5] = [
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
        0.236_926_885_056_189_1,
    ];
    let panels = 32;
    let width = 4.0 / panels as f64;
    let mut sum = 0.0;
    for p in 0..panels {
        let mid = (p as f64 + 0.5) * width;
        for (z, w) in NODES.iter().zip(WEIGHTS) {
            let u = mid + 0.5 * width * z;
            let t = x + u * u;
            sum += w * 2.0 * u.powi(6) * (-0.5 * t * t).exp();
        }
    }
    sum * 0.5 * width / (2.0 * std::f64::consts::PI).sqrt()
}

/// `ln F_5/2` on `[0, LAMBDA_MAX]` at `STEP`, computed once per process.
fn table() -> &'static [f64] {
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let n = (LAMBDA_MAX / STEP).round() as usize;
        (0..=n).map(|i| f52(i as f64 * STEP).ln()).collect()
    })
}

/// `F_5/2(lambda)` from the table (log-linear interpolation), for `lambda >= 0`; zero beyond
/// [`LAMBDA_MAX`].
pub fn f52_tabulated(lambda: f64) -> f64 {
    if lambda >= LAMBDA_MAX {
        return 0.0;
    }
    let t = table();
    let x = lambda.max(0.0) / STEP;
    let i = (x.floor() as usize).min(t.len() - 2);
    let frac = x - i as f64;
    (t[i] + frac * (t[i + 1] - t[i])).exp()
}

/// The rough surfaces' Greenwood-Tripp constants.
#[derive(Debug, Clone, Copy)]
pub struct Roughness {
    /// Composite RMS roughness sigma, m.
    pub sigma_m: f64,
    /// `K E'`, Pa: the asperity pressure is `K E' F_5/2(h / sigma)`.
    pub pressure_scale_pa: f64,
}

impl Roughness {
    /// From the roughness, the asperity density-radius-roughness product `eta_s beta sigma`, the
    /// slope measure `sigma / beta` and the composite modulus `E'`, Pa.
    pub fn new(sigma_m: f64, eta_beta_sigma: f64, sigma_over_beta: f64, modulus_pa: f64) -> Self {
        let k = 16.0 * std::f64::consts::SQRT_2 / 15.0
            * std::f64::consts::PI
            * eta_beta_sigma
            * eta_beta_sigma
            * sigma_over_beta.sqrt();
        Self {
            sigma_m,
            pressure_scale_pa: k * modulus_pa,
        }
    }

    /// Asperity load on a barrel pad `height_m` by `width_m` with gap `h0 + crown s^2`, N:
    /// `(L/2) integral_{-1}^{1} p_a ds`, composite Simpson over the part of the pad where the
    /// film parameter is below [`LAMBDA_MAX`].
    pub fn pad_load(&self, h0_m: f64, crown_m: f64, height_m: f64, width_m: f64) -> f64 {
        let reach = LAMBDA_MAX * self.sigma_m - h0_m;
        if reach <= 0.0 {
            return 0.0;
        }
        let s_max = if crown_m > 0.0 {
            (reach / crown_m).sqrt().min(1.0)
        } else {
            1.0
        };
        let n = 64;
        let ds = s_max / n as f64;
        let mut sum = 0.0;
        for i in 0..=n {
            let s = i as f64 * ds;
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            sum += w * f52_tabulated((h0_m + crown_m * s * s) / self.sigma_m);
        }
        // Both halves of the symmetric pad: 2 (L/2) integral_0^s_max.
        self.pressure_scale_pa * sum * ds / 3.0 * height_m * width_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `F_n(0) = 2^((n-1)/2) Gamma((n+1)/2) / sqrt(2 pi)`; for n = 5/2,
    /// `Gamma(7/4) = (3/4) Gamma(3/4)` with Gamma(3/4) = 1.2254167024651776.
    #[test]
    fn f52_at_zero_matches_its_closed_form() {
        let exact =
            2f64.powf(0.75) * 0.75 * 1.225_416_702_465_177_6 / (2.0 * std::f64::consts::PI).sqrt();
        assert!(
            (f52(0.0) - exact).abs() < 1e-12 * exact,
            "{} vs {exact}",
            f52(0.0)
        );
        assert!((f52_tabulated(0.0) - exact).abs() < 1e-12 * exact);
    }

    /// The table interpolates the quadrature to 1e-5 relative, and falls monotonically.
    #[test]
    fn table_follows_the_quadrature_and_falls() {
        let mut prev = f64::INFINITY;
        for i in 0..700 {
            let x = 0.011 * i as f64 + 0.0007;
            let (a, b) = (f52(x), f52_tabulated(x));
            assert!((a - b).abs() <= 1e-5 * a, "{x}: {a} vs {b}");
            assert!(b < prev);
            prev = b;
        }
    }
}
