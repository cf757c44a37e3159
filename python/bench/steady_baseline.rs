//! The Rust baseline of `bench/overhead.py`: the work of one `tribo.run(rig, lawset=...,
//! steady=True)` done straight through the libraries (load the rig and the law set, bind the
//! laws, the steady 7-speed run, the result serialised as JSON, which stands for handing it
//! out as the Python call must), repeated. Prints three figures in ms: the median of the whole
//! of it, the median of the same runs without the serialisation (the result left as Rust data,
//! the strictest yardstick), and the mean processor time of the whole per run (this thread's
//! time on a processor, from `/proc/thread-self/schedstat`: unlike the wall clock, it leaves
//! out the time the thread waited for a processor on a busy machine; `NaN` where that file
//! does not exist).
//!
//! ```text
//! cargo run --release -p tribo-python --example steady_baseline -- [REPEATS] [LAWSET]
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use tribo_config::lawset::LawSet;
use tribo_config::rig::{load_rig, simulation};
use tribo_plugin_api::loader::discover;

/// The time this thread has spent on a processor, in ns (the first field of
/// `/proc/thread-self/schedstat`), if the system reports it.
fn cpu_ns() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

/// The median of `times` (sorted in place).
fn median(times: &mut [f64]) -> f64 {
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

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
    let mut whole = Vec::with_capacity(repeats);
    let mut unserialised = Vec::with_capacity(repeats);
    let cpu_start = cpu_ns();
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        let mut rig = load_rig(Path::new("crf250r-motored"), &[])?;
        LawSet::load(&lawset)?.apply(&mut rig);
        let result = simulation(&rig, &registry)?.run_steady()?;
        let ran = t.elapsed();
        let json = serde_json::to_string(&result)?;
        std::hint::black_box(json);
        whole.push(t.elapsed().as_secs_f64() * 1e3);
        unserialised.push(ran.as_secs_f64() * 1e3);
    }
    let cpu_ms = match (cpu_start, cpu_ns()) {
        (Some(a), Some(b)) => (b - a) as f64 * 1e-6 / whole.len() as f64,
        _ => f64::NAN,
    };
    println!(
        "{:.4} {:.4} {:.4}",
        median(&mut whole),
        median(&mut unserialised),
        cpu_ms
    );
    Ok(())
}
