//! The simulator's default integration (one RK4 step per 1 ms control
//! period, one sin/cos of θ per step, perturbation phasors rotated along the
//! half-step grid) against the reference integration: four RK4 sub-steps per
//! period. Both paper cases, all three controllers, two seeds.
//!
//! Stated tolerance (BENCHMARKS.md, "Host simulator"): every position metric
//! within 10 µm, the torque RMS within 1e-4 N·m, the settling time equal to
//! the millisecond. Measured: at most 0.7 µm and 1.2e-6 N·m, i.e. the size
//! of the difference between 2 and 4 sub-steps (the closed loop amplifies
//! rounding-level differences of the f32 controller to this level).

use controller_core::ControllerKind;
use hil_sim::{run, Scenario};

#[test]
fn one_substep_matches_four_within_tolerance() {
    for seed in [1, 2] {
        for case in [1, 2] {
            let fast = Scenario::paper_case(case, seed, None, None).as_printed();
            assert_eq!(fast.substeps, 1, "the default is what is checked");
            let fine = Scenario {
                substeps: 4,
                ..fast.clone()
            };
            for kind in ControllerKind::ALL {
                let a = run(&fast, kind).unwrap().metrics;
                let b = run(&fine, kind).unwrap().metrics;
                let pos = [
                    (a.rms_pos_err_m, b.rms_pos_err_m),
                    (a.rms_pos_err_window_m, b.rms_pos_err_window_m),
                    (a.max_pos_err_window_m, b.max_pos_err_window_m),
                    (a.rms_pos_err_after5_m, b.rms_pos_err_after5_m),
                    (a.final_pos_err_m, b.final_pos_err_m),
                ];
                for (i, (x, y)) in pos.iter().enumerate() {
                    assert!(
                        (x - y).abs() < 1e-5,
                        "case {case} seed {seed} {kind:?} metric {i}: {x} vs {y}"
                    );
                }
                assert!((a.torque_rms_nm - b.torque_rms_nm).abs() < 1e-4);
                assert_eq!(a.settling_time_s, b.settling_time_s, "{kind:?}");
            }
        }
    }
}
