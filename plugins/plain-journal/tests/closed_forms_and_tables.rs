//! The journal bearing's film against closed forms and published tables: Ocvirk's short
//! bearing (load, attitude angle, friction to 1e-6), Raimondi and Boyd's finite bearing at
//! L/D = 1 and 1/2 (eccentricity ratio, minimum film, friction variable within 3%).

use std::f64::consts::PI;

use tribo_law_plain_journal::bearing::{torques, Bearing, Model};

const R: f64 = 0.025;
const C: f64 = 25e-6;
const MU: f64 = 0.01;

fn bearing(l_over_d: f64, model: Model) -> Bearing {
    Bearing {
        radius_m: R,
        length_m: l_over_d * 2.0 * R,
        clearance_m: C,
        model,
    }
}

/// The journal turning at `omega` in a fixed bearing, steadily loaded by `w` (downwards): its
/// eccentricity ratio, attitude angle and friction torque on the journal.
fn steady(b: &Bearing, w: f64, omega: f64) -> (f64, f64, f64) {
    let (eps, attitude) = b.steady(w, 0.5 * omega, MU);
    // Load downwards; the journal sits at the attitude angle from the load line, turned in the
    // direction of rotation.
    let theta = -0.5 * PI + attitude;
    let e = [eps * theta.cos(), eps * theta.sin()];
    // The film pushes the journal up.
    let t = torques(b, e, [0.0, w], omega, 0.0, MU);
    // The journal is at rest there under Booker's mobility: the squeeze velocity cancels the
    // whirl (exactly for the closed-form short bearing; the finite bearing's steady row and
    // its mobility table are separate interpolations of one solver, consistent to 1%).
    let m = b.motion(e, [0.0, w], 0.5 * omega, MU);
    let rate = m.eps_rate[0].hypot(m.eps_rate[1]);
    let tol = if b.model == Model::Short { 1e-6 } else { 1e-2 };
    assert!(
        rate <= tol * 0.5 * omega * eps.max(1e-3),
        "not at rest: {rate} at eps {eps}"
    );
    (eps, attitude, -t.inner_nm)
}

/// Ocvirk's short bearing, the textbook closed forms (e.g. Hamrock, Fundamentals of Fluid
/// Film Lubrication, short-bearing theory):
/// `W = mu U L^3 / (4 c^2) eps / (1 - eps^2)^2 sqrt(pi^2 (1 - eps^2) + 16 eps^2)`,
/// `tan(phi) = pi sqrt(1 - eps^2) / (4 eps)`, and the journal's friction torque
/// `T = 2 pi mu R^3 L omega / (c sqrt(1 - eps^2)) + e W sin(phi) / 2`.
#[test]
fn ocvirk_load_attitude_and_friction_to_1e_minus_6() {
    for l_over_d in [0.25, 0.5, 1.0] {
        let b = bearing(l_over_d, Model::Short);
        let l = b.length_m;
        for eps in [0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.95, 0.98] {
            let omega = 300.0;
            let u = omega * R;
            let s = 1.0 - eps * eps;
            let w = MU * u * l.powi(3) / (4.0 * C * C) * eps / (s * s)
                * (PI * PI * s + 16.0 * eps * eps).sqrt();
            let phi = (PI * s.sqrt() / (4.0 * eps)).atan();
            let torque = 2.0 * PI * MU * R.powi(3) * l * omega / (C * s.sqrt())
                + 0.5 * eps * C * w * phi.sin();
            let (e, att, t) = steady(&b, w, omega);
            assert!(
                (e - eps).abs() <= 1e-6 * eps,
                "L/D {l_over_d} eps {eps}: {e}"
            );
            assert!(
                (att - phi).abs() <= 1e-6 * phi,
                "L/D {l_over_d} eps {eps}: attitude {att} vs {phi}"
            );
            assert!(
                (t - torque).abs() <= 1e-6 * torque,
                "L/D {l_over_d} eps {eps}: torque {t} vs {torque}"
            );
        }
    }
}

/// Raimondi and Boyd, "A solution for the finite journal bearing and its application to
/// analysis and design", ASLE Transactions 1(1), 1958 (full 360-degree bearing, Reynolds
/// boundary condition), as tabulated in Shigley's Mechanical Engineering Design (dimensionless
/// performance parameters for full journal bearings): Sommerfeld number
/// `S = (R/c)^2 mu N / P` (N rev/s, P = W / (2 R L)), eccentricity ratio, minimum film
/// `h0/c`, friction variable `(R/c) f`.
/// One row: Sommerfeld number, eccentricity ratio, friction variable.
type Row = (f64, f64, f64);

const RAIMONDI_BOYD: [(f64, [Row; 6]); 2] = [
    (
        1.0,
        [
            (1.33, 0.1, 26.4),
            (0.631, 0.2, 12.8),
            (0.264, 0.4, 5.79),
            (0.121, 0.6, 3.22),
            (0.0446, 0.8, 1.70),
            (0.0188, 0.9, 1.05),
        ],
    ),
    (
        0.5,
        [
            (4.31, 0.1, 85.6),
            (2.03, 0.2, 40.9),
            (0.779, 0.4, 17.0),
            (0.319, 0.6, 8.10),
            (0.0923, 0.8, 3.26),
            (0.0313, 0.9, 1.60),
        ],
    ),
];

#[test]
fn raimondi_boyd_eccentricity_film_and_friction_within_3_percent() {
    let mut worst: f64 = 0.0;
    for (l_over_d, rows) in RAIMONDI_BOYD {
        let b = bearing(l_over_d, Model::Finite);
        let omega = 2.0 * PI * 50.0; // N = 50 rev/s
        for (s, eps_rb, friction_rb) in rows {
            let p = (R / C).powi(2) * MU * 50.0 / s;
            let w = p * 2.0 * R * b.length_m;
            let (eps, _, t) = steady(&b, w, omega);
            let friction = t / (C * w); // (R/c) f with f = T / (W R)
            let film = 1.0 - eps;
            for (what, got, want) in [
                ("eccentricity ratio", eps, eps_rb),
                ("minimum film h0/c", film, 1.0 - eps_rb),
                ("friction variable", friction, friction_rb),
            ] {
                let rel = (got - want).abs() / want;
                worst = worst.max(rel);
                assert!(
                    rel <= 0.03,
                    "L/D {l_over_d}, S {s}: {what} {got:.4} vs Raimondi-Boyd {want} ({:.1}%)",
                    100.0 * rel
                );
            }
        }
    }
    eprintln!(
        "largest deviation from Raimondi and Boyd: {:.2}%",
        100.0 * worst
    );
}

/// At zero load the journal stays centred and the torque is Petroff's.
#[test]
fn petroff_at_zero_load() {
    let b = bearing(0.4, Model::Finite);
    let (eps, _) = b.steady(0.0, 200.0, MU);
    assert_eq!(eps, 0.0);
    let t = torques(&b, [0.0, 0.0], [0.0, 0.0], 400.0, 0.0, MU);
    let petroff = 2.0 * PI * MU * R.powi(3) * b.length_m * 400.0 / C;
    assert!((t.inner_nm + petroff).abs() <= 1e-12 * petroff);
    assert!((t.outer_nm - petroff).abs() <= 1e-12 * petroff);
}
