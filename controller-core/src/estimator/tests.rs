//! Tests of the pose estimator: analytic cases, the delayed-measurement
//! equivalence, gating, the reasons for rejection and, by property test,
//! finite output for any input sequence.

use super::*;
use core::f32::consts::PI;
use proptest::prelude::*;

const D: f32 = 0.05;
const DT: f32 = 1e-3;

/// The example tuning with G at `p`, `D` ahead of the axle.
fn est_at(cfg: EstimatorConfig, p: Pose) -> PoseEstimator {
    PoseEstimator::new(cfg, D, p).unwrap()
}

fn est() -> PoseEstimator {
    est_at(EstimatorConfig::EXAMPLE, Pose::new(0.0, 0.0, 0.0))
}

fn meas(stamp_us: u32, pose: Pose, heading: bool) -> PoseMeasurement {
    PoseMeasurement {
        stamp_us,
        pose,
        position_std_m: 0.002,
        heading_std_rad: heading.then_some(0.005),
    }
}

fn gyro(rate: f32, stamp_us: u32) -> Option<GyroSample> {
    Some(GyroSample {
        rate_radps: rate,
        stamp_us,
    })
}

#[test]
fn invalid_config_rejected() {
    let ok = EstimatorConfig::EXAMPLE;
    let origin = Pose::new(0.0, 0.0, 0.0);
    assert!(PoseEstimator::new(ok, D, origin).is_ok());
    // The start and the geometry the owner passes are checked too.
    assert_eq!(
        PoseEstimator::new(ok, D, Pose::new(f32::NAN, 0.0, 0.0)).err(),
        Some(EstimatorConfigError::NonFinitePose)
    );
    assert_eq!(
        PoseEstimator::new(ok, f32::INFINITY, origin).err(),
        Some(EstimatorConfigError::NonFinitePose)
    );
    let bad = [
        EstimatorConfig {
            gyro_noise_density: 0.0,
            ..ok
        },
        EstimatorConfig {
            slip_fraction: -1.0,
            ..ok
        },
        EstimatorConfig {
            chi2_gate_3dof: f32::INFINITY,
            ..ok
        },
        EstimatorConfig {
            gyro_stale_us: 0,
            ..ok
        },
        EstimatorConfig {
            max_consecutive_outliers: 0,
            ..ok
        },
    ];
    for b in bad {
        assert!(PoseEstimator::new(b, D, origin).is_err(), "{b:?}");
    }
}

/// Without a gyro and corrections the estimate is wheel odometry: a circle
/// driven by constant wheel increments ends where the odometry ends.
#[test]
fn without_gyro_it_is_wheel_odometry() {
    let robot = crate::RobotParams::paper();
    let mut o = crate::runtime::Odometry::new(robot, Pose::new(0.05, 0.0, 0.3));
    let mut e = PoseEstimator::new(
        EstimatorConfig::EXAMPLE,
        robot.com_offset_m,
        Pose::new(0.05, 0.0, 0.3),
    )
    .unwrap();
    let dphi = [0.004f32, 0.002];
    let inc = robot.eta_from_wheel_rates(dphi);
    for k in 1..=5000u32 {
        o.update(dphi);
        e.predict(k * 1000, DT, inc.v_mps, inc.omega_radps, None);
    }
    let (a, b) = (o.pose(), e.estimate().pose);
    assert!((a.x_m - b.x_m).abs() < 1e-4 && (a.y_m - b.y_m).abs() < 1e-4);
    assert!(wrap_angle(a.theta_rad - b.theta_rad).abs() < 1e-5);
    assert_eq!(e.status().gyro, GyroState::Absent);
}

/// The gyro sees a yaw the wheels do not (the body skids round while the
/// wheels roll straight): the heading follows the gyro.
#[test]
fn gyro_heading_beats_wheels() {
    let mut e = est();
    let w = 0.5f32; // true body yaw rate, wheels say 0
    for k in 1..=1000u32 {
        e.predict(k * 1000, DT, 0.0005, 0.0, gyro(w, k * 1000));
    }
    let th = e.estimate().pose.theta_rad;
    assert!((th - 0.5).abs() < 2e-3, "{th}");
    assert_eq!(e.status().gyro, GyroState::Ok);
}

/// Standing still for 3 s with a gyro bias of 0.02 rad/s: the zero-rate
/// updates find the bias, and the heading drifts far less than bias·t.
#[test]
fn bias_found_at_standstill() {
    let mut e = est();
    let bias = 0.02f32;
    for k in 1..=3000u32 {
        e.predict(k * 1000, DT, 0.0, 0.0, gyro(bias, k * 1000));
    }
    let st = e.status();
    assert!((st.gyro_bias_radps - bias).abs() < 1e-3, "{st:?}");
    assert!(st.standstill_updates > 2000);
    // Without estimation the heading would be off by 0.06 rad.
    assert!(
        e.estimate().pose.theta_rad.abs() < 0.01,
        "{:?}",
        e.estimate()
    );
}

/// Driving a circle for 40 s with a biased gyro and heading-free position
/// fixes at 10 Hz: the bias becomes observable through the position track.
#[test]
fn bias_found_online_from_position_fixes() {
    let mut e = est();
    let (v, w, bias) = (0.5f32, 0.4f32, 0.03f32);
    let (mut x, mut y, mut th) = (0.0f32, 0.0f32, 0.0f32);
    for k in 1..=40_000u32 {
        let now = k * 1000;
        let ds = v * DT;
        let (s, c) = (th + 0.5 * w * DT).sin_cos();
        x += ds * c;
        y += ds * s;
        th = wrap_angle(th + w * DT);
        e.predict(now, DT, ds, w * DT, gyro(w + bias, now));
        if k % 100 == 0 {
            let g = Pose::new(x + D * th.cos(), y + D * th.sin(), th);
            let mut m = meas(now, g, false);
            m.position_std_m = 0.01;
            e.correct(&m).unwrap();
        }
    }
    let b = e.status().gyro_bias_radps;
    assert!((b - bias).abs() < 3e-3, "bias {b}");
    let eth = wrap_angle(e.estimate().pose.theta_rad - th);
    // Uncorrected, the bias would have turned the heading by 1.2 rad.
    assert!(eth.abs() < 0.05, "heading error {eth}");
}

/// Gyro fallbacks: absent, non-finite, saturated and stale samples are
/// refused, and the wheel yaw rate is used instead.
#[test]
fn gyro_fallbacks_reported_and_wheel_rate_used() {
    let cases = [
        (None, GyroState::Absent),
        (gyro(f32::NAN, 1000), GyroState::NonFinite),
        (gyro(1e9, 1000), GyroState::Saturated),
        (gyro(0.3, 0), GyroState::Stale),
    ];
    for (g, want) in cases {
        let mut e = est();
        let mut now = 0;
        for _ in 0..100 {
            now += 1000;
            let g = g.map(|s| GyroSample {
                stamp_us: if want == GyroState::Stale { 0 } else { now },
                ..s
            });
            e.predict(now.max(30_000), DT, 0.0, 0.001, g);
        }
        assert_eq!(e.status().gyro, want);
        assert!((e.estimate().pose.theta_rad - 0.1).abs() < 1e-4);
        assert!((e.estimate().yaw_rate_radps - 1.0).abs() < 1e-3);
    }
}

/// A static robot measured n times with position std σ: the posterior
/// variance of x is 1/(1/P0 + n/σ²) (the Kalman filter of a constant).
#[test]
fn static_position_variance_matches_information_sum() {
    let mut c = EstimatorConfig::EXAMPLE;
    c.speed_noise_mps_per_sqrt_hz = 1e-9;
    c.wheel_yaw_noise = 1e-9;
    c.gyro_noise_density = 1e-9;
    let mut e = PoseEstimator::new(c, 0.0, Pose::new(1.0, 2.0, 0.0)).unwrap();
    let sigma = 0.01f32;
    let n = 20;
    for k in 1..=n {
        e.predict(k * 1000, DT, 0.0, 0.0, None);
        let mut m = meas(k * 1000, Pose::new(1.0, 2.0, 0.0), false);
        m.position_std_m = sigma;
        e.correct(&m).unwrap();
    }
    let p0 = 0.05f32 * 0.05;
    let want = 1.0 / (1.0 / p0 + n as f32 / (sigma * sigma));
    let got = e.status().covariance_diag[0];
    assert!((got / want - 1.0).abs() < 1e-3, "{got} vs {want}");
}

/// Drives an S-curve with a biased gyro; measurements taken every `every`
/// ticks are delivered `delay` ticks later (0 = on time). Returns the
/// estimator at the end.
fn s_curve(every: u32, delay: u32, ticks: u32) -> PoseEstimator {
    s_curve_until(every, delay, ticks, ticks)
}

/// [`s_curve`] with measurements taken only up to tick `last`.
fn s_curve_until(every: u32, delay: u32, ticks: u32, last: u32) -> PoseEstimator {
    s_curve_sliced(every, delay, ticks, last, None)
}

/// [`s_curve_until`]; with `Some(budget)`, corrections re-propagate at most
/// `budget` ticks per tick ([`PoseEstimator::correct_within`] and
/// [`PoseEstimator::resume`], as the runtime calls them) and a measurement
/// waits while a re-propagation is pending.
fn s_curve_sliced(
    every: u32,
    delay: u32,
    ticks: u32,
    last: u32,
    budget: Option<usize>,
) -> PoseEstimator {
    let mut e = est();
    let mut pending: [Option<(u32, PoseMeasurement)>; 64] = [None; 64];
    let (mut x, mut y, mut th) = (0.0f32, 0.0f32, 0.0f32);
    for k in 1..=ticks {
        let now = k * 1000;
        let t = k as f32 * DT;
        let (v, w) = (0.6, 0.8 * (0.7 * t).sin());
        let ds = v * DT;
        let (s, c) = (th + 0.5 * w * DT).sin_cos();
        x += ds * c;
        y += ds * s;
        th += w * DT;
        // Wheels slip by 20 % (they over-report), the gyro is biased.
        e.predict(now, DT, 1.2 * ds, 1.1 * w * DT, gyro(w + 0.01, now));
        let mut used = budget.map_or(0, |b| e.resume(b));
        if k % every == 0 && k <= last {
            let g = Pose::new(x + D * th.cos(), y + D * th.sin(), wrap_angle(th));
            let slot = pending.iter_mut().find(|p| p.is_none()).unwrap();
            *slot = Some((k + delay, meas(now, g, true)));
        }
        // Deliver, oldest first.
        loop {
            let due = pending
                .iter_mut()
                .filter(|p| p.is_some_and(|(at, _)| at <= k))
                .min_by_key(|p| p.unwrap().1.stamp_us);
            match (due, budget) {
                (_, Some(_)) if e.is_repropagating() => break,
                (Some(p), None) => {
                    let (_, m) = p.take().unwrap();
                    e.correct(&m).unwrap();
                }
                (Some(p), Some(b)) => {
                    let (_, m) = p.take().unwrap();
                    used += e.correct_within(&m, b - used).unwrap();
                }
                (None, _) => break,
            }
        }
    }
    e
}

/// The estimate at *now* is the same whether the measurements arrived on
/// time or 250 ms late (re-propagation repeats the forward arithmetic; stated
/// tolerance 1 µm, 1 µrad, and the covariance to 1e-6 relative).
#[test]
fn late_measurements_equal_on_time_ones() {
    for (every, delay) in [(10, 250), (10, 37), (100, 250), (5, 249)] {
        let ticks = 3000 + delay; // the last late ones have arrived
        let on_time = s_curve_until(every, 0, ticks, 3000);
        let late = s_curve_until(every, delay, ticks, 3000);
        let (a, b) = (on_time.estimate().filter_pose, late.estimate().filter_pose);
        assert!(
            (a.x_m - b.x_m).abs() < 1e-6 && (a.y_m - b.y_m).abs() < 1e-6,
            "{every}/{delay}: {a:?} vs {b:?}"
        );
        assert!(wrap_angle(a.theta_rad - b.theta_rad).abs() < 1e-6);
        let (pa, pb) = (on_time.covariance(), late.covariance());
        for i in 0..4 {
            assert!((pa[i][i] - pb[i][i]).abs() <= 1e-6 * pa[i][i].abs().max(1e-12));
        }
        assert_eq!(on_time.status().accepted, late.status().accepted);
    }
}

/// Re-propagating in slices of a few ticks per tick (what the runtime
/// does, to bound a tick's cost) ends in exactly the state and covariance
/// of the whole re-propagation at once, for latencies up to the history.
#[test]
fn sliced_repropagation_equals_whole() {
    // Rates the slices keep up with: a correction `delay` late takes about
    // delay / (budget − 1) ticks, less than the time between measurements.
    for (every, delay, budget) in [(10, 37, 8), (20, 250, 24), (100, 250, 4), (5, 249, 64)] {
        // Enough ticks after the last measurement for the slices to finish.
        let ticks = 3000 + delay + 300;
        let whole = s_curve_sliced(every, delay, ticks, 3000, None);
        let sliced = s_curve_sliced(every, delay, ticks, 3000, Some(budget));
        assert!(!sliced.is_repropagating());
        let bits = |e: &PoseEstimator| {
            let f = e.estimate().filter_pose;
            let p = e.covariance().map(|r| r.map(f32::to_bits));
            ([f.x_m, f.y_m, f.theta_rad].map(f32::to_bits), p)
        };
        assert_eq!(bits(&whole), bits(&sliced), "{every}/{delay}/{budget}");
        assert_eq!(whole.status().accepted, sliced.status().accepted);
        assert_eq!(whole.status().accepted, 3000 / every);
    }
}

/// And the fused estimate is close to the truth although the wheels slip by
/// 20 %: corrections work (on-time case; the late one is equal).
#[test]
fn fused_estimate_tracks_truth_through_slip() {
    let e = s_curve(10, 0, 3000);
    let odo_only = s_curve(100_000, 0, 3000);
    // Truth at t = 3 s: recompute by the same integration as s_curve.
    let (mut x, mut y, mut th) = (0.0f32, 0.0f32, 0.0f32);
    for k in 1..=3000u32 {
        let t = k as f32 * DT;
        let w = 0.8 * (0.7 * t).sin();
        let (s, c) = (th + 0.5 * w * DT).sin_cos();
        x += 0.6 * DT * c;
        y += 0.6 * DT * s;
        th += w * DT;
    }
    let err = |p: Pose| (p.x_m - x - D * th.cos()).hypot(p.y_m - y - D * th.sin());
    assert!(err(e.estimate().pose) < 0.005, "{}", err(e.estimate().pose));
    // Without fixes: the gyro-vs-wheel yaw (D36) takes the speed scale to
    // 1/1.1 (the wheels' yaw over-reports by 10 %), so the distance is still
    // about 9 % long over the 1.8 m (0.15 m; 0.3 m with the scale at 1).
    assert!(
        err(odo_only.estimate().pose) > 0.1,
        "{}",
        err(odo_only.estimate().pose)
    );
}

/// The controller's pose takes a correction's jump with the time
/// constant output_smoothing_s: after τ, 1/e of the jump remains (to 1 %,
/// the per-tick factor 1/(1 + dt/τ) against exp(−dt/τ)); the filter's pose
/// jumps at once.
#[test]
fn output_smoothing_spreads_a_jump_over_its_time_constant() {
    let mut e = est();
    let tau = e.config().output_smoothing_s;
    e.predict(1000, DT, 0.0, 0.0, None);
    let before = e.estimate().pose;
    e.correct(&meas(1000, Pose::new(0.09, 0.02, 0.0), true))
        .unwrap();
    let jump = e.estimate().filter_pose.x_m - before.x_m;
    assert!(jump > 0.03, "{jump}");
    assert_eq!(e.estimate().pose, before);
    let n = (tau / DT).round() as u32;
    for k in 2..=(n + 1) {
        e.predict(k * 1000, DT, 0.0, 0.0, None);
    }
    let left = (e.estimate().filter_pose.x_m - e.estimate().pose.x_m) / jump;
    assert!((left - (-1.0f32).exp()).abs() < 0.01 * 0.37, "{left}");
}

/// With wheels over-reporting the distance by 20 % and mocap at 100 Hz,
/// the speed scale converges to 1/1.2.
#[test]
fn speed_scale_learns_wheel_over_reporting() {
    let e = s_curve(10, 0, 10_000);
    let k = e.status().speed_scale;
    assert!((k - 1.0 / 1.2).abs() < 0.02, "{k}");
}

#[test]
fn rejections_have_reasons() {
    let mut e = est();
    let p = Pose::new(0.05, 0.0, 0.0);
    assert_eq!(e.correct(&meas(0, p, true)), Err(RejectReason::TooOld));
    for k in 1..=300u32 {
        e.predict(k * 1000, DT, 0.0, 0.0, None);
    }
    let now = 300_000;
    assert_eq!(
        e.correct(&meas(now + 1, p, true)),
        Err(RejectReason::FromFuture)
    );
    assert_eq!(
        e.correct(&meas(now - 280_000, p, true)),
        Err(RejectReason::TooOld)
    );
    let nan = Pose::new(f32::NAN, 0.0, 0.0);
    assert_eq!(
        e.correct(&meas(now, nan, true)),
        Err(RejectReason::NonFinite)
    );
    for bad_std in [0.0, -1.0, f32::NAN] {
        let mut m = meas(now, p, true);
        m.position_std_m = bad_std;
        assert_eq!(e.correct(&m), Err(RejectReason::BadStdDev));
        let mut m = meas(now, p, true);
        m.heading_std_rad = Some(bad_std);
        assert_eq!(e.correct(&m), Err(RejectReason::BadStdDev));
    }
    assert_eq!(e.correct(&meas(now - 10_000, p, true)), Ok(()));
    assert_eq!(
        e.correct(&meas(now - 20_000, p, true)),
        Err(RejectReason::OutOfOrder)
    );
    let far = Pose::new(1.05, 0.0, 0.0);
    assert_eq!(e.correct(&meas(now, far, true)), Err(RejectReason::Outlier));
    let r = e.status().rejected;
    assert_eq!(
        (r.too_old, r.from_future, r.non_finite, r.bad_std_dev),
        (2, 1, 1, 6)
    );
    assert_eq!((r.out_of_order, r.outlier, r.total()), (1, 1, 12));
    assert_eq!(e.status().accepted, 1);
    // The outlier moved nothing.
    assert!(e.estimate().pose.x_m.abs() - 0.05 < 0.01);
}

/// Heading across ±π: the innovation is wrapped, so a measurement of
/// π − 0.01 for an estimate of −π + 0.01 is a 0.02 rad correction.
#[test]
fn heading_innovation_wraps() {
    let th0 = -PI + 0.01;
    let mut e = est_at(EstimatorConfig::EXAMPLE, Pose::new(0.0, 0.0, th0));
    e.predict(1000, DT, 0.0, 0.0, None);
    let g = e.estimate().pose;
    let m = meas(1000, Pose::new(g.x_m, g.y_m, PI - 0.01), true);
    e.correct(&m).unwrap();
    let inn = e.status().last_innovation[2];
    assert!((inn + 0.02).abs() < 1e-4, "{inn}");
    let th = e.estimate().pose.theta_rad;
    assert!(th > -PI && th <= PI);
    assert!(wrap_angle(th - (PI - 0.01)).abs() < 0.02);
}

/// After many gated measurements in a row (the estimate drifted during an
/// outage), the covariance is reset and the estimate jumps to the source.
#[test]
fn drifted_estimate_recovers_after_consecutive_outliers() {
    let mut e = est();
    for k in 1..=200u32 {
        e.predict(k * 1000, DT, 0.0, 0.0, None);
    }
    let truth = Pose::new(2.0, 1.0, 0.5);
    let max = e.config().max_consecutive_outliers as u32;
    for i in 0..max {
        let r = e.correct(&meas(100_000 + i * 1000, truth, true));
        if i + 1 < max {
            assert_eq!(r, Err(RejectReason::Outlier));
        } else {
            assert_eq!(r, Ok(()));
        }
    }
    assert_eq!(e.status().resets, 1);
    let p = e.estimate().pose;
    assert!(
        (p.x_m - 2.0).abs() < 0.01 && (p.y_m - 1.0).abs() < 0.01,
        "{p:?}"
    );
}

#[derive(Clone, Debug)]
enum Op {
    Predict {
        dt_us: u32,
        ds: f32,
        dth: f32,
        gyro: Option<(f32, i32)>,
    },
    Correct {
        age_us: i32,
        x: f32,
        y: f32,
        th: f32,
        pos_std: f32,
        head_std: Option<f32>,
    },
}

fn wild() -> impl Strategy<Value = f32> {
    prop_oneof![
        -10.0f32..10.0,
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(-f32::INFINITY),
        Just(1e30f32),
        Just(-1e30f32),
        Just(0.0f32),
        Just(-1.0f32),
    ]
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (
            0u32..300_000,
            wild(),
            wild(),
            proptest::option::of((wild(), -50_000i32..50_000))
        )
            .prop_map(|(dt_us, ds, dth, gyro)| Op::Predict {
                dt_us,
                ds,
                dth,
                gyro
            }),
        (
            -10_000i32..400_000,
            wild(),
            wild(),
            wild(),
            wild(),
            proptest::option::of(wild())
        )
            .prop_map(|(age_us, x, y, th, pos_std, head_std)| Op::Correct {
                age_us,
                x,
                y,
                th,
                pos_std,
                head_std
            }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]
    /// No input sequence (NaN or huge gyro, NaN pose, zero or negative
    /// std devs, out-of-order, future or too-old stamps, zero or huge dt)
    /// makes the estimate, the covariance or the status non-finite.
    #[test]
    fn output_always_finite(ops in proptest::collection::vec(op(), 1..400)) {
        let mut e = est();
        let mut now: u32 = u32::MAX - 100_000; // crosses the u32 wrap
        for o in ops {
            match o {
                Op::Predict { dt_us, ds, dth, gyro } => {
                    now = now.wrapping_add(dt_us);
                    let g = gyro.map(|(r, off)| GyroSample {
                        rate_radps: r,
                        stamp_us: now.wrapping_add(off as u32),
                    });
                    e.predict(now, dt_us as f32 * 1e-6, ds, dth, g);
                }
                Op::Correct { age_us, x, y, th, pos_std, head_std } => {
                    let _ = e.correct(&PoseMeasurement {
                        stamp_us: now.wrapping_sub(age_us as u32),
                        pose: Pose::new(x, y, th),
                        position_std_m: pos_std,
                        heading_std_rad: head_std,
                    });
                }
            }
            let est = e.estimate();
            prop_assert!(est.pose.is_finite(), "{:?}", est);
            prop_assert!(est.v_mps.is_finite() && est.yaw_rate_radps.is_finite());
            let st = e.status();
            prop_assert!(st.covariance_diag.iter().all(|v| v.is_finite() && *v >= 0.0), "{:?}", st);
            prop_assert!(st.gyro_bias_radps.is_finite());
            prop_assert!(e.covariance().iter().flatten().all(|v| v.is_finite()));
        }
    }
}

/// The batch EKF update (the textbook form: S = H P Hᵀ + R, K = P Hᵀ S⁻¹,
/// x += K ν, P −= K (P Hᵀ)ᵀ, d² = νᵀ S⁻¹ ν) for `n` rows of `h`, in f64.
fn batch_update(
    x: &[f32; N],
    p: &Mat,
    h: &[[f32; N]; 3],
    nu: &[f32; 3],
    r: &[f32; 3],
    n: usize,
) -> ([f64; N], [[f64; N]; N], f64) {
    let p64: [[f64; N]; N] = core::array::from_fn(|i| core::array::from_fn(|j| p[i][j] as f64));
    let mut pht = [[0.0f64; 3]; N];
    for i in 0..N {
        for a in 0..n {
            pht[i][a] = (0..N).map(|k| p64[i][k] * h[a][k] as f64).sum();
        }
    }
    let mut sm = [[0.0f32; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            sm[a][b] = if a < n && b < n {
                (0..N).map(|k| h[a][k] as f64 * pht[k][b]).sum::<f64>() as f32
            } else {
                (a == b) as u8 as f32
            };
        }
        if a < n {
            sm[a][a] += r[a];
        }
    }
    let si = invert3(&sm).expect("S invertible");
    let mut d2 = 0.0f64;
    for a in 0..n {
        for b in 0..n {
            d2 += nu[a] as f64 * si[a][b] as f64 * nu[b] as f64;
        }
    }
    let mut nx: [f64; N] = core::array::from_fn(|i| x[i] as f64);
    let mut np = p64;
    for i in 0..N {
        let k: [f64; 3] =
            core::array::from_fn(|a| (0..n).map(|b| pht[i][b] * si[b][a] as f64).sum::<f64>());
        nx[i] += (0..n).map(|a| k[a] * nu[a] as f64).sum::<f64>();
        for j in 0..N {
            np[i][j] -= (0..n).map(|a| k[a] * pht[j][a]).sum::<f64>();
        }
    }
    (nx, np, d2)
}

/// The sequential scalar updates of `update` equal the batch update (an
/// equivalence between two methods): on random states, covariances and
/// measurements with and without heading, the state, covariance and
/// Mahalanobis distance agree within f32 rounding of the sums involved.
#[test]
fn sequential_update_equals_batch() {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut uni = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut e = est();
    for case in 0..2000 {
        // P = A Aᵀ + δ I: symmetric positive definite, entries up to ~1.
        let a: [[f64; N]; N] = core::array::from_fn(|_| core::array::from_fn(|_| 0.5 * uni()));
        let p: Mat = core::array::from_fn(|i| {
            core::array::from_fn(|j| {
                ((0..N).map(|k| a[i][k] * a[j][k]).sum::<f64>() + if i == j { 1e-3 } else { 0.0 })
                    as f32
            })
        });
        let x: [f32; N] = [
            uni() as f32 * 5.0,
            uni() as f32 * 5.0,
            uni() as f32 * 3.0,
            uni() as f32 * 0.01,
            1.0 + uni() as f32 * 0.1,
        ];
        let heading = case % 2 == 0;
        let m = PoseMeasurement {
            stamp_us: 0,
            pose: Pose::new(
                x[0] + uni() as f32 * 0.3,
                x[1] + uni() as f32 * 0.3,
                x[2] + uni() as f32 * 0.3,
            ),
            position_std_m: 0.01 + 0.2 * uni().abs() as f32,
            heading_std_rad: heading.then_some(0.01 + 0.2 * uni().abs() as f32),
        };
        let (s, c) = sin_cos(x[2]);
        let h = [
            [1.0, 0.0, -D * s, 0.0, 0.0],
            [0.0, 1.0, D * c, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0, 0.0],
        ];
        let nu = [
            m.pose.x_m - (x[0] + D * c),
            m.pose.y_m - (x[1] + D * s),
            if heading {
                wrap_angle(m.pose.theta_rad - x[2])
            } else {
                0.0
            },
        ];
        let rp = m.position_std_m * m.position_std_m;
        let r = [rp, rp, m.heading_std_rad.map_or(1.0, |v| v * v)];
        let n = if heading { 3 } else { 2 };
        let (bx, bp, bd2) = batch_update(&x, &p, &h, &nu, &r, n);

        let (mut sx, mut sp) = (x, p);
        e.update(&mut sx, &mut sp, &m, false).unwrap();
        let sd2 = e.status.last_mahalanobis_sq as f64;
        assert!(
            (sd2 - bd2).abs() <= 1e-4 * bd2.max(1.0),
            "case {case}: d² {sd2} vs {bd2}"
        );
        // `update` wraps x[2] and clamps x[4] to its range afterwards.
        for i in 0..N {
            let want = match i {
                2 => wrap_angle(bx[i] as f32) as f64,
                4 => bx[i].clamp(SPEED_SCALE_RANGE.0 as f64, SPEED_SCALE_RANGE.1 as f64),
                _ => bx[i],
            };
            assert!(
                (sx[i] as f64 - want).abs() <= 1e-4 * (1.0 + want.abs()),
                "case {case}: x[{i}] {} vs {want}",
                sx[i]
            );
            for j in 0..N {
                let want = bp[i][j].max(if i == j { MIN_VAR as f64 } else { f64::MIN });
                assert!(
                    (sp[i][j] as f64 - want).abs() <= 1e-4,
                    "case {case}: P[{i}][{j}] {} vs {want}",
                    sp[i][j]
                );
            }
        }
    }
}

/// Without any external pose, the gyro against the wheels' yaw finds the
/// speed scale: wheels reporting 1.25x the body's motion (v and ω, as the
/// actuator fault ε = 0.2 makes them) give s → 1/1.25 = 0.8 within 0.03
/// after 20 s of an S-curve (the gyro biased by 0.01 rad/s); with the
/// update off it stays at 1, and the position is the better for it.
#[cfg(feature = "gyro-speed-scale")]
#[test]
fn gyro_speed_scale_finds_the_fault_without_fixes() {
    let run = |on: bool| {
        let mut e = est_at(
            EstimatorConfig {
                gyro_speed_scale: on,
                ..EstimatorConfig::EXAMPLE
            },
            Pose::new(0.0, 0.0, 0.0),
        );
        let (mut x, mut y, mut th) = (0.0f32, 0.0f32, 0.0f32);
        for k in 1..=20_000u32 {
            let t = k as f32 * DT;
            let (v, w) = (0.5, 0.8 * (0.7 * t).sin());
            let (s, c) = (th + 0.5 * w * DT).sin_cos();
            x += v * DT * c;
            y += v * DT * s;
            th += w * DT;
            e.predict(
                k * 1000,
                DT,
                1.25 * v * DT,
                1.25 * w * DT,
                gyro(w + 0.01, k * 1000),
            );
        }
        let p = e.estimate().filter_pose;
        let err = (p.x_m - x - D * th.cos()).hypot(p.y_m - y - D * th.sin());
        (e.status().speed_scale, err)
    };
    let ((s_on, err_on), (s_off, err_off)) = (run(true), run(false));
    assert!((s_on - 0.8).abs() < 0.03, "{s_on}");
    assert_eq!(s_off, 1.0);
    assert!(err_on < 0.5 * err_off, "{err_on} vs {err_off}");
}
