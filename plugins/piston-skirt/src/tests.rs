//! Unit tests of the skirt law: closed forms written here, the squeeze approach, dissipation,
//! the conformance checks and the trends.

use super::*;
use tribo_plugin_api::conformance::{assert_law_conforms, assert_law_conforms_with};
use tribo_plugin_api::create_from_table;

fn law(text: &str) -> PistonSkirt {
    create_from_table::<PistonSkirt>(&text.parse().expect("toml")).expect("valid parameters")
}

/// The CRF 250 R piston slide: half the 76.8 mm bore, sliding at `v` under side thrust `y`.
fn slide(v: f64, y: f64, eta: f64, dt: f64) -> LawInput {
    let mut i = LawInput::at_rest(JointKind::Prismatic).with_velocity(v);
    i.contact_radius_m = 0.0384;
    i.contact_length_m = 0.030;
    i.viscosity_pa_s = eta;
    i.normal_load_n = y.abs();
    i.reaction_y_n = y;
    i.load_on_inner_y_n = y;
    i.dt_s = dt;
    i
}

#[test]
fn conforms() {
    assert_law_conforms::<PistonSkirt>();
    assert_law_conforms_with::<PistonSkirt>("clearance_m = 1e-5\ncrown_m = 0.0\nsigma_m = 1.5e-6");
    assert_law_conforms_with::<PistonSkirt>(
        "clearance_m = 5e-5\ncrown_m = 3e-5\nskirt_height_m = 0.03",
    );
}

// ---- closed forms, written out here (not through the crate's reduction formula) ----

/// `[integral ds/q, ds/q^2, ds/q^3]` from -1 to s, q = 1 + k s^2, expanded by hand.
fn closed_integrals(k: f64, s: f64) -> [f64; 3] {
    let r = k.sqrt();
    let f = |s: f64| {
        let q = 1.0 + k * s * s;
        let a = (r * s).atan() / r;
        [
            a,
            s / (2.0 * q) + a / 2.0,
            s / (4.0 * q * q) + 3.0 * s / (8.0 * q) + 3.0 * a / 8.0,
        ]
    };
    let (hi, lo) = (f(s), f(-1.0));
    [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]]
}

/// The rupture point by plain bisection of `I_2 - (1 + k s^2) I_3 = 0`.
fn closed_rupture(k: f64) -> f64 {
    let g = |s: f64| {
        let i = closed_integrals(k, s);
        i[1] - (1.0 + k * s * s) * i[2]
    };
    let (mut a, mut b) = (0.0, 1.0);
    for _ in 0..200 {
        let m = 0.5 * (a + b);
        if g(m) > 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// Load and friction per unit width of the barrel pad in steady sliding, from the closed forms:
/// `w = -(L/2)^2 (6 eta U / h0^2) [ -1/(2k q) + m/(4k q^2) ]_{-1}^{s_c}` and
/// `f = (eta U L / 2 h0) [4 I_1 - 3 m I_2]_{-1}^{s_c} + (eta U L / 2 h0) m I_2 |_{s_c}^{1}`.
fn closed_sliding(h0: f64, crown: f64, l: f64, eta: f64, u: f64) -> (f64, f64) {
    let k = crown / h0;
    let sc = closed_rupture(k);
    let m = 1.0 + k * sc * sc;
    let anti = |s: f64| {
        let q = 1.0 + k * s * s;
        -1.0 / (2.0 * k * q) + m / (4.0 * k * q * q)
    };
    let w = -(l / 2.0).powi(2) * 6.0 * eta * u / (h0 * h0) * (anti(sc) - anti(-1.0));
    let full = closed_integrals(k, sc);
    let whole = closed_integrals(k, 1.0);
    let f =
        eta * u * l / (2.0 * h0) * (4.0 * full[0] - 3.0 * m * full[1] + m * (whole[1] - full[1]));
    (w, f)
}

/// The pad's sliding load and friction against the closed forms to 1e-6, over crowns from a
/// nearly flat to a strongly barrelled skirt.
#[test]
fn sliding_film_load_and_friction_match_the_closed_forms() {
    for (h0, crown) in [
        (20e-6, 1e-6),
        (10e-6, 10e-6),
        (5e-6, 15e-6),
        (2e-6, 30e-6),
        (1e-6, 100e-6),
    ] {
        let pad = Pad {
            height_m: 0.022,
            crown_m: crown,
            width_m: 1.0,
        };
        let got = pad.sliding(h0, 0.012, 7.5);
        let (w, f) = closed_sliding(h0, crown, 0.022, 0.012, 7.5);
        assert!(
            (got.load_n - w).abs() <= 1e-6 * w,
            "h0 {h0} crown {crown}: load {} vs {w}",
            got.load_n
        );
        assert!(
            (got.friction_n - f).abs() <= 1e-6 * f,
            "h0 {h0} crown {crown}: friction {} vs {f}",
            got.friction_n
        );
    }
}

/// Under a steady side thrust at a steady speed the committed offset settles where the two
/// films' closed-form loads balance the thrust (to 1e-6 of it), and the law's friction is the
/// two films' closed-form shear.
#[test]
fn steady_thrust_settles_where_the_closed_form_films_balance_it() {
    // Roughness small enough that no asperity touches: the films alone carry the thrust.
    let l = law("sigma_m = 1e-8");
    let (eta, u, y) = (0.012, 7.5, 400.0);
    let input = slide(u, y, eta, 1e-4);
    let mut s = [0.0; STATE];
    for _ in 0..2000 {
        l.commit(&input, &mut s);
    }
    let e = s[0];
    let (cl, crown, height) = (25e-6, 15e-6, 0.022);
    let width = 80f64.to_radians() * 0.0384;
    let (w_minus, f_minus) = closed_sliding(cl + e, crown, height, eta, u);
    let (w_plus, f_plus) = closed_sliding(cl - e, crown, height, eta, u);
    let balance = (w_minus - w_plus) * width;
    assert!(
        (balance - y).abs() <= 1e-6 * y,
        "films carry {balance} N of {y} N (e = {e})"
    );
    // Thrust towards +y: the piston sits towards -y.
    assert!(e < 0.0);
    let out = l.evaluate(&input, &s);
    let friction = (f_minus + f_plus) * width;
    assert!(
        (out.force + friction).abs() <= 1e-6 * friction,
        "{} vs {friction}",
        out.force
    );
    let h = out.min_film().expect("film");
    assert!((h - (cl + e)).abs() < 1e-18);
    assert_eq!(out.asperity_share(), Some(0.0));
    // Before the first commit the law places the piston at the same quasi-static offset.
    let first = l.evaluate(&input, &[0.0; STATE]);
    assert!((first.force - out.force).abs() <= 1e-9 * friction);
}

/// A flat pad squeezed at rest under a constant load: `1/h^2 = 1/h_i^2 + 2 W t / (eta B L^3)`
/// (the infinitely wide parallel squeeze film). The damping is that closed form's to 1e-12;
/// the committed film follows it within the implicit Euler step's error.
#[test]
fn squeeze_film_approach_follows_the_closed_form() {
    let (eta, w, height) = (0.02, 300.0, 0.022);
    let width = 80f64.to_radians() * 0.0384;
    let pad = Pad {
        height_m: height,
        crown_m: 0.0,
        width_m: width,
    };
    let h: f64 = 7e-6;
    let closed = eta * width * height.powi(3) / h.powi(3);
    assert!((pad.squeeze_damping(h, eta) - closed).abs() <= 1e-12 * closed);

    let l = law("crown_m = 0.0\nsigma_m = 1e-8\nclearance_m = 2.5e-5");
    let dt = 1e-6;
    let input = slide(0.0, w, eta, dt);
    let mut s = [0.0, 1.0]; // centred, placed
    let hi: f64 = 25e-6;
    for n in 1..=20_000 {
        l.commit(&input, &mut s);
        if n % 5000 == 0 {
            let t = n as f64 * dt;
            let exact = (1.0 / (hi * hi) + 2.0 * w * t / (eta * width * height.powi(3))).powf(-0.5);
            let film = 25e-6 + s[0];
            assert!(
                (film - exact).abs() <= 2e-3 * exact,
                "t {t}: {film} vs {exact}"
            );
        }
    }
}

/// Dissipation: over a cycle of a slider-crank-like speed and a side thrust changing side
/// twice per revolution, the force opposes the sliding at every step, the film stays inside the
/// clearance and the diagnostics make sense.
#[test]
fn a_cycle_of_changing_thrust_dissipates_and_keeps_the_film() {
    for text in ["", "clearance_m = 1e-5\nsigma_m = 1.5e-6\ncrown_m = 5e-6"] {
        let l = law(text);
        let mut s = [0.0; STATE];
        let omega = 942.0; // 9000 rpm
        let dt = 2e-6;
        let mut crossed = (false, false);
        for n in 0..((4.0 * std::f64::consts::PI / omega / dt) as usize) {
            let th = omega * n as f64 * dt;
            let v = 0.0269 * omega * (th.sin() + 0.13 * (2.0 * th).sin());
            let y = 2000.0 * (2.0 * th).sin();
            let input = slide(v, y, 0.01, dt);
            let out = l.evaluate(&input, &s);
            assert!(
                out.force * v <= 1e-12,
                "{text}: power {} at {th}",
                out.force * v
            );
            let h = out.min_film().expect("film");
            assert!(h > 0.0 && h <= 2.0 * l.p.clearance_m);
            let share = out.asperity_share().expect("share");
            assert!((0.0..=1.0).contains(&share));
            l.commit(&input, &mut s);
            crossed.0 |= s[0] > 0.01 * l.p.clearance_m;
            crossed.1 |= s[0] < -0.01 * l.p.clearance_m;
        }
        // The piston moves across the bore as the thrust changes side (a few per cent of the
        // clearance on the stiff films of the second set, a fifth of it on the first).
        assert!(crossed.0 && crossed.1, "{text}: {crossed:?}");
    }
}

/// A thin film touches: a rough skirt under a heavy thrust at low speed carries part of the
/// load on its asperities and reports the mixed or boundary regime, with boundary friction.
#[test]
fn heavy_load_at_low_speed_brings_asperity_contact() {
    let l = law("sigma_m = 1.5e-6");
    let input = slide(0.2, 3000.0, 0.008, 0.0);
    let out = l.evaluate(&input, &[0.0; STATE]);
    let share = out.asperity_share().expect("share");
    assert!(share > 0.05, "share {share}");
    assert_ne!(out.regime(), Some(Regime::Hydrodynamic));
    assert!(out.force < 0.0);
    // The same at mid-stroke speed floats on the film.
    let fast = l.evaluate(&slide(8.0, 300.0, 0.02, 0.0), &[0.0; STATE]);
    assert_eq!(fast.asperity_share(), Some(0.0));
}

/// The trends, each with its reason (docs/laws/piston-skirt.md): more load thins the film;
/// faster sliding thickens it; thinner oil thins it and lowers the full-film friction.
#[test]
fn film_and_friction_trends() {
    let l = law("");
    let at = |v: f64, y: f64, eta: f64| l.evaluate(&slide(v, y, eta, 0.0), &[0.0; STATE]);
    let film = |o: LawOutput| o.min_film().expect("film");
    assert!(film(at(5.0, 1000.0, 0.02)) < film(at(5.0, 200.0, 0.02)));
    assert!(film(at(10.0, 1000.0, 0.02)) > film(at(5.0, 1000.0, 0.02)));
    assert!(film(at(5.0, 1000.0, 0.007)) < film(at(5.0, 1000.0, 0.02)));
    assert!(at(5.0, 1000.0, 0.007).force.abs() < at(5.0, 1000.0, 0.02).force.abs());
}

#[test]
fn out_of_range_values_are_refused() {
    for bad in [
        "clearance_m = 0.0",
        "mu_b = -0.1",
        "crown_m = -1e-6",
        "wetted_arc_rad = 4.0",
    ] {
        let table: toml::Table = bad.parse().expect("toml");
        assert!(create_from_table::<PistonSkirt>(&table).is_err(), "{bad}");
    }
}
