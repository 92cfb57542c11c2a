//! book/src/reference/cli/hil-sim.md is `hil-sim --help` and every
//! subcommand's, generated from the clap definitions (`hil_sim::cli::Cli`).
//! `WMR_WRITE_REFERENCE=1 cargo test --release -p hil-sim --test reference`
//! rewrites it.

use clap::CommandFactory;
use std::path::Path;

const PAGE: &str = "book/src/reference/cli/hil-sim.md";
const COMMAND: &str = "WMR_WRITE_REFERENCE=1 cargo test --release -p hil-sim --test reference";

#[test]
fn the_cli_reference_is_the_help() {
    let md = wmr::reference::cli_markdown(
        hil_sim::cli::Cli::command(),
        "hil-sim/tests/reference.rs",
        "The simulator's commands, each with its `--help`.",
    );
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(PAGE);
    if let Err(e) = wmr::reference::check_or_write(&path, PAGE, &md, COMMAND) {
        panic!("{e}");
    }
}
