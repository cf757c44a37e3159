//! Ocvirk's short bearing (half-Sommerfeld) in pure squeeze, in closed form.
//!
//! With the axial pressure gradient dominant (`L / D -> 0`), the Reynolds equation of
//! [`crate::reynolds`] reduces at each angle to `d/dzeta(h^3 dp/dzeta) = -cos(theta - gamma)`,
//! so `p = cos(theta - gamma) (lambda^2 - zeta^2) / (2 h^3)` where it is positive and 0 where
//! it is not (half-Sommerfeld; at this limit every angle is independent, so the `p >= 0`
//! projection and the half-Sommerfeld cut coincide). Its force integral over
//! `theta in (gamma - pi/2, gamma + pi/2)` is
//!
//! ```text
//! G = (2 lambda^3 / 3) integral cos(theta - gamma) (cos theta, sin theta) / (1 - eps cos theta)^3
//! ```
//!
//! evaluated exactly: with `D = 1 - eps cos theta` and Sommerfeld's substitution
//! `tan(psi/2) = sqrt((1 + eps)/(1 - eps)) tan(theta/2)` the integrals `I_k = integral D^-k`
//! are `I_1 = psi / s`, `I_2 = (psi + eps sin psi) / s^3`,
//! `I_3 = (psi + 2 eps sin psi + eps^2 (psi/2 + sin 2psi / 4)) / s^5` (`s = sqrt(1 - eps^2)`),
//! and `cos^2/D^3 = (I_3 - 2 I_2 + I_1) / eps^2`, `sin^2/D^3 = I_3 - cos^2/D^3`,
//! `sin cos / D^3 = [(1/D - 1/(2 D^2)) / eps^2]`. Below `eps = 0.05`, where those differences
//! lose digits, 64-point Gauss-Legendre quadrature of the smooth integrand is used instead.

use std::f64::consts::PI;

/// `G` and the peak pressure of the short bearing (module docs), eccentricity frame.
pub fn squeeze(eps: f64, gamma: f64, lambda: f64) -> ([f64; 2], f64) {
    let (a, b) = (gamma - 0.5 * PI, gamma + 0.5 * PI);
    let (cc, sc, ss) = if eps < 0.05 {
        quadrature(eps, a, b)
    } else {
        closed(eps, a, b)
    };
    let (sg, cg) = gamma.sin_cos();
    let k = 2.0 * lambda.powi(3) / 3.0;
    let g = [k * (cg * cc + sg * sc), k * (cg * sc + sg * ss)];
    (g, 0.5 * lambda * lambda * peak_shape(eps, gamma))
}

/// The three integrals over `[a, b]` in closed form.
fn closed(eps: f64, a: f64, b: f64) -> (f64, f64, f64) {
    let s = (1.0 - eps * eps).sqrt();
    let k = ((1.0 + eps) / (1.0 - eps)).sqrt();
    let psi = |theta: f64| {
        // Continuous in theta: reduce to (-pi, pi], map, add back the whole turns.
        let turns = ((theta + PI) / (2.0 * PI)).floor();
        let t0 = theta - 2.0 * PI * turns;
        let half = 0.5 * t0;
        2.0 * (k * half.sin()).atan2(half.cos()) + 2.0 * PI * turns
    };
    let i_k = |p: f64| {
        let (sp, s2p) = (p.sin(), (2.0 * p).sin());
        (
            p / s,
            (p + eps * sp) / s.powi(3),
            (p + 2.0 * eps * sp + eps * eps * (0.5 * p + 0.25 * s2p)) / s.powi(5),
        )
    };
    let (pa, pb) = (psi(a), psi(b));
    let (ia, ib) = (i_k(pa), i_k(pb));
    let (i1, i2, i3) = (ib.0 - ia.0, ib.1 - ia.1, ib.2 - ia.2);
    let cc = (i3 - 2.0 * i2 + i1) / (eps * eps);
    let ss = i3 - cc;
    let d = |t: f64| 1.0 - eps * t.cos();
    let prim = |t: f64| (1.0 / d(t) - 0.5 / (d(t) * d(t))) / (eps * eps);
    (cc, prim(b) - prim(a), ss)
}

/// The three integrals by 64-point Gauss-Legendre quadrature (small eccentricity).
fn quadrature(eps: f64, a: f64, b: f64) -> (f64, f64, f64) {
    let (nodes, weights) = gauss_legendre_64();
    let (mid, half) = (0.5 * (a + b), 0.5 * (b - a));
    let (mut cc, mut sc, mut ss) = (0.0, 0.0, 0.0);
    for (x, w) in nodes.iter().zip(weights.iter()) {
        let t = mid + half * x;
        let (st, ct) = t.sin_cos();
        let d3 = (1.0 - eps * ct).powi(3);
        cc += w * ct * ct / d3;
        sc += w * st * ct / d3;
        ss += w * st * st / d3;
    }
    (cc * half, sc * half, ss * half)
}

/// Nodes and weights of 64-point Gauss-Legendre quadrature on [-1, 1], by Newton iteration
/// on the Legendre polynomial (computed once).
fn gauss_legendre_64() -> &'static (Vec<f64>, Vec<f64>) {
    static RULE: std::sync::OnceLock<(Vec<f64>, Vec<f64>)> = std::sync::OnceLock::new();
    RULE.get_or_init(|| {
        let n = 64;
        let (mut x, mut w) = (vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, z);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                let dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
                let dz = p1 / dp;
                z -= dz;
                if dz.abs() < 1e-15 {
                    let (mut q0, mut q1) = (1.0, z);
                    for k in 2..=n {
                        let q2 = ((2 * k - 1) as f64 * z * q1 - (k - 1) as f64 * q0) / k as f64;
                        q0 = q1;
                        q1 = q2;
                    }
                    let dq = n as f64 * (z * q1 - q0) / (z * z - 1.0);
                    x[i] = z;
                    w[i] = 2.0 / ((1.0 - z * z) * dq * dq);
                    break;
                }
            }
        }
        (x, w)
    })
}

/// Largest `cos(theta - gamma) / (1 - eps cos theta)^3` over the loaded half: a scan, then
/// golden-section refinement around the best node.
fn peak_shape(eps: f64, gamma: f64) -> f64 {
    let f = |t: f64| (t - gamma).cos() / (1.0 - eps * t.cos()).powi(3);
    let (lo, hi) = (gamma - 0.5 * PI, gamma + 0.5 * PI);
    let n = 64;
    let step = (hi - lo) / n as f64;
    let best = (0..=n)
        .map(|i| lo + step * i as f64)
        .fold((lo, f64::MIN), |acc, t| {
            let v = f(t);
            if v > acc.1 {
                (t, v)
            } else {
                acc
            }
        });
    let (mut a, mut b) = ((best.0 - step).max(lo), (best.0 + step).min(hi));
    let r = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..80 {
        let (c, d) = (b - r * (b - a), a + r * (b - a));
        if f(c) > f(d) {
            b = d;
        } else {
            a = c;
        }
    }
    f(0.5 * (a + b)).max(best.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed forms and the quadrature agree where both are accurate.
    #[test]
    fn closed_forms_agree_with_quadrature() {
        for &eps in &[0.05, 0.2, 0.5, 0.8] {
            for &gamma in &[-1.5, -0.3, 0.0, 0.7, 2.9] {
                let (a, b) = (gamma - 0.5 * PI, gamma + 0.5 * PI);
                let c = closed(eps, a, b);
                let q = quadrature(eps, a, b);
                for (x, y) in [(c.0, q.0), (c.1, q.1), (c.2, q.2)] {
                    assert!(
                        (x - y).abs() <= 1e-10 * x.abs().max(1.0),
                        "{eps} {gamma}: {x} {y}"
                    );
                }
            }
        }
    }
}
