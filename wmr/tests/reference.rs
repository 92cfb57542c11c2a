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
