//! Build script: with the cargo feature `mumps`, generates the bindings of
//! MUMPS's C interface (`dmumps_c.h`, from libmumps-headers-dev) and links
//! Debian's MPI build of MUMPS with PT-Scotch ordering. Without the feature
//! it does nothing.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    #[cfg(feature = "mumps")]
    mumps::generate();
}

#[cfg(feature = "mumps")]
mod mumps {
    use std::path::PathBuf;

    /// The header, and the libraries of Debian's `libmumps-ptscotch-dev`.
    const HEADER: &str = "dmumps_c.h";
    const LIBRARIES: [&str; 2] = ["dmumps_ptscotch", "mumps_common_ptscotch"];

    pub fn generate() {
        for library in LIBRARIES {
            println!("cargo:rustc-link-lib={library}");
        }
        let bindings = bindgen::Builder::default()
            .header_contents("mumps.h", &format!("#include <{HEADER}>\n"))
            .allowlist_function("dmumps_c")
            .allowlist_type("DMUMPS_STRUC_C")
            .derive_default(false)
            .layout_tests(false)
            .generate()
            .unwrap_or_else(|e| {
                panic!(
                    "cannot generate the MUMPS bindings from <{HEADER}> ({e}): the feature `mumps` needs the Debian packages libmumps-ptscotch-dev, libmumps-headers-dev, libopenmpi-dev and libclang-dev"
                )
            });
        let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
        bindings
            .write_to_file(out.join("mumps_bindings.rs"))
            .expect("cannot write the MUMPS bindings into OUT_DIR");
    }
}
