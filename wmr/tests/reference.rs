//! book/src/reference/cli/wmr.md is `wmr --help` and every subcommand's,
//! generated from the clap definitions (`wmr::cli::Cli`). `WMR_WRITE_REFERENCE=1
//! cargo test --release -p wmr --test reference` rewrites it.

use clap::CommandFactory;
use std::path::Path;

const PAGE: &str = "book/src/reference/cli/wmr.md";
const COMMAND: &str = "WMR_WRITE_REFERENCE=1 cargo test --release -p wmr --test reference";

#[test]
fn the_cli_reference_is_the_help() {
    let md = wmr::reference::cli_markdown(
        wmr::cli::Cli::command(),
        "wmr/tests/reference.rs",
        "The host tool's commands, each with its `--help`. The options before the \
         command (`--port`, `--serve`, `--timeout-ms`) apply to every command.",
    );
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(PAGE);
    if let Err(e) = wmr::reference::check_or_write(&path, PAGE, &md, COMMAND) {
        panic!("{e}");
    }
}

/// book/src/reference/errors.md's wmr section: the exit statuses wmr
/// declares (wmr::cli::EXIT_CODES) and clap's for a command line it cannot parse.
#[test]
fn the_exit_codes_are_the_declared_ones() {
    const ERRORS: &str = "book/src/reference/errors.md";
    let usage = <wmr::cli::Cli as clap::Parser>::try_parse_from(["wmr", "--no-such-option"])
        .expect_err("an unknown option is refused")
        .exit_code();
    let table = wmr::reference::exit_codes_markdown(&wmr::cli::EXIT_CODES, usage);
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(ERRORS);
    let doc = std::fs::read_to_string(&path).expect(ERRORS);
    let want = wmr::reference::fill_section(&doc, "wmr-exit", "wmr/tests/reference.rs", &table)
        .unwrap_or_else(|| panic!("{ERRORS}: the wmr-exit markers are missing"));
    if let Err(e) = wmr::reference::check_or_write(&path, ERRORS, &want, COMMAND) {
        panic!("{e}");
    }
}
