//! The robust cost of one set of gains over a part of the tuning set
//! (D92): the 95th percentile of the window RMS position error (taken
//! within each sensing preset of the set and averaged over the presets, so
//! that the drift of a preset without position measurement does not hide
//! the tracking of one with it), plus
//! small penalties on torque saturation and chatter, plus a penalty per
//! run that stopped (a safe stop of the health machine, any runtime stop,
//! a plant that diverged) large enough that no stopping set of gains ever
//! ranks above one that does not stop (the hard constraint).
//!
//! Each scenario runs through [`crate::sim::run_with`] (ideal sensing) or
//! [`crate::hil::run_runtime`] (the firmware runtime), the simulator's one
//! closed loop; the scenarios of one evaluation run in parallel on rayon's
//! pool and are summed in index order, so the cost does not depend on the
//! number of threads.

use crate::hil::{run_runtime, HilOptions};
use crate::montecarlo::summarize;
use crate::scenario::{Scenario, Sensing};
use controller_core::ControllerConfig;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Cost of a mean saturated fraction of 1 (saturated every step) \[m\].
pub const SATURATION_WEIGHT_M: f64 = 0.05;
/// Cost of a mean chatter of 1 (N·m/s)/(N·m of torque limit) \[m·s\] by
/// default (`--chatter-weight`, D129): 76 /s (the paper robot's proposed
/// controller through the runtime) costs 1.5 mm.
pub const CHATTER_WEIGHT_M_S: f64 = 2e-5;
/// Largest `--chatter-weight` \[m·s\]: at 1e-2 a chatter of 76 /s costs
/// 0.76 m, more than the drift of a gyro-only run; beyond it the cost would
/// rank a controller that stops moving its wheels above one that tracks.
pub const MAX_CHATTER_WEIGHT_M_S: f64 = 1e-2;
/// Cost of each run that stopped \[m\]: more than any window RMS a
/// running robot reaches on the tuning set.
pub const STOP_PENALTY_M: f64 = 100.0;

/// How the cost combines the sensing presets' p95 window RMS (D119).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum PresetMean {
    /// Their mean: a preset without a position measurement (`imu`, ~1 m
    /// of drift) outweighs one with it (`mocap`, centimetres) in absolute
    /// terms, so its changes steer the optimiser.
    #[default]
    Arithmetic,
    /// Their geometric mean: the same relative change of any preset's p95
    /// changes the cost by the same factor, so a halved `mocap` error
    /// counts as much as a halved `imu` drift.
    Geometric,
}

impl PresetMean {
    /// The mean of `values` (positive; each at least 1e-9 for the
    /// geometric mean).
    pub fn of(self, values: &[f64]) -> f64 {
        let n = values.len() as f64;
        match self {
            PresetMean::Arithmetic => values.iter().sum::<f64>() / n,
            PresetMean::Geometric => {
                (values.iter().map(|x| x.max(1e-9).ln()).sum::<f64>() / n).exp()
            }
        }
    }

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            PresetMean::Arithmetic => "arithmetic",
            PresetMean::Geometric => "geometric",
        }
    }
}

/// How the cost is made from the runs' scores: the preset mean (D119) and
/// the chatter weight (D129).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostSpec {
    /// How the presets' p95 window RMS are combined.
    pub preset_mean: PresetMean,
    /// Cost of a mean chatter of 1 (N·m/s)/(N·m of torque limit) \[m·s\].
    pub chatter_weight_m_s: f64,
}

impl Default for CostSpec {
    fn default() -> Self {
        PresetMean::default().into()
    }
}

impl From<PresetMean> for CostSpec {
    /// That mean with the default chatter weight ([`CHATTER_WEIGHT_M_S`]).
    fn from(preset_mean: PresetMean) -> Self {
        Self {
            preset_mean,
            chatter_weight_m_s: CHATTER_WEIGHT_M_S,
        }
    }
}

impl CostSpec {
    /// Refuses a chatter weight outside \[0, [`MAX_CHATTER_WEIGHT_M_S`]\].
    pub fn validate(&self) -> Result<(), String> {
        let w = self.chatter_weight_m_s;
        if !(0.0..=MAX_CHATTER_WEIGHT_M_S).contains(&w) {
            return Err(format!(
                "--chatter-weight must be in [0, {MAX_CHATTER_WEIGHT_M_S}] m·s (the cost of a chatter of 1 (N·m/s) per N·m of torque limit; default {CHATTER_WEIGHT_M_S}), got {w}"
            ));
        }
        Ok(())
    }
}

/// What one evaluation found.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Evaluation {
    /// The cost \[m\].
    pub cost: f64,
    /// Mean (the job's [`PresetMean`]) over the sensing presets of the 95th
    /// percentile of the window RMS position error of that preset's runs
    /// \[m\].
    pub p95_rms_win_m: f64,
    /// Per sensing preset (in the set's order): its p95 window RMS \[m\].
    pub per_sensing: Vec<(Sensing, f64)>,
    /// Per sensing preset (in the set's order): the mean over its runs of
    /// the window RMS sensing error (`rms_est_err_window_m`: the estimated
    /// position against the true one; reported, not in the cost) \[m\].
    #[serde(default)]
    pub per_sensing_est_err_m: Vec<(Sensing, f64)>,
    /// Per sensing preset (in the set's order): the 95th percentile over
    /// its runs of the window RMS sensing error \[m\]: beside
    /// [`Self::per_sensing`], how much of the p95 is the estimate's own
    /// drift (reported, not in the cost).
    #[serde(default)]
    pub per_sensing_est_err_p95_m: Vec<(Sensing, f64)>,
    /// Mean of the window RMS position error \[m\].
    pub mean_rms_win_m: f64,
    /// Mean saturated fraction of the steps.
    pub mean_saturated: f64,
    /// Mean chatter over the torque limit \[1/s\].
    pub mean_chatter_per_s: f64,
    /// Runs that stopped (safe stop, runtime stop or diverged).
    pub stops: usize,
    /// Runs evaluated.
    pub runs: usize,
    /// Each run's window RMS position error \[m\], in scenario order
    /// (paired comparisons between controllers on the same seeds).
    #[serde(default)]
    pub run_rms_win_m: Vec<f64>,
    /// Indices (scenario order) of the runs that stopped.
    #[serde(default)]
    pub stopped_runs: Vec<usize>,
}

/// The outcome of one run that enters the cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunScore {
    /// Window RMS position error \[m\] (NaN-safe: a diverged run counts
    /// [`STOP_PENALTY_M`]).
    pub rms_win_m: f64,
    /// Saturated fraction.
    pub saturated: f64,
    /// Chatter over the torque limit \[1/s\].
    pub chatter_per_s: f64,
    /// The run stopped.
    pub stopped: bool,
    /// Window RMS sensing error \[m\] (0 for a run that failed).
    pub est_err_win_m: f64,
    /// The run's sensing preset.
    pub sensing: Sensing,
}

/// Runs `scn` with `cfg` and scores it.
pub fn score(scn: &Scenario, cfg: ControllerConfig) -> RunScore {
    let out = match scn.sensing.preset {
        Sensing::Ideal => crate::sim::run_with(scn, cfg, 0),
        _ => run_runtime(
            scn,
            cfg,
            HilOptions {
                end_at_stop: true,
                ..HilOptions::default()
            },
            0,
        )
        .map(|o| o.sim),
    }
    .map(|o| {
        let runtime_stop = o.stop.is_some();
        (o, runtime_stop)
    });
    let tau = scn.torque_limit_nm().max(1e-9);
    match out {
        Ok((o, runtime_stop)) => {
            let m = o.metrics;
            let finite = m.rms_pos_err_window_m.is_finite();
            RunScore {
                rms_win_m: if finite {
                    m.rms_pos_err_window_m
                } else {
                    STOP_PENALTY_M
                },
                saturated: m.saturated_fraction,
                chatter_per_s: if m.chatter.is_finite() {
                    m.chatter / tau
                } else {
                    0.0
                },
                stopped: runtime_stop || m.safe_stop == Some(true) || !finite,
                est_err_win_m: m
                    .rms_est_err_window_m
                    .filter(|x| x.is_finite())
                    .unwrap_or(0.0),
                sensing: scn.sensing.preset,
            }
        }
        Err(_) => RunScore {
            rms_win_m: STOP_PENALTY_M,
            saturated: 1.0,
            chatter_per_s: 0.0,
            stopped: true,
            est_err_win_m: 0.0,
            sensing: scn.sensing.preset,
        },
    }
}

/// The cost of a list of run scores (in scenario order), the presets'
/// p95 averaged arithmetically, with the default chatter weight.
pub fn aggregate(scores: &[RunScore]) -> Evaluation {
    aggregate_with(scores, CostSpec::default())
}

/// The cost of a list of run scores (in scenario order) as `spec` makes it.
pub fn aggregate_with(scores: &[RunScore], spec: CostSpec) -> Evaluation {
    let n = scores.len().max(1) as f64;
    let rms: Vec<f64> = scores.iter().map(|s| s.rms_win_m).collect();
    let mut presets: Vec<Sensing> = Vec::new();
    for s in scores {
        if !presets.contains(&s.sensing) {
            presets.push(s.sensing);
        }
    }
    // Per preset, in the set's order: `f` of each of its runs, reduced by `g`.
    let per_preset = |f: fn(&RunScore) -> f64, g: &dyn Fn(&[f64]) -> f64| -> Vec<(Sensing, f64)> {
        presets
            .iter()
            .map(|&p| {
                let v: Vec<f64> = scores.iter().filter(|s| s.sensing == p).map(f).collect();
                (p, g(&v))
            })
            .collect()
    };
    let per_sensing = per_preset(|s| s.rms_win_m, &|v| {
        summarize(v).map_or(STOP_PENALTY_M, |s| s.p95)
    });
    let per_sensing_est_err_m = per_preset(|s| s.est_err_win_m, &|v| {
        v.iter().sum::<f64>() / v.len().max(1) as f64
    });
    let per_sensing_est_err_p95_m = per_preset(|s| s.est_err_win_m, &|v| {
        summarize(v).map_or(0.0, |s| s.p95)
    });
    let p95 = if per_sensing.is_empty() {
        STOP_PENALTY_M
    } else {
        spec.preset_mean
            .of(&per_sensing.iter().map(|x| x.1).collect::<Vec<_>>())
    };
    let mean_rms = rms.iter().sum::<f64>() / n;
    let sat = scores.iter().map(|s| s.saturated).sum::<f64>() / n;
    let chat = scores.iter().map(|s| s.chatter_per_s).sum::<f64>() / n;
    let stops = scores.iter().filter(|s| s.stopped).count();
    Evaluation {
        cost: p95
            + SATURATION_WEIGHT_M * sat
            + spec.chatter_weight_m_s * chat
            + STOP_PENALTY_M * stops as f64,
        p95_rms_win_m: p95,
        per_sensing,
        per_sensing_est_err_m,
        per_sensing_est_err_p95_m,
        mean_rms_win_m: mean_rms,
        mean_saturated: sat,
        mean_chatter_per_s: chat,
        stops,
        runs: scores.len(),
        run_rms_win_m: rms,
        stopped_runs: scores
            .iter()
            .enumerate()
            .filter(|(_, s)| s.stopped)
            .map(|(i, _)| i)
            .collect(),
    }
}

/// Evaluates the gains `make(scenario's own configuration)` on every
/// scenario of `scenarios` in parallel; `tick` once per finished run.
pub fn evaluate(
    scenarios: &[Scenario],
    kind: controller_core::ControllerKind,
    make: &(dyn Fn(&ControllerConfig) -> ControllerConfig + Sync),
    tick: &(dyn Fn() + Sync),
) -> Evaluation {
    evaluate_with(scenarios, kind, make, tick, CostSpec::default())
}

/// [`evaluate`] with the cost as `spec` makes it.
pub fn evaluate_with(
    scenarios: &[Scenario],
    kind: controller_core::ControllerKind,
    make: &(dyn Fn(&ControllerConfig) -> ControllerConfig + Sync),
    tick: &(dyn Fn() + Sync),
    spec: CostSpec,
) -> Evaluation {
    let scores: Vec<RunScore> = scenarios
        .par_iter()
        .map(|scn| {
            let s = score(scn, make(&scn.controller_config(kind)));
            tick();
            s
        })
        .collect();
    aggregate_with(&scores, spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(rms: f64, stopped: bool) -> RunScore {
        RunScore {
            rms_win_m: rms,
            saturated: 0.1,
            chatter_per_s: 10.0,
            stopped,
            est_err_win_m: rms / 2.0,
            sensing: Sensing::Mocap,
        }
    }

    #[test]
    fn a_stop_outweighs_any_running_error() {
        let ok: Vec<RunScore> = (0..20).map(|i| run(1.0 + i as f64, false)).collect();
        let mut one_stop: Vec<RunScore> = (0..20).map(|_| run(0.001, false)).collect();
        one_stop[3].stopped = true;
        assert!(aggregate(&one_stop).cost > aggregate(&ok).cost);
        assert_eq!(aggregate(&one_stop).stops, 1);
    }

    #[test]
    fn p95_and_penalties_add_up() {
        let s: Vec<RunScore> = (1..=20).map(|i| run(f64::from(i), false)).collect();
        let e = aggregate(&s);
        assert_eq!(e.p95_rms_win_m, 19.0);
        let want = 19.0 + SATURATION_WEIGHT_M * 0.1 + CHATTER_WEIGHT_M_S * 10.0;
        assert!((e.cost - want).abs() < 1e-12);
    }

    #[test]
    fn p95_is_taken_per_preset_and_averaged() {
        // 20 mocap runs 1..20 mm and 20 imu runs 1..20 m: (19 mm + 19 m)/2.
        let mut s: Vec<RunScore> = (1..=20).map(|i| run(1e-3 * f64::from(i), false)).collect();
        s.extend((1..=20).map(|i| RunScore {
            sensing: Sensing::Imu,
            ..run(f64::from(i), false)
        }));
        let e = aggregate(&s);
        assert!((e.p95_rms_win_m - (0.019 + 19.0) / 2.0).abs() < 1e-12);
        assert_eq!(e.per_sensing.len(), 2);
        assert_eq!(e.per_sensing[0], (Sensing::Mocap, 0.019));
        // The sensing error is each preset's plain mean (of 0.5..10 mm and m).
        assert!((e.per_sensing_est_err_m[0].1 - 0.5e-3 * 10.5).abs() < 1e-12);
        assert!((e.per_sensing_est_err_m[1].1 - 0.5 * 10.5).abs() < 1e-12);
        // Its p95 is taken like the window RMS's: half of 19 mm and 19 m.
        assert!((e.per_sensing_est_err_p95_m[0].1 - 0.0095).abs() < 1e-12);
        assert!((e.per_sensing_est_err_p95_m[1].1 - 9.5).abs() < 1e-12);
    }

    #[test]
    fn geometric_mean_weighs_relative_changes_of_each_preset_alike() {
        // mocap runs of 1..20 mm, imu runs of 1..20 m: p95 19 mm and 19 m.
        let set = |mocap_scale: f64, imu_scale: f64| {
            let mut s: Vec<RunScore> = (1..=20)
                .map(|i| run(mocap_scale * 1e-3 * f64::from(i), false))
                .collect();
            s.extend((1..=20).map(|i| RunScore {
                sensing: Sensing::Imu,
                ..run(imu_scale * f64::from(i), false)
            }));
            aggregate_with(&s, PresetMean::Geometric.into()).p95_rms_win_m
        };
        let base = set(1.0, 1.0);
        assert!((base - (0.019f64 * 19.0).sqrt()).abs() < 1e-12);
        // Halving either preset's errors divides the mean by sqrt(2); the
        // arithmetic mean would hardly see the mocap half.
        let (m, i) = (set(0.5, 1.0), set(1.0, 0.5));
        assert!((m / base - 0.5f64.sqrt()).abs() < 1e-12, "{m} {base}");
        assert!((i / base - 0.5f64.sqrt()).abs() < 1e-12, "{i} {base}");
        // One preset: the mean is its p95 (up to rounding of exp(ln x)).
        let one: Vec<RunScore> = (1..=20).map(|i| run(f64::from(i), false)).collect();
        let g = aggregate_with(&one, PresetMean::Geometric.into()).p95_rms_win_m;
        assert!((g - 19.0).abs() < 1e-12);
    }

    #[test]
    fn the_chatter_weight_prices_chatter_and_nothing_else() {
        let s: Vec<RunScore> = (1..=20).map(|i| run(f64::from(i), false)).collect();
        let with = |w: f64| {
            aggregate_with(
                &s,
                CostSpec {
                    preset_mean: PresetMean::Arithmetic,
                    chatter_weight_m_s: w,
                },
            )
        };
        let (none, heavy) = (with(0.0), with(5e-4));
        // Every run chatters 10 /s: 5e-4 m·s adds 5 mm, and nothing else moves.
        assert!((heavy.cost - none.cost - 5e-4 * 10.0).abs() < 1e-12);
        assert_eq!(heavy.p95_rms_win_m, none.p95_rms_win_m);
        assert_eq!(heavy.mean_chatter_per_s, none.mean_chatter_per_s);
        assert_eq!(with(CHATTER_WEIGHT_M_S), aggregate(&s));
    }

    #[test]
    fn a_chatter_weight_outside_its_range_is_refused_naming_the_flag() {
        for w in [
            -1e-6,
            MAX_CHATTER_WEIGHT_M_S * 1.01,
            f64::NAN,
            f64::INFINITY,
        ] {
            let spec = CostSpec {
                chatter_weight_m_s: w,
                ..CostSpec::default()
            };
            let e = spec.validate().unwrap_err();
            assert!(e.contains("--chatter-weight"), "{e}");
        }
        for w in [0.0, CHATTER_WEIGHT_M_S, MAX_CHATTER_WEIGHT_M_S] {
            let spec = CostSpec {
                chatter_weight_m_s: w,
                ..CostSpec::default()
            };
            assert!(spec.validate().is_ok(), "{w}");
        }
    }
}
