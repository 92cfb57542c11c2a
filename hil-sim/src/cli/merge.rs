//! `hil-sim merge`: the statistics of a sweep from its shard files.

use crate::report::{failed_error, merge_text};
use crate::shard::merge_shards;
use clap::Args;
use std::io::Write;
use std::path::PathBuf;

/// `merge` options.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// Shard files written by `montecarlo --shard I/N` (any order; together they must
    /// hold every run index of one sweep exactly once).
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Print the statistics as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// `merge`: read and check the shard files, print the statistics.
pub fn merge(a: &MergeArgs, out: &mut dyn Write) -> Result<(), String> {
    let m = merge_shards(&a.files)?;
    let text = merge_text(&m, a.json)?;
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    failed_error(m.stats.iter().map(|s| s.failed).sum(), "see above")
}
