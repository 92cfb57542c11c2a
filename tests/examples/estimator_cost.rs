//! Host cost of the pose estimator next to one controller step (relative
//! scale only; the Cortex-M4F instruction counts come from bench-m4):
//! mean ns per prediction, per correction at 10 ms and at 250 ms latency,
//! and per `Controller::step`.
//! `cargo run --release -p closed-loop-tests --example estimator_cost`

use controller_core::estimator::{EstimatorConfig, GyroSample, PoseEstimator, PoseMeasurement};
use controller_core::trajectory::Trajectory;
use controller_core::{Controller, ControllerConfig, ControllerKind, Pose, StepInput, Vel2};
use std::hint::black_box;
use std::time::Instant;

fn main() {
    let cfg = EstimatorConfig::EXAMPLE;
    let mut e = PoseEstimator::new(cfg, 0.05, Pose::new(0.0, 0.0, 0.0)).unwrap();
    let n = 200_000u32;
    let t0 = Instant::now();
    for k in 1..=n {
        let g = Some(GyroSample {
            rate_radps: 0.3,
            stamp_us: k * 1000,
        });
        black_box(e.predict(k * 1000, 1e-3, 5e-4, 3e-4, black_box(g)));
    }
    let predict_ns = t0.elapsed().as_nanos() as f64 / n as f64;
    let correct = |latency_ticks: u32, reps: u32| {
        let mut e = PoseEstimator::new(cfg, 0.05, Pose::new(0.0, 0.0, 0.0)).unwrap();
        let mut k = 0u32;
        let mut spent = 0u128;
        for _ in 0..reps {
            for _ in 0..latency_ticks.max(1) {
                k += 1;
                e.predict(k * 1000, 1e-3, 5e-4, 3e-4, None);
            }
            let m = PoseMeasurement {
                stamp_us: (k - latency_ticks) * 1000,
                pose: e.estimate().filter_pose,
                position_std_m: 0.002,
                heading_std_rad: Some(0.005),
            };
            let t = Instant::now();
            let _ = black_box(e.correct(black_box(&m)));
            spent += t.elapsed().as_nanos();
        }
        spent as f64 / reps as f64
    };
    let c10 = correct(10, 20_000);
    let c250 = correct(250, 2_000);
    let mut ctrl = Controller::new(ControllerConfig::paper(ControllerKind::Proposed)).unwrap();
    let reference = controller_core::trajectory::Reference::Paper(
        controller_core::trajectory::PaperCurve::paper(
            controller_core::trajectory::PaperHeading::SignedSmooth,
        ),
    );
    let t0 = Instant::now();
    for k in 0..n {
        let r = reference.sample(k as f32 * 1e-3);
        black_box(ctrl.step(&StepInput {
            reference: r,
            pose: r.pose,
            eta: Vel2::new(r.v_mps, r.omega_radps),
        }));
    }
    let step_ns = t0.elapsed().as_nanos() as f64 / n as f64;
    println!("host ns (mean): predict {predict_ns:.0}, correct at 10 ms latency {c10:.0}, at 250 ms {c250:.0}; proposed controller step incl. reference sample {step_ns:.0}");
}
