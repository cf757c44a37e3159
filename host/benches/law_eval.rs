//! One law evaluation through each path: a direct in-process call (static dispatch), the
//! in-process handle, the Rust plugin (abi_stable), and the C plugin (libloading). The same
//! Coulomb + viscous physics on every path, so the difference is the calling cost.
//!
//! Needs the release plugins: `cargo build --release && cargo bench -p tribo --bench law_eval`.
// criterion_group! generates an undocumented entry function.
#![allow(missing_docs)]

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use tribo::plugin_api::loader::{plugin_file_name, LawLibrary};
use tribo::plugin_api::{JointKind, Law, LawInput};
use tribo_law_coulomb::Coulomb;

fn plugin(lib: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("bench executable path");
    // target/<profile>/deps/law_eval-<hash> -> target/<profile>
    let dir = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("profile directory");
    let path = dir.join(plugin_file_name(lib));
    assert!(
        path.is_file(),
        "{} missing: run `cargo build --release` first",
        path.display()
    );
    path
}

fn bench(c: &mut Criterion) {
    let params: toml::Table = "mu = 0.0025\nc_viscous = 1e-4".parse().expect("toml");
    let mut input = LawInput::at_rest(JointKind::Revolute);
    input.normal_load_n = 4500.0;
    input.contact_radius_m = 0.017;
    let input = input.with_velocity(628.3);

    let direct = tribo::plugin_api::create_from_table::<Coulomb>(&params).expect("direct law");
    let handle = LawLibrary::in_process::<Coulomb>()
        .expect("describe")
        .create(&params)
        .expect("in-process instance");
    let rust_lib = LawLibrary::load(&plugin("tribo_law_coulomb")).expect("rust plugin");
    let rust = rust_lib.create(&params).expect("rust instance");
    let c_lib = LawLibrary::load(&plugin("tribo_law_c_coulomb")).expect("C plugin");
    let c_law = c_lib.create(&params).expect("C instance");

    let mut g = c.benchmark_group("law_eval");
    g.bench_function("direct", |b| {
        b.iter(|| black_box(direct.evaluate(black_box(&input), &[])))
    });
    g.bench_function("in_process_handle", |b| {
        b.iter(|| black_box(handle.evaluate(black_box(&input), &[])))
    });
    g.bench_function("rust_plugin", |b| {
        b.iter(|| black_box(rust.evaluate(black_box(&input), &[])))
    });
    g.bench_function("c_plugin", |b| {
        b.iter(|| black_box(c_law.evaluate(black_box(&input), &[])))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
