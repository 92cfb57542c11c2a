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

/// book/src/reference/errors.md's hil-sim section: the exit statuses hil-sim
/// declares (hil_sim::cli::EXIT_CODES) and clap's for a command line it cannot parse.
#[test]
fn the_exit_codes_are_the_declared_ones() {
    const ERRORS: &str = "book/src/reference/errors.md";
    let usage =
        <hil_sim::cli::Cli as clap::Parser>::try_parse_from(["hil-sim", "--no-such-option"])
            .expect_err("an unknown option is refused")
            .exit_code();
    let table = wmr::reference::exit_codes_markdown(&hil_sim::cli::EXIT_CODES, usage);
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(ERRORS);
    let doc = std::fs::read_to_string(&path).expect(ERRORS);
    let want =
        wmr::reference::fill_section(&doc, "hil-sim-exit", "hil-sim/tests/reference.rs", &table)
            .unwrap_or_else(|| panic!("{ERRORS}: the hil-sim-exit markers are missing"));
    if let Err(e) = wmr::reference::check_or_write(&path, ERRORS, &want, COMMAND) {
        panic!("{e}");
    }
}
