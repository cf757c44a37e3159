//! The finite-length Reynolds equation of a plain journal bearing with the Reynolds
//! (Swift-Stieber) film-rupture condition, solved by finite volumes and projected successive
//! over-relaxation (Christopherson's method: every update is clipped at `p = 0`, which makes
//! the discrete solution satisfy `p >= 0`, the Reynolds residual `>= 0` and their product `= 0`,
//! the complementarity form of the rupture condition).
//!
//! Only the pure squeeze problem is solved. A journal whose eccentricity ratio vector `eps`
//! changes at `eps_dot` while journal and bearing turn at `omega_j` and `omega_b` sees the film
//! thickness rate `dh/dt + omega_bar dh/dtheta = -c n . v` with the squeeze velocity
//! `v = eps_dot - omega_bar z x eps` and `omega_bar = (omega_j + omega_b) / 2`; so the pressure
//! of any motion is that of a pure squeeze at `v` (Booker's mobility method). In the frame of
//! `eps` (theta from the thinnest film), with `zeta = z / R` and `lambda = L / D`:
//!
//! ```text
//! d/dtheta(h^3 dp/dtheta) + d/dzeta(h^3 dp/dzeta) = -cos(theta - gamma),   h = 1 - eps cos theta
//! p = 0 at zeta = +-lambda, periodic in theta, p >= 0
//! ```
//!
//! where `gamma` is the direction of `v` from `eps`. The dimensional pressure is
//! `12 mu R^2 |v| / c^2` times `p`, and the film's force on the journal is
//! `-(12 mu R^4 |v| / c^2) G` with `G = integral of p (cos theta, sin theta) dtheta dzeta`.
//!
//! The grid is uniform in `xi` with `theta = xi - a sin xi`, denser near the thinnest film
//! (`a` grows with the eccentricity), and uniform in `zeta` over the half width (the plane
//! `zeta = 0` is a symmetry plane).

use std::f64::consts::PI;

/// Grid and iteration settings of [`solve_squeeze`].
#[derive(Debug, Clone, Copy)]
pub struct Grid {
    /// Nodes around the circumference.
    pub n_theta: usize,
    /// Intervals across the half width (from the symmetry plane to the edge).
    pub n_zeta: usize,
    /// Convergence: the largest update of a sweep below this fraction of the peak pressure.
    pub tol: f64,
    /// At most this many sweeps.
    pub max_sweeps: usize,
    /// Over-relaxation factor of the projected SOR sweeps.
    pub omega: f64,
}

impl Default for Grid {
    fn default() -> Self {
        Self {
            n_theta: 240,
            n_zeta: 24,
            tol: 1e-10,
            max_sweeps: 40_000,
            omega: 1.9,
        }
    }
}

/// One pure-squeeze solution.
#[derive(Debug, Clone)]
pub struct Squeeze {
    /// `G` in the eccentricity frame: the integral of the pressure times the unit normal.
    pub g: [f64; 2],
    /// Largest nondimensional pressure.
    pub peak: f64,
    /// Sweeps used.
    pub sweeps: usize,
    /// The pressure field (half width, `n_theta x (n_zeta + 1)`, row per `theta` node), for a
    /// warm start of the next solve.
    pub p: Vec<f64>,
}

/// Solve the pure-squeeze Reynolds problem at eccentricity ratio `eps` (0 <= eps < 1), squeeze
/// direction `gamma` (rad, from the eccentricity) and `lambda = L / D`, starting from `warm`
/// (a previous solution on the same grid) when given.
pub fn solve_squeeze(
    eps: f64,
    gamma: f64,
    lambda: f64,
    grid: &Grid,
    warm: Option<&[f64]>,
) -> Squeeze {
    let n = grid.n_theta;
    let m = grid.n_zeta;
    // Grid stretching towards theta = 0, where the film is thinnest.
    let a = (0.85 * eps).min(0.8);
    let theta: Vec<f64> = (0..n)
        .map(|i| {
            let xi = 2.0 * PI * i as f64 / n as f64;
            xi - a * xi.sin()
        })
        .collect();
    let gap = |i: usize| -> f64 {
        // theta_{i+1} - theta_i, wrapping around.
        if i + 1 < n {
            theta[i + 1] - theta[i]
        } else {
            theta[0] + 2.0 * PI - theta[i]
        }
    };
    let film = |t: f64| 1.0 - eps * t.cos();
    let dz = lambda / m as f64;
    // Coefficients per theta node: east/west conductances per unit zeta width, the node's own
    // film cubed, its control width and source.
    let mut east = vec![0.0; n];
    let mut width = vec![0.0; n];
    let mut h3 = vec![0.0; n];
    let mut source = vec![0.0; n];
    for i in 0..n {
        let d = gap(i);
        let mid = theta[i] + 0.5 * d;
        east[i] = film(mid).powi(3) / d;
    }
    for i in 0..n {
        let west = if i == 0 { n - 1 } else { i - 1 };
        width[i] = 0.5 * (gap(i) + gap(west));
        h3[i] = film(theta[i]).powi(3);
        source[i] = (theta[i] - gamma).cos() * width[i];
    }
    let cols = m + 1;
    let mut p = match warm {
        Some(w) if w.len() == n * cols => w.to_vec(),
        _ => vec![0.0; n * cols],
    };
    let omega = grid.omega;
    let mut sweeps = 0;
    loop {
        sweeps += 1;
        let mut change = 0.0f64;
        let mut peak = 0.0f64;
        for i in 0..n {
            let west = if i == 0 { n - 1 } else { i - 1 };
            let e_nb = if i + 1 < n { i + 1 } else { 0 };
            let (a_e, a_w) = (east[i], east[west]);
            let a_z = h3[i] * width[i] / (dz * dz);
            for k in 0..m {
                // Control volume of half height at the symmetry plane.
                let wz = if k == 0 { 0.5 } else { 1.0 };
                let (ae, aw) = (a_e * wz, a_w * wz);
                let an = a_z;
                let as_ = if k == 0 { 0.0 } else { a_z };
                let sum = ae + aw + an + as_;
                let idx = i * cols + k;
                let nb = ae * p[e_nb * cols + k]
                    + aw * p[west * cols + k]
                    + an * p[idx + 1]
                    + if k == 0 { 0.0 } else { as_ * p[idx - 1] };
                let gs = (nb + source[i] * wz) / sum;
                let new = (p[idx] + omega * (gs - p[idx])).max(0.0);
                change = change.max((new - p[idx]).abs());
                peak = peak.max(new);
                p[idx] = new;
            }
        }
        if change <= grid.tol * peak.max(1e-300) || sweeps >= grid.max_sweeps {
            break;
        }
    }
    // Integrals over the full width: twice the half width, the symmetry plane's cell half.
    let mut g = [0.0, 0.0];
    let mut peak = 0.0f64;
    for i in 0..n {
        let (s, c) = theta[i].sin_cos();
        for k in 0..m {
            let wz = if k == 0 { 0.5 } else { 1.0 };
            let v = p[i * cols + k];
            peak = peak.max(v);
            let area = 2.0 * width[i] * dz * wz;
            g[0] += v * c * area;
            g[1] += v * s * area;
        }
    }
    Squeeze { g, peak, sweeps, p }
}
