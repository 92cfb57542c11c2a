//! `hil-sim`: see `hil-sim --help` and the `cli` module.

fn main() {
    std::process::exit(hil_sim::cli::main_entry());
}
