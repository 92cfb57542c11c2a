//! book/src/reference/cli/wmr-ros2.md is `wmr-ros2 --help`, generated from
//! the clap definitions (`wmr_ros2::cli::Args`). `WMR_WRITE_REFERENCE=1
//! cargo test --release --locked --test reference` in wmr-ros2/ rewrites it.

use clap::CommandFactory;
use wmr::reference::ToolReference;

const TOOL: ToolReference = ToolReference {
    manifest_dir: env!("CARGO_MANIFEST_DIR"),
    generator: "wmr-ros2/tests/reference.rs",
    rewrite:
        "(cd wmr-ros2 && WMR_WRITE_REFERENCE=1 cargo test --release --locked --test reference)",
};

#[test]
fn the_cli_reference_is_the_help() {
    let intro = "The ROS 2 bridge's options (its own workspace, `wmr-ros2/`). Environment \
         variables named `[env: ...]` give an option's value when it is not on the \
         command line.";
    if let Err(e) = TOOL.check_cli(
        "book/src/reference/cli/wmr-ros2.md",
        wmr_ros2::cli::Args::command(),
        intro,
    ) {
        panic!("{e}");
    }
}

/// book/src/reference/errors.md's wmr-ros2 section: the exit statuses wmr-ros2
/// declares (wmr_ros2::cli::EXIT_CODES) and clap's for a command line it cannot parse.
#[test]
fn the_exit_codes_are_the_declared_ones() {
    let usage =
        <wmr_ros2::cli::Args as clap::Parser>::try_parse_from(["wmr-ros2", "--no-such-option"])
            .expect_err("an unknown option is refused")
            .exit_code();
    if let Err(e) = TOOL.check_exit_codes("wmr-ros2", &wmr_ros2::cli::EXIT_CODES, usage) {
        panic!("{e}");
    }
}
