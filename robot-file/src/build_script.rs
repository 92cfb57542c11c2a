//! For a build script (`build.rs`) that compiles a robot into a firmware
//! image: read the robot file named by `ROBOT_FILE`, validate it and write
//! its binary form for `include_bytes!`.

use crate::binary::MAX_ENCODED_LEN;
use crate::sections::Robot;
use std::path::{Path, PathBuf};
use std::string::String;
use std::{env, fs, println};

/// Name of the binary form written into `OUT_DIR`.
pub const EMBEDDED_ROBOT_FILE_NAME: &str = "robot.bin";

/// Reads the robot file `ROBOT_FILE` (relative to the package being built;
/// `default_path` when unset), validates it, writes its binary form to
/// `$OUT_DIR/robot.bin` and tells cargo to rebuild when either changes.
/// Returns the robot, or a message naming the file, line, field and reason
/// (the build script prints it and fails).
pub fn embed_robot_file(default_path: &Path) -> Result<Robot, String> {
    println!("cargo:rerun-if-env-changed=ROBOT_FILE");
    let path = env::var_os("ROBOT_FILE")
        .map(PathBuf::from)
        .unwrap_or_else(|| default_path.to_path_buf());
    println!("cargo:rerun-if-changed={}", path.display());
    let out = PathBuf::from(env::var_os("OUT_DIR").ok_or("OUT_DIR not set")?);
    embed(&path, &out)
}

/// [`embed_robot_file`] for the robot file `path`, writing into `out_dir`.
pub fn embed(path: &Path, out_dir: &Path) -> Result<Robot, String> {
    let text =
        fs::read_to_string(path).map_err(|e| std::format!("ROBOT_FILE {}: {e}", path.display()))?;
    let robot = Robot::from_toml_str(&text)
        .map_err(|e| std::format!("ROBOT_FILE {}: {e}", path.display()))?;
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let n = robot
        .encode(&mut buf)
        .map_err(|e| std::format!("ROBOT_FILE {}: {e}", path.display()))?;
    // The image decodes what this build checked.
    let back =
        Robot::decode(&buf[..n]).map_err(|e| std::format!("ROBOT_FILE {}: {e}", path.display()))?;
    if back != robot {
        return Err(std::format!(
            "ROBOT_FILE {}: binary form does not round-trip",
            path.display()
        ));
    }
    fs::write(out_dir.join(EMBEDDED_ROBOT_FILE_NAME), &buf[..n])
        .map_err(|e| std::format!("{}: {e}", out_dir.display()))?;
    Ok(robot)
}
