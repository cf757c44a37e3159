//! The cost of the gas-pressure model: the full thesis cycle (prescribed crank, fedem-baseline)
//! on the head-less rig, on the same rig with the head on (motored 4-stroke compression) and
//! with the head on and a vented crankcase (its tables, built once per process, are in place
//! after the warm-up); and the one-time cost of the vented crankcase's periodic cycles at all
//! the speeds the thesis cycle tabulates. Issue 17 allows the pressure model at most 20% more
//! (docs/performance.md).
//!
//! Needs the release plugins: `cargo build --release && cargo bench -p tribo --bench gas`.
// criterion_group! generates an undocumented entry function.
#![allow(missing_docs)]

use std::path::PathBuf;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use tribo::lawset::LawSet;
use tribo::rig::load_rig;

mod common;
use common::registry;

fn bench(c: &mut Criterion) {
    let reg = registry();
    let mut g = c.benchmark_group("gas");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    for rig_name in ["crf250r-motored", "crf250r-compression", "crf250r-vented"] {
        let mut rig = load_rig(&PathBuf::from(rig_name), &[]).expect("bundled rig");
        LawSet::load("fedem-baseline")
            .expect("bundled law set")
            .apply(&mut rig);
        let mut sim = tribo::rig::simulation(&rig, &reg).expect("simulation");
        g.bench_function(format!("full_cycle_{rig_name}"), |b| {
            b.iter(|| sim.run().expect("run"))
        });
        if let Some(gas) = sim.gas().filter(|g| g.depends_on_speed()) {
            // Every table of the cycle computed afresh (not from the process's cache).
            g.bench_function(format!("crankcase_tables_{rig_name}"), |b| {
                b.iter(|| {
                    for w in &gas.tabulated_speeds()[1..] {
                        criterion::black_box(gas.vented_cycle(*w));
                    }
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
