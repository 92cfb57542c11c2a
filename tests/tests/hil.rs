//! Hardware-in-the-loop on the host: the firmware runtime (encoder decoding,
//! speed estimate, odometry, controller, motor model, supervisor) closed
//! through integer encoder counts and integer PWM duty.

use controller_core::runtime::StopReason;
use controller_core::ControllerKind;
use hil_sim::hil::{run_hil, HilOptions};
use hil_sim::scenario::Sensing;
use hil_sim::{run, Scenario};

/// The quantised loop (24 000 counts/rev, 4-tick speed window, 4 800 duty
/// counts, back-EMF-limited motor) with motion capture (100 Hz, 10 ms late,
/// 2 mm) and a gyro still tracks the paper's Case 1: no safe stop, window
/// RMS below 10 cm and within 1.5x of the ideal-sensor run.
#[test]
fn quantised_loop_tracks_case1() {
    let ideal_scn = Scenario::paper_case(1, 1, None, None);
    let scn = {
        let mut s = ideal_scn.clone();
        s.sensing.preset = Sensing::Mocap;
        s
    };
    for kind in ControllerKind::ALL {
        let hil = run_hil(&scn, kind, HilOptions::default()).unwrap();
        assert_eq!(hil.sim.stop, None, "{kind:?}");
        let ideal = run(&ideal_scn, kind).unwrap().metrics;
        let m = &hil.sim.metrics;
        assert!(m.rms_pos_err_window_m < 0.1, "{kind:?}: {m:?}");
        assert!(
            m.rms_pos_err_window_m < 1.5 * ideal.rms_pos_err_window_m,
            "{kind:?}: HIL {:.4} vs ideal {:.4}",
            m.rms_pos_err_window_m,
            ideal.rms_pos_err_window_m
        );
        assert!(
            m.final_pos_err_m < 0.05,
            "{kind:?}: final {}",
            m.final_pos_err_m
        );
    }
}

/// Wheel odometry cannot see the actuator fault (the wheels turn as
/// commanded; the body does not follow): with odometry only, the proposed
/// controller's fault estimate stays near zero and the true tracking error in
/// Case 2 is much larger than with motion capture.
#[test]
fn odometry_cannot_see_the_actuator_fault() {
    let scn = {
        let mut s = Scenario::paper_case(2, 1, None, None);
        s.sensing.preset = Sensing::Mocap;
        s
    };
    let ext = run_hil(&scn, ControllerKind::Proposed, HilOptions::default()).unwrap();
    let odo_scn = {
        let mut s = scn.clone();
        s.sensing.preset = Sensing::Odometry;
        s
    };
    let odo = run_hil(&odo_scn, ControllerKind::Proposed, HilOptions::default()).unwrap();
    assert_eq!(ext.sim.stop, None);
    assert_eq!(odo.sim.stop, None);
    let (e, o) = (
        ext.sim.metrics.rms_pos_err_window_m,
        odo.sim.metrics.rms_pos_err_window_m,
    );
    assert!(o > 3.0 * e, "odometry {o:.3} vs external {e:.3}");
    let max_fhat_odo = odo
        .sim
        .trace
        .iter()
        .filter(|s| s.t_s > 12.0 && s.t_s < 35.0)
        .map(|s| s.f_hat[0].abs())
        .fold(0.0, f64::max);
    let rms_fault = {
        let v: Vec<f64> = ext
            .sim
            .trace
            .iter()
            .filter(|s| s.t_s > 12.0 && s.t_s < 35.0)
            .map(|s| s.f_true[0])
            .collect();
        (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
    };
    assert!(
        max_fhat_odo < 0.5 * rms_fault,
        "Δv̂ with odometry {max_fhat_odo:.3}, fault RMS {rms_fault:.3}"
    );
}

/// A dead encoder (broken wire at t = 12 s) is caught by the supervisor:
/// a latched stop for that wheel within the stall window, and zero torque from
/// then on.
#[test]
fn dead_encoder_latches_a_safe_stop() {
    let scn = {
        let mut s = Scenario::paper_case(1, 1, None, None);
        s.sensing.preset = Sensing::Mocap;
        s
    };
    let opts = HilOptions {
        dead_encoder: Some((1, 12.0)),
        ..HilOptions::default()
    };
    let out = run_hil(&scn, ControllerKind::Proposed, opts).unwrap();
    let (step, reason) = out.sim.stop.expect("the supervisor must stop");
    let t_stop = step as f64 * scn.control_period_s;
    assert!(
        matches!(
            reason,
            StopReason::EncoderStalled { .. } | StopReason::EncoderJump { .. }
        ),
        "{reason:?}"
    );
    assert!((12.0..13.0).contains(&t_stop), "stopped at {t_stop}");
    assert!(out
        .sim
        .trace
        .iter()
        .filter(|s| s.t_s > t_stop + 0.01)
        .all(|s| s.torque_nm == [0.0, 0.0]));
}
