//! Per-face diagnosis of the ring pack over one settled revolution of the 4B11 (86 mm bore,
//! 43 mm crank, 143 mm rod, no gas: the headless engine), with the ring data of the bundled
//! `4b11-physical` set: for every face (top, second, upper and lower rail) the minimum film,
//! the wetted width, the oil layer met, the asperity share, and the viscous and asperity
//! friction work over the revolution, stroke by stroke.
//!
//! ```sh
//! cargo run --release -p tribo-law-ring-pack --example pack_faces -- 1000 90 starved
//! ```
//! Arguments: speed (rpm), oil temperature (C), `flooded` or `starved`, and any further
//! `key=value` law parameters (TOML values).

use std::error::Error;
use std::f64::consts::PI;
use tribo_law_ring_pack::RingPack;
use tribo_plugin_api::tribology::WaltherLine;
use tribo_plugin_api::{create_from_table, JointKind, Law, LawInput};

const CRANK_M: f64 = 0.043;
const ROD_M: f64 = 0.143;
const RADIUS_M: f64 = 0.043;

/// Piston travel from top dead centre (m) and velocity (m/s, positive towards the head) at
/// crank angle `th` from TDC, turning at `w` rad/s.
fn slider(th: f64, w: f64) -> (f64, f64) {
    let (s, c) = th.sin_cos();
    let root = (ROD_M * ROD_M - CRANK_M * CRANK_M * s * s).sqrt();
    let travel = CRANK_M + ROD_M - (CRANK_M * c + root);
    (travel, -CRANK_M * w * s * (1.0 + CRANK_M * c / root))
}

#[derive(Default, Clone, Copy)]
struct Tally {
    viscous_j: f64,
    asperity_j: f64,
    h_min: f64,
    h_sum: f64,
    wet_sum: f64,
    supply_sum: f64,
    share_sum: f64,
    n: f64,
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let rpm: f64 = args.first().map_or(Ok(1000.0), |a| a.parse())?;
    let temp_c: f64 = args.get(1).map_or(Ok(90.0), |a| a.parse())?;
    let inlet = args.get(2).cloned().unwrap_or_else(|| "starved".into());
    let mut text = format!(
        "top_tension_n = 9.0\nsecond_tension_n = 8.0\noil_tension_n = 23.0\n\
         top_width_m = 1.2e-3\nsecond_width_m = 1.2e-3\noil_rail_width_m = 0.3e-3\n\
         roughness_m = 0.3e-6\ninlet = \"{inlet}\"\n"
    );
    for extra in args.iter().skip(3) {
        text.push_str(extra);
        text.push('\n');
    }
    let law: RingPack = create_from_table(&text.parse()?)?;
    // The rig's oil: Walther through 65 and 11 cSt, 850 kg/m^3.
    let mu = WaltherLine::through_40_100(65.0, 11.0).kinematic_cst(temp_c) * 1e-6 * 850.0;
    let w = rpm * PI / 30.0;
    let dt = (PI / 180.0) / w;
    let mut state = vec![0.0; law.state_size()];
    let names = ["top", "second", "upper rail", "lower rail"];
    // [stroke][face]: stroke 0 up (v > 0), 1 down.
    let mut tally = [[Tally::default(); 4]; 2];
    for t in tally.iter_mut().flatten() {
        t.h_min = f64::INFINITY;
    }
    let circ = 2.0 * PI * RADIUS_M;
    let bmu = 0.1;
    for step in 0..(10 * 360) {
        let th = step as f64 * PI / 180.0;
        let (travel, v) = slider(th, w);
        let mut i = LawInput::at_rest(JointKind::Prismatic).with_velocity(v);
        i.piston_from_tdc_m = travel;
        i.contact_radius_m = RADIUS_M;
        i.contact_length_m = 0.035;
        i.viscosity_pa_s = mu;
        i.engine_speed_rad_s = w;
        i.dt_s = dt;
        if step >= 9 * 360 {
            let p = law.pack(&i, &state);
            let faces = [p.contacts[0], p.contacts[1], p.contacts[2], p.lower_rail];
            let stroke = usize::from(v < 0.0);
            for (f, c) in faces.iter().enumerate() {
                let t = &mut tally[stroke][f];
                let half = law.rings()[f.min(2)].face.half_width_m;
                t.viscous_j += c.film.shear_n_per_m * circ * v.abs() * dt;
                t.asperity_j += bmu * c.asperity_n_per_m * circ * v.abs() * dt;
                t.h_min = t.h_min.min(c.h_m);
                t.h_sum += c.h_m;
                t.wet_sum += (c.film.rupture_m - c.film.inlet_m) / (2.0 * half);
                t.supply_sum += p.supplies[f].unwrap_or(f64::NAN);
                t.share_sum += c.asperity_n_per_m / c.load_n_per_m;
                t.n += 1.0;
            }
        }
        law.commit(&i, &mut state);
    }
    println!(
        "{rpm} rpm, {temp_c} C (mu {:.2} mPa s), {inlet}: per face and stroke over one revolution",
        mu * 1e3
    );
    println!(
        "stroke face        h_min_um h_mean_um supply_um wetted asp_share viscous_J asperity_J"
    );
    let mut total = (0.0, 0.0);
    for (s, row) in tally.iter().enumerate() {
        for (f, t) in row.iter().enumerate() {
            println!(
                "{:6} {:11} {:8.3} {:9.3} {:9.3} {:6.3} {:9.3} {:9.4} {:10.4}",
                ["up", "down"][s],
                names[f],
                t.h_min * 1e6,
                t.h_sum / t.n * 1e6,
                t.supply_sum / t.n * 1e6,
                t.wet_sum / t.n,
                t.share_sum / t.n,
                t.viscous_j,
                t.asperity_j
            );
            total.0 += t.viscous_j;
            total.1 += t.asperity_j;
        }
    }
    // FMEP of one piston's pack: work per revolution over the swept volume per revolution... per
    // 4-stroke cycle (2 revolutions) the work doubles and so does the divisor: W / V_d.
    let vd = PI * RADIUS_M * RADIUS_M * 2.0 * CRANK_M;
    println!(
        "viscous {:.3} J, asperity {:.3} J per revolution: FMEP {:.2} kPa ({:.2} viscous)",
        total.0,
        total.1,
        2.0 * (total.0 + total.1) / vd / 1e3,
        2.0 * total.0 / vd / 1e3
    );
    Ok(())
}
