//! `wmr upload FILE.toml`: a reference file into requests.
//!
//! The schema follows the simulator's scenario files (docs/scenario.md)
//! where it applies: `trajectory` names the same shapes, so
//! `wmr upload scenarios/example.toml` loads the reference that
//! `hil-sim run --scenario scenarios/example.toml` tracks. Keys that
//! describe the simulated world (perturbations, sensing, ...) do not apply
//! to a robot and are reported as ignored. Two keys are the robot's own:
//!
//! ```toml
//! trajectory = "paper"          # paper | circle | figure8 | line
//! start_pose = [0.0, 0.0, 0.0]  # optional: move the shape to start here [m, m, rad]
//! speed_scale = 0.25            # optional: follow r(s·t), default 1
//! ```
//!
//! or timed waypoints (instead of `trajectory`):
//!
//! ```toml
//! [[waypoints]]
//! t_s = 0.0
//! pose = [0.0, 0.0, 0.0]   # [m, m, rad]
//! v_mps = 0.0
//! omega_radps = 0.0
//! ```

use wmr_protocol::{named_shape, BuiltinReference, PoseMsg, Request, Waypoint, SEGMENT_POINTS};

/// What a file asks the robot to drive.
#[derive(Clone, Debug, PartialEq)]
pub enum Upload {
    /// A built-in reference.
    Builtin(BuiltinReference),
    /// Timed waypoints.
    Waypoints(Vec<Waypoint>),
}

/// Scenario keys that describe the simulated world, not the reference:
/// the flat keys of version-1 scenario files and the `version` key and part
/// tables of version 2 (docs/scenario.md).
const SIMULATOR_KEYS: [&str; 26] = [
    "version",
    "plant",
    "perturbations",
    "controller",
    "governor",
    "name",
    "duration_s",
    "control_period_s",
    "substeps",
    "window_s",
    "initial_pose",
    "beta",
    "eps",
    "skid_scale",
    "disturbance_nm",
    "mass_scale",
    "inertia_scale",
    "torque_limit_nm",
    "sensing",
    "encoder_cpr",
    "speed_window_ticks",
    "pwm_levels",
    "pose_noise_m",
    "heading_noise_rad",
    "seed",
    "k_y",
];

fn f32_of(v: &toml::Value, what: &str) -> Result<f32, String> {
    match v {
        toml::Value::Float(f) => Ok(*f as f32),
        toml::Value::Integer(i) => Ok(*i as f32),
        _ => Err(format!("{what} must be a number")),
    }
}

fn pose_of(v: &toml::Value, what: &str) -> Result<PoseMsg, String> {
    let a = v
        .as_array()
        .filter(|a| a.len() == 3)
        .ok_or_else(|| format!("{what} must be [x, y, theta]"))?;
    Ok(PoseMsg {
        x_m: f32_of(&a[0], what)?,
        y_m: f32_of(&a[1], what)?,
        theta_rad: f32_of(&a[2], what)?,
    })
}

/// Parses a reference file; returns the upload and the ignored keys.
pub fn parse_upload(text: &str, origin: &str) -> Result<(Upload, Vec<String>), String> {
    let table: toml::Table =
        toml::from_str(text).map_err(|e| format!("{origin}: {}", e.to_string().trim_end()))?;
    let err = |e: String| format!("{origin}: {e}");
    let mut ignored = Vec::new();
    for k in table.keys() {
        match k.as_str() {
            "trajectory" | "start_pose" | "speed_scale" | "waypoints" => {}
            k if SIMULATOR_KEYS.contains(&k) => ignored.push(k.to_string()),
            k => return Err(err(format!("unknown key `{k}`"))),
        }
    }
    match (table.get("trajectory"), table.get("waypoints")) {
        (Some(_), Some(_)) => Err(err("give `trajectory` or `waypoints`, not both".into())),
        (None, None) => Err(err("no `trajectory` and no `waypoints`".into())),
        (Some(t), None) => {
            let name = t
                .as_str()
                .ok_or_else(|| err("trajectory must be a string".into()))?;
            let shape = named_shape(name).ok_or_else(|| {
                err(format!(
                    "trajectory \"{name}\" is not available on the robot (paper, circle, figure8, line)"
                ))
            })?;
            let start = table
                .get("start_pose")
                .map(|v| pose_of(v, "start_pose"))
                .transpose()
                .map_err(err)?;
            let speed_scale = table
                .get("speed_scale")
                .map(|v| f32_of(v, "speed_scale"))
                .transpose()
                .map_err(err)?
                .unwrap_or(1.0);
            Ok((
                Upload::Builtin(BuiltinReference {
                    shape,
                    start,
                    speed_scale,
                }),
                ignored,
            ))
        }
        (None, Some(w)) => {
            if table.contains_key("start_pose") || table.contains_key("speed_scale") {
                return Err(err(
                    "start_pose and speed_scale apply to `trajectory` only".into()
                ));
            }
            let arr = w
                .as_array()
                .ok_or_else(|| err("waypoints must be an array of tables".into()))?;
            let mut pts = Vec::with_capacity(arr.len());
            for (i, v) in arr.iter().enumerate() {
                let t = v
                    .as_table()
                    .ok_or_else(|| err(format!("waypoint {i} is not a table")))?;
                let get = |k: &str| {
                    t.get(k)
                        .ok_or_else(|| err(format!("waypoint {i} lacks `{k}`")))
                };
                for k in t.keys() {
                    if !["t_s", "pose", "v_mps", "omega_radps"].contains(&k.as_str()) {
                        return Err(err(format!("waypoint {i}: unknown key `{k}`")));
                    }
                }
                pts.push(Waypoint {
                    t_s: f32_of(get("t_s")?, "t_s").map_err(err)?,
                    pose: pose_of(get("pose")?, "pose").map_err(err)?,
                    v_mps: f32_of(get("v_mps")?, "v_mps").map_err(err)?,
                    omega_radps: f32_of(get("omega_radps")?, "omega_radps").map_err(err)?,
                });
            }
            if pts.len() < 2 {
                return Err(err("at least two waypoints".into()));
            }
            if pts.windows(2).any(|w| w[1].t_s <= w[0].t_s) {
                return Err(err("waypoint times must increase".into()));
            }
            Ok((Upload::Waypoints(pts), ignored))
        }
    }
}

/// The segments of a waypoint upload, in order (first index, request).
pub fn segments(points: &[Waypoint]) -> Vec<Request> {
    points
        .chunks(SEGMENT_POINTS)
        .enumerate()
        .map(|(k, c)| Request::TrajectorySegment {
            first_index: (k * SEGMENT_POINTS) as u32,
            points: c.iter().copied().collect(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenario_files_upload_their_trajectory() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenarios/example.toml"
        ))
        .unwrap();
        let (u, ignored) = parse_upload(&text, "example.toml").unwrap();
        assert_eq!(
            u,
            Upload::Builtin(BuiltinReference {
                shape: named_shape("paper").unwrap(),
                start: None,
                speed_scale: 1.0
            })
        );
        assert!(ignored.contains(&"perturbations".to_string()));
        let (_, ignored) = parse_upload("beta = 0.1\ntrajectory = \"line\"\n", "v1.toml").unwrap();
        assert!(ignored.contains(&"beta".to_string()));
    }

    #[test]
    fn the_example_square_parses() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../trajectories/square.toml"
        ))
        .unwrap();
        let (u, ignored) = parse_upload(&text, "square.toml").unwrap();
        let Upload::Waypoints(p) = u else { panic!() };
        assert!(ignored.is_empty());
        assert_eq!(p.len(), 45);
        assert_eq!(p.last().unwrap().pose.x_m, 0.0);
        assert_eq!(segments(&p).len(), 6);
    }

    #[test]
    fn waypoints_and_errors() {
        let text = "[[waypoints]]\nt_s = 0\npose = [0, 0, 0]\nv_mps = 0\nomega_radps = 0\n\
                    [[waypoints]]\nt_s = 2.0\npose = [1.0, 0, 0]\nv_mps = 0.0\nomega_radps = 0\n";
        let (u, _) = parse_upload(text, "w").unwrap();
        let Upload::Waypoints(p) = u else { panic!() };
        assert_eq!(p.len(), 2);
        assert_eq!(segments(&p).len(), 1);
        let e = parse_upload("trajectory = \"paper-tangent\"\n", "x.toml").unwrap_err();
        assert!(e.contains("not available"), "{e}");
        let e = parse_upload("trajectory = \"circle\"\nbetta = 1\n", "x.toml").unwrap_err();
        assert!(e.contains("betta"), "{e}");
        let e = parse_upload(&text.replace("t_s = 2.0", "t_s = 0.0"), "x.toml").unwrap_err();
        assert!(e.contains("increase"), "{e}");
    }
}
