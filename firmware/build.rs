//! Puts the workspace's top-level `memory.x` on the link search path,
//! passes the cortex-m-rt and defmt linker scripts, and compiles the robot
//! file `ROBOT_FILE` (default `../robots/paper.toml`) into
//! `OUT_DIR/robot.bin` for `config::DEFAULT_ROBOT_BYTES`: a robot file
//! the validation refuses fails the build, naming the field.

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("manifest dir"));
    let memory_x = manifest.join("..").join("memory.x");
    fs::copy(&memory_x, out.join("memory.x")).expect("copy ../memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");
    if let Err(e) =
        robot_file::build_script::embed_robot_file(&manifest.join("../robots/paper.toml"))
    {
        eprintln!("error: {e}");
        std::process::exit(1);
    }

    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    println!("cargo:rustc-link-arg-bins=--icf=all");
}
