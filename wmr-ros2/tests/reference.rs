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
