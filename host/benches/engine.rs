//! The cost of the multi-cylinder crank train (issue 18), for the thesis rig as a one-cylinder
//! engine and for an inline-4:
//!
//! - `revolution_*`: one revolution of crank-train evaluations (kinematics, reactions under
//!   friction loads, the acceleration for a torque) at one-degree steps; the single-cylinder
//!   `Mechanism` (the 9x9 structured solve the thesis rig runs on) beside them;
//! - `steady_*`: the whole steady-state run (every plateau of the thesis cycle, one revolution
//!   each at one degree, fedem-baseline on every joint group) of the one-cylinder engine and of
//!   the inline-4 with the same cycle, bodies and joints; the single-cylinder solver's
//!   `run_steady` on the thesis rig beside them.
//!
//! The issue allows a 4-cylinder cycle at most 4.5 times a single cylinder's
//! (docs/performance.md). Needs the release plugins:
//! `cargo build --release && cargo bench -p tribo --bench engine`
// criterion_group! generates an undocumented entry function.
#![allow(missing_docs)]

use std::path::{Path, PathBuf};

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use tribo::engine::{
    geometry, CrankTrain, CylinderLoads, EngineGeometry, RodGeometry, ThrowGeometry,
    TrainKinematics, TrainLoads, TrainReactions,
};
use tribo::mechanics::{JointLoads, Mechanism};
use tribo::rig::load_rig;

/// The thesis rig's crank train described as a one-throw, one-cylinder engine.
mod common;
use common::registry;

fn thesis_as_engine(mech: &Mechanism) -> CrankTrain {
    let g = mech.geometry();
    CrankTrain::new(EngineGeometry {
        crank_radius_m: g.crank_radius_m,
        crank_mass_kg: g.crank_mass_kg,
        crank_inertia_kg_m2: g.crank_inertia_kg_m2,
        drive_inertia_kg_m2: g.drive_inertia_kg_m2,
        gravity_m_s2: g.gravity_m_s2,
        mains_axial_m: vec![0.0, 1.0],
        throws: vec![ThrowGeometry {
            angle_rad: 0.0,
            axial_m: 0.5,
            counterweights: Vec::new(),
        }],
        cylinders: vec![tribo::engine::CylinderGeometry {
            throw: 0,
            bank_rad: 0.0,
            pin_offset_m: 0.0,
            crank_offset_m: 0.0,
            rod: RodGeometry {
                mass_kg: g.rod_mass_kg,
                inertia_kg_m2: g.rod_inertia_kg_m2,
                length_m: g.rod_length_m,
                com_from_big_end_m: g.rod_com_from_big_end_m,
            },
            piston_mass_kg: g.piston_mass_kg,
        }],
    })
    .expect("valid engine")
}

/// One revolution of evaluations: kinematics, two friction rounds of reactions, the
/// acceleration for a torque.
fn revolution(train: &CrankTrain, kin: &mut TrainKinematics, re: &mut TrainReactions) -> f64 {
    let n = train.geometry().cylinders.len();
    let loads = TrainLoads {
        main_torque_nm: -0.05,
        cylinders: vec![
            CylinderLoads {
                big_end_torque_nm: 0.02,
                small_end_torque_nm: 0.0,
                slide_force_n: -3.0,
            };
            n
        ],
    };
    let mut sum = 0.0;
    for i in 0..360 {
        let theta = (i as f64).to_radians();
        train.kinematics_into(theta, 628.0, &[], kin);
        train.reactions_into(kin, 10.0, &TrainLoads::default(), re);
        train.reactions_into(kin, 10.0, &loads, re);
        sum += re.drive_torque_nm + train.alpha_for_torque(kin, 1.0, &loads);
    }
    sum
}

fn bench(c: &mut Criterion) {
    let thesis = load_rig(Path::new("crf250r-motored"), &[]).expect("bundled rig");
    let sim = tribo::rig::simulation(&thesis, &tribo::plugin_api::loader::LawRegistry::new())
        .expect("frictionless thesis rig");
    let mech = sim.mechanism().expect("the single-cylinder rig").clone();
    let one = thesis_as_engine(&mech);
    let fixture =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/engines/inline4.toml");
    let i4 = load_rig(&fixture, &[]).expect("inline-4 fixture");
    let four = CrankTrain::new(geometry(&i4.file).expect("engine")).expect("valid");
    let mut g = c.benchmark_group("engine");
    for (name, train) in [
        ("revolution_1_cylinder", &one),
        ("revolution_4_cylinders", &four),
    ] {
        let (mut kin, mut re) = (TrainKinematics::default(), TrainReactions::default());
        g.bench_function(name, |b| {
            b.iter(|| black_box(revolution(train, &mut kin, &mut re)))
        });
    }
    let loads = JointLoads {
        main_torque_nm: -0.05,
        big_end_torque_nm: 0.02,
        small_end_torque_nm: 0.0,
        slide_force_n: -3.0,
    };
    g.bench_function("revolution_mechanism_9x9", |b| {
        b.iter(|| {
            let mut sum = 0.0;
            for i in 0..360 {
                let k = mech.kinematics((i as f64).to_radians(), 628.0);
                let _ = black_box(k.reactions(10.0, &JointLoads::default()));
                sum += k.reactions(10.0, &loads).drive_torque_nm + k.alpha_for_torque(1.0, &loads);
            }
            black_box(sum)
        })
    });
    // Whole steady-state runs with a law set on every joint group.
    let reg = registry();
    let fedem = tribo::lawset::LawSet::load("fedem-baseline").expect("bundled set");
    let mut thesis_set = thesis.clone();
    fedem.apply(&mut thesis_set);
    let mut single = tribo::rig::simulation(&thesis_set, &reg).expect("thesis simulation");
    g.bench_function("steady_thesis_solver", |b| {
        b.iter(|| single.run_steady().expect("run"))
    });
    for (name, text) in [
        ("steady_engine_1_cylinder", one_cylinder_text()),
        ("steady_engine_4_cylinders", four_cylinder_text()),
    ] {
        let mut rig =
            tribo::rig::load_rig_text(Path::new("bench.toml"), &text, &[]).expect("engine rig");
        fedem.apply(&mut rig);
        let mut sim = tribo::rig::simulation(&rig, &reg).expect("engine simulation");
        g.bench_function(name, |b| b.iter(|| sim.run_steady().expect("run")));
    }
    g.finish();
    // Whole transient cycles (prescribed crank, Simpson's rule): a short cycle, ramp to 3000
    // rpm in 0.2 s and hold 0.3 s, about 11000 steps of 0.5 degree.
    let mut g = c.benchmark_group("engine_cycle");
    g.sample_size(10);
    // The thesis rig's seven per-plateau oil temperatures become one for the one plateau.
    let one_temperature = ["oil.temperature_c=80".to_string()];
    let mut thesis_cycle = tribo::rig::load_rig_text(
        Path::new("bench.toml"),
        &format!(
            "{}\n{SHORT_CYCLE}",
            tribo::bundled::rig("crf250r-motored").expect("bundled")
        ),
        &one_temperature,
    )
    .expect("thesis rig");
    fedem.apply(&mut thesis_cycle);
    let mut single = tribo::rig::simulation(&thesis_cycle, &reg).expect("thesis simulation");
    g.bench_function("cycle_thesis_solver", |b| {
        b.iter(|| single.run().expect("run"))
    });
    for (name, text) in [
        ("cycle_engine_1_cylinder", one_cylinder_text()),
        ("cycle_engine_4_cylinders", four_cylinder_text()),
    ] {
        let mut rig = tribo::rig::load_rig_text(
            Path::new("bench.toml"),
            &format!("{text}\n{SHORT_CYCLE}"),
            &one_temperature,
        )
        .expect("engine rig");
        fedem.apply(&mut rig);
        let mut sim = tribo::rig::simulation(&rig, &reg).expect("engine simulation");
        g.bench_function(name, |b| b.iter(|| sim.run().expect("run")));
    }
    g.finish();
}

/// A short test cycle for the transient benchmarks.
const SHORT_CYCLE: &str = "[cycle]\nsegments = [\n  { kind = \"ramp\", to_rpm = 3000.0, duration_s = 0.2 },\n  { kind = \"hold\", duration_s = 0.3 },\n]\n";

/// The thesis rig's text without its two `[joints.main_*]` tables, plus `engine`.
fn thesis_with(engine: &str) -> String {
    let thesis = tribo::bundled::rig("crf250r-motored").expect("bundled");
    let start = thesis.find("[joints.main_a]").expect("main_a");
    let end = thesis.find("[joints.big_end]").expect("big_end");
    format!("{}{}\n{engine}", &thesis[..start], &thesis[end..])
}

/// The thesis rig as a one-cylinder engine.
fn one_cylinder_text() -> String {
    thesis_with(
        "[engine]\nfiring_order = [1]\n\
         [[engine.mains]]\naxial_position_m = 0.0\nradius_m = 0.020\nlength_m = 0.015\n\
         [[engine.mains]]\naxial_position_m = 0.1\nradius_m = 0.020\nlength_m = 0.015\n\
         [[engine.throws]]\nangle_deg = 0.0\naxial_position_m = 0.05\n\
         [[engine.cylinders]]\nthrow = 1\n[[engine.rods]]\ncylinder = 1\n",
    )
}

/// Four of the thesis rig's cylinders on a flat-plane crank with five mains, firing 1-3-4-2.
fn four_cylinder_text() -> String {
    let mut e = String::from("[engine]\nfiring_order = [1, 3, 4, 2]\n");
    for i in 0..5 {
        e.push_str(&format!(
            "[[engine.mains]]\naxial_position_m = {}\nradius_m = 0.020\nlength_m = 0.015\n",
            0.1 * i as f64
        ));
    }
    for (i, angle) in [0.0, 180.0, 180.0, 0.0].iter().enumerate() {
        e.push_str(&format!(
            "[[engine.throws]]\nangle_deg = {angle}\naxial_position_m = {}\n",
            0.05 + 0.1 * i as f64
        ));
    }
    for k in 1..=4 {
        e.push_str(&format!(
            "[[engine.cylinders]]\nthrow = {k}\n[[engine.rods]]\ncylinder = {k}\n"
        ));
    }
    thesis_with(&e)
}

criterion_group!(benches, bench);
criterion_main!(benches);
