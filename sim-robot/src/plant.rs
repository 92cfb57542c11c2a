//! The paper's robot, in f64.
//!
//! State: q = \[x, y, θ, φ_R, φ_L\] (x, y of the centre of mass G) and the
//! body velocity ν = η − σ of eq. (6) (η = \[v, ω\] is what the wheels impose
//! and the encoders see; σ is the slip of eq. 3).
//!
//! * Dynamics (6): M1·ν̇ + N1(θ̇)·ν + P1 + Sᵀτ_d = B1·τ, with the plant's own
//!   (possibly scaled) mass and inertia. M1, N1 as derived in controller-core's
//!   `model` module; P1 = SᵀM0·U̇_D + SᵀC0·U_D in closed form:
//!   P1 = \[−m·θ̇·δ + I_w(ϖ̇_R + ϖ̇_L)/r, 2md·δ̇ + I_w·h(ϖ̇_R − ϖ̇_L)/r\]
//!   (C0·U_D = 0 because U_D has no θ component). Checked against the 5x5
//!   products in the tests.
//! * Kinematics (3) with the actuator fault (10): the wheels turn per η
//!   (φ̇_R = (v + hω)/r, φ̇_L = (v − hω)/r) while the body moves at
//!   η_b = (1 − ε)·η − σ, i.e. q̇_{x,y,θ} = S(θ)·η_b + U_D.
//!
//! Integration: classical RK4. The wheel torques come from a [`Drive`]
//! evaluated at each stage's wheel rates (a torque source holds them; a DC
//! motor at fixed duty feels its back-EMF continuously). At most one sin/cos
//! of θ per step, none when the step starts where the last one ended: the
//! stages' headings (and the end's) differ from the step's start by a small
//! angle δ, and sin/cos(θ + δ) follow from the angle-sum identities with
//! series for sin δ and cos δ (exact to rounding for |δ| ≤ [`SMALL_ANGLE_RAD`];
//! larger δ falls back to sin/cos).

use crate::math::sin_cos;
use controller_core::params::{eta_from_wheel_rates, m1_diagonal, wheel_rates};
use controller_core::RobotParams;
use core::cell::Cell;

/// Plant physical parameters (f64 copy of [`RobotParams`], possibly scaled).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantParams {
    /// m \[kg\].
    pub mass_kg: f64,
    /// I \[kg·m²\].
    pub inertia_kgm2: f64,
    /// I_w \[kg·m²\].
    pub wheel_inertia_kgm2: f64,
    /// r \[m\].
    pub wheel_radius_m: f64,
    /// h \[m\].
    pub half_track_m: f64,
    /// d \[m\].
    pub com_offset_m: f64,
}

impl PlantParams {
    /// The robot of `p` with mass and body inertia scaled (model mismatch).
    pub fn from_robot(p: &RobotParams, mass_scale: f64, inertia_scale: f64) -> Self {
        Self {
            mass_kg: p.mass_kg as f64 * mass_scale,
            inertia_kgm2: p.inertia_kgm2 as f64 * inertia_scale,
            wheel_inertia_kgm2: p.wheel_inertia_kgm2 as f64,
            wheel_radius_m: p.wheel_radius_m as f64,
            half_track_m: p.half_track_m as f64,
            com_offset_m: p.com_offset_m as f64,
        }
    }

    /// Diagonal of M1 (controller-core's [`m1_diagonal`], in f64).
    pub fn m1_diag(&self) -> [f64; 2] {
        let (m, i, iw, r, h, d) = self.unpack();
        m1_diagonal(m, i, iw, r, h, d)
    }

    fn unpack(&self) -> (f64, f64, f64, f64, f64, f64) {
        (
            self.mass_kg,
            self.inertia_kgm2,
            self.wheel_inertia_kgm2,
            self.wheel_radius_m,
            self.half_track_m,
            self.com_offset_m,
        )
    }
}

/// Perturbations acting at one instant (from the scenario).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Perturbation {
    /// Lateral skid velocity δ_sl \[m/s\] and its time derivative.
    pub skid_mps: f64,
    /// dδ_sl/dt \[m/s²\].
    pub skid_rate_mps2: f64,
    /// Wheel slip rates ϖ = \[ϖ_R, ϖ_L\] \[rad/s\].
    pub wheel_slip_radps: [f64; 2],
    /// dϖ/dt \[rad/s²\].
    pub wheel_slip_rate_radps2: [f64; 2],
    /// External disturbance τ_d = \[f_x, f_y, τ_θ, τ_R, τ_L\] (N, N, N·m, N·m, N·m).
    pub tau_d: [f64; 5],
    /// Actuator fault ε (body moves at (1 − ε)η), 0 = healthy.
    pub fault_eps: f64,
}

/// Plant state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlantState {
    /// q = \[x, y, θ, φ_R, φ_L\].
    pub q: [f64; 5],
    /// ν = η − σ \[m/s, rad/s\].
    pub nu: [f64; 2],
}

/// Where the wheel torques come from, evaluated at every integration
/// stage from the wheel rates φ̇ = \[φ̇_R, φ̇_L\] \[rad/s\].
pub trait Drive {
    /// Wheel torques `[right, left]` \[N·m\] at these wheel rates.
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2];
}

/// Torques held over the step (an ideal torque source, zero-order hold).
impl Drive for [f64; 2] {
    fn torque_nm(&self, _wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        *self
    }
}

/// A drive whose wheels deliver only `scale` of the inner drive's torque
/// (an actuator losing torque: a weak motor, a slipping gearbox), beyond
/// the paper. `scale = [1, 1]` gives the inner torques exactly.
#[derive(Clone, Copy, Debug)]
pub struct TorqueScaled<'a, D: Drive> {
    /// The commanded drive.
    pub drive: &'a D,
    /// Fraction of torque each wheel `[right, left]` delivers.
    pub scale: [f64; 2],
}

impl<D: Drive> Drive for TorqueScaled<'_, D> {
    fn torque_nm(&self, wheel_rates_radps: [f64; 2]) -> [f64; 2] {
        let t = self.drive.torque_nm(wheel_rates_radps);
        [t[0] * self.scale[0], t[1] * self.scale[1]]
    }
}

/// |δ| \[rad\] up to which sin/cos(θ + δ) are formed from sin/cos θ and
/// series in δ to δ⁷: the first omitted terms, δ⁸/8! and δ⁹/9!, stay below
/// 10⁻¹⁷ (under a tenth of an f64 ulp of 1). Beyond it: sin/cos.
pub const SMALL_ANGLE_RAD: f64 = 0.02;

/// sin/cos of θ0 + δ from (sin θ0, cos θ0): angle sums with Taylor series
/// of sin δ, cos δ for small |δ|, sin/cos otherwise.
#[inline]
fn sin_cos_offset(theta0: f64, sc0: (f64, f64), delta: f64) -> (f64, f64) {
    if delta.abs() > SMALL_ANGLE_RAD {
        return sin_cos(theta0 + delta);
    }
    // Horner with the reciprocals as constants (six divisions in a chain
    // cost more than the rest of a stage; the products differ from the
    // quotients by an ulp of terms below 10⁻⁴: D57).
    let d2 = delta * delta;
    let sd =
        delta * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0))));
    let cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
    let (s0, c0) = sc0;
    (s0 * cd + c0 * sd, c0 * cd - s0 * sd)
}

/// The simulated robot.
#[derive(Clone, Debug)]
pub struct Plant {
    params: PlantParams,
    /// Constants of (3) and (6) computed once.
    k: Constants,
    /// θ at the end of the last step (its bits) and its (sin, cos), formed
    /// from that step's start: the next step starting there needs no sin/cos.
    theta_end: Cell<(u64, (f64, f64))>,
}

/// Products and reciprocals of the parameters used at every evaluation.
#[derive(Clone, Copy, Debug)]
struct Constants {
    inv_r: f64,
    h: f64,
    d: f64,
    m: f64,
    /// 2·m·d (N1 and P1).
    two_md: f64,
    /// I_w/r (P1).
    iw_over_r: f64,
    /// 1/M1 diagonal.
    inv_m1: [f64; 2],
}

/// The parts of (3) and (6) that depend only on the perturbations at one
/// instant (shared by the RK4 stages at that instant).
#[derive(Clone, Copy, Debug)]
struct Forcing {
    /// σ of eq. (3).
    sigma: [f64; 2],
    /// 1 − ε of eq. (10).
    healthy: f64,
    /// δ_sl.
    skid_mps: f64,
    /// P1 without its θ̇ term: \[I_w(ϖ̇_R + ϖ̇_L)/r, 2md·δ̇ + I_w·h(ϖ̇_R − ϖ̇_L)/r\].
    p1_rest: [f64; 2],
    /// τ_d's world-frame force \[f_x, f_y\] (rotated by θ in Sᵀτ_d).
    force_xy: [f64; 2],
    /// Sᵀτ_d without the force: \[(τ_R + τ_L)/r, τ_θ + h(τ_R − τ_L)/r\].
    tau_body: [f64; 2],
}

impl Plant {
    /// The plant with these parameters.
    pub fn new(params: PlantParams) -> Self {
        let (m, _, iw, r, h, d) = params.unpack();
        let m1 = params.m1_diag();
        Self {
            params,
            theta_end: Cell::new((f64::NAN.to_bits(), (0.0, 1.0))),
            k: Constants {
                inv_r: 1.0 / r,
                h,
                d,
                m,
                two_md: 2.0 * m * d,
                iw_over_r: iw / r,
                inv_m1: [1.0 / m1[0], 1.0 / m1[1]],
            },
        }
    }

    /// Physical parameters.
    #[inline]
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// σ = \[σ_v, σ_ω\] of eq. (3) for wheel slip ϖ (with the sign fixed: D15):
    /// the η that wheel rates ϖ would give (controller-core's
    /// [`eta_from_wheel_rates`], in f64).
    #[inline]
    pub fn sigma(&self, slip: [f64; 2]) -> [f64; 2] {
        let (r, h) = (self.params.wheel_radius_m, self.params.half_track_m);
        eta_from_wheel_rates(r, h, slip)
    }

    /// η = ν + σ: the wheel-imposed velocities the encoders see.
    #[inline]
    pub fn eta(&self, st: &PlantState, p: &Perturbation) -> [f64; 2] {
        let s = self.sigma(p.wheel_slip_radps);
        [st.nu[0] + s[0], st.nu[1] + s[1]]
    }

    /// Wheel rates φ̇ = \[(v + hω)/r, (v − hω)/r\] \[rad/s\] (eq. 3, rows 4-5).
    #[inline]
    pub fn wheel_rates_radps(&self, st: &PlantState, p: &Perturbation) -> [f64; 2] {
        wheel_rates(self.k.inv_r, self.k.h, self.eta(st, p))
    }

    #[inline]
    fn forcing(&self, p: &Perturbation) -> Forcing {
        let k = &self.k;
        let sr = p.wheel_slip_rate_radps2;
        let t = p.tau_d;
        Forcing {
            sigma: self.sigma(p.wheel_slip_radps),
            healthy: 1.0 - p.fault_eps,
            skid_mps: p.skid_mps,
            p1_rest: [
                k.iw_over_r * (sr[0] + sr[1]),
                k.two_md * p.skid_rate_mps2 + k.iw_over_r * k.h * (sr[0] - sr[1]),
            ],
            force_xy: [t[0], t[1]],
            tau_body: [
                (t[3] + t[4]) * k.inv_r,
                t[2] + k.h * (t[3] - t[4]) * k.inv_r,
            ],
        }
    }

    /// q̇ (eq. 3 with the fault of eq. 10).
    #[inline]
    pub fn q_dot(&self, st: &PlantState, p: &Perturbation) -> [f64; 5] {
        self.q_dot_f(st, &self.forcing(p), sin_cos(st.q[2]))
    }

    /// q̇ of eq. (3) with the fault (10): the wheels turn per η = ν + σ, the
    /// body moves at (1 − ε)η − σ plus the skid.
    #[inline]
    fn q_dot_f(&self, st: &PlantState, f: &Forcing, (s, c): (f64, f64)) -> [f64; 5] {
        let k = &self.k;
        let eta = [st.nu[0] + f.sigma[0], st.nu[1] + f.sigma[1]];
        let vb = f.healthy * eta[0] - f.sigma[0];
        let wb = f.healthy * eta[1] - f.sigma[1];
        let dl = f.skid_mps;
        let [rate_r, rate_l] = wheel_rates(k.inv_r, k.h, eta);
        [
            vb * c - k.d * wb * s - s * dl,
            vb * s + k.d * wb * c + c * dl,
            wb,
            rate_r,
            rate_l,
        ]
    }

    /// ν̇ from eq. (6) for wheel torques `[right, left]`.
    #[inline]
    pub fn nu_dot(&self, st: &PlantState, p: &Perturbation, torque_nm: [f64; 2]) -> [f64; 2] {
        let sc = sin_cos(st.q[2]);
        let f = self.forcing(p);
        let theta_dot = self.q_dot_f(st, &f, sc)[2];
        self.nu_dot_f(st, &f, torque_nm, theta_dot, sc)
    }

    /// ν̇ of eq. (6): M1·ν̇ = B1·τ − N1(θ̇)·ν − P1 − Sᵀτ_d.
    #[inline]
    fn nu_dot_f(
        &self,
        st: &PlantState,
        f: &Forcing,
        torque_nm: [f64; 2],
        theta_dot: f64,
        (s, c): (f64, f64),
    ) -> [f64; 2] {
        let k = &self.k;
        let n1c = k.two_md * theta_dot;
        let n1nu = [-n1c * st.nu[1], n1c * st.nu[0]];
        let p1 = [-k.m * theta_dot * f.skid_mps + f.p1_rest[0], f.p1_rest[1]];
        let [fx, fy] = f.force_xy;
        let std = [
            c * fx + s * fy + f.tau_body[0],
            k.d * (c * fy - s * fx) + f.tau_body[1],
        ];
        let b1tau = [
            (torque_nm[0] + torque_nm[1]) * k.inv_r,
            k.h * (torque_nm[0] - torque_nm[1]) * k.inv_r,
        ];
        [
            (b1tau[0] - n1nu[0] - p1[0] - std[0]) * k.inv_m1[0],
            (b1tau[1] - n1nu[1] - p1[1] - std[1]) * k.inv_m1[1],
        ]
    }

    /// (q̇, ν̇) at (sin θ, cos θ) = `sc`, the drive's torque taken at the
    /// state's wheel rates (q̇ rows 4-5).
    #[inline]
    fn deriv(
        &self,
        st: &PlantState,
        f: &Forcing,
        drive: &impl Drive,
        sc: (f64, f64),
    ) -> PlantState {
        let q = self.q_dot_f(st, f, sc);
        let tau = drive.torque_nm([q[3], q[4]]);
        let nu = self.nu_dot_f(st, f, tau, q[2], sc);
        PlantState { q, nu }
    }

    /// One classical RK4 step of length `h_s` from `t_s`; `perturb(t)` gives
    /// the perturbations at time t (asked at t, t + h/2 and t + h: a
    /// [`PerturbationGrid`](crate::PerturbationGrid) of step h/2 serves them
    /// cheaply), `drive` the wheel torques at each stage.
    #[inline]
    pub fn rk4_step(
        &self,
        st: &PlantState,
        t_s: f64,
        h_s: f64,
        drive: &impl Drive,
        perturb: &mut impl FnMut(f64) -> Perturbation,
    ) -> PlantState {
        let add = |a: &PlantState, k: &PlantState, f: f64| {
            let mut o = *a;
            for i in 0..5 {
                o.q[i] += f * k.q[i];
            }
            for i in 0..2 {
                o.nu[i] += f * k.nu[i];
            }
            o
        };
        let th0 = st.q[2];
        let sc0 = match self.theta_end.get() {
            (bits, sc) if bits == th0.to_bits() => sc,
            _ => sin_cos(th0),
        };
        let p0 = self.forcing(&perturb(t_s));
        let pm = self.forcing(&perturb(t_s + 0.5 * h_s));
        let p1 = self.forcing(&perturb(t_s + h_s));
        let k1 = self.deriv(st, &p0, drive, sc0);
        let s2 = add(st, &k1, 0.5 * h_s);
        let k2 = self.deriv(&s2, &pm, drive, sin_cos_offset(th0, sc0, s2.q[2] - th0));
        let s3 = add(st, &k2, 0.5 * h_s);
        let k3 = self.deriv(&s3, &pm, drive, sin_cos_offset(th0, sc0, s3.q[2] - th0));
        let s4 = add(st, &k3, h_s);
        let k4 = self.deriv(&s4, &p1, drive, sin_cos_offset(th0, sc0, s4.q[2] - th0));
        let mut o = *st;
        for i in 0..5 {
            o.q[i] += h_s / 6.0 * (k1.q[i] + 2.0 * k2.q[i] + 2.0 * k3.q[i] + k4.q[i]);
        }
        for i in 0..2 {
            o.nu[i] += h_s / 6.0 * (k1.nu[i] + 2.0 * k2.nu[i] + 2.0 * k3.nu[i] + k4.nu[i]);
        }
        let sc_end = sin_cos_offset(th0, sc0, o.q[2] - th0);
        self.theta_end.set((o.q[2].to_bits(), sc_end));
        o
    }

    /// True when every state component is finite. (One sum: a NaN or an
    /// infinity in any component makes it non-finite; finite components
    /// only overflow it beyond 10³⁰⁷, a diverged state anyway.)
    #[inline]
    pub fn state_is_finite(st: &PlantState) -> bool {
        let [a, b, c, d, e] = st.q;
        let [f, g] = st.nu;
        (a + b + c + d + e + f + g).is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controller_core::RobotParams;

    fn paper_plant() -> Plant {
        Plant::new(PlantParams::from_robot(&RobotParams::paper(), 1.0, 1.0))
    }

    fn perturbed(t: f64) -> Perturbation {
        Perturbation {
            skid_mps: 0.1 + 0.04 * t.sin(),
            skid_rate_mps2: 0.04 * t.cos(),
            wheel_slip_radps: [0.15 * t.sin(), 0.15 * t.cos()],
            wheel_slip_rate_radps2: [0.15 * t.cos(), -0.15 * t.sin()],
            tau_d: [0.0, 0.0, 0.2 * t.sin(), 0.5, -0.3],
            fault_eps: 0.0,
        }
    }

    fn run(
        plant: &Plant,
        h: f64,
        t_end: f64,
        tau: [f64; 2],
        pert: &mut impl FnMut(f64) -> Perturbation,
    ) -> PlantState {
        let mut st = PlantState {
            q: [2.5, 0.0, 0.3, 0.0, 0.0],
            nu: [0.2, 0.1],
        };
        let n = (t_end / h).round() as usize;
        for k in 0..n {
            st = plant.rk4_step(&st, k as f64 * h, h, &tau, &mut *pert);
        }
        st
    }

    /// The angle-sum shortcut equals sin/cos(θ + δ) to rounding, on both
    /// sides of the series threshold.
    #[test]
    fn small_angle_sin_cos_matches_direct() {
        for i in 0..2000 {
            let th = -7.0 + 0.007 * i as f64;
            let delta = -0.03 + 0.00003 * i as f64;
            let (s, c) = sin_cos_offset(th, sin_cos(th), delta);
            let (s_ref, c_ref) = (th + delta).sin_cos();
            let err = (s - s_ref).abs().max((c - c_ref).abs());
            // θ + δ itself rounds by up to half an ulp of 8 (8.9e-16).
            assert!(err < 1.5e-15, "{th} {delta}: {err:e}");
        }
    }

    /// Fourth order: halving the step divides the error by ~16.
    #[test]
    fn rk4_converges_at_fourth_order() {
        let plant = paper_plant();
        let tau = [0.8, 0.3];
        let a = run(&plant, 0.04, 4.0, tau, &mut perturbed);
        let b = run(&plant, 0.02, 4.0, tau, &mut perturbed);
        let c = run(&plant, 0.01, 4.0, tau, &mut perturbed);
        let diff = |u: &PlantState, v: &PlantState| {
            (0..3).map(|i| (u.q[i] - v.q[i]).abs()).fold(0.0, f64::max)
        };
        let ratio = diff(&a, &b) / diff(&b, &c);
        assert!(ratio > 12.0 && ratio < 20.0, "ratio {ratio}");
    }

    /// No slip, no disturbance, equal torques τ on both wheels from rest:
    /// ω stays 0 and v̇ = 2τ/(r·M1₁₁), so the distance is a·t²/2 along θ0.
    #[test]
    fn constant_torque_straight_line_matches_analytic() {
        let plant = paper_plant();
        let tau = 0.5;
        let mut st = PlantState {
            q: [1.0, -1.0, 0.4, 0.0, 0.0],
            nu: [0.0, 0.0],
        };
        let h = 1e-3;
        let t_end = 3.0;
        for k in 0..3000 {
            st = plant.rk4_step(&st, k as f64 * h, h, &[tau, tau], &mut |_| {
                Perturbation::default()
            });
        }
        let a = 2.0 * tau / (plant.params().wheel_radius_m * plant.params().m1_diag()[0]);
        let dist = 0.5 * a * t_end * t_end;
        assert!((st.nu[0] - a * t_end).abs() < 1e-9);
        assert!(st.nu[1].abs() < 1e-12);
        assert!((st.q[0] - (1.0 + dist * 0.4f64.cos())).abs() < 1e-9);
        assert!((st.q[1] - (-1.0 + dist * 0.4f64.sin())).abs() < 1e-9);
        // Wheel angles: φ = distance / r.
        assert!((st.q[3] - dist / plant.params().wheel_radius_m).abs() < 1e-8);
    }

    /// Opposite torques from rest: ω̇ = 2hτ/(r·M1₂₂) = α constant (N1 ν has no
    /// ω component while v = ... small), and the offset d couples a centripetal
    /// v̇ = 2md·ω²/M1₁₁, so v(t) = 2md·α²t³/(3·M1₁₁) to leading order.
    #[test]
    fn opposite_torques_spin_with_analytic_rates() {
        let plant = paper_plant();
        let tau = 0.2;
        let mut st = PlantState::default();
        let h = 1e-3;
        for k in 0..1000 {
            st = plant.rk4_step(&st, k as f64 * h, h, &[tau, -tau], &mut |_| {
                Perturbation::default()
            });
        }
        let p = *plant.params();
        let m1 = p.m1_diag();
        let alpha = 2.0 * p.half_track_m * tau / (p.wheel_radius_m * m1[1]);
        let v_expect = 2.0 * p.mass_kg * p.com_offset_m * alpha * alpha / (3.0 * m1[0]);
        // ω̇ gets −2md·ω·v/M1₂₂, a relative correction of order 1e-4 here.
        assert!(
            (st.nu[1] - alpha).abs() < 1e-3 * alpha,
            "{} vs {alpha}",
            st.nu[1]
        );
        assert!(
            (st.nu[0] - v_expect).abs() < 1e-2 * v_expect,
            "{} vs {v_expect}",
            st.nu[0]
        );
    }

    /// The perturbed constraint (2), A(q)·q̇ = Δ_S, holds along a run with slip,
    /// skid and disturbance (no fault), with A's printed typos corrected.
    #[test]
    fn perturbed_constraint_holds_along_run() {
        let plant = paper_plant();
        let p = *plant.params();
        let (r, h, d) = (p.wheel_radius_m, p.half_track_m, p.com_offset_m);
        let mut st = PlantState {
            q: [0.0, 0.0, 0.5, 0.0, 0.0],
            nu: [0.3, 0.2],
        };
        let dt = 1e-3;
        for k in 0..5000 {
            let t = k as f64 * dt;
            let pert = perturbed(t);
            let qd = plant.q_dot(&st, &pert);
            let (s, c) = st.q[2].sin_cos();
            let aq = [
                -s * qd[0] + c * qd[1] - d * qd[2],
                c * qd[0] + s * qd[1] + h * qd[2] - r * qd[3],
                c * qd[0] + s * qd[1] - h * qd[2] - r * qd[4],
            ];
            let ds = [
                pert.skid_mps,
                -r * pert.wheel_slip_radps[0],
                -r * pert.wheel_slip_radps[1],
            ];
            for i in 0..3 {
                assert!((aq[i] - ds[i]).abs() < 1e-12, "row {i} at t {t}");
            }
            st = plant.rk4_step(&st, t, dt, &[0.3, 0.1], &mut perturbed);
        }
    }

    /// P1 closed form equals SᵀM0·U̇_D + SᵀC0·U_D from the 5x5 matrices.
    #[test]
    fn p1_closed_form_matches_matrices() {
        let plant = paper_plant();
        let p = *plant.params();
        let (m, i, iw, r, h, d) = p.unpack();
        let st = PlantState {
            q: [0.0, 0.0, 0.9, 0.0, 0.0],
            nu: [0.4, -0.6],
        };
        let pert = Perturbation {
            tau_d: [0.0; 5],
            ..perturbed(1.3)
        };
        let th = st.q[2];
        let thd = plant.q_dot(&st, &pert)[2];
        let (s, c) = th.sin_cos();
        let dl = pert.skid_mps;
        let dld = pert.skid_rate_mps2;
        let ud_dot = [
            -c * thd * dl - s * dld,
            -s * thd * dl + c * dld,
            0.0,
            pert.wheel_slip_rate_radps2[0],
            pert.wheel_slip_rate_radps2[1],
        ];
        let ud = [
            -s * dl,
            c * dl,
            0.0,
            pert.wheel_slip_radps[0],
            pert.wheel_slip_radps[1],
        ];
        let mut m0 = [[0.0; 5]; 5];
        m0[0][0] = m;
        m0[1][1] = m;
        m0[0][2] = -m * d * s;
        m0[2][0] = m0[0][2];
        m0[1][2] = m * d * c;
        m0[2][1] = m0[1][2];
        m0[2][2] = i;
        m0[3][3] = iw;
        m0[4][4] = iw;
        let mut c0 = [[0.0; 5]; 5];
        c0[0][2] = -m * d * thd * c;
        c0[1][2] = -m * d * thd * s;
        let sm = [
            [c, -d * s],
            [s, d * c],
            [0.0, 1.0],
            [1.0 / r, h / r],
            [1.0 / r, -h / r],
        ];
        let mut p1 = [0.0; 2];
        for j in 0..2 {
            for a in 0..5 {
                let row: f64 = (0..5)
                    .map(|b| m0[a][b] * ud_dot[b] + c0[a][b] * ud[b])
                    .sum();
                p1[j] += sm[a][j] * row;
            }
        }
        // ν̇ with zero torque and no τ_d is −(N1ν + P1)/M1: recover P1 from it.
        let nud = plant.nu_dot(&st, &pert, [0.0, 0.0]);
        let m1 = p.m1_diag();
        let n1c = 2.0 * m * d * thd;
        let p1_impl = [
            -nud[0] * m1[0] + n1c * st.nu[1],
            -nud[1] * m1[1] - n1c * st.nu[0],
        ];
        for j in 0..2 {
            assert!(
                (p1[j] - p1_impl[j]).abs() < 1e-12,
                "P1[{j}] {} vs {}",
                p1[j],
                p1_impl[j]
            );
        }
    }
}
