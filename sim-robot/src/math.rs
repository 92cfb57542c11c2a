//! f64 trigonometry of the simulation: the platform's (`std` feature, the
//! host) or the `libm` crate's (`no_std`, e.g. an emulated Cortex-M board).
//! Both are within an ulp; runs on the two differ at that level only.

/// (sin x, cos x).
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    (sin(x), cos(x))
}

/// sin x.
#[inline]
pub fn sin(x: f64) -> f64 {
    #[cfg(any(feature = "std", test))]
    return x.sin();
    #[cfg(not(any(feature = "std", test)))]
    return libm::sin(x);
}

/// cos x.
#[inline]
pub fn cos(x: f64) -> f64 {
    #[cfg(any(feature = "std", test))]
    return x.cos();
    #[cfg(not(any(feature = "std", test)))]
    return libm::cos(x);
}

/// Natural logarithm of x.
#[inline]
pub fn ln(x: f64) -> f64 {
    #[cfg(any(feature = "std", test))]
    return x.ln();
    #[cfg(not(any(feature = "std", test)))]
    return libm::log(x);
}

/// Square root of x (correctly rounded on both).
#[inline]
pub fn sqrt(x: f64) -> f64 {
    #[cfg(any(feature = "std", test))]
    return x.sqrt();
    #[cfg(not(any(feature = "std", test)))]
    return libm::sqrt(x);
}

/// x rounded to the nearest integer, halves away from zero.
#[inline]
pub fn round(x: f64) -> f64 {
    #[cfg(any(feature = "std", test))]
    return x.round();
    #[cfg(not(any(feature = "std", test)))]
    return libm::round(x);
}
