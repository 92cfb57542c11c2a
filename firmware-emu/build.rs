//! Puts memory.x (QEMU mps2-an386: 4 MiB code RAM, 4 MiB SRAM) on the
//! linker search path, passes cortex-m-rt's linker script, and compiles
//! the robot file `ROBOT_FILE` (default `../robots/paper.toml`) for the
//! firmware's `config.rs` (`OUT_DIR/robot.bin`), as firmware/build.rs does.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    if let Err(e) = robot_file::build_script::embed_robot_file("../robots/paper.toml".as_ref()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
