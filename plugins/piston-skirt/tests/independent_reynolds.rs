//! An independent numerical check of the skirt pad's closed forms: the Reynolds equation
//! `d/dx (h^3 dp/dx) = 6 eta U dh/dx + 12 eta dh/dt` solved by finite differences on the barrel
//! profile, cavitation by Christopherson's projected over-relaxation (`p >= 0`, which yields the
//! Swift-Stieber condition), the load and the friction integrated numerically. Written here from
//! the equation; it shares no code with the law.

use tribo_law_piston_skirt::pad::Pad;

/// Film at node `i` of `n` cells over the pad.
fn film(h0: f64, crown: f64, l: f64, n: usize, i: usize) -> f64 {
    let x = -0.5 * l + l * i as f64 / n as f64;
    let s = 2.0 * x / l;
    h0 + crown * s * s
}

/// Pressure on the nodes for sliding at `u` (surface moving towards +x), or squeezing at
/// `dh/dt = v`; ambient at both edges, never below it.
fn reynolds(h0: f64, crown: f64, l: f64, eta: f64, u: f64, v: f64, n: usize) -> Vec<f64> {
    let dx = l / n as f64;
    let h: Vec<f64> = (0..=n).map(|i| film(h0, crown, l, n, i)).collect();
    // Conductances at the cell faces, h^3 at the mid-point.
    let face: Vec<f64> = (0..n)
        .map(|i| {
            let hm = film(h0, crown, l, 2 * n, 2 * i + 1);
            hm * hm * hm
        })
        .collect();
    let rhs: Vec<f64> = (0..=n)
        .map(|i| {
            if i == 0 || i == n {
                0.0
            } else {
                6.0 * eta * u * (h[i + 1] - h[i - 1]) / (2.0 * dx) + 12.0 * eta * v
            }
        })
        .collect();
    let mut p = vec![0.0; n + 1];
    let omega = 2.0 / (1.0 + (std::f64::consts::PI / n as f64).sin());
    for sweep in 0..200_000 {
        let mut change: f64 = 0.0;
        let mut size: f64 = 0.0;
        for i in 1..n {
            let (a, b) = (face[i - 1], face[i]);
            let gs = (a * p[i - 1] + b * p[i + 1] - rhs[i] * dx * dx) / (a + b);
            let next = (p[i] + omega * (gs - p[i])).max(0.0);
            change = change.max((next - p[i]).abs());
            size = size.max(next.abs());
            p[i] = next;
        }
        if sweep > 10 && change <= 1e-11 * size {
            break;
        }
    }
    p
}

/// Load per unit width and friction on the moving surface per unit width (streamers behind the
/// rupture filling the fraction `h_c / h` of the gap).
fn load_and_friction(h0: f64, crown: f64, l: f64, eta: f64, u: f64, n: usize) -> (f64, f64) {
    let p = reynolds(h0, crown, l, eta, u, 0.0, n);
    let dx = l / n as f64;
    let load: f64 = p.iter().sum::<f64>() * dx;
    // Rupture: the first node, downstream of the peak, where the pressure is back to zero.
    let peak = (0..=n).fold(0, |m, i| if p[i] > p[m] { i } else { m });
    let rupture = (peak..=n).find(|&i| p[i] <= 0.0).unwrap_or(n);
    let hc = film(h0, crown, l, n, rupture);
    let mut friction = 0.0;
    for i in 0..n {
        let hm = film(h0, crown, l, 2 * n, 2 * i + 1);
        let dp = (p[i + 1] - p[i]) / dx;
        friction += if i < rupture {
            eta * u / hm + 0.5 * hm * dp
        } else {
            eta * u * hc / (hm * hm)
        } * dx;
    }
    (load, friction)
}

#[test]
fn sliding_load_and_friction_agree_with_a_numerical_reynolds_solution_within_1_percent() {
    let (l, eta, u) = (0.022, 0.012, 7.5);
    for (h0, crown) in [(10e-6, 10e-6), (5e-6, 15e-6), (3e-6, 30e-6)] {
        let (w_num, f_num) = load_and_friction(h0, crown, l, eta, u, 1600);
        let pad = Pad {
            height_m: l,
            crown_m: crown,
            width_m: 1.0,
        };
        let got = pad.sliding(h0, eta, u);
        let (ew, ef) = (
            (got.load_n / w_num - 1.0).abs(),
            (got.friction_n / f_num - 1.0).abs(),
        );
        assert!(
            ew < 0.01,
            "h0 {h0}, crown {crown}: load {} vs numerical {w_num}",
            got.load_n
        );
        assert!(
            ef < 0.01,
            "h0 {h0}, crown {crown}: friction {} vs numerical {f_num}",
            got.friction_n
        );
        let peak = reynolds(h0, crown, l, eta, u, 0.0, 1600)
            .into_iter()
            .fold(0.0, f64::max);
        assert!(
            (got.peak_pa / peak - 1.0).abs() < 0.01,
            "peak {} vs {peak}",
            got.peak_pa
        );
    }
}

#[test]
fn squeeze_damping_agrees_with_a_numerical_reynolds_solution_within_1_percent() {
    let (l, eta, v) = (0.022, 0.012, -1e-4);
    for (h0, crown) in [(10e-6, 0.0), (5e-6, 15e-6), (3e-6, 30e-6)] {
        let p = reynolds(h0, crown, l, eta, 0.0, v, 800);
        let load: f64 = p.iter().sum::<f64>() * l / 800.0;
        let pad = Pad {
            height_m: l,
            crown_m: crown,
            width_m: 1.0,
        };
        let k = pad.squeeze_damping(h0, eta) * -v;
        assert!(
            (k / load - 1.0).abs() < 0.01,
            "h0 {h0} crown {crown}: {k} vs {load}"
        );
        let peak = p.into_iter().fold(0.0, f64::max);
        let got = pad.squeeze_peak_pa(h0, eta, -v);
        assert!((got / peak - 1.0).abs() < 0.01, "peak {got} vs {peak}");
    }
}
