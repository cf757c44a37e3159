//! The physical law set of the 4B11 (issue 25): a steady run of `inline4-4b11` with
//! `4b11-physical` (plain journal bearings with their eccentricity as state on the five mains
//! and four big ends, the placeholder piston law) at the rig's seven plateau speeds, 1000-7000
//! rpm. Issue 25 asks for it under 2 s on the project's 2-core machine (docs/performance.md).
//! Needs the release plugins: `cargo build --release && cargo bench -p tribo --bench physical`
// criterion_group! generates an undocumented entry function.
#![allow(missing_docs)]

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};

mod common;
use common::registry;

fn bench(c: &mut Criterion) {
    let reg = registry();
    let mut rig = tribo::rig::load_rig(Path::new("inline4-4b11"), &[]).expect("bundled rig");
    tribo::lawset::LawSet::load("4b11-physical")
        .expect("bundled set")
        .apply(&mut rig);
    let mut sim = tribo::rig::simulation(&rig, &reg).expect("engine simulation");
    let mut g = c.benchmark_group("physical");
    g.sample_size(10);
    g.bench_function("steady_4b11_physical_7_speeds", |b| {
        b.iter(|| sim.run_steady().expect("run"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
