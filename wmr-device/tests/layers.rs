//! The modules of wmr-device form layers: each names (`crate::m`) only
//! modules below it, so there is no import cycle. The order is the one in
//! the crate documentation.

/// Bottom to top.
const LAYERS: [&str; 9] = [
    "framing",
    "limits",
    "reference",
    "params",
    "robot",
    "wheel_test",
    "telemetry",
    "selection",
    "requests",
];

#[test]
fn modules_use_only_the_layers_below() {
    let src = concat!(env!("CARGO_MANIFEST_DIR"), "/src/");
    for (i, m) in LAYERS.iter().enumerate() {
        let file = std::fs::read_to_string(format!("{src}{m}.rs")).unwrap();
        // Code only: no comments, no unit-test module.
        let code = file.split("#[cfg(test)]").next().unwrap_or_default();
        let text: String = code
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n");
        for (j, other) in LAYERS.iter().enumerate() {
            let named = text.contains(&format!("crate::{other}"))
                || text.contains(&format!("crate::{{{other}"));
            assert!(
                !(named && j >= i),
                "{m}.rs names crate::{other}, which is not below it"
            );
        }
        // Nothing from the crate root (the Device above every module).
        assert!(
            !text.contains("crate::Device") && !text.contains("super::"),
            "{m}.rs names the crate root"
        );
    }
}
