//! Puts memory.x on the linker search path (cortex-m-rt's link.x includes
//! it) and compiles the robot file `ROBOT_FILE` (default
//! `../robots/paper.toml`) into `OUT_DIR/robot.bin`, as the firmware's
//! build.rs does: the tick benchmark runs the firmware's robot.
use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").unwrap());
    fs::copy("memory.x", out.join("memory.x")).unwrap();
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-changed=build.rs");
    if let Err(e) = robot_file::build_script::embed_robot_file("../robots/paper.toml".as_ref()) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
