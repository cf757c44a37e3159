//! The cost of the multi-cylinder crank train (issue 18): one revolution of crank-train
//! evaluations (kinematics, reactions under friction loads, the acceleration for a torque) at
//! one-degree steps, for the thesis rig as a one-cylinder engine and for the inline-4 fixture.
//! The issue allows a 4-cylinder cycle at most 4.5 times a single cylinder's
//! (docs/performance.md); the single-cylinder `Mechanism` (the 9x9 structured solve the thesis
//! rig runs on) is timed beside them for reference.
//!
//! `cargo bench -p tribo --bench engine`
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
    let mech = sim.mechanism().clone();
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
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
