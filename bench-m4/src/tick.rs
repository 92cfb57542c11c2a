//! The firmware's whole control tick, timed: `LoopTimer::tick` +
//! `ControlLoop::tick` (encoders, pose estimator with gyro and external
//! poses, reference, proposed controller, pacer, supervisor, duty) closed
//! through sim-robot's `World` (plant and simulated hardware), plus the estimator's
//! `predict` and `correct` timed on their own on a second `PoseEstimator`
//! fed exactly what the loop's estimator was fed (checked bit for bit
//! against the loop's estimate every tick).
//!
//! The simulated sensors run outside the timed region (they are the
//! simulator's cost, in f64 soft-float on this core): before each tick their
//! readings are latched (`LatchedEncoders`, `LatchedGyro`, `LatchedPoses`), which the tick reads through the
//! runtime's hardware traits, as the firmware reads its timer registers,
//! its gyro buffer and its pose queue.

use core::hint::black_box;

use controller_core::estimator::{GyroSample, PoseEstimator, PoseMeasurement, HISTORY_LEN};
use controller_core::math;
use controller_core::runtime::{
    ControlLoop, Gyro, LoopTimer, PoseSource, RuntimeConfig, WheelEncoders, MAX_POSES_PER_TICK,
    MAX_REPROPAGATION_PER_TICK,
};
use controller_core::ControllerKind;
use sim_robot::sensors::PRESET_GYRO;
use sim_robot::world::{Actuation, HardwareSensing, Instruments};
use sim_robot::{PoseSourceModel, SimDriver};

use crate::timer::Counter;
use crate::{case2_world, fail, time, Stat};

/// Ticks per run: the paper's 40 s at 1 kHz.
const TICKS: u32 = 40_000;

/// UWB-like (position only, 10 Hz, 5 cm) at the maximal latency the
/// runtime accepts (250 ms, no jitter): every correction re-propagates 250
/// ticks of history.
pub const UWB_MAX_LATENCY: PoseSourceModel = PoseSourceModel {
    rate_hz: 10.0,
    latency_s: 0.250,
    jitter_s: 0.0,
    position_noise_m: 0.05,
    heading_noise_rad: None,
    dropout: 0.0,
    outage_s: None,
    outlier_fraction: 0.0,
    outlier_m: 1.0,
};

/// Encoder counts latched before a tick.
struct LatchedEncoders([u16; 2]);

impl WheelEncoders for LatchedEncoders {
    fn counts(&mut self) -> [u16; 2] {
        self.0
    }
}

/// The gyro's latest sample, latched before a tick.
struct LatchedGyro(Option<GyroSample>);

impl Gyro for LatchedGyro {
    fn sample(&mut self) -> Option<GyroSample> {
        self.0
    }
}

/// Pose measurements that have arrived (a queue, as the host link fills
/// it), and those the tick took.
struct LatchedPoses {
    queue: [Option<PoseMeasurement>; 8],
    /// `queue[head..len]` not yet taken.
    head: usize,
    len: usize,
    /// Measurements handed out during the current tick (for the shadow estimator).
    taken: [Option<PoseMeasurement>; MAX_POSES_PER_TICK],
    n_taken: usize,
}

impl PoseSource for LatchedPoses {
    fn measurement(&mut self) -> Option<PoseMeasurement> {
        if self.head == self.len {
            return None;
        }
        let m = self.queue[self.head];
        self.head += 1;
        if self.n_taken < MAX_POSES_PER_TICK {
            self.taken[self.n_taken] = m;
            self.n_taken += 1;
        }
        m
    }
}

/// Marks the start of a typical tick for an instruction profiler (a QEMU
/// plugin with a per-address histogram between this function's address
/// and [`profile_end`]'s: `bench-m4/profile.sh`). Called outside the timed
/// region, so the counts are unchanged.
#[inline(never)]
fn profile_start() {
    black_box(());
}

/// Marks the end of a typical tick (see [`profile_start`]).
#[inline(never)]
fn profile_end() {
    black_box(1u32);
}

/// Per-tick counts of one run.
#[derive(Default)]
pub struct TickResult {
    /// `LoopTimer::tick` + `ControlLoop::tick`, every tick.
    pub tick_all: Stat,
    /// Ticks that took no pose measurement and had no re-propagation pending.
    pub tick_plain: Stat,
    /// Ticks that took (at least) one pose measurement.
    pub tick_correction: Stat,
    /// Ticks that continued a pending re-propagation (and took no measurement).
    pub tick_resume: Stat,
    /// `PoseEstimator::predict` alone (second estimator, same inputs).
    pub predict: Stat,
    /// `PoseEstimator::resume` alone (the pending re-propagation's slice).
    pub resume: Stat,
    /// `PoseEstimator::correct_within` alone (second estimator, same inputs).
    pub correct: Stat,
    /// `PoseEstimator::correct` (the whole re-propagation at once) on a
    /// third estimator fed the same inputs.
    pub correct_whole: Stat,
    /// Largest re-propagation seen \[ticks between stamp and now\].
    pub max_latency_ticks: u32,
    /// Pose measurements accepted by the loop.
    pub accepted: u32,
    /// Max position error of G after 10 s \[m\].
    pub max_pos_error_after_10s: f32,
}

/// 40 s of paper Case 2 through the firmware runtime with the proposed
/// controller, a gyro and the pose source `source`.
#[inline(never)]
pub fn run_tick<C: Counter>(c: &C, source: PoseSourceModel) -> TickResult {
    // The firmware's robot (ROBOT_FILE at build time, as the firmware
    // embeds it), derived as the firmware derives it (`Robot::derive`),
    // with PWM on the STM32F411's 96 MHz timer clock and the preset gyro's
    // saturation, starting where the simulator starts by default.
    let mut robot =
        robot_file::Robot::decode(include_bytes!(concat!(env!("OUT_DIR"), "/robot.bin")))
            .unwrap_or_else(|_| fail("robot file"));
    robot.control.controller = ControllerKind::Proposed;
    robot.control.initial_x_m = 2.5;
    let mut board = robot_file::BoardFacts::of_timer(&robot, 96_000_000)
        .unwrap_or_else(|_| fail("robot's PWM resolution"));
    board.gyro_saturation_radps = Some(PRESET_GYRO.saturation_radps as f32);
    let derived = robot.derive(
        &board,
        RuntimeConfig::example(ControllerKind::Proposed).reference,
    );
    let (cfg, est) = (derived.runtime, derived.estimator);
    let initial_pose = cfg.initial_pose;
    let mut control: ControlLoop<HISTORY_LEN> =
        ControlLoop::with_estimator(cfg, est).unwrap_or_else(|_| fail("runtime config"));
    let mut shadow: PoseEstimator<HISTORY_LEN> =
        PoseEstimator::with_history(est, cfg.controller.robot.com_offset_m, initial_pose)
            .unwrap_or_else(|_| fail("estimator config"));
    let mut whole = shadow.clone();
    let mut timer = LoopTimer::from_config(&cfg).unwrap_or_else(|_| fail("loop timer"));
    if control.arm().is_err() {
        fail("arm");
    }
    let dt = cfg.controller.period_s as f64;
    let period_us = timer.period_us();
    // The world's hardware: the runtime's encoders and motors, the MEMS
    // gyro and `source` (noise from seed 0).
    let mut world = case2_world(
        &cfg.controller.robot,
        dt,
        Instruments::Hardware(HardwareSensing {
            encoder: cfg.encoder,
            motor: cfg.motor,
            motor_inverted: cfg.motor_inverted,
            gyro: Some(PRESET_GYRO),
            pose_source: Some(source),
        }),
    );
    let mut driver = SimDriver::default();
    let mut enc = LatchedEncoders([0; 2]);
    let mut gyro_hw = LatchedGyro(None);
    let mut pose_hw = LatchedPoses {
        queue: [None; 8],
        head: 0,
        len: 0,
        taken: [None; MAX_POSES_PER_TICK],
        n_taken: 0,
    };
    let mut res = TickResult::default();
    let robot = cfg.controller.robot;
    for k in 0..TICKS {
        let t = k as f64 * dt;
        // The simulated sensors (not timed).
        let reading = world.sense(t);
        enc.0 = world.encoder_counts();
        gyro_hw.0 = world.gyro_sample();
        // Keep what the loop did not take last tick, then what arrived.
        let q = &mut pose_hw;
        let left = q.len - q.head;
        q.queue.copy_within(q.head..q.len, 0);
        q.head = 0;
        q.len = left;
        while q.len < q.queue.len() {
            match world.pose_measurement() {
                Some(m) => {
                    q.queue[q.len] = Some(m);
                    q.len += 1;
                }
                None => break,
            }
        }
        q.n_taken = 0;
        let now_us = k.wrapping_mul(period_us);
        // The tick, as the firmware runs it (timer and loop).
        let was_repropagating = control.estimator().is_repropagating();
        let typical = !was_repropagating && pose_hw.head == pose_hw.len;
        if typical {
            profile_start();
        }
        let t0 = c.now();
        let timing = timer.tick(black_box(now_us));
        let rep = control.tick(&mut enc, &mut driver, &mut gyro_hw, &mut pose_hw, timing);
        // By reference: the report stays where the tick wrote it (as in the
        // firmware); by value, black_box would time a second copy of it.
        black_box(&rep);
        let t1 = c.now();
        if typical {
            profile_end();
        }
        let counts = c.elapsed(t0, t1);
        res.tick_all.add(counts);
        if pose_hw.n_taken > 0 {
            res.tick_correction.add(counts);
        } else if was_repropagating {
            res.tick_resume.add(counts);
        } else {
            res.tick_plain.add(counts);
        }
        if rep.stopped.is_some() || !rep.motors_enabled {
            fail("tick: the runtime stopped");
        }
        if rep.external_pose {
            res.accepted += 1;
        }
        // The estimator alone: the same inputs as the loop's, timed.
        let inc = robot.eta_from_wheel_rates(rep.counts.dphi_rad);
        let g = gyro_hw.0;
        let args = (
            timing.now_us,
            timing.elapsed_s(),
            inc.v_mps,
            inc.omega_radps,
            g,
        );
        time(c, &mut res.predict, || {
            shadow.predict(
                black_box(args.0),
                black_box(args.1),
                black_box(args.2),
                black_box(args.3),
                black_box(args.4),
            );
        });
        whole.predict(args.0, args.1, args.2, args.3, args.4);
        let mut used = if shadow.is_repropagating() {
            time(c, &mut res.resume, || {
                shadow.resume(black_box(MAX_REPROPAGATION_PER_TICK))
            })
        } else {
            0
        };
        for m in pose_hw.taken[..pose_hw.n_taken].iter().flatten() {
            let lat = now_us.wrapping_sub(m.stamp_us) / period_us;
            res.max_latency_ticks = res.max_latency_ticks.max(lat);
            let budget = MAX_REPROPAGATION_PER_TICK - used;
            let r = time(c, &mut res.correct, || {
                shadow.correct_within(black_box(m), black_box(budget))
            });
            used += r.unwrap_or(0);
            let _ = time(c, &mut res.correct_whole, || whole.correct(black_box(m)));
        }
        if *shadow.estimate() != rep.estimate {
            fail("tick: the estimator alone differs from the loop's");
        }
        // Sliced and whole re-propagation agree once the slices are done.
        if !shadow.is_repropagating()
            && (shadow.estimate().filter_pose != whole.estimate().filter_pose
                || shadow.covariance() != whole.covariance())
        {
            fail("tick: sliced re-propagation differs from the whole one");
        }
        // The plant over [t, t + dt] with the bridge's output (not timed).
        let p = reading.true_pose;
        let e = [
            rep.reference.pose.x_m - p[0] as f32,
            rep.reference.pose.y_m - p[1] as f32,
        ];
        if t >= 10.0 {
            let pe = math::sqrt(e[0] * e[0] + e[1] * e[1]);
            res.max_pos_error_after_10s = res.max_pos_error_after_10s.max(pe);
        }
        if world.advance(Actuation::Bridge(driver), dt).is_err() {
            fail("plant diverged");
        }
    }
    res
}
