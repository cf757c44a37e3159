//! Closed-form references written independently of the solver: the thesis's two-point-rod
//! kinematics and loads (eqs 4.4, 4.8, 4.9) with friction in the force balance, and revolution
//! means by plain quadrature. Coefficients are the thesis's table 9.5 (small end: big end's).

use std::f64::consts::PI;

/// Coulomb law exactly as the `coulomb` plugin documents it: -mu*N*arm*sgn_eps(v_s).
pub fn coulomb(mu: f64, load: f64, arm: f64, v_rel: f64) -> f64 {
    let vs = v_rel * arm;
    let eps = 1e-3; // the law's default v_smooth
    -mu * load * arm * vs / (vs * vs + eps * eps).sqrt()
}

/// Mean friction torque at the crank of each joint (main_a, main_b, big_end, small_end,
/// piston) at constant speed `omega`, for a two-point-mass rod, from the closed-form
/// kinematics (thesis eqs 4.4, 4.8, 4.9) and a force balance of the two point masses and the
/// massless link between them (friction torques at the rod ends included).
pub fn friction(omega: f64, m_c: f64) -> [f64; 5] {
    let (r, l, m_p) = (0.0269, 0.105, 0.27);
    let (m_a, m_b) = (2.0 / 3.0 * m_c, m_c / 3.0);
    let m_rec = m_p + m_b;
    let lam = r / l;
    let (mu_m, mu_b, mu_s, mu_p) = (0.00245, 0.0025, 0.0025, 0.08);
    let (r_m, r_b, r_s) = (0.020, 0.017, 0.008);
    let n = 7200;
    let mut power = [0.0; 5];
    for k in 0..n {
        let th = 2.0 * PI * k as f64 / n as f64;
        let (s, c) = th.sin_cos();
        let root = (1.0 - lam * lam * s * s).sqrt();
        let a = -r
            * omega
            * omega
            * (c + (lam * (2.0 * th).cos() + lam.powi(3) * s.powi(4)) / root.powi(3));
        let v = -r * omega * (s + lam / 2.0 * (2.0 * th).sin() / root);
        // Rod angular velocity, counter-clockwise (the thesis angle of eq 4.8 is its mirror).
        let w_rod = -omega * lam * c / root;
        let u = [lam * s, root]; // from crank pin to piston pin
        let nrm = [-u[1], u[0]];
        let a_pin = [omega * omega * r * s, -omega * omega * r * c]; // centripetal, pin at (-r s, r c)
        let (mut t_be, mut t_se, mut f_f) = (0.0, 0.0, 0.0);
        let mut out = [0.0; 5];
        for _ in 0..50 {
            let p = -(t_be - t_se) / l;
            let s_ax = (f_f - m_rec * a - p * nrm[1]) / u[1];
            let n_x = s_ax * u[0] + p * nrm[0];
            let f_se = [-n_x, m_p * a - f_f];
            let f_be = [f_se[0] + m_a * a_pin[0], f_se[1] + m_a * a_pin[1] + m_b * a];
            let main = (f_be[0].hypot(f_be[1])) / 2.0;
            let t_m = coulomb(mu_m, main, r_m, omega);
            t_be = coulomb(mu_b, f_be[0].hypot(f_be[1]), r_b, w_rod - omega);
            t_se = coulomb(mu_s, f_se[0].hypot(f_se[1]), r_s, -w_rod);
            f_f = coulomb(mu_p, n_x.abs(), 1.0, v);
            out = [
                -t_m * omega,
                -t_m * omega,
                -t_be * (w_rod - omega),
                -t_se * (-w_rod),
                -f_f * v,
            ];
        }
        for j in 0..5 {
            power[j] += out[j] / n as f64;
        }
    }
    power.map(|p| p / omega)
}

fn json_f64(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

/// `K - w^2 M` of the chain `tribo modes --json` printed (motor node fixed when prescribed).
pub fn dynamic_matrix(report: &serde_json::Value, omega: f64) -> Vec<Vec<f64>> {
    let j: Vec<f64> = report["inertias"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| json_f64(&n["inertia_kg_m2"]))
        .collect();
    let k: Vec<f64> = report["springs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| json_f64(&s["stiffness_nm_per_rad"]))
        .collect();
    let n = j.len();
    let mut a = vec![vec![0.0; n]; n];
    for (i, ki) in k.iter().enumerate() {
        a[i][i] += ki;
        a[i + 1][i + 1] += ki;
        a[i][i + 1] -= ki;
        a[i + 1][i] -= ki;
    }
    for (i, ji) in j.iter().enumerate() {
        a[i][i] -= omega * omega * ji;
    }
    // The prescribed motor is a fixed node: drop its row and column.
    a.remove(0);
    for row in &mut a {
        row.remove(0);
    }
    a
}

/// Every mode `tribo modes --json` printed (`report`) solves `(K - w^2 M) v = 0` of the chain
/// it printed, one mode per free node of the prescribed motor's chain.
pub fn assert_modes_solve(report: &serde_json::Value) {
    assert_eq!(report["motor_hold"], "prescribed");
    for s in report["springs"].as_array().unwrap() {
        assert_eq!(s["between"].as_array().unwrap().len(), 2);
    }
    let modes = report["modes"].as_array().unwrap();
    // A prescribed motor holds every node but itself: one mode per free node.
    assert_eq!(
        modes.len(),
        report["inertias"].as_array().unwrap().len() - 1
    );
    for m in modes {
        let omega = std::f64::consts::TAU * json_f64(&m["frequency_hz"]);
        let a = dynamic_matrix(report, omega);
        let shape: Vec<f64> = m["shape"].as_array().unwrap()[1..]
            .iter()
            .map(json_f64)
            .collect();
        // (K - w^2 M) v = 0 for the mode's shape, relative to the terms' size.
        for row in &a {
            let r: f64 = row.iter().zip(&shape).map(|(x, v)| x * v).sum();
            let scale: f64 = row.iter().zip(&shape).map(|(x, v)| (x * v).abs()).sum();
            assert!(
                r.abs() <= 1e-8 * scale,
                "residual {r} of {scale} at {omega} rad/s"
            );
        }
    }
}
