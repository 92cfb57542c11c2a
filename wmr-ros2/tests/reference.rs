//! book/src/reference/cli/wmr-ros2.md is `wmr-ros2 --help`, generated from
//! the clap definitions (`wmr_ros2::cli::Args`). `WMR_WRITE_REFERENCE=1
//! cargo test --release --locked --test reference` in wmr-ros2/ rewrites it.

use clap::CommandFactory;
use std::path::Path;

const PAGE: &str = "book/src/reference/cli/wmr-ros2.md";
const COMMAND: &str =
    "(cd wmr-ros2 && WMR_WRITE_REFERENCE=1 cargo test --release --locked --test reference)";

#[test]
fn the_cli_reference_is_the_help() {
    let md = wmr::reference::cli_markdown(
        wmr_ros2::cli::Args::command(),
        "wmr-ros2/tests/reference.rs",
        "The ROS 2 bridge's options (its own workspace, `wmr-ros2/`). Environment \
         variables named `[env: ...]` give an option's value when it is not on the \
         command line.",
    );
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(PAGE);
    if let Err(e) = wmr::reference::check_or_write(&path, PAGE, &md, COMMAND) {
        panic!("{e}");
    }
}

/// book/src/reference/errors.md's wmr-ros2 section: the exit statuses wmr-ros2
/// declares (wmr_ros2::cli::EXIT_CODES) and clap's for a command line it cannot parse.
#[test]
fn the_exit_codes_are_the_declared_ones() {
    const ERRORS: &str = "book/src/reference/errors.md";
    let usage =
        <wmr_ros2::cli::Args as clap::Parser>::try_parse_from(["wmr-ros2", "--no-such-option"])
            .expect_err("an unknown option is refused")
            .exit_code();
    let table = wmr::reference::exit_codes_markdown(&wmr_ros2::cli::EXIT_CODES, usage);
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(ERRORS);
    let doc = std::fs::read_to_string(&path).expect(ERRORS);
    let want =
        wmr::reference::fill_section(&doc, "wmr-ros2-exit", "wmr-ros2/tests/reference.rs", &table)
            .unwrap_or_else(|| panic!("{ERRORS}: the wmr-ros2-exit markers are missing"));
    if let Err(e) = wmr::reference::check_or_write(&path, ERRORS, &want, COMMAND) {
        panic!("{e}");
    }
}
