//! Bundles the page (view/web: three.js and the page's modules) into one
//! file with esbuild, so the binary embeds it and nothing is fetched at run time.
//!
//! The pinned packages are installed by `npm ci` into this build's `OUT_DIR`, never into the
//! source tree: two builds at once (cargo and maturin, two profiles) each have their own, and
//! an ordinary build leaves view/web untouched. The test drivers' copy in view/web is
//! installed by scripts/setup.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let web = Path::new(env!("CARGO_MANIFEST_DIR")).join("web");
    for f in ["package.json", "package-lock.json", "index.html", "src"] {
        println!("cargo:rerun-if-changed={}", web.join(f).display());
    }
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let fail = |what: &str| -> ! {
        panic!(
            "ves-view: {what} (for {}); install Node.js and npm (Debian: apt-get install nodejs npm; scripts/setup does)",
            web.display()
        )
    };
    let npm = out.join("npm");
    let read = |p: &Path| std::fs::read(p).ok();
    let lock = read(&web.join("package-lock.json")).unwrap_or_else(|| fail("no package-lock.json"));
    // Installed already from this very lockfile: nothing to do.
    if read(&npm.join("package-lock.json")).as_deref() != Some(&lock[..]) || !npm.join("node_modules").is_dir() {
        let copied = std::fs::create_dir_all(&npm).is_ok()
            && ["package.json", "package-lock.json"]
                .iter()
                .all(|f| std::fs::copy(web.join(f), npm.join(f)).is_ok());
        if !copied {
            fail("cannot copy the package files into OUT_DIR");
        }
        let ok = Command::new("npm")
            .args(["ci", "--no-audit", "--no-fund", "--ignore-scripts", "--prefer-offline"])
            .current_dir(&npm)
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            fail("`npm ci` failed");
        }
    }
    let ok = Command::new(npm.join("node_modules/.bin/esbuild"))
        .args([
            "src/main.js",
            "--bundle",
            "--minify",
            "--format=esm",
            "--target=es2020",
            "--log-level=warning",
        ])
        .arg(format!("--outfile={}", out.join("app.js").display()))
        // The page's imports of three.js resolve to the packages installed above.
        .env("NODE_PATH", npm.join("node_modules"))
        .current_dir(&web)
        .status()
        .is_ok_and(|s| s.success());
    if !ok {
        fail("esbuild could not bundle src/main.js");
    }
}
