//! The prediction of one tick in closed form (the EKF's time update, used
//! live and to replay and re-propagate the history; book/src/explanation/decisions.md D31).
//!
//! State x = \[x, y, θ, b, k\] (axle midpoint, heading, gyro bias, speed
//! scale), covariance P stored as its packed upper triangle. With the
//! heading change Δθ = (gyro − b)·Δt (or the wheels' Δθ) and the midpoint
//! heading θₘ = θ + Δθ/2, O_B moves by k·Δs·\[cos θₘ, sin θₘ\]. The Jacobian
//! F = I + E has seven non-zero off-diagonal entries,
//!
//! ```text
//! E[0][2] = a = −kΔs·sin θₘ   E[0][3] = g·a/2   E[0][4] = Δs·cos θₘ
//! E[1][2] = b =  kΔs·cos θₘ   E[1][3] = g·b/2   E[1][4] = Δs·sin θₘ
//! E[2][3] = g = −Δt (gyro; 0 with the wheels' Δθ)
//! ```
//!
//! so P' = F·P·Fᵀ + Q changes only rows 0-2 of P: with wⱼ = P₂ⱼ + (g/2)·P₃ⱼ
//! the rows of F·P are r₀ⱼ = P₀ⱼ + a·wⱼ + Δs cos θₘ·P₄ⱼ,
//! r₁ⱼ = P₁ⱼ + b·wⱼ + Δs sin θₘ·P₄ⱼ, r₂ⱼ = P₂ⱼ + g·P₃ⱼ, and the twelve
//! changed entries of the upper triangle are r's combined once more with
//! F's rows (37 multiply-adds instead of 250 for the dense product).
//!
//! sin/cos: the filter keeps (sin θ, cos θ) of its heading (computed once
//! per tick, for the output pose too); sin/cos θₘ is that pair rotated by
//! Δθ/2 with the Taylor polynomials of sin and cos (|Δθ/2| ≤ 1/64: errors
//! below 3·10⁻⁹), or a fresh sin/cos for larger turns.

use super::{N, NP};
use crate::math::{sin_cos, wrap_angle};

/// Largest variances kept \[m², m², rad², (rad/s)², 1\]: without
/// corrections the covariance grows; beyond these it is scaled down.
pub(super) const MAX_VAR: [f32; N] = [1.0e6, 1.0e6, 10.0, 1.0, 0.25];
/// The speed scale is kept in this range (a wheel-speed ratio).
pub(super) const SPEED_SCALE_RANGE: (f32, f32) = (0.2, 1.5);
/// Largest |Δθ/2| \[rad\] whose sin/cos are Taylor polynomials (beyond:
/// a sin/cos call). 1/64 rad is 31 rad/s at 1 kHz.
const MAX_TAYLOR_HALF_TURN_RAD: f32 = 1.0 / 64.0;

/// Packed upper-triangle index of (i, j), i <= j.
pub(super) const fn ix(i: usize, j: usize) -> usize {
    i * N - i * (i + 1) / 2 + j
}

/// The configuration's noise parameters squared, once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct NoiseSq {
    pub(super) gyro: f32,
    pub(super) wheel_yaw: f32,
    pub(super) speed: f32,
    pub(super) bias_walk: f32,
    pub(super) scale_walk: f32,
    pub(super) slip: f32,
    /// Smallest |wheel turn| \[rad\] of a window whose gyro-vs-wheel yaw
    /// updates the speed scale (∞ when off; `gyro_scale.rs`).
    pub(super) scale_min_turn: f32,
    /// `gyro_scale_yaw_noise`² plus the gyro's.
    pub(super) scale_yaw: f32,
}

impl NoiseSq {
    pub(super) fn of(cfg: &super::EstimatorConfig) -> Self {
        let sq = |v: f32| v * v;
        Self {
            gyro: sq(cfg.gyro_noise_density),
            wheel_yaw: sq(cfg.wheel_yaw_noise),
            speed: sq(cfg.speed_noise_mps_per_sqrt_hz),
            bias_walk: sq(cfg.gyro_bias_walk),
            scale_walk: sq(cfg.speed_scale_walk),
            slip: sq(cfg.slip_fraction),
            scale_min_turn: if cfg.gyro_speed_scale {
                cfg.gyro_scale_min_turn_rad
            } else {
                f32::INFINITY
            },
            scale_yaw: sq(cfg.gyro_scale_yaw_noise) + sq(cfg.gyro_noise_density),
        }
    }
}

/// One tick's inputs to the prediction (validated).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Input {
    /// Δt \[s\], in (0, 0.1].
    pub(super) dt_s: f32,
    /// Distance the axle midpoint rolled \[m\].
    pub(super) ds_m: f32,
    /// The gyro's rate \[rad/s\] when `gyro_used`, else the wheels' Δθ \[rad\].
    pub(super) yaw: f32,
    pub(super) gyro_used: bool,
    /// Zero-rate update of the bias (standing still, gyro used).
    pub(super) still: bool,
}

/// The filter: state, packed covariance and (sin, cos) of the heading
/// (always `sin_cos(x[2])`, so a state restored from the history has the
/// same pair).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Filter {
    pub(super) x: [f32; N],
    pub(super) p: [f32; NP],
    pub(super) sin_th: f32,
    pub(super) cos_th: f32,
}

impl Filter {
    pub(super) fn new(x: [f32; N], p: [f32; NP]) -> Self {
        let (sin_th, cos_th) = sin_cos(x[2]);
        Self {
            x,
            p,
            sin_th,
            cos_th,
        }
    }

    /// Whether state and covariance are finite.
    pub(super) fn is_finite(&self) -> bool {
        self.x.iter().chain(self.p.iter()).all(|v| v.is_finite())
    }
}

/// Whether all `v` are finite: their sum is (a NaN or an infinity makes it
/// NaN or infinite; the filter's values are far below f32's range, so the
/// sum of finite ones does not overflow). Unrolled, branch-free.
#[inline(always)]
fn sum_finite<const M: usize>(v: [f32; M]) -> bool {
    let mut z = 0.0f32;
    for i in 0..M {
        z += v[i];
    }
    z.is_finite()
}

/// (sin, cos) of θ + h from (sin θ, cos θ).
#[inline(always)]
fn rotated(f: &Filter, h: f32) -> (f32, f32) {
    if h.abs() <= MAX_TAYLOR_HALF_TURN_RAD {
        let h2 = h * h;
        let ch = 1.0 - 0.5 * h2;
        let sh = h - h * h2 * (1.0 / 6.0);
        (f.sin_th * ch + f.cos_th * sh, f.cos_th * ch - f.sin_th * sh)
    } else {
        sin_cos(f.x[2] + h)
    }
}

/// The prediction of one tick, in place; a result that is not finite is
/// dropped (`f` is kept: it was finite, and so it stays).
///
/// Only what changes is computed and stored: x, y, θ, rows 0-2 of P and
/// the diagonal of rows 3-4 (the still tick's zero-rate update and the
/// bounding of a too large variance take [`predict_rare`]). One copy (not
/// inlined) serves the live tick, the replay and the re-propagation.
#[inline(never)]
pub(super) fn predict(f: &mut Filter, u: &Input, nq: &NoiseSq) {
    let x = &f.x;
    let dt = u.dt_s;
    let inv_dt = 1.0 / dt;
    let (dth, g, q_th) = if u.gyro_used {
        ((u.yaw - x[3]) * dt, -dt, nq.gyro * dt)
    } else {
        // Wheel yaw noise plus the slip fraction of the wheel yaw rate.
        let dth = u.yaw;
        (dth, 0.0, nq.wheel_yaw * dt + nq.slip * dth * dth * inv_dt)
    };
    let (s, c) = rotated(f, 0.5 * dth);
    let ds = u.ds_m;
    let dsk = x[4] * ds;
    let (a, b) = (-dsk * s, dsk * c);
    let (kc, ks) = (ds * c, ds * s);
    let nx = [x[0] + b, x[1] - a, wrap_angle(x[2] + dth)];
    // Speed noise plus the slip fraction of the speed.
    let q_p = nq.speed * dt + nq.slip * ds * ds * inv_dt;

    let p = &f.p;
    let hg = 0.5 * g;
    let pp = |i, j| p[ix(i, j)];
    // Rows of F·P: w = P₂ + (g/2)·P₃, r₀ = P₀ + a·w + kc·P₄, r₁ = P₁ + b·w
    // + ks·P₄ (columns 1-4), r₂ = P₂ + g·P₃ (columns 2-4).
    let w = [
        pp(0, 2) + hg * pp(0, 3),
        pp(1, 2) + hg * pp(1, 3),
        pp(2, 2) + hg * pp(2, 3),
        pp(2, 3) + hg * pp(3, 3),
        pp(2, 4) + hg * pp(3, 4),
    ];
    let p4 = [pp(0, 4), pp(1, 4), pp(2, 4), pp(3, 4), pp(4, 4)];
    let p0 = [pp(0, 0), pp(0, 1), pp(0, 2), pp(0, 3), pp(0, 4)];
    let p1 = [pp(0, 1), pp(1, 1), pp(1, 2), pp(1, 3), pp(1, 4)];
    let r0: [f32; N] = core::array::from_fn(|j| p0[j] + a * w[j] + kc * p4[j]);
    let r1: [f32; N] = core::array::from_fn(|j| p1[j] + b * w[j] + ks * p4[j]);
    let r2 = [
        pp(2, 2) + g * pp(2, 3),
        pp(2, 3) + g * pp(3, 3),
        pp(2, 4) + g * pp(3, 4),
    ];
    // (F·P)·Fᵀ: F's row 0 = e₀ + a·(e₂ + (g/2)e₃) + kc·e₄, row 1 likewise
    // with b, ks; row 2 = e₂ + g·e₃; rows 3, 4 = e₃, e₄.
    let w0 = r0[2] + hg * r0[3];
    let w1 = r1[2] + hg * r1[3];
    // The changed entries, in packed order (0,0)..(2,4), then (3,3), (4,4).
    let np = [
        r0[0] + a * w0 + kc * r0[4] + q_p,
        r0[1] + b * w0 + ks * r0[4],
        r0[2] + g * r0[3],
        r0[3],
        r0[4],
        r1[1] + b * w1 + ks * r1[4] + q_p,
        r1[2] + g * r1[3],
        r1[3],
        r1[4],
        r2[0] + g * r2[1] + q_th,
        r2[1],
        r2[2],
        pp(3, 3) + nq.bias_walk * dt,
        pp(4, 4) + nq.scale_walk * dt,
    ];
    let within = (np[ix(0, 0)] <= MAX_VAR[0])
        & (np[ix(1, 1)] <= MAX_VAR[1])
        & (np[ix(2, 2)] <= MAX_VAR[2])
        & (np[12] <= MAX_VAR[3])
        & (np[13] <= MAX_VAR[4]);
    if !within || u.still {
        predict_rare(f, u, nq, nx, np);
        return;
    }
    if sum_finite([
        nx[0], nx[1], nx[2], np[0], np[1], np[2], np[3], np[4], np[5], np[6], np[7], np[8], np[9],
        np[10], np[11], np[12], np[13],
    ]) {
        f.x[..3].copy_from_slice(&nx);
        f.p[..12].copy_from_slice(&np[..12]);
        f.p[ix(3, 3)] = np[12];
        f.p[ix(4, 4)] = np[13];
        (f.sin_th, f.cos_th) = sin_cos(nx[2]);
    }
}

/// [`predict`]'s end on a tick with a zero-rate update or a variance to
/// bound: the whole filter is formed, then checked.
#[cold]
#[inline(never)]
fn predict_rare(f: &mut Filter, u: &Input, nq: &NoiseSq, nx: [f32; 3], np: [f32; 14]) {
    let mut x = f.x;
    x[..3].copy_from_slice(&nx);
    let mut p = f.p;
    p[..12].copy_from_slice(&np[..12]);
    p[ix(3, 3)] = np[12];
    p[ix(4, 4)] = np[13];
    bound_variances(&mut p);
    if u.still {
        zero_rate_update(&mut x, &mut p, u, nq);
    }
    let next = Filter::new(x, p);
    if next.is_finite() {
        *f = next;
    }
}

/// Scales each row and column of `p` whose variance exceeds `MAX_VAR`
/// (or is NaN) so that the variance is `MAX_VAR`.
fn bound_variances(p: &mut [f32; NP]) {
    for i in 0..N {
        let v = p[ix(i, i)];
        if v.is_nan() || v > MAX_VAR[i] {
            let k = if v.is_finite() {
                crate::math::sqrt(MAX_VAR[i] / v)
            } else {
                0.0
            };
            for j in 0..N {
                p[ix(i.min(j), i.max(j))] *= k;
            }
            p[ix(i, i)] = MAX_VAR[i];
        }
    }
}

/// Zero-rate update: standing still, the gyro reads its bias (a scalar
/// Kalman update with h = e₃, r = gyro noise² / Δt).
fn zero_rate_update(x: &mut [f32; N], p: &mut [f32; NP], u: &Input, nq: &NoiseSq) {
    let r = nq.gyro / u.dt_s;
    let s33 = p[ix(3, 3)] + r;
    let innov = u.yaw - x[3];
    let row3: [f32; N] = core::array::from_fn(|j| p[ix(3.min(j), 3.max(j))]);
    let k: [f32; N] = core::array::from_fn(|i| row3[i] / s33);
    for i in 0..N {
        x[i] += k[i] * innov;
        for j in i..N {
            p[ix(i, j)] -= k[i] * row3[j];
        }
    }
    x[2] = wrap_angle(x[2]);
    x[4] = x[4].clamp(SPEED_SCALE_RANGE.0, SPEED_SCALE_RANGE.1);
}
