fn main() {
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
