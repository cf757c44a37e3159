//! The law's film against an independent solution of the Reynolds equation written here: the
//! full time-dependent equation in the bearing's own frame (not the eccentricity frame, not
//! reduced to a pure squeeze), node-centred finite differences on a uniform grid over the whole
//! width, projected Gauss-Seidel for `p >= 0`. Given the eccentricity rate the law's mobility
//! predicts for a load, this solver's film force must be that load, within 1%.

use std::f64::consts::PI;

use tribo_law_plain_journal::bearing::{Bearing, Model};

/// Film force on the journal (N) and peak pressure (Pa) of a journal at eccentricity ratio
/// `eps` moving at `eps_dot` (1/s), journal and bearing turning at `wj`, `wb`.
fn film(
    b: &Bearing,
    mu: f64,
    eps: [f64; 2],
    eps_dot: [f64; 2],
    wj: f64,
    wb: f64,
) -> ([f64; 2], f64) {
    let (n, m) = (720usize, 80usize);
    let lam = b.length_m / (2.0 * b.radius_m);
    let (dth, dz) = (2.0 * PI / n as f64, 2.0 * lam / m as f64);
    let c = b.clearance_m;
    let wbar = 0.5 * (wj + wb);
    let h = |t: f64| c * (1.0 - eps[0] * t.cos() - eps[1] * t.sin());
    // d/dtheta(h^3 dp/dtheta) + d/dzeta(h^3 dp/dzeta) = 12 mu R^2 (wbar dh/dtheta + dh/dt)
    let rhs: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 * dth;
            let dh_dth = c * (eps[0] * t.sin() - eps[1] * t.cos());
            let dh_dt = -c * (eps_dot[0] * t.cos() + eps_dot[1] * t.sin());
            12.0 * mu * b.radius_m.powi(2) * (wbar * dh_dth + dh_dt)
        })
        .collect();
    let he: Vec<f64> = (0..n).map(|i| h((i as f64 + 0.5) * dth).powi(3)).collect();
    let hc: Vec<f64> = (0..n).map(|i| h(i as f64 * dth).powi(3)).collect();
    // Nodes k = 0..=m across the width; k = 0 and k = m are the edges (p = 0).
    let mut p = vec![0.0f64; n * (m + 1)];
    let omega = 1.85;
    for sweep in 0..200_000 {
        let mut change = 0.0f64;
        let mut peak = 0.0f64;
        for i in 0..n {
            let (ip, im) = ((i + 1) % n, (i + n - 1) % n);
            let (ae, aw) = (he[i] / (dth * dth), he[im] / (dth * dth));
            let az = hc[i] / (dz * dz);
            for k in 1..m {
                let idx = i * (m + 1) + k;
                let gs = (ae * p[ip * (m + 1) + k]
                    + aw * p[im * (m + 1) + k]
                    + az * (p[idx + 1] + p[idx - 1])
                    - rhs[i])
                    / (ae + aw + 2.0 * az);
                let new = (p[idx] + omega * (gs - p[idx])).max(0.0);
                change = change.max((new - p[idx]).abs());
                peak = peak.max(new);
                p[idx] = new;
            }
        }
        if sweep > 10 && change <= 1e-11 * peak {
            break;
        }
    }
    // Force on the journal: the pressure pushes it along -n; trapezoid rule across the width.
    let mut f = [0.0, 0.0];
    let mut peak = 0.0f64;
    for i in 0..n {
        let t = i as f64 * dth;
        for k in 0..=m {
            let w = if k == 0 || k == m { 0.5 } else { 1.0 };
            let v = p[i * (m + 1) + k];
            peak = peak.max(v);
            let a = w * dth * dz * b.radius_m * b.radius_m;
            f[0] -= v * t.cos() * a;
            f[1] -= v * t.sin() * a;
        }
    }
    (f, peak)
}

#[test]
fn the_mobility_method_on_the_tables_reproduces_an_independent_reynolds_solution() {
    let mu = 0.012;
    // (L/D, eps, load direction from the eccentricity, load N, journal and bearing speeds):
    // a main bearing of the 4B11 between two tables (L/D 0.4), a big end (bearing turning),
    // a small end (journal still), a heavily loaded short bearing, a long one.
    let cases = [
        (0.4, 0.58, 1.2, 8000.0, 600.0, 0.0),
        (0.5, 0.8, -0.7, 20000.0, 600.0, 150.0),
        (1.0, 0.3, 2.6, 3000.0, 0.0, -100.0),
        (0.25, 0.9, 0.2, 15000.0, 300.0, 0.0),
        (0.7, 0.65, -2.2, 10000.0, -400.0, 0.0),
    ];
    for (l_over_d, e, beta, load, wj, wb) in cases {
        let b = Bearing {
            radius_m: 0.025,
            length_m: l_over_d * 0.05,
            clearance_m: 25e-6,
            model: Model::Finite,
        };
        let theta_e: f64 = 0.9; // an arbitrary orientation of the eccentricity
        let eps = [e * theta_e.cos(), e * theta_e.sin()];
        // The load the journal carries points at beta from the eccentricity; the film pushes back.
        let tw = theta_e + beta;
        let force = [-load * tw.cos(), -load * tw.sin()];
        let motion = b.motion(eps, force, 0.5 * (wj + wb), mu);
        let (f, peak) = film(&b, mu, eps, motion.eps_rate, wj, wb);
        let err = (f[0] - force[0]).hypot(f[1] - force[1]) / load;
        assert!(
            err <= 0.01,
            "L/D {l_over_d}, eps {e}, beta {beta}: independent film force {f:?} vs the load {force:?} ({:.2}%)",
            100.0 * err
        );
        let perr = (motion.peak_pressure_pa - peak).abs() / peak;
        assert!(
            perr <= 0.05,
            "L/D {l_over_d}, eps {e}: peak pressure {} vs {peak} ({:.1}%)",
            motion.peak_pressure_pa,
            100.0 * perr
        );
        eprintln!(
            "L/D {l_over_d} eps {e}: force within {:.3}%, peak pressure within {:.2}%",
            100.0 * err,
            100.0 * perr
        );
    }
}
