//! Scalar math used by the control path, in one place so each routine can be
//! chosen by measured cost and accuracy on the Cortex-M4F (see BENCHMARKS.md).

use core::f32::consts::PI;

/// sin x.
#[inline]
pub fn sin(x: f32) -> f32 {
    libm::sinf(x)
}

/// cos x.
#[inline]
pub fn cos(x: f32) -> f32 {
    libm::cosf(x)
}

/// (sin x, cos x).
#[inline]
pub fn sin_cos(x: f32) -> (f32, f32) {
    libm::sincosf(x)
}

/// atan2(y, x) in (−π, π].
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    libm::atan2f(y, x)
}

/// Hyperbolic tangent.
#[inline]
pub fn tanh(x: f32) -> f32 {
    libm::tanhf(x)
}

/// Square root.
#[inline]
pub fn sqrt(x: f32) -> f32 {
    libm::sqrtf(x)
}

/// xʸ for x > 0.
#[inline]
pub fn powf(x: f32, y: f32) -> f32 {
    libm::powf(x, y)
}

/// Wraps an angle to (−π, π].
#[inline]
pub fn wrap_angle(x: f32) -> f32 {
    if x > -PI && x <= PI {
        return x;
    }
    let two_pi = 2.0 * PI;
    let mut y = x - two_pi * libm::floorf((x + PI) / two_pi);
    if y <= -PI {
        y += two_pi;
    }
    y
}

/// Clamps `x` to `[-limit, limit]` (limit >= 0). NaN stays NaN.
#[inline]
pub fn clamp_abs(x: f32, limit: f32) -> f32 {
    if x > limit {
        limit
    } else if x < -limit {
        -limit
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_range_and_identity() {
        for i in -2000..2000 {
            let x = i as f32 * 0.0173;
            let w = wrap_angle(x);
            assert!(w > -PI - 1e-6 && w <= PI + 1e-6, "{x} -> {w}");
            // Same direction: sin and cos unchanged.
            assert!((sin(w) - sin(x)).abs() < 1e-4 && (cos(w) - cos(x)).abs() < 1e-4);
        }
    }
}
