//! With feature `view`: bundles the page (runtime/web: three.js and the page's modules) into one
//! file with esbuild, installed from the pinned lockfile by `npm ci`, so the binary embeds it and
//! nothing is fetched at run time.

use std::path::Path;
use std::process::Command;

fn main() {
    if std::env::var_os("CARGO_FEATURE_VIEW").is_none() {
        return;
    }
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("web");
    for f in ["package.json", "package-lock.json", "index.html", "src"] {
        println!("cargo:rerun-if-changed={}", web.join(f).display());
    }
    let out = std::path::PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let fail = |what: &str| -> ! {
        panic!(
            "feature `view`: {what} in {}; install Node.js and npm (Debian: apt-get install nodejs npm; scripts/setup does)",
            web.display()
        )
    };
    let esbuild = web.join("node_modules/.bin/esbuild");
    let lock = web.join("package-lock.json");
    let stale = |p: &Path| match (
        p.metadata().and_then(|m| m.modified()),
        lock.metadata().and_then(|m| m.modified()),
    ) {
        (Ok(a), Ok(b)) => a < b,
        _ => true,
    };
    if !esbuild.is_file() || stale(&web.join("node_modules/.package-lock.json")) {
        let ok = Command::new("npm")
            .args(["ci", "--no-audit", "--no-fund", "--ignore-scripts"])
            .current_dir(&web)
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            fail("`npm ci` failed");
        }
    }
    let ok = Command::new(&esbuild)
        .args([
            "src/main.js",
            "--bundle",
            "--minify",
            "--format=esm",
            "--target=es2020",
            "--log-level=warning",
        ])
        .arg(format!("--outfile={}", out.join("app.js").display()))
        .current_dir(&web)
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        fail("esbuild could not bundle src/main.js");
    }
}
