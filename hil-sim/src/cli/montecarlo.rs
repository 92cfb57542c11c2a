//! `hil-sim montecarlo`: a sweep of random paper scenarios per controller,
//! or one shard of it for `merge`.

use crate::montecarlo::{run_records, McConfig, Outcome, MAX_RUNS};
use crate::progress::Progress;
use crate::report::{failed_error, mc_report, shard_report};
use crate::scenario::Sensing;
use crate::shard::{default_shard_path, write_shard, Shard, ShardHeader};
use clap::Args;
use controller_core::ControllerKind;
use std::io::Write;
use std::path::PathBuf;

/// `montecarlo` options.
#[derive(Debug, Args)]
pub struct McArgs {
    /// Runs per controller.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=MAX_RUNS))]
    pub runs: u64,
    /// Paper case.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub case: u8,
    /// Base seed; run i uses a seed derived from (seed, i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also draw the plant mass scale in [0.8, 1.2].
    #[arg(long)]
    pub vary_mass: bool,
    /// Run length [s] [default: the paper's 40 s].
    #[arg(long, value_name = "s")]
    pub duration: Option<f64>,
    /// Sensing preset of every run (book/src/reference/scenario-file.md).
    #[arg(long, value_enum, default_value = "ideal")]
    pub sensing: Sensing,
    /// Every run in the paper's setting (no governor or health machine, law (14)
    /// as printed), as `compare`'s first table.
    #[arg(long)]
    pub paper_setting: bool,
    /// Run only shard I of N (0-based: 0/N … N-1/N), a contiguous block of the run
    /// indices with the same seeds as the unsharded run; write its raw results to
    /// --out (default mc-case<C>-seed<S>-runs<R>-shard<I>of<N>.jsonl) for `merge`.
    #[arg(long, value_name = "I/N", value_parser = Shard::parse)]
    pub shard: Option<Shard>,
    /// Write the raw per-run results (JSON Lines, the shard file format) to FILE.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Print the statistics as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress (bar on a terminal, else a line every 10 s on stderr).
    #[arg(long)]
    pub quiet: bool,
    /// The robot files (`--robot`, `--plant`).
    #[command(flatten)]
    pub robots: super::robot_arg::RobotArgs,
}

/// `montecarlo`: run the sweep or one shard of it, write the records with
/// `--shard`/`--out`, print the statistics (unsharded) or the shard's summary.
pub fn montecarlo(a: &McArgs, out: &mut dyn Write) -> Result<(), String> {
    let (robot, plant) = a.robots.load()?;
    let cfg = McConfig {
        runs: a.runs as usize,
        case: a.case,
        seed: a.seed,
        vary_mass: a.vary_mass,
        duration_s: a.duration,
        sensing: a.sensing,
        paper_setting: a.paper_setting,
        robot,
        plant,
    };
    cfg.validate()?;
    crate::limits::check_scenario(&cfg.scenario(0))?;
    crate::limits::check_within_robot(&cfg.scenario(0))?;
    let shard = a.shard.unwrap_or(Shard::WHOLE);
    let runs = shard.runs(a.runs);
    let pb = Progress::new(
        "simulations",
        (runs.end - runs.start) * ControllerKind::ALL.len() as u64,
        a.quiet,
    );
    let rec = run_records(&cfg, runs, &|| pb.inc());
    pb.finish();
    let header = ShardHeader::new(&cfg, shard, rec.elapsed_s, rec.threads);
    let file = match (&a.out, a.shard) {
        (Some(p), _) => Some(p.clone()),
        (None, Some(s)) => Some(default_shard_path(&cfg, s)),
        (None, None) => None,
    };
    if let Some(path) = &file {
        write_shard(path, &header, &rec.records)?;
    }
    let text = match &file {
        Some(path) if a.shard.is_some() => shard_report(&cfg, &header, &rec, path, a.json)?,
        _ => mc_report(&cfg, &rec, file.as_deref(), a.json)?,
    };
    out.write_all(text.as_bytes()).map_err(|e| e.to_string())?;
    let failed = rec
        .records
        .iter()
        .filter(|r| matches!(r.outcome, Outcome::Error(_)))
        .count();
    let where_ = match &file {
        Some(p) if a.shard.is_some() => format!("their errors are in {}", p.display()),
        _ => "see above".to_string(),
    };
    failed_error(failed, &where_)
}
