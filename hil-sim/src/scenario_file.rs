//! Scenario files: TOML deserialised into [`Scenario`] (schema: book/src/reference/scenario-file.md).
//!
//! Version 2 (`version = 2`) has the run's keys at the top and one table per
//! part (`[plant]`, `[perturbations]`, `[sensing]`, `[controller]`,
//! `[governor]`). A file without `version` is version 1, the flat schema of
//! before (every key top-level): it is upgraded on load, each key moved into
//! the table of the part that declares it ([`upgrade_v1`]; book/src/explanation/decisions.md D65).
//! Every key is optional (missing keys take [`Scenario::default`]'s value);
//! unknown keys are errors, so a typo never silently falls back to a default.

use crate::scenario::{Scenario, SCENARIO_VERSION};
use serde::Deserialize;
use std::path::Path;

/// Version-1 keys whose version-2 name differs: (v1 key, part, v2 key).
/// Every other v1 key keeps its name and moves into the part that declares
/// it (found from the schema itself, [`v1_key_table`]).
const V1_RENAMED: [(&str, &str, &str); 2] = [
    ("sensing", "sensing", "preset"),
    ("governor", "governor", "enabled"),
];

/// Where a version-1 (flat) key lives in version 2: `(None, key)` for the
/// run's own keys, `(Some(part), key)` for a part's. Derived from the
/// schema (a scenario with every optional key set, serialised), so a key
/// added to a part is found without being listed here.
fn v1_key_table(key: &str) -> Option<(Option<String>, String)> {
    if let Some((_, part, new)) = V1_RENAMED.iter().find(|(old, _, _)| *old == key) {
        return Some((Some(part.to_string()), new.to_string()));
    }
    let full = match toml::Value::try_from(crate::scenario::every_key_set()) {
        Ok(toml::Value::Table(t)) => t,
        _ => unreachable!("Scenario serialises to a TOML table"),
    };
    for (k, v) in &full {
        match v {
            toml::Value::Table(part) if part.contains_key(key) => {
                return Some((Some(k.clone()), key.to_string()))
            }
            toml::Value::Table(_) => {}
            _ if k == key && k != "version" => return Some((None, key.to_string())),
            _ => {}
        }
    }
    None
}

/// A version-1 (flat) table as version 2: each key moved into its part's
/// table; an unknown key is an error naming it.
pub fn upgrade_v1(flat: toml::Table) -> Result<toml::Table, String> {
    let mut out = toml::Table::new();
    out.insert(
        "version".into(),
        toml::Value::Integer(SCENARIO_VERSION as i64),
    );
    for (key, value) in flat {
        match v1_key_table(&key) {
            Some((None, k)) => {
                out.insert(k, value);
            }
            Some((Some(part), k)) => {
                let t = out
                    .entry(part)
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()));
                if let toml::Value::Table(t) = t {
                    t.insert(k, value);
                }
            }
            None if value.is_table() && crate::scenario::PARTS.contains(&key.as_str()) => {
                return Err(format!(
                    "`[{key}]` is a table of the version-2 schema: add `version = {SCENARIO_VERSION}` at the top of the file (book/src/reference/scenario-file.md)"
                ))
            }
            None => {
                return Err(format!(
                    "unknown key `{key}` (a version-1 file: no `version` key; schema: book/src/reference/scenario-file.md)"
                ))
            }
        }
    }
    Ok(out)
}

/// Parses TOML text into a validated [`Scenario`]; `origin` names the source
/// in error messages. A file without `version` is read as version 1 and
/// upgraded.
pub fn parse_scenario(text: &str, origin: &str) -> Result<Scenario, String> {
    let err = |e: String| format!("scenario file {origin}: {}", e.trim_end());
    let table: toml::Table = toml::from_str(text).map_err(|e| err(e.to_string()))?;
    let scn: Scenario = if table.contains_key("version") {
        // Parsed from the text again: toml's errors then show the line.
        toml::from_str(text).map_err(|e| err(e.to_string()))?
    } else {
        let v2 = upgrade_v1(table).map_err(err)?;
        Scenario::deserialize(toml::Value::Table(v2)).map_err(|e| err(e.to_string()))?
    };
    scn.validate().map_err(err)?;
    Ok(scn)
}

/// Reads and parses a scenario file.
pub fn load_scenario(path: &Path) -> Result<Scenario, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read scenario file {}: {e}", path.display()))?;
    parse_scenario(&text, &path.display().to_string())
}

/// The scenario as TOML (what a version-2 file with every key spelled out
/// looks like).
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
        assert_eq!(s.perturbations.beta, 0.05);
        assert_eq!(s.sensing.encoder_cpr, 2048);
        assert_eq!(s.controller.k_y, Some(10.0));
        assert_eq!(s.perturbations.window_s, [5.0, 20.0]);
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
        assert!(e.contains("eps = 1.5 must be in [0, 1)"), "{e}");
    }

    #[test]
    fn round_trip_through_toml() {
        let mut s = Scenario::paper_case(2, 9, None, None);
        s.controller.k_y = Some(12.5);
        assert_eq!(parse_scenario(&to_toml(&s), "rt").unwrap(), s);
        let full = crate::scenario::every_key_set();
        assert_eq!(parse_scenario(&to_toml(&full), "rt").unwrap(), full);
    }

    /// A version-1 (flat) file reads as the version-2 file with the same
    /// values in their tables: every key of the schema, written flat by
    /// hand from the v2 form, gives the same scenario.
    #[test]
    fn version_1_files_are_upgraded() {
        let full = crate::scenario::every_key_set();
        let v2: toml::Table = toml::from_str(&to_toml(&full)).unwrap();
        let mut flat = toml::Table::new();
        for (k, v) in v2 {
            match v {
                toml::Value::Table(t) => {
                    for (kk, vv) in t {
                        let old = match (k.as_str(), kk.as_str()) {
                            ("sensing", "preset") => "sensing".to_string(),
                            ("governor", "enabled") => "governor".to_string(),
                            _ => kk,
                        };
                        assert!(flat.insert(old, vv).is_none(), "two parts share a key");
                    }
                }
                _ if k == "version" => {}
                _ => {
                    flat.insert(k, v);
                }
            }
        }
        let text = toml::to_string(&flat).unwrap();
        assert_eq!(parse_scenario(&text, "v1").unwrap(), full);
        // The shipped v1 form of quantized.toml (before D65) reads as its v2 form.
        let v1 = "name = \"quantized\"\nsensing = \"mocap\"\nbeta = 0.12\neps = 0.2\nmass_scale = 1.2\nencoder_cpr = 16384\npwm_levels = 255\npose_rate_hz = 1000.0\npose_latency_s = 0.0\ngovernor = false\n";
        let s = parse_scenario(v1, "v1").unwrap();
        assert_eq!(s.sensing.preset, crate::scenario::Sensing::Mocap);
        assert_eq!((s.perturbations.beta, s.plant.mass_scale), (0.12, 1.2));
        assert_eq!(s.sensing.pose.pose_rate_hz, Some(1000.0));
        assert!(!s.governor_on());
        let e = parse_scenario("betta = 0.1\n", "old.toml").unwrap_err();
        assert!(e.contains("old.toml") && e.contains("`betta`"), "{e}");
        let e = parse_scenario("[perturbations]\nbeta = 0.1\n", "new.toml").unwrap_err();
        assert!(e.contains("version = 2"), "{e}");
        let e = parse_scenario("version = 3\n", "future.toml").unwrap_err();
        assert!(e.contains("version = 3"), "{e}");
    }

    /// The shipped files as they were before D65 (version 1, flat, kept in
    /// hil-sim/tests/scenarios_v1/) read as the version-2 files.
    #[test]
    fn shipped_version_1_forms_equal_the_version_2_files() {
        for name in ["example", "quantized"] {
            let v1 = load_scenario(
                &Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join(format!("tests/scenarios_v1/{name}.toml")),
            )
            .unwrap();
            let v2 = load_scenario(&repo_file(&format!("scenarios/{name}.toml"))).unwrap();
            // A v1 file wrote `clean_start = true` and `governor = true`
            // where v2 leaves them to the robot file's `[control]` (D139):
            // the same run when the robot says the same.
            let effective = |mut s: crate::scenario::Scenario| {
                s.governor.enabled = Some(s.governor_on());
                let c = s.controller.clean_start;
                s.controller.clean_start = Some(c.unwrap_or(s.robot.control.clean_start));
                s
            };
            assert_eq!(effective(v1), effective(v2), "{name}");
        }
    }

    /// `[plant.<section>]` tables set robot-file fields of the simulated
    /// robot only; a misspelt or unphysical field is an error naming it.
    #[test]
    fn plant_tables_override_robot_fields() {
        let s = parse_scenario(
            "version = 2\n[plant]\nactuation_delay_s = 0.002\n[plant.body]\ntrack_m = 0.42\n[plant.motors]\ncoulomb_friction_nm = [0.5, 0.5]\n",
            "p",
        )
        .unwrap();
        let p = s.plant_robot().unwrap();
        assert_eq!(p.body.track_m, 0.42);
        assert_eq!(p.motors.coulomb_friction_nm, [0.5, 0.5]);
        assert_eq!(s.robot, crate::scenario::Robot::paper());
        assert_eq!(
            s.controller_config(controller_core::ControllerKind::Proposed)
                .robot
                .half_track_m,
            0.2
        );
        for (text, needle) in [
            (
                "version = 2\n[plant.body]\ntrak_m = 0.42\n",
                "plant.body.trak_m",
            ),
            (
                "version = 2\n[plant.body]\ntrack_m = -0.4\n",
                "body.track_m",
            ),
            (
                "version = 2\n[plant]\nactuation_delay_s = -1.0\n",
                "actuation_delay_s",
            ),
        ] {
            let e = parse_scenario(text, "p.toml").unwrap_err();
            assert!(e.contains(needle), "{e}");
        }
    }

    #[test]
    fn version_2_unknown_keys_are_named() {
        for (text, key) in [
            ("version = 2\n[perturbations]\nbetta = 0.1\n", "betta"),
            ("version = 2\n[sensing]\npose_rat_hz = 1.0\n", "pose_rat_hz"),
            ("version = 2\n[plnat]\nmass_scale = 1.0\n", "plnat"),
            ("version = 2\nbeta = 0.1\n", "beta"),
        ] {
            let e = parse_scenario(text, "x.toml").unwrap_err();
            assert!(e.contains("x.toml") && e.contains(key), "{e}");
        }
        let s = parse_scenario("version = 2\n[perturbations]\nbeta = 0.05\n", "x").unwrap();
        assert_eq!(s.perturbations.beta, 0.05);
    }

    #[test]
    fn shipped_example_files_parse() {
        let dir = repo_file("scenarios");
        let mut n = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            if p.extension().is_some_and(|e| e == "toml") {
                let text = std::fs::read_to_string(&p).unwrap();
                assert!(
                    text.contains("version = 2"),
                    "{} is not version 2",
                    p.display()
                );
                load_scenario(&p).unwrap_or_else(|e| panic!("{e}"));
                n += 1;
            }
        }
        assert!(n >= 2, "expected example scenarios in {}", dir.display());
    }

    #[test]
    fn every_field_is_documented() {
        let doc =
            std::fs::read_to_string(repo_file("book/src/reference/scenario-file.md")).unwrap();
        let full = crate::scenario::every_key_set();
        let table: toml::Table = toml::from_str(&to_toml(&full)).unwrap();
        for (key, v) in &table {
            assert!(
                doc.contains(&format!("`{key}`")),
                "book/src/reference/scenario-file.md lacks `{key}`"
            );
            if let toml::Value::Table(part) = v {
                for k in part.keys() {
                    assert!(
                        doc.contains(&format!("`{key}.{k}`")),
                        "book/src/reference/scenario-file.md lacks `{key}.{k}`"
                    );
                }
            }
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
            "square",
        ] {
            assert!(
                doc.contains(&format!("`\"{t}\"`")),
                "docs lack trajectory {t}"
            );
        }
    }
}
