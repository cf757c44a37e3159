//! Carrier crate for the C example law. The law itself is `c/c_coulomb.c`; `build.rs` compiles
//! it with the system C compiler into `libtribo_law_c_coulomb.so` in the build profile's output
//! directory (`target/release`, `target/debug`), where `tribo laws` finds it beside the
//! executable. There is no Rust code: the law is a plain C shared library.
