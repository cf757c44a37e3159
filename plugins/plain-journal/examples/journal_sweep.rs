//! The steady sweep of docs/laws/plain-journal.md: a 4B11 main bearing (50 x 20 mm, 20 um
//! radial clearance) steadily loaded, over oil temperature (the rig's 5W-30), speed and load:
//! eccentricity ratio, minimum film, friction torque and peak pressure.
//!
//! `cargo run --release -p tribo-law-plain-journal --example journal_sweep`

use std::f64::consts::PI;

use tribo_law_plain_journal::bearing::{torques, Bearing, Model};
use tribo_plugin_api::tribology::WaltherLine;

/// Dynamic viscosity of the 4B11 rig's oil (Walther through 65 cSt at 40 C and 11 cSt at
/// 100 C, 850 kg/m^3), Pa s.
fn viscosity(t_c: f64) -> f64 {
    WaltherLine::through_40_100(65.0, 11.0).kinematic_cst(t_c) * 1e-6 * 850.0
}

fn main() {
    let b = Bearing {
        radius_m: 0.025,
        length_m: 0.020,
        clearance_m: 20e-6,
        model: Model::Finite,
    };
    println!("| oil C | mu mPa s | rpm | load N | eps | h_min um | torque N m | Petroff N m | peak MPa |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for t in [40.0, 90.0, 110.0] {
        let mu = viscosity(t);
        for rpm in [1000.0, 3000.0, 7000.0] {
            let omega = rpm * PI / 30.0;
            for w in [1000.0, 5000.0, 20000.0] {
                let (eps, att) = b.steady(w, 0.5 * omega, mu);
                let th = -0.5 * PI + att;
                let e = [eps * th.cos(), eps * th.sin()];
                let q = torques(&b, e, [0.0, w], omega, 0.0, mu);
                let petroff = 2.0 * PI * mu * 0.025f64.powi(3) * 0.020 * omega / 20e-6;
                let m = b.motion(e, [0.0, w], 0.5 * omega, mu);
                println!(
                    "| {t} | {:.2} | {rpm} | {w} | {eps:.3} | {:.2} | {:.4} | {petroff:.4} | {:.2} |",
                    mu * 1e3,
                    20.0 * (1.0 - eps),
                    -q.inner_nm,
                    m.peak_pressure_pa * 1e-6
                );
            }
        }
    }
}
