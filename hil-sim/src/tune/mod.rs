//! `hil-sim tune`: gains for a robot chosen by minimising a robust cost
//! over a Monte-Carlo set drawn around it (issue 19, book/src/how-to/tuning.md).
//!
//! In layers: [`space`] (which gains, their bounds, the unit box),
//! [`set`] (the training and validation scenarios), [`cost`] (one
//! evaluation: the scenarios through the simulator's closed loop, the
//! robust cost), [`optimise`] (CMA-ES, Nelder-Mead, particle swarm), and
//! here the job: each controller tuned from the robot file's gains with
//! the same budget, restarts, shards and their merge, the tuned robot
//! file.
//!
//! Sharding (D94): a job of R restarts (independent optimisations: restart
//! 0 from the robot file's gains, restart r > 0 from a point drawn from
//! (seed, r)) splits into N shards like `montecarlo`'s, each running the
//! contiguous block of restarts `[⌊I·R/N⌋, ⌊(I+1)·R/N⌋)` with exactly the
//! seeds the unsharded job gives them; `tune-merge` takes the best restart
//! of each controller by training cost (the validation set stays out of
//! every choice) and writes the same robot file one process would.

pub mod cost;
pub mod margin;
pub mod optimise;
pub mod set;
pub mod space;

use crate::montecarlo::run_seed;
use crate::rng::Rng;
use crate::scenario::{Robot, Scenario};
use crate::shard::Shard;
use controller_core::ControllerKind;
use cost::{evaluate_with, CostSpec, Evaluation, PresetMean, CHATTER_WEIGHT_M_S};
use optimise::{minimise, Optimizer};
use serde::{Deserialize, Serialize};
use set::{Part, TuneSet};
use std::ops::Range;
use std::path::Path;

/// Format name of a tuning shard file.
pub const TUNE_SHARD_FORMAT: &str = "hil-sim tune shard";
/// Version of the tuning shard format.
pub const TUNE_SHARD_VERSION: u32 = 2;
/// Most cost evaluations per controller and restart (`--evaluations`).
pub const MAX_EVALUATIONS: usize = 100_000;
/// Most restarts of one job.
pub const MAX_RESTARTS: u64 = 10_000;

/// Everything that defines a tuning job (every shard must agree on it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TuneJob {
    /// The scenarios.
    pub set: TuneSet,
    /// The optimiser.
    pub optimizer: Optimizer,
    /// Cost evaluations per controller and restart (the budget).
    pub evaluations: usize,
    /// Restarts per controller.
    pub restarts: u64,
    /// Controllers tuned (names), in the paper's order.
    #[serde(with = "kinds")]
    pub controllers: Vec<ControllerKind>,
    /// How the cost combines the sensing presets' p95 (D119; shard files
    /// without it are of the arithmetic mean).
    #[serde(default)]
    pub preset_mean: PresetMean,
    /// Cost of chatter \[m·s\] (D129; shard files without it are of the
    /// default, [`CHATTER_WEIGHT_M_S`]).
    #[serde(default = "default_chatter_weight")]
    pub chatter_weight_m_s: f64,
}

fn default_chatter_weight() -> f64 {
    CHATTER_WEIGHT_M_S
}

mod kinds {
    use controller_core::ControllerKind;
    use serde::{de::Error, Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(k: &[ControllerKind], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(k.iter().map(|k| k.name()))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<ControllerKind>, D::Error> {
        Vec::<String>::deserialize(d)?
            .iter()
            .map(|n| super::kind_named(n).map_err(D::Error::custom))
            .collect()
    }
}

/// The controller named `name` (`smc`, `asmc`, `proposed`).
pub fn kind_named(name: &str) -> Result<ControllerKind, String> {
    ControllerKind::ALL
        .into_iter()
        .find(|k| k.name() == name)
        .ok_or_else(|| format!("unknown controller '{name}' (smc, asmc, proposed)"))
}

impl TuneJob {
    /// Refuses a job no shard could run.
    pub fn validate(&self) -> Result<(), String> {
        if self.evaluations == 0 || self.evaluations > MAX_EVALUATIONS {
            return Err(format!(
                "--evaluations must be in 1..={MAX_EVALUATIONS}, got {}",
                self.evaluations
            ));
        }
        if self.restarts == 0 || self.restarts > MAX_RESTARTS {
            return Err(format!(
                "--restarts must be in 1..={MAX_RESTARTS}, got {}",
                self.restarts
            ));
        }
        if self.controllers.is_empty() {
            return Err("no controller to tune".into());
        }
        self.cost().validate()?;
        self.set.validate()
    }

    /// How this job's cost is made.
    pub fn cost(&self) -> CostSpec {
        CostSpec {
            preset_mean: self.preset_mean,
            chatter_weight_m_s: self.chatter_weight_m_s,
        }
    }

    /// Evaluations the optimiser really spends per controller and restart
    /// (whole generations for CMA-ES and the swarm).
    pub fn evaluations_used(&self, dims: usize) -> usize {
        match self.optimizer {
            Optimizer::NelderMead => self.evaluations.max(dims + 1),
            _ => (self.evaluations / optimise::POPULATION).max(1) * optimise::POPULATION,
        }
    }

    /// Simulations a shard running `restarts` runs at most (the optimiser,
    /// the best point on both parts, the start gains on both parts when it
    /// holds restart 0).
    pub fn simulations(&self, restarts: &Range<u64>) -> u64 {
        let (t, v) = (
            self.set.training as u64,
            self.set.len(Part::Validation) as u64,
        );
        // The tuned baselines k's search may start from (its special
        // cases, run_shard): SMC for ASMC, both for the proposed controller.
        let has = |b: ControllerKind| u64::from(self.controllers.contains(&b));
        let warm = |k: ControllerKind| -> u64 {
            match k {
                ControllerKind::Smc => 0,
                ControllerKind::Asmc => has(ControllerKind::Smc),
                ControllerKind::Proposed => has(ControllerKind::Smc) + has(ControllerKind::Asmc),
            }
        };
        // The search, the start candidates (D166), the result on both parts.
        let per: u64 = self
            .controllers
            .iter()
            .map(|&k| (self.evaluations_used(space::dims(k).len()) as u64 + 2 + warm(k)) * t + v)
            .sum();
        let start = if restarts.contains(&0) {
            self.controllers.len() as u64 * (t + v)
        } else {
            0
        };
        per * (restarts.end - restarts.start) + start
    }
}

/// One controller's gains evaluated on both parts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scored {
    /// The gains (the robot file's `[gains.<kind>]`).
    pub gains: robot_file::GainSet,
    /// On the training part.
    pub training: Evaluation,
    /// On the validation part.
    pub validation: Evaluation,
}

/// The result of one restart for one controller.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RestartResult {
    /// Controller name.
    pub controller: String,
    /// Restart index.
    pub restart: u64,
    /// Unit-box coordinates of the best point.
    pub x: Vec<f64>,
    /// Its gains and costs.
    pub tuned: Scored,
    /// Evaluations spent.
    pub evaluations: usize,
    /// Best training cost after each generation: (evaluations, cost).
    pub history: Vec<(usize, f64)>,
    /// Where the search started (D166): `start` (the robot file's gains,
    /// or restart r's random point), `tuned asmc` or `tuned smc` (that
    /// restart's tuned baseline embedded in the proposed controller's box),
    /// whichever cost least on the training part.
    #[serde(default)]
    pub warm_start: String,
}

/// What a shard (or a whole job) wrote.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TuneShardFile {
    /// [`TUNE_SHARD_FORMAT`].
    pub format: String,
    /// [`TUNE_SHARD_VERSION`].
    pub version: u32,
    /// The hil-sim that ran it.
    pub hil_sim_version: String,
    /// The job.
    pub job: TuneJob,
    /// Which shard (index, count).
    pub shard: (u64, u64),
    /// Its restarts.
    pub restarts: Range<u64>,
    /// The robot file's gains per controller (names), when this shard
    /// holds restart 0.
    pub start: Option<Vec<(String, Scored)>>,
    /// One result per restart × controller.
    pub results: Vec<RestartResult>,
    /// Simulations run.
    pub simulations: u64,
    /// Wall-clock time \[s\].
    pub elapsed_s: f64,
    /// Worker threads.
    pub threads: usize,
}

/// Salt of a controller's optimiser seeds (so the three controllers do
/// not share a random stream).
fn kind_salt(k: ControllerKind) -> u64 {
    match k {
        ControllerKind::Smc => 0x0073_6d63,
        ControllerKind::Asmc => 0x6173_6d63,
        ControllerKind::Proposed => 0x7072_6f70,
    }
}

/// Scores `kind` with the unit-box point `x` (None: the robot file's own
/// gains) on `train` and `val`.
fn score_gains(
    kind: ControllerKind,
    x: Option<&[f64]>,
    train: &[Scenario],
    val: &[Scenario],
    tick: &(dyn Fn() + Sync),
    spec: CostSpec,
) -> Scored {
    let make = |c: &controller_core::ControllerConfig| match x {
        Some(x) => space::decode(c, x),
        None => *c,
    };
    Scored {
        gains: robot_file::GainSet::of(&make(&train[0].controller_config(kind))),
        training: evaluate_with(train, kind, &make, tick, spec),
        validation: evaluate_with(val, kind, &make, tick, spec),
    }
}

/// Runs the restarts `restarts` of `job` for each of its controllers;
/// `tick` once per simulation, `note` with a line of progress.
pub fn run_shard(
    job: &TuneJob,
    shard: Shard,
    tick: &(dyn Fn() + Sync),
    note: &(dyn Fn(&str) + Sync),
) -> Result<TuneShardFile, String> {
    job.validate()?;
    let restarts = shard.runs(job.restarts);
    let t0 = std::time::Instant::now();
    let train = job.set.scenarios(Part::Training);
    let val = job.set.scenarios(Part::Validation);
    let start = restarts.contains(&0).then(|| {
        job.controllers
            .iter()
            .map(|&k| {
                (
                    k.name().to_string(),
                    score_gains(k, None, &train, &val, tick, job.cost()),
                )
            })
            .collect::<Vec<_>>()
    });
    let mut results: Vec<RestartResult> = Vec::new();
    for r in restarts.clone() {
        for &kind in &job.controllers {
            let base = train[0].controller_config(kind);
            let dims = space::dims(kind).len();
            let x0 = if r == 0 {
                space::encode(&base)
            } else {
                let mut g = Rng::new(run_seed(job.set.seed ^ kind_salt(kind) ^ 0x7374_6172, r));
                (0..dims).map(|_| g.uniform()).collect()
            };
            let f = |u: &[f64]| {
                evaluate_with(&train, kind, &|c| space::decode(c, u), tick, job.cost()).cost
            };
            // The candidates the search may start from (D166): the start,
            // and for the proposed controller this restart's tuned
            // baselines embedded in its box; each evaluated, the cheapest
            // is the search's start and stays a candidate of its result.
            let tuned_x = |k: ControllerKind| {
                results
                    .iter()
                    .find(|x| x.restart == r && x.controller == k.name())
                    .map(|x| x.x.clone())
            };
            let mut cands = vec![("start".to_string(), x0.clone())];
            if kind == ControllerKind::Proposed {
                if let Some(xa) = tuned_x(ControllerKind::Asmc) {
                    cands.push(("tuned asmc".into(), space::embed_asmc(&xa, &x0)));
                }
            }
            if kind != ControllerKind::Smc {
                // SMC is ASMC's and the proposed controller's special
                // case exactly (space::embed_smc).
                if let Some(xs) = tuned_x(ControllerKind::Smc) {
                    cands.push(("tuned smc".into(), space::embed_smc(&xs, &x0)));
                }
            }
            let costs: Vec<f64> = cands.iter().map(|(_, x)| f(x)).collect();
            let i0 = (0..cands.len())
                .min_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)))
                .expect("a candidate");
            if cands.len() > 1 {
                note(&format!(
                    "{} restart {r}: warm start {} (training cost {})",
                    kind.name(),
                    cands[i0].0,
                    cands
                        .iter()
                        .zip(&costs)
                        .map(|((n, _), c)| format!("{n} {c:.4} m"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ));
            }
            let seed = run_seed(job.set.seed ^ kind_salt(kind), r);
            let opt = minimise(
                job.optimizer,
                &f,
                &cands[i0].1,
                Some(costs[i0]),
                job.evaluations,
                seed,
                &|e, c| {
                    note(&format!(
                        "{} restart {r}: {e} evaluations, best training cost {c:.4} m",
                        kind.name()
                    ))
                },
            )?;
            let tuned = score_gains(kind, Some(&opt.x), &train, &val, tick, job.cost());
            note(&format!(
                "{} restart {r}: training {:.4} m, validation {:.4} m",
                kind.name(),
                tuned.training.cost,
                tuned.validation.cost
            ));
            results.push(RestartResult {
                controller: kind.name().to_string(),
                restart: r,
                x: opt.x,
                tuned,
                evaluations: opt.evaluations,
                history: opt.history,
                warm_start: cands[i0].0.clone(),
            });
        }
    }
    Ok(TuneShardFile {
        format: TUNE_SHARD_FORMAT.into(),
        version: TUNE_SHARD_VERSION,
        hil_sim_version: env!("CARGO_PKG_VERSION").into(),
        job: job.clone(),
        shard: (shard.index, shard.count),
        simulations: job.simulations(&restarts),
        restarts,
        start,
        results,
        elapsed_s: t0.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
    })
}

/// The outcome of a whole job: per controller the start and the best
/// restart, and what is written.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TuneOutcome {
    /// The job.
    pub job: TuneJob,
    /// Per controller: (name, start gains, best restart).
    pub controllers: Vec<(String, Scored, RestartResult)>,
    /// Per controller (same order): the gains written (D165).
    pub choices: Vec<Choice>,
    /// The controller that validates best: the written file's
    /// `[control] controller` (D168).
    pub best: String,
    /// Why the start was kept, when the written file runs the robot file's
    /// own controller with its own gains (no tuned gains validated better).
    pub kept_start: Option<String>,
    /// Simulations over all shards.
    pub simulations: u64,
    /// Summed shard time \[s\].
    pub elapsed_s: f64,
}

/// Flag a gain within this factor of a bound of its range (5 %).
pub const BOUND_FLAG_FACTOR: f64 = 1.05;
/// Flag a mean saturated fraction above this on the validation part.
pub const SATURATION_FLAG: f64 = 0.10;
/// Flag a mean chatter above this (torque limits per second: the torque
/// swinging across its whole limit this often) on the validation part.
pub const CHATTER_FLAG_PER_S: f64 = 100.0;

/// One controller's written gains (D165).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Choice {
    /// Controller name.
    pub controller: String,
    /// True when the start gains are written: the tuned ones validated
    /// worse.
    pub kept_start: bool,
    /// The written gains and their costs.
    pub scored: Scored,
    /// What the report flags about them.
    pub flags: Vec<String>,
    /// Their mismatch margins (filled by [`TuneOutcome::add_margins`]).
    pub margins: Vec<margin::Margin>,
}

/// The written gains of one controller: the tuned ones unless the start
/// validates strictly better (D165).
fn choose(job: &TuneJob, name: &str, start: &Scored, best: &RestartResult) -> Choice {
    let kept = start.validation.cost < best.tuned.validation.cost;
    let scored = if kept { start } else { &best.tuned }.clone();
    let mut flags = Vec::new();
    if kept {
        flags.push(format!(
            "kept the start gains: the tuned ones validate at {:.4} m, the start at {:.4} m",
            best.tuned.validation.cost, start.validation.cost
        ));
    } else if let Ok(kind) = kind_named(name) {
        for (d, &u) in space::dims(kind).iter().zip(&best.x) {
            let g = space::value(d, u);
            let authority = d.name.ends_with("(scale)");
            let relative = space::is_relative(d);
            if g <= d.lo * BOUND_FLAG_FACTOR {
                let what = if d.name.starts_with("eso") {
                    "ESO"
                } else {
                    "fault observer"
                };
                flags.push(if authority && space::authority_off(u) {
                    format!("{} = 0: the {what} is off", d.name)
                } else if authority {
                    format!(
                        "{} at its low bound ({g:.2e}): the {what} is nearly off",
                        d.name
                    )
                } else {
                    format!("{} = {g:.4} at its low bound {}", d.name, d.lo)
                });
            } else if g >= d.hi / BOUND_FLAG_FACTOR && !relative {
                flags.push(format!("{} = {g:.4} at its high bound {}", d.name, d.hi));
            }
        }
    }
    let v = &scored.validation;
    if v.mean_saturated > SATURATION_FLAG {
        flags.push(format!(
            "torque saturated {:.1} % of the validation ticks (flag above {:.0} %)",
            100.0 * v.mean_saturated,
            100.0 * SATURATION_FLAG
        ));
    }
    if v.mean_chatter_per_s > CHATTER_FLAG_PER_S {
        flags.push(format!(
            "chatter {:.0} torque limits per second on the validation part (flag above {CHATTER_FLAG_PER_S:.0})",
            v.mean_chatter_per_s
        ));
    }
    for &i in &v.stopped_runs {
        let scn = job.set.scenario(Part::Validation, i as u64);
        flags.push(format!(
            "validation run {i} ({}, {}, seed {}) stopped or diverged",
            job.set.path_of(i).name(),
            scn.sensing.preset.name(),
            scn.seed
        ));
    }
    Choice {
        controller: name.to_string(),
        kept_start: kept,
        scored,
        flags,
        margins: Vec::new(),
    }
}

/// Combines shard files of one job: same job, same build, every restart
/// exactly once; the best restart per controller by training cost (ties:
/// the lower restart).
pub fn merge(files: &[TuneShardFile]) -> Result<TuneOutcome, String> {
    let first = files.first().ok_or("no tuning shard file")?;
    for f in files {
        if f.format != TUNE_SHARD_FORMAT || f.version != TUNE_SHARD_VERSION {
            return Err(format!(
                "not a tuning shard of version {TUNE_SHARD_VERSION}: {} {}",
                f.format, f.version
            ));
        }
        if f.job != first.job || f.hil_sim_version != first.hil_sim_version {
            return Err(format!(
                "shards of different tuning jobs or builds (shard {}/{} vs {}/{})",
                f.shard.0, f.shard.1, first.shard.0, first.shard.1
            ));
        }
    }
    let mut seen = vec![false; first.job.restarts as usize];
    for f in files {
        for r in f.restarts.clone() {
            let s = seen.get_mut(r as usize).ok_or(format!(
                "restart {r} outside the job's {}",
                first.job.restarts
            ))?;
            if *s {
                return Err(format!("restart {r} is in two shard files"));
            }
            *s = true;
        }
    }
    if let Some(r) = seen.iter().position(|s| !s) {
        return Err(format!(
            "restart {r} of 0..{} is in no file: add the shard that holds it",
            first.job.restarts
        ));
    }
    let start = files
        .iter()
        .find_map(|f| f.start.clone())
        .ok_or("no shard holds restart 0 (the start gains)")?;
    let mut controllers = Vec::new();
    for k in &first.job.controllers {
        let name = k.name();
        let best = files
            .iter()
            .flat_map(|f| &f.results)
            .filter(|r| r.controller == name)
            .min_by(|a, b| {
                a.tuned
                    .training
                    .cost
                    .total_cmp(&b.tuned.training.cost)
                    .then(a.restart.cmp(&b.restart))
            })
            .ok_or(format!("no result for {name}"))?;
        let s = start
            .iter()
            .find(|(n, _)| n == name)
            .ok_or(format!("no start gains for {name}"))?;
        controllers.push((name.to_string(), s.1.clone(), best.clone()));
    }
    let job = first.job.clone();
    let choices: Vec<Choice> = controllers
        .iter()
        .map(|(n, s, b)| choose(&job, n, s, b))
        .collect();
    // The controller that validates best (ties: the paper's order).
    let best = choices
        .iter()
        .min_by(|a, b| {
            a.scored
                .validation
                .cost
                .total_cmp(&b.scored.validation.cost)
        })
        .map(|c| c.controller.clone())
        .ok_or("no controller")?;
    let file_kind = job.set.robot.control.controller.name();
    let kept_start = choices
        .iter()
        .find(|c| c.controller == best && c.kept_start && best == file_kind)
        .map(|c| {
            format!(
                "no tuned gains validate better than the robot file's own ({} with its gains, validation cost {:.4} m): the start is kept",
                c.controller, c.scored.validation.cost
            )
        });
    Ok(TuneOutcome {
        job,
        controllers,
        choices,
        best,
        kept_start,
        simulations: files.iter().map(|f| f.simulations).sum(),
        elapsed_s: files.iter().map(|f| f.elapsed_s).sum(),
    })
}

impl TuneOutcome {
    /// The robot with every tuned controller's gains in its own
    /// `[gains.<kind>]` section, validated as a robot file and checked
    /// against the binary record's size.
    pub fn tuned_robot(&self) -> Result<Robot, String> {
        let mut robot = self.job.set.robot.clone();
        for c in &self.choices {
            let g = Some(c.scored.gains);
            match kind_named(&c.controller)? {
                ControllerKind::Smc => robot.gains.smc = g,
                ControllerKind::Asmc => robot.gains.asmc = g,
                ControllerKind::Proposed => robot.gains.proposed = g,
            }
        }
        robot.control.controller = kind_named(&self.best)?;
        let back = Robot::from_toml_str(&robot.to_toml_string())
            .map_err(|e| format!("the tuned robot file is invalid: {e}"))?;
        let mut buf = [0u8; robot_file::MAX_ENCODED_LEN];
        back.encode(&mut buf)
            .map_err(|e| format!("the tuned robot does not fit the binary record: {e:?}"))?;
        Ok(back)
    }

    /// Runs the mismatch sweep of each controller's written gains
    /// ([`margin::margins`]) and flags a stop within mass ±40 % or inertia
    /// ×0.6-1.6 (the first level of those directions); `tick` once per run.
    pub fn add_margins(&mut self, tick: &(dyn Fn() + Sync)) -> Result<(), String> {
        // The scenarios of the set with the written file's gains.
        let set = TuneSet {
            robot: self.tuned_robot()?,
            ..self.job.set.clone()
        };
        for c in &mut self.choices {
            let kind = kind_named(&c.controller)?;
            c.margins = margin::margins(&set, kind, &|c| *c, tick);
            for m in &c.margins {
                if matches!(m.field, margin::Field::Mass | margin::Field::Inertia)
                    && m.fails_at == Some(m.levels[0])
                {
                    c.flags.push(format!(
                        "stops with the plant's {} {}, within the range it must hold",
                        m.field.name(),
                        m.field.level_text(m.levels[0])
                    ));
                }
            }
        }
        Ok(())
    }

    /// Simulations [`Self::add_margins`] runs at most.
    pub fn margin_simulations(&self) -> u64 {
        self.choices.len() as u64 * margin::max_simulations(&self.job.set)
    }

    /// The paired difference proposed − the better baseline (by validation
    /// cost) of the written gains' window RMS over the validation runs:
    /// (baseline name, mean \[m\], standard error \[m\], runs); None without
    /// the proposed controller and a baseline.
    pub fn paired_validation(&self) -> Option<(String, f64, f64, usize)> {
        let p = self.choices.iter().find(|c| c.controller == "proposed")?;
        let b = self
            .choices
            .iter()
            .filter(|c| c.controller != "proposed")
            .min_by(|a, b| {
                a.scored
                    .validation
                    .cost
                    .total_cmp(&b.scored.validation.cost)
            })?;
        let (x, y) = (
            &p.scored.validation.run_rms_win_m,
            &b.scored.validation.run_rms_win_m,
        );
        let n = x.len().min(y.len());
        if n < 2 {
            return None;
        }
        let d: Vec<f64> = x.iter().zip(y).map(|(a, b)| a - b).collect();
        let mean = d.iter().sum::<f64>() / n as f64;
        let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n as f64 - 1.0);
        Some((b.controller.clone(), mean, (var / n as f64).sqrt(), n))
    }

    /// What the report says below the table: the controller written, the
    /// proposed controller against the better baseline, each controller's
    /// flags and margins.
    pub fn findings(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "best on validation: {} (written as [control] controller)",
            self.best
        );
        let tr = |n: &str| {
            self.controllers
                .iter()
                .find(|c| c.0 == n)
                .map(|c| c.2.tuned.training.cost)
        };
        if let (Some(p), Some(b)) = (
            tr("proposed"),
            ["smc", "asmc"]
                .iter()
                .filter_map(|n| tr(n))
                .reduce(f64::min),
        ) {
            let _ = writeln!(
                s,
                "training cost: tuned proposed {p:.4} m, better tuned baseline {b:.4} m ({:+.1} %)",
                100.0 * (p / b - 1.0)
            );
        }
        if let Some((b, m, se, n)) = self.paired_validation() {
            let _ = writeln!(
                s,
                "validation window RMS, proposed - {b} paired over {n} runs: {:+.2} ± {:.2} mm (standard error)",
                1e3 * m,
                1e3 * se
            );
        }
        if let Some(k) = &self.kept_start {
            let _ = writeln!(s, "{k}");
        }
        for c in &self.choices {
            for f in &c.flags {
                let _ = writeln!(s, "flag {}: {f}", c.controller);
            }
        }
        if self.choices.iter().any(|c| !c.margins.is_empty()) {
            let _ = writeln!(
                s,
                "mismatch margin (the first level at which a run stops; > : none up to it):"
            );
            for c in &self.choices {
                let m: Vec<String> = c
                    .margins
                    .iter()
                    .map(|m| format!("{} {}", m.field.name(), m.text()))
                    .collect();
                let _ = writeln!(s, "  {:<9} {}", c.controller, m.join(", "));
            }
        }
        s
    }

    /// The table: per controller the start gains' and the tuned gains'
    /// costs on the training and the validation part, then per sensing
    /// preset the validation p95 window RMS (start → tuned), the tuned
    /// gains' validation saturation, chatter, and stops (training /
    /// validation).
    pub fn table(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let presets = &self.job.set.sensing;
        let _ = write!(
            s,
            "{:<10} {:>9} {:>9} {:>9} {:>9}",
            "controller", "start_tr", "start_va", "tuned_tr", "tuned_va"
        );
        for p in presets {
            let _ = write!(s, " {:>17}", format!("p95_va {}", p.name()));
        }
        let _ = writeln!(
            s,
            " {:>6} {:>7} {:>6} {:>7}",
            "sat", "chatter", "stops", "written"
        );
        let _ = write!(
            s,
            "{:<10} {:>9} {:>9} {:>9} {:>9}",
            "", "[m]", "[m]", "[m]", "[m]"
        );
        for _ in presets {
            let _ = write!(s, " {:>17}", "start->tuned [m]");
        }
        let _ = writeln!(s, " {:>6} {:>7} {:>6} {:>7}", "[%]", "[1/s]", "tr/va", "");
        for (name, st, best) in &self.controllers {
            let t = &best.tuned;
            let _ = write!(
                s,
                "{:<10} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
                name, st.training.cost, st.validation.cost, t.training.cost, t.validation.cost
            );
            for p in presets {
                let of = |e: &Evaluation| {
                    e.per_sensing
                        .iter()
                        .find(|x| x.0 == *p)
                        .map_or(f64::NAN, |x| x.1)
                };
                let _ = write!(
                    s,
                    " {:>17}",
                    format!("{:.4}->{:.4}", of(&st.validation), of(&t.validation))
                );
            }
            let kept = self
                .choices
                .iter()
                .any(|c| &c.controller == name && c.kept_start);
            let _ = writeln!(
                s,
                " {:>6.2} {:>7.1} {:>3}/{:<2} {:>7}",
                100.0 * t.validation.mean_saturated,
                t.validation.mean_chatter_per_s,
                t.training.stops,
                t.validation.stops,
                if kept { "start" } else { "tuned" },
            );
        }
        s
    }

    /// The robot file's text with a header: the command, the job, the
    /// costs (D94).
    pub fn robot_file_text(&self, command: &str) -> Result<String, String> {
        let robot = self.tuned_robot()?;
        let j = &self.job;
        let mut h = String::new();
        h.push_str(&format!(
            "# {}: gains tuned by `hil-sim tune` (book/src/how-to/tuning.md).\n# Command:\n#   {command}\n",
            robot.name
        ));
        h.push_str(&format!(
            "# Set: {} training + {} validation scenarios (disjoint seeds), base seed {}, sensing {}, {} s, torque scale min {}; optimiser {}, {} evaluations x {} restart(s) per controller; {} simulations.\n",
            j.set.training,
            j.set.validation,
            j.set.seed,
            j.set.sensing.iter().map(|s| s.name()).collect::<Vec<_>>().join(","),
            j.set.duration_s,
            j.set.torque_scale_min,
            j.optimizer.name(),
            j.evaluations,
            j.restarts,
            self.simulations,
        ));
        if j.set.disturbance_max_fraction != crate::tune::set::DISTURBANCE_FRACTION.1 {
            h.push_str(&format!(
                "# Disturbance amplitude drawn in ({}, {}) x the torque limit.\n",
                crate::tune::set::DISTURBANCE_FRACTION.0,
                j.set.disturbance_max_fraction
            ));
        }
        if j.chatter_weight_m_s != CHATTER_WEIGHT_M_S {
            h.push_str(&format!(
                "# Chatter weight {} m·s (default {CHATTER_WEIGHT_M_S}).\n",
                j.chatter_weight_m_s
            ));
        }
        h.push_str(match j.preset_mean {
            PresetMean::Arithmetic => {
                "# Cost [m] = p95 window RMS + saturation and chatter penalties + 100 per stop:\n"
            }
            PresetMean::Geometric => {
                "# Cost [m] = geometric mean over the presets of the p95 window RMS + saturation and chatter penalties + 100 per stop:\n"
            }
        });
        for line in self.table().lines().chain(self.findings().lines()) {
            h.push_str("#   ");
            h.push_str(line);
            h.push('\n');
        }
        h.push('\n');
        Ok(h + &robot.to_toml_string())
    }
}

/// Writes `text` to `path` through `path.partial` (no half-written file).
pub fn write_atomic(path: &Path, text: &str) -> Result<(), String> {
    let tmp = path.with_extension("partial");
    std::fs::write(&tmp, text).map_err(|e| format!("cannot write {}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, path).map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// Reads a tuning shard file.
pub fn read_shard_file(path: &Path) -> Result<TuneShardFile, String> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    serde_json::from_str(&text)
        .map_err(|e| format!("{}: not a tuning shard file: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::Sensing;
    use controller_core::ControllerConfig;

    fn job() -> TuneJob {
        TuneJob {
            set: TuneSet {
                robot: Robot::paper(),
                sensing: vec![Sensing::Mocap, Sensing::Imu],
                seed: 1,
                training: 2,
                validation: 4,
                torque_scale_min: 1.0,
                duration_s: 35.0,
                disturbance_max_fraction: set::DISTURBANCE_FRACTION.1,
                figure8: 2,
                square: 0,
            },
            optimizer: Optimizer::Cmaes,
            evaluations: 10,
            restarts: 1,
            controllers: ControllerKind::ALL.to_vec(),
            preset_mean: PresetMean::Geometric,
            chatter_weight_m_s: CHATTER_WEIGHT_M_S,
        }
    }

    fn eval(cost: f64) -> Evaluation {
        Evaluation {
            cost,
            p95_rms_win_m: cost,
            runs: 6,
            run_rms_win_m: vec![cost; 6],
            ..Evaluation::default()
        }
    }

    fn scored(kind: ControllerKind, x: Option<&[f64]>, tr: f64, va: f64) -> Scored {
        let base = ControllerConfig::paper(kind);
        let c = x.map_or(base, |x| space::decode(&base, x));
        Scored {
            gains: robot_file::GainSet::of(&c),
            training: eval(tr),
            validation: eval(va),
        }
    }

    /// A shard file whose start and tuned costs are given per controller
    /// (smc, asmc, proposed): (start training, start validation, tuned
    /// training, tuned validation), the tuned point `x` (None: the middle
    /// of the box).
    fn file(costs: [(f64, f64, f64, f64); 3], x: [Option<Vec<f64>>; 3]) -> TuneShardFile {
        let j = job();
        let mut start = Vec::new();
        let mut results = Vec::new();
        for ((k, c), x) in ControllerKind::ALL.into_iter().zip(costs).zip(x) {
            let x = x.unwrap_or_else(|| vec![0.5; space::dims(k).len()]);
            start.push((k.name().to_string(), scored(k, None, c.0, c.1)));
            results.push(RestartResult {
                controller: k.name().into(),
                restart: 0,
                tuned: scored(k, Some(&x), c.2, c.3),
                x,
                evaluations: 10,
                history: vec![],
                warm_start: "start".into(),
            });
        }
        TuneShardFile {
            format: TUNE_SHARD_FORMAT.into(),
            version: TUNE_SHARD_VERSION,
            hil_sim_version: env!("CARGO_PKG_VERSION").into(),
            job: j,
            shard: (0, 1),
            restarts: 0..1,
            start: Some(start),
            results,
            simulations: 0,
            elapsed_s: 0.0,
            threads: 1,
        }
    }

    #[test]
    fn tuned_gains_that_validate_worse_are_not_written_and_the_start_is_kept() {
        // Every tuned controller trains better and validates worse than
        // its start: the file keeps every start, runs the robot file's own
        // controller (proposed, the best start) and says so.
        let f = file(
            [
                (0.5, 0.40, 0.1, 0.45),
                (0.5, 0.35, 0.1, 0.36),
                (0.5, 0.30, 0.1, 0.31),
            ],
            [None, None, None],
        );
        let o = merge(&[f]).unwrap();
        assert!(o.choices.iter().all(|c| c.kept_start));
        assert_eq!(o.best, "proposed");
        let why = o.kept_start.as_deref().expect("the start is kept");
        assert!(why.contains("0.3000"), "{why}");
        let robot = o.tuned_robot().unwrap();
        for k in ControllerKind::ALL {
            let g = robot_file::GainSet::of(&ControllerConfig::paper(k));
            let written = match k {
                ControllerKind::Smc => robot.gains.smc,
                ControllerKind::Asmc => robot.gains.asmc,
                ControllerKind::Proposed => robot.gains.proposed,
            };
            assert_eq!(written, Some(g), "{k:?}: the start gains are written");
        }
        assert_eq!(robot.control.controller, ControllerKind::Proposed);
        assert!(o.findings().contains("the start is kept"));
    }

    #[test]
    fn the_best_validating_controller_is_written_and_named() {
        // Tuned ASMC validates best (0.20): written as the controller; the
        // proposed controller's tuned gains (0.25 < its start 0.30) are
        // written in its section all the same.
        let f = file(
            [
                (0.5, 0.40, 0.1, 0.30),
                (0.5, 0.35, 0.1, 0.20),
                (0.5, 0.30, 0.1, 0.25),
            ],
            [None, None, None],
        );
        let o = merge(&[f]).unwrap();
        assert_eq!(o.best, "asmc");
        assert!(o.kept_start.is_none());
        assert!(o.choices.iter().all(|c| !c.kept_start));
        let robot = o.tuned_robot().unwrap();
        assert_eq!(robot.control.controller, ControllerKind::Asmc);
        let x = vec![0.5; space::dims(ControllerKind::Proposed).len()];
        let want = space::decode(&ControllerConfig::paper(ControllerKind::Proposed), &x);
        assert_eq!(robot.gains.proposed, Some(robot_file::GainSet::of(&want)));
        // The file says it, and reads back as a robot file naming ASMC.
        let text = o.robot_file_text("hil-sim tune").unwrap();
        assert!(text.contains("best on validation: asmc"));
        let back = Robot::from_toml_str(&text).unwrap();
        assert_eq!(back.control.controller, ControllerKind::Asmc);
    }

    #[test]
    fn a_gain_at_its_bound_and_heavy_saturation_are_flagged() {
        // SMC's k_y at the top of its range (u = 1), k_th 3 % above its
        // floor; ASMC in the middle of its box; proposed saturating 30 %
        // of the ticks with a stopped figure-8 run.
        let mut smc = vec![0.5; space::dims(ControllerKind::Smc).len()];
        smc[1] = 1.0;
        smc[2] = (1.03f64).ln() / (30.0f64 / 0.5).ln();
        let mut f = file(
            [
                (0.5, 0.40, 0.1, 0.30),
                (0.5, 0.35, 0.1, 0.20),
                (0.5, 0.30, 0.1, 0.25),
            ],
            [Some(smc), None, None],
        );
        let p = &mut f.results[2].tuned.validation;
        p.mean_saturated = 0.3;
        p.mean_chatter_per_s = 250.0;
        p.stopped_runs = vec![5];
        let o = merge(&[f]).unwrap();
        let flags = |n: &str| {
            o.choices
                .iter()
                .find(|c| c.controller == n)
                .unwrap()
                .flags
                .clone()
        };
        let s = flags("smc");
        assert!(
            s.iter()
                .any(|f| f.contains("kinematic.k_y") && f.contains("high bound")),
            "{s:?}"
        );
        assert!(
            s.iter()
                .any(|f| f.contains("kinematic.k_th") && f.contains("low bound")),
            "{s:?}"
        );
        assert_eq!(s.len(), 2, "{s:?}");
        assert!(flags("asmc").is_empty(), "{:?}", flags("asmc"));
        let p = flags("proposed");
        assert!(p.iter().any(|f| f.contains("saturated 30.0 %")), "{p:?}");
        assert!(p.iter().any(|f| f.contains("chatter 250")), "{p:?}");
        assert!(p.iter().any(|f| f.contains("run 5 (figure-8")), "{p:?}");
        assert!(o.findings().contains("flag smc: kinematic.k_y"));
    }
}
