//! Host benchmark (`hil-sim bench`): wall-clock time of one 40 s paper
//! scenario per controller (median of several runs, single thread, with and
//! without the 10 ms trace) and the Monte-Carlo throughput on all cores.

use crate::montecarlo::{run_montecarlo, McConfig};
use crate::scenario::Scenario;
use crate::sim::{controller_config, run, run_with};
use controller_core::ControllerKind;
use std::fmt;
use std::hint::black_box;
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
    /// RK4 sub-steps per control step.
    pub substeps: u32,
    /// The floor: each part of a control period timed alone.
    pub floor: Floor,
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

/// What every simulated control period must cost at least: one reference
/// sample, one controller step and the plant's evaluations (RK4 with the
/// perturbations), each timed alone in a loop over the scenario's periods
/// (median of the repetitions) \[ns per period\].
#[derive(Clone, Copy, Debug)]
pub struct Floor {
    /// `Reference::sample`.
    pub reference_ns: f64,
    /// `Controller::step` per controller kind (paper order).
    pub controller_ns: [f64; 3],
    /// The plant over one period (`World::advance`: `substeps` RK4 steps,
    /// perturbation grid).
    pub plant_ns: f64,
}

fn time_per_period(reps: usize, n: usize, mut f: impl FnMut()) -> f64 {
    let runs: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e9 / n as f64
        })
        .collect();
    median(runs)
}

/// Measures the [`Floor`] on the scenario's reference and plant.
pub fn measure_floor(scn: &Scenario, reps: usize) -> Floor {
    use controller_core::trajectory::Trajectory;
    use controller_core::{Controller, Pose, StepInput, Vel2};
    use sim_robot::world::Actuation;
    let dt = scn.control_period_s;
    let n = (scn.duration_s / dt).round() as usize;
    let reference = scn.trajectory.reference();
    let reference_ns = time_per_period(reps, n, || {
        for k in 0..n {
            black_box(reference.sample(black_box((k as f64 * dt) as f32)));
        }
    });
    // Controller inputs: the reference with a slowly varying pose offset
    // (the loop's error never vanishes) and the reference's velocities.
    let inputs: Vec<StepInput> = (0..n)
        .map(|k| {
            let t = k as f64 * dt;
            let r = reference.sample(t as f32);
            let off = 0.05 * (0.3 * t).sin() as f32;
            StepInput {
                reference: r,
                pose: Pose::new(r.pose.x_m + off, r.pose.y_m - off, r.pose.theta_rad + off),
                eta: Vel2::new(r.v_mps, r.omega_radps),
            }
        })
        .collect();
    let controller_ns = ControllerKind::ALL.map(|kind| {
        let cfg = controller_config(scn, kind);
        time_per_period(reps, n, || {
            let mut c = Controller::new(cfg).expect("paper gains are valid");
            for input in &inputs {
                black_box(c.step(black_box(input)));
            }
        })
    });
    // The plant as every loop runs it: the scenario's world (ideal
    // instruments: no sensor cost) advanced with held torques.
    let proposed = controller_config(scn, ControllerKind::Proposed);
    let world0 = crate::closed_loop::world::ideal_world(scn, &proposed)
        .expect("the scenario's world is valid");
    let plant_ns = time_per_period(reps, n, || {
        let mut world = world0.clone();
        for _ in 0..n {
            let _ = world.advance(Actuation::Torque([0.5, 0.4]), dt);
        }
        black_box(world.state());
    });
    Floor {
        reference_ns,
        controller_ns,
        plant_ns,
    }
}

/// Runs the benchmark.
pub fn run_bench(cfg: &BenchConfig) -> BenchReport {
    // The paper run (its setting: no governor), as `compare`'s first table.
    let scn = Scenario::paper_case(2, 1, None, None).as_printed();
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
            sensing: Default::default(),
            paper_setting: false,
            robot: None,
            plant: None,
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
        substeps: scn.substeps,
        floor: measure_floor(&scn, cfg.reps),
    }
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "one 40 s paper Case 2 scenario in the paper's setting ({} control steps at 1 kHz, {} RK4 sub-step(s)), single thread, {} reps:",
            self.steps, self.substeps, self.cfg.reps
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
        let fl = &self.floor;
        writeln!(
            f,
            "floor per period, each part alone: reference sample {:.0} ns, plant {:.0} ns, controller step {:.0} / {:.0} / {:.0} ns (smc / asmc / proposed)",
            fl.reference_ns, fl.plant_ns, fl.controller_ns[0], fl.controller_ns[1], fl.controller_ns[2]
        )?;
        for (t, c) in self.timings.iter().zip(fl.controller_ns) {
            let floor_ns = fl.reference_ns + fl.plant_ns + c;
            let full_ns = t.median_ms * 1e6 / self.steps as f64;
            writeln!(
                f,
                "{:<10} floor {:>4.0} ns, full loop {:>4.0} ns ({:.2}x the floor)",
                t.kind.name(),
                floor_ns,
                full_ns,
                full_ns / floor_ns
            )?;
        }
        writeln!(
            f,
            "Monte-Carlo throughput: {:.1} simulations/s ({} simulations of 40 s, {} threads)",
            self.mc_runs_per_s, self.mc_simulations, self.threads
        )
    }
}
