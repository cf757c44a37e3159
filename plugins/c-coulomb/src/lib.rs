//! Carrier crate for the C example law. The law itself is `c/c_coulomb.c`; `build.rs` compiles
//! it with the system C compiler into `libtribo_law_c_coulomb.so` in the build profile's output
//! directory (`target/release`, `target/debug`), where `tribo laws` finds it beside the
//! executable. There is no Rust code: the law is a plain C shared library.

#[cfg(test)]
mod tests {
    use std::path::Path;

    use tribo_plugin_api::conformance::assert_conforms;
    use tribo_plugin_api::loader::LawLibrary;

    /// The compiled C law passes the checks of `tribo check-law` through the C ABI, with its
    /// defaults and with the piston coefficient of the bundled tests.
    #[test]
    fn conforms() {
        // build.rs names the library it compiled; it compiles none on Windows.
        let Some(path) = option_env!("TRIBO_C_COULOMB_LIB") else {
            return;
        };
        let lib = LawLibrary::load(Path::new(path)).expect("the compiled C law loads");
        assert_conforms(&lib, &toml::Table::new());
        assert_conforms(&lib, &"mu = 0.08\nc_viscous = 0.5".parse().expect("TOML"));
    }
}
