//! Issue 19's tuning acceptance (book/src/how-to/tuning.md): the committed tuned robot
//! files evaluated on validation seeds (disjoint from the seeds they were
//! tuned on) against the paper's gains and the tuned baselines, and a
//! small tuning job showing improvement, determinism over thread counts
//! and shards that merge into the unsharded result.
//!
//! `cargo test --release -p hil-sim --test tune -- --nocapture` prints the
//! numbers.

use controller_core::ControllerKind;
use hil_sim::scenario::{Robot, Scenario, Sensing};
use hil_sim::shard::Shard;
use hil_sim::tune::cost::{evaluate, Evaluation};
use hil_sim::tune::optimise::Optimizer;
use hil_sim::tune::set::{Part, TuneSet};
use hil_sim::tune::{merge, run_shard, TuneJob};

fn robot(name: &str) -> Robot {
    let path = format!("{}/../robots/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    Robot::from_toml_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// Validation scenarios per sensing preset in these tests.
const VALIDATION: usize = 8;

/// The validation part of the tuning set of `r` (the committed files were
/// tuned with base seed 1) under one sensing preset.
fn validation(r: &Robot, sensing: Sensing) -> Vec<Scenario> {
    TuneSet {
        robot: r.clone(),
        sensing: vec![sensing],
        seed: 1,
        training: 1,
        validation: VALIDATION,
        torque_scale_min: 1.0,
        duration_s: 40.0,
        disturbance_max_fraction: hil_sim::tune::set::DISTURBANCE_FRACTION.1,
        figure8: 0,
        square: 0,
    }
    .scenarios(Part::Validation)
}

fn eval(scns: &[Scenario], kind: ControllerKind) -> Evaluation {
    evaluate(scns, kind, &|c| *c, &|| {})
}

/// Acceptance lines of issue 19 that the committed files do not meet,
/// measured by this test (book/src/explanation/results.md, "Tuning the gains for a robot"): (robot, sensing, line).
/// For these the test asserts the weaker bound given (a ratio), so that a
/// regression still fails, and checks the explanation: both are gyro-only
/// (`imu`), where the paper gains' p95 window RMS is the p95 of their own
/// sensing error (the estimate's drift with the skid and slip, D126) to
/// within [`PAPER_GAINS_AT_THE_DRIFT`]: tb6612 imu +0.8 % against the paper
/// gains (1.1738 vs 1.1646 m; with the arithmetic mean of D119 it was
/// −18.5 %, but then the tuned SMC tracked 3x better under mocap), bts7960
/// imu −3.3 %.
const SHORTFALLS: &[(&str, Sensing, Line, f64)] = &[];

/// Where a 30 % line is a shortfall, the paper gains' p95 window RMS is
/// at most this multiple of their p95 sensing error (their tracking adds
/// at most 2 % to the estimate's drift: measured 1.0000 and 1.0019).
const PAPER_GAINS_AT_THE_DRIFT: f64 = 1.02;

/// An acceptance line.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Line {
    /// Tuned proposed p95 at least 30 % below the proposed controller with
    /// the paper's gains.
    ThirtyPercent,
    /// Tuned proposed p95 not above the better tuned baseline's.
    NotWorseThanBaselines,
}

#[test]
fn tuned_files_beat_the_paper_gains_and_the_tuned_baselines_on_validation_seeds() {
    let mut failures = Vec::new();
    // Issue 19's lines, on the files tuned for it (the paper robot's; the
    // files regenerated for issue 34 are checked by
    // `regenerated_files_hold_issue_34s_lines`).
    for name in ["paper"] {
        let start = robot(name);
        let tuned = robot(&format!("{name}.tuned"));
        assert!(tuned.gains.smc.is_some() && tuned.gains.asmc.is_some());
        assert!(tuned.gains.proposed.is_some());
        for sensing in [Sensing::Imu, Sensing::Mocap] {
            let paper = eval(&validation(&start, sensing), ControllerKind::Proposed);
            let t = validation(&tuned, sensing);
            let [smc, asmc, prop] = ControllerKind::ALL.map(|k| eval(&t, k));
            let best = smc.p95_rms_win_m.min(asmc.p95_rms_win_m);
            eprintln!(
                "{name:<13} {:<6} p95 window RMS [m]: proposed paper gains {:.4} (stops {}), tuned {:.4} ({:+.1} %); tuned smc {:.4}, asmc {:.4} (proposed/best {:.3}); tuned stops {}/{}/{}",
                sensing.name(),
                paper.p95_rms_win_m,
                paper.stops,
                prop.p95_rms_win_m,
                100.0 * (prop.p95_rms_win_m / paper.p95_rms_win_m - 1.0),
                smc.p95_rms_win_m,
                asmc.p95_rms_win_m,
                prop.p95_rms_win_m / best,
                smc.stops,
                asmc.stops,
                prop.stops,
            );
            let est = |e: &Evaluation| e.per_sensing_est_err_m[0].1;
            let est95 = |e: &Evaluation| e.per_sensing_est_err_p95_m[0].1;
            eprintln!(
                "{name:<13} {:<6} window sensing error [m] (estimate against truth), mean / p95: paper gains {:.4} / {:.4}; tuned smc {:.4} / {:.4}, asmc {:.4} / {:.4}, proposed {:.4} / {:.4}",
                sensing.name(),
                est(&paper),
                est95(&paper),
                est(&smc),
                est95(&smc),
                est(&asmc),
                est95(&asmc),
                est(&prop),
                est95(&prop),
            );
            if prop.stops != 0 {
                failures.push(format!("{name} {sensing:?}: tuned proposed stopped"));
            }
            for (line, ratio, need) in [
                (
                    Line::ThirtyPercent,
                    prop.p95_rms_win_m / paper.p95_rms_win_m,
                    0.7,
                ),
                (Line::NotWorseThanBaselines, prop.p95_rms_win_m / best, 1.0),
            ] {
                let short = SHORTFALLS
                    .iter()
                    .find(|x| (x.0, x.1, x.2) == (name, sensing, line));
                let bound = short.map_or(need, |x| x.3);
                // The explanation of a 30 % shortfall, checked: the paper
                // gains already track their estimate (Minkowski: window RMS
                // <= sensing error + the controller's own error), so their
                // p95 is the estimate's drift, which the line would need
                // gains to cut by 30 %.
                if short.is_some() && line == Line::ThirtyPercent {
                    let floor = paper.p95_rms_win_m / est95(&paper);
                    eprintln!(
                        "{name:<13} {:<6} paper gains: p95 window RMS / p95 sensing error {floor:.4}",
                        sensing.name()
                    );
                    if floor > PAPER_GAINS_AT_THE_DRIFT {
                        failures.push(format!(
                            "{name} {sensing:?}: the paper gains' p95 is {floor:.3} x their sensing error's (> {PAPER_GAINS_AT_THE_DRIFT}): the shortfall's explanation no longer holds"
                        ));
                    }
                }
                if ratio > bound {
                    failures.push(format!(
                        "{name} {sensing:?} {line:?}: ratio {ratio:.3} > {bound}{}",
                        if short.is_some() {
                            " (known shortfall, weaker bound)"
                        } else {
                            ""
                        }
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Seeds of the paper's Case 2 for the gyro-only lines. Seed to seed a
/// controller's window RMS there swings by ±25 % (the estimator's drift,
/// D126): over 4 seeds the paired standard error of proposed − SMC was
/// 0.06 m, larger than the differences judged; 64 seeds bring it to about
/// 0.01 m (D128). None of them is a tuning seed (the tuning sets draw their
/// own scenarios, `TuneSet::scenarios`).
const CASE2_SEEDS: u64 = 64;

/// One line of Case 2 (gyro-only, or with the sensing given) over
/// [`CASE2_SEEDS`] seeds: per controller
/// (`ControllerKind::ALL` order) the mean window RMS and the mean sensing
/// error over the window (`rms_est_err_window_m`: the estimator's position
/// against the true one, the part of the error no controller can remove
/// without a position measurement), and the paired difference proposed −
/// better baseline (by mean) with its standard error.
struct Case2Line {
    sensing: Sensing,
    win_m: [f64; 3],
    est_m: [f64; 3],
    /// Mean chatter (`Metrics::chatter`) and saturated fraction of ticks.
    chatter: [f64; 3],
    saturated: [f64; 3],
    diff_m: f64,
    diff_se_m: f64,
    proposed_better: usize,
    /// Runs that stopped (the health machine's safe stop, a runtime stop
    /// other than the direction check's) or diverged, per controller.
    stops: [usize; 3],
    /// Runs the runtime's direction check stopped, per controller.
    direction_trips: [usize; 3],
}

impl Case2Line {
    fn measure(r: &Robot, sensing: Sensing, f: impl Fn(&mut Scenario) + Sync) -> Self {
        use rayon::prelude::*;
        // Per seed and controller: window RMS, sensing error, chatter,
        // saturated fraction.
        let rows: Vec<[[f64; 5]; 3]> = (1..=CASE2_SEEDS)
            .into_par_iter()
            .map(|seed| {
                ControllerKind::ALL.map(|k| {
                    let mut s = Scenario::paper_case(2, seed, None, None)
                        .with_robots(Some(r), None)
                        .with_sensing(sensing);
                    f(&mut s);
                    let o = hil_sim::sim::run_with(&s, s.controller_config(k), 0).unwrap();
                    let m = &o.metrics;
                    // 1: the runtime's direction check tripped; 2: any
                    // other stop (the health machine's safe stop, another
                    // runtime stop) or a diverged run.
                    let direction = matches!(
                        o.stop,
                        Some((
                            _,
                            controller_core::runtime::StopReason::DirectionMismatch { .. }
                        ))
                    );
                    let other = (o.stop.is_some() && !direction)
                        || m.safe_stop == Some(true)
                        || !m.rms_pos_err_window_m.is_finite();
                    [
                        m.rms_pos_err_window_m,
                        m.rms_est_err_window_m.unwrap(),
                        m.chatter,
                        m.saturated_fraction,
                        if other {
                            2.0
                        } else {
                            f64::from(u8::from(direction))
                        },
                    ]
                })
            })
            .collect();
        let n = rows.len() as f64;
        let mean = |c: usize, q: usize| rows.iter().map(|r| r[c][q]).sum::<f64>() / n;
        let of = |q: usize| -> [f64; 3] { std::array::from_fn(|c| mean(c, q)) };
        let (win_m, est_m, chatter, saturated) = (of(0), of(1), of(2), of(3));
        let best = if win_m[0] <= win_m[1] { 0 } else { 1 };
        let d: Vec<f64> = rows.iter().map(|r| r[2][0] - r[best][0]).collect();
        let diff_m = d.iter().sum::<f64>() / n;
        let var = d.iter().map(|x| (x - diff_m).powi(2)).sum::<f64>() / (n - 1.0);
        Self {
            sensing,
            win_m,
            est_m,
            chatter,
            saturated,
            diff_m,
            diff_se_m: (var / n).sqrt(),
            proposed_better: d.iter().filter(|x| **x < 0.0).count(),
            stops: std::array::from_fn(|c| rows.iter().filter(|r| r[c][4] > 1.5).count()),
            direction_trips: std::array::from_fn(|c| {
                rows.iter().filter(|r| r[c][4] == 1.0).count()
            }),
        }
    }

    /// Proposed mean over the better baseline's.
    fn ratio(&self) -> f64 {
        self.win_m[2] / self.win_m[0].min(self.win_m[1])
    }

    fn print(&self, label: &str) {
        let ([smc, asmc, prop], [es, ea, ep]) = (self.win_m, self.est_m);
        let base = smc.min(asmc);
        eprintln!(
            "{}, {label}, Case 2 seeds 1-{CASE2_SEEDS}: mean window RMS [m] smc {smc:.4}, asmc {asmc:.4}, proposed {prop:.4} (proposed/best {:.3}; paired proposed − best {:+.4} ± {:.4} m standard error, {:+.1} ± {:.1} %, proposed better on {}/{CASE2_SEEDS} seeds); sensing error smc {es:.4}, asmc {ea:.4}, proposed {ep:.4}; chatter {:.0} / {:.0} / {:.0}, torque saturated {:.3} / {:.3} / {:.3} of the ticks",
            self.sensing.name(),
            self.ratio(),
            self.diff_m,
            self.diff_se_m,
            100.0 * self.diff_m / base,
            100.0 * self.diff_se_m / base,
            self.proposed_better,
            self.chatter[0],
            self.chatter[1],
            self.chatter[2],
            self.saturated[0],
            self.saturated[1],
            self.saturated[2],
        );
    }
}

#[test]
fn gyro_only_with_inertia_mismatch_tuned_proposed_not_worse_than_the_better_baseline() {
    // Measured with robots/paper.tuned.toml (D119, D128), 64 seeds: ×0.6
    // proposed 3.2 % below the tuned SMC (paired standard error 2.3 %; over
    // seeds 1-4 it was 0.7 % above, within that noise), ×1.6 9.4 % below.
    let tuned = robot("paper.tuned");
    let mut ratios = Vec::new();
    for scale in [0.6, 1.6] {
        let line = Case2Line::measure(&tuned, Sensing::Imu, |s| s.plant.inertia_scale = scale);
        line.print(&format!("inertia x{scale}"));
        ratios.push((scale, line.ratio()));
    }
    for (scale, r) in ratios {
        assert!(
            r <= 1.0,
            "inertia x{scale}: proposed/best baseline {r:.3} > 1"
        );
    }
}

#[test]
fn at_a_2_nm_torque_limit_tuned_proposed_within_5_percent_of_the_better_baseline() {
    // The paper robot with a 2 N·m limit is its own robot: its file is
    // tuned for that limit over mocap, imu and uwb with Case 2's
    // disturbance (1 N·m, half the limit) in its range
    // (robots/paper-2nm.tuned.toml, D212). Issue 34's two cases (uwb with
    // the mass ×1.4: the file it measured had the proposed controller at
    // +105 % and diverging seeds; imu with the inertia ×1.6) and the plain
    // lines: the proposed controller within 5 % of the better baseline
    // (paired, two standard errors of slack) where the issue measured it,
    // and never worse than the controller the file names on every line.
    let tuned = robot("paper-2nm.tuned");
    assert_eq!(tuned.limits.torque_nm, 2.0);
    let named = ControllerKind::ALL
        .iter()
        .position(|&k| k == tuned.control.controller)
        .unwrap();
    let lines = [
        ("uwb, mass x1.4", Sensing::Uwb, 1.4, 1.0, true),
        ("imu, inertia x1.6", Sensing::Imu, 1.0, 1.6, true),
        ("imu", Sensing::Imu, 1.0, 1.0, false),
        ("mocap", Sensing::Mocap, 1.0, 1.0, false),
        ("uwb", Sensing::Uwb, 1.0, 1.0, false),
    ];
    let mut failures = Vec::new();
    for (label, sensing, mass, inertia, issue) in lines {
        let line = Case2Line::measure(&tuned, sensing, |s| {
            s.plant.mass_scale = mass;
            s.plant.inertia_scale = inertia;
        });
        line.print(&format!("2 N·m, {label}"));
        let best = line.win_m[0].min(line.win_m[1]);
        if issue && line.diff_m > 0.05 * best + 2.0 * line.diff_se_m {
            failures.push(format!(
                "{label}: proposed − better baseline {:+.4} ± {:.4} m, over 5 % of {best:.4} m",
                line.diff_m, line.diff_se_m
            ));
        }
        if line.win_m[2] > line.win_m[named] * 1.001 {
            failures.push(format!(
                "{label}: proposed {:.4} m above the named {} {:.4} m",
                line.win_m[2],
                tuned.control.controller.name(),
                line.win_m[named]
            ));
        }
        if line.stops.iter().any(|&n| n > 0) {
            failures.push(format!(
                "{label}: stops (smc, asmc, proposed) {:?}",
                line.stops
            ));
        }
        // Not asserted (D212, a limit of the direction check): a
        // disturbance of half the torque limit is 5x the unmodelled torque
        // the check is built to tolerate (0.1 of the limit, D110); with the
        // mass x1.4 it trips on a few seeds, late in the run.
        eprintln!(
            "2 N·m, {label}: direction-check trips (smc, asmc, proposed) {:?} of {CASE2_SEEDS}",
            line.direction_trips
        );
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A job small enough for a test: ideal sensing (the bare controller, no
/// runtime), 3 training and 2 validation scenarios of 20 s, 20 evaluations.
fn small_job(restarts: u64) -> TuneJob {
    TuneJob {
        set: TuneSet {
            robot: Robot::paper(),
            sensing: vec![Sensing::Ideal],
            seed: 5,
            training: 3,
            validation: 2,
            torque_scale_min: 1.0,
            duration_s: 20.0,
            disturbance_max_fraction: hil_sim::tune::set::DISTURBANCE_FRACTION.1,
            figure8: 0,
            square: 0,
        },
        optimizer: Optimizer::Cmaes,
        evaluations: 20,
        restarts,
        controllers: vec![ControllerKind::Smc],
        preset_mean: Default::default(),
        chatter_weight_m_s: hil_sim::tune::cost::CHATTER_WEIGHT_M_S,
    }
}

fn on_threads<T: Send>(n: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn small_tune_improves_and_is_deterministic_over_threads_and_shards() {
    let job = small_job(2);
    let whole = |threads| {
        on_threads(threads, || {
            run_shard(&job, Shard::WHOLE, &|| {}, &|_| {}).unwrap()
        })
    };
    let one = whole(1);
    let three = whole(3);
    assert_eq!(
        one.results, three.results,
        "thread count changed the result"
    );
    assert_eq!(one.start, three.start);
    let o = merge(std::slice::from_ref(&one)).unwrap();
    let (_, start, best) = &o.controllers[0];
    assert!(
        best.tuned.training.cost < start.training.cost,
        "no improvement: {} vs {}",
        best.tuned.training.cost,
        start.training.cost
    );
    // The cost the optimiser saw is the cost of the written gains.
    let tuned = o.tuned_robot().unwrap();
    let train = TuneSet {
        robot: tuned,
        ..job.set.clone()
    }
    .scenarios(Part::Training);
    let again = evaluate(&train, ControllerKind::Smc, &|c| *c, &|| {});
    assert!(
        (again.cost - best.tuned.training.cost).abs() <= 1e-9 * again.cost.max(1.0),
        "written gains cost {} vs tuned {}",
        again.cost,
        best.tuned.training.cost
    );
    // Two shards of the two restarts merge into the unsharded outcome.
    let shards: Vec<_> = (0..2)
        .map(|i| run_shard(&job, Shard::new(i, 2).unwrap(), &|| {}, &|_| {}).unwrap())
        .collect();
    let merged = merge(&[shards[1].clone(), shards[0].clone()]).unwrap();
    assert_eq!(merged.controllers, o.controllers);
    assert_eq!(merged.tuned_robot().unwrap(), o.tuned_robot().unwrap());
    // A missing or doubled shard is refused.
    assert!(merge(&shards[..1]).unwrap_err().contains("restart 1"));
    assert!(
        merge(&[shards[0].clone(), shards[0].clone(), shards[1].clone()])
            .unwrap_err()
            .contains("two shard files")
    );
}

#[test]
fn each_search_holds_the_tuned_baselines_below_it_and_trains_no_worse() {
    // Issue 34, D212: SMC is ASMC with ρ0 = ρ_max, ASMC the proposed
    // controller with the ESO's and the fault observer's clamps at 0. The
    // tuned baselines embedded in the boxes above them cost what they cost
    // (ASMC exactly: the same f32 gains, D̂ = F̂ = 0; SMC up to K's f32
    // rounding through two ranges), and each search, started from its
    // cheapest candidate, can only end at or below them.
    use hil_sim::tune::space;
    let mut job = small_job(1);
    job.controllers = ControllerKind::ALL.to_vec();
    let f = run_shard(&job, Shard::WHOLE, &|| {}, &|_| {}).unwrap();
    let of = |n: &str| f.results.iter().find(|r| r.controller == n).unwrap();
    let (s, a, p) = (of("smc"), of("asmc"), of("proposed"));
    let train = job.set.scenarios(Part::Training);
    let cost_in = |kind: ControllerKind, embed: &dyn Fn(&[f64]) -> Vec<f64>| {
        let base = train[0].controller_config(kind);
        let x = embed(&space::encode(&base));
        evaluate(&train, kind, &|c| space::decode(c, &x), &|| {}).cost
    };
    let asmc_in_p = cost_in(ControllerKind::Proposed, &|b| space::embed_asmc(&a.x, b));
    let smc_in_a = cost_in(ControllerKind::Asmc, &|b| space::embed_smc(&s.x, b));
    let smc_in_p = cost_in(ControllerKind::Proposed, &|b| space::embed_smc(&s.x, b));
    let (cs, ca, cp) = (
        s.tuned.training.cost,
        a.tuned.training.cost,
        p.tuned.training.cost,
    );
    eprintln!(
        "training cost [m]: tuned smc {cs:.6} (in the asmc box {smc_in_a:.6}, in the proposed box {smc_in_p:.6}), \
         tuned asmc {ca:.6} (in the proposed box {asmc_in_p:.6}), tuned proposed {cp:.6} (warm starts: asmc {}, proposed {})",
        a.warm_start, p.warm_start
    );
    assert_eq!(asmc_in_p, ca, "ASMC embedded in the proposed box");
    for (what, c) in [("asmc", smc_in_a), ("proposed", smc_in_p)] {
        let rel = (c / cs - 1.0).abs();
        assert!(rel < 1e-4, "SMC embedded in the {what} box: {rel:.2e}");
    }
    assert!(ca <= smc_in_a && cp <= asmc_in_p && cp <= smc_in_p);
}

/// The job the regenerated files were tuned with (D169's defaults: base
/// seed 1, 10 training and 16 + 4 figure-8 validation runs of 35 s,
/// `mocap,imu`).
fn issue34_set(r: &Robot) -> TuneSet {
    TuneSet {
        robot: r.clone(),
        sensing: vec![Sensing::Mocap, Sensing::Imu],
        seed: 1,
        training: 10,
        validation: 16,
        torque_scale_min: 1.0,
        duration_s: 35.0,
        disturbance_max_fraction: hil_sim::tune::set::DISTURBANCE_FRACTION.1,
        figure8: 4,
        square: 0,
    }
}

#[test]
fn regenerated_files_hold_issue_34s_lines() {
    // Per regenerated file, and robots/paper.tuned.toml (tuned before
    // D169 on its own set; measured here on the same default set, D212):
    // (1) the controller it names validates no worse
    // than what the robot file ran (its own controller, its own gains) on
    // the same validation runs (D165); (2) the proposed controller within
    // 5 % of the better baseline on the validation runs (paired over the
    // 20 runs, two standard errors of slack); (3) none of the 16 validation
    // seeds of the training path stops with the plant's mass ×0.6 or ×1.4
    // or its inertia ×0.6 or ×1.6, for the named controller and the
    // proposed one.
    use hil_sim::tune::cost::{evaluate_with, PresetMean};
    use hil_sim::tune::margin::{apply, Field};
    use rayon::prelude::*;
    let spec = PresetMean::Geometric.into();
    let mut failures = Vec::new();
    for name in ["n20-0p85kg", "tb6612-2kg", "bts7960-10kg", "paper"] {
        let (start, tuned) = (robot(name), robot(&format!("{name}.tuned")));
        let val = |r: &Robot| issue34_set(r).scenarios(Part::Validation);
        let ev = |r: &Robot, k| evaluate_with(&val(r), k, &|c| *c, &|| {}, spec);
        let (k0, k1) = (start.control.controller, tuned.control.controller);
        let (before, after) = (ev(&start, k0), ev(&tuned, k1));
        eprintln!(
            "{name}: validation cost {} (start) {:.4} m -> {} (written) {:.4} m",
            k0.name(),
            before.cost,
            k1.name(),
            after.cost
        );
        if after.cost > before.cost {
            failures.push(format!("{name}: the written file validates worse"));
        }
        let [smc, asmc, prop] = ControllerKind::ALL.map(|k| ev(&tuned, k));
        let mean = |e: &Evaluation| e.run_rms_win_m.iter().sum::<f64>() / e.runs as f64;
        let best = if mean(&smc) <= mean(&asmc) {
            &smc
        } else {
            &asmc
        };
        let d: Vec<f64> = prop
            .run_rms_win_m
            .iter()
            .zip(&best.run_rms_win_m)
            .map(|(a, b)| a - b)
            .collect();
        let n = d.len() as f64;
        let dm = d.iter().sum::<f64>() / n;
        let se = (d.iter().map(|x| (x - dm).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
        eprintln!(
            "{name}: validation mean window RMS smc {:.4}, asmc {:.4}, proposed {:.4} m; proposed - better baseline {:+.4} ± {:.4} m over {n} runs ({:+.1} %)",
            mean(&smc),
            mean(&asmc),
            mean(&prop),
            dm,
            se,
            100.0 * dm / mean(best)
        );
        if dm > 0.05 * mean(best) + 2.0 * se {
            failures.push(format!(
                "{name}: proposed more than 5 % above the better baseline"
            ));
        }
        let cases = [
            (Field::Mass, 0.6),
            (Field::Mass, 1.4),
            (Field::Inertia, 0.6),
            (Field::Inertia, 1.6),
        ];
        let base: Vec<Scenario> = val(&tuned).into_iter().take(16).collect();
        for k in [k1, ControllerKind::Proposed] {
            let stops: Vec<String> = cases
                .par_iter()
                .flat_map(|&(f, l)| {
                    base.par_iter().filter_map(move |s| {
                        let scn = apply(s.clone(), f, l);
                        let r = hil_sim::tune::cost::score(&scn, scn.controller_config(k));
                        r.stopped
                            .then(|| format!("{} x{l} seed {}", f.name(), s.seed))
                    })
                })
                .collect();
            eprintln!(
                "{name}: {} under mass x0.6/x1.4, inertia x0.6/x1.6 over 16 seeds: {} stops {stops:?}",
                k.name(),
                stops.len()
            );
            if !stops.is_empty() {
                failures.push(format!("{name} {}: {stops:?}", k.name()));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
