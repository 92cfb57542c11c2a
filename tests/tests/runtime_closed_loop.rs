//! The firmware runtime closed directly through the simulated robot
//! (`sim_robot::World`: 16-bit encoders, an H-bridge with integer duty, the motor
//! model and the paper's plant), without the simulator's scenario machinery.
//! Checks sign conventions end to end (mirrored encoder and motor) and that
//! wheel odometry agrees with the truth when nothing slips.

use controller_core::runtime::{ControlLoop, RunState, RuntimeConfig, TickTiming};
use controller_core::trajectory::{Circle, Reference, Trajectory};
use controller_core::ControllerKind;
use sim_robot::world::Actuation;
use sim_robot::{World, WorldConfig};

/// Circle of radius 1.5 m at 0.5 m/s with the proposed controller, the
/// example motor (24 V) and encoders (24 000 counts/rev, left mirrored) and
/// a mirrored left motor: the chain must stay running, track within 2 cm
/// after the transient, and the odometry must agree with the true pose
/// (no slip) to within a few millimetres after two laps.
#[test]
fn quantized_closed_loop_tracks_a_circle() {
    let reference = Reference::Circle(Circle {
        radius_m: 1.5,
        speed_mps: 0.5,
    });
    let start = reference.sample(0.0).pose;
    let cfg = RuntimeConfig {
        reference,
        initial_pose: start,
        ..RuntimeConfig::example(ControllerKind::Proposed)
    };
    let mut cl = ControlLoop::new(cfg).unwrap();
    let dt = cfg.controller.period_s as f64;
    let mut world = World::new(&WorldConfig::of_runtime(&cfg)).unwrap();
    cl.arm().unwrap();
    let mut worst_late = 0.0f64;
    let mut lag_s = 0.0;
    let steps = 20_000; // 20 s, over two laps
    for k in 0..steps {
        world.sense(k as f64 * dt);
        let on_time = TickTiming::on_schedule(1000);
        let io = world.io();
        let rep = cl.tick(io.encoders, io.motors, io.gyro, io.pose_source, on_time);
        assert_eq!(rep.stopped, None, "tick {k}: {rep:?}");
        world
            .advance(Actuation::Bridge(world.bridge()), dt)
            .unwrap();
        let st = *world.state();
        lag_s = (k + 1) as f64 * dt - rep.pace.tau_s as f64;
        if k > 5_000 {
            // The governed reference the next tick tracks (τ ≤ t).
            let r = reference.sample(rep.pace.tau_s).pose;
            let err = (r.x_m as f64 - st.q[0]).hypot(r.y_m as f64 - st.q[1]);
            worst_late = worst_late.max(err);
        }
    }
    assert!(
        worst_late < 0.02,
        "tracking error after 5 s: {worst_late} m"
    );
    // The governor (on by default) slowed only for the start from rest
    // (0.48 s behind, measured).
    assert!(lag_s < 1.0, "reference {lag_s} s behind schedule");
    // No gyro, no pose source: the estimate is wheel odometry.
    let odo = cl.estimator().estimate().pose;
    let p = world.true_pose();
    let drift = (p[0] - odo.x_m as f64).hypot(p[1] - odo.y_m as f64);
    assert!(drift < 5e-3, "odometry drift {drift} m");
    assert_eq!(cl.state(), RunState::Running);
}

/// How a simulated robot is wired differently from what its runtime
/// configuration says.
#[derive(Clone, Copy, Debug)]
enum Miswired {
    /// This wheel's encoder counts the other way.
    Encoder(usize),
    /// This wheel's motor turns the other way.
    Motor(usize),
}

/// Runs the proposed controller on the circle for up to `seconds` against a
/// robot wired as `fault` says; returns the stop (tick, reason), the
/// largest distance of G from its start while driven \[m\] and at the end
/// (after the motors were cut and the robot coasted) \[m\], and the largest
/// true wheel speed \[rad/s\].
fn run_miswired(
    fault: Miswired,
    safety: controller_core::runtime::SafetyLimits,
    seconds: f64,
) -> (
    Option<(usize, controller_core::runtime::StopReason)>,
    f64,
    f64,
    f64,
) {
    use sim_robot::world::Instruments;
    let reference = Reference::Circle(Circle {
        radius_m: 1.5,
        speed_mps: 0.5,
    });
    let start = reference.sample(0.0).pose;
    let cfg = RuntimeConfig {
        reference,
        initial_pose: start,
        safety,
        ..RuntimeConfig::example(ControllerKind::Proposed)
    };
    let mut cl = ControlLoop::new(cfg).unwrap();
    let dt = cfg.controller.period_s as f64;
    let mut wc = WorldConfig::of_runtime(&cfg);
    if let Instruments::Hardware(hw) = &mut wc.instruments {
        match fault {
            Miswired::Encoder(w) => hw.encoder.inverted[w] = !hw.encoder.inverted[w],
            Miswired::Motor(w) => hw.motor_inverted[w] = !hw.motor_inverted[w],
        }
    }
    let mut world = World::new(&wc).unwrap();
    let p0 = world.true_pose();
    cl.arm().unwrap();
    let (mut stop, mut far_driven, mut top_rate) = (None, 0.0f64, 0.0f64);
    let mut phi = [world.state().q[3], world.state().q[4]];
    for k in 0..(seconds / dt) as usize {
        world.sense(k as f64 * dt);
        let io = world.io();
        let rep = cl.tick(
            io.encoders,
            io.motors,
            io.gyro,
            io.pose_source,
            TickTiming::on_schedule(1000),
        );
        if let Some(r) = rep.stopped {
            stop.get_or_insert((k, r));
        }
        world
            .advance(Actuation::Bridge(world.bridge()), dt)
            .unwrap();
        let p = world.true_pose();
        let d = (p[0] - p0[0]).hypot(p[1] - p0[1]);
        if stop.is_none() {
            far_driven = far_driven.max(d);
        }
        let q = world.state().q;
        for (i, a) in phi.iter_mut().enumerate() {
            top_rate = top_rate.max(((q[3 + i] - *a) / dt).abs());
            *a = q[3 + i];
        }
    }
    let p = world.true_pose();
    (
        stop,
        far_driven,
        (p[0] - p0[0]).hypot(p[1] - p0[1]),
        top_rate,
    )
}

/// Issue 18: an inversion flag that disagrees with the wiring (encoder or
/// motor, either wheel) gives positive feedback. The direction check stops
/// the robot within 0.3 s of arming (its window is 80 ms; the wheel
/// accelerates against its torque from the first ticks), naming the wheel,
/// before the robot has gone 5 cm, and no wheel ever exceeds 5 rad/s (the
/// plant is frictionless, so after the cut it coasts at the speed it had:
/// the bound on the wheel speeds is the bound on how far it goes).
/// Control: with the check off (65,535 blocks in a row to latch) the
/// same robot runs away: a wheel beyond 8 rad/s (measured: 8.9-19.4), and
/// no stop for more than 1 s (the health machine's LostPath after about
/// 3.4 s, measured), so the bounds above are the check's doing.
#[test]
fn miswired_wheel_stops_on_direction_mismatch_and_never_runs_away() {
    use controller_core::runtime::{SafetyLimits, StopReason, Wheel};
    let on = SafetyLimits::EXAMPLE;
    // Off: no run of blocks ever long enough (a torque tolerance beyond
    // any torque is refused now, D112).
    let off = SafetyLimits {
        direction_blocks: u16::MAX,
        ..on
    };
    for fault in [
        Miswired::Encoder(0),
        Miswired::Encoder(1),
        Miswired::Motor(0),
        Miswired::Motor(1),
    ] {
        let w = match fault {
            Miswired::Encoder(w) | Miswired::Motor(w) => w,
        };
        let (stop, driven, end, top) = run_miswired(fault, on, 2.0);
        println!(
            "{fault:?}: stop {stop:?}, driven {driven:.3} m, end {end:.3} m, top {top:.1} rad/s"
        );
        let (k, reason) = stop.unwrap_or_else(|| panic!("{fault:?}: never stopped"));
        assert_eq!(
            reason,
            StopReason::DirectionMismatch {
                wheel: Wheel::BOTH[w]
            },
            "{fault:?}"
        );
        assert!(k < 300, "{fault:?}: stopped only at tick {k}");
        assert!(driven < 0.05, "{fault:?}: went {driven} m before the stop");
        let _ = end; // frictionless plant: it coasts at the speed it had
        assert!(top < 5.0, "{fault:?}: a wheel reached {top} rad/s");

        let (stop, driven, _, top) = run_miswired(fault, off, 10.0);
        println!("  check off: stop {stop:?}, driven {driven:.3} m, top {top:.1} rad/s");
        let late_or_none = stop.is_none_or(|(k, _)| k > 1000);
        assert!(
            late_or_none && top > 8.0,
            "{fault:?}: the control did not run away ({stop:?}, {driven} m, {top} rad/s)"
        );
    }
}

/// Issue 18: the direction check never trips on a healthy robot. Both
/// paper cases with Monte-Carlo draws of the perturbations (β, ε per seed,
/// half of them with the plant's mass varied in [0.8, 1.2] as
/// `hil-sim montecarlo --vary-mass` draws it), every firmware sensing
/// preset and all three controllers, through the runtime the firmware runs:
/// no `DirectionMismatch`, and no other stop either. (The first form of
/// the check, torque sign against acceleration sign without the body's
/// coupling, tripped here on Case 1's start: D74.)
#[test]
fn healthy_runs_never_trip_the_direction_check() {
    use hil_sim::hil::{run_hil, HilOptions};
    use hil_sim::montecarlo::sample_scenario;
    use hil_sim::scenario::Sensing;
    let mut runs = 0;
    for case in [1u8, 2] {
        for i in 0..4u64 {
            for sensing in [
                Sensing::Odometry,
                Sensing::Imu,
                Sensing::Mocap,
                Sensing::Uwb,
            ] {
                let mut scn = sample_scenario(case, 1, i, i % 2 == 1);
                scn.sensing.preset = sensing;
                for kind in ControllerKind::ALL {
                    let out = run_hil(&scn, kind, HilOptions::default()).unwrap();
                    assert_eq!(
                        out.sim.stop, None,
                        "case {case} draw {i} {sensing:?} {kind:?}"
                    );
                    runs += 1;
                }
            }
        }
    }
    assert_eq!(runs, 2 * 4 * 4 * 3);
}
