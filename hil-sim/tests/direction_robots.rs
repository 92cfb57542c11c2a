//! The runtime direction check (D74, D109, D111) on each example robot with
//! the thresholds its robot file derives (D110), with its untuned and its
//! tuned gains: a motor or an encoder wired backwards on either wheel
//! latches `DirectionMismatch` naming that wheel within two windows of
//! arming (`direction_block_ticks × direction_blocks` ticks, 80 ms, each;
//! the first may be the arming transient's, the second must latch: at most
//! 162 steps, the left wheel's verdict two ticks after a block's end),
//! before the robot has gone farther than the runaway can carry it in that
//! bound: a miswired wheel's torque is −τ_c − 2b·φ̇ (motor) or τ_c − 2b·φ̇
//! (encoder), so with |τ_c| ≤ the torque limit it cannot turn faster than
//! τ_max/(2b), and the robot's midpoint, half of each wheel's r·φ̇, not
//! faster than r·τ_max/(2b) while the healthy wheel follows the reference
//! (at most the reference's top speed, added); 10 cm at the least.
//!
//! Before D111 only the paper robot passed: the 2 kg TB6612 and the 10 kg
//! BTS7960 robots' miswired wheel runs at the torque limit into the
//! positive-feedback equilibrium φ̇ = −τ_c/(2b) within a block or two and
//! then stops accelerating, and D74's condition wanted a clear
//! acceleration against the torque in every block (on the 2 kg robot its
//! acceleration, ≈ 60 rad/s², is below one block's quantisation tolerance
//! of 89 rad/s² anyway). (Healthy runs of the same robots never stop:
//! `mismatch_sweep.rs`, the tune tests on robots/paper-2nm.tuned.toml.)

use controller_core::runtime::{MotorModel, StopReason, Wheel};
use controller_core::ControllerKind;
use hil_sim::closed_loop::run_loop;
use hil_sim::closed_loop::world::{hardware_world_miswired, Miswire};
use hil_sim::hil::RuntimeSide;
use hil_sim::scenario::Robot;
use hil_sim::sweep::base_scenario;
use sim_robot::world::Wiring;

fn robot(name: &str) -> Robot {
    let path = format!("{}/../robots/{name}.toml", env!("CARGO_MANIFEST_DIR"));
    Robot::from_toml_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every example robot file, untuned and tuned (the paper robot also at
/// the 2 N·m torque limit of its tuned file).
const ROBOTS: [&str; 7] = [
    "paper",
    "paper.tuned",
    "paper-2nm.tuned",
    "tb6612-2kg",
    "tb6612-2kg.tuned",
    "bts7960-10kg",
    "bts7960-10kg.tuned",
];

/// Cases known not to latch within the bound (printed, not asserted).
/// None today. D113's gap remains possible for some gains: an inverted
/// *encoder* on a strongly coupled body (W_ij = 0.6·W_ii for the paper
/// robot) under a controller that reverses both torques every ≈ 0.3 s
/// reads as the negated sum of both wheels' terms, near the correct
/// hypothesis (the check's inverted hypothesis flips only the wheel's own
/// term: exact for a backwards motor). The paper robot's earlier tuned
/// gains hit it (steps 201 and none); its re-tuned gains (D119) latch at
/// 81 and 142, so the case is asserted like every other.
const OPEN: [&str; 0] = [];

#[test]
fn a_backwards_wheel_stops_every_example_robot() {
    let mut failures = Vec::new();
    for name in ROBOTS {
        let r = robot(name);
        let scn = base_scenario(&r, 1, 2.0);
        let kind = ControllerKind::Proposed;
        let cfg = scn.runtime_config(scn.controller_config(kind), scn.safety_limits());
        let s = &cfg.safety;
        let window = s.direction_block_ticks as usize * s.direction_blocks as usize;
        let bound = 2 * window + 2;
        // How far the runaway can carry the robot within the bound (module
        // docs): the miswired wheel at most at τ_max/(2b), the healthy one
        // at most at the reference's top speed (half each at the midpoint).
        let b = MotorModel::new(cfg.motor)
            .unwrap()
            .back_emf_damping_nms_per_rad();
        let r_m = cfg.controller.robot.wheel_radius_m;
        let runaway_mps = 0.5 * r_m * cfg.controller.torque_limit_nm / (2.0 * b);
        let reference_mps = 0.5 * r.limits.max_speed_mps;
        let period_s = scn.control_period_s;
        let gone_bound_m =
            (f64::from(runaway_mps + reference_mps) * bound as f64 * period_s).max(0.1);
        println!(
            "{name}: direction check at {} N·m, {} rad/s², window {window} ticks: bound {bound} steps, {gone_bound_m:.3} m",
            s.direction_torque_nm, s.direction_accel_radps2
        );
        for wheel in [0usize, 1] {
            for motor in [true, false] {
                let mut wiring = Wiring::default();
                if motor {
                    wiring.motor_inverted[wheel] = true;
                } else {
                    wiring.encoder_inverted[wheel] = true;
                }
                let miswire = Miswire {
                    wiring,
                    counts_per_wheel_rev: None,
                };
                let mut world = hardware_world_miswired(&scn, &cfg, None, &miswire).unwrap();
                let est = scn.derive(kind).estimator;
                let mut side = RuntimeSide::new(cfg, est).unwrap();
                let out = run_loop(&scn, &mut world, &mut side, 1).unwrap();
                let what = format!(
                    "{name}, {} wheel, {} inverted",
                    ["right", "left"][wheel],
                    if motor { "motor" } else { "encoder" }
                );
                let open = OPEN.contains(&what.as_str());
                let Some((step, reason)) = out.stop else {
                    println!("{what}: no stop{}", if open { " (open, D113)" } else { "" });
                    if !open {
                        failures.push(format!("{what}: no stop"));
                    }
                    continue;
                };
                // Where the robot was when the check latched (trace every step).
                let (p0, p) = (out.trace[0].pose, out.trace[step].pose);
                let gone = (p[0] - p0[0]).hypot(p[1] - p0[1]);
                println!("{what}: {reason:?} at step {step}, {gone:.4} m gone");
                let named = StopReason::DirectionMismatch {
                    wheel: Wheel::BOTH[wheel],
                };
                if !open && (reason != named || step > bound || gone >= gone_bound_m) {
                    failures.push(format!("{what}: {reason:?} at step {step}, {gone} m"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
