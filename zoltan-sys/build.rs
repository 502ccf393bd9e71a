//! Generates raw bindings from the system's `zoltan.h`.
//!
//! Defaults fit Debian's `libtrilinos-zoltan-dev`. A cluster's own Trilinos is
//! used by setting:
//! - `ZOLTAN_INCLUDE_DIR`: directory holding `zoltan.h` (default `/usr/include/trilinos`)
//! - `ZOLTAN_LIB_DIR`: directory holding the library (default: the linker's search path)
//! - `ZOLTAN_LIB_NAME`: link name (default `trilinos_zoltan`; a plain Zoltan build is `zoltan`)
//! - `MPI_INCLUDE_DIRS`: `:`-separated MPI include dirs (default: asked of `mpicc`)
//! - `MPICC`: the MPI compiler wrapper to ask (default `mpicc`)

use std::env;
use std::path::PathBuf;
use std::process::Command;

fn main() {
    for var in [
        "ZOLTAN_INCLUDE_DIR",
        "ZOLTAN_LIB_DIR",
        "ZOLTAN_LIB_NAME",
        "MPI_INCLUDE_DIRS",
        "MPICC",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    println!("cargo:rerun-if-changed=wrapper.h");

    let include_dir =
        env::var("ZOLTAN_INCLUDE_DIR").unwrap_or_else(|_| "/usr/include/trilinos".into());
    let header = PathBuf::from(&include_dir).join("zoltan.h");
    if !header.exists() {
        fail(&format!(
            "zoltan.h not found in {include_dir}. Install Debian's libtrilinos-zoltan-dev \
             (scripts/install-deps.sh) or set ZOLTAN_INCLUDE_DIR to your Trilinos include directory."
        ));
    }

    if let Ok(dir) = env::var("ZOLTAN_LIB_DIR") {
        println!("cargo:rustc-link-search=native={dir}");
    }
    let lib_name = env::var("ZOLTAN_LIB_NAME").unwrap_or_else(|_| "trilinos_zoltan".into());
    println!("cargo:rustc-link-lib={lib_name}");
    println!("cargo:include={include_dir}");

    let mut builder = bindgen::Builder::default()
        .header("wrapper.h")
        .clang_arg(format!("-I{include_dir}"))
        // Zoltan's error codes and flags are `#define`s compared against `int`s.
        .default_macro_constant_type(bindgen::MacroTypeVariation::Signed)
        .allowlist_function("Zoltan_.*")
        .allowlist_type("ZOLTAN_.*|Zoltan_.*")
        .allowlist_var("ZOLTAN_.*")
        // MPI types come from mpi-sys so that rsmpi communicators pass straight through.
        .blocklist_type("MPI_.*|ompi_.*|_?MPI_.*")
        .blocklist_function("MPI_.*|PMPI_.*")
        .raw_line("use mpi_sys::*;")
        .derive_default(true)
        .layout_tests(false)
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()));
    for dir in mpi_include_dirs() {
        builder = builder.clang_arg(format!("-I{dir}"));
    }
    let bindings = builder
        .generate()
        .unwrap_or_else(|e| fail(&format!("bindgen failed on {}: {e}", header.display())));
    let out = PathBuf::from(env::var("OUT_DIR").unwrap()).join("bindings.rs");
    bindings
        .write_to_file(&out)
        .unwrap_or_else(|e| fail(&format!("cannot write {}: {e}", out.display())));
}

fn mpi_include_dirs() -> Vec<String> {
    if let Ok(dirs) = env::var("MPI_INCLUDE_DIRS") {
        return dirs
            .split(':')
            .filter(|s| !s.is_empty())
            .map(String::from)
            .collect();
    }
    let mpicc = env::var("MPICC").unwrap_or_else(|_| "mpicc".into());
    // Open MPI answers --showme:incdirs; MPICH and Intel MPI answer -show with -I flags.
    if let Ok(out) = Command::new(&mpicc).arg("--showme:incdirs").output() {
        if out.status.success() {
            return String::from_utf8_lossy(&out.stdout)
                .split_whitespace()
                .map(String::from)
                .collect();
        }
    }
    match Command::new(&mpicc).arg("-show").output() {
        Ok(out) if out.status.success() => String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .filter_map(|t| t.strip_prefix("-I").map(String::from))
            .collect(),
        _ => fail(&format!(
            "cannot ask `{mpicc}` for MPI include directories. Install libopenmpi-dev \
             (scripts/install-deps.sh) or set MPI_INCLUDE_DIRS."
        )),
    }
}

fn fail(msg: &str) -> ! {
    eprintln!("zoltan-sys: {msg}");
    std::process::exit(1);
}
