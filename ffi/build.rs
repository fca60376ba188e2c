fn main() {
    println!("cargo:rustc-link-lib=gmsh");
    println!("cargo:rustc-link-lib=arpack");
}
