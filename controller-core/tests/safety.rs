//! Bad input never panics and never reaches the output (property-based).

use controller_core::asmc::Switching;
use controller_core::trajectory::{PaperCurve, PaperHeading, RefSample, Trajectory};
use controller_core::{
    Controller, ControllerConfig, ControllerKind, InputFault, Pose, StepInput, Vel2,
};
use proptest::prelude::*;

/// Any f32 including NaN, ±inf, huge and tiny values.
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        3 => -20.0f32..20.0,
        1 => any::<f32>(),
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(1e30f32),
    ]
}

fn input() -> impl Strategy<Value = StepInput> {
    (
        any_f32(),
        any_f32(),
        any_f32(),
        any_f32(),
        any_f32(),
        any_f32(),
        any_f32(),
        0.0f32..40.0,
    )
        .prop_map(|(x, y, th, v, w, rv, rw, t)| {
            let mut reference = PaperCurve::paper(PaperHeading::SignedSmooth).sample(t);
            reference.v_dot_mps2 += rv * 1e-3;
            reference.omega_radps += rw * 1e-3;
            StepInput {
                reference,
                pose: Pose::new(x, y, th),
                eta: Vel2::new(v, w),
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Over random sequences of (often invalid) inputs, for every controller:
    /// outputs are finite and within the torque limit; an invalid input gives
    /// exactly zero torque and a fault flag.
    #[test]
    fn outputs_finite_and_limited(seq in proptest::collection::vec(input(), 1..60), k in 0usize..3) {
        let kind = ControllerKind::ALL[k];
        let cfg = ControllerConfig::paper(kind);
        let mut c = Controller::new(cfg).unwrap();
        for inp in &seq {
            let out = c.step(inp);
            for t in out.torque_nm {
                prop_assert!(t.is_finite());
                prop_assert!(t.abs() <= cfg.torque_limit_nm);
            }
            let valid = inp.pose.is_finite() && inp.eta.is_finite()
                && inp.pose.x_m.abs() <= 1000.0 && inp.pose.y_m.abs() <= 1000.0
                && inp.eta.v_mps.abs() <= 10.0 && inp.eta.omega_radps.abs() <= 30.0;
            if !valid {
                prop_assert_eq!(out.torque_nm, [0.0, 0.0]);
                prop_assert!(out.diag.fault.is_some());
            }
        }
    }
}

/// A NaN sample in the middle of a run is rejected (zero torque, flagged) and
/// the controller recovers: the next valid step gives the same torque as a
/// controller that never saw the NaN.
#[test]
fn recovers_after_a_nan_sample() {
    let cfg = ControllerConfig::paper(ControllerKind::Proposed);
    let mut a = Controller::new(cfg).unwrap();
    let mut b = Controller::new(cfg).unwrap();
    let traj = PaperCurve::paper(PaperHeading::SignedSmooth);
    let step = |t: f32| StepInput {
        reference: traj.sample(t),
        pose: Pose::new(2.5 + 0.1 * t, 0.0, 0.0),
        eta: Vel2::new(0.1, 0.0),
    };
    for k in 0..100 {
        let t = k as f32 * 1e-3;
        a.step(&step(t));
        b.step(&step(t));
    }
    let bad = StepInput {
        pose: Pose::new(f32::NAN, 0.0, 0.0),
        ..step(0.1)
    };
    let out = a.step(&bad);
    assert_eq!(out.torque_nm, [0.0, 0.0]);
    assert_eq!(out.diag.fault, Some(InputFault::NonFinitePose));
    assert_eq!(a.rejected_steps(), 1);
    let oa = a.step(&step(0.1));
    let ob = b.step(&step(0.1));
    assert_eq!(oa.torque_nm, ob.torque_nm);
    assert_eq!(oa.diag.fault, None);
}

/// Where the three laws should agree, they do, to the bit: on a first step
/// (observers not yet primed: F̂ = 0, D̂ = 0) the proposed law equals ASMC with
/// the same k_s, and SMC with K = ρ0 equals ASMC.
#[test]
fn baselines_and_proposed_agree_with_zero_observer_states() {
    let traj = PaperCurve::paper(PaperHeading::SignedSmooth);
    let inp = StepInput {
        reference: traj.sample(3.0),
        pose: Pose::new(2.9, 0.4, 0.5),
        eta: Vel2::new(0.3, -0.2),
    };
    let p_cfg = ControllerConfig::paper(ControllerKind::Proposed);
    let mut a_cfg = ControllerConfig::paper(ControllerKind::Asmc);
    a_cfg.sliding.k_s = p_cfg.sliding.k_s;
    let p = Controller::new(p_cfg).unwrap().step(&inp);
    let a = Controller::new(a_cfg).unwrap().step(&inp);
    assert_eq!(p.torque_nm, a.torque_nm);

    let a_cfg = ControllerConfig::paper(ControllerKind::Asmc);
    let Switching::Adaptive(ad) = a_cfg.sliding.switching else {
        panic!()
    };
    let mut s_cfg = ControllerConfig::paper(ControllerKind::Smc);
    s_cfg.sliding.switching = Switching::Fixed(ad.rho0);
    let a = Controller::new(a_cfg).unwrap().step(&inp);
    let s = Controller::new(s_cfg).unwrap().step(&inp);
    assert_eq!(a.torque_nm, s.torque_nm);
    // And the law is not trivially zero here.
    assert!(a.torque_nm[0].abs() > 1e-3);
}

/// Invalid configurations are rejected at construction with a clear variant.
#[test]
fn invalid_configs_rejected() {
    use controller_core::ConfigError;
    let mut c = ControllerConfig::paper(ControllerKind::Proposed);
    c.torque_limit_nm = 0.0;
    assert_eq!(
        Controller::new(c).err(),
        Some(ConfigError::NonPositiveTorqueLimit)
    );
    let mut c = ControllerConfig::paper(ControllerKind::Proposed);
    c.period_s = f32::NAN;
    assert_eq!(Controller::new(c).err(), Some(ConfigError::InvalidPeriod));
    let mut c = ControllerConfig::paper(ControllerKind::Asmc);
    c.robot.mass_kg = 0.0;
    assert_eq!(Controller::new(c).err(), Some(ConfigError::NonPositiveMass));
    let mut c = ControllerConfig::paper(ControllerKind::Smc);
    c.kinematic.k_th = -1.0;
    assert_eq!(Controller::new(c).err(), Some(ConfigError::NonPositiveGain));
}

/// Saturation: a huge tracking error asks for far more than the limit; the
/// output is the request scaled by one common factor (steering ratio kept).
#[test]
fn saturation_scales_both_wheels_together() {
    let cfg = ControllerConfig::paper(ControllerKind::Smc);
    let mut c = Controller::new(cfg).unwrap();
    let reference = RefSample {
        pose: Pose::new(50.0, 30.0, 1.0),
        ..RefSample::default()
    };
    let out = c.step(&StepInput {
        reference,
        pose: Pose::default(),
        eta: Vel2::default(),
    });
    let d = out.diag;
    assert!(d.saturated);
    let peak = out.torque_nm[0].abs().max(out.torque_nm[1].abs());
    assert!((peak - cfg.torque_limit_nm).abs() < 1e-4);
    let r_req = d.torque_request_nm[0] / d.torque_request_nm[1];
    let r_out = out.torque_nm[0] / out.torque_nm[1];
    assert!((r_req - r_out).abs() < 1e-4 * r_req.abs().max(1.0));
}

/// Anti-windup: while the output saturates, ∫e_η and ρ̂ are frozen, i.e.
/// s − e_η = k_s·∫e_η and ρ̂ do not change from step to step.
#[test]
fn integral_and_gain_frozen_while_saturated() {
    let cfg = ControllerConfig::paper(ControllerKind::Proposed);
    let mut c = Controller::new(cfg).unwrap();
    let reference = RefSample {
        pose: Pose::new(40.0, -30.0, 0.0),
        v_mps: 1.0,
        ..RefSample::default()
    };
    let eta = Vel2::new(0.2, 0.1);
    let mut first: Option<([f32; 2], [f32; 2])> = None;
    for _ in 0..2000 {
        let out = c.step(&StepInput {
            reference,
            pose: Pose::default(),
            eta,
        });
        let d = out.diag;
        assert!(d.saturated);
        let integ = [
            d.s[0] - (d.eta_c[0] - eta.v_mps),
            d.s[1] - (d.eta_c[1] - eta.omega_radps),
        ];
        match first {
            None => first = Some((integ, d.rho_hat)),
            Some((i0, r0)) => {
                assert!((integ[0] - i0[0]).abs() < 1e-4 && (integ[1] - i0[1]).abs() < 1e-4);
                assert_eq!(d.rho_hat, r0);
            }
        }
    }
}

/// Regression (found by `outputs_finite_and_limited`): limit/peak·request
/// exceeded the limit by one ulp for this input.
#[test]
fn saturated_output_never_exceeds_limit_by_rounding() {
    let cfg = ControllerConfig::paper(ControllerKind::Proposed);
    let mut c = Controller::new(cfg).unwrap();
    let reference = RefSample {
        pose: Pose::new(3.342_146_4, -0.520_157_75, 1.327_749_4),
        v_mps: -1.826_417_3,
        omega_radps: -0.112_361_84,
        v_dot_mps2: 0.139_943_02,
        omega_dot_radps2: -0.090_426_49,
    };
    let out = c.step(&StepInput {
        reference,
        pose: Pose::new(0.0, 0.0, 7.945_395_5),
        eta: Vel2::default(),
    });
    assert!(out.diag.saturated);
    for t in out.torque_nm {
        assert!(t.abs() <= cfg.torque_limit_nm);
    }
}
