//! Puts the workspace's top-level `memory.x` on the link search path,
//! passes the cortex-m-rt and defmt linker scripts, and compiles the robot
//! file `ROBOT_FILE` (default `../robots/paper.toml`) into
//! `OUT_DIR/robot.bin` for `config::DEFAULT_ROBOT_BYTES`: a robot file
//! the validation refuses fails the build, naming the field.
//! `BRIDGE_MODE=pwm-dir|two-pwm|pwm-in1-in2` replaces that robot's
//! `bridge.mode` (the compiled-in robot only: a robot stored in flash keeps
//! its own); anything else fails the build.

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
    let robot =
        match robot_file::build_script::embed_robot_file(&manifest.join("../robots/paper.toml")) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("error: {e}");
                std::process::exit(1);
            }
        };
    println!("cargo:rerun-if-env-changed=BRIDGE_MODE");
    if let Some(mode) = env::var_os("BRIDGE_MODE") {
        if let Err(e) = with_bridge_mode(robot, &mode.to_string_lossy(), &out) {
            eprintln!("error: BRIDGE_MODE: {e}");
            std::process::exit(1);
        }
    }

    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    println!("cargo:rustc-link-arg-bins=--icf=all");
}

/// Rewrites `OUT_DIR/robot.bin` with `robot`'s bridge mode set to `mode`,
/// validated and round-tripped as `embed_robot_file` does.
fn with_bridge_mode(
    mut robot: robot_file::Robot,
    mode: &str,
    out: &std::path::Path,
) -> Result<(), String> {
    use controller_core::runtime::BridgeMode;
    robot.bridge.mode = match mode {
        "pwm-dir" => BridgeMode::PwmDir,
        "two-pwm" => BridgeMode::TwoPwm,
        "pwm-in1-in2" => BridgeMode::PwmIn1In2,
        m => return Err(format!("{m:?}: expected pwm-dir, two-pwm or pwm-in1-in2")),
    };
    let mut buf = [0u8; robot_file::MAX_ENCODED_LEN];
    let n = robot.encode(&mut buf).map_err(|e| format!("{e}"))?;
    if robot_file::Robot::decode(&buf[..n]).map_err(|e| format!("{e}"))? != robot {
        return Err("the binary form does not round-trip".into());
    }
    let path = out.join(robot_file::build_script::EMBEDDED_ROBOT_FILE_NAME);
    fs::write(&path, &buf[..n]).map_err(|e| format!("{}: {e}", path.display()))
}
