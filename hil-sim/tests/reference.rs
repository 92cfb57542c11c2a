//! book/src/reference/cli/hil-sim.md is `hil-sim --help` and every
//! subcommand's, generated from the clap definitions (`hil_sim::cli::Cli`).
//! `WMR_WRITE_REFERENCE=1 cargo test --release -p hil-sim --test reference`
//! rewrites it.

use clap::CommandFactory;
use wmr::reference::ToolReference;

const TOOL: ToolReference = ToolReference {
    manifest_dir: env!("CARGO_MANIFEST_DIR"),
    generator: "hil-sim/tests/reference.rs",
    rewrite: "WMR_WRITE_REFERENCE=1 cargo test --release -p hil-sim --test reference",
};

#[test]
fn the_cli_reference_is_the_help() {
    let intro = "The simulator's commands, each with its `--help`.";
    if let Err(e) = TOOL.check_cli(
        "book/src/reference/cli/hil-sim.md",
        hil_sim::cli::Cli::command(),
        intro,
    ) {
        panic!("{e}");
    }
}

/// book/src/reference/errors.md's hil-sim section: the exit statuses hil-sim
/// declares (hil_sim::cli::EXIT_CODES) and clap's for a command line it cannot parse.
#[test]
fn the_exit_codes_are_the_declared_ones() {
    let usage =
        <hil_sim::cli::Cli as clap::Parser>::try_parse_from(["hil-sim", "--no-such-option"])
            .expect_err("an unknown option is refused")
            .exit_code();
    if let Err(e) = TOOL.check_exit_codes("hil-sim", &hil_sim::cli::EXIT_CODES, usage) {
        panic!("{e}");
    }
}
