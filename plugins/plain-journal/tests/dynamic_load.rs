//! Under a dynamic load the journal moves (Booker's mobility method, `Bearing::advance`) and
//! the film dissipates: a big end's rotating, pulsating load, the rod's eye swinging.

use std::f64::consts::PI;

use tribo_law_plain_journal::bearing::{relative_torque, Bearing, Model};

/// Over two crank revolutions after two to settle: Booker's film power
/// `K dw^2 - F . (c v) >= 0` at every step (the film only dissipates), the power the
/// relative-rotation torque books is positive over the cycle, and it equals the film's own up
/// to the translation work `F . de/dt` a rigid joint cannot book (here below 20%).
#[test]
fn a_dynamically_loaded_big_end_moves_and_dissipates() {
    let b = Bearing {
        radius_m: 0.024,
        length_m: 0.020,
        clearance_m: 20e-6,
        model: Model::Finite,
    };
    let (w_crank, mu, dt) = (400.0, 0.012, 1e-5);
    let mut eps = [0.0, 0.0];
    let (mut booked, mut film, mut travel) = (0.0, 0.0, 0.0f64);
    let steps = (4.0 * PI / w_crank / dt) as usize;
    for k in 0..2 * steps {
        let th = w_crank * k as f64 * dt;
        // The rod's eye (outer, body A) swings at +-0.3 w; the pin (inner, body B) turns.
        let w_rod = 0.3 * w_crank * th.cos();
        let load = 4000.0 + 3000.0 * (2.0 * th).cos();
        let f = [load * (th + 0.3).cos(), load * (th + 0.3).sin()];
        let omega_bar = 0.5 * (w_rod + w_crank);
        let m = b.motion(eps, f, omega_bar, mu);
        let dw = w_crank - w_rod;
        let k_c = b.couette(eps[0].hypot(eps[1]), mu);
        let phi = k_c * dw * dw - b.clearance_m * (f[0] * m.squeeze[0] + f[1] * m.squeeze[1]);
        assert!(phi >= 0.0, "film power {phi} W at step {k}");
        let rel = w_rod - w_crank;
        let t = relative_torque(&b, eps, f, rel, omega_bar, mu);
        if k >= steps {
            booked += -t * rel * dt;
            film += phi * dt;
        }
        let next = b.advance(eps, f, omega_bar, mu, dt);
        travel = travel.max((next[0] - eps[0]).hypot(next[1] - eps[1]));
        eps = next;
        assert!(eps[0].hypot(eps[1]) < 0.995 + 1e-12);
    }
    assert!(travel > 0.0, "the journal moved");
    assert!(booked > 0.0 && film > 0.0, "{booked} {film}");
    assert!(
        (booked - film).abs() < 0.2 * film,
        "booked {booked} J vs film {film} J"
    );
    eprintln!("booked {booked:.4} J, film {film:.4} J over two revolutions");
}
