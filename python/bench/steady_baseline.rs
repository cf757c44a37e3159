//! The Rust baseline of `bench/overhead.py`: the work of one `tribo.run(rig, lawset=...,
//! steady=True)` done straight through the libraries (load the rig and the law set, bind the
//! laws, the steady 7-speed run, the result as JSON), repeated; prints the median in ms.
//!
//! ```text
//! cargo run --release -p tribo-python --example steady_baseline -- [REPEATS] [LAWSET]
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use tribo_config::lawset::LawSet;
use tribo_config::rig::{load_rig, simulation};
use tribo_plugin_api::loader::discover;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let repeats: usize = args.next().map_or(Ok(50), |a| a.parse())?;
    let lawset = args.next().unwrap_or_else(|| "stribeck-duty".into());
    // The plugins of this checkout: target/release, two levels above target/release/examples/.
    let exe = std::env::current_exe()?;
    let plugins: Vec<PathBuf> = exe
        .parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .into_iter()
        .collect();
    let registry = discover(&plugins)?;
    let mut times = Vec::with_capacity(repeats);
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let mut rig = load_rig(Path::new("crf250r-motored"), &[])?;
        LawSet::load(&lawset)?.apply(&mut rig);
        let result = simulation(&rig, &registry)?.run_steady()?;
        let json = serde_json::to_string(&result)?;
        std::hint::black_box(json);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    println!("{:.4}", times[times.len() / 2]);
    Ok(())
}
