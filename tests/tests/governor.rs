//! Issue 12's acceptance: the reference governor, the large-error bound of
//! the kinematic law and the health machine (the simulator's defaults,
//! beyond the paper) against the paper's setting, over several seeds.
//!
//! Seeds change the measurement noise (1 mm, 1 mrad) where β and ε are fixed
//! by the issue, and β, ε (drawn in the paper's ranges) in the paper cases.
//! Position error is measured against the reference the controller tracks
//! (at the governed time τ); `time_lag_final_s` reports how far τ is behind.

use controller_core::ControllerKind;
use hil_sim::{run, Scenario, SimOutput};

const SEEDS: [u64; 3] = [1, 2, 3];

/// Case 2 with the β = 0.1, ε = 0.2, seeded noise, governor on.
fn case2_fixed(seed: u64) -> Scenario {
    let mut s = Scenario::paper_case(2, seed, Some(0.1), Some(0.2));
    s.sensing.pose_noise_m = 0.001;
    s.sensing.heading_noise_rad = 0.001;
    s
}

fn metrics(scn: &Scenario, kind: ControllerKind) -> hil_sim::Metrics {
    let out = run(scn, kind).expect("run");
    assert_eq!(out.rejected_steps, 0);
    out.metrics
}

/// Torque headroom: at 5, 4 and 3 N·m the proposed controller's window RMS
/// is at most the ASMC's and its final error under 5 cm (today, without
/// the governor, it loses the path at 4 and 3 N·m: window RMS > 3 m).
#[test]
fn proposed_keeps_the_path_at_low_torque_limits() {
    for limit in [5.0, 4.0, 3.0] {
        for seed in SEEDS {
            let scn = {
                let mut s = case2_fixed(seed);
                s.plant.torque_limit_nm = Some(limit);
                s
            };
            let p = metrics(&scn, ControllerKind::Proposed);
            let a = metrics(&scn, ControllerKind::Asmc);
            assert!(
                p.rms_pos_err_window_m <= a.rms_pos_err_window_m,
                "{limit} N·m seed {seed}: proposed {:.4} asmc {:.4}",
                p.rms_pos_err_window_m,
                a.rms_pos_err_window_m
            );
            assert!(
                p.final_pos_err_m < 0.05,
                "{limit} N·m seed {seed}: final {:.4}",
                p.final_pos_err_m
            );
            assert_eq!(p.safe_stop, Some(false));
        }
    }
}

/// Both paper cases: the proposed controller settles (error < 0.1 m until
/// the window) no later than the best baseline, and its window RMS is at
/// most the paper setting's (no governor, eq. 14 as printed) + 10 %.
#[test]
fn clean_start_settles_first_without_losing_window_accuracy() {
    for case in [1u8, 2] {
        for seed in SEEDS {
            let scn = Scenario::paper_case(case, seed, None, None);
            let settle = |m: &hil_sim::Metrics| m.settling_time_s.expect("settles");
            let p = metrics(&scn, ControllerKind::Proposed);
            let s = metrics(&scn, ControllerKind::Smc);
            let a = metrics(&scn, ControllerKind::Asmc);
            let best = settle(&s).min(settle(&a));
            assert!(
                settle(&p) <= best,
                "case {case} seed {seed}: proposed settles at {:.3} s, best baseline {best:.3} s",
                settle(&p)
            );
            let today = metrics(&scn.clone().as_printed(), ControllerKind::Proposed);
            assert!(
                p.rms_pos_err_window_m <= 1.10 * today.rms_pos_err_window_m,
                "case {case} seed {seed}: window RMS {:.4} vs paper setting {:.4}",
                p.rms_pos_err_window_m,
                today.rms_pos_err_window_m
            );
        }
    }
}

/// The start from the paper's 3.35 m offset heads for the path: the
/// position error never grows above its initial value, and the robot does
/// not drive below y = −0.2 m before reaching the path (today it loops down
/// to about (2.3, −0.6) m).
#[test]
fn start_heads_for_the_path() {
    for case in [1u8, 2] {
        let scn = Scenario::paper_case(case, 1, None, None);
        for kind in ControllerKind::ALL {
            let out = run(&scn, kind).unwrap();
            let e0 = out.trace[0].pos_err_m;
            let start: Vec<_> = out.trace.iter().filter(|s| s.t_s < 3.0).collect();
            assert!(
                start.iter().all(|s| s.pos_err_m <= e0 + 1e-9),
                "case {case} {kind:?}: error grew above {e0:.3} m"
            );
            let y_min = start
                .iter()
                .map(|s| s.pose[1])
                .fold(f64::INFINITY, f64::min);
            assert!(y_min > -0.2, "case {case} {kind:?}: y down to {y_min:.3} m");
            // In the paper's setting the proposed controller does loop away.
            if kind == ControllerKind::Proposed {
                let printed = run(&scn.clone().as_printed(), kind).unwrap();
                let y_printed = printed
                    .trace
                    .iter()
                    .filter(|s| s.t_s < 3.0)
                    .map(|s| s.pose[1])
                    .fold(f64::INFINITY, f64::min);
                assert!(y_printed < -0.4, "paper setting: y_min {y_printed:.3}");
            }
        }
    }
}

/// The robot slowed inside the window: the time scale dropped below 0.9 or
/// the health machine left nominal there.
fn slowed_in_window(out: &SimOutput, scn: &Scenario) -> bool {
    out.trace.iter().any(|s| {
        s.t_s >= scn.perturbations.window_s[0]
            && s.t_s < scn.perturbations.window_s[1]
            && (s.time_scale < 0.9 || s.health > 0)
    })
}

/// A growing fault, ε ramped 0 → 0.6 over the window: the proposed
/// controller slows (degraded, reason published) and stays within 0.3 m of
/// the path over the window, without a safe stop; with the governor off the
/// same run leaves the path by more than 0.3 m.
#[test]
fn growing_fault_slows_and_keeps_the_path() {
    for seed in SEEDS {
        let scn = {
            let mut s = case2_fixed(seed);
            s.perturbations.eps = 0.0;
            s.perturbations.eps_end = Some(0.6);
            s
        };
        let out = run(&scn, ControllerKind::Proposed).unwrap();
        let m = &out.metrics;
        assert!(
            m.max_pos_err_window_m < 0.3,
            "seed {seed}: max window error {:.3}",
            m.max_pos_err_window_m
        );
        assert_eq!(m.safe_stop, Some(false), "seed {seed}");
        assert!(slowed_in_window(&out, &scn), "seed {seed}: never slowed");
        // The reason published while degraded late in the ramp is the fault.
        let late = out.trace.iter().filter(|s| s.t_s > 30.0 && s.t_s < 35.0);
        assert!(
            late.clone().any(|s| s.health == 1 && s.health_reason == 3),
            "seed {seed}: no actuator-fault degradation at ε > 0.5"
        );
        let off = run(&scn.clone().as_printed(), ControllerKind::Proposed).unwrap();
        assert!(
            off.metrics.max_pos_err_window_m > 0.3,
            "seed {seed}: the paper setting kept {:.3}",
            off.metrics.max_pos_err_window_m
        );
    }
}

/// A wheel losing half its torque inside the window, at a 5 N·m limit:
/// the proposed controller slows and stays within 0.3 m of the path
/// without a safe stop. (Without the governor the outcome depends on β, ε:
/// it keeps 0.13 m at β = 0.1, ε = 0.2 but loses the path, 4.9 m, at seed
/// 1's drawn β = 0.18, ε = 0.15; D22.)
#[test]
fn weak_wheel_slows_and_keeps_the_path() {
    for seed in SEEDS {
        let scn = {
            let mut s = case2_fixed(seed);
            s.plant.torque_limit_nm = Some(5.0);
            s.perturbations.wheel_torque_scale = [1.0, 0.5];
            s
        };
        let out = run(&scn, ControllerKind::Proposed).unwrap();
        let m = &out.metrics;
        assert!(
            m.max_pos_err_window_m < 0.3,
            "seed {seed}: max window error {:.3}",
            m.max_pos_err_window_m
        );
        assert!(
            m.final_pos_err_m < 0.05,
            "seed {seed}: final {:.3}",
            m.final_pos_err_m
        );
        assert_eq!(m.safe_stop, Some(false), "seed {seed}");
        assert!(slowed_in_window(&out, &scn), "seed {seed}: never slowed");
    }
}

/// Along every run above the trace's time scale is finite, in [0, 1], and
/// τ never runs ahead of t nor backwards (the closed-loop counterpart of
/// the pacer's property test).
#[test]
fn traced_time_scale_bounded_and_clock_never_ahead() {
    let scns = [
        case2_fixed(1),
        {
            let mut s = case2_fixed(2);
            s.plant.torque_limit_nm = Some(3.0);
            s
        },
        {
            let mut s = case2_fixed(3);
            s.perturbations.eps = 0.0;
            s.perturbations.eps_end = Some(0.6);
            s
        },
    ];
    for scn in scns {
        for kind in ControllerKind::ALL {
            let out = run(&scn, kind).unwrap();
            let mut tau_prev = 0.0;
            for s in &out.trace {
                assert!(s.time_scale.is_finite() && (0.0..=1.0).contains(&s.time_scale));
                assert!(s.tau_s >= tau_prev && s.tau_s <= s.t_s + 1e-6, "{s:?}");
                tau_prev = s.tau_s;
            }
        }
    }
}
