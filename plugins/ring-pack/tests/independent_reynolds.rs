//! The crate's closed-form film against an independent numerical solution of the same problem:
//! the Reynolds equation `d/dx(h^3 dp/dx) = 6 mu u dh/dx + 12 mu hdot` on the face, discretised
//! by finite volumes and solved with the cavitation condition `p >= 0` as a complementarity
//! problem (projected successive over-relaxation, Christopherson's method), which finds the
//! rupture point itself. Given film, speed and load, the crate gives the squeeze velocity; the
//! numerical film run at that squeeze must carry the same load, with the same friction and peak
//! pressure, within 1%.

use tribo_law_ring_pack::profile::{film_for_load, Face};

struct Numerical {
    load: f64,
    friction: f64,
    peak: f64,
}

/// The film of the parabolic face (half width `a`, crown `c`) at minimum film `h0`, sliding
/// `u >= 0`, squeeze `hdot`, on `n` cells.
fn numerical(a: f64, c: f64, h0: f64, u: f64, hdot: f64, mu: f64, n: usize) -> Numerical {
    let dx = 2.0 * a / n as f64;
    let h = |x: f64| h0 + c * (x / a) * (x / a);
    let x = |i: usize| -a + i as f64 * dx;
    // Face conductances h^3 at i + 1/2, and the right-hand side per node.
    let k: Vec<f64> = (0..n).map(|i| h(x(i) + 0.5 * dx).powi(3)).collect();
    let rhs: Vec<f64> = (1..n)
        .map(|i| {
            let dh = h(x(i) + 0.5 * dx) - h(x(i) - 0.5 * dx);
            (6.0 * mu * u * dh / dx + 12.0 * mu * hdot) * dx * dx
        })
        .collect();
    let mut p = vec![0.0; n + 1];
    let omega = 1.97;
    for sweep in 0..2_000_000 {
        let mut change: f64 = 0.0;
        let mut top: f64 = 0.0;
        for i in 1..n {
            let (kw, ke) = (k[i - 1], k[i]);
            let gs = (ke * p[i + 1] + kw * p[i - 1] - rhs[i - 1]) / (ke + kw);
            let new = ((1.0 - omega) * p[i] + omega * gs).max(0.0);
            change = change.max((new - p[i]).abs());
            top = top.max(new);
            p[i] = new;
        }
        if sweep > 100 && change <= 1e-13 * top.max(1e-300) {
            break;
        }
    }
    let load: f64 = p.iter().sum::<f64>() * dx;
    let peak = p.iter().cloned().fold(0.0, f64::max);
    let i_peak = p.iter().position(|&v| v == peak).unwrap_or(0);
    // Shear on the liner per face: full film where the pressure is up and upstream of it;
    // downstream of the pressurised zone the oil runs on in streamers carrying the flux that
    // crossed the rupture (`h_c = 2 q / u`).
    let mut friction = 0.0;
    let mut h_c: Option<f64> = None;
    for i in 0..n {
        let xf = x(i) + 0.5 * dx;
        let hf = h(xf);
        let dp = (p[i + 1] - p[i]) / dx;
        let wet = p[i] > 0.0 || p[i + 1] > 0.0 || i < i_peak || peak == 0.0 && i == 0;
        if wet && h_c.is_none() {
            friction += (mu * u / hf + 0.5 * hf * dp) * dx;
        } else {
            let hc = *h_c.get_or_insert_with(|| {
                // Flux through the last wet face.
                let xw = xf - dx;
                let hw = h(xw);
                let dpw = (p[i] - p[i - 1]) / dx;
                2.0 * (0.5 * u * hw - hw.powi(3) * dpw / (12.0 * mu)) / u.max(1e-300)
            });
            friction += mu * u * hc / (hf * hf) * dx;
        }
    }
    Numerical {
        load,
        friction,
        peak,
    }
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs().max(1e-300)
}

/// Steady-ish, approaching (whole film), separating (early rupture), pure squeeze, an oil-ring
/// rail: the numerical film at the crate's squeeze carries the crate's load.
#[test]
fn the_closed_form_film_matches_a_numerical_reynolds_solution_within_one_percent() {
    let mu = 0.01;
    let cases = [
        // (width, crown, h0, u, load)
        (0.8e-3, 5e-6, 2e-6, 10.0, 150.0),
        (0.8e-3, 5e-6, 2e-6, 1.0, 2000.0),
        (0.8e-3, 5e-6, 2e-6, 10.0, 20.0),
        (0.8e-3, 5e-6, 1e-6, 0.0, 300.0),
        (0.3e-3, 2e-6, 0.5e-6, 3.0, 260.0),
        (1.2e-3, 10e-6, 0.8e-6, 12.0, 400.0),
    ];
    for (width, crown, h0, u, load) in cases {
        let face = Face {
            half_width_m: 0.5 * width,
            crown_m: crown,
        };
        let film = film_for_load(&face, h0, u, load, mu);
        let num = numerical(0.5 * width, crown, h0, u, film.squeeze_m_s, mu, 1600);
        let case = format!("width {width} crown {crown} h0 {h0} u {u} load {load}: {film:?}");
        assert!(
            close(num.load, load, 0.01),
            "{case}: numerical load {}",
            num.load
        );
        assert!(
            close(num.peak, film.peak_pa, 0.01),
            "{case}: numerical peak {}",
            num.peak
        );
        if u > 0.0 {
            assert!(
                close(num.friction, film.shear_n_per_m, 0.01),
                "{case}: numerical friction {}",
                num.friction
            );
        } else {
            assert_eq!(film.shear_n_per_m, 0.0, "{case}");
        }
    }
}
