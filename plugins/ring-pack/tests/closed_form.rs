//! The steady parabolic slider in full film, against formulas derived here independently of the
//! crate's: the face `h(x) = h0 + crown (x/a)^2` with the liner sliding at `u`, the Reynolds
//! equation `h^3 dp/dx = 6 mu u (h - h_c)` (`h_c` the film where `dp/dx = 0`), `p = 0` at the
//! inlet and `p = dp/dx = 0` at the rupture point (Reynolds condition), streamers filling
//! `h_c / h` of the gap beyond it.
//!
//! Derivation (substituting `x = L tan(theta)`, `L = a sqrt(h0 / crown)`, so that
//! `h = h0 sec^2(theta)` and `dx = L sec^2(theta) dtheta`):
//!
//! ```text
//! p(theta)  = P0 int_{th0}^{theta} (sin^2 cos^2 - t_c^2 cos^4) dth,      P0 = 6 mu u L / h0^2, t_c = tan(th_c)
//! rupture:  p(th_c) = 0  =>  Ia(th_c) - Ia(th0) = t_c^2 (Ib(th_c) - Ib(th0))
//!           Ia = th/8 - sin(4 th)/32  (int sin^2 cos^2),   Ib = 3 th/8 + sin(2 th)/4 + sin(4 th)/32  (int cos^4)
//! load:     W = int p dx = -L int (tan th - t_c) dp       (by parts, p = 0 at both ends)
//!             = -L P0 [ sin^4/4 - t_c Ia + t_c^2 cos^4/4 + t_c^3 Ib ]_{th0}^{th_c}
//! friction on the liner (per unit circumference):
//!   Couette   mu u int dx / h          = mu u (L / h0) (th_c - th0)
//!   Poiseuille  int (h/2) dp/dx dx     = (h0 P0 / 2) [ (th/2 - sin(2 th)/4) - t_c^2 (th/2 + sin(2 th)/4) ]_{th0}^{th_c}
//!   streamers mu u h_c int dx / h^2    = mu u (1 + t_c^2) (L / h0) [ th/2 + sin(2 th)/4 ]_{th_c}^{th1}
//! ```
//!
//! with `th0 = -atan(S)`, `th1 = atan(S)`, `S = sqrt(crown / h0)`. A starved face (a layer of oil
//! `h_s` thick on the liner, thinner than the gap at the leading edge) has the same closed form
//! with its inlet moved to where the gap closes to the layer: `th0 = -atan(sqrt(h_s / h0 - 1))`.

use tribo_law_ring_pack::profile::{
    film_for_load, film_for_load_supplied, film_from_inlet, starved_inlet_s, Face,
};
use tribo_law_ring_pack::ring::Ring;
use tribo_plugin_api::tribology::Roughness;

fn ia(t: f64) -> f64 {
    t / 8.0 - (4.0 * t).sin() / 32.0
}
fn ib(t: f64) -> f64 {
    3.0 * t / 8.0 + (2.0 * t).sin() / 4.0 + (4.0 * t).sin() / 32.0
}

/// Bisection on an increasing function to the last bit.
fn bisect(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if m <= lo || m >= hi {
            break;
        }
        if f(m) < 0.0 {
            lo = m;
        } else {
            hi = m;
        }
    }
    0.5 * (lo + hi)
}

/// (load N/m, friction N/m, rupture angle) of the steady slider at film `h0`.
fn slider(a: f64, crown: f64, h0: f64, u: f64, mu: f64) -> (f64, f64, f64) {
    slider_fed(a, crown, h0, u, mu, f64::INFINITY)
}

/// [`slider`] with its film beginning where the gap closes to a layer of oil `supply` thick on
/// the liner (infinite: flooded).
fn slider_fed(a: f64, crown: f64, h0: f64, u: f64, mu: f64, supply: f64) -> (f64, f64, f64) {
    let th1 = (crown / h0).sqrt().atan();
    let th0 = if supply < h0 + crown {
        -(supply / h0 - 1.0).max(0.0).sqrt().atan()
    } else {
        -th1
    };
    slider_from(a, crown, h0, u, mu, th0)
}

/// [`slider`] with its film beginning at angle `th0` (`-atan(S) <= th0 < 0`).
fn slider_from(a: f64, crown: f64, h0: f64, u: f64, mu: f64, th0: f64) -> (f64, f64, f64) {
    let s = (crown / h0).sqrt();
    let l = a / s;
    let th1 = s.atan();
    // p(th_c) as a function of th_c: negative just past the peak, zero at the rupture.
    let rupture = |tc: f64| {
        let t = tc.tan();
        -((ia(tc) - ia(th0)) - t * t * (ib(tc) - ib(th0)))
    };
    // The rupture lies between the apex and the outlet, where this residual changes sign once.
    let thc = bisect(rupture, 1e-12, th1);
    let tc = thc.tan();
    let p0 = 6.0 * mu * u * l / (h0 * h0);
    let big = |t: f64| {
        t.sin().powi(4) / 4.0 - tc * ia(t) + tc * tc * t.cos().powi(4) / 4.0 + tc.powi(3) * ib(t)
    };
    let load = -l * p0 * (big(thc) - big(th0));
    let sin2 = |t: f64| t / 2.0 - (2.0 * t).sin() / 4.0;
    let cos2 = |t: f64| t / 2.0 + (2.0 * t).sin() / 4.0;
    let couette = mu * u * l / h0 * (thc - th0);
    let poiseuille = 0.5 * h0 * p0 * ((sin2(thc) - sin2(th0)) - tc * tc * (cos2(thc) - cos2(th0)));
    let streamers = mu * u * (1.0 + tc * tc) * l / h0 * (cos2(th1) - cos2(thc));
    (load, couette + poiseuille + streamers, thc)
}

/// No asperity contact at the films of these cases (sigma 1 nm).
fn smooth() -> Roughness {
    Roughness {
        sigma_m: 1e-9,
        eta_beta_sigma: 0.04,
        sigma_over_beta: 1e-3,
        modulus_pa: 78e9,
    }
}

fn ring(width: f64, crown: f64) -> Ring {
    Ring {
        face: Face {
            half_width_m: 0.5 * width,
            crown_m: crown,
        },
        tension_n: 0.0,
        gas_fraction: 0.0,
        rails: 1,
    }
}

/// For a given load the law's steady film is the closed form's, and so is its friction, to 1e-6.
#[test]
fn steady_film_and_friction_for_a_given_load_match_the_closed_form() {
    let mu = 0.01;
    for &(width, crown, u, load) in &[
        (0.8e-3, 5e-6, 10.0, 200.0),
        (0.8e-3, 5e-6, 1.0, 600.0),
        (1.2e-3, 10e-6, 15.0, 3000.0),
        (0.3e-3, 2e-6, 5.0, 260.0),
        (0.8e-3, 5e-6, 20.0, 50.0),
    ] {
        let r = ring(width, crown);
        let h = r.steady(&smooth(), u, load, mu, None);
        // The closed form's film for this load: its load falls monotonically with the film.
        let h_ref = bisect(
            |lnh: f64| load - slider(0.5 * width, crown, lnh.exp(), u, mu).0,
            (1e-9f64).ln(),
            (1e-3f64).ln(),
        )
        .exp();
        assert!(
            (h - h_ref).abs() <= 1e-6 * h_ref,
            "width {width} crown {crown} u {u} load {load}: law {h}, closed form {h_ref}"
        );
        let (w_ref, f_ref, thc) = slider(0.5 * width, crown, h_ref, u, mu);
        assert!((w_ref - load).abs() <= 1e-9 * load);
        let c = r.contact(&smooth(), h, u, load, mu, None);
        assert_eq!(c.asperity_n_per_m, 0.0);
        let f = c.film.shear_n_per_m;
        assert!(
            (f - f_ref).abs() <= 1e-6 * f_ref,
            "friction: law {f}, closed form {f_ref}"
        );
        // The rupture point too (m from the apex).
        let x_ref = 0.5 * width * (h_ref / crown).sqrt() * thc.tan();
        assert!(
            (c.film.rupture_m - x_ref).abs() <= 1e-5 * x_ref,
            "rupture {} vs {x_ref}",
            c.film.rupture_m
        );
        // The steady film has no squeeze.
        assert!(c.film.squeeze_m_s.abs() <= 1e-9 * u * crown / width);
    }
}

/// A crown far above the film is a cylinder of radius `R = a^2 / (2 crown)` on a plane, whose
/// fully flooded Reynolds-condition load is the textbook `W = 4.90 eta u_mean R / h0` per unit
/// length (rigid cylinder on a plane with the Reynolds condition, quoted to three figures; one
/// surface moving, `u_mean = u / 2`) with rupture at `x_c = 0.475 sqrt(2 R h0)`: the closed form
/// above reproduces them (2.4475 and 0.47513), checking the derivation itself.
#[test]
fn the_closed_form_tends_to_the_rigid_cylinder_on_a_plane() {
    let (a, crown, h0, u, mu) = (0.4e-3, 5e-6, 1e-10, 10.0, 0.01);
    let (w, _, thc) = slider(a, crown, h0, u, mu);
    let r = a * a / (2.0 * crown);
    let want = 4.90 * mu * 0.5 * u * r / h0;
    assert!((w - want).abs() < 2e-3 * want, "{w} vs {want}");
    assert!((thc.tan() - 0.475).abs() < 1e-3, "{}", thc.tan());
    // The crate's film agrees at this film too.
    let f = film_for_load(
        &Face {
            half_width_m: a,
            crown_m: crown,
        },
        h0,
        u,
        w,
        mu,
    );
    assert!(
        f.squeeze_m_s.abs() < 1e-9 * u * crown / a,
        "{}",
        f.squeeze_m_s
    );
}

/// A film beginning where the gap closes to a layer of oil on the liner: at the closed form's
/// film for a given load, the crate's film from that inlet carries that load without squeeze,
/// with the closed form's friction and rupture point, to 1e-6.
#[test]
fn a_starved_steady_film_matches_the_closed_form_from_its_inlet() {
    let mu = 0.01;
    for &(width, crown, u, load, supply) in &[
        (0.8e-3, 5e-6, 10.0, 200.0, 2e-6),
        (0.8e-3, 5e-6, 1.0, 600.0, 0.5e-6),
        (1.2e-3, 10e-6, 15.0, 3000.0, 3e-6),
        (0.3e-3, 2e-6, 5.0, 260.0, 1e-6),
        (0.8e-3, 5e-6, 20.0, 50.0, 4e-6),
    ] {
        let a = 0.5 * width;
        let face = Face {
            half_width_m: a,
            crown_m: crown,
        };
        let h_ref = bisect(
            |lnh: f64| load - slider_fed(a, crown, lnh.exp(), u, mu, supply).0,
            (1e-10f64).ln(),
            f64::ln(supply),
        )
        .exp();
        let (w_ref, f_ref, thc) = slider_fed(a, crown, h_ref, u, mu, supply);
        assert!((w_ref - load).abs() <= 1e-9 * load, "{w_ref} vs {load}");
        // Starved indeed: the inlet lies inside the face.
        assert!(supply < h_ref + crown, "{supply} floods a film of {h_ref}");
        let s_in = starved_inlet_s(&face, h_ref, Some(supply)).expect("starved");
        let f = film_from_inlet(&face, h_ref, u, load, mu, None, s_in);
        // No squeeze: the squeeze number 2 hdot L / (h u) is rounding, so the law's load at
        // zero squeeze is the closed form's.
        let l = a * (h_ref / crown).sqrt();
        let q = 2.0 * f.squeeze_m_s * l / (h_ref * u);
        assert!(
            q.abs() <= 1e-7,
            "width {width} supply {supply}: squeeze number {q}"
        );
        assert!(
            (f.shear_n_per_m - f_ref).abs() <= 1e-6 * f_ref,
            "friction: law {}, closed form {f_ref}",
            f.shear_n_per_m
        );
        let x_ref = l * thc.tan();
        assert!(
            (f.rupture_m - x_ref).abs() <= 1e-5 * x_ref,
            "rupture {} vs {x_ref}",
            f.rupture_m
        );
        let x_in = -l * (supply / h_ref - 1.0).sqrt();
        assert!(
            (f.inlet_m - x_in).abs() <= 1e-12 * a,
            "inlet {} vs {x_in}",
            f.inlet_m
        );
        // Starving costs film: the flooded face carries the load on a thicker film.
        let h_flooded = bisect(
            |lnh: f64| load - slider(a, crown, lnh.exp(), u, mu).0,
            (1e-10f64).ln(),
            (1e-3f64).ln(),
        )
        .exp();
        assert!(h_ref < h_flooded, "{h_ref} vs flooded {h_flooded}");
    }
}

/// The starved slider takes in the whole layer it meets: in steady sliding (no squeeze) the
/// flux through the film is `|u| h_c / 2` (Couette at the rupture) and must equal the layer's
/// `|u| s`, so the rupture sits where the gap is twice the layer and the inlet where the film
/// carries the load with that rupture. The closed form (the inlet angle found by bisection on
/// `h_c = 2 s`, the film by bisection on the load) against the law's steady film, friction,
/// inlet and rupture, to 1e-6; the law's inflow and the layer it leaves are the layer's, and
/// the film is thinner than the flooded one (less oil) but not by the half the layer a
/// meniscus at the layer's thickness would take in.
#[test]
fn a_starved_steady_slider_takes_in_the_whole_layer_as_the_closed_form_says() {
    let mu = 0.01;
    for &(width, crown, u, load) in &[
        (0.8e-3, 5e-6, 10.0, 200.0),
        (1.2e-3, 5e-6, 15.0, 209.0),
        (1.2e-3, 10e-6, 15.0, 3000.0),
        (0.3e-3, 2e-6, 5.0, 260.0),
    ] {
        let a = 0.5 * width;
        let r = ring(width, crown);
        let h_flooded = bisect(
            |lnh: f64| load - slider(a, crown, lnh.exp(), u, mu).0,
            (1e-10f64).ln(),
            (1e-3f64).ln(),
        )
        .exp();
        let hc_flooded = h_flooded * (1.0 + slider(a, crown, h_flooded, u, mu).2.tan().powi(2));
        for frac in [0.2, 0.35, 0.48] {
            let supply = frac * hc_flooded;
            // The inlet whose rupture is at the gap 2 s, at film h0.
            let inlet = |h0: f64| {
                let th1 = (crown / h0).sqrt().atan();
                bisect(
                    |th0: f64| {
                        let tc = slider_from(a, crown, h0, u, mu, th0).2.tan();
                        2.0 * supply - h0 * (1.0 + tc * tc)
                    },
                    -th1,
                    0.0,
                )
            };
            let h_ref = bisect(
                |lnh: f64| {
                    let h0 = lnh.exp();
                    load - slider_from(a, crown, h0, u, mu, inlet(h0)).0
                },
                (1e-10f64).ln(),
                f64::ln(2.0 * supply),
            )
            .exp();
            let th0 = inlet(h_ref);
            let (w_ref, f_ref, thc) = slider_from(a, crown, h_ref, u, mu, th0);
            assert!((w_ref - load).abs() <= 1e-6 * load, "{w_ref} vs {load}");
            let case = format!("width {width} crown {crown} u {u} load {load} supply {supply}");
            let h = r.steady(&smooth(), u, load, mu, Some(supply));
            assert!(
                (h - h_ref).abs() <= 1e-6 * h_ref,
                "{case}: law {h}, closed form {h_ref}"
            );
            let c = r.contact(&smooth(), h, u, load, mu, Some(supply));
            let f = c.film;
            assert!(
                (f.shear_n_per_m - f_ref).abs() <= 1e-6 * f_ref,
                "{case}: friction {} vs {f_ref}",
                f.shear_n_per_m
            );
            let l = a * (h_ref / crown).sqrt();
            let (x_in, x_c) = (l * th0.tan(), l * thc.tan());
            assert!(
                (f.inlet_m - x_in).abs() <= 1e-5 * a && (f.rupture_m - x_c).abs() <= 1e-5 * a,
                "{case}: inlet {} vs {x_in}, rupture {} vs {x_c}",
                f.inlet_m,
                f.rupture_m
            );
            assert!(
                (f.outlet_film_m - 2.0 * supply).abs() <= 1e-6 * supply
                    && (f.inflow_m2_s - u * supply).abs() <= 1e-6 * u * supply
                    && (f.layer_left_m(u) - supply).abs() <= 1e-6 * supply,
                "{case}: outlet {}, inflow {}, left {}",
                f.outlet_film_m,
                f.inflow_m2_s,
                f.layer_left_m(u)
            );
            let h_meniscus = bisect(
                |lnh: f64| load - slider_fed(a, crown, lnh.exp(), u, mu, supply).0,
                (1e-10f64).ln(),
                f64::ln(supply),
            )
            .exp();
            assert!(
                h_meniscus < h && h < h_flooded,
                "{case}: {h_meniscus} < {h} < {h_flooded}"
            );
        }
    }
}

/// A face whose minimum film is above twice the layer it meets cannot take the layer in (its
/// Couette flux would fill no more than a gap of twice the layer): with the asperities carrying
/// the load it is dry, shears nothing, and the layer passes on whole.
#[test]
fn a_face_above_twice_its_layer_is_dry_and_passes_the_layer_on() {
    for (face, h, u, _, _) in starved_cases() {
        for frac in [0.1, 0.3, 0.49] {
            let supply = frac * h;
            let f = film_for_load_supplied(&face, h, u, 0.0, 0.02, None, Some(supply));
            assert_eq!(f.shear_n_per_m, 0.0, "{face:?} h {h} u {u} supply {supply}");
            assert!(
                (f.layer_left_m(u) - supply).abs() <= 1e-15 * supply,
                "{face:?} h {h} u {u}: left {} of {supply}",
                f.layer_left_m(u)
            );
        }
    }
}

/// The faces and films of the starved checks: steady, approaching, separating, slow and at rest.
fn starved_cases() -> Vec<(Face, f64, f64, f64, f64)> {
    let mut v = Vec::new();
    for (a, crown) in [(0.4e-3, 5e-6), (0.6e-3, 10e-6), (0.15e-3, 2e-6)] {
        let face = Face {
            half_width_m: a,
            crown_m: crown,
        };
        for h in [0.3e-6, 1e-6, 3e-6] {
            for frac in [1.0, 1.05, 1.5, 3.0] {
                for u in [0.0, 0.05, 1.0, 10.0] {
                    for load in [0.0, 20.0, 300.0, 3000.0] {
                        v.push((face, h, u, load, frac * h));
                    }
                }
            }
        }
    }
    v
}

/// Flow continuity at the starved inlet: the oil a face lays on the liner is never more than
/// the layer it ran into brought in (`|u| supply`) plus what the approaching face squeezes out
/// of the gap between its inlet and its outlet (`-hdot (x_out - x_in)` when `hdot < 0`).
#[test]
fn a_starved_face_never_carries_out_more_oil_than_it_had() {
    let mu = 0.02;
    for (face, h, u, load, supply) in starved_cases() {
        let f = film_for_load_supplied(&face, h, u, load, mu, None, Some(supply));
        let out = u * f.layer_left_m(u);
        let squeezed = (-f.squeeze_m_s).max(0.0) * (f.rupture_m - f.inlet_m);
        assert!(
            out <= u * supply + squeezed + 1e-12 * u * supply,
            "{face:?} h {h} u {u} load {load} supply {supply}: out {out}, in {} + {squeezed}",
            u * supply
        );
        // The film's own continuity: what leaves is what came in plus what the squeeze pushed
        // out between inlet and outlet (`dq/dx = -dh/dt`), and it takes in no more than the
        // layer brings.
        let x_out = if f.rupture_m > f.inlet_m {
            f.rupture_m
        } else {
            f.inlet_m
        };
        let pushed = -f.squeeze_m_s * (x_out - f.inlet_m);
        assert!(
            (f.outflow_m2_s - (f.inflow_m2_s + pushed)).abs()
                <= 1e-9 * (f.inflow_m2_s.abs() + pushed.abs() + 1e-18),
            "{face:?} h {h} u {u} load {load} supply {supply}: {f:?}"
        );
        assert!(
            f.inflow_m2_s <= u * supply * (1.0 + 1e-9) + 1e-18,
            "{face:?} h {h} u {u} load {load} supply {supply}: inflow {}",
            f.inflow_m2_s
        );
    }
}

/// The starved film never does negative work on the liner (its shear opposes the sliding) and
/// never sucks (its peak pressure is not negative).
#[test]
fn a_starved_film_dissipates() {
    let mu = 0.02;
    for (face, h, u, load, supply) in starved_cases() {
        let f = film_for_load_supplied(&face, h, u, load, mu, None, Some(supply));
        assert!(
            f.shear_n_per_m >= 0.0 && f.peak_pa >= 0.0 && f.squeeze_m_s.is_finite(),
            "{face:?} h {h} u {u} load {load} supply {supply}: {f:?}"
        );
    }
}

/// The flooded limit: a layer at least as thick as the gap at the leading edge gives the flooded
/// film to the bit, and a layer a hair thinner (the inlet a hair inside the edge) gives it to
/// 1e-6 through the starved formulas (their asymmetric moments tend to the symmetric ones).
#[test]
fn the_flooded_limit_recovers_the_flooded_film() {
    let mu = 0.02;
    for (face, h, u, load, _) in starved_cases() {
        let flooded = film_for_load(&face, h, u, load, mu);
        let edge = h + face.crown_m;
        let same = film_for_load_supplied(&face, h, u, load, mu, None, Some(edge));
        assert_eq!(same, flooded);
        let near = film_for_load_supplied(&face, h, u, load, mu, None, Some(edge * (1.0 - 1e-13)));
        let close = |x: f64, y: f64, scale: f64| (x - y).abs() <= 1e-6 * scale;
        let sq = face.crown_m * u.max(1.0) / face.half_width_m + flooded.squeeze_m_s.abs();
        assert!(
            close(near.squeeze_m_s, flooded.squeeze_m_s, sq)
                && close(
                    near.shear_n_per_m,
                    flooded.shear_n_per_m,
                    flooded.shear_n_per_m.max(0.5 * h * flooded.peak_pa)
                )
                && close(near.peak_pa, flooded.peak_pa, flooded.peak_pa.max(1.0)),
            "{face:?} h {h} u {u} load {load}: {near:?} vs {flooded:?}"
        );
    }
}
