//! `cargo test` builds this crate with libpython linked (maturin's build does not: it sets
//! `PYO3_BUILD_EXTENSION_MODULE`, so the module resolves Python's symbols from the interpreter
//! that imports it). The rpath lets the unit-test binary find libpython without
//! `LD_LIBRARY_PATH`, e.g. under pyenv.
fn main() {
    pyo3_build_config::add_libpython_rpath_link_args();
}
