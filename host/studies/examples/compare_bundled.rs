//! The bundled comparison run through the libraries alone, without the `tribo` command: the
//! CRF 250 R rig and the default law sets from `tribo_config`, the law plugins from
//! `tribo_plugin_api`'s loader, the study from `tribo_studies`. Prints one line per law set
//! (rank, in-sample and leave-one-out RMSE) and the model torque beside the measured one.
//!
//! ```text
//! cargo build --release                      # the law plugins, into target/release/
//! cargo run --release -p tribo-studies --example compare_bundled [PLUGIN_DIR_OR_FILE ...]
//! ```
//!
//! Plugins are searched in the paths given, else in the directory above this program's
//! (`target/release/` for `target/release/examples/compare_bundled`), then in
//! `TRIBO_PLUGIN_PATH` and the program's own directory.

use std::path::{Path, PathBuf};

use tribo_config::bundled::{DEFAULT_DATA, DEFAULT_LAWSETS, DEFAULT_RIG};
use tribo_config::lawset::LawSet;
use tribo_config::rig::load_rig;
use tribo_plugin_api::loader::discover;
use tribo_studies::study::{compare, CompareOptions, DataRun};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut plugins: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    if plugins.is_empty() {
        let exe = std::env::current_exe()?;
        if let Some(above) = exe.parent().and_then(Path::parent) {
            plugins.push(above.to_path_buf());
        }
    }
    let registry = discover(&plugins)?;

    let rig = load_rig(Path::new(DEFAULT_RIG), &[])?;
    let sets = DEFAULT_LAWSETS
        .iter()
        .map(|name| LawSet::load(name))
        .collect::<Result<Vec<_>, _>>()?;
    let data = DataRun::read(DEFAULT_DATA)?;
    let options = CompareOptions {
        steady: true,
        ..CompareOptions::default()
    };
    let cmp = compare(&rig, &sets, &data, &registry, &options)?;

    println!("rig {}, data {}, mode {}", cmp.rig, cmp.data_file, cmp.mode);
    println!(
        "{:<18} {:>4} {:>10} {:>10}",
        "law set", "rank", "RMSE N m", "LOO N m"
    );
    for s in &cmp.sets {
        let loo = s
            .scores
            .cv_rmse_nm
            .map_or("-".to_string(), |v| format!("{v:.4}"));
        println!(
            "{:<18} {:>4} {:>10.4} {loo:>10}",
            s.lawset, s.rank, s.rmse_nm
        );
    }
    print!("\n{:>7} {:>10}", "rpm", "measured");
    for s in &cmp.sets {
        print!(" {:>18}", s.lawset);
    }
    println!();
    for (i, row) in cmp.data.iter().enumerate() {
        print!("{:>7.0} {:>10.4}", row.speed_rpm, row.torque_nm);
        for s in &cmp.sets {
            let model = s.errors_nm.get(i).map_or(f64::NAN, |e| row.torque_nm + e);
            print!(" {model:>18.4}");
        }
        println!();
    }
    Ok(())
}
