//! The fast f32 math routines (the firmware default) keep closed-loop tracking
//! within 1 % of the accurate libm routines on the paper's Case 2.
//!
//! One test in its own binary: `math::select` is process-global.

use controller_core::math::{select, selected, MathImpl};
use controller_core::ControllerKind;
use hil_sim::{run, Scenario};

#[test]
fn fast_math_tracks_within_one_percent_of_accurate_math() {
    let mut any_difference = false;
    for seed in [1u64, 2] {
        let scn = Scenario::paper_case(2, seed, None, None);
        for kind in ControllerKind::ALL {
            assert!(select(MathImpl::Fast));
            assert_eq!(selected(), MathImpl::Fast);
            let fast = run(&scn, kind).unwrap().metrics;
            assert!(select(MathImpl::Accurate));
            assert_eq!(selected(), MathImpl::Accurate);
            let acc = run(&scn, kind).unwrap().metrics;
            select(MathImpl::Fast);
            any_difference |= fast != acc;
            for (name, f, a) in [
                ("rms_pos_err_m", fast.rms_pos_err_m, acc.rms_pos_err_m),
                (
                    "rms_pos_err_window_m",
                    fast.rms_pos_err_window_m,
                    acc.rms_pos_err_window_m,
                ),
                (
                    "max_pos_err_window_m",
                    fast.max_pos_err_window_m,
                    acc.max_pos_err_window_m,
                ),
            ] {
                let rel = (f - a).abs() / a;
                assert!(
                    rel < 0.01,
                    "seed {seed} {kind:?} {name}: fast {f:.5} accurate {a:.5} ({:.3} %)",
                    rel * 100.0
                );
            }
        }
    }
    // The switch really changes the arithmetic (else the bound above is vacuous).
    assert!(any_difference, "fast and accurate runs were bit-identical");
}
