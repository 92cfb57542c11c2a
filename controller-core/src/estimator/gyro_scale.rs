//! The speed scale seen by the gyro (book/src/explanation/decisions.md D36): a
//! pseudo-measurement of s from the gyro's yaw against the wheels'.
//!
//! The actuator fault ε of the paper (eq. 10) moves the body at (1 − ε)·η,
//! v and ω alike, and uniform slip on a slippery floor does the same: the
//! body turns by s·Δθ_wheel while the wheels report Δθ_wheel. The gyro
//! reads the body's rate plus its bias, so over a window of ticks with the
//! gyro in use
//!
//! ```text
//! z = Σ g·Δt = b·T + s·W + noise,   T = Σ Δt,   W = Σ Δθ_wheel
//! ν = z − b·T − s·W,   H = [0, 0, 0, T, W],
//! R = (σ_g² + σ_wheel²)·T + slip²·W²/T
//! ```
//!
//! (σ_g the gyro noise density, σ_wheel the wheel-yaw noise, slip² W²/T
//! the slip fraction's term of the wheel yaw, exact for a constant rate and
//! a lower bound of Σ slip²·Δθ²/Δt otherwise). A scalar Kalman update of b
//! and s with it (Schmidt form: the pose is not corrected, so it never
//! jumps) makes s observable whenever the robot turns, without an external
//! pose. It is applied only when |W| >= `gyro_scale_min_turn_rad` (a
//! window driving straight says nothing about s, and would only feed b with
//! yaw the wheels cannot see).
//!
//! The window is the history's snapshot interval (K = 17 ticks by
//! default): the sums are inputs only (they do not depend on the state),
//! so they are kept once per snapshot (12 B × 16) instead of per tick, and
//! the update is applied on the tick that takes a snapshot, before it, by
//! the live tick and by the re-propagation alike: the replayed ticks apply
//! it identically, bit for bit (D25, D31).

use super::predict::{Filter, Input, NoiseSq};
#[cfg(feature = "gyro-speed-scale")]
use super::{
    predict::{ix, SPEED_SCALE_RANGE},
    N,
};

/// Sums over a window of the ticks with the gyro in use (not standing
/// still): inputs only.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Window {
    /// Σ gyro rate·Δt \[rad\] (bias not removed).
    #[cfg(feature = "gyro-speed-scale")]
    gyro_rad: f32,
    /// Σ the wheels' Δθ \[rad\].
    #[cfg(feature = "gyro-speed-scale")]
    wheel_rad: f32,
    /// Σ Δt \[s\].
    #[cfg(feature = "gyro-speed-scale")]
    dt_s: f32,
}

// The update is compiled in with the `gyro-speed-scale` feature (default).
// Without it (the firmware built without an IMU, where no tick uses a gyro
// and the update could never run) it is left out of the image, and `Window`
// is empty: 0.9 KiB of flash and 192 B of RAM on the STM32F411
// (book/src/explanation/decisions.md D36).

impl Window {
    /// Adds the tick `u` whose wheels turned by `wheel_dth_rad`.
    #[inline(always)]
    pub(super) fn add(&mut self, u: &Input, wheel_dth_rad: f32) {
        #[cfg(not(feature = "gyro-speed-scale"))]
        let _ = (u, wheel_dth_rad);
        #[cfg(feature = "gyro-speed-scale")]
        if u.gyro_used && !u.still {
            self.gyro_rad += u.yaw * u.dt_s;
            self.wheel_rad += wheel_dth_rad;
            self.dt_s += u.dt_s;
        }
    }
}

/// Applies the window's pseudo-measurement to `f` (if the wheels turned by
/// at least `nq.scale_min_turn` over it) as a Schmidt (consider-state)
/// update: only b and s take the gain; x, y, θ are not corrected, their
/// covariance with b and s is (P'ᶜᵃ = Pᶜᵃ − (P·h)ᶜ·Kᵃ, P'ᶜᶜ unchanged). So the
/// pose does not jump (no sin/cos, nothing for the output smoothing) and
/// only 9 covariance entries change; a non-finite result is dropped.
#[inline(never)]
pub(super) fn update(f: &mut Filter, w: &Window, nq: &NoiseSq) {
    #[cfg(not(feature = "gyro-speed-scale"))]
    let _ = (f, w, nq);
    #[cfg(feature = "gyro-speed-scale")]
    update_compiled(f, w, nq);
}

#[cfg(feature = "gyro-speed-scale")]
#[inline(always)]
fn update_compiled(f: &mut Filter, w: &Window, nq: &NoiseSq) {
    let wr = w.wheel_rad;
    // Always true with the update off (the threshold is ∞); a NaN (the
    // inputs are validated: not expected) gives a non-finite result, dropped.
    if wr.abs() < nq.scale_min_turn {
        return;
    }
    let t = w.dt_s;
    let x = &f.x;
    let p = &f.p;
    let innov = w.gyro_rad - x[3] * t - x[4] * wr;
    let r = nq.scale_yaw * t + nq.slip * wr * wr / t;
    // P·h with h = [0, 0, 0, T, W].
    let ph: [f32; N] =
        core::array::from_fn(|i| p[ix(i.min(3), i.max(3))] * t + p[ix(i.min(4), i.max(4))] * wr);
    let inv = 1.0 / (t * ph[3] + wr * ph[4] + r);
    let (k3, k4) = (ph[3] * inv, ph[4] * inv);
    let b = x[3] + k3 * innov;
    let s = (x[4] + k4 * innov).clamp(SPEED_SCALE_RANGE.0, SPEED_SCALE_RANGE.1);
    let np = [
        p[ix(0, 3)] - ph[0] * k3,
        p[ix(0, 4)] - ph[0] * k4,
        p[ix(1, 3)] - ph[1] * k3,
        p[ix(1, 4)] - ph[1] * k4,
        p[ix(2, 3)] - ph[2] * k3,
        p[ix(2, 4)] - ph[2] * k4,
        p[ix(3, 3)] - ph[3] * k3,
        p[ix(3, 4)] - ph[4] * k3,
        p[ix(4, 4)] - ph[4] * k4,
    ];
    let sum = np.iter().fold(b + s, |a, v| a + v);
    if sum.is_finite() {
        f.x[3] = b;
        f.x[4] = s;
        for (k, v) in [
            ix(0, 3),
            ix(0, 4),
            ix(1, 3),
            ix(1, 4),
            ix(2, 3),
            ix(2, 4),
            ix(3, 3),
            ix(3, 4),
            ix(4, 4),
        ]
        .into_iter()
        .zip(np)
        {
            f.p[k] = v;
        }
    }
}
