//! `hil-sim bench`: host timing of the simulator.

use crate::bench::{run_bench, BenchConfig};
use clap::Args;
use std::io::Write;

/// `bench` options.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// Repetitions per controller (the median is reported).
    #[arg(long, default_value_t = 9, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub reps: u64,
    /// Monte-Carlo runs per controller for the throughput figure.
    #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    pub mc_runs: u64,
}

/// `bench`: time the paper run and the Monte-Carlo throughput, print them.
pub fn bench(a: &BenchArgs, out: &mut dyn Write) -> Result<(), String> {
    let cfg = BenchConfig {
        reps: a.reps as usize,
        mc_runs: a.mc_runs as usize,
    };
    let r = crate::progress::Progress::during("bench: timing", false, || run_bench(&cfg));
    out.write_all(r.to_string().as_bytes())
        .map_err(|e| e.to_string())
}
