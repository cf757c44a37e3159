//! What the benchmarks share: the release build's plugins.

use std::path::PathBuf;

use tribo::plugin_api::loader::{load_paths, LawRegistry};

/// Every law built next to the benchmark (the profile directory's plugins).
pub fn registry() -> LawRegistry {
    let exe = std::env::current_exe().expect("bench executable path");
    let dir: PathBuf = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("profile directory")
        .to_path_buf();
    load_paths(&[dir]).expect("release plugins: run `cargo build --release` first")
}
