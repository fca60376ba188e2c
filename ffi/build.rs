fn main() {
    println!("cargo:rustc-link-lib=gmsh");
    println!("cargo:rustc-link-lib=arpack");
    // LAPACK itself: XERBLA's test calls it directly (ARPACK needs it anyway).
    println!("cargo:rustc-link-lib=lapack");
    // Our XERBLA must win over liblapack's (which exits the process): export it from every
    // executable of this package (see src/xerbla.rs); pipeline/build.rs does the same.
    println!("cargo:rustc-link-arg=-Wl,--export-dynamic-symbol=xerbla_");
    println!("cargo:rerun-if-env-changed=CARGO_FEATURE_SLEPC");
    if std::env::var_os("CARGO_FEATURE_SLEPC").is_some() {
        // Library directories from pkg-config (Debian also links them into the default path).
        match std::process::Command::new("pkg-config")
            .args(["--libs-only-L", "slepc"])
            .output()
        {
            Ok(o) if o.status.success() => {
                for dir in String::from_utf8_lossy(&o.stdout).split_whitespace() {
                    if let Some(d) = dir.strip_prefix("-L") {
                        println!("cargo:rustc-link-search=native={d}");
                    }
                }
            }
            _ => println!(
                "cargo:warning=pkg-config does not know slepc: install libslepc-real-dev (Debian) for the slepc feature"
            ),
        }
    }
}
