//! The thermal sweep of docs/laws/plain-journal.md: a 4B11 main bearing (50 x 20 mm, 20 um
//! radial clearance, the rig's 5W-30) steadily loaded at its steady position, the film's
//! effective temperature from the heat balance (`thermal = "effective"`) against the isothermal
//! film at the sump's temperature, over oil temperature, speed and load.
//!
//! `cargo run --release -p tribo-law-plain-journal --example thermal_sweep`

use std::f64::consts::PI;

use tribo_law_plain_journal::thermal::{walther_slope, Oil};
use tribo_law_plain_journal::PlainJournal;
use tribo_plugin_api::{create_from_table, JointKind, Law, LawInput};

/// Dynamic viscosity of the 4B11 rig's oil (Walther through 65 cSt at 40 C and 11 cSt at
/// 100 C, 850 kg/m^3), Pa s: the law's own Walther line, started at 40 C.
fn viscosity(t_c: f64) -> f64 {
    let oil = Oil {
        walther_b: walther_slope(65.0, 11.0),
        density_kg_m3: 850.0,
        specific_heat_j_kg_k: 2150.0,
    };
    oil.viscosity_at(65e-6 * 850.0, 40.0, t_c)
}

fn law(thermal: &str) -> PlainJournal {
    let text = format!(
        "clearance_m = 2e-5\nthermal = \"{thermal}\"\noil_kv40_cst = 65.0\noil_kv100_cst = 11.0\ndensity_kg_m3 = 850.0"
    );
    create_from_table::<PlainJournal>(&text.parse().expect("toml")).expect("law")
}

fn main() {
    let (iso, eff) = (law("isothermal"), law("effective"));
    println!("| oil C | rpm | load N | T_eff C | rise K | mu_eff mPa s | torque N m (effective) | torque N m (isothermal) | ratio |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for t in [40.0, 90.0, 110.0] {
        for rpm in [1000.0, 3000.0, 7000.0] {
            let omega = rpm * PI / 30.0;
            for w in [1000.0, 5000.0, 20000.0] {
                let mut i = LawInput::at_rest(JointKind::Revolute).with_velocity(omega);
                i.contact_radius_m = 0.025;
                i.contact_length_m = 0.020;
                i.oil_temp_c = t;
                i.viscosity_pa_s = viscosity(t);
                i.normal_load_n = w;
                i.reaction_y_n = w;
                i.load_on_inner_y_n = w;
                let state = [0.0; 3];
                let f = eff.film_temperature(&i, &state).expect("effective film");
                let (te, ti) = (
                    -eff.evaluate(&i, &state).force,
                    -iso.evaluate(&i, &state).force,
                );
                println!(
                    "| {t} | {rpm} | {w} | {:.1} | {:.1} | {:.2} | {te:.4} | {ti:.4} | {:.2} |",
                    f.effective_c,
                    f.rise_k,
                    f.viscosity_pa_s * 1e3,
                    te / ti
                );
            }
        }
    }
}
