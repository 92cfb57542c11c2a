//! Scalar math used by the control path, in one place so each routine can be
//! chosen by measured cost and accuracy on the Cortex-M4F (see BENCHMARKS.md).
//!
//! Two implementations of every routine:
//!
//! * [`fast`]: single-precision polynomials (Cephes-style minimax
//!   coefficients, Cody-Waite range reduction). Only f32 adds, multiplies,
//!   divides and integer bit operations: on the M4F's FPv4-SP every operation
//!   is one hardware instruction, no f64 soft-float routine is linked.
//! * [`accurate`]: `libm` (correctly or nearly correctly rounded, but `sinf`,
//!   `cosf`, `sincosf`, `powf` and friends compute in f64, which the M4F
//!   emulates in software: about 1,000-2,000 instructions per call).
//!
//! Which one the top-level functions ([`sin`], [`cos`], ...) use:
//!
//! * default: [`fast`];
//! * feature `accurate-math`: [`accurate`];
//! * feature `runtime-math-select` (and not `accurate-math`): chosen at run
//!   time with [`select`] (default [`MathImpl::Fast`]), so one test binary can
//!   run the same closed loop with both and compare (costs a load and a branch
//!   per call; meant for host tests and simulators, not for firmware).
//!
//! The accuracy of the fast routines over the ranges the loop uses is bounded
//! by the tests at the end of this file, each bound with its justification.

// NaN handling is deliberate: `!(x <= limit)` is true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use core::f32::consts::PI;

/// Which implementation the top-level functions use (see [`select`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MathImpl {
    /// [`fast`] polynomials (the default).
    Fast,
    /// [`accurate`] (libm).
    Accurate,
}

#[cfg(all(feature = "runtime-math-select", not(feature = "accurate-math")))]
static USE_ACCURATE: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

/// Selects the implementation at run time. Only with feature
/// `runtime-math-select` (and without `accurate-math`); returns whether the
/// selection took effect.
pub fn select(which: MathImpl) -> bool {
    #[cfg(all(feature = "runtime-math-select", not(feature = "accurate-math")))]
    {
        USE_ACCURATE.store(
            which == MathImpl::Accurate,
            core::sync::atomic::Ordering::Relaxed,
        );
        true
    }
    #[cfg(not(all(feature = "runtime-math-select", not(feature = "accurate-math"))))]
    {
        which == selected()
    }
}

/// The implementation the top-level functions currently use.
pub fn selected() -> MathImpl {
    #[cfg(feature = "accurate-math")]
    {
        MathImpl::Accurate
    }
    #[cfg(all(feature = "runtime-math-select", not(feature = "accurate-math")))]
    {
        if USE_ACCURATE.load(core::sync::atomic::Ordering::Relaxed) {
            MathImpl::Accurate
        } else {
            MathImpl::Fast
        }
    }
    #[cfg(not(any(feature = "accurate-math", feature = "runtime-math-select")))]
    {
        MathImpl::Fast
    }
}

macro_rules! dispatch {
    ($f:ident($($a:expr),*)) => {{
        #[cfg(feature = "accurate-math")]
        {
            accurate::$f($($a),*)
        }
        #[cfg(all(feature = "runtime-math-select", not(feature = "accurate-math")))]
        {
            if USE_ACCURATE.load(core::sync::atomic::Ordering::Relaxed) {
                accurate::$f($($a),*)
            } else {
                fast::$f($($a),*)
            }
        }
        #[cfg(not(any(feature = "accurate-math", feature = "runtime-math-select")))]
        {
            fast::$f($($a),*)
        }
    }};
}

/// sin x.
#[inline]
pub fn sin(x: f32) -> f32 {
    dispatch!(sin(x))
}

/// cos x.
#[inline]
pub fn cos(x: f32) -> f32 {
    dispatch!(cos(x))
}

/// (sin x, cos x).
#[inline]
pub fn sin_cos(x: f32) -> (f32, f32) {
    dispatch!(sin_cos(x))
}

/// atan2(y, x) in (−π, π].
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    dispatch!(atan2(y, x))
}

/// Hyperbolic tangent.
#[inline]
pub fn tanh(x: f32) -> f32 {
    dispatch!(tanh(x))
}

/// Square root.
#[inline]
pub fn sqrt(x: f32) -> f32 {
    dispatch!(sqrt(x))
}

/// xʸ for x > 0.
#[inline]
pub fn powf(x: f32, y: f32) -> f32 {
    dispatch!(powf(x, y))
}

/// Largest integer-valued f32 <= x.
#[inline]
pub fn floor(x: f32) -> f32 {
    dispatch!(floor(x))
}

/// Wraps an angle to (−π, π].
#[inline]
pub fn wrap_angle(x: f32) -> f32 {
    if x > -PI && x <= PI {
        return x;
    }
    let two_pi = 2.0 * PI;
    let mut y = x - two_pi * floor((x + PI) / two_pi);
    if y <= -PI {
        y += two_pi;
    }
    y
}

/// True when every value is finite: x·0 is ±0 for a finite x and NaN for
/// an infinite or NaN one, and a sum of such terms is 0 exactly when all
/// are. One multiply and one add per value and a single compare, instead of
/// a move, a mask, a compare and a branch per value (`f32::is_finite` on
/// the Cortex-M4F). Equivalent to `xs.iter().all(|x| x.is_finite())`
/// (tested).
#[inline(always)]
pub fn all_finite<const N: usize>(xs: [f32; N]) -> bool {
    let mut acc = 0.0f32;
    for x in xs {
        acc += x * 0.0;
    }
    acc == 0.0
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

/// libm: accurate, but slow on an FPU without f64 (see the module docs).
pub mod accurate {
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
    /// atan2(y, x).
    #[inline]
    pub fn atan2(y: f32, x: f32) -> f32 {
        libm::atan2f(y, x)
    }
    /// tanh x.
    #[inline]
    pub fn tanh(x: f32) -> f32 {
        libm::tanhf(x)
    }
    /// √x.
    #[inline]
    pub fn sqrt(x: f32) -> f32 {
        libm::sqrtf(x)
    }
    /// xʸ.
    #[inline]
    pub fn powf(x: f32, y: f32) -> f32 {
        libm::powf(x, y)
    }
    /// ⌊x⌋.
    #[inline]
    pub fn floor(x: f32) -> f32 {
        libm::floorf(x)
    }
}

/// Single-precision polynomial approximations (see the module docs and the
/// tests for their accuracy).
pub mod fast {
    use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    /// 2/π.
    const FRAC_2_PI: f32 = core::f32::consts::FRAC_2_PI;
    /// π/2 = PIO2_1 + PIO2_2 + PIO2_3 (Cephes sinf's DP1..DP3 doubled): the
    /// first two have few significant bits, so k·PIO2_1 and k·PIO2_2 are
    /// exact for the k up to 8192·2/π that the direct path sees.
    const PIO2_1: f32 = 1.570_312_5;
    const PIO2_2: f32 = 4.837_513e-4;
    const PIO2_3: f32 = 7.549_79e-8;
    /// Beyond this |x|, sin/cos first remove whole turns (see `sin_cos`).
    const SINCOS_DIRECT_MAX: f32 = 8192.0;

    /// sin and cos on |r| <= π/4 (Cephes sinf/cosf minimax, ~1 ulp).
    #[inline(always)]
    fn sin_cos_kernel(r: f32) -> (f32, f32) {
        let z = r * r;
        let s = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * r + r;
        let c =
            ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
        (s, c)
    }

    /// Round to nearest (ties away from zero) as i32; saturates; NaN → 0.
    #[inline(always)]
    fn round_i32(x: f32) -> i32 {
        // `as` truncates toward zero and saturates (one VCVT on the M4F).
        (x + if x >= 0.0 { 0.5 } else { -0.5 }) as i32
    }

    /// (sin x, cos x). Non-finite x gives non-finite results.
    #[inline]
    pub fn sin_cos(x: f32) -> (f32, f32) {
        let mut x = x;
        if !(x.abs() <= SINCOS_DIRECT_MAX) {
            if !x.is_finite() {
                return (f32::NAN, f32::NAN);
            }
            // Rare: remove whole turns, 2π·trunc(x/2π) in f32, until x is in
            // the direct range (one pass below 2^25 rad, at most five up to
            // f32::MAX: each shrinks |x| by ~2^22). The phase error, |x|·1e-7
            // relative, is meaningless anyway at these magnitudes; the result
            // stays a bounded sin/cos pair (tested). Not libm's fmodf: its
            // exact remainder costs 1.1 KiB of flash with the u64 division.
            for _ in 0..8 {
                if x.abs() <= SINCOS_DIRECT_MAX {
                    break;
                }
                let turns = x * (0.5 * core::f32::consts::FRAC_1_PI);
                let whole = if turns.abs() < 8_388_608.0 {
                    turns as i32 as f32
                } else {
                    turns // |turns| >= 2^23: already an integer
                };
                x -= 2.0 * PI * whole;
            }
            if !(x.abs() <= SINCOS_DIRECT_MAX) {
                x = 0.0;
            }
        }
        let k = round_i32(x * FRAC_2_PI);
        let kf = k as f32;
        let r = ((x - kf * PIO2_1) - kf * PIO2_2) - kf * PIO2_3;
        let (s, c) = sin_cos_kernel(r);
        match k & 3 {
            0 => (s, c),
            1 => (c, -s),
            2 => (-s, -c),
            _ => (-c, s),
        }
    }

    /// sin x.
    #[inline]
    pub fn sin(x: f32) -> f32 {
        sin_cos(x).0
    }

    /// cos x.
    #[inline]
    pub fn cos(x: f32) -> f32 {
        sin_cos(x).1
    }

    /// atan r for 0 <= r <= 1 (Cephes atanf: reduce to |t| <= tan(π/8), ~1 ulp).
    #[inline(always)]
    fn atan_unit(r: f32) -> f32 {
        const TAN_PI_8: f32 = 0.414_213_57;
        let (t, base) = if r > TAN_PI_8 {
            ((r - 1.0) / (r + 1.0), FRAC_PI_4)
        } else {
            (r, 0.0)
        };
        let z = t * t;
        base + ((((8.053_744_5e-2 * z - 1.387_768_6e-1) * z + 1.997_771_1e-1) * z - 3.333_295e-1)
            * z
            * t
            + t)
    }

    /// atan2(y, x) in \[−π, π\] (π for y = ±0, x < 0; 0 for x = y = 0).
    /// NaN in → NaN out; both infinite → NaN.
    #[inline]
    pub fn atan2(y: f32, x: f32) -> f32 {
        let (ax, ay) = (x.abs(), y.abs());
        if ax == 0.0 && ay == 0.0 {
            return if x.is_sign_negative() { PI } else { 0.0 };
        }
        let swap = ay > ax;
        let r = if swap { ax / ay } else { ay / ax };
        let mut a = atan_unit(r);
        if swap {
            a = FRAC_PI_2 - a;
        }
        if x < 0.0 {
            a = PI - a;
        }
        if y < 0.0 {
            -a
        } else {
            a
        }
    }

    /// 2^n for integer n in \[−126, 127\] by building the exponent bits.
    #[inline(always)]
    fn pow2i(n: i32) -> f32 {
        f32::from_bits(((n + 127) as u32) << 23)
    }

    /// eˣ (Cephes expf: n = round(x·log2 e), r = x − n·ln 2 by Cody-Waite,
    /// degree-7 polynomial; ~1 ulp on \[−87, 88\]). Overflow → ∞, underflow → 0.
    #[inline]
    pub fn exp(x: f32) -> f32 {
        if !(x <= 88.72) {
            return if x.is_nan() { x } else { f32::INFINITY };
        }
        if x < -87.33 {
            return 0.0;
        }
        const LN2_HI: f32 = 0.693_359_4;
        const LN2_LO: f32 = -2.121_944_4e-4;
        let n = round_i32(x * core::f32::consts::LOG2_E);
        let nf = n as f32;
        let r = x - nf * LN2_HI - nf * LN2_LO;
        let z = r * r;
        let p = (((((1.987_569_1e-4 * r + 1.398_2e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2)
            * r
            + 1.666_666_5e-1)
            * r
            + 5.0e-1)
            * z
            + r
            + 1.0;
        // n in [-126, 128]: split the scaling so 2^n never overflows the bits.
        if n > 127 {
            p * pow2i(n - 1) * 2.0
        } else if n < -126 {
            p * pow2i(n + 1) * 0.5
        } else {
            p * pow2i(n)
        }
    }

    /// ln x for x > 0 (Cephes logf: x = m·2^e with m in \[√½, √2),
    /// degree-9 polynomial in m − 1; ~1 ulp). 0 → −∞, x < 0 or NaN → NaN, ∞ → ∞.
    #[inline]
    pub fn ln(x: f32) -> f32 {
        if !(x > 0.0) {
            return if x == 0.0 {
                f32::NEG_INFINITY
            } else {
                f32::NAN
            };
        }
        if x == f32::INFINITY {
            return x;
        }
        let (mut bits, mut e) = (x.to_bits(), 0i32);
        if bits < 0x0080_0000 {
            // subnormal: scale by 2^25
            bits = (x * 33_554_432.0).to_bits();
            e = -25;
        }
        e += ((bits >> 23) as i32) - 126; // x = m·2^e, m in [0.5, 1)
        let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f00_0000);
        if m < core::f32::consts::FRAC_1_SQRT_2 {
            e -= 1;
            m = m + m - 1.0;
        } else {
            m -= 1.0;
        }
        let z = m * m;
        let mut y = ((((((((7.037_683_6e-2 * m - 1.151_461e-1) * m + 1.167_699_9e-1) * m
            - 1.242_014_1e-1)
            * m
            + 1.424_932_3e-1)
            * m
            - 1.666_805_8e-1)
            * m
            + 2.000_071_4e-1)
            * m
            - 2.499_999_4e-1)
            * m
            + 3.333_333e-1)
            * m
            * z;
        let ef = e as f32;
        y += ef * -2.121_944_4e-4;
        y -= 0.5 * z;
        m + y + ef * 0.693_359_4
    }

    /// xʸ for x > 0 as exp(y·ln x): relative error about (1 + |y·ln x|)·1e-7.
    /// x = 0 → 0 (y > 0), 1 (y = 0), ∞ (y < 0); x < 0 or NaN → NaN.
    /// Not inlined: fal's usual path (the linear zone) skips it, and inlining
    /// its ~100 instructions into the ESO made that path slower (bench-m4).
    #[inline(never)]
    pub fn powf(x: f32, y: f32) -> f32 {
        if x == 0.0 {
            return if y > 0.0 {
                0.0
            } else if y == 0.0 {
                1.0
            } else {
                f32::INFINITY
            };
        }
        exp(y * ln(x))
    }

    /// tanh x. |x| < 0.625: Cephes tanhf odd polynomial (relative ~1 ulp);
    /// otherwise 1 − 2/(e^{2|x|} + 1) (absolute error ~1e-7); ±1 beyond |x| = 9.
    #[inline]
    pub fn tanh(x: f32) -> f32 {
        let a = x.abs();
        if a < 0.625 {
            let z = x * x;
            return ((((-5.704_988_7e-3 * z + 2.063_909e-2) * z - 5.373_971_6e-2) * z
                + 1.333_144_2e-1)
                * z
                - 3.333_328e-1)
                * z
                * x
                + x;
        }
        let t = if a > 9.0 {
            1.0
        } else {
            1.0 - 2.0 / (exp(2.0 * a) + 1.0)
        };
        // NaN: a < 0.625 and a > 9 both false → 1 − 2/(NaN) = NaN.
        if x < 0.0 {
            -t
        } else {
            t
        }
    }

    /// √x: reciprocal-square-root bit trick, three Newton steps, one Heron
    /// correction (relative error ~1e-7). 0 → 0, x < 0 or NaN → NaN, ∞ → ∞.
    #[inline]
    pub fn sqrt(x: f32) -> f32 {
        if !(x > 0.0) || x == f32::INFINITY {
            return if x == 0.0 || x == f32::INFINITY {
                x
            } else {
                f32::NAN
            };
        }
        // Subnormals: scale by 2^24, result by 2^-12.
        let (xs, scale) = if x < f32::MIN_POSITIVE {
            (x * 16_777_216.0, 1.0 / 4096.0)
        } else {
            (x, 1.0)
        };
        let half = 0.5 * xs;
        let mut y = f32::from_bits(0x5f37_5a86 - (xs.to_bits() >> 1));
        y *= 1.5 - half * y * y;
        y *= 1.5 - half * y * y;
        y *= 1.5 - half * y * y;
        let s = xs * y;
        (s + (xs - s * s) * (0.5 * y)) * scale
    }

    /// ⌊x⌋ via a truncating VCVT (|x| < 2^23; larger f32 are integers already).
    #[inline]
    pub fn floor(x: f32) -> f32 {
        if !(x.abs() < 8_388_608.0) {
            return x; // integer, ±∞ or NaN
        }
        let t = (x as i32) as f32;
        if t > x {
            t - 1.0
        } else {
            t
        }
    }
}

/// Configuration checks: every value finite and > 0. One loop for a whole
/// parameter set instead of a chain of compares per field (about 20 B of
/// flash per field on the Cortex-M4F: the constructors' validation was a
/// few KiB of the firmware image). Not for the control path.
#[inline(never)]
pub fn all_positive(xs: &[f32]) -> bool {
    xs.iter().all(|&x| x.is_finite() && x > 0.0)
}

/// Configuration checks: every value finite and >= 0 (see [`all_positive`]).
#[inline(never)]
pub fn all_non_negative(xs: &[f32]) -> bool {
    xs.iter().all(|&x| x.is_finite() && x >= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `all_finite` against `is_finite` on every triple of values drawn from
    /// finite extremes (largest, smallest subnormal, ±0) and non-finite ones.
    #[test]
    fn all_finite_equals_is_finite() {
        let vals = [
            0.0f32,
            -0.0,
            1.0,
            -3.5,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        for &a in &vals {
            for &b in &vals {
                for &c in &vals {
                    let xs = [a, b, c];
                    assert_eq!(all_finite(xs), xs.iter().all(|x| x.is_finite()), "{xs:?}");
                }
            }
        }
        assert!(all_finite::<0>([]));
    }

    /// Max |f(x) − g(x)| over `n` evenly spaced points of [lo, hi].
    fn max_abs_err(
        lo: f64,
        hi: f64,
        n: usize,
        f: impl Fn(f32) -> f32,
        g: impl Fn(f64) -> f64,
    ) -> f64 {
        (0..=n)
            .map(|i| {
                let x = (lo + (hi - lo) * i as f64 / n as f64) as f32;
                (f(x) as f64 - g(x as f64)).abs()
            })
            .fold(0.0, f64::max)
    }

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

    /// sin/cos arguments in the loop: headings θ (a robot that spins keeps
    /// integrating θ: a few hundred rad over a long run), e_θ in (−π, π], and
    /// the reference phases w·t, 2w·t, 3w·t = 0.6·t (24 rad at 40 s; 100 rad
    /// after 167 s). An error of 1e-6 in sin e_θ moves ω_c by k_th·1e-6 =
    /// 5e-6 rad/s, far below encoder resolution; 1e-6 in a heading's sin/cos
    /// moves the 4 m reference by 4 µm. The three-part reduction keeps the
    /// error at the kernel's ~1 ulp on the whole direct range: measured max
    /// 7.6e-8 on [−π, π], [−100, 100] and [−8192, 8192]; bound 2e-7.
    #[test]
    fn fast_sin_cos_abs_error() {
        for (range, bound) in [(core::f64::consts::PI, 2e-7), (100.0, 2e-7), (8192.0, 2e-7)] {
            let n = 400_000;
            let es = max_abs_err(-range, range, n, fast::sin, f64::sin);
            let ec = max_abs_err(-range, range, n, fast::cos, f64::cos);
            eprintln!("fast sin/cos on ±{range}: max abs error sin {es:.2e} cos {ec:.2e}");
            assert!(es < bound && ec < bound, "±{range}: sin {es:e} cos {ec:e}");
        }
        // Beyond the direct range: still bounded, periodic, finite.
        for &x in &[
            1.0e4f32,
            -3.0e5,
            1.0e7,
            3.3e7,
            -1.0e12,
            3.0e38,
            f32::MAX,
            f32::MIN,
        ] {
            let (s, c) = fast::sin_cos(x);
            assert!(
                s.abs() <= 1.0 + 1e-6 && c.abs() <= 1.0 + 1e-6,
                "{x}: {s} {c}"
            );
            assert!((s * s + c * c - 1.0).abs() < 1e-5);
        }
        // Just beyond it the turns removed in f32 cost a phase error of
        // |x|·(2π − 2π_f32)/2π ≈ 2.8e-8·|x| plus rounding: within 1e-7·|x|.
        let e = max_abs_err(8192.0, 1.0e5, 200_000, fast::sin, f64::sin);
        assert!(e < 1.0e-2, "sin on [8192, 1e5]: {e:e}");
        let e = max_abs_err(-1.0e5, -8192.0, 200_000, fast::cos, f64::cos);
        assert!(e < 1.0e-2, "cos on [-1e5, -8192]: {e:e}");
        let (s, c) = fast::sin_cos(f32::NAN);
        assert!(s.is_nan() && c.is_nan());
        assert!(fast::sin(f32::INFINITY).is_nan());
    }

    /// Identities that do not depend on a reference implementation: odd/even
    /// symmetry is exact, and sin² + cos² = 1 to a few ulp.
    #[test]
    fn fast_sin_cos_identities() {
        for i in 0..100_000 {
            let x = i as f32 * 1e-3 - 50.0;
            let (s, c) = fast::sin_cos(x);
            let (sn, cn) = fast::sin_cos(-x);
            assert_eq!((s, c), (-sn, cn), "x {x}");
            assert!((s * s + c * c - 1.0).abs() < 5e-7, "x {x}");
            assert_eq!(fast::sin(x), s);
            assert_eq!(fast::cos(x), c);
        }
        assert_eq!(fast::sin_cos(0.0), (0.0, 1.0));
    }

    /// atan2 gives the reference heading θ_s (from the curve's velocity,
    /// magnitudes 1e-3..10 m/s). A heading error of 1e-6 rad is 1e-6 rad of
    /// e_θ, negligible next to the 1e-3 rad an encoder resolves. Measured
    /// max error 2.6e-7 rad (≈ ulp(π)).
    #[test]
    fn fast_atan2_abs_error() {
        let mut worst = 0.0f64;
        for mag in [1e-4f64, 1e-2, 1.0, 37.0, 1e4] {
            for i in 0..=20_000 {
                let a = -core::f64::consts::PI + 2.0 * core::f64::consts::PI * i as f64 / 20_000.0;
                let (y, x) = ((mag * a.sin()) as f32, (mag * a.cos()) as f32);
                let e = (fast::atan2(y, x) as f64 - (y as f64).atan2(x as f64)).abs();
                // ±π are the same direction.
                let e = e.min((e - 2.0 * core::f64::consts::PI).abs());
                worst = worst.max(e);
            }
        }
        eprintln!("fast atan2: max abs error {worst:.2e} rad");
        assert!(worst < 5e-7, "atan2 max error {worst:e}");
        assert_eq!(fast::atan2(0.0, 0.0), 0.0);
        assert_eq!(fast::atan2(0.0, -1.0), PI);
        assert_eq!(fast::atan2(1.0, 0.0), core::f32::consts::FRAC_PI_2);
        assert_eq!(fast::atan2(-1.0, 0.0), -core::f32::consts::FRAC_PI_2);
        assert!(fast::atan2(f32::NAN, 1.0).is_nan() && fast::atan2(1.0, f32::NAN).is_nan());
    }

    /// tanh(s) is multiplied by ρ̂ <= ρ_max = 5 in eq. (24): an absolute error
    /// of 5e-7 is an acceleration error below 2.5e-6 m/s², 1e-6 of the
    /// torque limit's authority. Near s = 0 (the sliding regime) the
    /// polynomial branch is also relatively accurate (checked at 1e-6 rel).
    /// Measured: 7.1e-8 absolute over [−20, 20].
    #[test]
    fn fast_tanh_error() {
        let e = max_abs_err(-20.0, 20.0, 400_000, fast::tanh, f64::tanh);
        eprintln!("fast tanh on ±20: max abs error {e:.2e}");
        assert!(e < 5e-7, "tanh abs error {e:e}");
        for i in 1..10_000 {
            let x = i as f32 * 6e-5; // up to 0.6: polynomial branch
            let rel = ((fast::tanh(x) as f64 - (x as f64).tanh()) / (x as f64).tanh()).abs();
            assert!(rel < 1e-6, "x {x} rel {rel:e}");
        }
        assert_eq!(fast::tanh(100.0), 1.0);
        assert_eq!(fast::tanh(-100.0), -1.0);
        assert_eq!(fast::tanh(0.0), 0.0);
        assert!(fast::tanh(f32::NAN).is_nan());
    }

    /// powf serves fal (eq. 19): |e|^α with α = 0.01 for |e| > ζ, and the
    /// slope ζ^(α−1) (≈ 9.77 for ζ = 0.1). The ESO's gains multiply these,
    /// so a relative error of 2e-6 changes the observer's poles by 2e-6
    /// relative: nothing. Checked for exponents in [−1, 1] and |e| from 1e-6
    /// to 1e3, and y = 2 (|y·ln x| up to 28, where exp amplifies ln's
    /// rounding). Measured 1.0e-6 (at y = 2, x = 1e-6); bound 2e-6.
    #[test]
    fn fast_powf_rel_error() {
        let mut worst = 0.0f64;
        for &y in &[0.01f32, 0.5, 0.99, -0.99, -0.5, 1.0, 2.0] {
            for i in 0..=20_000 {
                // log-spaced base in [1e-6, 1e3]
                let x = 10f64.powf(-6.0 + 9.0 * i as f64 / 20_000.0) as f32;
                let r = (x as f64).powf(y as f64);
                let rel = ((fast::powf(x, y) as f64 - r) / r).abs();
                worst = worst.max(rel);
            }
        }
        eprintln!("fast powf: max rel error {worst:.2e}");
        assert!(worst < 2e-6, "powf max rel error {worst:e}");
        assert_eq!(fast::powf(0.0, 0.01), 0.0);
        assert!(fast::powf(-1.0, 0.5).is_nan());
        // ln and exp on their own.
        let el = max_abs_err(0.01, 100.0, 100_000, fast::ln, f64::ln);
        assert!(el < 5e-7, "ln abs error {el:e}");
        for i in 0..=100_000 {
            let x = -80.0 + 160.0 * i as f32 / 100_000.0;
            let r = (x as f64).exp();
            let rel = ((fast::exp(x) as f64 - r) / r).abs();
            assert!(rel < 3e-7, "exp({x}) rel {rel:e}");
        }
        assert_eq!(fast::exp(100.0), f32::INFINITY);
        assert_eq!(fast::exp(-100.0), 0.0);
    }

    /// sqrt gives |ṗ| (speed of the reference): relative 1e-6 is µm/s.
    /// Measured: 8.9e-8 relative (< 1 ulp) over 1e-30..1e30.
    #[test]
    fn fast_sqrt_rel_error() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let x = 10f64.powf(-30.0 + 60.0 * i as f64 / 200_000.0) as f32;
            let r = (x as f64).sqrt();
            worst = worst.max(((fast::sqrt(x) as f64 - r) / r).abs());
        }
        eprintln!("fast sqrt: max rel error {worst:.2e}");
        assert!(worst < 3e-7, "sqrt max rel error {worst:e}");
        // Perfect squares come out exact.
        for k in 1..2000u32 {
            let k = k as f32;
            assert_eq!(fast::sqrt(k * k), k);
        }
        assert_eq!(fast::sqrt(0.0), 0.0);
        assert!(fast::sqrt(-1.0).is_nan());
        assert_eq!(fast::sqrt(f32::INFINITY), f32::INFINITY);
        let sub = 1e-40f32;
        assert!(((fast::sqrt(sub) as f64 - (sub as f64).sqrt()) / 1e-20).abs() < 1e-3);
    }

    /// floor is exact; wrap_angle (built on it) stays within f32 resolution
    /// of the f64 reference (the phase error grows like ulp(x): 6e-5 at 1000).
    #[test]
    fn fast_floor_exact_and_wrap_accuracy() {
        for i in -200_000..200_000 {
            let x = i as f32 * 0.37 + 0.123;
            assert_eq!(fast::floor(x), libm::floorf(x), "{x}");
        }
        for x in [
            -0.0f32,
            0.0,
            -1.0,
            1.0,
            -0.5,
            1e9,
            -1e9,
            8_388_607.5,
            -8_388_607.5,
        ] {
            assert_eq!(fast::floor(x), libm::floorf(x), "{x}");
        }
        assert!(fast::floor(f32::NAN).is_nan());
        let mut worst = 0.0f64;
        for i in -100_000..100_000 {
            let x = i as f32 * 0.01;
            let w = wrap_angle(x) as f64;
            let d = (w - x as f64).rem_euclid(2.0 * core::f64::consts::PI);
            worst = worst.max(d.min(2.0 * core::f64::consts::PI - d));
        }
        eprintln!("wrap_angle on ±1000: max phase error {worst:.2e}");
        assert!(worst < 1e-4, "wrap error {worst:e}");
    }

    #[test]
    fn default_build_selects_fast() {
        #[cfg(not(any(feature = "accurate-math", feature = "runtime-math-select")))]
        {
            assert_eq!(selected(), MathImpl::Fast);
            assert_eq!(sin(1.0), fast::sin(1.0));
            assert!(!select(MathImpl::Accurate));
        }
        #[cfg(feature = "accurate-math")]
        {
            assert_eq!(selected(), MathImpl::Accurate);
            assert_eq!(sin(1.0), accurate::sin(1.0));
        }
    }

    /// With `runtime-math-select` the top-level functions follow [`select`].
    /// (Tests share the switch: only this test flips it, and it restores it.)
    #[cfg(all(feature = "runtime-math-select", not(feature = "accurate-math")))]
    #[test]
    fn runtime_selection_switches_implementation() {
        // An argument where the two differ in the last bits.
        let x = (1..1000)
            .map(|i| i as f32 * 0.0137)
            .find(|&x| fast::sin(x) != accurate::sin(x))
            .expect("fast and libm sin agree everywhere?");
        assert_eq!(selected(), MathImpl::Fast);
        assert_eq!(sin(x), fast::sin(x));
        assert!(select(MathImpl::Accurate));
        assert_eq!(selected(), MathImpl::Accurate);
        assert_eq!(sin(x), accurate::sin(x));
        assert!(select(MathImpl::Fast));
        assert_eq!(sin(x), fast::sin(x));
    }

    /// The table checks against the per-value predicate, on values
    /// including the special ones.
    #[test]
    fn table_checks_equal_per_value_checks() {
        let vals = [
            -1.0,
            -0.0,
            0.0,
            1e-30,
            1.0,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for &a in &vals {
            for &b in &vals {
                let pos = |x: f32| x.is_finite() && x > 0.0;
                let nonneg = |x: f32| x.is_finite() && x >= 0.0;
                assert_eq!(all_positive(&[a, b]), pos(a) && pos(b), "{a} {b}");
                assert_eq!(all_non_negative(&[a, b]), nonneg(a) && nonneg(b), "{a} {b}");
            }
        }
        assert!(all_positive(&[]) && all_non_negative(&[]));
    }

    /// Orderings written as differences: for finite a, b the difference
    /// is > 0 exactly when a > b, and >= 0 exactly when a >= b (f32
    /// subtraction of finite values never rounds a non-zero difference to
    /// zero or flips its sign; overflow gives an infinity, which fails).
    #[test]
    fn differences_order_like_comparisons() {
        let vals = [
            -3.0e38f32, -1.0, -1e-38, 0.0, 1e-45, 1e-38, 0.1, 0.1000001, 1.0, 3.0e38,
        ];
        for &a in &vals {
            for &b in &vals {
                let d = a - b;
                if d.is_finite() {
                    assert_eq!(d > 0.0, a > b, "{a} {b}");
                    assert_eq!(d >= 0.0, a >= b, "{a} {b}");
                }
            }
        }
    }
}
