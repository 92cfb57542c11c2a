//! The parameter table (controller-core `runtime::param_table`, D144)
//! covers the robot file: its reference page,
//! book/src/reference/parameters.md, is generated and checked by
//! tests/reference.rs.

use controller_core::runtime::param_table;

/// Every numeric field of the robot file is in the parameter table, and
/// every parameter the table puts in the file is a field of it: a new
/// field cannot be left out of the one declaration.
#[test]
fn the_table_covers_every_numeric_field_of_the_file() {
    use param_table::{InFile, ALL};
    const NOT_NUMBERS: &[&str] = &[
        "name",
        "format",
        "encoders.inverted",
        "bridge.mode",
        "bridge.idle",
        "bridge.motor_inverted",
        "imu.yaw_axis",
        "kinematic.printed_2ey_term",
        "control.controller",
        "control.clean_start",
        "control.governor",
    ];
    // An array's elements share one entry (`body.wheel_radius_m`) unless
    // their units differ (`gains.observer.max_estimate[0]`).
    let strip = |f: &str| -> String { f.split('[').next().unwrap().to_string() };
    let in_table = |path: &str| {
        ALL.iter()
            .any(|p| p.name == path || p.name == strip(path) || strip(p.name) == path)
    };
    for f in robot_file::FIELDS {
        if NOT_NUMBERS.contains(&strip(f).as_str()) {
            continue;
        }
        assert!(in_table(f), "{f} is not in the parameter table");
    }
    for f in robot_file::GAIN_FIELDS {
        if NOT_NUMBERS.contains(f) {
            continue;
        }
        let path = format!("gains.{f}");
        assert!(
            in_table(&path),
            "gains.<kind>.{f} is not in the parameter table"
        );
    }
    for p in ALL.iter() {
        let found = match p.in_file {
            InFile::Yes => robot_file::FIELDS
                .iter()
                .any(|f| *f == p.name || strip(f) == p.name),
            InFile::PerController => robot_file::GAIN_FIELDS.iter().any(|f| {
                let path = format!("gains.{f}");
                path == p.name || strip(&path) == p.name
            }),
            InFile::No => !robot_file::FIELDS.iter().any(|f| strip(f) == p.name),
        };
        assert!(
            found,
            "{}: its InFile ({:?}) disagrees with the file",
            p.name, p.in_file
        );
    }
}
