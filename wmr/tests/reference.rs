//! book/src/reference/cli/wmr.md is `wmr --help` and every subcommand's,
//! generated from the clap definitions (`wmr::cli::Cli`). `WMR_WRITE_REFERENCE=1
//! cargo test --release -p wmr --test reference` rewrites it.

use clap::CommandFactory;
use wmr::reference::ToolReference;

const TOOL: ToolReference = ToolReference {
    manifest_dir: env!("CARGO_MANIFEST_DIR"),
    generator: "wmr/tests/reference.rs",
    rewrite: "WMR_WRITE_REFERENCE=1 cargo test --release -p wmr --test reference",
};

#[test]
fn the_cli_reference_is_the_help() {
    let intro = "The host tool's commands, each with its `--help`. The options before the \
         command (`--port`, `--serve`, `--timeout-ms`) apply to every command.";
    if let Err(e) = TOOL.check_cli(
        "book/src/reference/cli/wmr.md",
        wmr::cli::Cli::command(),
        intro,
    ) {
        panic!("{e}");
    }
}

/// book/src/reference/errors.md's wmr section: the exit statuses wmr
/// declares (wmr::cli::EXIT_CODES) and clap's for a command line it cannot parse.
#[test]
fn the_exit_codes_are_the_declared_ones() {
    let usage = <wmr::cli::Cli as clap::Parser>::try_parse_from(["wmr", "--no-such-option"])
        .expect_err("an unknown option is refused")
        .exit_code();
    if let Err(e) = TOOL.check_exit_codes("wmr", &wmr::cli::EXIT_CODES, usage) {
        panic!("{e}");
    }
}
