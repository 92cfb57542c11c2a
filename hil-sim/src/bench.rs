//! Host benchmark (`hil-sim bench`): wall-clock time of one 40 s paper
//! scenario per controller (median of several runs, single thread, with and
//! without the 10 ms trace) and the Monte-Carlo throughput on all cores.

use crate::montecarlo::{run_montecarlo, McConfig};
use crate::scenario::Scenario;
use crate::sim::{controller_config, run, run_with};
use controller_core::ControllerKind;
use std::fmt;
use std::time::Instant;

/// Benchmark settings.
#[derive(Clone, Copy, Debug)]
pub struct BenchConfig {
    /// Repetitions per controller.
    pub reps: usize,
    /// Monte-Carlo runs per controller.
    pub mc_runs: usize,
}

/// Timings of one controller.
#[derive(Clone, Copy, Debug)]
pub struct ControllerTiming {
    /// Controller.
    pub kind: ControllerKind,
    /// Median time of one Case 2 run without trace \[ms\].
    pub median_ms: f64,
    /// Fastest run \[ms\].
    pub min_ms: f64,
    /// Median time with the 10 ms trace (what `compare` does) \[ms\].
    pub traced_median_ms: f64,
}

/// Benchmark result (prints as a report).
#[derive(Clone, Debug)]
pub struct BenchReport {
    /// Settings.
    pub cfg: BenchConfig,
    /// Per controller.
    pub timings: Vec<ControllerTiming>,
    /// Monte-Carlo simulations per second (all threads).
    pub mc_runs_per_s: f64,
    /// Monte-Carlo simulations run.
    pub mc_simulations: usize,
    /// Threads of the pool.
    pub threads: usize,
    /// Control steps per scenario.
    pub steps: usize,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Runs the benchmark.
pub fn run_bench(cfg: &BenchConfig) -> BenchReport {
    let scn = Scenario::paper_case(2, 1, None, None);
    let timings = ControllerKind::ALL
        .iter()
        .map(|&kind| {
            let c = controller_config(&scn, kind);
            let _ = run_with(&scn, c, 0); // warm-up
            let plain: Vec<f64> = (0..cfg.reps)
                .map(|_| {
                    let t = Instant::now();
                    let o = run_with(&scn, c, 0).expect("paper scenario runs");
                    std::hint::black_box(o);
                    t.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            let traced: Vec<f64> = (0..cfg.reps.div_ceil(2))
                .map(|_| {
                    let t = Instant::now();
                    let o = run(&scn, kind).expect("paper scenario runs");
                    std::hint::black_box(o);
                    t.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            ControllerTiming {
                kind,
                min_ms: plain.iter().copied().fold(f64::INFINITY, f64::min),
                median_ms: median(plain),
                traced_median_ms: median(traced),
            }
        })
        .collect();
    let mc = run_montecarlo(
        &McConfig {
            runs: cfg.mc_runs,
            case: 2,
            seed: 1,
            vary_mass: false,
            duration_s: None,
        },
        &|| {},
    );
    BenchReport {
        cfg: *cfg,
        timings,
        mc_runs_per_s: mc.runs_per_s,
        mc_simulations: mc.simulations,
        threads: mc.threads,
        steps: (scn.duration_s / scn.control_period_s).round() as usize,
    }
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "one 40 s paper Case 2 scenario ({} control steps at 1 kHz, 2 RK4 sub-steps), single thread, {} reps:",
            self.steps, self.cfg.reps
        )?;
        writeln!(
            f,
            "{:<10} {:>12} {:>10} {:>14} {:>12}",
            "controller", "median [ms]", "min [ms]", "traced [ms]", "per step"
        )?;
        for t in &self.timings {
            writeln!(
                f,
                "{:<10} {:>12.2} {:>10.2} {:>14.2} {:>9.0} ns",
                t.kind.name(),
                t.median_ms,
                t.min_ms,
                t.traced_median_ms,
                t.median_ms * 1e6 / self.steps as f64
            )?;
        }
        writeln!(
            f,
            "Monte-Carlo throughput: {:.1} simulations/s ({} simulations of 40 s, {} threads)",
            self.mc_runs_per_s, self.mc_simulations, self.threads
        )
    }
}
