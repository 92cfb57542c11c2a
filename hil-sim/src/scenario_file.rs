//! Scenario files: TOML deserialised into [`Scenario`] (schema: docs/scenario.md).
//!
//! Every key is optional (missing keys take [`Scenario::default`]'s value);
//! unknown keys are errors, so a typo never silently falls back to a default.

use crate::scenario::Scenario;
use std::path::Path;

/// Parses TOML text into a validated [`Scenario`]; `origin` names the source
/// in error messages.
pub fn parse_scenario(text: &str, origin: &str) -> Result<Scenario, String> {
    let scn: Scenario = toml::from_str(text)
        .map_err(|e| format!("scenario file {origin}: {}", e.to_string().trim_end()))?;
    scn.validate()
        .map_err(|e| format!("scenario file {origin}: {e}"))?;
    Ok(scn)
}

/// Reads and parses a scenario file.
pub fn load_scenario(path: &Path) -> Result<Scenario, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read scenario file {}: {e}", path.display()))?;
    parse_scenario(&text, &path.display().to_string())
}

/// The scenario as TOML (what a file with every key spelled out looks like).
pub fn to_toml(scn: &Scenario) -> String {
    toml::to_string(scn).expect("Scenario serialises to TOML")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::TrajectoryKind;

    fn repo_file(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
    }

    #[test]
    fn empty_file_is_the_default_scenario() {
        assert_eq!(parse_scenario("", "t").unwrap(), Scenario::default());
    }

    #[test]
    fn keys_override_defaults() {
        let s = parse_scenario(
            "name = \"q\"\ntrajectory = \"figure8\"\nbeta = 0.05\nsensing = \"odometry\"\nencoder_cpr = 2048\nk_y = 10.0\nwindow_s = [5.0, 20.0]\n",
            "t",
        )
        .unwrap();
        assert_eq!(s.name, "q");
        assert_eq!(s.trajectory, TrajectoryKind::Figure8);
        assert_eq!(s.beta, 0.05);
        assert_eq!(s.encoder_cpr, 2048);
        assert_eq!(s.k_y, Some(10.0));
        assert_eq!(s.window_s, [5.0, 20.0]);
        assert_eq!(s.duration_s, Scenario::default().duration_s);
    }

    #[test]
    fn unknown_keys_bad_types_and_invalid_values_are_errors() {
        let e = parse_scenario("betta = 0.1\n", "x.toml").unwrap_err();
        assert!(e.contains("x.toml") && e.contains("betta"), "{e}");
        let e = parse_scenario("beta = \"high\"\n", "x.toml").unwrap_err();
        assert!(e.contains("beta"), "{e}");
        let e = parse_scenario("trajectory = \"spiral\"\n", "x.toml").unwrap_err();
        assert!(e.contains("spiral"), "{e}");
        let e = parse_scenario("eps = 1.5\n", "x.toml").unwrap_err();
        assert!(e.contains("eps must be"), "{e}");
    }

    #[test]
    fn round_trip_through_toml() {
        let s = Scenario {
            k_y: Some(12.5),
            ..Scenario::paper_case(2, 9, None, None)
        };
        assert_eq!(parse_scenario(&to_toml(&s), "rt").unwrap(), s);
    }

    #[test]
    fn shipped_example_files_parse() {
        let dir = repo_file("scenarios");
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            if p.extension().is_some_and(|e| e == "toml") {
                load_scenario(&p).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
        assert!(n >= 2, "expected example scenarios in {}", dir.display());
    }

    #[test]
    fn every_field_is_documented() {
        let doc = std::fs::read_to_string(repo_file("docs/scenario.md")).unwrap();
        let full = Scenario {
            k_y: Some(1.0),
            eps_end: Some(0.5),
            wheel_torque_scale: [1.0, 0.5],
            governor: false,
            clean_start: false,
            gyro: crate::sensing::GyroOverrides {
                gyro_noise_density: Some(1.0),
                gyro_bias_radps: Some(1.0),
                gyro_bias_walk: Some(1.0),
                gyro_scale_error: Some(1.0),
                gyro_saturation_radps: Some(1.0),
                gyro_rate_hz: Some(1.0),
            },
            pose: crate::sensing::PoseOverrides {
                pose_rate_hz: Some(1.0),
                pose_latency_s: Some(1.0),
                pose_jitter_s: Some(1.0),
                pose_std_m: Some(1.0),
                pose_heading_std_rad: Some(1.0),
                pose_dropout: Some(1.0),
                pose_outage_s: Some(crate::sensing::Window([1.0, 2.0])),
                pose_outlier_fraction: Some(1.0),
                pose_outlier_m: Some(1.0),
            },
            ..Scenario::default()
        };
        let table: toml::Table = toml::from_str(&to_toml(&full)).unwrap();
        for key in table.keys() {
            assert!(
                doc.contains(&format!("`{key}`")),
                "docs/scenario.md lacks `{key}`"
            );
        }
        for p in crate::scenario::Sensing::ALL {
            assert!(
                doc.contains(&format!("`\"{}\"`", p.name())),
                "docs lack sensing preset {}",
                p.name()
            );
        }
        for t in [
            "paper",
            "paper-tangent",
            "paper-printed",
            "circle",
            "figure8",
            "line",
        ] {
            assert!(
                doc.contains(&format!("`\"{t}\"`")),
                "docs lack trajectory {t}"
            );
        }
    }
}
