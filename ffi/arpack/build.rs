fn main() {
    println!("cargo:rustc-link-lib=arpack");
    // LAPACK itself: XERBLA's test calls it directly (ARPACK needs it anyway).
    println!("cargo:rustc-link-lib=lapack");
    // Our XERBLA must win over liblapack's (which exits the process): export it from every
    // executable of this package (see src/xerbla.rs); pipeline/build.rs does the same.
    println!("cargo:rustc-link-arg=-Wl,--export-dynamic-symbol=xerbla_");
}
