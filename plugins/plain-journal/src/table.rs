//! The finite bearing's mobility tables: the solutions of [`crate::reynolds`] tabulated once
//! per length-to-diameter ratio (the generated `tables_data.rs`, written by
//! `cargo run --release -p tribo-law-plain-journal --example tabulate`) and interpolated.
//!
//! Each table holds, on a grid in `s = -ln(1 - eps)` and in the load direction `beta` (the
//! angle of the load the journal carries, from its eccentricity, in `[0, pi]`; the other half
//! is the mirror image), the squeeze direction `gamma` whose film force points along `-beta`,
//! `ln |G| - 3 ln lambda` and `ln(peak) - 2 ln lambda` (the short bearing's scaling taken out,
//! so the values vary slowly with `lambda`). A steady row gives `ln |G|` and the attitude angle
//! of the steadily loaded journal (squeeze direction `-pi/2`). Between tables the values are
//! interpolated linearly in `ln lambda`; below the smallest ratio the short bearing's scaling
//! carries the smallest table down (exact as `lambda -> 0`), above the largest the largest
//! table is used (a long bearing's load capacity is under-estimated there).

use std::f64::consts::PI;

/// One length-to-diameter ratio's table (module docs).
#[derive(Debug)]
pub struct Table {
    /// `L / D`.
    pub lambda: f64,
    /// Largest `s = -ln(1 - eps)` of the grid.
    pub s_max: f64,
    /// Grid points in `s` (uniform from 0).
    pub n_s: usize,
    /// Grid points in `beta` (uniform over `[0, pi]`).
    pub n_beta: usize,
    /// Squeeze direction, rad, `n_s x n_beta` row-major.
    pub gamma: &'static [f64],
    /// `ln |G| - 3 ln lambda`, `n_s x n_beta`.
    pub ln_g: &'static [f64],
    /// `ln(peak) - 2 ln lambda`, `n_s x n_beta`.
    pub ln_peak: &'static [f64],
    /// Steady load: `ln |G| - 3 ln lambda` at squeeze direction `-pi/2`, per `s`.
    pub steady_ln_g: &'static [f64],
    /// Steady load: attitude angle (load line to eccentricity), rad, per `s`.
    pub steady_attitude: &'static [f64],
}

/// What the tables give for one state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mobility {
    /// Squeeze direction from the eccentricity, rad (sign of the load side).
    pub gamma: f64,
    /// `|G|` (with the `lambda` scaling back in).
    pub g: f64,
    /// Peak nondimensional pressure.
    pub peak: f64,
}

/// Cubic Lagrange weights on a uniform grid `0, h, .., (n-1) h` of four nodes from the
/// returned first index: around `x` (clamped to the grid), shifted inside the grid at its ends
/// when `inside`, else centred (the caller extends the grid by symmetry).
fn cubic(x: f64, h: f64, n: usize, inside: bool) -> (isize, [f64; 4]) {
    let u = (x / h).clamp(0.0, (n - 1) as f64);
    let mut first = (u.floor() as isize).clamp(0, n as isize - 2) - 1;
    if inside {
        first = first.clamp(0, n as isize - 4);
    }
    let t = u - first as f64;
    // Nodes first .. first + 3 at t = 0, 1, 2, 3.
    let w = [
        -(t - 1.0) * (t - 2.0) * (t - 3.0) / 6.0,
        t * (t - 2.0) * (t - 3.0) / 2.0,
        -t * (t - 1.0) * (t - 3.0) / 2.0,
        t * (t - 1.0) * (t - 2.0) / 6.0,
    ];
    (first, w)
}

impl Table {
    /// Interpolated `(gamma, ln_g, ln_peak)` at `s`, `beta in [0, pi]`: cubic in both, the
    /// columns beyond `[0, pi]` taken from the mirror symmetry in `beta`.
    fn at(&self, s: f64, beta: f64) -> (f64, f64, f64) {
        let hs = self.s_max / (self.n_s - 1) as f64;
        let hb = PI / (self.n_beta - 1) as f64;
        let (i0, ws) = cubic(s, hs, self.n_s, true);
        let (j0, wb) = cubic(beta, hb, self.n_beta, false);
        let nb = self.n_beta as isize;
        let mut out = (0.0, 0.0, 0.0);
        for (a, wa) in ws.iter().enumerate() {
            let i = (i0 + a as isize) as usize;
            for (b, wbb) in wb.iter().enumerate() {
                let j = j0 + b as isize;
                // Mirror in beta: gamma(-b) = -gamma(b), gamma(pi + b) = 2 pi - gamma(pi - b).
                let (jj, flip) = if j < 0 {
                    (-j, Some(0.0))
                } else if j >= nb {
                    (2 * (nb - 1) - j, Some(2.0 * PI))
                } else {
                    (j, None)
                };
                let k = i * self.n_beta + jj as usize;
                let g = match flip {
                    Some(base) => base - self.gamma[k],
                    None => self.gamma[k],
                };
                let w = wa * wbb;
                out.0 += w * g;
                out.1 += w * self.ln_g[k];
                out.2 += w * self.ln_peak[k];
            }
        }
        out
    }

    /// Interpolated steady `(ln_g, attitude)` at `s`.
    fn steady(&self, s: f64) -> (f64, f64) {
        let hs = self.s_max / (self.n_s - 1) as f64;
        let (i0, ws) = cubic(s, hs, self.n_s, true);
        let mut out = (0.0, 0.0);
        for (a, w) in ws.iter().enumerate() {
            let i = (i0 + a as isize) as usize;
            out.0 += w * self.steady_ln_g[i];
            out.1 += w * self.steady_attitude[i];
        }
        out
    }

    /// Largest eccentricity ratio the table covers.
    pub fn eps_max(&self) -> f64 {
        1.0 - (-self.s_max).exp()
    }
}

/// The two tables around `lambda` and the weight of the upper one (`ln lambda` linear).
fn bracket(tables: &'static [Table], lambda: f64) -> (&'static Table, &'static Table, f64) {
    let first = &tables[0];
    let last = &tables[tables.len() - 1];
    if lambda <= first.lambda {
        return (first, first, 0.0);
    }
    if lambda >= last.lambda {
        return (last, last, 0.0);
    }
    let k = tables
        .windows(2)
        .position(|w| lambda <= w[1].lambda)
        .unwrap_or(tables.len() - 2);
    let (a, b) = (&tables[k], &tables[k + 1]);
    let w = (lambda.ln() - a.lambda.ln()) / (b.lambda.ln() - a.lambda.ln());
    (a, b, w)
}

/// The ratio whose table values stand for `lambda` (clamped to the tables' range) and the
/// scaling exponent's reference: below the smallest table the short-bearing scaling in
/// `lambda` itself is exact, so the scaling uses the true `lambda` there.
fn scale_lambda(tables: &'static [Table], lambda: f64) -> f64 {
    let last = tables[tables.len() - 1].lambda;
    lambda.min(last)
}

/// The squeeze direction, `|G|` and peak pressure for eccentricity ratio `eps`, load
/// direction `beta` (from the eccentricity, any sign) and `lambda = L / D`.
pub fn mobility(tables: &'static [Table], lambda: f64, eps: f64, beta: f64) -> Mobility {
    // Fold beta into [0, pi]; the lower half is the mirror image.
    let b = beta.rem_euclid(2.0 * PI);
    let (b, sign) = if b > PI {
        (2.0 * PI - b, -1.0)
    } else {
        (b, 1.0)
    };
    let (lo, hi, w) = bracket(tables, lambda);
    let s = -(1.0 - eps.clamp(0.0, lo.eps_max().min(hi.eps_max()))).ln();
    let (g0, l0, p0) = lo.at(s, b);
    let (g1, l1, p1) = if w > 0.0 { hi.at(s, b) } else { (g0, l0, p0) };
    let lam = scale_lambda(tables, lambda);
    let gamma = g0 + w * (g1 - g0);
    let ln_g = l0 + w * (l1 - l0) + 3.0 * lam.ln();
    let ln_p = p0 + w * (p1 - p0) + 2.0 * lam.ln();
    Mobility {
        gamma: sign * gamma,
        g: ln_g.exp(),
        peak: ln_p.exp(),
    }
}

/// Steadily loaded journal: `|G|` at squeeze direction `-pi/2` and the attitude angle, for
/// eccentricity ratio `eps` and `lambda = L / D`.
pub fn steady(tables: &'static [Table], lambda: f64, eps: f64) -> (f64, f64) {
    let (lo, hi, w) = bracket(tables, lambda);
    let s = -(1.0 - eps.clamp(0.0, lo.eps_max().min(hi.eps_max()))).ln();
    let (l0, a0) = lo.steady(s);
    let (l1, a1) = if w > 0.0 { hi.steady(s) } else { (l0, a0) };
    let lam = scale_lambda(tables, lambda);
    (
        (l0 + w * (l1 - l0) + 3.0 * lam.ln()).exp(),
        a0 + w * (a1 - a0),
    )
}

/// Largest eccentricity ratio every table covers.
pub fn eps_max(tables: &'static [Table]) -> f64 {
    tables.iter().map(Table::eps_max).fold(1.0, f64::min)
}
