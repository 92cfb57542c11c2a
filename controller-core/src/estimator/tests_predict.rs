//! The closed-form prediction (predict.rs) against a dense reference: the
//! EKF time update written out plainly in f64, x' = f(x, u) and
//! P' = F·P·Fᵀ + Q with F the Jacobian of f taken from first principles and
//! every product of the 5×5 matrices formed in full (two methods).

use super::predict::{predict, Filter, Input, NoiseSq};

/// The prediction, as a function.
fn predicted(f: &Filter, u: &Input, nq: &NoiseSq) -> Filter {
    let mut next = *f;
    predict(&mut next, u, nq);
    next
}
use super::*;

/// A small deterministic generator (LCG) of values in [−1, 1).
struct Rnd(u64);

impl Rnd {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
}

type M64 = [[f64; 5]; 5];

fn mul(a: &M64, b: &M64) -> M64 {
    core::array::from_fn(|i| core::array::from_fn(|j| (0..5).map(|k| a[i][k] * b[k][j]).sum()))
}

fn transpose(a: &M64) -> M64 {
    core::array::from_fn(|i| core::array::from_fn(|j| a[j][i]))
}

fn abs(a: &M64) -> M64 {
    a.map(|r| r.map(f64::abs))
}

/// The dense f64 prediction: (x', P', |F|·|P|·|F|ᵀ + |Q|).
fn dense_reference(f: &Filter, u: &Input, nq: &NoiseSq) -> ([f64; 5], M64, M64) {
    let x = f.x.map(f64::from);
    let p = unpack(&f.p).map(|r| r.map(f64::from));
    let dt = u.dt_s as f64;
    let ds = u.ds_m as f64;
    let sq = |v: f32| v as f64;
    // Heading change and its derivative by the bias.
    let (dth, ddth_db, q_th) = if u.gyro_used {
        ((u.yaw as f64 - x[3]) * dt, -dt, sq(nq.gyro) * dt)
    } else {
        let w = u.yaw as f64 / dt;
        let slip = sq(nq.slip) * w * w;
        (u.yaw as f64, 0.0, (sq(nq.wheel_yaw) + slip) * dt)
    };
    let m = x[2] + 0.5 * dth;
    let (s, c) = m.sin_cos();
    let nx = [
        x[0] + x[4] * ds * c,
        x[1] + x[4] * ds * s,
        x[2] + dth,
        x[3],
        x[4],
    ];
    // F = ∂f/∂x: the midpoint heading depends on θ (1) and b (ddth_db / 2).
    let mut fj = [[0.0f64; 5]; 5];
    for (i, row) in fj.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    fj[0][2] = -x[4] * ds * s;
    fj[1][2] = x[4] * ds * c;
    fj[0][3] = -x[4] * ds * s * 0.5 * ddth_db;
    fj[1][3] = x[4] * ds * c * 0.5 * ddth_db;
    fj[2][3] = ddth_db;
    fj[0][4] = ds * c;
    fj[1][4] = ds * s;
    let v = ds / dt;
    let q_p = (sq(nq.speed) + sq(nq.slip) * v * v) * dt;
    let q = [
        q_p,
        q_p,
        q_th,
        sq(nq.bias_walk) * dt,
        sq(nq.scale_walk) * dt,
    ];
    let mut np = mul(&mul(&fj, &p), &transpose(&fj));
    let mut scale = mul(&mul(&abs(&fj), &abs(&p)), &transpose(&abs(&fj)));
    for i in 0..5 {
        np[i][i] += q[i];
        scale[i][i] += q[i];
    }
    (nx, np, scale)
}

/// A random symmetric positive definite covariance L·Lᵀ with realistic
/// scales per state (m, m, rad, rad/s, 1), sometimes with large position
/// variances (after an outage).
fn random_covariance(r: &mut Rnd) -> [f32; NP] {
    let big = r.next() > 0.6;
    let sd = [
        if big { 30.0 } else { 0.05 },
        if big { 30.0 } else { 0.05 },
        0.05,
        0.01,
        0.1,
    ];
    let mut l = [[0.0f64; 5]; 5];
    for i in 0..5 {
        for j in 0..=i {
            l[i][j] = r.next() as f64 * sd[i];
        }
        l[i][i] = l[i][i].abs() + 0.1 * sd[i];
    }
    let p = mul(&l, &transpose(&l));
    pack(&p.map(|row| row.map(|v| v as f32)))
}

fn random_case(r: &mut Rnd) -> (Filter, Input) {
    let x = [
        100.0 * r.next(),
        100.0 * r.next(),
        core::f32::consts::PI * r.next(),
        0.05 * r.next(),
        1.0 + 0.5 * r.next(),
    ];
    let dt = if r.next() > 0.9 {
        0.1
    } else {
        1e-3 * (1.0 + 0.2 * r.next())
    };
    let gyro_used = r.next() > -0.5;
    // Mostly robot-like turns; some fast ones (|Δθ/2| > 1/64: sin/cos call).
    let fast = r.next() > 0.8;
    let rate = if fast { 40.0 } else { 3.0 } * r.next();
    let u = Input {
        dt_s: dt,
        ds_m: 2.0 * dt * r.next(),
        yaw: if gyro_used { rate } else { rate * dt },
        gyro_used,
        still: false,
    };
    (Filter::new(x, random_covariance(r)), u)
}

/// The closed-form prediction equals the dense f64 EKF time update on
/// random states, covariances and inputs (gyro and wheel yaw, slow and
/// fast turns, Δt 1 ms and 100 ms).
///
/// Tolerances (f32 against f64): each entry of P' is a sum of at most 25
/// products of three factors, each rounded to f32 (2⁻²⁴ ≈ 6·10⁻⁸
/// relative) and F's entries carry the f32 sin/cos error (≤ 3·10⁻⁷
/// relative, math.rs's bound plus the Taylor rotation's 3·10⁻⁹); so
/// |ΔP'ᵢⱼ| ≤ 2·10⁻⁶·(|F|·|P|·|F|ᵀ + |Q|)ᵢⱼ. Position: one rounding of
/// x (2⁻²⁴·|x|) plus k·Δs times the sin/cos error; heading: the sum's
/// rounding (≤ 2⁻²⁴·π).
#[test]
fn closed_form_prediction_equals_dense_reference() {
    let cfg = EstimatorConfig::EXAMPLE;
    let nq = NoiseSq::of(&cfg);
    let mut r = Rnd(0x5EED);
    for case in 0..2000 {
        let (f, u) = random_case(&mut r);
        let got = predicted(&f, &u, &nq);
        let (x, p, scale) = dense_reference(&f, &u, &nq);
        let gp = unpack(&got.p);
        for i in 0..5 {
            for j in 0..5 {
                let err = (gp[i][j] as f64 - p[i][j]).abs();
                assert!(
                    err <= 2e-6 * scale[i][j] + 1e-30,
                    "case {case} P[{i}][{j}]: {} vs {} (scale {})",
                    gp[i][j],
                    p[i][j],
                    scale[i][j]
                );
            }
        }
        let step = (f.x[4] * u.ds_m).abs() as f64;
        for i in 0..2 {
            let err = (got.x[i] as f64 - x[i]).abs();
            assert!(
                err <= 6e-8 * x[i].abs() + 4e-7 * step + 1e-12,
                "case {case} x[{i}]: {} vs {}",
                got.x[i],
                x[i]
            );
        }
        // θ + Δθ rounded once, Δθ = (gyro − b)·Δt twice; wrapping to
        // (−π, π] subtracts f32's 2π (off by 1.7·10⁻⁷) and rounds again.
        let err = wrap_angle((got.x[2] as f64 - x[2]) as f32).abs();
        let turn = (x[2] - f.x[2] as f64).abs() as f32;
        let wrapped = x[2].abs() > core::f64::consts::PI;
        let wrap_err = if wrapped { 6e-7 } else { 0.0 };
        assert!(
            err <= 6e-8 * (got.x[2].abs() + 2.0 * turn) + wrap_err + 1e-9,
            "case {case} θ: {err} ({} from {}, turn {turn})",
            got.x[2],
            f.x[2]
        );
        assert_eq!(&got.x[3..], &f.x[3..]);
        // The cached sin/cos are those of the new heading.
        assert_eq!((got.sin_th, got.cos_th), crate::math::sin_cos(got.x[2]));
    }
}

/// Standing still, the zero-rate update is the scalar Kalman update with
/// h = e₃ (the gyro reads its bias) after the prediction: compared with the
/// dense f64 form P − P·h·hᵀ·P / (hᵀ·P·h + r), x + P·h·(z − b) / (hᵀ·P·h + r).
#[test]
fn zero_rate_update_equals_dense_kalman_update() {
    let cfg = EstimatorConfig::EXAMPLE;
    let nq = NoiseSq::of(&cfg);
    let mut r = Rnd(0xB1A5);
    for case in 0..500 {
        let (f, mut u) = random_case(&mut r);
        u.gyro_used = true;
        u.ds_m = 0.0;
        u.yaw = 0.02 * r.next();
        u.still = true;
        let got = predicted(&f, &u, &nq);
        let (x, p, scale) = dense_reference(&f, &Input { still: false, ..u }, &nq);
        let rr = nq.gyro as f64 / u.dt_s as f64;
        let s = p[3][3] + rr;
        let innov = u.yaw as f64 - x[3];
        let gp = unpack(&got.p);
        for i in 0..5 {
            let mut want = x[i] + p[i][3] / s * innov;
            if i == 4 {
                want = want.clamp(0.2, 1.5);
            }
            let mut err = (got.x[i] as f64 - want).abs();
            if i == 2 {
                err = (wrap_angle((got.x[i] as f64 - want) as f32) as f64).abs();
                want = core::f64::consts::PI; // the wrap's rounding
            }
            assert!(
                err <= 1e-6 * (want.abs() + 1e-3),
                "case {case} x[{i}]: {} vs {want}",
                got.x[i]
            );
            for j in 0..5 {
                let gain_term = p[i][3] * p[3][j] / s;
                let want = p[i][j] - gain_term;
                let err = (gp[i][j] as f64 - want).abs();
                assert!(
                    err <= 4e-6 * (scale[i][j] + gain_term.abs()) + 1e-12,
                    "case {case} P[{i}][{j}]: {} vs {want}",
                    gp[i][j]
                );
            }
        }
    }
}

/// The gyro-vs-wheel update of the speed scale (gyro_scale.rs, D36) is the
/// Schmidt (consider-state) scalar Kalman update with h = [0, 0, 0, T, W],
/// ν = Σg·Δt − b·T − s·W, r = (σ_s² + σ_g²)·T + slip²·W²/T and the gain
/// of x, y, θ zeroed: compared with the dense f64 Joseph form
/// P' = (I − K·hᵀ)·P·(I − K·hᵀ)ᵀ + K·r·Kᵀ, K = (0, 0, 0, (P·h)₃, (P·h)₄) / S
/// (valid for any gain), on random states and covariances (scale kept
/// inside its range). The pose and its covariance are unchanged.
#[cfg(feature = "gyro-speed-scale")]
#[test]
fn gyro_scale_update_equals_dense_kalman_update() {
    use super::gyro_scale::{update, Window};
    let cfg = EstimatorConfig::EXAMPLE;
    let nq = NoiseSq::of(&cfg);
    let mut r = Rnd(0x5CA1E);
    let mut applied = 0;
    for case in 0..500 {
        let (f, _) = random_case(&mut r);
        let mut w = Window::default();
        let (dt, g, wheel) = (1e-3, 2.0 * r.next(), 2.0e-3 * r.next());
        let n = 17;
        for _ in 0..n {
            let u = Input {
                dt_s: dt,
                ds_m: 0.0,
                yaw: g,
                gyro_used: true,
                still: false,
            };
            w.add(&u, wheel);
        }
        let mut got = f;
        update(&mut got, &w, &nq);
        let (t, wr, z) = (17e-3f64, 17.0 * wheel as f64, 17e-3 * g as f64);
        if wr.abs() < cfg.gyro_scale_min_turn_rad as f64 {
            assert_eq!(got, f, "case {case}: no update below the turn threshold");
            continue;
        }
        applied += 1;
        let p = unpack(&f.p).map(|row| row.map(|v| v as f64));
        let x = f.x.map(|v| v as f64);
        let h = [0.0, 0.0, 0.0, t, wr];
        let ph: [f64; 5] = core::array::from_fn(|i| (0..5).map(|j| p[i][j] * h[j]).sum());
        let rr = (sq(cfg.gyro_scale_yaw_noise) + sq(cfg.gyro_noise_density)) * t
            + sq(cfg.slip_fraction) * wr * wr / t;
        let s = (0..5).map(|i| h[i] * ph[i]).sum::<f64>() + rr;
        let innov = z - x[3] * t - x[4] * wr;
        let gp = unpack(&got.p);
        let k: [f64; 5] = core::array::from_fn(|i| if i >= 3 { ph[i] / s } else { 0.0 });
        // Joseph form with this gain.
        let a: M64 = core::array::from_fn(|i| {
            core::array::from_fn(|j| f64::from(u8::from(i == j)) - k[i] * h[j])
        });
        let mut want_p = mul(&mul(&a, &p), &transpose(&a));
        for i in 0..5 {
            for j in 0..5 {
                want_p[i][j] += k[i] * rr * k[j];
            }
        }
        assert_eq!(
            &got.x[..3],
            &f.x[..3],
            "case {case}: the pose is not corrected"
        );
        for i in 0..5 {
            let want = x[i] + k[i] * innov;
            let err = (got.x[i] as f64 - want).abs();
            let clamped = i == 4 && !(0.2..=1.5).contains(&want);
            assert!(
                clamped || err <= 1e-5 * (want.abs() + 1e-3),
                "case {case} x[{i}]: {} vs {want}",
                got.x[i]
            );
            for j in 0..5 {
                let scale = p[i][j].abs() + (ph[i] * ph[j] / s).abs();
                assert!(
                    (gp[i][j] as f64 - want_p[i][j]).abs() <= 1e-5 * scale + 1e-12,
                    "case {case} P[{i}][{j}]: {} vs {}",
                    gp[i][j],
                    want_p[i][j]
                );
            }
        }
    }
    assert!(applied > 200, "{applied}");
}

fn sq(v: f32) -> f64 {
    v as f64 * v as f64
}
