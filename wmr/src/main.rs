//! `wmr`: see `wmr --help` and the `cli` module.

use clap::Parser;

fn main() {
    let cli = wmr::cli::Cli::parse();
    let stdout = std::io::stdout();
    let mut lock = stdout.lock();
    if let Err(e) = wmr::cli::execute(&cli, &mut lock) {
        use std::io::Write;
        let _ = lock.flush();
        eprintln!("error: {e}");
        std::process::exit(wmr::cli::EXIT_ERROR);
    }
}
