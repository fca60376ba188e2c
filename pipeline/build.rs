//! Exports ves-arpack's XERBLA from this crate's test binaries (the `ves` binary's crate, cli/,
//! has the same build script), so liblapack calls it instead of its own (which ends the process with exit status 0): see ffi/arpack/src/xerbla.rs.
fn main() {
    println!("cargo:rustc-link-arg=-Wl,--export-dynamic-symbol=xerbla_");
}
