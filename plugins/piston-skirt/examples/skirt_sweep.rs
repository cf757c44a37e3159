//! The skirt's steady response over oil temperature, sliding speed and side thrust
//! (docs/laws/piston-skirt.md): the default skirt on the CRF 250 R's 76.8 mm bore, the piston at
//! its quasi-static lateral offset.
//! `cargo run --release -p tribo-law-piston-skirt --example skirt_sweep`

use tribo_law_piston_skirt::PistonSkirt;
use tribo_plugin_api::{create_from_table, JointKind, Law, LawInput};

fn main() {
    let law = match create_from_table::<PistonSkirt>(&toml::Table::new()) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("the default parameters were refused: {e}");
            std::process::exit(1);
        }
    };
    // The bundled CRF 250 R oil (typical 10W-50, Walther two-point) at 40, 80 and 110 C, as
    // `tribo sweep` lists it.
    let oils = [(40.0, 0.09890), (80.0, 0.02485), (110.0, 0.01211)];
    // Mean piston speeds 2 S n: 5.4 m/s at 3000 rpm, 16.1 m/s at 9000 rpm; 0.5 m/s near a dead
    // centre.
    let speeds = [0.5, 5.4, 16.1];
    let thrusts = [100.0, 1000.0, 5000.0];
    println!("| oil C | mu mPa s | U m/s | thrust N | e/c | h_min um | friction N | asperity share | peak MPa |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (t, eta) in oils {
        for u in speeds {
            for y in thrusts {
                let mut i = LawInput::at_rest(JointKind::Prismatic).with_velocity(u);
                i.contact_radius_m = 0.0384;
                i.viscosity_pa_s = eta;
                i.oil_temp_c = t;
                i.normal_load_n = y;
                i.reaction_y_n = y;
                i.load_on_inner_y_n = y;
                let out = law.evaluate(&i, &[0.0; 2]);
                let (_, ecc) = out.eccentricity().unwrap_or((0.0, f64::NAN));
                println!(
                    "| {t:.0} | {:.2} | {u} | {y:.0} | {:.3} | {:.2} | {:.2} | {:.3} | {:.2} |",
                    eta * 1e3,
                    ecc,
                    out.min_film().unwrap_or(f64::NAN) * 1e6,
                    -out.force,
                    out.asperity_share().unwrap_or(f64::NAN),
                    out.peak_pressure().unwrap_or(f64::NAN) * 1e-6,
                );
            }
        }
    }
}
