//! Monte-Carlo over the paper's random parameters: β ∈ (0, 0.2) rad/s and
//! ε ∈ (0.125, 0.25) drawn per run by [`Scenario::paper_case`] from a seed
//! derived from the base seed and the run index, optionally the plant's mass
//! scale ∈ \[0.8, 1.2\]. Every controller sees the same N scenarios (paired
//! comparison). Runs go in parallel on rayon's pool.
//!
//! A sweep produces one [`SimRecord`] per run index × controller; the
//! statistics are computed from those records by one function,
//! [`stats_from_records`], whether they come from one process
//! ([`run_montecarlo`]) or from shard files merged later (the shard module,
//! which builds on this one).

use crate::metrics::Metrics;
use crate::rng::Rng;
use crate::scenario::{Scenario, Sensing};
use crate::sim::{controller_config, run_with};
use controller_core::ControllerKind;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Most runs per controller of one sweep (`--runs`).
pub const MAX_RUNS: u64 = 1_000_000;

/// Range of the plant mass scale with `--vary-mass`.
pub const MASS_SCALE_RANGE: (f64, f64) = (0.8, 1.2);

/// Seed of run `i` derived from the base seed (SplitMix64 of both).
pub fn run_seed(base: u64, i: u64) -> u64 {
    Rng::new(base ^ i.wrapping_mul(0xD1B5_4A32_D192_ED03)).next_u64()
}

/// The scenario of run `i`.
pub fn sample_scenario(case: u8, base_seed: u64, i: u64, vary_mass: bool) -> Scenario {
    let seed = run_seed(base_seed, i);
    let mut scn = Scenario::paper_case(case, seed, None, None);
    scn.name = format!("case{case}-mc{i}");
    if vary_mass {
        let mut r = Rng::new(seed ^ 0x6D61_7373); // independent of β, ε
        let u = r.uniform();
        scn.plant.mass_scale = MASS_SCALE_RANGE.0 + (MASS_SCALE_RANGE.1 - MASS_SCALE_RANGE.0) * u;
    }
    scn
}

/// mean / p95 / max of one metric over the runs that define it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Arithmetic mean.
    pub mean: f64,
    /// 95th percentile, nearest-rank: the ⌈0.95·n⌉-th smallest value.
    pub p95: f64,
    /// Maximum.
    pub max: f64,
    /// Number of values (runs where the metric is defined).
    pub n: usize,
}

/// Summary of `values` (NaN-free); None when empty.
pub fn summarize(values: &[f64]) -> Option<Summary> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n);
    Some(Summary {
        mean: v.iter().sum::<f64>() / n as f64,
        p95: v[rank - 1],
        max: v[n - 1],
        n,
    })
}

/// A metric's accessor (None = undefined in that run).
pub type MetricFn = fn(&Metrics) -> Option<f64>;

/// Names and accessors of the summarised metrics.
pub const METRICS: [(&str, MetricFn); 11] = [
    ("rms_pos_err_m", |m| Some(m.rms_pos_err_m)),
    ("rms_pos_err_window_m", |m| Some(m.rms_pos_err_window_m)),
    ("max_pos_err_window_m", |m| Some(m.max_pos_err_window_m)),
    ("rms_pos_err_after5_m", |m| Some(m.rms_pos_err_after5_m)),
    ("final_pos_err_m", |m| Some(m.final_pos_err_m)),
    ("settling_time_s", |m| m.settling_time_s),
    ("torque_rms_nm", |m| Some(m.torque_rms_nm)),
    ("max_abs_torque_nm", |m| Some(m.max_abs_torque_nm)),
    ("chatter", |m| Some(m.chatter)),
    ("saturated_fraction", |m| Some(m.saturated_fraction)),
    ("fault_est_rmse", |m| m.fault_est_rmse),
];

/// Statistics of one controller over the Monte-Carlo sample.
#[derive(Clone, Debug, Serialize)]
pub struct ControllerStats {
    /// Controller name.
    pub controller: &'static str,
    /// Runs attempted.
    pub runs: usize,
    /// Runs that failed (plant diverged); their messages are in `errors`.
    pub failed: usize,
    /// The first few failure messages.
    pub errors: Vec<String>,
    /// Per metric (in [`METRICS`] order): its summary, None if undefined in
    /// every run. Serialised as a JSON object keyed by the metric name.
    #[serde(serialize_with = "as_map")]
    pub metrics: Vec<(&'static str, Option<Summary>)>,
}

fn as_map<S: serde::Serializer>(
    v: &[(&'static str, Option<Summary>)],
    s: S,
) -> Result<S::Ok, S::Error> {
    s.collect_map(v.iter().map(|(k, x)| (k, x)))
}

/// Statistics of one controller's outcomes (in run-index order: the first
/// few errors are listed in that order).
pub fn controller_stats(kind: ControllerKind, outcomes: &[&Outcome]) -> ControllerStats {
    let ok: Vec<&Metrics> = outcomes
        .iter()
        .filter_map(|o| match o {
            Outcome::Metrics(m) => Some(m),
            Outcome::Error(_) => None,
        })
        .collect();
    let errors: Vec<&String> = outcomes
        .iter()
        .filter_map(|o| match o {
            Outcome::Error(e) => Some(e),
            Outcome::Metrics(_) => None,
        })
        .collect();
    ControllerStats {
        controller: kind.name(),
        runs: outcomes.len(),
        failed: errors.len(),
        errors: errors.into_iter().take(5).cloned().collect(),
        metrics: METRICS
            .iter()
            .map(|(name, f)| {
                let v: Vec<f64> = ok.iter().filter_map(|m| f(m)).collect();
                (*name, summarize(&v))
            })
            .collect(),
    }
}

/// Outcome of one simulation: its metrics, or why it failed (plant diverged).
/// In a shard file: `"metrics": {…}` or `"error": "…"`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// The run finished.
    Metrics(Metrics),
    /// The run failed.
    Error(String),
}

/// One simulation of a sweep: one line of a shard file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimRecord {
    /// Run index in `0..runs` (the scenario is [`McConfig::scenario`] of it).
    pub run: u64,
    /// Seed of the run, [`run_seed`]`(base seed, run)` (stored as a check).
    pub seed: u64,
    /// Controller (`smc`, `asmc`, `proposed`).
    #[serde(with = "controller_name")]
    pub controller: ControllerKind,
    /// Metrics or error.
    #[serde(flatten)]
    pub outcome: Outcome,
}

/// A [`ControllerKind`] as its name in JSON.
mod controller_name {
    use controller_core::ControllerKind;
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(k: &ControllerKind, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(k.name())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<ControllerKind, D::Error> {
        let name = String::deserialize(d)?;
        ControllerKind::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .ok_or_else(|| D::Error::custom(format!("unknown controller '{name}'")))
    }
}

/// The statistics of a sweep from its records, one [`ControllerStats`] per
/// controller in the paper's order. The one function behind both
/// `montecarlo` and `merge`: the records may come in any order (they are
/// sorted by run index first), so shards merged give bit-identical results.
pub fn stats_from_records(records: &[SimRecord]) -> Vec<ControllerStats> {
    let mut sorted: Vec<&SimRecord> = records.iter().collect();
    sorted.sort_by_key(|r| r.run);
    ControllerKind::ALL
        .iter()
        .map(|&k| {
            let outcomes: Vec<&Outcome> = sorted
                .iter()
                .filter(|r| r.controller == k)
                .map(|r| &r.outcome)
                .collect();
            controller_stats(k, &outcomes)
        })
        .collect()
}

/// Monte-Carlo settings (stored in every shard file's header).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct McConfig {
    /// Runs per controller.
    pub runs: usize,
    /// Paper case 1 or 2.
    pub case: u8,
    /// Base seed.
    pub seed: u64,
    /// Draw the plant mass scale too.
    pub vary_mass: bool,
    /// Run length \[s\]; None = the paper's.
    pub duration_s: Option<f64>,
    /// Sensing preset of every run (absent from shard files of ideal sweeps,
    /// so their format is unchanged).
    #[serde(default, skip_serializing_if = "is_ideal")]
    pub sensing: Sensing,
    /// Every run in the paper's setting (no governor, no health machine,
    /// law (14) as printed: [`Scenario::as_printed`]); absent from shard
    /// files of default sweeps, so their format is unchanged.
    #[serde(default, skip_serializing_if = "is_false")]
    pub paper_setting: bool,
    /// The controller's robot (`--robot`; None = the paper's); absent from
    /// shard files of paper-robot sweeps, so their format is unchanged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<crate::scenario::Robot>,
    /// The simulated robot when it differs (`--plant`; None = the
    /// controller's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plant: Option<crate::scenario::Robot>,
}

fn is_ideal(s: &Sensing) -> bool {
    *s == Sensing::Ideal
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl McConfig {
    /// The scenario of run `i`: [`sample_scenario`] with the run length
    /// override.
    pub fn scenario(&self, i: u64) -> Scenario {
        let mut scn = sample_scenario(self.case, self.seed, i, self.vary_mass);
        if let Some(d) = self.duration_s {
            scn.duration_s = d;
        }
        scn.sensing.preset = self.sensing;
        if self.paper_setting {
            scn = scn.as_printed();
        }
        scn.with_robots(self.robot.as_ref(), self.plant.as_ref())
    }

    /// Rejects settings no run could use (checks run 0's scenario).
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=2).contains(&self.case) {
            return Err(format!("case must be 1 or 2, got {}", self.case));
        }
        self.scenario(0).validate()
    }

    /// One line describing the sweep, e.g. `Monte-Carlo: case 2, 200 runs
    /// per controller, beta in (0, 0.2) rad/s, eps in (0.125, 0.25), base
    /// seed 1` (printed by `montecarlo` and `merge`).
    pub fn describe(&self) -> String {
        format!(
            "Monte-Carlo: case {}, {} runs per controller, beta in (0, 0.2) rad/s{}{}{}{}, base seed {}",
            self.case,
            self.runs,
            if self.case >= 2 { ", eps in (0.125, 0.25)" } else { "" },
            if self.vary_mass { ", mass scale in [0.8, 1.2]" } else { "" },
            self.duration_s.map_or(String::new(), |d| format!(", {d} s runs")),
            if self.sensing == Sensing::Ideal {
                String::new()
            } else {
                format!(", sensing {}", self.sensing.name())
            },
            self.seed,
        )
    }
}

/// Records of the run indices `runs` (a shard, or `0..cfg.runs`) and how
/// long they took.
#[derive(Clone, Debug)]
pub struct McRecords {
    /// One record per run index × controller, run-major, paper order.
    pub records: Vec<SimRecord>,
    /// Wall-clock time \[s\].
    pub elapsed_s: f64,
    /// Worker threads used.
    pub threads: usize,
}

impl McRecords {
    /// Simulations per second.
    pub fn sims_per_s(&self) -> f64 {
        self.records.len() as f64 / self.elapsed_s.max(1e-9)
    }
}

/// Runs the scenarios of the run indices `runs` × the three controllers in
/// parallel (no trace); `tick` is called once per finished simulation
/// (progress bar).
pub fn run_records(cfg: &McConfig, runs: Range<u64>, tick: &(dyn Fn() + Sync)) -> McRecords {
    let jobs: Vec<(u64, ControllerKind)> = runs
        .flat_map(|i| ControllerKind::ALL.map(|k| (i, k)))
        .collect();
    let t0 = std::time::Instant::now();
    let records: Vec<SimRecord> = jobs
        .par_iter()
        .map(|&(i, kind)| {
            let scn = cfg.scenario(i);
            let outcome = match run_with(&scn, controller_config(&scn, kind), 0) {
                Ok(o) => Outcome::Metrics(o.metrics),
                Err(e) => Outcome::Error(format!("run {i} (seed {}): {e}", scn.seed)),
            };
            tick();
            SimRecord {
                run: i,
                seed: scn.seed,
                controller: kind,
                outcome,
            }
        })
        .collect();
    McRecords {
        records,
        elapsed_s: t0.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
    }
}

/// Result of [`run_montecarlo`].
#[derive(Clone, Debug, Serialize)]
pub struct McResult {
    /// Statistics per controller, in the paper's order.
    pub stats: Vec<ControllerStats>,
    /// Simulations run (runs × 3).
    pub simulations: usize,
    /// Wall-clock time \[s\].
    pub elapsed_s: f64,
    /// Simulations per second.
    pub runs_per_s: f64,
    /// Worker threads used.
    pub threads: usize,
}

impl McResult {
    /// Statistics and timing of a complete set of records.
    pub fn from_records(r: &McRecords) -> Self {
        McResult {
            stats: stats_from_records(&r.records),
            simulations: r.records.len(),
            elapsed_s: r.elapsed_s,
            runs_per_s: r.sims_per_s(),
            threads: r.threads,
        }
    }
}

/// Runs `cfg.runs` scenarios × the three controllers in parallel (no trace);
/// `tick` is called once per finished simulation (progress bar).
pub fn run_montecarlo(cfg: &McConfig, tick: &(dyn Fn() + Sync)) -> McResult {
    McResult::from_records(&run_records(cfg, 0..cfg.runs as u64, tick))
}

/// The statistics as a table: one row per controller × statistic.
pub fn stats_table(stats: &[ControllerStats]) -> String {
    use std::fmt::Write as _;
    let short = [
        "rms", "rms_win", "max_win", "rms_t>5", "final", "settle", "tau_rms", "tau_max", "chatter",
        "sat", "F_rmse",
    ];
    let units = ["m", "m", "m", "m", "m", "s", "N·m", "N·m", "N·m/s", "%", ""];
    let mut s = String::new();
    let _ = write!(s, "{:<10} {:<5}", "controller", "stat");
    for h in short {
        let _ = write!(s, " {h:>9}");
    }
    s.push('\n');
    let _ = write!(s, "{:<10} {:<5}", "", "");
    for u in units {
        let u = if u.is_empty() {
            String::new()
        } else {
            format!("[{u}]")
        };
        let _ = write!(s, " {u:>9}");
    }
    s.push('\n');
    for st in stats {
        for (row, pick) in [
            ("mean", (|x: &Summary| x.mean) as fn(&Summary) -> f64),
            ("p95", |x| x.p95),
            ("max", |x| x.max),
        ] {
            let _ = write!(s, "{:<10} {:<5}", st.controller, row);
            for (name, sum) in &st.metrics {
                match sum {
                    // The saturated fraction in percent, 3 decimals: at 4
                    // decimals of a fraction, equal values round apart.
                    Some(x) if *name == "saturated_fraction" => {
                        let _ = write!(s, " {:>9.3}", 100.0 * pick(x));
                    }
                    Some(x) => {
                        let _ = write!(s, " {:>9.4}", pick(x));
                    }
                    None => {
                        let _ = write!(s, " {:>9}", "-");
                    }
                }
            }
            s.push('\n');
        }
        let settle = &st.metrics[5].1;
        let never = st.runs - st.failed - settle.map_or(0, |x| x.n);
        let _ = writeln!(
            s,
            "{:<10} runs {}, failed {}, never settled {}",
            "", st.runs, st.failed, never
        );
        for e in &st.errors {
            let _ = writeln!(s, "{:<10}   {e}", "");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p95_mean_max_of_1_to_100() {
        let v: Vec<f64> = (1..=100).rev().map(f64::from).collect();
        let s = summarize(&v).unwrap();
        assert_eq!(s.p95, 95.0);
        assert_eq!(s.max, 100.0);
        assert_eq!(s.mean, 50.5);
        assert_eq!(s.n, 100);
    }

    #[test]
    fn p95_small_samples() {
        assert_eq!(summarize(&[]), None);
        let one = summarize(&[3.0]).unwrap();
        assert_eq!((one.mean, one.p95, one.max), (3.0, 3.0, 3.0));
        // n = 10: ⌈9.5⌉ = 10th smallest = max.
        let ten: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(summarize(&ten).unwrap().p95, 10.0);
        // n = 20: ⌈19⌉ = 19th smallest.
        let twenty: Vec<f64> = (1..=20).map(f64::from).collect();
        assert_eq!(summarize(&twenty).unwrap().p95, 19.0);
    }

    #[test]
    fn samples_in_paper_ranges_distinct_and_reproducible() {
        let mut betas = Vec::new();
        for i in 0..100 {
            let s = sample_scenario(2, 42, i, true);
            assert!(s.perturbations.beta > 0.0 && s.perturbations.beta < 0.2);
            assert!(s.perturbations.eps > 0.125 && s.perturbations.eps < 0.25);
            assert!((0.8..=1.2).contains(&s.plant.mass_scale));
            assert_eq!(s, sample_scenario(2, 42, i, true));
            betas.push(s.perturbations.beta);
        }
        betas.sort_by(f64::total_cmp);
        betas.dedup();
        assert_eq!(betas.len(), 100);
        assert_eq!(sample_scenario(1, 42, 3, false).plant.mass_scale, 1.0);
        assert_eq!(sample_scenario(1, 42, 3, false).perturbations.eps, 0.0);
    }

    #[test]
    fn stats_split_undefined_and_failed_runs() {
        let m = |x: f64, settle: Option<f64>| Metrics {
            rms_pos_err_m: x,
            rms_pos_err_window_m: x,
            max_pos_err_window_m: x,
            rms_pos_err_after5_m: x,
            final_pos_err_m: x,
            settling_time_s: settle,
            torque_rms_nm: x,
            max_abs_torque_nm: x,
            chatter: x,
            saturated_fraction: 0.0,
            fault_est_rmse: None,
            time_lag_final_s: None,
            min_time_scale: None,
            degraded_fraction: None,
            health_transitions: None,
            safe_stop: None,
            rms_est_err_window_m: None,
        };
        let rs = [
            Outcome::Metrics(m(1.0, Some(2.0))),
            Outcome::Metrics(m(3.0, None)),
            Outcome::Error("diverged".to_string()),
        ];
        let st = controller_stats(ControllerKind::Smc, &rs.iter().collect::<Vec<_>>());
        assert_eq!((st.runs, st.failed), (3, 1));
        assert_eq!(st.metrics[0].1.unwrap().mean, 2.0);
        assert_eq!(st.metrics[5].1.unwrap().n, 1);
        assert_eq!(st.metrics[10].1, None);
        let v = serde_json::to_value(&st).unwrap();
        assert_eq!(v["metrics"]["rms_pos_err_m"]["mean"], 2.0);
        assert!(v["metrics"]["fault_est_rmse"].is_null());
    }
}
