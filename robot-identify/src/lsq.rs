//! Linear least squares with the statistics an identification needs:
//! estimates, their covariance from the residual, 95 % confidence
//! intervals, the residual RMS and the condition number of the regressor.
//!
//! Solved by the singular value decomposition (nalgebra) of the regressor
//! with each column scaled to unit norm (so that the condition number
//! measures collinearity, not units). σ² = RSS/(n − p); cov = σ²(ΦᵀΦ)⁻¹,
//! inflated by the residuals' correlation (the rows come from a filtered,
//! oversampled signal: neighbouring residuals are not independent):
//! f = 1 + 2·Σ_{j=1..L}(1 − j/(L + 1))·ρ_j over the lags L of the filter
//! window (a Bartlett-weighted long-run variance), at least 1.

use nalgebra::{DMatrix, DVector};

/// 97.5 % quantile of the standard normal (two-sided 95 % interval; the
/// fits have thousands of rows, where Student's t is the normal).
pub const Z95: f64 = 1.959_964;

/// A least-squares fit.
#[derive(Clone, Debug, PartialEq)]
pub struct LsqFit {
    /// Estimates, in the order of the regressor's columns.
    pub theta: Vec<f64>,
    /// Their standard errors (after the correlation inflation).
    pub std_err: Vec<f64>,
    /// Covariance of the estimates.
    pub cov: DMatrix<f64>,
    /// Root mean square of the residual, in the unit of y.
    pub residual_rms: f64,
    /// Condition number of the column-scaled regressor (∞ when singular).
    pub condition: f64,
    /// The right singular vector of the smallest singular value, in the
    /// scaled columns: which combination of parameters is least determined.
    pub weakest: Vec<f64>,
    /// Rows used.
    pub rows: usize,
    /// Variance inflation from the residuals' correlation (≥ 1).
    pub inflation: f64,
}

/// Why a fit could not be made.
#[derive(Clone, Debug, PartialEq)]
pub enum LsqError {
    /// Fewer rows than twice the parameters.
    TooFewRows {
        /// Rows given.
        rows: usize,
        /// Parameters.
        params: usize,
    },
    /// A column is all zero: its parameter is not excited at all.
    ZeroColumn(usize),
    /// A value is NaN or infinite.
    NonFinite,
}

impl std::fmt::Display for LsqError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TooFewRows { rows, params } => write!(
                f,
                "{rows} usable rows for {params} parameters: the log is too short"
            ),
            Self::ZeroColumn(j) => write!(f, "regressor column {j} is zero: not excited"),
            Self::NonFinite => f.write_str("a regressor value is not finite"),
        }
    }
}

/// Solves y ≈ Φθ; `corr_lags`: lags over which residuals are correlated
/// (the filter's window).
pub fn solve(phi: &DMatrix<f64>, y: &DVector<f64>, corr_lags: usize) -> Result<LsqFit, LsqError> {
    let (n, p) = phi.shape();
    if n < 2 * p || n <= p {
        return Err(LsqError::TooFewRows { rows: n, params: p });
    }
    if phi.iter().chain(y.iter()).any(|x| !x.is_finite()) {
        return Err(LsqError::NonFinite);
    }
    let norms: Vec<f64> = (0..p).map(|j| phi.column(j).norm()).collect();
    if let Some(j) = norms.iter().position(|&c| c == 0.0) {
        return Err(LsqError::ZeroColumn(j));
    }
    let mut scaled = phi.clone();
    for (j, c) in norms.iter().enumerate() {
        scaled.column_mut(j).scale_mut(1.0 / c);
    }
    let svd = scaled.clone().svd(true, true);
    let (u, vt) = (svd.u.as_ref().unwrap(), svd.v_t.as_ref().unwrap());
    let s = &svd.singular_values;
    let (mut smax, mut smin, mut imin) = (0.0f64, f64::INFINITY, 0);
    for (i, &x) in s.iter().enumerate() {
        smax = smax.max(x);
        if x < smin {
            smin = x;
            imin = i;
        }
    }
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    let tol = smax * 1e-12;
    // θ_scaled = V Σ⁺ Uᵀ y; (ΦsᵀΦs)⁻¹ = V Σ⁻² Vᵀ.
    let uty = u.transpose() * y;
    let mut theta_s = DVector::zeros(p);
    let mut inv_gram = DMatrix::zeros(p, p);
    for i in 0..s.len() {
        if s[i] > tol {
            let vi = vt.row(i).transpose();
            theta_s += &vi * (uty[i] / s[i]);
            inv_gram += &vi * vi.transpose() / (s[i] * s[i]);
        } else {
            // Singular: an unbounded variance along this direction.
            let vi = vt.row(i).transpose();
            inv_gram += &vi * vi.transpose() * 1e300;
        }
    }
    let resid = y - &scaled * &theta_s;
    let rss = resid.norm_squared();
    let sigma2 = rss / (n - p) as f64;
    // Residual autocorrelation up to the filter's lags.
    let lags = corr_lags.min(n / 4);
    let mut inflation = 1.0;
    if rss > 0.0 {
        for j in 1..=lags {
            let c: f64 = (j..n).map(|k| resid[k] * resid[k - j]).sum::<f64>() / rss;
            inflation += 2.0 * (1.0 - j as f64 / (lags + 1) as f64) * c;
        }
    }
    let inflation = inflation.max(1.0);
    let mut cov = inv_gram * (sigma2 * inflation);
    for i in 0..p {
        for j in 0..p {
            cov[(i, j)] /= norms[i] * norms[j];
        }
    }
    let theta: Vec<f64> = (0..p).map(|j| theta_s[j] / norms[j]).collect();
    let std_err = (0..p).map(|j| cov[(j, j)].max(0.0).sqrt()).collect();
    Ok(LsqFit {
        theta,
        std_err,
        cov,
        residual_rms: (rss / n as f64).sqrt(),
        condition,
        weakest: vt.row(imin).iter().copied().collect(),
        rows: n,
        inflation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    /// A known line with white noise: the estimates fall inside their 95 %
    /// intervals about 95 % of the time over many draws (checked loosely:
    /// at least 85 of 100), the interval shrinks like 1/√n, and the
    /// residual RMS is the noise's standard deviation.
    #[test]
    fn intervals_cover_the_truth() {
        let mut st = 7u64;
        let mut covered = 0;
        for _ in 0..100 {
            let n = 400;
            let phi = DMatrix::from_fn(n, 2, |i, j| if j == 0 { 1.0 } else { i as f64 / n as f64 });
            let y = DVector::from_fn(n, |i, _| 2.0 - 3.0 * (i as f64 / n as f64) + lcg(&mut st));
            let f = solve(&phi, &y, 0).unwrap();
            let ok = (0..2).all(|j| (f.theta[j] - [2.0, -3.0][j]).abs() <= Z95 * f.std_err[j]);
            covered += ok as u32;
            // Uniform(−0.5, 0.5): σ = 1/√12.
            assert!((f.residual_rms - 12f64.sqrt().recip()).abs() < 0.03);
        }
        assert!(covered >= 85, "{covered} of 100");
    }

    /// Two identical columns: the condition number is infinite (or huge)
    /// and the weakest direction is their difference.
    #[test]
    fn collinear_columns_are_flagged() {
        let n = 100;
        let phi = DMatrix::from_fn(n, 3, |i, j| match j {
            0 => (i as f64).sin(),
            1 => (i as f64).sin(),
            _ => (i as f64 * 0.37).cos(),
        });
        let y = DVector::from_fn(n, |i, _| (i as f64).sin());
        let f = solve(&phi, &y, 0).unwrap();
        assert!(f.condition > 1e8, "{}", f.condition);
        assert!((f.weakest[0] + f.weakest[1]).abs() < 1e-6);
        assert!(f.std_err[0] > 1e6);
        let z = DMatrix::from_fn(n, 2, |i, j| if j == 0 { i as f64 } else { 0.0 });
        assert_eq!(solve(&z, &y, 0), Err(LsqError::ZeroColumn(1)));
    }
}
