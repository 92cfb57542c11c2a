//! Reduced dynamic model of eqs. (5)-(7).
//!
//! With the printed M0 (m11 = m22 = m, m13 = −m·d·sθ, m23 = m·d·cθ, m33 = I,
//! m44 = m55 = I_w), C0 (c13 = −m·d·ω·cθ, c23 = −m·d·ω·sθ), B0 (wheel torques
//! on φ_R, φ_L) and S(q) of eq. (3), the products of eq. (6) reduce to
//! constant or ω-linear 2x2 matrices (derivation in `book/src/explanation/paper-departures.md`, D1):
//!
//! * M1 = SᵀM0S = diag(m + 2I_w/r², I + 3md² + 2I_w h²/r²)
//! * N1 = SᵀM0Ṡ + SᵀC0S = 2mdω·\[\[0, −1\], \[1, 0\]\] (skew: does no work)
//! * B1 = SᵀB0 = \[\[1/r, 1/r\], \[h/r, −h/r\]\]
//!
//! and eq. (7): η̇ = Mη + Nτ + D with M = −M1⁻¹N1, N = M1⁻¹B1.
//! The tests rebuild M1, N1, B1 from the full 5x5 matrices numerically.

use crate::error::ConfigError;
use crate::params::RobotParams;

/// 2x2 matrix, row-major.
pub type Mat2 = [[f32; 2]; 2];

/// Matrix-vector product.
#[inline]
pub fn mat2_mul_vec(a: &Mat2, x: [f32; 2]) -> [f32; 2] {
    [
        a[0][0] * x[0] + a[0][1] * x[1],
        a[1][0] * x[0] + a[1][1] * x[1],
    ]
}

/// Reduced model quantities derived once from [`RobotParams`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReducedModel {
    /// The parameters the model was derived from.
    pub params: RobotParams,
    /// Diagonal of M1 = SᵀM0S: \[translational \[kg\], rotational \[kg·m²\]\].
    pub m1_diag: [f32; 2],
    /// N1 = n1_coeff·ω·\[\[0, −1\], \[1, 0\]\]; n1_coeff = 2md \[kg·m\].
    pub n1_coeff: f32,
    /// B1 = SᵀB0.
    pub b1: Mat2,
    /// N = M1⁻¹B1 (eq. 7).
    pub n: Mat2,
    /// N⁻¹ = B1⁻¹M1 (used by eqs. 22-24).
    pub n_inv: Mat2,
}

impl ReducedModel {
    /// Derives M1, N1, B1, N, N⁻¹ from validated parameters.
    pub fn new(params: &RobotParams) -> Result<Self, ConfigError> {
        let p = params.validate()?;
        let (m, i, iw, r, h, d) = (
            p.mass_kg,
            p.inertia_kgm2,
            p.wheel_inertia_kgm2,
            p.wheel_radius_m,
            p.half_track_m,
            p.com_offset_m,
        );
        let m1_diag = crate::params::m1_diagonal(m, i, iw, r, h, d);
        let b1 = [[1.0 / r, 1.0 / r], [h / r, -h / r]];
        let n = [
            [b1[0][0] / m1_diag[0], b1[0][1] / m1_diag[0]],
            [b1[1][0] / m1_diag[1], b1[1][1] / m1_diag[1]],
        ];
        // B1⁻¹ = (r/2)·[[1, 1/h], [1, −1/h]]; N⁻¹ = B1⁻¹·M1.
        let n_inv = [
            [0.5 * r * m1_diag[0], 0.5 * r * m1_diag[1] / h],
            [0.5 * r * m1_diag[0], -0.5 * r * m1_diag[1] / h],
        ];
        Ok(Self {
            params: p,
            m1_diag,
            n1_coeff: 2.0 * m * d,
            b1,
            n,
            n_inv,
        })
    }

    /// M(ω) = −M1⁻¹N1 (eq. 7).
    #[inline]
    pub fn m_matrix(&self, omega_radps: f32) -> Mat2 {
        let k = self.n1_coeff * omega_radps;
        [[0.0, k / self.m1_diag[0]], [-k / self.m1_diag[1], 0.0]]
    }

    /// Mη for the measured η (eq. 7), without building the matrix.
    #[inline]
    pub fn m_eta(&self, eta: [f32; 2]) -> [f32; 2] {
        let k = self.n1_coeff * eta[1];
        [k * eta[1] / self.m1_diag[0], -k * eta[0] / self.m1_diag[1]]
    }

    /// Nτ (eq. 7) for wheel torques `[right, left]`.
    #[inline]
    pub fn n_tau(&self, torque_nm: [f32; 2]) -> [f32; 2] {
        mat2_mul_vec(&self.n, torque_nm)
    }

    /// Eq. (7)'s torques-to-wheel-accelerations map W = S·N, S =
    /// \[\[1/r, h/r\], \[1/r, −h/r\]\]: row i is wheel i's (right, left)
    /// angular acceleration per N·m at wheel j \[rad/s² per N·m\]; the
    /// diagonal W_ii is positive (a wheel's own torque speeds it up).
    pub fn wheel_accel_map(&self) -> Mat2 {
        let (h, inv_r) = (self.params.half_track_m, 1.0 / self.params.wheel_radius_m);
        let n = &self.n;
        [
            [
                (n[0][0] + h * n[1][0]) * inv_r,
                (n[0][1] + h * n[1][1]) * inv_r,
            ],
            [
                (n[0][0] - h * n[1][0]) * inv_r,
                (n[0][1] - h * n[1][1]) * inv_r,
            ],
        ]
    }

    /// N⁻¹a: the wheel torques `[right, left]` that produce the acceleration `a`.
    #[inline]
    pub fn n_inv_mul(&self, a: [f32; 2]) -> [f32; 2] {
        mat2_mul_vec(&self.n_inv, a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type M5 = [[f64; 5]; 5];

    fn s_mat(p: &RobotParams, th: f64) -> [[f64; 2]; 5] {
        let (r, h, d) = (
            p.wheel_radius_m as f64,
            p.half_track_m as f64,
            p.com_offset_m as f64,
        );
        let (s, c) = th.sin_cos();
        [
            [c, -d * s],
            [s, d * c],
            [0.0, 1.0],
            [1.0 / r, h / r],
            [1.0 / r, -h / r],
        ]
    }

    fn m0(p: &RobotParams, th: f64) -> M5 {
        let (m, i, iw, d) = (
            p.mass_kg as f64,
            p.inertia_kgm2 as f64,
            p.wheel_inertia_kgm2 as f64,
            p.com_offset_m as f64,
        );
        let (s, c) = th.sin_cos();
        let mut a = [[0.0; 5]; 5];
        a[0][0] = m;
        a[1][1] = m;
        a[0][2] = -m * d * s;
        a[2][0] = a[0][2];
        a[1][2] = m * d * c;
        a[2][1] = a[1][2];
        a[2][2] = i;
        a[3][3] = iw;
        a[4][4] = iw;
        a
    }

    /// Sᵀ X S for 5x5 X.
    fn congruence(sm: &[[f64; 2]; 5], x: &M5, sr: &[[f64; 2]; 5]) -> [[f64; 2]; 2] {
        let mut out = [[0.0; 2]; 2];
        for (i, row) in out.iter_mut().enumerate() {
            for (j, o) in row.iter_mut().enumerate() {
                for a in 0..5 {
                    for b in 0..5 {
                        *o += sm[a][i] * x[a][b] * sr[b][j];
                    }
                }
            }
        }
        out
    }

    #[test]
    fn reduced_matrices_match_full_model() {
        let p = RobotParams::paper();
        let model = ReducedModel::new(&p).unwrap();
        for &(th, om) in &[(0.0, 0.0), (0.7, 1.3), (-2.1, -0.4), (3.0, 2.0)] {
            let sm = s_mat(&p, th);
            let m1 = congruence(&sm, &m0(&p, th), &sm);
            // M1 symmetric positive definite, equal to the closed form.
            assert!((m1[0][1] - m1[1][0]).abs() < 1e-9);
            assert!(m1[0][0] > 0.0 && m1[0][0] * m1[1][1] - m1[0][1] * m1[1][0] > 0.0);
            assert!((m1[0][0] - model.m1_diag[0] as f64).abs() < 1e-4);
            assert!((m1[1][1] - model.m1_diag[1] as f64).abs() < 1e-4);
            assert!(m1[0][1].abs() < 1e-9);
            // Ṡ = dS/dθ · ω; N1 = SᵀM0Ṡ + SᵀC0S.
            let (s, c) = f64::sin_cos(th);
            let d = p.com_offset_m as f64;
            let mut sdot = [[0.0; 2]; 5];
            sdot[0] = [-s * om, -d * c * om];
            sdot[1] = [c * om, -d * s * om];
            let mut c0 = [[0.0; 5]; 5];
            let md = p.mass_kg as f64 * d;
            c0[0][2] = -md * om * c;
            c0[1][2] = -md * om * s;
            let n1a = congruence(&sm, &m0(&p, th), &sdot);
            let n1b = congruence(&sm, &c0, &sm);
            let mm = model.m_matrix(om as f32);
            for i in 0..2 {
                for j in 0..2 {
                    let n1 = n1a[i][j] + n1b[i][j];
                    // M = −M1⁻¹N1
                    let m_ref = -n1 / m1[i][i];
                    assert!((m_ref - mm[i][j] as f64).abs() < 1e-4, "M[{i}][{j}]");
                }
            }
            // Skew N1: no power, ηᵀN1η = 0 for any η.
            let eta = [0.8, om];
            let n1 = [
                [n1a[0][0] + n1b[0][0], n1a[0][1] + n1b[0][1]],
                [n1a[1][0] + n1b[1][0], n1a[1][1] + n1b[1][1]],
            ];
            let p_n = eta[0] * (n1[0][0] * eta[0] + n1[0][1] * eta[1])
                + eta[1] * (n1[1][0] * eta[0] + n1[1][1] * eta[1]);
            assert!(p_n.abs() < 1e-9);
        }
    }

    #[test]
    fn constraint_matrix_annihilates_s() {
        // A(q) with the corrected row 2 (Cθ Sθ) and row 3 (φ̇_L): A·S = 0.
        let p = RobotParams::paper();
        let (r, h, d) = (
            p.wheel_radius_m as f64,
            p.half_track_m as f64,
            p.com_offset_m as f64,
        );
        for th in [0.0f64, 0.4, 1.9, -2.7] {
            let (s, c) = th.sin_cos();
            let a = [
                [-s, c, -d, 0.0, 0.0],
                [c, s, h, -r, 0.0],
                [c, s, -h, 0.0, -r],
            ];
            let sm = s_mat(&p, th);
            for row in a {
                for j in 0..2 {
                    let v: f64 = (0..5).map(|k| row[k] * sm[k][j]).sum();
                    assert!(v.abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn n_and_n_inv_are_inverses() {
        let m = ReducedModel::new(&RobotParams::paper()).unwrap();
        let a = [1.3, -0.7];
        let back = m.n_tau(m.n_inv_mul(a));
        assert!((back[0] - a[0]).abs() < 1e-5 && (back[1] - a[1]).abs() < 1e-5);
    }

    #[test]
    fn invalid_params_rejected() {
        let mut p = RobotParams::paper();
        p.mass_kg = -1.0;
        assert_eq!(ReducedModel::new(&p), Err(ConfigError::NonPositiveMass));
        let mut p = RobotParams::paper();
        p.wheel_radius_m = f32::NAN;
        assert_eq!(p.validate(), Err(ConfigError::NonPositiveWheelRadius));
        let mut p = RobotParams::paper();
        p.half_track_m = 0.0;
        assert_eq!(p.validate(), Err(ConfigError::NonPositiveHalfTrack));
        let mut p = RobotParams::paper();
        p.com_offset_m = f32::INFINITY;
        assert_eq!(p.validate(), Err(ConfigError::NegativeComOffset));
    }
}
