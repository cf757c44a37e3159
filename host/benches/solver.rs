//! Solver benchmarks: one evaluation of the rig (mechanics + friction iteration + laws), the
//! full thesis cycle (both drives), the steady-state comparison, the mass sweep and a fit.
//!
//! Needs the release plugins: `cargo build --release && cargo bench -p tribo --bench solver`.
// criterion_group! generates an undocumented entry function.
#![allow(missing_docs)]

use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use tribo::lawset::LawSet;
use tribo::mechanics::JointLoads;
use tribo::rig::{load_rig, LawRef, Rig};
use tribo::study::{compare, mass_response, CompareOptions, DataRun, ScaledBody};

mod common;
use common::registry;

fn rig_with(set: &str, sets: &[&str]) -> Rig {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let mut rig = load_rig(&PathBuf::from("crf250r-motored"), &sets).expect("bundled rig");
    LawSet::load(set).expect("bundled law set").apply(&mut rig);
    rig
}

fn bench(c: &mut Criterion) {
    let reg = registry();
    let mut g = c.benchmark_group("solver");

    let rig = rig_with("fedem-baseline", &[]);
    let sim = tribo::rig::simulation(&rig, &reg).expect("sim");
    let mech = sim.mechanism().expect("the single-cylinder rig").clone();
    g.bench_function("kinematics_one_configuration", |b| {
        b.iter(|| black_box(mech.kinematics(black_box(1.234), black_box(628.3))))
    });
    g.bench_function("mechanics_solve_with_loads", |b| {
        let loads = JointLoads {
            main_torque_nm: -0.1,
            big_end_torque_nm: 0.05,
            small_end_torque_nm: 0.0,
            slide_force_n: 12.0,
        };
        b.iter(|| black_box(mech.solve(black_box(1.234), black_box(628.3), 0.0, &loads)))
    });

    g.sample_size(10).measurement_time(Duration::from_secs(20));
    // The PI cycle also with the integral step-size controller it had before the PI one, so
    // the two are measured in the same session (docs/performance.md).
    for (name, drive) in [
        ("thesis_cycle_prescribed", "drive={kind=\"prescribed\"}"),
        ("thesis_cycle_pi", "drive={kind=\"pi\"}"),
        (
            "thesis_cycle_pi_integral_control",
            "solver.step_control=\"integral\"",
        ),
    ] {
        // A dynamic-plugin law on every joint: fedem-baseline leaves the small end free (the
        // thesis did not model it); it gets the big end's coefficient [T table 9.5].
        let sets: &[&str] = if name.ends_with("integral_control") {
            &["drive={kind=\"pi\"}", drive]
        } else {
            &[drive]
        };
        let mut rig = rig_with("fedem-baseline", sets);
        let mut params = toml::Table::new();
        params.insert("mu".into(), toml::Value::Float(0.0025));
        rig.file.joints.small_end.laws.push(LawRef {
            law: "fedem-friction".into(),
            params,
        });
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut sim = tribo::rig::simulation(&rig, &reg).expect("sim");
                black_box(sim.run().expect("run"))
            })
        });
    }

    let base = load_rig(&PathBuf::from("crf250r-motored"), &[]).expect("rig");
    let sets = vec![
        LawSet::load("fedem-baseline").expect("set"),
        LawSet::load("stribeck-duty").expect("set"),
    ];
    let data = DataRun::read("crf250r-measured.csv").expect("data");
    // Scoring only, as the benchmark always measured: the sets at their file's values.
    let steady_no_cv = CompareOptions {
        steady: true,
        no_cv: true,
        no_fit: true,
        ..CompareOptions::default()
    };
    g.bench_function("compare_steady_two_lawsets_seven_speeds", |b| {
        b.iter(|| black_box(compare(&base, &sets, &data, &reg, &steady_no_cv).expect("compare")))
    });
    let scales: Vec<f64> = (0..13).map(|i| 0.5 + 0.05 * i as f64).collect();
    g.bench_function("mass_sweep_steady_13_scales_two_lawsets", |b| {
        b.iter(|| {
            black_box(
                mass_response(&base, &sets, ScaledBody::Rod, &scales, &reg, true, None)
                    .expect("sweep"),
            )
        })
    });
    let fixture = |name: &str, text: &str| {
        let set = LawSet::from_text(std::path::Path::new(name), text).expect("law set");
        let free = set.free_params(&reg, None).expect("free");
        (set, free)
    };
    let no_cv = tribo::fit::FitOptions {
        cross_validate: false,
        ..Default::default()
    };
    g.sample_size(10).measurement_time(Duration::from_secs(120));
    for (label, name, text) in [
        (
            "fit_six_parameters_from_start_values",
            "stribeck-duty-6p-start.toml",
            include_str!("../../tests/fixtures/lawsets/stribeck-duty-6p-start.toml"),
        ),
        (
            "fit_three_bounded_parameters_from_start_values",
            "stribeck-duty-start.toml",
            include_str!("../../tests/fixtures/lawsets/stribeck-duty-start.toml"),
        ),
    ] {
        let (start, free) = fixture(name, text);
        g.bench_function(label, |b| {
            b.iter(|| {
                black_box(
                    tribo::fit::fit(
                        &base,
                        &start,
                        &free,
                        std::slice::from_ref(&data),
                        &reg,
                        &no_cv,
                    )
                    .expect("fit"),
                )
            })
        });
    }
    // Leave-one-out scoring of the six-parameter calibration on seven points: seven refits,
    // each warm-started from the set's values (the cost `compare` pays for an out-of-sample
    // verdict on such a set).
    let (six, free) = fixture(
        "stribeck-duty-6p-2026-11-21.toml",
        include_str!("../../tests/fixtures/lawsets/stribeck-duty-6p-2026-11-21.toml"),
    );
    let model = tribo::fit::TorqueModel::new(&base, &six, &free, vec![data.clone()], &reg);
    let x: Vec<f64> = free.iter().map(|f| f.value).collect();
    let residuals: Vec<f64> = model
        .torques(&x)
        .expect("runs")
        .iter()
        .zip(&data.rows)
        .map(|(m, d)| m - d.torque_nm)
        .collect();
    g.bench_function("leave_one_out_six_parameters_seven_points", |b| {
        b.iter(|| black_box(tribo::score::scores_for_fit(&model, &x, &residuals, true)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
