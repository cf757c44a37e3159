//! Compile `c/c_coulomb.c` into a shared library with the system C compiler and place it in the
//! profile output directory, so a plain `cargo build` makes the C law available to `tribo`.

use std::env;
use std::path::{Path, PathBuf};

fn main() {
    let manifest =
        PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let source = manifest.join("c/c_coulomb.c");
    let include = manifest.join("../../plugin-api/include");
    println!("cargo:rerun-if-changed={}", source.display());
    println!(
        "cargo:rerun-if-changed={}",
        include.join("tribo_law.h").display()
    );

    let target_os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    let (prefix, suffix, shared_flag) = match target_os.as_str() {
        "macos" => ("lib", ".dylib", "-dynamiclib"),
        "windows" => {
            println!("cargo:warning=the C example law is not built on Windows by this script; build c/c_coulomb.c into tribo_law_c_coulomb.dll by hand");
            return;
        }
        _ => ("lib", ".so", "-shared"),
    };

    // OUT_DIR is <target>/<profile>/build/<package>-<hash>/out; the profile directory, where
    // cargo puts the tribo binary, is three levels up. Cargo has no stable way to name it.
    let out_dir = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let profile_dir: &Path = out_dir
        .ancestors()
        .nth(3)
        .expect("OUT_DIR has the documented depth");
    let output = profile_dir.join(format!("{prefix}tribo_law_c_coulomb{suffix}"));

    let compiler = cc::Build::new().get_compiler();
    let status = compiler
        .to_command()
        .args([
            shared_flag,
            "-fPIC",
            "-O2",
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-Werror",
        ])
        .arg("-I")
        .arg(&include)
        .arg(&source)
        .arg("-o")
        .arg(&output)
        .arg("-lm")
        .status()
        .expect("the C compiler could not be started; install gcc or clang, or set CC");
    assert!(status.success(), "compiling {} failed", source.display());
    // For the crate's unit test, which loads the library and runs the conformance checks.
    println!("cargo:rustc-env=TRIBO_C_COULOMB_LIB={}", output.display());
}
